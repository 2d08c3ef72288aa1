"""Where ``vrloco benchmark`` runs its jobs: the Ray backend (``--backend ray``).

The local backend (:func:`agents.benchmark.run._run_jobs`) runs the grid's jobs in a process pool on
this machine. :func:`run_jobs_ray` runs the same jobs — one per (cell group, batch of seeds),
each a call of :func:`agents.benchmark.jobs._job` — as Ray tasks on a Ray cluster, and yields each
job's episodes as it finishes, so that :func:`agents.benchmark.run.run_benchmark` keeps them in
``<out>/.resume`` and builds the table from them exactly as for the local backend: the rows are
the same, only where the episodes ran differs.

Ray is an optional extra (``pip install 'vrloco[ray]'``), imported only here and only when the
Ray backend is asked for.

Failures:

* a worker process or a node lost mid-run: Ray runs the task again, up to :data:`MAX_RETRIES`
  times; an exception raised by the job's own code (a policy that raises) is not retried — the
  episodes are seeded, so a rerun would raise again;
* a job that still fails is reported, after every other job has finished and been yielded, in a
  :class:`BackendError` naming its cells and seeds;
* an address where no Ray cluster answers: a :class:`BackendError` naming the address, within
  :data:`CONNECT_TIMEOUT_S` (Ray itself would retry for minutes).
"""

from __future__ import annotations

import logging
import socket
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any

__all__ = [
    "CONNECT_TIMEOUT_S",
    "MAX_RETRIES",
    "RAY_HINT",
    "BackendError",
    "cancel_pending",
    "describe_job",
    "import_ray",
    "ray_results",
    "run_jobs_ray",
]

#: Times Ray runs a task again after its worker process or node was lost.
MAX_RETRIES = 2
#: Seconds to wait for the cluster at a ``HOST:PORT`` address to accept a connection.
CONNECT_TIMEOUT_S = 5.0
TOKEN_HINT = (
    "no cluster there, or it wants a token: RAY_AUTH_MODE=token and "
    "RAY_AUTH_TOKEN=<`ray get-auth-token` on its head>"
)
RAY_HINT = (
    "--backend ray needs Ray: pip install 'vrloco[ray]' (or pip install 'ray>=2.9') "
    "in this environment and on every machine of the cluster"
)


class BackendError(RuntimeError):
    """A run on the Ray cluster could not start (``partial`` False) or lost jobs after others
    had finished (``partial`` True); the message says which, by cell and seeds."""

    def __init__(self, message: str, partial: bool = False) -> None:
        super().__init__(message)
        self.partial = partial


def import_ray() -> Any:
    """The ``ray`` module, or a ValueError with :data:`RAY_HINT` where it is not installed."""
    try:
        import ray
    except ImportError as err:
        raise ValueError(RAY_HINT) from err
    return ray


def run_jobs_ray(jobs: list, address: str | None, progress: bool) -> Iterator[list[tuple]]:
    """Yield each job's ``[(cell, index, stats, reset_info), ...]`` as its Ray task finishes, in
    any order, under the local backend's progress bar (advanced per finished job).

    Args:
        jobs: ``(episodes, batch_size)`` jobs of :func:`agents.benchmark.run._split_jobs`.
        address: the cluster: ``"auto"`` (one started with ``ray start`` on this machine, or
            ``RAY_ADDRESS``), ``"HOST:PORT"`` (its head), or None: ``"auto"``'s cluster where
            there is one, else a new local Ray instance on this machine's cores, shut down at
            the end. A Ray connection that this process already holds (an earlier
            ``ray.init``) is used as it is.
        progress: show the progress bar.

    Raises:
        ValueError: Ray is not installed (:data:`RAY_HINT`), a malformed address.
        BackendError: no cluster at ``address``; jobs that failed (after the others were
            yielded), by cell and seeds; the cluster lost mid-run.
    """
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    from agents.benchmark.jobs import _job

    ray = import_ray()
    if not jobs:  # every episode was found in .resume: no cluster needed
        return
    started = _connect(ray, address)
    columns = (
        "[progress.description]{task.description}",
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
    )  # the local backend's
    pending: dict[Any, tuple] = {}
    try:
        with Progress(*columns, disable=not progress, transient=False) as bar:
            task = bar.add_task("episodes", total=sum(len(job[0]) for job in jobs))
            remote = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(_job)
            pending = {remote.remote(job): job for job in jobs}
            failed: list[tuple[tuple, BaseException]] = []
            for job, done, err in ray_results(ray, pending, _lost):
                if err is not None:
                    failed.append((job, err))
                    continue
                yield done
                bar.advance(task, len(done))
        if failed:
            lines = [f"  {describe_job(job)}: {_cause(err)}" for job, err in failed]
            raise BackendError(
                f"{len(failed)} of {len(jobs)} Ray jobs failed (the other "
                f"{len(jobs) - len(failed)} finished):\n" + "\n".join(lines),
                partial=True,
            )
    finally:  # Ctrl-C or an error: stop what still runs
        cancel_pending(ray, pending)
        if started:
            ray.shutdown()


def ray_results(
    ray: Any, pending: dict[Any, Any], unfinished: Callable[[Iterable[Any]], str]
) -> Iterator[tuple[Any, Any, BaseException | None]]:
    """The Ray tasks of ``pending`` (a task's reference: what it stands for) as each finishes:
    ``(what, result, None)``, or ``(what, None, error)`` where its retries were spent or its
    code raised. A finished task leaves ``pending``, so that what is left there is what to
    cancel (:func:`cancel_pending`) when the caller stops early.

    Raises:
        BackendError: the cluster lost mid-run, naming ``unfinished(pending.values())``.
    """
    while pending:
        try:
            ready, _ = ray.wait(list(pending), num_returns=1)
        except ray.exceptions.RaySystemError as err:
            raise BackendError(
                f"lost the Ray cluster mid-run ({_first_line(err)}); "
                f"{unfinished(pending.values())}",
                partial=True,
            ) from err
        for ref in ready:
            what = pending.pop(ref)
            try:
                result = ray.get(ref)
            except ray.exceptions.RayError as err:  # retries spent, or the code raised
                yield what, None, err
                continue
            yield what, result, None


def cancel_pending(ray: Any, pending: dict[Any, Any]) -> None:
    """Cancel the Ray tasks still in ``pending`` (the cluster may be gone already)."""
    for ref in pending:
        try:
            ray.cancel(ref, force=True)
        except Exception:  # the cluster may be gone already
            pass


def describe_job(job: tuple) -> str:
    """A job's cells and seeds: ``cell (approach, goal_seeker, zhang2021) seeds 0-2, 5``, one per
    cell, joined by ``; ``."""
    seeds: dict[Any, list[int]] = {}
    for cell, _, seed, _ in job[0]:
        seeds.setdefault(cell, []).append(int(seed))
    return "; ".join(
        f"cell ({c.task}, {c.policy}, {c.technique_name}) "
        f"seed{'s' if len(s) > 1 else ''} {_ranges(s)}"
        for c, s in seeds.items()
    )


def _ranges(values: Sequence[int]) -> str:
    """``[0, 1, 2, 5]`` as ``0-2, 5``."""
    out: list[str] = []
    vs = sorted(set(values))
    lo = prev = vs[0]
    for v in [*vs[1:], None]:
        if v is not None and v == prev + 1:
            prev = v
            continue
        out.append(str(lo) if lo == prev else f"{lo}-{prev}")
        if v is not None:
            lo = prev = v
    return ", ".join(out)


def _lost(jobs: Any) -> str:
    jobs = list(jobs)
    return f"{len(jobs)} unfinished jobs: " + "; ".join(describe_job(j) for j in jobs)


def _cause(err: BaseException) -> str:
    """The error a task raised (a RayTaskError's cause), or Ray's own, in one line."""
    cause = getattr(err, "cause", None)
    if isinstance(cause, BaseException):
        return f"{type(cause).__name__}: {_first_line(cause)}"
    return f"{type(err).__name__} after {MAX_RETRIES} retries: {_first_line(err)}"


def _first_line(err: BaseException) -> str:
    lines = [s.strip() for s in str(err).splitlines() if s.strip()]
    return lines[0] if lines else type(err).__name__


def _connect(ray: Any, address: str | None) -> bool:
    """Connect to the cluster at ``address`` (see :func:`run_jobs_ray`); True when this call
    connected (``ray.shutdown`` at the end then stops a local instance it started, and only
    disconnects from a running cluster), False when this process was connected already.

    The address Ray would connect to is tried first with a plain TCP connection, so that a
    wrong address, or a cluster that went away without ``ray stop`` (its address still in
    ``/tmp/ray/ray_current_cluster``), gets an error in seconds."""
    if address is not None:
        if not isinstance(address, str) or not address.strip():
            raise ValueError(f"address must be 'auto' or 'HOST:PORT', got {address!r}")
        address = address.strip()
    if ray.is_initialized():
        if address not in (None, "auto") and not address.startswith("ray://"):
            _probe(address, address)
        return False
    if address is None or not address.startswith("ray://"):
        target = _resolve(address)
        if target is not None:
            _probe(target, address)
    refused = getattr(ray.exceptions, "AuthenticationError", ())  # Ray >= 2.52
    try:
        ray.init(address=address, include_dashboard=False, logging_level=logging.WARNING)
    except refused as err:
        raise BackendError(
            f"the Ray cluster at {address!r} refused the connection: "
            f"{_first_line(err)} ({TOKEN_HINT})"
        ) from err
    except ConnectionError as err:
        raise BackendError(
            f"could not connect to the Ray cluster at {address!r}: "
            f"{_first_line(err)} ({TOKEN_HINT})"
        ) from err
    res = ray.cluster_resources()
    nodes = sum(1 for n in ray.nodes() if n.get("Alive"))
    print(
        f"ray: the cluster at {ray.get_runtime_context().gcs_address}, {nodes} "
        f"node{'s' if nodes != 1 else ''}, {int(res.get('CPU', 0))} CPUs"
    )
    return True


def _resolve(address: str | None) -> str | None:
    """The ``HOST:PORT`` that ``ray.init(address)`` connects to (``RAY_ADDRESS``, then the last
    ``ray start`` of this machine, for ``"auto"`` and None), or None where it starts a local
    instance (or this Ray version does not say)."""
    try:
        from ray._private.services import canonicalize_bootstrap_address
    except ImportError:  # another layout: only an explicit address is tried
        return None if address in (None, "auto") else address
    try:
        return canonicalize_bootstrap_address(address)
    except ConnectionError as err:  # "auto" and no cluster
        raise BackendError(
            f"no Ray cluster found for address 'auto': {_first_line(err)} "
            "(start one with `ray start --head`, or leave out --address for a "
            "local instance)"
        ) from err
    except ValueError as err:
        raise ValueError(f"address must be 'auto' or 'HOST:PORT', got {address!r}") from err


def _probe(target: str, address: str | None) -> None:
    """A BackendError unless ``target`` (``HOST:PORT``, the resolved ``address``) accepts a TCP
    connection within :data:`CONNECT_TIMEOUT_S`."""
    host, sep, port = target.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise ValueError(f"address must be 'auto' or 'HOST:PORT', got {address!r}")
    try:
        socket.create_connection((host.strip("[]"), int(port)), CONNECT_TIMEOUT_S).close()
    except OSError as err:
        if address in (None, "auto"):
            given = "the default address" if address is None else "address 'auto'"
            raise BackendError(
                f"cannot reach the Ray cluster at {target}: {err} (found for "
                f"{given} in RAY_ADDRESS or the last `ray start` of this "
                "machine; `ray stop` forgets a cluster that went away)"
            ) from err
        named = address if address == target else f"{address} ({target})"
        hint = f"is `ray start --head --port={port}` running there, and the port open?"
        raise BackendError(f"cannot reach a Ray cluster at {named}: {err} ({hint})") from err

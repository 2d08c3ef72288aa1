"""One training run per seed: :func:`train_seeds` runs :func:`agents.learned.train.train_ppo` for
each seed in worker processes (or as Ray tasks) and draws their learning curves together
(:mod:`agents.learned.curves`).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from agents.learned.curves import _read_curves, write_seed_curves
from agents.learned.imitation import check_imitation
from agents.learned.mixed_env import training_cells
from agents.learned.models import env_settings
from agents.learned.train import (
    _policy_settings,
    _reward_kwargs,
    defaults_ppo,
    rollout_steps,
    train_ppo,
)

__all__ = ["train_seeds"]


def train_seeds(
    task: str,
    seeds: list[int],
    out_dir: Path,
    workers: int | None = None,
    backend: str = "local",
    address: str | None = None,
    **train_kwargs: Any,
) -> list[Path]:
    """:func:`train_ppo` once per seed; returns the final models' paths, in the order of ``seeds``.

    One seed is exactly ``train_ppo(task, seed=seed, out_dir=out_dir, ...)``: the same files in
    ``out_dir``. Several seeds train in a :class:`~concurrent.futures.ProcessPoolExecutor` of
    ``workers`` processes (default: one per seed, at most one per core; spawned, so a script
    that calls this needs the ``if __name__ == "__main__":`` guard; no progress bars), each in
    ``out_dir/seed_<s>/`` with the files of a single run, seeded by its seed. The workers keep
    torch's default thread count, so each seed's curve and model are bit-identical to training
    that seed alone (fewer torch threads changed the last digits). Then
    ``out_dir/learning_curve.json`` holds ``{"task", "seeds", "per_seed": {seed: curve},
    "mean": [...]}``, where ``mean`` has, for each evaluation step that every seed reached, the
    mean and the standard deviation over the seeds (``ddof=0``, keys ``<metric>_std``) of the
    success rate, collision rate and mean return, and ``out_dir/learning_curve.png`` draws each
    seed's success rate thin, the mean bold and a mean +- std band against environment steps.

    Ctrl-C stops the workers at once and re-raises ``KeyboardInterrupt``; what each seed saved
    stays (its checkpoints, best model and learning curve up to its last evaluation; not a final
    model), the combined curve is written from those, and one line says so.

    ``backend="ray"`` trains every seed (one too) as a Ray task of one CPU on the cluster at
    ``address`` (as ``vrloco benchmark --backend ray`` connects: ``"auto"``, ``"HOST:PORT"``,
    or None: a running cluster, else a local instance; ``workers`` is not used):
    :func:`_train_seeds_ray`.
    """
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    seeds = list(seeds)
    if not seeds:
        raise ValueError("seeds: give at least one seed")
    for s in seeds:
        if isinstance(s, bool) or not isinstance(s, int) or s < 0:
            raise ValueError(f"seeds: {s!r} is not an integer >= 0")
    repeated = sorted({s for s in seeds if seeds.count(s) > 1})
    if repeated:
        raise ValueError(f"seeds: {', '.join(map(str, repeated))} given more than once")
    out_dir = Path(out_dir)
    if backend not in ("local", "ray"):
        raise ValueError(f"backend must be 'local' or 'ray', got {backend!r}")
    if address is not None and backend != "ray":
        raise ValueError(f"address={address!r} needs backend 'ray'")
    _check_run(task, train_kwargs)  # a bad cell is named here, before any worker starts
    if backend == "ray":
        return _train_seeds_ray(task, seeds, out_dir, address, train_kwargs)
    if len(seeds) == 1:
        return [train_ppo(task, seed=seeds[0], out_dir=out_dir, **train_kwargs)]
    from estimators.kernels import usable_cores

    workers = min(len(seeds), usable_cores()) if workers is None else workers
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers={workers!r}: must be an integer >= 1")
    kwargs = _worker_kwargs(train_kwargs)
    out_dir.mkdir(parents=True, exist_ok=True)
    folders = {s: out_dir / f"seed_{s}" for s in seeds}
    pool = ProcessPoolExecutor(
        max_workers=workers,
        mp_context=get_context("spawn"),  # torch in a forked child can hang
        initializer=_ignore_sigint,
    )
    try:
        futures = [
            pool.submit(train_ppo, task, seed=s, out_dir=folders[s], **kwargs) for s in seeds
        ]
        paths = [f.result() for f in futures]
    except BaseException as err:  # Ctrl-C (or a failed seed): stop the workers now
        for process in list(getattr(pool, "_processes", {}).values()):
            process.terminate()
        pool.shutdown(wait=False, cancel_futures=True)
        curves = _read_curves(folders)
        if curves:
            write_seed_curves(task, curves, out_dir)
        why = "interrupted" if isinstance(err, KeyboardInterrupt) else "a seed run failed"
        print(
            f"{why}: stopped {len(seeds)} seed runs; kept what each saved (checkpoints, best "
            f"model, learning curve so far) in {out_dir}/seed_*"
        )
        raise
    pool.shutdown()
    write_seed_curves(task, _read_curves(folders), out_dir)
    return paths


def _check_run(task: str, train_kwargs: dict[str, Any]) -> None:
    """The cell and the policy settings of :func:`train_ppo`'s keywords, checked (its errors)."""
    cells = training_cells(
        *(train_kwargs.get(k) for k in ("technique", "population", "variability"))
    )
    for technique, population, _ in cells:
        env_settings(
            task,
            train_kwargs.get("sensor_preset"),
            technique,
            population,
            train_kwargs.get("condition"),
            **_reward_kwargs(train_kwargs.get("reward")),
        )
    _policy_settings(train_kwargs.get("frame_stack", 1), train_kwargs.get("recurrent", False))
    if train_kwargs.get("residual_on") is not None:
        from agents.learned.residual import check_residual

        check_residual(
            train_kwargs["residual_on"],
            train_kwargs.get("recurrent", False),
            train_kwargs.get("env_workers", 1),
        )
    if train_kwargs.get("imitate") is not None:
        check_imitation(
            train_kwargs["imitate"],
            train_kwargs.get("init"),
            train_kwargs.get("recurrent", False),
            cells,
            train_kwargs.get("env_workers", 1),
        )


def _worker_kwargs(train_kwargs: dict[str, Any]) -> dict[str, Any]:
    """:func:`train_ppo`'s keywords for a worker: no progress bar, and the steps rounded (and
    checked) once here rather than in every worker."""
    n_steps = train_kwargs.get("n_steps", defaults_ppo()["n_steps"])
    kwargs = dict(train_kwargs, progress=False)
    kwargs["steps"] = rollout_steps(
        kwargs.get("steps", 2_000_000), n_steps, kwargs.get("num_envs", 32)
    )
    return kwargs


def _train_seeds_ray(
    task: str, seeds: list[int], out_dir: Path, address: str | None, train_kwargs: dict
) -> list[Path]:
    """:func:`train_seeds` on the Ray backend: one Ray task of one CPU per seed
    (:func:`_train_seed_task`), which trains in a temporary folder on its node and returns the
    folder's files; each seed's files are written here, in ``out_dir/seed_<s>/`` (one seed:
    in ``out_dir``), as its task finishes, so the cluster's nodes need no shared disk. The
    tasks set torch's thread count to this machine's default (at most their node's cores), so
    that on one machine a seed's curve and model are bit-identical to the local backend's.

    Failures (:mod:`agents.benchmark.backends`): a worker or node lost mid-run is retried up to
    :data:`~agents.benchmark.backends.MAX_RETRIES` times; a seed whose own code raised is not (it
    would raise again). After every other seed has finished and been written, a
    :class:`~agents.benchmark.backends.BackendError` names each failed seed and why; the combined
    curve holds the finished seeds. Ctrl-C cancels the tasks: the finished seeds' files stay (an
    unfinished seed's were on its node and are lost), the combined curve is written from them.
    """
    import torch

    from agents.benchmark.backends import (
        MAX_RETRIES,
        BackendError,
        _cause,
        _connect,
        cancel_pending,
        import_ray,
        ray_results,
    )

    ray = import_ray()
    kwargs = _worker_kwargs(train_kwargs)
    out_dir.mkdir(parents=True, exist_ok=True)
    folders = {s: out_dir if len(seeds) == 1 else out_dir / f"seed_{s}" for s in seeds}
    started = _connect(ray, address)
    remote = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(_train_seed_task)
    threads = torch.get_num_threads()
    pending = {remote.remote(task, s, kwargs, threads): s for s in seeds}
    paths: dict[int, Path] = {}
    failed: list[tuple[int, BaseException]] = []

    def unfinished(left: Any) -> str:
        return f"seeds {', '.join(map(str, sorted(left)))} unfinished"

    try:
        for s, result, err in ray_results(ray, pending, unfinished):
            if err is not None:
                failed.append((s, err))
                continue
            name, files = result
            for rel, data in files.items():
                (folders[s] / rel).parent.mkdir(parents=True, exist_ok=True)
                (folders[s] / rel).write_bytes(data)
            paths[s] = folders[s] / name
            print(f"seed {s}: trained ({len(paths)} of {len(seeds)}), in {folders[s]}")
    except BaseException as err:
        cancel_pending(ray, pending)
        if isinstance(err, KeyboardInterrupt):
            print(
                f"interrupted: cancelled {len(pending)} seed runs on Ray; kept the "
                f"{len(paths)} finished seeds' files in {out_dir}"
            )
        raise
    finally:
        if len(seeds) > 1 and paths:
            write_seed_curves(task, _read_curves({s: folders[s] for s in paths}), out_dir)
        if started:
            ray.shutdown()
    if failed:
        lines = [f"  seed {s}: {_cause(err)}" for s, err in sorted(failed, key=lambda f: f[0])]
        raise BackendError(
            f"{len(failed)} of {len(seeds)} seed runs failed on Ray (the other "
            f"{len(seeds) - len(failed)} finished, in {out_dir}):\n" + "\n".join(lines),
            partial=True,
        )
    return [paths[s] for s in seeds]


def _train_seed_task(
    task: str, seed: int, kwargs: dict[str, Any], threads: int
) -> tuple[str, dict[str, bytes]]:
    """One seed's :func:`train_ppo` in a temporary folder, with ``threads`` torch threads (at
    most this node's cores); returns the final model's file name and every file written
    (relative path: bytes)."""
    import tempfile

    import torch

    torch.set_num_threads(max(1, min(threads, os.cpu_count() or 1)))
    with tempfile.TemporaryDirectory(prefix=f"vrloco_seed{seed}_") as tmp:
        root = Path(tmp)
        path = train_ppo(task, seed=seed, out_dir=root, **kwargs)
        files = {
            str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
        }
    return path.name, files


def _ignore_sigint() -> None:
    """:func:`train_seeds`' workers leave Ctrl-C to the main process, which stops them."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)

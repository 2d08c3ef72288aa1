"""The benchmark's jobs in its local worker processes: a job plays its episodes batched in the
vector env or one at a time in the single env (:func:`_job`, also what a Ray task runs,
:mod:`agents.benchmark.backends`), and the workers of one pool claim a shared job's episodes
one by one from a counter they share (:class:`_Claim`), so that they end together."""

from __future__ import annotations

from typing import Any

from agents.benchmark.episodes import play_claimed, run_batched, run_cell_episode


def _job(args: tuple) -> list[tuple]:
    """Episodes ``(cell, index, seed, trace)``: batched in the vector env (cells sharing a task
    and technique), or one at a time in the single env for ``batch_size`` 0. ``args`` is
    ``(episodes, batch_size)``, or in a local worker process ``(episodes, batch_size, k)``: then
    the episodes are claimed from job ``k``'s shared counter (:func:`_init_worker`), so that
    the same job may run in several workers at once, each playing the episodes it claims.
    Returns ``(cell, index, stats, reset_info)`` per episode played."""
    episodes, batch_size, *shared = args
    plays = [(c, s, t) for c, _, s, t in episodes]
    if batch_size == 0:
        done = dict(enumerate(run_cell_episode(*p) for p in plays))
    elif not shared:
        done = dict(enumerate(run_batched(plays, batch_size)))
    else:
        claim = _Claim(_CLAIMED, shared[0], len(plays))
        if claim.left() == 0:  # a helper of a job already handed out
            return []
        done = play_claimed(plays, batch_size, claim)
    return [(*episodes[j][:2], *d) for j, d in sorted(done.items())]


#: In a local worker process: how many episodes of each job have been claimed (a shared
#: ``multiprocessing.Array``, set by :func:`_init_worker`).
_CLAIMED: Any = None


def _init_worker(claimed: Any, threads: int) -> None:
    """A local worker process: the jobs' shared claim counters, and ``threads`` for its compiled
    kernels (its share of the cores, :func:`estimators.kernels.use_threads`: 1 where there are
    as many workers as cores). Ctrl-C is left to the main process, which stops the workers."""
    import signal

    from estimators.kernels import use_threads

    global _CLAIMED
    _CLAIMED = claimed
    use_threads(threads)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _worker_threads(n_workers: int) -> int:
    """Each of ``n_workers`` local workers' share of this process's cores (at least 1, at most
    numba's thread count)."""
    import numba

    from estimators.kernels import usable_cores

    return max(1, min(usable_cores() // n_workers, numba.config.NUMBA_NUM_THREADS))


def _pool_context() -> Any:
    """How to start the local workers: the platform's default (``fork`` on Linux: the workers
    start at once, with this process's compiled kernels), unless this process has started
    numba's threads (a vector env of many users did) or imported torch (loading a learned user
    does; its OpenMP pool may have threads): forking a process that runs OpenMP threads is
    unsafe (GNU OpenMP kills the child, or the child's first parallel region waits forever), so
    the workers are spawned instead."""
    import multiprocessing
    import sys

    import numba

    if "torch" in sys.modules:
        return multiprocessing.get_context("spawn")
    try:
        numba.threading_layer()
    except ValueError:  # no thread started yet
        return multiprocessing.get_context()
    return multiprocessing.get_context("spawn")


class _Claim:
    """The claims on job ``k``'s ``total`` episodes through the shared counters ``claimed``:
    ``claim(n)`` takes the next (up to) ``n`` indices, for this process alone."""

    def __init__(self, claimed: Any, k: int, total: int) -> None:
        self.claimed, self.k, self.total = claimed, k, total

    def left(self) -> int:
        """How many of the job's episodes nobody has claimed yet."""
        with self.claimed.get_lock():
            return self.total - self.claimed[self.k]

    def __call__(self, n: int) -> list[int]:
        with self.claimed.get_lock():
            lo = self.claimed[self.k]
            hi = min(lo + n, self.total)
            self.claimed[self.k] = hi
        return list(range(lo, hi))

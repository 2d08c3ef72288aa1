"""Serial and multi-threaded builds of one compiled kernel, chosen per call by batch size.

A kernel whose loop over users is ``numba.prange`` compiles twice: serially (``prange`` runs as
``range``), for one user or a few, where starting threads would cost more than the work
(~10 us a call), and with ``parallel=True`` for large batches (a vector env of 256 users), where
the users' independent iterations share the cores. Users never share scratch memory in such a
kernel, so both builds give the same bits.

The parallel build is compiled from a copy of the function under another name, because numba's
on-disk cache keys a function by its name and bytecode, not by its compile flags.

Busy cores. Numba's default threading layer here is OpenMP (GNU libgomp), whose idle threads
spin on a core after each parallel region. While another job holds a core, those spinning
threads take the time the real work needs: a vector env of 64 users ran 10,100 user-steps/s with
idle cores and 5,400 while one other process kept one of the two cores busy, below the serial
build's 8,400. With passive waiting (``OMP_WAIT_POLICY=PASSIVE``, idle threads sleep) the same
run gave 11,000 and 9,900: no loss with idle cores, graceful under load. This module sets that
policy unless the environment already chooses one; it must be set before the OpenMP runtime
starts, which happens at the first parallel call, after this import.
(``python benchmarks/bench_env.py --contention`` measures both cases.)

Worker processes. A process that runs beside as many busy workers as there are cores has no
core for a kernel's second thread; :func:`use_threads` (``1``) keeps its kernels on their serial
builds (no parallel region to start and join, and no second build to load).
"""

from __future__ import annotations

import contextlib
import os
import types
from collections.abc import Callable, Iterator

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numba  # after the OpenMP policy: see the module docstring

__all__ = ["PARALLEL_MIN_BATCH", "BatchKernel", "python_reference", "usable_cores", "use_threads"]

#: Batches at least this large take the multi-threaded build (measured on 2 cores: below ~16
#: users the thread start-up outweighs the work of the motion and Kinect kernels).
PARALLEL_MIN_BATCH = 16


_python_reference = False
_serial_only = False  # set by use_threads(1)


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform has one)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return cores or 1


def use_threads(n: int) -> None:
    """Let the kernels of this process use at most ``n`` threads (``numba.set_num_threads``);
    ``n = 1`` keeps every kernel on its serial build. For a worker process among others that
    share the cores (:mod:`agents.benchmark` gives each of its local workers its share)."""
    global _serial_only
    most = numba.config.NUMBA_NUM_THREADS
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= most:
        raise ValueError(f"n must be an integer in [1, {most}], got {n!r}")
    _serial_only = n == 1
    if not _serial_only:
        numba.set_num_threads(n)


@contextlib.contextmanager
def python_reference() -> Iterator[None]:
    """Run every :class:`BatchKernel` uncompiled (its ``py_func``) inside the ``with`` block.

    For debugging (breakpoints, prints inside a kernel) and for the tests that check each compiled
    build against its Python source. Helpers a kernel calls stay compiled.
    """
    global _python_reference
    before, _python_reference = _python_reference, True
    try:
        yield
    finally:
        _python_reference = before


class BatchKernel:
    """Callable builds of ``func``; call ``kernel(batch_size)(*args)``.

    Args:
        func: the kernel's Python source, its outer loop over users a ``numba.prange``.
        parallel: also compile the multi-threaded build, taken for batches of at least
            :data:`PARALLEL_MIN_BATCH` users. Off for kernels whose work per call is too small
            to share out (their serial build serves every batch and compiles once).
    """

    def __init__(self, func: Callable, parallel: bool = True) -> None:
        self.serial = numba.njit(cache=True)(func)
        self.py_func = func  # the uncompiled reference (prange runs as range in Python)
        self.__doc__ = func.__doc__
        self.parallel = self.serial
        if not parallel:
            return
        clone = types.FunctionType(
            func.__code__,
            func.__globals__,
            func.__name__ + "_parallel",
            func.__defaults__,
            func.__closure__,
        )
        clone.__qualname__ = func.__qualname__ + "_parallel"
        clone.__module__ = func.__module__
        clone.__doc__ = func.__doc__
        self.parallel = numba.njit(cache=True, parallel=True)(clone)

    def __call__(self, batch_size: int) -> Callable:
        """The build for a batch of ``batch_size`` users (``py_func`` under
        :func:`python_reference`)."""
        if _python_reference:
            return self.py_func
        if batch_size >= PARALLEL_MIN_BATCH and not _serial_only:
            return self.parallel
        return self.serial

"""Serial and multi-threaded builds of one compiled kernel, chosen per call by batch size.

A kernel whose loop over users is ``numba.prange`` compiles twice: serially (``prange`` runs as
``range``), for one user or a few, where starting threads would cost more than the work
(~10 us a call), and with ``parallel=True`` for large batches (a vector env of 256 users), where
the users' independent iterations share the cores. Users never share scratch memory in such a
kernel, so both builds give the same bits.

The parallel build is compiled from a copy of the function under another name, because numba's
on-disk cache keys a function by its name and bytecode, not by its compile flags.
"""

from __future__ import annotations

import types
from collections.abc import Callable

import numba

__all__ = ["PARALLEL_MIN_BATCH", "BatchKernel"]

#: Batches at least this large take the multi-threaded build (measured on 2 cores: below ~16
#: users the thread start-up outweighs the work of the motion and Kinect kernels).
PARALLEL_MIN_BATCH = 16


class BatchKernel:
    """Callable pair of builds of ``func``; call ``kernel(batch_size)(*args)``.

    Args:
        func: the kernel's Python source, its outer loop over users a ``numba.prange``.
    """

    def __init__(self, func: Callable) -> None:
        self.serial = numba.njit(cache=True)(func)
        clone = types.FunctionType(
            func.__code__, func.__globals__, func.__name__ + "_parallel", func.__defaults__,
            func.__closure__,
        )  # fmt: skip
        clone.__qualname__ = func.__qualname__ + "_parallel"
        clone.__module__ = func.__module__
        clone.__doc__ = func.__doc__
        self.parallel = numba.njit(cache=True, parallel=True)(clone)
        self.py_func = func  # the uncompiled reference (prange runs as range in Python)
        self.__doc__ = func.__doc__

    def __call__(self, batch_size: int) -> Callable:
        """The build for a batch of ``batch_size`` users."""
        return self.parallel if batch_size >= PARALLEL_MIN_BATCH else self.serial

"""Selecting streams (users) of a batch: the one parser of "indices or a (B,) boolean mask"."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["stream_rows"]


def stream_rows(
    which: ArrayLike | None, batch_size: int, name: str = "users", unique: bool = True
) -> NDArray[np.intp]:
    """Indices of the selected streams of a batch of ``batch_size``.

    Args:
        which: None (every stream), integer indices, or a (B,) boolean mask.
        batch_size: B.
        name: the argument's name, for error messages.
        unique: reject a repeated index.

    Raises:
        ValueError: a mask of the wrong shape, non-integer or out-of-range indices, repeats.
    """
    b = batch_size
    if which is None:
        return np.arange(b)
    u = np.asarray(which)
    if u.dtype == bool:
        if u.shape != (b,):
            raise ValueError(f"{name} as a boolean mask must have shape ({b},), got {u.shape}")
        return np.flatnonzero(u)
    if u.size == 0:
        return np.zeros(0, dtype=np.intp)
    if not np.issubdtype(u.dtype, np.integer):
        raise ValueError(f"{name} must be integer indices in [0, {b - 1}] or a (B,) mask, got {u}")
    u = u.astype(np.intp).ravel()
    if u.min() < 0 or u.max() >= b:
        raise ValueError(f"{name} must lie in [0, {b - 1}], got {u}")
    if unique and np.unique(u).size != u.size:
        raise ValueError(f"{name} must not repeat an index, got {u}")
    return u

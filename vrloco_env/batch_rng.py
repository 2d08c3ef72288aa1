"""Per-user random streams for batched simulation.

Every simulated user owns one ``numpy.random.Generator`` (a single env's ``np_random``; sub-env i of
a vector env owns its own). Models that simulate B users at once must draw user i's numbers from
user i's generator only, so that a batch of B users reproduces B single runs bit for bit — also
when one user starts a new episode while the others carry on (a vector env's autoreset).

Calling B generators for every small draw would be a Python loop over the batch on the hot path.
:class:`BatchRng` instead keeps, per user, a block of pre-drawn standard normals and its own read
position, and serves a draw for all users as one gather from a ``(B, block)`` array; the loop over
users runs only when a user's block runs out (every few thousand numbers). Uniform numbers are the
normal CDF of the same stream. So each user has exactly one sequence of numbers: its generator's
stream, consumed in the order of that user's own draws — the same in a batch and in a single run,
whatever the other users do and wherever block refills fall (a generator's stream does not depend
on how it is split into calls).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtr

from estimators.batching import TakesUsers, stream_rows

__all__ = ["BatchRng"]

_BELOW_ONE = 1.0 - 2.0**-53  # the largest double below 1


class BatchRng(TakesUsers):
    """Random draws of shape ``(B, *shape)`` where row i comes from generator i alone.

    Args:
        generators: one ``numpy.random.Generator`` per user (B of them).
        block: numbers drawn per user at each refill.

    Example:
        >>> rngs = BatchRng([np.random.default_rng(s) for s in (0, 1)])
        >>> rngs.normal((10, 3)).shape
        (2, 10, 3)
        >>> rngs.normal((4,), rows=[1]).shape   # only user 1 draws (e.g. its reset)
        (1, 4)
    """

    per_user_fields = ("generators", "_buf", "_pos")  # each user's stream and unread numbers

    def __init__(self, generators: Sequence[np.random.Generator], block: int = 4096) -> None:
        gens = list(generators)
        if not gens:
            raise ValueError("generators must hold at least one numpy.random.Generator")
        for i, g in enumerate(gens):
            if not isinstance(g, np.random.Generator):
                raise TypeError(
                    f"generators[{i}] must be a numpy.random.Generator, got {type(g).__name__}"
                )
        if block < 1:
            raise ValueError(f"block must be >= 1, got {block}")
        self.generators = gens
        self._block = int(block)
        self._buf = np.empty((len(gens), self._block))
        self._pos = np.full(len(gens), self._block, dtype=np.int64)  # all empty: fill on demand
        self._cols = np.arange(self._block)

    @classmethod
    def from_seeds(cls, seeds: Sequence[int], block: int = 4096) -> BatchRng:
        """One ``default_rng(seed)`` per user."""
        return cls([np.random.default_rng(s) for s in seeds], block)

    @property
    def batch_size(self) -> int:
        return len(self.generators)

    def reseed(self, index: int, generator: np.random.Generator) -> None:
        """Give user ``index`` a new generator (a new episode), leaving the other users alone.

        From now on user ``index`` draws exactly what a fresh ``BatchRng([generator])`` would.
        """
        if not isinstance(generator, np.random.Generator):
            raise TypeError(f"generator must be a numpy.random.Generator, got {type(generator)}")
        if not 0 <= index < self.batch_size:
            raise ValueError(f"index must be in [0, {self.batch_size - 1}], got {index}")
        self.generators[index] = generator
        self._pos[index] = self._buf.shape[1]  # discard the old generator's unread numbers

    def _rows(self, rows: ArrayLike | None) -> NDArray[np.intp]:
        return stream_rows(rows, self.batch_size, "rows", unique=False)

    def _take(self, n: int, rows: NDArray[np.intp]) -> NDArray[np.float64]:
        if n > self._buf.shape[1]:  # a draw larger than a block: widen every user's buffer
            width = max(n, 2 * self._buf.shape[1])
            grown = np.empty((self.batch_size, width))
            for i in range(self.batch_size):  # rare; unread numbers keep their order at the end
                unread = self._buf[i, self._pos[i] :]
                grown[i, width - unread.size :] = unread
                self._pos[i] = width - unread.size
            self._buf = grown
            self._cols = np.arange(width)
        width = self._buf.shape[1]
        if (self._pos[rows] + n > width).any():
            # a user's block runs out: every user moves its unread numbers forward and refills
            # the rest (its stream goes on in order), so that all read from one position again
            # and the draws that follow are plain slices (users who started a new episode in
            # between fall in line here)
            for i in range(self.batch_size):
                self._move_unread(i, 0)
        start = self._pos[rows]
        if rows.size and np.all(start == start[0]) and rows.size == self.batch_size:
            out = self._buf[:, start[0] : start[0] + n].copy()  # lock-step: a plain slice
        else:
            out = self._buf[rows[:, None], start[:, None] + self._cols[:n]]
        self._pos[rows] += n
        return out

    def _move_unread(self, i: int, to: int) -> None:
        """Move user ``i``'s unread numbers back to column ``to`` (at most its read position)
        and top its block up from its generator: its stream goes on in order, read from
        ``to``."""
        width, at = self._buf.shape[1], int(self._pos[i])
        self._buf[i, to : width - (at - to)] = self._buf[i, at:]
        self._buf[i, width - (at - to) :] = self.generators[i].standard_normal(at - to)
        self._pos[i] = to

    def _realign(self) -> None:
        """Bring every user's read position back to the lowest one: a user ahead (it drew
        alone, at a reset) moves its unread numbers there (:meth:`_move_unread`). Only the
        users ahead are touched."""
        low = int(self._pos.min())
        for i in np.flatnonzero(self._pos != low):
            self._move_unread(int(i), low)

    def normal(self, shape: tuple[int, ...] = (), rows: ArrayLike | None = None) -> NDArray:
        """Standard normal numbers of shape ``(B, *shape)``, or ``(len(rows), *shape)`` drawn by
        the users ``rows`` only (indices or a (B,) boolean mask)."""
        n = math.prod(shape)
        if rows is None:  # the hot path: every user draws, usually from a common position
            p = self._pos
            if p.size > 1 and not (p == p[0]).all():
                self._realign()
            start = int(p[0])
            if start + n <= self._buf.shape[1]:
                p += n
                return self._buf[:, start : start + n].reshape(self.batch_size, *shape).copy()
        r = self._rows(rows)
        return self._take(n, r).reshape(r.size, *shape)

    def uniform(self, shape: tuple[int, ...] = (), rows: ArrayLike | None = None) -> NDArray:
        """Uniform numbers in (0, 1), the normal CDF of :meth:`normal` draws (same ``rows``)."""
        return np.minimum(ndtr(self.normal(shape, rows)), _BELOW_ONE)

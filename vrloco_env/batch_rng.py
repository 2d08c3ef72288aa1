"""Per-user random streams for batched simulation.

Every simulated user owns one ``numpy.random.Generator`` (a single env's ``np_random``; sub-env i of
a vector env owns its own). Models that simulate B users at once must draw user i's numbers from
user i's generator only, so that a batch of B users reproduces B single runs bit for bit.

Calling B generators for every small draw would be a Python loop over the batch on the hot path.
:class:`BatchRng` instead keeps, per user, a block of pre-drawn standard normals and serves draws
as slices of a ``(B, block)`` array: the loop over users runs once per block refill (every few
thousand numbers). Uniform numbers are the normal CDF of the same stream, so each user has exactly
one sequence of numbers, which depends on nothing but its own generator and the sequence of draw
sizes — the same for a batch and a single run, and unaffected by where block refills fall.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtr

__all__ = ["BatchRng"]


class _Stream:
    """A ``(B, block)`` buffer of standard normals refilled from B generators."""

    def __init__(self, gens: Sequence[np.random.Generator], block: int) -> None:
        self._gens = gens
        self._block = block
        self._buf = np.empty((len(gens), 0))
        self._pos = 0

    @staticmethod
    def _draw(g: np.random.Generator, n: int) -> NDArray[np.float64]:
        return g.standard_normal(n)

    def reseed(self, index: int, g: np.random.Generator) -> None:
        """Replace row ``index``'s unread numbers with fresh ones from ``g``."""
        self._gens[index] = g
        unread = self._buf.shape[1] - self._pos
        if unread:
            self._buf[index, self._pos :] = self._draw(g, unread)

    def take(self, n: int) -> NDArray[np.float64]:
        if self._pos + n > self._buf.shape[1]:
            need = max(self._block, n)
            rest = self._buf[:, self._pos :]
            fresh = np.stack([self._draw(g, need) for g in self._gens])  # once per block
            self._buf = np.concatenate([rest, fresh], axis=1)
            self._pos = 0
        out = self._buf[:, self._pos : self._pos + n]
        self._pos += n
        return out


class BatchRng:
    """Random draws of shape ``(B, *shape)`` where row i comes from generator i alone.

    Args:
        generators: one ``numpy.random.Generator`` per user (B of them).
        block: numbers drawn per user at each refill.

    Example:
        >>> rngs = BatchRng([np.random.default_rng(s) for s in (0, 1)])
        >>> rngs.normal((10, 3)).shape
        (2, 10, 3)
    """

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
        self._stream = _Stream(list(gens), block)

    @classmethod
    def from_seeds(cls, seeds: Sequence[int], block: int = 4096) -> BatchRng:
        """One ``default_rng(seed)`` per user."""
        return cls([np.random.default_rng(s) for s in seeds], block)

    def reseed(self, index: int, generator: np.random.Generator) -> None:
        """Give user ``index`` a new generator (a new episode), leaving the other users alone.

        From now on user ``index`` draws the same numbers as a fresh ``BatchRng([generator])``
        would: a generator's stream does not depend on how it is split into draws.
        """
        if not isinstance(generator, np.random.Generator):
            raise TypeError(f"generator must be a numpy.random.Generator, got {type(generator)}")
        if not 0 <= index < self.batch_size:
            raise ValueError(f"index must be in [0, {self.batch_size - 1}], got {index}")
        self.generators[index] = generator
        self._stream.reseed(index, generator)

    @property
    def batch_size(self) -> int:
        return len(self.generators)

    def normal(self, shape: tuple[int, ...] = ()) -> NDArray[np.float64]:
        """Standard normal numbers of shape ``(B, *shape)``."""
        n = int(np.prod(shape, dtype=np.int64))
        return self._stream.take(n).reshape(self.batch_size, *shape)

    def uniform(self, shape: tuple[int, ...] = ()) -> NDArray[np.float64]:
        """Uniform numbers in (0, 1) of shape ``(B, *shape)`` (the normal CDF of normal draws)."""
        return ndtr(self.normal(shape))

"""2-D queries of N users in N rooms at once: :class:`RoomBatch`."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers
from estimators.validation import check_value
from vrloco_env.world.geometry import (
    _pack,
    _pack_many,
    _ray_cast_fast,
    _sdf_fast,
    _Solids,
    ray_fan_kernel,
)
from vrloco_env.world.layout import Layout

__all__ = ["RoomBatch"]


class RoomBatch(TakesUsers):
    """The solids of N layouts packed once, for 2-D queries of N users in one compiled call.

    The batched twin of :func:`signed_distance` and :func:`ray_cast_2d` (same kernels: those are
    the N = 1 case). Points are in each room's local frame. It is the fast alternative to
    PyBullet's rays and contacts for a vector env: at N = 256 users x 16 rays, 0.44 ms per step
    against 13 ms for ``rayTestBatch`` on one core (``benchmarks/bench_sim.py``), and exact where
    Bullet's ray cast is off by up to ~1 mm on cylinders. An avatar of radius r centred at p
    touches the room where ``signed_distance(p) <= r``. Obstacles are extruded footprints: rays
    at height z see only solids taller than z (pass ``z``).

    Args:
        layouts: one layout per user.
    """

    per_user_fields = ("layouts", "_solids")  # each user's room, and its packed solids

    def __init__(self, layouts: Sequence[Layout]) -> None:
        self.layouts = list(layouts)
        if not self.layouts or not all(isinstance(x, Layout) for x in self.layouts):
            raise ValueError("layouts must be a non-empty sequence of Layout")
        self._solids = _pack_many([x.solids for x in self.layouts])

    def __len__(self) -> int:
        return len(self.layouts)

    def set(self, i: int, layout: Layout) -> None:
        """Replace room ``i`` (a sub-env reset); repacks only if the new room has more solids."""
        if not 0 <= i < len(self.layouts):
            raise ValueError(f"i must lie in [0, {len(self.layouts) - 1}], got {i}")
        self.layouts[i] = layout
        one = _pack(layout.solids)
        s = self._solids
        if one.box_c.shape[1] > s.box_c.shape[1] or one.cyl_c.shape[1] > s.cyl_c.shape[1]:
            self._solids = _pack_many([x.solids for x in self.layouts])
            return
        nb, nc = one.box_c.shape[1], one.cyl_c.shape[1]
        for name in _Solids._fields:
            arr, new = getattr(s, name), getattr(one, name)
            k = nb if name.startswith("box") else nc
            arr[i] = False if arr.dtype == bool else 0.0
            arr[i, :k] = new[0]

    def signed_distance(self, points: ArrayLike, z: float | None = None) -> NDArray[np.float64]:
        """Signed distances ``(N, P)`` (m) of local points ``(N, P, 2)``; see
        :func:`signed_distance`."""
        p = np.asarray(points, dtype=np.float64)
        if p.ndim != 3 or p.shape[0] != len(self) or p.shape[2] != 2:
            raise ValueError(f"points must have shape ({len(self)}, P, 2), got {p.shape}")
        if not np.isfinite(p).all():
            raise ValueError("points must be finite")
        return _sdf_fast(self._solids.above(z), p)

    def ray_cast(
        self, origins: ArrayLike, angles: ArrayLike, max_range: float, z: float | None = None
    ) -> NDArray[np.float64]:
        """Ray distances ``(N, R)`` (m) from local origins ``(N, R, 2)`` along angles ``(N, R)``
        (rad); see :func:`ray_cast_2d`."""
        o = np.asarray(origins, dtype=np.float64)
        a = np.asarray(angles, dtype=np.float64)
        if o.ndim != 3 or o.shape[0] != len(self) or o.shape[2] != 2:
            raise ValueError(f"origins must have shape ({len(self)}, R, 2), got {o.shape}")
        if a.shape != o.shape[:2]:
            raise ValueError(f"angles must have shape {o.shape[:2]}, got {a.shape}")
        if not (np.all(np.isfinite(o)) and np.all(np.isfinite(a))):
            raise ValueError("origins and angles must be finite")
        check_value("max_range", max_range, 0.0, 1e6, "m", lo_open=True)
        r = float(max_range)
        u = np.stack([np.cos(a), np.sin(a)], axis=-1)
        return _ray_cast_fast(self._solids.above(z), o, u, r)

    def ray_fan(
        self,
        positions: NDArray[np.float64],
        headings: NDArray[np.float64],
        offsets: NDArray[np.float64],
        max_range: float,
    ) -> NDArray[np.float64]:
        """Ray distances ``(N, R)`` (m) from each room's point ``positions`` (N, 2) along
        ``headings`` (N,) + ``offsets`` (R,) (rad): :meth:`ray_cast` for the env's per-step fan
        of rays from the virtual head, with its checks reduced to finiteness (the env's arrays
        have the shapes by construction)."""
        if not (np.isfinite(positions).all() and np.isfinite(headings).all()):
            raise ValueError("ray_fan positions and headings must be finite")
        s = self._solids
        out = np.empty((positions.shape[0], offsets.shape[0]))
        ray_fan_kernel(positions.shape[0])(
            *s.kernel_args, positions, headings, offsets, float(max_range), out
        )
        return out

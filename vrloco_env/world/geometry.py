"""2-D geometry of a room's solids: the floor-standing primitives and the exact distance and
ray-cast queries on them.

:class:`Box` and :class:`Cylinder` are frozen footprints extruded from the floor (z = 0) to their
height, in a room's local frame (x, y in metres, yaw counter-clockwise from +x; ENU, z up, as in
:mod:`estimators.rotations`). For queries the solids of N rooms are packed into padded arrays
(:class:`_Solids`); each query is one compiled kernel over rooms and points (its ``py_func``,
under :func:`estimators.kernels.python_reference`, is the readable reference; the tests check
the queries against hand-computed distances and sphere tracing). :func:`solid_distance` is the
query a
task's layout generator uses on loose solids; the queries on a whole room are in
:mod:`vrloco_env.world.layout` (one room) and :mod:`vrloco_env.world.room_batch` (N rooms).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.kernels import BatchKernel

__all__ = ["Box", "Cylinder", "Solid", "solid_distance"]


@dataclass(frozen=True)
class Box:
    """An upright box standing on the floor.

    Attributes:
        center: ``(x, y)`` of the footprint centre (m, local frame).
        half_extents: half sizes ``(hx, hy)`` along the box's own x and y (m).
        yaw: rotation of the box about +z (rad).
        height: height of the top face above the floor (m).
    """

    center: tuple[float, float]
    half_extents: tuple[float, float]
    yaw: float = 0.0
    height: float = 1.0


@dataclass(frozen=True)
class Cylinder:
    """An upright cylinder standing on the floor.

    Attributes:
        center: ``(x, y)`` of the axis (m, local frame).
        radius: radius (m).
        height: height of the top face above the floor (m).
    """

    center: tuple[float, float]
    radius: float
    height: float = 1.0


Solid = Box | Cylinder


class _Solids(NamedTuple):
    """The solids of N rooms packed as padded arrays; ``*_ok`` masks out the padding."""

    box_c: NDArray[np.float64]  # (N, B, 2) centres
    box_h: NDArray[np.float64]  # (N, B, 2) half extents
    box_cs: NDArray[np.float64]  # (N, B, 2) cos, sin of yaw
    box_z: NDArray[np.float64]  # (N, B) heights
    box_ok: NDArray[np.bool_]  # (N, B) real (not padding)
    cyl_c: NDArray[np.float64]  # (N, C, 2) centres
    cyl_r: NDArray[np.float64]  # (N, C) radii
    cyl_z: NDArray[np.float64]  # (N, C) heights
    cyl_ok: NDArray[np.bool_]  # (N, C)

    @property
    def kernel_args(self) -> tuple[NDArray, ...]:
        """The arrays the compiled queries take, in their order (heights left out)."""
        return self.box_c, self.box_h, self.box_cs, self.box_ok, self.cyl_c, self.cyl_r, self.cyl_ok

    def above(self, z: float | None) -> _Solids:
        """Only the solids taller than ``z`` (a horizontal slice at height z); all if None."""
        if z is None:
            return self
        return self._replace(
            box_ok=self.box_ok & (self.box_z > z), cyl_ok=self.cyl_ok & (self.cyl_z > z)
        )


def _pack_many(rooms: list[tuple[Solid, ...]]) -> _Solids:
    """Pack the solids of N rooms, padding every room to the largest box and cylinder counts."""
    n = len(rooms)
    boxes = [[s for s in r if isinstance(s, Box)] for r in rooms]
    cyls = [[s for s in r if isinstance(s, Cylinder)] for r in rooms]
    nb, nc = max((len(b) for b in boxes), default=0), max((len(c) for c in cyls), default=0)
    box = np.zeros((n, nb, 6))  # cx, cy, hx, hy, yaw, height
    cyl = np.zeros((n, nc, 4))  # cx, cy, r, height
    box_ok, cyl_ok = np.zeros((n, nb), bool), np.zeros((n, nc), bool)
    for i, (bs, cs) in enumerate(zip(boxes, cyls, strict=True)):
        if bs:
            box[i, : len(bs)] = [(*b.center, *b.half_extents, b.yaw, b.height) for b in bs]
            box_ok[i, : len(bs)] = True
        if cs:
            cyl[i, : len(cs)] = [(*c.center, c.radius, c.height) for c in cs]
            cyl_ok[i, : len(cs)] = True
    yaw = box[..., 4]
    return _Solids(
        box[..., :2],
        box[..., 2:4],
        np.stack([np.cos(yaw), np.sin(yaw)], -1),
        box[..., 5],
        box_ok,
        cyl[..., :2],
        cyl[..., 2],
        cyl[..., 3],
        cyl_ok,
    )


def _pack(solids: tuple[Solid, ...]) -> _Solids:
    return _pack_many([solids])


@numba.njit(cache=True, inline="always")
def _sdf_point(box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok, n, px, py):
    """Signed distance from the point ``(px, py)`` to the union of room n's solids (inf if
    none): negative inside a solid. A box's distance is that of the point in the box's frame to
    the rectangle (outside: the norm of the positive parts of ``|x| - h``; inside: the largest
    of them), a cylinder's the distance to its centre less its radius."""
    best = np.inf
    for j in range(box_c.shape[1]):
        if box_ok[n, j]:
            dx, dy = px - box_c[n, j, 0], py - box_c[n, j, 1]
            c, s = box_cs[n, j, 0], box_cs[n, j, 1]
            lx = abs(c * dx + s * dy) - box_h[n, j, 0]
            ly = abs(-s * dx + c * dy) - box_h[n, j, 1]
            ox, oy = max(lx, 0.0), max(ly, 0.0)
            best = min(best, math.sqrt(ox * ox + oy * oy) + min(max(lx, ly), 0.0))
    for j in range(cyl_c.shape[1]):
        if cyl_ok[n, j]:
            dx, dy = px - cyl_c[n, j, 0], py - cyl_c[n, j, 1]
            best = min(best, math.sqrt(dx * dx + dy * dy) - cyl_r[n, j])
    return best


def _sdf_run(box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok, p, out):
    """Signed distance ``out`` (N, P) from points ``p`` (N, P, 2) to the union of room n's
    solids (:func:`_sdf_point`)."""
    n_rooms, n_pts = p.shape[0], p.shape[1]
    for n in numba.prange(n_rooms):
        for k in range(n_pts):
            out[n, k] = _sdf_point(
                box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok, n, p[n, k, 0], p[n, k, 1]
            )


@numba.njit(cache=True)
def _segment_clear(box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok, n, ax, ay, bx, by, k, thr):
    """Whether the segment ``(ax, ay) -> (bx, by)`` of room n keeps a signed distance
    (:func:`_sdf_point`) of at least ``thr`` at its ``k`` (>= 2) evenly spaced samples, ends
    included. Sample m is ``a + (b - a) * t`` at ``t = m * (1 / (k - 1))`` (1 for the last), as
    ``numpy.linspace(0, 1, k)`` gives it; the test stops at the first sample too close."""
    step = 1.0 / (k - 1)
    sx, sy = bx - ax, by - ay
    for m in range(k):
        t = 1.0 if m == k - 1 else m * step
        d = _sdf_point(
            box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok, n, ax + sx * t, ay + sy * t
        )
        if not d >= thr:
            return False
    return True


def _segments_clear_run(box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok, a, b, k, thr, out):
    """Whether each segment ``a[n, i] -> b[n, i]`` ((N, S, 2) each) of room n is clear
    (:func:`_segment_clear` with ``k`` samples and margin ``thr``): ``out`` (N, S)."""
    for n in numba.prange(a.shape[0]):
        for i in range(a.shape[1]):
            out[n, i] = _segment_clear(
                box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok,
                n, a[n, i, 0], a[n, i, 1], b[n, i, 0], b[n, i, 1], k, thr,
            )  # fmt: skip


@numba.njit(cache=True)
def _ray_one(box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok, n, ox, oy, ux, uy, max_range):
    """Distance along one ray (origin ``(ox, oy)``, unit direction ``(ux, uy)``) in room ``n``."""
    best = max_range
    for j in range(box_c.shape[1]):
        if not box_ok[n, j]:
            continue
        c, s = box_cs[n, j, 0], box_cs[n, j, 1]
        dx, dy = ox - box_c[n, j, 0], oy - box_c[n, j, 1]
        t_near, t_far = -np.inf, np.inf
        for axis in range(2):
            if axis == 0:
                lo, lu = c * dx + s * dy, c * ux + s * uy
            else:
                lo, lu = -s * dx + c * dy, -s * ux + c * uy
            h = box_h[n, j, axis]
            if abs(lu) < 1e-300:
                lu = 1e-300
            t1, t2 = (-h - lo) / lu, (h - lo) / lu
            t_near = max(t_near, min(t1, t2))
            t_far = min(t_far, max(t1, t2))
        if t_near <= t_far and t_far >= 0.0:
            best = min(best, max(t_near, 0.0))
    for j in range(cyl_c.shape[1]):
        if not cyl_ok[n, j]:
            continue
        dx, dy = ox - cyl_c[n, j, 0], oy - cyl_c[n, j, 1]
        b = dx * ux + dy * uy
        disc = b * b - (dx * dx + dy * dy - cyl_r[n, j] ** 2)
        if disc >= 0.0:
            root = math.sqrt(disc)
            if -b + root >= 0.0:
                best = min(best, max(-b - root, 0.0))
    return best


def _ray_run(box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok, o, u, max_range, out):
    """Distance ``out`` (N, R) along unit directions ``u`` from ``o`` (both (N, R, 2)) to the
    first of room n's solids, ``max_range`` if none, 0 from inside a solid (:func:`_ray_one`:
    the slab method for boxes, the quadratic for cylinders)."""
    for n in numba.prange(o.shape[0]):
        for k in range(o.shape[1]):
            ox, oy, ux, uy = o[n, k, 0], o[n, k, 1], u[n, k, 0], u[n, k, 1]
            out[n, k] = _ray_one(
                box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok, n, ox, oy, ux, uy, max_range
            )


def _ray_fan_run(
    box_c,
    box_h,
    box_cs,
    box_ok,
    cyl_c,
    cyl_r,
    cyl_ok,
    positions,
    headings,
    offsets,
    max_range,
    out,
):
    """:func:`_ray_run` for a fan of rays from one point per room: ``headings[n] +
    offsets[k]`` (rad) from ``positions[n]``."""
    for n in numba.prange(positions.shape[0]):
        for k in range(offsets.shape[0]):
            a = headings[n] + offsets[k]
            out[n, k] = _ray_one(
                box_c,
                box_h,
                box_cs,
                box_ok,
                cyl_c,
                cyl_r,
                cyl_ok,
                n,
                positions[n, 0],
                positions[n, 1],
                math.cos(a),
                math.sin(a),
                max_range,
            )


#: The compiled queries: ``sdf_kernel(n_rooms)(...)`` etc. (their ``py_func`` is the reference).
sdf_kernel = BatchKernel(_sdf_run, parallel=False)
segments_clear_kernel = BatchKernel(_segments_clear_run, parallel=False)
ray_kernel = BatchKernel(_ray_run, parallel=False)
ray_fan_kernel = BatchKernel(_ray_fan_run, parallel=False)


def _sdf_fast(s: _Solids, p: NDArray[np.float64]) -> NDArray[np.float64]:
    """Signed distance (N, P) from points (N, P, 2) to each room's solids (:func:`_sdf_run`)."""
    out = np.empty(p.shape[:2])
    sdf_kernel(p.shape[0])(*s.kernel_args, np.ascontiguousarray(p), out)
    return out


def _sdf(s: _Solids, p: NDArray[np.float64]) -> NDArray[np.float64]:
    """Signed distance ``(P,)`` from points ``(P, 2)`` to one room's solids (inf if none)."""
    return _sdf_fast(s, p[None])[0]


def _segments_clear(
    s: _Solids, a: NDArray[np.float64], b: NDArray[np.float64], k: int, thr: float
) -> NDArray[np.bool_]:
    """Whether each segment ``a[i] -> b[i]`` ((S, 2) each) of one room keeps a signed distance
    of at least ``thr`` at ``k`` evenly spaced samples (:func:`_segments_clear_run`)."""
    out = np.empty((1, a.shape[0]), np.bool_)
    segments_clear_kernel(1)(
        *s.kernel_args,
        np.ascontiguousarray(a, np.float64)[None],
        np.ascontiguousarray(b, np.float64)[None],
        int(k),
        float(thr),
        out,
    )
    return out[0]


def _ray_cast_fast(
    s: _Solids, o: NDArray[np.float64], u: NDArray[np.float64], max_range: float
) -> NDArray[np.float64]:
    """Ray ranges (N, R) from origins ``o`` along unit directions ``u`` (:func:`_ray_run`)."""
    out = np.empty(o.shape[:2])
    ray_kernel(o.shape[0])(
        *s.kernel_args, np.ascontiguousarray(o), np.ascontiguousarray(u), float(max_range), out
    )
    return out


def _points(name: str, points: ArrayLike) -> NDArray[np.float64]:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"{name} must have shape (P, 2) in metres, got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{name} must be finite")
    return p


def solid_distance(solids: Sequence[Solid], points: ArrayLike) -> NDArray[np.float64]:
    """Signed distance (m) from local points (P, 2) to the nearest of ``solids`` (+inf if none):
    what a task's layout generator checks a candidate start or goal against."""
    return _sdf(_pack(tuple(solids)), _points("points", points))

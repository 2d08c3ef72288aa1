"""Shortest collision-free paths for the avatar, planned when a layout is drawn.

Feasibility is guaranteed by planning on an occupancy grid inflated by the avatar radius plus one
grid cell (8-connected Dijkstra with ``scipy.sparse.csgraph``), then shortening the grid path by
string pulling against the exact geometry (:mod:`vrloco_env.world.geometry`). The inflation margin
makes the guarantee conservative (gaps within one grid cell of the avatar's diameter count as
closed), and the path length is an upper bound about 1 % above the true shortest path (it hugs
solids at a small extra clearance). Points are in the room's local frame (m).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from vrloco_env.world._planning_numba import _samples, goal_contains, relax_pass
from vrloco_env.world.geometry import _sdf, _segments_clear, _Solids

__all__: list[str] = []


def _plan(
    solids: _Solids,
    bounds: tuple[float, float, float, float],
    start: NDArray[np.float64],
    goal: tuple[float, float, float, float],
    radius: float,
    h: float,
) -> NDArray[np.float64] | None:
    """Shortest collision-free path (M, 2) for a disc of ``radius`` from ``start`` to the goal.

    ``goal`` is the goal region as numbers (:attr:`Layout.goal_region
    <vrloco_env.world.layout.Layout.goal_region>`). Returns None if the goal region cannot be
    reached on the grid inflated by ``radius + h``. The grid path is then shortened against the
    exact geometry (:func:`_string_pull`, :func:`_relax`), keeping a clearance of at least
    ``radius``.
    """
    xmin, xmax, ymin, ymax = bounds
    xs = np.arange(xmin + h / 2.0, xmax, h)
    ys = np.arange(ymin + h / 2.0, ymax, h)
    nx, ny = xs.size, ys.size
    gx, gy = np.meshgrid(xs, ys)  # (ny, nx)
    cells = np.stack([gx.ravel(), gy.ravel()], axis=-1)
    free = (_sdf(solids, cells) >= radius + h).reshape(ny, nx)
    goal_cells = _in_goal(cells, goal).reshape(ny, nx) & free
    ix = int(np.clip(np.floor((start[0] - xmin) / h), 0, nx - 1))
    iy = int(np.clip(np.floor((start[1] - ymin) / h), 0, ny - 1))
    if not free[iy, ix] or not goal_cells.any():
        return None
    idx = np.arange(nx * ny).reshape(ny, nx)
    rows, cols, wts = [], [], []
    # Right, up, and the two upward diagonals (no corner cutting); the graph is undirected.
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        y0, y1 = 0, ny - dy
        x0, x1 = max(0, -dx), nx - max(0, dx)
        a = free[y0:y1, x0:x1] & free[y0 + dy : y1 + dy, x0 + dx : x1 + dx]
        if dx and dy:
            a &= free[y0 + dy : y1 + dy, x0:x1] & free[y0:y1, x0 + dx : x1 + dx]
        rows.append(idx[y0:y1, x0:x1][a])
        cols.append(idx[y0 + dy : y1 + dy, x0 + dx : x1 + dx][a])
        wts.append(np.full(int(a.sum()), h * math.hypot(dx, dy)))
    graph = coo_matrix(
        (np.concatenate(wts), (np.concatenate(rows), np.concatenate(cols))), shape=(nx * ny,) * 2
    ).tocsr()
    src = int(idx[iy, ix])
    dist, pred = dijkstra(graph, directed=False, indices=src, return_predecessors=True)
    targets = idx[goal_cells]
    best = int(targets[np.argmin(dist[targets])])
    if not np.isfinite(dist[best]):
        return None
    chain = [best]
    while chain[-1] != src:
        chain.append(int(pred[chain[-1]]))
    pts = cells[chain[::-1]]
    pts[0] = start
    pulled = _string_pull(solids, pts, radius, h)
    path = _trim(pulled if _in_goal(pulled, goal).any() else pts, goal)
    relaxed = _relax(solids, path, radius, h, goal)
    # Relaxing can, rarely, pull the end back out of the goal region (seed 322 of the Approach
    # room did): then the unrelaxed path, slightly longer but valid, is kept.
    return _trim(relaxed, goal) if _in_goal(relaxed, goal).any() else path


def _clear(
    solids: _Solids, a: NDArray[np.float64], b: NDArray[np.float64], radius: float, h: float
) -> NDArray[np.bool_]:
    """Whether each segment ``a[i] -> b[i]`` (``(S, 2)`` each) keeps the disc of ``radius`` clear.

    Points sampled at most ``h / 4`` apart must have a signed distance ``>= radius + h / 8``; the
    signed distance is 1-Lipschitz, so between samples it stays ``>= radius``.
    """
    seg = b - a
    k = _samples(float(np.hypot(seg[:, 0], seg[:, 1]).max(initial=0.0)), h)
    return _segments_clear(solids, a, b, k, radius + h / 8.0)


def _string_pull(
    solids: _Solids, pts: NDArray[np.float64], radius: float, h: float
) -> NDArray[np.float64]:
    """Greedy shortcutting of a grid path: from each kept vertex jump to the farthest vertex in
    clear view. Consecutive grid vertices are always in view (free cells have clearance
    ``radius + h`` and are at most ``h * sqrt(2)`` apart)."""
    # Keep only the start, the end and the grid path's turning points: the straight runs between
    # them are the grid path itself, so the polyline is unchanged and there are far fewer
    # candidate shortcuts to test.
    d = np.diff(pts[1:], axis=0)
    turn = np.flatnonzero(np.any(np.abs(d[1:] - d[:-1]) > 1e-9, axis=1)) + 2
    pts = pts[np.unique(np.concatenate([[0, 1], turn, [pts.shape[0] - 1]]))]
    out = [pts[0]]
    i, m = 0, pts.shape[0]
    while i < m - 1:
        ok = _clear(solids, np.repeat(pts[i][None], m - i - 1, axis=0), pts[i + 1 :], radius, h)
        ok[0] = True
        i = i + 1 + int(np.flatnonzero(ok).max())
        out.append(pts[i])
    return np.array(out)


def _relax(
    solids: _Solids,
    path: NDArray[np.float64],
    radius: float,
    h: float,
    goal: tuple[float, float, float, float],
    passes: int = 30,
    split: float = 0.4,
) -> NDArray[np.float64]:
    """Shorten a clear path by moving its vertices while it stays clear.

    Each pass (:func:`~vrloco_env.world._planning_numba.relax_pass`) splits legs longer than
    ``split`` m (so the path can wrap round a cylinder or a corner's clearance circle), then moves
    every vertex after the start, in turn, as far as clearance allows toward the nearest point of
    the line through its neighbours (the last vertex: toward the goal point nearest to its
    predecessor; the move is searched on 17 steps, then 15 finer ones), and drops vertices whose
    neighbours see each other. No move lengthens the path (the leg-length sum is convex along the
    move), and passes stop once they gain < 1 mm. The result hugs the solids at a clearance of
    ``radius + h / 8`` with polygonal arcs: about 1 % longer than the true shortest path
    (``tests/test_vrloco_env/world/test_rooms.py``, the taut-string case). ``goal`` is the goal
    region as ``(x, y, radius, line_x)``: the disc, or where ``line_x`` is not NaN the half-plane
    ``x >= line_x``.
    """
    length = _path_length(path)
    for _ in range(passes):
        path = relax_pass(
            *solids.kernel_args, np.ascontiguousarray(path), radius, h, *goal, _COARSE, _FINE, split
        )
        new = _path_length(path)
        if length - new < 1e-3:
            break
        length = new
    return path


#: The move's search: fractions of the way to the target, falling from 1 to 0, and between each
#: two (row ``i - 1``: from ``_COARSE[i - 1]`` to ``_COARSE[i]``, both left out).
_COARSE = np.linspace(1.0, 0.0, 17)
_FINE = np.stack([np.linspace(_COARSE[i - 1], _COARSE[i], 17)[1:-1] for i in range(1, 17)])


def _in_goal(points: NDArray[np.float64], goal: tuple[float, ...]) -> NDArray[np.bool_]:
    """Whether the points ``(P, 2)`` lie in the goal region ``goal`` (:func:`_plan`)."""
    p = np.ascontiguousarray(points, dtype=np.float64)
    out = np.empty(p.shape[0], np.bool_)
    goal_contains(p, *goal, out)
    return out


def _trim(path: NDArray[np.float64], goal: tuple[float, ...]) -> NDArray[np.float64]:
    """Cut the path where it first enters the goal region (on the first entering leg, refined
    three times on 33 points: to 1/32768 of the leg, under 0.5 mm for a 14 m leg)."""
    inside = _in_goal(path, goal)
    if not inside.any():
        raise RuntimeError("internal error: the planned path does not reach the goal region")
    k = int(np.argmax(inside))
    if k == 0:
        return path[:1]
    a, b = path[k - 1], path[k]
    lo, hi = 0.0, 1.0  # a + lo * (b - a) is outside, a + hi * (b - a) inside
    for _ in range(3):
        t = np.linspace(lo, hi, 33)
        ins = _in_goal(a + t[:, None] * (b - a), goal)
        ins[-1] = True
        j = int(np.argmax(ins[1:])) + 1
        lo, hi = t[j - 1], t[j]
    return np.vstack([path[:k], b if hi == 1.0 else a + hi * (b - a)])


def _path_length(path: NDArray[np.float64]) -> float:
    d = np.diff(path, axis=0)
    return float(np.hypot(d[:, 0], d[:, 1]).sum())

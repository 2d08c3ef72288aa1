"""The path relaxation's compiled pass (:func:`relax_pass`) that
:func:`vrloco_env.world.planning._relax` repeats.

One scalar implementation; ``relax_pass.py_func`` is the readable reference and gives the same
numbers. The room is one packed room (``_Solids.kernel_args``, room index 0). The goal region is
a disc (``goal_x, goal_y, goal_radius``) or, where ``goal_line_x`` is not NaN, the half-plane
``x >= goal_line_x``; :func:`goal_contains` and :func:`goal_nearest` test and project points
onto it for :meth:`Layout.in_goal <vrloco_env.world.layout.Layout.in_goal>` and
:meth:`Layout.nearest_goal_point <vrloco_env.world.layout.Layout.nearest_goal_point>`.

The arithmetic is element by element in the order numpy's array expressions would evaluate it
(``a + t * (b - a)``, ``numpy.hypot``), and the projections onto a neighbour line use
``numpy.dot``, which sums with BLAS as numpy's does: the pass rounds as the same computation
written with numpy arrays, and the paths of the golden episodes replay bit for bit.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from vrloco_env.world.geometry import _segment_clear

__all__ = ["goal_contains", "goal_nearest", "relax_pass"]


@numba.njit(cache=True)
def _in_goal(px, py, goal_x, goal_y, goal_radius, goal_line_x):
    """Whether ``(px, py)`` lies in the goal region."""
    if not math.isnan(goal_line_x):
        return px >= goal_line_x
    return np.hypot(px - goal_x, py - goal_y) <= goal_radius


@numba.njit(cache=True)
def _nearest_goal_point(px, py, goal_x, goal_y, goal_radius, goal_line_x):
    """The goal region's point nearest to ``(px, py)`` (itself if inside)."""
    if not math.isnan(goal_line_x):
        return max(px, goal_line_x), py
    dx, dy = px - goal_x, py - goal_y
    n = np.hypot(dx, dy)
    if n > goal_radius:
        f = goal_radius / n
        return goal_x + dx * f, goal_y + dy * f
    return px, py


@numba.njit(cache=True)
def goal_contains(points, goal_x, goal_y, goal_radius, goal_line_x, out):
    """``out[i]``: whether ``points[i]`` (``(P, 2)``) lies in the goal region."""
    for i in range(points.shape[0]):
        out[i] = _in_goal(points[i, 0], points[i, 1], goal_x, goal_y, goal_radius, goal_line_x)


@numba.njit(cache=True)
def goal_nearest(points, goal_x, goal_y, goal_radius, goal_line_x, out):
    """``out[i]``: the goal region's point nearest to ``points[i]`` (``(P, 2)``)."""
    for i in range(points.shape[0]):
        out[i, 0], out[i, 1] = _nearest_goal_point(
            points[i, 0], points[i, 1], goal_x, goal_y, goal_radius, goal_line_x
        )


@numba.njit(cache=True)
def _samples(length, h):
    """Samples per segment for a batch of segments whose longest is ``length``: at most
    ``h / 4`` apart, at least 2."""
    return max(2, math.ceil(length / (h / 4)) + 1)


@numba.njit(cache=True)
def _first_feasible(solids, v, prev, nxt, target, t, last, radius, h, goal):
    """Index of the first ``t[j]`` whose move ``v + t[j] * (target - v)`` keeps both legs (the
    last vertex: its one leg, and the goal region) clear; -1 if none."""
    box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok = solids
    goal_x, goal_y, goal_radius, goal_line_x = goal
    n = t.size
    cx, cy = np.empty(n), np.empty(n)
    longest = 0.0
    for j in range(n):
        cx[j] = v[0] + t[j] * (target[0] - v[0])
        cy[j] = v[1] + t[j] * (target[1] - v[1])
        longest = max(longest, np.hypot(cx[j] - prev[0], cy[j] - prev[1]))
        if not last:
            longest = max(longest, np.hypot(nxt[0] - cx[j], nxt[1] - cy[j]))
    k = _samples(longest, h)
    thr = radius + h / 8.0
    for j in range(n):
        if last:
            ok = _in_goal(cx[j], cy[j], goal_x, goal_y, goal_radius, goal_line_x)
        else:
            ok = _segment_clear(
                box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok,
                0, cx[j], cy[j], nxt[0], nxt[1], k, thr,
            )  # fmt: skip
        if ok and _segment_clear(
            box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok,
            0, prev[0], prev[1], cx[j], cy[j], k, thr,
        ):  # fmt: skip
            return j
    return -1


@numba.njit(cache=True)
def relax_pass(
    box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok,
    path, radius, h, goal_x, goal_y, goal_radius, goal_line_x, coarse, fine, split,
):  # fmt: skip
    """One pass of :func:`~vrloco_env.world.planning._relax` over ``path`` (M, 2): split the legs
    that pass within 0.3 m of the clearance into pieces of at most ``split`` m, move each vertex
    after the start in turn toward its target (the nearest point of the line through its
    neighbours; the last vertex: the goal point nearest its predecessor) by the largest fraction
    of ``coarse`` (falling from 1 to 0) that keeps its legs clear, refined on row ``i - 1`` of
    ``fine`` (the fractions between ``coarse[i - 1]`` and ``coarse[i]``), then drop the vertices
    whose neighbours see each other. Returns the new path (a new array)."""
    solids = (box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok)
    goal = (goal_x, goal_y, goal_radius, goal_line_x)
    m = path.shape[0]
    # Split the legs near a solid (all judged with one sample count, that of the longest leg).
    longest = 0.0
    for i in range(m - 1):
        longest = max(longest, np.hypot(path[i + 1, 0] - path[i, 0], path[i + 1, 1] - path[i, 1]))
    k_near = _samples(longest, h)
    thr_near = (radius + 0.3) + h / 8.0
    pieces = np.ones(m - 1, np.int64)
    for i in range(m - 1):
        ax, ay, bx, by = path[i, 0], path[i, 1], path[i + 1, 0], path[i + 1, 1]
        if not _segment_clear(
            box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok, 0, ax, ay, bx, by, k_near, thr_near
        ):
            pieces[i] = max(math.ceil(np.hypot(bx - ax, by - ay) / split), 1)
    out = np.empty((1 + pieces.sum(), 2))
    out[0] = path[0]
    row = 1
    for i in range(m - 1):
        n = pieces[i]
        for j in range(1, n + 1):
            f = j / n
            out[row, 0] = path[i, 0] + (path[i + 1, 0] - path[i, 0]) * f
            out[row, 1] = path[i, 1] + (path[i + 1, 1] - path[i, 1]) * f
            row += 1
    path = out
    m = path.shape[0]
    # Move each vertex after the start, in turn.
    rel, ab = np.empty(2), np.empty(2)
    target = np.empty(2)
    for k in range(1, m):
        v, prev = path[k].copy(), path[k - 1]
        last = k == m - 1
        nxt = path[k] if last else path[k + 1]
        if last:
            target[0], target[1] = _nearest_goal_point(prev[0], prev[1], *goal)
        else:
            ab[0], ab[1] = nxt[0] - prev[0], nxt[1] - prev[1]
            rel[0], rel[1] = v[0] - prev[0], v[1] - prev[1]
            s = min(max(np.dot(rel, ab) / max(np.dot(ab, ab), 1e-18), 0.0), 1.0)
            target[0], target[1] = prev[0] + s * ab[0], prev[1] + s * ab[1]
        i = _first_feasible(solids, v, prev, nxt, target, coarse, last, radius, h, goal)
        if i < 0:
            continue
        best = coarse[i]
        if i > 0:
            j = _first_feasible(solids, v, prev, nxt, target, fine[i - 1], last, radius, h, goal)
            if j >= 0:
                best = fine[i - 1, j]
        path[k, 0] = v[0] + best * (target[0] - v[0])
        path[k, 1] = v[1] + best * (target[1] - v[1])
    # Drop the vertices whose neighbours see each other.
    thr = radius + h / 8.0
    keep = np.empty(m, np.int64)
    keep[0] = 0
    kept = 1
    for k in range(1, m - 1):
        a, b = path[keep[kept - 1]], path[k + 1]
        length = np.hypot(b[0] - a[0], b[1] - a[1])
        if not _segment_clear(
            box_c, box_h, box_cs, box_ok, cyl_c, cyl_r, cyl_ok,
            0, a[0], a[1], b[0], b[1], _samples(length, h), thr,
        ):  # fmt: skip
            keep[kept] = k
            kept += 1
    keep[kept] = m - 1
    return path[keep[: kept + 1]].copy()

"""The goal seeker's route planner: compiled kernels over its map of the virtual room.

For every user of a batch, :data:`plan_kernel` builds the clearance map around the cells where the
rays hit something, runs a Dijkstra search for the cost to go from the aim point (dearer close to
obstacles), scores the candidate headings by marching along each through the map, and gates the
walk (whether the current heading is clear to start walking, or to keep walking).

* ``_march`` — one heading through the map: clear for a given length, or into the goal.
* ``_bucket_push`` — the bucket (Dial) queue of the search.
* ``_plan_run`` — the per-user planner; :data:`plan_kernel` is its :class:`BatchKernel`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from estimators.kernels import BatchKernel

__all__ = ["plan_kernel"]


@numba.njit(cache=True)
def _march(clear, cost, i0, j0, x, y, ang, length, thr, land, geom):
    """Walk a ray through the planning box from ``(x, y)`` along ``ang`` up to ``length`` (m).

    ``geom`` = (sample spacing, map half side, cell size, goal tolerance) (m). Returns ``(ok,
    end_cost)``: ok when every sample up to ``length`` keeps a clearance of at least ``thr``,
    or when the ray reaches the goal (cost to go <= the goal tolerance) first — at any sample if
    ``land`` is 0, else at the first sample at or beyond ``land`` (m), where a bout that starts
    now puts the body down; and the cost to go at the last sample.
    """
    ds, half, cell, goal_tol = geom[0], geom[1], geom[2], geom[3]
    ni, nj = clear.shape
    ux, uy = math.cos(ang), math.sin(ang)
    end_cost = np.inf
    for m in range(1, math.ceil(length / ds - 1e-9) + 1):
        s = m * ds
        ii = int((x + s * ux + half) / cell) - i0
        jj = int((y + s * uy + half) / cell) - j0
        if ii < 0 or ii >= ni or jj < 0 or jj >= nj or clear[ii, jj] < thr:
            return False, end_cost
        end_cost = cost[ii, jj]
        if s >= land - 1e-9:
            if end_cost <= goal_tol:
                return True, end_cost
            if land > 0.0:
                land = np.inf  # the landing point missed the goal: only a clear way counts
    return True, end_cost


@numba.njit(cache=True, inline="always")
def _bucket_push(head, nxt, node_cost, node_key, used, nbk, width, c, k):
    """File ``(c, k)`` in bucket ``int(c / width)`` (slot mod ``nbk``) of the bucket queue; new
    number of nodes used. Every bucket is a singly linked list of nodes, pushed at its head."""
    s = int(c / width) % nbk
    node_cost[used], node_key[used] = c, k
    nxt[used] = head[s]
    head[s] = used
    return used + 1


def _plan_run(seen, pos, heading, target, keep_len, land, prev_aim, active, cands, prm, out):
    """Per user: clearance map, cost to go from the target, best heading, the walk gate.

    ``seen`` = ``(occ, lo, hi)``: ``occ`` (B, N, N) marks map cells with a ray hit, ``lo``/``hi``
    (B, 2) bound the marked cells. Planning runs on the box around the marked cells, the user
    and the target plus a margin; unseen cells are free. ``land`` (B,) is where the next move
    puts the body down (m): two step lengths for a standing user or one whose bout has not
    landed yet (a bout's first step is reported with the second), 0 once it moves a step at a
    time (any point of the way may be a landing). ``prm`` is the (1,) parameter record that
    :class:`~agents.scripted.goal_seeker.GoalSeeker` builds; users where ``active`` is False are
    skipped. Fills ``out`` = ``(aim, valid, go, keep)``, (B,) each: the heading relative to the
    current one (rad; 0 when nothing is valid), whether it is valid, whether the current heading
    is clear for ``look`` m or lands in the goal, and clear for ``keep_len`` (B,) m or into the
    goal.
    """
    occ, lo, hi = seen
    aim_out, valid_out, go_out, keep_out = out
    p = prm[0]
    cell, half, look, goal_tol = p["cell"], p["half"], p["look"], p["goal_tol"]
    r_tight, r_block, r_comfort = p["r_tight"], p["r_block"], p["r_comfort"]
    comfort_cost, tight_cost, turn_cost = p["comfort_cost"], p["tight_cost"], p["turn_cost"]
    step_a, tight_penalty, hold = p["step_a"], p["tight_penalty"], p["hold"]
    geom = np.array([0.5 * cell, half, cell, goal_tol])
    nb, n, _ = occ.shape
    w = math.ceil(r_comfort / cell) + 1
    cap = w * cell
    pad = w + math.ceil((look + 1.0) / cell)
    band = max(r_comfort - r_block, 1e-9)
    # distance to a marked cell at offset (di, dj), less half a cell, floored at 0
    nw = 2 * w + 1
    ring = np.empty(nw * nw)
    for di in range(-w, w + 1):
        for dj in range(-w, w + 1):
            d = max(math.sqrt(di * di + dj * dj) * cell - 0.5 * cell, 0.0)
            ring[(di + w) * nw + dj + w] = d
    # The search's bucket queue: buckets of width half the cheapest step (one straight cell at
    # the plain cost), so that a step out of the bucket being emptied always lands in a later
    # one; entries of one bucket are then settled in any order. ``nbk`` slots cover the dearest
    # step, so the buckets in use never wrap onto each other.
    width = 0.5 * cell
    nbk = int(cell * 1.4142135623730951 * (1.0 + comfort_cost + tight_cost) / width) + 3
    head = np.empty(nbk, np.int64)
    nxt = np.empty(0, np.int64)  # the queue's nodes, reused by every user
    node_cost = np.empty(0)
    node_key = np.empty(0, np.int64)
    for b in range(nb):
        if not active[b]:
            continue
        pi = min(max(int((pos[b, 0] + half) / cell), 0), n - 1)
        pj = min(max(int((pos[b, 1] + half) / cell), 0), n - 1)
        ti = min(max(int((target[b, 0] + half) / cell), 0), n - 1)
        tj = min(max(int((target[b, 1] + half) / cell), 0), n - 1)
        i0 = max(min(lo[b, 0], pi, ti) - pad, 0)
        i1 = min(max(hi[b, 0], pi, ti) + pad, n - 1)
        j0 = max(min(lo[b, 1], pj, tj) - pad, 0)
        j1 = min(max(hi[b, 1], pj, tj) + pad, n - 1)
        ni, nj = i1 - i0 + 1, j1 - j0 + 1
        # clearance: distance to the nearest marked cell (less half a cell), capped
        clear = np.full((ni, nj), cap)
        for oi in range(max(i0 - w, 0), min(i1 + w, n - 1) + 1):
            di0, di1 = max(-w, i0 - oi), min(w, i1 - oi)
            for oj in range(max(j0 - w, 0), min(j1 + w, n - 1) + 1):
                if not occ[b, oi, oj]:
                    continue
                dj0, dj1 = max(-w, j0 - oj), min(w, j1 - oj)
                for di in range(di0, di1 + 1):
                    ii = oi + di - i0
                    row = (di + w) * nw
                    for dj in range(dj0, dj1 + 1):
                        jj = oj + dj - j0
                        d = ring[row + dj + w]
                        if d < clear[ii, jj]:
                            clear[ii, jj] = d
        # cost to go from the target (Dijkstra, 8-connected), dearer close to obstacles. Only
        # the cells the rays below can read are needed (a square of ``reach`` cells around the
        # user): the search stops once every one of them that can be entered is settled, which
        # leaves their costs exactly what the full search gives.
        cost = np.full((ni, nj), np.inf)
        reach = math.ceil(max(look, keep_len[b]) / cell) + 1
        ri0, ri1 = max(pi - reach - i0, 0), min(pi + reach - i0, ni - 1)
        rj0, rj1 = max(pj - reach - j0, 0), min(pj + reach - j0, nj - 1)
        need = 0
        for i in range(ri0, ri1 + 1):
            for j in range(rj0, rj1 + 1):
                need += clear[i, j] > r_tight
        if nxt.size < 8 * ni * nj + 1:  # each cell is pushed at most once per neighbour
            nxt = np.empty(8 * ni * nj + 1, np.int64)
            node_cost = np.empty(8 * ni * nj + 1)
            node_key = np.empty(8 * ni * nj + 1, np.int64)
        head[:] = -1
        cost[ti - i0, tj - j0] = 0.0
        used = _bucket_push(head, nxt, node_cost, node_key, 0, nbk, width, 0.0,
                            (ti - i0) * nj + (tj - j0))  # fmt: skip
        size = 1
        cur = 0
        while size > 0 and need > 0:
            node = head[cur]
            if node < 0:
                cur = cur + 1 if cur + 1 < nbk else 0
                continue
            head[cur] = nxt[node]
            size -= 1
            c, k = node_cost[node], node_key[node]
            i, j = k // nj, k % nj
            if c > cost[i, j]:
                continue
            if ri0 <= i <= ri1 and rj0 <= j <= rj1 and clear[i, j] > r_tight:
                need -= 1
            for di in range(-1, 2):
                ii = i + di
                if ii < 0 or ii >= ni:
                    continue
                for dj in range(-1, 2):
                    if di == 0 and dj == 0:
                        continue
                    jj = j + dj
                    if jj < 0 or jj >= nj:
                        continue
                    cl = clear[ii, jj]
                    if cl <= r_tight:
                        continue
                    step = cell * (1.4142135623730951 if di != 0 and dj != 0 else 1.0)
                    mult = 1.0 + comfort_cost * min(max(r_comfort - cl, 0.0) / band, 1.0)
                    if cl <= r_block:
                        mult += tight_cost
                    nc = c + step * mult
                    if nc < cost[ii, jj]:
                        cost[ii, jj] = nc
                        used = _bucket_push(head, nxt, node_cost, node_key, used, nbk, width, nc,
                                            ii * nj + jj)  # fmt: skip
                        size += 1
        # every heading with the full margin, and with the tight one at a penalty; the aim of
        # the last step gets a bonus (hysteresis). The user may always move away from, or
        # along, what it already stands closer to.
        x, y = pos[b, 0], pos[b, 1]
        c0 = clear[pi - i0, pj - j0] - 0.02
        prev = prev_aim[b] - heading[b]
        prev = (prev + math.pi) % (2.0 * math.pi) - math.pi
        best = np.inf
        best_a = 0.0
        best_thr = min(r_block, c0)
        for tier in range(2):
            thr = min(r_block if tier == 0 else r_tight, c0)
            for a in cands:
                ok, end_cost = _march(
                    clear, cost, i0, j0, x, y, heading[b] + a, look, thr, land[b], geom
                )
                if ok and end_cost < np.inf:
                    score = end_cost + turn_cost * abs(a) + tier * tight_penalty
                    if abs(a - prev) <= step_a:
                        score -= hold
                    if score < best:
                        best, best_a, best_thr = score, a, thr
        thr = best_thr
        valid_out[b] = best < np.inf
        aim_out[b] = best_a
        h = heading[b]
        go_out[b] = _march(clear, cost, i0, j0, x, y, h, look, thr, land[b], geom)[0]
        keep_out[b] = _march(clear, cost, i0, j0, x, y, h, keep_len[b], thr, land[b], geom)[0]


#: The goal seeker's planner: ``plan_kernel(batch_size)(...)`` (see ``_plan_run``).
plan_kernel = BatchKernel(_plan_run, parallel=False)

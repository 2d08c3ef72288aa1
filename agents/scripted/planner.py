"""The goal seeker's route planner: compiled kernels over its map of the virtual room.

For every user of a batch, :data:`plan_kernel` builds the clearance map around the cells where the
rays hit something, runs a Dijkstra search for the cost to go from the aim point (dearer close to
obstacles), scores the candidate headings by marching along each through the map, and gates the
walk (whether the current heading is clear to start walking, or to keep walking). A user's
clearance map and cost to go are kept from one call to the next and reused while nothing they
are computed from has changed (most control steps of a user who stands, turns or sees nothing
new).

* ``_march`` — one heading through the map: clear for a given length, or into the goal.
* ``_clearance`` — the clearance map: distance to the nearest marked cell.
* ``_bucket_push``, ``_cost_to_go`` — the search for the cost to go, on a bucket (Dial) queue.
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


@numba.njit(cache=True)
def _clearance(occ, clear, i0, i1, j0, j1, w, ring, cap):
    """Fill ``clear`` (the box ``i0..i1`` x ``j0..j1`` of the (N, N) map ``occ``) with the
    distance to the nearest marked cell less half a cell, capped at ``cap``; ``ring`` holds that
    distance for every offset up to ``w`` cells, row-major over (2 w + 1)^2."""
    n = occ.shape[0]
    clear[:] = cap
    for oi in range(max(i0 - w, 0), min(i1 + w, n - 1) + 1):
        for oj in range(max(j0 - w, 0), min(j1 + w, n - 1) + 1):
            if occ[oi, oj]:
                _stamp(clear, oi, oj, i0, i1, j0, j1, w, ring)


@numba.njit(cache=True, inline="always")
def _stamp(clear, oi, oj, i0, i1, j0, j1, w, ring):
    """Lower ``clear`` (the box ``i0..i1`` x ``j0..j1``) to the distance from the marked cell
    ``(oi, oj)`` wherever that is smaller (cells up to ``w`` away; see :func:`_clearance`)."""
    nw = 2 * w + 1
    di0, di1 = max(-w, i0 - oi), min(w, i1 - oi)
    dj0, dj1 = max(-w, j0 - oj), min(w, j1 - oj)
    for di in range(di0, di1 + 1):
        ii = oi + di - i0
        row = (di + w) * nw
        for dj in range(dj0, dj1 + 1):
            jj = oj + dj - j0
            d = ring[row + dj + w]
            if d < clear[ii, jj]:
                clear[ii, jj] = d


@numba.njit(cache=True)
def _cost_to_go(mult, cost, ti, tj, box, cell, nodes):
    """Dijkstra's search for the cost to go from cell ``(ti, tj)`` over the 8-connected cells of
    ``mult`` (ni, nj): a step into a cell costs ``cell`` (straight) or ``cell * sqrt 2``
    (diagonal) times that cell's ``mult`` (>= 1; inf: never entered). Fills ``cost`` (ni, nj).

    The queue is a bucket (Dial) queue: buckets of width half the cheapest step (one straight
    cell at a multiplier of 1), so that a step out of the bucket being emptied always lands in a
    later one, and the entries of one bucket are settled in any order; its slots cover the
    dearest step, so the buckets in use never wrap onto each other. ``nodes`` = ``(nxt, cost,
    key)`` is its scratch memory, at least ``8 ni nj + 1`` each (a cell is pushed at most once
    per neighbour). The search stops once every cell of ``box`` = ``(i0, i1, j0, j1)`` (inclusive)
    that can be entered is settled, which leaves the costs of those cells exactly what the full
    search gives; other cells may keep a larger cost or inf.
    """
    nxt, node_cost, node_key = nodes
    ni, nj = mult.shape
    diag = cell * 1.4142135623730951
    width = 0.5 * cell
    top = 1.0
    need = 0
    for i in range(ni):
        for j in range(nj):
            if mult[i, j] < np.inf:
                top = max(top, mult[i, j])
                need += box[0] <= i <= box[1] and box[2] <= j <= box[3]
    nbk = int(diag * top / width) + 3
    head = np.full(nbk, -1, np.int64)
    cost[:] = np.inf
    cost[ti, tj] = 0.0
    used = _bucket_push(head, nxt, node_cost, node_key, 0, nbk, width, 0.0, ti * nj + tj)
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
        if box[0] <= i <= box[1] and box[2] <= j <= box[3] and mult[i, j] < np.inf:
            need -= 1
        for di in range(-1, 2):
            ii = i + di
            if ii < 0 or ii >= ni:
                continue
            for dj in range(-1, 2):
                jj = j + dj
                if (di == 0 and dj == 0) or jj < 0 or jj >= nj:
                    continue
                mk = mult[ii, jj]
                if mk == np.inf:
                    continue
                nc = c + (diag if di != 0 and dj != 0 else cell) * mk
                if nc < cost[ii, jj]:
                    cost[ii, jj] = nc
                    used = _bucket_push(head, nxt, node_cost, node_key, used, nbk, width, nc,
                                        ii * nj + jj)  # fmt: skip
                    size += 1


def _plan_run(seen, pos, heading, target, keep_len, land, prev_aim, active, cands, prm, memo,
              out):  # fmt: skip
    """Per user: clearance map, cost to go from the target, best heading, the walk gate.

    ``seen`` = ``(occ, lo, hi, version, prior, news)``: ``occ`` (B, N, N) marks map cells with a
    ray hit, ``lo``/``hi`` (B, 2) bound the marked cells, ``version`` (B,) counts the changes of
    a user's ``occ`` (any count that changes whenever ``occ`` does), ``prior`` (B,) is the
    version before the cells ``news`` (K, 3) = (user, i, j) were marked, and no other cell since
    (a user may repeat a cell). Planning runs on the box around the
    marked cells, the user and the target plus a margin; unseen cells are free. ``land`` (B,) is
    where the next move puts the body down (m): two step lengths for a standing user or one
    whose bout has not landed yet (a bout's first step is reported with the second), 0 once it
    moves a step at a time (any point of the way may be a landing). ``prm`` is the (1,) parameter
    record that :class:`~agents.scripted.goal_seeker.GoalSeeker` builds; users where ``active``
    is False are skipped. Fills ``out`` = ``(aim, valid, go, keep)``, (B,) each: the heading
    relative to the current one (rad; 0 when nothing is valid), whether it is valid, whether the
    current heading is clear for ``look`` m or lands in the goal, and clear for ``keep_len`` (B,)
    m or into the goal.

    ``memo`` = ``(key, clear, cost)``, ``key`` (B, 10) int64, ``clear`` and ``cost`` (B, N * N)
    float64: each user's last clearance map and cost to go (row-major over its box) and what they
    were computed from (the map's version, the box, the target's cell, the user's cell and the
    reach of the rays). A user whose ``key`` matches the present call reuses them: the same
    inputs give the same maps. One whose map was ``prior`` and whose box is the same only
    lowers its clearance map where ``news`` are near (a minimum over the marked cells, in any
    order) and searches again. A row of ``key`` that holds -1 (a new episode) matches nothing.
    """
    occ, lo, hi, version, prior, news = seen
    key, clear_memo, cost_memo = memo
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
    nxt = np.empty(0, np.int64)  # the search's queue nodes, reused by every user
    node_cost = np.empty(0)
    node_key = np.empty(0, np.int64)
    mult = np.empty(0)  # the cost multiplier of a step into each cell (inf: not to be entered)
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
        reach = math.ceil(max(look, keep_len[b]) / cell) + 1
        clear = clear_memo[b, : ni * nj].reshape((ni, nj))
        cost = cost_memo[b, : ni * nj].reshape((ni, nj))
        same_box = key[b, 1] == i0 and key[b, 2] == i1 and key[b, 3] == j0 and key[b, 4] == j1
        grown = same_box and key[b, 0] == prior[b] and prior[b] >= 0  # only ``news`` are new
        same = same_box and key[b, 0] == version[b]
        for q, v in enumerate((i0, i1, j0, j1, ti, tj, pi, pj, reach)):
            same = same and key[b, q + 1] == v
            key[b, q + 1] = v
        key[b, 0] = version[b]
        if not same:
            if grown and prior[b] != version[b]:
                for q in range(news.shape[0]):
                    oi, oj = news[q, 1], news[q, 2]
                    if (news[q, 0] == b and i0 - w <= oi <= i1 + w
                            and j0 - w <= oj <= j1 + w):  # fmt: skip
                        _stamp(clear, oi, oj, i0, i1, j0, j1, w, ring)
            elif not (grown and prior[b] == version[b]):
                _clearance(occ[b], clear, i0, i1, j0, j1, w, ring, cap)
            # the cost to go from the target, dearer close to obstacles. Only the cells the rays
            # below can read are needed: a square of ``reach`` cells around the user.
            if nxt.size < 8 * ni * nj + 1:  # each cell is pushed at most once per neighbour
                nxt = np.empty(8 * ni * nj + 1, np.int64)
                node_cost = np.empty(8 * ni * nj + 1)
                node_key = np.empty(8 * ni * nj + 1, np.int64)
                mult = np.empty(ni * nj)
            for i in range(ni):
                for j in range(nj):
                    cl = clear[i, j]
                    m = 1.0 + comfort_cost * min(max(r_comfort - cl, 0.0) / band, 1.0)
                    if cl <= r_block:
                        m += tight_cost
                    mult[i * nj + j] = m if cl > r_tight else np.inf
            box = (max(pi - reach - i0, 0), min(pi + reach - i0, ni - 1),
                   max(pj - reach - j0, 0), min(pj + reach - j0, nj - 1))  # fmt: skip
            _cost_to_go(mult[: ni * nj].reshape((ni, nj)), cost, ti - i0, tj - j0, box, cell,
                        (nxt, node_cost, node_key))  # fmt: skip
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

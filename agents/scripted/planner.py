"""The goal seeker's route planner: compiled kernels over its map of the virtual room.

For every user of a batch, :data:`plan_kernel` builds the clearance map around the cells where the
rays hit something, runs a Dijkstra search for the cost to go from the aim point (dearer close to
obstacles), scores the candidate headings by marching along each through the map, and gates the
walk (whether the current heading is clear to start walking, or to keep walking). A user's
clearance map and cost to go are kept from one call to the next and reused while nothing they
are computed from has changed (most control steps of a user who stands, turns or sees nothing
new). When only new cells were marked (a user turning on the spot sees more of an obstacle), the
last search is repaired instead of run again: only the cells whose way to the aim point passes
near the new marks are searched anew, and the costs come out bit for bit those of a new search.

* ``_march`` — one heading through the map: clear for a given length, or into the goal.
* ``_clearance``, ``_stamp`` — the clearance map: distance to the nearest marked cell.
* ``_multiplier`` — what a step into a cell costs, per metre, at its clearance.
* ``_bucket_push``, ``_cost_to_go``, ``_settle`` — the search for the cost to go, on a bucket
  (Dial) queue, and its level (up to which cost every cell holds its exact one).
* ``_repair``, ``_known`` — the search brought up to date after multipliers went up, and whether
  it covers the cells the marches read.
* ``_plan_run`` — the per-user planner; :data:`plan_kernel` is its :class:`BatchKernel`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from estimators.kernels import BatchKernel
from estimators.kernels.rotations import wrap_angle

__all__ = ["plan_kernel"]


@numba.njit(cache=True)
def _march(clear, cost, i0, j0, x, y, ang, length, thr, land, geom, goal):
    """Walk a ray through the planning box from ``(x, y)`` along ``ang`` up to ``length`` (m).

    ``clear`` and ``cost`` are the box's clearance map and cost to go in the padded layout
    (:func:`_cost_to_go`), ``(i0, j0)`` the map cell of the box's first cell. ``geom`` = (sample
    spacing, map half side, cell size, goal tolerance) (m). Returns ``(ok, end_cost)``: ok when
    every sample up to ``length`` keeps a clearance of at least ``thr``, or when the ray reaches
    the goal (cost to go <= the goal tolerance) first — at any sample if ``land`` is 0, else at
    the first sample at or beyond ``land`` (m), where a bout that starts now puts the body down;
    and, when ok, the cost to go at the last sample read (inf if there is none, or when not ok).

    ``goal`` = ``(ti, tj, r)``: a cell whose cost to go is within the goal tolerance lies within
    ``r`` cells (in i and in j) of the target's cell ``(ti, tj)`` (box indices), because every
    step costs at least one cell. Only there is the cost read along the way.
    """
    ds, half, cell, goal_tol = geom[0], geom[1], geom[2], geom[3]
    ti, tj, r = goal
    ni, nj = clear.shape[0] - 2, clear.shape[1] - 2
    ux, uy = math.cos(ang), math.sin(ang)
    ii = jj = -1
    for m in range(1, math.ceil(length / ds - 1e-9) + 1):
        s = m * ds
        ii = int((x + s * ux + half) / cell) - i0
        jj = int((y + s * uy + half) / cell) - j0
        if ii < 0 or ii >= ni or jj < 0 or jj >= nj or clear[ii + 1, jj + 1] < thr:
            return False, np.inf
        if s >= land - 1e-9:
            if abs(ii - ti) <= r and abs(jj - tj) <= r and cost[ii + 1, jj + 1] <= goal_tol:
                return True, cost[ii + 1, jj + 1]
            if land > 0.0:
                land = np.inf  # the landing point missed the goal: only a clear way counts
    return True, (np.inf if ii < 0 else cost[ii + 1, jj + 1])


@numba.njit(cache=True, inline="always")
def _slots(n):
    """The smallest power of two >= ``n``: a bucket queue's slots."""
    s = 1
    while s < n:
        s *= 2
    return s


@numba.njit(cache=True)
def _clearance(occ, clear, i0, i1, j0, j1, w, ring, cap):
    """Fill ``clear`` (the box ``i0..i1`` x ``j0..j1`` of the (N, N) map ``occ``, padded: map
    cell ``(i, j)`` at ``[i - i0 + 1, j - j0 + 1]``) with the distance to the nearest marked
    cell less half a cell, capped at ``cap``; ``ring`` holds that distance for every offset up
    to ``w`` cells, row-major over (2 w + 1)^2."""
    n = occ.shape[0]
    clear[:] = cap
    for oi in range(max(i0 - w, 0), min(i1 + w, n - 1) + 1):
        for oj in range(max(j0 - w, 0), min(j1 + w, n - 1) + 1):
            if occ[oi, oj]:
                _stamp(clear, oi, oj, i0, i1, j0, j1, w, ring)


@numba.njit(cache=True, inline="always")
def _stamp(clear, oi, oj, i0, i1, j0, j1, w, ring):
    """Lower ``clear`` (the box ``i0..i1`` x ``j0..j1``, padded) to the distance from the marked
    cell ``(oi, oj)`` wherever that is smaller (cells up to ``w`` away; see
    :func:`_clearance`)."""
    nw = 2 * w + 1
    di0, di1 = max(-w, i0 - oi), min(w, i1 - oi)
    dj0, dj1 = max(-w, j0 - oj), min(w, j1 - oj)
    for di in range(di0, di1 + 1):
        line = clear[oi + di - i0 + 1, oj + dj0 - j0 + 1 : oj + dj1 - j0 + 2]
        near = ring[(di + w) * nw + dj0 + w : (di + w) * nw + dj1 + w + 1]
        for q in range(line.size):  # a minimum run along the row (vectorised)
            line[q] = min(line[q], near[q])


#: The level of a search that ran until its queue was empty: every reached cell is exact.
_ALL = np.int64(2**62)


@numba.njit(cache=True, inline="always")
def _within(c, width, level):
    """Whether cost ``c`` is in a bucket (of ``width``) up to ``level``."""
    return c < np.inf and int(c / width) <= level


@numba.njit(cache=True, inline="always")
def _steps(nj, cell):
    """The 8 steps between neighbouring cells of a padded map of ``nj`` columns and cells of
    ``cell`` (m), in the order di = -1, 0, 1, then dj = -1, 0, 1: their flat offsets, the code of
    each (``(1 - di) * 3 + (1 - dj)`` for a step ``(di, dj)``) and its length (m)."""
    offs = np.array([-nj - 1, -nj, -nj + 1, -1, 1, nj - 1, nj, nj + 1])
    codes = np.array([8, 7, 6, 5, 3, 2, 1, 0], np.int8)
    diag = cell * 1.4142135623730951
    lengths = np.array([diag, cell, diag, cell, cell, diag, cell, diag])
    return offs, codes, lengths


@numba.njit(cache=True, inline="always")
def _box_mask(mult, box):
    """Per cell (flat): 1 for an enterable cell of ``box`` = ``(i0, i1, j0, j1)`` (inclusive),
    else 0; and how many such cells there are."""
    mask = np.zeros(mult.size, np.uint8)
    need = 0
    for i in range(box[0], box[1] + 1):
        for j in range(box[2], box[3] + 1):
            if mult[i, j] < np.inf:
                mask[i * mult.shape[1] + j] = 1
                need += 1
    return mask, need


@numba.njit(cache=True)
def _cost_to_go(mult, cost, parent, ti, tj, box, cell, nodes):
    """Dijkstra's search for the cost to go from cell ``(ti, tj)`` over the 8-connected cells of
    ``mult`` (ni, nj): a step into a cell costs ``cell`` (straight) or ``cell * sqrt 2``
    (diagonal) times that cell's ``mult`` (>= 1; inf: never entered). The map is padded: its
    first and last rows and columns are inf all round, so a step never leaves it. Fills
    ``cost`` (ni, nj) and ``parent`` (ni * nj,), each reached cell's step back toward ``(ti,
    tj)`` (:func:`_settle`).

    The queue is a bucket (Dial) queue: buckets of width half the cheapest step (one straight
    cell at a multiplier of 1), so that a step out of the bucket being emptied always lands in a
    later one, and every cell of that bucket already holds its exact cost; its slots cover the
    dearest step (at the map's largest multiplier), so the buckets in use never wrap onto each
    other. ``nodes`` (int32, at least ``2 (9 ni nj + 1)``) is its scratch memory: node ``q`` is a
    cell's flat index at ``2 q`` and the next node of its bucket at ``2 q + 1``. The search stops
    once every cell of ``box`` = ``(i0, i1, j0, j1)`` (inclusive) that can be entered is
    settled, which leaves the costs of those cells exactly what the full search gives; other
    cells may keep a larger cost or inf.

    Returns the search's level: every cell whose cost is in a bucket up to it
    (``int(cost / (cell / 2)) <= level``) holds its exact cost, and every other cell's exact cost
    is in a later bucket (:data:`_ALL` when the queue ran empty: every reached cell is exact).
    """
    nj = mult.shape[1]
    width = 0.5 * cell
    top = 1.0  # the dearest multiplier on the map
    for mk in mult.reshape(-1):
        if mk > top and mk < np.inf:
            top = mk
    mask, need = _box_mask(mult, box)
    head = np.full(_slots(int(cell * 1.4142135623730951 * top / width) + 3), -1, np.int32)
    cost[:] = np.inf
    k = ti * nj + tj
    cost[ti, tj] = 0.0
    parent[k] = -1
    nodes[0], nodes[1] = k, -1
    head[0] = 0
    return _settle(mult, cost, parent, head, nodes, 1, 1, 0, mask, cell, need, _ALL, 0)


@numba.njit(cache=True)
def _settle(mult, cost, parent, head, nodes, used, size, cur, mask, cell, need, last, floor):
    """Empty the bucket queue ``head`` (``size`` entries, ``used`` nodes, see
    :func:`_cost_to_go`) from bucket ``cur`` on, in order: settle each cell the first time it
    comes out (it then holds its exact cost; a later entry of the same cell is an older, dearer
    one) and relax its neighbours, storing in ``parent`` the step back to it (see
    :func:`_steps`). ``mask`` (flat, uint8) holds the cells ``need`` counts in bit 0, and this
    marks each cell it settles in bit 1. Stops when the queue is empty, once ``need`` (the
    counted cells not yet settled; a negative count never stops) reaches 0 at bucket ``floor``
    or later, or past bucket ``last`` (no cost in a later bucket is stored). Returns the level
    (see :func:`_cost_to_go`): the bucket it stopped in, or ``last``.
    """
    flat_mult, flat_cost = mult.reshape(-1), cost.reshape(-1)
    offs, codes, lengths = _steps(mult.shape[1], cell)
    slot = head.size - 1  # a power of two, less one: the slot of a bucket is bucket & slot
    width = 0.5 * cell
    while size > 0 and (need != 0 or cur < floor):
        if cur > last:
            return last
        node = head[cur & slot]
        if node < 0:
            cur += 1
            continue
        head[cur & slot] = nodes[2 * node + 1]
        size -= 1
        k = nodes[2 * node]
        flags = mask[k]
        if flags & 2:  # settled already
            continue
        mask[k] = flags | 2
        need -= flags & 1
        c = flat_cost[k]
        for q in range(8):
            kk = k + offs[q]
            mk = flat_mult[kk]
            if mk == np.inf:
                continue
            nc = c + lengths[q] * mk
            if nc < flat_cost[kk]:
                bucket = int(nc / width)
                if bucket <= last:
                    flat_cost[kk] = nc
                    parent[kk] = codes[q]
                    s = bucket & slot
                    nodes[2 * used], nodes[2 * used + 1] = kk, head[s]
                    head[s] = used
                    used += 1
                    size += 1
    return cur if need == 0 and cur >= floor else last


@numba.njit(cache=True)
def _repair(mult, cost, parent, changed, n_changed, ti, tj, box, level, cell, nodes, scratch):
    """Bring the costs of a search (:func:`_cost_to_go`, at ``level``; the same padded map)
    up to date after the multipliers of the cells ``changed[:n_changed]`` (flat indices) went
    up.

    The cells whose exact cost was known (in a bucket up to ``level``) and whose way back to the
    target passes through a changed cell lose their cost; each gets the best step from a known
    neighbour that kept its cost, and the search runs from those up to ``level`` again. Every cell
    whose new exact cost is in a bucket up to ``level`` then holds it, and the others none: the
    invariant of a search at ``level``, on the new multipliers. (Raising multipliers lowers no
    cost, so a cell that kept its cost keeps the exact one.) ``scratch`` = ``(flag, cells,
    seed)``, (ni * nj,) each, ``flag`` all 0 (and left so).
    """
    nj = mult.shape[1]
    flat_mult, flat_cost = mult.reshape(-1), cost.reshape(-1)
    offs, codes, lengths = _steps(nj, cell)
    width = 0.5 * cell
    flag, cells, seed = scratch
    n = 0
    for q in range(n_changed):  # the changed cells with a known cost, the target excepted
        k = changed[q]
        if k != ti * nj + tj and not flag[k] and _within(flat_cost[k], width, level):
            flag[k] = 1
            cells[n] = k
            n += 1
    q = 0
    while q < n:  # and every cell whose way back passes through one (a padding cell has none)
        k = cells[q]
        q += 1
        for s in range(8):
            kk = k + offs[s]
            if not flag[kk] and parent[kk] == codes[s] and _within(flat_cost[kk], width, level):
                flag[kk] = 1
                cells[n] = kk
                n += 1
    mask, _ = _box_mask(mult, box)
    need = 0  # the enterable cells of the box that lose their cost
    for q in range(n):
        need += mask[cells[q]]
        flat_cost[cells[q]] = np.inf
    floor = np.int64(0)  # the last bucket of a box cell that keeps its cost
    for i in range(box[0], box[1] + 1):
        for j in range(box[2], box[3] + 1):
            if not flag[i * nj + j] and _within(cost[i, j], width, level):
                floor = max(floor, np.int64(int(cost[i, j] / width)))
    lo, hi = _ALL, np.int64(0)
    top = 1.0
    for q in range(n):  # each such cell's best step from a neighbour that kept its cost
        k = cells[q]
        flag[k] = 0
        mk = flat_mult[k]
        seed[q] = np.inf
        if mk == np.inf:
            continue
        top = max(top, mk)
        for s in range(8):
            c = flat_cost[k - offs[s]]  # the neighbour that step ``s`` comes from
            if _within(c, width, level):
                nc = c + lengths[s] * mk
                if nc < seed[q]:
                    seed[q] = nc
                    parent[k] = codes[s]
        if _within(seed[q], width, level):
            lo = min(lo, np.int64(int(seed[q] / width)))
            hi = max(hi, np.int64(int(seed[q] / width)))
    if lo == _ALL:  # none can be reached up to the level
        return level
    # the search only ever lowers cells that lost their cost (any other cell up to the level
    # keeps its exact one, and a cell beyond it stays beyond), so their dearest multiplier
    # bounds a step
    head = np.full(_slots(int(hi - lo) + int(lengths[0] * top / width) + 3), -1, np.int32)
    used = 0
    for q in range(n):
        if _within(seed[q], width, level):
            flat_cost[cells[q]] = seed[q]
            s = int(seed[q] / width) & (head.size - 1)
            nodes[2 * used], nodes[2 * used + 1] = cells[q], head[s]
            head[s] = used
            used += 1
    return _settle(mult, cost, parent, head, nodes, used, used, lo, mask, cell, need, level, floor)


@numba.njit(cache=True)
def _known(mult, cost, box, level, cell):
    """Whether every enterable cell of ``box`` holds its exact cost under a search at ``level``
    (see :func:`_cost_to_go`)."""
    if level == _ALL:
        return True
    # ``_within`` without a division per cell: a cost below ``limit`` is in a bucket up to the
    # level (``limit`` sits a hair under the next bucket's start, so that rounding cannot put a
    # cost that is not into the level; a cost within that hair only makes the box unknown)
    limit = (level + 1) * (0.5 * cell) * (1.0 - 1e-12)
    for i in range(box[0], box[1] + 1):
        for j in range(box[2], box[3] + 1):
            if mult[i, j] < np.inf and not cost[i, j] < limit:
                return False
    return True


@numba.njit(cache=True, inline="always")
def _multiplier(cl, prm):
    """The cost multiplier of a step into a cell at clearance ``cl`` (inf: not to be entered);
    ``prm`` = (r_tight, r_block, r_comfort, comfort_cost, tight_cost)."""
    r_tight, r_block, r_comfort, comfort_cost, tight_cost = prm
    band = max(r_comfort - r_block, 1e-9)
    m = 1.0 + comfort_cost * min(max(r_comfort - cl, 0.0) / band, 1.0)
    m = m + tight_cost if cl <= r_block else m
    return m if cl > r_tight else np.inf


def _plan_run(seen, pos, heading, target, keep_len, land, prev_aim, active, cands, prm, memo, out):
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

    ``memo`` = ``(key, clear, mult, cost, parent, level)``: ``key`` (B, 10) int64, ``clear``,
    ``mult`` and ``cost`` (B, (N + 2)^2) float64, ``parent`` (B, (N + 2)^2) int8 and ``level``
    (B,) int64: each user's last clearance map, cost multipliers (:func:`_multiplier` of each
    cell's clearance), cost to go and its search's steps back and level (row-major over its box
    with a padding row and column on each side, never entered; see :func:`_cost_to_go`) and what
    they were computed from (the map's version, the box, the
    target's cell, the user's cell and the reach of the rays). A user whose ``key`` matches the
    present call reuses them: the same inputs give the same maps. One whose map was ``prior``
    and whose box is the same only lowers its clearance map and updates its multipliers where
    ``news`` are near (a minimum over the marked cells, in any order); if its target's cell is
    the same too, its
    search is repaired where the multipliers went up (:func:`_repair`) and kept if it still
    covers the square the marches read (:func:`_known`), else it searches again. A row of
    ``key`` that holds -1 (a new episode) matches nothing.
    """
    occ, lo, hi, version, prior, news = seen
    key, clear_memo, mult_memo, cost_memo, parent_memo, level_memo = memo
    aim_out, valid_out, go_out, keep_out = out
    p = prm[0]
    cell, half, look, goal_tol = p["cell"], p["half"], p["look"], p["goal_tol"]
    mult_prm = (p["r_tight"], p["r_block"], p["r_comfort"], p["comfort_cost"], p["tight_cost"])
    r_tight, r_block, turn_cost = p["r_tight"], p["r_block"], p["turn_cost"]
    step_a, tight_penalty, hold = p["step_a"], p["tight_penalty"], p["hold"]
    geom = np.array([0.5 * cell, half, cell, goal_tol])
    nb, n, _ = occ.shape
    w = math.ceil(p["r_comfort"] / cell) + 1
    cap = w * cell
    pad = w + math.ceil((look + 1.0) / cell)
    # distance to a marked cell at offset (di, dj), less half a cell, floored at 0
    nw = 2 * w + 1
    ring = np.empty(nw * nw)
    for di in range(-w, w + 1):
        for dj in range(-w, w + 1):
            d = max(math.sqrt(di * di + dj * dj) * cell - 0.5 * cell, 0.0)
            ring[(di + w) * nw + dj + w] = d
    # scratch memory reused by every user: the search's queue nodes, the cells near news, and
    # the repair's flags, cells and seed costs
    nodes = np.empty(0, np.int32)
    near = np.empty(0, np.int64)
    flag, cells, seed = np.zeros(0, np.uint8), np.empty(0, np.int64), np.empty(0)
    passed = np.zeros(cands.size, np.bool_)  # per candidate: clear with the full margin
    order = np.empty(cands.size, np.int64)  # per user: the candidates in the order tried
    by_turn = np.argsort(np.abs(cands), kind="mergesort")  # the candidates by size of turn
    # the cells a march reads: their centres lie within its last sample's distance and half a
    # cell's diagonal of the user, which is within ``around`` cells of the user's
    far = math.ceil(look / geom[0] - 1e-9) * geom[0] + 0.7072 * cell
    reach2 = far * far
    around = math.ceil(far / cell) + 1
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
        size = (ni + 2) * (nj + 2)  # map cell (i, j) is at [i - i0 + 1, j - j0 + 1]
        reach = math.ceil(max(look, keep_len[b]) / cell) + 1
        clear = clear_memo[b, :size].reshape((ni + 2, nj + 2))
        mult = mult_memo[b, :size].reshape((ni + 2, nj + 2))
        cost = cost_memo[b, :size].reshape((ni + 2, nj + 2))
        parent = parent_memo[b, :size]
        same_box = key[b, 1] == i0 and key[b, 2] == i1 and key[b, 3] == j0 and key[b, 4] == j1
        grown = same_box and key[b, 0] == prior[b] and prior[b] >= 0  # only ``news`` are new
        same_target = grown and key[b, 5] == ti and key[b, 6] == tj
        same = same_box and key[b, 0] == version[b]
        for q, v in enumerate((i0, i1, j0, j1, ti, tj, pi, pj, reach)):
            same = same and key[b, q + 1] == v
            key[b, q + 1] = v
        key[b, 0] = version[b]
        if not same:
            if nodes.size < 2 * (9 * size + 1):  # enough for a search and for a repair
                nodes = np.empty(2 * (9 * size + 1), np.int32)
                seed = np.empty(size)
                near, cells = np.empty(size, np.int64), np.empty(size, np.int64)
                flag = np.zeros(size, np.uint8)
            n_near = 0
            if grown and prior[b] != version[b]:
                # the cells the news can lower
                for q in range(news.shape[0]):
                    oi, oj = news[q, 1], news[q, 2]
                    if news[q, 0] != b:
                        continue
                    for ii in range(max(oi - w, i0), min(oi + w, i1) + 1):
                        for jj in range(max(oj - w, j0), min(oj + w, j1) + 1):
                            k = (ii - i0 + 1) * (nj + 2) + jj - j0 + 1
                            if not flag[k]:
                                flag[k] = 1
                                near[n_near] = k
                                n_near += 1
                for q in range(news.shape[0]):
                    oi, oj = news[q, 1], news[q, 2]
                    if news[q, 0] == b and i0 - w <= oi <= i1 + w and j0 - w <= oj <= j1 + w:
                        _stamp(clear, oi, oj, i0, i1, j0, j1, w, ring)
                m = 0
                for q in range(n_near):  # their new multipliers; keep those that changed
                    k = near[q]
                    flag[k] = 0
                    mk = _multiplier(clear.flat[k], mult_prm)
                    if mk != mult.flat[k]:
                        mult.flat[k] = mk
                        near[m] = k
                        m += 1
                n_near = m
            elif not grown:
                _clearance(occ[b], clear, i0, i1, j0, j1, w, ring, cap)
                mult[:] = np.inf  # the padding, never entered
                for i in range(1, ni + 1):
                    inner, line = mult[i, 1 : nj + 1], clear[i, 1 : nj + 1]
                    for j in range(nj):  # vectorised along the row
                        inner[j] = _multiplier(line[j], mult_prm)
            # the cost to go from the target, dearer close to obstacles. Only the cells the rays
            # below can read are needed: a square of ``reach`` cells around the user. A search
            # on the same box and target is brought up to date instead when it can be.
            box = (
                max(pi - reach - i0, 0) + 1,
                min(pi + reach - i0, ni - 1) + 1,
                max(pj - reach - j0, 0) + 1,
                min(pj + reach - j0, nj - 1) + 1,
            )
            known = False
            if same_target:
                if n_near:
                    level_memo[b] = _repair(
                        mult,
                        cost,
                        parent,
                        near,
                        n_near,
                        ti - i0 + 1,
                        tj - j0 + 1,
                        box,
                        level_memo[b],
                        cell,
                        nodes,
                        (flag, cells, seed),
                    )
                known = _known(mult, cost, box, level_memo[b], cell)
            if not known:
                level_memo[b] = _cost_to_go(
                    mult, cost, parent, ti - i0 + 1, tj - j0 + 1, box, cell, nodes
                )
        # every heading with the full margin, and with the tight one at a penalty; the aim of
        # the last step gets a bonus (hysteresis). The user may always move away from, or
        # along, what it already stands closer to. The best is the least score, the first
        # heading in (tier, candidate) order on a tie. A march on the map ends in a cell whose
        # centre lies within ``far`` of the user, so the least cost kept there bounds its end
        # cost from below, and with it the heading's score: a heading whose bound cannot beat the
        # best so far is not marched. The headings are tried near the last aim first, then by
        # the size of the turn, so that a good best comes early.
        x, y = pos[b, 0], pos[b, 1]
        goal = (ti - i0, tj - j0, int(goal_tol / cell) + 1)
        c0 = clear[pi - i0 + 1, pj - j0 + 1] - 0.02
        prev = prev_aim[b] - heading[b]
        prev = wrap_angle(prev)
        low = np.inf
        if not (-half <= x - far and x + far < half and -half <= y - far and y + far < half):
            low = -np.inf  # the marches may leave the map: no bound
        for ii in range(max(pi - around - i0, 0), min(pi + around - i0, ni - 1) + 1):
            dx = (ii + i0 + 0.5) * cell - half - x
            for jj in range(max(pj - around - j0, 0), min(pj + around - j0, nj - 1) + 1):
                dy = (jj + j0 + 0.5) * cell - half - y
                if dx * dx + dy * dy <= reach2:
                    low = min(low, cost[ii + 1, jj + 1])
        m = 0
        for q in range(cands.size):
            passed[q] = False
            if abs(cands[q] - prev) <= step_a:
                order[m] = q
                m += 1
        for q in by_turn:
            if not abs(cands[q] - prev) <= step_a:
                order[m] = q
                m += 1
        best = np.inf
        best_tier, best_q = 2, cands.size
        best_a = 0.0
        best_thr = best_thr0 = min(r_block, c0)
        for tier in range(2):
            thr = min(r_block if tier == 0 else r_tight, c0)
            for q in order:
                # a heading clear with the full margin is clear with the tight one, to the same
                # end, and scores no better with the penalty on top (>= 0): its march is skipped
                if tier == 1 and (passed[q] or thr == best_thr0) and tight_penalty >= 0.0:
                    continue
                a = cands[q]
                bound = low + turn_cost * abs(a) + tier * tight_penalty
                if abs(a - prev) <= step_a:
                    bound -= hold
                if (
                    not bound < np.inf
                    or bound > best
                    or (bound == best and (tier, q) > (best_tier, best_q))
                ):
                    continue
                ok, end_cost = _march(
                    clear, cost, i0, j0, x, y, heading[b] + a, look, thr, land[b], geom, goal
                )
                if tier == 0:
                    passed[q] = ok
                if ok and end_cost < np.inf:
                    score = end_cost + turn_cost * abs(a) + tier * tight_penalty
                    if abs(a - prev) <= step_a:
                        score -= hold
                    if score < best or (score == best and (tier, q) < (best_tier, best_q)):
                        best, best_a, best_thr = score, a, thr
                        best_tier, best_q = tier, q
        thr = best_thr
        valid_out[b] = best < np.inf
        aim_out[b] = best_a
        h = heading[b]
        go_out[b] = _march(clear, cost, i0, j0, x, y, h, look, thr, land[b], geom, goal)[0]
        keep_out[b] = _march(clear, cost, i0, j0, x, y, h, keep_len[b], thr, land[b], geom, goal)[0]


#: The goal seeker's planner: ``plan_kernel(batch_size)(...)`` (see ``_plan_run``).
plan_kernel = BatchKernel(_plan_run, parallel=False)

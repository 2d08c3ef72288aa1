"""The goal seeker's route planner: its search and its repair against scipy's Dijkstra, its memo
against planning afresh."""

import gymnasium as gym
import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

import vrloco_env  # noqa: F401  (registers the ids)
from agents.benchmark.policies import build_policy
from agents.scripted.planner import _cost_to_go, _known, _repair

SQRT2 = 1.4142135623730951


def _nodes(ni, nj):
    return np.empty(2 * (9 * ni * nj + 1), np.int32)


def _padded(mult):
    """``mult`` with a row and a column of walls on each side, as the planner keeps its maps."""
    return np.pad(mult, 1, constant_values=np.inf)


def _search(mult, start, box, cell):
    """The search's costs, its parents and its level on the padded map ``mult`` (``start`` and
    ``box`` in its indices)."""
    ni, nj = mult.shape
    cost, parent = np.empty((ni, nj)), np.empty(ni * nj, np.int8)
    level = _cost_to_go(mult, cost, parent, start[0], start[1], box, cell, _nodes(ni, nj))
    return cost, parent, level


def _random_map(rng, cell):
    """A padded map; then a random cell of it inside the padding."""
    ni, nj = rng.integers(5, 40, size=2)
    mult = 1.0 + rng.uniform(0.0, 4.0, (ni, nj)) * (rng.random((ni, nj)) < 0.5)
    mult[rng.random((ni, nj)) < 0.25] = np.inf  # walls: never entered
    return _padded(mult)


def _inner_cell(rng, mult):
    return int(rng.integers(1, mult.shape[0] - 1)), int(rng.integers(1, mult.shape[1] - 1))


def _square(i, j, mult, half=3):
    """The square of ``half`` cells around ``(i, j)``, inside the padding."""
    ni, nj = mult.shape
    return (max(i - half, 1), min(i + half, ni - 2), max(j - half, 1), min(j + half, nj - 2))


def _scipy_costs(mult, start, cell):
    """The same graph for scipy: an edge into every enterable cell from each of its 8
    neighbours, weighing the step length times the cell's multiplier."""
    ni, nj = mult.shape
    rows, cols, weights = [], [], []
    for i in range(ni):
        for j in range(nj):
            for di in (-1, 0, 1):
                for dj in (-1, 0, 1):
                    ii, jj = i + di, j + dj
                    if (di, dj) == (0, 0) or not (0 <= ii < ni and 0 <= jj < nj):
                        continue
                    if np.isfinite(mult[ii, jj]):
                        rows.append(i * nj + j)
                        cols.append(ii * nj + jj)
                        weights.append((cell * SQRT2 if di and dj else cell) * mult[ii, jj])
    graph = coo_matrix((weights, (rows, cols)), shape=(ni * nj, ni * nj)).tocsr()
    return dijkstra(graph, directed=True, indices=start[0] * nj + start[1]).reshape(ni, nj)


@pytest.mark.parametrize("seed", range(6))
def test_the_bucket_queue_search_gives_scipys_dijkstra_costs(seed):
    rng = np.random.default_rng(seed)
    cell = (0.05, 0.1, 0.25)[seed % 3]
    mult = _random_map(rng, cell)
    ni, nj = mult.shape
    start = _inner_cell(rng, mult)
    mult[start] = 1.0
    want = _scipy_costs(mult, start, cell)
    assert np.isinf(want[1:-1, 1:-1]).any() and np.isfinite(want).sum() > 10  # walls cut some off
    got, _, level = _search(mult, start, (1, ni - 2, 1, nj - 2), cell)
    np.testing.assert_array_equal(got, want)
    _assert_level(got, want, level, cell)
    # stopping early, once a small square is settled: that square keeps the full costs
    box = _square(*_inner_cell(rng, mult), mult)
    early, _, level = _search(mult, start, box, cell)
    sq = (slice(box[0], box[1] + 1), slice(box[2], box[3] + 1))
    np.testing.assert_array_equal(early[sq], want[sq])
    _assert_level(early, want, level, cell)


def _assert_level(cost, want, level, cell):
    """The invariant of a search at ``level``: a cell whose exact cost is in a bucket up to
    the level holds it, and any other cell a cost in a later bucket or none."""
    bucket = np.full(want.shape, np.inf)
    reached = np.isfinite(want)
    bucket[reached] = np.floor(want[reached] / (0.5 * cell))
    upto = bucket <= level
    np.testing.assert_array_equal(cost[upto], want[upto])
    held = np.isfinite(cost[~upto])
    assert np.all(np.floor(cost[~upto][held] / (0.5 * cell)) > level)


@pytest.mark.parametrize("seed", range(12))
def test_a_repaired_search_equals_a_search_on_the_raised_multipliers(seed):
    """Raise the multipliers of a few cells (some to walls), repair the search: where it says
    the box is known, the box's costs are bit for bit those of a search on the new map, and the
    level's invariant holds on the whole map, repair after repair."""
    rng = np.random.default_rng(100 + seed)
    cell = (0.05, 0.1, 0.25)[seed % 3]
    mult = _random_map(rng, cell)
    ni, nj = mult.shape
    start = _inner_cell(rng, mult)
    mult[start] = 1.0
    box = _square(*_inner_cell(rng, mult), mult)
    sq = (slice(box[0], box[1] + 1), slice(box[2], box[3] + 1))
    cost, parent, level = _search(mult, start, box, cell)
    scratch = (np.zeros(ni * nj, np.uint8), np.empty(ni * nj, np.int64), np.empty(ni * nj))
    known = 0
    for _ in range(6):
        inner = rng.integers(1, (ni - 1, nj - 1), size=(int(rng.integers(1, 8)), 2))
        changed = np.unique(inner[:, 0] * nj + inner[:, 1])  # flat indices, inside the padding
        raised = mult.ravel()[changed] * rng.uniform(1.0, 3.0, changed.size)
        raised[rng.random(changed.size) < 0.3] = np.inf
        mult.ravel()[changed] = raised
        want = _scipy_costs(mult, start, cell)
        level = _repair(
            mult,
            cost,
            parent,
            changed,
            changed.size,
            start[0],
            start[1],
            box,
            level,
            cell,
            _nodes(ni, nj),
            scratch,
        )
        _assert_level(cost, want, level, cell)
        assert not scratch[0].any()
        if _known(mult, cost, box, level, cell):
            known += 1
            np.testing.assert_array_equal(cost[sq], want[sq])
        else:  # what the goal seeker does then: search again
            cost, parent, level = _search(mult, start, box, cell)
    assert known > 0


def _seeker_actions(seed, reuse):
    """A goal seeker's actions over an Avoid episode, planning anew every step unless
    ``reuse``; also how many user-steps reused a plan."""
    env = gym.make("VRLoco-Avoid-v0")
    policy = build_policy("goal_seeker", env)
    policy.reuse_plans = reuse
    obs, _ = env.reset(seed=seed)
    policy.reset(np.random.default_rng([seed, 1]))
    actions = []
    for _ in range(300):
        actions.append(policy.act(obs))
        obs, _, terminated, truncated, _ = env.step(actions[-1])
        if terminated or truncated:
            break
    return np.array(actions), policy.plans_reused


def test_the_planners_memo_changes_no_action():
    memo, reused = _seeker_actions(3, reuse=True)
    again, none = _seeker_actions(3, reuse=False)
    assert reused > len(memo) // 4 and none == 0  # the memo served many steps
    np.testing.assert_array_equal(memo, again)

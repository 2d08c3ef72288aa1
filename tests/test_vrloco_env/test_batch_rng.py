"""Per-user random streams: a batch reproduces single runs, and the numbers are what they claim."""

import numpy as np
import pytest

from vrloco_env.batch_rng import BatchRng


def test_batch_equals_single_runs():
    seeds = [3, 7, 11]
    batch = BatchRng.from_seeds(seeds, block=64)
    singles = [BatchRng.from_seeds([s], block=64) for s in seeds]
    for shape in [(5, 3), (100,), (1,), (70, 2)]:
        n_b, u_b = batch.normal(shape), batch.uniform(shape)
        for i, single in enumerate(singles):
            np.testing.assert_array_equal(n_b[i], single.normal(shape)[0])
            np.testing.assert_array_equal(u_b[i], single.uniform(shape)[0])


def test_distributions():
    r = BatchRng.from_seeds([0, 1])
    n = r.normal((20000,))
    u = r.uniform((20000,))
    assert abs(n.mean()) < 0.03 and abs(n.std() - 1) < 0.03
    assert u.min() > 0 and u.max() < 1 and abs(u.mean() - 0.5) < 0.01
    assert not np.array_equal(n[0], n[1])


def test_rejects_non_generators():
    with pytest.raises(TypeError, match=r"generators\[0\]"):
        BatchRng([np.random.RandomState(0)])
    with pytest.raises(ValueError, match="at least one"):
        BatchRng([])


def test_reseeding_one_user_equals_a_fresh_single_stream():
    batch = BatchRng.from_seeds([1, 2, 3], block=50)
    batch.normal((37,))
    batch.uniform((11,))
    batch.reseed(1, np.random.default_rng(99))
    fresh = BatchRng.from_seeds([99], block=50)
    untouched = BatchRng.from_seeds([2], block=50)
    untouched.normal((37,))
    for shape in [(20, 3), (45,), (7,)]:
        n_b, u_b = batch.normal(shape), batch.uniform(shape)
        np.testing.assert_array_equal(n_b[1], fresh.normal(shape)[0])
        np.testing.assert_array_equal(u_b[1], fresh.uniform(shape)[0])
    reference = BatchRng.from_seeds([1, 3], block=50)
    reference.normal((37,))
    reference.uniform((11,))
    n_ref = reference.normal((20, 3))
    batch2 = BatchRng.from_seeds([1, 2, 3], block=50)
    batch2.normal((37,))
    batch2.uniform((11,))
    batch2.reseed(1, np.random.default_rng(99))
    np.testing.assert_array_equal(batch2.normal((20, 3))[[0, 2]], n_ref)  # others untouched


def test_one_user_drawing_alone_keeps_every_stream_equal_to_its_single_run():
    seeds = [4, 5, 6]
    batch = BatchRng.from_seeds(seeds, block=32)
    singles = [BatchRng.from_seeds([s], block=32) for s in seeds]
    plan = [
        ((10,), None),
        ((7,), [1]),
        ((25, 2), None),
        ((40,), [0, 2]),
        ((3,), None),
        ((100,), [2]),
        ((9,), None),
    ]
    for shape, rows in plan:
        got = batch.normal(shape, rows=rows)
        users = range(3) if rows is None else rows
        assert got.shape == (len(users), *shape)
        for k, i in enumerate(users):
            np.testing.assert_array_equal(got[k], singles[i].normal(shape)[0])


def test_streams_stay_single_runs_through_reseeds_and_refills_which_realign_every_user():
    """Users draw alone, start new streams and run out of their blocks at different times; each
    keeps drawing its own stream in order. A draw of every user first brings those ahead back
    to the others' position (so that it is a plain slice), and once a drawing user's block runs
    out every user refills and reads from one position again."""
    rng = np.random.default_rng(0)
    seeds = [10, 11, 12, 13]
    batch = BatchRng.from_seeds(seeds, block=40)
    singles = [BatchRng.from_seeds([s], block=40) for s in seeds]
    realigned = refilled = 0
    for step in range(60):
        if step % 7 == 3:  # a user starts a new episode
            i, seed = int(rng.integers(4)), 100 + step
            batch.reseed(i, np.random.default_rng(seed))
            singles[i] = BatchRng.from_seeds([seed], block=40)
        rows = None if rng.random() < 0.6 else sorted(rng.choice(4, 2, replace=False).tolist())
        shape = (int(rng.integers(1, 30)),)
        before = batch._pos.copy()
        got = batch.normal(shape, rows=rows)
        users = range(4) if rows is None else rows
        for k, i in enumerate(users):
            np.testing.assert_array_equal(got[k], singles[i].normal(shape)[0])
        if rows is None:
            assert np.all(batch._pos == batch._pos[0])
            realigned += bool(np.any(before != before[0]))
        elif np.any(before[list(users)] + shape[0] > 40):  # a block ran out in this draw
            assert np.all(batch._pos[[i for i in range(4) if i not in users]] == 0)
            assert np.all(batch._pos[list(users)] == shape[0])
            refilled += 1
    assert realigned > 5 and refilled > 2


def test_rows_are_validated():
    r = BatchRng.from_seeds([0, 1])
    with pytest.raises(ValueError, match=r"rows must lie in \[0, 1\]"):
        r.normal((2,), rows=[2])
    with pytest.raises(ValueError, match="rows as a boolean mask"):
        r.normal((2,), rows=np.array([True]))

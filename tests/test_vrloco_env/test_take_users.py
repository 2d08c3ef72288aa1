"""Dropping users from a running batch (``take_users``): the kept users go on bit for bit."""

from __future__ import annotations

import dataclasses
from collections import namedtuple
from typing import ClassVar

import numpy as np
import pytest
from _batch_walk import sized
from gymnasium.vector import AutoresetMode

from estimators.batching import TakesUsers, take_rows, take_rows_in_place, takes_users
from vrloco_env.techniques import TECHNIQUES
from vrloco_env.vector import VRLocoVectorEnv

B = 7
ROWS = np.array([5, 0, 3, 6])  # a new order, three users dropped


def _room_tuples(path: str) -> bool:
    """A room's own tuples (its obstacles or path points), whose length may equal B."""
    return ".layouts[" in path or ".layout." in path


def _env(task: str, technique: str, population: str | None, **kw) -> VRLocoVectorEnv:
    return VRLocoVectorEnv(
        B,
        task=task,
        technique=technique,
        population=population,
        autoreset_mode=AutoresetMode.DISABLED,
        **kw,
    )


def _check_kept_users_go_on(task: str, technique: str, population: str | None) -> None:
    """Two identical batches; one drops users after 30 steps, both go on (a reset of two
    kept users on the way): the kept users' observations, rewards, flags and infos are the
    whole batch's rows, to the bit, and nothing in the smaller batch is B long any more."""
    whole, kept = _env(task, technique, population), _env(task, technique, population)
    assert kept.can_take_users
    rng = np.random.default_rng(4)
    actions = rng.uniform(-1.0, 1.0, (120, B, whole.single_action_space.shape[0]))
    actions[:, :, 0] = np.abs(actions[:, :, 0])  # mostly walking
    actions = actions.astype(np.float32)
    whole.reset(seed=list(range(B)))
    kept.reset(seed=list(range(B)))
    for t in range(120):
        if t == 30:
            kept.take_users(ROWS)
            assert kept.num_envs == ROWS.size and kept.action_space.shape[0] == ROWS.size
            left = [p for p in sized(kept, B) if not _room_tuples(p)]
            assert not left, f"still {B} long after take_users: {left}"
        if t == 80:  # whole rows 0 and 6 are kept rows 1 and 3
            mask = np.isin(np.arange(B), [0, 6])
            seeds = [100 if i == 0 else 106 if i == 6 else None for i in range(B)]
            obs_w, _ = whole.reset(seed=seeds, options={"reset_mask": mask})
            mask = np.isin(np.arange(ROWS.size), [1, 3])
            obs_k, _ = kept.reset(seed=[None, 100, None, 106], options={"reset_mask": mask})
            np.testing.assert_array_equal(obs_w[ROWS], obs_k)
        out_w = whole.step(actions[t])
        out_k = kept.step(actions[t][ROWS] if t >= 30 else actions[t])
        sel = ROWS if t >= 30 else slice(None)
        for k, (w, c) in enumerate(zip(out_w[:4], out_k[:4], strict=True)):
            np.testing.assert_array_equal(w[sel], c, err_msg=f"step {t}, output {k}")
        for key, w in out_w[4].items():
            np.testing.assert_array_equal(
                np.asarray(w)[sel], out_k[4][key], err_msg=f"step {t}, info {key}"
            )


@pytest.mark.parametrize("task", ["approach", "avoid", "doorway", "interact", "reach"])
def test_every_task_s_kept_users_go_on_as_in_the_whole_batch(task):
    _check_kept_users_go_on(task, "zhang2021", "typical")


@pytest.mark.parametrize("technique", [t for t in TECHNIQUES if t != "zhang2021"])
def test_every_technique_s_kept_users_go_on_as_in_the_whole_batch(technique):
    _check_kept_users_go_on("approach", technique, "typical")


@pytest.mark.parametrize("population", [None, "human", "gaze_scanners", "nodders"])
def test_every_population_s_kept_users_go_on_as_in_the_whole_batch(population):
    _check_kept_users_go_on("avoid", "nod_robust", population)


def test_take_users_rejects_bad_rows_before_changing_anything():
    env = _env("approach", "zhang2021", None)
    with pytest.raises(RuntimeError, match="reset"):
        env.take_users([0])
    env.reset(seed=0)
    for rows, match in (([0, 0], "repeat"), ([7], r"\[0, 6\]"), ([], "at least one user")):
        with pytest.raises(ValueError, match=match):
            env.take_users(rows)
    assert env.num_envs == B and env.core.ep.position.shape == (B, 2)


def test_a_part_that_cannot_drop_users_stops_take_users_before_any_change():
    """The visual-inertial head tracker keeps per-user state and no ``take_users``: the batch
    says so, and refuses with the batch untouched."""
    env = _env("approach", "zhang2021", None, pose_source="visual_inertial")
    env.reset(seed=0)
    assert not env.can_take_users
    with pytest.raises(TypeError, match="cannot drop users"):
        env.take_users([0, 1])
    assert env.num_envs == B and env.core.rng.batch_size == B


# --------------------------------------------------------------------------- the helpers
Pair = namedtuple("Pair", "a b")


@dataclasses.dataclass
class _Chunk:
    shared_fields: ClassVar[tuple[str, ...]] = ("t",)
    t: np.ndarray
    x: np.ndarray
    inner: Pair


def test_take_rows_takes_users_of_every_container_and_leaves_shared_fields():
    x = np.arange(12.0).reshape(6, 2)
    rows = np.array([4, 1])
    chunk = _Chunk(t=np.arange(3.0), x=x, inner=Pair(np.arange(6), [f"u{i}" for i in range(6)]))
    got = take_rows({"c": chunk, "none": None, "tuple": (x, x[:, 0])}, rows)
    np.testing.assert_array_equal(got["c"].x, x[rows])
    np.testing.assert_array_equal(got["c"].t, chunk.t)  # the batch's clock, not per user
    assert isinstance(got["c"].inner, Pair) and got["c"].inner.b == ["u4", "u1"]
    np.testing.assert_array_equal(got["tuple"][1], [8.0, 2.0])
    assert got["none"] is None
    np.testing.assert_array_equal(chunk.x, np.arange(12.0).reshape(6, 2))  # left alone
    with pytest.raises(TypeError, match="float has no rows"):
        take_rows(1.5, rows)


def test_take_rows_in_place_moves_only_what_changes_place():
    rng = np.random.default_rng(0)
    for rows in ([0, 1, 2], [5, 1, 2, 3], [3, 0], [4, 5, 0, 1]):
        a = rng.normal(size=(6, 5))
        want = a[np.array(rows)].copy()
        got = take_rows_in_place(a, np.array(rows))
        np.testing.assert_array_equal(got, want)
        assert np.shares_memory(got, a)  # a prefix of the same memory, not a copy


class _Parent(TakesUsers):
    per_user_fields = ("x",)
    batch_size_field = "n"

    def __init__(self, n: int) -> None:
        self.n, self.x, self.shared = n, np.arange(n), np.arange(n)


class _Child(_Parent):  # new per-user state, undeclared
    def __init__(self, n: int) -> None:
        super().__init__(n)
        self.y = np.arange(n)


class _Holder(TakesUsers):
    per_user_parts = ("part", "again", "absent")

    def __init__(self, part) -> None:
        self.part, self.again, self.absent = part, part, None


def test_a_subclass_must_declare_its_own_per_user_fields():
    p = _Parent(4)
    p.take_users(np.array([2, 0]))
    assert p.n == 2 and list(p.x) == [2, 0] and list(p.shared) == [0, 1, 2, 3]
    assert takes_users(p) and not takes_users(_Child(4))
    with pytest.raises(TypeError, match="_Child does not declare"):
        _Child(4).take_users(np.array([0]))
    assert not takes_users(_Holder(_Child(3)))  # a part that cannot makes the whole unable
    holder = _Holder(_Parent(3))
    holder.take_users(np.array([1]))
    assert list(holder.part.x) == [1]  # a part named twice is taken once

"""A learned user trained on a mix of cells: the mixed vector env against its parts stepped alone,
the mix's parsing and errors, and a mixed model played on each of its cells."""

import numpy as np
import pytest

from agents.learned import train_ppo  # before torch: see its docs
from agents.learned.mixed_env import (
    MixedUsersEnv,
    mix_cell,
    mixed_users,
    split_users,
    training_cells,
)
from agents.learned.variability_env import HumanVariabilityEnv
from vrloco_env.vector import VRLocoVectorEnv


def _parts(seed):
    """An idealised part (no head_on_torso field) and a typical part with its variability."""
    return [
        VRLocoVectorEnv(2, task="avoid", population="idealised", max_episode_steps=30),
        HumanVariabilityEnv(
            VRLocoVectorEnv(3, task="avoid", population="typical", max_episode_steps=30),
            "typical",
            seed,
        ),
    ]


def test_a_mix_steps_each_part_as_it_steps_alone():
    mixed = MixedUsersEnv(_parts(5), ["idealised", "typical"])
    alone = _parts(5)
    assert mixed.num_envs == 5
    spec = mixed.observation_spec
    assert spec.fields[-1].name == "head_on_torso"  # the richest part's layout
    head = spec.offset("head_on_torso")
    obs, _ = mixed.reset(seed=11)
    first, _ = alone[0].reset(seed=11)
    second, _ = alone[1].reset(seed=13)
    np.testing.assert_array_equal(obs[:2, :head], first)
    assert (obs[:2, head] == 0).all()  # the idealised head is straight on the torso
    np.testing.assert_array_equal(obs[2:], second)
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(40):  # past the 30-step horizon: the autoreset's final observations too
        act = rng.uniform(-1, 1, (5, 5)).astype(np.float32)
        obs, reward, term, trunc, info = mixed.step(act)
        o1, r1, t1, u1, i1 = alone[0].step(act[:2])
        o2, r2, t2, u2, i2 = alone[1].step(act[2:])
        np.testing.assert_array_equal(obs[:2, :head], o1)
        np.testing.assert_array_equal(obs[2:], o2)
        np.testing.assert_array_equal(reward, np.concatenate([r1, r2]))
        np.testing.assert_array_equal(term | trunc, np.concatenate([t1 | u1, t2 | u2]))
        np.testing.assert_array_equal(
            info["collisions"], np.concatenate([i1["collisions"], i2["collisions"]])
        )
        done = np.flatnonzero(term | trunc)
        for row in done:
            if row < 2:
                np.testing.assert_array_equal(info["final_obs"][row, :head], i1["final_obs"][row])
            else:
                np.testing.assert_array_equal(info["final_obs"][row], i2["final_obs"][row - 2])
        ended += done.size
    assert ended >= 5


def test_the_cells_of_a_mix_and_its_errors():
    cells = training_cells("zhang2021,smooth", "idealised,typical", "none,typical")
    assert cells == [
        ("zhang2021", "idealised", None),
        ("zhang2021", "typical", "typical"),
        ("smooth", "idealised", None),
        ("smooth", "typical", "typical"),
    ]
    assert mix_cell(cells) == {
        "technique": ["zhang2021", "smooth"],
        "population": ["idealised", "typical"],
    }
    from vrloco_env.techniques import TECHNIQUES

    assert [c[0] for c in training_cells("all")] == list(TECHNIQUES)
    assert training_cells(None, "typical", "typical") == [(None, "typical", "typical")]
    with pytest.raises(ValueError, match=r"'nope'.*valid names: zhang2021"):
        training_cells("zhang2021,nope")
    with pytest.raises(ValueError, match="variability: give one population, or one per"):
        training_cells(None, "idealised,typical", "none,typical,nodders")
    with pytest.raises(ValueError, match="technique: smooth given more than once"):
        training_cells("smooth,smooth")
    with pytest.raises(ValueError, match="num_envs=3: a mix of 4 cells needs at least one"):
        mixed_users(3, "avoid", None, cells, None, None, seed=0)
    assert split_users(10, 4) == [3, 3, 2, 2]


def test_a_mix_refuses_parts_it_cannot_read_as_one():
    with pytest.raises(ValueError, match="a mix of cells trains one task"):
        MixedUsersEnv([VRLocoVectorEnv(1, task="avoid"), VRLocoVectorEnv(1)], ["a", "b"])


@pytest.mark.slow  # a tiny PPO run on a mix, then played on each of its cells
def test_a_model_trained_on_a_mix_knows_and_plays_each_of_its_cells(tmp_path):
    from agents.learned import evaluate_model

    path = train_ppo(
        "avoid",
        steps=256,
        num_envs=4,
        out_dir=tmp_path,
        eval_every=256,
        eval_episodes=4,
        progress=False,
        technique="zhang2021,smooth",
        population="idealised,typical",
        variability="none,typical",
        n_steps=64,
        batch_size=128,
    )
    from stable_baselines3 import PPO

    model = PPO.load(path)
    assert model.vrloco_cell["technique"] == ["zhang2021", "smooth"]
    assert model.vrloco_variability == [None, "typical", None, "typical"]
    assert model.vrloco_observation[-1]["name"] == "head_on_torso"
    for technique in ("zhang2021", "smooth"):
        row = evaluate_model(path, episodes=1, progress=False, technique=technique)
        assert row["technique"] == technique and row["trained_on"] is None
    with pytest.raises(ValueError, match=r"technique='vqf' \(trained: \['zhang2021', 'smooth'\]"):
        evaluate_model(path, episodes=1, progress=False, technique="vqf")


def _same(a, b, where="info"):
    """``a`` and ``b`` hold the same values (nested dicts of arrays)."""
    if isinstance(a, dict):
        assert set(a) == set(b), where
        for k in a:
            _same(a[k], b[k], k)
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape, where
    assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), where


def test_users_stepped_in_worker_processes_are_the_users_of_one_env():
    from dataclasses import replace

    from agents.learned.models import env_settings
    from agents.learned.parallel_env import parallel_users

    kwargs = env_settings("approach")  # episodes end at a user's first collision: apart
    kwargs["config"] = replace(kwargs["config"], terminate_on_collision=True, max_episode_steps=60)
    one = VRLocoVectorEnv(6, **kwargs)
    workers = parallel_users(6, 2, kwargs)
    try:
        first, _ = one.reset(seed=21)
        np.testing.assert_array_equal(workers.reset(seed=21)[0], first)
        rng = np.random.default_rng(2)
        apart = 0
        for _ in range(80):
            act = rng.uniform(-1, 1, (6, 5)).astype(np.float32)
            a, b = one.step(act), workers.step(act)
            for x, y in zip(a[:4], b[:4], strict=True):
                np.testing.assert_array_equal(x, y)
            done = a[2] | a[3]
            apart += done[:3].any() != done[3:].any()
            for key in ("final_obs", "collisions", "is_success", "distance_to_goal"):
                if key in a[4]:
                    _same(a[4][key][done], b[4][key][done], key)
            if "final_info" in a[4]:
                _same(
                    {k: v[done] for k, v in a[4]["final_info"].items()},
                    {k: v[done] for k, v in b[4]["final_info"].items()},
                )
        assert apart > 0  # one worker's users ended while the other's did not
        with pytest.raises(ValueError, match="action"):  # the env's error, from its worker
            workers.step(np.full((6, 5), np.nan, np.float32))
        act = rng.uniform(-1, 1, (6, 5)).astype(np.float32)  # both workers answer in turn again
        np.testing.assert_array_equal(workers.step(act)[0], one.step(act)[0])
    finally:
        workers.close()
    with pytest.raises(ValueError, match="env_workers=0: must be an integer >= 1"):
        parallel_users(6, 0, kwargs)


@pytest.mark.slow  # two tiny PPO runs: the second goes on from the first
def test_a_run_goes_on_from_a_model_reading_the_fields_it_knows(tmp_path):
    from stable_baselines3 import PPO

    tiny = dict(steps=256, num_envs=4, eval_every=256, eval_episodes=2, progress=False)
    first = train_ppo("avoid", out_dir=tmp_path / "a", n_steps=64, batch_size=128, **tiny)
    then = train_ppo(
        "avoid",
        out_dir=tmp_path / "b",
        population="idealised,typical",
        variability="none,typical",
        init=first,
        **tiny,
    )
    a, b = PPO.load(first), PPO.load(then)
    assert b.n_steps == 64 and b.batch_size == 128  # its PPO settings, kept
    assert b.vrloco_observation == a.vrloco_observation  # no head_on_torso: left unread
    assert b.vrloco_cell["population"] == ["idealised", "typical"]
    assert b.vrloco_cell["technique"] == a.vrloco_cell["technique"] == "zhang2021"
    moved = [
        not np.array_equal(x.numpy(), y.numpy())
        for x, y in zip(a.policy.state_dict().values(), b.policy.state_dict().values(), strict=True)
    ]
    assert any(moved)
    with pytest.raises(ValueError, match="was trained with frame_stack=1, this run has 2"):
        train_ppo("avoid", out_dir=tmp_path / "c", init=first, frame_stack=2, **tiny)
    with pytest.raises(ValueError, match="keeps its own PPO settings; drop n_steps"):
        train_ppo("avoid", out_dir=tmp_path / "c", init=first, n_steps=64, **tiny)


def test_a_mix_of_more_cells_than_the_default_evaluates_one_user_per_cell(tmp_path, monkeypatch):
    """``eval_episodes`` left out: 32 users, or one per cell of a bigger mix (17 techniques x 2
    populations: 34), rather than the error a mix with too few users is (which names the
    field); ``vrloco train --eval-episodes N`` chooses it."""
    import agents.learned.train as train
    from agents.cli import main

    asked = []

    class Stop(Exception):
        pass

    def users(n, *args, field="num_envs", **kwargs):
        asked.append((field, n))
        if field == "eval_episodes":
            raise Stop
        return None

    monkeypatch.setattr(train, "mixed_users", users)
    mix = dict(technique="all", population="idealised,typical", num_envs=34, progress=False)
    with pytest.raises(Stop):
        train_ppo("avoid", out_dir=tmp_path / "a", **mix)
    assert asked == [("num_envs", 34), ("eval_episodes", 34)]
    asked.clear()
    with pytest.raises(Stop):
        train_ppo("avoid", out_dir=tmp_path / "b", technique="zhang2021,smooth", progress=False)
    assert asked[-1] == ("eval_episodes", train.EVAL_EPISODES)
    asked.clear()
    cli = ["train", "--task", "avoid", "--technique", "zhang2021,smooth", "--steps", "8192"]
    with pytest.raises(Stop):
        main([*cli, "--eval-episodes", "40", "--out", str(tmp_path / "c")])
    assert asked[-1] == ("eval_episodes", 40)

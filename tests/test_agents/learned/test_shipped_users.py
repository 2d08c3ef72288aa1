"""Shipped learned users: the ``ppo`` policy spec, and stale models named by the field that
changed."""

import re

import gymnasium as gym
import numpy as np
import pytest

from agents.learned import SB3VecEnv, env_settings, make_model  # before torch: see its docs
from agents.learned.models import observation_columns, observation_layout
from vrloco_env.observation import Field, ObservationSpec
from vrloco_env.vector import VRLocoVectorEnv


def _untrained_model(tmp_path, task="approach", **saved):
    """A PPO model saved as vrloco train saves one (untrained: only its attributes matter)."""
    settings = env_settings(task)
    users = VRLocoVectorEnv(2, **settings)
    model = make_model(SB3VecEnv(users, seed=0), n_steps=8, batch_size=16)
    model.vrloco_env = settings
    model.vrloco_policy = {"frame_stack": 1, "recurrent": False}
    model.vrloco_observation = observation_layout(users.observation_spec)
    for key, value in saved.items():
        setattr(model, key, value)
    path = tmp_path / f"{task}.zip"
    model.save(path)
    return path


def test_a_model_reads_its_fields_by_name_and_a_changed_one_is_named():
    spec = ObservationSpec(
        [Field("goal_distance", scale=20.0, unit="m"), Field("rays", ("r0", "r1"))]
    )
    saved = observation_layout(spec)
    np.testing.assert_array_equal(observation_columns(saved, spec), [0, 1, 2])
    assert observation_columns(None, spec) is None  # a model saved without its layout
    # a field it does not know is left unread, and the fields it knows are found where they are
    wider = ObservationSpec([Field("extra"), *spec.fields[::-1]])
    np.testing.assert_array_equal(observation_columns(saved, wider), [3, 1, 2])
    cases = {
        "field 'rays' the env does not have": spec.fields[:1],
        "'rays' has 3 entries, the model was trained on 2 (r0, r1)": [
            spec.fields[0],
            Field("rays", ("r0", "r1", "r2")),
        ],
        "'goal_distance' reads 10 m as 1, the model was trained on 20.0 m": [
            Field("goal_distance", scale=10.0, unit="m"),
            spec.fields[1],
        ],
    }
    for phrase, fields in cases.items():
        with pytest.raises(ValueError, match=re.escape(phrase)):
            observation_columns(saved, ObservationSpec(fields))


def test_a_user_trained_without_a_populations_field_plays_that_population_unchanged(tmp_path):
    from agents.benchmark.policies import LearnedPolicy

    plain = gym.make("VRLoco-Approach-v0")
    typical = gym.make("VRLoco-Approach-v0", population="typical")
    path = _untrained_model(tmp_path)
    obs, _ = typical.reset(seed=1)
    spec = typical.unwrapped.observation_spec
    known = np.delete(obs, spec.slice("head_on_torso"))
    a = LearnedPolicy(path, typical).act(obs)
    b = LearnedPolicy(path, plain).act(known)
    np.testing.assert_array_equal(a, b)  # it reads exactly the fields it knows
    plain.close()
    typical.close()


def test_a_stale_model_is_refused_naming_the_field(tmp_path):
    from agents.benchmark.policies import LearnedPolicy

    env = gym.make("VRLoco-Approach-v0")
    layout = observation_layout(env.unwrapped.observation_spec)
    LearnedPolicy(_untrained_model(tmp_path), env)  # fits: no error
    layout[0] = {**layout[0], "scale": layout[0]["scale"] * 2}
    stale = _untrained_model(tmp_path, vrloco_observation=layout)
    name = layout[0]["name"]
    with pytest.raises(ValueError, match=rf"is stale: observation field '{name}' reads"):
        LearnedPolicy(stale, env)
    env.close()


def test_ppo_plays_the_tasks_shipped_user_and_names_the_tasks_that_have_one(tmp_path, monkeypatch):
    from agents.benchmark.policies import build_policy
    from agents.benchmark.resume import cell_inputs
    from agents.learned import users

    model = _untrained_model(tmp_path)
    monkeypatch.setattr(users, "HERE", tmp_path)
    monkeypatch.setitem(users.LEARNED_USERS, "approach", users.LearnedUser("approach", model.name))
    env = gym.make("VRLoco-Approach-v0")
    policy = build_policy("ppo+typical", env)
    assert policy.policy.path == model and policy.name.startswith("ppo")
    env.close()
    monkeypatch.delitem(users.LEARNED_USERS, "interact")
    monkeypatch.setitem(users.NOT_SHIPPED, "interact", "none met the bar (see the docs)")
    env = gym.make("VRLoco-Interact-v0")
    with pytest.raises(
        ValueError,
        match=r"no learned user is shipped for task 'interact' \(shipped: [a-z, ]*approach[a-z, "
        r"]*\): none met the bar \(see the docs\); train one with vrloco train --task interact",
    ):
        build_policy("ppo", env)
    env.close()

    class Cell:  # a benchmark cell: its key changes with the shipped model's bytes
        task, policy, technique, condition = "approach", "ppo", "zhang2021", "lab"

    before = cell_inputs([Cell])[Cell]
    model.write_bytes(model.read_bytes() + b"\0")
    assert cell_inputs([Cell])[Cell] != before


def test_every_shipped_user_fits_its_task_and_its_card_shows_how_it_does():
    """A shipped model still reads the current observation and action spaces (a stale one is an
    error naming the field), and its held-out card says it met the idealised bar (or the registry
    says what limits its task, with the command that shows it) and records the comparison with
    the goal seeker under every population."""
    import json

    from agents.benchmark.policies import LearnedPolicy
    from agents.learned.users import LEARNED_USERS
    from vrloco_env.tasks import env_id

    assert len(LEARNED_USERS) >= 1
    for name, user in LEARNED_USERS.items():
        task = user.task
        env = gym.make(env_id(task))
        LearnedPolicy(user.path, env)  # raises if stale
        env.close()
        card = json.loads(user.path.with_suffix(".json").read_text())
        assert card["task"] == task and card["train_command"].startswith("vrloco train")
        if user.limit:  # below the bar: the limit and the command that shows it
            assert not card["bar"]["holds_idealised"]
            assert "python -m " in user.limit or "vrloco " in user.limit
        else:
            assert card["bar"]["holds_idealised"]
        assert isinstance(card["bar"]["holds_against_goal_seeker"], bool)
        shown = {(r["user"], r["population"]) for r in card["held_out"]["rows"]}
        for pop in ("idealised", "typical", "nodders", "gaze_scanners"):
            assert {("ppo", pop), ("goal_seeker", pop)} <= shown
        assert user.path.with_name(f"{name}_curve.png").is_file()
        assert user.path.stem == name


def test_a_user_trained_with_a_turning_head_reads_a_straight_head_without_a_population(tmp_path):
    from agents.benchmark.policies import LearnedPolicy

    typical = VRLocoVectorEnv(1, **env_settings("approach", population="typical"))
    plain = gym.make("VRLoco-Approach-v0")
    saved = observation_layout(typical.observation_spec)
    columns = observation_columns(saved, plain.unwrapped.observation_spec)
    size = plain.unwrapped.observation_space.shape[0]
    assert columns[-1] == -1  # head_on_torso: 0, the head straight on the torso
    np.testing.assert_array_equal(columns[:-1], np.arange(size))
    model = make_model(SB3VecEnv(typical, seed=0), n_steps=8, batch_size=8)
    model.vrloco_env = env_settings("approach", population="typical")
    model.vrloco_policy = {"frame_stack": 1, "recurrent": False}
    model.vrloco_observation = saved
    model.save(tmp_path / "m.zip")
    obs, _ = plain.reset(seed=2)
    expected = model.predict(np.append(obs, 0.0).astype(np.float32), deterministic=True)[0]
    np.testing.assert_array_equal(LearnedPolicy(tmp_path / "m.zip", plain).act(obs), expected)
    plain.close()


def test_ship_names_a_missing_model_in_one_line(tmp_path, capsys):
    from agents.learned.users.ship import main

    assert main([str(tmp_path / "nope.zip"), "--dev"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ship: ") and "nope.zip" in err and "Traceback" not in err


def test_ship_evaluates_on_held_out_seeds_only_and_develops_on_the_others(capsys):
    """Shipping on a development seed, or developing on a held-out one, is refused by name."""
    from agents.learned.users import LEARNED_USERS
    from agents.learned.users.ship import HELD_OUT_SEED, main

    model = str(next(iter(LEARNED_USERS.values())).path)
    with pytest.raises(SystemExit) as shipped_low:
        main([model, "--command", "vrloco train --task approach", "--seed", "1000"])
    assert shipped_low.value.code == 2
    assert f"seed=1000: held-out seeds start at {HELD_OUT_SEED}" in capsys.readouterr().err
    with pytest.raises(SystemExit) as dev_high:
        main([model, "--dev", "--seed", str(HELD_OUT_SEED + 5)])
    assert dev_high.value.code == 2
    assert "are not for --dev" in capsys.readouterr().err


def test_a_learned_user_acts_as_stable_baselines3_predicts_to_the_last_bit():
    """The benchmark's actions of every shipped user (each row on its own) are those of
    ``model.predict(row, deterministic=True)``, the reference, on observations all over the
    observation box."""
    from agents.benchmark.policies import LearnedPolicy
    from agents.learned.users import LEARNED_USERS
    from vrloco_env.tasks import env_id

    rng = np.random.default_rng(7)
    for user in LEARNED_USERS.values():
        env = gym.make(env_id(user.task))
        policy = LearnedPolicy(user.path, env)
        env.close()
        rows = rng.uniform(-1.0, 1.0, (64, policy.model.observation_space.shape[0]))
        rows = rows.astype(np.float32)
        rows[:4] *= 3.0  # beyond the box too: predict clips the actions, not the observations
        want = np.stack([policy.model.predict(r, deterministic=True)[0] for r in rows])
        got = policy._act_rows(rows)
        assert got.dtype == want.dtype and np.array_equal(got, want), user.path.name
        assert len(np.unique(got[:, 0])) > 10  # the rows act differently: not a constant

"""Learned users that correct a scripted user: with no correction they are the scripted user,
step for step, in training and in the benchmark; the correction can reach any action; the runs
that cannot be built are refused by name."""

import numpy as np
import pytest

from agents.learned import train_ppo  # before torch: see its docs
from agents.learned.residual import (
    RESIDUAL_SCALE,
    ScriptedPlusCorrection,
    combine,
    scripted_field,
)
from agents.scripted import ObservationLayout, make_policy, params_from_env
from vrloco_env.vector import VRLocoVectorEnv


def _goal_seeker(env):
    return make_policy("goal_seeker", ObservationLayout.from_env(env), params_from_env(env))


def _users(n=4, task="approach"):
    return VRLocoVectorEnv(n, task=task, population="typical", max_episode_steps=80)


def test_with_no_correction_the_users_are_the_scripted_user_step_for_step():
    alone, corrected = _users(), _users()
    seeker = _goal_seeker(alone)
    env = ScriptedPlusCorrection(corrected, _goal_seeker(corrected), "goal_seeker")
    obs, _ = alone.reset(seed=5)
    seen, _ = env.reset(seed=5)
    width = alone.single_observation_space.shape[0]
    ends = 0
    for _ in range(200):  # past the 80-step time limit: autoresets included
        action = seeker.act(obs)
        np.testing.assert_array_equal(seen[:, :width], obs)
        np.testing.assert_array_equal(seen[:, width:], action)  # the field: what it does now
        obs, reward, term, trunc, _ = alone.step(action)
        seen, reward2, term2, trunc2, info = env.step(np.zeros((4, 5), np.float32))
        np.testing.assert_array_equal(reward, reward2)
        np.testing.assert_array_equal(term | trunc, term2 | trunc2)
        if (term | trunc).any():
            seeker.reset(rows=np.flatnonzero(term | trunc))
            assert info["final_obs"].shape == (4, width + 5)
        ends += int((term | trunc).sum())
    assert ends >= 8
    names = env.observation_spec.field("goal_seeker_action").entries
    assert names == scripted_field("goal_seeker").entries and names[0] == "goal_seeker_walk"


def test_with_no_correction_a_mix_of_techniques_is_each_ones_scripted_user_step_for_step():
    """A mix of techniques whose bodies differ (head tilt moves without steps) has one scripted
    user per body, each acting for its own users as it would alone."""
    from agents.learned.imitation import BodyTeachers, scripted_teacher
    from agents.learned.mixed_env import MixedUsersEnv

    techniques = ("zhang2021", "smooth", "head_tilt", "zhang2021_consumer")

    def part(t):
        return VRLocoVectorEnv(2, task="approach", technique=t, max_episode_steps=60)

    alone = [part(t) for t in techniques]
    mix = MixedUsersEnv([part(t) for t in techniques], list(techniques))
    teacher = scripted_teacher("goal_seeker", mix, mixed_bodies=True)
    bodies = []
    for e in alone:
        if params_from_env(e) not in bodies:
            bodies.append(params_from_env(e))
    assert isinstance(teacher, BodyTeachers) and len(teacher.policies) == len(bodies) >= 2
    env = ScriptedPlusCorrection(mix, teacher, "goal_seeker")
    seekers = [_goal_seeker(e) for e in alone]
    obs = [e.reset(seed=11 + 2 * i)[0] for i, e in enumerate(alone)]
    seen, _ = env.reset(seed=11)
    width = alone[0].single_observation_space.shape[0]
    ends = 0
    for _ in range(150):  # past the 60-step time limit: autoresets included
        actions = [s.act(o) for s, o in zip(seekers, obs, strict=True)]
        np.testing.assert_array_equal(seen[:, width:], np.concatenate(actions))
        steps = [e.step(a) for e, a in zip(alone, actions, strict=True)]
        seen, reward, *_ = env.step(np.zeros((8, 5), np.float32))
        np.testing.assert_array_equal(reward, np.concatenate([s[1] for s in steps]))
        for s, (_, _, te, tr, _) in zip(seekers, steps, strict=True):
            if (te | tr).any():
                s.reset(rows=np.flatnonzero(te | tr))
            ends += int((te | tr).sum())
        obs = [s[0] for s in steps]
        np.testing.assert_array_equal(seen[:, :width], np.concatenate(obs))
    assert ends >= 8
    with pytest.raises(ValueError, match="different bodies"):
        scripted_teacher("goal_seeker", mix)


def test_dropping_users_keeps_the_rest_as_they_were():
    u, v = _users(), _users()
    full = ScriptedPlusCorrection(u, _goal_seeker(u), "goal_seeker")
    part = ScriptedPlusCorrection(v, _goal_seeker(v), "goal_seeker")
    a, _ = full.reset(seed=2)
    b, _ = part.reset(seed=2)
    correction = np.random.default_rng(0).uniform(-0.2, 0.2, (60, 4, 5)).astype(np.float32)
    for t in range(30):
        a, *_ = full.step(correction[t])
        b, *_ = part.step(correction[t])
    assert part.can_take_users
    part.take_users(np.array([3, 1]))
    for t in range(30, 60):
        a, ra, *_ = full.step(correction[t])
        b, rb, *_ = part.step(correction[t][[3, 1]])
        np.testing.assert_array_equal(b, a[[3, 1]])
        np.testing.assert_array_equal(rb, ra[[3, 1]])


def test_the_correction_reaches_every_action_from_every_scripted_action():
    scripted = np.array([-1.0, 0.5, 1.0, 0.0, -0.3], np.float32)
    for target in np.linspace(-1.0, 1.0, 9):
        correction = (target - scripted) / RESIDUAL_SCALE
        assert np.abs(correction).max() <= 1.0
        np.testing.assert_allclose(combine(scripted[None], correction[None])[0], target, atol=1e-6)
    # out of range: the correction is clipped to [-1, 1], then the action to the box
    np.testing.assert_array_equal(
        combine(np.array([[0.5, -0.5, 0, 0, 0]]), np.array([[-9.0, 0.1, 0, 0, 0]])),
        np.array([[-1.0, -0.3, 0, 0, 0]], np.float32),
    )


@pytest.fixture(scope="module")
def uncorrected(tmp_path_factory):
    """A model trained with residual_on but a learning rate of 0: its correction stays zero."""
    out = tmp_path_factory.mktemp("residual")
    with pytest.MonkeyPatch.context() as patch:  # a short value fit: the test is of the policy
        patch.setattr("agents.learned.train.VALUE_STEPS", 256)
        return _train(out)


def _train(out):
    return train_ppo(
        "approach",
        steps=256,
        num_envs=4,
        n_steps=64,
        batch_size=64,
        learning_rate=0.0,
        frame_stack=2,
        out_dir=out,
        progress=False,
        eval_every=10**6,
        eval_episodes=2,
        residual_on="goal_seeker",
        population="typical",
    )


def test_a_model_with_no_correction_plays_as_the_goal_seeker(uncorrected):
    import json

    from agents.benchmark.policies import LearnedPolicy, load_ppo

    model = load_ppo(uncorrected)
    policy = {"frame_stack": 2, "recurrent": False, "residual_on": "goal_seeker"}
    assert model.vrloco_policy == policy
    assert model.vrloco_observation[-1]["name"] == "goal_seeker_action"
    warmup = json.loads((uncorrected.parent / "values.json").read_text())
    assert warmup["scripted_user"] == "goal_seeker" and warmup["steps"] == 256
    env, alone = _users(3), _users(3)
    learned, seeker = LearnedPolicy(uncorrected, env), _goal_seeker(alone)
    obs, _ = env.reset(seed=9)
    alone.reset(seed=9)
    learned.reset()
    for _ in range(120):
        action = learned.act(obs)
        np.testing.assert_array_equal(action, seeker.act(obs))
        obs, _, term, trunc, _ = env.step(action)
        alone.step(action)
        done = np.flatnonzero(term | trunc)
        if done.size:
            learned.reset(rows=done)
            seeker.reset(rows=done)


def test_an_unknown_scripted_user_in_a_model_is_named(uncorrected, tmp_path):
    from agents.benchmark.policies import LearnedPolicy, load_ppo

    model = load_ppo(uncorrected)
    model.vrloco_policy = {**model.vrloco_policy, "residual_on": "nobody"}
    model.save(tmp_path / "odd")
    with pytest.raises(ValueError, match=r"corrects the scripted user 'nobody'.*goal_seeker"):
        LearnedPolicy(tmp_path / "odd.zip", _users(1))


def test_going_on_from_a_model_needs_the_same_scripted_user(uncorrected, tmp_path):
    with pytest.raises(ValueError, match=r"residual_on='goal_seeker', this run has None"):
        train_ppo(
            "approach",
            steps=256,
            num_envs=4,
            frame_stack=2,
            out_dir=tmp_path,
            progress=False,
            population="typical",
            init=uncorrected,
        )


def test_an_adapted_copy_still_corrects_its_scripted_user(uncorrected, tmp_path, monkeypatch):
    from agents.benchmark.policies import LearnedPolicy, load_ppo
    from agents.learned import adapt
    from agents.learned.users import LearnedUser

    monkeypatch.setattr(
        "agents.learned.users.shipped_user", lambda task: LearnedUser(task, str(uncorrected))
    )
    path = adapt.adapted_user(
        "approach",
        "smooth",
        "typical",
        steps=256,
        cache_dir=tmp_path,
        num_envs=4,
        variability="typical",
    )
    model = load_ppo(path)
    assert model.vrloco_policy["residual_on"] == "goal_seeker"
    assert model.vrloco_cell["technique"] == "smooth"
    env = VRLocoVectorEnv(2, task="approach", technique="smooth", population="typical")
    obs, _ = env.reset(seed=1)
    assert LearnedPolicy(path, env).act(obs).shape == (2, 5)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"residual_on": "nobody"}, "not a scripted user; choose from .*goal_seeker"),
        ({"residual_on": "goal_seeker", "recurrent": True}, "feed-forward"),
        ({"residual_on": "goal_seeker", "imitate": "goal_seeker"}, "drop imitate"),
        ({"residual_on": "goal_seeker", "env_workers": 2}, "env_workers=1"),
    ],
)
def test_train_refuses_a_correction_it_cannot_learn(tmp_path, kwargs, match):
    with pytest.raises(ValueError, match=match):
        train_ppo("approach", steps=64, num_envs=1, out_dir=tmp_path, progress=False, **kwargs)


def test_the_value_fit_counts_the_scripted_users_episodes_and_leaves_the_policy_alone():
    import torch

    from agents.learned.residual import fit_values, zero_correction
    from agents.learned.train import SB3VecEnv, make_model

    users = VRLocoVectorEnv(4, task="approach", max_episode_steps=25)
    env = ScriptedPlusCorrection(users, _goal_seeker(users), "goal_seeker")
    model = make_model(SB3VecEnv(env), seed=0, n_steps=64, batch_size=64)
    zero_correction(model)
    actor = [p.detach().clone() for p in model.policy.mlp_extractor.policy_net.parameters()]
    critic = [p.detach().clone() for p in model.policy.value_net.parameters()]
    report = fit_values(model, env, 400, seed=3)
    # 4 users x 100 steps, every episode cut at 25 steps (too short to reach the goal)
    assert report["steps"] == 400 and report["episodes"] == 16
    assert 0.0 <= report["success_rate"] <= 1.0
    kept = zip(actor, model.policy.mlp_extractor.policy_net.parameters(), strict=True)
    for before, after in kept:
        torch.testing.assert_close(before, after, rtol=0, atol=0)
    assert (model.policy.action_net.weight == 0).all() and (model.policy.action_net.bias == 0).all()
    fitted = zip(critic, model.policy.value_net.parameters(), strict=True)
    assert any(not torch.equal(b, a) for b, a in fitted)

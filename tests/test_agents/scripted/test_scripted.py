"""Scripted users and the human-variability wrapper: they read the observation, reach goals, pass
the Avoid obstacle, and vary reproducibly."""

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401  (registers the ids)
from agents.benchmark.variability import HumanVariability, VariabilityParams
from agents.scripted import (
    AvoidManoeuvre,
    GoalSeeker,
    ObservationLayout,
    ObsView,
    PolicyParams,
    ReactiveAvoider,
    free_lengths,
    make_policy,
    params_from_env,
)
from vrloco_env.config import EnvConfig
from vrloco_env.world import signed_distance


def run(env, policy, seed, steps=600, rng=None):
    """One episode; returns the last info, the virtual positions and the actions."""
    obs, info = env.reset(seed=seed)
    policy.reset(rng)
    positions, actions = [env.unwrapped.core.ep.position[0].copy()], []
    for _ in range(steps):
        a = policy.act(obs)
        actions.append(a)
        obs, _, terminated, truncated, info = env.step(a)
        positions.append(info["position"])
        if terminated or truncated:
            break
    return info, np.array(positions), np.array(actions)


def seeker_for(env):
    return GoalSeeker(ObservationLayout.from_env(env), params_from_env(env))


# --------------------------------------------------------------------------- observation


def test_the_policy_decodes_what_the_env_encodes():
    config = EnvConfig(ray_count=9, ray_fov_deg=120.0, ray_range_m=4.0)
    env = gym.make("VRLoco-Approach-v0", config=config)
    layout = ObservationLayout.from_env(env)
    np.testing.assert_allclose(layout.ray_offsets, env.unwrapped.core.ray_offsets)
    obs, info = env.reset(seed=3)
    obs, *_, info = env.step(np.array([0.0, 0.5, 0, 0, 0], np.float32))
    v = ObsView.decode(obs[None].astype(np.float64), layout)
    assert v.distance[0] == pytest.approx(info["distance_to_goal"], abs=1e-5)
    assert v.heading[0] == pytest.approx(info["virtual_yaw"], abs=1e-5)
    core = env.unwrapped.core  # the rays the env cast from the virtual pose
    np.testing.assert_allclose(v.rays[0], core.last_rays[0], atol=1e-5)
    goal = np.asarray(env.unwrapped.layout.goal)
    to_goal = goal - info["position"]
    bearing = np.arctan2(to_goal[1], to_goal[0]) - info["virtual_yaw"]
    assert np.angle(np.exp(1j * (v.bearing[0] - bearing))) == pytest.approx(0.0, abs=1e-5)


def test_free_lengths_against_hand_made_geometry():
    pts = np.array([[[2.0, 0.0], [0.1, 0.3]]])
    ok = np.array([[True, False]])
    angles = np.array([0.0, np.pi / 2, np.pi])
    free = free_lengths(pts, ok, angles, half_width=0.35, max_length=5.0)
    # ahead: the disc touches the point 0.35 m before it; sideways and behind: nothing
    np.testing.assert_allclose(free[0], [2.0 - 0.35, 5.0, 5.0])
    # a point nearer than the half width blocks only headings toward it
    ok[:] = [False, True]
    free = free_lengths(pts, ok, angles, half_width=0.35, max_length=5.0)
    assert free[0, 0] < 0.01  # ahead: it would come closer
    assert free[0, 2] == 5.0  # away from it: free
    # per-row angles
    free2 = free_lengths(pts, ok, angles[None, :], 0.35, 5.0)
    np.testing.assert_array_equal(free, free2)


def test_bad_observations_and_parameters_are_rejected():
    policy = GoalSeeker()
    with pytest.raises(ValueError, match=r"obs must have shape \(31,\)"):
        policy.act(np.zeros(10, np.float32))
    with pytest.raises(ValueError, match="finite"):
        policy.act(np.full(31, np.nan))
    with pytest.raises(ValueError, match=r"PolicyParams.walk=2.0: must be in \[0, 1\]"):
        PolicyParams(walk=2.0)
    with pytest.raises(ValueError, match="stop_deg"):
        PolicyParams(go_deg=30.0, stop_deg=10.0)
    with pytest.raises(ValueError, match="policy='teleport'"):
        make_policy("teleport")
    with pytest.raises(ValueError, match="away_deg"):
        AvoidManoeuvre(away_deg=120.0)


# --------------------------------------------------------------------------- behaviour


@pytest.mark.parametrize(("task", "seeds"), [("approach", (0, 1, 2)), ("avoid", (0, 1))])
def test_the_goal_seeker_reaches_the_goal_without_collisions(task, seeds):
    env = gym.make(f"VRLoco-{task.capitalize()}-v0")
    policy = seeker_for(env)
    for seed in seeds:
        info, positions, _ = run(env, policy, seed)
        assert info["is_success"] and info["collisions"] == 0, seed
        assert info["distance_to_goal"] == 0.0
        # it went around what stood in the way: never closer than the avatar to any solid
        layout = env.unwrapped.layout
        assert signed_distance(layout, positions).min() > layout.avatar_radius


def test_the_goal_seeker_holds_the_hand_on_the_interact_target():
    # Seed 2's pedestal faces the Kinect (the user ends turned about 30 deg from it); at seeds 0, 1
    # and 3 the user faces 134-172 deg away at the pedestal, past KinectSpec.facing_lost_deg, where
    # the Kinect does not see the user and no hand can be held.
    env = gym.make("VRLoco-Interact-v0")
    policy = seeker_for(env)
    info, _, actions = run(env, policy, seed=2)
    assert info["is_success"]  # reached the pedestal and held the hand for the dwell time
    assert info["hand_error_deg"] < env.unwrapped.core.task.config.hand_tolerance_deg
    assert np.any(actions[:, 2:] != 0.0)  # the hand moved, under proportional control


def test_the_avoid_manoeuvre_turns_away_passes_the_obstacle_and_turns_back():
    env = gym.make("VRLoco-Avoid-v0")
    policy = AvoidManoeuvre(ObservationLayout.from_env(env), params_from_env(env))
    info, positions, _ = run(env, policy, seed=0)
    assert info["is_success"] and info["collisions"] == 0
    obstacle = env.unwrapped.layout.obstacles[0]
    beside = np.abs(positions[:, 0] - obstacle.center[0]) < 0.3
    # it passed the obstacle well to one side ...
    assert np.all(np.abs(positions[beside, 1] - obstacle.center[1]) > 0.5)
    # ... and walked on parallel to the corridor: the original heading again
    assert abs(info["virtual_yaw"]) < np.deg2rad(10.0)


def test_the_reactive_avoider_does_not_collide():
    env = gym.make("VRLoco-Approach-v0")
    policy = ReactiveAvoider(ObservationLayout.from_env(env), params_from_env(env))
    info, _, _ = run(env, policy, seed=1, steps=200)
    assert info["collisions"] == 0


def test_a_batch_of_observations_gives_the_single_actions():
    envs = [gym.make("VRLoco-Approach-v0") for _ in range(3)]
    batch = GoalSeeker(ObservationLayout.from_env(envs[0]))
    singles = [GoalSeeker(ObservationLayout.from_env(e)) for e in envs]
    obs = np.stack([e.reset(seed=10 + i)[0] for i, e in enumerate(envs)])
    batch.reset()
    for p in singles:
        p.reset()
    for _ in range(40):
        a = batch.act(obs)
        for i, p in enumerate(singles):
            np.testing.assert_array_equal(a[i], p.act(obs[i]))
        obs = np.stack([e.step(a[i])[0] for i, e in enumerate(envs)])


# --------------------------------------------------------------------------- variability


class Scripted:
    """A stub user: turns +1 for ``turn_steps`` control steps, then stands, walking at 0.5;
    echoes obs[0] as its hand yaw rate so that delays are visible."""

    name = "stub"

    def __init__(self, turn_steps=10, turn=1.0):
        self.turn_steps, self.turn = turn_steps, turn

    def reset(self, rng=None, rows=None):
        self.k = 0

    def act(self, obs):
        o = np.atleast_2d(obs)
        turn = self.turn if self.k < self.turn_steps else 0.0
        self.k += 1
        a = np.zeros((o.shape[0], 5), np.float32)
        a[:, 0], a[:, 1], a[:, 2] = 0.5, turn, o[:, 0]
        return a[0] if np.ndim(obs) == 1 else a


QUIET = {
    "reaction_delay_sd_s": 0.0,
    "overshoot": 0.0,
    "overshoot_sd": 0.0,
    "cadence_bias_sd": 0.0,
    "cadence_jitter_sd": 0.0,
}


def test_the_reaction_delay_shows_the_policy_old_observations():
    user = HumanVariability(Scripted(0), VariabilityParams(**{**QUIET, "reaction_delay_s": 0.3}))
    user.reset(np.random.default_rng(0))
    assert user.delay_steps.tolist() == [3]
    seen = [user.act(np.full(29, k / 100.0))[2] for k in range(8)]
    # steps 0-3 see the first observation, then the one of 3 steps before
    np.testing.assert_allclose(seen, [0, 0, 0, 0, 0.01, 0.02, 0.03, 0.04], atol=1e-7)


def test_a_turn_bout_overshoots_by_the_drawn_fraction():
    params = VariabilityParams(**{**QUIET, "reaction_delay_s": 0.0, "overshoot": 0.2})
    user = HumanVariability(Scripted(turn_steps=10), params)
    user.reset(np.random.default_rng(0))
    turns = np.array([user.act(np.zeros(29))[1] for _ in range(20)])
    np.testing.assert_allclose(turns[:10], 1.0)
    # 0.2 x 10 action-steps of extra turn, at the overshoot rate of 0.5 per step, then still
    np.testing.assert_allclose(turns[10:14], 0.5)
    np.testing.assert_allclose(turns[14:], 0.0)
    # a short correction (below min_bout) does not overshoot
    user = HumanVariability(Scripted(turn_steps=1, turn=0.3), params)
    user.reset(np.random.default_rng(0))
    turns = np.array([user.act(np.zeros(29))[1] for _ in range(5)])
    np.testing.assert_allclose(turns, [0.3, 0, 0, 0, 0], atol=1e-7)


def test_cadence_varies_around_each_users_own_pace():
    params = VariabilityParams(**{**QUIET, "cadence_bias_sd": 0.1, "cadence_jitter_sd": 0.05})
    user = HumanVariability(Scripted(0), params)
    user.reset(np.random.default_rng(5))
    walks = np.array([user.act(np.zeros(29))[0] for _ in range(400)])
    assert np.all(walks > 0.0)  # jitter never stops a walking user
    ratio = walks / 0.5
    assert ratio.mean() == pytest.approx(1.0 + user.cadence_bias[0], abs=0.015)
    assert ratio.std() == pytest.approx(0.05, rel=0.2)


def test_the_wrapper_is_seeded_and_batches_like_single_users():
    env = gym.make("VRLoco-Approach-v0")

    def actions(seed):
        user = HumanVariability(seeker_for(env))
        _, _, a = run(env, user, seed=4, steps=60, rng=np.random.default_rng(seed))
        return a

    a1, a2, b = actions(1), actions(1), actions(2)
    np.testing.assert_array_equal(a1, a2)
    assert not np.array_equal(a1, b)
    # two users in one batch draw exactly what two single users draw
    obs = np.random.default_rng(0).uniform(-1, 1, (30, 29)).astype(np.float32)
    batch = HumanVariability(Scripted(5))
    batch.reset([np.random.default_rng(7), np.random.default_rng(8)])
    out = np.stack([batch.act(np.stack([o, o])) for o in obs])
    for i, s in enumerate((7, 8)):
        single = HumanVariability(Scripted(5))
        single.reset(np.random.default_rng(s))
        np.testing.assert_array_equal(out[:, i], np.stack([single.act(o) for o in obs]))


def test_the_wrapper_needs_a_generator():
    user = HumanVariability(Scripted())
    with pytest.raises(ValueError, match="needs rng"):
        user.reset()
    with pytest.raises(RuntimeError, match="reset"):
        user.act(np.zeros(29))
    with pytest.raises(ValueError, match="reaction_delay_s"):
        VariabilityParams(reaction_delay_s=-1.0)


@pytest.mark.parametrize(
    ("task", "spec"),
    [
        ("approach", "goal_seeker+typical"),
        ("avoid", "goal_seeker"),
        ("avoid", "avoid_manoeuvre+human"),
        ("approach", "reactive_avoider"),
    ],
)
def test_a_policy_that_drops_users_acts_for_the_kept_ones_as_before(task, spec):
    """After 30 steps of 7 users a copy of the policy keeps users 5, 0, 3, 6: on their rows of
    the next observations it gives their rows of the whole batch's actions, to the bit; nothing
    in it is 7 long any more, and its reset and active mask take the new size."""
    import copy

    from _batch_walk import sized
    from gymnasium.vector import AutoresetMode

    from agents.benchmark.policies import build_policy
    from vrloco_env.vector import VRLocoVectorEnv

    b, rows = 7, np.array([5, 0, 3, 6])
    env = VRLocoVectorEnv(
        b,
        task=task,
        technique="zhang2021",
        population="typical",
        autoreset_mode=AutoresetMode.DISABLED,
    )
    whole = build_policy(spec, env)
    obs, _ = env.reset(seed=list(range(b)))
    whole.reset([np.random.default_rng([s, 1]) for s in range(b)], None)
    for _ in range(30):
        obs, *_ = env.step(whole.act(obs))
    kept = copy.deepcopy(whole)
    kept.take_users(rows)
    assert not sized(kept, b, "policy"), sized(kept, b, "policy")
    for t in range(80):
        if t == 40:  # whole rows 0 and 6 start anew: kept rows 1 and 3; kept row 2 idles
            whole.reset([np.random.default_rng([s, 2]) for s in (0, 6)], np.array([0, 6]))
            kept.reset([np.random.default_rng([s, 2]) for s in (0, 6)], np.array([1, 3]))
            kept.set_active(np.array([True, True, False, True]))
        a = whole.act(obs)
        live = [0, 1, 3] if t >= 40 else slice(None)
        np.testing.assert_array_equal(kept.act(obs[rows])[live], a[rows][live], err_msg=f"{t}")
        obs, *_ = env.step(a)
    env.close()

"""The play area of a walking-in-place user: validation, drift against the motion model's truth,
determinism, batch == single envs, and the boundary metrics."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from agents.benchmark.wip_measures import play_area_measures
from vrloco_env.config import EnvConfig
from vrloco_env.env import VRLocoEnv
from vrloco_env.user.play_area import PlayArea
from vrloco_env.user.population import POPULATIONS, RANGE_FIELDS, Population
from vrloco_env.vector import VRLocoVectorEnv

AREA_KEYS = ("play_area_position_m", "play_area_boundary_m", "play_area_outside")


def _action(env, walk: float, turn: float = 0.0) -> np.ndarray:
    a = np.zeros(env.action_space.shape, np.float32)
    a[0], a[1] = walk, turn
    return a


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"size_m": (0.5, 2.0)}, "size_m"),
        ({"size_m": (2.0, 11.0)}, "size_m"),
        ({"size_m": (2.0,)}, "size_m"),
        ({"lateral_ratio": -0.1}, "lateral_ratio"),
    ],
)
def test_bad_play_area_names_the_field(kwargs, field):
    with pytest.raises(ValueError, match=rf"^PlayArea\.{field}="):
        PlayArea(**kwargs)


def test_bad_drift_range_and_config_name_the_field():
    with pytest.raises(ValueError, match=r"^Population\.wip_drift_mps="):
        Population("x", "x", wip_drift_mps=(0.05, 0.01))
    with pytest.raises(ValueError, match=r"^EnvConfig\.play_area="):
        EnvConfig(play_area=(2.0, 2.0))  # type: ignore[arg-type]


def test_drift_is_drawn_last_and_only_some_populations_drift():
    assert RANGE_FIELDS[-2:] == ("wip_drift_mps", "wip_turn_deg_per_step")
    for name in ("idealised", "human"):
        assert POPULATIONS[name].wip_drift_mps == (0.0, 0.0)
        assert POPULATIONS[name].wip_turn_deg_per_step == (0.0, 0.0)
    for name in ("typical", "gaze_scanners", "nodders"):
        lo, hi = POPULATIONS[name].wip_drift_mps
        assert 0.0 < lo <= hi <= 0.1
        # Fukuda: under 30 deg in 50 steps and 45 deg in 100, either way
        lo, hi = POPULATIONS[name].wip_turn_deg_per_step
        assert lo < 0.0 < hi and max(-lo, hi) * 100 <= 45.0 and max(-lo, hi) * 50 <= 30.0


def test_the_turning_drift_adds_to_the_asked_turn_while_stepping_in_place():
    """The drift is the body's, added to the turn the action asks for (which keeps its
    meaning): rate (deg/step) times cadence while stepping, nothing standing, never beyond
    the largest turn rate, and nothing for a user who walks for real."""
    from vrloco_env.batch_rng import BatchRng
    from vrloco_env.user import Intent
    from vrloco_env.user.behaviour import GazeBehaviour

    b, top = 4, np.deg2rad(120.0)
    asked = np.array([0.0, 0.3, -top, top])
    cadence = np.array([1.7, 2.0, 1.5, 0.0])

    def turn(**kw):
        g = GazeBehaviour("typical", BatchRng.from_seeds(range(b)), 0.1, np.zeros(3), **kw)
        g.reset()
        intent = Intent(
            cadence=cadence,
            turn_rate=asked,
            hand_rates=np.zeros((b, 3)),
            gesture_amplitude=np.zeros((b, 3)),
            gesture_frequency=np.full((b, 3), 0.5),
            lean=np.zeros(b),
        )
        out = g.intent(intent, np.zeros(b), np.zeros(b), np.full((b, 3), 5.0), np.zeros(b, bool))
        return np.asarray(out.turn_rate), g.values["wip_turn_deg_per_step"]

    got, rate = turn(max_turn_rate=top)
    assert np.all(rate != 0.0)
    want = np.clip(asked + np.deg2rad(rate) * cadence, -top, top)
    np.testing.assert_array_equal(got, want)
    assert got[3] == top  # standing: the asked turn, untouched
    assert abs(got[0] - np.deg2rad(rate[0]) * 1.7) < 1e-15
    np.testing.assert_array_equal(turn(walk_in_place=False)[0], asked)
    with pytest.raises(ValueError, match=r"GazeBehaviour max_turn_rate=0.0: must be in"):
        turn(max_turn_rate=0.0)


def test_stepping_in_place_turns_the_body_and_drifts_forward_in_the_env():
    """Open loop (the action asks for no turn), every user of the env turns by its drawn rate
    per step taken and its spot drifts forward (Grostern et al. 2021: all 16 healthy subjects
    slowly turned and drifted forward)."""
    n = 6
    envs = VRLocoVectorEnv(n, population="typical", max_episode_steps=400)
    envs.reset(seed=30)
    core = envs.core
    start = core.users.motion.base.copy()
    a = np.zeros((n, envs.single_action_space.shape[0]), np.float32)
    a[:, 0] = 0.5  # step in place at 1.7 steps/s, no turn
    steps = np.zeros(n)
    for k in range(150):
        _, _, te, tr, _ = envs.step(a)
        assert not (te | tr).any()
        if k == 0:
            yaw0 = core.last.motion.body_yaw[:, 0]  # 10 ms in: the facing at the start
        steps += core.last.motion.step.sum(axis=1)
    assert steps.min() >= 20
    rate = core.behaviour.values["wip_turn_deg_per_step"]
    assert np.all(rate != 0.0)
    turned = np.rad2deg(core.last.motion.body_yaw[:, -1] - yaw0)
    np.testing.assert_allclose(turned, rate * steps, atol=0.6)
    moved = core.users.motion.base - start
    forward = moved[:, 0] * np.cos(yaw0) + moved[:, 1] * np.sin(yaw0)
    assert np.all(forward > 0.0)


def test_boundary_distance_inside_on_the_edge_and_outside():
    area = PlayArea(size_m=(2.0, 4.0))
    xy = np.array([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0], [1.5, 0.0], [2.0, 3.0], [0.0, -1.5]])
    np.testing.assert_allclose(
        area.boundary_distance(xy), [1.0, 0.5, 0.0, -0.5, -np.hypot(1, 1), 0.5]
    )


def test_drift_moves_the_spot_along_the_facing_while_stepping_only():
    env = VRLocoEnv(population="typical")
    env.reset(seed=5)
    core = env.core
    users = core.users
    forward, lateral = users._drift[0]
    lo, hi = POPULATIONS["typical"].wip_drift_mps
    assert lo <= forward <= hi
    assert abs(lateral) <= core.config.play_area.lateral_ratio * forward
    assert forward == core.behaviour.values["wip_drift_mps"][0]
    # Step while turning, then stand: each step's shift is the drift rate times the time mid-step,
    # along the torso's facing at the step's end (the motion model's own state is the truth).
    total_stepping = 0.0
    for k in range(80):
        walk = 1.0 if k < 50 else -1.0
        before = users.motion.base
        _, _, _, _, info = env.step(_action(env, walk, 0.3 if k < 50 else 0.0))
        chunk = core.last.motion
        moved = users.motion.base - before
        stepping_s = chunk.walking[0].mean() * users.dt
        yaw = chunk.body_yaw[0, -1]
        facing = np.array([np.cos(yaw), np.sin(yaw)])
        left = np.array([-np.sin(yaw), np.cos(yaw)])
        np.testing.assert_allclose(
            moved[0], (forward * facing + lateral * left) * stepping_s, atol=1e-12
        )
        total_stepping += stepping_s
        if not chunk.walking[0].any():
            assert np.all(moved == 0.0)
        np.testing.assert_array_equal(info["play_area_position_m"], users.motion.base[0])
    assert total_stepping > 3.0  # it did step for seconds
    assert not chunk.walking.any()  # and stood still at the end
    dist = np.hypot(*users.motion.base[0])
    assert dist == pytest.approx(total_stepping * np.hypot(forward, lateral), rel=0.5)
    assert info["play_area_boundary_m"] == pytest.approx(
        core.config.play_area.boundary_distance(users.motion.base[0])
    )


def test_the_head_and_the_skeleton_move_with_the_spot():
    env = VRLocoEnv(population="typical")
    env.reset(seed=2)
    for _ in range(40):
        env.step(_action(env, 1.0))
    for _ in range(10):  # stand: the spot has moved, the head and skeleton stand over it
        env.step(_action(env, -1.0))
    chunk = env.core.last.motion
    base = env.core.users.motion.base[0]
    assert np.hypot(*base) > 0.02
    head = chunk.pos[0, -1, :2]
    spine = chunk.kinect.joints[0, -1, 0, :2]
    assert np.hypot(*(head - base)) < 0.25
    assert np.hypot(*(spine - base)) < 0.1


def test_an_idealised_user_does_not_drift():
    env = VRLocoEnv(population="idealised")
    env.reset(seed=4)
    for _ in range(30):
        _, _, _, _, info = env.step(_action(env, 1.0))
        np.testing.assert_array_equal(info["play_area_position_m"], [0.0, 0.0])
        assert info["play_area_boundary_m"] == 1.0 and not info["play_area_outside"]


def test_a_small_area_is_left_and_reported_outside():
    config = replace(EnvConfig(), population="typical", play_area=PlayArea(size_m=(0.8, 0.8)))
    env = VRLocoEnv(config=config)
    env.reset(seed=9)
    outside = []
    for _ in range(400):
        _, _, te, tr, info = env.step(_action(env, 1.0))
        outside.append(info["play_area_outside"])
        assert info["play_area_outside"] == (info["play_area_boundary_m"] < 0.0)
        if te or tr:
            break
    forward = env.core.users._drift[0, 0]
    if forward * len(outside) * env.core.dt > 0.6:  # at 0.5+ of stepping time it must be out
        assert any(outside)


def test_same_seed_same_play_area_track():
    tracks = []
    for _ in range(2):
        env = VRLocoEnv(population="nodders")
        env.reset(seed=11)
        tracks.append(
            [env.step(_action(env, 1.0, 0.2))[4]["play_area_position_m"] for _ in range(30)]
        )
    np.testing.assert_array_equal(np.array(tracks[0]), np.array(tracks[1]))
    assert np.hypot(*tracks[0][-1]) > 0.0


def test_vector_env_equals_single_envs_for_the_play_area():
    n, seed, steps = 3, 20, 25
    envs = VRLocoVectorEnv(n, population="gaze_scanners")
    envs.reset(seed=seed)
    single = [VRLocoEnv(population="gaze_scanners") for _ in range(n)]
    for i, e in enumerate(single):
        e.reset(seed=seed + i)
    rng = np.random.default_rng(0)
    for _ in range(steps):
        a = rng.uniform(-1, 1, (n, *single[0].action_space.shape)).astype(np.float32)
        a[:, 0] = np.abs(a[:, 0])
        _, _, _, _, info = envs.step(a)
        for i, e in enumerate(single):
            one = e.step(a[i])[4]
            for k in AREA_KEYS:
                np.testing.assert_array_equal(info[k][i], one[k], err_msg=k)
    assert np.any(info["play_area_position_m"] != 0.0)


def test_boundary_metrics_of_a_hand_built_episode():
    margin = np.array([0.5, 0.1, -0.05, -0.2, 0.1, 0.0, -0.01, 0.3])
    steps = {"play_area_boundary_m": margin, "play_area_outside": margin < 0.0}
    m = play_area_measures(steps)
    assert m == {"boundary_violations": 2.0, "min_boundary_m": -0.2}
    inside = {
        "play_area_boundary_m": np.array([1.0, 0.9]),
        "play_area_outside": np.array([False, False]),
    }
    assert play_area_measures(inside) == {"boundary_violations": 0.0, "min_boundary_m": 0.9}
    starts_out = {
        "play_area_boundary_m": np.array([-0.1, -0.2]),
        "play_area_outside": np.array([True, True]),
    }
    assert play_area_measures(starts_out)["boundary_violations"] == 1.0


def test_a_row_averages_the_episodes_play_area_measures():
    from agents.benchmark.metrics import episode_stats, summarize

    def episode(margin):
        margin = np.asarray(margin, dtype=np.float64)
        t = margin.size
        steps = {
            "true_steps": np.zeros(t),
            "detected_steps": np.zeros(t),
            "true_step_times": np.full((t, 2), np.inf),
            "detected_step_times": np.full((t, 2), np.inf),
            "attitude_error_deg": np.zeros(t),
            "hand_error_deg": np.full(t, np.nan),
            "heading_error_deg": np.zeros(t),
            "play_area_boundary_m": margin,
            "play_area_outside": margin < 0.0,
        }
        last = {"is_success": True, "collisions": 0, "elapsed_time": 0.1 * t, "walked": 1.0}
        return episode_stats(0, 1.0, steps, last)

    row = summarize([episode([0.5, -0.1, 0.2, -0.3]), episode([0.9, 0.8, 0.7, 0.6])])
    assert row["boundary_violations"] == pytest.approx(1.0)  # (2 + 0) / 2
    assert row["min_boundary_m"] == pytest.approx((-0.3 + 0.6) / 2)
    lo, hi = row["min_boundary_m_ci"]
    assert lo <= row["min_boundary_m"] <= hi

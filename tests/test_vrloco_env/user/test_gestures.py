"""The gestures of the hands-free techniques, performed by the simulated users, and the view
that follows the head."""

import math

import gymnasium as gym
import numpy as np

import vrloco_env  # noqa: F401
from vrloco_env.core import EYE_ABOVE_NECK_M

WALK = np.array([1.0, 0.0, 0.0, 0.0, 0.0], np.float32)
STAND = np.array([-1.0, 0.0, 0.0, 0.0, 0.0], np.float32)


def _play(env, actions):
    """Per step: true head pitch (deg), true steps, virtual displacement (m), walk yaw - true body
    yaw (deg) and the true hand yaw on the torso (deg)."""
    rows = []
    for a in actions:
        env.step(a)
        us = env.unwrapped.core.last
        rows.append(
            (
                math.degrees(us.ypr_true[0, 1]),
                float(us.true_steps[0]),
                float(np.hypot(*us.displacement[0])),
                math.degrees(us.walk_yaw[0] - us.true_body_yaw[0]),
                math.degrees(us.hand_true[0, 0]),
            )
        )
    return np.array(rows)


def test_a_head_tilt_user_tilts_instead_of_stepping_and_moves_at_the_tilts_speed():
    env = gym.make("VRLoco-Avoid-v0", technique="head_tilt")
    env.reset(seed=3)
    walk = _play(env, [WALK] * 40)
    stand = _play(env, [STAND] * 40)
    assert walk[:, 1].sum() == 0 and stand[:, 1].sum() == 0  # no step at all
    assert abs(walk[-1, 0] - 30.0) < 1.0  # walk = 1: the full-speed tilt (default 30 deg)
    np.testing.assert_allclose(walk[-5:, 2], 0.14, atol=0.01)  # 1.4 m/s at full tilt
    assert walk[:3, 2].max() < 0.01  # the head takes a moment to pass the dead zone
    assert abs(stand[-1, 0]) < 1.0 and stand[-5:, 2].max() == 0.0  # head up again: stopped


def test_a_look_down_user_looks_down_to_start_and_to_stop_and_walks_looking_ahead():
    env = gym.make("VRLoco-Avoid-v0", technique="look_down_to_move")
    env.reset(seed=4)
    walk = _play(env, [WALK] * 40)
    started = int(np.argmax(walk[:, 2] > 0.0))
    assert started >= 3 and walk[: started + 1, 0].max() >= 30.0  # looked past the threshold
    assert walk[-1, 0] < 5.0 and walk[-1, 2] > 0.13  # head back up, auto-walk at 1.4 m/s
    assert walk[:, 1].sum() == 0
    stand = _play(env, [STAND] * 40)
    stopped = int(np.argmax(stand[:, 2] == 0.0))
    assert stopped >= 3 and stand[: stopped + 1, 0].max() >= 30.0  # a second look down: stop
    assert stand[stopped:, 2].max() == 0.0


def test_a_hand_steering_user_walks_where_the_hand_points():
    env = gym.make("VRLoco-Avoid-v0", technique="hand_steering")
    env.reset(seed=5)
    point_left = np.array([-1.0, 0.0, 1.0, 0.0, 0.0], np.float32)  # hand yaw rate up, standing
    turned = _play(env, [point_left] * 4)
    walk = _play(env, [WALK] * 30)
    moving = walk[:, 2] > 0.0
    assert moving.sum() >= 4 and walk[:, 1].sum() > 4  # it steps in place (eq 17 jumps)
    hand = turned[-1, 4]
    assert hand > 20.0  # the hand points well left of the torso
    offset = (walk[moving, 3] + 180.0) % 360.0 - 180.0
    assert abs(np.median(offset) - hand) < 10.0  # and the walk follows it (estimate errors)


def test_the_view_sees_only_the_floor_near_the_feet_when_the_head_pitches_past_half_the_fov():
    env = gym.make("VRLoco-Avoid-v0")
    env.reset(seed=6)
    env.step(STAND)
    core = env.unwrapped.core
    level = core._rays()
    half = math.radians(core.config.view_vertical_fov_deg) / 2.0
    eye = core.config.motion.neck_height_m + EYE_ABOVE_NECK_M
    core.last.ypr_est[:, 1] = half - 0.01  # just inside: the horizon is still in view
    np.testing.assert_array_equal(core._rays(), level)
    core.last.ypr_est[:, 1] = half + math.radians(25.0)
    seen = eye / math.tan(math.radians(25.0))
    down = core._rays()
    near = level <= seen
    assert near.any() and (~near).any()
    np.testing.assert_array_equal(down[near], level[near])  # what is near stays in view
    assert (down[~near] == core.config.ray_range_m).all()  # the rest reads: nothing seen


def test_a_reset_user_sees_ahead_whatever_its_last_episode_ended_looking_at():
    env = gym.make("VRLoco-Avoid-v0")
    env.reset(seed=6)
    core = env.unwrapped.core
    first = core.last_rays.copy()
    env.step(STAND)
    level = core._rays()
    core.last.ypr_est[:, 1] = math.radians(80.0)  # the episode ended looking at the floor
    assert (core._rays() != level).any()
    env.reset(seed=6)
    np.testing.assert_array_equal(core.last_rays, first)  # the new episode's first view

"""The user side of a step: the estimated hand orientation against the truth, and the compiled
hand-frame arithmetic against closed forms. (Compiled against its uncompiled source:
``tests/kernel_cases/hand.py``.)"""

import gymnasium as gym
import numpy as np

import vrloco_env  # noqa: F401
from estimators import rotations as rot
from vrloco_env._hand_frame_numba import hand_relative_to_torso
from vrloco_env.tasks.interact import hand_error


def test_hand_relative_to_torso_follows_the_true_hand():
    env = gym.make("VRLoco-Interact-v0")
    env.reset(seed=3)
    errors = []
    for k in range(40):
        rates = np.array([0.0, 0.0, 0.3 * np.sin(k / 6), 0.2 * np.cos(k / 9), 0.4], np.float32)
        _, _, _, _, info = env.step(rates)
        errors.append(info["hand_error_deg"])
    # Facing the Kinect, the estimate follows the true hand within a few degrees.
    assert np.nanmedian(errors[10:]) < 8.0


def test_hand_relative_to_torso_removes_the_torso_heading(rng):
    # Camera = world and SDK wrist = hand frame: the result is the hand's orientation turned
    # by minus the torso's heading (that of the left-to-right shoulder line, -90 deg), so the
    # ZYX yaw drops by the heading and pitch and roll stay.
    b = 200
    ypr = np.stack(
        [rng.uniform(-np.pi, np.pi, b), rng.uniform(-1.4, 1.4, b), rng.uniform(-np.pi, np.pi, b)],
        axis=-1,
    )
    heading = rng.uniform(-np.pi, np.pi, b)
    right = rng.normal(size=(b, 3))
    left = right + np.stack(
        [np.cos(heading + np.pi / 2), np.sin(heading + np.pi / 2), rng.normal(0.0, 0.1, b)], axis=-1
    )
    valid = rng.random(b) > 0.1
    left[3, 1] = np.nan
    identity = np.array([1.0, 0.0, 0.0, 0.0])
    out = np.empty((b, 3))
    hand_relative_to_torso(b)(ypr, valid, left, right, identity, identity, out)
    ok = valid & np.isfinite(left).all(axis=-1)
    assert not ok[3] and np.isnan(out[~ok]).all()
    want = ypr.copy()
    want[:, 0] = rot.wrap_angle(ypr[:, 0] - heading)
    np.testing.assert_allclose(rot.angle_diff(out[ok], want[ok]), 0.0, atol=1e-9)


def test_hand_error_is_the_rotation_angle_between_the_orientations():
    rng = np.random.default_rng(0)
    est = rng.uniform(-np.pi, np.pi, (50, 3))
    est[::7] = np.nan
    target = rng.uniform(-1, 1, (50, 3))
    q = rot.quat_multiply(
        rot.quat_conjugate(rot.quat_from_ypr(target)), rot.quat_from_ypr(np.nan_to_num(est))
    )
    truth = np.where(np.isnan(est[:, 0]), np.nan, rot.rotation_angle(q))
    np.testing.assert_allclose(hand_error(est, target), truth, atol=1e-12)
    assert np.isnan(hand_error(est, target)[0])

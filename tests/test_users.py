"""The user side of a step: compiled hand-frame arithmetic against its numpy reference, and the
estimated hand orientation against the truth."""

import gymnasium as gym
import numpy as np

import vrloco_env  # noqa: F401
from estimators import rotations as rot
from vrloco_env.tasks.interact import hand_error


def test_hand_relative_to_torso_matches_reference_and_truth():
    env = gym.make("VRLoco-Interact-v0")
    env.reset(seed=3)
    users = env.unwrapped.core.users
    errors = []
    for k in range(40):
        rates = np.array([0.0, 0.0, 0.3 * np.sin(k / 6), 0.2 * np.cos(k / 9), 0.4], np.float32)
        _, _, _, _, info = env.step(rates)
        hand = env.unwrapped.core.last.hand
        np.testing.assert_allclose(users._hand_relative_to_torso(hand),
                                   users._hand_relative_reference(hand), atol=1e-12)  # fmt: skip
        errors.append(info["hand_error_deg"])
    # Facing the Kinect, the estimate follows the true hand within a few degrees.
    assert np.nanmedian(errors[10:]) < 8.0


def test_hand_error_is_the_rotation_angle_between_the_orientations():
    rng = np.random.default_rng(0)
    est = rng.uniform(-np.pi, np.pi, (50, 3))
    est[::7] = np.nan
    target = rng.uniform(-1, 1, (50, 3))
    q = rot.quat_multiply(rot.quat_conjugate(rot.quat_from_ypr(target)),
                          rot.quat_from_ypr(np.nan_to_num(est)))  # fmt: skip
    truth = np.where(np.isnan(est[:, 0]), np.nan, rot.rotation_angle(q))
    np.testing.assert_allclose(hand_error(est, target), truth, atol=1e-12)
    assert np.isnan(hand_error(est, target)[0])

"""The user side of a step: compiled hand-frame arithmetic against its numpy reference, and the
estimated hand orientation against the truth."""

import gymnasium as gym
import numpy as np

import vrloco_env  # noqa: F401
from vrloco_env.tasks import hand_error, hand_error_reference


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


def test_hand_error_kernel_matches_reference():
    rng = np.random.default_rng(0)
    est = rng.uniform(-np.pi, np.pi, (50, 3))
    est[::7] = np.nan
    target = rng.uniform(-1, 1, (50, 3))
    np.testing.assert_allclose(hand_error(est, target), hand_error_reference(est, target),
                               atol=1e-12)  # fmt: skip
    assert np.isnan(hand_error(est, target)[0])

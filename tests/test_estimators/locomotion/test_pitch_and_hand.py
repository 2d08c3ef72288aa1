"""Head tilt, look down to move and hand steering: their laws against closed forms."""

import math

import numpy as np
import pytest

from estimators.locomotion import (
    HandSteering,
    HeadTilt,
    HeadTiltParams,
    LookDownParams,
    LookDownToMove,
)
from estimators.stages import LOCOMOTION, STEERING


def test_head_tilt_speed_follows_the_pitch_past_the_dead_zone():
    params = HeadTiltParams(dead_zone_deg=10.0, full_speed_deg=30.0, max_speed_mps=1.4)
    pitch_deg = np.array([-20.0, 0.0, 10.0, 15.0, 20.0, 30.0, 44.0])
    model = HeadTilt(pitch_deg.size, params=params, heading=0.0)
    dt = 0.1
    for _ in range(10):
        pos = model.update(
            np.zeros(pitch_deg.size), np.zeros(pitch_deg.size), dt, pitch=np.deg2rad(pitch_deg)
        )
    expected = 1.4 * np.clip((pitch_deg - 10.0) / 20.0, 0.0, 1.0)
    np.testing.assert_allclose(model.speed, expected, rtol=1e-12)
    np.testing.assert_allclose(pos[:, 0], expected * 1.0, rtol=1e-12)  # 10 updates of 0.1 s
    np.testing.assert_allclose(pos[:, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(model.distance, expected, rtol=1e-12)


def test_head_tilt_walks_along_the_mean_yaw_of_each_interval():
    model = HeadTilt(1, heading=0.0)
    pos = model.update([0.0], [math.pi / 2], 1.0, pitch=[math.radians(40.0)])
    np.testing.assert_allclose(
        pos[0], 1.4 * np.array([math.cos(math.pi / 4), math.sin(math.pi / 4)])
    )


def test_look_down_toggles_once_per_look_and_rearms_above_the_rearm_pitch():
    model = LookDownToMove(
        1, params=LookDownParams(threshold_deg=30.0, rearm_deg=20.0, speed_mps=1.0)
    )
    seq = [0, 31, 35, 25, 31, 15, 30, 0, 45]
    walking = []
    for p in seq:
        model.update([0.0], [0.0], 0.1, pitch=[math.radians(p)])
        walking.append(bool(model.walking[0]))
    # toggles at 31 (start), not again at 35 or 31 (not re-armed above 20), re-arms at 15,
    # toggles at 30 (stop), re-arms at 0, toggles at 45 (start)
    assert walking == [False, True, True, True, True, True, False, False, True]
    moving_updates = sum(walking)
    np.testing.assert_allclose(model.distance, 0.1 * moving_updates)


def test_pitch_driven_models_name_a_missing_or_bad_pitch():
    model = HeadTilt(2)
    with pytest.raises(ValueError, match="needs pitch="):
        model.update(np.zeros(2), np.zeros(2), 0.1)
    with pytest.raises(ValueError, match=r"pitch=3.0: must be in \[-pi/2, pi/2\] rad"):
        model.update(np.zeros(2), np.zeros(2), 0.1, pitch=[0.0, 3.0])
    with pytest.raises(ValueError, match="pitch contains NaN"):
        model.update(np.zeros(2), np.zeros(2), 0.1, pitch=[np.nan, 0.0])
    with pytest.raises(ValueError, match=r"full_speed_deg=5.0: must be in \(10"):
        HeadTiltParams(dead_zone_deg=10.0, full_speed_deg=5.0)
    with pytest.raises(ValueError, match=r"rearm_deg=30.0: must be in \[0, 30"):
        LookDownParams(threshold_deg=30.0, rearm_deg=30.0)


def test_hand_steering_adds_the_hand_to_the_torso_and_falls_back_on_torso_then_head():
    steer = HandSteering(4)
    head = np.array([0.1, 0.2, 0.3, 0.4])
    torso = np.array([1.0, 1.0, 1.0, 3.0])
    valid = np.array([True, True, False, True])
    hand = np.array([0.5, np.nan, 0.5, 0.5])
    yaw = steer.update(head, torso, valid, hand_yaw=hand)
    np.testing.assert_allclose(yaw, [1.5, 1.0, 0.3, 3.5 - 2 * math.pi])
    with pytest.raises(ValueError, match="needs hand_yaw="):
        steer.update(head, torso, valid)


def test_the_stages_are_registered_with_their_gestures():
    from estimators.locomotion.gestures import LookDownToToggle, PointToSteer, TiltToMove

    assert isinstance(LOCOMOTION.build("head_tilt", 2, 0.7).gesture, TiltToMove)
    assert isinstance(LOCOMOTION.build("look_down_to_move", 2, 0.7).gesture, LookDownToToggle)
    assert isinstance(STEERING.build("hand", 2).gesture, PointToSteer)

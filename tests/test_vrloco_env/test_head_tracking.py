"""The visual-inertial tracker's composition: camera triggers, PnP on frames, fused pose."""

import numpy as np
import pytest

from estimators import rotations as rot
from estimators.head_pose.visual_inertial import VioConfig
from vrloco_env.batch_rng import BatchRng
from vrloco_env.head_tracking import VisualInertialTracker, frame_triggers
from vrloco_env.sensors.camera import camera_spec, layout_landmarks
from vrloco_env.sensors.imu import HeadImu
from vrloco_env.tasks import make_layout
from vrloco_env.user import Intent, MotionParams, UserMotion
from vrloco_env.world import RoomConfig


def test_frame_triggers_keep_the_camera_rate_on_the_imu_clock():
    # 120 Hz beside 1 kHz: 120 frames per second, 8 or 9 samples apart, whatever the chunking.
    whole = frame_triggers(0, 1000, 1000.0, 120.0)
    assert whole.size == 120 and set(np.diff(whole)) == {8, 9}
    chunks = [frame_triggers(s, 100, 1000.0, 120.0) + s for s in range(0, 1000, 100)]
    chunks = np.concatenate(chunks)
    np.testing.assert_array_equal(chunks, whole)
    # 30 Hz beside 100 Hz, 10 samples per control step: the same offsets in every step.
    steps = [tuple(frame_triggers(10 * k, 10, 100.0, 30.0)) for k in range(50)]
    assert set(steps) == {(3, 6, 9)}


@pytest.mark.parametrize(("condition", "available"), [("ideal", 0.8), ("low_light", 0.6)])
def test_tracker_follows_a_walking_head_better_than_its_camera(condition, available):
    layout = make_layout("approach", RoomConfig(), np.random.default_rng(0)).with_origin((0, 0))
    points, normals = layout_landmarks(layout)
    rng = BatchRng.from_seeds([3, 4])
    motion = UserMotion(MotionParams(imu_rate_hz=200.0, overground=True), rng)
    motion.reset(yaw=[0.0, np.pi / 2], base=[(-1.0, -2.5), (2.5, -1.0)])
    imu = HeadImu("ig500n", rng, rate_hz=200.0)
    tracker = VisualInertialTracker(
        2, 200.0, camera_spec(condition, rate_hz=40.0), VioConfig(adaptive="sage_husa"), rng
    )
    for user in range(2):
        tracker.set_landmarks(user, points, normals)
    pos_err, att_err, cam_err, poses = [], [], [], np.zeros(2)
    for k in range(150):  # 15 s: stand 1 s, then walk a circle
        walking = k >= 10
        chunk = motion.advance(
            Intent(cadence=1.6 if walking else 0.0, turn_rate=0.4 if walking else 0.0)
        )
        s = imu.sample(chunk.quat, chunk.omega, chunk.acc, chunk.pos)
        if k == 0:
            tracker.reset(None, chunk.pos[:, 0], chunk.quat[:, 0])
        out = tracker.step(chunk.t, s.gyr, s.acc, chunk.pos, chunk.quat, chunk.omega)
        pos_err.append(np.linalg.norm(out.position - chunk.pos, axis=-1))
        q_err = rot.quat_multiply(rot.quat_conjugate(chunk.quat), out.quat)
        att_err.append(np.rad2deg(rot.rotation_angle(q_err)))
        ok = out.poses.ok
        poses += ok.sum(axis=1)
        truth = chunk.pos[:, out.frame_sample]
        cam_err.append(np.linalg.norm(out.poses.position - truth, axis=-1)[ok])
    pos_err = np.concatenate(pos_err, axis=1)
    cam = np.concatenate(cam_err)
    rms = np.sqrt(np.mean(pos_err**2))
    assert cam.size > available * 2 * 15 * 40  # most frames gave a pose
    assert rms < 0.05 and rms < np.sqrt(np.mean(cam**2))
    assert np.sqrt(np.mean(np.concatenate(att_err, axis=1) ** 2)) < 1.0
    # The filter took most poses (its gate refuses the gross PnP errors and some noisy ones).
    assert np.all(tracker.filter.updates > 0.7 * poses)


def test_tracker_rejects_a_camera_faster_than_the_imu():
    with pytest.raises(ValueError, match="must not exceed the IMU rate"):
        VisualInertialTracker(
            1, 100.0, camera_spec("ideal", rate_hz=120.0), VioConfig(), BatchRng.from_seeds([0])
        )

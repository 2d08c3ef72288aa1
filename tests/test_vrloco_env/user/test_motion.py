"""The user motion model against its own physics and the numbers it promises."""

import numpy as np
import pytest

from estimators import rotations as rot
from vrloco_env.batch_rng import BatchRng
from vrloco_env.user import (
    BONES,
    SCRIPTS,
    Intent,
    Joint,
    MotionParams,
    MotionRecord,
    UserMotion,
    run_script,
    script_intents,
)


def specific_force_norm_g(rec: MotionRecord) -> np.ndarray:
    f = rot.quat_rotate_inverse(rec.quat, rec.acc - np.array([0.0, 0.0, -rot.GRAVITY]))
    return np.linalg.norm(f, axis=-1) / rot.GRAVITY


def walk(cadence: float, seconds: float = 12.0, seeds=(0,), **params) -> MotionRecord:
    p = MotionParams(**params)
    m = UserMotion(p, BatchRng.from_seeds(seeds))
    m.reset()
    n = round(seconds * p.control_rate_hz)
    return MotionRecord.concatenate([m.advance(Intent(cadence=cadence)) for _ in range(n)])


@pytest.mark.parametrize("cadence", [1.2, 1.7, 2.2])
def test_stepping_peaks_and_step_events_match_cadence(cadence):
    rec = walk(cadence, seeds=(0, 1, 2))
    fn = specific_force_norm_g(rec)
    peaks = fn.max(axis=1)
    assert np.all((peaks > 1.08) & (peaks < 1.6)), peaks
    for times in rec.step_times:
        assert abs(len(times) - cadence * 12.0) <= 1
        np.testing.assert_allclose(np.diff(times), 1.0 / cadence, rtol=1e-9)
    # The |f| peak of each step sits at its heel strike (within one IMU sample).
    x = fn[0]
    peak = (x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:]) & (x[1:-1] > 1.05)
    t_peaks = rec.t[1:-1][peak]
    assert t_peaks.size == rec.step_times[0].size
    np.testing.assert_allclose(t_peaks, rec.step_times[0], atol=0.0101)
    bob = np.ptp(rec.pos[:, 200:, 2], axis=1)
    assert np.all((bob > 0.01) & (bob < 0.05)), bob


def test_acceleration_is_the_second_derivative_of_position():
    rec = walk(1.8, seconds=4.0, imu_rate_hz=1000.0)
    dt = 1e-3
    acc_fd = (rec.pos[:, 2:] - 2 * rec.pos[:, 1:-1] + rec.pos[:, :-2]) / dt**2
    err = np.abs(acc_fd - rec.acc[:, 1:-1])
    assert np.percentile(err, 99) < 0.05  # m/s^2, on peaks of ~4 m/s^2
    # Position and velocity are continuous across control steps (no jumps).
    v = np.diff(rec.pos, axis=1) / dt
    assert np.abs(np.diff(v, axis=1)).max() < 0.02


def test_integrating_true_rate_reproduces_orientation():
    rec = run_script("serpentine", BatchRng.from_seeds([5]), MotionParams(imu_rate_hz=1000.0))
    q = rec.quat[:, 0]
    dt = 1e-3
    for k in range(1, rec.t.size):
        # Midpoint rate over each interval: second-order accurate.
        q = rot.quat_integrate(q, 0.5 * (rec.omega[:, k - 1] + rec.omega[:, k]), dt)
    err = rot.rotation_angle(rot.quat_multiply(rot.quat_conjugate(q), rec.quat[:, -1]))
    assert np.rad2deg(err).max() < 0.01


def test_a_step_is_finished_before_standing():
    p = MotionParams()
    m = UserMotion(p, BatchRng.from_seeds([0]))
    m.reset()
    chunks = [m.advance(Intent(cadence=1.5)) for _ in range(13)]  # 1.3 s: mid-step
    chunks += [m.advance(Intent()) for _ in range(20)]
    rec = MotionRecord.concatenate(chunks)
    assert rec.walking[0, 130]  # still finishing the step after the intent changed
    assert not rec.walking[0, -1]
    standing_height = MotionParams().neck_height_m + MotionParams().imu_offset_m[2]
    np.testing.assert_allclose(rec.pos[0, -1, 2], standing_height, atol=1e-12)
    assert len(rec.step_times[0]) == 2  # 1.3 s at 1.5 Hz started two steps; both finish


def test_turning_and_scripts_reach_their_headings():
    spin = run_script("spin", BatchRng.from_seeds([0]))
    assert np.rad2deg(spin.ypr[0, -1, 0]) == pytest.approx(360.0, abs=1.0)
    avoid = run_script("avoid", BatchRng.from_seeds([0]))
    yaw = np.rad2deg(avoid.ypr[0, :, 0])
    assert yaw.max() == pytest.approx(45.0, abs=1.5)
    assert yaw[-1] == pytest.approx(0.0, abs=1.0)
    for name in ("serpentine", "pitch", "shake"):
        rec = run_script(name, BatchRng.from_seeds([0]))
        assert len(rec.step_times[0]) == 0  # head-only motions: no steps
        fn = specific_force_norm_g(rec)
        assert np.abs(fn - 1.0).max() < 0.07  # far below a stepping peak


def test_all_scripts_run_and_unknown_name_is_rejected():
    for name in SCRIPTS:
        assert script_intents(name)
    with pytest.raises(ValueError, match="unknown motion script 'moonwalk'"):
        script_intents("moonwalk")


def test_skeleton_bones_are_rigid_and_hand_follows_its_orientation():
    p = MotionParams()
    m = UserMotion(p, BatchRng.from_seeds([0]))
    m.reset()
    chunks = [
        m.advance(Intent(cadence=1.6, turn_rate=0.3, hand_rates=(0.2, -0.1, 0.3)))
        for _ in range(30)
    ]
    kin = MotionRecord.concatenate(chunks).kinect
    assert kin.joints.shape == (1, 90, 25, 3) and kin.t.size == 90
    np.testing.assert_allclose(np.diff(kin.t), 1 / 30.0, atol=1e-12)
    # Bones above the knees keep their length (legs bend while stepping).
    rigid = [
        (a, b)
        for a, b in BONES
        if b
        not in (
            Joint.KNEE_LEFT,
            Joint.KNEE_RIGHT,
            Joint.ANKLE_LEFT,
            Joint.ANKLE_RIGHT,
            Joint.FOOT_LEFT,
            Joint.FOOT_RIGHT,
        )
    ]
    for a, b in rigid:
        length = np.linalg.norm(kin.joints[0, :, a] - kin.joints[0, :, b], axis=-1)
        assert np.ptp(length) < 1e-9, (a, b)
    tip = kin.joints[0, :, Joint.HAND_TIP_RIGHT] - kin.joints[0, :, Joint.WRIST_RIGHT]
    x_axis = rot.quat_rotate(kin.hand_quat[0], [1.0, 0.0, 0.0])
    np.testing.assert_allclose(
        tip / np.linalg.norm(tip, axis=-1, keepdims=True), x_axis, atol=1e-12
    )
    np.testing.assert_allclose(
        np.rad2deg(kin.hand_ypr[0, -1]), np.rad2deg([0.2, -0.1, 0.3]) * 3, atol=1e-9
    )
    # Knees lift alternately while stepping.
    kl = kin.joints[0, :, Joint.KNEE_LEFT, 2] - kin.joints[0, :, Joint.HIP_LEFT, 2]
    kr = kin.joints[0, :, Joint.KNEE_RIGHT, 2] - kin.joints[0, :, Joint.HIP_RIGHT, 2]
    assert np.ptp(kl) > 0.05 and np.ptp(kr) > 0.05
    assert np.all(np.minimum(kl - kl.min(), kr - kr.min()) < 1e-9)


def test_hand_is_held_within_its_limits():
    m = UserMotion(MotionParams(), BatchRng.from_seeds([0]))
    m.reset()
    rec = MotionRecord.concatenate(
        [m.advance(Intent(hand_rates=(3.0, 3.0, -3.0))) for _ in range(20)]
    )
    np.testing.assert_allclose(np.rad2deg(rec.kinect.hand_ypr[0, -1]), [90, 80, -90], atol=1e-9)


def test_same_seed_same_motion_and_batch_equals_singles():
    def run(seeds):
        m = UserMotion(MotionParams(), BatchRng.from_seeds(seeds))
        m.reset(yaw=0.3)
        return MotionRecord.concatenate(
            [m.advance(Intent(cadence=1.7, turn_rate=0.2)) for _ in range(30)]
        )

    batch = run([4, 9])
    again = run([4, 9])
    np.testing.assert_array_equal(batch.acc, again.acc)
    for i, seed in enumerate([4, 9]):
        single = run([seed])
        for name in ("quat", "omega", "pos", "acc", "step", "step_time"):
            np.testing.assert_array_equal(getattr(batch, name)[i], getattr(single, name)[0])
        np.testing.assert_array_equal(batch.kinect.joints[i], single.kinect.joints[0])
    assert not np.array_equal(batch.acc[0], batch.acc[1])  # users differ in style


@pytest.mark.parametrize(
    ("intent", "match"),
    [
        (Intent(cadence=0.5), r"Intent.cadence=0.5: must be 0 \(stand\) or in \[1.2, 2.2\]"),
        (Intent(turn_rate=10.0), r"Intent.turn_rate=10.0: must be in"),
        (Intent(hand_rates=(0.0, np.nan, 0.0)), "hand_rates contains NaN"),
        (Intent(cadence=[1.5, 1.5, 1.5]), r"cadence must broadcast to shape \(2,\)"),
    ],
)
def test_bad_intent_is_rejected_clearly(intent, match):
    m = UserMotion(MotionParams(), BatchRng.from_seeds([0, 1]))
    m.reset()
    with pytest.raises(ValueError, match=match):
        m.advance(intent)


def test_bad_params_and_order_are_rejected_clearly():
    with pytest.raises(ValueError, match=r"imu_rate_hz=5000.0: must be in \[10, 1000\]"):
        MotionParams(imu_rate_hz=5000.0)
    with pytest.raises(ValueError, match="a divisor of imu_rate_hz"):
        MotionParams(imu_rate_hz=100.0, control_rate_hz=30.0)
    with pytest.raises(RuntimeError, match="reset"):
        UserMotion(MotionParams(), BatchRng.from_seeds([0])).advance(Intent())


def test_resetting_one_user_matches_a_fresh_single_run():
    it = Intent(cadence=[1.5, 1.8, 2.0], turn_rate=0.3, hand_rates=(0.2, 0.0, -0.1))
    batch_rng = BatchRng.from_seeds([1, 2, 3])
    batch = UserMotion(MotionParams(), batch_rng)
    batch.reset()
    for _ in range(13):
        batch.advance(it)
    batch_rng.reseed(1, np.random.default_rng(99))
    batch.reset(yaw=0.5, base=(1.0, 2.0), users=[1])
    after = [batch.advance(it) for _ in range(20)]

    fresh = UserMotion(MotionParams(), BatchRng([np.random.default_rng(99)]))
    fresh.reset(yaw=0.5, base=(1.0, 2.0))
    single = [
        fresh.advance(Intent(cadence=1.8, turn_rate=0.3, hand_rates=(0.2, 0.0, -0.1)))
        for _ in range(20)
    ]
    for a, s in zip(after, single, strict=True):
        for name in ("quat", "omega", "pos", "acc", "step", "walking"):
            np.testing.assert_array_equal(getattr(a, name)[1], getattr(s, name)[0])
        np.testing.assert_array_equal(a.kinect.joints[1], s.kinect.joints[0])
    uninterrupted = UserMotion(MotionParams(), BatchRng.from_seeds([1]))
    uninterrupted.reset()
    chunks = [
        uninterrupted.advance(Intent(cadence=1.5, turn_rate=0.3, hand_rates=(0.2, 0, -0.1)))
        for _ in range(33)
    ]
    np.testing.assert_array_equal(after[-1].acc[0], chunks[-1].acc[0])


def test_a_returned_chunk_is_not_changed_by_later_resets_or_steps():
    m = UserMotion(MotionParams(), BatchRng.from_seeds([1, 2]))
    m.reset()
    chunk = m.advance(Intent(cadence=1.5, turn_rate=0.3, lean=0.1))
    kept = {name: getattr(chunk, name).copy() for name in ("quat", "pos", "ypr", "body_yaw")}
    m.reset(yaw=2.0, users=[1])
    m.advance(Intent(cadence=1.8))
    for name, value in kept.items():
        np.testing.assert_array_equal(getattr(chunk, name), value)


def test_overground_walking_follows_the_heading_and_its_acceleration_integrates_to_it():
    """Overground (pose_source="visual_inertial"): the body covers stride * cadence per second
    along its yaw, and the linear acceleration the IMU senses integrates back to the path."""
    p = MotionParams(imu_rate_hz=1000.0, overground=True, stride_m=0.7)
    m = UserMotion(p, BatchRng.from_seeds([0, 1]))
    m.reset(yaw=[0.0, np.pi / 2], base=[(1.0, 2.0), (0.0, 0.0)])
    chunks = [m.advance(Intent(cadence=1.8, turn_rate=[0.0, 0.5])) for _ in range(60)]
    rec = MotionRecord.concatenate(chunks)
    dt = 1.0 / p.imu_rate_hz
    v = np.gradient(rec.pos, dt, axis=1)
    speed = np.linalg.norm(v[:, -200:-1, :2], axis=-1).mean(axis=1)
    np.testing.assert_allclose(speed, 0.7 * 1.8, rtol=0.02)
    # User 0 walks straight east (yaw 0): x grows ~1.26 m/s, y stays within the sway.
    assert rec.pos[0, -1, 0] - rec.pos[0, 0, 0] > 5.0
    assert abs(rec.pos[0, -1, 1] - rec.pos[0, 0, 1]) < 0.1
    # User 1 starts north and turns left: it ends up west of where it started.
    assert rec.pos[1, -1, 0] < -1.0
    # Trapezoid integration of the sensed acceleration reproduces the velocity of the path.
    vi = v[:, :1] + np.concatenate(
        [np.zeros((2, 1, 3)), np.cumsum(0.5 * (rec.acc[:, 1:] + rec.acc[:, :-1]) * dt, axis=1)],
        axis=1,
    )
    assert np.abs(vi[:, 1:-1] - v[:, 1:-1]).max() < 0.01
    # In place (the default) the body stays within the sway of its standing place.
    rec0 = walk(1.8, seconds=6.0)
    assert np.abs(rec0.pos[0, :, :2] - rec0.pos[0, 0, :2]).max() < 0.15


def test_head_yaw_is_body_yaw_plus_the_head_on_torso_gesture():
    from vrloco_env.batch_rng import BatchRng
    from vrloco_env.user import Intent, MotionParams, UserMotion

    motion = UserMotion(MotionParams(), BatchRng.from_seeds([1, 2]))
    motion.reset(yaw=np.array([0.3, -1.0]))
    amp = np.deg2rad(30.0)
    chunks = [
        motion.advance(
            Intent(
                cadence=np.array([1.6, 0.0]),
                turn_rate=np.array([0.0, 0.5]),
                gesture_amplitude=np.array([[amp, 0, 0], [0, 0, 0]]),
                gesture_frequency=np.array([[0.4, 0.4, 0.4]] * 2),
            )
        )
        for _ in range(60)
    ]
    body = np.concatenate([c.body_yaw for c in chunks], axis=1)
    rel = np.concatenate([c.head_on_torso_yaw for c in chunks], axis=1)
    np.testing.assert_allclose(body[0], 0.3, atol=1e-12)  # user 0 never turns its body ...
    assert np.abs(rel[0, -200:]).max() > np.deg2rad(25)  # ... but looks +-30 deg around
    np.testing.assert_allclose(rel[1], 0.0, atol=1e-9)  # user 1 turns, head with the body
    assert body[1, -1] - body[1, 0] > 2.0

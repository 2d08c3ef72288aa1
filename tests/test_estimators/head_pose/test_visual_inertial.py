"""Visual-inertial ESKF (the helmet-tracking paper) against ground truth on a synthetic walking
trajectory.

The truth is analytic (a 1 m/s circle with head bob and yaw turns), the IMU is exact plus white
noise at the consumer-MEMS densities and constant biases, and the visual poses are the truth at
120 Hz plus Gaussian noise (2 cm per axis, 0.5 deg per axis) unless a test says otherwise.
"""

from __future__ import annotations

import numpy as np
import pytest
from _trajectories import circle_motion

from estimators.head_pose.visual_inertial import (
    STATUS_ACCEPTED,
    STATUS_FORCED,
    STATUS_REJECTED,
    STATUS_SKIPPED,
    VioConfig,
    VisualInertialFilter,
)
from estimators.rotations import (
    GRAVITY,
    quat_conjugate,
    quat_from_rotvec,
    quat_from_ypr,
    quat_multiply,
    rotation_angle,
)

RATE = 1000.0  # IMU, Hz
CAM_RATE = 120.0  # camera, Hz
ACC_NOISE = 0.18e-3 * GRAVITY  # m/s^2/sqrt(Hz)
GYR_NOISE = np.radians(0.007)  # rad/s/sqrt(Hz)
ACC_BIAS = np.array([0.1, -0.15, 0.08])  # m/s^2 (about 10-15 mg)
GYR_BIAS = np.array([0.02, -0.015, 0.01])  # rad/s (about 1 deg/s)
POS_SIGMA = 0.02  # m
ATT_SIGMA = np.radians(0.5)  # rad
TUNED = VioConfig(position_sigma=POS_SIGMA, attitude_sigma=ATT_SIGMA)


class Run:
    """Truth, noisy IMU and camera frame times for one user over ``duration`` s."""

    def __init__(self, duration: float, seed: int, imu_noise_scale: float = 1.0) -> None:
        self.rng = np.random.default_rng(seed)
        n = round(duration * RATE)
        # Sample k of the IMU is at (k + 1) / RATE.
        self.truth = circle_motion(np.arange(n + 1) / RATE)
        an = ACC_NOISE * np.sqrt(RATE) * imu_noise_scale
        gn = GYR_NOISE * np.sqrt(RATE) * imu_noise_scale
        self.gyr = self.truth["w"][1:] + GYR_BIAS + self.rng.normal(0, gn, (n, 3))
        self.acc = self.truth["f"][1:] + ACC_BIAS + self.rng.normal(0, an, (n, 3))
        frames = np.arange(1, int(duration * CAM_RATE)) / CAM_RATE
        self.frame_sample = np.round(frames * RATE).astype(int) - 1

    def measurements(self, noise_scale=None, outlier_rate=0.0):
        """Noisy visual poses at the frame instants; ``noise_scale`` (M,) multiplies the sigmas;
        ``outlier_rate`` of the frames jump by 1 m in a random direction."""
        k = self.frame_sample + 1
        m = k.size
        s = np.ones(m) if noise_scale is None else noise_scale
        pos = self.truth["p"][k] + self.rng.normal(0, POS_SIGMA, (m, 3)) * s[:, None]
        rot = self.rng.normal(0, ATT_SIGMA, (m, 3)) * s[:, None]
        quat = quat_multiply(quat_from_rotvec(rot), self.truth["q"][k])
        bad = self.rng.random(m) < outlier_rate
        u = self.rng.normal(size=(m, 3))
        pos[bad] += u[bad] / np.linalg.norm(u[bad], axis=1, keepdims=True)
        return pos, quat, bad

    def filter(self, pos, quat, config: VioConfig):
        f = VisualInertialFilter(1, RATE, config)
        f.reset(self.truth["p"][0], self.truth["v"][0], self.truth["q"][0])
        valid = np.ones((1, len(pos)), dtype=bool)
        p, q, status = f.process(
            self.gyr[None], self.acc[None], self.frame_sample, pos[None], quat[None], valid
        )
        pos_err = np.linalg.norm(p[0] - self.truth["p"][1:], axis=1)
        att_err = rotation_angle(quat_multiply(q[0], quat_conjugate(self.truth["q"][1:])))
        return f, pos_err, att_err, status[0]


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def assert_user_state_equal(state: np.ndarray, other: np.ndarray, user: int) -> None:
    """Every field of one user's filter state record is the same."""
    for name in state.dtype.names:
        np.testing.assert_array_equal(state[name][user], other[name][user], err_msg=name)


@pytest.fixture(scope="module")
def run120():
    return Run(120.0, seed=11)


def test_fused_pose_beats_the_camera_and_stays_bounded(run120):
    pos, quat, _ = run120.measurements()
    f, pe, ae, status = run120.filter(pos, quat, TUNED)
    k = run120.frame_sample + 1
    meas_pos = rms(np.linalg.norm(pos - run120.truth["p"][k], axis=1))
    meas_att = rms(rotation_angle(quat_multiply(quat, quat_conjugate(run120.truth["q"][k]))))
    conv = int(5 * RATE)  # after convergence of the biases
    assert rms(pe[conv:]) < 0.05 and rms(pe[conv:]) < meas_pos / 3  # measured 5.5 mm vs 35 mm
    assert rms(ae[conv:]) < np.radians(1.0) and rms(ae[conv:]) < meas_att / 3  # 0.07 vs 0.87 deg
    first, last = rms(pe[conv : int(30 * RATE)]), rms(pe[-int(10 * RATE) :])
    assert last < 2 * first
    assert rms(ae[-int(10 * RATE) :]) < 2 * rms(ae[conv : int(30 * RATE)])
    np.testing.assert_allclose(f.accel_bias[0], ACC_BIAS, atol=0.03)
    np.testing.assert_allclose(f.gyro_bias[0], GYR_BIAS, atol=0.002)
    # A consistent filter gates out about 0.1 % of good frames (99.9 % gate).
    assert np.count_nonzero(status == STATUS_REJECTED) < 0.005 * status.size
    assert f.updates[0] + f.rejected[0] == status.size


def test_sage_husa_follows_a_noise_change(run120):
    """Visual noise x5 after 60 s (e.g. the light goes down): the adaptive R wins."""
    k = run120.frame_sample + 1
    scale = np.where(k / RATE >= 60.0, 5.0, 1.0)
    pos, quat, _ = run120.measurements(noise_scale=scale)
    _, pe_f, ae_f, _ = run120.filter(pos, quat, TUNED)
    sh, pe_a, ae_a, _ = run120.filter(pos, quat, TUNED.replace(adaptive="sage_husa"))
    half = int(60 * RATE)
    assert rms(pe_a[half:]) < rms(pe_f[half:])  # measured 2.2 cm vs 8 cm
    assert rms(ae_a[half:]) < rms(ae_f[half:])
    assert rms(pe_a[half:]) < 0.05
    # R tracked the new noise (0.1 m, 2.5 deg per axis) within its bounds.
    sig = np.sqrt(np.diag(sh.R[0]))
    np.testing.assert_allclose(sig[:3], 5 * POS_SIGMA, rtol=0.3)
    np.testing.assert_allclose(sig[3:], 5 * ATT_SIGMA, rtol=0.3)
    # ... and matches the fixed filter while the noise is what it was tuned for.
    assert rms(pe_a[5000:half]) < 1.2 * rms(pe_f[5000:half])


def test_gate_rejects_one_metre_jumps(run120):
    pos, quat, bad = run120.measurements(outlier_rate=0.02)
    f, pe, _, status = run120.filter(pos, quat, TUNED)
    assert bad.sum() > 200
    assert np.all(status[bad] == STATUS_REJECTED)
    assert np.count_nonzero(status[~bad] == STATUS_REJECTED) < 0.005 * (~bad).sum()
    assert f.rejected[0] == np.count_nonzero(status == STATUS_REJECTED)
    assert f.forced[0] == 0
    assert rms(pe[5000:]) < 0.02
    # Without the gate the jumps leak into the estimate.
    _, pe_open, _, _ = run120.filter(pos, quat, TUNED.replace(gate_probability=None))
    assert rms(pe_open[5000:]) > 2 * rms(pe[5000:])


def test_a_frame_is_forced_after_gate_max_consecutive_rejections():
    run = Run(2.0, seed=5)
    pos, quat, _ = run.measurements()
    pos[120:140] += [1.0, 0.0, 0.0]  # the camera jumps by 1 m for 20 frames
    f, _, _, status = run.filter(pos, quat, TUNED.replace(gate_max_consecutive=3))
    np.testing.assert_array_equal(status[120:124], [STATUS_REJECTED] * 3 + [STATUS_FORCED])
    assert f.forced[0] == np.count_nonzero(status == STATUS_FORCED) >= 1
    assert f.rejected[0] == np.count_nonzero(status == STATUS_REJECTED)
    assert f.updates[0] + f.rejected[0] == status.size


def test_adaptive_q_scales_up_for_a_noisier_imu():
    """The IMU is 30x noisier than configured: the Q scale grows and the error drops."""
    run = Run(60.0, seed=3, imu_noise_scale=30.0)
    pos, quat, _ = run.measurements()
    _, pe_f, _, _ = run.filter(pos, quat, TUNED)
    fq, pe_q, _, _ = run.filter(pos, quat, TUNED.replace(adapt_q=True))
    assert 3.0 < fq.q_scale[0] <= TUNED.q_scale_bounds[1]
    assert rms(pe_q[20000:]) < rms(pe_f[20000:])


def test_batch_of_three_equals_three_single_runs():
    runs = [Run(10.0, seed=s) for s in (21, 22, 23)]
    meas = [r.measurements(outlier_rate=0.05) for r in runs]
    cfg = TUNED.replace(adaptive="sage_husa", adapt_q=True)
    batch = VisualInertialFilter(3, RATE, cfg)
    batch.reset(
        np.stack([r.truth["p"][0] for r in runs]),
        np.stack([r.truth["v"][0] for r in runs]),
        np.stack([r.truth["q"][0] for r in runs]),
    )
    valid = np.ones((3, len(meas[0][0])), dtype=bool)
    valid[1, ::7] = False
    pb, qb, sb = batch.process(
        np.stack([r.gyr for r in runs]),
        np.stack([r.acc for r in runs]),
        runs[0].frame_sample,
        np.stack([m[0] for m in meas]),
        np.stack([m[1] for m in meas]),
        valid,
    )
    for i, (r, m) in enumerate(zip(runs, meas, strict=True)):
        f = VisualInertialFilter(1, RATE, cfg)
        f.reset(r.truth["p"][0], r.truth["v"][0], r.truth["q"][0])
        p, q, s = f.process(
            r.gyr[None], r.acc[None], r.frame_sample, m[0][None], m[1][None], valid[i : i + 1]
        )
        np.testing.assert_array_equal(p[0], pb[i])
        np.testing.assert_array_equal(q[0], qb[i])
        np.testing.assert_array_equal(s[0], sb[i])
        np.testing.assert_array_equal(f.P[0], batch.P[i])
        np.testing.assert_array_equal(f.R[0], batch.R[i])


def test_reset_mask_resets_one_user_only():
    run = Run(4.0, seed=31)
    pos, quat, _ = run.measurements()
    half = len(run.frame_sample) // 2
    cut = run.frame_sample[half - 1] + 1  # IMU samples before the reset
    gyr = np.stack([run.gyr, run.gyr])
    acc = np.stack([run.acc, run.acc])
    both = VisualInertialFilter(2, RATE, TUNED)
    both.reset(run.truth["p"][0], run.truth["v"][0], run.truth["q"][0])
    ok = np.ones((2, half), dtype=bool)
    pm, qm = np.stack([pos[:half]] * 2), np.stack([quat[:half]] * 2)
    both.process(gyr[:, :cut], acc[:, :cut], run.frame_sample[:half], pm, qm, ok)
    kept = both.state.copy()
    new_p, new_v, new_q = [1.0, 2.0, 3.0], [0.1, 0.0, 0.0], quat_from_ypr(np.array([0.3, 0, 0]))
    both.reset(np.tile(new_p, (2, 1)), np.tile(new_v, (2, 1)), np.tile(new_q, (2, 1)), mask=[0])
    assert_user_state_equal(both.state, kept, 1)
    assert both.updates[0] == 0 and both.updates[1] == half
    np.testing.assert_array_equal(both.P[0], TUNED.p0)
    # From here user 0 is a fresh filter, user 1 carries on as if nothing happened.
    fresh = VisualInertialFilter(1, RATE, TUNED)
    fresh.reset(new_p, new_v, new_q)
    rest = run.frame_sample[half:] - cut
    m = len(rest)
    pb, _, _ = both.process(
        gyr[:, cut:],
        acc[:, cut:],
        rest,
        np.stack([pos[half:]] * 2),
        np.stack([quat[half:]] * 2),
        np.ones((2, m), dtype=bool),
    )
    p0, _, _ = fresh.process(
        run.gyr[None, cut:],
        run.acc[None, cut:],
        rest,
        pos[None, half:],
        quat[None, half:],
        np.ones((1, m), dtype=bool),
    )
    np.testing.assert_array_equal(pb[0], p0[0])
    whole = VisualInertialFilter(1, RATE, TUNED)
    whole.reset(run.truth["p"][0], run.truth["v"][0], run.truth["q"][0])
    pw, _, _ = whole.process(
        run.gyr[None],
        run.acc[None],
        run.frame_sample,
        pos[None],
        quat[None],
        np.ones((1, len(pos)), dtype=bool),
    )
    np.testing.assert_array_equal(pb[1], pw[0, cut:])


def test_invalid_rows_are_skipped_and_bad_input_raises():
    f = VisualInertialFilter(2, RATE)
    f.reset([0, 0, 1.7], [0, 0, 0], [1, 0, 0, 0])
    f.predict(np.zeros((2, 8, 3)), np.tile([0, 0, GRAVITY], (2, 8, 1)))
    before = f.state.copy()
    pos = np.array([[0, 0, 1.75], [np.nan] * 3])
    quat = np.array([[1.0, 0, 0, 0], [np.nan] * 4])
    status = f.update(pos, quat, np.array([True, False]))
    np.testing.assert_array_equal(status, [STATUS_ACCEPTED, STATUS_SKIPPED])
    assert_user_state_equal(f.state, before, 1)
    assert f.position[0, 2] > 1.7  # pulled toward the measurement
    with pytest.raises(ValueError, match="finite"):
        f.update(pos, quat, np.array([True, True]))
    with pytest.raises(ValueError, match="valid"):
        f.update(pos, quat, np.array([1, 0]))
    with pytest.raises(ValueError, match="gyr"):
        f.predict(np.zeros((3, 8, 3)), np.zeros((3, 8, 3)))
    with pytest.raises(ValueError, match=r"forgetting=0\.5: must be in \[0\.9, 0\.9999\]"):
        VioConfig(forgetting=0.5)
    with pytest.raises(ValueError, match=r"VioConfig\.adaptive='ml': must be one of fixed, sage"):
        VioConfig(adaptive="ml")
    with pytest.raises(ValueError, match=r"position_sigma=0\.0001: must be in \[r_floor\[0\]="):
        VioConfig(position_sigma=1e-4)
    with pytest.raises(ValueError, match=r"gate_probability=1\.5: must be in \(0\.5, 1\) or None"):
        VioConfig(gate_probability=1.5)
    with pytest.raises(ValueError, match=r"q_scale_bounds=\(2\.0, 10\.0\): .* low <= 1 <= high"):
        VioConfig(q_scale_bounds=(2.0, 10.0))
    with pytest.raises(ValueError, match=r"r_prior_frames=2\.0: must be an integer in \[0, inf\)"):
        VioConfig(r_prior_frames=2.0)
    with pytest.raises(ValueError, match="config"):
        VisualInertialFilter(1, RATE, {"adaptive": "fixed"})
    assert VioConfig().gate_threshold == pytest.approx(22.4577, abs=1e-3)


def test_full_sage_husa_keeps_r_positive_definite(rng):
    """Wild innovations drive the raw full-matrix estimate indefinite; the clamp holds."""
    cfg = TUNED.replace(adaptive="sage_husa", sage_husa_diagonal=False, r_prior_frames=0)
    f = VisualInertialFilter(1, RATE, cfg)
    f.reset([0, 0, 1.7], [0, 0, 0], [1, 0, 0, 0])
    lo = min(cfg.r_floor) ** 2
    hi = max(cfg.r_ceiling) ** 2
    for _ in range(300):
        f.predict(np.zeros((1, 8, 3)), np.tile([0, 0, GRAVITY], (1, 8, 1)))
        pos = [[0, 0, 1.7]] + rng.normal(0, 0.05, (1, 3)) * rng.choice([0.01, 1.0, 10.0])
        quat = quat_from_rotvec(rng.normal(0, 0.02, (1, 3)))
        f.update(pos, quat, np.array([True]))
        w = np.linalg.eigvalsh(f.R[0])
        assert w.min() >= lo * (1 - 1e-9) and w.max() <= hi * (1 + 1e-9)
        assert np.linalg.eigvalsh(f.P[0]).min() > 0

"""The simulated user seen through its sensors: ground-truth checks end to end."""

import numpy as np
import pytest

from estimators import rotations as rot
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.imu import HeadImu, get_imu_spec
from vrloco_env.user import MotionParams, run_script


def sensed(script: str, seeds, preset="ig500n", noiseless=False, rate=100.0, **kw):
    params = MotionParams(imu_rate_hz=rate)
    rng = BatchRng.from_seeds(seeds)
    rec = run_script(script, rng, params, **kw)
    spec = get_imu_spec(preset)
    imu = HeadImu(spec.noiseless() if noiseless else spec, rng, rate_hz=rate)
    return rec, imu, imu.sample(rec.quat, rec.omega, rec.acc, rec.pos)


def test_noiseless_gyro_integrates_to_the_true_orientation():
    rec, _, s = sensed("stand_step_turn", [0], noiseless=True, rate=1000.0)
    q = rec.quat[:, 0]
    for k in range(1, rec.t.size):
        q = rot.quat_integrate(q, 0.5 * (s.gyr[:, k - 1] + s.gyr[:, k]), 1e-3)
    err = rot.rotation_angle(rot.quat_multiply(rot.quat_conjugate(q), rec.quat[:, -1]))
    assert np.rad2deg(err).max() < 0.01  # after 18 s of stepping and a 180 deg turn


@pytest.mark.parametrize("preset", ["ig500n", "consumer_mems"])
def test_stepping_specific_force_peaks_and_true_steps(preset):
    rec, _, s = sensed("straight", [1, 2], preset=preset)
    fn = np.linalg.norm(s.acc, axis=-1) / rot.GRAVITY
    stepping = (rec.t > 2.5) & (rec.t < 17.5)
    peaks = fn[:, stepping].max(axis=1)
    assert np.all((peaks > 1.1) & (peaks < 1.5)), peaks
    for times in rec.step_times:
        assert len(times) == pytest.approx(1.7 * 16.0, abs=1.0)  # 16 s at 1.7 steps/s
    standing = rec.t < 1.9
    a = get_imu_spec(preset).accel
    tol = 0.005 + 3.0 * np.sqrt(3.0) * (a.bias_stability + a.turn_on_bias) / rot.GRAVITY
    assert np.abs(fn[:, standing].mean(axis=1) - 1.0).max() < tol  # 1 g within the biases


def test_static_user_reads_gravity_and_the_earth_field():
    rec, imu, s = sensed("stand", [3], duration_s=5.0)
    g_body = rot.quat_rotate_inverse(rec.quat, imu.gravity_world * -1.0)
    m_body = rot.quat_rotate_inverse(rec.quat, imu.field_world)
    n = rec.t.size
    acc_sigma = get_imu_spec("ig500n").accel.noise_std(100.0) / np.sqrt(n)
    bias = get_imu_spec("ig500n").accel.bias_stability
    assert np.abs(s.acc[0].mean(0) - g_body[0].mean(0)).max() < 5 * acc_sigma + 4 * bias
    assert np.linalg.norm(s.mag[0].mean(0) - m_body[0].mean(0)) < 0.02 * np.linalg.norm(
        imu.field_world
    )


def test_same_seed_same_signals_and_batch_equals_singles():
    _, _, a = sensed("avoid", [5, 6])
    _, _, b = sensed("avoid", [5, 6])
    np.testing.assert_array_equal(a.gyr, b.gyr)
    for i, seed in enumerate([5, 6]):
        _, _, single = sensed("avoid", [seed])
        for name in ("acc", "gyr", "mag"):
            np.testing.assert_array_equal(getattr(a, name)[i], getattr(single, name)[0])

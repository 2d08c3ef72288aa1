"""Tests of the head IMU model against analytic ground truth and its own statistics."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from estimators.rotations import (
    GRAVITY,
    quat_from_rotvec,
    quat_from_ypr,
    quat_identity,
    quat_integrate,
    quat_multiply,
    quat_rotate_inverse,
    rotation_angle,
)
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.imu import (
    MU0_OVER_4PI,
    PRESETS,
    EarthField,
    HeadImu,
    ImuSpec,
    MagneticDisturbance,
    SensorSpec,
    get_imu_spec,
)

SEEDS = (11, 22, 33, 44)


def _static(b: int, n: int, q=None):
    """Static pose arrays: (B, N, 4) quaternions and zero rates/accelerations."""
    quat = quat_identity((b, n)) if q is None else np.broadcast_to(q, (b, n, 4)).copy()
    zeros = np.zeros((b, n, 3))
    return quat, zeros, zeros


def _only(spec: ImuSpec, **fields) -> ImuSpec:
    """``spec`` made noiseless, then the given SensorSpec fields set on all three sensors."""
    base = spec.noiseless()
    return dataclasses.replace(
        base,
        accel=dataclasses.replace(base.accel, **fields),
        gyro=dataclasses.replace(base.gyro, **fields),
        mag=dataclasses.replace(base.mag, **fields),
    )


@pytest.mark.parametrize("preset", sorted(PRESETS))
@pytest.mark.parametrize("ypr_deg", [(0.0, 0.0, 0.0), (40.0, 25.0, -35.0)])
def test_static_imu_reads_gravity_and_earth_field(preset, ypr_deg):
    b, n = len(SEEDS), 2000
    field = EarthField(intensity=48.0, inclination=62.0, declination=3.0)
    imu = HeadImu(preset, BatchRng.from_seeds(SEEDS), rate_hz=100.0, field=field)
    q_true = quat_from_ypr(np.radians(ypr_deg))
    out = imu.sample(*_static(b, n, q_true))
    spec = imu.spec

    f_true = quat_rotate_inverse(q_true, [0.0, 0.0, GRAVITY])
    m_body = quat_rotate_inverse(q_true, field.vector_enu())
    if ypr_deg == (0.0, 0.0, 0.0):
        np.testing.assert_allclose(f_true, [0.0, 0.0, GRAVITY], atol=1e-12)
    m_true = np.einsum("bij,j->bi", imu.soft_iron, m_body)  # soft iron applied to the body field

    for got, truth, bias, sens in (
        (out.acc, f_true, imu.last_bias.acc, spec.accel),
        (out.gyr, np.zeros(3), imu.last_bias.gyr, spec.gyro),
        (out.mag, m_true, imu.last_bias.mag, spec.mag),
    ):
        assert got.shape == (b, n, 3) and got.dtype == np.float64
        noise_se = sens.noise_std(100.0) / math.sqrt(n)
        tol = 5.0 * noise_se + sens.resolution  # mean of noise, plus quantisation
        # Knowing the true per-sample bias, the mean error is noise only.
        np.testing.assert_allclose(
            (got - bias).mean(axis=1), np.broadcast_to(truth, (b, 3)), atol=tol
        )
        # Without it, the raw mean is within a few sigma of bias + noise.
        bias_sd = math.hypot(sens.turn_on_bias, sens.bias_stability)
        if sens is spec.mag:
            bias_sd = math.hypot(bias_sd, spec.hard_iron)
        raw_tol = 5.0 * math.hypot(bias_sd, noise_se) + sens.resolution
        truth_raw = f_true if sens is spec.accel else (m_body if sens is spec.mag else 0.0)
        if sens is spec.mag:  # soft iron: a few % of the field on top
            raw_tol += 5.0 * 2.0 * max(spec.soft_iron_scale, spec.soft_iron_cross) * field.intensity
        assert np.all(np.abs(got.mean(axis=1) - truth_raw) < raw_tol)


def test_noiseless_outputs_equal_analytic_values_and_gyro_integrates_to_truth():
    b, n, rate = 2, 400, 200.0
    spec = get_imu_spec("ig500n").noiseless()
    d = MagneticDisturbance.with_field_at((1.0, 0.5, 1.2), field_ut=20.0, distance_m=0.5)
    imu = HeadImu(spec, BatchRng.from_seeds([1, 2]), rate_hz=rate, disturbances=[d])

    # Constant body rate from a tilted start; each user a different rate.
    omega = np.array([[0.3, -0.2, 1.1], [-0.6, 0.4, 0.2]])  # rad/s
    q0 = quat_from_ypr(np.radians([[10.0, -20.0, 5.0], [-70.0, 15.0, 30.0]]))
    t = np.arange(n) / rate
    q_true = quat_multiply(q0[:, None, :], quat_from_rotvec(omega[:, None, :] * t[None, :, None]))
    w = np.broadcast_to(omega[:, None, :], (b, n, 3)).copy()
    acc_world = np.stack([np.sin(t), 0.5 * np.cos(2 * t), 0.2 * t], -1)[None].repeat(b, 0)
    pos = np.stack([0.1 * t, 0.05 * t, 1.6 + 0 * t], -1)[None].repeat(b, 0)

    out = imu.sample(q_true, w, acc_world, pos)
    f_true = quat_rotate_inverse(q_true, acc_world - np.array([0.0, 0.0, -GRAVITY]))
    m_true = quat_rotate_inverse(q_true, EarthField().vector_enu() + d.field_at(pos))
    np.testing.assert_allclose(out.acc, f_true, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(out.gyr, w)
    np.testing.assert_allclose(out.mag, m_true, rtol=0, atol=1e-12)

    # Integrating the noiseless gyro reproduces the true orientation.
    q = q0.copy()
    for k in range(1, n):
        q = quat_integrate(q, out.gyr[:, k - 1], 1.0 / rate)
        assert np.all(rotation_angle(quat_multiply(q, q_true[:, k] * [1, -1, -1, -1])) < 1e-9)


def test_a_moving_dipole_reads_as_a_still_one_where_it_is_at_each_sample():
    """A dipole wheeled past at 1 m/s from 0.5 s to 1.5 s: each noiseless magnetometer sample
    of a still head is the earth field plus a *still* dipole's field at the moving one's place
    at that sample's time ((s + 1) / rate); it reads the same before the start as a dipole at
    the start, and after the stop as one at the end; a reset user starts the motion over."""
    rate, n = 100.0, 200
    spec = get_imu_spec("ig500n").noiseless()
    v, start, stop = np.array([1.0, 0.0, 0.0]), 0.5, 1.5
    moving = MagneticDisturbance.with_field_at(
        (-1.0, 0.8, 1.0), field_ut=20.0, distance_m=0.8, velocity=v, moving=(start, stop)
    )
    imu = HeadImu(spec, BatchRng.from_seeds([1]), rate_hz=rate, disturbances=[moving])
    q = np.tile([1.0, 0.0, 0.0, 0.0], (1, n, 1))
    zero = np.zeros((1, n, 3))
    head = np.tile([0.0, 0.0, 1.6], (1, n, 1))
    truth = imu.true_field_world(head, (1, n))  # the next n samples' field, before taking them
    mag = np.concatenate(
        [
            imu.sample(q[:, :90], zero[:, :90], zero[:, :90], head[:, :90]).mag,
            imu.sample(q[:, 90:], zero[:, 90:], zero[:, 90:], head[:, 90:]).mag,
        ],
        axis=1,
    )  # two calls: the clock carries over
    t = np.arange(1, n + 1) / rate
    for k in (0, 40, 49, 50, 99, 100, 149, 150, 199):
        at = np.asarray(moving.position) + v * min(max(t[k] - start, 0.0), stop - start)
        still = MagneticDisturbance(tuple(at), moving.moment)
        want = EarthField().vector_enu() + still.field_at(head[0, k])
        np.testing.assert_allclose(mag[0, k], want, rtol=0, atol=1e-12, err_msg=f"sample {k}")
    assert np.linalg.norm(mag[0, 99] - mag[0, 0]) > 1.0  # it moved: the field changed
    np.testing.assert_allclose(truth, mag, rtol=0, atol=1e-12)  # identity attitude: world = body
    np.testing.assert_array_equal(moving.position_at(0.2), moving.position)
    np.testing.assert_allclose(moving.position_at(9.0), np.add(moving.position, v * 1.0))
    np.testing.assert_allclose(
        moving.field_at(head[0, :3], t[:3]), mag[0, :3] - EarthField().vector_enu(), atol=1e-12
    )
    imu.reset()
    again = imu.sample(q[:, :90], zero[:, :90], zero[:, :90], head[:, :90]).mag
    np.testing.assert_array_equal(again, mag[:, :90])


def test_a_moving_dipole_is_checked_field_by_field():
    d = ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    with pytest.raises(
        ValueError,
        match=r"^MagneticDisturbance\.moving=\(2\.0, 1\.0\): must "
        r"be a tuple of 2 numbers in \[0, inf\) s, low <= high$",
    ):
        MagneticDisturbance(*d, velocity=(1.0, 0.0, 0.0), moving=(2.0, 1.0))
    with pytest.raises(ValueError, match=r"^MagneticDisturbance\.velocity=\(1\.0, 0\.0\)"):
        MagneticDisturbance(*d, velocity=(1.0, 0.0))
    with pytest.raises(ValueError, match=r"t must be finite times >= 0 s"):
        MagneticDisturbance(*d).field_at((1.0, 0.0, 0.0), t=-1.0)
    with pytest.raises(ValueError, match=r"t of shape \(2,\) does not broadcast"):
        MagneticDisturbance(*d).field_at(np.ones((3, 3)), t=(0.0, 1.0))


@pytest.mark.parametrize("rate", [100.0, 1000.0])
def test_white_noise_std_matches_density_times_sqrt_rate(rate):
    spec = _only(get_imu_spec("consumer_mems"), noise_density=0.0)
    spec = dataclasses.replace(
        spec,
        accel=dataclasses.replace(spec.accel, noise_density=2e-3),
        gyro=dataclasses.replace(spec.gyro, noise_density=1e-3),
        mag=dataclasses.replace(spec.mag, noise_density=0.05),
    )
    b, n = 4, 5000
    imu = HeadImu(spec, BatchRng.from_seeds(SEEDS), rate_hz=rate)
    out = imu.sample(*_static(b, n))
    m_true = EarthField().vector_enu()
    for got, truth, sens in (
        (out.acc, [0, 0, GRAVITY], spec.accel),
        (out.gyr, [0, 0, 0], spec.gyro),
        (out.mag, m_true, spec.mag),
    ):
        err = (got - np.asarray(truth)).reshape(-1, 3)
        want = sens.noise_density * math.sqrt(rate)
        np.testing.assert_allclose(err.std(axis=0), want, rtol=0.05)
        assert np.all(np.abs(err.mean(axis=0)) < 5 * want / math.sqrt(err.shape[0]))


def test_gauss_markov_bias_has_the_stated_stationary_std_and_correlation_time():
    rate, tau, sigma = 100.0, 1.0, 0.02
    spec = _only(get_imu_spec("ig500n"), bias_stability=sigma, bias_tau=tau)
    b, n = 8, 20000  # 200 s = 200 correlation times per user
    imu = HeadImu(spec, BatchRng.from_seeds(range(b)), rate_hz=rate)
    out = imu.sample(*_static(b, n))
    bias = out.gyr  # noiseless apart from the bias, and omega = 0
    np.testing.assert_array_equal(bias, imu.last_bias.gyr)
    std = bias.reshape(-1, 3).std(axis=0)
    np.testing.assert_allclose(std, sigma, rtol=0.1)
    lag = int(tau * rate)
    x = bias - bias.mean(axis=1, keepdims=True)
    rho = (x[:, lag:] * x[:, :-lag]).mean() / (x * x).mean()
    assert abs(rho - math.exp(-1.0)) < 0.06


def test_random_walk_bias_variance_grows_linearly():
    k, rate, n, b = 0.01, 100.0, 400, 300  # rad/s/sqrt(s)
    spec = _only(get_imu_spec("ig500n"), bias_walk=k)
    imu = HeadImu(spec, BatchRng.from_seeds(range(b)), rate_hz=rate)
    out = imu.sample(*_static(b, n))
    var_end = out.gyr[:, -1].var()  # over users and axes
    np.testing.assert_allclose(var_end, k * k * n / rate, rtol=0.15)


def test_saturation_clips_at_the_range():
    spec = get_imu_spec("ig500n")
    imu = HeadImu(spec, BatchRng.from_seeds([3]))
    q, w, a = _static(1, 20)
    w = w.copy()
    a = a.copy()
    w[0, :10, 0] = 10.0  # rad/s, beyond 300 deg/s
    w[0, 10:, 2] = -10.0
    a[0, :, 1] = 100.0  # m/s^2, beyond 5 g
    out = imu.sample(q, w, a)
    np.testing.assert_array_equal(out.gyr[0, :10, 0], spec.gyro.range)
    np.testing.assert_array_equal(out.gyr[0, 10:, 2], -spec.gyro.range)
    np.testing.assert_array_equal(out.acc[0, :, 1], spec.accel.range)
    assert np.all(np.abs(out.acc) <= spec.accel.range)
    # Magnetometer: a strong dipole next to the head saturates at 1.2 G = 120 uT.
    d = MagneticDisturbance.with_field_at((0.0, 0.0, 0.0), field_ut=1000.0, distance_m=0.3)
    imu = HeadImu(spec, BatchRng.from_seeds([3]), disturbances=[d])
    out = imu.sample(q, *_static(1, 20)[1:], pos=np.tile([0.0, 0.0, 0.3], (1, 20, 1)))
    np.testing.assert_array_equal(out.mag[0, :, 2], spec.mag.range)


def test_quantisation_step_equals_resolution():
    spec = get_imu_spec("consumer_mems").noiseless(keep_resolution=True)
    imu = HeadImu(spec, BatchRng.from_seeds([4]))
    n = 3000
    q, w, a = _static(1, n)
    w = w.copy()
    w[0, :, 0] = np.linspace(0.0, 0.2, n)  # a slow ramp over many LSBs
    out = imu.sample(q, w, a)
    lsb = spec.gyro.resolution
    steps = np.diff(np.unique(out.gyr[0, :, 0]))
    np.testing.assert_allclose(steps, lsb, rtol=1e-9)
    np.testing.assert_allclose(out.gyr[0, :, 0] / lsb, np.round(out.gyr[0, :, 0] / lsb), atol=1e-9)
    assert np.max(np.abs(out.gyr[0, :, 0] - w[0, :, 0])) <= 0.5 * lsb + 1e-15
    assert np.allclose(
        out.acc[0, :, 2] / spec.accel.resolution,
        np.round(out.acc[0, :, 2] / spec.accel.resolution),
        atol=1e-9,
    )


def test_dipole_field_decays_as_inverse_cube_and_raises_the_field_near_the_object():
    centre = np.array([2.0, 1.0, 1.0])
    d = MagneticDisturbance.with_field_at(centre, field_ut=30.0, distance_m=0.5, axis=(1, 0, 0))
    axis_pts = centre + np.array([[0.5, 0, 0], [1.0, 0, 0], [2.0, 0, 0]])
    b_axis = np.linalg.norm(d.field_at(axis_pts), axis=-1)
    np.testing.assert_allclose(b_axis[0], 30.0, rtol=1e-12)
    np.testing.assert_allclose(b_axis[:-1] / b_axis[1:], 8.0, rtol=1e-12)  # 1/r^3
    eq = np.linalg.norm(d.field_at(centre + np.array([0.0, 0.5, 0.0])))
    np.testing.assert_allclose(eq, 15.0, rtol=1e-12)  # equatorial = half the axial field
    # Explicit formula at an oblique point.
    r = np.array([0.3, -0.4, 0.2])
    m = np.asarray(d.moment)
    want = MU0_OVER_4PI * (3 * r * (m @ r) / np.linalg.norm(r) ** 5 - m / np.linalg.norm(r) ** 3)
    np.testing.assert_allclose(d.field_at(centre + r), want * 1e6, rtol=1e-12)

    # Through the IMU: a user walking away from the object sees |m| return to the earth value.
    spec = get_imu_spec("ig500n").noiseless()
    imu = HeadImu(spec, BatchRng.from_seeds([0]), disturbances=[d])
    dist = np.array([0.5, 1.0, 2.0, 4.0])
    pos = (centre + dist[:, None] * [1.0, 0.0, 0.0])[None]
    q, w, a = _static(1, len(dist))
    out = imu.sample(q, w, a, pos)
    excess = np.linalg.norm(out.mag[0] - EarthField().vector_enu(), axis=-1)
    np.testing.assert_allclose(excess, 30.0 * (0.5 / dist) ** 3, rtol=1e-9)
    # Inside min_distance the field stays finite.
    assert np.all(np.isfinite(d.field_at(centre[None])))


def test_earth_field_vector_and_wmm():
    np.testing.assert_allclose(
        EarthField(50.0, 60.0, 0.0).vector_enu(),
        [0.0, 25.0, -50.0 * math.sin(math.radians(60))],
        atol=1e-12,
    )
    np.testing.assert_allclose(
        EarthField(40.0, 0.0, 90.0).vector_enu(), [40.0, 0.0, 0.0], atol=1e-12
    )  # declination 90 deg east: magnetic north is east
    np.testing.assert_allclose(
        EarthField(40.0, -90.0, 0.0).vector_enu(), [0.0, 0.0, 40.0], atol=1e-12
    )  # southern magnetic pole region: field points up
    pytest.importorskip("ahrs")
    berlin = EarthField.from_wmm(52.52, 13.40, 0.05, 2025.0)
    assert 45.0 < berlin.intensity < 55.0 and 60.0 < berlin.inclination < 75.0
    assert 0.0 < berlin.declination < 10.0
    sydney = EarthField.from_wmm(-33.87, 151.21, 0.0, 2025.0)
    assert sydney.inclination < -50.0


def _run(seeds, preset="consumer_mems", chunks=(30, 20)):
    b = len(seeds)
    imu = HeadImu(preset, BatchRng.from_seeds(seeds), rate_hz=250.0)
    n = sum(chunks)
    t = np.arange(n)[None, :, None] * 0.004
    q = quat_from_ypr(np.concatenate([np.sin(t), 0.3 * t, -0.2 * t], -1)).repeat(b, 0)
    w = np.concatenate([0.5 * np.cos(t), 0.2 + 0 * t, np.sin(3 * t)], -1).repeat(b, 0)
    a = np.concatenate([np.cos(t), np.sin(t), 0 * t], -1).repeat(b, 0)
    outs, biases, start = [], [], 0
    for c in chunks:
        s = slice(start, start + c)
        outs.append(imu.sample(q[:, s], w[:, s], a[:, s]))
        biases.append(imu.last_bias)
        start += c
    cat = [np.concatenate([o[k] for o in outs], axis=1) for k in range(3)]
    bcat = [np.concatenate([o[k] for o in biases], axis=1) for k in range(3)]
    return cat, bcat, imu


def test_same_seeds_give_identical_output_and_batch_equals_single_runs():
    seeds = [7, 8, 9]
    a, ab, _ = _run(seeds)
    b, bb, _ = _run(seeds)
    for x, y in zip(a + ab, b + bb, strict=True):
        np.testing.assert_array_equal(x, y)
    other, _, _ = _run([7, 8, 10])
    assert np.array_equal(other[0][:2], a[0][:2]) and not np.array_equal(other[0][2], a[0][2])
    for i, s in enumerate(seeds):
        single, single_b, _ = _run([s])
        for x, y in zip(a + ab, single + single_b, strict=True):
            np.testing.assert_array_equal(x[i], y[0])


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_streaming_in_chunks_equals_one_call(preset):
    one, one_b, imu1 = _run([1, 2], preset, chunks=(50,))
    two, two_b, imu2 = _run([1, 2], preset, chunks=(20, 30))
    many, many_b, _ = _run([1, 2], preset, chunks=(1, 19, 0, 25, 5))
    for x, y, z in zip(one + one_b, two + two_b, many + many_b, strict=True):
        np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(x, z)
    for x, y in zip(imu1.bias, imu2.bias, strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(imu1.samples_taken, [50, 50])
    np.testing.assert_array_equal(imu2.samples_taken, [50, 50])


def test_reset_redraws_biases_from_each_users_stream():
    imu = HeadImu("consumer_mems", BatchRng.from_seeds([5, 6]))
    first = imu.bias
    assert not np.array_equal(first.gyr[0], first.gyr[1])
    imu.reset()
    assert not np.array_equal(imu.bias.gyr, first.gyr)
    np.testing.assert_array_equal(imu.samples_taken, [0, 0])
    # Turn-on gyro bias of the consumer part is degrees per second, of the IG-500N a tenth of one.
    big = HeadImu("consumer_mems", BatchRng.from_seeds(range(200))).bias.gyr
    small = HeadImu("ig500n", BatchRng.from_seeds(range(200))).bias.gyr
    assert np.degrees(big.std()) > 1.0 and np.degrees(small.std()) < 0.15


def _walk_inputs(b: int, n: int):
    """Different head motions per user: (quat, omega, acc_world, pos), each (B, n, ...)."""
    t = (np.arange(n) * 0.01)[None, :, None] * (1.0 + 0.3 * np.arange(b))[:, None, None]
    q = quat_from_ypr(np.concatenate([np.sin(t), 0.3 * np.cos(t), -0.2 * t], -1))
    w = np.concatenate([0.5 * np.cos(t), 0.2 + 0 * t, np.sin(3 * t)], -1)
    a = np.concatenate([np.cos(t), np.sin(t), 0 * t], -1)
    pos = np.concatenate([0.3 * t, 0 * t, 1.6 + 0 * t], -1)
    return q, w, a, pos


def _sample_in_chunks(imu: HeadImu, inputs, chunks):
    """Sample ``inputs`` in chunks; returns (outputs, last biases), each three (B, N, 3) arrays."""
    outs, biases, start = [], [], 0
    for c in chunks:
        outs.append(imu.sample(*(x[:, start : start + c] for x in inputs)))
        biases.append(imu.last_bias)
        start += c
    cat = [np.concatenate([o[k] for o in outs], axis=1) for k in range(3)]
    return cat, [np.concatenate([o[k] for o in biases], axis=1) for k in range(3)]


def test_resetting_one_user_equals_a_fresh_single_run_and_leaves_the_others_alone():
    base = get_imu_spec("consumer_mems")  # with a gyro random walk, so its state is exercised too
    spec = dataclasses.replace(base, gyro=dataclasses.replace(base.gyro, bias_walk=0.01))
    dist = [MagneticDisturbance.with_field_at((1.0, 0.5, 1.5), 20.0, 0.8)]
    seeds, n1, n2 = (3, 4, 5), 70, 90
    inputs = _walk_inputs(3, n1 + n2)
    first = [x[:, :n1] for x in inputs]
    second = [x[:, n1:] for x in inputs]

    rng = BatchRng.from_seeds(seeds)
    imu = HeadImu(spec, rng, rate_hz=200.0, disturbances=dist)
    _sample_in_chunks(imu, first, (25, 45))
    before = imu.bias
    rng.reseed(1, np.random.default_rng(99))
    imu.reset(users=[1])
    after = imu.bias
    np.testing.assert_array_equal(imu.samples_taken, [n1, 0, n1])
    out, bias = _sample_in_chunks(imu, second, (40, 50))

    # User 1: a fresh single-user IMU on the new generator, fed the same samples.
    fresh = HeadImu(spec, BatchRng([np.random.default_rng(99)]), rate_hz=200.0, disturbances=dist)
    for x, y in zip(after, fresh.bias, strict=True):
        np.testing.assert_array_equal(x[1], y[0])
    np.testing.assert_array_equal(imu.soft_iron[1], fresh.soft_iron[0])
    f_out, f_bias = _sample_in_chunks(fresh, [x[1:2] for x in second], (40, 50))
    for x, y in zip(out + bias, f_out + f_bias, strict=True):
        np.testing.assert_array_equal(x[1], y[0])
    # The reset changed user 1: its new biases are not the ones it had.
    assert not np.array_equal(after.gyr[1], before.gyr[1])

    # Users 0 and 2: their uninterrupted single runs.
    for i in (0, 2):
        np.testing.assert_array_equal(after.gyr[i], before.gyr[i])
        single = HeadImu(spec, BatchRng.from_seeds([seeds[i]]), rate_hz=200.0, disturbances=dist)
        s_out, s_bias = _sample_in_chunks(single, [x[i : i + 1] for x in inputs], (25, 45, 40, 50))
        for x, y in zip(out + bias, s_out + s_bias, strict=True):
            np.testing.assert_array_equal(x[i], y[0, n1:])
        for x, y in zip(imu.bias, single.bias, strict=True):
            np.testing.assert_array_equal(x[i], y[0])
    np.testing.assert_array_equal(imu.samples_taken, [n1 + n2, n2, n1 + n2])


def test_reset_users_as_a_mask_equals_indices_and_bad_users_raise():
    def run(users):
        rng = BatchRng.from_seeds([1, 2, 3])
        imu = HeadImu("consumer_mems", rng)
        imu.sample(*_static(3, 10))
        imu.reset(users=users)
        return imu.sample(*_static(3, 10))

    by_index = run([0, 2])
    by_mask = run(np.array([True, False, True]))
    for x, y in zip(by_index, by_mask, strict=True):
        np.testing.assert_array_equal(x, y)
    unchanged = run([])
    assert np.array_equal(unchanged.gyr[1], by_index.gyr[1])
    assert not np.array_equal(unchanged.gyr[0], by_index.gyr[0])
    imu = HeadImu("ig500n", BatchRng.from_seeds([0, 1]))
    for bad, match in (
        ([2], r"\[0, 1\]"),
        ([-1], r"\[0, 1\]"),
        ([1, 1], "repeat"),
        (np.array([True]), r"shape \(2,\)"),
        ([0.5], "integer"),
    ):
        with pytest.raises(ValueError, match=match):
            imu.reset(users=bad)


def test_presets_hold_the_paper_figures():
    ig = get_imu_spec("ig500n")
    np.testing.assert_allclose(ig.accel.range, 5 * GRAVITY)
    np.testing.assert_allclose(ig.accel.bias_stability, 4e-3 * GRAVITY)
    np.testing.assert_allclose(np.degrees(ig.gyro.range), 300.0)
    np.testing.assert_allclose(np.degrees(ig.gyro.bias_stability), 0.1)
    np.testing.assert_allclose(ig.mag.range, 120.0)  # 1.2 G
    np.testing.assert_allclose(ig.mag.bias_stability, 0.05)  # 0.5 mG
    c = get_imu_spec("consumer_mems")
    assert c.hard_iron >= 2.0 and c.gyro.turn_on_bias > ig.gyro.bias_stability
    assert c.mag.noise_density > ig.mag.noise_density


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"rate_hz": 0.0}, "rate_hz"),
        ({"rate_hz": 2000.0}, "rate_hz"),
        ({"rate_hz": float("nan")}, "rate_hz"),
        ({"spec": "bogus"}, "consumer_mems"),
        ({"field": "north"}, "field"),
    ],
)
def test_bad_construction_raises_clear_value_error(kwargs, match):
    args = {"spec": "ig500n", "rng": BatchRng.from_seeds([0])} | kwargs
    with pytest.raises(ValueError, match=match):
        HeadImu(**args)


def test_bad_sample_input_raises_clear_value_error():
    d = MagneticDisturbance((1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    imu = HeadImu("ig500n", BatchRng.from_seeds([0, 1]), disturbances=[d])
    q, w, a = _static(2, 5)
    p = np.zeros((2, 5, 3))
    bad_q = q.copy()
    bad_q[1, 2, 0] = np.nan
    bad_w = w.copy()
    bad_w[0, 0, 0] = np.inf
    cases = [
        ((q[..., :3], w, a, p), "quat"),
        ((q[:1], w, a, p), "quat"),
        ((q[0], w, a, p), "quat"),
        ((bad_q, w, a, p), "quat"),
        ((np.zeros((2, 5, 4)), w, a, p), "quat"),
        ((q, w[:, :4], a, p), "omega"),
        ((q, bad_w, a, p), "omega"),
        ((q, w, a[..., :2], p), "acc_world"),
        ((q, w, a, None), "pos"),
        ((q, w, a, p[:, :3]), "pos"),
    ]
    bad_a = a.copy()
    bad_a[1, 4, 2] = -np.inf
    bad_p = p.copy()
    bad_p[0, 3, 1] = np.nan
    zero_q = q.copy()
    zero_q[1, 1] = 0.0
    cases += [
        ((zero_q, w, a, p), "zero-norm"),
        ((q, w, bad_a, p), "acc_world"),
        ((q, w, a, bad_p), "pos"),
        ((q, w, a, p[..., :2]), "pos"),
    ]
    for args, match in cases:
        with pytest.raises(ValueError, match=match):
            imu.sample(*args)
    # A call that raises draws nothing and changes no state: the next call is a fresh IMU's first.
    fresh = HeadImu("ig500n", BatchRng.from_seeds([0, 1]), disturbances=[d])
    for x, y in zip(imu.sample(q, w, a, p), fresh.sample(q, w, a, p), strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(imu.samples_taken, [5, 5])


def test_bad_spec_fields_raise_clear_value_error():
    ig = get_imu_spec("ig500n")
    rep = dataclasses.replace
    cases = [
        (
            lambda: rep(ig.gyro, noise_density=-1.0),
            r"SensorSpec\(gyro\)\.noise_density=-1\.0: must be in \[0, inf\) rad/s/sqrt\(Hz\)$",
        ),
        (
            lambda: rep(ig.accel, bias_tau=0.0),
            r"SensorSpec\(accel\)\.bias_tau=0\.0: must be in \(0, inf\] s$",
        ),
        (
            lambda: rep(ig.mag, resolution=500.0),
            r"SensorSpec\(mag\)\.resolution=500\.0: must be in \[0, range=.*\) uT$",
        ),
        (
            lambda: SensorSpec(
                "accel", "m/s^2", range=float("nan"), noise_density=0, bias_stability=0, bias_tau=1
            ),
            r"SensorSpec\(accel\)\.range=nan: must be in \(0, inf\) m/s\^2$",
        ),
        (lambda: rep(ig, hard_iron=-1.0), r"ImuSpec\.hard_iron=-1\.0: must be in \[0, inf\) uT$"),
        (
            lambda: rep(ig, soft_iron_cross=0.2),
            r"ImuSpec\.soft_iron_cross=0\.2: must be in \[0, 0\.2\)",
        ),
        (lambda: rep(ig, gyro=ig.accel), r"ImuSpec\.gyro\.label='accel': must be 'gyro'$"),
        (
            lambda: EarthField(inclination=100.0),
            r"EarthField\.inclination=100\.0: must be in \[-90, 90\] deg$",
        ),
        (
            lambda: EarthField(intensity=0.0),
            r"EarthField\.intensity=0\.0: must be in \(0, inf\) uT$",
        ),
        (
            lambda: MagneticDisturbance((0, 0, 0), (0, np.nan, 0)),
            r"MagneticDisturbance\.moment=\(0, nan, 0\): "
            r"must be a tuple of 3 finite numbers A m\^2$",
        ),
        (
            lambda: MagneticDisturbance.with_field_at((0, 0, 0), field_ut=10.0, distance_m=0.0),
            r"^distance_m=0\.0: must be in \(0, inf\) m$",
        ),
    ]
    for make, message in cases:
        with pytest.raises(ValueError, match=message):
            make()
    # bias_tau = inf is a constant bias (accepted); an array position is stored as floats
    assert rep(ig.accel, bias_tau=math.inf).bias_tau == math.inf
    assert MagneticDisturbance(np.array([1, 2, 3]), (0.0, 0.0, 1.0)).position == (1.0, 2.0, 3.0)


# --- input layouts and the converter ----------------------------------------------------------

_DIPOLES = (
    MagneticDisturbance.with_field_at((1.0, 0.5, 1.5), 20.0, 0.8),
    MagneticDisturbance((0.3, 0.0, 1.6), (0.0, 0.0, 5.0), min_distance=0.2),
)


def test_sample_takes_strided_read_only_and_non_float_inputs():
    """Every input layout gives the numbers of the same values as C-contiguous float64 arrays."""
    q, w, a, pos = _walk_inputs(2, 40)

    def same(inputs, seeds=(1, 2), spec="ig500n", dist=_DIPOLES):
        got = HeadImu(spec, BatchRng.from_seeds(seeds), disturbances=dist).sample(*inputs)
        plain = [np.array(x, dtype=np.float64, order="C") for x in inputs]
        want = HeadImu(spec, BatchRng.from_seeds(seeds), disturbances=dist).sample(*plain)
        for x, y in zip(got, want, strict=True):
            np.testing.assert_array_equal(x, y)

    same([x[:, ::2] for x in (q, w, a, pos)])  # every other sample: non-contiguous views
    frozen = q[:, :20].copy()
    frozen.flags.writeable = False
    same([frozen, w[:, :20], a[:, :20], np.broadcast_to(pos[:1, :1], (2, 20, 3))])  # stride 0
    zi = [[[0, 0, 0]] * 3]
    same([np.ones((1, 3, 4), dtype=np.int64), zi, zi], seeds=(4,), dist=())  # integers, lists


def test_quantisation_rounds_half_lsb_to_even():
    lsb = 2.0**-8  # rad/s, a power of two: (k + 1/2) lsb / lsb is exactly k + 1/2
    base = get_imu_spec("ig500n").noiseless()
    spec = dataclasses.replace(base, gyro=dataclasses.replace(base.gyro, resolution=lsb))
    k = np.arange(-4, 4)
    q, w, a = _static(1, k.size)
    w = w.copy()
    w[0, :, 0] = (k + 0.5) * lsb
    out = HeadImu(spec, BatchRng.from_seeds([0])).sample(q, w, a)
    even = np.where(k % 2 == 0, k, k + 1)  # the even neighbour of k + 1/2
    np.testing.assert_array_equal(out.gyr[0, :, 0], even * lsb)

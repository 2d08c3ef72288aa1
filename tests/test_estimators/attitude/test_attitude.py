"""Attitude EKF (Zhang 2021, section 1) against ground truth: synthetic head motion and BROAD."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.attitude import AttitudeEKF, AttitudeParams, estimate_attitude
from estimators.attitude.errors import orientation_errors
from estimators.io.broad import broad_trials, load_broad
from estimators.rotations import (
    GRAVITY,
    angle_diff,
    quat_conjugate,
    quat_from_rotvec,
    quat_from_ypr,
    quat_multiply,
    quat_rotate_inverse,
    quat_to_rotvec,
    quat_to_ypr,
    rotation_angle,
)

FS = 100.0
BIAS = np.array([0.02, -0.015, 0.01])  # rad/s, about 1.1 deg/s: a consumer MEMS turn-on bias
DIP = np.radians(60.0)  # rad, mid-latitude inclination
FIELD = 50.0  # uT


def field_world(declination: float = 0.0, norm: float = FIELD) -> np.ndarray:
    """Earth field in ENU: magnetic north at yaw pi/2 - declination, pointing DIP below."""
    return norm * np.array(
        [np.sin(declination) * np.cos(DIP), np.cos(declination) * np.cos(DIP), -np.sin(DIP)]
    )


def synth(
    rng: np.random.Generator,
    kind: str = "head",
    seconds: float = 60.0,
    bias: np.ndarray = BIAS,
    noise: bool = True,
    declination: float = 0.0,
) -> tuple[np.ndarray, ...]:
    """True attitude and IMU samples (gyr rad/s, acc m/s^2, mag uT) at FS.

    ``head``: sinusoidal yaw/pitch/roll head motion; ``spin``: constant 0.5 rad/s yaw rate (the
    heading wraps through +-180 deg five times) with a small wobble. The gyro sample n is the
    constant rate that takes the true attitude from sample n-1 to n, so a perfect filter matches
    the truth at every sample. Noise: gyro 0.002 rad/s, acc 0.02 m/s^2, mag 0.3 uT per sample
    (consumer MEMS at 100 Hz, BMI160/BMM150 datasheet orders of magnitude).
    """
    t = np.arange(int(seconds * FS)) / FS
    if kind == "head":
        ypr = np.stack(
            [
                1.0 + 0.6 * np.sin(2 * np.pi * 0.2 * t),
                0.3 * np.sin(2 * np.pi * 0.3 * t),
                0.2 * np.sin(2 * np.pi * 0.25 * t + 1.0),
            ],
            axis=-1,
        )
    else:
        ypr = np.stack(
            [0.5 * t, 0.1 * np.sin(2 * np.pi * 0.1 * t), 0.1 * np.cos(2 * np.pi * 0.13 * t)],
            axis=-1,
        )
    q = quat_from_ypr(ypr)
    w = np.zeros_like(ypr)
    w[1:] = quat_to_rotvec(quat_multiply(quat_conjugate(q[:-1]), q[1:])) * FS
    sd = (0.002, 0.02, 0.3) if noise else (0.0, 0.0, 0.0)
    gyr = w + bias + rng.normal(0.0, sd[0], w.shape)
    acc = quat_rotate_inverse(q, [0.0, 0.0, GRAVITY]) + rng.normal(0.0, sd[1], w.shape)
    mag = quat_rotate_inverse(q, field_world(declination)) + rng.normal(0.0, sd[2], w.shape)
    return t, q, gyr, acc, mag


def ypr_rmse_deg(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    d = angle_diff(quat_to_ypr(q_est), quat_to_ypr(q_true))
    return np.degrees(np.sqrt(np.mean(d**2, axis=0)))


def total_err_deg(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    return np.degrees(rotation_angle(quat_multiply(q_est, quat_conjugate(q_true))))


# ------------------------------------------------------------------------------------------------
# Accuracy against ground truth, and the bias: correct model vs the paper's printed F = 0.
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["head", "spin"])
def test_rmse_against_truth_and_bias_convergence(rng, kind):
    t, q, gyr, acc, mag = synth(rng, kind)
    ekf = AttitudeEKF(1, FS)
    q_est = ekf.update_batch(gyr[None], acc[None], mag[None])[0]
    late = t >= 30.0  # after convergence (tilt/heading time constants about 11 s and 17 s)
    # Bound 0.5 deg: the noise above moves the estimate by < 0.2 deg (measured 0.13 deg yaw,
    # 0.02 deg pitch/roll); with the printed F = 0 the uncorrected 1.1 deg/s bias leaves 1-13 deg.
    assert np.all(ypr_rmse_deg(q_est[late], q[late]) < 0.5)
    # The bias is estimated: < 0.05 deg/s after 60 s (measured < 0.01 deg/s).
    assert np.degrees(np.max(np.abs(ekf.bias[0] - BIAS))) < 0.05
    np.testing.assert_allclose(ekf.ypr, quat_to_ypr(ekf.quat))


def test_bias_not_estimated_with_the_paper_literal_model(rng):
    t, q, gyr, acc, mag = synth(rng, "head")
    correct = AttitudeEKF(1, FS)
    literal = AttitudeEKF(1, FS, model="paper_literal")
    q_c = correct.update_batch(gyr[None], acc[None], mag[None])[0]
    q_l = literal.update_batch(gyr[None], acc[None], mag[None])[0]
    err_c = np.linalg.norm(correct.bias[0] - BIAS)
    err_l = np.linalg.norm(literal.bias[0] - BIAS)
    assert err_c < 0.05 * np.linalg.norm(BIAS)  # converged
    assert err_l > 0.95 * np.linalg.norm(BIAS)  # never moved from its initial 0
    late = t >= 30.0
    assert np.sqrt(np.mean(total_err_deg(q_l, q)[late] ** 2)) > 5.0 * np.sqrt(
        np.mean(total_err_deg(q_c, q)[late] ** 2)
    )


def rest_stream(
    rng: np.random.Generator,
    bias: np.ndarray,
    rest: float = 4.0,
    move: float = 12.0,
    moves: int = 4,
) -> tuple[np.ndarray, ...]:
    """A head that rests ``rest`` s, moves ``move`` s, rests again, ... (``moves`` movements
    between ``moves + 1`` rests), sampled as in :func:`synth`. Each movement swings the yaw and
    nods pitch and roll (up to 0.8, 0.25 and 0.2 rad), its rates zero at both ends; yaw 0 at rest.
    Returns t, q, gyr, acc, mag."""
    t = np.arange(int((moves * (rest + move) + rest) * FS)) / FS
    ypr = np.zeros((t.size, 3))
    for k in range(moves):
        u = (t - (k * (rest + move) + rest)) / move
        on = (u >= 0.0) & (u <= 1.0)
        uo = u[on]
        ypr[on, 0] = 0.8 * np.sin(np.pi * uo) ** 2 * np.sin(4 * np.pi * uo)
        ypr[on, 1] = 0.25 * (-1) ** k * np.sin(3 * np.pi * uo) ** 2
        ypr[on, 2] = 0.2 * np.sin(4 * np.pi * uo) ** 2
    q = quat_from_ypr(ypr)
    w = np.zeros_like(ypr)
    w[1:] = quat_to_rotvec(quat_multiply(quat_conjugate(q[:-1]), q[1:])) * FS
    gyr = w + bias + rng.normal(0.0, 0.002, w.shape)
    acc = quat_rotate_inverse(q, [0.0, 0.0, GRAVITY]) + rng.normal(0.0, 0.02, w.shape)
    mag = quat_rotate_inverse(q, field_world()) + rng.normal(0.0, 0.3, w.shape)
    return t, q, gyr, acc, mag


def heading_err_deg(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """Signed heading error (deg): the turn about the world vertical in q_est ⊗ conj(q_true)."""
    e = quat_multiply(q_est, quat_conjugate(q_true))
    return np.degrees(angle_diff(2.0 * np.arctan2(e[..., 3], e[..., 0]), 0.0))


def test_rest_periods_teach_the_bias_to_the_corrected_filter_and_not_to_the_printed_one(rng):
    # 1 deg/s about the sensor z axis; 68 s: five 4 s rests between four 12 s movements.
    bias = np.radians([0.0, 0.0, 1.0])
    t, q, gyr, acc, mag = rest_stream(rng, bias)
    last_rest = t >= t[-1] - 4.0
    for nine_d in (False, True):
        m = mag[None] if nine_d else None
        run = {}
        for model in ("trawny", "f_zero", "paper_literal"):
            ekf = AttitudeEKF(1, FS, model=model)
            run[model] = (
                heading_err_deg(ekf.update_batch(gyr[None], acc[None], m)[0], q),
                ekf.bias[0],
            )
        # Corrected: the bias to 0.05 deg/s (measured < 0.01 deg/s on every axis) ...
        head, b = run["trawny"]
        assert np.degrees(np.max(np.abs(b - bias))) < 0.05
        if not nine_d:
            # ... and in 6D the heading drifts only before the first rest has taught it:
            # 1.5 deg = rest_time * 1 deg/s (measured 1.4-1.5 deg at most, then no drift).
            assert np.abs(head).max() < 2.5
            assert abs(np.polyfit(t, head, 1)[0]) < 0.02  # deg/s; measured < 0.01
        assert np.abs(head[last_rest]).max() < 0.5  # measured 0.25 (6D), 0.01 (9D)
        # F = 0 with the zero-rate update at rest still learns it (measured < 0.03 deg/s) ...
        assert np.degrees(np.max(np.abs(run["f_zero"][1] - bias))) < 0.05
        # ... the printed filter never does: its bias stays exactly at its initial 0.
        head, b = run["paper_literal"]
        assert np.all(b == 0.0)
        if not nine_d:
            # 6D: the heading drifts at the bias rate, slightly less as the tilted sensor z axis
            # is off the vertical (measured 0.99 deg/s; 67 deg after 68 s).
            assert 0.9 < np.polyfit(t, head, 1)[0] < 1.05
            assert head[-1] == pytest.approx(np.degrees(bias[2]) * t[-1], rel=0.1)
        else:
            # 9D: the compass holds the heading, behind by bias * mag_noise / gyr_noise, 17 deg
            # (measured 16.3 deg).
            assert np.abs(head[last_rest]).min() > 10.0


@pytest.mark.parametrize("model", ["trawny", "f_zero", "paper_literal"])
@pytest.mark.parametrize(
    "ypr", [(1.0, 0.2, -0.3), (-2.9, -0.6, 2.5), (3.1, 0.4, -3.0), (0.3, 1.2, 0.1)]
)
def test_every_model_pulls_a_wrong_attitude_back_to_a_static_truth(model, ypr):
    # The measurement equations in our frame (the printed eqs 11-13 derived for ENU, the roll and
    # yaw residuals wrapped near +-180 deg): a static, noiseless sensor, the state turned 14 deg.
    q_true = quat_from_ypr(np.array(ypr))
    n = int(60 * FS)
    f = np.tile(quat_rotate_inverse(q_true, [0.0, 0.0, GRAVITY]), (1, n, 1))
    m = np.tile(quat_rotate_inverse(q_true, field_world(0.1)), (1, n, 1))
    ekf = AttitudeEKF(1, FS, model=model, declination=0.1)
    ekf.update_batch(np.zeros((1, 1, 3)), f[:, :1], m[:, :1])
    ekf.state.q[0] = quat_multiply(q_true, quat_from_rotvec(np.radians([8.0, -6.0, 10.0])))
    q_est = ekf.update_batch(np.zeros((1, n - 1, 3)), f[:, 1:], m[:, 1:])[0]
    err = total_err_deg(q_est, q_true[None])
    assert err[int(30 * FS)] < 0.2  # measured 0.006-0.08 deg
    assert err[-1] < 0.05  # measured 0.001-0.02 deg


# ------------------------------------------------------------------------------------------------
# Entry points agree: batch == singles; offline == streaming; reset == a fresh filter.
# ------------------------------------------------------------------------------------------------


def test_batch_equals_single_streams_and_offline_equals_streaming(rng):
    streams = [synth(rng, kind, seconds=5.0) for kind in ("head", "spin", "head", "spin")]
    gyr, acc, mag = (np.stack([s[i] for s in streams]) for i in (2, 3, 4))
    batched = estimate_attitude(gyr, acc, mag, FS)
    for i in range(len(streams)):
        np.testing.assert_array_equal(batched[i], estimate_attitude(gyr[i], acc[i], mag[i], FS))
    ekf = AttitudeEKF(len(streams), FS)
    streamed = np.stack([ekf.update(gyr[:, k], acc[:, k], mag[:, k]) for k in range(300)], 1)
    np.testing.assert_array_equal(streamed, batched[:, :300])


def test_resetting_one_stream_equals_a_fresh_filter_and_leaves_the_others_alone(rng):
    streams = [synth(rng, kind, seconds=5.0) for kind in ("head", "spin", "head")]
    q_true = np.stack([s[1] for s in streams])
    gyr, acc, mag = (np.stack([s[i] for s in streams]) for i in (2, 3, 4))
    n1 = 200
    ekf = AttitudeEKF(3, FS)
    ekf.update_batch(gyr[:, :n1], acc[:, :n1], mag[:, :n1])
    learned = ekf.state.copy()
    ekf.reset([1])
    assert not ekf.initialized[1] and ekf.initialized[0] and ekf.initialized[2]
    for name in ekf.state.dtype.names:  # the other streams' state is untouched
        np.testing.assert_array_equal(ekf.state[name][[0, 2]], learned[name][[0, 2]])
    after = ekf.update_batch(gyr[:, n1:], acc[:, n1:], mag[:, n1:])

    fresh = AttitudeEKF(1, FS)
    np.testing.assert_array_equal(
        after[1], fresh.update_batch(gyr[1:2, n1:], acc[1:2, n1:], mag[1:2, n1:])[0]
    )
    for name in ekf.state.dtype.names:
        np.testing.assert_array_equal(ekf.state[name][1], fresh.state[name][0])
    for i in (0, 2):
        np.testing.assert_array_equal(after[i], estimate_attitude(gyr[i], acc[i], mag[i], FS)[n1:])
    # Stream 1 re-initialised from its next acc/mag sample: right at once, and not the old estimate.
    assert total_err_deg(after[1, :1], q_true[1, n1 : n1 + 1])[0] < 3.0
    uninterrupted = estimate_attitude(gyr[1], acc[1], mag[1], FS)[n1:]
    assert not np.array_equal(after[1], uninterrupted)

    # A boolean mask does the same, sample by sample too; bad masks raise.
    ekf2 = AttitudeEKF(3, FS)
    ekf2.update_batch(gyr[:, :n1], acc[:, :n1], mag[:, :n1])
    ekf2.reset(np.array([False, True, False]))
    for k in range(5):
        np.testing.assert_array_equal(
            ekf2.update(gyr[:, n1 + k], acc[:, n1 + k], mag[:, n1 + k]), after[:, k]
        )
    for bad, match in (([3], r"\[0, 2\]"), (np.ones(2, bool), r"shape \(3,\)"), ([0.5], "indices")):
        with pytest.raises(ValueError, match=match):
            ekf2.reset(bad)


# ------------------------------------------------------------------------------------------------
# Initialisation, magnetic disturbance, dropouts.
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("ypr", [(1.0, 0.2, -0.3), (-2.9, -0.6, 2.5), (0.3, 1.2, 0.1)])
def test_initialisation_from_first_samples_is_right_at_once(rng, ypr):
    declination = 0.1
    q_true = quat_from_ypr(np.array(ypr))
    f = quat_rotate_inverse(q_true, [0.0, 0.0, GRAVITY])
    m = quat_rotate_inverse(q_true, field_world(declination))
    ekf = AttitudeEKF(1, FS, declination=declination)
    q0 = ekf.update(np.zeros((1, 3)), f[None], m[None])
    assert total_err_deg(q0, q_true[None])[0] < 1e-6
    # With sensor noise: one mag sample gives the heading to atan(0.3 uT * sqrt(2) / 25 uT),
    # about 1 deg (1 sigma), plus tan(dip) times the 0.1 deg tilt noise: 3 deg is 3 sigma.
    ekf = AttitudeEKF(1, FS, declination=declination)
    q0 = ekf.update(
        np.zeros((1, 3)), (f + rng.normal(0, 0.02, 3))[None], (m + rng.normal(0, 0.3, 3))[None]
    )
    assert total_err_deg(q0, q_true[None])[0] < 3.0


def test_magnetic_disturbance_is_rejected(rng):
    t, q, gyr, acc, mag = synth(rng, "head", seconds=30.0)
    # 2 s near a metal object: an extra eastward field, norm +50 % and the compass turned by
    # atan(1.12 / cos(60 deg)), about 66 deg.
    dist = (t >= 20.0) & (t < 22.0)
    extra = np.sqrt(1.5**2 - 1.0) * FIELD * np.array([1.0, 0.0, 0.0])
    mag_d = mag.copy()
    mag_d[dist] += quat_rotate_inverse(q[dist], extra)
    assert np.linalg.norm(field_world() + extra) == pytest.approx(1.5 * FIELD)
    window = t >= 19.0
    heading = {}
    for name, kw in {"gated": {}, "ungated": {"mag_norm_tol": 10.0, "mag_dip_tol": 10.0}}.items():
        q_est = estimate_attitude(gyr, acc, mag_d, FS, **kw)
        heading[name] = np.abs(
            np.degrees(angle_diff(quat_to_ypr(q_est)[:, 0], quat_to_ypr(q)[:, 0]))
        )
    assert heading["gated"][window].max() < 0.5  # the disturbance never reaches the heading
    assert heading["ungated"][window].max() > 3.0  # without the gate it does


def test_lasting_field_change_becomes_the_reference_and_6d_never_sets_a_heading(rng):
    params = AttitudeParams(mag_learn_time=0.2, mag_ok_time=0.1, mag_new_time=1.0)
    streams = [synth(rng, "head", seconds=7.0) for _ in range(2)]
    q_true = np.stack([s[1] for s in streams])
    gyr, acc, mag = (np.stack([s[i] for s in streams]) for i in (2, 3, 4))
    mag[0, 300:] *= 1.5  # a move to another room: rejected first, adopted after mag_new_time
    mag[1] = np.nan  # 6D
    ekf = AttitudeEKF(2, FS, params)
    q_est = ekf.update_batch(gyr, acc, mag)
    assert ekf.state.mag_norm[0] == pytest.approx(1.5 * FIELD, rel=0.05)
    assert ekf.state.head_init[1] == 0.0 and ekf.state.mag_learn_n[1] == 0.0
    # The new field scales the old one: once adopted, the heading stays right.
    assert total_err_deg(q_est[0, -100:], q_true[0, -100:]).max() < 1.0


def test_nan_samples_are_skipped_and_the_filter_carries_on(rng):
    t, q, gyr, acc, mag = synth(rng, "head", seconds=60.0)
    gyr, acc, mag = gyr.copy(), acc.copy(), mag.copy()
    acc[:5] = np.nan  # no accelerometer yet: initialisation waits
    gyr[1000:1005] = np.nan  # 50 ms without propagation: up to 2 deg of head turn is missed
    acc[1200:1300] = np.nan
    mag[1300:1600] = np.nan
    mag[1700, 1] = np.inf
    q_est = estimate_attitude(gyr, acc, mag, FS)
    assert np.all(np.isfinite(q_est))
    err = total_err_deg(q_est, q)
    assert err[5] < 3.0  # initialised from the first finite accelerometer sample
    assert err[5:].max() < 3.0  # the dropouts cost little ...
    assert err[t >= 45.0].max() < 0.5  # ... and the measurements remove it


def test_bias_at_rest_is_estimated_on_all_axes_without_magnetometer(rng):
    # A level sensor at rest: tilt alone cannot see the vertical bias; the zero-rate update can.
    n = int(10 * FS)
    gyr = BIAS + rng.normal(0.0, 0.002, (n, 3))
    acc = np.array([0.0, 0.0, GRAVITY]) + rng.normal(0.0, 0.02, (n, 3))
    ekf = AttitudeEKF(1, FS)
    ekf.update_batch(gyr[None], acc[None])
    assert np.degrees(np.max(np.abs(ekf.bias[0] - BIAS))) < 0.05
    no_rest = AttitudeEKF(1, FS, rest_time=1e9)
    no_rest.update_batch(gyr[None], acc[None])
    assert np.degrees(abs(no_rest.bias[0, 2] - BIAS[2])) > 0.5  # unobservable without it


def test_6d_without_magnetometer_tracks_tilt(rng):
    t, q, gyr, acc, _ = synth(rng, "head", seconds=60.0)
    q_est = estimate_attitude(gyr, acc, None, FS)
    late = t >= 30.0
    res = orientation_errors(q_est[late], q[late], align_heading=True)
    assert res["inclination_rmse_deg"] < 0.3


# ------------------------------------------------------------------------------------------------
# The metric.
# ------------------------------------------------------------------------------------------------


def test_orientation_errors_separate_heading_and_inclination(rng):
    q_true = quat_from_ypr(rng.uniform(-1, 1, (50, 3)))
    yaw_off = quat_from_rotvec([0.0, 0.0, np.radians(7.0)])  # earth-frame heading error
    tilt_off = quat_from_rotvec([np.radians(3.0), 0.0, 0.0])  # earth-frame tilt error
    res = orientation_errors(quat_multiply(yaw_off, q_true), q_true)
    assert res["heading_rmse_deg"] == pytest.approx(7.0)
    assert res["inclination_rmse_deg"] == pytest.approx(0.0, abs=1e-6)
    res = orientation_errors(quat_multiply(tilt_off, q_true), q_true)
    assert res["inclination_rmse_deg"] == pytest.approx(3.0)
    assert res["heading_rmse_deg"] == pytest.approx(0.0, abs=1e-6)
    both = quat_multiply(yaw_off, quat_multiply(tilt_off, q_true))
    q_nan = q_true.copy()
    q_nan[::5] = np.nan  # lost markers are ignored
    mask = np.arange(50) < 40
    res = orientation_errors(both, q_nan, mask, align_heading=True)
    assert res["heading_offset_deg"] == pytest.approx(7.0, abs=0.05)
    assert res["inclination_rmse_deg"] == pytest.approx(3.0, abs=0.05)
    assert res["n_samples"] == 32
    batched = orientation_errors(np.stack([both, q_true]), np.stack([q_true, q_true]))
    assert batched["total_rmse_deg"][1] == pytest.approx(0.0, abs=1e-6)


# ------------------------------------------------------------------------------------------------
# Real data: BROAD, one parameter set (the defaults) for all nine trials.
# ------------------------------------------------------------------------------------------------


def test_broad_mean_total_rmse(real_data):
    files = broad_trials(real_data("broad"))
    assert len(files) == 9
    totals = []
    for path in files:
        trial = load_broad(path)
        q_est = estimate_attitude(trial.gyr, trial.acc, trial.mag, trial.fs)
        totals.append(orientation_errors(q_est, trial.quat, trial.movement)["total_rmse_deg"])
    # Issue target 4.0 deg; measured 2.59 deg (VQF 2.61 deg with the same metric).
    assert np.mean(totals) <= 4.0
    assert max(totals) < 10.0


# ------------------------------------------------------------------------------------------------
# Bad input.
# ------------------------------------------------------------------------------------------------


def test_bad_input_raises_clearly(rng):
    _, _, gyr, acc, mag = synth(rng, "head", seconds=2.0)
    ekf = AttitudeEKF(2, FS)
    with pytest.raises(ValueError, match="gyr"):
        ekf.update(np.zeros((2, 2)), acc[:2], mag[:2])
    with pytest.raises(ValueError, match="acc"):
        ekf.update(gyr[:2], acc[:3], mag[:2])
    with pytest.raises(ValueError, match="mag"):
        ekf.update(gyr[:2], acc[:2], mag[:1])
    with pytest.raises(ValueError, match="acc"):
        estimate_attitude(gyr, acc[:-1], mag, FS)
    with pytest.raises(ValueError, match="fs"):
        AttitudeEKF(1, 0.0)
    with pytest.raises(ValueError, match="n_streams"):
        AttitudeEKF(0, FS)
    with pytest.raises(ValueError, match=r"Params\.acc_noise=-1\.0: must be in \(0, inf\)$"):
        AttitudeParams(acc_noise=-1.0)
    with pytest.raises(ValueError, match=r"AttitudeParams\.model='euler': must be one of trawny"):
        AttitudeParams(model="euler")
    with pytest.raises(ValueError, match=r"mag_new_time=0\.0: must be in \(0, inf\] s$"):
        AttitudeParams(mag_new_time=0.0)
    assert AttitudeParams(mag_new_time=np.inf).mag_new_time == np.inf
    with pytest.raises(ValueError, match="unknown attitude parameter"):
        estimate_attitude(gyr, acc, mag, FS, acc_nosie=0.1)
    with pytest.raises(
        ValueError, match=r"mag_ref_norm=50\.0: must be given together with mag_ref_dip"
    ):
        AttitudeParams(mag_ref_norm=50.0)
    # Unit mix-ups: a gyro in deg/s during motion, an accelerometer in g.
    with pytest.raises(ValueError, match="rad/s"):
        estimate_attitude(np.degrees(gyr) * 20, acc, mag, FS)
    with pytest.raises(ValueError, match="m/s\\^2"):
        estimate_attitude(gyr, acc / GRAVITY, mag, FS)
    with pytest.raises(ValueError, match="m/s\\^2"):
        one = AttitudeEKF(1, FS)
        for k in range(20):
            one.update(gyr[k : k + 1], acc[k : k + 1] / GRAVITY, mag[k : k + 1])
    # A rad/s gyro with a single glitch is fine.
    glitch = gyr.copy()
    glitch[50] = 100.0
    assert np.all(np.isfinite(estimate_attitude(glitch, acc, mag, FS)))


def test_given_magnetic_reference_skips_learning(rng):
    _, _, gyr, acc, mag = synth(rng, "head", seconds=3.0)
    ekf = AttitudeEKF(1, FS, mag_ref_norm=FIELD, mag_ref_dip=DIP)
    ekf.update_batch(gyr[None], acc[None], mag[None])
    assert ekf.state.mag_norm[0] == FIELD
    assert ekf.state.mag_learn_n[0] == 0.0


# ------------------------------------------------------------------------------------------------
# Offline mode: the forward-backward smoother of estimate_attitude(..., offline=True).
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["head", "spin"])
def test_offline_smoother_beats_the_forward_filter_against_the_truth(rng, kind):
    t, q, gyr, acc, mag = synth(rng, kind)
    rms = {}
    for offline in (False, True):
        q_est = estimate_attitude(gyr, acc, mag, FS, offline=offline)
        rms[offline] = np.sqrt(np.mean(total_err_deg(q_est, q) ** 2))
        early = t < 10.0  # the forward filter still learns the 1.1 deg/s bias here
        rms[offline, "early"] = np.sqrt(np.mean(total_err_deg(q_est[early], q[early]) ** 2))
    # Measured: head 0.27 -> 0.08 deg, spin 0.32 -> 0.10 deg over the 60 s.
    assert rms[True] < 0.5 * rms[False]
    assert rms[True, "early"] < 0.5 * rms[False, "early"]
    # 6D: no heading, but the inclination improves the same way (0.22 -> 0.07 deg).
    incl = [
        orientation_errors(estimate_attitude(gyr, acc, None, FS, offline=o), q, align_heading=True)[
            "inclination_rmse_deg"
        ]
        for o in (False, True)
    ]
    assert incl[1] < 0.5 * incl[0]


def test_offline_smoother_is_deterministic_and_batches_like_single_streams(rng):
    streams = [synth(rng, kind, seconds=8.0) for kind in ("head", "spin")]
    gyr, acc, mag = (np.stack([s[i] for s in streams]) for i in (2, 3, 4))
    gyr[1, 300:320] = np.nan  # a gyro dropout in one stream only
    first = estimate_attitude(gyr, acc, mag, FS, offline=True)
    np.testing.assert_array_equal(first, estimate_attitude(gyr, acc, mag, FS, offline=True))
    for i in range(len(streams)):
        single = estimate_attitude(gyr[i], acc[i], mag[i], FS, offline=True)
        np.testing.assert_array_equal(single, first[i])
    assert np.all(np.isfinite(first))
    np.testing.assert_allclose(np.linalg.norm(first, axis=-1), 1.0, atol=1e-12)
    # Every model smooths (the printed one through its Euler-angle covariance).
    for model in ("f_zero", "paper_literal"):
        assert np.all(np.isfinite(estimate_attitude(gyr, acc, mag, FS, offline=True, model=model)))
    with pytest.raises(ValueError, match="rad/s"):
        estimate_attitude(np.degrees(gyr) * 20, acc, mag, FS, offline=True)

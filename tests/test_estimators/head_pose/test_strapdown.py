"""Strapdown inertial navigation (the helmet-tracking paper): accuracy against closed forms and
analytic motion."""

from __future__ import annotations

import numpy as np
import pytest
from _trajectories import G_WORLD, circle_motion
from scipy.spatial.transform import Rotation

from estimators.head_pose.strapdown import Strapdown, coarse_alignment, static_gyro_bias
from estimators.rotations import (
    GRAVITY,
    quat_conjugate,
    quat_from_rotvec,
    quat_from_ypr,
    quat_multiply,
    quat_rotate_inverse,
    rotation_angle,
)

F_REST = -G_WORLD  # a level IMU at rest reads +g up


def test_circle_motion_rates_are_consistent():
    """The generator's body rate is the derivative of its attitude (guards the other tests)."""
    t = np.linspace(0.0, 10.0, 101)
    h = 1e-6
    m0, m1 = circle_motion(t - h), circle_motion(t + h)
    dq = quat_multiply(quat_conjugate(m0["q"]), m1["q"])  # body-frame increment
    w_num = Rotation.from_quat(dq[:, [1, 2, 3, 0]]).as_rotvec() / (2 * h)
    np.testing.assert_allclose(w_num, circle_motion(t)["w"], atol=1e-7)
    np.testing.assert_allclose((m1["v"] - m0["v"]) / (2 * h), circle_motion(t)["a"], atol=1e-6)


def test_rk4_constant_rate_matches_closed_form():
    rate = 1000.0
    n = 10_000
    axis = np.array([0.3, -0.5, 0.8])
    w = 1.3 * axis / np.linalg.norm(axis)  # rad/s
    q0 = quat_from_ypr(np.array([[0.4, -0.2, 0.7]]))
    nav = Strapdown(1, rate)
    nav.reset(np.zeros(3), np.zeros(3), q0, gyr=w, acc=[0, 0, GRAVITY])
    traj = nav.propagate(np.tile(w, (1, n, 1)), np.zeros((1, n, 3)))
    t = np.arange(1, n + 1) / rate
    exact = quat_multiply(q0[:, None], quat_from_rotvec(w * t[:, None])[None])
    err = rotation_angle(quat_multiply(quat_conjugate(exact), traj.q))
    assert err.max() < 1e-6
    assert err.max() < 1e-10  # RK4 is far better than the requirement


def test_linearly_varying_rate_about_a_fixed_axis_matches_closed_form():
    """A rate growing linearly along a fixed axis turns by the integral of its magnitude,
    ``(|w0| + |w1|) dt / 2`` per interval; RK4 leaves only its O(dt^5) local error."""
    rate, n = 100.0, 200
    axis = np.array([0.6, -0.0, 0.8])
    mag = np.linspace(0.0, 6.0, n + 1)  # rad/s, up to 0.06 rad per 10 ms step
    gyr = mag[:, None] * axis
    q0 = quat_from_ypr(np.array([[0.3, 0.2, -0.1]]))
    nav = Strapdown(1, rate)
    nav.reset(np.zeros(3), np.zeros(3), q0, gyr=gyr[0], acc=F_REST)
    traj = nav.propagate(gyr[None, 1:], np.tile(F_REST, (1, n, 1)))
    angle = np.cumsum(0.5 * (mag[:-1] + mag[1:]) / rate)
    exact = quat_multiply(q0, quat_from_rotvec(angle[:, None] * axis))
    err = rotation_angle(quat_multiply(quat_conjugate(exact), traj.q[0]))
    assert err.max() < 1e-7  # 1.3e-8 rad after 2 s at 100 Hz, 6 rad/s at the end
    # Euler's step (q <- q exp(w1 dt)) would be off by ~0.03 rad here: the test can tell.


def test_rk4_step_with_a_turning_rate_vector_matches_a_fine_integration(rng):
    """One 10 ms interval whose rate vector changes direction (no closed form): the kernel's RK4
    step on the linear rate against 2000 exact sub-rotations of the same linear rate."""
    b = 4
    w0 = rng.normal(0.0, 2.0, (b, 3))
    w1 = rng.normal(0.0, 2.0, (b, 3))
    q0 = quat_from_ypr(rng.uniform(-1, 1, (b, 3)))
    nav = Strapdown(b, 100.0)
    nav.reset(np.zeros((b, 3)), np.zeros((b, 3)), q0, gyr=w0, acc=np.tile(F_REST, (b, 1)))
    q1 = nav.propagate(w1[:, None], np.tile(F_REST, (b, 1, 1))).q[:, 0]
    fine, m = q0, 2000
    for j in range(m):
        s = (j + 0.5) / m
        fine = quat_multiply(fine, quat_from_rotvec((w0 + s * (w1 - w0)) * (0.01 / m)))
    err = rotation_angle(quat_multiply(quat_conjugate(fine), q1))
    assert err.max() < 1e-6  # rates of a few rad/s over a 10 ms step: RK4 O((|w| dt)^5)


def test_biases_are_removed_from_both_ends_of_every_interval(rng):
    """Samples carrying constant biases, propagated with those biases given, retrace the
    bias-free run (to rounding), for every user of a batch."""
    b, n = 3, 400
    gyr = rng.normal(0.0, 2.0, (b, n, 3))
    acc = rng.normal(0.0, 3.0, (b, n, 3)) + F_REST
    bg = rng.normal(0.0, 0.05, (b, 3))
    ba = rng.normal(0.0, 0.2, (b, 3))
    q0 = quat_from_ypr(rng.uniform(-1, 1, (b, 3)))
    p0, v0 = rng.normal(size=(b, 3)), rng.normal(size=(b, 3))
    clean, biased = Strapdown(b, 500.0), Strapdown(b, 500.0)
    clean.reset(p0, v0, q0, gyr=gyr[:, 0], acc=acc[:, 0])
    biased.reset(p0, v0, q0, gyr=gyr[:, 0] + bg, acc=acc[:, 0] + ba)
    ref = clean.propagate(gyr[:, 1:], acc[:, 1:])
    out = biased.propagate(
        gyr[:, 1:] + bg[:, None], acc[:, 1:] + ba[:, None], gyro_bias=bg, accel_bias=ba
    )
    np.testing.assert_allclose(out.q, ref.q, atol=1e-12)
    np.testing.assert_allclose(out.v, ref.v, atol=1e-10)
    np.testing.assert_allclose(out.p, ref.p, atol=1e-10)
    # Without the biases the runs part: the comparison above can fail.
    off = Strapdown(b, 500.0)
    off.reset(p0, v0, q0, gyr=gyr[:, 0] + bg, acc=acc[:, 0] + ba)
    drift = off.propagate(gyr[:, 1:] + bg[:, None], acc[:, 1:] + ba[:, None])
    assert np.abs(drift.p - ref.p).max() > 1e-3


def test_analytic_trajectory_position_within_1mm():
    rate = 1000.0
    n = 10_000
    t = np.arange(n + 1) / rate
    m = circle_motion(t)
    nav = Strapdown(1, rate)
    nav.reset(m["p"][0], m["v"][0], m["q"][0], gyr=m["w"][0], acc=m["f"][0])
    traj = nav.propagate(m["w"][None, 1:], m["f"][None, 1:])
    pos_err = np.linalg.norm(traj.p[0] - m["p"][1:], axis=-1)
    att_err = rotation_angle(quat_multiply(quat_conjugate(m["q"][1:]), traj.q[0]))
    assert pos_err.max() < 1e-3
    assert pos_err.max() < 1e-4  # measured 3.7e-5 m (trapezoid dt^2 error on the bob's jerk)
    assert att_err.max() < 1e-6  # 1.8e-7: dt^3 |w''| / 12 per step from the linear hold of w


def test_tumbling_at_rest_keeps_position():
    """Uniform rotation about a horizontal axis, at rest (the paper's turntable test): the body
    sees gravity turn at 1 rad/s; the end-point trapezoid cancels it exactly at every sample."""
    rate, n = 1000.0, 20_000
    w = np.array([1.0, 0.0, 0.0])
    t = np.arange(n + 1) / rate
    q = quat_from_rotvec(w * t[:, None])
    f = quat_rotate_inverse(q, -G_WORLD)
    nav = Strapdown(1, rate)
    nav.reset(np.zeros(3), np.zeros(3), q[0], gyr=w, acc=f[0])
    traj = nav.propagate(np.tile(w, (1, n, 1)), f[None, 1:])
    assert np.abs(traj.p).max() < 1e-6
    # The mid-interval alternative would drift by g (w dt)^2 / 8 * t^2 / 2 = 2.5e-4 m here.


def test_accelerometer_bias_gives_half_b_t_squared():
    rate, n = 1000.0, 10_000
    b = np.array([0.02, -0.05, 0.01])  # m/s^2, level and still: body = world axes
    acc = np.tile(F_REST + b, (1, n, 1))
    nav = Strapdown(1, rate)
    nav.reset(np.zeros(3), np.zeros(3), [1, 0, 0, 0], gyr=np.zeros(3), acc=acc[0, 0])
    traj = nav.propagate(np.zeros((1, n, 3)), acc)
    t = np.arange(1, n + 1) / rate
    np.testing.assert_allclose(traj.p[0], 0.5 * b * t[:, None] ** 2, rtol=1e-9, atol=1e-12)
    # Correcting with the known bias removes the drift entirely.
    nav.reset(np.zeros(3), np.zeros(3), [1, 0, 0, 0], gyr=np.zeros(3), acc=acc[0, 0])
    traj = nav.propagate(np.zeros((1, n, 3)), acc, accel_bias=b)
    assert np.abs(traj.p).max() < 1e-9


def test_gyro_bias_gives_g_b_t_cubed_over_six():
    """A roll-rate bias b tilts the platform by b t: the horizontal error is g b t^3 / 6."""
    rate, n = 1000.0, 10_000
    bx = 1e-4  # rad/s, small enough for the small-angle law
    nav = Strapdown(1, rate)
    nav.reset(np.zeros(3), np.zeros(3), [1, 0, 0, 0])
    gyr = np.tile([bx, 0.0, 0.0], (1, n, 1))
    traj = nav.propagate(gyr, np.tile([0.0, 0.0, GRAVITY], (1, n, 1)))
    t = np.arange(1, n + 1) / rate
    # Rolling by +b t turns body z toward world -y: the y acceleration is -g sin(b t).
    expected = -GRAVITY * bx * t**3 / 6
    np.testing.assert_allclose(traj.p[0, :, 1], expected, rtol=1e-3, atol=1e-9)


def test_static_bias_calibration_and_zero_order_start(rng):
    n = 2000
    bias = np.array([[0.01, -0.02, 0.005]])
    gyr = bias[:, None] + rng.normal(0, 0.005, (1, n, 3))
    est = static_gyro_bias(gyr)
    assert np.abs(est - bias).max() < 5 * 0.005 / np.sqrt(n)
    # Without a sample at the reset instant the first one is held: a constant rate is still exact.
    nav = Strapdown(1, 100.0)
    nav.reset(np.zeros(3), np.zeros(3), [1, 0, 0, 0])
    w = np.array([0.0, 0.0, 1.0])
    traj = nav.propagate(np.tile(w, (1, 100, 1)), np.tile([0, 0, GRAVITY], (1, 100, 1)))
    assert abs(rotation_angle(traj.q[0, -1]) - 1.0) < 1e-10


def test_coarse_alignment_recovers_attitude(rng):
    b = 50
    q_true = Rotation.random(b, random_state=1).as_quat()[:, [3, 0, 1, 2]]
    field = np.array([0.0, 20.0, -40.0])  # uT, north along +y, dipping down
    acc = quat_rotate_inverse(q_true, -G_WORLD)
    mag = quat_rotate_inverse(q_true, field)
    q = coarse_alignment(acc, mag, field)
    assert rotation_angle(quat_multiply(quat_conjugate(q_true), q)).max() < 1e-9
    with pytest.raises(ValueError, match="acc_mean"):
        coarse_alignment(acc / GRAVITY, mag, field)  # g units
    with pytest.raises(ValueError, match="vertical"):
        coarse_alignment(acc[:1], acc[:1], field)


def test_reset_mask_and_batch_independence(rng):
    n = 300
    gyr = rng.normal(0, 1, (2, n, 3))
    acc = rng.normal(0, 1, (2, n, 3)) + F_REST
    both = Strapdown(2, 200.0)
    both.reset(np.zeros((2, 3)), np.zeros((2, 3)), np.tile([1.0, 0, 0, 0], (2, 1)))
    both.propagate(gyr, acc)
    before = both.p.copy()
    q1 = quat_from_ypr(np.array([1.0, 0.1, 0.0]))
    both.reset([4.0, 5.0, 6.0], [1.0, 2.0, 3.0], np.tile(q1, (2, 1)), mask=[True, False])
    np.testing.assert_array_equal(both.p[1], before[1])
    np.testing.assert_array_equal(both.p[0], [4.0, 5.0, 6.0])
    out = both.propagate(gyr, acc)
    single = Strapdown(1, 200.0)
    single.reset([4.0, 5.0, 6.0], [1.0, 2.0, 3.0], q1)
    np.testing.assert_array_equal(single.propagate(gyr[:1], acc[:1]).p[0], out.p[0])


def test_bad_input_names_the_field():
    nav = Strapdown(2, 100.0)
    with pytest.raises(ValueError, match="gyr"):
        nav.propagate(np.zeros((3, 4, 3)), np.zeros((3, 4, 3)))
    with pytest.raises(ValueError, match="acc"):
        nav.propagate(np.zeros((2, 4, 3)), np.zeros((2, 5, 3)))
    with pytest.raises(ValueError, match="NaN"):
        nav.propagate(np.full((2, 4, 3), np.nan), np.zeros((2, 4, 3)))
    with pytest.raises(ValueError, match="rate_hz"):
        Strapdown(1, 0.0)
    with pytest.raises(ValueError, match="batch_size"):
        Strapdown(0, 100.0)
    with pytest.raises(ValueError, match="q"):
        nav.reset(np.zeros(3), np.zeros(3), np.zeros((2, 4)))

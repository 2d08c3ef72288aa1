"""Strapdown inertial navigation of the helmet-tracking paper (inertial part of the helmet pose),
batched.

Source: the helmet-tracking paper, section 2.1 ("慣性捷聯(lián)位姿解算"): the attitude quaternion
obeys ``q_dot = 0.5 q ⊗ [0, w]`` and is integrated "e.g. with the Runge-Kutta method"; the specific
force is rotated into the navigation frame, gravity is removed, and the result is integrated twice
for velocity and position. The paper gives no discretisation; the choices below are ours.

Conventions (:mod:`estimators.rotations`): ENU world (z up), Hamilton ``q = [w, x, y, z]``
rotating body coordinates into the world, gyro ``w`` in rad/s in the body frame, accelerometer
``f`` the specific force in m/s^2 in the body frame, ``f = R^T (a_world - g_world)`` with
``g_world = [0, 0, -g]``: a level sensor at rest reads ``[0, 0, +g]``.

Discretisation (one interval ``[t_{k-1}, t_k]`` of length ``dt = 1 / rate_hz``)
-----------------------------------------------------------------------------
* Attitude: one classical RK4 step of ``q_dot = 0.5 q ⊗ [0, w(t)]`` with ``w(t)`` linear between
  the samples at ``t_{k-1}`` and ``t_k`` (RK4's midpoint stages use the mean rate), then
  renormalised. Local error O(dt^5) for the ODE, O(dt^3) from the linear interpolation of ``w``:
  10 s of a constant 1 rad/s rotation at 1 kHz stays within 1e-12 rad of the closed form.
* Velocity: trapezoid on the world acceleration at the two ends, ``a_k = R(q_k) f_k + g_world``,
  ``v_k = v_{k-1} + dt (a_{k-1} + a_k) / 2``. A common alternative is "the mid-interval attitude"
  (``R(q_mid) (f_{k-1} + f_k) / 2``); rotating each sample with the attitude *at its own instant*
  and averaging in the world is the same order, but exact whenever the world acceleration is linear
  over the interval. The mid-attitude form is not exact even at rest while rotating: the two body
  samples of gravity, averaged, are shortened by ``cos(|w| dt / 2)``, a vertical acceleration error
  ``g (|w| dt)^2 / 8`` that integrates twice: in the paper's 120 s uniform-rotation test (1 rad/s, 1
  kHz) that is 9 mm of position from the discretisation alone, where the end-point form stays at
  1e-8 m (``tests/test_estimators/head_pose/test_strapdown.py``). On the 10 s walking-circle
  trajectory of the tests both end within 4e-5 m of the truth at 1 kHz (the trapezoid's ``dt^2``
  error on the head bob's jerk; the mid-attitude form 3e-5 m).
* Position: trapezoid on the velocity, ``p_k = p_{k-1} + dt (v_{k-1} + v_k) / 2``.

Timing: the state always refers to the instant of the last sample consumed. :meth:`Strapdown.reset`
sets the state at a sample instant; pass that instant's sample to ``reset`` (``gyr=``, ``acc=``)
for an exact first interval. Without it the first sample after a reset is held over the first
interval (zero-order hold; an O(dt^2) error in v once, negligible at 100 Hz and above).

Biases: ``propagate`` subtracts the given biases from both ends of each interval; the seed
calibrates them before its experiments (static gyro bias: :func:`static_gyro_bias`; the
accelerometer on a turntable, which we do not model).

The per-sample loop is the one mechanisation of the project,
:func:`estimators.head_pose._kernel.strapdown_run` (the visual-inertial filter's prediction
runs the same :func:`~estimators.head_pose._kernel._mech_step`);
``tests/test_estimators/head_pose/test_strapdown.py``
checks it against closed forms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import stream_rows
from estimators.head_pose import _kernel as _k
from estimators.rotations import (
    GRAVITY,
    ensure_quaternion,
    matrix_to_quat,
)
from estimators.validation import check_array, check_batch_size, check_rate, check_value

__all__ = [
    "Strapdown",
    "StrapdownTrajectory",
    "coarse_alignment",
    "set_nominal_state",
    "static_gyro_bias",
]


# ------------------------------------------------------------------------------------------------
# Validation helpers.
# ------------------------------------------------------------------------------------------------


def _rows_arg(a: ArrayLike | None, name: str, b: int, n: int, default: NDArray) -> NDArray:
    """A per-user (B, n) argument that may be given as (n,) (same for all) or None (default)."""
    if a is None:
        return np.broadcast_to(default, (b, n)).astype(np.float64)
    arr = np.asarray(a, dtype=np.float64)
    if arr.shape == (n,):
        arr = np.broadcast_to(arr, (b, n))
    return check_array(arr, name, (b, n)).copy()


def _check_gravity(gravity: object) -> float:
    """``gravity`` as a float, a ValueError unless in [9, 10.5] m/s^2."""
    check_value("gravity", gravity, 9.0, 10.5, "m/s^2")
    return float(gravity)  # type: ignore[arg-type]


# ------------------------------------------------------------------------------------------------
# Public API.
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class StrapdownTrajectory:
    """Per-sample output of :meth:`Strapdown.propagate`.

    Attributes:
        q: (B, N, 4) attitude body -> world after each sample.
        v: (B, N, 3) world velocity, m/s.
        p: (B, N, 3) world position, m.
    """

    q: NDArray[np.float64]
    v: NDArray[np.float64]
    p: NDArray[np.float64]


def set_nominal_state(
    x: NDArray[np.float64],
    rows: NDArray[np.intp],
    p: ArrayLike,
    v: ArrayLike,
    q: ArrayLike,
    accel_bias: ArrayLike | None = None,
    gyro_bias: ArrayLike | None = None,
    gyr: ArrayLike | None = None,
    acc: ArrayLike | None = None,
) -> float:
    """Write a checked nominal state into rows ``rows`` of the kernels' state array ``x``
    (B, ``N_X``): position, velocity, attitude, biases and the IMU sample at this instant.

    The arguments are as in :meth:`Strapdown.reset` (``accel_bias``, ``gyro_bias`` (B, 3) or (3,)
    m/s^2 and rad/s, None: zero); the filter of :mod:`estimators.head_pose.visual_inertial` shares
    it.

    Returns:
        1.0 when the sample at this instant was given (it starts the first interval), else 0.0.
    """
    b = x.shape[0]
    qa = np.asarray(q, dtype=np.float64)
    qa = ensure_quaternion(np.broadcast_to(qa, (b, 4)) if qa.shape == (4,) else qa, "q")
    qa = check_array(qa, "q", (b, 4))
    pa = _rows_arg(p, "p", b, 3, np.zeros(3))
    va = _rows_arg(v, "v", b, 3, np.zeros(3))
    ba = _rows_arg(accel_bias, "accel_bias", b, 3, np.zeros(3))
    bg = _rows_arg(gyro_bias, "gyro_bias", b, 3, np.zeros(3))
    if (gyr is None) != (acc is None):
        raise ValueError("gyr and acc at the reset instant must be given together (or neither)")
    x[rows, _k.X_P : _k.X_P + 3] = pa[rows]
    x[rows, _k.X_V : _k.X_V + 3] = va[rows]
    x[rows, _k.X_Q : _k.X_Q + 4] = qa[rows]
    x[rows, _k.X_BA : _k.X_BA + 3] = ba[rows]
    x[rows, _k.X_BG : _k.X_BG + 3] = bg[rows]
    if gyr is None:
        x[rows, _k.X_GYR :] = 0.0
        return 0.0
    x[rows, _k.X_GYR : _k.X_GYR + 3] = _rows_arg(gyr, "gyr", b, 3, np.zeros(3))[rows]
    x[rows, _k.X_ACC : _k.X_ACC + 3] = _rows_arg(acc, "acc", b, 3, np.zeros(3))[rows]
    return 1.0


class Strapdown:
    """Batched strapdown inertial navigation (B independent users).

    Args:
        batch_size: number of users B, >= 1.
        rate_hz: IMU sampling rate, Hz (uniform samples).
        gravity: gravity magnitude, m/s^2 (world gravity ``[0, 0, -gravity]``).

    The state starts at identity attitude, zero velocity and position, with no previous sample;
    call :meth:`reset` to set it.

    Example:
        >>> nav = Strapdown(1, 1000.0)
        >>> traj = nav.propagate(np.zeros((1, 5, 3)), np.tile([0, 0, GRAVITY], (1, 5, 1)))
        >>> traj.p.shape, float(abs(traj.p).max())
        ((1, 5, 3), 0.0)
    """

    def __init__(self, batch_size: int, rate_hz: float, gravity: float = GRAVITY) -> None:
        self.batch_size = check_batch_size(batch_size)
        self.rate_hz = check_rate(rate_hz, "rate_hz")
        self.dt = 1.0 / self.rate_hz
        self.gravity = _check_gravity(gravity)
        self._x = np.zeros((self.batch_size, _k.N_X))
        self._x[:, _k.X_Q] = 1.0
        self._has_prev = np.zeros(self.batch_size)

    def reset(
        self,
        p: ArrayLike,
        v: ArrayLike,
        q: ArrayLike,
        mask: ArrayLike | None = None,
        gyr: ArrayLike | None = None,
        acc: ArrayLike | None = None,
    ) -> None:
        """Set the state of some or all users at a sample instant.

        Args:
            p: (B, 3) or (3,) world position, m.
            v: (B, 3) or (3,) world velocity, m/s.
            q: (B, 4) or (4,) attitude body -> world (normalised here).
            mask: users to reset, (B,) bool or indices; None: all. Only the selected rows of
                ``p``, ``v``, ``q`` are used.
            gyr, acc: (B, 3) or (3,) the IMU sample *at this instant* (rad/s, m/s^2), used as the
                start of the first interval; None: the first sample after the reset is held over
                the first interval.

        Raises:
            ValueError: wrong shapes, non-finite values, zero quaternion, bad mask.
        """
        rows = stream_rows(mask, self.batch_size, "mask", unique=False)
        self._has_prev[rows] = set_nominal_state(self._x, rows, p, v, q, gyr=gyr, acc=acc)

    def propagate(
        self,
        gyr: ArrayLike,
        acc: ArrayLike,
        gyro_bias: ArrayLike | None = None,
        accel_bias: ArrayLike | None = None,
    ) -> StrapdownTrajectory:
        """Integrate N samples per user.

        Args:
            gyr: (B, N, 3) body angular rate, rad/s.
            acc: (B, N, 3) specific force, m/s^2 (level at rest: ``[0, 0, +g]``).
            gyro_bias: (B, 3) or (3,) gyro bias subtracted from every sample, rad/s; None: zero.
            accel_bias: (B, 3) or (3,) accelerometer bias subtracted, m/s^2; None: zero.

        Returns:
            The state after each sample (:class:`StrapdownTrajectory`).

        Raises:
            ValueError: wrong shapes or non-finite samples.
        """
        b = self.batch_size
        g = check_array(gyr, "gyr", (b, -1, 3))
        a = check_array(acc, "acc", g.shape)
        x = self._x
        x[:, _k.X_BG : _k.X_BG + 3] = _rows_arg(gyro_bias, "gyro_bias", b, 3, np.zeros(3))
        x[:, _k.X_BA : _k.X_BA + 3] = _rows_arg(accel_bias, "accel_bias", b, 3, np.zeros(3))
        n = g.shape[1]
        out_q = np.empty((b, n, 4))
        out_v = np.empty((b, n, 3))
        out_p = np.empty((b, n, 3))
        _k.strapdown_run(
            x,
            self._has_prev,
            np.ascontiguousarray(g),
            np.ascontiguousarray(a),
            self.dt,
            self.gravity,
            out_q,
            out_v,
            out_p,
        )
        return StrapdownTrajectory(out_q, out_v, out_p)

    @property
    def q(self) -> NDArray[np.float64]:
        """(B, 4) current attitude body -> world."""
        return self._x[:, _k.X_Q : _k.X_Q + 4].copy()

    @property
    def v(self) -> NDArray[np.float64]:
        """(B, 3) current world velocity, m/s."""
        return self._x[:, _k.X_V : _k.X_V + 3].copy()

    @property
    def p(self) -> NDArray[np.float64]:
        """(B, 3) current world position, m."""
        return self._x[:, _k.X_P : _k.X_P + 3].copy()


def coarse_alignment(acc_mean: ArrayLike, mag_mean: ArrayLike, field_world: ArrayLike) -> NDArray:
    """Initial attitude of a stationary IMU from gravity and the magnetic field (TRIAD).

    The primary vector is gravity (exact direction: the accelerometer at rest reads "up"), the
    secondary the magnetic field (only its component orthogonal to up is used, so the dip and the
    field's magnitude do not matter). Body triad: ``u = f/|f|``, ``e = (f x m)/|f x m|``,
    ``n = u x e``; world triad the same from ``[0, 0, 1]`` and ``field_world``.

    Args:
        acc_mean: (B, 3) mean specific force at rest, m/s^2 (body).
        mag_mean: (B, 3) mean magnetic field, any unit (body).
        field_world: (3,) the field in the world (same unit; e.g. ``[0, B_h, -B_v]`` for magnetic
            north along +y in ENU).

    Returns:
        (B, 4) quaternions body -> world (``w >= 0``).

    Raises:
        ValueError: shapes, non-finite values, a specific force far from g (not at rest:
            norm outside [0.5 g, 1.5 g]) or a field (anti)parallel to gravity (within 1 deg).
    """
    f = check_array(acc_mean, "acc_mean", (-1, 3))
    m = check_array(mag_mean, "mag_mean", f.shape)
    fw = check_array(field_world, "field_world", (3,))
    fn = np.linalg.norm(f, axis=-1)
    if np.any((fn < 0.5 * GRAVITY) | (fn > 1.5 * GRAVITY)):
        raise ValueError(
            f"acc_mean norms must be in [{0.5 * GRAVITY:.2f}, {1.5 * GRAVITY:.2f}] m/s^2 "
            f"(a stationary IMU reads g), got {fn}"
        )

    def triad(up: NDArray, field: NDArray, name: str) -> NDArray:
        u = up / np.linalg.norm(up, axis=-1, keepdims=True)
        e = np.cross(up, field)
        en = np.linalg.norm(e, axis=-1, keepdims=True)
        fnorm = np.linalg.norm(field, axis=-1, keepdims=True)
        upn = np.linalg.norm(up, axis=-1, keepdims=True)
        if np.any(en <= math.sin(math.radians(1.0)) * upn * fnorm):
            raise ValueError(f"{name} must not be within 1 deg of the vertical (no heading)")
        e = e / en
        n = np.cross(u, e)
        return np.stack([u, e, n], axis=-1)  # columns

    body = triad(f, m, "mag_mean")
    world = triad(np.array([0.0, 0.0, 1.0]), fw, "field_world")
    rot = world @ np.swapaxes(body, -1, -2)
    return matrix_to_quat(rot)


def static_gyro_bias(gyr: ArrayLike) -> NDArray[np.float64]:
    """Gyro bias from a stationary recording: the per-axis mean rate.

    The seed calibrates its IMU before the experiments (turntable for the accelerometer, the
    gyro's zero-rate output at rest); at rest the true rate is zero (Earth's 7.3e-5 rad/s is
    below a MEMS gyro's noise and ignored), so the mean of N samples estimates the bias with a
    standard error ``noise_density * sqrt(rate / N)``.

    Args:
        gyr: (B, N, 3) body angular rate at rest, rad/s, N >= 1.

    Returns:
        (B, 3) bias, rad/s, to pass as ``gyro_bias`` to :meth:`Strapdown.propagate`.
    """
    g = check_array(gyr, "gyr", (-1, -1, 3))
    if g.shape[1] < 1:
        raise ValueError("gyr must hold at least one sample per user (N >= 1)")
    return g.mean(axis=1)

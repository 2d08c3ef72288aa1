"""Stage 3 of Yao 2023's hand pipeline, compiled: eq (1)/(2), the Kalman filter, the median.

The scalar stages run per user and frame inside the pipeline's kernel
(:data:`estimators.hand._kernel.pipeline.hand_kernel`) and alone, without target selection and
joint smoothing, in :data:`filter_kernel` (Kalman and median over raw angles) after
:data:`angles_kernel` (eq (1)/(2) of quaternions): the same scalar functions, so
:class:`~estimators.hand.orientation.OrientationFilter`, which drives them, gives the pipeline's
angles bit for bit.

* :func:`_paper_ypr` / :func:`quat_angles` — eq (1), or eq (2) where ``|wy - zx|`` exceeds the
  threshold (Yao 2023, 1.3; the names are discussed in :mod:`estimators.hand.angles`);
* :func:`kalman_step` — the Kalman filter of each angle (1.4; the model is documented in
  :class:`~estimators.hand.params.KalmanParams`);
* :func:`median_step` — the median over the last Kalman angles.

Layouts: the per-user state is a (B,) record array of :data:`USER_FIELDS` and the median window
(B, window, 3), newest first; the per-angle parameters a (3,) record of :data:`AXIS_FIELDS`.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from estimators.kernels.batch import BatchKernel
from estimators.kernels.records import state_records
from estimators.kernels.rotations import wrap_angle

__all__ = [
    "AXIS_FIELDS",
    "MIN_QUAT_NORM",
    "USER_FIELDS",
    "angles_kernel",
    "filter_kernel",
    "forget_orientation",
    "kalman_step",
    "median_step",
    "new_filter_state",
    "quat_angles",
    "shared_layout",
    "write_angles",
]


#: Per-angle parameter record fields, ``[yaw, pitch, roll]`` rows.
AXIS_FIELDS = (
    "measurement_var",  # rad^2
    "accel_psd",  # angular acceleration PSD at rest, rad^2/s^3
    "max_accel_psd",  # cap of the adapted PSD, rad^2/s^3
    "init_rate_var",  # rate variance at (re)initialisation, rad^2/s^2
)

#: Per-user state (B,): Kalman filter per angle, median output and the held outputs.
USER_FIELDS = {
    "angle": (3,),  # unwrapped Kalman angle, rad (NaN before the first measurement)
    "rate": (3,),  # rad/s
    "p00": (3,),  # covariance of [angle, rate]
    "p01": (3,),
    "p11": (3,),
    "nis": (3,),  # low-passed normalised innovation squared
    "active": (),  # 1.0 while the filter holds an estimate that is updated or coasted
    "missed": (),  # frames since the last usable wrist quaternion
    "median": (3,),  # last median of the Kalman angles, rad (unwrapped)
    "ypr_raw": (3,),  # last usable eq (1)/(2) angles, rad
    "ypr_kalman": (3,),  # last Kalman output, wrapped to (-pi, pi], rad
}

MIN_QUAT_NORM = 1e-6  # below this a quaternion is treated as a dropout (no orientation)

_LAYOUTS: dict[np.dtype, np.dtype] = {}


def shared_layout(a: NDArray) -> NDArray:
    """``a``, a record array, viewed with the one dtype object of its layout, so that numba's
    dispatcher finds the record type by identity whichever pipeline built the array."""
    return a.view(_LAYOUTS.setdefault(a.dtype, a.dtype))


@numba.njit(cache=True, inline="always")
def forget_orientation(s, win):
    """Clear one user's angle filters: Kalman inactive, outputs NaN, median window empty."""
    s["active"] = 0.0
    for c in range(3):
        s["angle"][c] = np.nan
        s["rate"][c] = 0.0
        s["median"][c] = np.nan
        s["ypr_raw"][c] = np.nan
        s["ypr_kalman"][c] = np.nan
        for i in range(win.shape[0]):
            win[i, c] = np.nan


@numba.njit(cache=True, inline="always")
def _paper_ypr(w, x, y, z, threshold):
    """Eq (1), or eq (2) where ``|wy - zx| > threshold``, of a unit quaternion in our order:
    ``(about_z, pitch, about_x, singular)`` (see :mod:`estimators.hand.angles` for the names)."""
    s = w * y - z * x
    singular = abs(s) > threshold
    about_x = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(min(max(2.0 * s, -1.0), 1.0))
    about_z = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    if singular:
        sgn = 1.0 if s > 0.0 else -1.0
        about_z = wrap_angle(-2.0 * sgn * math.atan2(x, w))
        pitch = sgn * (0.5 * np.pi)
        about_x = 0.0
    return about_z, pitch, about_x, singular


@numba.njit(cache=True, inline="always")
def quat_angles(qw, qx, qy, qz, threshold):
    """A quaternion of any norm to eq (1)/(2) angles: ``(usable, about_z, pitch, about_x,
    singular)``; not usable (NaN, infinite or norm <= 1e-6) gives the identity's angles."""
    norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    usable = math.isfinite(norm) and norm > MIN_QUAT_NORM
    if usable:
        w, x, y, z = qw / norm, qx / norm, qy / norm, qz / norm
    else:
        w, x, y, z = 1.0, 0.0, 0.0, 0.0
    about_z, pitch, about_x, singular = _paper_ypr(w, x, y, z, threshold)
    return usable, about_z, pitch, about_x, singular


@numba.njit(cache=True, inline="always")
def _kalman_axis(s, c, a, p, z, init, a_act, upd, stale):
    """One frame of the Kalman filter of angle ``c`` (axis parameters ``a``): (re)initialise
    from ``z``, predict and correct with ``z``, predict only, or stop a stale stream's rate."""
    dt = p["dt"]
    p00_0 = s["p00"][c]
    p01_0 = s["p01"][c]
    p11_0 = s["p11"][c]
    a_p = s["angle"][c] + dt * s["rate"][c]
    nis_old = s["nis"][c]
    q = min(a["accel_psd"] * max(nis_old, 1.0) ** 2, a["max_accel_psd"])
    p00 = p00_0 + 2.0 * dt * p01_0 + dt * dt * p11_0 + q * p["dt3_3"]
    p01 = p01_0 + dt * p11_0 + q * p["dt2_2"]
    p11 = p11_0 + q * dt
    if init:
        s["angle"][c] = z
        s["rate"][c] = 0.0
        s["p00"][c] = a["measurement_var"]
        s["p01"][c] = 0.0
        s["p11"][c] = a["init_rate_var"]
        s["nis"][c] = 1.0
    elif a_act:
        if upd:
            a_p0 = a_p if math.isfinite(a_p) else 0.0
            innov = wrap_angle(z - a_p0)
            sv = p00 + a["measurement_var"]
            k0 = p00 / sv
            k1 = p01 / sv
            nis = innov * innov / sv
            s["nis"][c] = nis_old + p["nis_gain"] * (nis - nis_old)
            s["angle"][c] = a_p + k0 * innov
            s["rate"][c] = s["rate"][c] + k1 * innov
            s["p00"][c] = (1.0 - k0) * p00
            s["p01"][c] = (1.0 - k0) * p01
            s["p11"][c] = p11 - k1 * p01
        else:
            s["angle"][c] = a_p
            s["p00"][c] = p00
            s["p01"][c] = p01
            s["p11"][c] = p11
    elif stale:
        s["rate"][c] = 0.0


@numba.njit(cache=True, inline="always")
def kalman_step(s, axes, p, ok, z0, z1, z2):
    """The Kalman filters of the three angles, measurement ``z`` where ``ok``; returns
    ``(init, active)``: re-initialised this frame, holds an estimate after it."""
    act = s["active"] != 0.0
    missed = 0.0 if ok else s["missed"] + 1.0
    s["missed"] = missed
    stale = act and missed > p["max_coast_frames"]
    init = ok and not act
    upd = act and ok
    a_act = act and not stale
    _kalman_axis(s, 0, axes[0], p, z0, init, a_act, upd, stale)
    _kalman_axis(s, 1, axes[1], p, z1, init, a_act, upd, stale)
    _kalman_axis(s, 2, axes[2], p, z2, init, a_act, upd, stale)
    active = a_act or init
    s["active"] = 1.0 if active else 0.0
    if active:
        for c in range(3):
            s["ypr_kalman"][c] = wrap_angle(s["angle"][c])
    return init, active


@numba.njit(cache=True, inline="always")
def _sorted_at(win, c, k):
    """The ``k``-th (0-based) finite value of ``win[:, c]`` in ascending order, ties in window
    order (a stable sort's order)."""
    for i in range(win.shape[0]):
        v = win[i, c]
        if not math.isfinite(v):
            continue
        rank = 0
        for i2 in range(win.shape[0]):
            u = win[i2, c]
            if math.isfinite(u) and (u < v or (u == v and i2 < i)):
                rank += 1
        if rank == k:
            return v
    return np.nan


@numba.njit(cache=True, inline="always")
def write_angles(s, r, o_raw, o_kalman, o_ypr) -> bool:
    """Row ``r`` of the outputs from the stream's state ``s``: the raw, Kalman and median-filtered
    angles (rad); whether the Kalman estimate is finite (the row is valid)."""
    valid = True
    for c in range(3):
        o_raw[r, c] = s["ypr_raw"][c]
        o_kalman[r, c] = s["ypr_kalman"][c]
        o_ypr[r, c] = wrap_angle(s["median"][c])
        if not math.isfinite(s["ypr_kalman"][c]):
            valid = False
    return valid


@numba.njit(cache=True, inline="always")
def median_step(s, win, init, active):
    """Median over the window of Kalman angles: emptied on (re)initialisation, fed while the
    filter is active (its median then in ``s["median"]``, NaN without a finite sample)."""
    if init:
        for c in range(3):
            s["median"][c] = np.nan
            for i in range(win.shape[0]):
                win[i, c] = np.nan
    if not active:
        return
    for c in range(3):
        for i in range(win.shape[0] - 1, 0, -1):
            win[i, c] = win[i - 1, c]
        win[0, c] = s["angle"][c]
        n = 0
        for i in range(win.shape[0]):
            if math.isfinite(win[i, c]):
                n += 1
        if n == 0:
            s["median"][c] = np.nan
            continue
        lo = _sorted_at(win, c, (n - 1) // 2)
        hi = lo if n % 2 == 1 else _sorted_at(win, c, n // 2)
        s["median"][c] = 0.5 * (lo + hi)


# ----------------------------------------------------------------------------------------------
# Stage 3 alone: the orientation filter over angle or quaternion sequences


def new_filter_state(batch_size: int, window: int) -> tuple[NDArray, NDArray]:
    """A fresh state ``(user, window)`` for :data:`filter_kernel`: the ``user`` records
    (:data:`USER_FIELDS`) and median windows (B, window, 3) of :func:`new_state`, all forgotten."""
    user = shared_layout(state_records(USER_FIELDS, batch_size))
    user["nis"] = 1.0
    for name in ("angle", "median", "ypr_raw", "ypr_kalman"):
        user[name] = np.nan
    return user, np.full((batch_size, window, 3), np.nan)


def _filter_angles(z, usable, restart, m_count, prm, axes, state, out):
    """Stage 3 without target selection: Kalman then median of B streams of M raw angles.

    The same per-frame steps as :func:`_orientation` after its eq (1)/(2) (:func:`kalman_step`,
    :func:`median_step`), so a stream fed the pipeline's ``ypr_raw`` and ``quat_valid`` (and
    restarted where the pipeline reselected) reproduces its ``ypr_kalman`` and ``ypr``.

    Args:
        z: (B*M, 3) raw ``[yaw, pitch, roll]``, rad, rows ``r = b * M + t``.
        usable: (B*M,) bool, the frame's angles are a measurement (False: a dropout; NaN angles
            are a dropout too).
        restart: (B*M,) bool, forget the stream before this frame (a new target).
        m_count: M.
        prm, axes: the parameter records of :func:`~estimators.hand.params.kernel_params`.
        state: :func:`new_filter_state`'s ``(user, window)``, updated in place.
        out: ``(ypr_raw, ypr_kalman, ypr, valid)``: (B*M, 3) x 3 and (B*M,) bool, written.
    """
    user, window = state
    o_raw, o_kalman, o_ypr, o_valid = out
    for i in numba.prange(user.shape[0]):  # streams are independent (estimators.kernels.batch)
        p = prm[0]
        s = user[i]
        win = window[i]
        for t in range(m_count):
            r = i * m_count + t
            if restart[r]:
                forget_orientation(s, win)
            z0 = z[r, 0]
            z1 = z[r, 1]
            z2 = z[r, 2]
            ok = usable[r] and math.isfinite(z0) and math.isfinite(z1) and math.isfinite(z2)
            if ok:
                s["ypr_raw"][0] = z0
                s["ypr_raw"][1] = z1
                s["ypr_raw"][2] = z2
            init, active = kalman_step(s, axes, p, ok, z0, z1, z2)
            median_step(s, win, init, active)
            o_valid[r] = write_angles(s, r, o_raw, o_kalman, o_ypr)


#: ``filter_kernel(B)(z, usable, restart, m_count, prm, axes, state, out)``.
filter_kernel = BatchKernel(_filter_angles, parallel=False)


def _angle_rows(quat, threshold, out, usable, singular):
    """Eq (1)/(2) of N quaternions of any norm (:func:`quat_angles`), row by row.

    Args:
        quat: (N, 4) ``[w, x, y, z]``. threshold: eq (2) threshold on ``|wy - zx|``.
        out: (N, 3) our ``[yaw, pitch, roll]``, rad, written (the identity's angles where not
            usable). usable, singular: (N,) bool, written.
    """
    for r in numba.prange(quat.shape[0]):
        ok, about_z, pitch, about_x, sing = quat_angles(
            quat[r, 0], quat[r, 1], quat[r, 2], quat[r, 3], threshold
        )
        out[r, 0] = about_z
        out[r, 1] = pitch
        out[r, 2] = about_x
        usable[r] = ok
        singular[r] = sing and ok


#: ``angles_kernel(N)(quat, threshold, out, usable, singular)``.
angles_kernel = BatchKernel(_angle_rows, parallel=False)

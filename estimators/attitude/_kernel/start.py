"""How the reference attitude stages start a stream, compiled: scalar helpers shared by
:mod:`~estimators.attitude._kernel.gyro`, :mod:`~estimators.attitude._kernel.madgwick` and
:mod:`~estimators.attitude._kernel.mahony` (same conventions as
:mod:`estimators.kernels.rotations`): the initialisation of a stream's attitude from one
accelerometer (+ magnetometer) sample (:func:`quat_from_acc`, :func:`quat_from_acc_mag`) and the
sample-validity test (:func:`usable3`).

Initialisation (one convention for these stages and VQF, so that they compare fairly): the tilt
is the smallest rotation that takes the normalised specific force onto world +z (VQF's
inclination correction applied to the identity; Laidig & Seel, Information Fusion 91, 2023), then
a rotation about world z turns the horizontal part of the field, rotated into the world by the
tilt, onto north (+y, ENU) — VQF's heading correction with gain 1, which it applies to its first
magnetometer sample. Without a usable magnetometer sample the heading is left at that of the
tilt rotation (no rotation about the vertical).
"""

from __future__ import annotations

import math

import numba

from estimators.kernels.rotations import quat_mul, quat_rotate

__all__ = ["quat_from_acc", "quat_from_acc_mag", "usable3"]


@numba.njit(cache=True)
def usable3(x, y, z):
    """Whether a 3-vector sample can be used: finite and not all zero."""
    return (
        math.isfinite(x)
        and math.isfinite(y)
        and math.isfinite(z)
        and (x != 0.0 or y != 0.0 or z != 0.0)
    )


@numba.njit(cache=True)
def quat_from_acc(ax, ay, az):
    """Tilt quaternion (tuple) of one specific-force sample: the smallest rotation taking
    ``a / |a|`` to world +z (VQF's formula; a sensor upside down gets the half-turn about x)."""
    n = math.sqrt(ax * ax + ay * ay + az * az)
    ux, uy, uz = ax / n, ay / n, az / n
    w = math.sqrt(max(0.0, 0.5 * (uz + 1.0)))
    if w > 1e-6:
        return w, 0.5 * uy / w, -0.5 * ux / w, 0.0
    return 0.0, 1.0, 0.0, 0.0


@numba.njit(cache=True)
def quat_from_acc_mag(ax, ay, az, mx, my, mz):
    """Attitude quaternion (tuple) of one specific-force and one field sample: the tilt of
    :func:`quat_from_acc`, then the rotation about world z that puts the horizontal part of the
    field on +y (north, ENU). A field along the vertical leaves the heading of the tilt."""
    qw, qx, qy, qz = quat_from_acc(ax, ay, az)
    ex, ey, _ = quat_rotate(qw, qx, qy, qz, mx, my, mz)
    if ex * ex + ey * ey <= 1e-24 * (mx * mx + my * my + mz * mz):
        return qw, qx, qy, qz
    delta = math.atan2(ex, ey)  # rotating the field by +delta about z brings it onto +y
    c, s = math.cos(0.5 * delta), math.sin(0.5 * delta)
    rw, rx, ry, rz = quat_mul(c, 0.0, 0.0, s, qw, qx, qy, qz)
    n = math.sqrt(rw * rw + rx * rx + ry * ry + rz * rz)
    return rw / n, rx / n, ry / n, rz / n


@numba.njit(cache=True)
def start_quat(ax, ay, az, mx, my, mz, mag_ok):
    """The attitude a filter starts from at its first usable sample: :func:`quat_from_acc_mag`
    where the field sample is usable (``mag_ok``), else :func:`quat_from_acc`."""
    if mag_ok:
        return quat_from_acc_mag(ax, ay, az, mx, my, mz)
    return quat_from_acc(ax, ay, az)

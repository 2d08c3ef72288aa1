"""Scalar rotation helpers for every compiled kernel: the formulas of :mod:`estimators.rotations`.

One home for the small per-sample rotation arithmetic that kernels share (same conventions as the
numpy module: Hamilton ``[w, x, y, z]``, sensor -> world, intrinsic ZYX ``[yaw, pitch, roll]``);
``tests/test_estimators/test_rotations.py`` checks each against its numpy counterpart. Quaternions
travel as
components and come back as tuples, so a kernel keeps them in registers.
"""

from __future__ import annotations

import math

import numba

_TWO_PI = 2.0 * math.pi


@numba.njit(cache=True, inline="always")
def wrap_angle(a):
    """``pi - mod(pi - a, 2 pi)``: an angle (rad) wrapped into (-pi, pi], NaN stays NaN; bit for
    bit :func:`estimators.rotations.wrap_angle` (numba's float ``%`` is Python's floored modulo,
    numpy's algorithm)."""
    x = math.pi - a
    if 0.0 <= x < _TWO_PI:  # the usual case, where the modulo returns x itself: skip its fmod
        return math.pi - x
    return math.pi - x % _TWO_PI


@numba.njit(cache=True, inline="always")
def rotation_matrix(qw, qx, qy, qz, m):
    """Fill ``m`` (3, 3) with the rotation matrix of unit quaternion ``q`` (body -> world)."""
    xx, yy, zz = qx * qx, qy * qy, qz * qz
    xy, xz, yz = qx * qy, qx * qz, qy * qz
    wx, wy, wz = qw * qx, qw * qy, qw * qz
    m[0, 0] = 1.0 - 2.0 * (yy + zz)
    m[0, 1] = 2.0 * (xy - wz)
    m[0, 2] = 2.0 * (xz + wy)
    m[1, 0] = 2.0 * (xy + wz)
    m[1, 1] = 1.0 - 2.0 * (xx + zz)
    m[1, 2] = 2.0 * (yz - wx)
    m[2, 0] = 2.0 * (xz - wy)
    m[2, 1] = 2.0 * (yz + wx)
    m[2, 2] = 1.0 - 2.0 * (xx + yy)


@numba.njit(cache=True)
def quat_from_ypr(y, p, r):
    """Quaternion of ZYX angles (rad), as a tuple (w, x, y, z)."""
    cy, sy = math.cos(0.5 * y), math.sin(0.5 * y)
    cp, sp = math.cos(0.5 * p), math.sin(0.5 * p)
    cr, sr = math.cos(0.5 * r), math.sin(0.5 * r)
    return (
        cy * cp * cr + sy * sp * sr,
        cy * cp * sr - sy * sp * cr,
        cy * sp * cr + sy * cp * sr,
        sy * cp * cr - cy * sp * sr,
    )


@numba.njit(cache=True)
def quat_mul(pw, px, py, pz, qw, qx, qy, qz):
    """Hamilton product p (x) q, as a tuple."""
    return (
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )


@numba.njit(cache=True)
def quat_rotate(qw, qx, qy, qz, vx, vy, vz):
    """R(q) v, as a tuple."""
    tx = 2.0 * (qy * vz - qz * vy)
    ty = 2.0 * (qz * vx - qx * vz)
    tz = 2.0 * (qx * vy - qy * vx)
    return (
        vx + qw * tx + (qy * tz - qz * ty),
        vy + qw * ty + (qz * tx - qx * tz),
        vz + qw * tz + (qx * ty - qy * tx),
    )


@numba.njit(cache=True)
def quat_to_ypr(w, x, y, z):
    """ZYX angles (rad) of a unit quaternion, as a tuple (gimbal lock as the numpy twin)."""
    sinp = min(max(2.0 * (w * y - x * z), -1.0), 1.0)
    pitch = math.asin(sinp)
    if abs(sinp) > 1.0 - 1e-12:
        yaw = -2.0 * math.copysign(1.0, sinp) * math.atan2(x, w)
        yaw = wrap_angle(yaw)
        return yaw, pitch, 0.0
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    return yaw, pitch, roll


@numba.njit(cache=True)
def rotation_angle(w, x, y, z):
    """Rotation angle (rad, [0, pi]) of a unit quaternion."""
    return 2.0 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w))


@numba.njit(cache=True)
def quat_from_rotvec(rx, ry, rz):
    """Unit quaternion ``exp([rx, ry, rz])`` of a rotation vector (rad), as a tuple; a series
    below 1e-8 rad."""
    angle = math.sqrt(rx * rx + ry * ry + rz * rz)
    c = math.cos(0.5 * angle)
    s = 0.5 - angle * angle / 48.0 if angle < 1e-8 else math.sin(0.5 * angle) / angle
    return c, s * rx, s * ry, s * rz

"""The one rotation module of vrloco: quaternions, matrices, rotation vectors and Euler angles.

Conventions (used everywhere in the project, tested against ``scipy.spatial.transform``):

* World frame: ENU — x east, y north, z up. Gravity is ``[0, 0, -9.81]`` m/s^2 in the world.
  Yaw is measured counter-clockwise from +x (east), so yaw = 90 deg faces north.
* Quaternions are Hamilton, scalar first, ``q = [w, x, y, z]``, and a quaternion **rotates sensor
  (body) coordinates into world coordinates**: ``v_world = q ⊗ v_body ⊗ q*`` = ``R(q) @ v_body``.
* Euler angles are intrinsic Z-Y-X (Tait-Bryan): ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``, stored in
  arrays as ``[yaw, pitch, roll]`` in radians — scipy's ``Rotation.from_euler("ZYX", ...)``.
  With a body frame x forward, y left, z up, positive pitch tilts the nose *down* and positive roll
  tilts the right side down (right-hand rule about each axis).
* Angular velocity is expressed in the body frame, so ``q_dot = 0.5 * q ⊗ [0, w]``.

Every function takes arrays with any number of leading batch dimensions ``(..., 4)``, ``(..., 3)``
or ``(..., 3, 3)`` and broadcasts them against each other. No Python loop runs over the batch.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "GRAVITY",
    "angle_diff",
    "ensure_quaternion",
    "matrix_to_quat",
    "quat_canonical",
    "quat_conjugate",
    "quat_from_rotvec",
    "quat_from_ypr",
    "quat_identity",
    "quat_integrate",
    "quat_multiply",
    "quat_normalize",
    "quat_rotate",
    "quat_rotate_inverse",
    "quat_to_matrix",
    "quat_to_rotvec",
    "quat_to_ypr",
    "rotation_angle",
    "skew",
    "wrap_angle",
]

#: Standard gravity in m/s^2; the world gravity vector is ``[0, 0, -GRAVITY]``. Compiled kernels
#: read it (numba freezes it into the machine code; naming numba here puts this file in the
#: cache's fingerprint, :mod:`estimators.numba_cache`).
GRAVITY = 9.80665

_SMALL_ANGLE = 1e-8


def _as_float(a: ArrayLike) -> NDArray[np.float64]:
    return np.asarray(a, dtype=np.float64)


def _check_last(a: NDArray, n: int, name: str) -> None:
    if a.ndim == 0 or a.shape[-1] != n:
        raise ValueError(f"{name} must have shape (..., {n}), got {a.shape}")


def ensure_quaternion(q: ArrayLike, name: str = "q") -> NDArray[np.float64]:
    """Return ``q`` as a float array of unit quaternions, or raise naming ``name``.

    Raises:
        ValueError: wrong trailing dimension, a non-finite entry or a zero-norm quaternion.
    """
    q = _as_float(q)
    _check_last(q, 4, name)
    if not np.all(np.isfinite(q)):
        raise ValueError(f"{name} contains NaN or infinite entries")
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < 1e-12):
        raise ValueError(f"{name} contains a zero-norm quaternion; a rotation needs |q| > 0")
    return q / norm


def quat_identity(shape: tuple[int, ...] = ()) -> NDArray[np.float64]:
    """Identity quaternions of the given batch shape, ``(*shape, 4)``."""
    q = np.zeros((*shape, 4))
    q[..., 0] = 1.0
    return q


def quat_normalize(q: ArrayLike) -> NDArray[np.float64]:
    """Scale quaternions to unit norm (no validation; see :func:`ensure_quaternion`)."""
    q = _as_float(q)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_canonical(q: ArrayLike) -> NDArray[np.float64]:
    """Pick the sign of each quaternion so that ``w >= 0`` (q and -q are the same rotation)."""
    q = _as_float(q)
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_conjugate(q: ArrayLike) -> NDArray[np.float64]:
    """Conjugate ``[w, -x, -y, -z]``: the inverse rotation of a unit quaternion."""
    q = _as_float(q)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_multiply(p: ArrayLike, q: ArrayLike) -> NDArray[np.float64]:
    """Hamilton product ``p ⊗ q`` (apply ``q`` first, then ``p``)."""
    p = _as_float(p)
    q = _as_float(q)
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def quat_rotate(q: ArrayLike, v: ArrayLike) -> NDArray[np.float64]:
    """Rotate body-frame vectors into the world frame: ``R(q) @ v``."""
    q = _as_float(q)
    v = _as_float(v)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    vx, vy, vz = v[..., 0], v[..., 1], v[..., 2]
    # t = 2 u x v;  v' = v + w t + u x t  (component form: np.cross is slow on small arrays)
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return np.stack(
        [
            vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx),
        ],
        axis=-1,
    )


def quat_rotate_inverse(q: ArrayLike, v: ArrayLike) -> NDArray[np.float64]:
    """Rotate world-frame vectors into the body frame: ``R(q).T @ v``."""
    return quat_rotate(quat_conjugate(q), v)


def quat_to_matrix(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices ``(..., 3, 3)`` of unit quaternions (body to world)."""
    q = _as_float(q)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    m = np.stack(
        [
            1 - 2 * (yy + zz),
            2 * (xy - wz),
            2 * (xz + wy),
            2 * (xy + wz),
            1 - 2 * (xx + zz),
            2 * (yz - wx),
            2 * (xz - wy),
            2 * (yz + wx),
            1 - 2 * (xx + yy),
        ],
        axis=-1,
    )
    return m.reshape(*m.shape[:-1], 3, 3)


def matrix_to_quat(m: ArrayLike) -> NDArray[np.float64]:
    """Unit quaternions (``w >= 0``) of rotation matrices ``(..., 3, 3)``.

    Uses the numerically stable branch choice (largest of w, x, y, z first), like scipy.
    """
    m = _as_float(m)
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"m must have shape (..., 3, 3), got {m.shape}")
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    trace = m00 + m11 + m22
    # 4 * component^2 for each of w, x, y, z.
    cand = np.stack([1 + trace, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    k = np.argmax(cand, axis=-1)
    s = np.sqrt(np.take_along_axis(cand, k[..., None], axis=-1)[..., 0]) * 2.0  # 4 * |component|
    d21 = m[..., 2, 1] - m[..., 1, 2]
    d02 = m[..., 0, 2] - m[..., 2, 0]
    d10 = m[..., 1, 0] - m[..., 0, 1]
    s01 = m[..., 0, 1] + m[..., 1, 0]
    s02 = m[..., 0, 2] + m[..., 2, 0]
    s12 = m[..., 1, 2] + m[..., 2, 1]
    q = np.stack(
        [
            np.select([k == 0, k == 1, k == 2], [s / 4, d21 / s, d02 / s], d10 / s),
            np.select([k == 0, k == 1, k == 2], [d21 / s, s / 4, s01 / s], s02 / s),
            np.select([k == 0, k == 1, k == 2], [d02 / s, s01 / s, s / 4], s12 / s),
            np.select([k == 0, k == 1, k == 2], [d10 / s, s02 / s, s12 / s], s / 4),
        ],
        axis=-1,
    )
    return quat_canonical(quat_normalize(q))


def quat_from_rotvec(r: ArrayLike) -> NDArray[np.float64]:
    """Exponential map: rotation vectors (axis * angle, rad) to unit quaternions."""
    r = _as_float(r)
    _check_last(r, 3, "rotvec")
    angle = np.linalg.norm(r, axis=-1, keepdims=True)
    half = 0.5 * angle
    small = angle < _SMALL_ANGLE
    # sin(a/2)/a, with its Taylor series near zero.
    safe = np.where(small, 1.0, angle)
    scale = np.where(small, 0.5 - angle**2 / 48.0, np.sin(half) / safe)
    return np.concatenate([np.cos(half), scale * r], axis=-1)


def quat_to_rotvec(q: ArrayLike) -> NDArray[np.float64]:
    """Logarithm map: unit quaternions to rotation vectors with angle in [0, pi]."""
    q = quat_canonical(q)
    w = np.clip(q[..., :1], -1.0, 1.0)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, w)
    small = s < _SMALL_ANGLE
    scale = np.where(small, 2.0 / np.where(small, w, 1.0), angle / np.where(small, 1.0, s))
    return scale * v


def quat_integrate(q: ArrayLike, omega: ArrayLike, dt: float | ArrayLike) -> NDArray[np.float64]:
    """Integrate a body angular rate held constant over ``dt``: ``q ⊗ exp(omega * dt)``."""
    omega = _as_float(omega)
    dt = _as_float(dt)
    if dt.ndim:
        dt = dt[..., None]
    return quat_normalize(quat_multiply(q, quat_from_rotvec(omega * dt)))


def quat_from_ypr(ypr: ArrayLike) -> NDArray[np.float64]:
    """Quaternions from ZYX Euler angles ``[..., (yaw, pitch, roll)]`` in radians."""
    ypr = _as_float(ypr)
    _check_last(ypr, 3, "ypr")
    hy, hp, hr = 0.5 * ypr[..., 0], 0.5 * ypr[..., 1], 0.5 * ypr[..., 2]
    cy, sy = np.cos(hy), np.sin(hy)
    cp, sp = np.cos(hp), np.sin(hp)
    cr, sr = np.cos(hr), np.sin(hr)
    return np.stack(
        [
            cy * cp * cr + sy * sp * sr,
            cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr,
            sy * cp * cr - cy * sp * sr,
        ],
        axis=-1,
    )


def quat_to_ypr(q: ArrayLike) -> NDArray[np.float64]:
    """ZYX Euler angles ``[..., (yaw, pitch, roll)]`` in radians of unit quaternions.

    Pitch lies in [-pi/2, pi/2]; yaw and roll in (-pi, pi]. At gimbal lock (|pitch| = pi/2) the
    split between yaw and roll is arbitrary: roll is set to 0, as scipy does.
    """
    q = _as_float(q)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    sinp = np.clip(2.0 * (w * y - x * z), -1.0, 1.0)
    pitch = np.arcsin(sinp)
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    lock = np.abs(sinp) > 1.0 - 1e-12
    if np.any(lock):
        yaw = np.where(lock, -2.0 * np.sign(sinp) * np.arctan2(x, w), yaw)
        roll = np.where(lock, 0.0, roll)
        yaw = wrap_angle(yaw)
    return np.stack([yaw, pitch, roll], axis=-1)


def rotation_angle(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation angle in [0, pi] of unit quaternions (e.g. of an error quaternion)."""
    q = _as_float(q)
    v = np.linalg.norm(q[..., 1:], axis=-1)
    return 2.0 * np.arctan2(v, np.abs(q[..., 0]))


def skew(v: ArrayLike) -> NDArray[np.float64]:
    """Cross-product matrices ``[v x]`` of shape ``(..., 3, 3)``, so ``skew(a) @ b = a x b``."""
    v = _as_float(v)
    _check_last(v, 3, "v")
    x, y, z = np.moveaxis(v, -1, 0)
    o = np.zeros_like(x)
    m = np.stack([o, -z, y, z, o, -x, -y, x, o], axis=-1)
    return m.reshape(*m.shape[:-1], 3, 3)


def wrap_angle(a: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles (rad) into (-pi, pi]."""
    a = _as_float(a)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def angle_diff(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Smallest signed difference ``a - b`` of angles (rad), in (-pi, pi]."""
    return wrap_angle(_as_float(a) - _as_float(b))

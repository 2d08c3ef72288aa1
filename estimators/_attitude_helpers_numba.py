"""What the reference attitude stages (gyro_only, Madgwick, Mahony, VQF) share.

* Scalar helpers for their compiled kernels (same conventions as
  :mod:`estimators.kernels.rotations`: Hamilton ``[w, x, y, z]``, sensor -> ENU world): the
  initialisation of a stream's attitude from one accelerometer (+ magnetometer) sample and the
  sample-validity tests.
* The checks of a stage's constructor arguments and of the (B, N, 3) samples of one ``update``.

Initialisation (one convention for all four stages, so that they compare fairly): the tilt is the
smallest rotation that takes the normalised specific force onto world +z (VQF's inclination
correction applied to the identity; Laidig & Seel, Information Fusion 91, 2023), then a
rotation about world z turns the horizontal part of the field, rotated into the world by the
tilt, onto north (+y, ENU) — VQF's heading correction with gain 1, which it applies to its first
magnetometer sample. Without a usable magnetometer sample the heading is left at that of the
tilt rotation (no rotation about the vertical).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.kernels.rotations import quat_mul, quat_rotate
from estimators.validation import check_value

__all__ = [
    "check_batch_size",
    "check_fs",
    "check_samples",
    "quat_from_acc",
    "quat_from_acc_mag",
    "usable3",
]


@numba.njit(cache=True)
def usable3(x, y, z):
    """Whether a 3-vector sample can be used: finite and not all zero."""
    return (
        math.isfinite(x) and math.isfinite(y) and math.isfinite(z)
        and (x != 0.0 or y != 0.0 or z != 0.0)
    )  # fmt: skip


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


def check_batch_size(batch_size: object, who: str) -> int:
    """``batch_size`` as an int >= 1, or a ValueError naming ``who``."""
    check_value(f"{who}: batch_size", batch_size, 1, math.inf, integer=True)
    return int(batch_size)  # type: ignore[call-overload]


def check_fs(fs: object, who: str) -> float:
    """``fs`` as a float in (0, 100000] Hz, or a ValueError naming ``who``."""
    check_value(f"{who}: fs", fs, 0.0, 100_000.0, "Hz", lo_open=True)
    return float(fs)  # type: ignore[arg-type]


def check_samples(
    gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, batch_size: int, who: str
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None]:
    """The samples of one ``update`` as C-contiguous float64 arrays of shape (B, N, 3).

    Raises:
        ValueError: naming the argument and the shape expected.
    """
    out = []
    shape = None
    for name, value in (("gyr", gyr), ("acc", acc), ("mag", mag)):
        if value is None and name == "mag":
            out.append(None)
            continue
        try:
            arr = np.ascontiguousarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(
                f"{who}.update: {name} must be a float array of shape ({batch_size}, N, 3), got "
                f"{type(value).__name__}"
            ) from None
        if shape is None:
            if arr.ndim != 3 or arr.shape[0] != batch_size or arr.shape[2] != 3:
                raise ValueError(
                    f"{who}.update: {name} must have shape ({batch_size}, N, 3), got {arr.shape}"
                )
            shape = arr.shape
        elif arr.shape != shape:
            raise ValueError(f"{who}.update: {name} must have the shape of gyr {shape}, got "
                             f"{arr.shape}")  # fmt: skip
        out.append(arr)
    return out[0], out[1], out[2]

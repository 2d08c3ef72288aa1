"""Yao 2023's angle convention: the wrist quaternion to Euler angles, eq (1) and eq (2) (Yao,
Chen, Pan & Huang 2023, section 1.3), and the order of its angles.

Axis names. Yao 2023's eq (1) writes::

    theta_yaw   = atan2(2 (w x + y z), 1 - 2 (x^2 + y^2))
    theta_pitch = asin(2 (w y - z x))
    theta_roll  = atan2(2 (w z + x y), 1 - 2 (y^2 + z^2))

These are the intrinsic Z-Y-X (Tait-Bryan) angles of q, exactly those of
:func:`estimators.rotations.quat_to_ypr`, under other names: the paper's *yaw* is the rotation
about x (our **roll**), its *pitch* is ours, its *roll* is the rotation about z (our **yaw**). So
the paper's vector ``[yaw, pitch, roll]`` is our ``[roll, pitch, yaw]``: the same three numbers in
reverse order. :func:`quat_to_euler_paper` returns the paper's order (as eq (1) is printed); every
other function here uses the project's ``[yaw, pitch, roll]`` (``ypr``), and the paper's Table
rows *Roll, Pitch, Yaw* are therefore our ``ypr`` columns 0, 1, 2 in that order.

Eq (2), the gimbal-lock branch, is printed as ``theta_yaw = -2 sign(wy - zx) atan2(x, w)``,
``theta_pitch = sign(wy - zx) pi/2``, ``theta_roll = 0``. Read with eq (1)'s names that puts the
combined angle about x and zeroes the angle about z, which is wrong: at pitch +-90 deg,
``-2 sign(s) atan2(x, w)`` is the standard gimbal-lock value of the angle about **z** with the
angle about x set to zero (as scipy and :func:`~estimators.rotations.quat_to_ypr` do). The paper
evidently took eq (2) from a source using the usual names. We implement the correct reading —
about-z angle ``-2 sign(s) atan2(x, w)`` (wrapped to (-pi, pi]), pitch ``sign(s) pi/2``, about-x
angle 0 — which reconstructs the rotation within 5.13 deg (the pitch is snapped from >= 86.38 deg
to 90 deg, and the yaw/roll split is exact only at 90 deg); the literal reading errs by up to
180 deg. Where the branch switches, the rotation described by the angles moves by at most that
5.13 deg, but yaw and roll taken alone can jump further (near +-90 deg pitch only their
combination is defined), as with any Euler conversion; ``singular`` flags those frames.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.hand._kernel import MIN_QUAT_NORM, angles_kernel
from estimators.validation import check_value

__all__ = [
    "PAPER_AXIS_NAMES",
    "PAPER_SINGULARITY_THRESHOLD",
    "paper_angles",
    "paper_to_ypr",
    "quat_to_euler_paper",
    "unwrap_angles",
    "ypr_to_paper",
]

#: Yao 2023's names of our ``[yaw, pitch, roll]`` columns (its Tables' row order Roll, Pitch, Yaw).
PAPER_AXIS_NAMES = ("roll", "pitch", "yaw")

#: Yao 2023's gimbal-lock threshold on ``|wy - zx|`` (section 1.3; 0.5 is pitch +-90 deg).
PAPER_SINGULARITY_THRESHOLD = 0.499


def ypr_to_paper(ypr: ArrayLike) -> NDArray[np.float64]:
    """Our ``[yaw, pitch, roll]`` (..., 3) to Yao 2023's eq (1) order ``[yaw_p, pitch_p, roll_p]``.

    The paper's yaw is our roll and its roll our yaw, so this reverses the last axis.
    """
    return np.asarray(ypr, dtype=np.float64)[..., ::-1].copy()


def paper_to_ypr(euler: ArrayLike) -> NDArray[np.float64]:
    """Yao 2023's eq (1) order (..., 3) to our ``[yaw, pitch, roll]`` (reverses the last axis)."""
    return np.asarray(euler, dtype=np.float64)[..., ::-1].copy()


def quat_to_euler_paper(
    q: ArrayLike, threshold: float = PAPER_SINGULARITY_THRESHOLD
) -> NDArray[np.float64]:
    """Yao 2023's quaternion -> Euler conversion, eq (1), with eq (2) where ``|wy - zx| > 0.499``.

    Args:
        q: (..., 4) quaternions ``[w, x, y, z]`` (normalised here; sign does not matter).
        threshold: ``|wy - zx|`` above which eq (2) is used, in (0, 0.5]; the paper's 0.499
            switches at pitch asin(0.998) = 86.38 deg.

    Returns:
        (..., 3) angles in radians in the paper's order ``[yaw_p, pitch_p, roll_p]`` = our
        ``[roll, pitch, yaw]`` (see the module docstring); pitch in [-pi/2, pi/2], the others in
        (-pi, pi]. In the eq (2) branch the about-z angle (paper's roll slot) carries
        ``-2 sign(wy - zx) atan2(x, w)`` and the about-x angle is 0 (the paper prints them in the
        other slots; see the module docstring for why that is an error).

    Raises:
        ValueError: wrong shape, NaN/inf entries or a zero-norm quaternion. (The streaming filters
            treat those as dropouts instead; see :class:`OrientationFilter`.)
    """
    qa = np.asarray(q, dtype=np.float64)
    if qa.ndim == 0 or qa.shape[-1] != 4:
        raise ValueError(f"q must have shape (..., 4), got {qa.shape}")
    if not np.all(np.isfinite(qa)):
        raise ValueError("q contains NaN or infinite entries")
    if np.any(np.linalg.norm(qa, axis=-1) <= MIN_QUAT_NORM):
        raise ValueError(f"q contains a zero-norm quaternion (|q| <= {MIN_QUAT_NORM})")
    check_value("threshold", threshold, 0.0, 0.5, lo_open=True)
    ypr, _, _ = paper_angles(qa, threshold)
    return ypr_to_paper(ypr)


def paper_angles(
    q: NDArray[np.float64], threshold: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]:
    """Eq (1)/(2) of (..., 4) quaternions of any norm through the kernel
    (:data:`estimators.hand._kernel.angles_kernel`): our ``[yaw, pitch, roll]`` (..., 3), usable
    (...: finite, norm > 1e-6), singular (...: eq (2) was taken)."""
    lead = q.shape[:-1]
    rows = np.ascontiguousarray(q.reshape(-1, 4), dtype=np.float64)
    n = rows.shape[0]
    ypr, usable, singular = np.empty((n, 3)), np.empty(n, bool), np.empty(n, bool)
    angles_kernel(n)(rows, float(threshold), ypr, usable, singular)
    return ypr.reshape(*lead, 3), usable.reshape(lead), singular.reshape(lead)


def unwrap_angles(a: ArrayLike, axis: int = -2) -> NDArray[np.float64]:
    """Unwrap angles (rad) along the time ``axis``, tolerating NaN gaps (kept as NaN).

    Steps larger than pi between consecutive finite samples are taken the short way round, as
    ``numpy.unwrap`` does; a NaN gap is bridged from the last finite sample.
    """
    x = np.moveaxis(np.asarray(a, dtype=np.float64), axis, 0)
    if x.shape[0] == 0:
        return np.moveaxis(x.copy(), 0, axis)
    finite = np.isfinite(x)
    t = np.arange(x.shape[0]).reshape((-1,) + (1,) * (x.ndim - 1))
    idx = np.maximum.accumulate(np.where(finite, t, -1), axis=0)  # last finite sample
    idx = np.where(idx < 0, np.argmax(finite, axis=0), idx)  # leading NaN: first finite one
    filled = np.take_along_axis(x, idx, axis=0)
    out = np.where(finite, np.unwrap(filled, axis=0), np.nan)
    return np.moveaxis(out, 0, axis)

"""Attitude error metrics: BROAD's orientation errors (total, heading, inclination)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.rotations import quat_conjugate, quat_multiply, quat_normalize

__all__ = ["heading_twist", "orientation_errors"]


def heading_twist(e: NDArray) -> NDArray:
    """Signed angle (rad) of the rotation about world z contained in earth-frame errors ``e``."""
    return 2.0 * np.arctan2(e[..., 3], e[..., 0])


def orientation_errors(
    q_est: ArrayLike,
    q_true: ArrayLike,
    mask: ArrayLike | None = None,
    *,
    align_heading: bool = False,
) -> dict[str, Any]:
    """BROAD's orientation error metric (Laidig et al., Data 6(7), 2021, and its example code).

    The earth-frame error ``e = q_est ⊗ conj(q_true)``; total error ``2 acos(|e_w|)``; heading
    error ``2 atan(|e_z / e_w|)``; inclination error ``2 acos(sqrt(e_w^2 + e_z^2))``; each as an
    RMSE in degrees over the masked samples, NaN (lost markers) ignored.

    BROAD's own evaluation does not align headings: its ``opt_quat`` is already expressed in the
    magnetometer's ENU frame (VQF scores 2.6 deg on our nine trials without any alignment, as the
    data README says). ``align_heading=True`` first removes the constant heading offset between the
    two earth frames (circular mean of the heading twist of ``e`` over the masked samples), for 6D
    estimates or data whose reference frame has an arbitrary heading; for 6D only the
    inclination is meaningful anyway.

    Args:
        q_est: estimated quaternions, (N, 4) or (B, N, 4), sensor -> earth.
        q_true: reference quaternions, same shape (NaN rows ignored).
        mask: (N,) or (B, N) booleans selecting the samples to score (BROAD: ``movement``), or
            None for all.
        align_heading: remove a constant heading offset first.

    Returns:
        dict with ``total_rmse_deg``, ``heading_rmse_deg``, ``inclination_rmse_deg`` (floats for
        one recording, (B,) arrays for B), ``heading_offset_deg`` (the removed offset, 0 if not
        aligned) and ``n_samples`` (samples scored).
    """
    qe = np.asarray(q_est, dtype=np.float64)
    qt = np.asarray(q_true, dtype=np.float64)
    if qe.ndim not in (2, 3) or qe.shape[-1] != 4:
        raise ValueError(f"q_est must have shape (N, 4) or (B, N, 4), got {qe.shape}")
    if qt.shape != qe.shape:
        raise ValueError(f"q_true must have the shape of q_est {qe.shape}, got {qt.shape}")
    if mask is None:
        sel = np.ones(qe.shape[:-1], dtype=bool)
    else:
        sel = np.asarray(mask)
        if sel.dtype != bool:
            raise ValueError(f"mask must be boolean, got dtype {sel.dtype}")
        if sel.shape != qe.shape[:-1]:
            raise ValueError(f"mask must have shape {qe.shape[:-1]}, got {sel.shape}")
    with np.errstate(invalid="ignore", divide="ignore"):
        e = quat_normalize(quat_multiply(qe, quat_conjugate(qt)))
    valid = sel & np.all(np.isfinite(e), axis=-1)
    offset = np.zeros(qe.shape[:-2])
    if align_heading:
        tw = heading_twist(e)
        s = np.sum(np.where(valid, np.sin(tw), 0.0), axis=-1)
        c = np.sum(np.where(valid, np.cos(tw), 0.0), axis=-1)
        offset = np.arctan2(s, c)
        half = -0.5 * offset[..., None]
        rz = np.stack([np.cos(half), 0 * half, 0 * half, np.sin(half)], axis=-1)
        e = quat_multiply(rz, e)
    w = np.abs(e[..., 0])
    with np.errstate(invalid="ignore", divide="ignore"):
        total = 2.0 * np.arccos(np.clip(w, 0.0, 1.0))
        heading = 2.0 * np.arctan(np.abs(e[..., 3] / e[..., 0]))
        incl = 2.0 * np.arccos(np.clip(np.sqrt(e[..., 0] ** 2 + e[..., 3] ** 2), 0.0, 1.0))
    n = np.sum(valid, axis=-1)

    def rmse(x: NDArray) -> NDArray:
        sq = np.where(valid, x * x, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.degrees(np.sqrt(np.sum(sq, axis=-1) / n))

    out: dict[str, Any] = {
        "total_rmse_deg": rmse(total),
        "heading_rmse_deg": rmse(heading),
        "inclination_rmse_deg": rmse(incl),
        "heading_offset_deg": np.degrees(offset),
        "n_samples": n,
    }
    if qe.ndim == 2:
        out = {k: (int(v) if k == "n_samples" else float(v)) for k, v in out.items()}
    return out

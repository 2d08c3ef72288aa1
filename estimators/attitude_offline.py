"""Offline attitude: the forward-backward smoother behind
``estimators.attitude.estimate_attitude(..., offline=True)`` (the method, its assumptions and its
cost are in that function's docstring).

One pass of the seed 000 EKF runs forward, a second one on the time-reversed recording
(:meth:`estimators.attitude.AttitudeEKF.filter_with_covariance` keeps each pass's attitude
covariance after every sample), and the two estimates are fused per sample, each weighted by the
inverse of its covariance in the world frame (Fraser & Potter, IEEE TAC 14(4), 1969).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from estimators.attitude_errors import heading_twist
from estimators.rotations import (
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    quat_to_matrix,
    quat_to_rotvec,
    quat_to_ypr,
)

if TYPE_CHECKING:
    from estimators.attitude import AttitudeEKF

__all__ = ["UNKNOWN_VAR", "smooth_attitude"]

#: Variance (rad^2) standing for "unknown" in the fusion: a pass not yet initialised, or its
#: heading before its first magnetometer sample (a 1000 rad standard deviation).
UNKNOWN_VAR = 1e6


def _world_cov(q: NDArray, p_att: NDArray, printed: bool) -> NDArray:
    """(..., 3, 3) attitude error covariance in the world frame (small rotations about the ENU
    axes, ``q_true = exp(e) ⊗ q``) from the filter's attitude block ``p_att``: the local error
    ``dphi`` (``e = R(q) dphi``), or under the printed model the Euler-angle errors
    ``[pitch, roll, yaw]`` (``e = J d``, J the ZYX Euler-rate Jacobian: yaw about e_z, pitch
    about ``Rz(yaw) e_y``, roll about ``Rz(yaw) Ry(pitch) e_x``)."""
    if printed:
        ypr = quat_to_ypr(q)
        cy, sy = np.cos(ypr[..., 0]), np.sin(ypr[..., 0])
        cp, sp = np.cos(ypr[..., 1]), np.sin(ypr[..., 1])
        zero, one = np.zeros_like(cy), np.ones_like(cy)
        j = np.stack(
            [-sy, cy * cp, zero,
             cy, sy * cp, zero,
             zero, -sp, one],
            axis=-1,
        ).reshape(*cy.shape, 3, 3)  # fmt: skip
    else:
        j = quat_to_matrix(q)
    w = j @ p_att @ np.swapaxes(j, -1, -2)
    return 0.5 * (w + np.swapaxes(w, -1, -2))


def _heading_offset(q_f: NDArray, q_b: NDArray, w_zz: NDArray, both: NDArray) -> NDArray:
    """(B,) constant heading (rad, about world z) from ``q_f`` to ``q_b``: the circular mean of
    the heading twist of ``q_b ⊗ conj(q_f)`` over the samples ``both``, weights ``1 / w_zz``."""
    tw = heading_twist(quat_multiply(q_b, quat_conjugate(q_f)))
    wt = np.where(both, 1.0 / w_zz, 0.0)
    return np.arctan2(np.sum(wt * np.sin(tw), axis=-1), np.sum(wt * np.cos(tw), axis=-1))


def smooth_attitude(ekf: AttitudeEKF, g: NDArray, a: NDArray, m: NDArray | None) -> NDArray:
    """The forward-backward smoother of ``estimate_attitude(..., offline=True)`` on (B, N, 3)
    checked samples (``m`` None for 6D), ``ekf`` a fresh filter with the parameters of both
    passes; (B, N, 4) quaternions."""
    if m is None:
        m = np.full(g.shape, np.nan)  # 6D: every magnetometer sample missing
    q_f, p_f, init_f, head_f = ekf.filter_with_covariance(g, a, m)
    # The reversed stream: reversed sample k is sample N-1-k; its gyro is -gyr[N-k] (NaN first).
    g_r = np.empty_like(g)
    g_r[:, :1] = np.nan
    g_r[:, 1:] = -g[:, :0:-1]
    ekf.reset()
    backward = ekf.filter_with_covariance(g_r, a[:, ::-1], m[:, ::-1])
    q_b, p_b, init_b, head_b = (x[:, ::-1] for x in backward)

    printed = ekf.params.model == "paper_literal"
    has_mag = np.any(np.isfinite(m).all(axis=-1), axis=-1)
    absolute = has_mag & head_f.any(axis=-1) & head_b.any(axis=-1)  # (B,)
    both = init_f & init_b
    if not absolute.all():  # no common heading origin: turn the backward pass onto the forward
        w_zz = _world_cov(q_f, p_f, printed)[..., 2, 2] + _world_cov(q_b, p_b, printed)[..., 2, 2]
        off = np.where(absolute, 0.0, _heading_offset(q_f, q_b, w_zz, both))
        half = -0.5 * off[:, None]
        rz = np.stack([np.cos(half), 0.0 * half, 0.0 * half, np.sin(half)], axis=-1)
        q_b = quat_normalize(quat_multiply(rz, q_b))

    def world(q: NDArray, p: NDArray, init: NDArray, head: NDArray) -> NDArray:
        w = _world_cov(q, p, printed)
        w[..., 2, 2] += np.where(absolute[:, None] & ~head, UNKNOWN_VAR, 0.0)
        return np.where(init[..., None, None], w, UNKNOWN_VAR * np.eye(3))

    w_f, w_b = world(q_f, p_f, init_f, head_f), world(q_b, p_b, init_b, head_b)
    d = quat_to_rotvec(quat_multiply(q_b, quat_conjugate(q_f)))
    e = (w_f @ np.linalg.solve(w_f + w_b, d[..., None]))[..., 0]
    q_s = quat_normalize(quat_multiply(quat_from_rotvec(e), q_f))
    return np.where((init_f | init_b)[..., None], q_s, q_f)

"""Attitude of whole recordings: :func:`estimate_attitude` runs Zhang 2021's EKF over one or B
recordings, causally or, with ``offline=True``, through the forward-backward smoother
:func:`smooth_attitude` (the method, its assumptions and its cost are in
:func:`estimate_attitude`'s docstring).

One pass of the Zhang 2021 EKF runs forward, a second one on the time-reversed recording
(:meth:`estimators.attitude.ekf.AttitudeEKF.filter_with_covariance` keeps each pass's attitude
covariance after every sample), and the two estimates are fused per sample, each weighted by the
inverse of its covariance in the world frame (Fraser & Potter, IEEE TAC 14(4), 1969).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.attitude.ekf import AttitudeEKF, AttitudeParams
from estimators.attitude.errors import heading_twist
from estimators.rotations import (
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    quat_to_matrix,
    quat_to_rotvec,
    quat_to_ypr,
)
from estimators.validation import check_xyz

__all__ = ["UNKNOWN_VAR", "estimate_attitude", "smooth_attitude"]

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
            [-sy, cy * cp, zero, cy, sy * cp, zero, zero, -sp, one],
            axis=-1,
        ).reshape(*cy.shape, 3, 3)
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


def estimate_attitude(
    gyr: ArrayLike,
    acc: ArrayLike,
    mag: ArrayLike | None,
    fs: float,
    params: AttitudeParams | None = None,
    *,
    offline: bool = False,
    **overrides: Any,
) -> NDArray[np.float64]:
    """Attitude of one recording (N, 3) or of B recordings (B, N, 3), filtered or smoothed.

    ``offline=False``: the causal filter, the estimate at sample n uses samples 0..n (bit for bit
    what :meth:`AttitudeEKF.update_batch` returns).

    ``offline=True``: a forward-backward (two-filter) smoother for recordings, the estimate at
    sample n uses the whole recording:

    1. Forward pass: the filter as above, its attitude covariance kept after every sample.
    2. Backward pass: the same compiled filter, same parameters, started afresh on the
       time-reversed recording. The accelerometer and magnetometer samples are read in reverse;
       the gyro is negated and shifted by one sample: the filter's model is that gyro sample n is
       the rate over the interval from sample n-1 to n, so the step of the reversed stream that
       arrives at sample n rotates by ``-gyr[n+1] dt`` (the first reversed sample, n = N-1, has
       no rate: NaN, which the filter treats as a dropout). Its bias estimate converges to minus
       the forward one and is not used.
    3. Fusion, per sample: each pass's attitude error covariance (the 3x3 attitude block of P,
       after that sample) is turned into the world frame, ``W = R(q) P_att R(q)^T`` (for
       ``model="paper_literal"``, whose error state is Euler-angle errors, ``W = J P_att
       J^T`` with J the ZYX Euler-rate Jacobian). With ``d`` the rotation vector of
       ``q_b ⊗ conj(q_f)`` (world frame, from the forward to the backward estimate), the smoothed
       attitude is ``exp(W_f (W_f + W_b)^-1 d) ⊗ q_f``: the mean of two independent Gaussian
       estimates of the same attitude, each weighted by the inverse of its covariance
       (Fraser & Potter, "The optimum linear smoother as a combination of two optimum linear
       filters", IEEE TAC 14(4), 1969), to first order in the small angle between them. A pass
       not yet initialised at a sample (no accelerometer sample within g/2 of g yet) counts
       there with a variance of :data:`_UNKNOWN_VAR`, and so does its heading before its first
       magnetometer sample; where neither pass is initialised the forward estimate is kept.
    4. Without an absolute heading (``mag=None``, or a stream in which one pass never set its
       heading from the field) the two passes' headings have different, arbitrary origins: the
       backward estimates are first turned about the vertical by the constant angle that maps
       them onto the forward ones (the circular mean of the heading twist of
       ``q_b ⊗ conj(q_f)``, weighted by ``1 / (W_f,zz + W_b,zz)``), so the smoothed heading
       keeps the forward filter's origin (and drifts as a 6D heading does: only the
       inclination of a 6D estimate is meaningful).

    Assumptions: the filter's covariance describes its error (first-order Gaussian errors;
    where the filter inflates R in motion or rejects the field, its covariance grows and the
    other pass takes over); the two passes are independent, although both use sample n itself
    (one sample of N, each carrying little information: ``R = sigma^2 / dt``); only the
    attitude marginals are fused (the passes' bias information enters through their attitude
    covariances). Cost: the covariance is read after every sample, so each pass makes one
    kernel call per sample (measured: 2-3 us per sample and pass on an idle core, some 25 times
    the causal filter's 0.2 us in one call).

    Args:
        gyr: angular rate, rad/s, sensor frame, (N, 3) or (B, N, 3).
        acc: specific force, m/s^2, same shape.
        mag: magnetic field in any fixed unit (uT in our data), same shape, or None for 6D
            (heading then starts at 0 and drifts with the gyro).
        fs: sampling rate, Hz.
        params: filter parameters (defaults: :class:`AttitudeParams`).
        offline: smooth the whole recording (forward-backward, above) instead of filtering.
        **overrides: fields of :class:`AttitudeParams` to change, e.g. ``declination=0.05``.

    Returns:
        Quaternions ``[w, x, y, z]`` rotating sensor to ENU, (N, 4) or (B, N, 4); bit-for-bit
        reproducible for the same input, parameters and machine, in both modes.
    """
    g = check_xyz(gyr, "gyr", None)
    if g.ndim not in (2, 3):
        raise ValueError(f"gyr must have shape (N, 3) or (B, N, 3), got {g.shape}")
    single = g.ndim == 2
    if single:
        g = g[None]
    a = check_xyz(acc, "acc", None)
    a = a[None] if single and a.ndim == 2 else a
    if a.shape != g.shape:
        raise ValueError(f"acc must have the shape of gyr {g.shape[single:]}, got {a.shape}")
    m = None
    if mag is not None:
        m = check_xyz(mag, "mag", None)
        m = m[None] if single and m.ndim == 2 else m
        if m.shape != g.shape:
            raise ValueError(f"mag must have the shape of gyr {g.shape[single:]}, got {m.shape}")
    ekf = AttitudeEKF(g.shape[0], fs, params, **overrides)
    out = smooth_attitude(ekf, g, a, m) if offline else ekf.update_batch(g, a, m)
    return out[0] if single else out

"""The real recording of :mod:`agents.experiments.hand_variance`: Holt smoothing on the
kinect_laban Kinect v2 recording (:func:`recording_jitter`) and the white and correlated shares of
a still forearm's orientation jitter there (:func:`recording_orientation_noise`, by
:func:`variogram_split`): the evidence behind the Kinect model's wrist-noise split.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from agents.recordings.data import DataMissing, data_path
from estimators.hand import HoltSmoother, estimate_lag
from estimators.io.kinect import read_kinect_csv
from estimators.rotations import matrix_to_quat, quat_conjugate, quat_multiply, quat_to_rotvec

__all__ = ["recording_jitter", "recording_orientation_noise", "variogram_split"]


def _laban_csv(path: Path | None) -> Path | None:
    """``path``, else the kinect_laban recording (:func:`agents.recordings.data.data_path`), or None
    where it is absent."""
    if path is not None:
        return path if path.is_file() else None
    try:
        return data_path("kinect")
    except DataMissing:
        return None


def recording_jitter(path: Path | None = None) -> dict | None:
    """Holt smoothing (SDK defaults + 5-frame average) on a real Kinect v2 recording (default
    the kinect_laban recording, ``vrloco data fetch kinect``).

    Jitter is the RMS second difference of a joint's path (mm per frame^2); lag the delay of the
    smoothed path behind the raw one. Returns None when the recording is absent.
    """
    path = _laban_csv(path)
    if path is None:
        return None
    rec = read_kinect_csv(path)
    holt = HoltSmoother(1, rec.joints.shape[1])
    smooth = np.array(
        [holt.update(rec.joints[None, k], rec.state[None, k])[0] for k in range(rec.t.size)]
    )
    out = {"file": path.name, "frames": int(rec.t.size)}
    for name, j in (("wrist_right", 10), ("hand_right", 11)):
        raw, sm = rec.joints[:, j], smooth[:, j]
        jit = [
            float(np.sqrt(np.nanmean(np.sum(np.diff(a, 2, axis=0) ** 2, axis=-1))))
            for a in (raw, sm)
        ]
        lag = estimate_lag(sm, raw, rec.rate_hz)
        out[name] = {
            "jitter_raw_mm": 1e3 * jit[0],
            "jitter_smoothed_mm": 1e3 * jit[1],
            "lag_ms": float(1e3 * np.max(lag)),
        }
    return out


def variogram_split(x: ArrayLike, rate_hz: float, max_lag: int = 40) -> dict:
    """White and correlated shares of a noisy series, from its variogram.

    ``gamma(k) = mean((x[t+k] - x[t])^2) / 2`` for k = 1 .. ``max_lag`` is fitted (least squares
    on the relative misfit) with ``n + s (1 - exp(-k dt / tau)) + c k^2``: a white part of variance
    ``n`` (the variogram's "nugget", reached at once), an AR(1) part of variance ``s`` and time
    constant ``tau``, and a quadratic drift ``c`` that absorbs slow true motion. The white share
    is ``n / (n + s)``.

    Args:
        x: (N,) samples at ``rate_hz``.
        rate_hz: sampling rate, Hz.
        max_lag: largest lag fitted, samples (< N / 2).

    Returns:
        ``white_var``, ``correlated_var`` (units of x squared), ``tau_s``, ``white_share``.
    """
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 1 or not 2 <= max_lag < a.size // 2:
        raise ValueError(f"x must be 1-D with more than 2 * max_lag samples, got {a.shape}")
    dt = 1.0 / rate_hz
    k = np.arange(1, max_lag + 1)
    gamma = np.array([0.5 * np.nanmean((a[j:] - a[:-j]) ** 2) for j in k])  # a loop over lags

    def misfit(p: NDArray) -> NDArray:
        n, s, tau, c = p
        return (n + s * (1.0 - np.exp(-k * dt / tau)) + c * k**2 - gamma) / gamma

    fit = least_squares(
        misfit,
        [0.5 * gamma[0], gamma[-1], 0.3, 0.0],
        bounds=([0.0, 0.0, dt, 0.0], [np.inf, np.inf, 5.0, np.inf]),
    )
    n, s, tau, _ = fit.x
    return {
        "white_var": float(n),
        "correlated_var": float(s),
        "tau_s": float(tau),
        "white_share": float(n / (n + s)) if n + s > 0 else float("nan"),
    }


def recording_orientation_noise(path: Path | None = None) -> dict | None:
    """The white share of a still forearm's orientation jitter in a real Kinect v2 recording.

    In kinect_laban's wave the left arm hangs still. A frame is built from its joints as the
    wrist's orientation would be: x along ElbowLeft -> WristLeft (the SDK's wrist bone), y toward
    ThumbLeft (made orthogonal to x), z = x cross y. Its rotation vector relative to the mean
    orientation (deg, about the frame's own axes: x the forearm, y the thumb side, z the normal)
    is split per axis by :func:`variogram_split`. Returns None when the recording is absent
    (default: the kinect_laban recording).
    """
    path = _laban_csv(path)
    if path is None:
        return None
    rec = read_kinect_csv(path)
    j = rec.joints
    x = j[:, 6] - j[:, 5]
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    y = j[:, 22] - j[:, 6]
    y -= np.sum(y * x, axis=-1, keepdims=True) * x
    y /= np.linalg.norm(y, axis=-1, keepdims=True)
    q = matrix_to_quat(np.stack([x, y, np.cross(x, y)], axis=-1))
    q *= np.where(q @ q[0] < 0.0, -1.0, 1.0)[:, None]  # one hemisphere
    mean = q.mean(axis=0)
    mean /= np.linalg.norm(mean)  # the mean orientation (chordal; the spread is a few deg)
    rel = quat_multiply(quat_conjugate(mean), q)  # deviation in the frame's own axes
    rv = np.rad2deg(quat_to_rotvec(rel))
    out: dict = {
        "file": path.name,
        "frames": int(rec.t.size),
        "frame": "x ElbowLeft->WristLeft, y toward ThumbLeft",
    }
    for i, name in enumerate(("about_forearm", "about_thumb_axis", "about_normal")):
        out[name] = variogram_split(rv[:, i], rec.rate_hz)
        out[name]["std_deg"] = float(np.std(rv[:, i]))
    return out

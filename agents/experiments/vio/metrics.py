"""Error measures of the helmet-tracking paper's experiment: the position and attitude error series
of an estimate against the truth (:func:`error_series`), and their RMSE, percentiles, largest
values, windowed and first/last RMS (:func:`error_stats`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from agents.experiments.vio.settings import IMU_RATE_HZ, WINDOW_S
from estimators import rotations as rot

__all__ = ["error_series"]


def error_series(
    pos: NDArray, quat: NDArray, pos_true: NDArray, quat_true: NDArray
) -> tuple[NDArray, NDArray]:
    """Position error (m, 3-D norm) and attitude error (deg, angle of ``q_true^-1 q``)."""
    ep = np.linalg.norm(pos - pos_true, axis=-1)
    ea = np.rad2deg(rot.rotation_angle(rot.quat_multiply(rot.quat_conjugate(quat_true), quat)))
    return ep, ea


def rms(x: NDArray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def error_stats(ep: NDArray, ea: NDArray, samples: bool = True) -> dict:
    """RMSE, 95th percentile and max of position (m) and attitude (deg) errors; with
    ``samples`` (1 kHz series over the whole run) also windowed and first/last RMS."""
    if ep.size == 0:
        nan = float("nan")
        return {
            "pos_m": nan,
            "att_deg": nan,
            "pos_p95_m": nan,
            "att_p95_deg": nan,
            "pos_max_m": nan,
            "att_max_deg": nan,
        }
    out = {
        "pos_m": rms(ep),
        "att_deg": rms(ea),
        "pos_p95_m": float(np.percentile(ep, 95)),
        "att_p95_deg": float(np.percentile(ea, 95)),
        "pos_max_m": float(ep.max()),
        "att_max_deg": float(ea.max()),
    }
    if samples:
        n = ep.size
        w = round(WINDOW_S * IMU_RATE_HZ)
        nw = max(n // w, 1)
        wp = [rms(ep[i * w : (i + 1) * w]) for i in range(nw)]
        wa = [rms(ea[i * w : (i + 1) * w]) for i in range(nw)]
        edge = min(round(30.0 * IMU_RATE_HZ), n // 4)
        out.update(
            {
                "pos_window_max_m": float(max(wp)),
                "att_window_max_deg": float(max(wa)),
                "edge_s": edge / IMU_RATE_HZ,
                "pos_first_m": rms(ep[:edge]),
                "pos_last_m": rms(ep[-edge:]),
                "att_first_deg": rms(ea[:edge]),
                "att_last_deg": rms(ea[-edge:]),
            }
        )
    return out

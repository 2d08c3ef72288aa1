"""The settings of :mod:`agents.experiments.hand_variance`: Yao 2023's static angles and published
reductions, the development seeds of the tuned hand-filter parameters, the filters reported, the
Kinect frame rate and the filter start-up left out of the statistics.
"""

from __future__ import annotations

__all__ = [
    "COMPETITORS",
    "DEV_MOVING_SEEDS",
    "DEV_STATIC_SEEDS",
    "FILTERS",
    "PAPER_ANGLES_DEG",
    "PAPER_REDUCTION",
]

#: Yao 2023's 11 static angles (deg), in the order of its Tables 1-3.
PAPER_ANGLES_DEG = (-90, 0, 90, -35, -50, -65, -75, 30, 45, 60, 75)
#: Yao 2023 Table 4: variance reduction (%) per axis (roll, pitch, yaw).
PAPER_REDUCTION = {
    "kalman": {"roll": 54.0, "pitch": 40.0, "yaw": 54.0},
    "kalman_median": {"roll": 65.0, "pitch": 54.0, "yaw": 69.0},
}
#: Development seeds of every tuned hand-filter parameter: static trials (5 repeats per angle) and
#: moving ones (10 users). Reported figures use other seeds.
DEV_STATIC_SEEDS = (1, 2)
DEV_MOVING_SEEDS = (101, 102)
#: Registered hand stages (:data:`estimators.stages.HAND`) run beside Yao 2023's filters.
COMPETITORS = ("one_euro", "adaptive_kalman")
#: Every filter the experiment reports: the pipeline's own outputs, then the competitors.
FILTERS = ("raw", "kalman", "kalman_median", *COMPETITORS)
_WARMUP_FRAMES = 30  # filter start-up left out of the statistics (1 s)
_FS = 30.0  # the Kinect v2 frame rate (Hz)

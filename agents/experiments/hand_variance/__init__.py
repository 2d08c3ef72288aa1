"""Yao 2023's experiment 2 on the synthetic Kinect v2, plus what variance alone hides.

1. Static: the user holds the right hand still, turned about the forearm to each of the paper's 11
   angles (-90, 0, 90, -35, -50, -65, -75, 30, 45, 60, 75 deg), R repeats of 10 s at 30 Hz. The
   variance of the raw Euler angles (eq 1/2), of the Kalman output and of Kalman + median, and the
   pooled variance reduction per axis, as in Tables 1-4; the median's own share (Kalman + median
   minus Kalman, percentage points); and the RMSE against the true orientation at rest.
2. Moving: the hand sweeps about the forearm at 90 deg/s between -75 and +75 deg. RMSE against the
   true orientation per axis and lag on the swept axis (ms).

Both for raw, Yao 2023's Kalman and Kalman + median, and the registered hand stages that compete
with them (:data:`COMPETITORS`: the One Euro filter and the motion-adaptive Kalman filter).

Everything runs through the real chain: motion model -> Kinect model (bystanders, ids, tracking
states, noise) -> :class:`estimators.hand.HandPipeline` (target selection, Holt smoothing, eq 1/2,
Kalman, median) -> hand stages. Axis names are the paper's (see :mod:`estimators.hand.angles`): its
*roll, pitch, yaw* are our ZYX ``[yaw, pitch, roll]`` columns of the wrist orientation in camera
space; the sweep about the forearm moves the paper's *roll*.

Seeds. Every tuned parameter of the hand filters (:class:`estimators.hand.KalmanParams`'
``accel_psd``, :mod:`estimators.hand.one_euro`, :mod:`estimators.hand.adaptive`) was chosen on the
development seeds :data:`DEV_STATIC_SEEDS` (static trials) and :data:`DEV_MOVING_SEEDS` (moving
ones); :func:`run_hand_variance` reports seed ``s`` (static) and ``s + 1`` (moving), default 0 and
1, and labels its figures held-out unless one of them is a development seed.

Real data: :func:`recording_jitter` (Holt smoothing on the kinect_laban recording) and
:func:`recording_orientation_noise` (the white and correlated shares of a still forearm's
orientation jitter there: the evidence behind the Kinect model's wrist-noise split).

The core of the static experiment on given orientation sequences is
:func:`hand_variance_experiment` (through :class:`estimators.hand.OrientationFilter`, the pipeline's
compiled stage 3). Run: ``vrloco experiment hand-variance --json out/hand_variance.json``; the
tuning rules on the development seeds: ``python -m agents.experiments.hand_variance [--only
yao2023 adaptive_kalman one_euro]`` (:func:`run_tuning`).

Modules:

* :mod:`~agents.experiments.hand_variance.settings` — the paper's angles and reductions, the
  development seeds, the filters;
* :mod:`~agents.experiments.hand_variance.trials` — the simulated trials and the filters' outputs;
* :mod:`~agents.experiments.hand_variance.scores` — variance reduction, RMSE, lag;
* :mod:`~agents.experiments.hand_variance.recording` — the real recording;
* :mod:`~agents.experiments.hand_variance.report` — the experiments and their printed table;
* :mod:`~agents.experiments.hand_variance.tuning` — the tuning rules.

Every public name of these modules is importable from this package.
"""

from agents.experiments.hand_variance.recording import (
    recording_jitter,
    recording_orientation_noise,
    variogram_split,
)
from agents.experiments.hand_variance.report import (
    format_table,
    moving_accuracy,
    run_hand_variance,
    static_variance,
)
from agents.experiments.hand_variance.scores import (
    HandVarianceResult,
    hand_variance_experiment,
    moving_scores,
    static_scores,
)
from agents.experiments.hand_variance.settings import (
    COMPETITORS,
    DEV_MOVING_SEEDS,
    DEV_STATIC_SEEDS,
    FILTERS,
    PAPER_ANGLES_DEG,
    PAPER_REDUCTION,
)
from agents.experiments.hand_variance.trials import (
    HandTrial,
    filter_outputs,
    moving_trial,
    simulate_trial,
    static_trial,
)
from agents.experiments.hand_variance.tuning import (
    development_scores,
    development_trials,
    run_tuning,
    tune_adaptive_kalman,
    tune_one_euro,
    tune_yao2023_accel_psd,
)

__all__ = [
    "COMPETITORS",
    "DEV_MOVING_SEEDS",
    "DEV_STATIC_SEEDS",
    "FILTERS",
    "PAPER_ANGLES_DEG",
    "PAPER_REDUCTION",
    "HandTrial",
    "HandVarianceResult",
    "development_scores",
    "development_trials",
    "filter_outputs",
    "format_table",
    "hand_variance_experiment",
    "moving_accuracy",
    "moving_scores",
    "moving_trial",
    "recording_jitter",
    "recording_orientation_noise",
    "run_hand_variance",
    "run_tuning",
    "simulate_trial",
    "static_scores",
    "static_trial",
    "static_variance",
    "tune_adaptive_kalman",
    "tune_one_euro",
    "tune_yao2023_accel_psd",
    "variogram_split",
]

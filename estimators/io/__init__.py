"""Readers of the real recordings the estimators are validated against.

* :mod:`~estimators.io.broad` — BROAD, the Berlin Robust Orientation Estimation Assessment
  Dataset (IMU and optical ground truth): :func:`load_broad`, :func:`broad_trials`.
* :mod:`~estimators.io.oxford` — the Oxford step-counter recording (a phone in a neck pouch, with
  a foot switch): :func:`load_oxford`, :func:`read_accelerometer`, :func:`foot_switch_steps`.
* :mod:`~estimators.io.kinect` — Kinect v2 skeletons in the CSV layout of Microsoft's
  LabanotationSuite: :func:`read_kinect_csv`.
"""

from estimators.io.broad import BroadTrial, broad_trials, load_broad
from estimators.io.kinect import KinectRecording, read_kinect_csv
from estimators.io.oxford import (
    DEFAULT_RECORDING,
    OxfordRecording,
    foot_switch_steps,
    load_oxford,
    read_accelerometer,
)

__all__ = [
    "DEFAULT_RECORDING",
    "BroadTrial",
    "KinectRecording",
    "OxfordRecording",
    "broad_trials",
    "foot_switch_steps",
    "load_broad",
    "load_oxford",
    "read_accelerometer",
    "read_kinect_csv",
]

"""VQF as an attitude stage: an adapter of the ``vqf`` package (one ``vqf.VQF`` per stream).

Source: D. Laidig, T. Seel, "VQF: Highly accurate IMU orientation estimation with bias
estimation and magnetic disturbance rejection", Information Fusion 91:187-204, 2023; the
reference implementation is the ``vqf`` package (``pip install vqf``, in this project's ``bench``
extra). VQF integrates the gyro in an almost inertial frame, low-passes the specific force there
(time constant ``tau_acc``) and corrects the inclination to it, corrects the heading with the
magnetometer through a first-order filter (``tau_mag``), estimates the gyro bias at rest and in
motion, and rejects magnetic disturbances.

Frames: ``vqf.VQF`` returns ``quat9D`` ``[w, x, y, z]`` (Hamilton) rotating sensor coordinates into
its earth frame, whose heading correction drives the horizontal field onto +y (it takes the
disagreement angle ``atan2(m_E,x, m_E,y)``): x east, y (magnetic) north, z up, i.e. ENU with zero
declination, the frame of this project. No conversion is needed;
``tests/test_estimators/attitude/test_attitude_stages.py`` checks it on static samples of known
attitude (heading 30 deg) and on an analytic trajectory.

Start and missing data: VQF's own start matches the convention of the other reference stages
(:mod:`estimators.attitude._kernel.start`): its low-pass filter of the specific force starts at
the first sample and the inclination correction is complete at every sample, and its heading
gain starts at 1 (then 1/2, 1/3, ... until ``tau_mag``), so the first sample sets the tilt and
the heading. ``vqf`` skips a ``[0, 0, 0]`` accelerometer or magnetometer sample, so non-finite
readings are passed as zeros (that sensor is skipped for that sample); a non-finite gyro reading
is passed as a zero rate (the attitude holds; VQF's rest detector sees that zero). With
``mag=None`` the field is skipped for the whole step and ``quat9D`` keeps its last heading offset
(the 6D estimate's heading drifts with the gyro from then on).

The loop over the B streams is a Python loop over ``vqf.VQF.updateBatch`` calls (C++ inside);
``vqf`` has no batched filter.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers, stream_rows
from estimators.validation import (
    check_batch_size,
    check_bool,
    check_in_range,
    check_rate,
    check_samples,
)

__all__ = ["VqfParams", "VqfStage"]


# (field, vqf name, low, high, low inclusive, unit) of the numeric fields.
_RANGES: tuple[tuple[str, str, float, float, bool, str], ...] = (
    ("tau_acc", "tauAcc", 0.0, 100.0, False, "s"),
    ("tau_mag", "tauMag", 0.0, 1000.0, False, "s"),
    ("bias_sigma_init", "biasSigmaInit", 0.0, 10.0, False, "deg/s"),
    ("bias_forgetting_time", "biasForgettingTime", 0.0, 10000.0, False, "s"),
    ("bias_clip", "biasClip", 0.0, 30.0, False, "deg/s"),
    ("bias_sigma_motion", "biasSigmaMotion", 0.0, 10.0, False, "deg/s"),
    ("bias_vertical_forgetting_factor", "biasVerticalForgettingFactor", 0.0, 1.0, True, ""),
    ("bias_sigma_rest", "biasSigmaRest", 0.0, 10.0, False, "deg/s"),
    ("rest_min_t", "restMinT", 0.0, 60.0, False, "s"),
    ("rest_filter_tau", "restFilterTau", 0.0, 10.0, False, "s"),
    ("rest_th_gyr", "restThGyr", 0.0, 100.0, False, "deg/s"),
    ("rest_th_acc", "restThAcc", 0.0, 10.0, False, "m/s^2"),
    ("mag_current_tau", "magCurrentTau", -1.0, 10.0, True, "s (<= 0 disables it)"),
    ("mag_ref_tau", "magRefTau", 0.0, 1000.0, False, "s"),
    ("mag_norm_th", "magNormTh", 0.0, 1.0, False, "(fraction)"),
    ("mag_dip_th", "magDipTh", 0.0, 90.0, False, "deg"),
    ("mag_new_time", "magNewTime", 0.0, 1000.0, False, "s"),
    ("mag_new_first_time", "magNewFirstTime", 0.0, 1000.0, False, "s"),
    ("mag_new_min_gyr", "magNewMinGyr", 0.0, 1000.0, True, "deg/s"),
    ("mag_min_undisturbed_time", "magMinUndisturbedTime", 0.0, 100.0, True, "s"),
    ("mag_max_rejection_time", "magMaxRejectionTime", 0.0, 1000.0, True, "s"),
    ("mag_rejection_factor", "magRejectionFactor", 0.0, 100.0, False, ""),
)
_FLAGS: tuple[tuple[str, str], ...] = (
    ("motion_bias_est", "motionBiasEstEnabled"),
    ("rest_bias_est", "restBiasEstEnabled"),
    ("mag_dist_rejection", "magDistRejectionEnabled"),
)


@dataclass(frozen=True)
class VqfParams:
    """Parameters of :class:`VqfStage`: the ``vqf.VQFParams`` of the ``vqf`` package, in snake
    case. Every default is the package's (Laidig & Seel 2023, the values of its evaluation);
    none is tuned on the data of this project. Every field is validated on construction.
    """

    tau_acc: float = 3.0
    """Time constant (s) of the low-pass filter of the specific force in the almost inertial
    frame (cut-off ``sqrt(2) / (2 pi tau_acc)``). Default 3.0 s (vqf ``tauAcc``)."""
    tau_mag: float = 9.0
    """Time constant (s) of the first-order heading correction. Default 9.0 s (``tauMag``)."""
    motion_bias_est: bool = True
    """Estimate the gyro bias during motion (from the inclination correction only). Default True
    (``motionBiasEstEnabled``)."""
    rest_bias_est: bool = True
    """Detect rest and estimate the gyro bias at rest. Default True (``restBiasEstEnabled``)."""
    mag_dist_rejection: bool = True
    """Detect and reject magnetic disturbances. Default True (``magDistRejectionEnabled``)."""
    bias_sigma_init: float = 0.5
    """Standard deviation (deg/s) of the initial bias uncertainty. Default 0.5 deg/s
    (``biasSigmaInit``)."""
    bias_forgetting_time: float = 100.0
    """Time (s) in which the bias uncertainty grows from 0 to 0.1 deg/s (the bias filter's
    process noise). Default 100 s (``biasForgettingTime``)."""
    bias_clip: float = 2.0
    """Largest expected gyro bias (deg/s): clips the estimate and the bias innovation. Default
    2.0 deg/s (``biasClip``)."""
    bias_sigma_motion: float = 0.1
    """Standard deviation (deg/s) of the converged bias uncertainty in motion. Default 0.1 deg/s
    (``biasSigmaMotion``)."""
    bias_vertical_forgetting_factor: float = 0.0001
    """Relative weight of the artificial zero measurement of the (unobservable in motion)
    vertical bias. Default 0.0001 (``biasVerticalForgettingFactor``)."""
    bias_sigma_rest: float = 0.03
    """Standard deviation (deg/s) of the converged bias uncertainty at rest. Default 0.03 deg/s
    (``biasSigmaRest``)."""
    rest_min_t: float = 1.5
    """Time (s) the readings must stay near their low-passed reference to detect rest. Default
    1.5 s (``restMinT``)."""
    rest_filter_tau: float = 0.5
    """Time constant (s) of the low-pass reference of rest detection. Default 0.5 s
    (``restFilterTau``)."""
    rest_th_gyr: float = 2.0
    """Angular-rate threshold (deg/s) of rest detection. Default 2.0 deg/s (``restThGyr``)."""
    rest_th_acc: float = 0.5
    """Specific-force threshold (m/s^2) of rest detection. Default 0.5 m/s^2 (``restThAcc``)."""
    mag_current_tau: float = 0.05
    """Time constant (s) of the low-pass filter of the current field norm and dip; <= 0 disables
    it. Default 0.05 s (``magCurrentTau``)."""
    mag_ref_tau: float = 20.0
    """Time constant (s) of the adaptation of the field reference (norm, dip). Default 20 s
    (``magRefTau``)."""
    mag_norm_th: float = 0.1
    """Relative field-norm threshold of disturbance detection. Default 0.1 (``magNormTh``)."""
    mag_dip_th: float = 10.0
    """Dip-angle threshold (deg) of disturbance detection. Default 10 deg (``magDipTh``)."""
    mag_new_time: float = 20.0
    """Time (s) a different homogeneous field must persist (in motion) to become the reference.
    Default 20 s (``magNewTime``)."""
    mag_new_first_time: float = 5.0
    """As ``mag_new_time`` while there is no reference yet. Default 5 s (``magNewFirstTime``)."""
    mag_new_min_gyr: float = 20.0
    """Angular rate (deg/s) below which time does not count towards ``mag_new_time``. Default
    20 deg/s (``magNewMinGyr``)."""
    mag_min_undisturbed_time: float = 0.5
    """Time (s) within the thresholds after which the field counts as undisturbed again.
    Default 0.5 s (``magMinUndisturbedTime``)."""
    mag_max_rejection_time: float = 60.0
    """Longest full rejection (s) of a disturbed field; after it the heading is corrected with a
    slower time constant. Default 60 s (``magMaxRejectionTime``)."""
    mag_rejection_factor: float = 2.0
    """Factor slowing the heading correction after ``mag_max_rejection_time``. Default 2.0
    (``magRejectionFactor``)."""

    def __post_init__(self) -> None:
        for name, _, lo, hi, lo_in, unit in _RANGES:
            check_in_range(self, name, lo, hi, unit, lo_open=not lo_in)
        for name, _ in _FLAGS:
            check_bool(self, name)

    def vqf_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of ``vqf.VQF`` (its camel-case parameter names)."""
        out: dict[str, Any] = {v: float(getattr(self, k)) for k, v, *_ in _RANGES}
        out.update({v: bool(getattr(self, k)) for k, v in _FLAGS})
        return out

    def build(self, batch_size: int, fs: float) -> VqfStage:
        """The :class:`VqfStage` with these parameters."""
        return VqfStage(batch_size, fs, self)


def _import_vqf() -> Any:
    try:
        import vqf
    except ImportError as err:
        raise ImportError(
            "VqfStage needs the 'vqf' package (pip install vqf, or the project's 'bench' extra: "
            f"pip install -e .[bench]): {err}"
        ) from None
    return vqf


class VqfStage(TakesUsers):
    """VQF (``vqf.VQF``, one filter per stream) as an attitude stage
    (:class:`estimators.stages.AttitudeStage`).

    Args:
        batch_size: B streams (users).
        fs: IMU rate, Hz (one sample every ``1 / fs`` s; gyro, accelerometer and magnetometer
            share it).
        params: :class:`VqfParams` (the ``vqf`` defaults if None).
    """

    name = "vqf"
    per_user_fields = ("filters",)  # one vqf.VQF per user
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int, fs: float, params: VqfParams | None = None) -> None:
        self.batch_size = check_batch_size(batch_size, "VqfStage")
        self.fs = check_rate(fs, who="VqfStage")
        if params is None:
            params = VqfParams()
        if not isinstance(params, VqfParams):
            raise ValueError(f"VqfStage: params must be a VqfParams, got {params!r}")
        self.params = params
        self.dt = 1.0 / self.fs
        self._vqf = _import_vqf().VQF
        self._kwargs = params.vqf_kwargs()
        self.filters: list[Any] = [self._new() for _ in range(self.batch_size)]

    def _new(self) -> Any:
        return self._vqf(self.dt, **self._kwargs)

    def __getstate__(self) -> dict[str, Any]:
        """The stage with each ``vqf.VQF`` as its state dict (``vqf.VQF`` itself, a C++ object,
        can be neither copied nor pickled): ``copy.deepcopy`` and ``pickle`` go through it."""
        state = self.__dict__.copy()
        state["filters"] = [f.state for f in self.filters]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        """A new ``vqf.VQF`` per stream (same ``dt`` and parameters, so the same coefficients)
        given the stored state: it goes on exactly as the stream it was taken from."""
        self.__dict__.update(state)
        filters = []
        for saved in state["filters"]:
            f = self._new()
            f.state = saved
            filters.append(f)
        self.filters = filters

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the streams ``rows`` (indices, a (B,) mask, or None for all): each gets a new
        ``vqf.VQF``. Other streams are untouched."""
        for r in stream_rows(rows, self.batch_size, "rows", unique=False):
            self.filters[r] = self._new()

    def update(
        self, gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Consume (B, N, 3) gyro (rad/s), accelerometer (m/s^2) and magnetometer (any unit, or
        None) samples; return the (B, N, 4) attitude ``[w, x, y, z]`` (sensor -> ENU) after each."""
        g, a, m = check_samples(gyr, acc, mag, self.batch_size, "VqfStage")
        out = np.empty((g.shape[0], g.shape[1], 4))
        if g.shape[1] == 0:
            return out
        # vqf skips [0, 0, 0] accelerometer / magnetometer samples: zero the unusable ones.
        g = np.where(np.isfinite(g).all(axis=-1, keepdims=True), g, 0.0)
        a = np.where(np.isfinite(a).all(axis=-1, keepdims=True), a, 0.0)
        if m is None:
            m = np.zeros_like(g)
        else:
            m = np.where(np.isfinite(m).all(axis=-1, keepdims=True), m, 0.0)
        for i, f in enumerate(self.filters):
            out[i] = f.updateBatch(g[i], a[i], m[i])["quat9D"]
        return out

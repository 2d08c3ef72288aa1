"""Hand orientation from Kinect v2 frames: the pipeline of seed 003 (Yao, Chen, Pan, Huang 2023).

The stages (seed 003, sections 1.1-1.4):

1. Target user selection (1.1): among the tracked bodies pick the one nearest the sensor, keep it
   by id from frame to frame, re-select when its id is gone or no longer tracked.
2. Joint smoothing (1.2): the Kinect SDK's Holt double-exponential joint filter plus a weighted
   average over the last 5 frames (:class:`~estimators.joint_smoothing.HoltSmoother`).
3. :func:`quat_to_euler_paper` — the wrist quaternion to Euler angles with eq (1), and eq (2) where
   ``|wy - zx| > 0.499`` (1.3).
4. A Kalman filter per angle (:class:`KalmanParams` documents the model), then a median over
   consecutive Kalman outputs (1.4).

Every stage runs in one compiled kernel, :mod:`estimators._hand_numba`. :class:`HandPipeline`
runs all four for the environment: one Kinect frame per ``update`` call, or the M frames of a
control step per ``update_frames`` call; :func:`estimate_hand_orientation` runs it over recorded
or simulated sequences. :class:`OrientationFilter` runs stages 3 and 4 alone on wrist quaternions
or raw angles, batched over B streams, with the same code. The paper's static-variance experiment
(Tables 1-4) lives in :mod:`agents.experiments.hand_variance`.

Axis names. Seed 003's eq (1) writes::

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

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import _hand_numba as _k
from estimators.batching import TakesUsers, stream_rows
from estimators.joint_smoothing import (
    INFERRED,
    TRACKED,
    HoltParams,
    HoltSmoother,
    OneEuroFilter,
    OneEuroParams,
)
from estimators.kernels.records import param_record, record_dtype
from estimators.validation import (
    check_batch_size,
    check_condition,
    check_in_range,
    check_instance,
    check_numbers,
    check_rate,
    check_value,
    value_repr,
)

__all__ = [
    "PAPER_AXIS_NAMES",
    "HandFrame",
    "HandParams",
    "HandPipeline",
    "HoltParams",
    "HoltSmoother",
    "KalmanParams",
    "OneEuroFilter",
    "OneEuroParams",
    "OrientationFilter",
    "OrientationFrame",
    "RawHand",
    "Seed003Hand",
    "estimate_hand_orientation",
    "estimate_lag",
    "paper_to_ypr",
    "quat_to_euler_paper",
    "unwrap_angles",
    "ypr_to_paper",
]

#: Seed 003's names of our ``[yaw, pitch, roll]`` columns (its Tables' row order Roll, Pitch, Yaw).
PAPER_AXIS_NAMES = ("roll", "pitch", "yaw")

#: Seed 003's gimbal-lock threshold on ``|wy - zx|`` (section 1.3; 0.5 is pitch +-90 deg).
PAPER_SINGULARITY_THRESHOLD = 0.499

#: Kinect v2 frame rate, Hz (Kinect for Windows SDK 2.0; seed 003, section 2.2).
KINECT_RATE_HZ = 30.0

# Kinect v2 JointType indices (Kinect for Windows SDK 2.0), as defaults; the environment's
# vrloco_env.user.skeleton.Joint holds the same numbers.
_SPINE_BASE, _SPINE_MID, _WRIST_RIGHT, _SPINE_SHOULDER = 0, 1, 10, 20

_MIN_QUAT_NORM = 1e-6  # below this a quaternion is treated as a dropout (no orientation)


# ----------------------------------------------------------------------------------------------
# Quaternion -> Euler (eq 1, eq 2)


def ypr_to_paper(ypr: ArrayLike) -> NDArray[np.float64]:
    """Our ``[yaw, pitch, roll]`` (..., 3) to seed 003's eq (1) order ``[yaw_p, pitch_p, roll_p]``.

    The paper's yaw is our roll and its roll our yaw, so this reverses the last axis.
    """
    return np.asarray(ypr, dtype=np.float64)[..., ::-1].copy()


def paper_to_ypr(euler: ArrayLike) -> NDArray[np.float64]:
    """Seed 003's eq (1) order (..., 3) to our ``[yaw, pitch, roll]`` (reverses the last axis)."""
    return np.asarray(euler, dtype=np.float64)[..., ::-1].copy()


def quat_to_euler_paper(
    q: ArrayLike, threshold: float = PAPER_SINGULARITY_THRESHOLD
) -> NDArray[np.float64]:
    """Seed 003's quaternion -> Euler conversion, eq (1), with eq (2) where ``|wy - zx| > 0.499``.

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
    if np.any(np.linalg.norm(qa, axis=-1) <= _MIN_QUAT_NORM):
        raise ValueError(f"q contains a zero-norm quaternion (|q| <= {_MIN_QUAT_NORM})")
    check_value("threshold", threshold, 0.0, 0.5, lo_open=True)
    ypr, _, _ = _angles_of(qa, threshold)
    return ypr_to_paper(ypr)


def _angles_of(
    q: NDArray[np.float64], threshold: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]:
    """Eq (1)/(2) of (..., 4) quaternions through the kernel (:data:`estimators._hand_numba.
    angles_kernel`): our ``[yaw, pitch, roll]`` (..., 3), usable (...), singular (...)."""
    lead = q.shape[:-1]
    rows = np.ascontiguousarray(q.reshape(-1, 4), dtype=np.float64)
    n = rows.shape[0]
    ypr, usable, singular = np.empty((n, 3)), np.empty(n, bool), np.empty(n, bool)
    _k.angles_kernel(n)(rows, float(threshold), ypr, usable, singular)
    return ypr.reshape(*lead, 3), usable.reshape(lead), singular.reshape(lead)


# ----------------------------------------------------------------------------------------------
# Euler filtering (1.4)


def _per_axis(value: float | Sequence[float]) -> NDArray[np.float64]:
    """A validated field that is a number or one per axis, as a (3,) array."""
    return np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)).copy()


@dataclass(frozen=True)
class KalmanParams:
    """Kalman filter on each Euler angle: constant-rate model with adaptive process noise.

    Seed 003 gives the generic equations (3)-(8) but neither its model nor its noise values. We
    choose per axis the state ``[angle, rate]`` with ``A = [[1, dt], [0, 1]]``, ``H = [1, 0]``,
    driven by white angular acceleration of spectral density ``q`` (``Q = q [[dt^3/3, dt^2/2],
    [dt^2/2, dt]]``). A constant-rate model follows a steady rotation without lag, which a
    random-walk (A = 1) model cannot.

    A fixed ``q`` forces a choice between smoothing a still hand (small ``q``) and following a
    turning one (large ``q``); variance alone rewards the first (SPEC section 3). So ``q`` adapts:
    with ``nis`` the normalised innovation squared ``y^2 / S`` low-passed with time constant
    ``adapt_time``, ``q = accel_psd * clip(nis, 1, .)^2``, capped at ``max_accel_psd``. At rest
    ``nis`` is about 1 (strong smoothing); when the hand accelerates the innovations grow and the
    filter opens within a few frames (the noise-level adjustment of Bar-Shalom, Li, Kirubarajan,
    "Estimation with Applications to Tracking and Navigation", 2001, ch. 11: adjustable
    process noise level).
    ``max_accel_psd == accel_psd`` gives the plain Kalman filter. The innovation is wrapped to
    (-pi, pi] and the angle state kept unwrapped, so crossing +-180 deg gives no 360 deg jump.

    Seed 003 states no values; ``accel_psd`` was chosen on the development seeds of
    :mod:`agents.experiments.hand_variance` (static: seeds 1, 2, the paper's 11 angles x 5
    repeats x 10 s; moving: seeds 101, 102, 10 users sweeping about the forearm at 90 deg/s), the
    other fields set by the reasoning given with each.

    Attributes:
        rate_hz: frame rate, Hz (Kinect v2: 30).
        measurement_std: std of the raw Euler angles, rad (one value or one per ``[yaw, pitch,
            roll]``). Default 2 deg: seed 003's raw static variances (Tables 1-3) span 0.5 to
            14 deg^2 (0.7 to 3.7 deg), typically about 4 deg^2.
        accel_psd: spectral density of the angular acceleration at rest, rad^2/s^3 (one or per
            axis). Default 1: on the development seeds, the value of the grid 0.03, 0.1, 0.3, 1,
            3, 10 whose Kalman output has the smallest RMSE against the truth relative to raw's,
            averaged over the three axes, the still and the moving trials (0.926; 0.935 at 0.3,
            0.926 at 3; ``python -m agents.experiments.hand_variance --only seed003``). Smaller
            values smooth a still hand more (higher variance reduction) and fall behind a moving
            one.
        max_accel_psd: cap of the adapted density, rad^2/s^3 (one or per axis, >= accel_psd).
            Default 10.
        adapt_time: time constant of the innovation average that drives the adaptation, s.
            Default 0.1 s (3 frames).
        init_rate_std: std of the rate at initialisation, rad/s. Default 90 deg/s, a brisk wrist
            rotation.
        max_coast_frames: frames a stream without a valid measurement keeps predicting before it
            is declared stale (its output then holds and the next valid measurement
            re-initialises it). Default 5 (167 ms at 30 Hz).
    """

    rate_hz: float = KINECT_RATE_HZ
    measurement_std: float | tuple[float, float, float] = float(np.deg2rad(2.0))
    accel_psd: float | tuple[float, float, float] = 1.0
    max_accel_psd: float | tuple[float, float, float] = 10.0
    adapt_time: float = 0.1
    init_rate_std: float | tuple[float, float, float] = float(np.deg2rad(90.0))
    max_coast_frames: int = 5

    def __post_init__(self) -> None:
        inf = math.inf
        check_in_range(self, "rate_hz", 0.0, inf, "Hz", lo_open=True)
        per_axis = (("measurement_std", "rad"), ("accel_psd", "rad^2/s^3"),
                    ("max_accel_psd", "rad^2/s^3"), ("init_rate_std", "rad/s"))  # fmt: skip
        for name, unit in per_axis:  # a number, or one per axis
            if isinstance(getattr(self, name), numbers.Real):
                check_in_range(self, name, 0.0, inf, unit, lo_open=True)
            else:
                check_numbers(self, name, 0.0, inf, unit, length=3, lo_open=True)
        lo, hi = _per_axis(self.accel_psd), _per_axis(self.max_accel_psd)
        check_condition(self, "max_accel_psd", bool(np.all(hi >= lo)),
                        f">= accel_psd={value_repr(self.accel_psd)} on every axis")  # fmt: skip
        check_in_range(self, "adapt_time", 0.0, inf, "s", lo_open=True)
        check_in_range(self, "max_coast_frames", 0, inf, "frames", whole=True)


def _kalman_constants(
    p: KalmanParams,
) -> tuple[float, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
           NDArray[np.float64], float]:  # fmt: skip
    """The filter's constants: frame period dt (s); per axis the measurement variance, the
    acceleration PSD at rest and its cap, the initial rate variance; the gain per frame of the
    innovation low-pass, ``1 - exp(-dt / adapt_time)``."""
    dt = 1.0 / p.rate_hz
    return (
        dt,
        _per_axis(p.measurement_std) ** 2,
        _per_axis(p.accel_psd),
        _per_axis(p.max_accel_psd),
        _per_axis(p.init_rate_std) ** 2,
        1.0 - np.exp(-dt / p.adapt_time),
    )


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


# ----------------------------------------------------------------------------------------------
# Orientation chain: eq (1)/(2) -> Kalman -> median


@dataclass(frozen=True)
class HandParams:
    """Parameters of the hand pipeline.

    Attributes:
        holt: joint smoothing, :class:`HoltParams` (Kinect SDK defaults).
        kalman: Euler Kalman filter, :class:`KalmanParams`.
        median_window: frames in the median over consecutive Kalman outputs, >= 1. Default 3:
            seed 003 does not state it. On a steady rotation a causal median of n frames lags
            (n - 1) / 2 frames: 33 ms for 3, 67 ms for 5 at 30 Hz. Behind our Kalman filter the
            median removes a few points more variance at rest but adds that lag in motion (its
            share and its price: ``vrloco experiment hand-variance``), so we keep the smallest
            window that is still a median; 1 disables it.
        singularity_threshold: eq (2) is used where ``|wy - zx|`` exceeds this (paper: 0.499).
        wrist_joint: joint whose orientation ``hand_quat`` is (default 10, WristRight).
        center_joints: joints whose mean locates a body for the nearest-body rule (default 0
            SpineBase, 1 SpineMid, 20 SpineShoulder).
        min_wrist_state: the wrist quaternion is used only if the wrist joint's tracking state is
            at least this (1: inferred accepted, the default, since the Kinect still reports an
            orientation; 2: tracked only). Below it the frame is an orientation dropout.
    """

    holt: HoltParams = field(default_factory=HoltParams)
    kalman: KalmanParams = field(default_factory=KalmanParams)
    median_window: int = 3
    singularity_threshold: float = PAPER_SINGULARITY_THRESHOLD
    wrist_joint: int = _WRIST_RIGHT
    center_joints: tuple[int, ...] = (_SPINE_BASE, _SPINE_MID, _SPINE_SHOULDER)
    min_wrist_state: int = INFERRED

    def __post_init__(self) -> None:
        check_instance(self, "holt", HoltParams)
        check_instance(self, "kalman", KalmanParams)
        check_in_range(self, "median_window", 1, math.inf, "frames", whole=True)
        check_in_range(self, "singularity_threshold", 0.0, 0.5, lo_open=True)
        check_in_range(self, "min_wrist_state", INFERRED, TRACKED, whole=True,
                       allowed="1 (inferred) or 2 (tracked)")  # fmt: skip
        check_in_range(self, "wrist_joint", 0, math.inf, "(a joint index)", whole=True)
        check_numbers(self, "center_joints", 0, math.inf, "(joint indices)", whole=True)


@dataclass
class OrientationFrame:
    """Output of :class:`OrientationFilter`; angles ``[yaw, pitch, roll]`` in rad.

    Arrays are (B, ...) for :meth:`OrientationFilter.update`, (B, M, ...) for the M-frame calls.

    Attributes:
        ypr_raw: (B, 3) eq (1)/(2) of this frame's quaternion; the last valid value is held on a
            dropout (NaN before the first).
        ypr_kalman: (B, 3) Kalman output, wrapped to (-pi, pi].
        ypr: (B, 3) Kalman + median output (the pipeline's estimate), wrapped.
        quat_valid: (B,) bool, this frame's quaternion (or angles) was used (False: dropout,
            value held).
        singular: (B,) bool, eq (2) was used (|wy - zx| > threshold).
        valid: (B,) bool, the outputs hold an estimate (False before the first valid frame).
    """

    ypr_raw: NDArray[np.float64]
    ypr_kalman: NDArray[np.float64]
    ypr: NDArray[np.float64]
    quat_valid: NDArray[np.bool_]
    singular: NDArray[np.bool_]
    valid: NDArray[np.bool_]


class OrientationFilter(TakesUsers):
    """Eq (1)/(2), then the Kalman filter, then the median, for B streams of wrist quaternions.

    Stage 3 of :class:`HandPipeline` without target selection and joint smoothing, run by the same
    compiled code (:data:`estimators._hand_numba.filter_kernel` after
    :data:`estimators._hand_numba.angles_kernel`): fed the target's wrist quaternions, it gives the
    pipeline's ``ypr_raw``, ``ypr_kalman`` and ``ypr`` bit for bit. For recorded or simulated
    orientation sequences (the static-variance experiment of seed 003) and for hand stages that
    filter the pipeline's raw angles again with other parameters (:meth:`update_angles`).

    Dropouts -- a NaN or zero-norm quaternion, NaN angles, or ``valid`` False -- are never
    propagated as NaN: the raw angles hold their last value, the Kalman filter coasts (then holds,
    see :class:`KalmanParams`), the median is not fed, and ``quat_valid`` is False. Infinite
    entries are a ValueError. The median runs on the Kalman filter's unwrapped angles, so its
    window never straddles a +-180 deg wrap.

    Args:
        batch_size: number of streams B.
        params: :class:`HandParams` (only ``kalman``, ``median_window`` and
            ``singularity_threshold`` are used here).
    """

    per_user_fields = ("_state", "_pending")  # the kernel's (user, window) state, resets due
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int, params: HandParams | None = None) -> None:
        self.batch_size = check_batch_size(batch_size, "OrientationFilter")
        self.params = params if params is not None else HandParams()
        if not isinstance(self.params, HandParams):
            raise ValueError(
                f"OrientationFilter: params must be a HandParams, got {self.params!r}"
            )
        self._prm, self._axes = _kernel_params(self.params)
        self._state = _k.new_filter_state(self.batch_size, self.params.median_window)
        self._pending = np.zeros(self.batch_size, bool)  # streams to forget before next frame

    @property
    def active(self) -> NDArray[np.bool_]:
        """(B,) bool: the stream's Kalman filter holds an estimate (updated or coasted)."""
        return (self._state[0]["active"] != 0.0) & ~self._pending

    def reset(self, mask: ArrayLike | None = None) -> None:
        """Forget the streams where ``mask`` (B,) is True (all if None), before their next frame."""
        m = np.ones(self.batch_size, bool) if mask is None else np.asarray(mask, dtype=bool)
        if m.shape != (self.batch_size,):
            raise ValueError(f"mask must have shape ({self.batch_size},), got {m.shape}")
        self._pending |= m

    def _flags(self, name: str, value: ArrayLike | None, m: int, default: bool) -> NDArray:
        if value is None:
            return np.full((self.batch_size, m), default)
        v = np.asarray(value, dtype=bool)
        if v.shape != (self.batch_size, m):
            raise ValueError(f"{name} must have shape ({self.batch_size}, {m}), got {v.shape}")
        return v

    def _frames(self, name: str, x: ArrayLike, width: int) -> NDArray[np.float64]:
        """``x`` as (B, M, width) float64 frames (M >= 1, no inf; NaN is a dropout), or a
        ValueError naming ``name``."""
        a = np.asarray(x, dtype=np.float64)
        if a.ndim != 3 or a.shape[0] != self.batch_size or a.shape[2] != width or a.shape[1] < 1:
            raise ValueError(
                f"{name} must have shape ({self.batch_size}, M, {width}) with M >= 1, "
                f"got {a.shape}"
            )
        if np.isinf(a).any():
            raise ValueError(f"{name} contains infinite entries; use NaN for a dropout")
        return a

    def update_angles(
        self, ypr: ArrayLike, usable: ArrayLike | None = None, restart: ArrayLike | None = None
    ) -> OrientationFrame:
        """Filter M frames of raw angles (the Kalman filter and the median only).

        Args:
            ypr: (B, M, 3) raw ``[yaw, pitch, roll]``, rad (NaN = dropout).
            usable: (B, M) bool, False marks a dropout; None = every frame with finite angles.
            restart: (B, M) bool, forget the stream before that frame (e.g. a new target user).

        Returns:
            :class:`OrientationFrame` of (B, M, ...) arrays; ``singular`` is all False (the
            angles carry no quaternion).
        """
        z = self._frames("ypr", ypr, 3)
        m = z.shape[1]
        ok = self._flags("usable", usable, m, True) & np.isfinite(z).all(axis=-1)
        return self._run(z, ok, self._flags("restart", restart, m, False), np.zeros_like(ok))

    def update_frames(
        self, q: ArrayLike, valid: ArrayLike | None = None, reset: ArrayLike | None = None
    ) -> OrientationFrame:
        """Filter M frames of wrist quaternions: the same numbers as M :meth:`update` calls.

        Args:
            q: (B, M, 4) quaternions ``[w, x, y, z]`` (any norm > 1e-6; NaN or zero = dropout).
            valid: (B, M) bool, False marks a dropout (e.g. no target user); None = all valid.
            reset: (B, M) bool, streams to forget before that frame (e.g. a new target user).

        Returns:
            :class:`OrientationFrame` of (B, M, ...) arrays.
        """
        qa = self._frames("hand_quat", q, 4)
        m = qa.shape[1]
        ypr, usable, singular = _angles_of(qa, self.params.singularity_threshold)
        ok = usable & self._flags("valid", valid, m, True)
        return self._run(ypr, ok, self._flags("reset", reset, m, False), singular & ok)

    def update(
        self, q: ArrayLike, valid: ArrayLike | None = None, reset: ArrayLike | None = None
    ) -> OrientationFrame:
        """Filter one frame of wrist quaternions.

        Args:
            q: (B, 4) quaternions ``[w, x, y, z]`` (any norm > 1e-6; NaN or zero = dropout).
            valid: (B,) bool, False marks a dropout (e.g. no target user); None = all valid.
            reset: (B,) bool, streams to forget before this frame (e.g. a new target user).

        Returns:
            :class:`OrientationFrame` of (B, ...) arrays.
        """
        qa = np.asarray(q, dtype=np.float64)
        if qa.shape != (self.batch_size, 4):
            raise ValueError(f"hand_quat must have shape ({self.batch_size}, 4), got {qa.shape}")
        flags = [None if f is None else np.asarray(f, dtype=bool) for f in (valid, reset)]
        for name, f in zip(("valid", "reset"), flags, strict=True):
            if f is not None and f.shape != (self.batch_size,):
                raise ValueError(f"{name} must have shape ({self.batch_size},), got {f.shape}")
        out = self.update_frames(qa[:, None], *(None if f is None else f[:, None] for f in flags))
        return OrientationFrame(*(getattr(out, f.name)[:, 0] for f in fields(OrientationFrame)))

    def _run(
        self, z: NDArray, ok: NDArray, restart: NDArray, singular: NDArray
    ) -> OrientationFrame:
        """The kernel over (B, M) frames, the pending resets applied before the first."""
        b, m = ok.shape
        restart = restart.copy()
        restart[:, 0] |= self._pending
        self._pending[:] = False
        rows = b * m
        raw, kalman, ypr = np.empty((rows, 3)), np.empty((rows, 3)), np.empty((rows, 3))
        valid = np.empty(rows, bool)
        _k.filter_kernel(b)(
            np.ascontiguousarray(z.reshape(rows, 3)), ok.reshape(rows), restart.reshape(rows), m,
            self._prm, self._axes, self._state, (raw, kalman, ypr, valid),
        )  # fmt: skip
        return OrientationFrame(
            ypr_raw=raw.reshape(b, m, 3),
            ypr_kalman=kalman.reshape(b, m, 3),
            ypr=ypr.reshape(b, m, 3),
            quat_valid=ok,
            singular=singular,
            valid=valid.reshape(b, m),
        )

# ----------------------------------------------------------------------------------------------
# The whole pipeline


@dataclass
class HandFrame:
    """Output of :class:`HandPipeline` for one Kinect frame of B streams.

    Angles are ``[yaw, pitch, roll]`` in rad (the project's ZYX names; seed 003 calls these
    columns Roll, Pitch, Yaw), of the wrist orientation in camera space.

    Attributes:
        slot: (B,) int64 body slot of the target, -1 when no tracked body.
        body_id: (B,) int64 target id, 0 when none.
        reselected: (B,) bool, a new target was selected this frame (filters were reset).
        has_target: (B,) bool, a tracked target exists in this frame.
        joints: (B, J, 3) smoothed target joints, metres (NaN without target or for untracked
            joints).
        joint_state: (B, J) int8 raw tracking states of the target's joints (0 without target).
        all_inferred: (B,) bool, the target has no *tracked* joint, only inferred ones.
        ypr_raw, ypr_kalman, ypr, quat_valid, singular, valid: see :class:`OrientationFrame`.
    """

    slot: NDArray[np.int64]
    body_id: NDArray[np.int64]
    reselected: NDArray[np.bool_]
    has_target: NDArray[np.bool_]
    joints: NDArray[np.float64]
    joint_state: NDArray[np.int8]
    all_inferred: NDArray[np.bool_]
    ypr_raw: NDArray[np.float64]
    ypr_kalman: NDArray[np.float64]
    ypr: NDArray[np.float64]
    quat_valid: NDArray[np.bool_]
    singular: NDArray[np.bool_]
    valid: NDArray[np.bool_]

    def at(self, t: int) -> HandFrame:
        """Frame ``t`` of a frame stack such as :meth:`HandPipeline.update_frames` returns.

        Args:
            t: time index (negative counts from the end: ``at(-1)`` is the last frame).

        Returns:
            :class:`HandFrame` of views ``field[:, t]`` (B, ...).
        """
        return HandFrame(*(getattr(self, name)[:, t] for name in _HAND_FRAME_FIELDS))


_HAND_FRAME_FIELDS = tuple(f.name for f in fields(HandFrame))  # in the constructor's order


class HandPipeline(TakesUsers):
    """Seed 003's hand-orientation pipeline, streaming, batched over B users.

    Per frame: select the target user (seed 003, 1.1), reset the filters of streams whose
    target changed, smooth its joints (the Kinect SDK's Holt filter and the weighted average, as
    :class:`~estimators.joint_smoothing.HoltSmoother` does), convert its wrist quaternion (eq 1/2)
    and filter the angles (Kalman, then median), as :class:`OrientationFilter` does.

    Target selection. The current target is kept while a slot holds its id and is tracked, else
    the tracked body nearest the sensor is selected: nearest by the Euclidean distance from the
    sensor of a body's centre, the mean of its valid ``center_joints`` (default SpineBase,
    SpineMid, SpineShoulder: the torso, which moves least). Seed 003 says "nearest by depth
    data"; the Euclidean distance differs from depth only for bodies far off-axis. Slots with id
    0, untracked slots and bodies without a valid centre joint are never selected; ties go to the
    lowest slot. The current target is kept even when another body comes nearer.

    Documented behaviour on bad frames:

    * no tracked body: ``has_target`` False, ``slot`` -1, ``body_id`` 0, joints NaN; the angles
      coast then hold their last value with ``quat_valid`` False. The next target found is a new
      selection and resets the filters (even if it has the old id: the gap may be long).
    * the angles are NaN, with ``valid`` False, only between a (re)selection and the new target's
      first usable wrist quaternion: they never carry one user's estimate over to another.
    * NaN joints / untracked joints: NaN in ``joints`` for those joints only; their filter
      restarts when they come back.
    * a frame with only inferred joints: the body is still the target if tracked; joints are
      smoothed with the doubled inferred radii; ``all_inferred`` is True; the wrist quaternion is
      used if ``min_wrist_state`` is 1 (default), else the frame is an orientation dropout.
    * zero-norm or NaN wrist quaternion: orientation dropout (as above), ``quat_valid`` False.
    * infinite values, wrong shapes, states outside {0, 1, 2}, ids that are not integers,
      negative or repeated within a frame: ValueError.

    The frames run through the compiled kernel :mod:`estimators._hand_numba`, one user at a
    time: :meth:`update` takes one frame, :meth:`update_frames` the M frames of a control step
    in one call, with the same numbers. The pipeline holds the kernel's state (target ids, Holt
    filters, Kalman filters, median windows); :meth:`reset` clears it.

    Args:
        batch_size: number of users B.
        params: :class:`HandParams` (defaults if None).
        num_joints: joints per body J (25 for Kinect v2).
        num_bodies: body slots per frame K (6 for Kinect v2).
    """

    per_user_fields = ("_state",)  # the kernel's (target, user, joint, ring, window) arrays
    batch_size_field = "batch_size"

    def __init__(
        self,
        batch_size: int,
        params: HandParams | None = None,
        num_joints: int = 25,
        num_bodies: int = 6,
    ) -> None:
        if batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        self.params = params if params is not None else HandParams()
        p = self.params
        if max(p.wrist_joint, *p.center_joints) >= num_joints:
            raise ValueError(f"wrist_joint and center_joints must be < num_joints={num_joints}")
        self.batch_size = int(batch_size)
        self.num_joints = int(num_joints)
        self.num_bodies = int(num_bodies)
        w = np.asarray(p.holt.average_weights, dtype=np.float64)
        self._weights = w / w.sum()  # the Holt average's weights, newest first
        self._head = 0  # the Holt ring's newest slot, shared by all users
        self._center = np.asarray(p.center_joints, dtype=np.int64)
        self._prm, self._axes = _kernel_params(p)
        self._state = _k.new_state(self.batch_size, self.num_joints, w.size, p.median_window)
        #: (B,) int64 id of each stream's current target, 0 for none (the kernel's own array).
        self.target_id = self._state[0]

    def reset(self, mask: ArrayLike | None = None) -> None:
        """Forget target and filters of the streams where ``mask`` (B,) is True (all if None)."""
        m = np.ones(self.batch_size, bool) if mask is None else np.asarray(mask, dtype=bool)
        if m.shape != (self.batch_size,):
            raise ValueError(f"mask must have shape ({self.batch_size},), got {m.shape}")
        _k.forget_kernel(self.batch_size)(m, self._state)

    def take_users(self, rows: NDArray[np.intp]) -> None:
        """Keep the streams ``rows`` (:class:`~estimators.batching.TakesUsers`), and
        :attr:`target_id` with them (a view of the kernel's target array)."""
        super().take_users(rows)
        self.target_id = self._state[0]

    def _inputs(
        self,
        body_id: ArrayLike,
        body_tracked: ArrayLike,
        joints: ArrayLike,
        joint_state: ArrayLike,
        hand_quat: ArrayLike,
        lead: tuple[int, ...],
    ) -> tuple[NDArray[np.int64], NDArray[np.bool_], NDArray[np.float64], NDArray, NDArray]:
        """The kernel's input tuple, shapes checked against ``lead`` + (K, ...): int64 ids, bool
        tracking flags, float64 joints and quaternions, integer joint states."""
        k, nj = self.num_bodies, self.num_joints
        ids = np.asarray(body_id)
        tracked = np.asarray(body_tracked)
        jts = np.asarray(joints, dtype=np.float64)
        st = np.asarray(joint_state)
        hq = np.asarray(hand_quat, dtype=np.float64)
        for name, arr, shape in (
            ("body_id", ids, (*lead, k)),
            ("body_tracked", tracked, (*lead, k)),
            ("joints", jts, (*lead, k, nj, 3)),
            ("joint_state", st, (*lead, k, nj)),
            ("hand_quat", hq, (*lead, k, 4)),
        ):
            if arr.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
        tracked = tracked if tracked.dtype == np.bool_ else tracked.astype(bool)
        return _kernel_ids(ids), tracked, jts, _kernel_states(st), hq

    def update(
        self,
        body_id: ArrayLike,
        body_tracked: ArrayLike,
        joints: ArrayLike,
        joint_state: ArrayLike,
        hand_quat: ArrayLike,
    ) -> HandFrame:
        """Process one Kinect frame.

        Args:
            body_id: (B, K) int body ids, 0 = empty slot.
            body_tracked: (B, K) bool.
            joints: (B, K, J, 3) camera-space joints, metres, NaN where not tracked.
            joint_state: (B, K, J) int tracking states (0 not tracked, 1 inferred, 2 tracked).
            hand_quat: (B, K, 4) wrist orientations ``[w, x, y, z]`` in camera space.

        Returns:
            :class:`HandFrame`.

        Raises:
            ValueError: see the class docstring.
        """
        b = self.batch_size
        frames = self._inputs(body_id, body_tracked, joints, joint_state, hand_quat, (b,))
        out = _new_frames((b,), self.num_joints)
        self._run(frames, 1, out, "")
        return HandFrame(*out)

    def update_frames(
        self,
        body_id: ArrayLike,
        body_tracked: ArrayLike,
        joints: ArrayLike,
        joint_state: ArrayLike,
        hand_quat: ArrayLike,
    ) -> HandFrame:
        """Process M consecutive Kinect frames in one call: the same numbers as M :meth:`update`.

        For the environment, which receives the M (about 3) Kinect frames of a control step at
        once: one call instead of M. ``HandFrame.at(-1)`` is the frame a last :meth:`update` would
        have returned.

        Args:
            body_id: (B, M, K) int body ids, 0 = empty slot.
            body_tracked: (B, M, K) bool.
            joints: (B, M, K, J, 3) camera-space joints, metres, NaN where not tracked.
            joint_state: (B, M, K, J) int tracking states.
            hand_quat: (B, M, K, 4) wrist orientations ``[w, x, y, z]``.

        Returns:
            :class:`HandFrame` whose arrays carry the frame axis after the batch axis, e.g.
            ``ypr`` (B, M, 3), ``joints`` (B, M, J, 3).

        Raises:
            ValueError: as :meth:`update`; every frame is checked before any is processed, so a
                bad frame leaves the state untouched (M :meth:`update` calls would have processed
                the frames before it), and the message names the frame.
        """
        b = self.batch_size
        shape = np.shape(body_id)
        if len(shape) != 3 or shape[0] != b or shape[1] < 1:
            raise ValueError(
                f"body_id must have shape ({b}, M, {self.num_bodies}) with M >= 1, got {shape}"
            )
        m = shape[1]
        frames = self._inputs(body_id, body_tracked, joints, joint_state, hand_quat, (b, m))
        rows = b * m
        out = _new_frames((b, m), self.num_joints)
        self._run(
            tuple(a.reshape(rows, *a.shape[2:]) for a in frames),
            m,
            tuple(a.reshape(rows, *a.shape[2:]) for a in out),
            " (frame {t})",
        )
        return HandFrame(*out)

    def _run(
        self, frames: tuple[NDArray, ...], m: int, out: tuple[NDArray, ...], where: str
    ) -> None:
        """Validate, then run the kernel over rows ``b * m + t``, writing into ``out``."""
        b = self.batch_size
        ids, _, jts, st, hq = frames
        flat = jts.reshape(-1) if jts.flags.c_contiguous else _EMPTY
        code, t = _k.validate(ids, jts, st, hq, b, m, flat)
        if code:
            raise ValueError(_KERNEL_ERRORS[code] + where.format(t=t))
        _k.hand_kernel(b)(
            frames, m, self._prm, self._axes, self._center, self._weights, self._head,
            self._state, out,
        )  # fmt: skip
        n_hist = self._weights.size
        if n_hist > 1:  # the ring advances once per frame
            self._head = (self._head - m) % n_hist


def _kernel_params(p: HandParams) -> tuple[NDArray, NDArray]:
    """The kernel's parameter records (:mod:`estimators._hand_numba`): ``prm`` (1,) with the
    fields of :class:`HoltParams` and ``PARAM_FIELDS``, ``axes`` (3,) with ``AXIS_FIELDS``."""
    dt, r, q, q_max, p11_init, lam = _kalman_constants(p.kalman)
    values = {
        "singularity_threshold": p.singularity_threshold,
        "wrist_joint": p.wrist_joint,
        "min_wrist_state": p.min_wrist_state,
        "max_coast_frames": p.kalman.max_coast_frames,
        "dt": dt,
        "dt2_2": dt**2 / 2.0,
        "dt3_3": dt**3 / 3.0,
        "nis_gain": lam,
    }
    prm = param_record(p.holt, **{name: values[name] for name in _k.PARAM_FIELDS})
    axes = np.zeros(3, record_dtype({name: () for name in _k.AXIS_FIELDS}))
    for name, value in zip(_k.AXIS_FIELDS, (r, q, q_max, p11_init), strict=True):
        axes[name] = value
    return _k.shared_layout(prm), _k.shared_layout(axes)


def _kernel_ids(ids: NDArray) -> NDArray[np.int64]:
    """Body ids as int64 (uint64 ids below 2**63 included); ValueError for other dtypes."""
    kind = ids.dtype.kind
    if kind == "i" or (kind == "u" and ids.dtype.itemsize < 8):
        return ids if ids.dtype == np.int64 else ids.astype(np.int64)
    if kind == "u":
        if ids.size and ids.max() > np.iinfo(np.int64).max:
            raise ValueError("body_id must be < 2**63")
        return ids.astype(np.int64)
    raise ValueError(f"body_id must hold integers, got dtype {ids.dtype}")


def _kernel_states(st: NDArray) -> NDArray:
    """Tracking states as int64 (one dtype, so the kernel is compiled once whatever the caller
    passes); float or bool states must be whole numbers."""
    if st.dtype.kind in "iu":
        return st if st.dtype == np.int64 else st.astype(np.int64)
    with np.errstate(invalid="ignore"):
        whole = st.astype(np.int64)
    if not np.array_equal(whole, st):
        raise ValueError(_KERNEL_ERRORS[_k.ERR_STATE_RANGE])
    return whole


def _new_frames(lead: tuple[int, ...], nj: int) -> tuple[NDArray, ...]:
    """Empty :class:`HandFrame` fields (in their order) for ``lead`` = (B,) or (B, M)."""
    return (
        np.empty(lead, np.int64),
        np.empty(lead, np.int64),
        np.empty(lead, bool),
        np.empty(lead, bool),
        np.empty((*lead, nj, 3)),
        np.empty((*lead, nj), np.int8),
        np.empty(lead, bool),
        np.empty((*lead, 3)),
        np.empty((*lead, 3)),
        np.empty((*lead, 3)),
        np.empty(lead, bool),
        np.empty(lead, bool),
        np.empty(lead, bool),
    )


_EMPTY = np.empty(0)  # "no flat view" for _hand_numba.validate

#: ValueError messages of the kernel's input checks.
_KERNEL_ERRORS = {
    _k.ERR_JOINTS_INF: "joints contains infinite coordinates; use NaN for untracked joints",
    _k.ERR_QUAT_INF: "hand_quat contains infinite entries; use NaN for a dropout",
    _k.ERR_STATE_RANGE: "joint_state values must be 0 (not tracked), 1 (inferred) or 2",
    _k.ERR_NEGATIVE_ID: "body_id must be >= 0 (0 marks an empty slot)",
    _k.ERR_DUPLICATE_ID: "body_id holds the same non-zero id in two slots of one stream",
}


def estimate_hand_orientation(
    body_id: ArrayLike,
    body_tracked: ArrayLike,
    joints: ArrayLike,
    joint_state: ArrayLike,
    hand_quat: ArrayLike,
    params: HandParams | None = None,
) -> HandFrame:
    """Run :class:`HandPipeline` over whole sequences (offline API; same numbers as streaming).

    Args:
        body_id: (B, M, K) or, for one stream, (M, K) body ids over M frames.
        body_tracked: (B, M, K) or (M, K) bool.
        joints: (B, M, K, J, 3) or (M, K, J, 3) metres.
        joint_state: (B, M, K, J) or (M, K, J).
        hand_quat: (B, M, K, 4) or (M, K, 4).
        params: :class:`HandParams`.

    Returns:
        :class:`HandFrame` whose arrays carry the time axis after the batch axis, e.g. ``ypr`` is
        (B, M, 3) — or (M, 3) for single-stream input.
    """
    ids = np.asarray(body_id)
    single = ids.ndim == 2
    arrays = [np.asarray(a) for a in (body_id, body_tracked, joints, joint_state, hand_quat)]
    if single:
        arrays = [a[None] for a in arrays]
    ids = arrays[0]
    if ids.ndim != 3:
        raise ValueError(f"body_id must have shape (B, M, K) or (M, K), got {np.shape(body_id)}")
    b, m, k = ids.shape
    for name, a in zip(
        ("body_tracked", "joints", "joint_state", "hand_quat"), arrays[1:], strict=True
    ):
        if a.shape[:3] != (b, m, k):
            raise ValueError(f"{name} must start with shape {(b, m, k)}, got {a.shape}")
    if arrays[2].ndim != 5:
        raise ValueError(
            f"joints must have shape (B, M, K, J, 3) or (M, K, J, 3), got {np.shape(joints)}"
        )
    nj = arrays[2].shape[3]
    pipe = HandPipeline(b, params, num_joints=nj, num_bodies=k)
    if m == 0:
        raise ValueError("the sequences hold no frame (M = 0)")
    out = pipe.update_frames(*arrays)  # the same numbers as M calls of update()
    if single:
        return HandFrame(**{f.name: getattr(out, f.name)[0] for f in fields(HandFrame)})
    return out


# ----------------------------------------------------------------------------------------------
# Experiment helpers


def estimate_lag(
    estimate: ArrayLike,
    reference: ArrayLike,
    rate_hz: float,
    max_lag_s: float = 0.5,
    axis: int = 0,
) -> NDArray[np.float64]:
    """Delay (s) of ``estimate`` behind ``reference``: the shift minimising their RMS difference.

    Shifts from 0 to ``max_lag_s`` are tried in steps of 1/10 frame (linear interpolation of the
    reference); NaN samples are ignored. Works per channel: the result has the shape of one time
    sample (e.g. (3,) for (M, 3) inputs with ``axis=0``).
    """
    est = np.moveaxis(np.asarray(estimate, dtype=np.float64), axis, 0)
    ref = np.moveaxis(np.asarray(reference, dtype=np.float64), axis, 0)
    if est.shape != ref.shape:
        raise ValueError(f"estimate and reference shapes differ: {est.shape} vs {ref.shape}")
    if not (rate_hz > 0 and max_lag_s >= 0):
        raise ValueError("rate_hz must be > 0 and max_lag_s >= 0")
    m = est.shape[0]
    flat_e = est.reshape(m, -1)
    flat_r = ref.reshape(m, -1)
    t = np.arange(m, dtype=np.float64)
    shifts = np.arange(0.0, max_lag_s * rate_hz + 1e-9, 0.1)  # frames
    cost = np.empty((shifts.size, flat_e.shape[1]))
    for i, sh in enumerate(shifts):  # a loop over candidate delays, not over the batch
        pos = t - sh
        i0 = np.floor(pos).astype(np.int64)
        frac = (pos - i0)[:, None]
        inside = (i0 >= 0)[:, None]
        lo = flat_r[np.clip(i0, 0, m - 1)]
        hi = flat_r[np.clip(i0 + 1, 0, m - 1)]
        shifted = np.where(inside, lo * (1.0 - frac) + hi * frac, np.nan)
        d = flat_e - shifted
        cost[i] = np.sqrt(np.nanmean(d * d, axis=0))
    best = shifts[np.nanargmin(cost, axis=0)] / rate_hz
    return best.reshape(est.shape[1:])


# ----------------------------------------------------------------------------------------------
# Hand stages (estimators.stages.HAND): the pipeline's own outputs


def check_hand_frames(frames: HandFrame, batch_size: int, who: str) -> int:
    """The number of frames M of a (B, M) :class:`HandFrame` stack, or a ValueError naming
    ``who`` when its angles are not (batch_size, M, 3) or its flags not (batch_size, M)."""
    ypr = np.shape(getattr(frames, "ypr_raw", None))
    if len(ypr) != 3 or ypr[0] != batch_size or ypr[2] != 3 or ypr[1] < 1:
        raise ValueError(
            f"{who}: frames must be a HandFrame stacked over M >= 1 frames, ypr_raw of shape "
            f"({batch_size}, M, 3); got {ypr}"
        )
    m = ypr[1]
    for name in ("ypr", "quat_valid", "reselected", "valid"):
        shape = np.shape(getattr(frames, name))
        want = (batch_size, m, 3) if name == "ypr" else (batch_size, m)
        if shape != want:
            raise ValueError(f"{who}: frames.{name} must have shape {want}, got {shape}")
    return m


class Seed003Hand(TakesUsers):
    """Seed 003's Kalman + median output as a hand stage (:class:`estimators.stages.HandStage`).

    :class:`HandPipeline` already runs the filter (its state is the pipeline's); this stage
    reports the frames' ``ypr`` and ``valid`` unchanged (copies, bit for bit). It holds no state,
    so :meth:`reset` only checks its argument: the pipeline's own reset forgets the filter.

    Args:
        batch_size: B streams (users).
        fs: Kinect frame rate, Hz (checked, not used: the pipeline's :class:`KalmanParams` carry
            the rate of its filter).
        params: unused; accepted for the factory signature ``(batch_size, fs)`` of
            :data:`estimators.stages.HAND`.
    """

    name = "seed003"
    per_user_fields = ()  # stateless: dropping users changes only B
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int, fs: float = KINECT_RATE_HZ, params: None = None) -> None:
        self.batch_size = check_batch_size(batch_size, "Seed003Hand")
        self.fs = check_rate(fs, who="Seed003Hand")
        if params is not None:
            raise ValueError(
                f"Seed003Hand: takes no params (the pipeline's HandParams), got {params!r}"
            )

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Nothing to forget (the pipeline holds the filter); ``rows`` is checked."""
        stream_rows(rows, self.batch_size, "rows", unique=False)

    def update(self, frames: HandFrame) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """(B, M, 3) ``frames.ypr`` and (B, M) ``frames.valid``, copied."""
        check_hand_frames(frames, self.batch_size, "Seed003Hand")
        return np.array(frames.ypr, dtype=np.float64), np.array(frames.valid, dtype=bool)


class RawHand(TakesUsers):
    """The unfiltered eq (1)/(2) angles as a hand stage: the floor any filter must beat.

    Returns the frames' ``ypr_raw``: this frame's angles where its quaternion was usable, the last
    usable ones held through a dropout (``quat_valid`` False), NaN between a (re)selection and the
    new target's first usable quaternion. ``valid`` is True where a raw estimate of the current
    target exists (the angles are finite): it stays True through a dropout, as the seed 003
    stage's does. Stateless; :meth:`reset` only checks its argument.

    Args:
        batch_size: B streams (users).
        fs: Kinect frame rate, Hz (checked, not used).
        params: unused; accepted for the factory signature.
    """

    name = "raw"
    per_user_fields = ()  # stateless: dropping users changes only B
    batch_size_field = "batch_size"

    def __init__(self, batch_size: int, fs: float = KINECT_RATE_HZ, params: None = None) -> None:
        self.batch_size = check_batch_size(batch_size, "RawHand")
        self.fs = check_rate(fs, who="RawHand")
        if params is not None:
            raise ValueError(f"RawHand: takes no params, got {params!r}")

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Nothing to forget; ``rows`` is checked."""
        stream_rows(rows, self.batch_size, "rows", unique=False)

    def update(self, frames: HandFrame) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """(B, M, 3) ``frames.ypr_raw`` (copied) and (B, M) validity (all three angles finite)."""
        check_hand_frames(frames, self.batch_size, "RawHand")
        ypr = np.array(frames.ypr_raw, dtype=np.float64)
        return ypr, np.isfinite(ypr).all(axis=-1)

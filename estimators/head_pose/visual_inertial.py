"""Loosely coupled visual-inertial helmet pose: an error-state Kalman filter (the helmet-tracking
paper), batched.

Source: the helmet-tracking paper section 3 ("組合測(cè)量算法"): a Kalman filter with the inertial
solution as the prediction and the visual pose as the measurement, and an adaptive variant that
re-estimates the noise statistics from the innovations (Sage-Husa) for time-varying visual noise.
The paper gives no state vector, Jacobians or noise values; the filter below is the standard loosely
coupled error-state filter (Solà, "Quaternion kinematics for the error-state Kalman filter", 2017,
with the *global* attitude error of its section 7) and every choice is stated here.

State
-----
Nominal, per user: position ``p`` (m, world ENU), velocity ``v`` (m/s), attitude ``q`` (body ->
world), accelerometer bias ``b_a`` (m/s^2), gyro bias ``b_g`` (rad/s). Error state (15):
``dx = [dp, dv, dtheta, db_a, db_g]`` with ``p = p_hat + dp``, ``q = exp(dtheta) ⊗ q_hat``
(``dtheta`` a small rotation in the *world* frame, so that it is what the camera's attitude
residual measures directly) and ``b = b_hat + db``.

Prediction (every IMU sample, interval ``dt``)
----------------------------------------------
* Nominal: :mod:`estimators.head_pose.strapdown`'s mechanisation (RK4 attitude with the gyro linear
  between samples, end-point trapezoid for v and p) with the bias estimates removed from both ends.
* Error dynamics, with ``R = R(q_hat)`` and ``a_f = R (f - b_a)`` the world specific force at the
  end of the interval: ``dp' = dv``, ``dv' = -[a_f x] dtheta - R db_a - R n_a``,
  ``dtheta' = -R db_g - R n_g``, ``db_a' = n_ba``, ``db_g' = n_bg``. First-order transition
  ``F = I + A dt`` and ``Q = diag(0, s_a^2, s_g^2, s_ba^2, s_bg^2) dt`` (the isotropic noise is
  unchanged by ``R``): ``s_a``, ``s_g`` are the white-noise densities, ``s_ba``, ``s_bg`` the
  bias random walks. Both are evaluated at the end of the interval (first order in dt).
* ``P <- F P F^T + Q`` every sample: at 1 kHz ``|A| dt`` is < 1e-2 even in fast head turns, so a
  lower covariance rate would save little and the hot loop is compiled anyway.

Measurement (a visual pose, :mod:`estimators.head_pose.pnp`)
----------------------------------------------------------
``z = [p_meas - p_hat, log(q_meas ⊗ q_hat^-1)]`` (6), ``H = [[I 0 0 0 0], [0 0 I 0 0]]``,
``S = H P H^T + R``. Gate: frames whose normalised innovation squared ``nu^T S^-1 nu`` exceeds the
chi-square quantile (6 dof, ``gate_probability``) are rejected and counted. A filter that rejects
everything never recovers (its P stays small while the truth walks away, or the visual noise has
grown): after ``gate_max_consecutive`` rejections in a row the next frame is taken anyway (counted
in ``forced``), which also lets the adaptive R see a noise increase. Gain ``K = P H^T S^-1``,
Joseph form ``P <- (I - K H) P (I - K H)^T + K R K^T``, injection (``q <- exp(dtheta) ⊗ q``), and
the error reset ``P <- G P G^T`` with ``G = I + [dtheta/2 x]`` on the attitude block (Solà eq 287,
global error).

Measurements apply at the current filter time: the caller feeds the IMU samples up to the camera
frame's instant, then the frame (the camera clock quantised to the IMU's 1 ms; a real system would
also model the exposure delay).

Adaptive noise (``adaptive="sage_husa"``)
----------------------------------------
Sage-Husa fading-memory estimate of R from the innovations, before the gain of the same frame:
``d_k = (1 - b) / (1 - b^(k+1))``, ``R_k = (1 - d_k) R_{k-1} + d_k (nu nu^T - H P^- H^T)``. The raw
estimate can be non-positive (``nu nu^T`` is rank one and ``H P H^T`` is subtracted), so:

* diagonal mode (default, ``sage_husa_diagonal=True``): only the diagonal is estimated and each
  entry is clamped to ``[r_floor^2, r_ceiling^2]`` (position and attitude bounds separately): a
  6x6 full estimate from rank-one terms is noisy, and the camera's position and attitude errors
  are correlated mostly through the geometry, which the filter need not model.
* full mode: the symmetrised estimate's eigenvalues are clamped to ``[min floor^2, max ceiling^2]``.

Refused frames still count (robust Sage-Husa, decision): a frame the gate refuses enters the R
estimate with its innovation scaled down to the gate (``nu sqrt(gate / NIS)``, Huber's clipping),
while the state is not updated. Without it R learns only from frames that already agree with it:
after the light dims, a third of the frames are refused for seconds (the env's low-light episodes
showed it) and R climbs only through the forced frames. A single wrong PnP pose moves R by at
most one gate-sized term.

Departure from the literal formula: ``k`` starts at ``r_prior_frames`` instead of 0. With ``k = 0``,
``d_0 = 1`` and the first frame's single outer product replaces the configured R0 (then
``d_1 = 1/(1 + b)``...), so the first frames' R is mostly noise; starting at ``k0`` weighs R0 as
``k0`` frames' worth of evidence. Rejected frames do not enter the estimate (outliers would
inflate it); forced frames do.

Adaptive Q (``adapt_q=True``): one scale factor on Q per user from the normalised innovation,
``alpha <- clip(alpha (1 + d_q (nis / 6 - 1)), q_scale_bounds)`` with its own slower forgetting
factor ``q_forgetting``: ``E[nis] = 6`` when the filter is consistent, so alpha grows while the
prediction is over-confident and shrinks when it is under-confident. It is identifiable only
while ``H P^- H^T`` is a visible part of ``S`` (otherwise nis hardly depends on alpha and alpha
drifts slowly between its bounds); with both adaptations on, R (faster) absorbs measurement noise
changes and Q (slower) persistent prediction errors.

The per-sample prediction and the update are the compiled per-user kernels of
:mod:`estimators.head_pose._kernel` (their uncompiled ``py_func`` is the readable source).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2

from estimators.batching import TakesUsers, stream_rows
from estimators.head_pose import _kernel as _k
from estimators.head_pose.strapdown import set_nominal_state
from estimators.kernels.records import param_record
from estimators.rotations import GRAVITY
from estimators.validation import (
    check_array,
    check_batch_size,
    check_bool,
    check_choice,
    check_condition,
    check_in_range,
    check_numbers,
    check_rate,
)

__all__ = [
    "STATUS_ACCEPTED",
    "STATUS_FORCED",
    "STATUS_REJECTED",
    "STATUS_SKIPPED",
    "VioConfig",
    "VisualInertialFilter",
]

STATUS_SKIPPED = _k.STATUS_SKIPPED
STATUS_ACCEPTED = _k.STATUS_ACCEPTED
STATUS_REJECTED = _k.STATUS_REJECTED
STATUS_FORCED = _k.STATUS_FORCED

_ADAPTIVE = ("fixed", "sage_husa")
_MG = 1e-3 * GRAVITY
_DEG = math.pi / 180.0
#: Numeric fields of :class:`VioConfig` the kernels do not read (``reset`` and the derived
#: record values use them).
_NOT_IN_KERNEL = (
    "init_position_sigma",
    "init_velocity_sigma",
    "init_attitude_sigma",
    "init_accel_bias_sigma",
    "init_gyro_bias_sigma",
    "position_sigma",
    "attitude_sigma",
    "r_prior_frames",
    "gate_probability",
)


@dataclass(frozen=True)
class VioConfig:
    """Parameters of :class:`VisualInertialFilter`, with units, defaults and reasons.

    IMU defaults follow the consumer MEMS of ``vrloco_env``'s IMU presets (Bosch BMI160: accel
    0.18 mg/sqrt(Hz), gyro 0.007 deg/s/sqrt(Hz); bias stability 5 mg and 0.25 deg/s with a 100 s
    correlation time, turned into the random walk ``sigma sqrt(2 / tau)`` that has the same
    short-term growth).

    Attributes:
        accel_noise_density: accelerometer white noise, m/s^2/sqrt(Hz). Default 0.18 mg/sqrt(Hz).
        gyro_noise_density: gyro white noise, rad/s/sqrt(Hz). Default 0.007 deg/s/sqrt(Hz).
        accel_bias_walk: accelerometer bias random walk, m/s^2/sqrt(s). Default
            ``5 mg * sqrt(2 / 100 s)`` = 6.9e-3.
        gyro_bias_walk: gyro bias random walk, rad/s/sqrt(s). Default
            ``0.25 deg/s * sqrt(2 / 100 s)`` = 6.2e-4.
        init_position_sigma: initial position std, m. Default 0.05 (a visual fix).
        init_velocity_sigma: initial velocity std, m/s. Default 0.1 (standing user).
        init_attitude_sigma: initial attitude std, rad. Default 2 deg.
        init_accel_bias_sigma: initial accelerometer bias std, m/s^2. Default 20 mg (BMI160
            turn-on offset, 1 sigma).
        init_gyro_bias_sigma: initial gyro bias std, rad/s. Default 1.5 deg/s (BMI160).
        position_sigma: visual position noise, m (R0 diagonal sqrt). Default 0.025: the seed's
            "+-0.05 m" ideal visual accuracy read as a 2-sigma bound.
        attitude_sigma: visual attitude noise per axis, rad. Default 0.5 deg (seed: "+-1 deg").
        adaptive: ``"fixed"`` (R stays R0) or ``"sage_husa"`` (module docstring).
        forgetting: Sage-Husa forgetting factor b, in [0.9, 0.9999] (typ. 0.95-0.999). Default
            0.98: a memory of about ``1 / (1 - b)`` = 50 frames (0.4 s at 120 Hz), short enough to
            follow a lighting change, long enough to average 50 rank-one terms.
        sage_husa_diagonal: estimate only the diagonal of R (default True, recommended).
        r_prior_frames: frames of evidence the initial R0 (and Q scale 1) count for, >= 0.
            Default 50 (= ``1 / (1 - b)``).
        adapt_q: adapt a Q scale factor from the normalised innovations. Default False.
        q_forgetting: forgetting factor of the Q scale, in [0.9, 0.99999]. Default 0.998
            (about 4 s at 120 Hz): slower than R so that the two do not chase each other.
        q_scale_bounds: (low, high) bounds of the Q scale, 0 < low <= 1 <= high. Default
            (0.1, 100).
        gate_probability: chi-square quantile of the 6-dof innovation gate in (0.5, 1), or None
            for no gate. Default 0.999 (threshold 22.46): a consistent filter rejects 0.1 % of
            good frames.
        gate_max_consecutive: rejections in a row after which a frame is taken anyway, >= 1.
            Default 12 (0.1 s at 120 Hz): long against isolated wrong matches, short against
            an IMU-only drift.
        r_floor: (position m, attitude rad) lower bound of the adapted R's standard deviations.
            Default (1 mm, 0.05 deg): no camera in the seed is better.
        r_ceiling: (position m, attitude rad) upper bound. Default (0.5 m, 10 deg): beyond that
            a frame carries no information the IMU lacks over 0.1 s.
        gravity: gravity magnitude, m/s^2, in [9.0, 10.5]. Default standard gravity.
    """

    accel_noise_density: float = 0.18 * _MG
    gyro_noise_density: float = 0.007 * _DEG
    accel_bias_walk: float = 5.0 * _MG * math.sqrt(2.0 / 100.0)
    gyro_bias_walk: float = 0.25 * _DEG * math.sqrt(2.0 / 100.0)
    init_position_sigma: float = 0.05
    init_velocity_sigma: float = 0.1
    init_attitude_sigma: float = 2.0 * _DEG
    init_accel_bias_sigma: float = 20.0 * _MG
    init_gyro_bias_sigma: float = 1.5 * _DEG
    position_sigma: float = 0.025
    attitude_sigma: float = 0.5 * _DEG
    adaptive: str = "fixed"
    forgetting: float = 0.98
    sage_husa_diagonal: bool = True
    r_prior_frames: int = 50
    adapt_q: bool = False
    q_forgetting: float = 0.998
    q_scale_bounds: tuple[float, float] = (0.1, 100.0)
    gate_probability: float | None = 0.999
    gate_max_consecutive: int = 12
    r_floor: tuple[float, float] = (1e-3, 0.05 * _DEG)
    r_ceiling: tuple[float, float] = (0.5, 10.0 * _DEG)
    gravity: float = GRAVITY
    _record: NDArray | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        positive = (
            "accel_noise_density",
            "gyro_noise_density",
            "accel_bias_walk",
            "gyro_bias_walk",
            "init_position_sigma",
            "init_velocity_sigma",
            "init_attitude_sigma",
            "init_accel_bias_sigma",
            "init_gyro_bias_sigma",
            "position_sigma",
            "attitude_sigma",
        )
        inf = math.inf
        for name in positive:
            check_in_range(self, name, 0.0, inf, lo_open=True)
        check_choice(self, "adaptive", _ADAPTIVE)
        check_in_range(self, "forgetting", 0.9, 0.9999)
        check_in_range(self, "q_forgetting", 0.9, 0.99999)
        check_in_range(self, "gravity", 9.0, 10.5, "m/s^2")
        check_bool(self, "sage_husa_diagonal")
        check_bool(self, "adapt_q")
        check_in_range(self, "r_prior_frames", 0, inf, integer=True)
        check_in_range(self, "gate_max_consecutive", 1, inf, integer=True)
        check_numbers(self, "q_scale_bounds", 0.0, inf, length=2, lo_open=True)
        lo, hi = (float(x) for x in self.q_scale_bounds)
        check_condition(self, "q_scale_bounds", lo <= 1.0 <= hi, "(low, high), low <= 1 <= high")
        check_numbers(self, "r_floor", 0.0, inf, "(m, rad)", length=2, lo_open=True)
        check_numbers(self, "r_ceiling", 0.0, inf, "(m, rad)", length=2, lo_open=True)
        f_pos, f_att = (float(x) for x in self.r_floor)
        c_pos, c_att = (float(x) for x in self.r_ceiling)
        pos = f"in [r_floor[0]={f_pos:g}, r_ceiling[0]={c_pos:g}] m"
        check_in_range(self, "position_sigma", f_pos, c_pos, allowed=pos)
        att = f"in [r_floor[1]={f_att:g}, r_ceiling[1]={c_att:g}] rad"
        check_in_range(self, "attitude_sigma", f_att, c_att, allowed=att)
        gp = self.gate_probability
        if gp is not None:
            check_in_range(
                self,
                "gate_probability",
                0.5,
                1.0,
                lo_open=True,
                hi_open=True,
                allowed="in (0.5, 1) or None",
            )
        prm = param_record(
            self,
            exclude=_NOT_IN_KERNEL,
            sage_husa_diagonal=1.0 if self.sage_husa_diagonal else 0.0,
            adapt_q=1.0 if self.adapt_q else 0.0,
            sage_husa=1.0 if self.adaptive == "sage_husa" else 0.0,
            q_min=lo,
            q_max=hi,
            gate=math.inf if gp is None else float(chi2.ppf(gp, 6)),
            r_floor_pos=f_pos**2,
            r_floor_att=f_att**2,
            r_ceil_pos=c_pos**2,
            r_ceil_att=c_att**2,
        )
        prm = prm.view(np.dtype((np.record, prm.dtype)))
        prm.flags.writeable = False
        object.__setattr__(self, "_record", prm)

    def packed(self) -> NDArray:
        """The parameters as the kernels' read-only (1,) float64 record: the numeric fields the
        kernels read, by name (booleans as 0.0/1.0), and the derived ``sage_husa`` (1.0 for
        ``adaptive="sage_husa"``), ``q_min``/``q_max`` (``q_scale_bounds``), ``gate``
        (:attr:`gate_threshold`) and the variance bounds ``r_floor_pos``, ``r_floor_att``,
        ``r_ceil_pos``, ``r_ceil_att`` (m^2, rad^2)."""
        return self._record

    @property
    def gate_threshold(self) -> float:
        """The chi-square threshold on the 6-dof NIS (inf without a gate)."""
        return float(self._record[0]["gate"])

    @property
    def r0(self) -> NDArray[np.float64]:
        """(6, 6) initial R: ``diag(position_sigma^2 I, attitude_sigma^2 I)`` (m^2, rad^2)."""
        return np.diag([self.position_sigma**2] * 3 + [self.attitude_sigma**2] * 3)

    @property
    def p0(self) -> NDArray[np.float64]:
        """(15, 15) initial error-state covariance from the ``init_*_sigma`` fields."""
        s = [self.init_position_sigma, self.init_velocity_sigma, self.init_attitude_sigma]
        s += [self.init_accel_bias_sigma, self.init_gyro_bias_sigma]
        return np.diag(np.repeat(np.square(s), 3))

    def replace(self, **changes: Any) -> VioConfig:
        """A copy with some fields changed (validated like the original)."""
        return replace(self, **changes)

    def as_dict(self) -> dict[str, Any]:
        """The public fields as a plain dict."""
        d = asdict(self)
        d.pop("_record", None)
        return d


# ------------------------------------------------------------------------------------------------
# Public API.
# ------------------------------------------------------------------------------------------------


class VisualInertialFilter(TakesUsers):
    """Loosely coupled visual-inertial ESKF for B independent users (see the module docstring).

    Args:
        batch_size: number of users B, >= 1.
        imu_rate_hz: IMU sampling rate, Hz (uniform).
        config: filter parameters (default :class:`VioConfig`).

    Until :meth:`reset`, every user starts at the origin, at rest, level, with zero biases.

    Attributes:
        state: (B,) record array of the users' filter state, fields
            :data:`estimators.head_pose._kernel.STATE_FIELDS` (nominal state ``x``,
            covariances ``P`` and ``R``, counters); the properties below give copies.

    Example:
        >>> f = VisualInertialFilter(1, 1000.0)
        >>> f.reset([0, 0, 1.7], [0, 0, 0], [1, 0, 0, 0])
        >>> p, q = f.predict(np.zeros((1, 8, 3)), np.tile([0, 0, GRAVITY], (1, 8, 1)))
        >>> status = f.update([[0.0, 0.0, 1.7]], [[1.0, 0.0, 0.0, 0.0]], [True])
        >>> p.shape, int(status[0]), int(f.updates[0])
        ((1, 8, 3), 1, 1)
    """

    per_user_fields = ("state", "_work")  # filter state, kernel scratch
    batch_size_field = "batch_size"

    def __init__(
        self, batch_size: int, imu_rate_hz: float, config: VioConfig | None = None
    ) -> None:
        self.batch_size = check_batch_size(batch_size)
        self.imu_rate_hz = check_rate(imu_rate_hz, "imu_rate_hz")
        self.dt = 1.0 / self.imu_rate_hz
        if config is None:
            config = VioConfig()
        if not isinstance(config, VioConfig):
            raise ValueError(f"config must be a VioConfig, got {type(config).__name__}")
        self.config = config
        self._prm = config.packed()
        b = self.batch_size
        self.state = _k.records(_k.STATE_FIELDS, b)
        self._work = _k.records(_k.WORK_FIELDS, b)
        self.reset(np.zeros(3), np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))

    def reset(
        self,
        p: ArrayLike,
        v: ArrayLike,
        q: ArrayLike,
        mask: ArrayLike | None = None,
        accel_bias: ArrayLike | None = None,
        gyro_bias: ArrayLike | None = None,
        gyr: ArrayLike | None = None,
        acc: ArrayLike | None = None,
    ) -> None:
        """Restart some or all users at a given pose (covariances, R and counters to defaults).

        Args:
            p: (B, 3) or (3,) world position, m.
            v: (B, 3) or (3,) world velocity, m/s.
            q: (B, 4) or (4,) attitude body -> world (normalised here).
            mask: users to reset, (B,) bool or indices; None: all. Only their rows are used.
            accel_bias, gyro_bias: (B, 3) or (3,) initial bias estimates (m/s^2, rad/s), e.g.
                from :func:`estimators.head_pose.strapdown.static_gyro_bias`; None: zero.
            gyr, acc: (B, 3) or (3,) the IMU sample at the reset instant (start of the first
                interval); None: the first sample after the reset is held over the first interval.

        Raises:
            ValueError: shapes, non-finite values, a zero quaternion or a bad mask.
        """
        rows = stream_rows(mask, self.batch_size, "mask", unique=False)
        has_prev = set_nominal_state(self._x, rows, p, v, q, accel_bias, gyro_bias, gyr, acc)
        s = self.state
        s["P"][rows] = self.config.p0
        s["R"][rows] = self.config.r0
        s["has_prev"][rows] = has_prev
        s["k"][rows] = self.config.r_prior_frames
        s["q_scale"][rows] = 1.0
        for name in ("consec", "updates", "rejected", "forced", "nis"):
            s[name][rows] = 0.0

    @property
    def _x(self) -> NDArray[np.float64]:
        """(B, N_X) the nominal states: a view of :attr:`state`, taken at each use (a view kept
        as an attribute would become an array of its own in a copy or after ``take_users``)."""
        return self.state["x"]

    def predict(self, gyr: ArrayLike, acc: ArrayLike) -> tuple[NDArray, NDArray]:
        """Propagate every user through N IMU samples.

        Args:
            gyr: (B, N, 3) body angular rate, rad/s.
            acc: (B, N, 3) specific force, m/s^2 (level at rest: ``[0, 0, +g]``).

        Returns:
            ``(p (B, N, 3), q (B, N, 4))``: the estimated head position (m) and attitude (body ->
            world) after each sample.

        Raises:
            ValueError: wrong shapes or non-finite samples.
        """
        b = self.batch_size
        g = check_array(gyr, "gyr", (b, -1, 3))
        a = check_array(acc, "acc", g.shape)
        n = g.shape[1]
        out_p = np.empty((b, n, 3))
        out_q = np.empty((b, n, 4))
        _k.predict_kernel(b)(
            self.state,
            self._prm,
            np.ascontiguousarray(g),
            np.ascontiguousarray(a),
            self.dt,
            out_p,
            out_q,
            self._work,
        )
        return out_p, out_q

    def update(self, pos: ArrayLike, quat: ArrayLike, valid: ArrayLike) -> NDArray[np.int8]:
        """Correct with one visual pose per user, at the current filter time.

        Args:
            pos: (B, 3) measured head position, m (rows with ``valid`` False may be NaN).
            quat: (B, 4) measured head attitude body -> world (any sign, normalised here).
            valid: (B,) bool: which users have a pose this frame (e.g. ``VisualPoseBatch.ok``).

        Returns:
            (B,) int8 status: ``STATUS_SKIPPED`` (not valid), ``STATUS_ACCEPTED``,
            ``STATUS_REJECTED`` (gated out), ``STATUS_FORCED`` (gated out but taken after
            ``gate_max_consecutive`` rejections).

        Raises:
            ValueError: wrong shapes, a non-bool ``valid``, or non-finite / zero-norm values in a
                valid row.
        """
        b = self.batch_size
        ok = np.asarray(valid)
        if ok.dtype != np.bool_ or ok.shape != (b,):
            raise ValueError(f"valid must be a ({b},) bool array, got {ok.dtype} {ok.shape}")
        pm = check_array(pos, "pos", (b, 3), finite=False)
        qm = check_array(quat, "quat", (b, 4), finite=False)
        if not (np.all(np.isfinite(pm[ok])) and np.all(np.isfinite(qm[ok]))):
            raise ValueError("pos and quat must be finite in the rows where valid is True")
        if np.any(np.einsum("bi,bi->b", qm[ok], qm[ok]) < 1e-24):
            raise ValueError("quat contains a zero-norm quaternion in a valid row")
        status = np.empty(b, dtype=np.int8)
        _k.update_kernel(b)(
            self.state,
            self._prm,
            np.ascontiguousarray(pm),
            np.ascontiguousarray(qm),
            np.ascontiguousarray(ok),
            status,
            self._work,
        )
        return status

    def process(
        self,
        gyr: ArrayLike,
        acc: ArrayLike,
        frame_sample: ArrayLike,
        pos: ArrayLike,
        quat: ArrayLike,
        valid: ArrayLike,
    ) -> tuple[NDArray, NDArray, NDArray]:
        """Offline convenience: N IMU samples and M camera frames in one call.

        Frame ``j`` applies right after IMU sample ``frame_sample[j]`` (non-decreasing indices in
        [0, N)); equivalent to the interleaved :meth:`predict` / :meth:`update` calls.

        Args:
            gyr, acc: (B, N, 3) IMU samples (rad/s, m/s^2).
            frame_sample: (M,) int index of the IMU sample each frame follows.
            pos: (B, M, 3) measured positions, m. quat: (B, M, 4). valid: (B, M) bool.

        Returns:
            ``(p (B, N, 3), q (B, N, 4), status (B, M))``; p and q are the estimates after each
            IMU sample and after any update that follows it.
        """
        b = self.batch_size
        g = check_array(gyr, "gyr", (b, -1, 3))
        a = check_array(acc, "acc", g.shape)
        n = g.shape[1]
        idx = np.asarray(frame_sample)
        if idx.ndim != 1 or not np.issubdtype(idx.dtype, np.integer):
            raise ValueError(f"frame_sample must be a (M,) int array, got {idx.dtype} {idx.shape}")
        m = idx.size
        if m and (idx.min() < 0 or idx.max() >= n or np.any(np.diff(idx) < 0)):
            raise ValueError(f"frame_sample must be non-decreasing indices in [0, {n})")
        pm = check_array(pos, "pos", (b, m, 3), finite=False)
        qm = check_array(quat, "quat", (b, m, 4), finite=False)
        ok = np.asarray(valid)
        if ok.dtype != np.bool_ or ok.shape != (b, m):
            raise ValueError(f"valid must be a ({b}, {m}) bool array, got {ok.dtype} {ok.shape}")
        out_p = np.empty((b, n, 3))
        out_q = np.empty((b, n, 4))
        status = np.empty((b, m), dtype=np.int8)
        start = 0
        for j in range(m):
            stop = int(idx[j]) + 1
            if stop > start:
                out_p[:, start:stop], out_q[:, start:stop] = self.predict(
                    g[:, start:stop], a[:, start:stop]
                )
                start = stop
            status[:, j] = self.update(pm[:, j], qm[:, j], ok[:, j])
            out_p[:, stop - 1] = self._x[:, _k.X_P : _k.X_P + 3]
            out_q[:, stop - 1] = self._x[:, _k.X_Q : _k.X_Q + 4]
        if start < n:
            out_p[:, start:], out_q[:, start:] = self.predict(g[:, start:], a[:, start:])
        return out_p, out_q, status

    @property
    def position(self) -> NDArray[np.float64]:
        """(B, 3) current position estimate, m."""
        return self._x[:, _k.X_P : _k.X_P + 3].copy()

    @property
    def velocity(self) -> NDArray[np.float64]:
        """(B, 3) current velocity estimate, m/s."""
        return self._x[:, _k.X_V : _k.X_V + 3].copy()

    @property
    def quat(self) -> NDArray[np.float64]:
        """(B, 4) current attitude estimate, body -> world."""
        return self._x[:, _k.X_Q : _k.X_Q + 4].copy()

    @property
    def accel_bias(self) -> NDArray[np.float64]:
        """(B, 3) accelerometer bias estimate, m/s^2."""
        return self._x[:, _k.X_BA : _k.X_BA + 3].copy()

    @property
    def gyro_bias(self) -> NDArray[np.float64]:
        """(B, 3) gyro bias estimate, rad/s."""
        return self._x[:, _k.X_BG : _k.X_BG + 3].copy()

    @property
    def P(self) -> NDArray[np.float64]:
        """(B, 15, 15) error-state covariance."""
        return self.state["P"].copy()

    @property
    def R(self) -> NDArray[np.float64]:
        """(B, 6, 6) current measurement covariance (m^2, rad^2)."""
        return self.state["R"].copy()

    @property
    def updates(self) -> NDArray[np.int64]:
        """(B,) frames taken (accepted or forced) since the last reset."""
        return self.state["updates"].astype(np.int64)

    @property
    def rejected(self) -> NDArray[np.int64]:
        """(B,) frames rejected by the innovation gate since the last reset."""
        return self.state["rejected"].astype(np.int64)

    @property
    def forced(self) -> NDArray[np.int64]:
        """(B,) frames taken despite the gate (after too many consecutive rejections)."""
        return self.state["forced"].astype(np.int64)

    @property
    def q_scale(self) -> NDArray[np.float64]:
        """(B,) current Q scale factor (1 unless ``adapt_q``)."""
        return self.state["q_scale"].copy()

    @property
    def nis(self) -> NDArray[np.float64]:
        """(B,) normalised innovation squared of each user's last valid frame."""
        return self.state["nis"].copy()

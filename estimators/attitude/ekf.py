"""Head attitude from a 9D IMU: the indirect (error-state) EKF of Zhang 2021, section 1.

Source: Zhang, Chen, Gao, "Hands-free interaction based on an IMU in a VR device" (2021), eqs
(1)-(14) (``shared/seeds/000_*.txt``), corrected with the paper's own reference [21], Trawny &
Roumeliotis, "Indirect Kalman filter for 3D attitude estimation" (TR 2005-002, 2005), and with the
robustness of modern filters (VQF: Laidig & Seel, Information Fusion 91, 2023).

Conventions (:mod:`estimators.rotations`): ENU world, Hamilton ``q = [w, x, y, z]`` rotating sensor
coordinates into the world, ZYX Euler ``[yaw, pitch, roll]``. A static level sensor reads the
specific force ``f = [0, 0, +g]``; gyro in rad/s (body frame), accelerometer in m/s^2, magnetometer
in any unit (uT in our data).

The filter, step by step (paper structure kept; each departure is stated and justified)
--------------------------------------------------------------------------------------------
Nominal state: ``q`` and the gyro bias ``b`` (eq 1). Error state ``dx = [dphi, db]`` (eq 6), with
the *local* attitude error ``q_true = q ⊗ exp(dphi)`` and ``b_true = b + db``.

1. Propagation, eqs (3)-(5): ``q <- q ⊗ exp((y - b) dt)``; ``b`` constant (random walk).
2. Error dynamics, eqs (7)-(9): ``Phi = I + F dt``, ``P <- Phi P Phi^T + Q dt`` with
   ``Q = diag(gyr_noise^2 I, bias_walk^2 I)`` (the paper's ``G = G_c dt`` would give a Q in
   rad^2/s^2 * s^2 = rad^2 * dt^2, which vanishes with dt; the standard discretisation of white
   noise is ``G_c Q_c G_c^T dt``, used here). The paper prints ``F_c = 0``: then the bias never
   correlates with the attitude error, is unobservable and stays at its initial value. The default
   ``model="trawny"`` uses the error dynamics of the paper's reference [21],
   ``F = [[-[w x], -I], [0, 0]]`` (``w = y - b``); the other models keep ``F = 0`` (below).
3. Measurement, eqs (10)-(13). The paper measures Euler residuals
   ``z = [theta - theta_acc, gamma - gamma_acc, psi - psi_mag]`` with ``H = [I 0]``. That ``H`` is
   wrong for this error state: ``dphi`` is a small rotation in the sensor frame, not a vector of
   Euler increments (``d[yaw, pitch, roll] = E^-1 dphi`` with a matrix E that depends on pitch and
   roll and is singular at pitch = +-90 deg), so ``H = [I 0]`` is right only at yaw = pitch =
   roll = 0. The fix kept here measures the same three angles as small rotations about the world
   axes, ``dtheta_w = R(q) dphi``, so the paper's ``z = H dx`` stays with ``H = [R(q) 0]``:

   * tilt (rows x, y; "pitch and roll from the specific force", eq 11): with ``a = R(q) f`` the
     measured specific force in the world, ``a = Exp(-dtheta_w) g e_z + (linear acceleration)`` so
     ``z_x = a_y / g = dtheta_x`` and ``z_y = -a_x / g = dtheta_y`` to first order. We keep the
     horizontal components *linear* in ``f`` instead of taking angles (atan of the normalised
     vector, eq 11): a linear acceleration then enters the innovation linearly and averages out
     in the filter (VQF's insight: low-pass the specific force in an almost inertial frame).
     Measured on BROAD during development: the angle form left up to 8 deg of inclination error
     in the fast-translation trial 16, the linear form 1 deg.
   * heading (row z; "tilt-compensated magnetometer heading + declination", eqs 12-13): the field
     is rotated into the world with the *predicted* attitude, ``m_w = R(q) m``, and the residual is
     ``z_psi = wrap(pi/2 - D - atan2(m_w,y, m_w,x))``: magnetic north lies at yaw ``pi/2 - D`` in
     ENU (D the declination, positive east). The printed eq (12) compensates the tilt with the
     accelerometer angles; compensating with the filter's tilt removes the accelerometer's
     disturbances from the heading (measured on BROAD during development: mean total RMSE
     2.6 deg against 7.7 deg with ``east = m x f``). The row is ``H = [R(q)[2, :] 0]``; the
     coupling of a tilt error into the heading through the dip (``tan(dip) * tilt error``) is
     neglected so that the compass never tilts the estimate (VQF makes the same choice). The
     wrap keeps the innovation in (-pi, pi] when the heading crosses +-180 deg.

   Eq (14) is applied one measurement row at a time (three scalar updates; identical to the
   joint update for a diagonal R): ``dx <- dx + K (z - H dx)``, ``P <- P - K H P``. At rest a
   zero-rate update follows (below).
4. Inject and reset: ``q <- q ⊗ exp(dphi)``, ``b <- b + db``, ``dx <- 0`` (the reset Jacobian
   ``I - [dphi/2 x]`` is taken as I, dphi being small).

Measurement noise is given as a *density* (rad*sqrt(s)), ``R = sigma^2 / dt``: the correction
time constants (about ``acc_noise / gyr_noise`` and ``mag_noise / gyr_noise`` seconds) then do
not change with the sample rate, which matters because the disturbances they must ride out
(head accelerations, local fields) are not white.

Beyond the paper
----------------
* Walking: the tilt weight is lowered with the motion level ``l``, the low-passed
  ``| |f| - g |`` (time constant ``motion_tau``): ``R_acc = acc_noise^2 (1 + (l / acc_motion_ref)^2)
  / dt``. The level is low-passed on purpose: a weight that follows the instantaneous deviation
  is correlated with the disturbance and biases the tilt (BROAD, measured during development:
  4.6 deg mean total RMSE against 2.6 deg). No hard rejection either: dropping the samples with
  a large ``| |f| - g |`` biases the average the same way (BROAD: 3.0-4.3 deg).
* Rest: after ``rest_time`` with a small rate and ``| |f| - g |``, every sample adds a
  zero-rate update (the gyro reads its bias, ``z = y - b``, ``H = [0 I]``), so all three bias
  components are learned at rest, the vertical one included (unobservable from tilt alone).
* Magnetic disturbance: the reference norm and dip (dip from the field rotated into the world by
  the predicted attitude) are learned from the first ``mag_learn_time`` seconds of field samples
  (or given); a sample whose norm departs by more than
  ``mag_norm_tol`` (fraction) or whose dip departs by more than ``mag_dip_tol`` is rejected, and
  the field must agree again for ``mag_ok_time`` before it is used (VQF's thresholds, 10 %, 10 deg,
  0.5 s). A disturbed field that stays self-consistent for ``mag_new_time`` becomes the new
  reference (a wrong initial reference, or a move to another room).
* Initialisation: the attitude is set from the first accelerometer sample whose norm is within
  g/2 of g (tilt) and the first magnetometer sample (heading, tilt-compensated with that
  accelerometer sample: ``east = m x f``); until then the gyro is integrated from identity.
* Dropouts: a non-finite gyro sample skips the propagation (the attitude variance grows by
  ``(gyr_gap_rate * dt)^2``, the rotation missed), a non-finite accelerometer or magnetometer
  sample skips its measurement. Timestamps are not taken: samples are uniform at ``fs``.

Models
------
``model`` selects the time update and the measurement update, each as printed or as corrected
above (one kernel, two switches in its parameter record):

* ``"trawny"`` (default): Trawny's ``F`` and the corrected measurements with everything of
  "Beyond the paper".
* ``"f_zero"``: an ablation, the printed ``F = 0`` with the corrected measurements, robustness
  included. The zero-rate update at rest measures the bias directly (``H = [0 I]``), so this
  model still learns the bias whenever the sensor rests, and ``F = 0`` shows only in motion.
* ``"paper_literal"``: the filter as Zhang 2021 prints it, eqs (1)-(14), read as follows.

  Printed and used as printed: the state ``x = [phi, b]`` with ``phi = [theta, gamma, psi]``
  (pitch, roll, yaw; eq 1) and the error state ``dx = [dphi, db]`` (eq 6); the quaternion update
  with the bias-compensated rate (eqs 3-4) and the bias random walk (eq 5); ``F_c = 0``,
  ``G_c = I``, ``Phi = I + F_c dt = I`` (eqs 7-9); the prior angles from ``q_k^-`` by the ZYX
  formulas of eq (2); ``z = H dx + n`` (eq 10) with
  ``z = [theta - theta_acc, gamma - gamma_acc, psi - psi_compass]`` and ``H = [I 0]``; pitch and
  roll from the specific force (eq 11); the field levelled with those accelerometer angles
  (eq 12, "theta_k and gamma_k from eq (11)"); ``psi_compass = atan(m_y^n / m_x^n) + D``
  (eq 13); ``dx+ = dx- + K (z - H dx-)`` (eq 14); the compensation of the Euler angles by
  ``dphi`` and the conversion of the posterior angles back to ``q_k^+`` (section 1, the text of
  Fig 1). No rest detection, no motion-dependent R and no magnetometer check appear in the
  paper, so none is applied: ``acc_motion_ref``, ``motion_tau``, ``mag_norm_tol``,
  ``mag_dip_tol``, ``mag_ref_*``, ``mag_learn_time``, ``mag_ok_time``, ``mag_new_time`` and
  ``rest_*`` are not read.

  Interpreted (the printed text is damaged, frame-specific or silent):

  - Eq (11) prints ``theta = arcsin(f_y / f_z)``, ``gamma = arctan(f_x / sqrt(f_y^2 + f_z^2))``:
    an arcsin of a ratio that exceeds 1 beyond 45 deg, and the axes of the authors' mounting.
    Derived for our frame (``f = g [-sin theta, cos theta sin gamma, cos theta cos gamma]`` at
    rest): ``theta_acc = atan2(-f_x, sqrt(f_y^2 + f_z^2))``, ``gamma_acc = atan2(f_y, f_z)``,
    the printed pair of formulas with the arcsin read as arctan and the two axes exchanged.
  - Eq (12) prints ``m_x^n = m_x cos(theta) + m_y sin(theta) sin(gamma) + m_z cos(theta)
    sin(gamma)``, ``m_y^n = m_y cos(gamma) - m_z sin(gamma)``. Levelling ``m`` by
    ``Ry(theta) Rx(gamma)`` gives the same except for the last term, ``m_z sin(theta)
    cos(gamma)`` (the standard tilt-compensated compass), used here.
  - Eq (13) is north-referenced and clockwise; in ENU, with yaw counter-clockwise from east, it
    reads ``psi_compass = pi/2 - D - atan2(m_y^n, m_x^n)`` (D positive east). Its arctan, and
    eq (2)'s, are taken quadrant-correct (atan2).
  - The residual after eq (13) is printed ``-theta_k - theta_k^{*c}`` (OCR damage), read as
    ``theta_k - theta_k^acc`` like the two rows below it. The roll and yaw residuals are
    wrapped into (-pi, pi] (an angle difference; unwrapped, a heading crossing +-180 deg would
    be a 360 deg innovation).
  - Sign: with ``z`` = prior minus measured and ``H = [I 0]``, ``dx`` estimates the prior minus
    the truth, so the compensation subtracts: ``phi+ = phi- - dphi``, ``b+ = b - db``; ``dx`` is
    then reset to 0 (the feedback form of the indirect filter, [21]).
  - Not printed: the gain and covariance update of eq (14) ("the standard Kalman filter",
    [20]): ``K = P H^T (H P H^T + R)^-1``, ``P <- P - K H P``, one row at a time (identical
    for a diagonal R); the covariances of ``w_k`` and ``n_k``. ``Q`` is that of the corrected
    filter: eq (8)'s ``G_k = G_c dt`` applied to per-sample gyro noise of variance
    ``gyr_noise^2 / dt`` gives ``gyr_noise^2 dt``, and eq (5)'s increment has variance
    ``bias_walk^2 dt``. ``R`` is constant, ``diag(acc_noise^2, acc_noise^2, mag_noise^2) / dt``
    (the densities of the corrected filter, without its motion term).
  - Not printed either, and shared with the corrected filter: the initialisation, the
    discretisation ``q <- q ⊗ exp((y - b) dt)`` of eq (3), and the handling of non-finite
    samples. A heading update needs the accelerometer sample of the same instant (eq 12).

  With ``F = 0`` and ``H = [I 0]`` the cross covariance of angles and bias stays 0, so ``db``
  is always 0 and the bias keeps its initial value 0; in 6D the yaw is never measured and
  drifts at the vertical bias rate. The Euler-angle state is singular at pitch +-90 deg, as
  printed.

The per-sample loop runs in the numba kernel :mod:`estimators.attitude._kernel.ekf`, one stage per
step above; its uncompiled Python source is the readable reference. The filter state of each
stream is a record (:attr:`AttitudeEKF.state`), the parameters a record built once from
:class:`AttitudeParams`.

Offline, ``estimate_attitude(..., offline=True)`` smooths a whole recording: the same kernel runs
forward and on the time-reversed stream, and the two estimates are fused per sample, each
weighted by its attitude covariance (the method and its assumptions: :func:`estimate_attitude`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.attitude import _kernel as _k
from estimators.batching import TakesUsers, stream_rows
from estimators.kernels import param_record, state_records
from estimators.rotations import GRAVITY, quat_to_ypr
from estimators.validation import (
    check_choice,
    check_condition,
    check_in_range,
    check_rate,
    check_xyz,
)

__all__ = [
    "MAX_GYR_NORM",
    "MIN_ACC_NORM",
    "AttitudeEKF",
    "AttitudeParams",
    "EkfStage",
    "f_zero_ekf",
    "paper_literal_ekf",
]

#: Gyro readings above this norm (rad/s, 2000 deg/s: the largest range of MEMS gyros, e.g. the
#: Bosch BMI160/BMI270 datasheets) mean the data is not in rad/s (deg/s, most likely).
MAX_GYR_NORM = 35.0
#: Accelerometer norms below this (m/s^2) most of the time mean the data is in g, not m/s^2.
MIN_ACC_NORM = 3.0
#: Samples over the gyro limit before a stream is declared in the wrong unit (and at least 1 %).
_UNIT_MIN_COUNT = 10

_MODELS = ("trawny", "f_zero", "paper_literal")
#: Stage name of each model (:data:`estimators.stages.ATTITUDE`).
_STAGE_NAMES = {"trawny": "ekf", "f_zero": "ekf_f_zero", "paper_literal": "ekf_paper_literal"}


@dataclass(frozen=True)
class AttitudeParams:
    """Every parameter of the attitude EKF, with its unit, default and the reason for it.

    One set for all data: the defaults give a mean total RMSE of 2.58 deg over the nine BROAD
    trials in ``shared/data/broad`` (VQF: 2.61 deg; ``benchmarks/broad_table.py``); they were
    chosen there among round values, and are not tuned per trial. That figure is in-sample;
    ``benchmarks/broad_loto.py`` chooses ``acc_noise``, ``mag_noise`` and ``bias_walk`` on a
    log grid over eight trials and scores the ninth: 2.44 deg mean out-of-sample, every fold
    choosing these defaults but ``bias_walk`` 0.01 deg/s/sqrt(s).

    Attributes:
        model: the filter (module docstring, "Models"). ``"trawny"`` (default): the error
            dynamics ``F = [[-[w x], -I], [0, 0]]`` of the paper's reference [21] and the
            corrected, robust measurement update; the gyro bias is estimated. ``"f_zero"``:
            the printed ``F = 0`` (Zhang 2021 eq 7) with the same measurement update; the bias
            is learned at rest only. ``"paper_literal"``: the filter as printed, ``F = 0``
            and the Euler-angle residuals of eqs (10)-(14) with a constant R, no rest update and
            no magnetometer check; the bias is never estimated. ``paper_literal`` reads only
            ``gyr_noise``, ``bias_walk``, ``att_init_std``, ``bias_init_std``, ``acc_noise``,
            ``gravity`` (initialisation), ``mag_noise``, ``declination`` and ``gyr_gap_rate``.
        gyr_noise: gyro noise density in the process model, rad/s/sqrt(Hz). Default 0.1 deg/s/
            sqrt(Hz): ten times a MEMS white noise (0.007 deg/s/sqrt(Hz), BMI160 datasheet) to
            cover scale-factor and misalignment errors during fast head turns; 0.05-0.2 change
            the BROAD mean by < 0.3 deg.
        bias_walk: gyro bias random walk, rad/s/sqrt(s). Default 0.001 deg/s/sqrt(s), about
            0.06 deg/s per hour: the drift of a consumer MEMS bias at constant temperature.
        att_init_std: initial attitude standard deviation, rad. Default 5 deg: one noisy
            accelerometer/magnetometer sample sets the initial attitude.
        bias_init_std: initial gyro bias standard deviation, rad/s. Default 1 deg/s: the
            turn-on bias of a consumer MEMS gyro (SBG IG-500N: 0.1 deg/s stability, Zhang 2021
            section 4; consumer parts up to a few deg/s).
        acc_noise: tilt measurement noise density, rad*sqrt(s) (``R = acc_noise^2 / dt``).
            Default 0.02: a tilt correction time constant of about ``acc_noise / gyr_noise``
            = 11 s, long enough to average head accelerations out, short enough to follow the
            gyro drift (BROAD: 0.015-0.04 within 0.15 deg of the best).
        acc_motion_ref: motion level (m/s^2) at which the tilt variance doubles. Default 5 m/s^2
            (about 0.5 g, the peaks of the specific-force norm while walking, Zhang 2021 Fig 2).
        motion_tau: time constant (s) of the low-pass on ``| |f| - g |`` that gives the motion
            level, and of the candidate-field average. Default 5 s, a few strides.
        gravity: gravity magnitude, m/s^2, for the tilt measurement and the initialisation
            gate. Default: standard gravity (ISO 80000-3), 9.80665.
        mag_noise: heading measurement noise density, rad*sqrt(s). Default 0.03: a heading
            time constant of about 17 s, slower than the tilt because indoor fields are
            disturbed more often than gravity (BROAD: 0.02-0.03 best).
        mag_norm_tol: relative field-norm deviation above which a magnetometer sample is
            rejected. Default 0.1 (VQF's ``magNormTh``).
        mag_dip_tol: dip-angle deviation above which a magnetometer sample is rejected, rad.
            Default 10 deg (VQF's ``magDipTh``).
        mag_ref_norm: reference field norm in the magnetometer's unit, or None to learn it
            from the first ``mag_learn_time`` seconds. Give it together with ``mag_ref_dip``.
        mag_ref_dip: reference dip angle, rad (positive: the field points below the horizon,
            the northern hemisphere), or None to learn it.
        mag_learn_time: seconds of field samples averaged into the learned reference. Default
            1 s; samples are not gated while it is learned.
        mag_ok_time: seconds the field must agree with the reference again before it is used
            after a disturbance. Default 0.5 s (VQF's ``magMinUndisturbedTime``).
        mag_new_time: seconds a disturbed but self-consistent field must last to become the
            new reference. Default 20 s (VQF's ``magNewTime``); ``math.inf`` never adopts one.
        declination: magnetic declination D, rad, positive when magnetic north is east of true
            north (eq 13). Default 0: the yaw is then relative to magnetic north.
        gyr_gap_rate: angular rate (rad/s) assumed unknown during a gyro dropout: each missing
            sample adds ``(gyr_gap_rate * dt)^2`` to the attitude variance, so the measurements
            that follow correct the missed rotation as attitude, not as bias. Default 2 rad/s
            (115 deg/s), a fast head turn (peaks reach 200-300 deg/s).
        rest_gyr: rest detection, largest bias-corrected angular rate, rad/s. Default 2 deg/s
            (VQF's ``restThGyr``).
        rest_acc: rest detection, largest ``| |f| - g |``, m/s^2. Default 0.5 (VQF's
            ``restThAcc``).
        rest_time: seconds both must hold before the sensor counts as at rest; at rest each
            sample adds a zero-rate update ``z = y - b``, ``H = [0 I]``, ``R = gyr_noise^2 / dt``
            (the gyro then reads its bias). Default 1.5 s (VQF's ``restMinT``). Without it, a
            6D filter that starts level never observes the vertical bias before moving, and the
            first fast motion pulls that bias by up to 17 deg/s (BROAD trial 21).
    """

    model: str = "trawny"
    gyr_noise: float = math.radians(0.1)
    bias_walk: float = math.radians(0.001)
    att_init_std: float = math.radians(5.0)
    bias_init_std: float = math.radians(1.0)
    acc_noise: float = 0.02
    acc_motion_ref: float = 5.0
    motion_tau: float = 5.0
    gravity: float = GRAVITY
    mag_noise: float = 0.03
    mag_norm_tol: float = 0.1
    mag_dip_tol: float = math.radians(10.0)
    mag_ref_norm: float | None = None
    mag_ref_dip: float | None = None
    mag_learn_time: float = 1.0
    mag_ok_time: float = 0.5
    mag_new_time: float = 20.0
    declination: float = 0.0
    gyr_gap_rate: float = 2.0
    rest_gyr: float = math.radians(2.0)
    rest_acc: float = 0.5
    rest_time: float = 1.5

    def __post_init__(self) -> None:
        check_choice(self, "model", _MODELS)
        positive = (
            "gyr_noise",
            "bias_walk",
            "att_init_std",
            "bias_init_std",
            "acc_noise",
            "acc_motion_ref",
            "motion_tau",
            "mag_noise",
            "mag_norm_tol",
            "mag_dip_tol",
            "gyr_gap_rate",
            "rest_gyr",
            "rest_acc",
            "rest_time",
        )
        for name in positive:
            check_in_range(self, name, 0.0, math.inf, lo_open=True)
        for name in ("mag_learn_time", "mag_ok_time"):
            check_in_range(self, name, 0.0, math.inf, "s")
        check_in_range(self, "mag_new_time", 0.0, math.inf, "s", lo_open=True, allow_inf=True)
        check_in_range(self, "gravity", 9.0, 10.5, "m/s^2")
        check_in_range(self, "declination", -math.pi, math.pi, allowed="in [-pi, pi] rad")
        together = (self.mag_ref_norm is None) == (self.mag_ref_dip is None)
        check_condition(
            self, "mag_ref_norm", together, "given together with mag_ref_dip (or neither)"
        )
        if self.mag_ref_norm is not None:
            check_in_range(self, "mag_ref_norm", 0.0, math.inf, lo_open=True)
            check_in_range(
                self, "mag_ref_dip", -math.pi / 2, math.pi / 2, allowed="in [-pi/2, pi/2] rad"
            )

    def replace(self, **changes: Any) -> AttitudeParams:
        """A copy with some fields changed (validated like the original)."""
        return replace(self, **changes)

    def as_dict(self) -> dict[str, Any]:
        """The public fields as a plain dict."""
        return asdict(self)

    def build(self, batch_size: int, fs: float) -> EkfStage:
        """The EKF with these parameters as an attitude stage (:mod:`estimators.stages`)."""
        return EkfStage(batch_size, fs, self)


_PARAM_NAMES = frozenset(f.name for f in fields(AttitudeParams) if f.init)


def _make_params(params: AttitudeParams | None, overrides: dict[str, Any]) -> AttitudeParams:
    if params is not None and not isinstance(params, AttitudeParams):
        raise TypeError(f"params must be an AttitudeParams, got {type(params).__name__}")
    unknown = set(overrides) - _PARAM_NAMES
    if unknown:
        raise ValueError(
            f"unknown attitude parameter(s) {sorted(unknown)}; allowed: {sorted(_PARAM_NAMES)}"
        )
    base = params if params is not None else AttitudeParams()
    return base.replace(**overrides) if overrides else base


def _fresh_state(n_streams: int, params: AttitudeParams) -> NDArray:
    """(B,) records of uninitialised streams for ``params`` (fields
    :data:`estimators.attitude._kernel.STATE_FIELDS`): identity attitude, zero bias, the initial
    covariance, the magnetic reference unlearned or as given, zeroed unit-guard counters."""
    state = state_records(_k.STATE_FIELDS, n_streams)
    if params.mag_ref_norm is not None:
        state["mag_norm"] = params.mag_ref_norm
        state["mag_dip"] = params.mag_ref_dip
        state["mag_learn_t"] = math.inf
    P = state["P"]
    P[:, :3, :3] = np.eye(3) * params.att_init_std**2
    P[:, 3:, 3:] = np.eye(3) * params.bias_init_std**2
    state["q"][:, 0] = 1.0
    return state


def _kernel_params(params: AttitudeParams, dt: float) -> NDArray:
    """The kernel's (1,) parameter record: the numeric fields of ``params`` it reads, the model
    as two switches, ``trawny`` (1.0: Trawny's error dynamics, 0.0: ``F = 0``) and
    ``printed_meas`` (1.0: the printed measurement update, 0.0: the corrected one), the sample
    interval ``dt`` (s) and the unit guard's limits (squared norms)."""
    return param_record(
        params,
        exclude=("mag_ref_norm", "mag_ref_dip"),
        trawny=1.0 if params.model == "trawny" else 0.0,
        printed_meas=1.0 if params.model == "paper_literal" else 0.0,
        dt=dt,
        max_gyr_norm2=MAX_GYR_NORM**2,
        min_acc_norm2=MIN_ACC_NORM**2,
        unit_min_count=_UNIT_MIN_COUNT,
    )


def _raise_units(flag: int, state: NDArray) -> None:
    """Turn the kernel's unit-guard flag into a clear error."""
    i, kind = divmod(flag, 2)
    s = state[i]
    if kind == 0:
        raise ValueError(
            f"gyr must be in rad/s: stream {i} has {int(s['n_gyr_big'])} samples above "
            f"{MAX_GYR_NORM} rad/s (2000 deg/s, beyond MEMS ranges); deg/s data? Convert with "
            "np.radians. The filter state is now meaningless: call reset()."
        )
    raise ValueError(
        f"acc must be in m/s^2: stream {i} reads a specific-force norm below {MIN_ACC_NORM} "
        f"m/s^2 in {int(s['n_acc_small'])} of {int(s['n_seen'])} samples (about 1 "
        f"means g units); multiply by {GRAVITY}. The filter state is now meaningless: call reset()."
    )


# ------------------------------------------------------------------------------------------------
# Public API.
# ------------------------------------------------------------------------------------------------


class AttitudeEKF(TakesUsers):
    """Streaming error-state attitude EKF for B independent IMU streams.

    Args:
        n_streams: number of streams B (users), >= 1.
        fs: sampling rate, Hz (fixed; one sample every ``1/fs`` s).
        params: filter parameters (defaults: :class:`AttitudeParams`).
        **overrides: fields of :class:`AttitudeParams` to change, e.g.
            ``model="paper_literal"``.

    Example:
        >>> ekf = AttitudeEKF(2, fs=100.0)
        >>> q = ekf.update(np.zeros((2, 3)), np.tile([0, 0, 9.81], (2, 1)), [[20, 0, -40]] * 2)
        >>> q.shape, ekf.ypr.shape
        ((2, 4), (2, 3))
    """

    per_user_fields = ("_state", "_scratch", "_no_mag")  # filter state, kernel scratch, 6D input
    batch_size_field = "n_streams"

    def __init__(
        self, n_streams: int, fs: float, params: AttitudeParams | None = None, **overrides: Any
    ) -> None:
        if isinstance(n_streams, bool) or not isinstance(n_streams, (int, np.integer)):
            raise ValueError(f"n_streams must be an int >= 1, got {n_streams!r}")
        if n_streams < 1:
            raise ValueError(f"n_streams must be >= 1, got {n_streams}")
        self.n_streams = int(n_streams)
        self.fs = check_rate(fs)
        self.dt = 1.0 / self.fs
        self.params = _make_params(params, overrides)
        self._prm = _kernel_params(self.params, self.dt)
        self._scratch = state_records(_k.SCRATCH_FIELDS, self.n_streams)
        self._no_mag = np.full((self.n_streams, 1, 3), np.nan)
        self.reset()

    def reset(self, mask: ArrayLike | None = None) -> None:
        """Forget some or all streams: their next accelerometer/magnetometer samples re-initialise.

        A reset stream's state record is that of a new filter (identity attitude, zero bias,
        initial covariance, magnetic reference unlearned or as given, zeroed unit-guard
        counters); from then on it equals a new single-stream filter fed the same samples. The
        other streams are untouched (a vector env resetting one sub-env).

        Args:
            mask: the streams to reset, as a (B,) boolean mask or indices; None resets all.

        Raises:
            ValueError: an index outside [0, B), or a mask of the wrong shape.
        """
        b = self.n_streams
        if mask is None:
            self._state = _fresh_state(b, self.params)
            return
        rows = stream_rows(mask, b, "mask", unique=False)
        self._state[rows] = _fresh_state(rows.size, self.params)

    def update(self, gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None) -> NDArray:
        """Process one sample per stream.

        Args:
            gyr: (B, 3) angular rate, rad/s, sensor frame.
            acc: (B, 3) specific force, m/s^2 (a static level sensor reads [0, 0, +g]).
            mag: (B, 3) magnetic field in any fixed unit, or None for a 6D update.
                Non-finite entries in any input skip that sensor for that stream and sample.

        Returns:
            (B, 4) quaternions ``[w, x, y, z]``, sensor -> ENU, after the sample.
        """
        b = self.n_streams
        g = check_xyz(gyr, "gyr", (b, 3)).reshape(b, 1, 3)
        a = check_xyz(acc, "acc", (b, 3)).reshape(b, 1, 3)
        m = self._no_mag if mag is None else check_xyz(mag, "mag", (b, 3)).reshape(b, 1, 3)
        return self._run(g, a, m)[:, 0]

    def update_batch(
        self, gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Process N samples per stream at once (same result as N calls of :meth:`update`).

        Args:
            gyr: (B, N, 3) angular rate, rad/s.
            acc: (B, N, 3) specific force, m/s^2.
            mag: (B, N, 3) magnetic field (any unit), or None for 6D.

        Returns:
            (B, N, 4) quaternions, sensor -> ENU, after each sample.
        """
        g = check_xyz(gyr, "gyr", None)
        if g.ndim != 3 or g.shape[0] != self.n_streams:
            raise ValueError(f"gyr must have shape ({self.n_streams}, N, 3), got {g.shape}")
        a = check_xyz(acc, "acc", g.shape)
        m = None if mag is None else check_xyz(mag, "mag", g.shape)
        if m is None:
            m = np.broadcast_to(np.float64(np.nan), g.shape)
        return self._run(g, a, m)

    def _run(self, g: NDArray, a: NDArray, m: NDArray) -> NDArray[np.float64]:
        out = np.empty((self.n_streams, g.shape[1], 4))
        flag = _k.ekf_kernel(self.n_streams)(
            self._state,
            self._scratch,
            np.ascontiguousarray(g),
            np.ascontiguousarray(a),
            np.ascontiguousarray(m),
            self._prm,
            out,
        )
        if flag >= 0:
            _raise_units(flag, self._state)
        return out

    def filter_with_covariance(
        self, gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None
    ) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """Process N samples per stream (B, N, 3) as :meth:`update_batch`, one kernel call per
        sample, keeping after each sample what a smoother needs.

        Returns:
            ``q`` (B, N, 4) (bit for bit :meth:`update_batch`), the attitude block of P
            (B, N, 3, 3), and the ``init`` and ``head_init`` flags (B, N) bool.

        Raises:
            ValueError: the unit guard, as :meth:`update_batch` raises it (its counters are
                cumulative, so the flag of the last call is that of a single call).
        """
        g = check_xyz(gyr, "gyr", None)
        if g.ndim != 3 or g.shape[0] != self.n_streams:
            raise ValueError(f"gyr must have shape ({self.n_streams}, N, 3), got {g.shape}")
        a = check_xyz(acc, "acc", g.shape)
        m = np.full(g.shape, np.nan) if mag is None else check_xyz(mag, "mag", g.shape)
        b, n = g.shape[0], g.shape[1]

        def per_sample(x: NDArray) -> NDArray:  # (N, B, 1, 3): x_s[k] is the kernel's (B, 1, 3)
            x_s = np.empty((n, b, 1, 3))  # fresh C-ordered strides: the kernel's compiled layout
            x_s[:, :, 0] = np.moveaxis(x, 1, 0)
            return x_s

        gs, as_, ms = per_sample(g), per_sample(a), per_sample(m)
        out = np.empty((n, b, 1, 4))
        cov = np.empty((n, b, 3, 3))
        flags = np.empty((n, 2, b))
        state, scratch, prm = self._state, self._scratch, self._prm
        # Views of the state record, which the kernel updates in place.
        p_att, init, head = state["P"][:, :3, :3], state["init"], state["head_init"]
        kernel = _k.ekf_kernel(b)
        flag = -1
        for k in range(n):
            flag = kernel(state, scratch, gs[k], as_[k], ms[k], prm, out[k])
            cov[k] = p_att
            flags[k, 0] = init
            flags[k, 1] = head
        if flag >= 0:
            _raise_units(flag, state)
        return (
            np.moveaxis(out[:, :, 0], 0, 1),
            np.moveaxis(cov, 0, 1),
            np.moveaxis(flags[:, 0], 0, 1) != 0.0,
            np.moveaxis(flags[:, 1], 0, 1) != 0.0,
        )

    @property
    def state(self) -> np.recarray:
        """(B,) filter state, one record per stream, fields named in
        :data:`estimators.attitude._kernel.STATE_FIELDS`: ``q`` (4,) quaternion, ``b`` (3,) gyro
        bias (rad/s), ``P`` (6, 6) error-state covariance, the initialisation flags, magnetic
        reference and timers, motion level and unit-guard counters (``ekf.state.mag_norm``).
        A live view: the filter updates it in place, and writes to it reach the filter."""
        return self._state.view(np.recarray)

    @property
    def quat(self) -> NDArray[np.float64]:
        """(B, 4) current quaternions ``[w, x, y, z]``, sensor -> ENU."""
        return self._state["q"].copy()

    @property
    def bias(self) -> NDArray[np.float64]:
        """(B, 3) current gyro bias estimates, rad/s."""
        return self._state["b"].copy()

    @property
    def ypr(self) -> NDArray[np.float64]:
        """(B, 3) current ZYX Euler angles ``[yaw, pitch, roll]``, rad (yaw from east, CCW)."""
        return quat_to_ypr(self._state["q"].copy())

    @property
    def cov(self) -> NDArray[np.float64]:
        """(B, 6, 6) current error-state covariance (``[dphi (rad), db (rad/s)]``)."""
        return self._state["P"].copy()

    @property
    def initialized(self) -> NDArray[np.bool_]:
        """(B,) whether each stream has been initialised from an accelerometer sample."""
        return self._state["init"] != 0.0


class EkfStage(TakesUsers):
    """:class:`AttitudeEKF` as an attitude stage (:class:`estimators.stages.AttitudeStage`):
    ``update`` takes the (B, N, 3) samples of a control step (:meth:`AttitudeEKF.update_batch`).

    Args:
        batch_size: B.
        fs: IMU rate (Hz).
        params: :class:`AttitudeParams` (defaults if None).
    """

    per_user_parts = ("ekf",)

    def __init__(self, batch_size: int, fs: float, params: AttitudeParams | None = None) -> None:
        self.ekf = AttitudeEKF(batch_size, fs, params)
        self.params = self.ekf.params
        self.name = _STAGE_NAMES[self.params.model]

    def reset(self, rows: ArrayLike | None = None) -> None:
        self.ekf.reset(rows)

    def update(
        self, gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        return self.ekf.update_batch(gyr, acc, mag)


def paper_literal_ekf(batch_size: int, fs: float) -> EkfStage:
    """Zhang 2021's EKF as printed, ``model="paper_literal"`` (:attr:`AttitudeParams.model`)."""
    return EkfStage(batch_size, fs, AttitudeParams(model="paper_literal"))


def f_zero_ekf(batch_size: int, fs: float) -> EkfStage:
    """The corrected EKF with the printed ``F = 0``, ``model="f_zero"`` (an ablation)."""
    return EkfStage(batch_size, fs, AttitudeParams(model="f_zero"))

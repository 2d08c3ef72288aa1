"""The simulated VR user's body: intent in, true head pose, true steps and true skeleton out.

A user stands in a tracked space wearing a head IMU, with a Kinect v2 in front of them. Per control
step they express an :class:`Intent` — stepping cadence, turn rate, hand angular rates and optional
head gestures — and :class:`UserMotion` turns it into

* the true head pose at the IMU rate: orientation (sensor -> world quaternion), body-frame angular
  rate, IMU position and world linear acceleration (gravity excluded), and the true heel strikes;
* the true Kinect v2 skeleton (25 joints, world frame) and the true right-hand orientation at the
  Kinect rate.

All users of a batch advance in lock-step over the same time grid; every array carries a leading
batch dimension B. Frames follow :mod:`estimators.rotations` (ENU world, ZYX yaw-pitch-roll).

Stepping in place (the walking-in-place metaphor of Zhang 2021):

* A *step* is one unit of the continuous step phase ``phi``; it starts and ends with the head at
  standing height and zero vertical speed (``phi`` integer) and has its heel strike, the peak of
  vertical acceleration, at mid-step (``phi = n + 0.5``). A step, once started, is finished at the
  cadence it started with; a new cadence (or stopping) takes effect at the next step boundary, so
  the head path is smooth (C1) whatever the intent does.
* Vertical acceleration over a step is a von Mises pulse (concentration 3) centred on the heel
  strike, mean removed. Its peak grows with cadence from 0.12 g at 1.2 Hz to 0.45 g at 2.2 Hz, so
  the specific-force norm peaks at about 1.1-1.5 g — the range of head-worn accelerometers during
  walking in place (Zhang 2021 Fig. 2 shows |f| peaks of roughly 11-15 m/s^2; Tregillus & Folmer,
  VR-STEP, CHI 2016, Zhang 2021 ref. [15], report similar head-bob peaks). The resulting vertical
  head travel is 2-3 cm per step (stepping in place moves the head less than overground walking's
  4-5 cm; Kavanagh et al., Gait & Posture 2006, for the head during walking).
* The body sways laterally at half the step rate (one sway per stride), 2 cm by default, with a
  matching head roll of about 1.5 deg.
* Cadence: 1.2-2.2 steps/s (the comfortable walking-in-place range; VR-STEP users stepped at
  about 1.5-2 Hz).

The head turns with the body (yaw rate with a 0.1 s first-order lag, so angular acceleration stays
finite) and may add gesture oscillations about each axis (serpentine, nod, shake) and a lean, as in
Zhang 2021's five head motions, and turn on the torso toward the intent's ``head_yaw`` (critically
damped, ``MotionParams.head_turn_lag_s``: where a user looks, set by
:class:`vrloco_env.user.behaviour.GazeBehaviour` for a user population). The IMU sits on the
forehead, 9 cm in front of and 12 cm above the head's pivot at the neck, so head rotations also
accelerate it (centripetal and tangential terms).

The right hand is held in front of the body; its orientation relative to the torso heading is an
intrinsic ZYX [yaw, pitch, roll] integrated from the intent's hand rates and held within joint
limits. Hand frame: x along the forearm toward the fingertips, y to the thumb side of a palm-down
right hand (left), z out of the back of the hand (up when palm-down).

The parts live beside this module, each re-exported here: the settings
(:mod:`~vrloco_env.user.motion_params`: :class:`MotionParams`), the input
(:mod:`~vrloco_env.user.intent`: :class:`Intent`, :data:`MAX_HEAD_YAW`), the outputs
(:mod:`~vrloco_env.user.motion_records`: :class:`MotionChunk`, :class:`KinectChunk`,
:class:`MotionRecord`), what the compiled body reads (:mod:`vrloco_env.user._motion_inputs`) and
Zhang 2021's scripted motions (:mod:`~vrloco_env.user.scripts`: :data:`SCRIPTS`,
:func:`script_intents`, :func:`run_script`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers, stream_rows
from estimators.kernels import state_records
from vrloco_env.batch_rng import BatchRng
from vrloco_env.user._motion_inputs import _BODY, _kernel_params
from vrloco_env.user._motion_numba import SCALARS, STATE, VECTORS, evaluate_kernel, skeleton_kernel
from vrloco_env.user.intent import MAX_HEAD_YAW, Intent, _intent_arrays
from vrloco_env.user.motion_params import MotionParams
from vrloco_env.user.motion_records import KinectChunk, MotionChunk, MotionRecord
from vrloco_env.user.scripts import SCRIPTS, run_script, script_intents
from vrloco_env.user.skeleton import NUM_JOINTS

__all__ = [
    "MAX_HEAD_YAW",
    "SCRIPTS",
    "Intent",
    "KinectChunk",
    "MotionChunk",
    "MotionParams",
    "MotionRecord",
    "UserMotion",
    "run_script",
    "script_intents",
]

_DIFF_H = 1e-4  # s, central-difference step for the head's linear acceleration
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(12)  # overground walking quadrature


class _State:
    """Per-user state carried between control steps: the kernel's (B,) record array ``rec``
    (fields :data:`vrloco_env.user._motion_numba.STATE`), a view of each of its fields as the
    attribute of that name ((B,) or (B, k); ``s.phase[:] = x`` writes the record), and the
    control steps done since every user was last reset (time is ``steps_done / rate``).

    A copy (``copy.deepcopy``, ``pickle``) holds the copied record and views of *it*: the views
    are made again from the record (:meth:`__setstate__`), never copied as arrays of their own.
    """

    def __init__(self, batch_size: int) -> None:
        self._bind(state_records(STATE, batch_size))
        self.steps_done = 0

    def _bind(self, rec: NDArray) -> None:
        """Hold ``rec`` and a view of each of its fields under the field's name."""
        self.rec = rec
        for name in STATE:
            setattr(self, name, rec[name])

    def __getstate__(self) -> dict:
        return {"rec": self.rec, "steps_done": self.steps_done}

    def __setstate__(self, state: dict) -> None:
        self._bind(state["rec"])
        self.steps_done = state["steps_done"]

    def take(self, rows: NDArray[np.intp]) -> _State:
        """The state of users ``rows`` alone (the same clock)."""
        kept = _State(rows.size)
        kept.rec[:] = self.rec[rows]
        kept.steps_done = self.steps_done
        return kept

    def time(self, rate: float) -> float:
        return self.steps_done / rate


@dataclass
class UserMotion(TakesUsers):
    """Batched motion model of B simulated users.

    Args:
        params: rates, limits and body measurements.
        rng: one random stream per user (user styles are drawn at :meth:`reset`).

    Call :meth:`reset` once, then :meth:`advance` with one :class:`Intent` per control step.
    """

    params: MotionParams
    rng: BatchRng
    _state: _State | None = field(default=None, init=False, repr=False)
    _grids: dict = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        p = self.params
        self._hand_limits = np.deg2rad(np.asarray(p.hand_limits_deg, dtype=np.float64))
        self._control_dt = np.array([1.0 / p.control_rate_hz])
        self._sample_index = np.arange(1, p.samples_per_step + 1)
        self._kernel_params = _kernel_params(p)

    @property
    def batch_size(self) -> int:
        return self.rng.batch_size

    def take_users(self, rows: NDArray[np.intp]) -> None:
        """Keep the users ``rows`` (their state; the random streams belong to the caller's
        :class:`~vrloco_env.batch_rng.BatchRng`, which takes them itself)."""
        if self._state is not None:
            self._state = self._state.take(np.asarray(rows, dtype=np.intp))

    @property
    def time(self) -> float:
        """Simulated time (s) at the end of the last control step."""
        return 0.0 if self._state is None else self._state.time(self.params.control_rate_hz)

    def reset(
        self,
        yaw: ArrayLike = 0.0,
        base: ArrayLike = (0.0, 0.0),
        hand_ypr: ArrayLike = (0.0, 0.0, 0.0),
        users: ArrayLike | None = None,
    ) -> None:
        """Stand users still at ``base`` (m) facing ``yaw`` (rad), hand at ``hand_ypr`` (rad).

        Args:
            yaw, base, hand_ypr: per reset user, broadcast to (U,), (U, 2), (U, 3).
            users: the users to reset (indices or a (B,) bool mask); None resets all. The others
                carry on untouched, and each reset user's style is drawn from its own stream
                only, so a vector env's autoreset matches a fresh single env. The first call
                must reset all users. Resetting all users restarts the clock at 0; resetting
                some keeps the batch's clock (times in chunks are batch times).
        """
        b = self.batch_size
        rows = np.arange(b) if users is None else stream_rows(users, b)
        if self._state is None and rows.size != b:
            raise RuntimeError("the first UserMotion.reset() must reset every user")
        u = rows.size
        style = 1.0 + self.params.style_spread * np.clip(
            self.rng.normal((2,), rows=rows), -2.5, 2.5
        )
        fresh = _State(u)  # standing still at a step boundary
        fresh.yaw[:] = _batch(yaw, (u,), "yaw")
        fresh.hand_ypr[:] = _batch(hand_ypr, (u, 3), "hand_ypr")
        fresh.base[:] = _batch(base, (u, 2), "base")
        fresh.impact_scale[:] = style[:, 0]
        fresh.sway_scale[:] = style[:, 1]
        if self._state is None or rows.size == b:
            self._state = fresh  # the clock restarts at 0
            return
        self._state.rec[rows] = fresh.rec

    def shift_base(self, delta: ArrayLike) -> None:
        """Move every user's standing spot by ``delta`` (m, (B, 2)) in the world's xy: the head,
        the IMU and the skeleton move with it from the next control step on (a walking-in-place
        user's drift, :mod:`vrloco_env.user.play_area`)."""
        if self._state is None:
            raise RuntimeError("UserMotion.reset() must be called before shift_base()")
        self._state.base += _batch(delta, (self.batch_size, 2), "delta")

    @property
    def base(self) -> NDArray[np.float64]:
        """Each user's standing spot in the world's xy (m), (B, 2) (a copy)."""
        if self._state is None:
            raise RuntimeError("UserMotion.reset() must be called before base")
        return np.array(self._state.base, dtype=np.float64)

    def scale_style(self, rows: ArrayLike, impact: ArrayLike) -> None:
        """Multiply the step-impact style of users ``rows`` (drawn at :meth:`reset`) by
        ``impact`` (> 0, broadcast to the rows): a population's heavier or lighter steppers.
        The vertical head acceleration of every step scales with it."""
        if self._state is None:
            raise RuntimeError("UserMotion.reset() must be called before scale_style()")
        r = stream_rows(rows, self.batch_size)
        f = _batch(impact, (r.size,), "impact")
        _check_range(f, 0.05, 5.0, "UserMotion.scale_style impact", "(a factor)")
        self._state.impact_scale[r] *= f

    # ------------------------------------------------------------------ intent validation
    def _check_intent(self, intent: Intent) -> dict[str, NDArray[np.float64]]:
        p, b = self.params, self.batch_size
        out = {
            "cadence": _batch(intent.cadence, (b,), "cadence"),
            "turn_rate": _batch(intent.turn_rate, (b,), "turn_rate"),
            "hand_rates": _batch(intent.hand_rates, (b, 3), "hand_rates"),
            "gesture_amplitude": _batch(intent.gesture_amplitude, (b, 3), "gesture_amplitude"),
            "gesture_frequency": _batch(intent.gesture_frequency, (b, 3), "gesture_frequency"),
            "lean": _batch(intent.lean, (b,), "lean"),
            "head_yaw": _batch(intent.head_yaw, (b,), "head_yaw"),
        }
        lo, hi = p.cadence_range_hz
        c = out["cadence"]
        bad = (c != 0.0) & ((c < lo - 1e-9) | (c > hi + 1e-9))
        if np.any(bad):
            raise ValueError(
                f"Intent.cadence={float(c[bad][0])!r}: must be 0 (stand) or in [{lo}, {hi}] steps/s"
            )
        _check_range(
            out["turn_rate"], -p.max_turn_rate, p.max_turn_rate, "Intent.turn_rate", "rad/s"
        )
        _check_range(
            out["hand_rates"], -p.max_hand_rate, p.max_hand_rate, "Intent.hand_rates", "rad/s"
        )
        _check_range(
            out["gesture_amplitude"], 0.0, np.deg2rad(80.0), "Intent.gesture_amplitude", "rad"
        )
        _check_range(out["gesture_frequency"], 0.0, 3.0, "Intent.gesture_frequency", "Hz")
        _check_range(out["lean"], -np.deg2rad(45.0), np.deg2rad(45.0), "Intent.lean", "rad")
        _check_range(out["head_yaw"], -MAX_HEAD_YAW, MAX_HEAD_YAW, "Intent.head_yaw", "rad")
        return out

    # ------------------------------------------------------------------ the time functions
    def _evaluate(self, s: _State, cmd: dict, tau: NDArray[np.float64]) -> dict:
        """Head and body quantities at times ``tau`` (s after the step start), shape (B, T, ...):
        one call of :data:`vrloco_env.user._motion_numba.evaluate_kernel`. Keys: its
        :data:`~vrloco_env.user._motion_numba.SCALARS` (B, T) and
        :data:`~vrloco_env.user._motion_numba.VECTORS` (B, T, 3), ``quat`` (B, T, 4), ``walking``
        (B, T) bool and ``t_boundary`` (B,), the time the step in progress ends."""
        b, t = self.batch_size, tau.shape[-1]
        scalars = np.empty((len(SCALARS), b, t))
        vectors = np.empty((len(VECTORS), b, t, 3))
        quat = np.empty((b, t, 4))
        t_boundary = np.empty(b)
        evaluate_kernel(b)(
            s.rec,
            cmd["cadence"],
            cmd["turn_rate"],
            cmd["gesture_amplitude"],
            cmd["gesture_frequency"],
            cmd["lean"],
            cmd["head_yaw"],
            self._kernel_params,
            tau,
            t_boundary,
            scalars,
            vectors,
            quat,
        )
        out = dict(zip(SCALARS, scalars, strict=True))
        out.update(zip(VECTORS, vectors, strict=True))
        out["quat"] = quat
        out["t_boundary"] = t_boundary
        out["walking"] = out["cadence"] > 0.0
        return out

    # ------------------------------------------------------------------ one control step
    def advance(self, intent: Intent, validate: bool = True) -> MotionChunk:
        """Advance all users by one control step under ``intent``; return the true motion.

        ``validate=False`` skips the intent's range checks: for callers whose intents are valid
        by construction (the env maps checked actions into the allowed ranges); arrays must
        then already have the batch shapes.
        """
        if self._state is None:
            raise RuntimeError("UserMotion.reset() must be called before advance()")
        s, p = self._state, self.params
        cmd = self._check_intent(intent) if validate else _intent_arrays(intent)
        if cmd["head_yaw"].ndim == 0:  # an unchecked intent may leave the head straight
            cmd["head_yaw"] = np.full(self.batch_size, float(cmd["head_yaw"]))
        n = p.samples_per_step
        t0 = s.time(p.control_rate_hz)
        tau_k, t_k, times = self._time_grid(s.steps_done)
        # One evaluation at every time needed (see _time_grid): the samples, +-h around them for
        # the linear acceleration, the last sample's left limit, and the Kinect frames.
        ev_all = self._evaluate(s, cmd, times)
        if p.overground:
            walked, speed_end = self._overground(s, cmd, ev_all, times)
        h = _DIFF_H
        imu_pos = ev_all["imu_pos"]
        p_m, p_0, p_p = imu_pos[:, :n], imu_pos[:, n : 2 * n], imu_pos[:, 2 * n : 3 * n]
        ends = imu_pos[:, 3 * n : 3 * n + 3]
        acc = (p_p - 2.0 * p_0 + p_m) / h**2
        acc[:, -1] = (ends[:, 2] - 2.0 * ends[:, 1] + ends[:, 0]) / h**2
        samples = slice(n, 2 * n)
        frames = {k: ev_all[k][:, 3 * n + 3 :] for k in ("yaw", "neck", "quat", "phase", "walking")}
        quat = ev_all["quat"][:, samples]
        head_ypr = ev_all["head_ypr"][:, samples]
        phase = ev_all["phase"][:, samples]
        omega = ev_all["omega"][:, samples]

        # Heel strikes: the phase crosses n + 0.5 inside a sample interval.
        ph_prev = np.concatenate([s.phase[:, None], phase[:, :-1]], axis=1)
        k_now = np.floor(phase - 0.5)
        step = k_now > np.floor(ph_prev - 0.5)
        if step.any():
            step_offset = self._heel_strike_offsets(s, cmd, ev_all["t_boundary"], k_now, step)
        else:
            step_offset = np.full(step.shape, np.nan)

        # Kinect frames falling in (t, t + dt_ctrl].
        kin = self._skeleton(s, cmd, frames, tau_k, t_k)

        # Carry the state to the end of the step (the last sample).
        end = 2 * n - 1
        end_phase = ev_all["phase"][:, end]
        s.step_cadence[:] = np.where(
            np.abs(end_phase - np.round(end_phase)) < 1e-9, 0.0, ev_all["cadence"][:, end]
        )
        s.phase[:] = np.where(s.step_cadence == 0.0, np.round(end_phase), end_phase)
        s.yaw[:] = ev_all["yaw"][:, end]
        s.yaw_rate[:] = ev_all["yaw_rate"][:, end]
        s.gesture_amp[:] = ev_all["gesture_amp"][:, end, :]
        s.gesture_amp_rate[:] = ev_all["gesture_amp_rate"][:, end, :]
        s.lean_rate[:] = ev_all["lean_rate"][:, end]
        s.gesture_phase[:] = np.mod(ev_all["g_phase"][:, end, :], 2.0 * np.pi)
        s.lean[:] = ev_all["lean"][:, end]
        s.head_yaw[:] = ev_all["head_yaw"][:, end]
        s.head_yaw_rate[:] = ev_all["head_yaw_rate"][:, end]
        s.hand_ypr[:] = self._hand_ypr(s, cmd, self._control_dt)[:, -1]
        if p.overground:
            s.base += walked
            s.speed[:] = speed_end
        t_abs = (s.steps_done * n + self._sample_index) / p.imu_rate_hz
        s.steps_done += 1
        return MotionChunk(
            t=t_abs,
            quat=quat,
            omega=omega,
            pos=p_0,
            acc=acc,
            ypr=head_ypr,
            body_yaw=ev_all["yaw"][:, samples],
            step=step,
            step_time=t0 + step_offset,
            step_offset=step_offset,
            walking=ev_all["walking"][:, samples],
            kinect=kin,
        )

    def _overground(
        self, s: _State, cmd: dict, ev: dict, times: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Walk the body through the tracked space: shift ``ev``'s neck and IMU positions (in
        place) by the distance walked since the step start at each of ``times``.

        The speed follows ``stride_m * cadence`` with a first-order lag; the direction is the body
        yaw (the closed form of :func:`vrloco_env.user._motion_numba._body_yaw`). The walked offset
        ``int_0^tau v(t) [cos yaw(t), sin yaw(t)] dt`` is integrated by 12-point Gauss-Legendre
        quadrature on [0, tau] — exact to rounding for a 0.1 s step — so the central differences of
        the positions give the true linear acceleration the IMU senses.

        Returns:
            The offset at the step's end (B, 2) m and the speed there (B,) m/s.
        """
        p = self.params
        dt = 1.0 / p.control_rate_hz
        t_all = np.append(times, dt)  # the evaluation times and the step's end
        nodes = 0.5 * (_GL_NODES + 1.0)  # on [0, 1]
        tq = t_all[:, None] * nodes[None, :]  # (T, Q) quadrature times
        v0 = s.speed[:, None, None]
        vc = (p.stride_m * cmd["cadence"])[:, None, None]
        speed = vc + (v0 - vc) * np.exp(-tq / p.speed_lag_s)  # (B, T, Q)
        r0, rc = s.yaw_rate[:, None, None], cmd["turn_rate"][:, None, None]
        yaw = (
            s.yaw[:, None, None]
            + rc * tq
            + (r0 - rc) * p.turn_lag_s * (1.0 - np.exp(-tq / p.turn_lag_s))
        )
        w = 0.5 * t_all[None, :, None] * _GL_WEIGHTS * speed  # (B, T, Q)
        off = np.stack([(w * np.cos(yaw)).sum(-1), (w * np.sin(yaw)).sum(-1)], -1)  # (B, T, 2)
        ev["neck"][..., :2] += off[:, :-1]
        ev["imu_pos"][..., :2] += off[:, :-1]
        speed_end = (vc + (v0 - vc) * math.exp(-dt / p.speed_lag_s))[:, 0, 0]
        return off[:, -1], speed_end

    def _time_grid(self, steps_done: int) -> tuple[NDArray, NDArray, NDArray]:
        """Kinect frame offsets and absolute times of control step ``steps_done``, and every time
        (s after the step start) :meth:`advance` evaluates the body at: the N sample times, the
        same -h and +h (central differences of the analytic position, h = 0.1 ms), three points
        for the last sample's left limit (the next intent is not known yet: backward second
        difference), and the Kinect frames. The offsets repeat from step to step, so they are
        built once per distinct pattern."""
        p = self.params
        tau_k, t_k = _frame_times(steps_done, p.control_rate_hz, p.kinect_rate_hz)
        key = tau_k.tobytes()
        times = self._grids.get(key)
        if times is None:
            n, h = p.samples_per_step, _DIFF_H
            tau = np.arange(1, n + 1) / p.imu_rate_hz
            times = np.concatenate(
                [tau - h, tau, tau + h, tau[-1] - np.array([2 * h, h, 0.0]), tau_k]
            )
            self._grids[key] = times
        return tau_k, t_k, times

    def _heel_strike_offsets(self, s, cmd, t_b_all, k_now, step) -> NDArray[np.float64]:
        """Exact heel-strike times after the control step's start, for the samples flagged in
        ``step`` (NaN elsewhere)."""
        t_b = t_b_all[:, None]
        target = k_now + 0.5  # the phase value crossed
        c_old = s.step_cadence[:, None]
        c_new = cmd["cadence"][:, None]
        ph0 = s.phase[:, None]
        to_boundary = np.ceil(ph0 - 1e-12) - ph0
        with np.errstate(divide="ignore", invalid="ignore"):
            t_old = (target - ph0) / c_old
            t_new = t_b + (target - ph0 - to_boundary) / c_new
        tau = np.where((c_old > 0) & (target <= ph0 + to_boundary), t_old, t_new)
        return np.where(step, tau, np.nan)

    def _hand_ypr(self, s: _State, cmd: dict, tau: NDArray[np.float64]) -> NDArray[np.float64]:
        lim = self._hand_limits
        ypr = s.hand_ypr[:, None, :] + cmd["hand_rates"][:, None, :] * tau[None, :, None]
        return np.minimum(np.maximum(ypr, -lim), lim)

    def _skeleton(
        self, s: _State, cmd: dict, ev: dict, tau: NDArray[np.float64], t_abs: NDArray[np.float64]
    ) -> KinectChunk:
        """True Kinect v2 skeleton (world frame) at times ``tau`` after the step start, from the
        body evaluated at those times (``ev``)."""
        b, m = self.batch_size, tau.shape[0]
        if m == 0:
            return KinectChunk(
                t_abs, np.zeros((b, 0, NUM_JOINTS, 3)), np.zeros((b, 0, 4)), np.zeros((b, 0, 3))
            )
        hand_ypr = self._hand_ypr(s, cmd, tau)
        joints = np.empty((b, m, NUM_JOINTS, 3))
        hand_q = np.empty((b, m, 4))
        skeleton_kernel(b)(
            ev["neck"],
            ev["quat"],
            ev["yaw"],
            ev["phase"],
            ev["walking"],
            hand_ypr,
            _BODY,
            joints,
            hand_q,
        )
        return KinectChunk(t=t_abs, joints=joints, hand_quat=hand_q, hand_ypr=hand_ypr)


def _frame_times(step: int, control_rate: float, rate: float) -> tuple[NDArray, NDArray]:
    """Frames k / rate in control step ``step``'s interval (t0, t1]: times after t0, and absolute.

    The times after t0 come from integers alone, so they do not depend on the absolute time (a
    user reset mid-run sees exactly the frame offsets of a fresh run).
    """
    k0 = np.floor(step * rate / control_rate + 1e-9) + 1
    k1 = np.floor((step + 1) * rate / control_rate + 1e-9)
    k = np.arange(k0, k1 + 1)
    return (k * control_rate - step * rate) / (rate * control_rate), k / rate


def _batch(value: ArrayLike, shape: tuple[int, ...], name: str) -> NDArray[np.float64]:
    a = np.asarray(value, dtype=np.float64)
    try:
        a = np.broadcast_to(a, shape).copy()
    except ValueError:
        raise ValueError(f"{name} must broadcast to shape {shape}, got {a.shape}") from None
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or infinite values")
    return a


def _check_range(a: NDArray, lo: float, hi: float, name: str, unit: str) -> None:
    bad = (a < lo - 1e-12) | (a > hi + 1e-12)
    if np.any(bad):
        raise ValueError(f"{name}={float(a[bad][0])!r}: must be in [{lo:.4g}, {hi:.4g}] {unit}")

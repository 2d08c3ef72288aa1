"""What every scripted user shares: the policy protocol, the parameters and the walk gate.

* :class:`Policy` — what the benchmark needs from a simulated user (``reset``, ``act``), and
  :func:`is_batched`, whether a policy plays a batch of users at once.
* :class:`PolicyParams` — what the scripted users know of their own body (how far one detected
  step carries them in VR, their width) and how they behave; :func:`params_from_env` matches them
  to an env.
* :class:`ScriptedPolicy` — the machinery of the scripted users: observation decoding, per-row
  state, the walk gate and the hand. A policy subclasses it and decides its ``_steer``: the target
  heading and whether it wants to walk.

An observation is one ``(n,)`` row (then the action is ``(5,)``) or a batch ``(B, n)`` from the
vector env (then ``(B, 5)``; the rules are evaluated for all rows at once and the per-row state
lives in arrays). Actions are float32 in [-1, 1]: ``[walk, turn, hand_yaw_rate, hand_pitch_rate,
hand_roll_rate]`` (:mod:`vrloco_env.actions`).

The walk gate. Walking-in-place steps cannot be stopped at will: a started step is finished, and
the gait detector reports the first step of a bout only together with the second
(:mod:`estimators.steps.zhang2021`), so the shortest walk moves the body two step lengths at once.
The users start walking only when the way ahead is free for ``go_steps`` step lengths (or up to the
goal region) and stop as soon as it is free for fewer than ``stop_steps``. After a stop the step
under way still lands, along whatever heading the body has when the detector reports it, so the
users hold their heading until then (``settle_steps``).

The head. With a user population that turns the head on the torso (gaze,
:mod:`vrloco_env.user.behaviour`) the view — heading, bearing, rays — follows the head, while the
turn action turns the body. A human knows where their head points relative to their body
(proprioception), so the users read the observation's ``head_on_torso`` and turn the body toward
their target: the target relative to the view plus the head's yaw on the torso. The walking
direction is the head's under Zhang 2021's steering and the torso's under torso steering
(``PolicyParams.walks_with_torso``, learnt like the step length): the goal seeker dead-reckons its
map and checks the way ahead along it, and plans relative to it
(:attr:`ScriptedPolicy.plans_along_walk`); the reactive users check the way ahead along the view.

The hand. In the goal region of Interact every policy stands still and turns the hand toward the
target by proportional control on the hand rates from the ``hand_error_*`` entries (target minus
the Kinect-estimated hand, which the VR scene shows the user).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from agents.scripted.observation import (
    ObservationLayout,
    ObsView,
    _check_obs,
    free_lengths,
    ray_points,
)
from estimators.batching import TakesUsers
from estimators.rotations import wrap_angle
from estimators.validation import check_bool, check_condition, check_in_range
from vrloco_env.actions import ACTION_SIZE

__all__ = ["Policy", "PolicyParams", "ScriptedPolicy", "is_batched", "params_from_env"]


@runtime_checkable
class Policy(Protocol):
    """What the benchmark needs from a simulated user. A policy that plays batches of users
    (``act`` on (B, n), ``reset`` with one generator per reset row) says so with a class
    attribute ``batched = True``; the benchmark then runs its episodes as users of one vector
    env (:func:`agents.benchmark.episodes.run_cell_batched`), else one at a time."""

    def reset(self, rng: Any = None, rows: ArrayLike | None = None) -> None:
        """Start new episodes (all rows, or only ``rows`` of a batch)."""

    def act(self, obs: ArrayLike) -> NDArray[np.float32]:
        """Actions ``(5,)`` for one observation ``(n,)``, or ``(B, 5)`` for ``(B, n)``."""


def is_batched(policy: Any) -> bool:
    """Whether ``policy`` plays a batch of users (``act`` on (B, n), ``reset(rngs, rows)``): it
    says so with a true ``batched`` attribute. A policy without one (a user's class written for
    the single env) gets one episode at a time from the benchmark."""
    return bool(getattr(policy, "batched", False))


# --------------------------------------------------------------------------- parameters


@dataclass(frozen=True)
class PolicyParams:
    """What the scripted users know and how they behave.

    Attributes:
        step_length_m: how far one detected step carries the virtual body (m): eq 17's SL,
            ``EstimatorConfig.step_length`` (a user learns it by walking).
        avatar_radius_m: the body's radius in the virtual room (m), ``RoomConfig.avatar_radius``.
        margin_m: clearance kept from every obstacle seen (m).
        tight_margin_m: the goal seeker squeezes through with only this clearance (m) when no
            heading keeps ``margin_m``; such ways cost ``1 + tight_cost`` times their length.
            (The map's clearance is already conservative by half a cell.)
        tight_cost: extra cost factor of ways closer than ``margin_m`` (dimensionless).
        tight_penalty_m: a heading clear only with ``tight_margin_m`` scores this much worse (m).
        hold_m: the heading aimed at in the last control step scores this much better (m):
            hysteresis, so that the aim does not flip between two ways as the user turns.
        comfort_m: further clearance preferred where the room allows (m): the goal seeker's
            way costs up to ``1 + comfort_cost`` times its length inside this band.
        comfort_cost: extra cost factor of walking close to obstacles (dimensionless).
        walk: walk action while walking (0.5: 1.7 steps/s, the middle of the comfortable
            1.2-2.2 steps/s of :class:`vrloco_env.user.motion.MotionParams`).
        turn_gain: turn action per radian of heading error (1/rad). 1.2 turns at the full
            120 deg/s above 48 deg of error; the loop gain 1.2 x 2.09 rad/s = 2.5 /s keeps the
            turn stable under a human reaction delay of up to ~0.6 s (a delayed integrator
            oscillates once gain x delay exceeds pi / 2): with 2.5 /rad the seeker behind
            :class:`agents.benchmark.variability.HumanVariability`'s 0.25 s delay circled its
            heading.
        go_deg: start walking when the heading error is below this (deg).
        stop_deg: stop walking and re-align when the heading error exceeds this (deg).
        go_steps: start walking only when the way ahead is free for this many step lengths:
            a bout's first step is reported with its second, so a start moves the body two
            step lengths at once; stopping on that report keeps a third step from starting
            (checked at walk 0.2, 0.5 and 0.8), so 2.15 leaves 0.1 m to spare.
        stop_steps: once a bout has landed, steps come one at a time; keep walking only while
            the way ahead is free for this many step lengths (the step under way lands one
            step length ahead whatever the user does; 1.3 leaves 0.2 m).
        settle_steps: after stopping, hold the heading for up to this many control steps until
            the step under way is detected (8 = 0.8 s at 10 Hz: a step at 1.7 steps/s lasts
            0.59 s and is detected 0.135 s after its heel strike, ``estimators.steps.zhang2021``).
        candidate_step_deg: spacing of the headings considered (deg).
        turn_cost_m: the goal seeker charges this many metres of way per radian of turning,
            so it does not swing round for a marginally shorter way.
        goal_depth_m: the goal seeker aims this far inside the goal region (m).
        map_cell_m: the goal seeker's map resolution (m).
        map_size_m: side of the goal seeker's square map, centred on the start (m).
        hand_gain: hand rate action per radian of hand error (1/rad).
        hand_deadband_deg: no hand motion below this error per axis (deg).
        walks_with_torso: the steps carry the body where the torso faces, not where the head
            points (``EstimatorConfig.steering`` ``"torso"``, or ``"hand"`` for a user who
            points straight ahead): how the locomotion works, which a user learns by walking, as
            the step length.
        reckons_by_sight: the user places what it has seen by the self-motion it sees (the
            observation's ``self_motion``) instead of by counting its detected steps: how a
            user of a technique that moves the body without steps (head tilt, look down to
            move) or where the hand points (hand steering) knows where it is
            (:func:`reckons_by_sight`). Under walking in place the step count is the cue (exact
            under eq 17).
        moves_by_steps: the body moves by detected steps, so a start lands two step lengths at
            once (:func:`moves_by_steps`); False for a technique that moves it continuously
            from the head's pitch.
    """

    step_length_m: float = 0.7
    avatar_radius_m: float = 0.25
    margin_m: float = 0.1
    tight_margin_m: float = 0.03
    tight_cost: float = 10.0
    tight_penalty_m: float = 1.0
    hold_m: float = 0.3
    comfort_m: float = 0.3
    comfort_cost: float = 2.0
    walk: float = 0.5
    turn_gain: float = 1.2
    go_deg: float = 8.0
    stop_deg: float = 25.0
    go_steps: float = 2.15
    stop_steps: float = 1.3
    settle_steps: int = 8
    candidate_step_deg: float = 3.0
    turn_cost_m: float = 0.3
    goal_depth_m: float = 0.25
    map_cell_m: float = 0.1
    map_size_m: float = 32.0
    hand_gain: float = 1.5
    hand_deadband_deg: float = 2.0
    walks_with_torso: bool = False
    reckons_by_sight: bool = False
    moves_by_steps: bool = True

    def __post_init__(self) -> None:
        check_in_range(self, "step_length_m", 0.05, 2.0, "m")
        check_in_range(self, "avatar_radius_m", 0.0, 2.0, "m")
        check_in_range(self, "margin_m", 0.0, 2.0, "m")
        check_in_range(self, "tight_margin_m", 0.0, self.margin_m, "m (<= margin_m)")
        check_in_range(self, "tight_cost", 0.0, 1000.0)
        check_in_range(self, "tight_penalty_m", 0.0, 100.0, "m")
        check_in_range(self, "hold_m", 0.0, 100.0, "m")
        check_in_range(self, "comfort_m", 0.0, 2.0, "m")
        check_in_range(self, "comfort_cost", 0.0, 100.0)
        check_in_range(self, "walk", 0.0, 1.0)
        check_in_range(self, "turn_gain", 0.01, 100.0, "1/rad")
        check_in_range(self, "go_deg", 0.1, 90.0, "deg")
        check_in_range(self, "stop_deg", self.go_deg, 180.0, "deg (>= go_deg)")
        check_in_range(self, "stop_steps", 0.0, 20.0)
        check_in_range(self, "go_steps", self.stop_steps, 20.0, "(>= stop_steps)")
        check_in_range(self, "candidate_step_deg", 0.1, 45.0, "deg")
        check_in_range(self, "settle_steps", 0, 100, "control steps", integer=True)
        check_in_range(self, "turn_cost_m", 0.0, 100.0, "m/rad")
        check_in_range(self, "goal_depth_m", 0.0, 10.0, "m")
        check_in_range(self, "map_cell_m", 0.02, 1.0, "m")
        check_in_range(self, "map_size_m", 4.0, 200.0, "m")
        check_in_range(self, "hand_gain", 0.0, 100.0, "1/rad")
        check_in_range(self, "hand_deadband_deg", 0.0, 45.0, "deg")
        check_bool(self, "walks_with_torso")
        check_bool(self, "reckons_by_sight")
        check_bool(self, "moves_by_steps")
        cells = self.map_size_m / self.map_cell_m
        check_condition(
            self,
            "map_size_m",
            cells <= 2000,
            f"at most 2000 map cells a side (map_cell_m={float(self.map_cell_m):g} "
            f"gives {cells:.0f})",
        )


def moves_by_steps(locomotion: Any) -> bool:
    """Whether a locomotion stage (a registered name, or what an ``EstimatorConfig`` holds)
    moves the body by detected steps; False for one that reads the head's pitch instead
    (``uses_pitch``: head tilt, look down to move)."""
    from estimators.stages import LOCOMOTION

    try:
        return not getattr(LOCOMOTION.factory(locomotion), "uses_pitch", False)
    except ValueError:
        return True


def reckons_by_sight(locomotion: Any, steering: Any = "head") -> bool:
    """Whether a user of these stages knows where it is by what it sees rather than by its
    steps: the locomotion moves the body without steps (:func:`moves_by_steps`), or the
    steering walks where the estimated hand points (``uses_hand``), a direction the user does
    not feel."""
    from estimators.stages import STEERING

    try:
        by_hand = bool(getattr(STEERING.factory(steering), "uses_hand", False))
    except ValueError:
        by_hand = False
    return by_hand or not moves_by_steps(locomotion)


#: For a stepless technique, the way ahead must be free for this many step lengths more than the
#: stop distance to start walking (a hysteresis, so that a user who just stopped does not start
#: again at once). A choice.
GO_SPARE_STEPS = 0.2


def stop_distance_m(locomotion: Any, motion: Any, walk: float, dt: float) -> float:
    """How far (m) a user of a stepless technique still moves after deciding to stop, while
    walking at the action ``walk``: what it learns by using the technique. Computed from the
    models, not measured on episodes: the head follows the lean with the motion model's
    critically damped lag ``tau = MotionParams.gesture_lag_s`` (:mod:`vrloco_env.user.gestures`).

    * Head tilt: the lean returns from the walk's tilt to 0 as ``x0 (1 + t / tau) e^(-t / tau)``;
      the speed follows it through the technique's dead zone.
    * Look down to move: the look down reaches the threshold at ``t`` with
      ``x_down (1 - (1 + t / tau) e^(-t / tau)) = threshold``; the user walks on at full speed
      until then, plus one control step ``dt`` to decide.
    * Anything else (walking in place): 0; the step gate's ``stop_steps`` covers it.
    """
    from estimators.locomotion.gestures import LookDownToToggle, TiltToMove
    from vrloco_env.user.gestures import LOOK_MARGIN_DEG

    gesture = getattr(locomotion, "gesture", None)
    params = getattr(locomotion, "params", None)
    tau = float(motion.gesture_lag_s)
    t = np.arange(0.0, 20.0 * tau, 0.005)
    if isinstance(gesture, TiltToMove) and params is not None:
        lo, hi = motion.cadence_range_hz
        fraction = min((lo + walk * (hi - lo)) / hi, 1.0)
        x0 = gesture.dead_zone_rad + fraction * (gesture.full_speed_rad - gesture.dead_zone_rad)
        x = x0 * (1.0 + t / tau) * np.exp(-t / tau)
        span = gesture.full_speed_rad - gesture.dead_zone_rad
        speed = params.max_speed_mps * np.clip((x - gesture.dead_zone_rad) / span, 0.0, 1.0)
        return float(np.sum(speed) * 0.005 + speed[0] * dt)
    if isinstance(gesture, LookDownToToggle) and params is not None:
        down = gesture.threshold_rad + np.deg2rad(LOOK_MARGIN_DEG)
        x = down * (1.0 - (1.0 + t / tau) * np.exp(-t / tau))
        reached = t[np.argmax(x >= gesture.threshold_rad)]
        return float(params.speed_mps * (reached + dt))
    return 0.0


def params_from_env(env: Any, **overrides: Any) -> PolicyParams:
    """Policy parameters matching an env's step length and avatar radius (what a user learns
    about their own body by walking) and, for a technique that moves the body without steps, its
    stop distance (:func:`stop_distance_m`, added to ``stop_steps``; ``go_steps`` at least
    :data:`GO_SPARE_STEPS` more), with
    ``overrides`` (PolicyParams fields)."""
    u = env.unwrapped
    names = {f.name for f in fields(PolicyParams)}
    bad = set(overrides) - names
    if bad:
        raise ValueError(f"unknown PolicyParams fields: {', '.join(sorted(bad))}")
    base = PolicyParams(
        step_length_m=float(u.estimators.step_length),
        avatar_radius_m=float(u.room.avatar_radius),
        walks_with_torso=u.estimators.steering in ("torso", "hand"),
        reckons_by_sight=reckons_by_sight(u.estimators.locomotion, u.estimators.steering),
        moves_by_steps=moves_by_steps(u.estimators.locomotion),
    )
    core = getattr(u, "core", None)
    if core is not None:  # a stepless technique: the way ahead must also hold its stop distance
        extra = (
            stop_distance_m(core.stages.locomotion, core.users.motion_params, base.walk, core.dt)
            / base.step_length_m
        )
        if extra > 0.0:  # no step to commit to at a start: go once the stop distance is free
            stop = base.stop_steps + extra
            base = replace(
                base, go_steps=max(base.go_steps, stop + GO_SPARE_STEPS), stop_steps=stop
            )
    return replace(base, **overrides)


# --------------------------------------------------------------------------- shared machinery


class ScriptedPolicy(TakesUsers):
    """Shared machinery: observation decoding, per-row state, the walk gate and the hand.

    A batch drops users with ``take_users(rows)`` (:class:`~estimators.batching.TakesUsers`):
    the per-row state and the active mask keep the rows ``rows``, and each kept user acts on as
    in the whole batch. Every subclass declares its own :attr:`per_user_fields`: these, plus
    any per-row attributes it keeps outside the state of :meth:`_init_state`.

    Args:
        layout: the observation layout (default: that of the default :class:`EnvConfig`).
        params: behaviour parameters.
    """

    name = "scripted"
    batched = True  # act() takes (B, n) rows: the benchmark may batch its episodes
    #: ``_steer``'s target is relative to the walking direction (``walk_offset``), not the view.
    plans_along_walk = False
    per_user_fields = ("_state", "_active")  # rows of the batch: state, which rows act

    def __init__(
        self, layout: ObservationLayout | None = None, params: PolicyParams | None = None
    ) -> None:
        self.layout = layout or ObservationLayout.from_config()
        self.params = params or PolicyParams()
        if not isinstance(self.layout, ObservationLayout):
            raise TypeError(f"layout must be an ObservationLayout, got {type(layout).__name__}")
        if not isinstance(self.params, PolicyParams):
            raise TypeError(f"params must be a PolicyParams, got {type(self.params).__name__}")
        self.offsets = self.layout.ray_offsets
        self._half_width = self.params.avatar_radius_m + self.params.margin_m
        self._state: dict[str, NDArray] | None = None
        self._active: NDArray[np.bool_] | None = None
        self._head_on_torso = "head_on_torso" in self.layout.spec

    def set_active(self, mask: ArrayLike | None) -> None:
        """The rows whose actions will be used ((B,) bool; None: all). The others' actions are
        not computed with care (the planner skips them) until they are reset and active again:
        for a batch whose finished users idle, or rows that belong to another policy."""
        self._active = None if mask is None else np.array(mask, dtype=bool)

    # ---------------------------------------------------------------- state
    def _init_state(self, b: int) -> dict[str, NDArray]:
        """Fresh per-row state (arrays with a leading B)."""
        return {"walking": np.zeros(b, bool), "settle": np.zeros(b, np.int64)}

    def reset(self, rng: Any = None, rows: ArrayLike | None = None) -> None:
        """Start new episodes.

        Args:
            rng: accepted for the common interface; scripted users are deterministic.
            rows: reset only these rows of a batch (a vector env's autoreset); None: all.
        """
        if rows is None or self._state is None:
            self._state = None
            return
        r = np.asarray(rows)
        b = next(iter(self._state.values())).shape[0]
        fresh = self._init_state(b)
        for k, v in self._state.items():
            v[r] = fresh[k][r]

    def _rows_state(self, b: int) -> dict[str, NDArray]:
        if self._state is None or next(iter(self._state.values())).shape[0] != b:
            self._state = self._init_state(b)
        return self._state

    # ---------------------------------------------------------------- acting
    def act(self, obs: ArrayLike) -> NDArray[np.float32]:
        """Actions for one observation ``(n,)`` -> ``(5,)`` or a batch ``(B, n)`` -> ``(B, 5)``.

        Raises:
            ValueError: wrong observation shape or non-finite entries.
        """
        o, single = _check_obs(obs, self.layout)
        v = ObsView.decode(o, self.layout)
        state = self._rows_state(o.shape[0])
        action = np.zeros((o.shape[0], ACTION_SIZE))
        target, want_walk, can_go, can_keep = self._steer(v, state)
        if self._head_on_torso:  # the turn action turns the body: aim it, not the view
            frame = self.walk_offset(v) if self.plans_along_walk else 0.0
            target = wrap_angle(target + v.head_on_torso - frame)
        self._gate(v, state, target, want_walk, can_go, can_keep, action)
        self._hand(v, action)
        a = np.clip(action, -1.0, 1.0).astype(np.float32)
        return a[0] if single else a

    def walk_offset(self, v: ObsView) -> NDArray[np.float64] | float:
        """The view heading minus the walking direction (rad): the head's yaw on the torso
        when the steps follow the torso, else 0."""
        return v.head_on_torso if self.params.walks_with_torso else 0.0

    def _steer(
        self, v: ObsView, state: dict[str, NDArray]
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
        """Target heading relative to the current one (rad), whether walking is wanted, whether
        the way ahead allows starting a walk and keeping on walking. Subclasses decide."""
        raise NotImplementedError

    def _ray_gate(
        self, v: ObsView, ahead: NDArray[np.float64]
    ) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """Start / keep walking from the free length ``ahead`` (m) seen by the rays: free for
        ``go_steps`` / ``stop_steps`` step lengths, or half a step into the goal region."""
        p = self.params
        sl = p.step_length_m
        near_goal = ahead >= v.distance + 0.5 * sl
        return (ahead >= p.go_steps * sl) | near_goal, (ahead >= p.stop_steps * sl) | near_goal

    def _ray_free(self, v: ObsView, angles: NDArray[np.float64]) -> NDArray[np.float64]:
        """Free lengths (m) along ``angles`` (relative, (C,) or (B, C)) from the current rays."""
        pts, ok = ray_points(v.rays, self.offsets, self.layout.ray_range_m)
        return free_lengths(pts, ok, angles, self._half_width, self.layout.ray_range_m)

    def _gate(
        self,
        v: ObsView,
        state: dict[str, NDArray],
        target: NDArray[np.float64],
        want_walk: NDArray[np.bool_],
        can_go: NDArray[np.bool_],
        can_keep: NDArray[np.bool_],
        action: NDArray[np.float64],
    ) -> None:
        """Turn toward ``target``; walk with hysteresis on the heading error and the free way.

        Starting a walk commits to two step lengths, so the way must be free for ``go_steps``
        step lengths — or into the goal region, when that is nearer — and walking stops when it
        is free for fewer than ``stop_steps``. After a stop the user holds the heading for up to
        ``settle_steps`` control steps, until the step under way has been detected: that step
        moves the body along the heading it is detected at, which was checked; a turn would aim
        it elsewhere. Inside the goal region the user stands still.
        """
        p = self.params
        err = np.abs(target)
        settling = state["settle"] > 0
        start = ~state["walking"] & ~settling & want_walk & (err < np.deg2rad(p.go_deg)) & can_go
        keep = state["walking"] & want_walk & (err < np.deg2rad(p.stop_deg)) & can_keep
        in_goal = v.distance <= 0.0
        walking = (start | keep) & ~in_goal
        stopped = state["walking"] & ~walking
        state["settle"] = np.where(
            stopped, p.settle_steps, np.where(v.steps > 0, 0, np.maximum(state["settle"] - 1, 0))
        )
        state["walking"] = walking
        hold = in_goal | (state["settle"] > 0)
        action[:, 0] = np.where(walking, p.walk, -1.0)
        action[:, 1] = np.where(hold, 0.0, np.clip(p.turn_gain * target, -1.0, 1.0))

    def _hand(self, v: ObsView, action: NDArray[np.float64]) -> None:
        """In the goal region, proportional control of the hand toward the target (Interact)."""
        p = self.params
        err = v.hand_error
        dead = np.abs(err) < np.deg2rad(p.hand_deadband_deg)
        rate = np.where(dead, 0.0, np.clip(p.hand_gain * err, -1.0, 1.0))
        on = (v.distance <= 0.0) & v.hand_valid
        action[:, 2:5] = np.where(on[:, None], rate, 0.0)

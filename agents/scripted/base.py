"""Scripted simulated users: policies that act on what the user sees in VR, and nothing else.

A policy is a small class with ``reset(rng=None, rows=None)`` and ``act(obs) -> action``; ``obs``
is one observation ``(n,)`` (then the action is ``(5,)``) or a batch ``(B, n)`` from the vector
env (then ``(B, 5)``; the rules are evaluated for all rows at once and the per-row state lives in
arrays). Actions are float32 in [-1, 1]: ``[walk, turn, hand_yaw_rate, hand_pitch_rate,
hand_roll_rate]`` (:mod:`vrloco_env.actions`).

Policies read the observation only (decoded with the env's
:class:`~vrloco_env.observation.ObservationSpec`): the virtual
heading, the goal bearing and distance and the ray ranges seen from the *virtual* pose (what the
headset shows), the detected steps, and for Interact the hand error — never the ground truth in
``info``. What a user knows about their own body (how far one detected step carries them in VR,
their width) is in :class:`PolicyParams`.

Three users:

* :class:`GoalSeeker` — turn toward the goal, step when aligned, stop and re-align when the
  bearing error grows. "Toward the goal" is toward the next stretch of the shortest way around
  what the user has seen: it remembers the ray hits in a map of the virtual room (placed by
  counting its own detected steps along its virtual heading — exactly how eq 17 moves the body)
  and plans on it, as a VR user who sees the room would.
* :class:`AvoidManoeuvre` — seed 000's Fig. 5 manoeuvre as a script: walk at the goal; when an
  obstacle stands on the line ahead, turn away by a fixed angle, step until the original heading
  is clear, turn back to the original heading and walk on.
* :class:`ReactiveAvoider` — a potential field on the current rays (Khatib 1986): the goal
  attracts the heading, close ray hits repel it; no memory.

In the goal region of Interact every policy stands still and turns the hand toward the target by
proportional control on the hand rates from the ``hand_error_*`` entries (target minus the
Kinect-estimated hand, which the VR scene shows the user).

Engineering decisions (the papers script no users beyond seed 000's straight walk and its Fig. 5
turn-away-and-back):

* Walking-in-place steps cannot be stopped at will: a started step is finished, and the gait
  detector reports the first step of a bout only together with the second
  (:mod:`estimators.gait`), so the shortest walk moves the body two step lengths at once. The
  users start walking only when the way ahead is free for ``go_steps`` step lengths (or up to the
  goal region) and stop as soon as it is free for fewer than ``stop_steps``. After a stop the
  step under way still lands, along whatever heading the body has when the detector reports
  it, so the users hold their heading until then (``settle_steps``).
* Rays are thin: an obstacle may be unseen between two rays from afar, and which edge of it the
  rays catch changes as the user turns, so headings computed from one frame of rays jump (the
  reactive users show this). The goal seeker's map accumulates every frame, which removes both.
  A first goal seeker that chose its heading from the current rays alone (the free heading
  nearest the goal bearing, no memory) reached only 9-17 of 30 Avoid goals and 26-28 of 30
  Approach goals at the default difficulty: it stalled in front of the obstacle as the rays
  slid over its edges, with no collision and with the estimators doing nothing wrong (the
  policy, not the estimation, lost those episodes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any, Protocol, runtime_checkable

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.kernels import BatchKernel, param_record
from vrloco_env.actions import ACTION_SIZE
from vrloco_env.config import EnvConfig
from vrloco_env.observation import ObservationSpec, env_spec, ray_offsets
from vrloco_env.validation import check_in_range

__all__ = [
    "POLICIES",
    "AvoidManoeuvre",
    "GoalSeeker",
    "ObsView",
    "ObservationLayout",
    "Policy",
    "PolicyParams",
    "ReactiveAvoider",
    "ScriptedPolicy",
    "free_lengths",
    "make_policy",
    "params_from_env",
    "ray_points",
]

@runtime_checkable
class Policy(Protocol):
    """What the benchmark needs from a simulated user. A policy that plays batches of users
    (``act`` on (B, n), ``reset`` with one generator per reset row) says so with a class
    attribute ``batched = True``; the benchmark then runs its episodes as users of one vector
    env (:func:`agents.benchmark.run_cell_batched`), else one at a time."""

    def reset(self, rng: Any = None, rows: ArrayLike | None = None) -> None:
        """Start new episodes (all rows, or only ``rows`` of a batch)."""

    def act(self, obs: ArrayLike) -> NDArray[np.float32]:
        """Actions ``(5,)`` for one observation ``(n,)``, or ``(B, 5)`` for ``(B, n)``."""


def is_batched(policy: Any) -> bool:
    """Whether ``policy`` plays a batch of users (``act`` on (B, n), ``reset(rngs, rows)``): it
    says so with a true ``batched`` attribute. A policy without one (a user's class written for
    the single env) gets one episode at a time from the benchmark."""
    return bool(getattr(policy, "batched", False))


# --------------------------------------------------------------------------- observation


class ObservationLayout:
    """What a policy knows of the observation: the env's :class:`ObservationSpec` (entries,
    scales, the decoder) and the directions of its rays.

    Args:
        spec: the env's observation spec (``env.unwrapped.observation_spec``).
        ray_offsets: ray directions relative to the heading (rad, counter-clockwise).
    """

    def __init__(self, spec: ObservationSpec, ray_offsets: ArrayLike) -> None:
        self.spec = spec
        self.ray_offsets = np.asarray(ray_offsets, dtype=np.float64)
        if "rays" not in spec or spec.field("rays").size != self.ray_offsets.size:
            raise ValueError("ray_offsets must give one direction per ray of the spec")
        self.ray_count = self.ray_offsets.size
        self.ray_range_m = spec.field("rays").scale

    @classmethod
    def from_config(
        cls, config: EnvConfig | None = None, task: str = "approach", task_config: Any = None
    ) -> ObservationLayout:
        """The layout of envs of ``task`` built with ``config`` (defaults if None)."""
        from vrloco_env.tasks import get_task

        config = config or EnvConfig()
        fields = get_task(task)(1, 0.1, task_config).fields()
        spec = env_spec(config.ray_count, config.ray_range_m, fields)
        return cls(spec, ray_offsets(config.ray_count, config.ray_fov_deg))

    @classmethod
    def from_env(cls, env: Any) -> ObservationLayout:
        """The layout of a ``gym.make``-built env (or its vector twin)."""
        core = env.unwrapped.core
        return cls(core.spec, core.ray_offsets)

    @property
    def names(self) -> list[str]:
        return self.spec.names

    @property
    def size(self) -> int:
        return self.spec.size

    def index(self, name: str) -> int:
        return self.spec.index(name)


@dataclass
class ObsView:
    """A batch of observations decoded into physical units (arrays over B rows).

    Attributes:
        heading: virtual heading (rad).
        walking: the gait detector says walking.
        steps: steps detected in the last control step (the entry saturates at 3).
        bearing: goal bearing relative to the heading (rad, counter-clockwise positive).
        distance: distance to the goal region (m); 0 inside it.
        rays: ray ranges (m), (B, R).
        hand_error: target minus estimated hand [yaw, pitch, roll] (rad), (B, 3).
        hand_valid: a hand estimate exists.
        dwell: fraction of the Interact dwell time held so far.
    """

    heading: NDArray[np.float64]
    walking: NDArray[np.bool_]
    steps: NDArray[np.float64]
    bearing: NDArray[np.float64]
    distance: NDArray[np.float64]
    rays: NDArray[np.float64]
    hand_error: NDArray[np.float64]
    hand_valid: NDArray[np.bool_]
    dwell: NDArray[np.float64]

    @classmethod
    def decode(cls, obs: NDArray[np.float64], layout: ObservationLayout) -> ObsView:
        """Decode ``(B, n)`` observations with the env's spec (tasks without a hand target
        read a zero hand error and dwell)."""
        d = layout.spec.decode(obs)
        b = obs.shape[0]
        return cls(
            heading=np.arctan2(d["heading"][:, 0], d["heading"][:, 1]),
            walking=d["walking"][:, 0] > 0.5,
            steps=np.rint(d["steps"][:, 0]),
            bearing=np.arctan2(d["goal_bearing"][:, 0], d["goal_bearing"][:, 1]),
            distance=d["goal_distance"][:, 0],
            rays=d["rays"],
            hand_error=d["hand_error"] if "hand_error" in d else np.zeros((b, 3)),
            hand_valid=d["hand_valid"][:, 0] > 0.5,
            dwell=d["dwell"][:, 0] if "dwell" in d else np.zeros(b),
        )


def _wrap(a: ArrayLike) -> NDArray[np.float64]:
    """Angles wrapped into [-pi, pi) (rad)."""
    return (np.asarray(a, dtype=np.float64) + np.pi) % (2.0 * np.pi) - np.pi


def _check_obs(obs: ArrayLike, layout: ObservationLayout) -> tuple[NDArray[np.float64], bool]:
    """The observations as ``(B, n)`` float64 and whether a single one was given."""
    o = np.asarray(obs, dtype=np.float64)
    single = o.ndim == 1
    if single:
        o = o[None]
    if o.ndim != 2 or o.shape[1] != layout.size:
        raise ValueError(
            f"obs must have shape ({layout.size},) or (B, {layout.size}) for "
            f"{layout.ray_count} rays, got {np.shape(obs)}"
        )
    if not np.all(np.isfinite(o)):
        raise ValueError("obs must be finite (an env observation lies in [-1, 1])")
    return o, single


# --------------------------------------------------------------------------- ray geometry


def ray_points(
    rays: NDArray[np.float64], offsets: NDArray[np.float64], range_m: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Obstacle points seen by the rays, in the body frame (x ahead, y left).

    Args:
        rays: ray ranges (m), (B, R).
        offsets: ray directions relative to the heading (rad), (R,).
        range_m: ray range (m); a ray this long saw nothing.

    Returns:
        points (B, R, 2) (m) and which of them are hits (B, R).
    """
    hit = rays < range_m * (1.0 - 1e-4)
    return rays[..., None] * np.stack([np.cos(offsets), np.sin(offsets)], -1), hit


def free_lengths(
    points: NDArray[np.float64],
    valid: NDArray[np.bool_],
    angles: NDArray[np.float64],
    half_width: float,
    max_length: float,
) -> NDArray[np.float64]:
    """How far a disc of radius ``half_width`` can move from the origin along each heading.

    Args:
        points: obstacle points in the body frame (m), (B, P, 2).
        valid: which points are real, (B, P).
        angles: headings relative to the body x axis (rad), (C,) for every row or (B, C).
        half_width: disc radius (m): the avatar's radius plus a margin.
        max_length: the length reported when nothing blocks (m).

    Returns:
        Free lengths (m), (B, C), in [0, max_length]. A point already closer than
        ``half_width`` blocks only the headings that would bring the body closer to it: the user
        may always move away from, or along, what they stand next to.
    """
    ang = np.asarray(angles, dtype=np.float64)
    if ang.ndim == 1:
        ang = np.broadcast_to(ang, (points.shape[0], ang.size))
    if ang.ndim != 2 or ang.shape[0] != points.shape[0]:
        raise ValueError(f"angles must have shape (C,) or (B, C), got {np.shape(angles)}")
    ux, uy = np.cos(ang)[:, None, :], np.sin(ang)[:, None, :]  # (B, 1, C)
    px, py = points[..., 0:1], points[..., 1:2]  # (B, P, 1)
    along = px * ux + py * uy
    lat = np.abs(px * uy - py * ux)
    rad = np.minimum(np.hypot(px, py) - 1e-3, half_width)
    half_chord = np.sqrt(np.maximum(rad**2 - lat**2, 0.0))
    blocks = valid[..., None] & (lat < rad) & (along > 0.0)
    first = np.where(blocks, np.maximum(along - half_chord, 0.0), np.inf).min(axis=1)
    return np.minimum(first, max_length)


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
            1.2-2.2 steps/s of :class:`vrloco_env.motion.MotionParams`).
        turn_gain: turn action per radian of heading error (1/rad). 1.2 turns at the full
            120 deg/s above 48 deg of error; the loop gain 1.2 x 2.09 rad/s = 2.5 /s keeps the
            turn stable under a human reaction delay of up to ~0.6 s (a delayed integrator
            oscillates once gain x delay exceeds pi / 2): with 2.5 /rad the seeker behind
            :class:`agents.variability.HumanVariability`'s 0.25 s delay circled its heading.
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
            0.59 s and is detected 0.135 s after its heel strike, ``estimators.gait``).
        candidate_step_deg: spacing of the headings considered (deg).
        turn_cost_m: the goal seeker charges this many metres of way per radian of turning,
            so it does not swing round for a marginally shorter way.
        goal_depth_m: the goal seeker aims this far inside the goal region (m).
        map_cell_m: the goal seeker's map resolution (m).
        map_size_m: side of the goal seeker's square map, centred on the start (m).
        hand_gain: hand rate action per radian of hand error (1/rad).
        hand_deadband_deg: no hand motion below this error per axis (deg).
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

    def __post_init__(self) -> None:
        def check(name: str, lo: float, hi: float, unit: str = "") -> None:
            check_in_range(self, name, lo, hi, unit)

        check("step_length_m", 0.05, 2.0, "m")
        check("avatar_radius_m", 0.0, 2.0, "m")
        check("margin_m", 0.0, 2.0, "m")
        check("tight_margin_m", 0.0, self.margin_m, "m (<= margin_m)")
        check("tight_cost", 0.0, 1000.0)
        check("tight_penalty_m", 0.0, 100.0, "m")
        check("hold_m", 0.0, 100.0, "m")
        check("comfort_m", 0.0, 2.0, "m")
        check("comfort_cost", 0.0, 100.0)
        check("walk", 0.0, 1.0)
        check("turn_gain", 0.01, 100.0, "1/rad")
        check("go_deg", 0.1, 90.0, "deg")
        check("stop_deg", self.go_deg, 180.0, "deg (>= go_deg)")
        check("stop_steps", 0.0, 20.0)
        check("go_steps", self.stop_steps, 20.0, "(>= stop_steps)")
        check("candidate_step_deg", 0.1, 45.0, "deg")
        if isinstance(self.settle_steps, bool) or not isinstance(self.settle_steps, int):
            raise ValueError(f"PolicyParams.settle_steps={self.settle_steps!r}: must be an int")
        check("settle_steps", 0, 100, "control steps")
        check("turn_cost_m", 0.0, 100.0, "m/rad")
        check("goal_depth_m", 0.0, 10.0, "m")
        check("map_cell_m", 0.02, 1.0, "m")
        check("map_size_m", 4.0, 200.0, "m")
        check("hand_gain", 0.0, 100.0, "1/rad")
        check("hand_deadband_deg", 0.0, 45.0, "deg")
        if self.map_size_m / self.map_cell_m > 2000:
            raise ValueError(
                "PolicyParams.map_size_m / map_cell_m must be <= 2000 cells a side, got "
                f"{self.map_size_m / self.map_cell_m:.0f}"
            )


def params_from_env(env: Any, **overrides: Any) -> PolicyParams:
    """Policy parameters matching an env's step length and avatar radius (what a user learns
    about their own body by walking), with ``overrides`` (PolicyParams fields)."""
    u = env.unwrapped
    names = {f.name for f in fields(PolicyParams)}
    bad = set(overrides) - names
    if bad:
        raise ValueError(f"unknown PolicyParams fields: {', '.join(sorted(bad))}")
    base = PolicyParams(
        step_length_m=float(u.estimators.step_length), avatar_radius_m=float(u.room.avatar_radius)
    )
    return replace(base, **overrides)


# --------------------------------------------------------------------------- policies


class ScriptedPolicy:
    """Shared machinery: observation decoding, per-row state, the walk gate and the hand.

    Args:
        layout: the observation layout (default: that of the default :class:`EnvConfig`).
        params: behaviour parameters.
    """

    name = "scripted"
    batched = True  # act() takes (B, n) rows: the benchmark may batch its episodes

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
        self._gate(v, state, target, want_walk, can_go, can_keep, action)
        self._hand(v, action)
        a = np.clip(action, -1.0, 1.0).astype(np.float32)
        return a[0] if single else a

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


@numba.njit(cache=True)
def _march(clear, cost, i0, j0, x, y, ang, length, thr, land, geom):
    """Walk a ray through the planning box from ``(x, y)`` along ``ang`` up to ``length`` (m).

    ``geom`` = (sample spacing, map half side, cell size, goal tolerance) (m). Returns ``(ok,
    end_cost)``: ok when every sample up to ``length`` keeps a clearance of at least ``thr``,
    or when the ray reaches the goal (cost to go <= the goal tolerance) first — at any sample if
    ``land`` is 0, else at the first sample at or beyond ``land`` (m), where a bout that starts
    now puts the body down; and the cost to go at the last sample.
    """
    ds, half, cell, goal_tol = geom[0], geom[1], geom[2], geom[3]
    ni, nj = clear.shape
    ux, uy = math.cos(ang), math.sin(ang)
    end_cost = np.inf
    for m in range(1, math.ceil(length / ds - 1e-9) + 1):
        s = m * ds
        ii = int((x + s * ux + half) / cell) - i0
        jj = int((y + s * uy + half) / cell) - j0
        if ii < 0 or ii >= ni or jj < 0 or jj >= nj or clear[ii, jj] < thr:
            return False, end_cost
        end_cost = cost[ii, jj]
        if s >= land - 1e-9:
            if end_cost <= goal_tol:
                return True, end_cost
            if land > 0.0:
                land = np.inf  # the landing point missed the goal: only a clear way counts
    return True, end_cost


@numba.njit(cache=True, inline="always")
def _heap_push(heap_cost, heap_key, size, c, k):
    """Push ``(c, k)`` onto the binary min-heap held in the first ``size`` entries; new size.

    Ties in ``c`` go by ``k``; the order among equal costs does not change a Dijkstra search's
    settled costs, only which of equal entries comes out first."""
    i = size
    while i > 0:
        parent = (i - 1) >> 1
        if heap_cost[parent] < c or (heap_cost[parent] == c and heap_key[parent] <= k):
            break
        heap_cost[i], heap_key[i] = heap_cost[parent], heap_key[parent]
        i = parent
    heap_cost[i], heap_key[i] = c, k
    return size + 1


@numba.njit(cache=True, inline="always")
def _heap_pop(heap_cost, heap_key, size):
    """Pop the smallest ``(c, k)`` of the heap of ``size`` entries; ``(c, k, new size)``."""
    c, k = heap_cost[0], heap_key[0]
    size -= 1
    lc, lk = heap_cost[size], heap_key[size]
    i = 0
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        if child + 1 < size and (
            heap_cost[child + 1] < heap_cost[child]
            or (heap_cost[child + 1] == heap_cost[child] and heap_key[child + 1] < heap_key[child])
        ):
            child += 1
        if lc < heap_cost[child] or (lc == heap_cost[child] and lk <= heap_key[child]):
            break
        heap_cost[i], heap_key[i] = heap_cost[child], heap_key[child]
        i = child
    heap_cost[i], heap_key[i] = lc, lk
    return c, k, size


def _plan_run(seen, pos, heading, target, keep_len, land, prev_aim, active, cands, prm, out):
    """Per user: clearance map, cost to go from the target, best heading, the walk gate.

    ``seen`` = ``(occ, lo, hi)``: ``occ`` (B, N, N) marks map cells with a ray hit, ``lo``/``hi``
    (B, 2) bound the marked cells. Planning runs on the box around the marked cells, the user
    and the target plus a margin; unseen cells are free. ``land`` (B,) is where the next move
    puts the body down (m): two step lengths for a standing user or one whose bout has not
    landed yet (a bout's first step is reported with the second), 0 once it moves a step at a
    time (any point of the way may be a landing). ``prm`` is the policy's (1,) record of
    :data:`PLAN_PARAMS`; users where ``active`` is False are skipped. Fills ``out`` =
    ``(aim, valid, go, keep)``, (B,) each: the heading relative to the current one (rad; 0 when
    nothing is valid), whether it is valid, whether the current heading is clear for ``look`` m
    or lands in the goal, and clear for ``keep_len`` (B,) m or into the goal.
    """
    occ, lo, hi = seen
    aim_out, valid_out, go_out, keep_out = out
    p = prm[0]
    cell, half, look, goal_tol = p["cell"], p["half"], p["look"], p["goal_tol"]
    r_tight, r_block, r_comfort = p["r_tight"], p["r_block"], p["r_comfort"]
    comfort_cost, tight_cost, turn_cost = p["comfort_cost"], p["tight_cost"], p["turn_cost"]
    step_a, tight_penalty, hold = p["step_a"], p["tight_penalty"], p["hold"]
    geom = np.array([0.5 * cell, half, cell, goal_tol])
    nb, n, _ = occ.shape
    w = math.ceil(r_comfort / cell) + 1
    cap = w * cell
    pad = w + math.ceil((look + 1.0) / cell)
    band = max(r_comfort - r_block, 1e-9)
    heap_cost = np.empty(0)  # the search's binary heap, reused by every user
    heap_key = np.empty(0, np.int64)
    for b in range(nb):
        if not active[b]:
            continue
        pi = min(max(int((pos[b, 0] + half) / cell), 0), n - 1)
        pj = min(max(int((pos[b, 1] + half) / cell), 0), n - 1)
        ti = min(max(int((target[b, 0] + half) / cell), 0), n - 1)
        tj = min(max(int((target[b, 1] + half) / cell), 0), n - 1)
        i0 = max(min(lo[b, 0], pi, ti) - pad, 0)
        i1 = min(max(hi[b, 0], pi, ti) + pad, n - 1)
        j0 = max(min(lo[b, 1], pj, tj) - pad, 0)
        j1 = min(max(hi[b, 1], pj, tj) + pad, n - 1)
        ni, nj = i1 - i0 + 1, j1 - j0 + 1
        # clearance: distance to the nearest marked cell (less half a cell), capped
        clear = np.full((ni, nj), cap)
        for oi in range(max(i0 - w, 0), min(i1 + w, n - 1) + 1):
            for oj in range(max(j0 - w, 0), min(j1 + w, n - 1) + 1):
                if not occ[b, oi, oj]:
                    continue
                for di in range(-w, w + 1):
                    ii = oi + di - i0
                    if ii < 0 or ii >= ni:
                        continue
                    for dj in range(-w, w + 1):
                        jj = oj + dj - j0
                        if jj < 0 or jj >= nj:
                            continue
                        d = max(math.sqrt(di * di + dj * dj) * cell - 0.5 * cell, 0.0)
                        if d < clear[ii, jj]:
                            clear[ii, jj] = d
        # cost to go from the target (Dijkstra, 8-connected), dearer close to obstacles. Only
        # the cells the rays below can read are needed (a square of ``reach`` cells around the
        # user): the search stops once every one of them that can be entered is settled, which
        # leaves their costs exactly what the full search gives.
        cost = np.full((ni, nj), np.inf)
        reach = math.ceil(max(look, keep_len[b]) / cell) + 1
        ri0, ri1 = max(pi - reach - i0, 0), min(pi + reach - i0, ni - 1)
        rj0, rj1 = max(pj - reach - j0, 0), min(pj + reach - j0, nj - 1)
        need = 0
        for i in range(ri0, ri1 + 1):
            for j in range(rj0, rj1 + 1):
                need += clear[i, j] > r_tight
        if heap_cost.size < 8 * ni * nj + 1:  # each cell is pushed at most once per neighbour
            heap_cost = np.empty(8 * ni * nj + 1)
            heap_key = np.empty(8 * ni * nj + 1, np.int64)
        cost[ti - i0, tj - j0] = 0.0
        heap_cost[0], heap_key[0] = 0.0, (ti - i0) * nj + (tj - j0)
        size = 1
        while size > 0 and need > 0:
            c, k, size = _heap_pop(heap_cost, heap_key, size)
            i, j = k // nj, k % nj
            if c > cost[i, j]:
                continue
            if ri0 <= i <= ri1 and rj0 <= j <= rj1 and clear[i, j] > r_tight:
                need -= 1
            for di in range(-1, 2):
                for dj in range(-1, 2):
                    if di == 0 and dj == 0:
                        continue
                    ii, jj = i + di, j + dj
                    if ii < 0 or ii >= ni or jj < 0 or jj >= nj:
                        continue
                    cl = clear[ii, jj]
                    if cl <= r_tight:
                        continue
                    step = cell * (1.4142135623730951 if di != 0 and dj != 0 else 1.0)
                    mult = 1.0 + comfort_cost * min(max(r_comfort - cl, 0.0) / band, 1.0)
                    if cl <= r_block:
                        mult += tight_cost
                    nc = c + step * mult
                    if nc < cost[ii, jj]:
                        cost[ii, jj] = nc
                        size = _heap_push(heap_cost, heap_key, size, nc, ii * nj + jj)
        # every heading with the full margin, and with the tight one at a penalty; the aim of
        # the last step gets a bonus (hysteresis). The user may always move away from, or
        # along, what it already stands closer to.
        x, y = pos[b, 0], pos[b, 1]
        c0 = clear[pi - i0, pj - j0] - 0.02
        prev = prev_aim[b] - heading[b]
        prev = (prev + math.pi) % (2.0 * math.pi) - math.pi
        best = np.inf
        best_a = 0.0
        best_thr = min(r_block, c0)
        for tier in range(2):
            thr = min(r_block if tier == 0 else r_tight, c0)
            for a in cands:
                ok, end_cost = _march(
                    clear, cost, i0, j0, x, y, heading[b] + a, look, thr, land[b], geom
                )
                if ok and end_cost < np.inf:
                    score = end_cost + turn_cost * abs(a) + tier * tight_penalty
                    if abs(a - prev) <= step_a:
                        score -= hold
                    if score < best:
                        best, best_a, best_thr = score, a, thr
        thr = best_thr
        valid_out[b] = best < np.inf
        aim_out[b] = best_a
        h = heading[b]
        go_out[b] = _march(clear, cost, i0, j0, x, y, h, look, thr, land[b], geom)[0]
        keep_out[b] = _march(clear, cost, i0, j0, x, y, h, keep_len[b], thr, land[b], geom)[0]


#: The goal seeker's planner: ``plan_kernel(batch_size)(...)`` (see ``_plan_run``).
plan_kernel = BatchKernel(_plan_run, parallel=False)


class GoalSeeker(ScriptedPolicy):
    """Turn toward the goal, step when aligned, re-align when the bearing error grows.

    The user remembers what the rays have shown: every hit goes into a map of the virtual room
    (cells of ``map_cell_m``), placed by dead reckoning from the observation alone — each
    detected step carries the body one step length along the virtual heading, exactly eq (17)'s
    update, so the map is exact under eq (17) locomotion (a blocked step, seen as a step that
    left the goal where it was, does not count). The aim point is ``goal_depth_m`` inside the
    goal region along the goal bearing. Each control step it computes the cost to go from the
    aim point over the map (Dijkstra on the cells farther than ``avatar_radius_m +
    tight_margin_m`` from every hit, dearer within ``margin_m`` and within ``comfort_m`` more;
    unseen cells count as free), then scores the headings every ``candidate_step_deg`` all
    round: a heading qualifies when the next ``go_steps`` step lengths along it keep
    ``margin_m`` (or, at ``tight_penalty_m``, ``tight_margin_m``), or when the next landing —
    two step lengths for a bout that starts now, one for a bout under way — is in the goal;
    its score is the cost to go at the end, plus ``turn_cost_m`` per radian of turning, less
    ``hold_m`` for last step's aim. It turns to the best, walks when aligned within ``go_deg``
    and that way is clear, and stops to re-align beyond ``stop_deg``. A heading into unseen
    space is turned to first, and the rays then show what is there.

    Under the smooth locomotion filter (seed 001) the body moves between detected steps, so the
    dead-reckoned map is approximate (the filter's lag, well under a metre).

    Args:
        layout: observation layout.
        params: behaviour parameters.
    """

    name = "goal_seeker"

    def __init__(
        self, layout: ObservationLayout | None = None, params: PolicyParams | None = None
    ) -> None:
        super().__init__(layout, params)
        p = self.params
        self._cells = round(p.map_size_m / p.map_cell_m)
        r = p.avatar_radius_m
        self._plan_prm = param_record(
            cell=p.map_cell_m, half=0.5 * self._cells * p.map_cell_m,
            look=p.go_steps * p.step_length_m, goal_tol=p.goal_depth_m,
            r_tight=r + p.tight_margin_m, r_block=self._half_width,
            r_comfort=self._half_width + p.comfort_m, comfort_cost=p.comfort_cost,
            tight_cost=p.tight_cost, turn_cost=p.turn_cost_m,
            step_a=np.deg2rad(p.candidate_step_deg) * 1.01, tight_penalty=p.tight_penalty_m,
            hold=p.hold_m,
        )  # fmt: skip
        n = int(np.floor(180.0 / p.candidate_step_deg))
        self.candidates = _wrap(np.deg2rad(p.candidate_step_deg) * np.arange(-n, n + 1))
        self.candidates = np.unique(np.round(self.candidates, 12))

    def _init_state(self, b: int) -> dict[str, NDArray]:
        n = self._cells
        return {
            "walking": np.zeros(b, bool),
            "settle": np.zeros(b, np.int64),
            "started": np.zeros(b, bool),
            "landed": np.zeros(b, bool),
            "aim": np.full(b, np.nan),  # last aimed heading, room frame (rad)
            "goal_vec": np.zeros((b, 2)),
            "pos": np.zeros((b, 2)),
            "occ": np.zeros((b, n, n), bool),
            "lo": np.full((b, 2), n, np.int64),
            "hi": np.full((b, 2), -1, np.int64),
        }

    def _remember(self, v: ObsView, state: dict[str, NDArray]) -> None:
        """Dead-reckon the body and put the current ray hits into the map.

        A detected step toward or away from the goal that left the goal where it was (the
        vector to the goal region, in the room frame, unchanged to 1 mm) was blocked by an
        obstacle — the user sees that they did not move — and does not move the reckoned
        position.
        """
        p = self.params
        ang = v.heading + v.bearing
        goal_vec = v.distance[:, None] * np.stack([np.cos(ang), np.sin(ang)], -1)
        u = np.stack([np.cos(v.heading), np.sin(v.heading)], -1)
        # a step with a fair component toward (or away from) the goal changes the distance to a
        # goal disc or line; one that did not was blocked (a sideways step along an end line
        # leaves the goal vector alone either way, and is trusted)
        to_goal = goal_vec / np.maximum(np.linalg.norm(goal_vec, axis=1, keepdims=True), 1e-9)
        radial = np.abs(np.sum(u * to_goal, axis=1)) > 0.2
        still = np.linalg.norm(goal_vec - state["goal_vec"], axis=1) < 1e-3
        blocked = still & radial & (v.distance > 0.0)
        state["goal_vec"] = goal_vec
        moved = np.where(state["started"] & ~blocked, v.steps * p.step_length_m, 0.0)
        state["pos"] += moved[:, None] * u
        state["started"][:] = True
        pts, ok = ray_points(v.rays, self.offsets, self.layout.ray_range_m)
        c, s = np.cos(v.heading)[:, None], np.sin(v.heading)[:, None]
        wx = state["pos"][:, 0:1] + c * pts[..., 0] - s * pts[..., 1]
        wy = state["pos"][:, 1:2] + s * pts[..., 0] + c * pts[..., 1]
        half = 0.5 * self._cells * p.map_cell_m
        ix = np.floor((wx + half) / p.map_cell_m).astype(np.int64)
        iy = np.floor((wy + half) / p.map_cell_m).astype(np.int64)
        ok = ok & (ix >= 0) & (ix < self._cells) & (iy >= 0) & (iy < self._cells)
        rows = np.broadcast_to(np.arange(ok.shape[0])[:, None], ok.shape)
        state["occ"][rows[ok], ix[ok], iy[ok]] = True
        big, small = self._cells, -1
        state["lo"][:, 0] = np.minimum(state["lo"][:, 0], np.where(ok, ix, big).min(1))
        state["lo"][:, 1] = np.minimum(state["lo"][:, 1], np.where(ok, iy, big).min(1))
        state["hi"][:, 0] = np.maximum(state["hi"][:, 0], np.where(ok, ix, small).max(1))
        state["hi"][:, 1] = np.maximum(state["hi"][:, 1], np.where(ok, iy, small).max(1))

    def _steer(self, v, state):
        p = self.params
        self._remember(v, state)
        b = v.heading.size
        ang = v.heading + v.bearing
        depth = v.distance + p.goal_depth_m
        target = state["pos"] + depth[:, None] * np.stack([np.cos(ang), np.sin(ang)], -1)
        # a bout's first two steps land together: until they have, the next move is 2 SL
        state["landed"] = state["walking"] & (state["landed"] | (v.steps > 0))
        single = state["walking"] & state["landed"]
        land = np.where(single, 0.0, 2.0 * p.step_length_m)
        keep_len = np.where(single, p.stop_steps * p.step_length_m, self._plan_prm[0]["look"])
        aim, valid = np.zeros(b), np.zeros(b, bool)
        can_go, can_keep = np.zeros(b, bool), np.zeros(b, bool)
        active = np.ones(b, bool) if self._active is None else self._active
        plan_kernel(b)(
            (state["occ"], state["lo"], state["hi"]), state["pos"], v.heading, target, keep_len,
            land, state["aim"], active, self.candidates, self._plan_prm,
            (aim, valid, can_go, can_keep),
        )  # fmt: skip
        state["aim"] = np.where(valid, v.heading + aim, np.nan)
        return np.where(valid, aim, v.bearing), valid, can_go, can_keep


class AvoidManoeuvre(ScriptedPolicy):
    """Seed 000 Fig. 5: turn away, step, turn back to the original heading.

    Phases per user: *cruise* (turn to the goal, walk when aligned); when the way along the
    heading, seen by the rays, is free for less than ``trigger_m`` short of the goal, remember
    the goal heading, pick the side whose rays see farther and *turn away* by ``away_deg``;
    *sidestep* — walk on the new heading until the rays show the remembered heading free for
    ``trigger_m + beyond_m`` (past where the obstacle stood), or into the goal region; *turn
    back* to the remembered heading; then *cruise* again (a new obstacle starts a new
    manoeuvre). If the way ahead closes while side-stepping, it turns back early and
    tries the other side at the next manoeuvre. No memory beyond these few numbers.

    Args:
        layout: observation layout.
        params: behaviour parameters.
        away_deg: how far to turn away (deg); seed 000 Fig. 5 shows roughly 45 deg.
        trigger_m: start the manoeuvre when the obstacle ahead is this close (m).
        beyond_m: how far past the trigger distance the original heading must be free before
            turning back (m).
    """

    name = "avoid_manoeuvre"
    CRUISE, AWAY, SIDESTEP, BACK = 0, 1, 2, 3

    def __init__(
        self,
        layout: ObservationLayout | None = None,
        params: PolicyParams | None = None,
        away_deg: float = 40.0,
        trigger_m: float = 2.0,
        beyond_m: float = 1.5,
    ) -> None:
        super().__init__(layout, params)
        if not 5.0 <= away_deg <= 90.0:
            raise ValueError(f"away_deg must be in [5, 90] deg, got {away_deg}")
        if not 0.5 <= trigger_m <= self.layout.ray_range_m:
            raise ValueError(
                f"trigger_m must be in [0.5, {self.layout.ray_range_m}] m (the ray range), "
                f"got {trigger_m}"
            )
        if not 0.0 <= beyond_m <= 10.0:
            raise ValueError(f"beyond_m must be in [0, 10] m, got {beyond_m}")
        self.away = np.deg2rad(away_deg)
        self.trigger = float(trigger_m)
        self.beyond = float(beyond_m)

    def _init_state(self, b: int) -> dict[str, NDArray]:
        return {
            "walking": np.zeros(b, bool),
            "settle": np.zeros(b, np.int64),
            "phase": np.zeros(b, np.int64),
            "heading0": np.zeros(b),
            "side": np.zeros(b),
            "failed": np.zeros(b),  # side of a manoeuvre that got stuck: try the other one
        }

    def _steer(self, v, state):
        p = self.params
        sl = p.step_length_m
        phase, h0, side = state["phase"], state["heading0"], state["side"]
        ahead = self._ray_free(v, np.zeros(1))[:, 0]
        # cruise -> turn away when the way at the goal is blocked
        blocked = (
            (phase == self.CRUISE)
            & (np.abs(v.bearing) < np.deg2rad(p.stop_deg))
            & (ahead < np.minimum(self.trigger, v.distance + 0.5 * sl))
        )
        pos_side, neg_side = self.offsets > 0, self.offsets < 0
        left = v.rays[:, pos_side].mean(1) if np.any(pos_side) else v.rays[:, 0]
        right = v.rays[:, neg_side].mean(1) if np.any(neg_side) else v.rays[:, 0]
        h0 = np.where(blocked, v.heading + v.bearing, h0)
        fresh_side = np.where(left >= right, 1.0, -1.0)
        side = np.where(blocked, np.where(state["failed"] != 0, -state["failed"], fresh_side), side)
        state["failed"] = np.where(blocked, 0.0, state["failed"])
        phase = np.where(blocked, self.AWAY, phase)
        to_h0 = _wrap(h0 - v.heading)
        away_target = _wrap(to_h0 + side * self.away)
        # turn away -> sidestep when turned
        phase = np.where(
            (phase == self.AWAY) & (np.abs(away_target) < np.deg2rad(p.go_deg)),
            self.SIDESTEP,
            phase,
        )
        # sidestep -> turn back when the original heading is free (or the way ahead closes)
        in_fan = np.abs(to_h0) <= np.max(np.abs(self.offsets)) + 1e-9
        free_h0 = self._ray_free(v, to_h0[:, None])[:, 0]
        side_stepping = phase == self.SIDESTEP
        clear_len = np.minimum(v.distance + 0.5 * sl, self.trigger + self.beyond)
        passed = side_stepping & in_fan & (free_h0 >= clear_len)
        stuck = side_stepping & ~state["walking"] & (ahead < p.stop_steps * sl)
        phase = np.where(passed | stuck, self.BACK, phase)
        state["failed"] = np.where(stuck, side, state["failed"])
        # turn back -> cruise when turned back
        phase = np.where(
            (phase == self.BACK) & (np.abs(to_h0) < np.deg2rad(p.go_deg)), self.CRUISE, phase
        )
        target = np.select(
            [phase == self.AWAY, phase == self.SIDESTEP, phase == self.BACK],
            [away_target, away_target, to_h0],
            v.bearing,
        )
        want = (phase == self.CRUISE) | (phase == self.SIDESTEP)
        state["phase"], state["heading0"], state["side"] = phase, h0, side
        return target, want, *self._ray_gate(v, ahead)


class ReactiveAvoider(ScriptedPolicy):
    """A potential field on the VR rays: the goal attracts, close ray hits repel.

    The aimed heading is the direction of ``goal_weight * e(bearing) - sum_j w_j e(offset_j)``
    with ``w_j = (1 / (r_j - avatar radius) - 1 / influence_m)^+`` for ray j at range ``r_j``
    (Khatib's repulsive potential gradient, up to a constant); it walks when the heading is near
    the aim and the way ahead is free (the walk gate of :class:`ScriptedPolicy`). Where the field
    points at a blocked way it turns ``detour_deg`` toward the more open side and holds that
    heading until the goal bearing is clear (or that way closes too). It knows only the
    current rays, so it can still dither between obstacles: the classic weakness of potential
    fields, kept on purpose as a baseline.

    Args:
        layout: observation layout.
        params: behaviour parameters.
        influence_m: ray hits closer than this repel (m).
        goal_weight: attraction of the goal (1/m: in the units of the repulsion).
        detour_deg: when the field points at a blocked way (its symmetric local minimum in
            front of an obstacle), turn this far toward the side whose rays see farther (deg).
        clear_m: the detour ends when the goal bearing is free for this long (m), or into the
            goal region.
    """

    name = "reactive_avoider"

    def __init__(
        self,
        layout: ObservationLayout | None = None,
        params: PolicyParams | None = None,
        influence_m: float = 1.5,
        goal_weight: float = 1.0,
        detour_deg: float = 45.0,
        clear_m: float = 3.5,
    ) -> None:
        super().__init__(layout, params)
        if not 0.1 <= influence_m <= self.layout.ray_range_m:
            raise ValueError(
                f"influence_m must be in [0.1, {self.layout.ray_range_m}] m, got {influence_m}"
            )
        if not 0.0 < goal_weight <= 100.0:
            raise ValueError(f"goal_weight must be in (0, 100], got {goal_weight}")
        if not 0.0 < detour_deg <= 90.0:
            raise ValueError(f"detour_deg must be in (0, 90] deg, got {detour_deg}")
        self.influence = float(influence_m)
        self.goal_weight = float(goal_weight)
        self.detour = np.deg2rad(detour_deg)
        if not 0.5 <= clear_m <= self.layout.ray_range_m:
            raise ValueError(
                f"clear_m must be in [0.5, {self.layout.ray_range_m}] m, got {clear_m}"
            )
        self.clear_m = float(clear_m)

    def _steer(self, v, state):
        p = self.params
        ahead = self._ray_free(v, np.zeros(1))[:, 0]
        r = np.maximum(v.rays - p.avatar_radius_m, 0.05)
        w = np.maximum(1.0 / r - 1.0 / self.influence, 0.0)
        fx = self.goal_weight * np.cos(v.bearing) - (w * np.cos(self.offsets)).sum(1)
        fy = self.goal_weight * np.sin(v.bearing) - (w * np.sin(self.offsets)).sum(1)
        target = np.arctan2(fy, fx)
        can_go, can_keep = self._ray_gate(v, ahead)
        # a symmetric field stalls in front of an obstacle: turn to the more open side
        stalled = ~can_go & (np.abs(target) < np.deg2rad(p.go_deg))
        pos_side, neg_side = self.offsets > 0, self.offsets < 0
        left = v.rays[:, pos_side].mean(1) if np.any(pos_side) else v.rays[:, 0]
        right = v.rays[:, neg_side].mean(1) if np.any(neg_side) else v.rays[:, 0]
        detour = v.heading + np.where(left >= right, 1.0, -1.0) * self.detour
        going = state["detour"]
        # the detour ends when the goal bearing is clear well past the obstacle, or its own
        # way closes
        sl = p.step_length_m
        goal_free = self._ray_free(v, v.bearing[:, None])[:, 0]
        in_fan = np.abs(v.bearing) <= np.max(np.abs(self.offsets)) + 1e-9
        clear = in_fan & (goal_free >= np.minimum(v.distance + 0.5 * sl, self.clear_m))
        done = clear | (state["walking"] & ~can_keep)
        going = np.where(done, np.nan, going)
        going = np.where(stalled & np.isnan(going), detour, going)
        state["detour"] = going
        target = np.where(np.isnan(going), target, _wrap(going - v.heading))
        return target, np.ones_like(ahead, bool), can_go, can_keep

    def _init_state(self, b: int) -> dict[str, NDArray]:
        return {**super()._init_state(b), "detour": np.full(b, np.nan)}


POLICIES: dict[str, type[ScriptedPolicy]] = {
    GoalSeeker.name: GoalSeeker,
    AvoidManoeuvre.name: AvoidManoeuvre,
    ReactiveAvoider.name: ReactiveAvoider,
}


def make_policy(
    name: str, layout: ObservationLayout | None = None, params: PolicyParams | None = None,
    **kwargs: Any,
) -> ScriptedPolicy:  # fmt: skip
    """A scripted user by name: ``goal_seeker``, ``avoid_manoeuvre`` or ``reactive_avoider``.

    Raises:
        ValueError: an unknown name (the valid ones are listed).
    """
    if name not in POLICIES:
        raise ValueError(f"policy={name!r}: must be one of {', '.join(POLICIES)}")
    return POLICIES[name](layout, params, **kwargs)

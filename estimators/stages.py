"""The estimation stages of a hands-free VR headset: their protocols, the contract every plug-in
stage is checked against, and the registries of named implementations.

A stage is batched over B users and streaming: ``reset(...)`` forgets some users and
``update(...)`` consumes the samples of one control step and returns that step's estimates.
Stages know nothing of the environment; the environment (:mod:`vrloco_env.users`) builds the
ones a technique names and composes them::

    head IMU  --gyr, acc, mag-->  attitude       --quat-->  step detector  --steps-->  locomotion
    Kinect    --frames------->  hand pipeline  --hand frames-->  hand filter
                                               --shoulders-->  torso yaw --> steering --> yaw

Every registry (:class:`estimators.registry.StageRegistry`) holds named implementations and also
accepts ``"package.module:attr"`` (or ``"path/to/file.py:attr"``), naming a user's class or
factory; unknown names get a clear error listing the valid ones. What each factory is called with
is fixed per stage.

Each stage has a protocol (:class:`AttitudeStage`, :class:`StepStage`, :class:`HandStage`,
:class:`SteeringStage`, :class:`Locomotion`) and, beside it, a :class:`StageContract`: how the
environment calls the protocol's methods, and the shapes and meaning of what ``update`` returns
(:class:`Output`, :class:`Rule`, from the tolerances :data:`QUAT_NORM_TOLERANCE`,
:data:`ANGLE_TOLERANCE_RAD` and :data:`POSITION_BOUND_M`). A step stage returns a
:class:`GaitChunk`.

* :meth:`estimators.registry.StageRegistry.build` checks, when a stage is built, that it has every
  member of its protocol (:func:`estimators.registry.protocol_members`, named in the error if
  missing) and that each method accepts the call the environment makes.
* :class:`estimators.checked.CheckedStage` wraps a plug-in that is not one of the package's own
  stages (:func:`vrloco_env.pipeline.build_stages` does it once) and checks every output of
  ``update`` against the contract: a wrong shape, a NaN, a zero quaternion, a step time from the
  future or a position 1e9 m away gets a :class:`~estimators.registry.StageError` naming the
  stage, the plug-in, the first offending user and sample, its value and the rule.
* :func:`estimators.stage_docs.protocol_reference` renders all of it as markdown
  (``docs/protocols.md``: ``python -m estimators.stage_docs > docs/protocols.md``), so the
  documentation is the check.

Optionally, any stage may drop users mid-run: ``take_users(rows)`` keeps the users ``rows``
(distinct indices, in their new order) and forgets the others, each kept user going on as it
would have (:mod:`estimators.batching`; :class:`~estimators.batching.TakesUsers` builds it from
the names of the per-user attributes). The benchmark's batched runner then steps only the users
still playing; with a stage that lacks it, the finished users idle to the batch's end instead.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.registry import StageRegistry

__all__ = [
    "ANGLE_TOLERANCE_RAD",
    "ATTITUDE",
    "HAND",
    "LOCOMOTION",
    "POSITION_BOUND_M",
    "QUAT_NORM_TOLERANCE",
    "STEERING",
    "STEPS",
    "AttitudeStage",
    "GaitChunk",
    "HandStage",
    "Locomotion",
    "MalformedOutput",
    "Output",
    "Rule",
    "StageContract",
    "SteeringStage",
    "StepStage",
]

#: Largest distance of an attitude plug-in's quaternion norm from 1.
QUAT_NORM_TOLERANCE = 1e-3
#: Slack (rad) of the hand angles' range [-pi, pi].
ANGLE_TOLERANCE_RAD = 1e-6
#: Largest distance (m) of a locomotion plug-in's position from the virtual room's origin.
POSITION_BOUND_M = 1e4


# ------------------------------------------------------------------------------ contracts
@dataclass(frozen=True)
class Output:
    """One array that a stage's ``update`` returns.

    Attributes:
        name: its name in errors and docs (``"quat"``).
        shape: its shape, with ``"B"`` (users), ``"N"`` (IMU samples of the control step) or
            ``"M"`` (Kinect frames of the control step) for the sizes that vary.
        kind: ``"float"``, ``"int"`` or ``"bool"``: what the environment receives.
        axes: names of the leading axes that an error indexes (``("user", "sample")``).
        meaning: what it holds, in words.
    """

    name: str
    shape: tuple[str | int, ...]
    kind: str
    axes: tuple[str, ...]
    meaning: str


@dataclass(frozen=True)
class Rule:
    """A rule on the meaning of one :class:`Output`.

    Attributes:
        output: the output's name.
        text: the rule as the docs and the errors state it.
        broken: ``(arrays, context) -> mask`` over the output's :attr:`Output.axes`: True where
            the rule is broken. ``arrays`` maps every output's name to its float64 array;
            ``context`` holds ``"clock"`` (samples each user's stream has seen since its last
            reset, (B,)) and ``"fs"`` (the stage's rate, Hz).
    """

    output: str
    text: str
    broken: Callable[[dict[str, NDArray[np.float64]], dict[str, Any]], NDArray[np.bool_]]


@dataclass(frozen=True)
class StageContract:
    """What the environment does with a stage beyond the protocol's member names.

    Attributes:
        factory: the factory's arguments, in words.
        calls: method -> (positional argument names, keyword argument names) of the environment's
            call; :meth:`StageRegistry.build` checks that each method accepts it.
        returns: what ``update`` returns, in words (the error for a malformed result cites it).
        outputs: the arrays of ``update``'s result, checked for shape.
        rules: the rules on their meaning, checked in order.
        optional: (member, meaning) of members the environment reads where present.
        dims: the sizes ``B``, ``N``, ``M`` of a call, from ``update``'s arguments.
        unpack: ``(result, stage) -> {output name: value}``; raises :class:`MalformedOutput` for a
            result of the wrong structure.
        pack: ``(checked arrays, result) -> what the environment receives``.
        clock: the size (``"N"``) each ``update`` advances the per-user clock by, or None.
        notes: what else a plug-in author needs to know of the calls, in words.
    """

    factory: str
    calls: dict[str, tuple[tuple[str, ...], tuple[str, ...]]]
    returns: str
    outputs: tuple[Output, ...]
    rules: tuple[Rule, ...]
    optional: tuple[tuple[str, str], ...]
    dims: Callable[[tuple[Any, ...]], dict[str, int]]
    unpack: Callable[[Any, Any], dict[str, Any]]
    pack: Callable[[dict[str, NDArray[np.float64]], Any], Any]
    clock: str | None = None
    notes: str = ""


class MalformedOutput(Exception):
    """A stage's result lacks the structure of its contract (the message says what it is):
    raised by a contract's ``unpack``, reported by :class:`estimators.checked.CheckedStage`."""


_TAKE_USERS = (
    "take_users(rows)",
    "keep the users `rows` (distinct indices, in their new order) and forget the others "
    "(`estimators.batching.TakesUsers` builds it from `per_user_fields`); lets the benchmark's "
    "batches shed finished users, who otherwise idle to the batch's end",
)


_GESTURE = (
    "gesture",
    "what the technique asks its users to do with their body to move "
    "(`estimators.locomotion.gestures`: tilt the head, look down, point the hand); the "
    "environment's simulated users perform it (default: step in place)",
)


def _bad_rows(ok: NDArray[np.bool_], axes: int) -> NDArray[np.bool_]:
    """True where ``ok`` is False anywhere beyond its first ``axes`` axes."""
    return ~(ok if ok.ndim == axes else ok.all(axis=tuple(range(axes, ok.ndim))))


def _finite(name: str, axes: int) -> Rule:
    """The rule "finite" on output ``name`` with ``axes`` indexed axes."""
    return Rule(name, "finite (no NaN or inf)", lambda a, c: _bad_rows(np.isfinite(a[name]), axes))


def _dims_bn(args: tuple[Any, ...]) -> dict[str, int]:
    b, n = np.shape(args[0])[:2]
    return {"B": int(b), "N": int(n)}


# ------------------------------------------------------------------------------ attitude
@runtime_checkable
class AttitudeStage(Protocol):
    """Head attitude from IMU samples (B streams)."""

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the users ``rows`` (integer indices or a (B,) boolean mask; None: all)."""
        ...

    def update(
        self, gyr: NDArray[np.float64], acc: NDArray[np.float64], mag: NDArray[np.float64] | None
    ) -> NDArray[np.float64]:
        """Consume (B, N, 3) gyro (rad/s), accelerometer (m/s^2) and magnetometer (any fixed
        unit, or None for a 6-axis IMU) samples; return (B, N, 4) quaternions ``[w, x, y, z]``,
        sensor -> ENU world, after each sample."""
        ...


def _quat_norm(a: dict[str, NDArray[np.float64]]) -> NDArray[np.float64]:
    return np.sqrt(np.sum(a["quat"] ** 2, axis=-1))


#: How the environment uses an :class:`AttitudeStage`.
ATTITUDE_CONTRACT = StageContract(
    factory="`factory(batch_size, fs)`: B users, fs the IMU sample rate (Hz)",
    calls={"reset": (("rows",), ()), "update": (("gyr", "acc", "mag"), ())},
    returns="a float array of shape (B, N, 4)",
    outputs=(
        Output(
            "quat",
            ("B", "N", 4),
            "float",
            ("user", "sample"),
            "`[w, x, y, z]`, sensor -> ENU world, after each of the step's N IMU samples",
        ),
    ),
    rules=(
        _finite("quat", 2),
        Rule(
            "quat", "not the zero quaternion (it is no rotation)", lambda a, c: _quat_norm(a) == 0.0
        ),
        Rule(
            "quat",
            f"unit length: | |q| - 1 | <= {QUAT_NORM_TOLERANCE:g}",
            lambda a, c: np.abs(_quat_norm(a) - 1.0) > QUAT_NORM_TOLERANCE,
        ),
    ),
    optional=(_TAKE_USERS,),
    dims=_dims_bn,
    unpack=lambda out, stage: {"quat": out},
    pack=lambda a, out: a["quat"],
)


# ------------------------------------------------------------------------------ steps
@dataclass
class GaitChunk:
    """What a step stage's ``update`` returns for one chunk of n samples of B streams (and
    :meth:`estimators.steps.StepDetector.update`).

    Attributes:
        state: 0 still, 1 walk, per sample, (B, n) int8.
        steps: number of steps confirmed at each sample (0, 1, or 2 when the second step of a bout
            also releases the first), (B, n) int8.
        peak_time: estimated heel-strike times (s since the stream's last reset, or since the
            detector started) of the steps confirmed at each sample, NaN-padded: ``[..., 0]`` the
            newest step, ``[..., 1]`` the released first step of a bout, (B, n, 2).
        sample_time: time (s since the detector started) of each sample of the chunk, (n,).
    """

    state: NDArray[np.int8]
    steps: NDArray[np.int8]
    peak_time: NDArray[np.float64]
    sample_time: NDArray[np.float64]

    def events(self) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
        """Every step of the chunk as ``(user, sample, peak_time)`` arrays, sorted by user then
        heel-strike time; ``sample`` indexes the chunk sample that confirmed the step."""
        b, i, j = np.nonzero(np.isfinite(self.peak_time))
        pt = self.peak_time[b, i, j]
        order = np.lexsort((pt, b))
        return b[order], i[order], pt[order]


@runtime_checkable
class StepStage(Protocol):
    """Still/walk and step events from IMU samples (B streams).

    Heel-strike times are on each stream's own clock: sample k after the stream's last
    ``reset`` (or the start) is at k / fs s, so that a user reset mid-run gets the numbers a new
    detector would give."""

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the users ``rows`` (integer indices or a (B,) boolean mask; None: all); their
        clocks restart at 0."""
        ...

    def update(
        self, acc: NDArray[np.float64], gyr: NDArray[np.float64], quat: NDArray[np.float64]
    ) -> Any:
        """Consume (B, N, 3) specific force (m/s^2) and angular rate (rad/s) and the attitude
        stage's (B, N, 4) estimate for the same samples (a detector may ignore it); return an
        :class:`GaitChunk` (or any object with its ``state``, ``steps`` and
        ``peak_time`` arrays)."""
        ...


_MAX_STEPS_PER_SAMPLE = 2  # the slots of peak_time: the newest step and a bout's released first


def _gait_fields(out: Any, stage: Any) -> dict[str, Any]:
    fields = {}
    for name in ("state", "steps", "peak_time"):
        if not hasattr(out, name):
            raise MalformedOutput(f"a {type(out).__name__} without {name!r}")
        fields[name] = getattr(out, name)
    return fields


def _pack_gait(a: dict[str, NDArray[np.float64]], out: Any) -> Any:
    sample_time = getattr(out, "sample_time", None)
    if sample_time is None:
        sample_time = np.full(a["steps"].shape[1], np.nan)
    return GaitChunk(
        state=a["state"].astype(np.int8),
        steps=a["steps"].astype(np.int8),
        peak_time=a["peak_time"],
        sample_time=sample_time,
    )


def _peak_slots_broken(a: dict[str, NDArray[np.float64]], c: dict[str, Any]) -> NDArray[np.bool_]:
    wanted = a["steps"][..., None] > np.arange(_MAX_STEPS_PER_SAMPLE)
    t = a["peak_time"]
    return ~np.where(wanted, np.isfinite(t), np.isnan(t)).all(axis=-1)


def _peak_time_broken(a: dict[str, NDArray[np.float64]], c: dict[str, Any]) -> NDArray[np.bool_]:
    t, period = a["peak_time"], 1.0 / c["fs"]
    now = (c["clock"][:, None] + np.arange(t.shape[1])) * period  # (B, N): each sample's time
    with np.errstate(invalid="ignore"):
        bad = (t < -period) | (t > now[..., None] + period)
    return bad.any(axis=-1)


#: How the environment uses a :class:`StepStage`.
STEPS_CONTRACT = StageContract(
    factory="`factory(batch_size, fs)`: B users, fs the IMU sample rate (Hz)",
    calls={"reset": (("rows",), ()), "update": (("acc", "gyr", "quat"), ())},
    returns="an `estimators.stages.GaitChunk` (an object with `state`, `steps` and `peak_time`)",
    outputs=(
        Output("state", ("B", "N"), "int", ("user", "sample"), "still (0) or walking (1)"),
        Output("steps", ("B", "N"), "int", ("user", "sample"), "steps confirmed at each sample"),
        Output(
            "peak_time",
            ("B", "N", 2),
            "float",
            ("user", "sample"),
            "the heel-strike times (s) of the steps confirmed at each sample: `[..., 0]` the "
            "newest, `[..., 1]` a bout's first step released with it; NaN-padded",
        ),
    ),
    rules=(
        Rule("state", "0 or 1", lambda a, c: (a["state"] != 0) & (a["state"] != 1)),
        Rule(
            "steps",
            "an integer 0, 1 or 2",
            lambda a, c: ~np.isin(a["steps"], np.arange(_MAX_STEPS_PER_SAMPLE + 1)),
        ),
        Rule(
            "peak_time",
            "finite in the first `steps` of its 2 slots, NaN in the others",
            _peak_slots_broken,
        ),
        Rule(
            "peak_time",
            "on the stream's own clock (sample k after its last reset is at k / fs s) and "
            "within one sample period (1 / fs) of the span from that reset to the sample "
            "that confirms the step: no step before the reset or from the future",
            _peak_time_broken,
        ),
    ),
    optional=(
        (
            "report_delay_s: float",
            "the longest delay (s) from a heel strike to its report, read once at build (the "
            "benchmark's step-matching window); `latency` is read if it is absent, else 0",
        ),
        (
            "uses_position: bool",
            "True: `update` is also given `position=`, the (B, N, 3) tracked headset position "
            "(m, z up; default False)",
        ),
        _TAKE_USERS,
    ),
    dims=_dims_bn,
    unpack=_gait_fields,
    pack=_pack_gait,
    clock="N",
)


# ------------------------------------------------------------------------------ hand
@runtime_checkable
class HandStage(Protocol):
    """Filtering of the wrist angles that the hand pipeline extracts from Kinect frames."""

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the users ``rows`` (integer indices or a (B,) boolean mask; None: all)."""
        ...

    def update(self, frames: Any) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Filter the step's M frames of B users: an :class:`estimators.hand.HandFrame` whose
        arrays are stacked over the frames (``ypr_raw`` (B, M, 3) rad, the raw eq (1)/(2)
        ``[yaw, pitch, roll]``; ``quat_valid``, ``reselected``, ``has_target`` (B, M); ...);
        return (B, M, 3) angles and their (B, M) validity."""
        ...


def _hand_range_broken(a: dict[str, NDArray[np.float64]], c: dict[str, Any]) -> NDArray[np.bool_]:
    with np.errstate(invalid="ignore"):
        return (np.abs(a["ypr"]) > np.pi + ANGLE_TOLERANCE_RAD).any(axis=-1)


def _hand_nan_broken(a: dict[str, NDArray[np.float64]], c: dict[str, Any]) -> NDArray[np.bool_]:
    ypr, valid = a["ypr"], a["valid"][..., None] == 1
    return np.where(valid, ~np.isfinite(ypr), np.isinf(ypr)).any(axis=-1)


def _hand_pair(out: Any, stage: Any) -> dict[str, Any]:
    if not (isinstance(out, tuple) and len(out) == 2):
        raise MalformedOutput(f"a {type(out).__name__}")
    return {"ypr": out[0], "valid": out[1]}


#: How the environment uses a :class:`HandStage`.
HAND_CONTRACT = StageContract(
    factory="`factory(batch_size, fs)`: B users, fs the Kinect frame rate (Hz)",
    calls={"reset": (("rows",), ()), "update": (("frames",), ())},
    returns="a tuple (ypr, valid)",
    outputs=(
        Output(
            "ypr",
            ("B", "M", 3),
            "float",
            ("user", "frame"),
            "filtered wrist `[yaw, pitch, roll]` (rad), camera space",
        ),
        Output("valid", ("B", "M"), "bool", ("user", "frame"), "whether the angles hold"),
    ),
    rules=(
        Rule("valid", "True or False (1 or 0)", lambda a, c: (a["valid"] != 0) & (a["valid"] != 1)),
        Rule(
            "ypr",
            "finite where `valid` is True; NaN (never inf) allowed where it is False",
            _hand_nan_broken,
        ),
        Rule(
            "ypr",
            f"every angle in [-pi, pi] where finite (radians, wrapped; {ANGLE_TOLERANCE_RAD:g} "
            "rad of slack); a filtered pitch may pass +-pi/2, as yao2023's Kalman filter's does "
            "near the pole",
            _hand_range_broken,
        ),
    ),
    optional=(_TAKE_USERS,),
    dims=lambda args: dict(zip(("B", "M"), map(int, np.shape(args[0].ypr_raw)[:2]), strict=True)),
    unpack=_hand_pair,
    pack=lambda a, out: (a["ypr"], a["valid"].astype(bool)),
)


# ------------------------------------------------------------------------------ steering
@runtime_checkable
class SteeringStage(Protocol):
    """Which physical yaw turns the walking direction."""

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the users ``rows`` (integer indices or a (B,) boolean mask; None: all)."""
        ...

    def update(
        self,
        head_yaw: NDArray[np.float64],
        torso_yaw: NDArray[np.float64],
        torso_valid: NDArray[np.bool_],
    ) -> NDArray[np.float64]:
        """(B,) walking yaw (rad) from the (B,) estimated head yaw and the Kinect's torso yaw
        (rad, both in the virtual room's frame) and whether the torso yaw holds (one frame)."""
        ...


#: How the environment uses a :class:`SteeringStage`.
STEERING_CONTRACT = StageContract(
    factory="`factory(batch_size)`: B users",
    calls={"reset": (("rows",), ()), "update": (("head_yaw", "torso_yaw", "torso_valid"), ())},
    returns="a float array of shape (B,)",
    outputs=(Output("yaw", ("B",), "float", ("user",), "the walking yaw (rad)"),),
    rules=(_finite("yaw", 1),),
    optional=(
        (
            "uses_torso: bool",
            "False says `torso_yaw` is never read, so the environment skips computing it "
            "(default True)",
        ),
        (
            "uses_hand: bool",
            "True: `update` is also given `hand_yaw=`, the (B,) estimated hand yaw on the torso "
            "(rad, NaN without an estimate; default False)",
        ),
        _GESTURE,
        _TAKE_USERS,
    ),
    dims=lambda args: {"B": int(np.shape(args[0])[0])},
    unpack=lambda out, stage: {"yaw": out},
    pack=lambda a, out: a["yaw"],
)


# ------------------------------------------------------------------------------ locomotion
@runtime_checkable
class Locomotion(Protocol):
    """What the environment needs from a locomotion model (eq 17 or smooth)."""

    batch_size: int

    def update(
        self, steps: ArrayLike, yaw: ArrayLike, dt: float, bearing: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Advance by ``dt`` s with ``steps`` (B,) new steps and heading ``yaw`` (B,) rad;
        return positions (B, 2) m."""
        ...

    def reset(
        self,
        mask: ArrayLike | None = None,
        position: ArrayLike | None = None,
        heading: ArrayLike | None = None,
    ) -> None:
        """Restart the users selected by ``mask`` (all if None)."""
        ...

    @property
    def position(self) -> NDArray[np.float64]:
        """Virtual positions (m), (B, 2)."""
        ...

    @property
    def heading(self) -> NDArray[np.float64]:
        """Heading (rad) of the motion, (B,)."""
        ...

    @property
    def distance(self) -> NDArray[np.float64]:
        """Path length travelled since reset (m), (B,)."""
        ...


#: How the environment uses a :class:`Locomotion` stage.
LOCOMOTION_CONTRACT = StageContract(
    factory="`factory(batch_size, step_length)`: B users, the step length (m)",
    calls={"reset": (("mask",), ("position", "heading")), "update": (("steps", "yaw", "dt"), ())},
    returns="a float array of shape (B, 2)",
    outputs=(
        Output(
            "position",
            ("B", 2),
            "float",
            ("user",),
            "the virtual position (m) in the room, returned by `update`",
        ),
        Output(
            "heading",
            ("B",),
            "float",
            ("user",),
            "the `heading` property (rad), read after each `update`",
        ),
    ),
    rules=(
        _finite("position", 1),
        Rule(
            "position",
            f"within {POSITION_BOUND_M:g} m of the room's origin",
            lambda a, c: np.hypot(a["position"][:, 0], a["position"][:, 1]) > POSITION_BOUND_M,
        ),
        _finite("heading", 1),
    ),
    optional=(
        (
            "uses_pitch: bool",
            "True: `update` is also given `pitch=`, the (B,) estimated head pitch (rad, "
            "positive nose down; default False)",
        ),
        _GESTURE,
        _TAKE_USERS,
    ),
    dims=lambda args: {"B": int(np.shape(args[0])[0])},
    unpack=lambda out, stage: {"position": out, "heading": stage.heading},
    pack=lambda a, out: a["position"],
    notes="The environment calls `reset` with a (B,) boolean `mask`, every user's (B, 2) "
    "`position` (m) and (B,) `heading` (rad); only the masked users restart, at theirs. "
    "`update` gets (B,) step counts (float), the (B,) walking yaw (rad) and `dt` (s); "
    "`bearing` is not passed.",
)


# Registries. A target is "module:attr" of a class or factory called with the stage's
# arguments (and returning an object of the stage's protocol); it is imported on first use.

#: Attitude filters: ``factory(batch_size, fs)`` with fs the IMU rate (Hz).
ATTITUDE = StageRegistry(
    "attitude",
    AttitudeStage,
    "(batch_size, fs)",
    ATTITUDE_CONTRACT,
    home="estimators.stages:ATTITUDE",
)
ATTITUDE.register(
    "ekf", "estimators.attitude.ekf:EkfStage", "Zhang 2021 error-state EKF (corrected)"
)
ATTITUDE.register(
    "ekf_paper_literal", "estimators.attitude.ekf:paper_literal_ekf", "Zhang 2021 EKF as printed"
)
ATTITUDE.register("ekf_f_zero", "estimators.attitude.ekf:f_zero_ekf", "corrected EKF with F = 0")
ATTITUDE.register("vqf", "estimators.attitude.vqf:VqfStage", "VQF (Laidig & Seel), vqf package")
ATTITUDE.register("madgwick", "estimators.attitude.madgwick:Madgwick", "Madgwick gradient descent")
ATTITUDE.register("mahony", "estimators.attitude.mahony:Mahony", "Mahony complementary PI filter")
ATTITUDE.register("gyro_only", "estimators.attitude.gyro:GyroOnly", "gyro integration: the floor")

#: Step detectors: ``factory(batch_size, fs)`` with fs the IMU rate (Hz).
STEPS = StageRegistry(
    "steps",
    StepStage,
    "(batch_size, fs)",
    STEPS_CONTRACT,
    home="estimators.stages:STEPS",
)
STEPS.register(
    "zhang2021", "estimators.steps.zhang2021:Zhang2021Steps", "Zhang 2021 eqs 15-16 on |f|"
)
STEPS.rename("seed000", "zhang2021")
STEPS.register("threshold", "estimators.steps.threshold:ThresholdSteps", "naive |f| peak picker")
STEPS.register(
    "nod_robust",
    "estimators.steps.nod_robust:NodRobustSteps",
    "world-vertical specific force, gated by head rotation",
)
STEPS.register(
    "lee2018",
    "estimators.steps.lee2018:Lee2018Steps",
    "Lee 2018 style: dips of the headset's tracked, pitch-compensated height",
)

#: Hand filters: ``factory(batch_size, fs)`` with fs the Kinect frame rate (Hz).
HAND = StageRegistry(
    "hand",
    HandStage,
    "(batch_size, fs)",
    HAND_CONTRACT,
    home="estimators.stages:HAND",
)
HAND.register("yao2023", "estimators.hand.pipeline_stages:Yao2023Hand", "Yao 2023 Kalman + median")
HAND.rename("seed003", "yao2023")
HAND.register("one_euro", "estimators.hand.one_euro:OneEuroHand", "One Euro filter on the angles")
HAND.register("raw", "estimators.hand.pipeline_stages:RawHand", "the unfiltered eq (1)/(2) angles")
HAND.register(
    "adaptive_kalman",
    "estimators.hand.adaptive:AdaptiveKalmanHand",
    "motion-adaptive Kalman, no median",
)

#: Steering: ``factory(batch_size)``.
STEERING = StageRegistry(
    "steering",
    SteeringStage,
    "(batch_size,)",
    STEERING_CONTRACT,
    home="estimators.stages:STEERING",
)
STEERING.register(
    "head", "estimators.locomotion.steering:HeadSteering", "walk where the head points"
)
STEERING.register(
    "torso", "estimators.locomotion.steering:TorsoSteering", "walk where the torso points"
)
STEERING.register(
    "hand", "estimators.locomotion.steering:HandSteering", "walk where the hand points"
)

#: Locomotion: ``factory(batch_size, step_length)`` with step_length in m.
LOCOMOTION = StageRegistry(
    "locomotion",
    Locomotion,
    "(batch_size, step_length)",
    LOCOMOTION_CONTRACT,
    home="estimators.stages:LOCOMOTION",
)
LOCOMOTION.register(
    "eq17", "estimators.locomotion.dead_reckoning:DeadReckoning", "Zhang 2021 eq 17 jumps"
)
LOCOMOTION.register(
    "smooth",
    "estimators.locomotion.smooth:SmoothLocomotion",
    "the smooth-locomotion paper's filter",
)
LOCOMOTION.register(
    "cadence_speed",
    "estimators.locomotion.cadence_speed:CadenceSpeed",
    "speed proportional to the estimated cadence",
)
LOCOMOTION.register(
    "head_tilt",
    "estimators.locomotion.head_tilt:HeadTilt",
    "speed from the head's forward tilt (Tregillus 2017)",
)
LOCOMOTION.register(
    "look_down_to_move",
    "estimators.locomotion.look_down:LookDownToMove",
    "a look down toggles an auto-walk",
)

"""The estimation stages of a hands-free VR headset, as protocols with registries of named
implementations, and the contract every plug-in stage is checked against.

A stage is batched over B users and streaming: ``reset(...)`` forgets some users and
``update(...)`` consumes the samples of one control step and returns that step's estimates.
Stages know nothing of the environment; the environment (:mod:`vrloco_env.users`) builds the
ones a technique names and composes them::

    head IMU  --gyr, acc, mag-->  attitude       --quat-->  step detector  --steps-->  locomotion
    Kinect    --frames------->  hand pipeline  --hand frames-->  hand filter
                                               --shoulders-->  torso yaw --> steering --> yaw

Every registry holds named implementations and also accepts ``"package.module:attr"`` (or
``"path/to/file.py:attr"``), naming a user's class or factory; unknown names get a clear error
listing the valid ones. What each factory is called with is fixed per stage.

Each stage has a protocol (:class:`AttitudeStage`, :class:`StepStage`, :class:`HandStage`,
:class:`SteeringStage`, :class:`estimators.locomotion.Locomotion`) and, beside it, a
:class:`StageContract`: how the environment calls the protocol's methods, and the shapes and
meaning of what ``update`` returns (:class:`Output`, :class:`Rule`, from the tolerances
:data:`QUAT_NORM_TOLERANCE`, :data:`ANGLE_TOLERANCE_RAD` and :data:`POSITION_BOUND_M`).

* :meth:`Registry.build` checks, when a stage is built, that it has every member of its protocol
  (:func:`protocol_members`, named in the error if missing) and that each method accepts the
  call the environment makes.
* :class:`CheckedStage` wraps a plug-in that is not one of the package's own stages
  (:func:`vrloco_env.pipeline.build_stages` does it once) and checks every output of ``update``
  against the contract: a wrong shape, a NaN, a zero quaternion, a step time from the future or
  a position 1e9 m away gets a :class:`StageError` naming the stage, the plug-in, the first
  offending user and sample, its value and the rule.
* :func:`protocol_reference` renders all of it as markdown (``docs/protocols.md``:
  ``python -m estimators.stages > docs/protocols.md``), so the documentation is the check.

Optionally, any stage may drop users mid-run: ``take_users(rows)`` keeps the users ``rows``
(distinct indices, in their new order) and forgets the others, each kept user going on as it
would have (:mod:`estimators.batching`; :class:`~estimators.batching.TakesUsers` builds it from
the names of the per-user attributes). The benchmark's batched runner then steps only the users
still playing; with a stage that lacks it, the finished users idle to the batch's end instead.
"""

from __future__ import annotations

import importlib
import inspect
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import stream_rows, takes_users
from estimators.locomotion import Locomotion

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
    "CheckedStage",
    "HandStage",
    "Output",
    "Registry",
    "Rule",
    "StageContract",
    "StageError",
    "SteeringStage",
    "StepStage",
    "load_attr",
    "protocol_members",
    "protocol_reference",
]

#: Largest distance of an attitude plug-in's quaternion norm from 1.
QUAT_NORM_TOLERANCE = 1e-3
#: Slack (rad) of the hand angles' range [-pi, pi].
ANGLE_TOLERANCE_RAD = 1e-6
#: Largest distance (m) of a locomotion plug-in's position from the virtual room's origin.
POSITION_BOUND_M = 1e4


class StageError(ValueError):
    """A stage's plug-in could not be built, raised, or returned what the stage does not allow."""


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
            call; :meth:`Registry.build` checks that each method accepts it.
        returns: what ``update`` returns, in words (the error for a malformed result cites it).
        outputs: the arrays of ``update``'s result, checked for shape.
        rules: the rules on their meaning, checked in order.
        optional: (member, meaning) of members the environment reads where present.
        dims: the sizes ``B``, ``N``, ``M`` of a call, from ``update``'s arguments.
        unpack: ``(result, stage) -> {output name: value}``; raises :class:`_Malformed` for a
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


class _Malformed(Exception):
    """A stage's result lacks the structure of its contract (the message says what it is)."""


_TAKE_USERS = (
    "take_users(rows)",
    "keep the users `rows` (distinct indices, in their new order) and forget the others "
    "(`estimators.batching.TakesUsers` builds it from `per_user_fields`); lets the benchmark's "
    "batches shed finished users, who otherwise idle to the batch's end",
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
        :class:`estimators.gait.GaitChunk` (or any object with its ``state``, ``steps`` and
        ``peak_time`` arrays)."""
        ...


_MAX_STEPS_PER_SAMPLE = 2  # the slots of peak_time: the newest step and a bout's released first


def _gait_fields(out: Any, stage: Any) -> dict[str, Any]:
    fields = {}
    for name in ("state", "steps", "peak_time"):
        if not hasattr(out, name):
            raise _Malformed(f"a {type(out).__name__} without {name!r}")
        fields[name] = getattr(out, name)
    return fields


def _pack_gait(a: dict[str, NDArray[np.float64]], out: Any) -> Any:
    from estimators.gait import GaitChunk

    sample_time = getattr(out, "sample_time", None)
    if sample_time is None:
        sample_time = np.full(a["steps"].shape[1], np.nan)
    return GaitChunk(state=a["state"].astype(np.int8), steps=a["steps"].astype(np.int8),
                     peak_time=a["peak_time"], sample_time=sample_time)  # fmt: skip


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
    returns="an `estimators.gait.GaitChunk` (an object with `state`, `steps` and `peak_time`)",
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
        raise _Malformed(f"a {type(out).__name__}")
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
            "rad of slack); a filtered pitch may pass +-pi/2, as seed003's Kalman filter's does "
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
        _TAKE_USERS,
    ),
    dims=lambda args: {"B": int(np.shape(args[0])[0])},
    unpack=lambda out, stage: {"yaw": out},
    pack=lambda a, out: a["yaw"],
)


# ------------------------------------------------------------------------------ locomotion
#: How the environment uses a :class:`estimators.locomotion.Locomotion` stage.
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
    optional=(_TAKE_USERS,),
    dims=lambda args: {"B": int(np.shape(args[0])[0])},
    unpack=lambda out, stage: {"position": out, "heading": stage.heading},
    pack=lambda a, out: a["position"],
    notes="The environment calls `reset` with a (B,) boolean `mask`, every user's (B, 2) "
    "`position` (m) and (B,) `heading` (rad); only the masked users restart, at theirs. "
    "`update` gets (B,) step counts (float), the (B,) walking yaw (rad) and `dt` (s); "
    "`bearing` is not passed.",
)


# ------------------------------------------------------------------------------ members
def protocol_members(protocol: type) -> list[str]:
    """The public members a protocol class declares, in declaration order: its annotated
    attributes and the methods and properties of its class body (and of its protocol bases).

    Read from the classes' own ``__annotations__`` and ``__dict__``, so it works on every
    Python that has :class:`typing.Protocol` (3.12's ``__protocol_attrs__`` is not needed)."""
    names: dict[str, None] = {}
    for base in reversed(protocol.__mro__):
        if base in (object, Protocol, Generic) or not base.__dict__.get("_is_protocol", False):
            continue
        for name in (*inspect.get_annotations(base), *vars(base)):
            if not name.startswith("_"):
                names[name] = None
    return list(names)


def _member(protocol: type, name: str) -> Any:
    """The object the protocol's class body binds to ``name`` (None: annotated only)."""
    for base in protocol.__mro__:
        if name in vars(base):
            return vars(base)[name]
    return None


def _is_method(obj: Any) -> bool:
    return callable(obj) and not isinstance(obj, type)


def _call_text(method: str, call: tuple[tuple[str, ...], tuple[str, ...]]) -> str:
    positional, keywords = call
    return f"{method}({', '.join((*positional, *(f'{k}=...' for k in keywords)))})"


def check_members(stage: Any, protocol: type, contract: StageContract) -> list[str]:
    """What ``stage`` lacks of ``protocol`` and its contract, one phrase each (empty: nothing):
    the members it does not have, by name, the methods that are not callable, and those whose
    signature does not accept the environment's call."""
    problems: list[str] = []
    missing = [name for name in protocol_members(protocol) if not hasattr(stage, name)]
    if missing:
        problems.append(f"lacks {', '.join(missing)} of the {protocol.__name__} protocol")
    for name in protocol_members(protocol):
        if name in missing or not _is_method(_member(protocol, name)):
            continue
        method = getattr(stage, name)
        if not callable(method):
            problems.append(f"has a {type(method).__name__} {name!r} where a method is needed")
            continue
        if name not in contract.calls:
            continue
        positional, keywords = contract.calls[name]
        try:
            signature = inspect.signature(method)
        except (TypeError, ValueError):  # a builtin without a signature: let the call tell
            continue
        try:
            signature.bind(*positional, **dict.fromkeys(keywords))
        except TypeError as err:
            problems.append(
                f"has {name}{signature}, which cannot be called as "
                f"{_call_text(name, contract.calls[name])} ({err})"
            )
    return problems


# ------------------------------------------------------------------------------ registries
def load_attr(spec: str, what: str) -> Any:
    """The object a ``"package.module:attr"`` string names, or ``"path/to/file.py:attr"`` (the
    file is imported as a module of its own), with clear errors for bad strings."""
    module_name, _, attr = spec.rpartition(":")
    if not module_name or not attr:
        raise StageError(
            f"{what}={spec!r}: a plug-in is named 'package.module:attr' or 'path/file.py:attr'"
        )
    if module_name.endswith(".py"):
        module = _import_file(module_name, spec, what)
    else:
        try:
            module = importlib.import_module(module_name)
        except ImportError as err:
            raise StageError(f"{what}={spec!r}: cannot import {module_name!r} ({err})") from None
    obj: Any = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise StageError(f"{what}={spec!r}: {module_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    return obj


def _import_file(path_text: str, spec: str, what: str) -> Any:
    """Import a Python file once per process, under a name derived from its resolved path."""
    import hashlib
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(path_text).expanduser().resolve()
    if not path.is_file():
        raise StageError(f"{what}={spec!r}: no such file {str(path)!r}")
    digest = hashlib.sha1(str(path).encode()).hexdigest()[:10]
    name = f"vrloco_plugin_{path.stem}_{digest}"
    if name in sys.modules:
        return sys.modules[name]
    loader_spec = importlib.util.spec_from_file_location(name, path)
    if loader_spec is None or loader_spec.loader is None:
        raise StageError(f"{what}={spec!r}: cannot import {str(path)!r}")
    module = importlib.util.module_from_spec(loader_spec)
    sys.modules[name] = module
    try:
        loader_spec.loader.exec_module(module)
    except Exception as err:
        del sys.modules[name]
        raise StageError(f"{what}={spec!r}: importing {str(path)!r} failed: {err}") from err
    return module


@dataclass(frozen=True)
class _Entry:
    target: str  # "module:attr" of the factory, imported on first use
    description: str


class Registry:
    """Named implementations of one stage.

    Args:
        stage: the stage's name, for error messages (``"attitude"``).
        protocol: the protocol every built stage must satisfy.
        signature: how factories are called, for the docs and error messages.
        contract: how the environment calls the stage and what it must return.
    """

    def __init__(self, stage: str, protocol: type, signature: str, contract: StageContract) -> None:
        self.stage = stage
        self.protocol = protocol
        self.signature = signature
        self.contract = contract
        self._entries: dict[str, _Entry] = {}

    def register(self, name: str, target: str, description: str) -> None:
        """Add ``name`` -> the factory at ``target`` ("module:attr"), with a one-line
        description. Re-registering a name replaces it."""
        if ":" not in target:
            raise ValueError(f"target {target!r} must be 'package.module:attr'")
        self._entries[name] = _Entry(target, description)

    def names(self) -> list[str]:
        """The registered names, in registration order."""
        return list(self._entries)

    def describe(self) -> dict[str, str]:
        """name -> one-line description."""
        return {k: e.description for k, e in self._entries.items()}

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickled by name: one of the module's five registries (its contract holds lambdas)."""
        return (_registry, (self.stage,))

    def check(self, spec: Any) -> None:
        """Raise a clear :class:`StageError` if ``spec`` names nothing buildable (without
        building it). Registered names pass (their modules are imported when first built);
        "module:attr" strings are imported and resolved; other objects must be callable or
        have a ``build`` method."""
        if not (isinstance(spec, str) and spec in self._entries):
            self.factory(spec)

    def label(self, spec: Any) -> str:
        """A short name of ``spec`` for tables and errors."""
        if isinstance(spec, str):
            return spec
        name = getattr(spec, "name", None)
        if isinstance(name, str):
            return name
        return type(spec).__name__ if not callable(spec) else getattr(spec, "__name__", "custom")

    def factory(self, spec: Any) -> Callable[..., Any]:
        """The callable that builds ``spec``'s stage.

        ``spec`` is a registered name, a ``"module:attr"`` string naming a class or factory, an
        object with a ``build(...)`` method (a parameter dataclass such as
        :class:`estimators.attitude.AttitudeParams`), or a class / factory.
        """
        if isinstance(spec, str):
            if spec in self._entries:
                return load_attr(self._entries[spec].target, self.stage)
            if ":" in spec:
                return _as_factory(load_attr(spec, self.stage), self.stage, spec)
            raise StageError(
                f"{self.stage}={spec!r}: unknown; valid names: {', '.join(self.names())}, or "
                "'package.module:attr' (or 'path/file.py:attr') naming your own"
            )
        return _as_factory(spec, self.stage, type(spec).__name__)

    def build(self, spec: Any, *args: Any, **kwargs: Any) -> Any:
        """Build ``spec``'s stage with the stage's factory arguments and check that it has every
        member of the protocol and that its methods accept the environment's calls
        (:func:`check_members`)."""
        factory = self.factory(spec)
        label = self.label(spec)
        try:
            stage = factory(*args, **kwargs)
        except StageError:
            raise
        except Exception as err:  # a user's factory failing: say which stage and plug-in
            raise StageError(
                f"{self.stage} plug-in {label!r} failed to build with {self.signature}: "
                f"{type(err).__name__}: {err}"
            ) from err
        problems = check_members(stage, self.protocol, self.contract)
        if problems:
            raise StageError(
                f"{self.stage} plug-in {label!r} built a {type(stage).__name__}, which "
                f"{'; and '.join(problems)} (docs/protocols.md)"
            )
        return stage


def _registry(stage: str) -> Registry:
    """The module's registry of ``stage`` (``"attitude"``, ...)."""
    return globals()[stage.upper()]


def _as_factory(obj: Any, stage: str, label: str) -> Callable[..., Any]:
    build = getattr(obj, "build", None)
    if callable(build) and not isinstance(obj, type):
        return build
    if callable(obj):
        return obj
    raise StageError(
        f"{stage}={label!r}: a plug-in must be a registered name, 'package.module:attr', a class "
        "or factory, or an object with a build() method"
    )


# ------------------------------------------------------------------------------ checked proxy
def _format_value(value: NDArray[np.float64]) -> str:
    """A number or a short vector, 6 significant digits each."""
    if np.ndim(value) == 0:
        return f"{float(value):.6g}"
    return "[" + ", ".join(f"{float(v):.6g}" for v in np.ravel(value)) + "]"


class CheckedStage:
    """A plug-in stage behind its stage's :class:`StageContract`.

    ``update`` calls the plug-in's and checks the result: its structure, the shape of each
    :class:`Output` and then every :class:`Rule`, in order; the environment receives the checked
    arrays (as float64, ``int8`` step states and counts, a boolean hand validity; a step stage's
    result as an :class:`estimators.gait.GaitChunk`). ``reset`` forwards to the plug-in's. An
    exception inside either, or a result the contract does not allow, is a :class:`StageError`
    naming the stage and the plug-in (and, for a broken rule, the first offending user and
    sample, its value and the rule). Every other attribute is the plug-in's: ``take_users``
    exists exactly where the plug-in can drop users (:func:`estimators.batching.takes_users`),
    and ``report_delay_s``, ``uses_torso`` or ``heading`` read through.

    The proxy keeps one number per user: the samples its stream has seen since its last reset
    (the clock that step times are checked on), which ``reset`` and ``take_users`` follow.

    Args:
        stage: the built plug-in.
        registry: its stage's registry (name and contract).
        label: the plug-in's short name, for errors.
        batch_size: B.
        rate_hz: the stage's sample rate (Hz) for the stages built with one.
    """

    def __init__(
        self,
        stage: Any,
        registry: Registry,
        label: str,
        batch_size: int,
        rate_hz: float | None = None,
    ) -> None:
        self._stage = stage
        self._registry = registry
        self._name = registry.stage
        self._label = label
        self._rate_hz = rate_hz
        self._clock = np.zeros(batch_size, np.int64)

    @property
    def wrapped(self) -> Any:
        """The plug-in."""
        return self._stage

    @property
    def _contract(self) -> StageContract:
        return self._registry.contract

    def __repr__(self) -> str:
        return f"CheckedStage({self._name} plug-in {self._label!r}: {self._stage!r})"

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name in ("_stage", "_registry", "_name", "_label", "_clock"):
            raise AttributeError(name)  # copying or unpickling: the instance is not set up yet
        if name == "take_users":
            if not takes_users(self._stage):
                raise AttributeError(
                    f"{self._name} plug-in {self._label!r} has no take_users (its users idle "
                    "to the batch's end instead)"
                )
            return self._take_users
        return getattr(self._stage, name)

    def reset(self, *args: Any, **kwargs: Any) -> None:
        """The plug-in's ``reset``; the reset users' clocks restart at 0."""
        self._call("reset", args, kwargs)
        if self._contract.clock is not None:
            rows = args[0] if args else kwargs.get(self._contract.calls["reset"][0][0])
            self._clock[stream_rows(rows, self._clock.size, unique=False)] = 0

    def _take_users(self, rows: ArrayLike) -> None:
        self._stage.take_users(rows)
        self._clock = self._clock[np.asarray(rows, dtype=np.intp)]

    def update(self, *args: Any) -> Any:
        """The plug-in's ``update``, its result checked against the contract."""
        contract = self._contract
        dims = contract.dims(args)
        out = self._call("update", args, {})
        try:
            raw = contract.unpack(out, self._stage)
        except _Malformed as err:
            raise self._error(f"returned {err}; expected {contract.returns}") from None
        except Exception as err:
            raise self._error(f"raised reading its output: {type(err).__name__}: {err}") from err
        arrays = {o.name: self._array(o, raw[o.name], dims) for o in contract.outputs}
        context = {"clock": self._clock, "fs": self._rate_hz}
        for rule in contract.rules:
            broken = rule.broken(arrays, context)
            if broken.any():
                raise self._broken(rule, arrays[rule.output], broken)
        if contract.clock is not None:
            self._clock += dims[contract.clock]
        return contract.pack(arrays, out)

    def _call(self, method: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
        try:
            return getattr(self._stage, method)(*args, **kwargs)
        except StageError:
            raise
        except Exception as err:
            raise self._error(f"raised in {method}(): {type(err).__name__}: {err}") from err

    def _array(self, output: Output, value: Any, dims: dict[str, int]) -> NDArray[np.float64]:
        shape = tuple(dims[s] if isinstance(s, str) else s for s in output.shape)
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise self._error(
                f"returned {type(value).__name__} for {output.name}; expected a {output.kind} "
                f"array of shape {shape}"
            ) from None
        if arr.shape != shape:
            raise self._error(f"returned {output.name} of shape {arr.shape}; expected {shape}")
        return arr

    def _broken(self, rule: Rule, value: NDArray[np.float64], broken: NDArray) -> StageError:
        output = next(o for o in self._contract.outputs if o.name == rule.output)
        at = tuple(int(i) for i in np.argwhere(broken)[0])
        where = ", ".join(f"{axis} {i}" for axis, i in zip(output.axes, at, strict=True))
        return self._error(
            f"returned {rule.output} at {where}: {_format_value(value[at])}, which breaks the "
            f"rule: {rule.text}"
        )

    def _error(self, what: str) -> StageError:
        return StageError(f"{self._name} plug-in {self._label!r} {what}")


# ------------------------------------------------------------------------------ reference
_REGENERATE = ".venv/bin/python -m estimators.stages > docs/protocols.md"


def _annotation(value: Any) -> str:
    if value is inspect.Parameter.empty:
        return ""
    return value if isinstance(value, str) else inspect.formatannotation(value)


def _signature_text(function: Callable[..., Any]) -> str:
    signature = inspect.signature(function)
    params = []
    for p in list(signature.parameters.values())[1:]:  # without self
        text = p.name + (f": {_annotation(p.annotation)}" if _annotation(p.annotation) else "")
        if p.default is not inspect.Parameter.empty:
            text += f" = {p.default!r}"
        params.append(text)
    returns = _annotation(signature.return_annotation)
    return f"({', '.join(params)})" + (f" -> {returns}" if returns else "")


def _doc(obj: Any) -> str:
    """``obj``'s docstring on one line, its Sphinx roles as code."""
    text = " ".join((inspect.getdoc(obj) or "").split())
    return re.sub(r":[a-z]+:`~?([^`]+)`", r"`\1`", text)


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def _stage_reference(registry: Registry) -> list[str]:
    protocol, contract = registry.protocol, registry.contract
    built_in = ", ".join(f"`{k}` ({v})" for k, v in registry.describe().items())
    lines = [
        f"## `{registry.stage}`: `{protocol.__module__}.{protocol.__name__}`",
        "",
        _doc(protocol),
        "",
        f"Built as {contract.factory}. Built in: {built_in}.",
        "",
        "Members (each must exist; each method must accept the call shown):",
        "",
    ]
    annotations: dict[str, Any] = {}
    for base in reversed(protocol.__mro__):
        annotations.update(inspect.get_annotations(base))
    for name in protocol_members(protocol):
        obj = _member(protocol, name)
        if isinstance(obj, property):
            returns = _annotation(inspect.signature(obj.fget).return_annotation)
            lines.append(f"- `{name}` (property) `-> {returns}`: {_doc(obj)}")
        elif _is_method(obj):
            called = contract.calls.get(name)
            how = f", called as `{_call_text(name, called)}`" if called else ""
            lines.append(f"- `{name}{_signature_text(obj)}`{how}: {_doc(obj)}")
        else:
            lines.append(f"- `{name}: {_annotation(annotations.get(name))}` (attribute)")
    if contract.notes:
        lines += ["", contract.notes]
    lines += [
        "",
        f"`update` returns {contract.returns}. For a plug-in, every step:",
        "",
        "| output | shape | kind | meaning | rules |",
        "|---|---|---|---|---|",
    ]
    for out in contract.outputs:
        shape = "(" + ", ".join(map(str, out.shape)) + ("," if len(out.shape) == 1 else "") + ")"
        rules = "; ".join(r.text for r in contract.rules if r.output == out.name) or "-"
        lines.append(
            f"| `{out.name}` | {shape} | {out.kind} | {_cell(out.meaning)} | {_cell(rules)} |"
        )
    lines += ["", "Optional members:", ""]
    lines += [f"- `{member}`: {meaning}" for member, meaning in contract.optional]
    return lines


def protocol_reference() -> str:
    """The markdown reference of every stage protocol (``docs/protocols.md``): each member's
    signature and docstring, how the environment calls it, and the output contract that
    :class:`CheckedStage` enforces, rendered from the same classes and constants."""
    lines = [
        "# Stage protocols",
        "",
        "<!-- Generated from estimators/stages.py; do not edit. Regenerate with:",
        f"     {_REGENERATE} -->",
        "",
        "What a plug-in for each estimation stage must have and return, exactly as the "
        "environment checks it. A stage field of `EstimatorConfig` takes a registered name, "
        '`"package.module:attr"` or `"path/to/file.py:attr"` naming a class or factory, a '
        "class or factory itself, or an object with a `build(...)` method. Every stage is "
        "batched over B users and streaming.",
        "",
        "When a plug-in is built (`gym.make`), it must have every member listed for its "
        "stage, and each method must accept the call the environment makes; the error names "
        "what is missing. A plug-in that is not one of the package's own stages is then wrapped "
        "once in `estimators.stages.CheckedStage`, which checks every result of `update` "
        "against its stage's table: first the structure and each output's shape, then the "
        "rules, in order. A broken rule is a `StageError` naming the stage, the plug-in, the "
        "first offending user and sample (or frame), its value and the rule; an exception "
        "inside `reset` or `update` is a `StageError` naming the stage and the plug-in.",
        "",
        "Sizes: B users, N IMU samples of one control step, M Kinect frames of one control "
        "step. Tolerances: `QUAT_NORM_TOLERANCE` = "
        f"{QUAT_NORM_TOLERANCE:g}, `ANGLE_TOLERANCE_RAD` = {ANGLE_TOLERANCE_RAD:g} rad, "
        f"`POSITION_BOUND_M` = {POSITION_BOUND_M:g} m.",
        "",
        "Examples, one working plug-in per stage, each run by `tests/test_examples.py`: "
        "`examples/custom_estimator.py` (attitude), `examples/custom_steps.py`, "
        "`examples/custom_hand.py`, `examples/custom_steering.py`, "
        "`examples/custom_locomotion.py`.",
    ]
    for registry in (ATTITUDE, STEPS, HAND, STEERING, LOCOMOTION):
        lines += ["", *_stage_reference(registry)]
    return "\n".join(lines) + "\n"


# Registries. A target is "module:attr" of a class or factory called with the stage's
# arguments (and returning an object of the stage's protocol); it is imported on first use.

#: Attitude filters: ``factory(batch_size, fs)`` with fs the IMU rate (Hz).
ATTITUDE = Registry("attitude", AttitudeStage, "(batch_size, fs)", ATTITUDE_CONTRACT)
ATTITUDE.register("ekf", "estimators.attitude:EkfStage", "seed 000 error-state EKF (corrected)")
ATTITUDE.register(
    "ekf_paper_literal", "estimators.attitude:paper_literal_ekf", "seed 000 EKF as printed"
)
ATTITUDE.register("ekf_f_zero", "estimators.attitude:f_zero_ekf", "corrected EKF with F = 0")
ATTITUDE.register("vqf", "estimators.attitude_vqf:VqfStage", "VQF (Laidig & Seel), vqf package")
ATTITUDE.register("madgwick", "estimators.attitude_madgwick:Madgwick", "Madgwick gradient descent")
ATTITUDE.register("mahony", "estimators.attitude_mahony:Mahony", "Mahony complementary PI filter")
ATTITUDE.register("gyro_only", "estimators.attitude_gyro:GyroOnly", "gyro integration: the floor")

#: Step detectors: ``factory(batch_size, fs)`` with fs the IMU rate (Hz).
STEPS = Registry("steps", StepStage, "(batch_size, fs)", STEPS_CONTRACT)
STEPS.register("seed000", "estimators.gait:Seed000Steps", "seed 000 eqs 15-16 on |f|")
STEPS.register("threshold", "estimators.steps_threshold:ThresholdSteps", "naive |f| peak picker")
STEPS.register(
    "nod_robust", "estimators.steps_nod_robust:NodRobustSteps",
    "world-vertical specific force, gated by head rotation",
)  # fmt: skip

#: Hand filters: ``factory(batch_size, fs)`` with fs the Kinect frame rate (Hz).
HAND = Registry("hand", HandStage, "(batch_size, fs)", HAND_CONTRACT)
HAND.register("seed003", "estimators.hand:Seed003Hand", "seed 003 Kalman + median")
HAND.register("one_euro", "estimators.hand_one_euro:OneEuroHand", "One Euro filter on the angles")
HAND.register("raw", "estimators.hand:RawHand", "the unfiltered eq (1)/(2) angles")
HAND.register("adaptive_kalman", "estimators.hand_adaptive:AdaptiveKalmanHand",
              "motion-adaptive Kalman, no median")  # fmt: skip

#: Steering: ``factory(batch_size)``.
STEERING = Registry("steering", SteeringStage, "(batch_size,)", STEERING_CONTRACT)
STEERING.register("head", "estimators.steering:HeadSteering", "walk where the head points")
STEERING.register("torso", "estimators.steering:TorsoSteering", "walk where the torso points")

#: Locomotion: ``factory(batch_size, step_length)`` with step_length in m.
LOCOMOTION = Registry("locomotion", Locomotion, "(batch_size, step_length)", LOCOMOTION_CONTRACT)
LOCOMOTION.register("eq17", "estimators.dead_reckoning:DeadReckoning", "seed 000 eq 17 jumps")
LOCOMOTION.register("smooth", "estimators.locomotion:SmoothLocomotion", "seed 001 smooth filter")
LOCOMOTION.register(
    "cadence_speed", "estimators.locomotion_cadence:CadenceSpeed",
    "speed proportional to the estimated cadence",
)  # fmt: skip


if __name__ == "__main__":  # python -m estimators.stages > docs/protocols.md
    import sys

    from estimators import stages

    sys.stdout.write(stages.protocol_reference())

"""The estimation stages of a hands-free VR headset, as protocols with registries of named
implementations.

A stage is batched over B users and streaming: ``reset(rows=None)`` forgets some users (indices,
a (B,) boolean mask, or None for all), ``update(...)`` consumes the samples of one control step
and returns that step's estimates. Stages know nothing of the environment; the environment
(:mod:`vrloco_env.users`) builds the ones a technique names and composes them::

    head IMU  --gyr, acc, mag-->  attitude       --quat-->  step detector  --steps-->  locomotion
    Kinect    --frames------->  hand pipeline  --hand frames-->  hand filter
                                               --shoulders-->  torso yaw --> steering --> yaw

Every registry holds named implementations and also accepts ``"package.module:attr"``, naming a
user's class or factory; unknown names get a clear error listing the valid ones. What each
factory is called with is fixed per stage (:data:`ATTITUDE` ... :data:`LOCOMOTION` say it).

Protocols (each a :class:`typing.Protocol`, checked structurally):

* :class:`AttitudeStage` — ``update(gyr, acc, mag) -> quat`` (B, N, 4) ``[w, x, y, z]``, sensor
  -> ENU world, after each of the step's N IMU samples. ``mag`` may be None.
* :class:`StepStage` — ``update(acc, gyr, quat) -> GaitChunk``: still/walk per sample, steps
  confirmed per sample and their estimated heel-strike times on the stream's own clock: sample k
  after the stream's last ``reset`` (or the start) is at ``k / fs`` s, so that a user reset
  mid-run gets the numbers a new detector would give. ``quat`` is
  the attitude stage's output for the same samples (a detector may ignore it). An optional
  ``report_delay_s`` gives the longest delay from a heel strike to its report (the step-matching
  window of the benchmark; ``latency`` or 0 if absent).
* :class:`HandStage` — ``update(frames) -> (ypr, valid)``: filters the raw wrist angles of the
  hand pipeline's frames (:class:`estimators.hand.HandFrame` stacked over the step's M Kinect
  frames: ``ypr_raw``, ``quat_valid``, ``reselected``, ...) into (B, M, 3) angles and a (B, M)
  validity.
* :class:`SteeringStage` — ``update(head_yaw, torso_yaw, torso_valid) -> yaw`` (B,): which yaw turns
  the walking direction, from the estimated head yaw and the Kinect's torso yaw (rad, both in
  the virtual room's frame); an optional attribute ``uses_torso = False`` says the torso yaw is
  never read.
* :class:`estimators.locomotion.Locomotion` — ``update(steps, yaw, dt) -> position`` (B, 2).

Optionally, any stage may drop users mid-run: ``take_users(rows)`` keeps the users ``rows``
(distinct indices, in their new order) and forgets the others, each kept user going on as it
would have (:mod:`estimators.batching`; :class:`~estimators.batching.TakesUsers` builds it from
the names of the per-user attributes). The benchmark's batched runner then steps only the users
still playing; with a stage that lacks it, the finished users idle to the batch's end instead.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.locomotion import Locomotion

__all__ = [
    "ATTITUDE",
    "HAND",
    "LOCOMOTION",
    "STEERING",
    "STEPS",
    "AttitudeStage",
    "HandStage",
    "Registry",
    "StageError",
    "SteeringStage",
    "StepStage",
    "check_output",
    "load_attr",
]


class StageError(ValueError):
    """A stage's plug-in could not be built, raised, or returned what the stage does not allow."""


@runtime_checkable
class AttitudeStage(Protocol):
    """Head attitude from IMU samples (B streams)."""

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the users ``rows`` (indices or a (B,) mask; None: all)."""
        ...

    def update(
        self, gyr: NDArray[np.float64], acc: NDArray[np.float64], mag: NDArray[np.float64] | None
    ) -> NDArray[np.float64]:
        """Consume (B, N, 3) gyro (rad/s), accelerometer (m/s^2) and magnetometer (any fixed
        unit, or None) samples; return (B, N, 4) quaternions ``[w, x, y, z]``, sensor -> ENU."""
        ...


@runtime_checkable
class StepStage(Protocol):
    """Still/walk and step events from IMU samples (B streams)."""

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the users ``rows``; their clocks restart at 0."""
        ...

    def update(
        self, acc: NDArray[np.float64], gyr: NDArray[np.float64], quat: NDArray[np.float64]
    ) -> Any:
        """Consume (B, N, 3) specific force and angular rate and the (B, N, 4) attitude
        estimate; return an :class:`estimators.gait.GaitChunk`."""
        ...


@runtime_checkable
class HandStage(Protocol):
    """Filtering of the wrist angles that the hand pipeline extracts from Kinect frames."""

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the users ``rows``."""
        ...

    def update(self, frames: Any) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Filter the (B, M) frames of one step; return (B, M, 3) angles and (B, M) validity."""
        ...


@runtime_checkable
class SteeringStage(Protocol):
    """Which physical yaw turns the walking direction."""

    def reset(self, rows: ArrayLike | None = None) -> None:
        """Forget the users ``rows``."""
        ...

    def update(
        self,
        head_yaw: NDArray[np.float64],
        torso_yaw: NDArray[np.float64],
        torso_valid: NDArray[np.bool_],
    ) -> NDArray[np.float64]:
        """(B,) walking yaw (rad) from the estimated head yaw and the torso yaw (one frame)."""
        ...


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
    """

    def __init__(self, stage: str, protocol: type, signature: str) -> None:
        self.stage = stage
        self.protocol = protocol
        self.signature = signature
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
        """Build ``spec``'s stage with the stage's factory arguments and check its protocol."""
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
        if not isinstance(stage, self.protocol):
            missing = [
                m for m in _protocol_members(self.protocol) if not hasattr(stage, m)
            ]
            raise StageError(
                f"{self.stage} plug-in {label!r} built a {type(stage).__name__}, which lacks "
                f"{', '.join(missing)} of the {self.protocol.__name__} protocol"
            )
        return stage


def _protocol_members(protocol: type) -> Iterable[str]:
    return sorted(getattr(protocol, "__protocol_attrs__", None) or ("reset", "update"))


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


def check_output(
    stage: str, label: str, name: str, value: Any, shape: tuple[int, ...], finite: bool = True
) -> NDArray[np.float64]:
    """``value`` as a float array of ``shape`` (finite if asked), or a :class:`StageError`
    naming the stage, the plug-in and what was expected."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise StageError(
            f"{stage} plug-in {label!r} returned {type(value).__name__} for {name}; expected a "
            f"float array of shape {shape}"
        ) from None
    if arr.shape != shape:
        raise StageError(
            f"{stage} plug-in {label!r} returned {name} of shape {arr.shape}; expected {shape}"
        )
    if finite and not np.isfinite(arr).all():
        raise StageError(f"{stage} plug-in {label!r} returned non-finite {name} (NaN or inf)")
    return arr


# Registries. A target is "module:attr" of a class or factory called with the stage's
# arguments (and returning an object of the stage's protocol); it is imported on first use.

#: Attitude filters: ``factory(batch_size, fs)`` with fs the IMU rate (Hz).
ATTITUDE = Registry("attitude", AttitudeStage, "(batch_size, fs)")
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
STEPS = Registry("steps", StepStage, "(batch_size, fs)")
STEPS.register("seed000", "estimators.gait:Seed000Steps", "seed 000 eqs 15-16 on |f|")
STEPS.register("threshold", "estimators.steps_threshold:ThresholdSteps", "naive |f| peak picker")
STEPS.register(
    "nod_robust", "estimators.steps_nod_robust:NodRobustSteps",
    "world-vertical specific force, gated by head rotation",
)  # fmt: skip

#: Hand filters: ``factory(batch_size, fs)`` with fs the Kinect frame rate (Hz).
HAND = Registry("hand", HandStage, "(batch_size, fs)")
HAND.register("seed003", "estimators.hand:Seed003Hand", "seed 003 Kalman + median")
HAND.register("one_euro", "estimators.hand_one_euro:OneEuroHand", "One Euro filter on the angles")
HAND.register("raw", "estimators.hand:RawHand", "the unfiltered eq (1)/(2) angles")
HAND.register("adaptive_kalman", "estimators.hand_adaptive:AdaptiveKalmanHand",
              "motion-adaptive Kalman, no median")  # fmt: skip

#: Steering: ``factory(batch_size)``.
STEERING = Registry("steering", SteeringStage, "(batch_size,)")
STEERING.register("head", "estimators.steering:HeadSteering", "walk where the head points")
STEERING.register("torso", "estimators.steering:TorsoSteering", "walk where the torso points")

#: Locomotion: ``factory(batch_size, step_length)`` with step_length in m.
LOCOMOTION = Registry("locomotion", Locomotion, "(batch_size, step_length)")
LOCOMOTION.register("eq17", "estimators.dead_reckoning:DeadReckoning", "seed 000 eq 17 jumps")
LOCOMOTION.register("smooth", "estimators.locomotion:SmoothLocomotion", "seed 001 smooth filter")
LOCOMOTION.register(
    "cadence_speed", "estimators.locomotion_cadence:CadenceSpeed",
    "speed proportional to the estimated cadence",
)  # fmt: skip

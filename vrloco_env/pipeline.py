"""The estimation stages of B simulated users, built from an :class:`EstimatorConfig`.

:func:`build_stages` resolves each stage of the configuration in its registry
(:mod:`estimators.stages`) and builds it for the batch; :class:`SimulatedUsers
<vrloco_env.users.SimulatedUsers>` receives the result and only composes the stages. A stage
that comes from outside the package (a ``"module:attr"`` string, a class or an object with a
``build`` method that is not one of ours) is wrapped once in an
:class:`estimators.checked.CheckedStage`, which checks every output against its stage's contract
(shape and meaning: unit quaternions, step times on the stream's clock, hand angles in range,
bounded positions; ``docs/protocols.md``) and names the stage, the plug-in, the offending value
and the rule on a failure. The package's own stages are used as built.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from estimators import stages as st
from estimators.checked import CheckedStage
from estimators.registry import Registry
from vrloco_env.config import STAGE_FIELDS, EstimatorConfig

__all__ = ["Stages", "build_stages"]

_OURS = ("estimators.", "vrloco_env.", "agents.")


@dataclass
class Stages:
    """One built stage per field of :data:`~vrloco_env.config.STAGE_FIELDS`, for B users.

    Attributes:
        labels: stage -> the short name of its choice.
        trusted: stage -> whether it is one of the package's own (used as built); the others
            are :class:`~estimators.checked.CheckedStage` proxies of the plug-in.
    """

    attitude: st.AttitudeStage
    steps: st.StepStage
    hand: st.HandStage
    steering: st.SteeringStage
    locomotion: st.Locomotion
    labels: dict[str, str]
    trusted: dict[str, bool]


def _is_ours(spec: Any, registry: Registry) -> bool:
    if isinstance(spec, str):
        return spec in registry
    return type(spec).__module__.startswith(_OURS)


def build_stages(
    estimators: EstimatorConfig, batch_size: int, imu_rate_hz: float, kinect_rate_hz: float
) -> Stages:
    """Build every stage of ``estimators`` for ``batch_size`` users: the attitude and step
    stages at the IMU rate, the hand stage at the Kinect's frame rate, steering, and locomotion
    with the configuration's step length. A plug-in that is not one of the package's own is
    returned inside a :class:`~estimators.checked.CheckedStage`."""
    args = {
        "attitude": (batch_size, imu_rate_hz),
        "steps": (batch_size, imu_rate_hz),
        "hand": (batch_size, kinect_rate_hz),
        "steering": (batch_size,),
        "locomotion": (batch_size, estimators.step_length),
    }
    built: dict[str, Any] = {}
    labels: dict[str, str] = {}
    trusted: dict[str, bool] = {}
    for name in STAGE_FIELDS:
        registry: Registry = getattr(st, name.upper())
        spec = getattr(estimators, name)
        stage = registry.build(spec, *args[name])
        labels[name] = registry.label(spec)
        trusted[name] = _is_ours(spec, registry)
        if not trusted[name]:
            rate = args[name][1] if name in ("attitude", "steps", "hand") else None
            stage = CheckedStage(stage, registry, labels[name], batch_size, rate)
        built[name] = stage
    return Stages(**built, labels=labels, trusted=trusted)

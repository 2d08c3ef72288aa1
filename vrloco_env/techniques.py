"""Techniques: named bundles of a sensor preset and one choice (with parameters) per stage.

A technique is what a study compares: "the consumer IMU with VQF and torso steering" against
"seed 000 as published". ``gym.make(env_id, technique="vqf")`` runs one; ``vrloco benchmark
--techniques seed000,vqf`` compares them; ``vrloco techniques`` lists the registered ones.
Adding one is one :func:`register` call (or a :class:`Technique` passed directly).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

from vrloco_env.config import EstimatorConfig
from vrloco_env.sensors.imu import get_imu_spec

__all__ = ["TECHNIQUES", "Technique", "get_technique", "register"]


@dataclass(frozen=True)
class Technique:
    """A sensor preset plus the estimation stages.

    Attributes:
        name: the technique's name (tables, JSON rows).
        description: one line.
        sensor_preset: the head IMU preset (``"ig500n"``, ``"consumer_mems"``).
        estimators: the stages and their parameters.
    """

    name: str
    description: str
    sensor_preset: str = "ig500n"
    estimators: EstimatorConfig = field(default_factory=EstimatorConfig)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"Technique.name={self.name!r}: must be a non-empty string")
        get_imu_spec(self.sensor_preset)  # raises with the valid names
        if not isinstance(self.estimators, EstimatorConfig):
            raise ValueError(
                f"Technique.estimators must be an EstimatorConfig, got "
                f"{type(self.estimators).__name__}"
            )


TECHNIQUES: dict[str, Technique] = {}


def register(technique: Technique) -> Technique:
    """Add ``technique`` to :data:`TECHNIQUES` under its name (replacing one of that name)."""
    TECHNIQUES[technique.name] = technique
    return technique


def _chain(name: str, description: str, preset: str = "ig500n", **stages: Any) -> None:
    register(Technique(name, description, preset, replace(EstimatorConfig(), **stages)))


_chain("seed000", "seed 000 as published (EKF, |f| steps, head steering, eq 17 jumps)")
_chain("seed000_consumer", "seed 000's chain on a consumer MEMS IMU", preset="consumer_mems")
_chain("paper_literal", "seed 000 with the EKF as printed", attitude="ekf_paper_literal")
_chain("vqf", "VQF attitude (Laidig & Seel) in seed 000's chain", attitude="vqf")
_chain("madgwick", "Madgwick attitude in seed 000's chain", attitude="madgwick")
_chain("mahony", "Mahony attitude in seed 000's chain", attitude="mahony")
_chain("threshold_steps", "a naive |f| peak picker instead of seed 000's detector",
       steps="threshold")  # fmt: skip
_chain("nod_robust", "steps from world-vertical force, gated by head rotation",
       steps="nod_robust")  # fmt: skip
_chain("torso_steering", "walk where the torso points (Kinect shoulders)", steering="torso")
_chain("smooth", "seed 001's smooth locomotion filter instead of eq 17 jumps", locomotion="smooth")
_chain("cadence_speed", "speed proportional to the estimated cadence (GUD-WIP style)",
       locomotion="cadence_speed")  # fmt: skip
_chain("one_euro_hand", "One Euro filter on the hand angles instead of Kalman + median",
       hand="one_euro")  # fmt: skip
_chain("adaptive_kalman_hand", "motion-adaptive Kalman filter on the hand angles, no median",
       hand="adaptive_kalman")  # fmt: skip

#: The technique of an env built without one.
DEFAULT_TECHNIQUE = "seed000"


def get_technique(technique: str | Technique) -> Technique:
    """A registered technique by name, ``"module:attr"`` naming a :class:`Technique`, or the
    technique itself; unknown names get an error listing the registered ones."""
    if isinstance(technique, Technique):
        return technique
    if isinstance(technique, str):
        if technique in TECHNIQUES:
            return TECHNIQUES[technique]
        if ":" in technique:
            from estimators.registry import load_attr

            obj = load_attr(technique, "technique")
            if callable(obj) and not isinstance(obj, Technique):
                obj = obj()
            if isinstance(obj, Technique):
                return obj
            raise ValueError(
                f"technique={technique!r} names a {type(obj).__name__}, not a Technique"
            )
    raise ValueError(
        f"technique={technique!r}: unknown; valid names: {', '.join(TECHNIQUES)}, or "
        "'package.module:attr' naming a Technique"
    )

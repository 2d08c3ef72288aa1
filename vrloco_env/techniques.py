"""Techniques: named bundles of a sensor preset and one choice (with parameters) per stage.

A technique is what a study compares: "the consumer IMU with VQF and torso steering" against
"Zhang, Chen & Gao 2021 as published". ``gym.make(env_id, technique="vqf")`` runs one;
``vrloco benchmark --techniques zhang2021,vqf`` compares them; ``vrloco techniques`` lists the
registered ones. Adding one is one :func:`register` call (or a :class:`Technique` passed directly).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from estimators.registry import Registry
from vrloco_env.config import EstimatorConfig
from vrloco_env.sensors.imu import get_imu_spec

__all__ = ["RENAMED", "TECHNIQUES", "Technique", "canonical_name", "get_technique", "register"]


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


def _loaded_technique(obj: Any, name: str, target: str) -> Technique:
    """The Technique a ``"module:attr"`` names: the object, or what calling it returns."""
    if callable(obj) and not isinstance(obj, Technique):
        obj = obj()
    if isinstance(obj, Technique):
        return obj
    raise ValueError(f"technique={target!r} names a {type(obj).__name__}, not a Technique")


#: The registered techniques, by name; ``"package.module:attr"`` names a plug-in's own.
TECHNIQUES: Registry[Technique] = Registry(
    "technique",
    kind=Technique,
    load=_loaded_technique,
    plugins=True,
    also="'package.module:attr' naming a Technique",
)


def register(technique: Technique) -> Technique:
    """Add ``technique`` to :data:`TECHNIQUES` under its name (replacing one of that name)."""
    return TECHNIQUES.register(technique.name, technique, technique.description)


def _chain(name: str, description: str, preset: str = "ig500n", **stages: Any) -> None:
    register(Technique(name, description, preset, replace(EstimatorConfig(), **stages)))


_chain(
    "zhang2021", "Zhang, Chen & Gao 2021 as published (EKF, |f| steps, head steering, eq 17 jumps)"
)
_chain("zhang2021_consumer", "Zhang 2021's chain on a consumer MEMS IMU", preset="consumer_mems")
_chain("zhang2021_as_printed", "Zhang 2021 with the EKF as printed", attitude="ekf_paper_literal")
_chain("vqf", "VQF attitude (Laidig & Seel) in Zhang 2021's chain", attitude="vqf")
_chain("madgwick", "Madgwick attitude in Zhang 2021's chain", attitude="madgwick")
_chain("mahony", "Mahony attitude in Zhang 2021's chain", attitude="mahony")
_chain(
    "threshold_steps", "a naive |f| peak picker instead of Zhang 2021's detector", steps="threshold"
)
_chain("nod_robust", "steps from world-vertical force, gated by head rotation", steps="nod_robust")
_chain("torso_steering", "walk where the torso points (Kinect shoulders)", steering="torso")
_chain("smooth", "the smooth-locomotion paper's filter instead of eq 17 jumps", locomotion="smooth")
_chain(
    "cadence_speed",
    "speed proportional to the estimated cadence (GUD-WIP style)",
    locomotion="cadence_speed",
)
_chain(
    "one_euro_hand",
    "One Euro filter on the hand angles instead of Kalman + median",
    hand="one_euro",
)
_chain(
    "adaptive_kalman_hand",
    "motion-adaptive Kalman filter on the hand angles, no median",
    hand="adaptive_kalman",
)

_chain(
    "head_tilt",
    "tilt the head forward to walk, no stepping (Tregillus, Al Zayer & Folmer 2017)",
    locomotion="head_tilt",
)
_chain(
    "look_down_to_move",
    "look down to start or stop an auto-walk, no stepping (mobile VR; Tregillus & Folmer 2016)",
    locomotion="look_down_to_move",
)
_chain(
    "lee2018_steps",
    "steps from the headset's tracked height (Lee, Ahn & Hwang 2018 style) in Zhang 2021's chain",
    steps="lee2018",
)
_chain(
    "hand_steering",
    "Zhang 2021's steps, walking where the hand points (Yao 2023's hand estimate steers)",
    steering="hand",
)

#: The technique of an env built without one.
DEFAULT_TECHNIQUE = "zhang2021"


TECHNIQUES.rename("seed000", "zhang2021")
TECHNIQUES.rename("seed000_consumer", "zhang2021_consumer")
TECHNIQUES.rename("paper_literal", "zhang2021_as_printed")

#: Earlier names of techniques -> their names now (read-only). An old name still works for one
#: release, with a :class:`DeprecationWarning`; listings show only the new names.
RENAMED: Mapping[str, str] = TECHNIQUES.renamed


def canonical_name(name: Any) -> Any:
    """``name``, or the current name of a technique it used to name (with a warning)."""
    return TECHNIQUES.canonical(name, stacklevel=4)


def get_technique(technique: str | Technique) -> Technique:
    """A registered technique by name, ``"module:attr"`` naming a :class:`Technique`, or the
    technique itself; unknown names get an error listing the registered ones."""
    return TECHNIQUES.get(technique)

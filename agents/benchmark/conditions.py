"""Conditions of the physical room a benchmark cell runs in: what surrounds the real user.

A technique is what a study compares; a condition is where it is compared. The sensing stages
see the same simulated human in every condition, but the physical room changes what the sensors
read: a steel cabinet beside the play area bends the magnetic field the head IMU's magnetometer
reads (:class:`~vrloco_env.sensors.imu.MagneticDisturbance`), which an attitude filter that trusts
its magnetometer turns into heading error and one that gates it does not.

Registered (:data:`CONDITIONS`; :func:`get_condition` raises naming them):

* ``lab`` — nothing near the play area: the env's default sensors, bit for bit.
* ``beside_metal`` — a steel cabinet at the left edge of the play area: a magnetic dipole 1.3 m
  to the left of the start spot (the 2 m play area's edge is 1 m away) at 1.0 m height, whose
  field is 20 uT at 0.8 m on its axis (about 5 uT at the start spot, a fifth of the horizontal
  geomagnetic field of the default :class:`~vrloco_env.sensors.imu.EarthField`). Ferrous office
  furniture is known to bend the field by that order within a metre (Bachmann et al.,
  "Investigation of the effects of magnetic variations on inertial/magnetic orientation
  sensors", IEEE Robotics & Automation Magazine 14(3), 2007; de Vries et al., "Magnetic
  distortion in motion labs, implications for validating inertial magnetic sensors", Gait &
  Posture 29, 2009); the exact strength and place are an engineering choice, the same dipole
  the sensor benchmark uses, not set to make any technique win or lose.
* ``trolley_passing`` — the same dipole wheeled past: a steel trolley pushed along the line of
  that cabinet (1.3 m to the left of the start spot, 1.0 m high) at 1 m/s, a walking pace, along
  the physical room's x axis from x = -3 m to x = +3 m (the start spot at 0), 2 s to 8 s into the
  episode (most of an Approach walk). Unlike a still object, whose constant bend of north the
  start-of-episode recentring absorbs, it changes the field at the head while the user walks, by
  up to a few uT; the path, speed and timing are an engineering choice made before any run, not
  set to make a technique win or lose.

Adding one is one :func:`register` call.
"""

from __future__ import annotations

from dataclasses import dataclass

from estimators.registry import Registry
from estimators.validation import check_instance, value_repr
from vrloco_env.sensors.imu import MagneticDisturbance

__all__ = ["CONDITIONS", "DEFAULT_CONDITION", "Condition", "get_condition", "register"]


@dataclass(frozen=True)
class Condition:
    """A named physical room around the play area.

    Attributes:
        name: the registry name (tables, JSON rows).
        description: one line.
        magnetic_disturbances: dipoles in the physical room (the env's
            ``SensorConfig.magnetic_disturbances``).
    """

    name: str
    description: str
    magnetic_disturbances: tuple[MagneticDisturbance, ...] = ()

    def __post_init__(self) -> None:
        check_instance(self, "name", str)
        if not self.name:
            raise ValueError("Condition.name='': must be a non-empty string")
        check_instance(self, "magnetic_disturbances", tuple)
        if not all(isinstance(d, MagneticDisturbance) for d in self.magnetic_disturbances):
            raise ValueError(
                f"Condition.magnetic_disturbances={value_repr(self.magnetic_disturbances)}: "
                "must be a tuple of MagneticDisturbance"
            )

    def sensors(self) -> object | None:
        """The env's ``sensors=`` for this condition (a SensorConfig), None where it changes
        nothing (the env's default then applies, and the technique's IMU preset with it)."""
        if not self.magnetic_disturbances:
            return None
        from vrloco_env.config import SensorConfig

        return SensorConfig(magnetic_disturbances=self.magnetic_disturbances)


#: The registered conditions, by name.
CONDITIONS: Registry[Condition] = Registry("condition", kind=Condition)

#: The condition of a cell given none: nothing near the play area.
DEFAULT_CONDITION = "lab"


def register(condition: Condition) -> Condition:
    """Add ``condition`` to :data:`CONDITIONS` under its name (replacing one of that name)."""
    return CONDITIONS.register(condition.name, condition, condition.description)


register(Condition("lab", "nothing near the play area"))
register(
    Condition(
        "beside_metal",
        "a steel cabinet at the play area's left edge (a magnetic dipole, 20 uT at 0.8 m)",
        (MagneticDisturbance.with_field_at((0.0, 1.3, 1.0), field_ut=20.0, distance_m=0.8),),
    )
)


register(
    Condition(
        "trolley_passing",
        "a steel trolley wheeled past the play area's left edge at 1 m/s, 2-8 s into the episode",
        (
            MagneticDisturbance.with_field_at(
                (-3.0, 1.3, 1.0),
                field_ut=20.0,
                distance_m=0.8,
                velocity=(1.0, 0.0, 0.0),
                moving=(2.0, 8.0),
            ),
        ),
    )
)


def get_condition(name: str | Condition, field: str = "condition") -> Condition:
    """The registered condition ``name`` (or the :class:`Condition` itself); unknown names get a
    ValueError naming ``field`` and the registered ones."""
    return CONDITIONS.get(name, field=field)

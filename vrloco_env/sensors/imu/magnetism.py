"""The magnetic field the head IMU's magnetometer reads: the undisturbed geomagnetic field
(:class:`EarthField`) and the dipole fields of metal objects and magnets in the physical room
(:class:`MagneticDisturbance`)."""

from __future__ import annotations

import datetime
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.kernels import record_dtype
from estimators.validation import check_in_range, check_numbers, check_value
from vrloco_env.sensors.imu import _kernel

__all__ = ["MU0_OVER_4PI", "EarthField", "MagneticDisturbance"]

#: mu0 / (4 pi) in T m / A (SI, exact before the 2019 redefinition; 1e-7 to 10 significant digits).
MU0_OVER_4PI = _kernel.MU0_OVER_4PI


@dataclass(frozen=True)
class EarthField:
    """The undisturbed geomagnetic field at the user's place.

    Attributes:
        intensity: total intensity F (uT), > 0. Default 50 uT (mid-latitudes; the WMM gives
            ~25-65 uT over the Earth).
        inclination: dip angle I (deg) in [-90, 90], positive when the field points below the
            horizon (northern hemisphere). Default +60 deg, as at mid-northern latitudes.
        declination: angle D (deg) in [-180, 180] from true north (+y) to magnetic north, positive
            towards east. Default 0 deg (magnetic north = true north), so yaw from the magnetometer
            equals true yaw unless a declination is configured.
    """

    intensity: float = 50.0
    inclination: float = 60.0
    declination: float = 0.0

    def __post_init__(self) -> None:
        check_in_range(self, "intensity", 0.0, math.inf, "uT", lo_open=True)
        check_in_range(self, "inclination", -90.0, 90.0, "deg")
        check_in_range(self, "declination", -180.0, 180.0, "deg")

    def vector_enu(self) -> NDArray[np.float64]:
        """The field vector in the world ENU frame (uT), shape (3,).

        ``m = F [cos I sin D, cos I cos D, -sin I]``: the horizontal part points to magnetic north,
        rotated by D from +y towards +x (east); a positive inclination points the field down (-z).
        """
        inc = math.radians(self.inclination)
        dec = math.radians(self.declination)
        h = self.intensity * math.cos(inc)
        return np.array([h * math.sin(dec), h * math.cos(dec), -self.intensity * math.sin(inc)])

    @classmethod
    def from_wmm(
        cls,
        latitude: float,
        longitude: float,
        height_km: float = 0.0,
        date: datetime.date | float | None = None,
    ) -> EarthField:
        """The World Magnetic Model's field at a place and date (needs the optional ``ahrs``).

        Args:
            latitude: geodetic latitude (deg, north positive), in [-90, 90].
            longitude: longitude (deg, east positive), in [-180, 360].
            height_km: height above the WGS-84 ellipsoid (km).
            date: a ``datetime.date`` or decimal year; default today.

        Returns:
            The field with the WMM's total intensity F (nT -> uT), inclination I and declination D.

        Raises:
            ImportError: ``ahrs`` is not installed (it is in the ``bench`` extra).
            ValueError: latitude or longitude out of range.
        """
        if not -90.0 <= float(latitude) <= 90.0:
            raise ValueError(f"latitude must be in [-90, 90] deg, got {latitude}")
        if not -180.0 <= float(longitude) <= 360.0:
            raise ValueError(f"longitude must be in [-180, 360] deg, got {longitude}")
        try:
            from ahrs.utils import WMM
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError(
                "EarthField.from_wmm needs the 'ahrs' package: pip install 'vrloco[bench]'"
            ) from exc
        if date is None:
            date = datetime.date.today()
        wmm = WMM(
            date=date, latitude=float(latitude), longitude=float(longitude), height=float(height_km)
        )
        return cls(
            intensity=float(wmm.F) * 1e-3, inclination=float(wmm.I), declination=float(wmm.D)
        )


@dataclass(frozen=True)
class MagneticDisturbance:
    """A magnetic dipole in the world: a metal object near the user, still or moving.

    Field at offset ``r = p - position`` (SI, in tesla, returned in uT):
    ``B = mu0/(4 pi) * (3 r (m . r) / |r|^5 - m / |r|^3)``.
    Inside ``min_distance`` (the object's own size) the offset is stretched to ``min_distance`` so
    the field stays finite. A moving object (a steel trolley wheeled past) keeps its moment and
    moves in a straight line at ``velocity`` between the times of ``moving``, counted from the
    user's reset (each user of a batch on its own clock): at ``position`` before, at
    ``position + velocity * (stop - start)`` after (:meth:`position_at`).

    Attributes:
        position: dipole position in the world (m), shape (3,).
        moment: dipole moment in the world (A m^2), shape (3,).
        min_distance: radius below which the field no longer grows (m), > 0.
        velocity: its velocity while it moves (m/s), (3,); 0: it stays at ``position``.
        moving: ``(start, stop)``, the time it moves (s after the reset), 0 <= start <= stop.
    """

    position: tuple[float, float, float]
    moment: tuple[float, float, float]
    min_distance: float = 0.1
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    moving: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        check_numbers(self, "position", -math.inf, math.inf, "m", length=3)
        check_numbers(self, "moment", -math.inf, math.inf, "A m^2", length=3)
        check_numbers(self, "velocity", -math.inf, math.inf, "m/s", length=3)
        check_numbers(self, "moving", 0.0, math.inf, "s", length=2, ordered=True)
        for name in ("position", "moment", "velocity", "moving"):
            object.__setattr__(self, name, tuple(float(x) for x in getattr(self, name)))
        check_in_range(self, "min_distance", 0.0, math.inf, "m", lo_open=True)

    def position_at(self, t: float) -> NDArray[np.float64]:
        """Where the dipole is (m), (3,), at time ``t`` (s after the reset): the IMU kernel's
        own motion (:func:`vrloco_env.sensors.imu._kernel._dipole_offset` of the origin)."""
        check_value("t", t, 0.0, math.inf, "s")
        offset = _kernel._dipole_offset(_dipole_records((self,))[0], 0.0, 0.0, 0.0, float(t))
        return -np.array(offset)

    @classmethod
    def with_field_at(
        cls,
        position: ArrayLike,
        field_ut: float,
        distance_m: float,
        axis: ArrayLike = (0.0, 0.0, 1.0),
        min_distance: float = 0.1,
        velocity: ArrayLike = (0.0, 0.0, 0.0),
        moving: tuple[float, float] = (0.0, 0.0),
    ) -> MagneticDisturbance:
        """A dipole whose field magnitude is ``field_ut`` at ``distance_m`` on its axis.

        On the dipole axis ``|B| = 2 mu0/(4 pi) |m| / r^3``; in the equatorial plane the field is
        half of that, so the given value is the largest field at that distance.

        Args:
            position: dipole position (m), (3,).
            field_ut: field magnitude wanted (uT), > 0.
            distance_m: distance from the dipole (m), > 0.
            axis: direction of the moment (normalised here), (3,).
            min_distance, velocity, moving: see the class.

        Returns:
            The disturbance.
        """
        check_value("field_ut", field_ut, 0.0, math.inf, "uT", lo_open=True)
        check_value("distance_m", distance_m, 0.0, math.inf, "m", lo_open=True)
        axis = np.asarray(axis, dtype=np.float64)
        if axis.shape != (3,) or not np.all(np.isfinite(axis)) or np.linalg.norm(axis) < 1e-12:
            raise ValueError(f"axis must be a finite, non-zero 3-vector, got {axis!r}")
        moment_mag = field_ut * 1e-6 * distance_m**3 / (2.0 * MU0_OVER_4PI)  # A m^2
        moment = moment_mag * axis / np.linalg.norm(axis)
        return cls(
            position=tuple(position),
            moment=tuple(moment),
            min_distance=min_distance,
            velocity=tuple(velocity),
            moving=tuple(moving),
        )

    def field_at(self, points: ArrayLike, t: ArrayLike = 0.0) -> NDArray[np.float64]:
        """Dipole field (uT) at world points (m), shape ``(..., 3)`` -> ``(..., 3)``, with the
        dipole where it is at time ``t`` (s after the reset; a number, or one per point, any
        shape that broadcasts to ``points.shape[:-1]``): the IMU kernel's own field
        (:func:`vrloco_env.sensors.imu._kernel._dipole_field`)."""
        p = np.asarray(points, dtype=np.float64)
        if p.ndim == 0 or p.shape[-1] != 3:
            raise ValueError(f"points must have shape (..., 3), got {p.shape}")
        t = np.asarray(t, dtype=np.float64)
        try:
            times = np.ascontiguousarray(np.broadcast_to(t, p.shape[:-1])).reshape(-1)
        except ValueError:
            raise ValueError(
                f"t of shape {t.shape} does not broadcast to the points' {p.shape[:-1]}"
            ) from None
        if not (np.isfinite(times).all() and (times >= 0.0).all()):
            raise ValueError("t must be finite times >= 0 s (after the reset)")
        flat = np.ascontiguousarray(p.reshape(-1, 3))
        out = np.empty_like(flat)
        _kernel.dipole_kernel(flat.shape[0])(_dipole_records((self,)), flat, times, out)
        return out.reshape(p.shape)


def _dipole_records(disturbances: Sequence[MagneticDisturbance]) -> NDArray:
    """The kernel's dipole records (:data:`vrloco_env.sensors.imu._kernel.DIPOLE`), one per
    disturbance."""
    dip = np.zeros(len(disturbances), record_dtype(_kernel.DIPOLE))
    for i, d in enumerate(disturbances):
        moment = np.asarray(d.moment)
        dip["position"][i] = d.position
        dip["moment"][i] = moment
        dip["direction"][i] = moment / max(np.linalg.norm(moment), 1e-300)  # used at the dipole
        dip["min_distance"][i] = d.min_distance
        dip["velocity"][i] = d.velocity
        dip["t_start"][i], dip["t_stop"][i] = d.moving
    return dip

"""Head-worn IMU sensor model: accelerometer, gyroscope and magnetometer for B users at once.

Measurement model (one sample, body frame = sensor frame, conventions of
:mod:`estimators.rotations`: ENU world, Hamilton ``[w, x, y, z]`` sensor -> world):

* accelerometer: ``f = R^T (a - g) + b_a + n_a`` with ``g = [0, 0, -GRAVITY]``, so a static, level
  IMU reads ``[0, 0, +GRAVITY]``;
* gyroscope: ``y = w + b_g + n_g`` with ``w`` the true body-frame angular rate;
* magnetometer: ``m = S R^T (m_earth + sum_k B_k(p)) + h + b_m + n_m`` with ``S`` the soft-iron
  matrix, ``h`` the hard-iron offset and ``B_k`` the fields of magnetic dipoles (metal objects) at
  the IMU position ``p``;

then each output is quantised to its resolution and clipped at its range (saturation).

Every bias ``b`` is the sum of a turn-on bias (constant, drawn at :meth:`HeadImu.reset`), a
first-order Gauss-Markov process ``x_k = a x_{k-1} + sigma sqrt(1 - a^2) u_k`` with
``a = exp(-dt / tau)`` (stationary standard deviation ``sigma`` = the datasheet's bias stability,
initial state drawn from the stationary distribution) and an optional random walk
``r_k = r_{k-1} + K sqrt(dt) u_k``. The recursions run along the time axis from the carried
state, so a stream sampled in chunks equals the same stream sampled at once, bit for bit.

The whole model runs in one compiled loop per user (:mod:`vrloco_env.sensors._imu_numba`), the
recursions in the order ``scipy.signal.lfilter`` runs them.

White noise follows the discrete-time convention of angle/velocity random walk (IEEE Std 952,
Kalibr's IMU noise model): a noise density ``N`` (unit/sqrt(Hz)) sampled at ``f_s`` gives a
per-sample standard deviation ``N * sqrt(f_s)``. Decision: the same convention is used for the
magnetometer, so its per-sample noise grows with the rate as well; a real magnetometer often has a
fixed per-sample noise set by its measurement time, which the presets' densities are chosen to
match at 100 Hz.

Units: accelerometer m/s^2, gyroscope rad/s, magnetometer microtesla (uT; 1 Gauss = 100 uT),
lengths m, magnetic moments A m^2, rates Hz, angles in the public :class:`EarthField` in degrees.
"""

from __future__ import annotations

import dataclasses
import datetime
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import stream_rows
from estimators.kernels import param_record, record_dtype, state_records
from estimators.rotations import GRAVITY
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors import _imu_numba as _kernel

__all__ = [
    "MAX_RATE_HZ",
    "MU0_OVER_4PI",
    "PRESETS",
    "EarthField",
    "HeadImu",
    "ImuSamples",
    "ImuSpec",
    "MagneticDisturbance",
    "SensorSpec",
    "get_imu_spec",
]

#: mu0 / (4 pi) in T m / A (SI, exact before the 2019 redefinition; 1e-7 to 10 significant digits).
MU0_OVER_4PI = _kernel.MU0_OVER_4PI
#: One milli-g in m/s^2 (standard gravity, :data:`estimators.rotations.GRAVITY`).
_MG = 1e-3 * GRAVITY
#: One degree in rad.
_DEG = math.pi / 180.0
#: One milligauss in uT (1 G = 1e-4 T = 100 uT).
_MGAUSS = 0.1
#: Largest sample rate the model accepts, Hz.
MAX_RATE_HZ = 1000.0
#: Normal draws per sample: white noise, Gauss-Markov drive, random-walk drive, 3 sensors x 3 axes.
_DRAWS_PER_SAMPLE = _kernel.DRAWS_PER_SAMPLE  # 27
#: Normal draws at reset: turn-on biases 9, Gauss-Markov initial states 9, hard iron 3, soft iron 6.
_DRAWS_PER_RESET = 27


def _check_number(
    value: float, name: str, unit: str, *, positive: bool, allow_inf: bool = False
) -> None:
    """Raise a ValueError naming ``name`` unless ``value`` is a real number in the allowed range."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number ({unit}), got {value!r}") from None
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise ValueError(f"{name} must be finite ({unit}), got {value!r}")
    if positive and not v > 0.0:
        raise ValueError(f"{name} must be > 0 {unit}, got {value!r}")
    if not positive and v < 0.0:
        raise ValueError(f"{name} must be >= 0 {unit}, got {value!r}")


@dataclass(frozen=True)
class SensorSpec:
    """Error model of one triaxial sensor (the same numbers on all three axes).

    Attributes:
        label: sensor name used in error messages ("accel", "gyro" or "mag").
        unit: unit of the measured quantity ("m/s^2", "rad/s" or "uT").
        range: saturation level; outputs are clipped to ``[-range, +range]`` (unit).
        noise_density: white-noise density (unit/sqrt(Hz)); per-sample std is
            ``noise_density * sqrt(rate_hz)``.
        bias_stability: 1-sigma of the stationary first-order Gauss-Markov bias (unit).
        bias_tau: correlation time of the Gauss-Markov bias (s), > 0; ``inf`` makes the bias a
            constant drawn at reset with std ``bias_stability``.
        bias_walk: rate-random-walk coefficient of an additional random-walk bias
            (unit/sqrt(s)); the walk starts at 0 at reset. 0 disables it.
        turn_on_bias: 1-sigma of a constant bias drawn per user at reset (unit).
        resolution: quantisation step, one LSB (unit); 0 disables quantisation.
    """

    label: str
    unit: str
    range: float
    noise_density: float
    bias_stability: float
    bias_tau: float
    bias_walk: float = 0.0
    turn_on_bias: float = 0.0
    resolution: float = 0.0

    def __post_init__(self) -> None:
        p = f"{self.label}."
        u = self.unit
        _check_number(self.range, p + "range", u, positive=True)
        _check_number(self.noise_density, p + "noise_density", u + "/sqrt(Hz)", positive=False)
        _check_number(self.bias_stability, p + "bias_stability", u, positive=False)
        _check_number(self.bias_tau, p + "bias_tau", "s", positive=True, allow_inf=True)
        _check_number(self.bias_walk, p + "bias_walk", u + "/sqrt(s)", positive=False)
        _check_number(self.turn_on_bias, p + "turn_on_bias", u, positive=False)
        _check_number(self.resolution, p + "resolution", u, positive=False)
        if self.resolution >= self.range:
            raise ValueError(
                f"{p}resolution must be smaller than {p}range ({self.range} {u}), "
                f"got {self.resolution}"
            )

    def noise_std(self, rate_hz: float) -> float:
        """Per-sample white-noise standard deviation (unit) at ``rate_hz`` (Hz)."""
        return self.noise_density * math.sqrt(rate_hz)

    def noiseless(self, keep_resolution: bool = False) -> SensorSpec:
        """This sensor without noise or bias (range kept; resolution kept only if asked)."""
        return dataclasses.replace(
            self,
            noise_density=0.0,
            bias_stability=0.0,
            bias_walk=0.0,
            turn_on_bias=0.0,
            resolution=self.resolution if keep_resolution else 0.0,
        )


@dataclass(frozen=True)
class ImuSpec:
    """Error model of a 9-axis IMU.

    Attributes:
        name: preset name or a free label.
        accel: accelerometer model, unit m/s^2.
        gyro: gyroscope model, unit rad/s.
        mag: magnetometer model, unit uT.
        hard_iron: 1-sigma per axis of the constant hard-iron offset drawn per user at reset (uT):
            magnetised parts of the headset that move with the sensor.
        soft_iron_scale: 1-sigma of the diagonal deviations of the soft-iron matrix from identity
            (dimensionless; 0.01 = 1 % scale error per axis).
        soft_iron_cross: 1-sigma of the off-diagonal entries of the (symmetric) soft-iron matrix
            (dimensionless; cross-axis coupling and misalignment).
    """

    name: str
    accel: SensorSpec
    gyro: SensorSpec
    mag: SensorSpec
    hard_iron: float = 0.0
    soft_iron_scale: float = 0.0
    soft_iron_cross: float = 0.0

    def __post_init__(self) -> None:
        for attr, label in (("accel", "accel"), ("gyro", "gyro"), ("mag", "mag")):
            s = getattr(self, attr)
            if not isinstance(s, SensorSpec):
                raise ValueError(f"ImuSpec.{attr} must be a SensorSpec, got {type(s).__name__}")
            if s.label != label:
                raise ValueError(f"ImuSpec.{attr}.label must be {label!r}, got {s.label!r}")
        _check_number(self.hard_iron, "hard_iron", "uT", positive=False)
        _check_number(self.soft_iron_scale, "soft_iron_scale", "(dimensionless)", positive=False)
        _check_number(self.soft_iron_cross, "soft_iron_cross", "(dimensionless)", positive=False)
        if self.soft_iron_scale >= 0.2 or self.soft_iron_cross >= 0.2:
            raise ValueError(
                "soft_iron_scale and soft_iron_cross must be < 0.2 (a 1-sigma above 20 % can "
                f"make the soft-iron matrix singular), got {self.soft_iron_scale}, "
                f"{self.soft_iron_cross}"
            )

    def noiseless(self, keep_resolution: bool = False) -> ImuSpec:
        """The same IMU with every noise, bias and iron term zero (ranges kept).

        Args:
            keep_resolution: keep the quantisation steps (default: drop them, so outputs equal the
                analytic values exactly below saturation).

        Returns:
            A new spec named ``<name>-noiseless``.
        """
        return ImuSpec(
            name=f"{self.name}-noiseless",
            accel=self.accel.noiseless(keep_resolution),
            gyro=self.gyro.noiseless(keep_resolution),
            mag=self.mag.noiseless(keep_resolution),
            hard_iron=0.0,
            soft_iron_scale=0.0,
            soft_iron_cross=0.0,
        )


def _lsb(full_scale: float, bits: int = 16) -> float:
    """One LSB of a signed ``bits``-bit converter spanning ``[-full_scale, +full_scale]``."""
    return 2.0 * full_scale / 2**bits


# SBG Systems IG-500N, the sensor of seed 000 (Zhang, Chen, Gao 2021, section 4).
# Ranges and bias stabilities: the paper (accel +-5 g, 4 mg; gyro +-300 deg/s, 0.1 deg/s;
# magnetometer +-1.2 G, 0.5 mG). The paper's "+-" bias stability is taken as the 1-sigma of the
# Gauss-Markov bias, whose initial state is drawn at reset, so each run starts with a bias of that
# spread; turn-on bias is therefore 0 (the unit is factory calibrated).
# Noise densities: SBG's IG-500 series leaflet as we recall it (accel 0.25 mg/sqrt(Hz), gyro
# 0.05 deg/s/sqrt(Hz), magnetometer 0.01 mG/sqrt(Hz)); the datasheet was not at hand, so these are
# best estimates. The magnetometer figure matches the ~27 uG resolution (10 Hz bandwidth) of the
# Honeywell AMR sensors such units used.
# Correlation time 100 s: estimate; MEMS in-run bias instability typically shows its Allan-deviation
# minimum at 10-1000 s.
# Resolution: estimate, a 16-bit converter over the full range.
# Hard/soft iron: estimate of the residual after SBG's magnetic calibration of a head mount.
_IG500N = ImuSpec(
    name="ig500n",
    accel=SensorSpec(
        label="accel",
        unit="m/s^2",
        range=5.0 * GRAVITY,
        noise_density=0.25 * _MG,
        bias_stability=4.0 * _MG,
        bias_tau=100.0,
        turn_on_bias=0.0,
        resolution=_lsb(5.0 * GRAVITY),
    ),
    gyro=SensorSpec(
        label="gyro",
        unit="rad/s",
        range=300.0 * _DEG,
        noise_density=0.05 * _DEG,
        bias_stability=0.1 * _DEG,
        bias_tau=100.0,
        turn_on_bias=0.0,
        resolution=_lsb(300.0 * _DEG),
    ),
    mag=SensorSpec(
        label="mag",
        unit="uT",
        range=1.2 * 100.0,
        noise_density=0.01 * _MGAUSS,
        bias_stability=0.5 * _MGAUSS,
        bias_tau=100.0,
        turn_on_bias=0.0,
        resolution=_lsb(1.2 * 100.0),
    ),
    hard_iron=0.2,
    soft_iron_scale=0.002,
    soft_iron_cross=0.002,
)

# Consumer MEMS: Bosch BMI160 accelerometer/gyroscope (datasheet BST-BMI160-DS000-07) with an
# AKM AK09916 magnetometer (the one inside TDK InvenSense ICM-20948, datasheet DS-000189 rev 1.3).
# Ranges/resolutions: BMI160 at +-8 g (4096 LSB/g) and +-2000 deg/s (16.4 LSB/(deg/s)), the usual
# motion-tracking settings; AK09916 +-4900 uT at 0.15 uT/LSB (ICM-20948 table 3).
# Noise densities: BMI160 typ. 180 ug/sqrt(Hz) and 0.007 deg/s/sqrt(Hz). Note that the modern
# BMI160 gyro has *less* white noise than the 2009-era IG-500N; "noisier" holds for its biases and
# for the magnetometer. AK09916 noise is not in the datasheet: estimate 0.5 uT rms per sample at its
# 100 Hz maximum rate, i.e. 0.05 uT/sqrt(Hz).
# Turn-on biases: BMI160 typ. zero-g offset +-40 mg and zero-rate offset +-3 deg/s, read as 2-sigma
# spreads -> 1-sigma 20 mg and 1.5 deg/s.
# Bias stability: BMI160 temperature drifts (typ. 1 mg/K accel, 0.05 deg/s/K gyro) over a +-5 K
# warm-up/session swing -> 5 mg and 0.25 deg/s; magnetometer 0.5 uT (estimate). Correlation 100 s.
# Hard iron 5 uT per axis (1-sigma): estimate of the residual of a headset's speaker magnets and
# PCB after a factory calibration ("several uT"); soft iron 2 % scale, 1 % cross-axis.
_CONSUMER_MEMS = ImuSpec(
    name="consumer_mems",
    accel=SensorSpec(
        label="accel",
        unit="m/s^2",
        range=8.0 * GRAVITY,
        noise_density=0.180 * _MG,
        bias_stability=5.0 * _MG,
        bias_tau=100.0,
        turn_on_bias=20.0 * _MG,
        resolution=GRAVITY / 4096.0,
    ),
    gyro=SensorSpec(
        label="gyro",
        unit="rad/s",
        range=2000.0 * _DEG,
        noise_density=0.007 * _DEG,
        bias_stability=0.25 * _DEG,
        bias_tau=100.0,
        turn_on_bias=1.5 * _DEG,
        resolution=_DEG / 16.4,
    ),
    mag=SensorSpec(
        label="mag",
        unit="uT",
        range=4900.0,
        noise_density=0.05,
        bias_stability=0.5,
        bias_tau=100.0,
        turn_on_bias=0.0,
        resolution=0.15,
    ),
    hard_iron=5.0,
    soft_iron_scale=0.02,
    soft_iron_cross=0.01,
)

#: Sensor presets by name.
PRESETS: dict[str, ImuSpec] = {"ig500n": _IG500N, "consumer_mems": _CONSUMER_MEMS}


def get_imu_spec(name_or_spec: str | ImuSpec) -> ImuSpec:
    """Return a preset by name, or the given spec unchanged.

    Raises:
        ValueError: unknown preset name (the message lists the valid names).
    """
    if isinstance(name_or_spec, ImuSpec):
        return name_or_spec
    if isinstance(name_or_spec, str) and name_or_spec in PRESETS:
        return PRESETS[name_or_spec]
    raise ValueError(
        f"imu spec must be an ImuSpec or one of {sorted(PRESETS)}, got {name_or_spec!r}"
    )


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
        _check_number(self.intensity, "EarthField.intensity", "uT", positive=True)
        for name, lim in (("inclination", 90.0), ("declination", 180.0)):
            v = getattr(self, name)
            try:
                v = float(v)
            except (TypeError, ValueError):
                raise ValueError(f"EarthField.{name} must be a real number (deg)") from None
            if not (-lim <= v <= lim):  # also rejects NaN
                raise ValueError(f"EarthField.{name} must be in [-{lim}, {lim}] deg, got {v}")

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
    """A magnetic dipole fixed in the world: a metal object near the user's path.

    Field at offset ``r = p - position`` (SI, in tesla, returned in uT):
    ``B = mu0/(4 pi) * (3 r (m . r) / |r|^5 - m / |r|^3)``.
    Inside ``min_distance`` (the object's own size) the offset is stretched to ``min_distance`` so
    the field stays finite.

    Attributes:
        position: dipole position in the world (m), shape (3,).
        moment: dipole moment in the world (A m^2), shape (3,).
        min_distance: radius below which the field no longer grows (m), > 0.
    """

    position: tuple[float, float, float]
    moment: tuple[float, float, float]
    min_distance: float = 0.1

    def __post_init__(self) -> None:
        for name in ("position", "moment"):
            v = np.asarray(getattr(self, name), dtype=np.float64)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                got = getattr(self, name)
                raise ValueError(
                    f"MagneticDisturbance.{name} must be 3 finite numbers, got {got!r}"
                )
            object.__setattr__(self, name, tuple(float(x) for x in v))
        _check_number(self.min_distance, "MagneticDisturbance.min_distance", "m", positive=True)

    @classmethod
    def with_field_at(
        cls,
        position: ArrayLike,
        field_ut: float,
        distance_m: float,
        axis: ArrayLike = (0.0, 0.0, 1.0),
        min_distance: float = 0.1,
    ) -> MagneticDisturbance:
        """A dipole whose field magnitude is ``field_ut`` at ``distance_m`` on its axis.

        On the dipole axis ``|B| = 2 mu0/(4 pi) |m| / r^3``; in the equatorial plane the field is
        half of that, so the given value is the largest field at that distance.

        Args:
            position: dipole position (m), (3,).
            field_ut: field magnitude wanted (uT), > 0.
            distance_m: distance from the dipole (m), > 0.
            axis: direction of the moment (normalised here), (3,).
            min_distance: see the class.

        Returns:
            The disturbance.
        """
        _check_number(field_ut, "field_ut", "uT", positive=True)
        _check_number(distance_m, "distance_m", "m", positive=True)
        axis = np.asarray(axis, dtype=np.float64)
        if axis.shape != (3,) or not np.all(np.isfinite(axis)) or np.linalg.norm(axis) < 1e-12:
            raise ValueError(f"axis must be a finite, non-zero 3-vector, got {axis!r}")
        moment_mag = field_ut * 1e-6 * distance_m**3 / (2.0 * MU0_OVER_4PI)  # A m^2
        moment = moment_mag * axis / np.linalg.norm(axis)
        return cls(position=tuple(position), moment=tuple(moment), min_distance=min_distance)

    def field_at(self, points: ArrayLike) -> NDArray[np.float64]:
        """Dipole field (uT) at world points (m), shape ``(..., 3)`` -> ``(..., 3)``: the IMU
        kernel's own field (:func:`vrloco_env.sensors._imu_numba._dipole_field`)."""
        p = np.asarray(points, dtype=np.float64)
        if p.ndim == 0 or p.shape[-1] != 3:
            raise ValueError(f"points must have shape (..., 3), got {p.shape}")
        flat = np.ascontiguousarray(p.reshape(-1, 3))
        out = np.empty_like(flat)
        _kernel.dipole_kernel(flat.shape[0])(_dipole_records((self,)), flat, out)
        return out.reshape(p.shape)


def _dipole_records(disturbances: Sequence[MagneticDisturbance]) -> NDArray:
    """The kernel's dipole records (:data:`vrloco_env.sensors._imu_numba.DIPOLE`), one per
    disturbance."""
    dip = np.zeros(len(disturbances), record_dtype(_kernel.DIPOLE))
    for i, d in enumerate(disturbances):
        moment = np.asarray(d.moment)
        dip["position"][i] = d.position
        dip["moment"][i] = moment
        dip["direction"][i] = moment / max(np.linalg.norm(moment), 1e-300)  # used at the dipole
        dip["min_distance"][i] = d.min_distance
    return dip


class ImuSamples(NamedTuple):
    """IMU outputs (or per-sample biases) of B users over N samples, each ``(B, N, 3)`` float64.

    Attributes:
        acc: specific force (m/s^2), body frame.
        gyr: angular rate (rad/s), body frame.
        mag: magnetic field (uT), body frame.
    """

    acc: NDArray[np.float64]
    gyr: NDArray[np.float64]
    mag: NDArray[np.float64]


def _batch_shaped(x: ArrayLike, name: str, b: int, last: int, n: int) -> NDArray[np.float64]:
    """``x`` as a C-contiguous float64 array of shape (b, n, last), or a ValueError naming it.

    Only the shape is checked here; the values are checked in one compiled pass
    (:func:`vrloco_env.sensors._imu_numba.first_invalid`).
    """
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 3 or a.shape[0] != b or a.shape[1] != n or a.shape[2] != last:
        raise ValueError(
            f"{name} must have shape ({b}, {n}, {last}) (B users, N samples), got {a.shape}"
        )
    return _kernel_layout(a)


#: SensorSpec fields the kernel does not read: it reads ``range`` and ``resolution`` and the
#: values :func:`_sensor_record` derives from the others.
_SENSOR_UNREAD = ("noise_density", "bias_stability", "bias_tau", "bias_walk", "turn_on_bias")


def _sensor_record(sens: SensorSpec, dt: float, rate_hz: float) -> NDArray:
    """The kernel's (1,) parameter record of one sensor sampled every ``dt`` s (at ``rate_hz``):
    its ``range`` and ``resolution``, the Gauss-Markov pole ``a = exp(-dt / tau)`` and drive std
    ``sigma sqrt(1 - a^2)``, the random-walk drive std ``K sqrt(dt)`` and the white-noise std per
    sample (unit of the sensor)."""
    a = math.exp(-dt / sens.bias_tau)
    return param_record(
        sens,
        exclude=_SENSOR_UNREAD,
        pole=a,
        gm_std=sens.bias_stability * math.sqrt(max(0.0, 1.0 - a * a)),
        rw_std=sens.bias_walk * math.sqrt(dt),
        noise_std=sens.noise_std(rate_hz),
    )


def _kernel_layout(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a`` itself when C-contiguous and writeable, else a copy that is: the one array type the
    kernels are compiled for (numba types strided and read-only arrays apart, each a compilation).
    """
    if a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.array(a, dtype=np.float64, order="C")


#: Stand-in for ``pos`` when none is given (the kernel reads positions only with disturbances).
#: Left writeable: numba types a read-only array apart, which would compile the kernel twice.
_NO_POS = np.zeros((0, 0, 3))

#: Messages of the kernel's input check, by its return code.
_INVALID = {
    _kernel.BAD_QUAT: "quat contains NaN or infinite entries",
    _kernel.ZERO_QUAT: "quat contains a zero-norm quaternion; a rotation needs |q| > 0",
    _kernel.BAD_OMEGA: "omega contains NaN or infinite entries",
    _kernel.BAD_ACC: "acc_world contains NaN or infinite entries",
    _kernel.BAD_POS: "pos contains NaN or infinite entries",
}


class HeadImu:
    """A head-worn 9-axis IMU for B users, streaming: biases carry over between calls.

    Args:
        spec: an :class:`ImuSpec` or a preset name (see :data:`PRESETS`).
        rng: one random stream per user; B = ``rng.batch_size``. The IMU draws nothing else from
            it than what :meth:`reset` and :meth:`sample` need, in a fixed order, so a batch
            reproduces B single-user runs bit for bit.
        rate_hz: sample rate (Hz) in (0, 1000]; default 100 Hz.
        field: the undisturbed geomagnetic field.
        disturbances: magnetic dipoles in the world (metal obstacles).

    Attributes:
        samples_taken: (B,) int64, samples synthesised per user since that user's last
            :meth:`reset`.
        last_bias: per-sample total additive biases of the last :meth:`sample` call
            (:class:`ImuSamples`, each (B, N, 3); the magnetometer's includes hard iron), or None
            after a reset of all users. A reset of some users leaves it as it was (it describes
            that call's samples; :attr:`bias` gives the current biases).

    The constructor calls :meth:`reset` for all users. ``reset(users=...)`` redraws only the given
    users, from their own streams, so one user of a batch can start a new episode while the others
    carry on.
    """

    def __init__(
        self,
        spec: str | ImuSpec,
        rng: BatchRng,
        rate_hz: float = 100.0,
        field: EarthField | None = None,
        disturbances: Sequence[MagneticDisturbance] = (),
    ) -> None:
        self.spec = get_imu_spec(spec)
        if not isinstance(rng, BatchRng):
            raise ValueError(
                f"rng must be a vrloco_env.batch_rng.BatchRng, got {type(rng).__name__}"
            )
        try:
            rate = float(rate_hz)
        except (TypeError, ValueError):
            raise ValueError(f"rate_hz must be a number in (0, {MAX_RATE_HZ:g}] Hz") from None
        if not (0.0 < rate <= MAX_RATE_HZ):
            raise ValueError(f"rate_hz must be in (0, {MAX_RATE_HZ:g}] Hz, got {rate_hz!r}")
        field = EarthField() if field is None else field
        if not isinstance(field, EarthField):
            raise ValueError(f"field must be an EarthField, got {type(field).__name__}")
        disturbances = tuple(disturbances)
        for i, d in enumerate(disturbances):
            if not isinstance(d, MagneticDisturbance):
                raise ValueError(
                    f"disturbances[{i}] must be a MagneticDisturbance, got {type(d).__name__}"
                )
        self.rng = rng
        self.rate_hz = rate
        self.dt = 1.0 / rate
        self.field = field
        self.disturbances = disturbances
        self._field_world = field.vector_enu()
        # The kernel's parameter records (vrloco_env.sensors._imu_numba), built once here.
        self._sensors = np.concatenate([
            _sensor_record(sens, self.dt, rate)
            for sens in (self.spec.accel, self.spec.gyro, self.spec.mag)
        ])  # fmt: skip
        east, north, up = self._field_world
        self._earth = param_record(east=east, north=north, up=up)
        self._dipoles = _dipole_records(disturbances)
        self.reset()

    @property
    def batch_size(self) -> int:
        """B, the number of users."""
        return self.rng.batch_size

    @property
    def gravity_world(self) -> NDArray[np.float64]:
        """The gravity vector the model uses, ``[0, 0, -GRAVITY]`` (m/s^2), (3,)."""
        return np.array([0.0, 0.0, -GRAVITY])

    @property
    def field_world(self) -> NDArray[np.float64]:
        """The undisturbed reference field in ENU (uT), (3,): what an estimator may assume."""
        return self._field_world.copy()

    def reset(self, users: ArrayLike | None = None) -> None:
        """Draw turn-on biases, hard/soft iron and initial bias states for some or all users.

        Each reset user draws one block of 27 normals from its own stream (turn-on biases 9,
        Gauss-Markov initial states 9, hard iron 3, soft iron 6); its random walks restart at 0
        and its :attr:`samples_taken` at 0. The other users' state and streams are untouched, so
        after ``rng.reseed(i, g)`` and ``reset(users=[i])`` user i continues exactly as a fresh
        single-user ``HeadImu`` on ``BatchRng([g])`` would (a vector env's autoreset).

        Args:
            users: the users to reset, as indices or a (B,) boolean mask; None resets all.

        Raises:
            ValueError: an index outside [0, B), a repeated index or a mask of the wrong shape.
        """
        b = self.batch_size
        rows = stream_rows(users, b)
        if users is None or not hasattr(self, "_state"):  # first call: allocate every user
            self._state = state_records(_kernel.STATE, b)
            self._state["soft_iron"] = np.eye(3)
            self.samples_taken = np.zeros(b, dtype=np.int64)
            self.last_bias: ImuSamples | None = None
        r = rows.size
        spec = self.spec
        st = self._state
        z = self.rng.normal((_DRAWS_PER_RESET,), rows=rows)  # (r, 27)
        sensors = (spec.accel, spec.gyro, spec.mag)
        turn_on = z[:, 0:9].reshape(r, 3, 3)
        gm0 = z[:, 9:18].reshape(r, 3, 3)
        st["turn_on"][rows] = np.stack(
            [turn_on[:, i] * s.turn_on_bias for i, s in enumerate(sensors)], 1
        )
        st["gm"][rows] = np.stack([gm0[:, i] * s.bias_stability for i, s in enumerate(sensors)], 1)
        st["rw"][rows] = 0.0
        st["hard_iron"][rows] = z[:, 18:21] * spec.hard_iron
        diag = z[:, 21:24] * spec.soft_iron_scale
        off = z[:, 24:27] * spec.soft_iron_cross
        s = np.zeros((r, 3, 3))
        s[:, 0, 0] = 1.0 + diag[:, 0]
        s[:, 1, 1] = 1.0 + diag[:, 1]
        s[:, 2, 2] = 1.0 + diag[:, 2]
        s[:, 0, 1] = s[:, 1, 0] = off[:, 0]
        s[:, 0, 2] = s[:, 2, 0] = off[:, 1]
        s[:, 1, 2] = s[:, 2, 1] = off[:, 2]
        st["soft_iron"][rows] = s
        self.samples_taken[rows] = 0

    @property
    def bias(self) -> ImuSamples:
        """Current total additive bias per user, each (B, 3): turn-on + Gauss-Markov + walk.

        For the magnetometer this includes the hard-iron offset (uT); the soft-iron matrix is
        multiplicative and lives in :attr:`soft_iron`. After :meth:`sample` these are the biases of
        its last sample.
        """
        st = self._state
        tot = st["turn_on"] + st["gm"] + st["rw"]
        return ImuSamples(tot[:, 0].copy(), tot[:, 1].copy(), tot[:, 2] + st["hard_iron"])

    @property
    def hard_iron(self) -> NDArray[np.float64]:
        """Hard-iron offset per user (uT), (B, 3)."""
        return self._state["hard_iron"].copy()

    @property
    def soft_iron(self) -> NDArray[np.float64]:
        """Soft-iron matrix per user (dimensionless), (B, 3, 3), applied to the body-frame field."""
        return self._state["soft_iron"].copy()

    def true_field_world(
        self, pos: ArrayLike | None, shape: tuple[int, int]
    ) -> NDArray[np.float64]:
        """True world-frame field (uT) at the IMU: earth field plus every dipole's field.

        Args:
            pos: IMU positions in the world (m), (B, N, 3); may be None without disturbances.
            shape: (B, N).

        Returns:
            (B, N, 3) field in ENU (uT).
        """
        m = np.broadcast_to(self._field_world, (*shape, 3)).copy()
        for d in self.disturbances:  # a handful of objects, not a batch or time loop
            m = m + d.field_at(pos)
        return m

    def sample(
        self,
        quat: ArrayLike,
        omega: ArrayLike,
        acc_world: ArrayLike,
        pos: ArrayLike | None = None,
    ) -> ImuSamples:
        """Synthesize N successive samples for each of the B users.

        One call of :data:`vrloco_env.sensors._imu_numba.sample_kernel` after the input checks.

        Args:
            quat: true sensor -> world orientations, (B, N, 4) Hamilton [w, x, y, z] (normalised
                here; must be finite and non-zero).
            omega: true body-frame angular rates (rad/s), (B, N, 3).
            acc_world: true linear acceleration of the sensor in the world (m/s^2), gravity NOT
                included, (B, N, 3).
            pos: sensor positions in the world (m), (B, N, 3); required only with disturbances.

        Returns:
            :class:`ImuSamples` with acc (m/s^2), gyr (rad/s), mag (uT), each (B, N, 3) float64.
            The per-sample total biases are kept in :attr:`last_bias`.

        Raises:
            ValueError: a wrong shape, a non-finite entry, a zero quaternion, or ``pos`` missing
                with disturbances. Nothing is drawn and no state changes when it raises.
        """
        b = self.batch_size
        q = np.asarray(quat, dtype=np.float64)
        if q.ndim != 3 or q.shape[0] != b or q.shape[2] != 4:
            raise ValueError(
                f"quat must have shape ({b}, N, 4) (B users, N samples), got {q.shape}"
            )
        q = _kernel_layout(q)
        n = q.shape[1]
        w = _batch_shaped(omega, "omega", b, 3, n)
        a = _batch_shaped(acc_world, "acc_world", b, 3, n)
        if pos is not None:
            p = _batch_shaped(pos, "pos", b, 3, n)
        elif self.disturbances:
            raise ValueError("pos (B, N, 3) in m is required when magnetic disturbances are set")
        else:
            p = _NO_POS
        code = _kernel.first_invalid(q, w, a, p)
        if code != _kernel.OK:
            raise ValueError(_INVALID[code])

        z = self.rng.normal((n, _DRAWS_PER_SAMPLE))  # (B, N, 27), time-major: streams chunk-safe
        out = np.empty((6, b, n, 3))
        _kernel.sample_kernel(b)(
            q, w, a, p, z, self._sensors, self._earth, self._dipoles, self._state, out
        )
        self.samples_taken += n  # every user advances by the same N samples
        self.last_bias = ImuSamples(out[3], out[4], out[5])
        return ImuSamples(out[0], out[1], out[2])

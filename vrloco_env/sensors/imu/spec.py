"""IMU specifications: one triaxial sensor's error model (:class:`SensorSpec`), a head IMU's three
sensors (:class:`ImuSpec`) and the presets (:data:`PRESETS`, :func:`get_imu_spec`), from
datasheets (units and the noise convention: :mod:`vrloco_env.sensors.imu`)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from estimators.registry import Registry
from estimators.rotations import GRAVITY
from estimators.validation import check_in_range, check_instance, check_value

__all__ = ["MAX_RATE_HZ", "PRESETS", "ImuSpec", "SensorSpec", "get_imu_spec"]

#: One milli-g in m/s^2 (standard gravity, :data:`estimators.rotations.GRAVITY`).
_MG = 1e-3 * GRAVITY
#: One degree in rad.
_DEG = math.pi / 180.0
#: One milligauss in uT (1 G = 1e-4 T = 100 uT).
_MGAUSS = 0.1
#: Largest sample rate the model accepts, Hz.
MAX_RATE_HZ = 1000.0


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
        p = f"SensorSpec({self.label})."
        u = self.unit
        inf = math.inf
        check_value(p + "range", self.range, 0.0, inf, u, lo_open=True)
        check_value(p + "noise_density", self.noise_density, 0.0, inf, u + "/sqrt(Hz)")
        check_value(p + "bias_stability", self.bias_stability, 0.0, inf, u)
        check_value(p + "bias_tau", self.bias_tau, 0.0, inf, "s", lo_open=True, allow_inf=True)
        check_value(p + "bias_walk", self.bias_walk, 0.0, inf, u + "/sqrt(s)")
        check_value(p + "turn_on_bias", self.turn_on_bias, 0.0, inf, u)
        check_value(
            p + "resolution",
            self.resolution,
            0.0,
            self.range,
            hi_open=True,
            allowed=f"in [0, range={float(self.range):g}) {u}",
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
        for attr in ("accel", "gyro", "mag"):
            check_instance(self, attr, SensorSpec)
            s = getattr(self, attr)
            if s.label != attr:
                raise ValueError(f"ImuSpec.{attr}.label={s.label!r}: must be {attr!r}")
        check_in_range(self, "hard_iron", 0.0, math.inf, "uT")
        for name in ("soft_iron_scale", "soft_iron_cross"):
            check_in_range(
                self,
                name,
                0.0,
                0.2,
                hi_open=True,
                allowed="in [0, 0.2) (dimensionless; a 1-sigma of 20 % or more can make "
                "the soft-iron matrix singular)",
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


# SBG Systems IG-500N, the sensor of Zhang, Chen & Gao 2021 (section 4).
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
PRESETS: Registry[ImuSpec] = Registry("imu", kind=ImuSpec, also="an ImuSpec")
PRESETS.register("ig500n", _IG500N, "Zhang 2021's SBG IG-500N")
PRESETS.register(
    "consumer_mems",
    _CONSUMER_MEMS,
    "a consumer MEMS IMU: Bosch BMI160 accelerometer and gyroscope, AKM AK09916 magnetometer",
)


def get_imu_spec(name_or_spec: str | ImuSpec) -> ImuSpec:
    """Return a preset by name, or the given spec unchanged.

    Raises:
        ValueError: unknown preset name (the message lists the valid names).
    """
    return PRESETS.get(name_or_spec)

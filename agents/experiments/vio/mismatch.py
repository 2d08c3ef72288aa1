"""The model mismatch of the helmet-tracking paper's experiment: what to draw (:class:`Mismatch`)
and one run's draw, the truth the simulator uses beside the nominal values the estimators get
(:class:`Setup`, :func:`make_setup`); the package docstring (:mod:`agents.experiments.vio`) gives
the evidence behind each default.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from agents.experiments.vio.settings import IMU_PRESET, IMU_RATE_HZ
from estimators.validation import check_in_range
from vrloco_env.sensors.camera import CameraSpec, camera_spec, layout_landmarks
from vrloco_env.sensors.imu import ImuSpec, get_imu_spec
from vrloco_env.tasks import make_layout
from vrloco_env.world import RoomConfig

__all__ = ["Mismatch", "Setup", "make_setup"]


@dataclass(frozen=True)
class Mismatch:
    """How far the simulated sensors and room are from what the estimators are told (1-sigma of
    the per-run draws unless stated; package docstring for the evidence behind each default).

    Attributes:
        gyro_scale: scale-factor error per gyro axis, dimensionless, in [0, 0.05].
        gyro_misalignment_deg: each off-diagonal entry of the gyro's axis error matrix (axis
            misalignment and non-orthogonality), deg, in [0, 2].
        accel_scale: scale-factor error per accelerometer axis, in [0, 0.05].
        accel_misalignment_deg: the accelerometer's off-diagonal entries, deg, in [0, 2].
        noise_scatter: log-normal sigma of the unit's white-noise densities and bias
            instabilities around the datasheet values the filter is given, in [0, 1].
        time_offset_s: how much later than its IMU trigger stamp a frame is exposed (constant,
            not drawn), s, in [0, 0.05].
        landmark_sigma_m: survey error of each landmark of the map the PnP uses, per axis, m,
            in [0, 0.1].
        focal_sigma: relative error of fx and fy (each drawn) in the intrinsics the PnP uses,
            in [0, 0.05].
        principal_sigma_px: error of cx and cy in the intrinsics the PnP uses, px, in [0, 20].
    """

    gyro_scale: float = 0.003
    gyro_misalignment_deg: float = 0.1
    accel_scale: float = 0.003
    accel_misalignment_deg: float = 0.1
    noise_scatter: float = 0.2
    time_offset_s: float = 0.005
    landmark_sigma_m: float = 0.005
    focal_sigma: float = 0.002
    principal_sigma_px: float = 1.0

    def __post_init__(self) -> None:
        for name, hi, unit in (
            ("gyro_scale", 0.05, ""),
            ("gyro_misalignment_deg", 2.0, "deg"),
            ("accel_scale", 0.05, ""),
            ("accel_misalignment_deg", 2.0, "deg"),
            ("noise_scatter", 1.0, ""),
            ("time_offset_s", 0.05, "s"),
            ("landmark_sigma_m", 0.1, "m"),
            ("focal_sigma", 0.05, ""),
            ("principal_sigma_px", 20.0, "px"),
        ):
            check_in_range(self, name, 0.0, hi, unit)

    @classmethod
    def none(cls) -> Mismatch:
        """No mismatch: the estimators are told the simulator's truth (for comparison)."""
        return cls(**{f.name: 0.0 for f in dataclasses.fields(cls)})


@dataclass(frozen=True)
class Setup:
    """One run's draw of the mismatch: the truth the simulator uses beside the nominal values.

    Attributes:
        mismatch: what was drawn from.
        gyro_matrix, accel_matrix: (3, 3) ``I + error``: the unit outputs ``matrix @ reading``.
        imu_spec: the unit's true error model (the datasheet's with the drawn noise scatter).
        offset_samples: the time offset in IMU samples (rounded).
        landmarks: (K, 3) true landmark positions (the room's), m; normals: (K, 3) inward.
        map_landmarks: (K, 3) the surveyed map the PnP uses, m.
        intrinsics_error: (dfx, dfy, dcx, dcy): true minus nominal, px.
    """

    mismatch: Mismatch
    gyro_matrix: NDArray[np.float64]
    accel_matrix: NDArray[np.float64]
    imu_spec: ImuSpec
    offset_samples: int
    landmarks: NDArray[np.float64]
    normals: NDArray[np.float64]
    map_landmarks: NDArray[np.float64]
    intrinsics_error: tuple[float, float, float, float]

    def true_camera(self, nominal: CameraSpec) -> CameraSpec:
        """The camera that takes the images: ``nominal`` with the drawn intrinsics error."""
        dfx, dfy, dcx, dcy = self.intrinsics_error
        return nominal.with_(
            fx=nominal.fx + dfx, fy=nominal.fy + dfy, cx=nominal.cx + dcx, cy=nominal.cy + dcy
        )

    def summary(self) -> dict:
        """The drawn values, for the result's JSON (scale factors, misalignments in deg)."""
        out = {
            "mismatch": dataclasses.asdict(self.mismatch),
            "offset_samples": self.offset_samples,
            "map_error_rms_m": float(
                np.sqrt(np.mean(np.sum((self.map_landmarks - self.landmarks) ** 2, axis=1)))
            ),
            "intrinsics_error_px": list(self.intrinsics_error),
        }
        nominal = get_imu_spec(IMU_PRESET)
        for name, m in (("gyro", self.gyro_matrix), ("accel", self.accel_matrix)):
            off = m - np.diag(np.diag(m))
            out[f"{name}_scale"] = (np.diag(m) - 1.0).tolist()
            out[f"{name}_misalignment_deg"] = np.rad2deg(off[off != 0.0]).tolist()
            true_s, nom_s = getattr(self.imu_spec, name), getattr(nominal, name)
            out[f"{name}_noise_factor"] = true_s.noise_density / nom_s.noise_density
            out[f"{name}_bias_factor"] = true_s.bias_stability / nom_s.bias_stability
        return out


def _error_matrix(rng: np.random.Generator, scale: float, misalign_deg: float) -> NDArray:
    m = np.eye(3) + np.diag(rng.normal(0.0, 1.0, 3) * scale)
    off = rng.normal(0.0, 1.0, (3, 3)) * math.radians(misalign_deg)
    return m + off - np.diag(np.diag(off))


def make_setup(seed: int, mismatch: Mismatch | None = None) -> Setup:
    """Draw one run's mismatch (its own random stream of ``seed``) in the experiment's room.

    Args:
        seed: the run's seed.
        mismatch: what to draw; None: the defaults (:class:`Mismatch`).
    """
    mm = Mismatch() if mismatch is None else mismatch
    if not isinstance(mm, Mismatch):
        raise ValueError(f"mismatch must be a Mismatch or None, got {type(mm).__name__}")
    rng = np.random.default_rng([seed, 7])
    gyro = _error_matrix(rng, mm.gyro_scale, mm.gyro_misalignment_deg)
    accel = _error_matrix(rng, mm.accel_scale, mm.accel_misalignment_deg)
    f = np.exp(rng.normal(0.0, 1.0, 4) * mm.noise_scatter)
    nominal = get_imu_spec(IMU_PRESET)
    spec = dataclasses.replace(
        nominal,
        accel=dataclasses.replace(
            nominal.accel,
            noise_density=nominal.accel.noise_density * f[0],
            bias_stability=nominal.accel.bias_stability * f[2],
        ),
        gyro=dataclasses.replace(
            nominal.gyro,
            noise_density=nominal.gyro.noise_density * f[1],
            bias_stability=nominal.gyro.bias_stability * f[3],
        ),
    )
    layout = make_layout("approach", RoomConfig(), np.random.default_rng(seed)).with_origin((0, 0))
    lm, nrm = layout_landmarks(layout)
    survey = rng.normal(0.0, 1.0, lm.shape) * mm.landmark_sigma_m
    cam = camera_spec("ideal")
    dfx, dfy = rng.normal(0.0, 1.0, 2) * mm.focal_sigma * np.array([cam.fx, cam.fy])
    dcx, dcy = rng.normal(0.0, 1.0, 2) * mm.principal_sigma_px
    return Setup(
        mismatch=mm,
        gyro_matrix=gyro,
        accel_matrix=accel,
        imu_spec=spec,
        offset_samples=round(mm.time_offset_s * IMU_RATE_HZ),
        landmarks=lm,
        normals=nrm,
        map_landmarks=lm + survey,
        intrinsics_error=(float(dfx), float(dfy), float(dcx), float(dcy)),
    )

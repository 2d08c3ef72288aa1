"""Madgwick's gradient-descent attitude filter (IMU and MARG); attitude output sensor -> ENU.

Sources: S. O. H. Madgwick, "An efficient orientation filter for inertial and inertial/magnetic
sensor arrays", report, University of Bristol, 2010; S. O. H. Madgwick, A. J. L. Harrison,
R. Vaidyanathan, "Estimation of IMU and MARG orientation using a gradient descent algorithm",
IEEE ICORR 2011.

Per sample, with ``q`` the attitude (sensor -> world), ``w`` the gyro reading (rad/s), ``a`` and
``m`` the normalised accelerometer and magnetometer readings:

1. Rate of change from the gyro: ``qdot = 0.5 q ⊗ [0, w]``.
2. One normalised gradient-descent step on the misfit of the predicted directions of the
   references: for a world reference ``d`` and its sensor reading ``s``, ``f(q) = R(q)^T d - s``
   and its Jacobian ``J = df/dq`` (the report's general objective function and Jacobian for an
   arbitrary ``d``); ``grad = sum J^T f`` over gravity ``d = [0, 0, 1]`` and, in MARG mode, the
   field ``d = b``; ``qdot -= beta grad / |grad|``.
3. Magnetic reference (the report's magnetic distortion compensation): the field rotated into
   the world, ``h = R(q) m``, with its horizontal part put on north: ``b = [|h_xy|, 0, h_z]``.
4. Integration: ``q <- normalise(q + qdot dt)``.

World frames. Madgwick's world has north on +x and up on +z (north-west-up, NWU), as in step 3. The
filter runs in that frame, exactly as published, and its attitude is turned into this project's ENU
world on output: ``q_ENU = r ⊗ q_NWU`` with ``r`` the +90 deg rotation about the vertical (it takes
north, NWU +x, onto ENU +y); a state given in ENU (the start, below) enters as ``conj(r) ⊗ q_ENU``.
Running the same steps in ENU with ``b = [0, |h_xy|, h_z]`` would not be exactly the same filter:
Madgwick's objective function uses ``1 - 2 y^2 - 2 z^2``-type diagonal terms, equal to the rotation
matrix only on unit quaternions, so its gradient is not equivariant under a change of world heading
(on random noisy samples the two versions differ by 1e-5 after ten samples and by 1e-2 after 2000).
``tests/test_estimators/attitude/test_attitude_stages.py`` checks this filter against
``ahrs.filters.Madgwick`` (which uses the NWU world) to 1e-9.

The gain ``beta`` is ``sqrt(3/4)`` times the gyro measurement error (rad/s); the report's
experiments found 0.033 rad/s (IMU) and 0.041 rad/s (MARG) best. These are this module's
defaults (and those of ``ahrs.filters.Madgwick``); they are not tuned on any data of this project.
The report's gyro bias drift compensation (gain ``zeta``) is not implemented (neither ``ahrs`` nor
Madgwick's published C code implement it).

Missing data: a sample whose accelerometer reading is not usable (non-finite or zero) gets no
correction (the MARG step needs the accelerometer, as in the report); a sample whose magnetometer
reading is not usable takes the IMU step with ``beta_imu``; a non-finite gyro reading counts as a
zero rate for that sample. Start: the convention of the reference stages
(:mod:`estimators.attitude._kernel.start`): the first sample of a (re)set stream with a usable
accelerometer reading sets the attitude (tilt, plus heading from that sample's field when usable)
and takes no filter step.

The per-sample loop is the compiled kernel :data:`estimators.attitude._kernel.madgwick_kernel`
(loop over users inside; ``madgwick_kernel.py_func`` is its readable uncompiled source).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.attitude._kernel import madgwick_kernel
from estimators.attitude.base import QuaternionStage
from estimators.rotations import quat_multiply
from estimators.validation import check_in_range

__all__ = ["Madgwick", "MadgwickParams"]

#: ``r``: the +90 deg rotation about the vertical taking Madgwick's NWU world to ENU.
_NWU_TO_ENU = np.array([math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)])
#: The ENU identity attitude expressed in the NWU world, ``conj(r)``.
_ENU_IDENTITY_NWU = np.array([math.sqrt(0.5), 0.0, 0.0, -math.sqrt(0.5)])


@dataclass(frozen=True)
class MadgwickParams:
    """Parameters of :class:`Madgwick`.

    Every field is validated on construction.
    """

    beta_imu: float = 0.033
    """Gradient-descent gain (rad/s) of a step without magnetometer (IMU). Default 0.033 rad/s:
    Madgwick 2010 (the best value in its experiments; also ``ahrs`` ``gain_imu``)."""
    beta_marg: float = 0.041
    """Gradient-descent gain (rad/s) of a step with magnetometer (MARG). Default 0.041 rad/s:
    Madgwick 2010 (the best value in its experiments; also ``ahrs`` ``gain_marg``)."""

    def __post_init__(self) -> None:
        for name in ("beta_imu", "beta_marg"):
            check_in_range(self, name, 0.0, 10.0, "rad/s")

    def build(self, batch_size: int, fs: float) -> Madgwick:
        """The :class:`Madgwick` stage with these parameters."""
        return Madgwick(batch_size, fs, self)


class Madgwick(QuaternionStage):
    """Madgwick's filter as an attitude stage (:class:`estimators.stages.AttitudeStage`).

    Args:
        batch_size: B streams (users).
        fs: IMU rate, Hz (one sample every ``1 / fs`` s).
        params: :class:`MadgwickParams` (defaults if None).
    """

    name = "madgwick"
    Params = MadgwickParams
    per_user_fields = QuaternionStage.per_user_fields
    identity = tuple(_ENU_IDENTITY_NWU)

    def _run(self, gyr: NDArray, acc: NDArray, mag: NDArray, out: NDArray) -> None:
        p = self.params
        madgwick_kernel(self.batch_size)(
            self.q, self.ready, gyr, acc, mag, self.dt, float(p.beta_imu), float(p.beta_marg), out
        )

    @property
    def quat(self) -> NDArray[np.float64]:
        """(B, 4) current attitude, sensor -> ENU."""
        return quat_multiply(_NWU_TO_ENU, self.q)

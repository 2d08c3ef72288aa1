"""Gyro-only attitude: strapdown integration of the angular rate, no correction (the floor).

Each sample rotates the attitude by the sample's rotation vector, ``q <- q ⊗ exp(w dt)`` (the
exact update for a rate that is constant over the sample interval: the single-sample rotation
vector of P. G. Savage, "Strapdown inertial navigation integration algorithm design, part 1:
attitude algorithms", Journal of Guidance, Control, and Dynamics 21(1), 1998). Nothing corrects
it: the tilt drifts with the gyro bias and noise at ``|bias| t`` (rad), the heading likewise. It
is the floor any fusion filter must beat.

Start and dropouts (the convention of all the reference stages,
:mod:`estimators.attitude._kernel.start`): the first sample of a (re)set stream whose
accelerometer reading is usable sets the attitude from the accelerometer (tilt) and, when that
sample's magnetometer reading is usable, the field (heading); its gyro reading is not integrated.
Until such a sample arrives the gyro is integrated from the identity. A non-finite gyro sample
holds the attitude.

The per-sample loop is the compiled kernel :data:`estimators.attitude._kernel.gyro_kernel` (one
scalar implementation, loop over users inside; ``gyro_kernel.py_func`` is its readable uncompiled
source).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.attitude._kernel import gyro_kernel
from estimators.attitude.base import QuaternionStage
from estimators.validation import check_bool

__all__ = ["GyroOnly", "GyroOnlyParams"]


@dataclass(frozen=True)
class GyroOnlyParams:
    """Parameters of :class:`GyroOnly`.

    Every field is validated on construction.
    """

    init_from_acc: bool = True
    """Set the attitude of a (re)set stream from its first usable accelerometer (+ magnetometer)
    sample (the convention shared by the reference stages). False: start at the identity and
    only integrate. Default True."""

    def __post_init__(self) -> None:
        check_bool(self, "init_from_acc")

    def build(self, batch_size: int, fs: float) -> GyroOnly:
        """The :class:`GyroOnly` stage with these parameters."""
        return GyroOnly(batch_size, fs, self)


class GyroOnly(QuaternionStage):
    """Gyro integration as an attitude stage (:class:`estimators.stages.AttitudeStage`).

    Args:
        batch_size: B streams (users).
        fs: IMU rate, Hz (one sample every ``1 / fs`` s).
        params: :class:`GyroOnlyParams` (defaults if None).
    """

    name = "gyro_only"
    Params = GyroOnlyParams
    per_user_fields = QuaternionStage.per_user_fields

    def _run(self, gyr: NDArray, acc: NDArray, mag: NDArray, out: NDArray) -> None:
        gyro_kernel(self.batch_size)(
            self.q, self.ready, gyr, acc, mag, self.dt, bool(self.params.init_from_acc), out
        )

    @property
    def quat(self) -> NDArray[np.float64]:
        """(B, 4) current attitude."""
        return self.q.copy()

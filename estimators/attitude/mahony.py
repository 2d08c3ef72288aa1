"""Mahony's explicit complementary filter with gyro-bias estimation (a PI filter on SO(3)).

Source: R. Mahony, T. Hamel, J.-M. Pflimlin, "Nonlinear complementary filters on the special
orthogonal group", IEEE Transactions on Automatic Control 53(5):1203-1218, 2008 (the explicit
complementary filter with bias correction, in its quaternion form).

Per sample, with ``q`` the attitude (sensor -> ENU world), ``w`` the gyro reading (rad/s) and
``b`` the bias estimate (rad/s):

1. Predicted directions in the sensor frame: gravity ``v_a = R(q)^T [0, 0, 1]`` and, when the
   magnetometer is used, the field ``v_m = R(q)^T [0, |h_xy|, h_z]`` with ``h = R(q) m`` the
   measured field in the world (its horizontal part put on north, +y: only the heading is taken
   from the magnetometer, as in the reference implementation ``ahrs.filters.Mahony``).
2. Innovation ``w_mes = a × v_a + m × v_m`` (``a``, ``m`` the normalised readings; the paper's
   ``sum_i k_i v_i × v̂_i`` with unit weights).
3. Bias and rate: ``b <- b - k_I w_mes dt``, ``W = w - b + k_P w_mes``.
4. Integration: ``q <- normalise(q + 0.5 q ⊗ [0, W] dt)``.

Gains: ``k_P = 1`` rad/s and ``k_I = 0.3`` rad/s^2, the defaults of ``ahrs.filters.Mahony``
(which gives them as the experimental settings of the paper); they are not tuned on any data of
this project. ``tests/test_estimators/attitude/test_attitude_stages.py`` checks this filter against
``ahrs.filters.Mahony``
to 1e-9 (its world frame puts the field's horizontal part on +y as here, so no frame change).

Missing data: a sample whose accelerometer reading is not usable (non-finite or zero) gets no
correction (``W = w - b``); a sample whose magnetometer reading is not usable uses gravity only;
a non-finite gyro reading counts as a zero rate for that sample (``W = -b + k_P w_mes``). Start:
the convention of the reference stages (:mod:`estimators.attitude._kernel.start`): the first
sample of a (re)set stream with a usable accelerometer reading sets the attitude (tilt, plus
heading from that sample's field when usable) and takes no filter step; the bias starts at 0.

The per-sample loop is the compiled kernel :data:`estimators.attitude._kernel.mahony_kernel`
(loop over users inside; ``mahony_kernel.py_func`` is its readable uncompiled source).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.attitude._kernel import mahony_kernel
from estimators.attitude.base import QuaternionStage
from estimators.validation import check_in_range

__all__ = ["Mahony", "MahonyParams"]


@dataclass(frozen=True)
class MahonyParams:
    """Parameters of :class:`Mahony`.

    Every field is validated on construction.
    """

    kp: float = 1.0
    """Proportional gain ``k_P`` (rad/s): the bandwidth of the attitude correction. Default 1.0:
    ``ahrs.filters.Mahony`` ``k_P`` (the experimental setting of Mahony et al. 2008)."""
    ki: float = 0.3
    """Integral gain ``k_I`` (rad/s^2) of the gyro-bias estimate; 0 disables the bias estimate.
    Default 0.3: ``ahrs.filters.Mahony`` ``k_I`` (the experimental setting of Mahony et al.
    2008)."""

    def __post_init__(self) -> None:
        check_in_range(self, "kp", 0.0, 100.0, "rad/s")
        check_in_range(self, "ki", 0.0, 100.0, "rad/s^2")

    def build(self, batch_size: int, fs: float) -> Mahony:
        """The :class:`Mahony` stage with these parameters."""
        return Mahony(batch_size, fs, self)


class Mahony(QuaternionStage):
    """Mahony's filter as an attitude stage (:class:`estimators.stages.AttitudeStage`).

    Args:
        batch_size: B streams (users).
        fs: IMU rate, Hz (one sample every ``1 / fs`` s).
        params: :class:`MahonyParams` (defaults if None).
    """

    name = "mahony"
    Params = MahonyParams
    per_user_fields = (*QuaternionStage.per_user_fields, "b")

    def _allocate(self) -> None:
        self.b = np.zeros((self.batch_size, 3))  # gyro-bias estimates (rad/s)

    def _reset_rows(self, rows: NDArray[np.intp]) -> None:
        self.b[rows] = 0.0

    def _run(self, gyr: NDArray, acc: NDArray, mag: NDArray, out: NDArray) -> None:
        p = self.params
        mahony_kernel(self.batch_size)(
            self.q, self.b, self.ready, gyr, acc, mag, self.dt, float(p.kp), float(p.ki), out
        )

    @property
    def quat(self) -> NDArray[np.float64]:
        """(B, 4) current attitude."""
        return self.q.copy()

    @property
    def bias(self) -> NDArray[np.float64]:
        """(B, 3) current gyro-bias estimates, rad/s."""
        return self.b.copy()

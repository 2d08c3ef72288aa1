"""The physical play area of a walking-in-place user, and the user's unintended drift in it.

A walking-in-place user stays in a small tracked space while the virtual body travels. People who
step in place do not stay on one spot: they drift forward along the direction the body faces and
slowly turn. In the Fukuda stepping test (stepping in place blindfolded) healthy adults turn by
less than 30 deg in 50 steps and 45 deg in 100 steps (Fukuda's cut-offs, as cited by the
Front. Neurol. 14:1128760, 2023, study of the test's reliability, whose 24 subjects deviated
left and right about equally often); all 16 healthy young adults of Grostern, Lajoie & Paquet
(Physiother. Can. 73(4), 2021) "slowly turned and drifted forward" over 50 steps. Nilsson, Serafin
& Nordahl (IEEE 3DUI 2014) measured the same unintended positional drift in VR. Both drifts
belong to the user population, drawn per user and episode:

* **Forward drift** (:attr:`vrloco_env.user.population.Population.wip_drift_mps`): while a user
  steps (the motion model's cadence is non-zero), its standing spot moves by
  ``(forward * facing + lateral * left) * dt``, ``facing`` the torso's yaw, ``forward`` the
  user's drawn drift rate (m/s) and ``lateral`` a per-episode fraction of it within
  +-``lateral_ratio``; standing still, it does not move. No drift speed of the studies above is
  used: the few-cm/s magnitudes are engineering choices, stated as such. The spot shifts
  between control steps (:meth:`vrloco_env.user.motion.UserMotion.shift_base`, applied by
  :class:`vrloco_env.users.SimulatedUsers`), so the head, the IMU position and the Kinect
  skeleton all move with it. The acceleration of such a drift (a few cm/s, changing only at the
  steps' starts and stops) is far below the IMU's noise (the accelerometer's white noise alone
  is of order 0.01-0.1 m/s^2 per sample), so the IMU's specific force does not carry it.
* **Turning drift** (:attr:`~vrloco_env.user.population.Population.wip_turn_deg_per_step`): a
  per-user turn of ``r`` deg per step, ``r`` drawn uniformly within the population's range
  (``typical``'s +-0.45 deg/step: at most 45 deg in 100 steps and 22.5 deg in 50, inside both
  Fukuda cut-offs, left or right). It reaches the true motion through the body's yaw rate: while
  the intent steps at cadence ``c`` (steps/s), :class:`vrloco_env.user.behaviour.GazeBehaviour`
  adds ``r * c`` to the intent's turn rate (held within ``MotionParams.max_turn_rate``), so the
  torso, the head, the gyro's angular rate and the Kinect skeleton all turn with it and the
  forward drift follows the turning torso. The action keeps its meaning: its ``turn`` is still
  the turn the user means; the drift is what the body adds unasked, as the gaze adds the head's
  turns. A user who watches the scene corrects it like any other error of heading (the scripted
  users steer by what they see); one who does not (an open-loop action sequence) turns by up to
  the Fukuda figures. Blindfolded stepping is the upper bound: in a headset the view turns with
  the body, so a seeing user notices the turn.

The area is a rectangle centred on the start spot (the tracked space's origin), ``size_m`` wide
along x (the start facing) and y.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.validation import check_in_range, check_numbers

__all__ = ["PlayArea", "turning_drift"]


def turning_drift(deg_per_step: ArrayLike, cadence: ArrayLike) -> NDArray[np.float64]:
    """The body's yaw rate (rad/s) of a turning drift of ``deg_per_step`` (deg per step,
    counter-clockwise positive) while stepping at ``cadence`` (steps/s; 0 standing: no drift)."""
    return np.deg2rad(np.asarray(deg_per_step, dtype=np.float64)) * np.asarray(
        cadence, dtype=np.float64
    )


@dataclass(frozen=True)
class PlayArea:
    """The tracked space of a walking-in-place user (see the module docstring).

    Attributes:
        size_m: the rectangle's sides along x and y (m), centred on the start spot. Each side
            is at least a step (0.8 m) and at most 10 m (room-scale tracking spaces).
        lateral_ratio: the lateral drift rate is drawn uniformly within +- this fraction of the
            forward drift rate, per user and episode (an engineering choice: drift is "mostly
            along the facing").
    """

    size_m: tuple[float, float] = (2.0, 2.0)
    lateral_ratio: float = 0.3

    def __post_init__(self) -> None:
        check_numbers(self, "size_m", 0.8, 10.0, "m", length=2)
        check_in_range(self, "lateral_ratio", 0.0, 1.0)

    def boundary_distance(self, xy: NDArray[np.float64]) -> NDArray[np.float64]:
        """Distance (m) from positions ``xy`` (..., 2) to the nearest edge; negative outside
        (then minus the distance to the rectangle)."""
        half = 0.5 * np.asarray(self.size_m, dtype=np.float64)
        d = np.abs(np.asarray(xy, dtype=np.float64)) - half  # > 0 beyond an edge
        outside = np.hypot(np.maximum(d[..., 0], 0.0), np.maximum(d[..., 1], 0.0))
        inside = -np.maximum(d[..., 0], d[..., 1])
        return np.where((d[..., 0] > 0.0) | (d[..., 1] > 0.0), -outside, inside)

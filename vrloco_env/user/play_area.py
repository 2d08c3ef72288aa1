"""The physical play area of a walking-in-place user, and the user's unintended drift in it.

A walking-in-place user stays in a small tracked space while the virtual body travels. People who
step in place do not stay on one spot: they drift, mostly forward along the direction the body
faces. Nilsson, Serafin & Nordahl ("A comparison of different methods for reducing the
unintended positional drift accompanying walking-in-place locomotion", IEEE 3DUI 2014) measured
that unintended positional drift of participants walking in place in VR and compared methods of
reducing it. No drift speed from that study is used here: the drift *magnitudes*
(a forward speed of a few cm/s while stepping, a slower lateral part) are engineering choices,
stated as such, and they belong to the user population
(:attr:`vrloco_env.user.population.Population.wip_drift_mps`), drawn per user and episode.

The model (applied per control step by :class:`vrloco_env.users.SimulatedUsers`): while a user
steps (the motion model's cadence is non-zero), its standing spot moves by
``(forward * facing + lateral * left) * dt``, ``facing`` the torso's yaw, ``forward`` the user's
drawn drift rate (m/s) and ``lateral`` a per-episode fraction of it within
+-``lateral_ratio``; standing still, it does not move. The spot shifts between control steps
(:meth:`vrloco_env.user.motion.UserMotion.shift_base`), so the head, the IMU position and the
Kinect skeleton all move with it. The acceleration of such a drift (a few cm/s, changing only at
the steps' starts and stops) is far below the IMU's noise (the accelerometer's white noise alone
is of order 0.01-0.1 m/s^2 per sample), so the IMU's specific force does not carry it.

The area is a rectangle centred on the start spot (the tracked space's origin), ``size_m`` wide
along x (the start facing) and y.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators.validation import check_in_range, check_numbers

__all__ = ["PlayArea"]


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

"""Smooth locomotion: a Kalman filter that turns step events and yaw into continuous motion.

Zhang 2021's eq (17) (:class:`estimators.locomotion.dead_reckoning.DeadReckoning`) moves the virtual
body one step length SL in a single frame at each detected step: a 0.7 m jump twice a second, the
kind of discontinuous visual motion that VR comfort guidelines avoid. The smooth-locomotion paper
(an EKF tutorial for VR position tracking) suggests the remedy: a filter with a motion model,
predicting between measurements. :class:`SmoothLocomotion` is that filter; it shares eq (17)'s
interface (the :class:`estimators.stages.Locomotion` protocol), so the environment can use either.

Model (per user, per update of length dt):

* State ``[s, v, psi, omega]``: distance travelled along the path s (m), speed v (m/s), heading
  psi (rad, ENU, counter-clockwise from +x) and heading rate omega (rad/s). Constant-velocity
  models for both pairs, driven by white acceleration noise (Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]],
  the usual discretisation).
* Measurements, every update:

  - the yaw estimate of the attitude filter measures psi (innovation wrapped to (-pi, pi]: the one
    nonlinearity, which makes this the EKF of an otherwise linear model);
  - the step events give a pseudo-measurement of travelled distance (the smooth-locomotion paper's
  "measurement"
    slot). Eq (17) would say s = SL x (steps so far): a staircase. Measuring that staircase would
    pull the path forward in jerks, so the filter measures a *ramped* staircase ``D_ref``: at each
    step event ``D_ref`` starts moving from where it is towards SL x (steps so far), and stops
    there. Its speed is the remaining lag, at most ``(1 + catch_up)`` SL, per estimated step
    interval (the time since the previous event divided by the steps it carried, clamped to
    [min_step_interval, max_step_interval]; ``default_step_interval`` for the first event of a
    bout). Walking at a steady cadence makes ``D_ref`` a straight line at SL x cadence; stopping
    makes it flat one to two step intervals later; the bout's first step, which the gait detector
    releases together with the second, is caught up gradually instead of by a burst of speed.

* x and y are not filter states: nothing observes them, so their covariance would grow without
  bound and their Kalman corrections would only re-distribute those of s and psi. The virtual
  position integrates the filtered motion instead: ``P += ds [cos(psi + bearing), sin(psi +
  bearing)]`` with ``ds`` the increase of the filtered s (never negative: the path length only
  grows; a small overshoot when stopping is held, not walked back).

Why this is smooth: the measurement ``D_ref`` is continuous, and a constant-velocity Kalman filter
tracking it is a second-order low-pass (natural frequency ``distance_bandwidth_hz``, damping
1/sqrt(2), the Kalman-Bucy steady state), so the speed is continuous and the jerk bounded: a
change of cadence or a stop bends the path over a few tenths of a second instead of in one frame.

Distance: ``D_ref`` ends exactly at SL x (steps so far) and the filter has no steady-state error,
so after stopping the travelled distance converges to eq (17)'s (checked by
:func:`agents.experiments.locomotion_table.compare_locomotion`).

Stopping (no drift): once the events stop, ``D_ref`` reaches its end within one step interval and
the filter's speed then decays with time constant ``1 / (zeta * omega_n) = 1 / (sqrt(1/2) * 2 pi
* distance_bandwidth_hz)``, 0.23 s at the default 1 Hz (99 % of the remaining speed gone ~1 s
after the ramp ends). With no events at all the speed stays exactly 0.

Tuning by bandwidth: only the ratio of process to measurement noise shapes a Kalman filter's
estimate. With a pseudo-measurement noise density r (R = r / dt per update, so the result does not
depend on the update rate) and process noise density q, the steady-state natural frequency is
``(q / r) ** (1/4)`` rad/s. We set r = 1 and q = (2 pi f)^4 for the chosen bandwidth f: 1 Hz for
the distance (about half the cadence: the ramp already removes the step rhythm), 2 Hz for the
heading (a turn of the head redirects the walk within ~0.1 s, as in eq (17), minus its jitter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers
from estimators.locomotion.dead_reckoning import DeadReckoning
from estimators.rotations import wrap_angle
from estimators.validation import (
    check_in_range,
    check_locomotion_update,
    check_mask,
    check_per_user,
    check_positions,
    check_step_intervals,
    check_step_length,
)

__all__ = [
    "SmoothLocomotion",
    "SmoothParams",
    "make_locomotion",
]


@dataclass(frozen=True)
class SmoothParams:
    """Parameters of :class:`SmoothLocomotion` (validated on construction)."""

    distance_bandwidth_hz: float = 1.0
    """Natural frequency (Hz) of the distance/speed filter, in [0.1, 10]."""
    heading_bandwidth_hz: float = 2.0
    """Natural frequency (Hz) of the heading filter, in [0.1, 20]."""
    default_step_interval: float = 0.8
    """Step interval (s) assumed for the first event of a bout, before any interval is known:
    the slow end of in-place stepping (1.25 steps/s), so a bout starts gently and speeds up to
    its cadence at the next event rather than starting too fast."""
    min_step_interval: float = 1.0 / 3.5
    """Shortest step interval (s) the ramp assumes (humans step at most ~3.5 steps/s)."""
    max_step_interval: float = 1.2
    """Longest step interval (s) within a bout; a longer gap starts a new bout (as the gait
    detector's gamma_t)."""
    catch_up: float = 0.25
    """How much faster than SL per step interval the reference may move to catch up a lag of
    more than one step (fraction, in [0, 2]): the first step of a bout, released with the second,
    is made up over 1 / catch_up steps instead of by a burst of double speed."""

    def __post_init__(self) -> None:
        check_in_range(self, "distance_bandwidth_hz", 0.1, 10.0, "Hz")
        check_in_range(self, "heading_bandwidth_hz", 0.1, 20.0, "Hz")
        check_step_intervals(self)
        check_in_range(self, "catch_up", 0.0, 2.0)

    @property
    def stop_time_constant(self) -> float:
        """Time constant (s) of the speed's decay once the distance reference stops."""
        return 1.0 / (math.sqrt(0.5) * 2.0 * math.pi * self.distance_bandwidth_hz)


def _cv_step(
    x0: NDArray,
    x1: NDArray,
    p: NDArray,
    z: NDArray,
    dt: float,
    q: float,
    r: float,
    wrap: bool,
) -> None:
    """One predict + update of B constant-velocity Kalman filters, in place.

    Args:
        x0, x1: the state components (value, rate), (B,) each.
        p: covariances [[p00, p01], [p01, p11]] packed as (B, 3) = (p00, p01, p11).
        z: measurements of x0, (B,).
        dt: interval (s); q: process noise density; r: measurement noise density (R = r / dt).
        wrap: wrap the innovation and the value to (-pi, pi] (an angle).
    """
    # Predict: F = [[1, dt], [0, 1]], Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]].
    x0 += dt * x1
    p00, p01, p11 = p[:, 0], p[:, 1], p[:, 2]
    n00 = p00 + dt * (2.0 * p01 + dt * p11) + q * dt**3 / 3.0
    n01 = p01 + dt * p11 + q * dt**2 / 2.0
    n11 = p11 + q * dt
    # Update with H = [1, 0].
    innov = z - x0
    if wrap:
        innov = wrap_angle(innov)
    s = n00 + r / dt
    k0 = n00 / s
    k1 = n01 / s
    x0 += k0 * innov
    x1 += k1 * innov
    if wrap:
        x0[:] = wrap_angle(x0)
    p[:, 0] = (1.0 - k0) * n00
    p[:, 1] = (1.0 - k0) * n01
    p[:, 2] = n11 - k1 * n01


class SmoothLocomotion(TakesUsers):
    """Continuous virtual motion from step events and yaw, for B users (see the module docstring).

    Args:
        batch_size: B >= 1.
        step_length: SL (m), scalar or (B,), in [0, 3].
        params: filter parameters (:class:`SmoothParams` defaults if None).
        position: initial positions (m), (B, 2) or (2,); zeros by default.
        heading: initial heading (rad), scalar or (B,); taken from the first yaw if None.
    """

    per_user_fields = (
        "step_length",
        "_time",
        "_pos",
        "_s",
        "_v",
        "_ps",
        "_psi",
        "_omega",
        "_ph",
        "_head_init",
        "_travelled",
        "_target",
        "_ref",
        "_rate",
        "_last_event",
        "_bearing",
    )
    batch_size_field = "batch_size"

    def __init__(
        self,
        batch_size: int,
        step_length: ArrayLike = 0.7,
        params: SmoothParams | None = None,
        position: ArrayLike | None = None,
        heading: ArrayLike | None = None,
    ) -> None:
        if not isinstance(batch_size, int | np.integer) or batch_size < 1:
            raise ValueError(f"batch_size must be an integer >= 1, got {batch_size!r}")
        self.params = SmoothParams() if params is None else params
        if not isinstance(self.params, SmoothParams):
            raise ValueError(f"params must be a SmoothParams, got {type(self.params).__name__}")
        b = self.batch_size = int(batch_size)
        self.step_length = check_step_length(step_length, (b,))
        wd = 2.0 * math.pi * self.params.distance_bandwidth_hz
        wh = 2.0 * math.pi * self.params.heading_bandwidth_hz
        self._q_dist, self._q_head = wd**4, wh**4  # process noise densities (r = 1)
        self._time = np.zeros(b)  # s since each user's reset: an episode's own clock
        self._pos = np.zeros((b, 2))
        self._s = np.zeros(b)  # filtered distance (m)
        self._v = np.zeros(b)  # filtered speed (m/s)
        self._ps = np.zeros((b, 3))
        self._psi = np.zeros(b)
        self._omega = np.zeros(b)
        self._ph = np.zeros((b, 3))
        self._head_init = np.zeros(b, dtype=bool)
        self._travelled = np.zeros(b)  # rendered path length (m)
        self._target = np.zeros(b)  # SL x steps so far (m): eq (17)'s distance
        self._ref = np.zeros(b)  # ramped reference D_ref (m)
        self._rate = np.zeros(b)  # its current slope (m/s)
        self._last_event = np.full(b, -np.inf)
        self._bearing = np.zeros(b)
        self.reset(position=position, heading=heading)

    @property
    def position(self) -> NDArray[np.float64]:
        """Virtual positions (m), (B, 2)."""
        return self._pos.copy()

    @property
    def heading(self) -> NDArray[np.float64]:
        """Filtered heading (rad, in (-pi, pi]), (B,)."""
        return self._psi.copy()

    @property
    def distance(self) -> NDArray[np.float64]:
        """Path length travelled since reset (m), (B,)."""
        return self._travelled.copy()

    @property
    def speed(self) -> NDArray[np.float64]:
        """Filtered speed (m/s), (B,)."""
        return self._v.copy()

    @property
    def target_distance(self) -> NDArray[np.float64]:
        """Eq (17)'s distance, SL x steps since reset (m), (B,)."""
        return self._target.copy()

    def reset(
        self,
        mask: ArrayLike | None = None,
        position: ArrayLike | None = None,
        heading: ArrayLike | None = None,
    ) -> None:
        """Stop the users selected by ``mask`` (B,) bool (all if None) at ``position`` (m); their
        heading is ``heading`` (rad) if given, else the next yaw measurement."""
        b = self.batch_size
        sel = check_mask(mask, b)
        self._pos[sel] = check_positions(position, b)[sel]
        for arr in (
            self._s,
            self._v,
            self._travelled,
            self._target,
            self._ref,
            self._rate,
            self._omega,
            self._bearing,
        ):
            arr[sel] = 0.0
        self._ps[sel] = 0.0
        self._ph[sel] = 0.0
        self._last_event[sel] = -np.inf
        self._time[sel] = 0.0
        if heading is None:
            self._psi[sel] = 0.0
            self._head_init[sel] = False
        else:
            self._psi[sel] = wrap_angle(check_per_user(heading, b, "heading", 0.0, "rad"))[sel]
            self._head_init[sel] = True

    def update(
        self,
        steps: ArrayLike,
        yaw: ArrayLike,
        dt: float,
        bearing: ArrayLike | None = None,
    ) -> NDArray[np.float64]:
        """Advance every user by ``dt`` seconds.

        Args:
            steps: steps detected during this interval per user, (B,) counts >= 0 (or bool).
            yaw: heading estimate at the end of the interval (rad), (B,) or scalar.
            dt: length of the interval (s), in (0, 10].
            bearing: direction of the steps relative to the heading (rad), 0 forward, pi
                backward; held from one step event to the next. (B,) or scalar.

        Returns:
            The new positions (m), (B, 2).
        """
        st, y, dt, br = check_locomotion_update(steps, yaw, dt, bearing, self.batch_size)
        p = self.params
        t = self._time + dt
        # Step events: extend eq (17)'s distance and restart the ramp towards it.
        ev = st > 0.0
        if np.any(ev):
            since = t - self._last_event
            interval = np.where(
                since <= p.max_step_interval * np.maximum(st, 1.0),
                since / np.maximum(st, 1.0),
                p.default_step_interval,
            )
            interval = np.clip(interval, p.min_step_interval, p.max_step_interval)
            self._target = np.where(ev, self._target + st * self.step_length, self._target)
            lag = self._target - self._ref
            rate = np.minimum(lag, (1.0 + p.catch_up) * self.step_length) / interval
            self._rate = np.where(ev, rate, self._rate)
            self._last_event = np.where(ev, t, self._last_event)
            self._bearing = np.where(ev, br, self._bearing)
        self._ref = np.minimum(self._ref + self._rate * dt, self._target)
        self._rate = np.where(self._ref >= self._target, 0.0, self._rate)
        # Distance / speed filter.
        _cv_step(self._s, self._v, self._ps, self._ref, dt, self._q_dist, 1.0, wrap=False)
        # Heading filter; a user's first yaw initialises it.
        fresh = ~self._head_init
        if np.any(fresh):
            self._psi[fresh] = wrap_angle(y[fresh])
            self._head_init[fresh] = True
        _cv_step(self._psi, self._omega, self._ph, y, dt, self._q_head, 1.0, wrap=True)
        # Integrate the filtered motion; the path length never decreases.
        ds = np.maximum(self._s - self._travelled, 0.0)
        self._travelled += ds
        ang = self._psi + self._bearing
        self._pos[:, 0] += ds * np.cos(ang)
        self._pos[:, 1] += ds * np.sin(ang)
        self._time = t
        return self._pos.copy()


def make_locomotion(
    kind: str, batch_size: int, step_length: ArrayLike = 0.7, **kwargs
) -> DeadReckoning | SmoothLocomotion:
    """Build a locomotion model by name: ``"eq17"`` (:class:`DeadReckoning`) or ``"smooth"``
    (:class:`SmoothLocomotion`); ``kwargs`` go to the constructor."""
    if kind == "eq17":
        return DeadReckoning(batch_size, step_length, **kwargs)
    if kind == "smooth":
        return SmoothLocomotion(batch_size, step_length, **kwargs)
    raise ValueError(f"unknown locomotion kind {kind!r}; choose 'eq17' or 'smooth'")

"""Speed proportional to the estimated cadence: continuous walking-in-place locomotion.

Walking-in-place interfaces that understand gait set the virtual speed from the step frequency
rather than moving a fixed distance per step: GUD WIP (J. D. Wendt, M. C. Whitton, F. P. Brooks
Jr., "GUD WIP: Gait-Understanding-Driven Walking-In-Place", IEEE VR 2010, 51-58) estimates the
step frequency at every gait event and outputs a speed that follows it smoothly, with realistic
starting and stopping. :class:`CadenceSpeed` does the same with the simplest frequency-to-speed
law, ``speed = SL x cadence`` (GUD WIP maps the frequency through a biomechanical model of real
walking instead; with a fixed step length SL, eq (17)'s assumption, the law here is the one that
keeps eq (17)'s distance per step). It shares eq (17)'s interface (the
:class:`estimators.stages.Locomotion` protocol).

Per user:

* Cadence. Each update's step events are time-stamped at the start of its interval (they happened
  during it). The step interval ``T`` is the time spanned by the bout's last
  ``cadence_window`` event intervals divided by the steps they carried (clamped to
  [min_step_interval, max_step_interval]); the bout's first event — which the gait detector
  releases together with the second step — carries no timing, so ``T = default_step_interval``
  until the second event. The cadence is ``1 / T``.
* Target speed ``SL / T``, set at every event. Stop timeout: when no event has come for
  ``stop_factor x T`` s, the target becomes 0 and the bout ends (the next event starts a new one).
* Ramp. At every change of target the speed leaves its current value and acceleration along a
  cubic (a Hermite segment) that reaches the target with zero acceleration after ``ramp_time``
  s, and stays there. Speed and acceleration are therefore continuous and the jerk is bounded
  (by ``(6 |dv| + 4 |a0| ramp_time) / ramp_time^2`` for a change ``dv`` started at acceleration
  ``a0``): no jump of position or speed, unlike eq (17).
* Position. The distance of an update is the exact integral of the speed over its interval, so
  the path does not depend on the update rate beyond the time-stamping of the events; it moves
  along ``yaw + bearing`` (the yaw halfway between the previous update's and this one's; the
  bearing held from one step event to the next). The speed is clipped at 0 (a cubic started while
  decelerating can dip a little below 0 near its end): the path length never decreases.

Stopping. The speed is exactly 0 at most ``stop_factor x T + ramp_time`` s plus one update after
the last step event (:meth:`CadenceSpeedParams.stop_time`): 1.68 s at 1.7 steps/s with the
defaults. With no events at all the speed stays exactly 0.

Distance. With steady stepping at interval ``T`` the speed is ``SL / T`` from the second event
until the timeout, ``stop_factor`` intervals after the last one, and ``SL / default_step_interval``
during the first interval; the ramps add and remove the same area. A bout of N steps (N - 1
events, the first carrying two steps) thus travels ``SL (N - 3 + stop_factor + T /
default_step_interval)``: with the default ``stop_factor = 2``, eq (17)'s ``SL x N`` up to ``SL |T /
default_step_interval - 1|`` (less than one step).

The per-update loop is the compiled kernel :data:`estimators.locomotion._kernel.cadence_kernel`
(loop over users inside; ``cadence_kernel.py_func`` is its readable uncompiled source).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.kernels import param_record
from estimators.locomotion._kernel import CADENCE_SPEED_STATE, cadence_kernel
from estimators.locomotion.record_state import RecordLocomotion
from estimators.validation import (
    check_in_range,
    check_locomotion_update,
    check_step_intervals,
    check_step_length,
)

__all__ = ["CadenceSpeed", "CadenceSpeedParams"]


@dataclass(frozen=True)
class CadenceSpeedParams:
    """Parameters of :class:`CadenceSpeed`; every field is validated on construction."""

    ramp_time: float = 0.5
    """Duration of a speed change, s, in [0.05, 3]. Default 0.5 s: about one step interval at the
    typical in-place cadence of 1.7-2 steps/s, so the speed settles on a new cadence within the
    step that revealed it; a start to 1.2 m/s (SL 0.7 m at 1.7 steps/s) peaks at 3.6 m/s^2."""
    stop_factor: float = 2.0
    """Stop timeout in step intervals, in [1, 5]: with no event for ``stop_factor x T`` s the
    speed ramps to 0. Default 2: the bout then lasts as many intervals as it has steps (its first
    event carries two), so the distance equals eq (17)'s SL x steps (module docstring)."""
    cadence_window: int = 2
    """Event intervals averaged into the step interval, integer in [1, 16]. Default 2: one stride,
    which cancels the left/right alternation of step times and halves the effect of events
    time-stamped at the update rate (0.1 s in the environment), while following a change of
    cadence within a stride."""
    default_step_interval: float = 0.8
    """Step interval (s) before the bout's second event, in [min_step_interval,
    max_step_interval]. Default 0.8 s, as :class:`estimators.locomotion.SmoothParams`: the slow
    end of in-place stepping (1.25 steps/s), so a bout starts gently."""
    min_step_interval: float = 1.0 / 3.5
    """Shortest step interval (s), in [0.05, 2]. Default 1 / 3.5 s: humans step at most ~3.5
    steps/s (as :class:`estimators.locomotion.SmoothParams`)."""
    max_step_interval: float = 1.2
    """Longest step interval (s), in [min_step_interval, 10]. Default 1.2 s, as
    :class:`estimators.locomotion.SmoothParams` (the gait detector's gamma_t): slower stepping
    is not walking."""

    def __post_init__(self) -> None:
        check_in_range(self, "ramp_time", 0.05, 3.0, "s")
        check_in_range(self, "stop_factor", 1.0, 5.0, "step intervals")
        check_in_range(self, "cadence_window", 1, 16, integer=True)
        check_step_intervals(self)

    def stop_time(self, step_interval: float) -> float:
        """Seconds after the last step event by which the speed is exactly 0 (plus one update),
        for an estimated step interval ``step_interval`` (s; clamped as the estimate is)."""
        t = min(max(float(step_interval), self.min_step_interval), self.max_step_interval)
        return self.stop_factor * t + self.ramp_time

    def build(self, batch_size: int, step_length: ArrayLike) -> CadenceSpeed:
        """The :class:`CadenceSpeed` model with these parameters."""
        return CadenceSpeed(batch_size, step_length, self)


class CadenceSpeed(RecordLocomotion):
    """Continuous virtual motion at SL x the estimated cadence, for B users (module docstring).

    Args:
        batch_size: B >= 1.
        step_length: SL (m), scalar or (B,), in [0, 3].
        params: :class:`CadenceSpeedParams` (defaults if None).
        position: initial positions (m), (B, 2) or (2,); zeros by default.
        heading: initial heading (rad), scalar or (B,); the first yaw if None.
    """

    name = "cadence_speed"
    per_user_fields = ("step_length", "_state")

    def __init__(
        self,
        batch_size: int,
        step_length: ArrayLike = 0.7,
        params: CadenceSpeedParams | None = None,
        position: ArrayLike | None = None,
        heading: ArrayLike | None = None,
    ) -> None:
        self.params = CadenceSpeedParams() if params is None else params
        if not isinstance(self.params, CadenceSpeedParams):
            raise ValueError(
                f"params must be a CadenceSpeedParams, got {type(self.params).__name__}"
            )
        super().__init__(batch_size, CADENCE_SPEED_STATE)
        self.step_length = check_step_length(step_length, (self.batch_size,))
        self._prm = param_record(self.params)
        self.reset(position=position, heading=heading)

    @property
    def cadence(self) -> NDArray[np.float64]:
        """Estimated cadence of the current bout (steps/s), 0 where not stepping, (B,)."""
        st = self._state
        return np.where(st["active"] != 0.0, 1.0 / np.maximum(st["interval"], 1e-9), 0.0)

    @property
    def step_interval(self) -> NDArray[np.float64]:
        """Estimated step interval of the current bout (s), NaN where not stepping, (B,)."""
        return np.where(self._state["active"] != 0.0, self._state["interval"], np.nan)

    def reset(
        self,
        mask: ArrayLike | None = None,
        position: ArrayLike | None = None,
        heading: ArrayLike | None = None,
    ) -> None:
        """Stop the users selected by ``mask`` (B,) bool (all if None) at ``position`` (m), with
        zero speed and distance and no bout; their heading is ``heading`` (rad) if given, else
        the next yaw."""
        sel = self._restart(mask, position, heading)
        self._state["interval"][sel] = self.params.default_step_interval

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
        st, y, dtf, br = check_locomotion_update(steps, yaw, dt, bearing, self.batch_size)
        cadence_kernel(self.batch_size)(
            np.ascontiguousarray(st),
            np.ascontiguousarray(y),
            np.ascontiguousarray(br),
            self.step_length,
            dtf,
            self._prm,
            self._state,
        )
        return self._state["pos"].copy()

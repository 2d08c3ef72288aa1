"""Collision attribution: every collision of an episode is put down to one cause, from the
episode's ``info`` alone (:func:`collision_causes`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from agents.benchmark.step_matching import STEP_TOLERANCE_S, finite_times
from agents.benchmark.wip_measures import steering_offsets_deg

__all__ = [
    "CAUSE_WINDOW_S",
    "COLLISION_CAUSES",
    "HEADING_BOUND_DEG",
    "STEERING_BOUND_DEG",
    "collision_causes",
]

#: The causes a collision is put down to, in the order they are tested: the first that holds is
#: the cause (:func:`collision_causes`).
COLLISION_CAUSES = ("phantom_step", "stop_latency", "heading_error", "steering", "policy")
#: The detected steps that may have carried the body into a collision: those reported in the
#: control steps of the last second (eq 17 moves the body with the step it reports; the smooth
#: filter of the smooth-locomotion paper spreads a step over about 0.5 s).
CAUSE_WINDOW_S = 1.0
#: A heading error (virtual minus true head yaw) beyond this (deg) is the cause: at 10 deg a
#: 0.7 m step lands 0.12 m to the side, more than the scripted users' 0.1 m margin (engineering
#: choice).
HEADING_BOUND_DEG = 10.0
#: The walking direction (the steering stage's yaw) farther than this (deg) from the direction
#: the body faces (the true torso yaw in the virtual room) is the cause: the body was walked
#: where it was not facing, e.g. where the head looked (engineering choice, as the heading bound).
STEERING_BOUND_DEG = 10.0


def collision_causes(steps: dict[str, NDArray]) -> dict[str, int]:
    """How many of an episode's collisions (``info["collision"]``) go to each cause of
    :data:`COLLISION_CAUSES`, from its stacked ``info`` values. A collision's cause is the first
    that holds at its control step:

    * ``phantom_step``: a step the detector reported in the last :data:`CAUSE_WINDOW_S` has no
      true heel strike within :data:`STEP_TOLERANCE_S` of its estimated time;
    * ``stop_latency``: the user meant to stand (``intent_walk`` false), the body still moved;
    * ``heading_error``: ``|info["heading_error_deg"]|`` beyond :data:`HEADING_BOUND_DEG`;
    * ``steering``: the walking direction (``info["walk_yaw_deg"]``) beyond
      :data:`STEERING_BOUND_DEG` from the true torso direction (``info["true_body_yaw_deg"]``),
      both in the virtual room (tested only where the ``info`` has them);
    * ``policy``: none of these — sensing did what perfect sensing would have, and the user
      walked into the obstacle.
    """
    out = dict.fromkeys(COLLISION_CAUSES, 0)
    hit = np.asarray(steps["collision"], dtype=bool).ravel()
    if not hit.any():
        return out
    n = hit.size
    t_end = np.asarray(steps["elapsed_time"], dtype=np.float64).ravel()
    intent = np.asarray(steps["intent_walk"], dtype=bool).ravel()
    heading = np.asarray(steps["heading_error_deg"], dtype=np.float64).ravel()
    strikes = finite_times(steps["true_step_times"])
    detected = np.asarray(steps["detected_step_times"], dtype=np.float64).reshape(n, -1)
    steer = steering_offsets_deg(steps)
    if steer is not None:
        steer = np.abs(steer)
    for k in np.flatnonzero(hit):
        recent = detected[(t_end > t_end[k] - CAUSE_WINDOW_S - 1e-9) & (t_end <= t_end[k])]
        recent = recent[np.isfinite(recent)]
        if strikes.size:
            gap = np.abs(recent[:, None] - strikes[None, :]).min(axis=1)
        else:
            gap = np.full(recent.size, np.inf)
        if np.any(gap > STEP_TOLERANCE_S):
            cause = "phantom_step"
        elif not intent[k]:
            cause = "stop_latency"
        elif abs(heading[k]) > HEADING_BOUND_DEG:
            cause = "heading_error"
        elif steer is not None and steer[k] > STEERING_BOUND_DEG:
            cause = "steering"
        else:
            cause = "policy"
        out[cause] += 1
    return out

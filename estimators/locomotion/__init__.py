"""Virtual motion from steps and yaw: the locomotion models of :data:`estimators.stages.LOCOMOTION`
and the steering stages of :data:`estimators.stages.STEERING`.

* :mod:`~estimators.locomotion.dead_reckoning` — Zhang 2021's eq (17): a jump of one step length
  along the heading at each step (:class:`DeadReckoning`, :func:`dead_reckon` offline).
* :mod:`~estimators.locomotion.smooth` — the smooth-locomotion paper's filter: continuous
motion from the same
  events (:class:`SmoothLocomotion`).
* :mod:`~estimators.locomotion.cadence_speed` — speed proportional to the estimated cadence
  (:class:`CadenceSpeed`).
* :mod:`~estimators.locomotion.head_tilt` — speed from the head's forward tilt (Tregillus 2017;
  :class:`HeadTilt`).
* :mod:`~estimators.locomotion.look_down` — a look down toggles an auto-walk
  (:class:`LookDownToMove`).
* :mod:`~estimators.locomotion.steering` — which yaw turns the walk: the head's, the torso's or
  the hand's (:class:`HeadSteering`, :class:`TorsoSteering`, :class:`HandSteering`,
  :func:`torso_yaw`).
* :mod:`~estimators.locomotion.gestures` — what a technique asks its users to do with their body.
* :mod:`~estimators.locomotion.record_state` — the kinematics the compiled models share
  (:class:`~estimators.locomotion.record_state.RecordLocomotion`).
* :mod:`~estimators.locomotion._kernel` — the package's compiled kernels (cadence speed, head
  tilt, look-down toggle).

Every model follows the :class:`estimators.stages.Locomotion` protocol.
"""

from estimators.locomotion.cadence_speed import CadenceSpeed, CadenceSpeedParams
from estimators.locomotion.dead_reckoning import DeadReckoning, dead_reckon
from estimators.locomotion.gestures import (
    STEP_IN_PLACE,
    LookDownToToggle,
    PointToSteer,
    StepInPlace,
    TiltToMove,
)
from estimators.locomotion.head_tilt import HeadTilt, HeadTiltParams
from estimators.locomotion.look_down import LookDownParams, LookDownToMove
from estimators.locomotion.smooth import SmoothLocomotion, SmoothParams, make_locomotion
from estimators.locomotion.steering import HandSteering, HeadSteering, TorsoSteering, torso_yaw

__all__ = [
    "STEP_IN_PLACE",
    "CadenceSpeed",
    "CadenceSpeedParams",
    "DeadReckoning",
    "HandSteering",
    "HeadSteering",
    "HeadTilt",
    "HeadTiltParams",
    "LookDownParams",
    "LookDownToMove",
    "LookDownToToggle",
    "PointToSteer",
    "SmoothLocomotion",
    "SmoothParams",
    "StepInPlace",
    "TiltToMove",
    "TorsoSteering",
    "dead_reckon",
    "make_locomotion",
    "torso_yaw",
]

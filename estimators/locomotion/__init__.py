"""Virtual motion from steps and yaw: the locomotion models of :data:`estimators.stages.LOCOMOTION`
and the steering stages of :data:`estimators.stages.STEERING`.

* :mod:`~estimators.locomotion.dead_reckoning` — Zhang 2021's eq (17): a jump of one step length
  along the heading at each step (:class:`DeadReckoning`, :func:`dead_reckon` offline).
* :mod:`~estimators.locomotion.smooth` — the smooth-locomotion paper's filter: continuous
motion from the same
  events (:class:`SmoothLocomotion`).
* :mod:`~estimators.locomotion.cadence_speed` — speed proportional to the estimated cadence
  (:class:`CadenceSpeed`).
* :mod:`~estimators.locomotion.steering` — which yaw turns the walk: the head's or the torso's
  (:class:`HeadSteering`, :class:`TorsoSteering`, :func:`torso_yaw`).
* :mod:`~estimators.locomotion._kernel` — the package's compiled kernel (cadence speed).

Every model follows the :class:`estimators.stages.Locomotion` protocol.
"""

from estimators.locomotion.cadence_speed import CadenceSpeed, CadenceSpeedParams
from estimators.locomotion.dead_reckoning import DeadReckoning, dead_reckon
from estimators.locomotion.smooth import SmoothLocomotion, SmoothParams, make_locomotion
from estimators.locomotion.steering import HeadSteering, TorsoSteering, torso_yaw

__all__ = [
    "CadenceSpeed",
    "CadenceSpeedParams",
    "DeadReckoning",
    "HeadSteering",
    "SmoothLocomotion",
    "SmoothParams",
    "TorsoSteering",
    "dead_reckon",
    "make_locomotion",
    "torso_yaw",
]

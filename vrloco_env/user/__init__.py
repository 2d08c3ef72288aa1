"""The simulated VR user: body motion from intent, and the Kinect v2 skeleton it is drawn on.

* :mod:`~vrloco_env.user.motion`: :class:`UserMotion` turns each user's :class:`Intent` into the
  true head pose, steps, skeleton and hand orientation (its compiled body is
  :mod:`vrloco_env.user._motion_numba`, which reads :mod:`vrloco_env.user._motion_inputs`).
* :mod:`~vrloco_env.user.motion_params`: :class:`MotionParams`, the user's rates, limits and body
  measurements.
* :mod:`~vrloco_env.user.intent`: :class:`Intent`, what the users want to do in one control step.
* :mod:`~vrloco_env.user.motion_records`: :class:`MotionChunk`, :class:`KinectChunk` and
  :class:`MotionRecord`, the true motion of a control step and of a run.
* :mod:`~vrloco_env.user.scripts`: Zhang 2021's scripted motions (:func:`script_intents`,
  :func:`run_script`).
* :mod:`~vrloco_env.user.skeleton`: the Kinect v2 joint indices, bones and tracking states shared
  by the motion and sensor models.
* :mod:`~vrloco_env.user.population`: user populations, seeded distributions of head behaviour
  and variability (:data:`POPULATIONS`).
* :mod:`~vrloco_env.user.behaviour`: :class:`GazeBehaviour`, the head's gaze and nods of a
  population's users, on top of the intent the action asks for.

The names below are re-exported from their modules.
"""

from vrloco_env.user.behaviour import GazeBehaviour
from vrloco_env.user.intent import MAX_HEAD_YAW, Intent
from vrloco_env.user.motion import UserMotion
from vrloco_env.user.motion_params import MotionParams
from vrloco_env.user.motion_records import KinectChunk, MotionChunk, MotionRecord
from vrloco_env.user.population import POPULATIONS, Population, get_population
from vrloco_env.user.scripts import SCRIPTS, run_script, script_intents
from vrloco_env.user.skeleton import (
    BONES,
    INFERRED,
    NOT_TRACKED,
    NUM_JOINTS,
    PARENT,
    TRACKED,
    Joint,
)

__all__ = [
    "BONES",
    "INFERRED",
    "MAX_HEAD_YAW",
    "NOT_TRACKED",
    "NUM_JOINTS",
    "PARENT",
    "POPULATIONS",
    "SCRIPTS",
    "TRACKED",
    "GazeBehaviour",
    "Intent",
    "Joint",
    "KinectChunk",
    "MotionChunk",
    "MotionParams",
    "MotionRecord",
    "Population",
    "UserMotion",
    "get_population",
    "run_script",
    "script_intents",
]

"""The simulated VR user: body motion from intent, and the Kinect v2 skeleton it is drawn on.

* :mod:`~vrloco_env.user.motion`: :class:`UserMotion` turns each user's :class:`Intent` into the
  true head pose, steps, skeleton and hand orientation (its compiled body is
  :mod:`vrloco_env.user._motion_numba`).
* :mod:`~vrloco_env.user.skeleton`: the Kinect v2 joint indices, bones and tracking states shared
  by the motion and sensor models.

The names below are re-exported from their modules.
"""

from vrloco_env.user.motion import (
    SCRIPTS,
    Intent,
    KinectChunk,
    MotionChunk,
    MotionParams,
    MotionRecord,
    UserMotion,
    run_script,
    script_intents,
)
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
    "NOT_TRACKED",
    "NUM_JOINTS",
    "PARENT",
    "SCRIPTS",
    "TRACKED",
    "Intent",
    "Joint",
    "KinectChunk",
    "MotionChunk",
    "MotionParams",
    "MotionRecord",
    "UserMotion",
    "run_script",
    "script_intents",
]

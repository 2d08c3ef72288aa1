"""The Kinect v2 skeleton: joint indices and bone structure shared by the motion and sensor models.

Joint order is Kinect v2's ``JointType`` (0 SpineBase ... 24 ThumbRight), the order used by the
Kinect SDK and by recordings such as ``../shared/data/kinect_laban``.
"""

from __future__ import annotations

from enum import IntEnum


class Joint(IntEnum):
    """Kinect v2 ``JointType`` indices."""

    SPINE_BASE = 0
    SPINE_MID = 1
    NECK = 2
    HEAD = 3
    SHOULDER_LEFT = 4
    ELBOW_LEFT = 5
    WRIST_LEFT = 6
    HAND_LEFT = 7
    SHOULDER_RIGHT = 8
    ELBOW_RIGHT = 9
    WRIST_RIGHT = 10
    HAND_RIGHT = 11
    HIP_LEFT = 12
    KNEE_LEFT = 13
    ANKLE_LEFT = 14
    FOOT_LEFT = 15
    HIP_RIGHT = 16
    KNEE_RIGHT = 17
    ANKLE_RIGHT = 18
    FOOT_RIGHT = 19
    SPINE_SHOULDER = 20
    HAND_TIP_LEFT = 21
    THUMB_LEFT = 22
    HAND_TIP_RIGHT = 23
    THUMB_RIGHT = 24


# Compiled kernels read NUM_JOINTS and the tracking states below (numba freezes them into the
# machine code): this comment names numba, so its cache's fingerprint covers this file.
NUM_JOINTS = len(Joint)

#: Parent of each joint in the kinematic tree (SpineBase is the root, its parent is -1).
PARENT = (
    -1,
    0,
    20,
    2,
    20,
    4,
    5,
    6,
    20,
    8,
    9,
    10,
    0,
    12,
    13,
    14,
    0,
    16,
    17,
    18,
    1,
    7,
    6,
    11,
    10,
)

#: Bones as (parent, child) pairs, for drawing.
BONES = tuple((p, c) for c, p in enumerate(PARENT) if p >= 0)

#: Tracking states, as the Kinect SDK's ``TrackingState``.
NOT_TRACKED, INFERRED, TRACKED = 0, 1, 2

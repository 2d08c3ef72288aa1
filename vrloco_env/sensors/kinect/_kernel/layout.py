"""The layout of the Kinect v2 kernel's inputs (:mod:`vrloco_env.sensors.kinect._kernel`): the
joints it names, the sizes of its tables, the fields of its records (the sensor's
:data:`GEOMETRY_FIELDS`, each user's session :data:`STATE_FIELDS`) and where each number of a
frame's draws sits (offsets ``Z_*``, ``B_*``, ``Y_*``; :func:`draw_size`; "Draw layout" in the
package docstring).

The kernels (``numba.njit(cache=True)``) read these constants as compile-time values.
"""

from __future__ import annotations

from vrloco_env.user import NUM_JOINTS, Joint

__all__ = [
    "BODY_DRAWS",
    "BYSTANDER_DRAWS",
    "GEOMETRY_FIELDS",
    "MAX_BODIES",
    "MAX_LIMB_JOINTS",
    "N_LIMB_GROUPS",
    "N_TORSO_JOINTS",
    "STATE_FIELDS",
    "Z_BODIES",
    "bystander_offset",
    "draw_size",
]

WRIST_RIGHT = int(Joint.WRIST_RIGHT)
SHOULDER_LEFT, SHOULDER_RIGHT = int(Joint.SHOULDER_LEFT), int(Joint.SHOULDER_RIGHT)
HIP_LEFT, HIP_RIGHT = int(Joint.HIP_LEFT), int(Joint.HIP_RIGHT)
#: Bodies the Kinect v2 tracks at once (Microsoft Kinect for Windows v2 specification: six).
MAX_BODIES = 6
#: Most joints in one burst limb (an arm: elbow, wrist, hand, hand tip, thumb).
MAX_LIMB_JOINTS = 5
#: Limbs a jitter burst can hit (``spec.LIMB_GROUPS``) and torso joints (``spec.TORSO_JOINTS``).
N_LIMB_GROUPS, N_TORSO_JOINTS = 4, 8

#: The sensor's pose and the per-joint tables (one record per sensor; SI units). Camera -> world
#: rotation ``cam_rot`` and quaternion ``cam_quat``, position ``cam_pos``; ``sdk_from_hand``:
#: ``kinect.HAND_FROM_SDK_WRIST``; ``by_template``: a bystander's standing skeleton of height 1 m
#: in its body frame (pelvis over the origin, facing +x), ``by_hand_quat`` its right hand (hand
#: frame -> body frame); ``joint_scale``: per-joint noise multiplier; ``hand_white_sd`` /
#: ``hand_ar_sd``: wrist rotation noise (rad) about the hand axes; ``inferred_z[k]``:
#: ndtri(1 - (1 - p)^k), below which at least one of k joints starts a random inferred episode;
#: ``limb_index[g, j]``: joint j's place in burst limb g (-1: not in it); ``is_torso`` (0 / 1) and
#: ``torso_joints`` (indices): the torso silhouette; ``limb_side``: +1 for the joints of the
#: left arm and leg, -1 for the right ones, 0 for the others.
GEOMETRY_FIELDS = {
    "cam_rot": (3, 3),
    "cam_pos": (3,),
    "cam_quat": (4,),
    "sdk_from_hand": (4,),
    "by_template": (NUM_JOINTS, 3),
    "by_hand_quat": (4,),
    "joint_scale": (NUM_JOINTS,),
    "hand_white_sd": (3,),
    "hand_ar_sd": (3,),
    "inferred_z": (NUM_JOINTS + 1,),
    "limb_index": (N_LIMB_GROUPS, NUM_JOINTS),
    "is_torso": (NUM_JOINTS,),
    "torso_joints": (N_TORSO_JOINTS,),
    "limb_side": (NUM_JOINTS,),
}

#: A user's session (``KinectV2``), per body (the target first, then the bystanders; rows past
#: the spec's bodies are unused). Integers and flags are exact in float64. ``slot``: each body's
#: slot; ``body_id``: its tracking id (1 .. 2^53); ``acquired``: consecutive detectable frames
#: (up to ``acquire_frames``); ``prev_tracked``: tracked in the last frame (0 / 1); ``bias``: the
#: session's joint offsets (m); ``joint_noise`` / ``joint_innov``: the target's ARMA(1, 1) state
#: (y_{t-1}, e_{t-1}); ``ar_hand``: every wrist's and ``ar_by`` the bystanders' rigid joint
#: noise's unit AR(1) states; ``burst_left`` / ``burst_group``: frames left and limb of a jitter
#: burst; ``inferred_left``: frames left of random inferred episodes; ``frame``: frames since the
#: reset (the bystanders' sway clock); ``by_*``: the bystanders' floor position (m), yaw (rad),
#: height (m), sway amplitude (m), frequency (Hz) and phase (rad), walk target (m), speed (m/s)
#: and whether they walk (0 / 1).
STATE_FIELDS = {
    "slot": (MAX_BODIES,),
    "body_id": (MAX_BODIES,),
    "acquired": (MAX_BODIES,),
    "prev_tracked": (MAX_BODIES,),
    "bias": (MAX_BODIES, NUM_JOINTS, 3),
    "joint_noise": (NUM_JOINTS, 3),
    "joint_innov": (NUM_JOINTS, 3),
    "ar_hand": (MAX_BODIES, 3),
    "ar_by": (MAX_BODIES - 1, 3),
    "burst_left": (MAX_BODIES,),
    "burst_group": (MAX_BODIES,),
    "inferred_left": (MAX_BODIES, NUM_JOINTS),
    "frame": (),
    "by_pos": (MAX_BODIES - 1, 2),
    "by_yaw": (MAX_BODIES - 1,),
    "by_height": (MAX_BODIES - 1,),
    "by_sway_amp": (MAX_BODIES - 1,),
    "by_sway_freq": (MAX_BODIES - 1,),
    "by_sway_phase": (MAX_BODIES - 1,),
    "by_target": (MAX_BODIES - 1, 2),
    "by_speed": (MAX_BODIES - 1,),
    "by_moving": (MAX_BODIES - 1,),
}

# Draw layout of one frame (see the package docstring).
Z_JOINT = 0
Z_BURST = 3 * NUM_JOINTS
Z_HAND_WHITE = Z_BURST + 3 * MAX_LIMB_JOINTS
Z_HAND_AR = Z_HAND_WHITE + 3
Z_BODIES = Z_HAND_AR + 3
BODY_DRAWS = 3
B_BURST, B_NEW_ID, B_INFERRED = 0, 1, 2
BYSTANDER_DRAWS = 10
Y_WHITE, Y_AR, Y_WALK_START, Y_WALK_DIST, Y_WALK_LATERAL, Y_WALK_SPEED = 0, 3, 6, 7, 8, 9


def bystander_offset(n_bodies: int) -> int:
    """Offset of the bystanders' block in a frame's draws."""
    return Z_BODIES + BODY_DRAWS * n_bodies


def draw_size(n_bodies: int) -> int:
    """Normals drawn per user and frame for ``n_bodies`` bodies (target + bystanders)."""
    return bystander_offset(n_bodies) + BYSTANDER_DRAWS * (n_bodies - 1)

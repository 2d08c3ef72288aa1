"""Kinect v2 body-tracking model: joints, wrist orientation, tracking states and body ids.

The model turns the target user's true skeleton (world frame, from :mod:`vrloco_env.user.motion`)
into what the Kinect v2 SDK hands an application at 30 frames/s: up to six body slots, each with a
tracking id, 25 joints in camera space with a per-joint tracking state, and the right wrist's
orientation quaternion. It adds what makes the real sensor hard to use (Yao 2023, section 1):

* joint noise whose standard deviation grows with depth, part white and part temporally correlated
  (an AR(1) process), plus a per-session offset of every joint;
* jitter bursts: now and then one limb jitters strongly for a few frames;
* a noisy wrist orientation (white + AR(1) rotation noise: its level calibrated to Yao 2023
  Tables 1-3, its white share measured on a real Kinect v2 recording);
* tracking states: joints outside the field of view or depth range are not tracked (NaN); joints
  hidden behind a torso (the user's own or another body's), or in a short random episode, are
  *inferred* and noisier; a body with most of its joints out of view or hidden is lost, and gets a
  new id when it is acquired again;
* facing: the tracker expects people to face the sensor. A body turned side-on past
  ``KinectSpec.facing_inferred_deg`` (its torso's facing, from its shoulder and hip lines, against
  its line of sight to the sensor) has the arm and leg on its far side inferred (the right hand,
  when the right side is the far one); turned past ``facing_lost_deg`` it is not detected: it is
  lost, and acquired again with a new id once it turns back (the same rule for every body);
* bystanders: other people standing and swaying farther away, now and then walking in or out of
  view, in random slots, so the target user must be chosen (nearest tracked body). Their noise has
  the same per-joint std, white fraction and time constants as the target's, but one noise vector
  per frame moves all their joints (and their wrist): a rigidly jittering skeleton, drawn at lower
  dimension for speed (an engineering decision: bystanders matter by where they stand and
  whom they hide, not by the shape of their jitter);
* optional latency of a whole number of frames.

Frames and conventions
----------------------
*World*: ENU, z up, the floor at z = 0 (see :mod:`estimators.rotations`).

*Camera space* follows the Kinect v2 SDK (``CameraSpacePoint``): origin at the depth sensor, +z out
of the sensor toward the scene, +y up, +x to the sensor's left (right-handed; a user facing the
sensor has her right hand at +x). :func:`world_to_camera` / :func:`camera_to_world` convert points;
:func:`quat_world_to_camera` / :func:`quat_camera_to_world` convert orientations.

*Hand frame* (what the motion model gives in the world): x along the forearm toward the
fingertips, y to the left of the palm (the thumb side of a right hand held palm-down), z out of the
back of the hand.

*Wrist frame* (what :attr:`KinectFrames.hand_quat` reports): the Kinect v2 SDK's joint frame for
WristRight. The SDK gives a joint's orientation as the absolute orientation, in camera space, of
the bone ending at the joint, with "bone direction Y, normal Z, binormal X" (Kinect v2 SDK
documentation, as answered on the MSDN Kinect v2 forum, 2014): +y along the forearm (elbow ->
wrist). We fix the two free axes as binormal x = back of the hand (hand z) and normal z = thumb side
(hand y), i.e. SDK (x, y, z) = hand (z, x, y) (:data:`HAND_FROM_SDK_WRIST`). The model reports
the hand's orientation in that convention (for a straight wrist the forearm and the hand's x axis
coincide; the poses of :func:`standing_skeleton` and motion.py keep the wrist straight).
``hand_quat`` is the Hamilton quaternion [w, x, y, z] rotating wrist-frame vectors into camera
space; :func:`hand_to_sdk_wrist` / :func:`sdk_wrist_to_hand` convert from / to the hand frame.

Yao 2023's eq (1) on this quaternion — an engineering decision
----------------------------------------------------------------
Eq (1) names ``atan2(2(wx + yz), 1 - 2(x^2 + y^2))`` "yaw" (in :mod:`estimators.rotations`'s ZYX
naming that is the *roll*, ``quat_to_ypr(q)[..., 2]``, the rotation about the frame's own x axis),
``asin(2(wy - zx))`` "pitch" (our pitch, ``[..., 1]``) and ``atan2(2(wz + xy), 1 - 2(y^2 + z^2))``
"roll" (our *yaw* about z, ``[..., 0]``). With the SDK frame and the forearm pointing at the sensor
— the posture of :mod:`vrloco_env.user.motion` (right arm held forward, user facing the Kinect) and
of a user reaching toward it — these names are the hand's own, as for an aircraft whose nose is the
fingertips. Starting from the rest pose (palm down, pointing at the sensor) and rotating about one
hand axis:

    paper "roll"  = quat_to_ypr(q)[..., 0] =  90 deg - turn about the forearm (hand roll)
    paper "pitch" = quat_to_ypr(q)[..., 1] =           fingertips up/down    (hand pitch)
    paper "yaw"   = quat_to_ypr(q)[..., 2] = -90 deg + sweep left/right      (hand yaw)

(combined rotations couple, as for any Euler set). Eq (2)'s singularity is where the back of the
hand faces the sensor or away from it (e.g. fingertips straight up or down); the rest pose is
90 deg from it, and motion.py's hand limits (pitch within +-80 deg) stay clear of it for single-axis
rotations.

One would like the turn about the forearm to be the paper's "yaw", as the paper's text says
(its Tables 1-3 sweep "yaw" from -90 to 90 deg turning the hand about the bone). That cannot hold
together with the SDK's bone-on-+y convention: right-multiplying by a rotation about a frame axis
changes exactly the last ZYX angle only for the x axis, so "yaw" follows the forearm only if the
forearm is the x axis of the frame fed to eq (1) — and then eq (1) is singular (pitch = 90 deg)
whenever the forearm points at the sensor, which is motion.py's rest pose. We keep the SDK
convention, which is lock-free there, and read the paper's 11 "yaw angles" as turns about the
forearm: in this model they move eq (1)'s "roll". Whoever needs the other reading gets it with
``sdk_wrist_to_hand(q)`` (forearm on x; then eq (1)'s "yaw" is the turn, singular for a hand
pointing at the sensor but fine for a raised hand).

Randomness and speed
--------------------
Every number comes from the :class:`~vrloco_env.batch_rng.BatchRng` passed in:
:meth:`KinectV2.reset` draws the session (slots, ids, joint offsets, noise states, bystanders) and
:meth:`KinectV2.capture` draws a fixed block of normals per frame (125 with two bystanders; layout
and the devices that keep it small -- event thresholds, split uniforms, the white + AR(1) joint
noise as one ARMA(1, 1) process -- in :mod:`vrloco_env.sensors.kinect._kernel`), so a batch of B
users reproduces B single runs bit for bit and a capture split into chunks equals one capture.
The frames are computed by one compiled kernel (``_kernel.capture_frames``, explicit loops
over users, frames, bodies and joints; its uncompiled ``py_func`` is the reference the tests compare
it with): ``benchmarks/bench_sensors.py`` times a capture of 3 frames.
:meth:`KinectV2.reset` redraws all users, or only those given (``users=``), from their own
streams and leaving the others' state alone, so a vector env can start a new episode for one user
while the others carry on (every per-user state, the frame counter included, is a (B, ...) array).

Modules: :mod:`~vrloco_env.sensors.kinect.spec` (the specification and joint tables),
:mod:`~vrloco_env.sensors.kinect.frames` (the frames delivered and the frame conversions),
:mod:`~vrloco_env.sensors.kinect.skeleton` (a standing skeleton),
:mod:`~vrloco_env.sensors.kinect.model` (the sensor :class:`KinectV2`) and
:mod:`~vrloco_env.sensors.kinect._kernel` (its compiled frame loop).
"""

from vrloco_env.sensors.kinect.frames import (
    HAND_FROM_SDK_WRIST,
    KinectFrames,
    KinectTruth,
    camera_quat,
    camera_to_world,
    hand_to_sdk_wrist,
    quat_camera_to_world,
    quat_world_to_camera,
    sdk_wrist_to_hand,
    world_to_camera,
)
from vrloco_env.sensors.kinect.model import KinectV2
from vrloco_env.sensors.kinect.skeleton import standing_skeleton
from vrloco_env.sensors.kinect.spec import LIMB_GROUPS, MAX_BODIES, TORSO_JOINTS, KinectSpec

__all__ = [
    "HAND_FROM_SDK_WRIST",
    "LIMB_GROUPS",
    "MAX_BODIES",
    "TORSO_JOINTS",
    "KinectFrames",
    "KinectSpec",
    "KinectTruth",
    "KinectV2",
    "camera_quat",
    "camera_to_world",
    "hand_to_sdk_wrist",
    "quat_camera_to_world",
    "quat_world_to_camera",
    "sdk_wrist_to_hand",
    "standing_skeleton",
    "world_to_camera",
]

"""The Kinect v2 model on a short capture that takes every branch of its frame kernel.

Jitter bursts, random inferred episodes, torso occlusion, walking bystanders, a target lost and
acquired again with a new id (out of view, or turned away), a target turned side-on (its far limbs
inferred), latency, a capture in two chunks; two users (the serial build; the multi-threaded one
is pinned by the golden vector env).
"""

import numpy as np

from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.kinect import KinectSpec, KinectV2, standing_skeleton

SPEC = KinectSpec(
    n_bystanders=3,
    burst_prob=0.1,
    random_inferred_prob=0.02,
    bystander_dwell_s=0.3,
    latency_frames=1,
)
FRAMES = 40


def inputs(b: int = 2, m: int = FRAMES):
    """Frame times (m,) s, true joints (b, m, 25, 3) m and hands (b, m, 4): different users
    (distance, facing, hand turn, a moving body); user 1 steps out of view for frames 12-19,
    user 0 turns side-on (80 deg) for frames 4-9 and away from the sensor (150 deg) for frames
    26-31."""
    rng = np.random.default_rng(42)
    pos = np.zeros((b, 3))
    pos[:, 0] = rng.uniform(0.0, 0.8, b)
    yaw = rng.uniform(-0.3, 0.3, b)[:, None] + np.zeros((b, m))
    yaw[0, 4:10] = np.radians(80.0)
    yaw[0, 26:32] = np.radians(150.0)
    joints, q = standing_skeleton(
        pos[:, None], yaw, right_arm="forward", hand_ypr_rad=rng.uniform(-1, 1, (b, 1, 3))
    )
    jw = joints + 0.05 * np.sin(np.arange(m) / 10.0)[None, :, None, None]
    jw[1, 12:20, :, 1] -= 4.0
    return np.arange(m) / 30.0, jw, q


def capture():
    """The frames of :func:`inputs` from a fresh sensor, captured in two chunks."""
    t, jw, qw = inputs()
    kinect = KinectV2(SPEC, BatchRng.from_seeds([11, 12]))
    kinect.reset()
    cut = 25
    return [kinect.capture(t[a:b], jw[:, a:b], qw[:, a:b]) for a, b in ((0, cut), (cut, FRAMES))]


def _play():
    out = {}
    for k, frames in enumerate(capture()):
        for name in ("body_tracked", "joints", "joint_state", "hand_quat"):
            out[f"{name}_{k}"] = getattr(frames, name)
        out[f"body_id_{k}"] = frames.body_id & 0xFFFFF  # low bits: exact under the tolerance
        out[f"truth_joints_{k}"] = frames.truth.joints
        out[f"truth_hand_{k}"] = frames.truth.hand_quat
    return out


CASES = {"kinect_capture": _play}

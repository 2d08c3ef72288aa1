"""The hand pipeline (target selection, Holt, eq (1)/(2), Kalman, median), its orientation stage
alone (OrientationFilter: eq (1)/(2) rows, the Kalman + median over angles), its joint smoothing
alone (HoltSmoother) and the env's
hand-frame arithmetic on short sequences that take every branch: reselection, a gap longer than
the Kalman's coasting, untracked and all-inferred bodies, NaN joints, NaN and zero quaternions,
gimbal lock, angles sweeping through +-180 deg, and a reset mid-sequence."""

import numpy as np

from estimators import rotations as rot
from estimators.hand import HandParams, HandPipeline, KalmanParams, OrientationFilter
from estimators.hand.joint_smoothing import HoltParams, HoltSmoother
from vrloco_env._hand_frame_numba import hand_error, hand_relative_to_torso

_K, _J, _WRIST = 3, 25, 10


def _sequence(seed: int, b: int = 2, m: int = 36) -> dict[str, np.ndarray]:
    """(B, M, ...) Kinect frames: two bodies per stream with every edge case."""
    rng = np.random.default_rng(seed)
    t = np.arange(m)
    seq = {
        "body_id": np.zeros((b, m, _K), np.int64),
        "body_tracked": np.zeros((b, m, _K), bool),
        "joints": np.full((b, m, _K, _J, 3), np.nan),
        "joint_state": np.zeros((b, m, _K, _J), np.int8),
        "hand_quat": np.full((b, m, _K, 4), np.nan),
    }
    offsets = rng.uniform(-0.4, 0.4, (_J, 3))
    for i in range(b):
        for slot, bid, depth in ((0, 5 + i, 2.0), (2, 9, 3.0)):
            present = rng.random(m) > 0.1
            seq["body_id"][i, present, slot] = bid
            seq["body_tracked"][i, present, slot] = True
            walk = np.cumsum(rng.normal(0.0, 0.01, (m, 3)), axis=0) + np.array([0.0, 0.0, depth])
            seq["joints"][i, :, slot] = np.where(
                present[:, None, None],
                walk[:, None] + offsets + rng.normal(0.0, 0.004, (m, _J, 3)),
                np.nan,
            )
            inferred = rng.random(m) < 0.15  # the whole body inferred
            seq["joint_state"][i, present, slot] = np.where(inferred, 1, 2)[present, None]
            yaw = np.deg2rad(178.0 + 25.0 * np.sin(2 * np.pi * t / 12.0))  # crosses +-180 deg
            pitch = np.where(rng.random(m) < 0.2, np.deg2rad(89.5), 0.3)  # eq (2) or eq (1)
            q = rot.quat_from_ypr(np.stack([yaw, pitch, -0.2 + 0 * t], axis=-1))
            q[rng.random(m) < 0.1] = np.nan
            q[rng.random(m) < 0.1] = 0.0
            seq["hand_quat"][i, :, slot] = np.where(present[:, None], q * 1.7, np.nan)
        lost = rng.random(m) < 0.08
        seq["joints"][i, lost, 0, _WRIST] = np.nan
        seq["joint_state"][i, lost, 0, _WRIST] = 0
    seq["body_tracked"][:, 12:20] = False  # 8 frames without a body: coast, stale, reselect
    seq["body_tracked"][0, 24:27, 0] = False  # the target untracked: the other body is taken
    return seq


def _pipeline(params: HandParams | None):
    def play():
        seq = _sequence(3)
        b, m = seq["body_id"].shape[:2]
        pipe = HandPipeline(b, params, num_joints=_J, num_bodies=_K)
        out: dict[str, list[np.ndarray]] = {}
        for t in range(0, m, 3):
            if t == 27:
                pipe.reset(np.arange(b) == 1)
            if t % 2:
                frames = [
                    pipe.update(**{k: v[:, u] for k, v in seq.items()}) for u in range(t, t + 3)
                ]
            else:
                chunk = pipe.update_frames(**{k: v[:, t : t + 3] for k, v in seq.items()})
                frames = [chunk.at(i) for i in range(3)]
            for fr in frames:
                for name, value in vars(fr).items():
                    out.setdefault(name, []).append(np.asarray(value, dtype=np.float64))
        return {name: np.stack(v, axis=1) for name, v in out.items()}

    return play


def _orientation(params: HandParams | None):
    def play():
        seq = _sequence(4)
        q = seq["hand_quat"][:, :, 0]  # (B, M, 4): NaN, zero, eq (2) and wrapping quaternions
        b, m = q.shape[:2]
        valid = np.isfinite(seq["joints"][:, :, 0, _WRIST]).all(axis=-1)
        reset = np.zeros((b, m), bool)
        reset[1, 20] = True
        f = OrientationFilter(b, params)
        first = f.update_frames(q[:, :18], valid[:, :18], reset[:, :18])
        f.reset(np.arange(b) == 0)
        second = f.update_frames(q[:, 18:], valid[:, 18:], reset[:, 18:])
        again = OrientationFilter(b, params).update_angles(
            np.concatenate([first.ypr_raw, second.ypr_raw], axis=1),
            np.concatenate([first.quat_valid, second.quat_valid], axis=1),
            reset,
        )
        out = {
            name: np.concatenate([getattr(first, name), getattr(second, name)], axis=1)
            for name in ("ypr_raw", "ypr_kalman", "ypr", "quat_valid", "singular", "valid")
        }
        out.update({f"angles_{k}": getattr(again, k) for k in ("ypr_kalman", "ypr", "valid")})
        return {k: np.asarray(v, dtype=np.float64) for k, v in out.items()}

    return play


def _holt(params: HoltParams | None):
    def play():
        seq = _sequence(6)
        joints, state = seq["joints"][:, :, 0], seq["joint_state"][:, :, 0]  # (B, M, J, ...)
        b, m = joints.shape[:2]
        h = HoltSmoother(b, _J, params)
        out, holt = [], []
        for t in range(m):
            reset = (np.arange(b) == 1) if t == 20 else None
            out.append(h.update(joints[:, t], state[:, t] if t % 5 else None, reset))
            holt.append(h.holt_output)
        return {"joints": np.stack(out, axis=1), "holt": np.stack(holt, axis=1)}

    return play


def _hand_frame():
    rng = np.random.default_rng(5)
    b = 6
    ypr = rng.uniform(-3.0, 3.0, (b, 3))
    ypr[1, 1] = np.nan
    valid = np.array([True, True, False, True, True, True])
    left, right = rng.normal(size=(b, 3)), rng.normal(size=(b, 3))
    left[3, 2] = np.nan
    cam = np.array([0.9, 0.1, -0.2, 0.3])
    cam /= np.linalg.norm(cam)
    sdk_to_hand = np.array([0.5, 0.5, -0.5, 0.5])
    rel = np.empty((b, 3))
    hand_relative_to_torso(b)(ypr, valid, left, right, cam, sdk_to_hand, rel)
    return {"relative": rel, "error": hand_error(rel, rng.uniform(-1.0, 1.0, (b, 3)))}


CASES = {
    "hand_pipeline_default": _pipeline(None),
    "hand_pipeline_window4_tracked_wrist": _pipeline(
        HandParams(median_window=4, min_wrist_state=2)
    ),
    "hand_pipeline_no_average_plain_kalman": _pipeline(
        HandParams(
            holt=HoltParams(average_weights=(1.0,)),
            kalman=KalmanParams(max_coast_frames=0, accel_psd=0.01, max_accel_psd=0.01),
            median_window=1,
            singularity_threshold=0.45,
        )
    ),
    "hand_orientation_default": _orientation(None),
    "hand_orientation_window4_plain_kalman": _orientation(
        HandParams(
            kalman=KalmanParams(max_coast_frames=0, accel_psd=0.01, max_accel_psd=0.01),
            median_window=4,
            singularity_threshold=0.45,
        )
    ),
    "hand_holt_default": _holt(None),
    "hand_holt_no_average": _holt(HoltParams(average_weights=(1.0,))),
    "hand_frame": _hand_frame,
}

"""The Kinect v2 frame loop (:mod:`vrloco_env.sensors.kinect._kernel`): :data:`capture_frames`
runs every stage per user and frame (:mod:`~vrloco_env.sensors.kinect._kernel.scene`,
:mod:`~vrloco_env.sensors.kinect._kernel.tracking`,
:mod:`~vrloco_env.sensors.kinect._kernel.noise`), its serial and multi-threaded builds compiled
by :class:`~estimators.kernels.batch.BatchKernel` (``numba.njit(cache=True)``);
``capture_frames.py_func`` is the readable uncompiled source.
"""

from __future__ import annotations

import numba
import numpy as np

from estimators.kernels.batch import BatchKernel
from estimators.kernels.rotations import quat_mul
from vrloco_env.sensors.kinect._kernel.layout import BODY_DRAWS, Z_BODIES
from vrloco_env.sensors.kinect._kernel.noise import _body_out, _episodes, _noise_states
from vrloco_env.sensors.kinect._kernel.scene import _bystanders, _camera_space, _facing, _occlusion
from vrloco_env.sensors.kinect._kernel.tracking import _track
from vrloco_env.user import NOT_TRACKED, NUM_JOINTS

__all__ = ["capture_frames"]


def _capture_frames(joints_world, hand_world, z, new_ids, prm, geo, state, out) -> None:
    """Run M frames for B users, updating the session state in place and filling the outputs.

    Per user and frame, in stages: the bystanders move (:func:`_bystanders`), every body into
    camera space and the field of view (:func:`_camera_space`), each body's facing
    (:func:`_facing`), occlusion by the torsos and of turned bodies' far-side limbs
    (:func:`_occlusion`), tracking and ids (:func:`_track`), jitter bursts and random inferred
    episodes (:func:`_episodes`), the noise states (:func:`_noise_states`), then each body's
    slot (:func:`_body_out`).

    Args (shapes; B users, M frames, N bodies, nb = N - 1 bystanders, K = 6 slots, J = 25):
        joints_world: (B, M, J, 3) m, the target's true joints in the world.
        hand_world: (B, M, 4) the target's unit hand quaternion, hand frame -> world.
        z: (B, M, draw_size(N)) standard normals (layout in the package docstring).
        new_ids: (B, M, N) int64, the id each body gets if it is acquired in that frame.
        prm: (1,) parameter record: :class:`~vrloco_env.sensors.kinect.KinectSpec`'s fields and
            the derived values of ``KinectV2._param_record`` (SI units).
        geo: (1,) record of :data:`GEOMETRY_FIELDS`: the sensor's pose and per-joint tables.
        state: (B,) records of :data:`STATE_FIELDS`, the users' sessions, updated in place.
        out: the slots' frames ``(body_id, body_tracked, joints, joint_state, hand_quat)``,
            (B, M, K, ...), and the target's camera-space truth ``(truth_joints, truth_hand)``,
            (B, M, J, 3) m and (B, M, 4), filled here.
    """
    out_id, out_tracked, out_joints, out_state, out_hand, truth_joints, truth_hand = out
    B, M = joints_world.shape[0], joints_world.shape[1]
    K = out_id.shape[2]
    J = NUM_JOINTS

    for b in numba.prange(B):  # users are independent (estimators.kernels.batch)
        # The records are read inside the loop (the parallel build takes no record value in), and
        # the session's sub-arrays are bound right after ``s``: numba's parallel build keeps the
        # writes through names it sees derive from an argument, and may drop others.
        p, g, s = prm[0], geo[0], state[b]
        slot = s["slot"]
        body_id = s["body_id"]
        acquired = s["acquired"]
        prev_tracked = s["prev_tracked"]
        bias = s["bias"]
        noise = (s["joint_noise"], s["joint_innov"], s["ar_hand"], s["ar_by"])
        episodes = (s["burst_left"], s["burst_group"], s["inferred_left"])
        by = (
            s["by_pos"],
            s["by_yaw"],
            s["by_height"],
            s["by_sway_amp"],
            s["by_sway_freq"],
            s["by_sway_phase"],
            s["by_target"],
            s["by_speed"],
            s["by_moving"],
        )
        N = int(p["n_bystanders"]) + 1
        nb = N - 1
        z_by = Z_BODIES + BODY_DRAWS * N  # bystander_offset(N)
        cam_rot, cam_pos, cq = g["cam_rot"], g["cam_pos"], g["cam_quat"]
        cq_inv = (cq[0], -cq[1], -cq[2], -cq[3])  # world -> camera
        # Scratch of this user (users run in parallel: nothing is shared). Each body's joints in
        # camera space are an affine map of a source skeleton: the target's world joints, or the
        # bystander template.
        src = np.empty((N, J, 3))
        for n in range(1, N):
            src[n] = g["by_template"]
        aff = np.empty((N, 3, 4))  # camera point = aff[:, :3] @ source point + aff[:, 3]
        view = (
            np.empty((N, J, 3)),
            np.empty((N, J)),
            np.empty((N, J)),
            np.empty((N, J), dtype=np.bool_),
        )  # cam, image x / z, y / z, in view
        hand_cam = np.empty((N, 4))
        occluded = np.empty((N, J), dtype=np.bool_)  # by a torso or a random inferred episode
        torso = (np.empty(N), np.empty(N), np.empty(N), np.empty(N), np.empty(N))
        pose = (np.empty(N), np.empty(N))  # facing (deg), near side (+1 left, -1 right)
        n_visible = np.empty(N, dtype=np.int64)
        tracked = np.empty(N, dtype=np.bool_)
        fresh = np.empty(N, dtype=np.bool_)
        b_active = np.empty(N, dtype=np.bool_)
        body_of_slot = np.empty(K, dtype=np.int64)
        # The target: camera = R^T world - R^T c.
        for a in range(3):
            for i in range(3):
                aff[0, a, i] = cam_rot[i, a]
            aff[0, a, 3] = -(cam_rot[0, a] * cam_pos[0] + cam_rot[1, a] * cam_pos[1])
            aff[0, a, 3] -= cam_rot[2, a] * cam_pos[2]
        frame = (view, occluded, hand_cam, tracked, b_active, episodes[1], bias)

        body_of_slot[:] = -1
        for n in range(N):
            body_of_slot[int(slot[n])] = n
        for m in range(M):
            zf = z[b, m]
            src[0] = joints_world[b, m]
            hand_cam[0, 0], hand_cam[0, 1], hand_cam[0, 2], hand_cam[0, 3] = quat_mul(
                cq_inv[0],
                cq_inv[1],
                cq_inv[2],
                cq_inv[3],
                hand_world[b, m, 0],
                hand_world[b, m, 1],
                hand_world[b, m, 2],
                hand_world[b, m, 3],
            )
            _bystanders(zf, z_by, nb, (s["frame"] + m) * p["dt"], p, g, by, aff, hand_cam, cq_inv)
            _camera_space(N, p, src, aff, view)
            _facing(N, g, view[0], pose)
            _occlusion(N, p, g, view, pose, occluded, n_visible, torso)
            _track(
                N,
                p,
                n_visible,
                pose[0],
                (acquired, prev_tracked, body_id),
                new_ids[b, m],
                tracked,
                fresh,
            )
            _episodes(N, zf, p, g, episodes, b_active, occluded)
            _noise_states(zf, z_by, nb, p, noise)
            for k in range(K):
                if body_of_slot[k] < 0:
                    out_id[b, m, k] = 0
                    out_tracked[b, m, k] = False
                    out_state[b, m, k] = NOT_TRACKED
                    out_joints[b, m, k] = np.nan
                    out_hand[b, m, k] = np.nan
            for n in range(N):
                k = int(slot[n])
                out_id[b, m, k] = int(body_id[n]) if tracked[n] else 0
                out_tracked[b, m, k] = tracked[n]
                _body_out(
                    n,
                    zf,
                    z_by,
                    p,
                    g,
                    frame,
                    noise,
                    (out_joints[b, m, k], out_state[b, m, k], out_hand[b, m, k], truth_hand[b, m]),
                )
            truth_joints[b, m] = view[0][0]
        s["frame"] += M


capture_frames = BatchKernel(_capture_frames)
"""The Kinect's frames for B users: ``capture_frames(B)(...)`` (see ``_capture_frames``)."""

"""Stages 6 to 8 of the Kinect v2 frame loop (:mod:`vrloco_env.sensors.kinect._kernel`), compiled
(``numba.njit(cache=True)``): jitter bursts and random inferred episodes (:func:`_episodes`), the
noise states (:func:`_noise_states`), and each body's slot with its tracking states, noisy joints
and wrist orientation (:func:`_body_out`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from estimators.kernels.rotations import quat_from_rotvec, quat_mul
from vrloco_env.sensors.kinect._kernel.draws import (
    _BELOW_ONE,
    bernoulli_split,
    categorical_split,
    geometric_split,
    uniform,
)
from vrloco_env.sensors.kinect._kernel.layout import (
    B_BURST,
    B_INFERRED,
    BODY_DRAWS,
    BYSTANDER_DRAWS,
    N_LIMB_GROUPS,
    WRIST_RIGHT,
    Y_AR,
    Z_BODIES,
    Z_BURST,
    Z_HAND_AR,
    Z_HAND_WHITE,
    Z_JOINT,
)
from vrloco_env.user import INFERRED, NOT_TRACKED, NUM_JOINTS, TRACKED


@numba.njit(cache=True)
def _episodes(n_bodies, zf, p, g, episodes, b_active, occluded) -> None:
    """Stage 6, jitter bursts (one limb, a few frames) and random inferred episodes.
    ``episodes`` = (burst_left, burst_group (N,), inferred_left (N, J)), the session's, updated
    in place; fills ``b_active`` (N,) and marks the joints of inferred episodes in ``occluded``."""
    burst_left, burst_group, inferred_left = episodes
    inferred_z = g["inferred_z"]
    n_len = int(p["burst_max"]) - int(p["burst_min"]) + 1
    for n in range(n_bodies):
        zb = zf[Z_BODIES + BODY_DRAWS * n :]
        if burst_left[n] == 0.0 and zb[B_BURST] < p["burst_z"]:
            # Given the start, ndtr(z) / p is uniform: it picks the limb, then the length.
            u = min(uniform(zb[B_BURST]) / p["burst_prob"], _BELOW_ONE)
            burst_group[n], u = categorical_split(u, N_LIMB_GROUPS)
            length, u = categorical_split(u, n_len)
            burst_left[n] = int(p["burst_min"]) + length
        b_active[n] = burst_left[n] > 0.0
        burst_left[n] = max(burst_left[n] - 1.0, 0.0)
        # Every joint not in an episode starts one with probability p, of geometric length.
        # Trials and lengths are one chain of splits of one uniform; most frames have no start
        # at all (u >= 1 - (1 - p)^k for k free joints), which one comparison tells.
        free = 0
        for j in range(NUM_JOINTS):
            if inferred_left[n, j] == 0:
                free += 1
        if zb[B_INFERRED] < inferred_z[free]:
            u = uniform(zb[B_INFERRED])
            for j in range(NUM_JOINTS):
                if inferred_left[n, j] == 0:
                    hit, u = bernoulli_split(u, p["random_inferred_prob"])
                    if hit:
                        inferred_left[n, j], u = geometric_split(u, p["inferred_q"])
        for j in range(NUM_JOINTS):
            if inferred_left[n, j] > 0:
                occluded[n, j] = True
                inferred_left[n, j] -= 1


@numba.njit(cache=True)
def _noise_states(zf, z_by, nb, p, noise) -> None:
    """Stage 7, noise states: the target's ARMA(1, 1) joint noise (unit variance); unit AR(1)
    states of every wrist and of the bystanders' joint noise (a bystander's wrist and joints
    share their innovations). ``noise`` = the session's (joint_noise, joint_innov, ar_hand,
    ar_by), updated in place."""
    joint_noise, joint_innov, ar_hand, ar_by = noise
    rho_j, rho_h = p["rho_joint"], p["rho_hand"]
    c_j, c_h = math.sqrt(1.0 - rho_j * rho_j), math.sqrt(1.0 - rho_h * rho_h)
    arma_s, arma_theta = p["arma_s"], p["arma_theta"]
    for j in range(NUM_JOINTS):
        for a in range(3):
            e = zf[Z_JOINT + 3 * j + a]
            joint_noise[j, a] = rho_j * joint_noise[j, a] + arma_s * (
                e + arma_theta * joint_innov[j, a]
            )
            joint_innov[j, a] = e
    for a in range(3):
        ar_hand[0, a] = rho_h * ar_hand[0, a] + c_h * zf[Z_HAND_AR + a]
    for i in range(nb):
        zi = zf[z_by + BYSTANDER_DRAWS * i :]
        for a in range(3):
            ar_hand[i + 1, a] = rho_h * ar_hand[i + 1, a] + c_h * zi[Y_AR + a]
            ar_by[i, a] = rho_j * ar_by[i, a] + c_j * zi[Y_AR + a]


@numba.njit(cache=True)
def _body_out(n, zf, z_by, p, g, frame, noise, row) -> None:
    """Stage 8, one body's slot: tracking states, noisy joints, wrist orientation. ``frame`` =
    (view, occluded, hand_cam, tracked, b_active, burst_group, bias) of this frame and session,
    ``noise`` the session's noise states (:func:`_noise_states`), ``row`` = the slot's (joints
    (J, 3), joint_state (J,), hand_quat (4,)) of this frame, and the target's truth hand (4,)."""
    view, occluded, hand_cam, tracked, b_active, burst_group, bias = frame
    cam, _, _, in_view = view
    joint_noise, _, ar_hand, ar_by = noise
    out_joints, out_state, out_hand, truth_hand = row
    sdk, joint_scale, limb_index = g["sdk_from_hand"], g["joint_scale"], g["limb_index"]
    hand_white_sd, hand_ar_sd = g["hand_white_sd"], g["hand_ar_sd"]
    noise_a, noise_b, ref_std = p["noise_a"], p["noise_b"], p["ref_std"]
    burst_pos = p["burst_position_std_m"]
    wf = p["joint_noise_white_fraction"]
    sq_ar = math.sqrt(1.0 - wf)
    grp = int(burst_group[n]) if b_active[n] else -1
    # White normals of the wrist (target) or of the whole body (bystander).
    zw = zf[Z_HAND_WHITE:] if n == 0 else zf[z_by + BYSTANDER_DRAWS * (n - 1) :]
    w0, w1, w2 = zw[0], zw[1], zw[2]
    a0, a1, a2 = 0.0, 0.0, 0.0
    if n > 0:
        a0, a1, a2 = ar_by[n - 1, 0], ar_by[n - 1, 1], ar_by[n - 1, 2]
    wrist_factor = 1.0
    for j in range(NUM_JOINTS):
        if not (tracked[n] and in_view[n, j]):
            out_state[j] = NOT_TRACKED
            for a in range(3):
                out_joints[j, a] = np.nan
            continue
        factor = 1.0
        if occluded[n, j]:
            out_state[j] = INFERRED
            factor = p["inferred_noise_factor"]
        else:
            out_state[j] = TRACKED
        if j == WRIST_RIGHT:
            wrist_factor = factor
        d = cam[n, j, 2]
        sigma = (noise_a + noise_b * d * d) * joint_scale[j] * factor
        limb = int(limb_index[grp, j]) if grp >= 0 else -1
        if n == 0:  # the target: independent noise per joint, burst noise per joint
            for a in range(3):
                pos = cam[0, j, a] + bias[0, j, a] + sigma * joint_noise[j, a]
                if limb >= 0:
                    pos += burst_pos * zf[Z_BURST + 3 * limb + a]
                out_joints[j, a] = pos
        else:  # a bystander: its rigid noise vectors, scaled per joint
            burst = burst_pos if limb >= 0 else 0.0
            white = math.sqrt(wf * sigma * sigma + burst * burst)
            ar = sq_ar * sigma
            out_joints[j, 0] = cam[n, j, 0] + bias[n, j, 0] + white * w0 + ar * a0
            out_joints[j, 1] = cam[n, j, 1] + bias[n, j, 1] + white * w1 + ar * a1
            out_joints[j, 2] = cam[n, j, 2] + bias[n, j, 2] + white * w2 + ar * a2
    # Wrist orientation: white + AR(1) rotation noise about the hand axes, scaled with the joint
    # noise at the wrist's depth, then into the SDK wrist frame.
    qw_, qx_, qy_, qz_ = hand_cam[n, 0], hand_cam[n, 1], hand_cam[n, 2], hand_cam[n, 3]
    if n == 0:
        truth_hand[0], truth_hand[1], truth_hand[2], truth_hand[3] = quat_mul(
            qw_, qx_, qy_, qz_, sdk[0], sdk[1], sdk[2], sdk[3]
        )
    if out_state[WRIST_RIGHT] == NOT_TRACKED:
        out_hand[:] = np.nan
        return
    d = cam[n, WRIST_RIGHT, 2]
    f_w = wrist_factor
    if ref_std > 0:
        f_w *= (noise_a + noise_b * d * d) / ref_std
    burst = p["burst_rot"] if grp == 0 else 0.0
    r0 = math.sqrt((f_w * hand_white_sd[0]) ** 2 + burst * burst) * w0
    r1 = math.sqrt((f_w * hand_white_sd[1]) ** 2 + burst * burst) * w1
    r2 = math.sqrt((f_w * hand_white_sd[2]) ** 2 + burst * burst) * w2
    r0 += f_w * hand_ar_sd[0] * ar_hand[n, 0]
    r1 += f_w * hand_ar_sd[1] * ar_hand[n, 1]
    r2 += f_w * hand_ar_sd[2] * ar_hand[n, 2]
    ew, ex_, ey_, ez_ = quat_from_rotvec(r0, r1, r2)
    nw, nx, ny, nz = quat_mul(qw_, qx_, qy_, qz_, ew, ex_, ey_, ez_)
    out_hand[0], out_hand[1], out_hand[2], out_hand[3] = quat_mul(
        nw, nx, ny, nz, sdk[0], sdk[1], sdk[2], sdk[3]
    )

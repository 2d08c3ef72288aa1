"""Stages 1 to 4 of the Kinect v2 frame loop (:mod:`vrloco_env.sensors.kinect._kernel`), compiled
(``numba.njit(cache=True)``): where the bodies are and what the sensor sees of them. The
bystanders stand and walk (:func:`_bystanders`), every body's joints go into camera space and
the field of view (:func:`_camera_space`), each body's facing relative to the sensor
(:func:`_facing`), and occlusion by the torsos and of a turned body's far-side limbs
(:func:`_occlusion`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from estimators.kernels.rotations import quat_mul
from vrloco_env.sensors.kinect._kernel.draws import uniform
from vrloco_env.sensors.kinect._kernel.layout import (
    BYSTANDER_DRAWS,
    HIP_LEFT,
    HIP_RIGHT,
    N_TORSO_JOINTS,
    SHOULDER_LEFT,
    SHOULDER_RIGHT,
    Y_WALK_DIST,
    Y_WALK_LATERAL,
    Y_WALK_SPEED,
    Y_WALK_START,
)
from vrloco_env.user import NUM_JOINTS


@numba.njit(cache=True)
def _bystanders(zf, z_by, nb, t_frame, p, g, by, aff, hand_cam, cq) -> None:
    """Stage 1, the bystanders: each stands for an exponential time, then walks at a random speed
    to a random spot of the bystander area (sensor floor frame: d along the axis, l to its left);
    its pose (yaw, quiet-standing sway on the frame clock ``t_frame`` s, height) goes into its
    affine map ``aff[i + 1]`` (camera point of a template point) and its hand into
    ``hand_cam[i + 1]``. ``by`` = the session's (pos, yaw, height, sway amplitude, frequency,
    phase, target, speed, moving) arrays; ``cq`` the world -> camera quaternion."""
    by_pos, by_yaw, by_height, by_amp, by_freq, by_phase, by_target, by_speed, by_moving = by
    cam_rot, cam_pos, by_hand_quat = g["cam_rot"], g["cam_pos"], g["by_hand_quat"]
    dt = p["dt"]
    for i in range(nb):
        zi = zf[z_by + BYSTANDER_DRAWS * i :]
        if by_moving[i] == 0.0 and zi[Y_WALK_START] < p["walk_z"]:
            d = p["by_d0"] + (p["by_d1"] - p["by_d0"]) * uniform(zi[Y_WALK_DIST])
            lat = p["bystander_lateral_m"] * (2.0 * uniform(zi[Y_WALK_LATERAL]) - 1.0)
            by_target[i, 0] = cam_pos[0] + d * p["cam_cos"] - lat * p["cam_sin"]
            by_target[i, 1] = cam_pos[1] + d * p["cam_sin"] + lat * p["cam_cos"]
            v0, v1 = p["by_v0"], p["by_v1"]
            by_speed[i] = v0 + (v1 - v0) * uniform(zi[Y_WALK_SPEED])
            by_moving[i] = 1.0
        dx = by_target[i, 0] - by_pos[i, 0]
        dy = by_target[i, 1] - by_pos[i, 1]
        dist = math.sqrt(dx * dx + dy * dy)
        step = min(by_speed[i] * dt, dist)
        if by_moving[i] != 0.0 and dist > 1e-9:
            by_pos[i, 0] += step * dx / dist
            by_pos[i, 1] += step * dy / dist
            by_yaw[i] = math.atan2(dy, dx)
        by_moving[i] = 1.0 if by_moving[i] != 0.0 and dist - step > 1e-9 else 0.0
        # Pose: yaw about z (body -> world), quiet-standing sway as a lateral shift on the
        # bystander's own frame clock, height h: world = h Rz(yaw) template + (px, py, 0).
        ch, sh = math.cos(0.5 * by_yaw[i]), math.sin(0.5 * by_yaw[i])
        c_yaw, s_yaw = ch * ch - sh * sh, 2.0 * ch * sh
        sway = by_amp[i] * math.sin(2.0 * math.pi * by_freq[i] * t_frame + by_phase[i])
        ex = by_pos[i, 0] - sway * s_yaw - cam_pos[0]
        ey = by_pos[i, 1] + sway * c_yaw - cam_pos[1]
        h = by_height[i]
        for a in range(3):  # camera = h R^T Rz template + R^T ((px, py, 0) - c)
            aff[i + 1, a, 0] = h * (cam_rot[0, a] * c_yaw + cam_rot[1, a] * s_yaw)
            aff[i + 1, a, 1] = h * (cam_rot[1, a] * c_yaw - cam_rot[0, a] * s_yaw)
            aff[i + 1, a, 2] = h * cam_rot[2, a]
            aff[i + 1, a, 3] = cam_rot[0, a] * ex + cam_rot[1, a] * ey
            aff[i + 1, a, 3] -= cam_rot[2, a] * cam_pos[2]
        bw, bx, by_, bz = quat_mul(
            ch,
            0.0,
            0.0,
            sh,
            by_hand_quat[0],
            by_hand_quat[1],
            by_hand_quat[2],
            by_hand_quat[3],
        )
        (hand_cam[i + 1, 0], hand_cam[i + 1, 1], hand_cam[i + 1, 2], hand_cam[i + 1, 3]) = quat_mul(
            cq[0], cq[1], cq[2], cq[3], bw, bx, by_, bz
        )


@numba.njit(cache=True)
def _camera_space(n_bodies, p, src, aff, view) -> None:
    """Stage 2, camera space: every body's joints (``aff @ src``) into ``view`` = (cam (N, J, 3)
    m, image coordinates x / z and y / z (N, J), in the field of view (N, J))."""
    cam, img_u, img_v, in_view = view
    near, far, tan_h, tan_v = p["near"], p["far"], p["tan_h"], p["tan_v"]
    for n in range(n_bodies):
        for j in range(NUM_JOINTS):
            p0, p1, p2 = src[n, j, 0], src[n, j, 1], src[n, j, 2]
            x = aff[n, 0, 0] * p0 + aff[n, 0, 1] * p1 + aff[n, 0, 2] * p2 + aff[n, 0, 3]
            y = aff[n, 1, 0] * p0 + aff[n, 1, 1] * p1 + aff[n, 1, 2] * p2 + aff[n, 1, 3]
            d = aff[n, 2, 0] * p0 + aff[n, 2, 1] * p1 + aff[n, 2, 2] * p2 + aff[n, 2, 3]
            cam[n, j, 0], cam[n, j, 1], cam[n, j, 2] = x, y, d
            in_view[n, j] = d >= near and d <= far and abs(x) <= tan_h * d and abs(y) <= tan_v * d
            inv = 1.0 / max(d, 1e-3)
            img_u[n, j], img_v[n, j] = x * inv, y * inv


@numba.njit(cache=True)
def _facing(n_bodies, g, cam, pose) -> None:
    """Stage 3, facing: each body's torso facing relative to its line of sight to the sensor, and
    the side it turns toward the sensor. The torso's lateral direction is its shoulder line plus
    its hip line (right to left), its forward direction that lateral line turned a quarter turn
    about the world's vertical; the line of sight runs from the mean of those four joints to the
    sensor (the camera origin), and all three are taken horizontal. ``cam`` (N, J, 3) m: the
    bodies' joints in camera space; fills ``pose`` = (facing (N,) deg in [0, 180], 0 facing the
    sensor and 90 side-on; near_side (N,), +1 when the body's left side is the nearer, -1 its
    right)."""
    facing, near_side = pose
    up = g["cam_rot"][2]  # the world's vertical in camera space (camera = R^T world)
    ux, uy, uz = up[0], up[1], up[2]
    sl, sr = cam[:, SHOULDER_LEFT], cam[:, SHOULDER_RIGHT]
    hl, hr = cam[:, HIP_LEFT], cam[:, HIP_RIGHT]
    for n in range(n_bodies):
        # Lateral (right to left) and line of sight (torso to sensor), then their horizontal parts.
        lx = sl[n, 0] - sr[n, 0] + hl[n, 0] - hr[n, 0]
        ly = sl[n, 1] - sr[n, 1] + hl[n, 1] - hr[n, 1]
        lz = sl[n, 2] - sr[n, 2] + hl[n, 2] - hr[n, 2]
        sx = -0.25 * (sl[n, 0] + sr[n, 0] + hl[n, 0] + hr[n, 0])
        sy = -0.25 * (sl[n, 1] + sr[n, 1] + hl[n, 1] + hr[n, 1])
        sz = -0.25 * (sl[n, 2] + sr[n, 2] + hl[n, 2] + hr[n, 2])
        l_up, s_up = lx * ux + ly * uy + lz * uz, sx * ux + sy * uy + sz * uz
        lx, ly, lz = lx - l_up * ux, ly - l_up * uy, lz - l_up * uz
        sx, sy, sz = sx - s_up * ux, sy - s_up * uy, sz - s_up * uz
        # forward = lateral x up (body frame: x forward = y left x z up), as long as lateral
        fx, fy, fz = ly * uz - lz * uy, lz * ux - lx * uz, lx * uy - ly * ux
        ahead = fx * sx + fy * sy + fz * sz
        aside = lx * sx + ly * sy + lz * sz
        facing[n] = math.degrees(math.atan2(abs(aside), ahead))
        near_side[n] = 1.0 if aside >= 0.0 else -1.0


@numba.njit(cache=True)
def _occlusion(n_bodies, p, g, view, pose, occluded, n_visible, torso) -> None:
    """Stage 4, occlusion: each torso is an image rectangle over its shoulder and hip joints,
    widened by the margin, at the mean depth of its torso joints (``torso`` = (depth, u_lo, u_hi,
    v_lo, v_hi), (N,)); a joint deeper than that by ``occlusion_depth_m`` whose image falls
    inside is hidden (own torso: inferred, never for the torso's own joints; another body's:
    inferred and not "visible"). A body turned beyond ``facing_inferred_deg`` (``pose``, from
    :func:`_facing`) has the joints of its far-side arm and leg inferred. Fills ``occluded``
    (N, J) and ``n_visible`` (N,)."""
    cam, img_u, img_v, in_view = view
    facing, near_side = pose
    zt, u_lo, u_hi, v_lo, v_hi = torso
    is_torso, torso_joints, limb_side = g["is_torso"], g["torso_joints"], g["limb_side"]
    margin_m, occlusion_depth = p["torso_margin_m"], p["occlusion_depth_m"]
    for n in range(n_bodies):
        acc = 0.0
        ulo, uhi, vlo, vhi = np.inf, -np.inf, np.inf, -np.inf
        for t in range(N_TORSO_JOINTS):
            j = int(torso_joints[t])
            acc += cam[n, j, 2]
            ulo, uhi = min(ulo, img_u[n, j]), max(uhi, img_u[n, j])
            vlo, vhi = min(vlo, img_v[n, j]), max(vhi, img_v[n, j])
        zt[n] = acc / N_TORSO_JOINTS
        margin = margin_m / max(zt[n], 1e-3)
        u_lo[n], u_hi[n], v_lo[n], v_hi[n] = ulo - margin, uhi + margin, vlo, vhi
    for n in range(n_bodies):
        n_visible[n] = 0
        turned = facing[n] > p["facing_inferred_deg"]
        for j in range(NUM_JOINTS):
            occluded[n, j] = False
            if not in_view[n, j]:  # not tracked whatever hides it
                continue
            d, u, v = cam[n, j, 2], img_u[n, j], img_v[n, j]
            own, other = False, False
            for o in range(n_bodies):
                if (
                    zt[o] > 0
                    and d > zt[o] + occlusion_depth
                    and u_lo[o] <= u <= u_hi[o]
                    and v_lo[o] <= v <= v_hi[o]
                ):
                    if o == n:
                        own = True
                    else:
                        other = True
            far = turned and limb_side[j] == -near_side[n]  # a far-side limb joint
            occluded[n, j] = other or (own and is_torso[j] == 0.0) or far
            if not other:
                n_visible[n] += 1

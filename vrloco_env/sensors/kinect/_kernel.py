"""Compiled frame loop of the Kinect v2 model (see :mod:`vrloco_env.sensors.kinect`).

:meth:`vrloco_env.sensors.kinect.KinectV2.capture` validates its input, draws one block of
standard normals per frame from the users' :class:`~vrloco_env.batch_rng.BatchRng` and hands
everything to :func:`capture_frames`, which runs the whole model in one call, per user and frame
in stages: the bystanders (:func:`_bystanders`), camera transform and field of view
(:func:`_camera_space`), each body's facing relative to the sensor (:func:`_facing`), occlusion
(:func:`_occlusion`), tracking and ids (:func:`_track`), jitter
bursts and random inferred episodes (:func:`_episodes`), the noise states
(:func:`_noise_states`), and each body's slot with its noisy joints and wrist orientation
(:func:`_body_out`).

The kernel is plain Python on scalars and small arrays; ``capture_frames.py_func`` runs the same
code uncompiled (``tests/kernel_cases/kinect.py`` checks that both give the same frames). Its
quaternion products are the scalar helpers of :mod:`estimators.kernels.rotations`. Parameters
are named: the spec's fields and derived values in a parameter record, the sensor's pose and the
per-joint tables in :data:`GEOMETRY_FIELDS`, each user's session in :data:`STATE_FIELDS`.

Draw layout
-----------
Each frame of each user consumes ``draw_size(n_bodies)`` normals, in this order (offsets ``Z_*``,
``B_*``, ``Y_*``):

* the target: 75 innovations of its per-joint noise process (joint-major, x y z), 15 normals for
  the extra white noise of a jitter burst (up to 5 limb joints x 3; unused outside bursts), then
  its wrist rotation noise: white (3) and AR(1) innovations (3);
* per body (target first, then the bystanders), ``BODY_DRAWS`` = 3 numbers: the jitter burst
  (start, limb and length from one number), the id the body gets if it is acquired in this frame,
  and the random inferred episodes (starts and lengths from one number);
* per bystander, ``BYSTANDER_DRAWS`` = 10 numbers: its noise vectors, white (3) and AR(1)
  innovations (3), then walk start, distance, lateral offset and speed.

That is 125 numbers per frame for the default two bystanders. Four devices keep the statistics
of the spec while drawing few numbers:

* Rare events test their normal against a threshold, ``z < ndtri(p)`` being ``ndtr(z) < p``; where
  a value is needed the uniform is ``ndtr(z)`` (computed here with ``erfc``).
* Several decisions come from one uniform by *splitting* (:func:`bernoulli_split`,
  :func:`categorical_split`, :func:`geometric_split`): given the outcome of an inverse-CDF draw,
  the uniform's position inside the outcome's interval is again uniform and independent of the
  outcome, so it is rescaled and used for the next decision (exact in real arithmetic; a decision
  of probability P costs log2(1/P) of the double's 53 bits).
* The target's joint noise, white (variance fraction ``wf``) plus unit AR(1) (coefficient ``rho``),
  is the Gaussian process with autocorrelation 1 at lag 0 and ``(1 - wf) rho^k`` at lag k >= 1.
  An AR(1) process plus white noise is an ARMA(1, 1) process (Granger & Morris 1976, "Time series
  modelling and interpretation", J. R. Statist. Soc. A 139(2)), so it is generated from one
  innovation per coordinate and frame in its innovations form
  ``y_t = rho y_{t-1} + s (e_t + theta e_{t-1})`` (:func:`arma_parameters`), not two: the same
  process, half the numbers.
* A bystander's noise is drawn at lower dimension: one white and one AR(1) innovation vector per
  frame drive all its joints (each scaled by its own std, so every joint keeps the spec's std,
  white fraction and time constant, but the skeleton jitters rigidly) and its wrist rotation (its
  own AR(1) state, time constant ``hand_rot_tau_s``). Bystanders matter by where they stand, hide
  the user and get tracked, not by the shape of their jitter; the target keeps independent noise
  per joint and per wrist axis.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from estimators.kernels.batch import BatchKernel
from estimators.kernels.rotations import quat_from_rotvec, quat_mul
from vrloco_env.user import INFERRED, NOT_TRACKED, NUM_JOINTS, TRACKED, Joint

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

# Draw layout of one frame (see the module docstring).
Z_JOINT = 0
Z_BURST = 3 * NUM_JOINTS
Z_HAND_WHITE = Z_BURST + 3 * MAX_LIMB_JOINTS
Z_HAND_AR = Z_HAND_WHITE + 3
Z_BODIES = Z_HAND_AR + 3
BODY_DRAWS = 3
B_BURST, B_NEW_ID, B_INFERRED = 0, 1, 2
BYSTANDER_DRAWS = 10
Y_WHITE, Y_AR, Y_WALK_START, Y_WALK_DIST, Y_WALK_LATERAL, Y_WALK_SPEED = 0, 3, 6, 7, 8, 9

_BELOW_ONE = 1.0 - 2.0**-53
_SQRT_HALF = math.sqrt(0.5)


def bystander_offset(n_bodies: int) -> int:
    """Offset of the bystanders' block in a frame's draws."""
    return Z_BODIES + BODY_DRAWS * n_bodies


def draw_size(n_bodies: int) -> int:
    """Normals drawn per user and frame for ``n_bodies`` bodies (target + bystanders)."""
    return bystander_offset(n_bodies) + BYSTANDER_DRAWS * (n_bodies - 1)


def arma_parameters(white_fraction: float, rho: float) -> tuple[float, float]:
    """Innovation scale ``s`` and MA coefficient ``theta`` of white + AR(1) noise as ARMA(1, 1).

    The unit-variance process ``x_t = sqrt(wf) w_t + sqrt(1 - wf) a_t`` (w white, a AR(1) with
    coefficient rho) satisfies ``x_t - rho x_{t-1} = m_t``, an MA(1) with variance
    ``g0 = wf (1 + rho^2) + (1 - wf)(1 - rho^2)`` and lag-1 covariance ``g1 = -rho wf``, so
    ``m_t = s (e_t + theta e_{t-1})`` with ``s^2 (1 + theta^2) = g0``, ``s^2 theta = g1`` and the
    invertible root ``|theta| <= 1``.

    Args:
        white_fraction: wf in [0, 1].
        rho: AR(1) coefficient per step in [0, 1).

    Returns:
        ``(s, theta)``; the stationary state has ``var(y) = 1`` and ``cov(y_t, e_t) = s``.
    """
    g0 = white_fraction * (1.0 + rho * rho) + (1.0 - white_fraction) * (1.0 - rho * rho)
    g1 = -rho * white_fraction
    r = g1 / g0
    if r == 0.0:
        return math.sqrt(g0), 0.0
    theta = (1.0 - math.sqrt(max(1.0 - 4.0 * r * r, 0.0))) / (2.0 * r)
    return math.sqrt(g1 / theta), theta


@numba.njit(cache=True)
def uniform(z: float) -> float:
    """Uniform in [0, 1) from a standard normal: its CDF, ndtr(z), kept below 1."""
    return min(0.5 * math.erfc(-z * _SQRT_HALF), _BELOW_ONE)


@numba.njit(cache=True)
def bernoulli_split(u: float, p: float) -> tuple[bool, float]:
    """A Bernoulli(p) trial ``u < p`` on a uniform, and the uniform rescaled for the next draw.

    Given the outcome, ``u`` is uniform on [0, p) or [p, 1); rescaled to [0, 1) it is independent
    of the outcome, so a chain of calls on one uniform gives independent trials.
    """
    if u < p:
        return True, min(u / p, _BELOW_ONE)
    return False, min((u - p) / (1.0 - p), _BELOW_ONE)


@numba.njit(cache=True)
def categorical_split(u: float, n: int) -> tuple[int, float]:
    """A uniform choice among ``n`` values, floor(u n), and the uniform rescaled (fraction)."""
    x = u * n
    k = min(int(x), n - 1)
    return k, min(max(x - k, 0.0), _BELOW_ONE)


@numba.njit(cache=True)
def geometric_split(u: float, q: float) -> tuple[int, float]:
    """A length L >= 1 with P(L > k) = q^k, and the uniform rescaled for the next draw.

    L = max(1, ceil(log(1 - u) / log(q))): an exponential length of mean -1 / log(q) frames
    rounded up, as the numpy model drew it. Given L, ``u`` is uniform on
    [1 - q^(L-1), 1 - q^L); rescaled to [0, 1) it is independent of L.
    """
    length = max(1, math.ceil(math.log1p(-u) / math.log(q)))
    top = q ** (length - 1)  # P(L >= length)
    return length, min(max((u - (1.0 - top)) / (top * (1.0 - q)), 0.0), _BELOW_ONE)


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


@numba.njit(cache=True)
def _track(n_bodies, p, n_visible, facing, session, new_ids, tracked, fresh) -> None:
    """Stage 5, tracking: a body is detectable while at least ``min_visible_fraction`` of its
    joints are visible and it is turned no further than ``facing_lost_deg`` from the sensor
    (``facing`` (N,) deg, :func:`_facing`); it is tracked after ``acquire_frames`` consecutive
    detectable frames; one tracked again gets a fresh id (``new_ids`` (N,)), unique among the
    user's bodies. ``session`` = (acquired, prev_tracked, body_id), (N,) each, updated in place;
    fills ``tracked`` and ``fresh`` (N,)."""
    acquired, prev_tracked, body_id = session
    acq = int(p["acquire_frames"])
    for n in range(n_bodies):
        seen = n_visible[n] / NUM_JOINTS >= p["min_visible_fraction"]
        if seen and facing[n] <= p["facing_lost_deg"]:
            acquired[n] = min(acquired[n] + 1, acq)
        else:
            acquired[n] = 0
        tracked[n] = acquired[n] >= acq
        fresh[n] = tracked[n] and prev_tracked[n] == 0.0
        if fresh[n]:
            body_id[n] = new_ids[n]
        prev_tracked[n] = 1.0 if tracked[n] else 0.0
    _unique_ids(body_id[:n_bodies], fresh)


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
        z: (B, M, draw_size(N)) standard normals (layout in the module docstring).
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


@numba.njit(cache=True)
def _unique_ids(ids: np.ndarray, fresh: np.ndarray) -> None:
    """Move a fresh id that equals another body's (not fresh, or fresh and earlier) to the next
    value, until the user's ids differ (as ``model._unique_ids`` does for a batch)."""
    n = ids.size
    if not fresh.any():  # the common case: no body (re)acquired in this frame
        return
    clash = np.zeros(n, dtype=np.bool_)
    while True:
        any_clash = False
        for j in range(n):
            clash[j] = False
            if not fresh[j]:
                continue
            for k in range(n):
                if k != j and ids[k] == ids[j] and (not fresh[k] or k < j):
                    clash[j] = True
                    any_clash = True
                    break
        if not any_clash:
            return
        for j in range(n):
            if clash[j]:
                ids[j] = ids[j] % (2**53) + 1


def _unique_rows(ids, fresh) -> None:
    """:func:`_unique_ids` on every row (user) of ``ids`` (B, N) in place; ``fresh`` (B, N)."""
    for b in numba.prange(ids.shape[0]):
        _unique_ids(ids[b], fresh[b])


#: The ids of a reset: ``unique_ids(B)(ids, fresh)``, :func:`_unique_ids` per user, in place.
unique_ids = BatchKernel(_unique_rows, parallel=False)

"""The Kinect v2 body tracker of B simulated users (:class:`KinectV2`): the model is described in
:mod:`vrloco_env.sensors.kinect`, its frame loop is :mod:`vrloco_env.sensors.kinect._kernel`."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtr, ndtri

from estimators.batching import TakesUsers, stream_rows
from estimators.kernels import param_record, state_records
from estimators.rotations import (
    ensure_quaternion,
    quat_to_matrix,
)
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.kinect import _kernel as _k
from vrloco_env.sensors.kinect.frames import (
    HAND_FROM_SDK_WRIST,
    KinectFrames,
    KinectTruth,
    camera_quat,
)
from vrloco_env.sensors.kinect.skeleton import standing_skeleton
from vrloco_env.sensors.kinect.spec import LIMB_GROUPS, MAX_BODIES, TORSO_JOINTS, KinectSpec
from vrloco_env.user import NOT_TRACKED, NUM_JOINTS

__all__ = ["KinectV2"]

# Each joint's place in each burst limb (-1: not in it): the target's burst noise normals.
_LIMB_INDEX = np.full((len(LIMB_GROUPS), NUM_JOINTS), -1.0)
for _g, _members in enumerate(LIMB_GROUPS):
    _LIMB_INDEX[_g, list(_members)] = np.arange(len(_members))
# Each limb joint's side, +1 left and -1 right (0: torso and head): a turned body's far limbs.
_LIMB_SIDE = np.zeros(NUM_JOINTS)
for _members in LIMB_GROUPS:
    _LIMB_SIDE[list(_members)] = [1.0 if j.name.endswith("_LEFT") else -1.0 for j in _members]
_ID_SCALE = float(2**53)
_BELOW_ONE = np.nextafter(1.0, 0.0)  # ndtr(z) rounds to 1.0 for z > 8.3; keep uniforms < 1
# A bystander: the standing skeleton of height 1 m facing +x with its pelvis over the origin, and
# its right hand's orientation (hand frame -> body frame). Joints scale with the height.
_BYSTANDER_TEMPLATE, _BYSTANDER_HAND = standing_skeleton(np.zeros(3), 0.0, 1.0)
if (len(LIMB_GROUPS), len(TORSO_JOINTS)) != (_k.N_LIMB_GROUPS, _k.N_TORSO_JOINTS) or max(
    map(len, LIMB_GROUPS)
) > _k.MAX_LIMB_JOINTS:  # pragma: no cover - the kernel's table sizes must match
    raise ImportError("vrloco_env.sensors.kinect._kernel disagrees with the limb and torso tables")


def _z_threshold(p: float) -> float:
    """The normal ``z`` below which an event of probability ``p`` happens: ndtr(z) < p."""
    return float(ndtri(p)) if 0.0 < p < 1.0 else (-math.inf if p <= 0.0 else math.inf)


class KinectV2(TakesUsers):
    """Stateful, batched Kinect v2 body tracker for B simulated users (one sensor per user).

    Args:
        spec: sensor parameters.
        rng: per-user random streams; its batch size is B.

    Call :meth:`reset` at the start of every session, then :meth:`capture` with the target user's
    true skeleton at the Kinect rate, in one call or in chunks (identical results).
    ``reset(users=...)`` starts a new session for some users only; the others carry on.

    The frame loop runs in one compiled kernel, :func:`vrloco_env.sensors.kinect._kernel.
    capture_frames` (its uncompiled ``py_func`` is the readable reference the tests compare with).
    """

    # each user's session state and delay line (the random streams belong to the caller's
    # BatchRng)
    per_user_fields = ("_ready", "_state", "_target_slot", "_delay")
    batch_size_field = "batch_size"

    def __init__(self, spec: KinectSpec, rng: BatchRng) -> None:
        if not isinstance(spec, KinectSpec):
            raise TypeError(f"spec must be a KinectSpec, got {type(spec).__name__}")
        if not isinstance(rng, BatchRng):
            raise TypeError(
                f"rng must be a vrloco_env.batch_rng.BatchRng, got {type(rng).__name__}"
            )
        self.spec = spec
        self.rng = rng
        self.batch_size = rng.batch_size
        self.n_bodies = 1 + int(spec.n_bystanders)
        self._dt = 1.0 / spec.frame_rate_hz
        self._rho_joint = math.exp(-self._dt / spec.joint_noise_tau_s)
        self._rho_hand = math.exp(-self._dt / spec.hand_rot_tau_s)
        self._ready = np.zeros(self.batch_size, dtype=bool)  # per user: reset at least once
        self._arma = _k.arma_parameters(spec.joint_noise_white_fraction, self._rho_joint)
        self._draws = _k.draw_size(self.n_bodies)  # normals per user and frame
        self._id_cols = _k.Z_BODIES + _k.BODY_DRAWS * np.arange(self.n_bodies) + _k.B_NEW_ID
        self._prm = self._param_record()
        self._geo = self._geometry()

    def _param_record(self) -> NDArray:
        """The kernel's parameter record: the spec's numeric fields and the derived values the
        kernel reads (SI units)."""
        s = self.spec
        near, far = s.depth_range_m
        (by_d0, by_d1), (by_v0, by_v1) = s.bystander_distance_m, s.bystander_speed_mps
        burst_min, burst_max = s.burst_frames
        return param_record(
            s,
            tan_h=math.tan(math.radians(s.fov_deg[0]) / 2),
            tan_v=math.tan(math.radians(s.fov_deg[1]) / 2),
            near=near,
            far=far,
            noise_a=s.joint_noise_a_mm * 1e-3,  # m: joint noise std at depth z is a + b z^2
            noise_b=s.joint_noise_b_mm_per_m2 * 1e-3,  # m / m^2
            rho_joint=self._rho_joint,  # AR(1) coefficients per frame, joints and wrists
            rho_hand=self._rho_hand,
            arma_s=self._arma[0],  # the target's joint noise as ARMA(1, 1) (arma_parameters)
            arma_theta=self._arma[1],
            ref_std=float(s.joint_noise_std_m(s.noise_ref_depth_m)),  # m
            burst_rot=math.radians(s.burst_rotation_std_deg),
            burst_z=_z_threshold(s.burst_prob),
            inferred_q=math.exp(-1.0 / s.random_inferred_frames),  # ratio of episode lengths
            # a standing bystander starts walking when its normal lies below walk_z
            walk_z=_z_threshold(1.0 - math.exp(-self._dt / s.bystander_dwell_s)),
            dt=self._dt,
            by_d0=by_d0,
            by_d1=by_d1,
            by_v0=by_v0,
            by_v1=by_v1,
            cam_cos=math.cos(s.camera_yaw_rad),
            cam_sin=math.sin(s.camera_yaw_rad),
            burst_min=burst_min,
            burst_max=burst_max,
        )

    @property
    def geometry(self) -> NDArray:
        """The kernel's geometry record (the sensor's pose, the per-joint tables:
        ``_kernel.GEOMETRY_FIELDS``), one row, read-only by convention."""
        return self._geo

    def _geometry(self) -> NDArray:
        """The kernel's record of the sensor's pose and the per-joint tables
        (``_kernel.GEOMETRY_FIELDS``)."""
        s = self.spec
        geo = state_records(_k.GEOMETRY_FIELDS, 1)
        g = geo[0]
        q_cam = camera_quat(s)
        g["cam_rot"] = quat_to_matrix(q_cam)
        g["cam_pos"] = s.camera_position_m
        g["cam_quat"] = q_cam
        g["sdk_from_hand"] = HAND_FROM_SDK_WRIST
        g["by_template"] = _BYSTANDER_TEMPLATE
        g["by_hand_quat"] = _BYSTANDER_HAND
        g["joint_scale"] = s.joint_noise_scale
        g["hand_white_sd"] = np.radians(np.asarray(s.hand_rot_white_std_deg, np.float64))
        g["hand_ar_sd"] = np.radians(np.asarray(s.hand_rot_ar_std_deg, np.float64))
        p = s.random_inferred_prob
        g["inferred_z"] = [_z_threshold(1.0 - (1.0 - p) ** k) for k in range(NUM_JOINTS + 1)]
        g["limb_index"] = _LIMB_INDEX
        g["is_torso"][list(TORSO_JOINTS)] = 1.0
        g["torso_joints"] = TORSO_JOINTS
        g["limb_side"] = _LIMB_SIDE
        return geo

    # ----------------------------------------------------------------------------------- session

    def reset(self, users: ArrayLike | None = None) -> None:
        """Start a session for some or all users: slots, ids, offsets, noise states, bystanders.

        Each reset user draws one block of normals from its own stream; the state of the other
        users (their slots, ids, noise and burst states, bystanders, delay line and frame counter)
        and their streams are untouched. So after ``rng.reseed(i, g)`` and ``reset(users=[i])``
        user i continues exactly as a single-user ``KinectV2`` on ``BatchRng([g])`` that was just
        reset (a vector env's autoreset), and the others as if nothing happened.

        Args:
            users: the users to reset, as indices or a (B,) boolean mask; None resets all. Every
                user must have been reset once before :meth:`capture`.

        Raises:
            ValueError: an index outside [0, B), a repeated index or a mask of the wrong shape.
        """
        s, B, N = self.spec, self.batch_size, self.n_bodies
        rows = stream_rows(users, B)
        if not hasattr(self, "_state"):
            self._allocate()
        R, nb = rows.size, N - 1
        st = self._state
        # One draw per reset user (uniforms are the normal CDF of the user's single stream).
        nj3 = NUM_JOINTS * 3
        sizes = (MAX_BODIES, N, N * nj3, nj3, nj3, N * 3, nb * 3, nb * 7)
        z = self.rng.normal((sum(sizes),), rows=rows)
        parts = np.split(z, np.cumsum(sizes)[:-1], axis=1)
        slot_u, id_u = ndtr(parts[0]), np.minimum(ndtr(parts[1]), _BELOW_ONE)
        # Slots: a random permutation of the 6 slots per user; body 0 (the target) takes the first.
        slots = np.argsort(slot_u, axis=1)[:, :N]
        self._target_slot[rows] = slots[:, :1]
        st["slot"][rows, :N] = slots
        ids = self._new_ids(id_u)
        _k.unique_ids(R)(ids, np.ones((R, N), dtype=bool))  # ids differ within each user
        st["body_id"][rows, :N] = ids
        st["acquired"][rows] = int(s.acquire_frames)
        st["prev_tracked"][rows] = 1.0
        st["bias"][rows, :N] = s.joint_bias_std_m * parts[2].reshape(R, N, NUM_JOINTS, 3)
        # Noise states, started stationary: the target's ARMA(1, 1) joint noise (y, e) with
        # var(y) = 1 and cov(y, e) = s; unit AR(1) states of every wrist and of the bystanders'
        # rigid joint noise.
        s_arma = self._arma[0]
        st["joint_innov"][rows] = parts[3].reshape(R, NUM_JOINTS, 3)
        st["joint_noise"][rows] = (
            s_arma * parts[3] + math.sqrt(max(1.0 - s_arma**2, 0.0)) * parts[4]
        ).reshape(R, NUM_JOINTS, 3)
        st["ar_hand"][rows, :N] = parts[5].reshape(R, N, 3)
        st["ar_by"][rows, :nb] = parts[6].reshape(R, nb, 3)
        st["burst_left"][rows] = 0.0
        st["burst_group"][rows] = 0.0
        st["inferred_left"][rows] = 0.0
        st["frame"][rows] = 0.0
        # Bystanders, in the sensor's floor frame (d along the axis, l to the sensor's left).
        u = np.minimum(ndtr(parts[7]), _BELOW_ONE).reshape(R, nb, 7)
        d0, d1 = s.bystander_distance_m
        local = np.stack(
            [d0 + (d1 - d0) * u[..., 0], s.bystander_lateral_m * (2 * u[..., 1] - 1)], axis=-1
        )
        st["by_pos"][rows, :nb] = self._floor_to_world(local)
        # Facing the sensor within +-30 deg (engineering choice: people near a screen face it).
        yaw = s.camera_yaw_rad + math.pi + math.radians(30.0) * (2 * u[..., 2] - 1)
        st["by_yaw"][rows, :nb] = yaw
        h0, h1 = s.bystander_height_m
        st["by_height"][rows, :nb] = h0 + (h1 - h0) * u[..., 3]
        # Quiet-standing sway: 5-20 mm at 0.15-0.4 Hz, the amplitude and band of the body's sway
        # in quiet stance (Winter 1995, "Human balance and posture control during standing and
        # walking", Gait & Posture 3(4)); applied as a lateral shift of the whole skeleton.
        st["by_sway_amp"][rows, :nb] = 0.005 + 0.015 * u[..., 4]
        st["by_sway_freq"][rows, :nb] = 0.15 + 0.25 * u[..., 5]
        st["by_sway_phase"][rows, :nb] = 2 * math.pi * u[..., 6]
        st["by_target"][rows] = st["by_pos"][rows]
        st["by_speed"][rows] = 0.0
        st["by_moving"][rows] = 0.0
        # Latency delay line, filled with empty frames: nothing delivered yet.
        empty = self._empty_slots(int(s.latency_frames))
        for k, v in self._delay.items():
            v[rows] = empty[k][rows]
        self._ready[rows] = True

    def _allocate(self) -> None:
        """Create the per-user session records (``_kernel.STATE_FIELDS``) and the delay
        line, before the first :meth:`reset`."""
        self._state = state_records(_k.STATE_FIELDS, self.batch_size)
        self._target_slot = np.zeros((self.batch_size, 1), dtype=np.int64)
        self._delay = self._empty_slots(int(self.spec.latency_frames))

    def _new_ids(self, u: NDArray[np.float64]) -> NDArray[np.int64]:
        # A uniform double holds 53 random bits; ids are 1 .. 2^53 (the SDK's are opaque uint64).
        return (np.floor(u * _ID_SCALE) + 1).astype(np.int64)

    def _floor_to_world(self, local: NDArray[np.float64]) -> NDArray[np.float64]:
        s = self.spec
        c, sn = math.cos(s.camera_yaw_rad), math.sin(s.camera_yaw_rad)
        x = s.camera_position_m[0] + local[..., 0] * c - local[..., 1] * sn
        y = s.camera_position_m[1] + local[..., 0] * sn + local[..., 1] * c
        return np.stack([x, y], axis=-1)

    def _empty_slots(self, m: int) -> dict[str, NDArray]:
        B, K = self.batch_size, MAX_BODIES
        return {
            "body_id": np.zeros((B, m, K), dtype=np.int64),
            "body_tracked": np.zeros((B, m, K), dtype=bool),
            "joints": np.full((B, m, K, NUM_JOINTS, 3), np.nan),
            "joint_state": np.full((B, m, K, NUM_JOINTS), NOT_TRACKED, dtype=np.int8),
            "hand_quat": np.full((B, m, K, 4), np.nan),
        }

    # ----------------------------------------------------------------------------------- capture

    def _validate(
        self, t: ArrayLike, joints_world: ArrayLike, hand_quat_world: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        B = self.batch_size
        jw = np.asarray(joints_world, dtype=np.float64)
        if jw.ndim != 4 or jw.shape[0] != B or jw.shape[2:] != (NUM_JOINTS, 3):
            raise ValueError(
                f"joints_world must have shape (B={B}, M, {NUM_JOINTS}, 3) m, got {jw.shape}"
            )
        M = jw.shape[1]
        if M < 1:
            raise ValueError("joints_world must hold at least one frame (M >= 1)")
        if not np.isfinite(jw).all():
            raise ValueError(
                "joints_world contains NaN or infinite positions; truth must be finite"
            )
        q = np.asarray(hand_quat_world, dtype=np.float64)
        if q.shape != (B, M, 4):
            raise ValueError(f"hand_quat_world must have shape (B={B}, M={M}, 4), got {q.shape}")
        q = ensure_quaternion(q, "hand_quat_world")
        tt = np.asarray(t, dtype=np.float64)
        if tt.shape == (M,):
            tt = np.broadcast_to(tt, (B, M))
        if tt.shape != (B, M):
            raise ValueError(f"t must have shape (M={M},) or (B={B}, M={M}) s, got {tt.shape}")
        if not np.isfinite(tt).all():
            raise ValueError("t contains NaN or infinite times")
        return tt.copy(), np.ascontiguousarray(jw), q

    def capture(
        self,
        t: ArrayLike,
        joints_world: ArrayLike,
        hand_quat_world: ArrayLike,
        validated: bool = False,
    ) -> KinectFrames:
        """Sense M frames of the target user (and the bystanders).

        Args:
            t: frame times, (M,) or (B, M) s, at the Kinect rate (the model steps its noise and the
                bystanders by ``1 / frame_rate_hz`` per frame; ``t`` is passed through).
            joints_world: the target user's true joints in the world, (B, M, 25, 3) m, finite.
            hand_quat_world: the target's true right-hand orientation, hand frame -> world,
                (B, M, 4), finite and non-zero.

            validated: the caller promises float64 C-contiguous arrays of those shapes, finite,
                with unit quaternions (the env's motion model makes them so): the checks are
                skipped.

        Returns:
            The delivered frames (delayed by ``latency_frames``) and the undelayed truth.
        """
        if not self._ready.all():
            missing = np.flatnonzero(~self._ready).tolist()
            raise RuntimeError(
                f"call KinectV2.reset() before capture() (users {missing} never were)"
            )
        if validated:
            jw, qw = joints_world, hand_quat_world
            t = t[None, :].repeat(self.batch_size, 0) if t.ndim == 1 else t.copy()
        else:
            t, jw, qw = self._validate(t, joints_world, hand_quat_world)
        B, M, K = self.batch_size, jw.shape[1], MAX_BODIES
        # One draw per call, a fixed block of normals per frame (layout in _kernel), so
        # that a capture in chunks equals one capture.
        z = self.rng.normal((M, self._draws))
        new_ids = self._new_ids(np.minimum(ndtr(z[:, :, self._id_cols]), _BELOW_ONE))
        out = {
            "body_id": np.empty((B, M, K), dtype=np.int64),
            "body_tracked": np.empty((B, M, K), dtype=bool),
            "joints": np.empty((B, M, K, NUM_JOINTS, 3)),
            "joint_state": np.empty((B, M, K, NUM_JOINTS), dtype=np.int8),
            "hand_quat": np.empty((B, M, K, 4)),
        }
        truth_joints = np.empty((B, M, NUM_JOINTS, 3))
        truth_hand = np.empty((B, M, 4))
        _k.capture_frames(B)(
            jw,
            qw,
            z,
            new_ids,
            self._prm,
            self._geo,
            self._state,
            (
                out["body_id"],
                out["body_tracked"],
                out["joints"],
                out["joint_state"],
                out["hand_quat"],
                truth_joints,
                truth_hand,
            ),
        )
        L = int(self.spec.latency_frames)
        if L:
            joined = {k: np.concatenate([self._delay[k], v], axis=1) for k, v in out.items()}
            out = {k: v[:, :M] for k, v in joined.items()}
            self._delay = {k: v[:, M:].copy() for k, v in joined.items()}
        truth = KinectTruth(
            slot=self._target_slot.repeat(M, 1),
            joints=truth_joints,
            hand_quat=truth_hand,
        )
        return KinectFrames(t=t, truth=truth, **out)

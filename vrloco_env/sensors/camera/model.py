"""The head camera of B users (:class:`HeadCamera`): the model is described in
:mod:`vrloco_env.sensors.camera`."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtr

from estimators.batching import stream_rows
from estimators.rotations import (
    ensure_quaternion,
    quat_multiply,
    quat_rotate,
    quat_rotate_inverse,
)
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.camera.frames import CameraFrames
from vrloco_env.sensors.camera.spec import (
    _BELOW_ONE,
    _FRAME_DRAWS,
    _SLOT_DRAWS,
    CameraSpec,
    _mount_quat,
    camera_spec,
)

__all__ = ["HeadCamera"]


def _check(cond: bool, msg: str) -> None:
    """Raise ``ValueError(msg)`` unless ``cond`` (the capture arrays' shape and value checks)."""
    if not cond:
        raise ValueError(msg)


def _fold(x: NDArray[np.float64], lo: float, hi: float) -> NDArray[np.float64]:
    """Reflect ``x`` into [lo, hi] (a random walk between two mirrors)."""
    s = np.mod((x - lo) / (hi - lo), 2.0)
    return lo + (hi - lo) * (1.0 - np.abs(1.0 - s))


class HeadCamera:
    """The head camera of B users: landmark observations with detection and matching errors.

    Args:
        spec: the camera, a :class:`CameraSpec` or a condition name of :data:`CONDITIONS`.
        rng: one random stream per user.

    The constructor resets every user. Per-user state: the occluder's (unfolded) band centre and a
    frame counter.
    """

    def __init__(self, spec: CameraSpec | str, rng: BatchRng) -> None:
        if isinstance(spec, str):
            spec = camera_spec(spec)
        if not isinstance(spec, CameraSpec):
            raise ValueError(f"spec must be a CameraSpec or a condition name, got {spec!r}")
        if not isinstance(rng, BatchRng):
            raise ValueError(
                f"rng must be a vrloco_env.batch_rng.BatchRng, got {type(rng).__name__}"
            )
        self.spec = spec
        self.rng = rng
        self.dt = 1.0 / spec.rate_hz
        self._mount_q = _mount_quat(spec)
        self._mount_off = np.asarray(spec.mount_offset_m, dtype=np.float64)
        band = spec.occluder_fraction * spec.width
        self._band_half = 0.5 * band
        # Band centre range: the band lies inside the image [-0.5, width - 0.5].
        self._occ_lo = -0.5 + 0.5 * band
        self._occ_hi = spec.width - 0.5 - 0.5 * band
        self._draws = _FRAME_DRAWS + _SLOT_DRAWS * spec.max_landmarks
        self._nb_key: tuple[NDArray, NDArray] | None = None
        self.reset()

    @property
    def batch_size(self) -> int:
        """B, the number of users."""
        return self.rng.batch_size

    def reset(self, users: ArrayLike | None = None) -> None:
        """Start a new session for some or all users (the occluder's start position).

        Each reset user draws one normal from its own stream; the other users' state and streams
        are untouched, so after ``rng.reseed(i, g)`` and ``reset(users=[i])`` user i continues as
        a fresh single-user camera on ``BatchRng([g])``.

        Args:
            users: indices or a (B,) boolean mask; None resets all.

        Raises:
            ValueError: an index outside [0, B), a repeated index or a mask of the wrong shape.
        """
        b = self.batch_size
        rows = stream_rows(users, b)
        if not hasattr(self, "_occ_raw"):
            self._occ_raw = np.zeros(b)
            #: Frames captured per user since its reset.
            self.frames_taken = np.zeros(b, dtype=np.int64)
        z = self.rng.normal((1,), rows=rows)[:, 0]
        u = np.minimum(ndtr(z), _BELOW_ONE)
        self._occ_raw[rows] = self._occ_lo + (self._occ_hi - self._occ_lo) * u
        self.frames_taken[rows] = 0

    # ------------------------------------------------------------------------------ validation

    def _validate(self, t, pos, quat, omega, landmarks, mask, normals, blocked):
        b = self.batch_size
        p = np.asarray(pos, dtype=np.float64)
        _check(
            p.ndim == 3 and p.shape[0] == b and p.shape[2] == 3,
            f"pos must have shape (B={b}, N, 3) m, got {p.shape}",
        )
        n = p.shape[1]
        _check(n >= 1, "pos must hold at least one frame (N >= 1)")
        _check(bool(np.isfinite(p).all()), "pos contains NaN or infinite positions")
        q = np.asarray(quat, dtype=np.float64)
        _check(q.shape == (b, n, 4), f"quat must have shape (B={b}, N={n}, 4), got {q.shape}")
        q = ensure_quaternion(q, "quat")
        w = np.asarray(omega, dtype=np.float64)
        _check(
            w.shape == (b, n, 3), f"omega must have shape (B={b}, N={n}, 3) rad/s, got {w.shape}"
        )
        _check(bool(np.isfinite(w).all()), "omega contains NaN or infinite rates")
        tt = np.asarray(t, dtype=np.float64)
        if tt.shape == (n,):
            tt = np.broadcast_to(tt, (b, n))
        _check(
            tt.shape == (b, n), f"t must have shape (N={n},) or (B={b}, N={n}) s, got {tt.shape}"
        )
        _check(bool(np.isfinite(tt).all()), "t contains NaN or infinite times")
        lm = np.asarray(landmarks, dtype=np.float64)
        if lm.ndim == 2:
            lm = np.broadcast_to(lm, (b, *lm.shape))
        _check(
            lm.ndim == 3 and lm.shape[0] == b and lm.shape[2] == 3,
            f"landmarks must have shape (K, 3) or (B={b}, K, 3) m, got {np.shape(landmarks)}",
        )
        k = lm.shape[1]
        cap = self.spec.max_landmarks
        _check(
            1 <= k <= cap,
            f"landmarks must hold 1 <= K <= max_landmarks = {cap} rows, got K = {k} "
            "(raise CameraSpec.max_landmarks for larger rooms)",
        )
        if mask is None:
            m = np.ones((b, k), dtype=bool)
        else:
            m = np.asarray(mask)
            if m.shape == (k,):
                m = np.broadcast_to(m, (b, k))
            _check(
                m.shape == (b, k) and m.dtype == bool,
                f"mask must be a bool array of shape (K={k},) or (B={b}, K={k}), "
                f"got {m.dtype} {np.shape(mask)}",
            )
        _check(
            bool(np.isfinite(lm[m]).all()),
            "landmarks contains NaN or infinite coordinates in rows the mask marks valid",
        )
        lm = np.where(m[..., None], lm, 0.0)
        nrm = None
        if normals is not None:
            nrm = np.asarray(normals, dtype=np.float64)
            if nrm.shape == (k, 3):
                nrm = np.broadcast_to(nrm, (b, k, 3))
            _check(
                nrm.shape == (b, k, 3),
                f"normals must have shape (K={k}, 3) or (B={b}, K={k}, 3), got {np.shape(normals)}",
            )
            nrm = np.where(m[..., None], nrm, 0.0)
            norm = np.sqrt(nrm[..., 0] ** 2 + nrm[..., 1] ** 2 + nrm[..., 2] ** 2)
            _check(
                bool(np.all(np.isfinite(norm)) and np.all(norm[m] > 1e-9)),
                "normals must be finite and non-zero in rows the mask marks valid",
            )
            nrm = nrm / np.where(norm > 0.0, norm, 1.0)[..., None]
        blk = None
        if blocked is not None:
            blk = np.asarray(blocked)
            _check(
                blk.shape == (b, n, k) and blk.dtype == bool,
                f"blocked must be a bool array of shape (B={b}, N={n}, K={k}), "
                f"got {blk.dtype} {blk.shape}",
            )
        return tt.copy(), p, q, w, np.ascontiguousarray(lm), np.ascontiguousarray(m), nrm, blk

    def _neighbors(
        self, lm: NDArray[np.float64], mask: NDArray[np.bool_]
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """The ``match_neighbors`` nearest valid other landmarks of each landmark, (B, K, M), and
        how many of them exist per user, (B,). Cached while the landmarks do not change."""
        key = self._nb_key
        if key is not None and key[0].shape == lm.shape:
            same = np.all(key[0] == lm, axis=(1, 2)) & np.all(key[1] == mask, axis=1)
            if same.all():
                return self._nb, self._nb_count
            rows = np.flatnonzero(~same)
            nb, cnt = self._nb.copy(), self._nb_count.copy()
        else:
            b, k = mask.shape
            rows = np.arange(b)
            nb = np.zeros((b, k, self.spec.match_neighbors), dtype=np.int64)
            cnt = np.zeros(b, dtype=np.int64)
        p, mk = lm[rows], mask[rows]
        d = p[:, :, None, :] - p[:, None, :, :]
        d2 = d[..., 0] ** 2 + d[..., 1] ** 2 + d[..., 2] ** 2  # elementwise: batch == single
        k = mask.shape[1]
        bad = ~(mk[:, :, None] & mk[:, None, :]) | np.eye(k, dtype=bool)
        d2[bad] = np.inf
        m = min(self.spec.match_neighbors, k)
        order = np.argsort(d2, axis=2, kind="stable")[:, :, :m]
        nb[rows] = 0
        nb[rows, :, :m] = order
        cnt[rows] = np.minimum(self.spec.match_neighbors, np.maximum(mk.sum(axis=1) - 1, 0))
        self._nb, self._nb_count = nb, cnt
        self._nb_key = (lm.copy(), mask.copy())
        return nb, cnt

    # --------------------------------------------------------------------------------- capture

    def capture(
        self,
        t: ArrayLike,
        pos: ArrayLike,
        quat: ArrayLike,
        omega: ArrayLike,
        landmarks: ArrayLike,
        mask: ArrayLike | None = None,
        normals: ArrayLike | None = None,
        blocked: ArrayLike | None = None,
    ) -> CameraFrames:
        """Observe the landmarks in N successive frames of each of the B users.

        The model steps the occluder by ``1 / rate_hz`` per frame; ``t`` is passed through (the
        caller samples the head at the camera's rate, mid-exposure).

        Args:
            t: frame times, (N,) or (B, N) s, finite.
            pos: true head positions in the world, (B, N, 3) m.
            quat: true head orientations body -> world, (B, N, 4) [w, x, y, z], finite, non-zero.
            omega: true head angular rates in the body frame, (B, N, 3) rad/s (for motion blur).
            landmarks: landmark positions in the world, (K, 3) or (B, K, 3) m, K <=
                ``spec.max_landmarks``; rows the mask marks invalid may hold anything.
            mask: (K,) or (B, K) bool, True for real landmarks (False: padding); None: all real.
            normals: inward unit normals of each landmark's wall, (K, 3) or (B, K, 3); None skips
                the viewing-angle test.
            blocked: (B, N, K) bool, True where something in the scene (an obstacle) hides a
                landmark's line of sight; None: nothing does.

        Returns:
            :class:`CameraFrames`; K equals the landmarks' K.

        Raises:
            ValueError: a wrong shape or dtype, a non-finite value, a zero quaternion or more
                landmarks than ``spec.max_landmarks``. Nothing is drawn when it raises.
        """
        s = self.spec
        t, p, q, w, lm, mk, nrm, blk = self._validate(
            t, pos, quat, omega, landmarks, mask, normals, blocked
        )
        b, n = p.shape[:2]
        k = lm.shape[1]
        cap = s.max_landmarks
        nb, nb_count = self._neighbors(lm, mk)

        z = self.rng.normal((n, self._draws))  # (B, N, 1 + 4 C): fixed per frame and user
        self.frames_taken += n

        # Geometry: camera pose, camera-frame points, projections.
        cam_q = quat_multiply(q, self._mount_q)  # (B, N, 4) camera -> world
        cam_p = p + quat_rotate(q, self._mount_off)
        d = lm[:, None, :, :] - cam_p[:, :, None, :]  # (B, N, K, 3)
        xyz = quat_rotate_inverse(cam_q[:, :, None, :], d)
        zc = xyz[..., 2]
        front = zc >= s.min_range_m
        zsafe = np.where(front, zc, 1.0)
        x, y = xyz[..., 0] / zsafe, xyz[..., 1] / zsafe
        u = s.fx * x + s.cx
        v = s.fy * y + s.cy
        dist = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2 + d[..., 2] ** 2)
        visible = (
            front
            & mk[:, None, :]
            & (dist <= s.max_range_m)
            & (u >= -0.5)
            & (u <= s.width - 0.5)
            & (v >= -0.5)
            & (v <= s.height - 0.5)
        )
        if nrm is not None:  # seen from the room side, at most max_view_angle from the normal
            cos_view = -(
                nrm[:, None, :, 0] * d[..., 0]
                + nrm[:, None, :, 1] * d[..., 1]
                + nrm[:, None, :, 2] * d[..., 2]
            )
            limit = math.cos(math.radians(s.max_view_angle_deg)) * dist
            visible &= cos_view > limit
        if blk is not None:
            visible &= ~blk

        # Occluder band: a folded random walk of its centre, one step per frame.
        if s.occluder_fraction > 0.0:
            steps = s.occluder_drift_px_per_sqrt_s * math.sqrt(self.dt) * z[:, :, 0]
            walk = np.cumsum(np.concatenate([self._occ_raw[:, None], steps], axis=1), axis=1)
            self._occ_raw = walk[:, -1].copy()
            centre = _fold(walk[:, 1:], self._occ_lo, self._occ_hi)  # (B, N)
            band = np.stack([centre - self._band_half, centre + self._band_half], axis=-1)
            occluded = visible & (u >= band[:, :, None, 0]) & (u <= band[:, :, None, 1])
        else:
            band = np.full((b, n, 2), np.nan)
            occluded = np.zeros((b, n, k), dtype=bool)

        # Motion blur: rotational optical flow times the exposure.
        wc = quat_rotate_inverse(self._mount_q, w)  # (B, N, 3) camera-frame rate
        wx, wy, wz = (wc[:, :, None, i] for i in range(3))
        du = s.fx * (x * y * wx - (1.0 + x * x) * wy + y * wz)
        dv = s.fy * ((1.0 + y * y) * wx - x * y * wy - x * wz)
        blur = np.where(visible, np.sqrt(du * du + dv * dv) * s.exposure_s, 0.0)

        # Detection, then matching from the same uniform: given u < p_det (extracted), u / p_det
        # is again uniform on (0, 1) and independent of the detection outcome, so one number per
        # slot decides both (3 draws per slot instead of 4: the draws dominate the cost).
        c0 = _FRAME_DRAWS
        u_slot = np.minimum(ndtr(z[:, :, c0 : c0 + k]), _BELOW_ONE)
        p_det = s.extraction_prob * np.exp(
            -np.maximum(blur - s.blur_free_px, 0.0) / s.blur_scale_px
        )
        extracted = visible & ~occluded & (u_slot < p_det)

        # Pixel noise.
        sigma = np.sqrt(s.pixel_noise_px**2 + (s.blur_noise_per_px * blur) ** 2)
        nu = z[:, :, c0 + cap : c0 + cap + k]
        nv = z[:, :, c0 + 2 * cap : c0 + 2 * cap + k]
        pixels = np.where(
            extracted[..., None], np.stack([u + sigma * nu, v + sigma * nv], axis=-1), np.nan
        )
        pixels_true = np.where(visible[..., None], np.stack([u, v], axis=-1), np.nan)

        # Matching: own index with match_prob, else one of the nearest landmarks.
        u_match = np.minimum(u_slot / np.where(extracted, p_det, 1.0), _BELOW_ONE)
        own = np.broadcast_to(np.arange(k), (b, n, k))
        cnt = nb_count[:, None, None]
        wrong = (u_match >= s.match_prob) & (cnt > 0)
        if s.match_prob < 1.0:
            u_pick = (u_match - s.match_prob) / (1.0 - s.match_prob)  # uniform given a wrong match
        else:
            u_pick = np.zeros_like(u_match)
        j = np.minimum(np.floor(np.clip(u_pick, 0.0, _BELOW_ONE) * cnt), np.maximum(cnt - 1, 0))
        j = j.astype(np.int64)
        other = np.take_along_axis(
            np.broadcast_to(nb[:, None], (b, n, k, nb.shape[2])), j[..., None], axis=3
        )[..., 0]
        matched = np.where(wrong, other, own)
        matched_id = np.where(extracted, matched, -1).astype(np.int64)

        correct = extracted & (matched_id == own)
        return CameraFrames(
            t=t,
            pixels=pixels,
            pixels_true=pixels_true,
            visible=visible,
            occluded=occluded,
            extracted=extracted,
            matched_id=matched_id,
            blur_px=blur,
            occluder=band,
            n_visible=visible.sum(axis=2, dtype=np.int64),
            n_extracted=extracted.sum(axis=2, dtype=np.int64),
            n_correct=correct.sum(axis=2, dtype=np.int64),
        )

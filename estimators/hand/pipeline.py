"""Hand orientation from Kinect v2 frames: the pipeline of Yao, Chen, Pan & Huang 2023.

The stages (Yao 2023, sections 1.1-1.4):

1. Target user selection (1.1): among the tracked bodies pick the one nearest the sensor, keep it
   by id from frame to frame, re-select when its id is gone or no longer tracked.
2. Joint smoothing (1.2): the Kinect SDK's Holt double-exponential joint filter plus a weighted
   average over the last 5 frames (:class:`~estimators.hand.joint_smoothing.HoltSmoother`).
3. :func:`~estimators.hand.angles.quat_to_euler_paper` — the wrist quaternion to Euler angles with
   eq (1), and eq (2) where ``|wy - zx| > 0.499`` (1.3; :mod:`estimators.hand.angles`).
4. A Kalman filter per angle (:class:`~estimators.hand.params.KalmanParams` documents the model),
   then a median over consecutive Kalman outputs (1.4).

Every stage runs in one compiled kernel, :mod:`estimators.hand._kernel`. :class:`HandPipeline`
runs all four for the environment: one Kinect frame per ``update`` call, or the M frames of a
control step per ``update_frames`` call; :func:`estimate_hand_orientation` runs it over recorded
or simulated sequences. :class:`~estimators.hand.orientation.OrientationFilter` runs stages 3 and
4 alone on wrist quaternions or raw angles, batched over B streams, with the same code. The
paper's static-variance experiment (Tables 1-4) lives in :mod:`agents.experiments.hand_variance`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators.batching import TakesUsers
from estimators.hand import _kernel as _k
from estimators.hand.params import HandParams, kernel_params

__all__ = [
    "HandFrame",
    "HandPipeline",
    "check_hand_frames",
    "estimate_hand_orientation",
]


@dataclass
class HandFrame:
    """Output of :class:`HandPipeline` for one Kinect frame of B streams.

    Angles are ``[yaw, pitch, roll]`` in rad (the project's ZYX names; Yao 2023 calls these
    columns Roll, Pitch, Yaw), of the wrist orientation in camera space.

    Attributes:
        slot: (B,) int64 body slot of the target, -1 when no tracked body.
        body_id: (B,) int64 target id, 0 when none.
        reselected: (B,) bool, a new target was selected this frame (filters were reset).
        has_target: (B,) bool, a tracked target exists in this frame.
        joints: (B, J, 3) smoothed target joints, metres (NaN without target or for untracked
            joints).
        joint_state: (B, J) int8 raw tracking states of the target's joints (0 without target).
        all_inferred: (B,) bool, the target has no *tracked* joint, only inferred ones.
        ypr_raw, ypr_kalman, ypr, quat_valid, singular, valid: see
            :class:`~estimators.hand.orientation.OrientationFrame`.
    """

    slot: NDArray[np.int64]
    body_id: NDArray[np.int64]
    reselected: NDArray[np.bool_]
    has_target: NDArray[np.bool_]
    joints: NDArray[np.float64]
    joint_state: NDArray[np.int8]
    all_inferred: NDArray[np.bool_]
    ypr_raw: NDArray[np.float64]
    ypr_kalman: NDArray[np.float64]
    ypr: NDArray[np.float64]
    quat_valid: NDArray[np.bool_]
    singular: NDArray[np.bool_]
    valid: NDArray[np.bool_]

    def at(self, t: int) -> HandFrame:
        """Frame ``t`` of a frame stack such as :meth:`HandPipeline.update_frames` returns.

        Args:
            t: time index (negative counts from the end: ``at(-1)`` is the last frame).

        Returns:
            :class:`HandFrame` of views ``field[:, t]`` (B, ...).
        """
        return HandFrame(*(getattr(self, name)[:, t] for name in _HAND_FRAME_FIELDS))


_HAND_FRAME_FIELDS = tuple(f.name for f in fields(HandFrame))  # in the constructor's order


class HandPipeline(TakesUsers):
    """Yao 2023's hand-orientation pipeline, streaming, batched over B users.

    Per frame: select the target user (Yao 2023, 1.1), reset the filters of streams whose
    target changed, smooth its joints (the Kinect SDK's Holt filter and the weighted average, as
    :class:`~estimators.hand.joint_smoothing.HoltSmoother` does), convert its wrist quaternion
    (eq 1/2) and filter the angles (Kalman, then median), as
    :class:`~estimators.hand.orientation.OrientationFilter` does.

    Target selection. The current target is kept while a slot holds its id and is tracked, else
    the tracked body nearest the sensor is selected: nearest by the Euclidean distance from the
    sensor of a body's centre, the mean of its valid ``center_joints`` (default SpineBase,
    SpineMid, SpineShoulder: the torso, which moves least). Yao 2023 says "nearest by depth
    data"; the Euclidean distance differs from depth only for bodies far off-axis. Slots with id
    0, untracked slots and bodies without a valid centre joint are never selected; ties go to the
    lowest slot. The current target is kept even when another body comes nearer.

    Documented behaviour on bad frames:

    * no tracked body: ``has_target`` False, ``slot`` -1, ``body_id`` 0, joints NaN; the angles
      coast then hold their last value with ``quat_valid`` False. The next target found is a new
      selection and resets the filters (even if it has the old id: the gap may be long).
    * the angles are NaN, with ``valid`` False, only between a (re)selection and the new target's
      first usable wrist quaternion: they never carry one user's estimate over to another.
    * NaN joints / untracked joints: NaN in ``joints`` for those joints only; their filter
      restarts when they come back.
    * a frame with only inferred joints: the body is still the target if tracked; joints are
      smoothed with the doubled inferred radii; ``all_inferred`` is True; the wrist quaternion is
      used if ``min_wrist_state`` is 1 (default), else the frame is an orientation dropout.
    * zero-norm or NaN wrist quaternion: orientation dropout (as above), ``quat_valid`` False.
    * infinite values, wrong shapes, states outside {0, 1, 2}, ids that are not integers,
      negative or repeated within a frame: ValueError.

    The frames run through the compiled kernel :mod:`estimators.hand._kernel`, one user at a
    time: :meth:`update` takes one frame, :meth:`update_frames` the M frames of a control step
    in one call, with the same numbers. The pipeline holds the kernel's state (target ids, Holt
    filters, Kalman filters, median windows); :meth:`reset` clears it.

    Args:
        batch_size: number of users B.
        params: :class:`HandParams` (defaults if None).
        num_joints: joints per body J (25 for Kinect v2).
        num_bodies: body slots per frame K (6 for Kinect v2).
    """

    per_user_fields = ("_state",)  # the kernel's (target, user, joint, ring, window) arrays
    batch_size_field = "batch_size"

    def __init__(
        self,
        batch_size: int,
        params: HandParams | None = None,
        num_joints: int = 25,
        num_bodies: int = 6,
    ) -> None:
        if batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        self.params = params if params is not None else HandParams()
        p = self.params
        if max(p.wrist_joint, *p.center_joints) >= num_joints:
            raise ValueError(f"wrist_joint and center_joints must be < num_joints={num_joints}")
        self.batch_size = int(batch_size)
        self.num_joints = int(num_joints)
        self.num_bodies = int(num_bodies)
        w = np.asarray(p.holt.average_weights, dtype=np.float64)
        self._weights = w / w.sum()  # the Holt average's weights, newest first
        self._head = 0  # the Holt ring's newest slot, shared by all users
        self._center = np.asarray(p.center_joints, dtype=np.int64)
        self._prm, self._axes = kernel_params(p)
        self._state = _k.new_state(self.batch_size, self.num_joints, w.size, p.median_window)
        #: (B,) int64 id of each stream's current target, 0 for none (the kernel's own array).
        self.target_id = self._state[0]

    def reset(self, mask: ArrayLike | None = None) -> None:
        """Forget target and filters of the streams where ``mask`` (B,) is True (all if None)."""
        m = np.ones(self.batch_size, bool) if mask is None else np.asarray(mask, dtype=bool)
        if m.shape != (self.batch_size,):
            raise ValueError(f"mask must have shape ({self.batch_size},), got {m.shape}")
        _k.forget_kernel(self.batch_size)(m, self._state)

    def take_users(self, rows: NDArray[np.intp]) -> None:
        """Keep the streams ``rows`` (:class:`~estimators.batching.TakesUsers`), and
        :attr:`target_id` with them (a view of the kernel's target array)."""
        super().take_users(rows)
        self.target_id = self._state[0]

    def _inputs(
        self,
        body_id: ArrayLike,
        body_tracked: ArrayLike,
        joints: ArrayLike,
        joint_state: ArrayLike,
        hand_quat: ArrayLike,
        lead: tuple[int, ...],
    ) -> tuple[NDArray[np.int64], NDArray[np.bool_], NDArray[np.float64], NDArray, NDArray]:
        """The kernel's input tuple, shapes checked against ``lead`` + (K, ...): int64 ids, bool
        tracking flags, float64 joints and quaternions, integer joint states."""
        k, nj = self.num_bodies, self.num_joints
        ids = np.asarray(body_id)
        tracked = np.asarray(body_tracked)
        jts = np.asarray(joints, dtype=np.float64)
        st = np.asarray(joint_state)
        hq = np.asarray(hand_quat, dtype=np.float64)
        for name, arr, shape in (
            ("body_id", ids, (*lead, k)),
            ("body_tracked", tracked, (*lead, k)),
            ("joints", jts, (*lead, k, nj, 3)),
            ("joint_state", st, (*lead, k, nj)),
            ("hand_quat", hq, (*lead, k, 4)),
        ):
            if arr.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
        tracked = tracked if tracked.dtype == np.bool_ else tracked.astype(bool)
        return _kernel_ids(ids), tracked, jts, _kernel_states(st), hq

    def update(
        self,
        body_id: ArrayLike,
        body_tracked: ArrayLike,
        joints: ArrayLike,
        joint_state: ArrayLike,
        hand_quat: ArrayLike,
    ) -> HandFrame:
        """Process one Kinect frame.

        Args:
            body_id: (B, K) int body ids, 0 = empty slot.
            body_tracked: (B, K) bool.
            joints: (B, K, J, 3) camera-space joints, metres, NaN where not tracked.
            joint_state: (B, K, J) int tracking states (0 not tracked, 1 inferred, 2 tracked).
            hand_quat: (B, K, 4) wrist orientations ``[w, x, y, z]`` in camera space.

        Returns:
            :class:`HandFrame`.

        Raises:
            ValueError: see the class docstring.
        """
        b = self.batch_size
        frames = self._inputs(body_id, body_tracked, joints, joint_state, hand_quat, (b,))
        out = _new_frames((b,), self.num_joints)
        self._run(frames, 1, out, "")
        return HandFrame(*out)

    def update_frames(
        self,
        body_id: ArrayLike,
        body_tracked: ArrayLike,
        joints: ArrayLike,
        joint_state: ArrayLike,
        hand_quat: ArrayLike,
    ) -> HandFrame:
        """Process M consecutive Kinect frames in one call: the same numbers as M :meth:`update`.

        For the environment, which receives the M (about 3) Kinect frames of a control step at
        once: one call instead of M. ``HandFrame.at(-1)`` is the frame a last :meth:`update` would
        have returned.

        Args:
            body_id: (B, M, K) int body ids, 0 = empty slot.
            body_tracked: (B, M, K) bool.
            joints: (B, M, K, J, 3) camera-space joints, metres, NaN where not tracked.
            joint_state: (B, M, K, J) int tracking states.
            hand_quat: (B, M, K, 4) wrist orientations ``[w, x, y, z]``.

        Returns:
            :class:`HandFrame` whose arrays carry the frame axis after the batch axis, e.g.
            ``ypr`` (B, M, 3), ``joints`` (B, M, J, 3).

        Raises:
            ValueError: as :meth:`update`; every frame is checked before any is processed, so a
                bad frame leaves the state untouched (M :meth:`update` calls would have processed
                the frames before it), and the message names the frame.
        """
        b = self.batch_size
        shape = np.shape(body_id)
        if len(shape) != 3 or shape[0] != b or shape[1] < 1:
            raise ValueError(
                f"body_id must have shape ({b}, M, {self.num_bodies}) with M >= 1, got {shape}"
            )
        m = shape[1]
        frames = self._inputs(body_id, body_tracked, joints, joint_state, hand_quat, (b, m))
        rows = b * m
        out = _new_frames((b, m), self.num_joints)
        self._run(
            tuple(a.reshape(rows, *a.shape[2:]) for a in frames),
            m,
            tuple(a.reshape(rows, *a.shape[2:]) for a in out),
            " (frame {t})",
        )
        return HandFrame(*out)

    def _run(
        self, frames: tuple[NDArray, ...], m: int, out: tuple[NDArray, ...], where: str
    ) -> None:
        """Validate, then run the kernel over rows ``b * m + t``, writing into ``out``."""
        b = self.batch_size
        ids, _, jts, st, hq = frames
        flat = jts.reshape(-1) if jts.flags.c_contiguous else _EMPTY
        code, t = _k.validate(ids, jts, st, hq, b, m, flat)
        if code:
            raise ValueError(_KERNEL_ERRORS[code] + where.format(t=t))
        _k.hand_kernel(b)(
            frames,
            m,
            self._prm,
            self._axes,
            self._center,
            self._weights,
            self._head,
            self._state,
            out,
        )
        n_hist = self._weights.size
        if n_hist > 1:  # the ring advances once per frame
            self._head = (self._head - m) % n_hist


def _kernel_ids(ids: NDArray) -> NDArray[np.int64]:
    """Body ids as int64 (uint64 ids below 2**63 included); ValueError for other dtypes."""
    kind = ids.dtype.kind
    if kind == "i" or (kind == "u" and ids.dtype.itemsize < 8):
        return ids if ids.dtype == np.int64 else ids.astype(np.int64)
    if kind == "u":
        if ids.size and ids.max() > np.iinfo(np.int64).max:
            raise ValueError("body_id must be < 2**63")
        return ids.astype(np.int64)
    raise ValueError(f"body_id must hold integers, got dtype {ids.dtype}")


def _kernel_states(st: NDArray) -> NDArray:
    """Tracking states as int64 (one dtype, so the kernel is compiled once whatever the caller
    passes); float or bool states must be whole numbers."""
    if st.dtype.kind in "iu":
        return st if st.dtype == np.int64 else st.astype(np.int64)
    with np.errstate(invalid="ignore"):
        whole = st.astype(np.int64)
    if not np.array_equal(whole, st):
        raise ValueError(_KERNEL_ERRORS[_k.ERR_STATE_RANGE])
    return whole


def _new_frames(lead: tuple[int, ...], nj: int) -> tuple[NDArray, ...]:
    """Empty :class:`HandFrame` fields (in their order) for ``lead`` = (B,) or (B, M)."""
    return (
        np.empty(lead, np.int64),
        np.empty(lead, np.int64),
        np.empty(lead, bool),
        np.empty(lead, bool),
        np.empty((*lead, nj, 3)),
        np.empty((*lead, nj), np.int8),
        np.empty(lead, bool),
        np.empty((*lead, 3)),
        np.empty((*lead, 3)),
        np.empty((*lead, 3)),
        np.empty(lead, bool),
        np.empty(lead, bool),
        np.empty(lead, bool),
    )


_EMPTY = np.empty(0)  # "no flat view" for _kernel.validate

#: ValueError messages of the kernel's input checks.
_KERNEL_ERRORS = {
    _k.ERR_JOINTS_INF: "joints contains infinite coordinates; use NaN for untracked joints",
    _k.ERR_QUAT_INF: "hand_quat contains infinite entries; use NaN for a dropout",
    _k.ERR_STATE_RANGE: "joint_state values must be 0 (not tracked), 1 (inferred) or 2",
    _k.ERR_NEGATIVE_ID: "body_id must be >= 0 (0 marks an empty slot)",
    _k.ERR_DUPLICATE_ID: "body_id holds the same non-zero id in two slots of one stream",
}


def estimate_hand_orientation(
    body_id: ArrayLike,
    body_tracked: ArrayLike,
    joints: ArrayLike,
    joint_state: ArrayLike,
    hand_quat: ArrayLike,
    params: HandParams | None = None,
) -> HandFrame:
    """Run :class:`HandPipeline` over whole sequences (offline API; same numbers as streaming).

    Args:
        body_id: (B, M, K) or, for one stream, (M, K) body ids over M frames.
        body_tracked: (B, M, K) or (M, K) bool.
        joints: (B, M, K, J, 3) or (M, K, J, 3) metres.
        joint_state: (B, M, K, J) or (M, K, J).
        hand_quat: (B, M, K, 4) or (M, K, 4).
        params: :class:`HandParams`.

    Returns:
        :class:`HandFrame` whose arrays carry the time axis after the batch axis, e.g. ``ypr`` is
        (B, M, 3) — or (M, 3) for single-stream input.
    """
    ids = np.asarray(body_id)
    single = ids.ndim == 2
    arrays = [np.asarray(a) for a in (body_id, body_tracked, joints, joint_state, hand_quat)]
    if single:
        arrays = [a[None] for a in arrays]
    ids = arrays[0]
    if ids.ndim != 3:
        raise ValueError(f"body_id must have shape (B, M, K) or (M, K), got {np.shape(body_id)}")
    b, m, k = ids.shape
    for name, a in zip(
        ("body_tracked", "joints", "joint_state", "hand_quat"), arrays[1:], strict=True
    ):
        if a.shape[:3] != (b, m, k):
            raise ValueError(f"{name} must start with shape {(b, m, k)}, got {a.shape}")
    if arrays[2].ndim != 5:
        raise ValueError(
            f"joints must have shape (B, M, K, J, 3) or (M, K, J, 3), got {np.shape(joints)}"
        )
    nj = arrays[2].shape[3]
    pipe = HandPipeline(b, params, num_joints=nj, num_bodies=k)
    if m == 0:
        raise ValueError("the sequences hold no frame (M = 0)")
    out = pipe.update_frames(*arrays)  # the same numbers as M calls of update()
    if single:
        return HandFrame(**{f.name: getattr(out, f.name)[0] for f in fields(HandFrame)})
    return out


def check_hand_frames(frames: HandFrame, batch_size: int, who: str) -> int:
    """The number of frames M of a (B, M) :class:`HandFrame` stack, or a ValueError naming
    ``who`` when its angles are not (batch_size, M, 3) or its flags not (batch_size, M)."""
    ypr = np.shape(getattr(frames, "ypr_raw", None))
    if len(ypr) != 3 or ypr[0] != batch_size or ypr[2] != 3 or ypr[1] < 1:
        raise ValueError(
            f"{who}: frames must be a HandFrame stacked over M >= 1 frames, ypr_raw of shape "
            f"({batch_size}, M, 3); got {ypr}"
        )
    m = ypr[1]
    for name in ("ypr", "quat_valid", "reselected", "valid"):
        shape = np.shape(getattr(frames, name))
        want = (batch_size, m, 3) if name == "ypr" else (batch_size, m)
        if shape != want:
            raise ValueError(f"{who}: frames.{name} must have shape {want}, got {shape}")
    return m

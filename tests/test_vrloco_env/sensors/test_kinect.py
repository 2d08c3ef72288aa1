"""Kinect v2 model: Yao 2023 calibration, noise vs depth, tracking states, bodies, determinism."""

import numpy as np
import pytest
from kernel_cases.kinect import capture

from estimators.rotations import (
    angle_diff,
    quat_conjugate,
    quat_multiply,
    quat_rotate,
    quat_to_ypr,
    rotation_angle,
)
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.kinect import (
    MAX_BODIES,
    TORSO_JOINTS,
    KinectFrames,
    KinectSpec,
    KinectV2,
    camera_quat,
    camera_to_world,
    hand_to_sdk_wrist,
    quat_camera_to_world,
    quat_world_to_camera,
    sdk_wrist_to_hand,
    standing_skeleton,
    world_to_camera,
)
from vrloco_env.sensors.kinect import _kernel as _kinect_numba
from vrloco_env.sensors.kinect._kernel import scene as _kinect_scene
from vrloco_env.user import INFERRED, NOT_TRACKED, TRACKED, Joint

FPS = 30.0
# Yao 2023, Tables 1-3: the 11 static hand "yaw" angles (turn about the forearm), deg.
PAPER_ANGLES_DEG = (-90, 0, 90, -35, -50, -65, -75, 30, 45, 60, 75)
# A quiet sensor for tests that check one mechanism at a time.
QUIET = {
    "joint_bias_std_m": 0.0,
    "burst_prob": 0.0,
    "random_inferred_prob": 0.0,
    "n_bystanders": 0,
}


def make(spec: KinectSpec, seeds) -> KinectV2:
    k = KinectV2(spec, BatchRng.from_seeds(list(seeds)))
    k.reset()
    return k


def static(joints, quat, m):
    """Repeat one (B, 25, 3) pose and (B, 4) orientation over m frames."""
    b = joints.shape[0]
    return (
        np.arange(m) / FPS,
        np.broadcast_to(joints[:, None], (b, m, 25, 3)),
        np.broadcast_to(quat[:, None], (b, m, 4)),
    )


def user_at(distance, b=1, lateral=0.0, **kw):
    """Users standing `distance` m in front of the default sensor (at x = 2.5 m, facing west)."""
    pos = np.zeros((b, 3))
    pos[:, 0] = 2.5 - np.asarray(distance)
    pos[:, 1] = lateral
    return standing_skeleton(pos, np.zeros(b), **kw)


def target(frames: KinectFrames, name: str):
    """The target user's slot of a per-slot field, (B, M, ...)."""
    arr = getattr(frames, name)
    b = np.arange(arr.shape[0])[:, None]
    m = np.arange(arr.shape[1])[None, :]
    return arr[b, m, frames.truth.slot]


def assert_frames_equal(a: KinectFrames, b: KinectFrames):
    for name in ("t", "body_id", "body_tracked", "joints", "joint_state", "hand_quat"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for name in ("slot", "joints", "hand_quat"):
        np.testing.assert_array_equal(getattr(a.truth, name), getattr(b.truth, name))


# ------------------------------------------------------------------------------------ conventions


def test_camera_space_follows_the_kinect_sdk():
    """+z from the sensor to the user, +y up, +x to the sensor's left = the user's right."""
    spec = KinectSpec()
    joints, _ = user_at(2.5)
    cam = world_to_camera(spec, joints[0])
    assert cam[Joint.SPINE_BASE, 2] == pytest.approx(2.5, abs=1e-9)
    assert cam[Joint.HEAD, 1] > cam[Joint.SPINE_BASE, 1] + 0.5
    assert cam[Joint.SHOULDER_RIGHT, 0] > 0.1 > -0.1 > cam[Joint.SHOULDER_LEFT, 0]
    # Floor height: the sensor is 0.9 m up, so the feet sit near y = -0.9 + foot height.
    assert cam[Joint.FOOT_LEFT, 1] == pytest.approx(-0.9 + 0.02 * 1.7, abs=1e-9)
    np.testing.assert_allclose(camera_to_world(spec, cam), joints[0], atol=1e-12)
    # A tilted sensor moved elsewhere: the round trips still hold.
    spec2 = KinectSpec.facing([1.0, -2.0], 0.7, distance_m=3.0, height_m=1.1, camera_tilt_deg=-10)
    q = np.array([0.3, -0.2, 0.9, 0.1]) / np.linalg.norm([0.3, -0.2, 0.9, 0.1])
    np.testing.assert_allclose(
        camera_to_world(spec2, world_to_camera(spec2, joints)), joints, atol=1e-12
    )
    np.testing.assert_allclose(quat_camera_to_world(spec2, quat_world_to_camera(spec2, q)), q)
    # facing(): the sensor looks back at the user, level camera z along the user's -forward.
    z_axis = quat_rotate(camera_quat(KinectSpec.facing([0, 0], 0.7)), [0.0, 0.0, 1.0])
    np.testing.assert_allclose(z_axis, [-np.cos(0.7), -np.sin(0.7), 0.0], atol=1e-12)


def test_wrist_quaternion_is_the_sdk_frame_and_eq1_names_match_the_hand():
    """SDK wrist frame: +y along the forearm. With the forearm pointing at the sensor (motion.py's
    pose), Yao 2023's eq (1) "roll" / "pitch" / "yaw" -- quat_to_ypr(q)[..., 0 / 1 / 2] -- follow
    the hand's turn about the forearm, fingertips up/down and sweep left/right.
    """
    spec = KinectSpec()
    # Up to 90 deg from rest; pitch stops at 75 deg (fingertips straight up/down is eq (2)'s lock).
    a = np.radians([-90.0, -40.0, 0.0, 25.0, 75.0])
    zero = np.zeros_like(a)
    poses = {  # hand [yaw, pitch, roll] relative to the arm pose, one axis at a time
        "roll": np.stack([zero, zero, a], -1),
        "pitch": np.stack([zero, np.clip(a, -1.31, 1.31), zero], -1),
        "yaw": np.stack([a, zero, zero], -1),
    }
    for axis, hand_ypr in poses.items():
        joints, q_world = user_at(2.5, b=a.size, right_arm="forward", hand_ypr_rad=hand_ypr)
        frames = make(KinectSpec(**QUIET), range(a.size)).capture(*static(joints, q_world, 1))
        q = frames.truth.hand_quat[:, 0]
        # Truth equals the explicit conversion: world -> camera, then hand -> SDK wrist frame.
        np.testing.assert_allclose(
            q, hand_to_sdk_wrist(quat_world_to_camera(spec, q_world)), atol=1e-12
        )
        np.testing.assert_allclose(
            sdk_wrist_to_hand(q), quat_world_to_camera(spec, q_world), atol=1e-12
        )
        ypr = quat_to_ypr(q)  # [paper roll, paper pitch, paper yaw]
        expected = {
            "roll": [np.pi / 2 - a, zero, zero - np.pi / 2],
            "pitch": [zero + np.pi / 2, np.clip(a, -1.31, 1.31), zero - np.pi / 2],
            "yaw": [zero + np.pi / 2, zero, a - np.pi / 2],
        }[axis]
        np.testing.assert_allclose(ypr, np.stack(expected, -1), atol=1e-9, err_msg=axis)
        # SDK +y is the bone elbow -> wrist, in camera space, for every hand pose.
        cam = frames.truth.joints[:, 0]
        bone = cam[:, Joint.WRIST_RIGHT] - cam[:, Joint.ELBOW_RIGHT]
        bone /= np.linalg.norm(bone, axis=-1, keepdims=True)
        forearm = quat_rotate(q, [0.0, 1.0, 0.0])
        if axis == "roll":  # the forearm itself does not move when the hand turns about it
            np.testing.assert_allclose(forearm, bone, atol=1e-9)
        # The thumb joint sits on the SDK +z (normal) side, the hand tip along SDK +y.
        thumb = cam[:, Joint.THUMB_RIGHT] - cam[:, Joint.HAND_RIGHT]
        tip = cam[:, Joint.HAND_TIP_RIGHT] - cam[:, Joint.HAND_RIGHT]
        assert np.all(np.sum(thumb * quat_rotate(q, [0.0, 0.0, 1.0]), axis=-1) > 0.02)
        np.testing.assert_allclose(
            tip / np.linalg.norm(tip, axis=-1, keepdims=True), forearm, atol=1e-9
        )


# ------------------------------------------------------------------------------------ calibration


def circular_var_deg2(angles):
    """Variance (deg^2) over axis 1 of angles (rad) about their circular mean (no wrap jumps)."""
    mean = np.angle(np.exp(1j * angles).mean(axis=1, keepdims=True))
    return np.degrees(angle_diff(angles, mean)).var(axis=1)


def test_static_hand_raw_euler_variance_matches_seed_003_tables():
    """A static hand turned about the forearm to the paper's 11 angles, 10 s at 30 Hz, default
    sensor: the raw eq (1) variances lie in Tables 1-3's range 0.5-14 deg^2 (mean of 3 runs).

    Eq (1) is computed as rotations.quat_to_ypr -- the same formula with eq (1)'s "roll", "pitch",
    "yaw" at indices 0, 1, 2. The turn about the forearm is eq (1)'s "roll" in the SDK frame (see
    the module docstring); the variances are taken about the circular mean, as the "roll" of a hand
    turned by -90 deg sits at 180 deg.
    """
    repeats, m = 3, 300
    turns = np.repeat(np.radians(PAPER_ANGLES_DEG), repeats)
    hand_ypr = np.stack([0 * turns, 0 * turns, turns], axis=-1)
    joints, q = user_at(2.5, b=turns.size, right_arm="forward", hand_ypr_rad=hand_ypr)
    kinect = make(KinectSpec(), range(100, 100 + turns.size))
    frames = kinect.capture(*static(joints, q, m))
    q_meas = target(frames, "hand_quat")
    assert np.all(np.isfinite(q_meas)), "the hand must stay tracked"
    ypr = quat_to_ypr(q_meas)
    var = circular_var_deg2(ypr).reshape(len(PAPER_ANGLES_DEG), repeats, 3).mean(axis=1)
    assert np.all((var > 0.5) & (var < 14.0)), np.round(var, 2)
    # Not an over- or under-scaled sensor either: the means over the angles sit near the tables'
    # means ("roll" 4.7, "pitch" 3.5, "yaw" 6.5 deg^2).
    np.testing.assert_allclose(var.mean(axis=0), [4.7, 3.5, 6.5], rtol=0.35)
    # And the noise is noise: the time mean recovers the true turn within 1 deg.
    true_roll = quat_to_ypr(frames.truth.hand_quat)[..., 0]
    err = np.degrees(angle_diff(ypr[..., 0], true_roll)).mean(axis=1)
    assert np.abs(err).max() < 1.0


# ------------------------------------------------------------------------------------ joint noise


def test_joint_noise_grows_with_depth_as_specified():
    spec = KinectSpec(**QUIET)
    depths = np.array([1.5, 2.5, 3.5, 4.3])
    joints, q = user_at(depths, b=depths.size)
    frames = make(spec, range(4)).capture(*static(joints, q, 1800))
    meas = target(frames, "joints")[:, :, list(TORSO_JOINTS)]  # scale-1 joints
    assert np.all(np.isfinite(meas))
    std = np.sqrt(meas.var(axis=1).mean(axis=(1, 2)))
    true_z = frames.truth.joints[:, 0, list(TORSO_JOINTS), 2]
    expected = np.sqrt((spec.joint_noise_std_m(true_z) ** 2).mean(axis=1))
    np.testing.assert_allclose(std, expected, rtol=0.08)
    assert np.all(np.diff(std) > 0)
    # Mean error is zero (no bias configured), and extremities are noisier than the trunk.
    err = meas.mean(axis=1) - frames.truth.joints[:, 0, list(TORSO_JOINTS)]
    assert np.abs(err).max() < 4 * expected.max()
    tips = target(frames, "joints")[:, :, [Joint.HAND_TIP_LEFT, Joint.HAND_TIP_RIGHT]]
    assert np.all(np.sqrt(tips.var(axis=1).mean(axis=(1, 2))) > 3 * std)


def test_target_joint_noise_has_the_specified_white_fraction_and_time_constant():
    """White (variance fraction wf) + AR(1) (tau): autocorrelation (1 - wf) exp(-k / (fps tau)) at
    lag k >= 1 -- the model draws it as one ARMA(1, 1) process, which must be the same process."""
    spec = KinectSpec(**QUIET)
    joints, q = user_at(2.5, b=4)
    frames = make(spec, range(40, 44)).capture(*static(joints, q, 3000))
    noise = target(frames, "joints") - frames.truth.joints  # no offsets configured
    x = noise / noise.std(axis=1, keepdims=True)
    rho = np.exp(-1.0 / (FPS * spec.joint_noise_tau_s))
    wf = spec.joint_noise_white_fraction
    for lag in (1, 2, 5, 15, 30):
        r = np.mean(x[:, lag:] * x[:, :-lag])
        assert r == pytest.approx((1 - wf) * rho**lag, abs=0.025), lag
    # Pure AR(1) (no white part) would give 0.936 at lag 1: the test sees the difference.
    assert abs(np.mean(x[:, 1:] * x[:, :-1]) - rho) > 0.03


@pytest.mark.slow
def test_joint_noise_is_stationary_from_the_first_frame():
    """Noise states start in their stationary distribution: the std over users at frames 0 and 1
    is the spec's std (no warm-up transient)."""
    spec = KinectSpec(**QUIET)
    b = 200
    joints, q = user_at(np.linspace(2.0, 4.0, b), b=b)
    frames = make(spec, range(b)).capture(*static(joints, q, 2))
    truth = frames.truth.joints
    sigma = spec.joint_noise_std_m(truth[..., 2]) * np.asarray(spec.joint_noise_scale)
    ratio = (target(frames, "joints") - truth) / sigma[..., None]
    assert np.all(np.isfinite(ratio))
    for m in (0, 1):
        assert ratio[:, m].std() == pytest.approx(1.0, abs=0.03), m


def test_arma_form_of_white_plus_ar1_noise():
    """s (e_t + theta e_{t-1}) has the variance and lag-1 covariance of (1 - rho B) applied to
    sqrt(wf) white + sqrt(1 - wf) unit AR(1), with the invertible root."""
    for wf in (0.0, 0.05, 0.5, 1.0):
        for rho in (0.0, 0.5, 0.9355):
            s, theta = _kinect_numba.arma_parameters(wf, rho)
            g0 = wf * (1 + rho**2) + (1 - wf) * (1 - rho**2)
            assert s**2 * (1 + theta**2) == pytest.approx(g0, abs=1e-12)
            assert s**2 * theta == pytest.approx(-rho * wf, abs=1e-12)
            assert abs(theta) <= 1.0 and 0.0 <= s <= 1.0 + 1e-12


def test_split_uniforms_give_independent_draws():
    """One uniform through a chain of splits (Bernoulli, categorical, geometric, geometric) gives
    draws whose joint distribution is the product of their marginals: fed an even grid of
    uniforms, the chain's outcome frequencies match the product probabilities."""
    n = 20000
    p, groups, q = 0.3, 4, 0.6
    outcomes = np.empty((n, 4), dtype=int)
    for i in range(n):
        u = (i + 0.5) / n
        hit, u = _kinect_numba.bernoulli_split.py_func(u, p)
        group, u = _kinect_numba.categorical_split.py_func(u, groups)
        first, u = _kinect_numba.geometric_split.py_func(u, q)
        second, _ = _kinect_numba.geometric_split.py_func(u, q)
        outcomes[i] = hit, group, min(first, 3), min(second, 3)
    geo = np.array([1 - q, (1 - q) * q, q**2])  # P(L = 1), P(L = 2), P(L >= 3)
    expected = np.einsum("a,b,c,d->abcd", [1 - p, p], np.full(groups, 1 / groups), geo, geo)
    counts = np.zeros_like(expected)
    np.add.at(counts, (outcomes[:, 0], outcomes[:, 1], outcomes[:, 2] - 1, outcomes[:, 3] - 1), 1)
    np.testing.assert_allclose(counts / n, expected, atol=5e-4)


def test_bystander_joints_keep_their_noise_level_and_jitter_rigidly():
    """Bystanders' noise is drawn at lower dimension: every joint keeps its own std (depth and
    per-joint scale), but one noise vector moves them all, so the noise of the difference of two
    joints is the difference of their stds (sway and offsets cancel in it too)."""
    spec = KinectSpec(
        **{**QUIET, "n_bystanders": 2},
        bystander_dwell_s=1e9,  # they stand (and sway)
        bystander_distance_m=(3.6, 3.9),
        bystander_lateral_m=1.5,
    )
    b, m = 4, 3000
    joints, q = user_at(2.0, b=b, lateral=-0.8)
    frames = make(spec, range(60, 60 + b)).capture(*static(joints, q, m))
    tip, spine = Joint.HAND_TIP_LEFT, Joint.SPINE_MID
    scale = np.asarray(spec.joint_noise_scale)
    measured, expected = [], []
    for u in range(b):
        for k in range(MAX_BODIES):
            state = frames.joint_state[u, :, k]
            if k == frames.truth.slot[u, 0] or not np.all(state[:, [tip, spine]] == TRACKED):
                continue
            meas = frames.joints[u, :, k]
            depth = meas[:, [tip, spine], 2].mean(axis=0)
            sig = spec.joint_noise_std_m(depth) * scale[[tip, spine]]
            # RMS over the axes of the std of (tip - spine): |sigma_tip - sigma_spine| if rigid,
            # sqrt(sigma_tip^2 + sigma_spine^2) (38 % more here) if independent.
            measured.append(np.sqrt((meas[:, tip] - meas[:, spine]).var(axis=0).mean()))
            expected.append(abs(sig[0] - sig[1]))
    assert len(measured) >= 3, "some bystanders must stand in view, fully tracked"
    np.testing.assert_allclose(measured, expected, rtol=0.15)
    assert np.mean(measured) / np.mean(expected) == pytest.approx(1.0, abs=0.08)


# ------------------------------------------------------------------------------ tracking states


def in_frustum(spec: KinectSpec, cam):
    th, tv = np.tan(np.radians(spec.fov_deg) / 2)
    z = cam[..., 2]
    return (
        (z >= spec.depth_range_m[0])
        & (z <= spec.depth_range_m[1])
        & (np.abs(cam[..., 0]) <= th * z)
        & (np.abs(cam[..., 1]) <= tv * z)
    )


def test_joints_outside_the_field_of_view_or_range_are_not_tracked():
    spec = KinectSpec(**QUIET)
    # User 2 m away, 1.25 m to the sensor's left: her right arm leaves the field of view (the
    # half-width there is 2 tan(35.3 deg) = 1.42 m). Second user: 4.8 m away, beyond the range.
    j1, q1 = user_at(2.0, lateral=-1.25)
    j2, q2 = user_at(4.8)
    frames = make(spec, [1, 2]).capture(
        *static(np.concatenate([j1, j2]), np.concatenate([q1, q2]), 30)
    )
    state = target(frames, "joint_state")
    joints = target(frames, "joints")
    inside = in_frustum(spec, frames.truth.joints)
    # User 1: tracked, with exactly the joints outside the frustum not tracked (and NaN).
    assert target(frames, "body_tracked")[0].all()
    assert (~inside[0]).any() and inside[0].mean() > 0.5
    np.testing.assert_array_equal(state[0] == NOT_TRACKED, ~inside[0])
    np.testing.assert_array_equal(np.isnan(joints[0]).any(axis=-1), ~inside[0])
    assert np.all(state[0][inside[0]] == TRACKED)
    assert Joint.HAND_RIGHT in np.flatnonzero(~inside[0, 0])
    # Its right wrist is out of view: no wrist orientation.
    assert np.isnan(target(frames, "hand_quat")[0]).all()
    # User 2: beyond 4.5 m the body is lost: no id, all joints NaN and not tracked.
    assert not target(frames, "body_tracked")[1].any()
    assert np.all(target(frames, "body_id")[1] == 0)
    assert np.isnan(joints[1]).all() and np.all(state[1] == NOT_TRACKED)


def test_hand_behind_the_torso_is_inferred_and_noisier():
    spec = KinectSpec(**QUIET)
    joints, q = user_at(2.5, b=2)
    behind = [Joint.WRIST_RIGHT, Joint.HAND_RIGHT, Joint.HAND_TIP_RIGHT, Joint.THUMB_RIGHT]
    # User 0: right hand 15 cm behind the back, near the spine (+x world is toward the sensor).
    joints[0, behind] = joints[0, Joint.SPINE_MID] + np.array([-0.15, -0.05, -0.1])
    frames = make(spec, [5, 6]).capture(*static(joints, q, 300))
    state = target(frames, "joint_state")
    assert np.all(state[0][:, behind] == INFERRED)
    others = np.setdiff1d(np.arange(25), behind)
    assert np.all(state[0][:, others] == TRACKED)
    assert np.all(state[1] == TRACKED)
    # Inferred joints are still reported, with more noise (x inferred_noise_factor).
    meas = target(frames, "joints")
    assert np.all(np.isfinite(meas))
    std = meas.std(axis=1)
    ratio = std[0, Joint.HAND_RIGHT].mean() / std[1, Joint.HAND_RIGHT].mean()
    assert 2.0 < ratio < 4.5
    err = rotation_angle(
        quat_multiply(quat_conjugate(frames.truth.hand_quat), target(frames, "hand_quat"))
    )
    rms = np.sqrt(np.mean(err**2, axis=1))
    assert 2.0 < rms[0] / rms[1] < 4.5


def test_jitter_bursts_hit_one_limb_for_a_few_frames():
    spec = KinectSpec(**{**QUIET, "burst_prob": 0.02})
    joints, q = user_at(2.5, b=4)
    frames = make(spec, range(4)).capture(*static(joints, q, 900))
    meas = target(frames, "joints")
    step = np.linalg.norm(np.diff(meas, axis=1), axis=-1)  # frame-to-frame jump, (B, M-1, 25)
    calm = make(KinectSpec(**QUIET), range(4)).capture(*static(joints, q, 900))
    calm_step = np.linalg.norm(np.diff(target(calm, "joints"), axis=1), axis=-1)
    limit = calm_step.max(axis=(0, 1))  # per joint, without bursts
    jumps = step > 3 * limit
    assert not jumps[..., list(TORSO_JOINTS)].any(), "bursts hit limbs only"
    assert jumps[..., Joint.WRIST_RIGHT].any() and jumps[..., Joint.ANKLE_LEFT].any()
    # Bursts are short: no joint jumps in more than 8 consecutive frames.
    run = np.zeros(jumps.shape[::2], dtype=int)
    longest = 0
    for m in range(jumps.shape[1]):
        run = np.where(jumps[:, m], run + 1, 0)
        longest = max(longest, run.max())
    assert 1 <= longest <= spec.burst_frames[1] + 1


def test_random_inferred_episodes_start_independently_at_the_specified_rate():
    """Each free joint starts an episode with probability p per frame, independently of the other
    joints (frames with several starts in one body as often as binomial), with geometric lengths
    P(L > k) = exp(-k / random_inferred_frames)."""
    p, mean = 0.01, 4.0
    spec = KinectSpec(**{**QUIET, "random_inferred_prob": p, "random_inferred_frames": mean})
    b, m = 4, 600
    joints, q = user_at(2.5, b=b)
    frames = make(spec, range(30, 30 + b)).capture(*static(joints, q, m))
    state = target(frames, "joint_state")
    inferred = state == INFERRED  # nothing else hides a joint of a user standing in the open
    assert np.all(state[~inferred] == TRACKED)
    prev = np.concatenate([np.zeros_like(inferred[:, :1]), inferred[:, :-1]], axis=1)
    starts = inferred & ~prev  # (back-to-back episodes merge: a fraction p of them)
    assert starts.sum() / (~prev).sum() == pytest.approx(p, rel=0.15)
    assert inferred.sum() / starts.sum() == pytest.approx(1 / (1 - np.exp(-1 / mean)), rel=0.15)
    k_free = (~prev).sum(axis=-1)  # (B, M) joints free to start
    p_multi = 1 - (1 - p) ** k_free - k_free * p * (1 - p) ** (k_free - 1)
    multi = np.sum(starts.sum(axis=-1) >= 2)
    assert 0.6 * p_multi.sum() < multi < 1.5 * p_multi.sum()


# ---------------------------------------------------------------------------------------- bodies


def test_bodies_have_stable_unique_ids_and_the_target_is_nearest():
    spec = KinectSpec(n_bystanders=5, bystander_dwell_s=2.0)
    b, m = 6, 900
    joints, q = user_at(2.5, b=b)
    frames = make(spec, range(20, 20 + b)).capture(*static(joints, q, m))
    ids, trk = frames.body_id, frames.body_tracked
    np.testing.assert_array_equal(ids != 0, trk)
    # Unique within a frame.
    srt = np.sort(np.where(trk, ids, -np.arange(1, MAX_BODIES + 1)), axis=-1)
    assert np.all(np.diff(srt, axis=-1) != 0)
    # Stable while tracked; a new id after the body was lost.
    both = trk[:, 1:] & trk[:, :-1]
    assert np.all(ids[:, 1:][both] == ids[:, :-1][both])
    reacquired = 0
    for u in range(b):
        for k in range(MAX_BODIES):
            on = np.concatenate([[0], trk[u, :, k].astype(int)])
            runs = int(np.sum(np.diff(on) == 1))  # tracked runs in this slot
            reacquired += max(runs - 1, 0)
            # Each tracked run has its own id (constant within the run, checked above).
            assert len(set(ids[u, :, k][trk[u, :, k]].tolist())) == runs
    assert reacquired >= 5, "bystanders should walk in and out of view during the test"
    # The target is tracked throughout, keeps one id, and is the nearest tracked body.
    assert target(frames, "body_tracked").all()
    assert np.all(target(frames, "body_id") == target(frames, "body_id")[:, :1])
    z = frames.joints[..., 2]
    seen = np.isfinite(z)
    depth = np.where(seen, z, 0.0).sum(axis=-1) / np.maximum(seen.sum(axis=-1), 1)
    nearest = np.argmin(np.where(trk, depth, np.inf), axis=-1)
    np.testing.assert_array_equal(nearest, frames.truth.slot)
    assert np.unique(frames.truth.slot[:, 0]).size >= 3, "the target slot must be random"
    assert trk.sum(axis=-1).max() >= 3, "several bodies must be tracked at once"


def test_a_lost_target_comes_back_with_a_new_id_after_acquisition():
    spec = KinectSpec(**QUIET)
    joints, q = user_at(2.5)
    t, jw, qw = static(joints, q, 120)
    jw = jw.copy()
    jw[:, 40:70, :, 1] -= 4.0  # steps 4 m aside: out of view for 30 frames
    frames = make(spec, [9]).capture(t, jw, qw)
    trk = target(frames, "body_tracked")[0]
    ids = target(frames, "body_id")[0]
    assert trk[:40].all() and not trk[40 : 70 + spec.acquire_frames - 1].any()
    assert trk[70 + spec.acquire_frames - 1 :].all()
    assert ids[0] != 0 and ids[-1] != 0 and ids[0] != ids[-1]


# ------------------------------------------------------------------------------------- facing

LEFT_LIMBS = [
    Joint.ELBOW_LEFT,
    Joint.WRIST_LEFT,
    Joint.HAND_LEFT,
    Joint.HAND_TIP_LEFT,
    Joint.THUMB_LEFT,
    Joint.KNEE_LEFT,
    Joint.ANKLE_LEFT,
    Joint.FOOT_LEFT,
]
RIGHT_LIMBS = [
    Joint.ELBOW_RIGHT,
    Joint.WRIST_RIGHT,
    Joint.HAND_RIGHT,
    Joint.HAND_TIP_RIGHT,
    Joint.THUMB_RIGHT,
    Joint.KNEE_RIGHT,
    Joint.ANKLE_RIGHT,
    Joint.FOOT_RIGHT,
]
NO_FACING = {"facing_inferred_deg": 179.0, "facing_lost_deg": 180.0}  # the rule off


def wrap_deg(a):
    return (np.asarray(a) + 180.0) % 360.0 - 180.0


@pytest.mark.parametrize("tilt_deg", [0.0, 20.0])
def test_facing_is_the_torso_angle_to_the_line_of_sight(tilt_deg):
    """Closed form: a standing body at floor point P turned to yaw psi, with the sensor at C, faces
    |wrap(psi - atan2(C - P))| away from the sensor (horizontal angles, whatever the tilt), and
    its left side is the nearer when the sensor lies to its left."""
    spec = KinectSpec(camera_tilt_deg=tilt_deg, camera_position_m=(2.5, 0.3, 1.1))
    rng = np.random.default_rng(3)
    n = 200
    pos = np.zeros((n, 3))
    pos[:, :2] = rng.uniform(-1.0, 1.0, (n, 2))
    yaw = rng.uniform(-np.pi, np.pi, n)
    joints, _ = standing_skeleton(pos, yaw, height_m=rng.uniform(1.5, 1.9, n), right_arm="raised")
    cam = world_to_camera(spec, joints)
    geo = KinectV2(spec, BatchRng.from_seeds([0])).geometry[0]
    facing, near = np.empty(n), np.empty(n)
    _kinect_scene._facing(n, geo, cam, (facing, near))
    cx, cy, _ = spec.camera_position_m
    to_sensor = np.arctan2(cy - pos[:, 1], cx - pos[:, 0])
    rel = wrap_deg(np.degrees(to_sensor - yaw))  # the sensor's bearing from the body's front
    np.testing.assert_allclose(facing, np.abs(rel), atol=1e-9)
    side = np.abs(rel) > 1e-6
    np.testing.assert_array_equal(near[side], np.where(rel[side] > 0, 1.0, -1.0))
    assert facing.min() < 5 and facing.max() > 175


@pytest.mark.parametrize("yaw_deg", [-75.0, 75.0])
def test_turned_past_facing_inferred_the_far_side_limbs_are_inferred(yaw_deg):
    """Facing the sensor every joint is tracked; turned past ``facing_inferred_deg`` the far-side
    arm and leg (the right hand too when the right side is away) are inferred, the near side and
    the torso tracked; below the angle the rule leaves the states as they are without it."""
    spec = KinectSpec(**QUIET)
    assert spec.facing_inferred_deg < abs(yaw_deg) < spec.facing_lost_deg
    pos = np.zeros((3, 3))
    yaws = np.radians([0.0, yaw_deg, np.sign(yaw_deg) * (spec.facing_inferred_deg - 10.0)])
    joints, q = standing_skeleton(pos, yaws, right_arm="forward")
    t, jw, qw = static(joints, q, 30)
    state = target(make(spec, [1, 2, 3]).capture(t, jw, qw), "joint_state")
    off = target(make(spec.with_(**NO_FACING), [1, 2, 3]).capture(t, jw, qw), "joint_state")
    assert np.all(state[0] == TRACKED)  # facing the sensor: hand and all tracked
    # yaw > 0 turns the body to its left: its right side comes toward the sensor.
    far, near = (LEFT_LIMBS, RIGHT_LIMBS) if yaw_deg > 0 else (RIGHT_LIMBS, LEFT_LIMBS)
    assert np.all(state[1][:, far] == INFERRED)
    assert np.all(state[1][:, near] == TRACKED)
    assert np.all(state[1][:, list(TORSO_JOINTS)] == TRACKED)
    assert np.any(off[1][:, far] == TRACKED), "the far limbs are inferred by the facing rule"
    np.testing.assert_array_equal(state[2], off[2])  # below the angle: no change
    assert target(make(spec, [1, 2, 3]).capture(t, jw, qw), "body_tracked").all()


def test_turned_past_facing_lost_the_body_is_lost_and_comes_back_with_a_new_id():
    spec = KinectSpec(**QUIET)
    start, back = 40, 70
    yaw = np.zeros(120)
    yaw[start:back] = np.radians(spec.facing_lost_deg + 15.0)  # turned away for 30 frames
    joints, q = standing_skeleton(np.zeros((120, 3)), yaw, right_arm="forward")
    t = np.arange(120) / FPS
    frames = make(spec, [9]).capture(t, joints[None], q[None])
    trk = target(frames, "body_tracked")[0]
    ids = target(frames, "body_id")[0]
    acq = spec.acquire_frames
    assert trk[:start].all() and not trk[start : back + acq - 1].any()
    assert trk[back + acq - 1 :].all()
    assert ids[0] != 0 and ids[-1] != 0 and ids[0] != ids[-1]
    assert np.all(target(frames, "joint_state")[0, start : back + acq - 1] == NOT_TRACKED)
    # Just short of the angle the body stays tracked with one id.
    yaw[start:back] = np.radians(spec.facing_lost_deg - 5.0)
    joints, q = standing_skeleton(np.zeros((120, 3)), yaw, right_arm="forward")
    frames = make(spec, [9]).capture(t, joints[None], q[None])
    assert target(frames, "body_tracked").all()
    assert np.unique(target(frames, "body_id")).size == 1


def test_bystanders_follow_the_facing_rule():
    """A bystander walking across the room turns side-on or away: the same rule infers its far
    limbs and loses it, so with the rule there are fewer tracked bystander frames and more
    inferred limb joints than without."""
    spec = KinectSpec(
        n_bystanders=5, bystander_dwell_s=0.5, burst_prob=0.0, random_inferred_prob=0.0
    )
    joints, q = user_at(2.5, b=4)
    args = static(joints, q, 300)
    on = make(spec, range(4)).capture(*args)
    off = make(spec.with_(**NO_FACING), range(4)).capture(*args)
    others = np.ones(on.body_tracked.shape, dtype=bool)
    np.put_along_axis(others, on.truth.slot[..., None], False, axis=-1)
    assert on.body_tracked[others].sum() < off.body_tracked[others].sum()
    limbs = LEFT_LIMBS + RIGHT_LIMBS
    both = on.body_tracked & off.body_tracked & others
    inferred_on = (on.joint_state[both][:, limbs] == INFERRED).sum()
    assert inferred_on > (off.joint_state[both][:, limbs] == INFERRED).sum()


def test_a_user_turning_away_in_the_env_loses_the_hand():
    """Env level: a walking-in-place user who turns on the spot (a full turn in 3 s) faces away
    from the Kinect for part of the turn, so the hand is missing from some steps
    (``hand_tracking_availability`` below 1); standing facing it, the hand is always there. No
    bystanders: with them the hand pipeline, its target lost, selects the nearest bystander and
    reports that body's hand (its documented target rule), which is not missing but wrong."""
    import gymnasium as gym

    from agents.benchmark.metrics import EpisodeRecorder, summarize
    from vrloco_env.config import SensorConfig

    alone = SensorConfig(kinect=KinectSpec(n_bystanders=0))
    availability = {}
    for turn in (0.0, 1.0):
        env = gym.make("VRLoco-Approach-v0", sensors=alone)
        try:
            _, info = env.reset(seed=0)
            rec = EpisodeRecorder(0, info)
            for _ in range(30):
                _, _, _, _, info = env.step(np.array([-1.0, turn, 0.0, 0.0, 0.0], np.float32))
                rec.add(info)
        finally:
            env.close()
        availability[turn] = summarize([rec.finish()])["hand_tracking_availability"]
    assert availability[0.0] == 1.0
    assert 0.3 < availability[1.0] < 0.9


# ------------------------------------------------------------------------------ reproducibility


def varied_users(b, m):
    """Different users: distance, facing, hand turn, a moving hand."""
    rng = np.random.default_rng(42)
    pos = np.zeros((b, 3))
    pos[:, 0] = rng.uniform(0.0, 0.8, b)
    joints, q = standing_skeleton(
        pos, rng.uniform(-0.3, 0.3, b), right_arm="forward", hand_ypr_rad=rng.uniform(-1, 1, (b, 3))
    )
    t, jw, qw = static(joints, q, m)
    jw = jw + 0.05 * np.sin(np.arange(m) / 10.0)[None, :, None, None]
    return t, jw, qw


def test_same_seeds_same_frames_and_batch_equals_single_runs():
    spec = KinectSpec(n_bystanders=3, latency_frames=1)
    seeds = [3, 14, 15]
    t, jw, qw = varied_users(len(seeds), 60)
    batch = make(spec, seeds).capture(t, jw, qw)
    assert_frames_equal(batch, make(spec, seeds).capture(t, jw, qw))
    for i, s in enumerate(seeds):
        single = make(spec, [s]).capture(t, jw[i : i + 1], qw[i : i + 1])
        for name in ("body_id", "body_tracked", "joints", "joint_state", "hand_quat"):
            np.testing.assert_array_equal(getattr(single, name)[0], getattr(batch, name)[i])
        np.testing.assert_array_equal(single.truth.slot[0], batch.truth.slot[i])
    other = make(spec, [4, 14, 15]).capture(t, jw, qw)
    assert not np.array_equal(other.joints[0], batch.joints[0], equal_nan=True)


def test_the_kernel_case_takes_every_branch():
    """The compiled-vs-source case of the frame kernel (``kernel_cases/kinect.py``) has bursts,
    random inferred episodes, occlusion, walking bystanders, a target lost and acquired again
    with a new id (out of view, and turned away), a target turned side-on, and several tracked
    bodies."""
    frames = KinectFrames.concatenate(capture())
    ids = target(frames, "body_id")[1]
    assert ids[1] != 0 and ids[-1] != 0 and ids[1] != ids[-1], "user 1 must be re-acquired"
    ids = target(frames, "body_id")[0]  # latency 1: frame k delivers frame k - 1's capture
    assert ids[1] != 0 and ids[-1] != 0 and ids[1] != ids[-1], "user 0 must be re-acquired"
    assert not target(frames, "body_tracked")[0, 27:33].any(), "user 0 turned away is lost"
    side_on = target(frames, "joint_state")[0, 5:11]
    assert np.all(side_on[:, [Joint.KNEE_LEFT, Joint.FOOT_LEFT, Joint.ELBOW_LEFT]] == INFERRED)
    assert (frames.joint_state == INFERRED).any()
    assert np.isnan(frames.joints).any() and frames.body_tracked.sum(axis=-1).max() >= 3


def test_capture_in_chunks_equals_one_capture():
    spec = KinectSpec(n_bystanders=3, latency_frames=2, burst_prob=0.05, random_inferred_prob=0.01)
    t, jw, qw = varied_users(2, 90)
    whole = make(spec, [7, 8]).capture(t, jw, qw)
    k = make(spec, [7, 8])
    parts = [k.capture(t[a:b], jw[:, a:b], qw[:, a:b]) for a, b in ((0, 1), (1, 38), (38, 90))]
    assert_frames_equal(KinectFrames.concatenate(parts), whole)


def _user(frames: KinectFrames, i: int, start: int = 0) -> KinectFrames:
    """User i's frames from frame ``start`` on, as a batch of one."""
    sel = (slice(i, i + 1), slice(start, None))
    return KinectFrames(
        t=frames.t[sel],
        body_id=frames.body_id[sel],
        body_tracked=frames.body_tracked[sel],
        joints=frames.joints[sel],
        joint_state=frames.joint_state[sel],
        hand_quat=frames.hand_quat[sel],
        truth=type(frames.truth)(
            slot=frames.truth.slot[sel],
            joints=frames.truth.joints[sel],
            hand_quat=frames.truth.hand_quat[sel],
        ),
    )


def test_resetting_one_user_equals_a_fresh_single_session_and_leaves_the_others_alone():
    spec = KinectSpec(
        n_bystanders=3,
        latency_frames=2,
        burst_prob=0.05,
        random_inferred_prob=0.01,
        bystander_dwell_s=0.5,
    )
    seeds, m1, m2 = (31, 32, 33), 40, 50
    t, jw, qw = varied_users(3, m1 + m2)
    rng = BatchRng.from_seeds(seeds)
    k = KinectV2(spec, rng)
    k.reset()
    k.capture(t[:m1], jw[:, :m1], qw[:, :m1])
    rng.reseed(1, np.random.default_rng(99))
    k.reset(users=[1])
    after = k.capture(t[m1:], jw[:, m1:], qw[:, m1:])

    fresh = KinectV2(spec, BatchRng([np.random.default_rng(99)]))
    fresh.reset()
    one = fresh.capture(t[m1:], jw[1:2, m1:], qw[1:2, m1:])
    assert_frames_equal(_user(after, 1), one)
    assert not after.body_tracked[1, :2].any(), "the reset user's delay line starts empty"
    for i in (0, 2):
        single = make(spec, [seeds[i]]).capture(t, jw[i : i + 1], qw[i : i + 1])
        assert_frames_equal(_user(after, i), _user(single, 0, m1))
    # The reset really restarted user 1: an uninterrupted run of it delivers something else.
    uninterrupted = make(spec, [seeds[1]]).capture(t, jw[1:2], qw[1:2])
    assert not np.array_equal(_user(uninterrupted, 0, m1).body_id, one.body_id), (
        "user 1 must have new body ids after its reset"
    )


def test_bystander_sway_clock_is_per_user():
    """Sway phase follows each user's own frame count since its reset, not a batch-wide one."""
    noiseless = dict(
        QUIET,
        n_bystanders=2,
        bystander_dwell_s=1e9,  # bystanders never walk: only the sway moves them
        joint_noise_a_mm=0.0,
        joint_noise_b_mm_per_m2=0.0,
        hand_rot_white_std_deg=(0.0, 0.0, 0.0),
        hand_rot_ar_std_deg=(0.0, 0.0, 0.0),
    )
    spec = KinectSpec(**noiseless)
    t, jw, qw = varied_users(2, 60)
    k = make(spec, [5, 6])
    k.capture(t[:30], jw[:, :30], qw[:, :30])
    k.rng.reseed(0, np.random.default_rng(5))  # the same session again for user 0
    k.reset(users=np.array([True, False]))
    again = k.capture(t[30:], jw[:, 30:], qw[:, 30:])
    first = make(spec, [5]).capture(t[:30], jw[:1, 30:], qw[:1, 30:])
    np.testing.assert_array_equal(again.joints[0], first.joints[0])
    # Without the restart the same bystanders stand elsewhere in their sway: the clock matters.
    cont = make(spec, [5]).capture(t, jw[:1, :], qw[:1, :])
    by = np.arange(MAX_BODIES) != again.truth.slot[0, 0]
    seen = np.isfinite(cont.joints[0, 30:][:, by]) & np.isfinite(again.joints[0][:, by])
    assert seen.sum() > 100
    diff = np.abs(cont.joints[0, 30:][:, by][seen] - again.joints[0][:, by][seen])
    assert diff.max() > 1e-3  # metres of sway (5-20 mm amplitude)


def test_ids_stay_unique_within_a_frame_even_if_draws_collide(monkeypatch):
    """Force every drawn id to 7: the model must still give each body of a user its own id."""
    monkeypatch.setattr(KinectV2, "_new_ids", lambda self, u: np.full(u.shape, 7, np.int64))
    spec = KinectSpec(n_bystanders=5, bystander_dwell_s=2.0)
    joints, q = user_at(2.5, b=2)
    k = make(spec, [20, 21])
    frames = k.capture(*static(joints, q, 300))
    k.reset(users=[1])
    frames = KinectFrames.concatenate([frames, k.capture(*static(joints, q, 300))])
    ids, trk = frames.body_id, frames.body_tracked
    srt = np.sort(np.where(trk, ids, -np.arange(1, MAX_BODIES + 1)), axis=-1)
    assert np.all(np.diff(srt, axis=-1) != 0)
    assert trk.sum(axis=-1).max() >= 3 and (ids == 7).any()


def test_reset_users_are_validated_and_every_user_needs_a_first_reset():
    joints, q = user_at(2.5, b=2)
    k = KinectV2(KinectSpec(), BatchRng.from_seeds([0, 1]))
    k.reset(users=[0])
    with pytest.raises(RuntimeError, match=r"users \[1\]"):
        k.capture(*static(joints, q, 3))
    k.reset(users=[1])
    k.capture(*static(joints, q, 3))
    for bad, match in (([2], r"\[0, 1\]"), ([0, 0], "repeat"), (np.ones(3, bool), "shape")):
        with pytest.raises(ValueError, match=match):
            k.reset(users=bad)


def test_latency_delays_the_frames_not_the_truth():
    lag = 3
    t, jw, qw = varied_users(2, 40)
    spec0 = KinectSpec(n_bystanders=2)
    now = make(spec0, [1, 2]).capture(t, jw, qw)
    late = make(spec0.with_(latency_frames=lag), [1, 2]).capture(t, jw, qw)
    for name in ("body_id", "body_tracked", "joints", "joint_state", "hand_quat"):
        np.testing.assert_array_equal(getattr(late, name)[:, lag:], getattr(now, name)[:, :-lag])
    assert not late.body_tracked[:, :lag].any() and np.isnan(late.joints[:, :lag]).all()
    np.testing.assert_array_equal(late.t, now.t)
    np.testing.assert_array_equal(late.truth.joints, now.truth.joints)


# ------------------------------------------------------------------------------------ bad input


def test_bad_spec_raises_clear_errors():
    with pytest.raises(ValueError, match="fov_deg"):
        KinectSpec(fov_deg=(0.0, 60.0))
    with pytest.raises(ValueError, match="fov_deg"):
        KinectSpec(fov_deg=(70.6, -1.0))
    with pytest.raises(ValueError, match="depth_range_m"):
        KinectSpec(depth_range_m=(4.5, 0.5))
    with pytest.raises(ValueError, match="n_bystanders"):
        KinectSpec(n_bystanders=6)
    with pytest.raises(ValueError, match="latency_frames"):
        KinectSpec(latency_frames=-1)
    with pytest.raises(ValueError, match="joint_noise_scale"):
        KinectSpec(joint_noise_scale=(1.0,) * 24)
    with pytest.raises(ValueError, match="frame_rate_hz"):
        KinectSpec(frame_rate_hz=0.0)
    with pytest.raises(ValueError, match="hand_rot_white_std_deg"):
        KinectSpec(hand_rot_white_std_deg=(1.0, float("nan"), 1.0))
    for bad in (-1.0, 181.0, float("nan"), "60"):
        with pytest.raises(ValueError, match=r"KinectSpec\.facing_inferred_deg=.*\[0, 180\] deg"):
            KinectSpec(facing_inferred_deg=bad)
    with pytest.raises(ValueError, match=r"KinectSpec\.facing_lost_deg=.*\(facing_inferred_deg"):
        KinectSpec(facing_inferred_deg=90.0, facing_lost_deg=90.0)  # lost must exceed inferred
    with pytest.raises(ValueError, match=r"KinectSpec\.facing_lost_deg=.*180\] deg"):
        KinectSpec(facing_lost_deg=190.0)
    spec = KinectSpec(facing_inferred_deg=0.0, facing_lost_deg=180.0)  # the extremes are allowed
    assert (spec.facing_inferred_deg, spec.facing_lost_deg) == (0.0, 180.0)


def test_spec_bounds_are_exact_and_the_messages_name_field_and_range():
    """Open bounds stay open, counts may be whole floats, and a bool is not a count."""
    for tilt in (-45.0, 45.0):
        with pytest.raises(ValueError, match=r"KinectSpec\.camera_tilt_deg=.*\(-45, 45\) deg"):
            KinectSpec(camera_tilt_deg=tilt)
    assert KinectSpec(camera_tilt_deg=44.9).camera_tilt_deg == 44.9
    with pytest.raises(ValueError, match=r"KinectSpec\.depth_range_m=.*low < high"):
        KinectSpec(depth_range_m=(2.0, 2.0))  # near must be below far
    assert KinectSpec(burst_frames=(2.0, 8.0)).burst_frames == (2.0, 8.0)
    with pytest.raises(ValueError, match=r"KinectSpec\.burst_frames=.*whole numbers"):
        KinectSpec(burst_frames=(2.5, 8))
    with pytest.raises(ValueError, match=r"KinectSpec\.n_bystanders=True: .*integer"):
        KinectSpec(n_bystanders=True)
    with pytest.raises(ValueError, match=r"KinectSpec\.min_visible_fraction=0\.0: .*\(0, 1\]"):
        KinectSpec(min_visible_fraction=0.0)
    spec = KinectSpec(bystander_speed_mps=np.array([0.9, 1.2]))  # a 1-D array is a pair too
    assert tuple(spec.bystander_speed_mps) == (0.9, 1.2)


def test_bad_capture_input_raises_clear_errors():
    kinect = KinectV2(KinectSpec(), BatchRng.from_seeds([0, 1]))
    joints, q = user_at(2.5, b=2)
    t, jw, qw = static(joints, q, 5)
    with pytest.raises(RuntimeError, match="reset"):
        kinect.capture(t, jw, qw)
    kinect.reset()
    with pytest.raises(ValueError, match="joints_world"):
        kinect.capture(t, jw[:, :, :20], qw)
    with pytest.raises(ValueError, match="joints_world"):
        kinect.capture(t, jw[:1], qw[:1])  # batch of 1 for a sensor of 2 users
    with pytest.raises(ValueError, match="hand_quat_world"):
        kinect.capture(t, jw, qw[:, :4])
    bad_q = qw.copy()
    bad_q[1, 2] = np.nan
    with pytest.raises(ValueError, match="hand_quat_world"):
        kinect.capture(t, jw, bad_q)
    bad_q[1, 2] = 0.0
    with pytest.raises(ValueError, match="hand_quat_world"):
        kinect.capture(t, jw, bad_q)
    bad_j = jw.copy()
    bad_j[0, 1, 3, 2] = np.inf
    with pytest.raises(ValueError, match="joints_world"):
        kinect.capture(t, bad_j, qw)
    with pytest.raises(ValueError, match="t must"):
        kinect.capture(t[:3], jw, qw)
    with pytest.raises(ValueError, match="height_m"):
        standing_skeleton(np.zeros(3), 0.0, height_m=3.0)

"""Head camera model: projection and frames, visibility, the helmet-tracking paper's rates, blur,
determinism."""

import math

import cv2
import numpy as np
import pytest

from estimators.rotations import (
    quat_conjugate,
    quat_from_rotvec,
    quat_from_ypr,
    quat_multiply,
    quat_to_matrix,
    rotation_angle,
)
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.camera import (
    LIGHTING,
    CameraFrames,
    CameraSpec,
    HeadCamera,
    camera_pose,
    camera_spec,
    extraction_rate,
    head_pose_from_camera,
    layout_landmarks,
    matching_rate,
    pad_landmarks,
    project,
)
from vrloco_env.tasks import make_layout
from vrloco_env.world import RoomConfig

RATE = 120.0


@pytest.fixture(scope="module")
def room():
    """The default 8 m x 8 m Approach room: (K, 3) landmarks and their inward wall normals."""
    layout = make_layout("approach", RoomConfig(), np.random.default_rng(3))
    return layout_landmarks(layout)


def make(spec, seeds=(0,)):
    return HeadCamera(spec, BatchRng.from_seeds(list(seeds)))


def still(b, n, pos=(0.0, 0.0, 1.6), ypr=(0.0, 0.0, 0.0)):
    """B users holding one pose for N frames: t (N,), pos, quat, omega."""
    p = np.broadcast_to(np.asarray(pos, float), (b, n, 3)).copy()
    q = np.broadcast_to(quat_from_ypr(np.asarray(ypr, float)), (b, n, 4)).copy()
    return np.arange(n) / RATE, p, q, np.zeros((b, n, 3))


def turning(b, n, rng, yaw_rate=0.3, spread=2.0):
    """B users at random places in the room, turning about z at ``yaw_rate`` rad/s, with a
    small nod: t, pos, quat, omega (omega in the body frame; pitch rate neglected, tiny)."""
    t = np.arange(n) / RATE
    yaw = rng.uniform(-np.pi, np.pi, (b, 1)) + yaw_rate * t
    pitch = 0.1 * np.sin(2.0 * np.pi * 0.2 * t) * np.ones((b, 1))
    q = quat_from_ypr(np.stack([yaw, pitch, np.zeros((b, n))], axis=-1))
    pos = np.zeros((b, n, 3))
    pos[..., :2] = rng.uniform(-spread, spread, (b, 1, 2))
    pos[..., 2] = 1.6
    omega = np.zeros((b, n, 3))
    omega[..., 2] = yaw_rate
    return t, pos, q, omega


# --------------------------------------------------------------------------------------- geometry


def test_straight_ahead_left_and_above():
    spec = CameraSpec().noiseless()
    cam = make(spec)
    t, pos, q, om = still(1, 1, pos=(1.0, 2.0, 1.6), ypr=(0.7, 0.0, 0.0))
    fwd = np.array([math.cos(0.7), math.sin(0.7), 0.0])
    left = np.array([-math.sin(0.7), math.cos(0.7), 0.0])
    base = np.array([1.0, 2.0, 1.6])
    lm = np.stack(
        [
            base + 3.0 * fwd,  # straight ahead
            base + 3.0 * fwd + 0.5 * left,  # to the left
            base + 3.0 * fwd + np.array([0, 0, 0.5]),  # above
        ]
    )
    f = cam.capture(t, pos, q, om, lm)
    px = f.pixels[0, 0]
    assert f.visible.all() and f.extracted.all()
    np.testing.assert_allclose(px[0], [spec.cx, spec.cy], atol=1e-9)
    assert px[1, 0] < spec.cx - 50 and abs(px[1, 1] - spec.cy) < 1e-9
    assert px[2, 1] < spec.cy - 50 and abs(px[2, 0] - spec.cx) < 1e-9
    np.testing.assert_allclose(px[1, 0], spec.cx - spec.fx * 0.5 / 3.0, atol=1e-9)
    assert (f.matched_id[0, 0] == [0, 1, 2]).all()


def test_mount_tilt_and_offset():
    spec = CameraSpec(mount_tilt_deg=20.0, mount_offset_m=(0.1, 0.0, 0.05)).noiseless()
    cam = make(spec)
    t, pos, q, om = still(1, 1, pos=(0.0, 0.0, 1.6))
    # A point on the tilted optical axis, from the camera centre (0.1, 0, 1.65).
    th = math.radians(20.0)
    lm = np.array([[0.1 + 3.0 * math.cos(th), 0.0, 1.65 - 3.0 * math.sin(th)]])
    f = cam.capture(t, pos, q, om, lm)
    np.testing.assert_allclose(f.pixels[0, 0, 0], [spec.cx, spec.cy], atol=1e-9)
    cp, cq = camera_pose(spec, pos[0, 0], q[0, 0])
    np.testing.assert_allclose(cp, [0.1, 0.0, 1.65], atol=1e-12)
    hp, hq = head_pose_from_camera(spec, cp, cq)
    np.testing.assert_allclose(hp, pos[0, 0], atol=1e-12)
    assert rotation_angle(quat_multiply(quat_conjugate(hq), q[0, 0])) < 1e-12
    np.testing.assert_allclose(quat_to_matrix(cq)[:, 2], (lm[0] - cp) / 3.0, atol=1e-12)


def _cv2_project(spec, pos, quat, pts):
    cp, cq = camera_pose(spec, pos, quat)
    r_cw = quat_to_matrix(cq).T
    rvec, _ = cv2.Rodrigues(r_cw)
    tvec = -r_cw @ cp
    uv, _ = cv2.projectPoints(pts, rvec, tvec, spec.camera_matrix, np.zeros(5))
    return uv[:, 0, :]


def test_projection_matches_opencv(rng, room):
    spec = camera_spec("ideal", mount_tilt_deg=10.0, mount_offset_m=(0.08, 0.01, 0.06))
    spec = spec.noiseless()
    pts, normals = room
    b, n = 3, 5
    pos = np.zeros((b, n, 3))
    pos[..., :2] = rng.uniform(-3, 3, (b, n, 2))
    pos[..., 2] = rng.uniform(1.4, 1.9, (b, n))
    q = quat_from_rotvec(rng.normal(0, 0.6, (b, n, 3)))
    cam = make(spec, range(b))
    f = cam.capture(np.arange(n) / RATE, pos, q, rng.normal(0, 1, (b, n, 3)), pts, normals=normals)
    uv_all, _ = project(spec, pos, q, pts)
    checked = 0
    for i in range(b):
        for j in range(n):
            ref = _cv2_project(spec, pos[i, j], q[i, j], pts)
            vis = f.visible[i, j]
            np.testing.assert_allclose(f.pixels[i, j][vis], ref[vis], rtol=0, atol=1e-9)
            np.testing.assert_allclose(f.pixels_true[i, j][vis], ref[vis], rtol=0, atol=1e-9)
            np.testing.assert_allclose(uv_all[i, j][vis], ref[vis], rtol=0, atol=1e-9)
            checked += vis.sum()
    assert checked > 50


def test_pnp_on_noiseless_frames_recovers_head_pose(room):
    """End to end: OpenCV's solvePnP on the camera's output gives back the true head pose."""
    spec = CameraSpec(mount_tilt_deg=15.0, mount_offset_m=(0.09, 0.0, 0.07)).noiseless()
    pts, normals = room
    t, pos, q, om = still(1, 1, pos=(0.5, -1.0, 1.7), ypr=(2.0, 0.1, -0.05))
    f = make(spec).capture(t, pos, q, om, pts, normals=normals)
    ok = f.extracted[0, 0]
    assert ok.sum() >= 6
    obj = pts[f.matched_id[0, 0][ok]]
    img = f.pixels[0, 0][ok]
    good, rvec, tvec = cv2.solvePnP(obj, img, spec.camera_matrix, np.zeros(5))
    assert good
    r_cw, _ = cv2.Rodrigues(rvec)
    cam_pos = -r_cw.T @ tvec[:, 0]
    from estimators.rotations import matrix_to_quat

    hp, hq = head_pose_from_camera(spec, cam_pos, matrix_to_quat(r_cw.T))
    np.testing.assert_allclose(hp, pos[0, 0], atol=1e-6)
    assert rotation_angle(quat_multiply(quat_conjugate(hq), q[0, 0])) < 1e-6


def test_visibility_front_image_range_walls_blocked():
    spec = CameraSpec(max_range_m=6.0).noiseless()
    cam = make(spec)
    t, pos, q, om = still(1, 1)
    c = np.array([0.0, 0.0, 1.6])
    off = np.array
    lm = np.array(
        [
            c + off([3.0, 0.0, 0.0]),  # ahead: visible
            c + off([-3.0, 0.0, 0.0]),  # behind the camera
            c + off([3.0, 3.0, 0.0]),  # 45 deg left, outside the 35 deg half field of view
            c + off([3.0, 0.0, -2.0]),  # 34 deg below, outside the 27.5 deg half vertical field
            c + off([7.0, 0.0, 0.0]),  # beyond max_range_m
            c + off([3.0, 0.5, 0.2]),  # visible
            c + off([0.05, 0.0, 0.0]),  # closer than min_range_m
        ]
    )
    f = cam.capture(t, pos, q, om, lm)
    assert f.visible[0, 0].tolist() == [True, False, False, False, False, True, False]
    assert np.isnan(f.pixels[0, 0][~f.visible[0, 0]]).all()
    assert (f.matched_id[0, 0][~f.visible[0, 0]] == -1).all()
    assert f.n_visible[0, 0] == 2 and f.n_extracted[0, 0] == 2 and f.n_correct[0, 0] == 2
    # A wall normal facing away from the camera (seen from behind the wall): not visible; a
    # grazing view (85 deg > 80 deg) neither; a frontal one is.
    normals = np.zeros((7, 3))
    normals[:, 0] = -1.0  # walls facing the head
    normals[5] = [1.0, 0.0, 0.0]  # facing away
    f = cam.capture(t, pos, q, om, lm, normals=normals)
    assert f.visible[0, 0].tolist() == [True] + [False] * 6
    a = math.radians(85.0)
    normals[0] = [-math.cos(a), math.sin(a), 0.0]
    assert not cam.capture(t, pos, q, om, lm, normals=normals).visible[0, 0, 0]
    # Caller-blocked lines of sight and masked (padding) rows.
    blocked = np.zeros((1, 1, 7), bool)
    blocked[0, 0, 0] = True
    f = cam.capture(t, pos, q, om, lm, blocked=blocked)
    assert f.visible[0, 0].tolist() == [False] * 5 + [True, False]
    mask = np.ones(7, bool)
    mask[5] = False
    lm_nan = lm.copy()
    lm_nan[5] = np.nan  # padding may hold anything
    f = cam.capture(t, pos, q, om, lm_nan, mask=mask)
    assert f.visible[0, 0].tolist() == [True] + [False] * 6


# ------------------------------------------------------------------------------------ rates


@pytest.mark.parametrize(
    ("condition", "extraction", "matching"),
    [("ideal", 0.95, 0.90), ("low_light", 0.70, 0.85), ("occlusion", None, 0.60)],
)
def test_seed004_rates(condition, extraction, matching, rng, room):
    pts, normals = room
    b, n = 4, 400
    t, pos, q, om = turning(b, n, rng)
    f = make(condition, range(b)).capture(t, pos, q, om, pts, normals=normals)
    assert f.visible.sum() > 20000  # a few thousand observations and more
    if extraction is not None:
        assert abs(extraction_rate(f) - extraction) < 0.015
    assert abs(matching_rate(f) - matching) < 0.015
    if condition == "occlusion":
        free = f.visible & ~f.occluded
        assert abs(f.extracted.sum() / free.sum() - 0.95) < 0.015
        covered = f.occluded.sum() / f.visible.sum()
        assert 0.22 < covered < 0.40  # the band covers 30 % of the image width
        assert abs(extraction_rate(f) - 0.95 * (1 - covered)) < 0.02
        assert not (f.extracted & f.occluded).any()
    else:
        assert not f.occluded.any() and np.isnan(f.occluder).all()


def test_pixel_noise_level(rng, room):
    pts, normals = room
    for cond, sigma in (("ideal", 0.5), ("low_light", 1.5)):
        t, pos, q, om = still(3, 300, ypr=(0.4, 0.0, 0.0))
        f = make(cond, range(3)).capture(t, pos, q, om, pts, normals=normals)
        err = (f.pixels - f.pixels_true)[f.extracted]
        assert err.shape[0] > 2000
        assert abs(err.std() / sigma - 1.0) < 0.05
        assert abs(err.mean()) < 0.05 * sigma


def test_wrong_matches_point_to_nearby_landmarks(rng, room):
    pts, normals = room
    t, pos, q, om = turning(3, 300, rng)
    spec = camera_spec("occlusion", pixel_noise_px=0.0, blur_noise_per_px=0.0)
    f = make(spec, range(3)).capture(t, pos, q, om, pts, normals=normals)
    k = np.broadcast_to(np.arange(pts.shape[0]), f.matched_id.shape)
    wrong = f.extracted & (f.matched_id != k)
    assert wrong.sum() > 1000
    gap = np.linalg.norm(pts[f.matched_id[wrong]] - pts[k[wrong]], axis=-1)
    assert gap.max() < 1.2  # one of the 4 nearest: 0.5 m above/below, ~1 m beside
    assert gap.min() > 0.1
    # The pixel stays where the true landmark projects (noise off here).
    np.testing.assert_array_equal(f.pixels[wrong], f.pixels_true[wrong])
    # Several neighbours are used, not always the same one.
    assert np.unique(np.round(gap, 3)).size >= 2


def test_motion_blur_lowers_extraction_and_adds_noise(rng, room):
    pts, normals = room
    spec = camera_spec("motion_blur")
    rates, errs = {}, {}
    for w in (0.0, 3.0):
        t, pos, q, _ = still(3, 300, ypr=(1.0, 0.0, 0.0))
        om = np.zeros_like(pos)
        om[..., 2] = w  # the pose is held; only the blur depends on omega
        f = make(spec, range(3)).capture(t, pos, q, om, pts, normals=normals)
        rates[w] = extraction_rate(f)
        errs[w] = np.std((f.pixels - f.pixels_true)[f.extracted])
        if w > 0:
            # Blur length near the image centre: |omega_perp| * exposure * f.
            centre = np.abs(f.pixels_true[..., 0] - spec.cx) < 20
            centre &= np.abs(f.pixels_true[..., 1] - spec.cy) < 20
            expect = w * spec.exposure_s * spec.fx
            if centre.any():
                np.testing.assert_allclose(f.blur_px[centre], expect, rtol=0.01)
            assert f.blur_px[f.visible].min() >= expect * 0.99
    assert abs(rates[0.0] - 0.95) < 0.02
    assert rates[3.0] < 0.5 * rates[0.0]
    assert errs[3.0] > 2.0 * errs[0.0]
    # The ideal (short exposure) camera suffers less at the same rate.
    t, pos, q, _ = still(3, 300, ypr=(1.0, 0.0, 0.0))
    om = np.zeros_like(pos)
    om[..., 2] = 3.0
    f = make("ideal", range(3)).capture(t, pos, q, om, pts, normals=normals)
    assert rates[3.0] < extraction_rate(f) < rates[0.0]


def test_occluder_band_stays_in_image_and_drifts(room):
    spec = camera_spec("occlusion")
    cam = make(spec, range(2))
    t, pos, q, om = still(2, 1200)
    band = cam.capture(t, pos, q, om, room[0], normals=room[1]).occluder
    np.testing.assert_allclose(band[..., 1] - band[..., 0], 0.3 * spec.width, rtol=1e-12)
    assert band[..., 0].min() >= -0.5 - 1e-9 and band[..., 1].max() <= spec.width - 0.5 + 1e-9
    moved = np.abs(band[:, -1, 0] - band[:, 0, 0])
    assert (moved > 5.0).all()  # ~60 px/sqrt(s) over 10 s
    assert np.abs(np.diff(band[..., 0], axis=1)).max() < 30.0  # slowly, no jumps


# ------------------------------------------------------------------------------ determinism


def test_batch_equals_single_runs_and_chunks(rng, room):
    pts, normals = room
    spec = camera_spec("occlusion", exposure_s=0.006)
    b, n = 3, 40
    t, pos, q, om = turning(b, n, rng, yaw_rate=1.5)
    # User 2 has a smaller room: its 60 landmarks are padded to K in the batch.
    sets = [pts, pts + np.array([0.1, 0.0, 0.0]), pts[:60]]
    nrms = [normals, normals, normals[:60]]
    lm, nrm, mask = pad_landmarks(sets, nrms)
    cam = make(spec, (11, 12, 13))
    first = cam.capture(t[:15], pos[:, :15], q[:, :15], om[:, :15], lm, mask, nrm)
    second = cam.capture(t[15:], pos[:, 15:], q[:, 15:], om[:, 15:], lm, mask, nrm)
    batch = CameraFrames.concatenate([first, second])
    for i, seed in enumerate((11, 12, 13)):
        single = make(spec, (seed,)).capture(
            t, pos[i : i + 1], q[i : i + 1], om[i : i + 1], sets[i], normals=nrms[i]
        )
        k = sets[i].shape[0]
        for name in CameraFrames._fields:
            a, s = getattr(batch, name)[i : i + 1], getattr(single, name)
            if a.ndim >= 3 and name not in ("occluder",):
                a = a[:, :, :k]
            np.testing.assert_array_equal(a, s, err_msg=name)
        assert batch.extracted[i, :, k:].sum() == 0
    assert batch.n_extracted.sum() > 0 and (batch.matched_id >= 0).any()


def test_reset_some_users(rng, room):
    pts, normals = room
    spec = camera_spec("occlusion")
    t, pos, q, om = turning(2, 30, rng)
    ref = make(spec, (1, 2))
    ref.capture(t, pos, q, om, pts, normals=normals)
    cam = make(spec, (1, 2))
    cam.capture(t, pos, q, om, pts, normals=normals)
    g = np.random.default_rng(99)
    cam.rng.reseed(1, g)
    cam.reset(users=[1])
    after = cam.capture(t, pos, q, om, pts, normals=normals)
    cont = ref.capture(t, pos, q, om, pts, normals=normals)
    fresh = HeadCamera(spec, BatchRng([np.random.default_rng(99)])).capture(
        t, pos[1:], q[1:], om[1:], pts, normals=normals
    )
    for name in CameraFrames._fields:
        np.testing.assert_array_equal(getattr(after, name)[0], getattr(cont, name)[0], name)
        np.testing.assert_array_equal(getattr(after, name)[1], getattr(fresh, name)[0], name)
    assert not np.array_equal(after.occluder[1], cont.occluder[1])
    assert cam.frames_taken.tolist() == [60, 30]


# ----------------------------------------------------------------------------- validation


def test_spec_presets_and_validation():
    assert set(LIGHTING) == {"ideal", "low_light", "occlusion", "motion_blur"}
    s = camera_spec("low_light", rate_hz=60.0)
    assert s.rate_hz == 60.0 and s.extraction_prob == 0.70 and s.name == "low_light"
    h, v = CameraSpec().fov_deg
    assert 68.0 < h < 72.0 and 50.0 < v < 58.0
    with pytest.raises(ValueError, match="condition='foggy': unknown; valid names: ideal, "):
        camera_spec("foggy")
    with pytest.raises(ValueError, match="no field"):
        camera_spec("ideal", focal=400.0)
    bad = {
        "rate_hz": 300.0,
        "fx": 0.0,
        "cx": 700.0,
        "width": 0,
        "exposure_s": 0.02,
        "extraction_prob": 1.2,
        "match_prob": -0.1,
        "occluder_fraction": 1.0,
        "mount_tilt_deg": 95.0,
        "max_range_m": 0.05,
        "pixel_noise_px": float("nan"),
        "match_neighbors": 0,
        "blur_scale_px": 0.0,
        "max_landmarks": 0,
        "mount_offset_m": (0.0, 0.0),
    }
    for field, value in bad.items():
        with pytest.raises(ValueError, match=rf"^CameraSpec\.{field}=.*: must be "):
            CameraSpec(**{field: value})
    with pytest.raises(ValueError, match=r"mount_tilt_deg=-90\.0: must be in \(-90, 90\) deg$"):
        CameraSpec(mount_tilt_deg=-90.0)
    with pytest.raises(ValueError, match=r"occluder_fraction=1\.0: must be in \[0, 1\)$"):
        CameraSpec(occluder_fraction=1.0)
    with pytest.raises(ValueError, match=r"width=640\.0: must be an integer in \[1, 10000\] px$"):
        CameraSpec(width=640.0)
    with pytest.raises(ValueError, match=r"fx=True: must be in \(0, inf\) px$"):
        CameraSpec(fx=True)
    # the blur's effect on detection can be switched off; a float tilt just inside is accepted
    assert CameraSpec(blur_scale_px=math.inf, mount_tilt_deg=89.9).blur_scale_px == math.inf
    with pytest.raises(ValueError, match="spec"):
        HeadCamera(42, BatchRng.from_seeds([0]))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="rng"):
        HeadCamera(CameraSpec(), np.random.default_rng(0))  # type: ignore[arg-type]


def test_capture_rejects_bad_input(room):
    pts, normals = room
    cam = make("ideal", (0, 1))
    t, pos, q, om = still(2, 3)
    cases = {
        "pos": dict(pos=pos[:, :, :2]),
        "quat": dict(quat=np.where(np.arange(4) == 0, np.nan, q)),
        "omega": dict(omega=om[:1]),
        "t": dict(t=np.array([0.0, np.nan, 1.0])),
        "landmarks": dict(landmarks=pts[:, :2]),
        "mask": dict(mask=np.ones(pts.shape[0], dtype=int)),
        "normals": dict(normals=np.zeros_like(normals)),
        "blocked": dict(blocked=np.zeros((2, 3, 5), bool)),
        "max_landmarks": dict(landmarks=np.zeros((200, 3))),
    }
    base = dict(t=t, pos=pos, quat=q, omega=om, landmarks=pts, normals=normals)
    for field, change in cases.items():
        with pytest.raises(ValueError, match=field):
            cam.capture(**{**base, **change})
    # nothing drawn on a failed call: the next draws are a fresh camera's
    np.testing.assert_array_equal(cam.rng.normal((7,)), make("ideal", (0, 1)).rng.normal((7,)))
    nan_pts = pts.copy()
    nan_pts[0] = np.nan
    with pytest.raises(ValueError, match="landmarks"):
        cam.capture(**{**base, "landmarks": nan_pts})
    pos_nan = pos.copy()
    pos_nan[0, 1, 2] = np.nan
    with pytest.raises(ValueError, match="pos"):
        cam.capture(**{**base, "pos": pos_nan})
    with pytest.raises(ValueError, match="users"):
        cam.reset(users=[2])


def test_rates_need_observations():
    cam = make("ideal")
    t, pos, q, om = still(1, 2)
    f = cam.capture(t, pos, q, om, np.array([[-5.0, 0.0, 1.6]]))  # behind the head
    with pytest.raises(ValueError, match="visible"):
        extraction_rate(f)
    with pytest.raises(ValueError, match="extracted"):
        matching_rate(f)


def test_layout_landmarks_normals_point_into_the_room():
    layout = make_layout("avoid", RoomConfig(), np.random.default_rng(5)).with_origin((10.0, -3.0))
    pts, normals = layout_landmarks(layout)
    xmin, xmax, ymin, ymax = layout.bounds
    local = pts - np.array([10.0, -3.0, 0.0])
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    inside = local + 0.1 * normals
    assert ((inside[:, 0] > xmin) & (inside[:, 0] < xmax)).all()
    assert ((inside[:, 1] > ymin) & (inside[:, 1] < ymax)).all()
    assert pts.shape[0] <= CameraSpec().max_landmarks


def test_blur_length_follows_rotational_flow():
    """Pitch and yaw smear the image centre by |omega| * exposure * f (yaw by f + r^2 / f at a
    point r px beside it on the horizon); roll smears a point by its radius from the principal
    point times |omega| * exposure, and leaves the centre sharp."""
    spec = camera_spec("motion_blur").noiseless()
    c = np.array([0.0, 0.0, 1.6])
    lm = np.array([c + np.array([4.0, 0.0, 0.0]), c + np.array([4.0, 1.0, 0.0])])
    r = spec.fx * 1.0 / 4.0  # the second point's distance from the principal point, px
    w = 2.0
    for axis, expect in (
        (1, [w * spec.fx, w * spec.fx]),  # pitch: (1 + y^2) with y = 0
        (2, [w * spec.fx, w * (spec.fx + r * r / spec.fx)]),
        (0, [0.0, w * r]),
    ):
        t, pos, q, om = still(1, 1)
        om[..., axis] = w
        f = make(spec).capture(t, pos, q, om, lm)
        np.testing.assert_allclose(f.blur_px[0, 0], np.array(expect) * spec.exposure_s, rtol=1e-9)

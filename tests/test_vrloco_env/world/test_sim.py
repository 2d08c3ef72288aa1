"""The PyBullet wrapper: rays, contacts, poses and images against analytic ground truth."""

import sys

import numpy as np
import pytest

from vrloco_env.tasks import make_layout
from vrloco_env.tasks.interact import interact_layout
from vrloco_env.world import RoomConfig, build, ray_cast_2d, signed_distance, tile_origins
from vrloco_env.world.sim import Simulation, display_available

TASK_NAMES = ("approach", "avoid", "interact")
CFG = RoomConfig()


@pytest.fixture
def sim():
    s = Simulation()
    yield s
    s.close()


def _rays(origins: np.ndarray, angles: np.ndarray, z: float, length: float):
    o = np.column_stack([origins, np.full(len(origins), z)])
    e = o + length * np.column_stack([np.cos(angles), np.sin(angles), np.zeros(len(angles))])
    return o, e


def test_ray_toward_a_wall_returns_its_distance_and_empty_space_no_hit(sim):
    wall = sim.create_box("wall", [0.1, 2.0, 1.0], [3.1, 0.0, 1.0])  # face at x = 3
    o = np.array([[0.0, 0.0, 1.0], [0.0, 0.5, 0.5], [0.0, 0.0, 1.0], [0.0, 0.0, 2.5]])
    e = np.array([[5.0, 0.0, 1.0], [10.0, 0.5, 0.5], [-5.0, 0.0, 1.0], [5.0, 0.0, 2.5]])
    frac, hit = sim.ray_test(o, e)
    np.testing.assert_allclose(frac[:2] * np.array([5.0, 10.0]), [3.0, 3.0], atol=1e-6)
    np.testing.assert_array_equal(hit, [wall, wall, -1, -1])  # behind, and above the 2 m wall
    np.testing.assert_array_equal(frac[2:], [1.0, 1.0])


def test_rays_ignore_avatars_markers_and_visual_bodies(sim):
    wall = sim.create_box("wall", [0.1, 2.0, 1.0], [3.1, 0.0, 1.0])
    sim.create_capsule("avatar", 0.25, 1.7, [1.0, 0.0, 0.85])
    sim.create_capsule("head_avatar", 0.25, 1.7, [0.0, 0.0, 0.85])  # the ray starts inside it
    sim.create_marker("goal", 0.2, [2.0, 0.0, 1.0])
    sim.create_cylinder("disc", 0.3, 2.0, [2.5, 0.0, 1.0], collide=False)
    frac, hit = sim.ray_test([[0.0, 0.0, 1.0]], [[5.0, 0.0, 1.0]])
    assert hit[0] == wall
    assert frac[0] * 5.0 == pytest.approx(3.0, abs=1e-6)


def test_pybullet_rays_match_the_analytic_2d_cast_on_random_tiled_layouts(sim):
    origins = tile_origins(9)
    err, on_surface, excluded, total = [], [], 0, 0
    for s in range(9):
        lay = make_layout(TASK_NAMES[s % 3], CFG, np.random.default_rng(s))
        lay = lay.with_origin(origins[s])
        build(sim, lay, prefix=f"r{s}/")
        rng = np.random.default_rng(100 + s)
        xmin, xmax, ymin, ymax = lay.bounds
        p = np.column_stack([rng.uniform(xmin, xmax, 600), rng.uniform(ymin, ymax, 600)])
        p = p[signed_distance(lay, p) > 0.05][:150]
        a = rng.uniform(-np.pi, np.pi, p.shape[0])
        d2 = ray_cast_2d(lay, p, a, 20.0, z=0.5)
        o, e = _rays(lay.to_world(p), a, 0.5, 20.0)
        frac, hit = sim.ray_test(o, e)
        assert np.all(hit >= 0)  # closed rooms: every ray hits something of its own room
        assert all(sim.name_of(b).startswith(f"r{s}/") for b in hit)
        d_pb = frac * 20.0
        u = np.column_stack([np.cos(a), np.sin(a)])
        on_surface.append(signed_distance(lay, p + d_pb[:, None] * u))
        # Grazing rays (a 3 mm parallel shift changes the distance by > 1 cm) are ill-posed:
        # there a sub-mm shape difference flips hit/miss. Compare the well-posed rest.
        n = np.column_stack([-np.sin(a), np.cos(a)])
        dp = ray_cast_2d(lay, p + 0.003 * n, a, 20.0, z=0.5)
        dm = ray_cast_2d(lay, p - 0.003 * n, a, 20.0, z=0.5)
        ok = (np.abs(dp - d2) < 0.01) & (np.abs(dm - d2) < 0.01)
        err.append(np.abs(d_pb - d2)[ok])
        excluded += int((~ok).sum())
        total += ok.size
    err = np.concatenate(err)
    assert excluded < 0.1 * total
    # Bullet's GJK ray cast on cylinders is within ~1 mm (boxes: exact to 1e-9).
    assert np.percentile(err, 99) < 1e-3
    assert err.max() < 3e-3
    # Every PyBullet hit point lies on a true surface, to 1.5 mm.
    assert np.abs(np.concatenate(on_surface)).max() < 1.5e-3


def test_ray_batches_beyond_pybullets_limit_are_chunked(sim):
    sim.create_box("wall", [0.1, 50.0, 1.0], [10.1, 0.0, 1.0])
    n = 20_000  # > 16,384, PyBullet's batch limit
    y = np.linspace(-40.0, 40.0, n)
    o = np.column_stack([np.zeros(n), y, np.ones(n)])
    e = o + np.array([20.0, 0.0, 0.0])
    frac, hit = sim.ray_test(o, e)
    np.testing.assert_allclose(frac * 20.0, 10.0, atol=1e-5)
    assert np.all(hit == sim.body_id("wall"))


def test_contacts_overlap_vs_clear_and_avatars_ignore_each_other(sim):
    sim.create_box("obstacle", [0.5, 0.5, 0.5], [0.0, 0.0, 0.5])
    a = sim.create_capsule("a", 0.25, 1.7, [0.7, 0.0, 0.85])  # 0.05 m into the box
    b = sim.create_capsule("b", 0.25, 1.7, [0.76, 0.0, 0.85])  # 0.01 m clear of it
    c = sim.create_capsule("c", 0.25, 1.7, [3.0, 0.0, 0.85])  # overlaps d only
    d = sim.create_capsule("d", 0.25, 1.7, [3.1, 0.0, 0.85])
    np.testing.assert_array_equal(sim.contacts(np.array([a, b, c, d])), [True, False, False, False])
    # Move them: a clear by 1 mm, b into the box by 1 mm.
    sim.set_poses(np.array([a, b]), [[0.751, 0.0, 0.85], [0.749, 0.0, 0.85]], [0.0, 1.0])
    np.testing.assert_array_equal(sim.contacts(np.array([a, b])), [False, True])


def test_contacts_of_many_avatars_in_tiled_rooms_match_signed_distance(sim):
    n = 12
    origins = tile_origins(n)
    lays = [
        make_layout(TASK_NAMES[s % 3], CFG, np.random.default_rng(s)).with_origin(origins[s])
        for s in range(n)
    ]
    avatars = np.array([build(sim, lay, prefix=f"r{s}/")["avatar"] for s, lay in enumerate(lays)])
    assert not sim.contacts(avatars).any()  # everyone at a free start
    lo = np.array([[x.bounds[0], x.bounds[2]] for x in lays])
    hi = np.array([[x.bounds[1], x.bounds[3]] for x in lays])
    rng = np.random.default_rng(5)
    r = CFG.avatar_radius
    checked = 0
    for _ in range(60):  # random teleports, each avatar in its own room
        p = rng.uniform(lo, hi)
        sd = np.array([signed_distance(x, p[i : i + 1])[0] for i, x in enumerate(lays)])
        world = np.column_stack([p + origins, np.full(n, CFG.avatar_height / 2)])
        sim.set_poses(avatars, world, rng.uniform(-np.pi, np.pi, n))
        got = sim.contacts(avatars)
        clear = np.abs(sd - r) > 1e-3  # box corners are rounded by Bullet's 1 mm margin
        np.testing.assert_array_equal(got[clear], (sd <= r)[clear])
        checked += int(clear.sum())
    assert checked > 0.95 * 60 * n


def test_set_poses_round_trips_and_validates(sim):
    ids = np.array([sim.create_capsule(f"a{i}", 0.25, 1.7, [0.0, 0.0, 0.85]) for i in range(3)])
    pos = np.array([[1.0, 2.0, 0.85], [-3.0, 0.5, 0.85], [100.0, -50.0, 0.85]])
    yaw = np.array([0.3, -2.0, 3.0])
    sim.set_poses(ids, pos, yaw)
    got_pos, got_yaw = sim.get_poses(ids)
    np.testing.assert_allclose(got_pos, pos, atol=1e-9)
    np.testing.assert_allclose(got_yaw, yaw, atol=1e-9)
    with pytest.raises(ValueError, match="positions"):
        sim.set_poses(ids, pos[:2], yaw)
    with pytest.raises(ValueError, match="yaws"):
        sim.set_poses(ids, pos, [0.0, np.nan, 0.0])


def test_bodies_by_name_removal_clear_and_compaction_keep_ids(sim):
    ids = {f"b{i}": sim.create_box(f"b{i}", [0.2, 0.2, 0.5], [i * 2.0, 5.0, 0.5]) for i in range(6)}
    av = sim.create_capsule("avatar", 0.25, 1.7, [0.0, 4.6, 0.85])  # touches b0
    assert sim.body_id("b3") == ids["b3"] and sim.name_of(ids["b3"]) == "b3"
    with pytest.raises(ValueError, match="already exists"):
        sim.create_box("b3", [1, 1, 1], [0, 0, 0])
    sim.remove_body("b1")
    sim.remove_prefix("b4")
    assert "b1" not in sim and "b4" not in sim
    with pytest.raises(KeyError, match="b1"):
        sim.body_id("b1")
    sim.set_poses(np.array([av]), [[4.0, 4.6, 0.85]], [0.0])  # now 0.05 m into b2
    sim.compact()  # rebuild the world: same ids, shapes and poses
    assert {n: sim.body_id(n) for n in sim.names if n != "avatar"} == {
        k: v for k, v in ids.items() if k not in ("b1", "b4")
    }
    assert sim.body_id("avatar") == av
    assert sim.contacts(np.array([av]))[0]
    o = np.array([[6.0, 0.0, 0.5], [2.0, 0.0, 0.5]])
    frac, hit = sim.ray_test(o, o + np.array([0.0, 10.0, 0.0]))
    assert hit[0] == ids["b3"] and hit[1] == -1  # b1 is gone
    assert frac[0] * 10.0 == pytest.approx(4.8, abs=1e-6)
    sim.clear()
    assert sim.names == []
    assert sim.ray_test([[6.0, 0.0, 0.5]], [[6.0, 10.0, 0.5]])[1][0] == -1


def test_automatic_compaction_after_many_removals():
    with Simulation(compact_after=50) as sim:
        keep = sim.create_box("keep", [0.5, 0.5, 0.5], [0.0, 3.0, 0.5])
        sim.create_marker("marker", 0.1, [1.0, 1.0, 1.0])
        sim.create_compound(
            "pair",
            [([0.2, 0.2, 0.2], [0.0, 0.0, 0.2], 0.5)],
            [(0.2, 0.4, [1.0, 0.0, 0.2])],
            [0.0, -3.0, 0.0],
            collide=False,
        )
        before = {n: sim.body_id(n) for n in sim.names}
        for i in range(120):
            sim.create_cylinder(f"tmp{i}", 0.1, 1.0, [5.0, 0.0, 0.5])
            sim.remove_body(f"tmp{i}")
        assert {n: sim.body_id(n) for n in sim.names} == before
        assert sim.ray_test([[0.0, 0.0, 0.5]], [[0.0, 10.0, 0.5]])[1][0] == keep
        np.testing.assert_allclose(sim.get_poses(np.array([before["pair"]]))[0], [[0, -3, 0]])


def test_images_show_the_scene(sim):
    sim.create_box("red", [0.5, 0.5, 0.5], [3.0, 0.0, 0.5], rgba=(1.0, 0.0, 0.0, 1.0))
    img = sim.camera_image([0.0, 0.0, 0.5], [1.0, 0.0, 0.5], width=64, height=48, fov_deg=60.0)
    assert img.shape == (48, 64, 3) and img.dtype == np.uint8
    centre = img[24, 32].astype(int)
    assert centre[0] > 120 and centre[1] < 60 and centre[2] < 60  # the red box straight ahead
    corner = img[2, 2].astype(int)
    assert not (corner[0] > 120 and corner[1] < 60)  # sky above it is not red
    # Top-down: the box at x = 3 appears right of centre, on the horizontal mid-line.
    top = sim.top_down_image([0.0, 0.0], 5.0, width=100, height=100)
    red = (top[..., 0] > 120) & (top[..., 1] < 60)
    ys, xs = np.nonzero(red)
    assert xs.mean() == pytest.approx(50 + 3.0 / 5.0 * 50, abs=3)
    assert ys.mean() == pytest.approx(50, abs=3)


def test_build_creates_named_bodies_at_the_origin(sim):
    lay = interact_layout(CFG, np.random.default_rng(3)).with_origin([60.0, 30.0])
    a = np.linspace(-np.pi, np.pi, 64, endpoint=False)
    o, e = _rays(np.tile(lay.to_world(lay.start[:2]), (64, 1)), a, 0.5, 10.0)
    # Headless sim: no visual-only bodies unless asked; walls and obstacles as two compounds.
    assert set(build(sim, lay, prefix="a/")) == {"walls", "obstacles", "target", "avatar"}
    frac_merged = sim.ray_test(o, e)[0]
    sim.remove_prefix("a/")
    assert sim.names == []
    ids = build(sim, lay, prefix="room/", merge=False, visuals=True, landmark_markers=True)
    want = {"floor", "target", "target_marker", "goal_marker", "avatar"}
    want |= {f"wall_{i}" for i in range(4)} | {f"obstacle_{i}" for i in range(len(lay.obstacles))}
    want |= {f"landmark_{k}" for k in lay.landmark_ids}
    assert set(ids) == want
    assert all(sim.body_id("room/" + k) == v for k, v in ids.items())
    pos, yaw = sim.get_poses(np.array([ids["avatar"]]))
    want_pos = [lay.start[0] + 60.0, lay.start[1] + 30.0, CFG.avatar_height / 2]
    np.testing.assert_allclose(pos[0], want_pos, atol=1e-9)
    assert yaw[0] == pytest.approx(lay.start[2])
    # Merged or not, the rays from the start see the same room, the one of the 2-D geometry.
    frac = sim.ray_test(o, e)[0]
    np.testing.assert_allclose(frac_merged, frac, atol=1e-9)
    d2 = ray_cast_2d(lay, np.tile(lay.start[:2], (64, 1)), a, 10.0)
    np.testing.assert_allclose(frac * 10.0, d2, atol=3e-3)


def test_close_twice_is_safe_and_use_after_close_raises():
    s = Simulation()
    s.create_box("b", [1, 1, 1], [0, 0, 1])
    s.close()
    s.close()
    assert not s.is_open
    with pytest.raises(RuntimeError, match="closed"):
        s.ray_test([[0, 0, 0]], [[1, 0, 0]])
    del s  # __del__ after close must not raise


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="X display check is Linux-only")
def test_gui_without_a_display_raises_a_clear_error(monkeypatch):
    if display_available():
        pytest.skip("a display is available here")
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(RuntimeError, match="display"):
        Simulation(render_mode="human")


def test_bad_arguments_raise_clear_errors(sim):
    with pytest.raises(ValueError, match="render_mode"):
        Simulation(render_mode="vr")
    with pytest.raises(ValueError, match="contact_tolerance"):
        Simulation(contact_tolerance=0.5)
    with pytest.raises(ValueError, match="half_extents"):
        sim.create_box("b", [1.0, -1.0, 1.0], [0, 0, 0])
    with pytest.raises(ValueError, match="position"):
        sim.create_box("b", [1.0, 1.0, 1.0], [0, 0])
    with pytest.raises(ValueError, match="rgba"):
        sim.create_marker("m", 0.1, [0, 0, 0], rgba=(2.0, 0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="height"):
        sim.create_capsule("a", 0.5, 0.8, [0, 0, 1])
    with pytest.raises(ValueError, match="ends"):
        sim.ray_test(np.zeros((3, 3)), np.ones((2, 3)))
    with pytest.raises(ValueError, match="origins"):
        sim.ray_test(np.full((1, 3), np.inf), np.ones((1, 3)))
    with pytest.raises(ValueError, match="fov_deg"):
        sim.camera_image([0, 0, 1], [1, 0, 1], fov_deg=180.0)
    with pytest.raises(ValueError, match="width"):
        sim.camera_image([0, 0, 1], [1, 0, 1], width=0)

"""The precision tasks, Doorway and Reach, against the room's geometry."""

import itertools

import gymnasium as gym
import numpy as np
import pytest

import vrloco_env  # noqa: F401
from vrloco_env.tasks import get_task
from vrloco_env.tasks.doorway import Doorway, DoorwayConfig, doorway_layout
from vrloco_env.tasks.reach import Reach, ReachConfig
from vrloco_env.world import RoomConfig, signed_distance, solid_distance

ROOM = RoomConfig()
R = ROOM.avatar_radius


def _dense(path, spacing=0.01):
    """Points every ``spacing`` m along a polyline."""
    out = [path[:1]]
    for a, b in itertools.pairwise(path):
        n = max(int(np.ceil(np.hypot(*(b - a)) / spacing)), 1)
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.concatenate(out)


def _drawn_doorway(seed, config=None):
    task = Doorway(1, 0.1, config)
    layout = task.draw(0, ROOM, np.random.default_rng(seed))
    task.reset(np.array([0]))
    return task, layout


# ------------------------------------------------------------------------------ Doorway


@pytest.mark.parametrize("seed", range(6))
def test_each_wall_closes_the_room_but_for_one_gap_in_the_drawn_width_range(seed):
    cfg = DoorwayConfig()
    _, layout = _drawn_doorway(seed)
    ymin, ymax = layout.bounds[2:]
    ys = np.linspace(ymin, ymax, 2001)
    walls = np.unique([o.center[0] for o in layout.obstacles])
    assert walls.size == cfg.n_doorways
    np.testing.assert_allclose(np.diff(walls), cfg.wall_spacing)
    for x in walls:
        free = signed_distance(layout, np.column_stack([np.full_like(ys, x), ys])) > 0.0
        edges = np.flatnonzero(np.diff(free.astype(int)))
        assert edges.size == 2  # one open stretch on the wall's line: the doorway
        width = ys[edges[1]] - ys[edges[0]]
        assert cfg.width_range[0] - 0.01 <= width <= cfg.width_range[1] + 0.01
        assert (
            ys[edges[0]] - ymin >= cfg.jamb_min - 0.01
            and ymax - ys[edges[1]] >= cfg.jamb_min - 0.01
        )
    for point in (layout.start[:2], layout.goal):
        assert signed_distance(layout, [point])[0] >= ROOM.keepout_radius - 1e-9


@pytest.mark.parametrize("seed", range(4))
def test_walking_the_planned_path_passes_the_doorways_in_order_and_the_goal_last(seed):
    """Along the layout's collision-free path, a doorway counts as passed once the avatar's
    disc is past the wall's far face, the goal distance never grows by more than the way walked
    (it drops as a doorway is passed) and is 0 only at the goal, and the bearing points at a
    free point on the next doorway's centre line, ``aim_lead`` beyond the passing line."""
    cfg = DoorwayConfig()
    task, layout = _drawn_doorway(seed)
    pts = _dense(layout.path)
    assert np.all(signed_distance(layout, pts) >= R - 1e-6)
    walls = np.sort(np.unique([o.center[0] for o in layout.obstacles]))
    through = walls + ROOM.wall_thickness / 2 + R
    dist, passed = np.empty(len(pts)), np.empty(len(pts), np.int64)
    for i, p in enumerate(pts):  # one step of the body at a time
        dist[i] = task.goal_distance(p[None])[0]
        passed[i] = task.info()["doorways_passed"][0]
    aims = np.array([task.goal_point(p[None])[0] for p in pts])
    np.testing.assert_array_equal(passed, (through[None] < pts[:, :1]).sum(1))
    assert np.all(np.diff(passed) >= 0) and passed[-1] == walls.size  # in order, each once
    steps = np.diff(dist)
    assert np.all(steps <= 0.01 + 1e-9)  # the path's points are <= 0.01 m apart
    assert np.all(steps[np.diff(passed) > 0] >= -2.0 * np.hypot(cfg.aim_lead, 0.6))
    assert np.all(dist[:-1] > 0.0) and dist[-1] == 0.0
    assert np.hypot(*(pts[-1] - layout.goal)) <= layout.goal_radius + 1e-9
    ahead = passed < walls.size
    np.testing.assert_allclose(aims[ahead, 0], through[passed[ahead]] + cfg.aim_lead)
    assert np.all(signed_distance(layout, aims[ahead]) > R)  # free: the body fits there
    ys = np.linspace(layout.bounds[2], layout.bounds[3], 4001)
    for k, x in enumerate(walls):  # on the doorway's centre line: the middle of the open stretch
        open_ = ys[signed_distance(layout, np.column_stack([np.full_like(ys, x), ys])) > 0.0]
        np.testing.assert_allclose(aims[passed == k, 1], (open_[0] + open_[-1]) / 2, atol=2e-3)
    np.testing.assert_allclose(aims[~ahead], np.tile(layout.goal, ((~ahead).sum(), 1)))


def test_the_doorway_info_is_the_jamb_clearance_the_geometry_gives():
    task, layout = _drawn_doorway(11)
    walls = np.sort(np.unique([o.center[0] for o in layout.obstacles]))
    rng = np.random.default_rng(0)
    for j, x in enumerate(walls):
        y0 = task.door_y[0, j]
        for off in rng.uniform(-0.3, 0.3, 5):
            p = np.array([[x, y0 + off]])
            task.goal_distance(p)
            info = task.info()
            assert info["doorway_index"][0] == j and info["doorways_passed"][0] == j
            assert info["doorway_along_m"][0] == pytest.approx(0.0, abs=1e-12)
            # on the wall's line inside the passage the nearest solid is a jamb face
            truth = signed_distance(layout, p)[0] - R
            assert info["doorway_margin_m"][0] == pytest.approx(truth, abs=1e-9)
            assert info["doorway_offset_m"][0] == pytest.approx(off, abs=1e-12)


def test_the_env_bears_on_the_first_doorway_and_reports_it():
    env = gym.make("VRLoco-Doorway-v0")
    obs, _ = env.reset(seed=4)
    core = env.unwrapped.core
    layout = env.unwrapped.layout
    spec = env.unwrapped.observation_spec
    sin, cos = spec.decode(obs[None])["goal_bearing"][0]
    x0 = min(o.center[0] for o in layout.obstacles) + ROOM.wall_thickness / 2 + R
    door = np.array([x0 + DoorwayConfig().aim_lead, core.task.door_y[0, 0]])
    d = door - np.asarray(layout.start[:2])
    want = np.arctan2(d[1], d[0]) - layout.start[2]
    assert np.arctan2(sin, cos) == pytest.approx(np.angle(np.exp(1j * want)), abs=1e-4)
    waypoint = spec.decode(obs[None])["waypoint_distance"][0, 0]
    assert waypoint == pytest.approx(np.hypot(*d), abs=20.0 * 1e-6)  # float32 of value / 20 m
    route = spec.decode(obs[None])["goal_distance"][0, 0]
    assert route >= np.hypot(*(np.asarray(layout.goal) - layout.start[:2])) - layout.goal_radius
    _, _, _, _, info = env.step(np.zeros(5, np.float32))
    assert info["doorways_passed"] == 0 and info["doorway_index"] == 0
    assert info["doorway_along_m"] < -ROOM.keepout_radius and not info["is_success"]


def test_impossible_doorways_are_refused_naming_the_field():
    with pytest.raises(
        ValueError,
        match=r"DoorwayConfig.width_range=\(0.6, 1.2\): width_range\[0\]"
        r" must be >= .* = 0.8 m",
    ):
        doorway_layout(ROOM, np.random.default_rng(0), DoorwayConfig(width_range=(0.6, 1.2)))
    wide = RoomConfig(avatar_radius=0.4, keepout_radius=1.0)
    with pytest.raises(ValueError, match=r"DoorwayConfig.width_range=.* = 1.1 m"):
        doorway_layout(wide, np.random.default_rng(0), DoorwayConfig())
    with pytest.raises(ValueError, match=r"DoorwayConfig.wall_spacing=1.5: must be >= .* 2.1 m"):
        doorway_layout(ROOM, np.random.default_rng(0), DoorwayConfig(wall_spacing=1.5))
    with pytest.raises(ValueError, match=r"DoorwayConfig.width=2.0: must be >= .* = 2.2 m"):
        DoorwayConfig(width=2.0)
    with pytest.raises(ValueError, match=r"DoorwayConfig.aim_lead=2.5: must be <= .* = 2.3 m"):
        doorway_layout(ROOM, np.random.default_rng(0), DoorwayConfig(aim_lead=2.5))
    with pytest.raises(ValueError, match=r"DoorwayConfig.n_doorways=0"):
        DoorwayConfig(n_doorways=0)
    env = gym.make("VRLoco-Doorway-v0", task_config=DoorwayConfig(width_range=(0.5, 0.9)))
    with pytest.raises(ValueError, match=r"DoorwayConfig\.width_range"):
        env.reset(seed=0)


# ------------------------------------------------------------------------------ Reach


def _drawn_reach(seed, config=None):
    task = Reach(1, 0.1, config)
    layout = task.draw(0, ROOM, np.random.default_rng(seed))
    task.reset(np.array([0]))
    return task, layout


@pytest.mark.parametrize("seed", range(3))
def test_the_reach_band_is_the_arms_reach_in_front_of_the_face(seed):
    """In front of the face (within its width), a body is in the band exactly where the gap
    between its surface and the pedestal, from the exact geometry, is 0.3-0.8 m; the goal
    distance elsewhere is the distance to the nearest band point found by brute force."""
    cfg = ReachConfig()
    task, layout = _drawn_reach(seed)
    ped = layout.target
    c, s = np.cos(ped.yaw), np.sin(ped.yaw)
    rng = np.random.default_rng(seed)
    along = rng.uniform(-2.0, 2.5, 4000)
    across = rng.uniform(-2.0, 2.0, 4000)
    pts = np.asarray(ped.center) + np.column_stack([c * along - s * across, s * along + c * across])
    d = task.goal_distance(pts)
    gap = solid_distance((ped,), pts) - R
    front = (along > ped.half_extents[0]) & (np.abs(across) <= ped.half_extents[1])
    lo, hi = cfg.standoff_range
    np.testing.assert_array_equal(d[front] == 0.0, (gap[front] >= lo) & (gap[front] <= hi))
    assert np.all(gap[d == 0.0] >= lo - 1e-9)  # nowhere in the band touches the pedestal
    # brute force: the band sampled on a fine grid
    w = cfg.band_half_width
    e = 1e-9  # the band's edges, just inside (round-off of the pedestal frame)
    ga, gc = np.meshgrid(np.linspace(lo + e, hi - e, 51), np.linspace(e - w, w - e, 101))
    ga = ga.ravel() + ped.half_extents[0] + R
    gc = gc.ravel()
    band = np.asarray(ped.center) + np.column_stack([c * ga - s * gc, s * ga + c * gc])
    assert np.all(task.goal_distance(band) == 0.0)
    near = np.min(np.hypot(*(pts[:, None, :] - band[None, ::7, :]).transpose(2, 0, 1)), axis=1)
    assert np.all(d <= near + 1e-9)
    assert np.all(near - d <= 0.1)  # the grid's spacing (one in seven of 0.01 m rows)


def test_the_reach_room_plans_into_the_band_and_reports_the_pedestal_gap():
    task, layout = _drawn_reach(5)
    assert layout.task == "reach" and layout.target is not None
    assert task.goal_distance(np.asarray(layout.goal)[None])[0] == 0.0
    assert task.goal_distance(layout.path[-1:])[0] == 0.0
    assert np.all(signed_distance(layout, _dense(layout.path)) >= R - 1e-6)
    pts = _dense(layout.path)[::20]
    task.goal_distance(pts[:1])
    for p in pts:
        task.goal_distance(p[None])
        info = task.info()
        truth = solid_distance((layout.target,), p[None])[0] - R
        assert info["pedestal_gap_m"][0] == pytest.approx(truth, abs=1e-9)


def test_reach_finishes_on_the_hand_held_in_the_band_only():
    task, layout = _drawn_reach(2)
    hold = np.asarray(layout.goal)[None]
    c, s = np.cos(layout.target.yaw), np.sin(layout.target.yaw)
    too_close = np.asarray(layout.target.center)[None] + (0.25 + R + 0.2) * np.array([[c, s]])

    class Step:
        hand_est = task.hand_target.copy()

    def frames(position, hand, n):
        task.reset(np.array([0]))
        Step.hand_est = hand
        return [bool(task.finished(task.goal_distance(position) <= 0.0, Step)[0]) for _ in range(n)]

    done = frames(hold, task.hand_target.copy(), 12)
    assert done.index(True) == 9  # dwell_s = 1.0 s at dt = 0.1 s: the tenth frame
    assert not any(frames(too_close, task.hand_target.copy(), 30))  # 0.2 m: not in the band
    off = task.hand_target + np.deg2rad([0.0, 0.0, 20.0])
    assert not any(frames(hold, off, 30))
    assert get_task("reach").collision_free_success and get_task("doorway").collision_free_success


def test_impossible_reach_bands_are_refused_naming_the_field():
    with pytest.raises(ValueError, match=r"ReachConfig.standoff_range=\(0.8, 0.3\)"):
        ReachConfig(standoff_range=(0.8, 0.3))
    with pytest.raises(ValueError, match=r"ReachConfig.standoff_range=\(0.5, 0.52\): must be at"):
        ReachConfig(standoff_range=(0.5, 0.52))
    with pytest.raises(ValueError, match=r"ReachConfig.band_half_width=0.0"):
        ReachConfig(band_half_width=0.0)
    with pytest.raises(TypeError, match="takes a ReachConfig"):
        gym.make("VRLoco-Reach-v0", task_config=DoorwayConfig())

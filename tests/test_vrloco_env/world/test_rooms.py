"""Room layouts: feasibility, determinism, and the 2-D geometry against hand-computed truth."""

import itertools
from dataclasses import replace
from functools import cache

import numpy as np
import pytest

from vrloco_env.tasks import make_layout
from vrloco_env.tasks.approach import approach_layout
from vrloco_env.tasks.avoid import AvoidConfig, avoid_layout
from vrloco_env.tasks.interact import InteractConfig
from vrloco_env.world import (
    Box,
    Cylinder,
    Layout,
    RoomBatch,
    RoomConfig,
    finish_layout,
    ray_cast_2d,
    signed_distance,
    tile_origins,
)

TASK_NAMES = ("approach", "avoid", "interact")
CFG = RoomConfig()
AVOID = AvoidConfig()
INTERACT = InteractConfig()


def _dense(path: np.ndarray, step: float = 0.005) -> np.ndarray:
    """Points every ``step`` metres along a polyline."""
    pts = [path[:1]]
    for a, b in itertools.pairwise(path):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        pts.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.concatenate(pts)


@cache
def _layouts(task: str, n: int = 200) -> tuple[Layout, ...]:
    """Layouts for seeds 0..n-1, drawn once per test session."""
    return tuple(make_layout(task, CFG, np.random.default_rng(s)) for s in range(n))


def _empty_room() -> Layout:
    """An approach room with its obstacles removed: walls only, interior [-4, 4]^2."""
    return replace(approach_layout(CFG, np.random.default_rng(0)), obstacles=())


def _planned(obstacles, start, goal) -> Layout:
    """The empty room's walls plus ``obstacles``, its path planned by :func:`finish_layout`."""
    lay = finish_layout(
        CFG,
        "approach",
        _empty_room().bounds,
        list(obstacles),
        np.array(start),
        0.0,
        np.array(goal),
        None,
        None,
    )
    assert lay is not None
    return lay


@pytest.mark.parametrize("task", TASK_NAMES)
def test_200_seeds_feasible_with_collision_free_shortest_paths(task):
    r = CFG.avatar_radius
    for lay in _layouts(task):
        assert lay.task == task
        start, goal = np.array(lay.start[:2]), np.array(lay.goal)
        # Start outside every solid by the keep-out (>= the avatar radius).
        assert signed_distance(lay, start[None])[0] >= CFG.keepout_radius - 1e-9
        sd_goal = signed_distance(lay, goal[None])[0]
        if task == "interact":  # the stand point faces the pedestal at the stand-off
            d_t = signed_distance(replace(lay, walls=(), obstacles=()), goal[None])[0]
            assert d_t == pytest.approx(r + INTERACT.standoff, abs=1e-9)
            assert sd_goal >= r
        else:
            assert sd_goal >= CFG.keepout_radius - 1e-9
        # The planned path starts at the start, ends in the goal region, and keeps the whole
        # avatar disc clear of every solid all along.
        assert np.allclose(lay.path[0], start)
        assert lay.in_goal(lay.path[-1:])[0]
        assert not lay.in_goal(lay.path[:-1]).any()
        assert signed_distance(lay, _dense(lay.path)).min() >= r
        # Its length is the reported shortest length, and no shorter than the straight line.
        seg = np.diff(lay.path, axis=0)
        assert lay.shortest_path_length == pytest.approx(np.hypot(*seg.T).sum(), abs=1e-9)
        straight = (
            lay.goal_line[0][0] - start[0]
            if task == "avoid"
            else np.linalg.norm(goal - start) - lay.goal_radius
        )
        assert lay.shortest_path_length >= straight - 1e-9
        if task != "avoid":
            assert np.linalg.norm(goal - start) >= CFG.min_start_goal_distance


def test_shortest_path_is_near_optimal_in_an_empty_room():
    lay = _planned((), start=(-3.0, -1.0), goal=(2.0, 1.0))
    true = np.hypot(5.0, 2.0) - lay.goal_radius  # a straight line to the disc
    assert lay.shortest_path_length == pytest.approx(true, abs=0.01)


def test_shortest_path_around_a_wall_matches_the_taut_string():
    # A thin wall x in [-0.05, 0.05], y in [-4, 2] splits the room; the avatar (radius r) must
    # pass over its top. The shortest path is a taut string: a tangent leg from the start to the
    # clearance circle (radius r) round the corner (-0.05, 2), an arc, 0.1 m along the top, the
    # mirror arc and leg towards the goal, less the goal radius.
    lay = _planned((Box((0.0, -1.0), (0.05, 3.0), 0.0, 2.0),), start=(-2.0, -2.0), goal=(2.0, -2.0))
    path = lay.path
    assert signed_distance(lay, _dense(path)).min() >= lay.avatar_radius
    r = lay.avatar_radius
    d = np.hypot(1.95, 4.0)  # start to the corner
    turn = np.arctan2(4.0, 1.95) + np.arcsin(r / d)  # leg heading, turned back to +x on the arc
    true = 2.0 * np.sqrt(d**2 - r**2) + 2.0 * r * turn + 0.1 - lay.goal_radius
    length = lay.shortest_path_length
    assert length == pytest.approx(np.hypot(*np.diff(path, axis=0).T).sum(), abs=1e-12)
    assert length >= true - 1e-9  # nothing collision-free beats the taut string
    assert length == pytest.approx(true, rel=0.015)


def test_same_seed_same_layout_different_seeds_differ():
    for task in TASK_NAMES:
        a = make_layout(task, CFG, np.random.default_rng(7))
        b = make_layout(task, CFG, np.random.default_rng(7))
        c = make_layout(task, CFG, np.random.default_rng(8))
        assert a == b
        assert a != c
        assert a.start != c.start or a.obstacles != c.obstacles


def test_avoid_obstacle_blocks_the_straight_walk():
    for lay in _layouts("avoid"):
        assert lay.start[2] == 0.0  # facing along the corridor
        x_line = lay.goal_line[0][0]
        line = np.column_stack([np.linspace(lay.start[0], x_line, 2000), np.zeros(2000)])
        sd = signed_distance(lay, line)
        assert sd.min() < lay.avatar_radius  # a straight walk would collide
        (obstacle,) = lay.obstacles
        ahead = obstacle.center[0] - lay.start[0]
        assert AVOID.obstacle_distance_range[0] <= ahead <= AVOID.obstacle_distance_range[1]
        run = AVOID.corridor_length - 2 * AVOID.corridor_margin
        assert x_line - lay.start[0] == pytest.approx(run)


def test_signed_distance_matches_hand_computed_values():
    lay = replace(
        _empty_room(),
        obstacles=(Box((1.0, 1.0), (0.5, 0.25), np.pi / 2, 1.0), Cylinder((-2.0, 0.0), 0.5, 1.0)),
    )
    pts = np.array(
        [
            [0.0, 0.0],  # nearest: the cylinder surface at x = -1.5 ... or the box
            [3.5, 0.0],  # 0.5 m from the east wall's inner face at x = 4
            [1.0, 1.0],  # box centre: inside by the smaller half extent (0.25 along world x)
            [1.0, 2.0],  # above the turned box (half extent 0.5 along world y): 0.5 m away
            [-2.0, 0.0],  # cylinder axis: -radius
            [-2.0, 1.0],  # 0.5 m from the cylinder
            [1.25 + 0.3, 1.5 + 0.4],  # diagonal from the box corner (1.25, 1.5): 0.5 m
        ]
    )
    want = [min(1.5, np.hypot(0.75, 0.5)), 0.5, -0.25, 0.5, -0.5, 0.5, 0.5]
    np.testing.assert_allclose(signed_distance(lay, pts), want, atol=1e-12)
    # A slice above the 1 m obstacles sees only the 2.5 m walls.
    np.testing.assert_allclose(signed_distance(lay, pts[:1], z=1.2), [4.0], atol=1e-12)


def test_a_segment_is_clear_where_every_sample_keeps_the_margin():
    """The planner's segment test against the signed distance of its samples: the cylinder of
    radius 0.5 at (-2, 0) blocks a 0.3 m disc on the segments that pass within 0.8 m of its
    axis, and only those (the walls are 4 m away)."""
    from vrloco_env.world.geometry import _segments_clear

    lay = replace(_empty_room(), obstacles=(Cylinder((-2.0, 0.0), 0.5, 1.0),))
    y = np.linspace(-1.5, 1.5, 61)  # horizontal segments x = -3.5 .. -0.5 at height y
    a, b = np.stack([np.full_like(y, -3.5), y], -1), np.stack([np.full_like(y, -0.5), y], -1)
    got = _segments_clear(lay._packed, a, b, 121, 0.3)
    t = np.linspace(0.0, 1.0, 121)
    samples = a[:, None] + (b - a)[:, None] * t[None, :, None]
    want = (signed_distance(lay, samples.reshape(-1, 2)) >= 0.3).reshape(61, 121).all(axis=1)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(got, np.abs(y) >= 0.8)  # the samples 2.5 cm apart cross x = -2
    assert _segments_clear(lay._packed, a[:0], b[:0], 2, 0.3).shape == (0,)


def test_ray_cast_2d_matches_hand_computed_values_and_sphere_tracing():
    lay = replace(
        _empty_room(),
        obstacles=(Box((2.0, 0.0), (0.5, 0.5), np.pi / 4, 1.0), Cylinder((0.0, 2.0), 0.5, 1.0)),
    )
    o = np.zeros((5, 2))
    ang = np.array([0.0, np.pi / 2, np.pi, -np.pi / 2, np.pi / 4])
    d = ray_cast_2d(lay, o, ang, 10.0)
    # +x: the diamond's near vertex at x = 2 - 0.5 * sqrt(2); +y: the cylinder at 1.5; -x, -y:
    # the walls at 4; 45 deg: the wall corner region, the x = 4 face at 4 * sqrt(2).
    want = [2.0 - 0.5 * np.sqrt(2.0), 1.5, 4.0, 4.0, 4.0 * np.sqrt(2.0)]
    np.testing.assert_allclose(d, want, atol=1e-12)
    assert ray_cast_2d(lay, o[:1], ang[:1], 1.0)[0] == 1.0  # nothing within range
    # Random layouts: compare with sphere tracing on the signed distance (independent code).
    rng = np.random.default_rng(3)
    for seed in range(10):
        lay = make_layout(TASK_NAMES[seed % 3], CFG, np.random.default_rng(seed))
        xmin, xmax, ymin, ymax = lay.bounds
        p = np.column_stack([rng.uniform(xmin, xmax, 400), rng.uniform(ymin, ymax, 400)])
        p = p[signed_distance(lay, p) > 0.01]
        a = rng.uniform(-np.pi, np.pi, p.shape[0])
        u = np.column_stack([np.cos(a), np.sin(a)])
        t = np.zeros(p.shape[0])
        for _ in range(400):
            t += np.maximum(signed_distance(lay, p + t[:, None] * u), 0.0)
        d = ray_cast_2d(lay, p, a, 30.0)
        # Sphere tracing converges slowly on grazing rays; the rest must agree closely.
        done = signed_distance(lay, p + t[:, None] * u) < 1e-9
        assert done.mean() > 0.95
        np.testing.assert_allclose(d[done], t[done], atol=1e-6)


def test_room_batch_equals_single_room_calls_and_updates_one_room():
    lays = [make_layout(TASK_NAMES[s % 3], CFG, np.random.default_rng(s)) for s in range(6)]
    batch = RoomBatch(lays)
    rng = np.random.default_rng(1)
    o = rng.uniform(-3.0, 3.0, (6, 20, 2))
    a = rng.uniform(-np.pi, np.pi, (6, 20))
    single = np.stack([ray_cast_2d(x, o[i], a[i], 12.0) for i, x in enumerate(lays)])
    np.testing.assert_array_equal(batch.ray_cast(o, a, 12.0), single)
    sd = np.stack([signed_distance(x, o[i]) for i, x in enumerate(lays)])
    np.testing.assert_array_equal(batch.signed_distance(o), sd)
    new = avoid_layout(CFG, np.random.default_rng(99))
    batch.set(2, new)
    lays[2] = new
    np.testing.assert_array_equal(batch.ray_cast(o, a, 12.0), RoomBatch(lays).ray_cast(o, a, 12.0))


def test_landmarks_lie_on_the_inner_wall_faces():
    for task in TASK_NAMES:
        lay = make_layout(task, CFG, np.random.default_rng(0))
        walls_only = replace(lay, obstacles=(), target=None)
        lm = lay.landmarks
        assert lm.shape[1] == 3 and lm.shape[0] == lay.landmark_ids.shape[0] > 0
        np.testing.assert_array_equal(lay.landmark_ids, np.arange(lm.shape[0]))
        np.testing.assert_allclose(signed_distance(walls_only, lm[:, :2]), 0.0, atol=1e-12)
        assert set(np.unique(lm[:, 2])) == set(CFG.landmark_heights)
        gaps = np.diff(
            np.sort(lm[(lm[:, 2] == 1.0) & (np.abs(lm[:, 1] - lay.bounds[2]) < 1e-9), 0])
        )
        assert np.all(np.abs(gaps - CFG.landmark_spacing) < 0.35)


def test_interact_target_faces_the_goal():
    for lay in _layouts("interact")[:50]:
        t = lay.target
        facing = np.array([np.cos(t.yaw), np.sin(t.yaw)])
        reach = INTERACT.pedestal_half_size + CFG.avatar_radius + INTERACT.standoff
        np.testing.assert_allclose(
            np.array(lay.goal) - np.array(t.center), reach * facing, atol=1e-9
        )
        assert t in lay.solids


def test_origin_and_tiling():
    lay = approach_layout(CFG, np.random.default_rng(0))
    moved = lay.with_origin([30.0, 60.0])
    assert moved.origin == (30.0, 60.0) and moved.obstacles == lay.obstacles
    np.testing.assert_allclose(moved.to_world([[1.0, 2.0]]), [[31.0, 62.0]])
    o = tile_origins(10, 30.0)
    assert o.shape == (10, 2) and np.all(o[0] == 0.0)
    dist = np.linalg.norm(o[:, None] - o[None], axis=-1) + np.eye(10) * 1e9
    assert dist.min() == pytest.approx(30.0)
    corridor = avoid_layout(CFG, np.random.default_rng(0))
    assert 2 * corridor.half_extent < 30.0  # the default spacing keeps rooms apart


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("room_width", 0.0),
        ("room_depth", float("nan")),
        ("avatar_radius", -0.1),
        ("grid_resolution", 0.0),
        ("n_obstacles_min", 8),
        ("n_obstacles_max", 2.5),
        ("obstacle_size_range", (0.6, 0.2)),
        ("cylinder_probability", 1.5),
        ("keepout_radius", 0.3),
        ("min_start_goal_distance", 20.0),
        ("landmark_heights", (1.0, 3.0)),
        ("max_attempts", 0),
        ("avatar_height", 0.4),
    ],
)
def test_bad_config_raises_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        RoomConfig(**{field: value})


@pytest.mark.parametrize(
    "field, value",
    [
        ("obstacle_lateral_jitter", 0.3),
        ("obstacle_distance_range", (5.0, 12.5)),
        ("corridor_width_jitter", 1.6),
        ("corridor_margin", 7.5),
        ("obstacle_size_range", (0.5, 0.25)),
    ],
)
def test_bad_avoid_config_raises_naming_the_field(field, value):
    with pytest.raises(ValueError, match=f"AvoidConfig.{field}="):
        AvoidConfig(**{field: value})


def test_a_corridor_the_avatar_cannot_pass_is_refused_at_the_first_draw():
    narrow = AvoidConfig(corridor_width=1.5)
    with pytest.raises(ValueError, match=r"AvoidConfig.corridor_width=1.5: .*avatar_radius"):
        avoid_layout(CFG, np.random.default_rng(0), narrow)
    wide_avatar = replace(CFG, avatar_radius=0.5)
    with pytest.raises(ValueError, match="corridor_width"):
        avoid_layout(wide_avatar, np.random.default_rng(0))


def test_bad_inputs_raise_clear_errors():
    lay = approach_layout(CFG, np.random.default_rng(0))
    with pytest.raises(ValueError, match="points"):
        signed_distance(lay, np.zeros(3))
    with pytest.raises(ValueError, match="angles"):
        ray_cast_2d(lay, np.zeros((2, 2)), np.zeros(3), 5.0)
    with pytest.raises(ValueError, match="max_range"):
        ray_cast_2d(lay, np.zeros((2, 2)), np.zeros(2), -1.0)
    with pytest.raises(ValueError, match="task"):
        make_layout("dance", CFG, np.random.default_rng(0))
    with pytest.raises(TypeError, match="rng"):
        approach_layout(CFG, 0)
    with pytest.raises(RuntimeError, match="max_attempts"):
        approach_layout(
            RoomConfig(n_obstacles_min=40, n_obstacles_max=40, max_attempts=2),
            np.random.default_rng(0),
        )


def test_layouts_that_once_broke_the_planner_are_feasible():
    """Approach seed 322: relaxing the path pulled its end out of the goal region."""
    layout = approach_layout(RoomConfig(), np.random.default_rng(322))
    assert layout.in_goal(layout.path[-1:])[0]
    straight = np.hypot(*np.subtract(layout.goal, layout.start[:2])) - layout.goal_radius
    assert layout.shortest_path_length >= straight - 1e-9


def test_a_rooms_path_is_planned_once_and_equals_a_fresh_plan(monkeypatch):
    """Drawing the same room again reuses its plan (the same read-only array); with the kept
    plans cleared it plans again, to the same numbers, and another room gets its own plan."""
    from vrloco_env.world import layout as layout_module

    first = avoid_layout(CFG, np.random.default_rng(5))
    again = avoid_layout(CFG, np.random.default_rng(5))
    assert again.path is first.path and not first.path.flags.writeable
    monkeypatch.setattr(layout_module, "_PATHS", type(layout_module._PATHS)())
    fresh = avoid_layout(CFG, np.random.default_rng(5))
    assert fresh.path is not first.path
    np.testing.assert_array_equal(fresh.path, first.path)
    other = avoid_layout(CFG, np.random.default_rng(6))
    assert other.obstacles != first.obstacles and not np.array_equal(other.path, first.path)


def test_the_compiled_relaxation_equals_its_python_source_on_rooms_of_every_goal_kind():
    """One relaxation pass, compiled and as Python (its ``py_func``), on the grid paths of a disc
    goal (Approach, Interact) and an end line (Avoid): the same path, bit for bit; the pass
    moves each path and lengthens none."""
    from vrloco_env.world import _planning_numba, planning

    for task, seed in (("approach", 3), ("avoid", 4), ("interact", 5)):
        lay = make_layout(task, CFG, np.random.default_rng(seed))
        line = np.nan if lay.goal_line is None else lay.goal_line[0][0]
        goal = (*lay.goal, lay.goal_radius, line)
        # a detour through the room's start, a point off the path and the path's end
        rough = np.array([lay.start[:2], lay.path[len(lay.path) // 2] + 0.05, lay.path[-1]])
        args = (
            *lay._packed.kernel_args,
            rough,
            CFG.avatar_radius,
            CFG.grid_resolution,
            *goal,
            planning._COARSE,
            planning._FINE,
            0.4,
        )
        compiled = _planning_numba.relax_pass(*args)
        python = _planning_numba.relax_pass.py_func(*args)
        np.testing.assert_array_equal(compiled, python, err_msg=task)
        assert compiled.shape != rough.shape or not np.array_equal(compiled, rough), task
        assert planning._path_length(compiled) <= planning._path_length(rough) + 1e-12, task


def test_the_goal_region_tests_and_projections_are_the_discs_and_the_end_lines():
    """The goal region's test and projection (the compiled functions that the relaxation pass
    and :meth:`Layout.in_goal` / :meth:`Layout.nearest_goal_point` share): the projection lands
    in the region, leaves points inside where they are, and no point of the region is nearer
    (checked against 20,000 points drawn in it); the compiled batch equals its ``py_func``."""
    from vrloco_env.world._planning_numba import goal_contains, goal_nearest

    rng = np.random.default_rng(0)
    for task in ("approach", "avoid"):
        lay = make_layout(task, CFG, np.random.default_rng(1))
        x, y, r, line = lay.goal_region
        assert np.isnan(line) == (lay.goal_line is None), task
        pts = np.concatenate(
            [rng.uniform(-4.0, 4.0, (200, 2)), np.array([x, y]) + rng.normal(0.0, r, (200, 2))]
        )
        inside = lay.in_goal(pts)
        near = lay.nearest_goal_point(pts)
        assert inside.any() and not inside.all(), task
        np.testing.assert_array_equal(near[inside], pts[inside])
        # the projection is in the region up to rounding: a hair inside it, it tests as inside
        pulled = near + 1e-9 * (np.array([x, y]) - near if np.isnan(line) else np.array([1, 0]))
        assert lay.in_goal(pulled).all(), task
        if np.isnan(line):  # the disc: points drawn in it, none nearer than the projection
            a, rad = rng.uniform(0, 2 * np.pi, 20_000), r * np.sqrt(rng.uniform(0, 1, 20_000))
            region = np.array([x, y]) + rad[:, None] * np.stack([np.cos(a), np.sin(a)], 1)
            np.testing.assert_array_equal(np.hypot(*(region - [x, y]).T) <= r, True)
        else:  # the half-plane x >= line, drawn up to 4 m beyond it
            region = np.stack([line + rng.uniform(0, 4, 20_000), rng.uniform(-4, 4, 20_000)], 1)
        assert lay.in_goal(region).all(), task
        best = np.min(np.hypot(*(pts[:, None] - region[None]).transpose(2, 0, 1)), axis=1)
        got = np.hypot(*(pts - near).T)
        assert (got <= best + 1e-12).all(), task
        for kernel, out in (
            (goal_contains, np.empty(400, bool)),
            (goal_nearest, np.empty((400, 2))),
        ):
            ref = out.copy()
            kernel(pts, x, y, r, line, out)
            kernel.py_func(pts, x, y, r, line, ref)
            np.testing.assert_array_equal(out, ref, err_msg=task)

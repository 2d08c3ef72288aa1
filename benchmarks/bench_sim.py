"""Per-call cost of the PyBullet world for N users sharing one world (N = 1, 16, 256).

Run: ``python benchmarks/bench_sim.py [--rays 16] [--repeats 50] [--threads 1]``

For each N it builds N Approach rooms tiled in one ``Simulation`` and times the per-step calls a
vector env makes (``set_poses`` of the N avatars, one ``ray_test`` of N x R head rays, one
``contacts`` pass), the analytic 2-D alternatives of :class:`vrloco_env.world.room_batch.RoomBatch`,
and the per-episode costs (draw a layout, build a room, rebuild one room of a running vector env).
It prints milliseconds per call, microseconds per user, and the share of the per-user-step budget of
the issue's targets (a single env >= 2,000 steps/s: 500 us/step; the vector env at N = 256 >= 20,000
user-steps/s: 50 us/user-step). Timings are medians over repeats; the machine may be shared, so
compare ratios rather than absolute numbers across runs.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np

from vrloco_env.tasks.approach import approach_layout
from vrloco_env.world import RoomBatch, RoomConfig, build, tile_origins
from vrloco_env.world.sim import Simulation


def _median_ms(fn: Callable[[], object], repeats: int) -> float:
    fn()  # warm-up (numba compilation, caches)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) * 1e3


def bench(n: int, n_rays: int, repeats: int, threads: int) -> list[tuple[str, float, float]]:
    """Rows of (call, ms per call, us per user) for n users."""
    cfg = RoomConfig()
    origins = tile_origins(n)
    rows = []
    approach_layout(cfg, np.random.default_rng(12345))  # warm-up: numba kernels
    t0 = time.perf_counter()
    layouts = [
        approach_layout(cfg, np.random.default_rng(s)).with_origin(origins[s]) for s in range(n)
    ]
    rows.append(("draw layout (per room)", (time.perf_counter() - t0) * 1e3 / n, float("nan")))
    sim = Simulation(ray_threads=threads)
    t0 = time.perf_counter()
    avatars = np.array(
        [build(sim, lay, prefix=f"r{i}/")["avatar"] for i, lay in enumerate(layouts)]
    )
    rows.append(("build room (per room)", (time.perf_counter() - t0) * 1e3 / n, float("nan")))

    rng = np.random.default_rng(0)
    start = np.array([lay.start[:2] for lay in layouts])
    local = start + rng.normal(0.0, 0.3, (n, 2))  # near the start: a few avatars touch things
    world = np.column_stack([local + origins, np.full(n, cfg.avatar_height / 2)])
    yaw = rng.uniform(-np.pi, np.pi, n)
    angles = yaw[:, None] + np.linspace(-np.pi / 2, np.pi / 2, n_rays)[None]  # 180 deg fan
    max_range = 8.0
    ray_z = 1.0  # m: below the shortest obstacles' tops (0.8-2.2 m) would miss some; timing only
    o3 = np.repeat(np.column_stack([world[:, :2], np.full(n, ray_z)]), n_rays, axis=0)
    dirs = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], -1).reshape(-1, 3)
    e3 = o3 + max_range * dirs
    batch = RoomBatch(layouts)
    o2 = np.repeat(local[:, None], n_rays, axis=1)

    per_step = {
        "set_poses": lambda: sim.set_poses(avatars, world, yaw),
        f"ray_test ({n_rays} rays/user)": lambda: sim.ray_test(o3, e3),
        "contacts": lambda: sim.contacts(avatars),
        f"RoomBatch.ray_cast ({n_rays} rays/user)": lambda: batch.ray_cast(
            o2, angles, max_range, z=ray_z
        ),
        "RoomBatch.signed_distance": lambda: batch.signed_distance(local[:, None]),
    }
    for name, fn in per_step.items():
        ms = _median_ms(fn, repeats)
        rows.append((name, ms, ms * 1e3 / n))

    def reset_one_room() -> None:
        i = int(rng.integers(n))
        sim.remove_prefix(f"r{i}/")
        lay = approach_layout(cfg, rng).with_origin(origins[i])
        build(sim, lay, prefix=f"r{i}/")

    rows.append(("reset one room (draw+rebuild)", _median_ms(reset_one_room, 10), float("nan")))
    rows.append(("compact whole world", _median_ms(sim.compact, 3), float("nan")))
    sim.close()
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rays", type=int, default=16, help="head rays per user")
    ap.add_argument("--repeats", type=int, default=50, help="timed repeats per call")
    ap.add_argument("--threads", type=int, default=1, help="rayTestBatch threads (0 = Bullet)")
    ap.add_argument("--n", type=int, nargs="+", default=[1, 16, 256], help="users per world")
    args = ap.parse_args()
    for n in args.n:
        budget_us = 500.0 if n == 1 else 50.0  # per user-step, from the targets
        print(f"\nN = {n} users, {args.rays} rays/user, ray threads = {args.threads}")
        print(f"{'call':42s} {'ms/call':>9s} {'us/user':>9s} {'of budget':>10s}")
        sim_total = 0.0
        for name, ms, us in bench(n, args.rays, args.repeats, args.threads):
            share = f"{us / budget_us:9.1%}" if np.isfinite(us) else ""
            print(f"{name:42s} {ms:9.3f} {us:9.2f} {share:>10s}")
            if name.startswith(("set_poses", "ray_test", "contacts")):
                sim_total += us
        print(
            f"{'PyBullet per user-step (poses+rays+contacts)':42s} {'':9s} {sim_total:9.2f} "
            f"{sim_total / budget_us:9.1%}"
        )


if __name__ == "__main__":
    main()

"""Episodes per second of the benchmark grid: one episode at a time vs batched users.

Run from the repository root::

    python benchmarks/bench_benchmark.py              # the main grid, its episodes per cell
    python benchmarks/bench_benchmark.py --episodes 10 --batch-size 10
    python benchmarks/bench_benchmark.py --seed 1000  # other seeds (episode i uses 1000 + i)
    python benchmarks/bench_benchmark.py --policies avoid_manoeuvre   # no route planner
    python benchmarks/bench_benchmark.py --techniques zhang2021 madgwick --tasks avoid reach
    python benchmarks/bench_benchmark.py --profile    # where the batched path's time goes

Both paths run the same grid (``vrloco benchmark``'s main grid: its default tasks, policies and
techniques, or those of ``--tasks``, ``--policies`` and ``--techniques``) with the same worker
processes, in this one run: ``batch_size=0`` plays every episode alone in a single env
(:func:`agents.benchmark.episodes.run_cell_episode`), the batched path plays each cell's episodes as
users of the native vector env (:func:`agents.benchmark.episodes.run_cell_batched`). It prints
episodes/s of each, their ratio, and whether the two tables are identical (they must be).
Each path runs once untimed first on a small grid in this process, so that neither numba's
compilation nor the loading of the compiled code into a process is timed: the workers, forked
from this process, start with the kernels loaded, as those of a long run soon have them.
``--profile`` instead plays the first technique's cells of each task batched in this process
under cProfile and prints the functions that took the most time, with their share, and how many
of the user-steps simulated were users whose episode had ended (none where every part of the env
and the policy can drop users; otherwise a batch steps all its users until its last episode
ends).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from agents.benchmark import run_benchmark
from agents.benchmark.episodes import DEFAULT_BATCH_SIZE
from agents.benchmark.grid import (
    DEFAULT_EPISODES,
    DEFAULT_POLICIES,
    DEFAULT_TASKS,
    DEFAULT_TECHNIQUES,
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=DEFAULT_EPISODES, help="episodes per cell")
    ap.add_argument("--batch-size", type=int, default=DEFAULT_BATCH_SIZE)
    ap.add_argument("--seed", type=int, default=0, help="episode i uses seed + i")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--tasks", nargs="+", default=list(DEFAULT_TASKS))
    ap.add_argument("--policies", nargs="+", default=list(DEFAULT_POLICIES))
    ap.add_argument("--techniques", nargs="+", default=list(DEFAULT_TECHNIQUES))
    ap.add_argument("--profile", action="store_true", help="profile the batched path instead")
    args = ap.parse_args()
    if args.profile:
        profile(args)
        return
    grid = dict(
        tasks=args.tasks,
        policies=args.policies,
        techniques=args.techniques,
        workers=args.workers,
        seed=args.seed,
        progress=False,
        print_table=False,
    )
    n_cells = len(args.tasks) * len(args.policies) * len(args.techniques)
    total = n_cells * args.episodes
    print(
        f"grid: {', '.join(args.tasks)} x {', '.join(args.policies)} x "
        f"{', '.join(args.techniques)}: {n_cells} cells x {args.episodes} episodes = {total} "
        f"episodes, {args.workers} workers"
    )
    rates, tables = {}, {}
    for label, batch in (
        ("one episode at a time", 0),
        (f"batched ({args.batch_size})", args.batch_size),
    ):
        # compile and load the kernels here, for the forked workers (batches of 2: serial builds)
        run_benchmark(**{**grid, "episodes": 2, "workers": 1}, batch_size=batch)
        t = time.perf_counter()
        tables[label] = run_benchmark(**grid, episodes=args.episodes, batch_size=batch)
        dt = time.perf_counter() - t
        rates[label] = total / dt
        print(f"  {label:<24} {dt:7.1f} s  {rates[label]:7.1f} episodes/s")
    (a, ra), (b, rb) = rates.items()
    print(f"  ratio batched / one at a time: {rb / ra:.2f}x")
    same = tables[a] == tables[b]
    print(f"  tables identical: {same}")
    if not same:
        sys.exit(1)


def profile(args: argparse.Namespace) -> None:
    """cProfile of the batched path on the first technique's cells, one group per task."""
    import cProfile
    import pstats

    from agents.benchmark.episodes import run_batched
    from agents.benchmark.grid import Cell
    from vrloco_env.vector import VRLocoVectorEnv

    cells = [Cell(t, p, args.techniques[0]) for t in args.tasks for p in args.policies]
    for c in cells:  # compile outside the profile
        run_batched([(c, s, False) for s in range(2)], 2)
    stepped = [0]  # user-steps the vector envs simulated, idle users included
    env_step = VRLocoVectorEnv.step

    def counted(env, actions):
        stepped[0] += env.num_envs
        return env_step(env, actions)

    prof = cProfile.Profile()
    played = 0  # user-steps of the episodes themselves
    t = time.perf_counter()
    VRLocoVectorEnv.step = counted  # type: ignore[method-assign]
    prof.enable()
    try:
        for c in cells:
            done = run_batched([(c, s, False) for s in range(args.episodes)], args.batch_size)
            played += sum(stats.steps for stats, _ in done)
    finally:
        prof.disable()
        VRLocoVectorEnv.step = env_step  # type: ignore[method-assign]
    total = time.perf_counter() - t
    print(
        f"{len(cells)} cells x {args.episodes} episodes batched ({args.batch_size}) in this "
        f"process: {total:.1f} s under the profiler; by own time:"
    )
    stats = pstats.Stats(prof)
    rows = sorted(stats.stats.items(), key=lambda kv: -kv[1][2])[:15]  # type: ignore[attr-defined]
    for (file, line, name), (_, calls, own, _cum, _) in rows:
        where = f"{Path(file).name}:{line}({name})"
        print(f"  {100 * own / total:5.1f} %  {own:6.2f} s  {calls:7d} calls  {where}")
    stages = {
        "the env's step (users, world, observation)": ("core.py", "step"),
        "the env's reset (room generation included)": ("core.py", "reset"),
        "room generation (layout and its path plan)": ("planning.py", "_plan"),
        "the policy's act (route planning included)": ("base.py", "act"),
    }
    print("by time including callees:")
    for label, (file, name) in stages.items():
        cum = sum(
            v[3]
            for (f, _, n), v in stats.stats.items()  # type: ignore[attr-defined]
            if Path(f).name == file and n == name
        )
        print(f"  {100 * cum / total:5.1f} %  {cum:6.2f} s  {label}")
    idle = stepped[0] - played
    print(
        f"user-steps simulated: {stepped[0]}, of them {idle} ({100 * idle / stepped[0]:.0f} %) "
        "by users whose episode had ended, waiting for the batch's last one"
    )


if __name__ == "__main__":
    main()

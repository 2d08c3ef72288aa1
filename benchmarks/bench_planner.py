"""The goal seeker's route planner: its kernel's time per user and control step.

Run from the repository root::

    python benchmarks/bench_planner.py                 # batches of 30 and of 1
    python benchmarks/bench_planner.py --batch-sizes 30 --seed 1000

Plays the goal seeker's episodes of three cells (Approach with Zhang 2021, Avoid with Zhang 2021 and
with the smooth filter; episode i uses seed + i) batched in this process, timing every call of
:data:`agents.scripted.planner.plan_kernel`, and prints the kernel's total time, its time per
user and call, and a digest of the episodes' numbers (the same for every batch size and every
version of the planner that plans the same routes). One untimed episode per cell first compiles
and loads the kernels. A batch of 1 is the one-at-a-time path's planner: one user per call, its
maps warm in the cache; a batch of 30 visits 30 users' maps per call.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import agents.scripted.goal_seeker as goal_seeker
from agents.benchmark.episodes import run_batched
from agents.benchmark.grid import Cell

CELLS = (
    Cell("approach", "goal_seeker+typical", "zhang2021"),
    Cell("avoid", "goal_seeker+typical", "zhang2021"),
    Cell("avoid", "goal_seeker+typical", "smooth"),
)


class _Timed:
    """``plan_kernel`` with a stopwatch: the kernel's seconds and the users it planned for."""

    def __init__(self, kernel) -> None:
        self.kernel, self.seconds, self.users = kernel, 0.0, 0

    def __call__(self, batch_size: int):
        build = self.kernel(batch_size)

        def run(*args):
            active = args[7]
            t = time.perf_counter()
            build(*args)
            self.seconds += time.perf_counter() - t
            self.users += int(active.sum())

        return run


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch-sizes", type=int, nargs="+", default=[30, 1])
    ap.add_argument("--episodes", type=int, default=60, help="episodes per cell")
    ap.add_argument("--seed", type=int, default=0, help="episode i uses seed + i")
    args = ap.parse_args()
    timed = _Timed(goal_seeker.plan_kernel)
    goal_seeker.plan_kernel = timed
    for cell in CELLS:  # compile and load
        run_batched([(cell, args.seed + args.episodes, False)], 1)
    print(
        f"{len(CELLS)} cells x {args.episodes} episodes (seeds {args.seed}-"
        f"{args.seed + args.episodes - 1}), the goal seeker's planner kernel:"
    )
    for size in args.batch_sizes:
        timed.seconds, timed.users = 0.0, 0
        digest = hashlib.sha256()
        for cell in CELLS:
            done = run_batched([(cell, args.seed + i, False) for i in range(args.episodes)], size)
            digest.update(repr([stats for stats, _ in done]).encode())
        per_call = 1e6 * timed.seconds / timed.users
        print(
            f"  batches of {size:3d}: {timed.seconds:6.2f} s, {per_call:6.1f} us per user and "
            f"call ({timed.users} user-calls); digest {digest.hexdigest()[:12]}"
        )


if __name__ == "__main__":
    main()

"""Episodes per second of the benchmark grid: one episode at a time vs batched users.

Run from the repository root::

    python benchmarks/bench_benchmark.py              # the main grid, its episodes per cell
    python benchmarks/bench_benchmark.py --episodes 10 --batch-size 10
    python benchmarks/bench_benchmark.py --policies avoid_manoeuvre   # no route planner
    python benchmarks/bench_benchmark.py --techniques seed000 madgwick --tasks avoid reach

Both paths run the same grid (``vrloco benchmark``'s main grid: its default tasks, policies and
techniques, or those of ``--tasks``, ``--policies`` and ``--techniques``) with the same worker
processes, in this one run: ``batch_size=0`` plays every episode alone in a single env
(:func:`agents.benchmark.run_cell_episode`), the batched path plays each cell's episodes as
users of the native vector env (:func:`agents.benchmark.run_cell_batched`). It prints
episodes/s of each, their ratio, and whether the two tables are identical (they must be).
Each path runs once untimed first on a small grid, so that numba's compilation is not timed.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from agents.benchmark import (
    DEFAULT_BATCH_SIZE,
    DEFAULT_EPISODES,
    DEFAULT_POLICIES,
    DEFAULT_TASKS,
    DEFAULT_TECHNIQUES,
    run_benchmark,
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=DEFAULT_EPISODES, help="episodes per cell")
    ap.add_argument("--batch-size", type=int, default=DEFAULT_BATCH_SIZE)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--tasks", nargs="+", default=list(DEFAULT_TASKS))
    ap.add_argument("--policies", nargs="+", default=list(DEFAULT_POLICIES))
    ap.add_argument("--techniques", nargs="+", default=list(DEFAULT_TECHNIQUES))
    args = ap.parse_args()
    grid = dict(tasks=args.tasks, policies=args.policies, techniques=args.techniques,
                workers=args.workers, progress=False, print_table=False)  # fmt: skip
    n_cells = len(args.tasks) * len(args.policies) * len(args.techniques)
    total = n_cells * args.episodes
    print(f"grid: {', '.join(args.tasks)} x {', '.join(args.policies)} x "
          f"{', '.join(args.techniques)}: {n_cells} cells x {args.episodes} episodes = {total} "
          f"episodes, {args.workers} workers")  # fmt: skip
    rates, tables = {}, {}
    for label, batch in (("one episode at a time", 0), (f"batched ({args.batch_size})",
                                                        args.batch_size)):  # fmt: skip
        run_benchmark(**{**grid, "episodes": 2}, batch_size=batch)  # compile, warm the workers
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


if __name__ == "__main__":
    main()

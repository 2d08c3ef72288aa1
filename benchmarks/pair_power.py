"""How many episodes per cell the default run needs to tell each technique pair apart.

Run from the repository root::

    python benchmarks/pair_power.py                      # every pair, development seeds 1000..1079
    python benchmarks/pair_power.py --pairs torso_steering madgwick --sizes 40 80 160

For each pair of :data:`agents.benchmark.discrimination.PAIRS` it plays the pair's cells of the
default run (:data:`agents.benchmark.grid.DEFAULT_GRIDS`: the technique and the baseline
``zhang2021`` on each task the run compares them on, the same users and room) on *development*
seeds, ``--seed`` onwards (1000 by default, disjoint from the run's seeds 0, 1, ...), then estimates
the power of the run's test at each cell size ``N`` of ``--sizes``: the share of ``--resamples``
bootstrap draws of ``N`` paired episodes (the same seed indices in every task, drawn with
replacement) in which the pair separates as :func:`agents.benchmark.discrimination.pair_results`
decides it (some signature or outcome metric at p < 0.01 in the expected direction, in some task),
and the share in which it separates on an outcome; and the share in which the run's claim holds:
every pair the scenario tells apart (power >= 0.5 at the largest size) separates and at least three
separate on an outcome. A pair whose power stays near 0 at every size is one the scenario does not
tell apart (the techniques behave alike there), not one that needs more episodes.

The episode count of the default run (:data:`agents.benchmark.grid.DEFAULT_EPISODES`) is the
smallest size at which that claim holds in at least 99 % of the resamples on development seeds.
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from agents.benchmark.discrimination import PAIRS, Pair, pair_results
from agents.benchmark.episodes import DEFAULT_BATCH_SIZE, run_cell_batched
from agents.benchmark.grid import DEFAULT_GRIDS, Cell
from agents.benchmark.paired import compare_values, episode_values

BASELINE = "zhang2021"


def pair_tasks(pair: Pair) -> list[str]:
    """The tasks on which the default run compares ``pair`` with the baseline."""
    tasks: list[str] = []
    for g in DEFAULT_GRIDS:
        if (
            pair.technique in g.techniques
            and BASELINE in g.techniques
            and pair.policy in g.policies
            and pair.condition in g.conditions
        ):
            tasks += [t for t in g.tasks if t not in tasks]
    return tasks


def _values(args: tuple[Cell, list[int]]) -> tuple[Cell, list[dict[str, float]]]:
    cell, seeds = args
    return cell, [
        episode_values(s) for s, _ in run_cell_batched(cell, seeds, batch_size=DEFAULT_BATCH_SIZE)
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", nargs="+", help="techniques of the pairs (default: every pair)")
    ap.add_argument("--seed", type=int, default=1000, help="first development seed")
    ap.add_argument("--episodes", type=int, default=80, help="development episodes per cell")
    ap.add_argument(
        "--sizes",
        type=int,
        nargs="+",
        default=[20, 40, 60, 80, 120],
        help="cell sizes N to estimate the power at",
    )
    ap.add_argument("--resamples", type=int, default=400)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    for name, value, low in (
        ("--episodes", args.episodes, 2),
        ("--resamples", args.resamples, 1),
        ("--workers", args.workers, 1),
        ("--sizes", min(args.sizes), 1),
    ):
        if value < low:
            ap.error(f"{name} must be >= {low}, got {value}")
    pairs = [p for p in PAIRS if args.pairs is None or p.technique in args.pairs]
    if not pairs:
        ap.error(
            f"--pairs: none of {args.pairs} is a pair; pairs: "
            f"{', '.join(p.technique for p in PAIRS)}"
        )
    seeds = list(range(args.seed, args.seed + args.episodes))
    cells = list(
        dict.fromkeys(
            Cell(t, p.policy, k, p.condition)
            for p in pairs
            for t in pair_tasks(p)
            for k in (BASELINE, p.technique)
        )
    )
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        values = dict(pool.map(_values, [(c, seeds) for c in cells]))
    print(
        f"{len(cells)} cells x {args.episodes} development episodes (seeds {seeds[0]}.."
        f"{seeds[-1]}) in {time.perf_counter() - t0:.0f} s; power = share of "
        f"{args.resamples} resamples of N paired episodes in which the pair separates "
        "(on an outcome)"
    )
    rng = np.random.default_rng(args.seed)
    # every resample draws one set of seed indices for every pair and task, as a run uses the
    # same seeds in every cell: sep[n][pair] and out[n][pair] hold a flag per resample
    sep = {n: {p.name: np.zeros(args.resamples, bool) for p in pairs} for n in args.sizes}
    out = {n: {p.name: np.zeros(args.resamples, bool) for p in pairs} for n in args.sizes}
    for n in args.sizes:
        for r in range(args.resamples):
            idx = rng.integers(0, args.episodes, n)
            for pair in pairs:
                res = pair_results(
                    [_resampled_row(values, pair, t, idx) for t in pair_tasks(pair)], (pair,)
                )[0]
                sep[n][pair.name][r], out[n][pair.name][r] = res["separates"], res["on_outcome"]
    head = "".join(f"{'N=' + str(n):>14}" for n in args.sizes)
    print(f"{'pair':<46}{head}")
    for pair in pairs:
        cols = [
            f"{sep[n][pair.name].mean():.2f} ({out[n][pair.name].mean():.2f})" for n in args.sizes
        ]
        print(f"{pair.name:<46}" + "".join(f"{c:>14}" for c in cols))
    # the run's claim: every pair the scenario tells apart separates, >= 3 on an outcome
    largest = max(args.sizes)
    apart = [p.name for p in pairs if sep[largest][p.name].mean() >= 0.5]
    joint = []
    for n in args.sizes:
        every = np.all([sep[n][name] for name in apart], axis=0)
        outcomes = np.sum([out[n][p.name] for p in pairs], axis=0)
        joint.append(f"{np.mean(every & (outcomes >= 3)):.2f}")
    print(
        f"{'all of ' + str(len(apart)) + ' told apart, >= 3 on an outcome':<46}"
        + "".join(f"{c:>14}" for c in joint)
    )
    print(f"(told apart: the pairs with power >= 0.5 at N={largest}: {', '.join(apart)})")


def _resampled_row(values: dict, pair: Pair, task: str, idx: np.ndarray) -> dict:
    """A benchmark row of ``pair`` in ``task`` whose paired tests are those of the episodes
    ``idx`` (repeats kept)."""
    base = values[Cell(task, pair.policy, BASELINE, pair.condition)]
    other = values[Cell(task, pair.policy, pair.technique, pair.condition)]
    return {
        "task": task,
        "technique": pair.technique,
        "policy": pair.policy,
        "condition": pair.condition,
        "vs_baseline": compare_values([base[i] for i in idx], [other[i] for i in idx]),
    }


if __name__ == "__main__":
    main()

"""Learning curves: one run's (:func:`plot_learning_curve`) and several seeds' together, with the
mean and the spread over the seeds (:func:`write_seed_curves`); the SB3 and RLlib trainers
both write them. Runs compared side by side (:func:`compare_runs`)::

    python -m agents.learned.curves docs/results/memory_curves.json [--at 1000000]

reads a file of runs (each its training command and its ``learning_curve.json``) and prints, per
run, the evaluation at a given step and the mean of its last five evaluations.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

#: The evaluation metrics averaged over the seeds by :func:`~agents.learned.seeds.train_seeds`.
_CURVE_KEYS = ("success_rate", "collision_rate", "mean_return")


def _read_curves(folders: dict[int, Path]) -> dict[int, list[dict[str, float]]]:
    """Each seed's ``learning_curve.json`` that exists (and is whole)."""
    curves = {}
    for s, folder in folders.items():
        try:
            curves[s] = json.loads((folder / "learning_curve.json").read_text())
        except (OSError, ValueError):
            continue
    return curves


def seed_curves_summary(curves: dict[int, list[dict[str, float]]]) -> list[dict[str, float]]:
    """The mean and standard deviation (``ddof=0``) over the seeds of each metric in
    :data:`_CURVE_KEYS`, at every evaluation step that all the seeds' curves have."""
    if not curves:
        return []
    by_seed = [{c["steps"]: c for c in curve} for curve in curves.values()]
    common = sorted(set.intersection(*(set(b) for b in by_seed)))
    rows = []
    for step in common:
        row: dict[str, float] = {"steps": step}
        for key in _CURVE_KEYS:
            values = np.array([b[step][key] for b in by_seed], dtype=float)
            row[key] = float(values.mean())
            row[f"{key}_std"] = float(values.std())
        rows.append(row)
    return rows


def write_seed_curves(
    task: str, curves: dict[int, list[dict[str, float]]], out_dir: Path
) -> dict[str, Any]:
    """``out_dir/learning_curve.json`` and ``.png`` of a :func:`~agents.learned.seeds.train_seeds`
    run; returns the JSON's content (the png only where the seeds share an evaluation step)."""
    mean = seed_curves_summary(curves)
    data = {
        "task": task,
        "seeds": sorted(curves),
        "per_seed": {str(s): c for s, c in sorted(curves.items())},
        "mean": mean,
    }
    (out_dir / "learning_curve.json").write_text(json.dumps(data, indent=2))
    if mean:
        plot_seed_curves(curves, mean, out_dir / "learning_curve.png", title=f"PPO on {task}")
    return data


def plot_seed_curves(
    curves: dict[int, list[dict[str, float]]],
    mean: list[dict[str, float]],
    path: Path,
    title: str = "",
) -> None:
    """Evaluation success rate against environment steps: one thin line per seed, the mean over
    the seeds bold and a shaded mean +- std band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    for s, curve in sorted(curves.items()):
        ax.plot(
            [c["steps"] for c in curve],
            [c["success_rate"] for c in curve],
            lw=0.8,
            alpha=0.6,
            label=f"seed {s}",
        )
    steps = np.array([m["steps"] for m in mean])
    mu = np.array([m["success_rate"] for m in mean])
    sd = np.array([m["success_rate_std"] for m in mean])
    ax.fill_between(steps, mu - sd, mu + sd, color="C0", alpha=0.2, lw=0, label="mean ± std")
    ax.plot(steps, mu, color="k", lw=2.5, label=f"mean of {len(curves)} seeds")
    ax.axhline(0.9, color="0.6", lw=0.8, ls=":")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("evaluation success rate")
    ax.set_ylim(-0.02, 1.02)
    ax.legend(loc="lower right", fontsize="small")
    ax.set_title(
        f"{title}: {mu[-1]:.0%} ± {sd[-1]:.0%} success after {steps[-1]:,} steps "
        f"({len(curves)} seeds)"
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_learning_curve(curve: list[dict[str, float]], path: Path, title: str = "") -> None:
    """Evaluation success and collision rates against environment steps (wall time on top)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = np.array([c["steps"] for c in curve])
    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    ax.plot(steps, [c["success_rate"] for c in curve], "o-", label="success rate")
    ax.plot(steps, [c["collision_rate"] for c in curve], "s--", label="collision rate")
    ax.axhline(0.9, color="0.6", lw=0.8, ls=":")
    ax.set_xlabel("environment steps")
    ax.set_ylim(-0.02, 1.02)
    ax.legend(loc="center right")
    wall = curve[-1]["wall_s"]
    ax.set_title(
        f"{title}: {curve[-1]['success_rate']:.0%} success after {steps[-1]:,} steps, "
        f"{wall / 60:.1f} min"
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)


def compare_runs(runs: dict[str, dict[str, Any]], at: int, last: int = 5) -> list[dict[str, Any]]:
    """Per run (``name -> {"command": ..., "curve": [...]}``, a curve as ``learning_curve.json``
    holds it): its last evaluation's steps, the evaluation nearest ``at`` steps (the earlier of
    two as near; None where none lies within 5 % of ``at``), and the mean success and collision
    rates of its last ``last`` evaluations and of its last ``last`` evaluations up to that one.

    Raises:
        ValueError: a run without a curve, naming it.
    """
    rows = []
    for name, run in runs.items():
        curve = run.get("curve") or []
        if not curve:
            raise ValueError(f"run {name!r} has no learning curve")
        near = min(range(len(curve)), key=lambda i: (abs(curve[i]["steps"] - at), i))
        upto = curve[: near + 1] if abs(curve[near]["steps"] - at) <= 0.05 * at else []

        def mean(points: list[dict[str, float]], key: str) -> float | None:
            points = points[-last:]
            return float(np.mean([p[key] for p in points])) if points else None

        rows.append(
            {
                "run": name,
                "steps": int(curve[-1]["steps"]),
                "at": upto[-1] if upto else None,
                "success_up_to_at": mean(upto, "success_rate"),
                "success_last": mean(curve, "success_rate"),
                "collision_last": mean(curve, "collision_rate"),
            }
        )
    return rows


def main(argv: list[str] | None = None) -> None:
    import argparse

    parser = argparse.ArgumentParser(description="compare training runs' learning curves")
    parser.add_argument("runs", type=Path, help="a JSON file: run name -> command and curve")
    parser.add_argument("--at", type=int, default=1_000_000, help="steps to compare at")
    args = parser.parse_args(argv)
    runs = json.loads(args.runs.read_text())["runs"]
    print(
        f"{'run':<22} {'steps':>10} {'at ' + format(args.at, ','):>16} "
        f"{'last 5 to there':>16} {'last 5':>8} {'coll. last 5':>13}"
    )
    for r in compare_runs(runs, args.at):
        at = "-" if r["at"] is None else f"{r['at']['success_rate']:.2f}"
        upto = "-" if r["success_up_to_at"] is None else f"{r['success_up_to_at']:.2f}"
        print(
            f"{r['run']:<22} {r['steps']:>10,} {at:>16} {upto:>16} {r['success_last']:>8.2f} "
            f"{r['collision_last']:>13.2f}"
        )
    print("evaluation success rate (training evaluation seeds 10000 + seed onwards, development)")


if __name__ == "__main__":
    main()

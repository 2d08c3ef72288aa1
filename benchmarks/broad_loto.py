"""Leave-one-trial-out (LOTO) check of the attitude EKF's defaults on BROAD.

    python benchmarks/broad_loto.py [--data FOLDER] [--out out/broad_loto.png]

The defaults of :class:`estimators.attitude.AttitudeParams` were chosen during development on the
nine BROAD trials (``vrloco data fetch broad``): their mean RMSE there is an in-sample figure. This
script asks how much of it survives on a trial the choice has not seen. For each trial in turn
the three noise parameters that set the filter's time constants are chosen on the other eight
(the grid point with the lowest mean total RMSE over them), and the held-out trial is scored
with that choice: an out-of-sample RMSE per trial. The other parameters keep their defaults
(the rest and magnetic-gate thresholds are VQF's, not fitted here).

Grid (log-spaced, 5 x 5 x 4 = 100 points, the defaults in it):

* ``acc_noise``: 0.005, 0.01, 0.02, 0.04, 0.08 rad*sqrt(s) (default 0.02);
* ``mag_noise``: 0.0075, 0.015, 0.03, 0.06, 0.12 rad*sqrt(s) (default 0.03);
* ``bias_walk``: 1e-4, 1e-3, 1e-2, 1e-1 deg/s/sqrt(s) (default 1e-3).

Metric: BROAD's total RMSE (deg) over the ``movement`` samples
(:func:`estimators.attitude.errors.orientation_errors`, as ``benchmarks/broad_table.py``). Printed
per trial: the defaults (in-sample), the LOTO choice and its held-out RMSE (out-of-sample), VQF
with its package defaults (out-of-sample); then the means, and the grid point best on all nine (the
most optimistic, in-sample figure). The figure (per-trial bars: defaults in-sample, LOTO held out,
VQF; the means last) goes to ``--out``.
"""

from __future__ import annotations

import argparse
import itertools
import math
import time
from pathlib import Path

import numpy as np

from agents.recordings.data import DataMissing, data_path
from estimators.attitude import AttitudeParams, estimate_attitude
from estimators.attitude.errors import orientation_errors
from estimators.io.broad import BroadTrial, broad_trials, load_broad

ACC_NOISE = (0.005, 0.01, 0.02, 0.04, 0.08)
MAG_NOISE = (0.0075, 0.015, 0.03, 0.06, 0.12)
BIAS_WALK_DEG = (1e-4, 1e-3, 1e-2, 1e-1)  # deg/s/sqrt(s)
GRID = [
    {"acc_noise": a, "mag_noise": m, "bias_walk": math.radians(b)}
    for a, m, b in itertools.product(ACC_NOISE, MAG_NOISE, BIAS_WALK_DEG)
]


def total_rmse(trial: BroadTrial, q: np.ndarray) -> float:
    return orientation_errors(q, trial.quat, trial.movement)["total_rmse_deg"]


def grid_errors(trials: list[BroadTrial]) -> np.ndarray:
    """(grid points, trials) total RMSE of the EKF at every grid point."""
    err = np.empty((len(GRID), len(trials)))
    for i, point in enumerate(GRID):
        for j, t in enumerate(trials):
            err[i, j] = total_rmse(t, estimate_attitude(t.gyr, t.acc, t.mag, t.fs, **point))
    return err


def loto(err: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each held-out trial j: the grid point best on the others, and its RMSE on j."""
    n = err.shape[1]
    chosen = np.empty(n, dtype=int)
    for j in range(n):
        others = np.delete(err, j, axis=1).mean(axis=1)
        chosen[j] = int(np.argmin(others))  # first of equals: deterministic
    return chosen, err[chosen, np.arange(n)]


def describe(i: int) -> str:
    p = GRID[i]
    return f"acc {p['acc_noise']:g}, mag {p['mag_noise']:g}, bw {math.degrees(p['bias_walk']):.0e}"


def plot(names: list[str], bars: dict[str, np.ndarray], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [n.split("_")[0] for n in names] + ["mean"]
    x = np.arange(len(labels))
    width = 0.8 / len(bars)
    fig, ax = plt.subplots(figsize=(11, 4.5), constrained_layout=True)
    for k, (label, values) in enumerate(bars.items()):
        ax.bar(
            x + (k - (len(bars) - 1) / 2) * width,
            np.append(values, values.mean()),
            width,
            label=label,
        )
    ax.set_xticks(x, labels)
    ax.set_xlabel("BROAD trial")
    ax.set_ylabel("total RMSE (deg)")
    ax.set_title("Attitude EKF on BROAD: defaults (in-sample) vs leave-one-trial-out vs VQF")
    ax.axvline(len(names) - 0.5, color="0.6", lw=0.8)
    ax.legend(fontsize=8)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--data",
        type=Path,
        help="BROAD folder (default: the one $VRLOCO_DATA or `vrloco data fetch broad` provides)",
    )
    parser.add_argument(
        "--out", type=Path, default=Path("out/broad_loto.png"), help="figure path (PNG)"
    )
    args = parser.parse_args()
    if args.data is None:
        try:
            args.data = data_path("broad")
        except DataMissing as err:  # one line naming the command that fetches it
            parser.error(str(err))

    trials = [load_broad(p) for p in broad_trials(args.data)]
    names = [t.name for t in trials]
    defaults = AttitudeParams()
    centre = {
        "acc_noise": defaults.acc_noise,
        "mag_noise": defaults.mag_noise,
        "bias_walk": defaults.bias_walk,
    }
    i_def = next(
        i for i, p in enumerate(GRID) if all(math.isclose(p[k], v) for k, v in centre.items())
    )
    t0 = time.perf_counter()
    err = grid_errors(trials)
    seconds = time.perf_counter() - t0
    chosen, held_out = loto(err)
    from vqf import VQF

    vqf = np.array(
        [total_rmse(t, VQF(1.0 / t.fs).updateBatch(t.gyr, t.acc, t.mag)["quat9D"]) for t in trials]
    )
    d = err[i_def]
    i_best = int(np.argmin(err.mean(axis=1)))

    print(
        f"BROAD, {len(trials)} trials from {args.data}, 9D; total RMSE (deg) over the movement "
        f"phases; grid of {len(GRID)} points ({seconds:.0f} s)"
    )
    print(
        f"grid: acc_noise {ACC_NOISE}, mag_noise {MAG_NOISE}, bias_walk {BIAS_WALK_DEG} deg/s/"
        "sqrt(s); other parameters at their defaults"
    )
    print(f"\n{'trial':<36}{'defaults':>10}{'LOTO':>10}{'VQF':>10}   LOTO choice (on the other 8)")
    print(f"{'':<36}{'in':>10}{'out':>10}{'out':>10}")
    for j, name in enumerate(names):
        print(
            f"{name[:35]:<36}{d[j]:10.2f}{held_out[j]:10.2f}{vqf[j]:10.2f}   {describe(chosen[j])}"
        )
    print(f"{'MEAN':<36}{d.mean():10.2f}{held_out.mean():10.2f}{vqf.mean():10.2f}")
    print(f"\nin-sample defaults ({describe(i_def)}): mean {d.mean():.3f} deg")
    print(
        f"leave-one-trial-out (out-of-sample):    mean {held_out.mean():.3f} deg "
        f"({held_out.mean() - d.mean():+.3f}); held-out trial lower than VQF on "
        f"{int(np.sum(held_out < vqf))} of {len(trials)}"
    )
    print(f"VQF, package defaults (out-of-sample):  mean {vqf.mean():.3f} deg")
    print(
        f"best grid point on all nine (in-sample, the most optimistic; {describe(i_best)}): "
        f"mean {err[i_best].mean():.3f} deg"
    )
    print(f"LOTO choices that equal the defaults: {int(np.sum(chosen == i_def))} of {len(trials)}")
    plot(
        names,
        {
            "EKF defaults (in-sample)": d,
            "EKF LOTO, held-out trial (out-of-sample)": held_out,
            "VQF defaults (out-of-sample)": vqf,
        },
        args.out,
    )
    print(f"figure: {args.out}")


if __name__ == "__main__":
    main()

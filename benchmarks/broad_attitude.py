"""Every registered attitude stage on the BROAD trials, 9D, one metric: the table of record.

    python benchmarks/broad_attitude.py [--data FOLDER]

Data: Laidig, Caruso, Cereatti, Seel, "BROAD - A Benchmark for Robust Inertial Orientation
Estimation", Data 6(7):72, 2021, CC-BY-4.0 (nine of its 39 trials, ``vrloco data fetch broad``;
reader :mod:`estimators.io.broad`).

Each name of :data:`estimators.stages.ATTITUDE` is built as the environment builds it,
``ATTITUDE.build(name, 1, fs)`` with the trial's rate, and fed the whole trial (gyro, specific
force, magnetometer) in one ``update``. A stage that cannot be built (its module missing or not
importable) is skipped with a note.

Metric (:func:`estimators.attitude.errors.orientation_errors`, BROAD's definitions): RMSE (deg)
over the ``movement`` samples of the earth-frame error ``q_est ⊗ conj(q_true)``: total angle,
heading (rotation about the vertical) and inclination; no heading alignment (the optical reference
is in the magnetometer's ENU frame). Time: wall time of the ``update`` call per sample (us), after
a warm-up call that loads the compiled kernels.

Where the parameters come from (read the table with this in mind):

* ``madgwick``, ``mahony``, ``vqf``: the defaults of their papers / reference libraries
  (Madgwick 2010, beta 0.041 rad/s; ``ahrs`` Mahony k_P 1, k_I 0.3; the ``vqf`` package). They
  were never fitted to BROAD: out of sample.
* ``ekf``, ``ekf_f_zero``, ``ekf_paper_literal``: this project's EKF (corrected; with the
  printed ``F = 0``; as printed), whose defaults were chosen during development on these same
  nine trials: in sample (an optimistic figure for it).
* ``gyro_only``: no parameters; its error is the floor a fusion filter must beat.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from agents.recordings.data import DataMissing, data_path
from estimators.attitude.errors import orientation_errors
from estimators.io.broad import broad_trials, load_broad
from estimators.registry import StageError
from estimators.stages import ATTITUDE

METRICS = (
    ("total", "total_rmse_deg"),
    ("heading", "heading_rmse_deg"),
    ("inclination", "inclination_rmse_deg"),
)
SOURCE = {
    "ekf": "in-sample (defaults chosen on these trials)",
    "ekf_paper_literal": "in-sample (same noise densities, the EKF as printed)",
    "ekf_f_zero": "in-sample (same defaults, printed F = 0)",
    "vqf": "out-of-sample (vqf package defaults)",
    "madgwick": "out-of-sample (Madgwick 2010 beta)",
    "mahony": "out-of-sample (ahrs / Mahony 2008 gains)",
    "gyro_only": "no parameters (the floor)",
}


def buildable(names: list[str], fs: float) -> list[str]:
    """The names whose stage builds; a note for each one that does not."""
    ok = []
    for name in names:
        try:
            stage = ATTITUDE.build(name, 1, fs)
            acc = np.tile(np.array([0.0, 0.0, 9.81]), (1, 2, 1))
            mag = np.tile(np.array([0.0, 20.0, -40.0]), (1, 2, 1))
            stage.update(np.zeros((1, 2, 3)), acc, mag)  # warm-up (loads the compiled kernels)
        except (StageError, ImportError) as err:
            print(f"note: skipping attitude stage {name!r}: {err}")
            continue
        ok.append(name)
    return ok


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--data",
        type=Path,
        help="BROAD folder (default: the one $VRLOCO_DATA or `vrloco data fetch broad` provides)",
    )
    args = parser.parse_args()
    if args.data is None:
        try:
            args.data = data_path("broad")
        except DataMissing as err:  # one line naming the command that fetches it
            parser.error(str(err))

    files = broad_trials(args.data)
    trials = [load_broad(p) for p in files]
    names = buildable(ATTITUDE.names(), trials[0].fs)
    print(f"BROAD, {len(trials)} trials from {args.data}, 9D; RMSE (deg) over the movement phases")
    for n in names:
        print(f"  {n:<18} {SOURCE.get(n, 'user plug-in')}")

    err = {n: {k: [] for _, k in METRICS} for n in names}
    seconds = dict.fromkeys(names, 0.0)
    samples = 0
    for trial in trials:
        samples += trial.n_samples
        g, a, m = trial.gyr[None], trial.acc[None], trial.mag[None]
        for n in names:
            stage = ATTITUDE.build(n, 1, trial.fs)
            t0 = time.perf_counter()
            q = stage.update(g, a, m)[0]
            seconds[n] += time.perf_counter() - t0
            e = orientation_errors(q, trial.quat, trial.movement)
            for _, k in METRICS:
                err[n][k].append(e[k])

    width = max(12, *(len(n) + 2 for n in names))
    header = f"{'trial':<36}" + "".join(f"{n:>{width}}" for n in names)
    for label, key in METRICS:
        print(f"\n{label} RMSE (deg)")
        print(header)
        table = np.array([err[n][key] for n in names])  # (implementations, trials)
        for j, trial in enumerate(trials):
            row = "".join(f"{table[i, j]:{width}.2f}" for i in range(len(names)))
            print(f"{trial.name[:35]:<36}{row}")
        print(f"{'MEAN':<36}" + "".join(f"{v:{width}.2f}" for v in table.mean(axis=1)))
        best = table == table.min(axis=0, keepdims=True)
        print(
            f"{'wins (lowest; ties count for each)':<36}"
            + "".join(f"{int(v):{width}d}" for v in best.sum(axis=1))
        )
    print(
        f"\n{'wall time per sample (us)':<36}"
        + "".join(f"{1e6 * seconds[n] / samples:{width}.3f}" for n in names)
    )
    print(f"({samples} samples in all, one stream, whole trial per update call)")


if __name__ == "__main__":
    main()

"""Attitude EKF accuracy on real data (BROAD) beside reference filters, same run, same metric.

    python benchmarks/broad_table.py [--data FOLDER] [--no-madgwick] [--ablations]

Data: Laidig, Caruso, Cereatti, Seel, "BROAD - A Benchmark for Robust Inertial Orientation
Estimation", Data 6(7):72, 2021, CC-BY-4.0 (nine of its 39 trials: ``vrloco data fetch broad``).

Metric (:func:`estimators.attitude.errors.orientation_errors`, BROAD's own definitions): RMSE in
degrees over the ``movement`` samples of the earth-frame error ``q_est ⊗ conj(q_true)``: total
angle, heading (rotation about the vertical) and inclination, one table each, per trial, with the
mean and the win counts (the lowest RMSE of the trial among the six main columns; ties count for
each). As in BROAD's example code no heading alignment is applied to 9D estimates: the optical
reference is already in the magnetometer's ENU frame. Then the head-to-head counts, online EKF
against online VQF and offline EKF against offline VQF, and the gain of each offline mode over its
online filter.

Columns, each with its library defaults and the data's sampling rate, and where its parameters
come from (``in``: in-sample, ``out``: out-of-sample):

* ``EKF`` (in): :func:`estimators.attitude.estimate_attitude` with the default
  :class:`AttitudeParams`, one parameter set for all trials, chosen during development on these
  nine trials (``benchmarks/broad_loto.py`` gives the leave-one-trial-out figure).
* ``EKF offline`` (in): the same, ``offline=True``: the forward-backward smoother (no parameter
  of its own; the filter's defaults, hence in-sample too).
* ``VQF`` (out): ``vqf.VQF.updateBatch``, causal; ``VQF offline`` (out): ``vqf.offlineVQF``
  (Laidig & Seel 2023, the ``vqf`` package's defaults, never fitted to BROAD).
* ``Madgwick`` (out): ``ahrs.filters.Madgwick``, default gain 0.041; ``imufusion`` (out):
  ``imufusion.Ahrs``, default settings but ``sample_rate``. Both return NWU-earth quaternions,
  turned to ENU by a +90 deg rotation about the vertical, as BROAD's example code does for its
  Madgwick.
* ``--ablations`` adds, outside the win counts, ``EKF 6D`` (in; no magnetometer, inclination
  only: a 6D estimate has no absolute heading) and ``EKF printed`` (in: the same noise densities
  in ``model="paper_literal"``, the EKF as Zhang 2021 prints it, bias never estimated).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.recordings.data import DataMissing, data_path
from estimators.attitude import estimate_attitude
from estimators.attitude.errors import orientation_errors
from estimators.io.broad import BroadTrial, broad_trials, load_broad
from estimators.rotations import GRAVITY, quat_from_rotvec, quat_multiply

NWU_TO_ENU = quat_from_rotvec([0.0, 0.0, np.pi / 2])
METRICS = (
    ("total", "total_rmse_deg"),
    ("heading", "heading_rmse_deg"),
    ("inclination", "inclination_rmse_deg"),
)


def ours(t: BroadTrial) -> np.ndarray:
    return estimate_attitude(t.gyr, t.acc, t.mag, t.fs)


def ours_offline(t: BroadTrial) -> np.ndarray:
    return estimate_attitude(t.gyr, t.acc, t.mag, t.fs, offline=True)


def ours_6d(t: BroadTrial) -> np.ndarray:
    return estimate_attitude(t.gyr, t.acc, None, t.fs)


def ours_paper_literal(t: BroadTrial) -> np.ndarray:
    return estimate_attitude(t.gyr, t.acc, t.mag, t.fs, model="paper_literal")


def vqf_online(t: BroadTrial) -> np.ndarray:
    from vqf import VQF

    return VQF(1.0 / t.fs).updateBatch(t.gyr, t.acc, t.mag)["quat9D"]


def vqf_offline(t: BroadTrial) -> np.ndarray:
    from vqf import offlineVQF

    return offlineVQF(t.gyr, t.acc, t.mag, 1.0 / t.fs, {})["quat9D"]


def madgwick(t: BroadTrial) -> np.ndarray:
    from ahrs.filters import Madgwick

    return quat_multiply(NWU_TO_ENU, Madgwick(gyr=t.gyr, acc=t.acc, mag=t.mag, frequency=t.fs).Q)


def imufusion_ahrs(t: BroadTrial) -> np.ndarray:
    import imufusion

    ahrs = imufusion.Ahrs()
    settings = imufusion.AhrsSettings()
    settings.sample_rate = t.fs
    ahrs.set_settings(settings)
    gyr_dps, acc_g = np.degrees(t.gyr), t.acc / GRAVITY
    q = np.empty((t.n_samples, 4))
    for k in range(t.n_samples):
        ahrs.update(gyr_dps[k], acc_g[k], t.mag[k])
        q[k] = ahrs.get_quaternion()
    return quat_multiply(NWU_TO_ENU, q)


@dataclass(frozen=True)
class Method:
    """One column: the estimator, where its parameters come from, and what it is scored on."""

    fn: Callable[[BroadTrial], np.ndarray]
    sample: str  # "in" (in-sample) or "out" (out-of-sample)
    source: str
    scored: tuple[str, ...] = ("total", "heading", "inclination")
    in_wins: bool = True


def methods(madgwick_too: bool, ablations: bool) -> dict[str, Method]:
    """The columns, in print order."""
    out = {
        "EKF": Method(ours, "in", "estimate_attitude defaults, chosen on these nine trials"),
        "EKF offline": Method(
            ours_offline,
            "in",
            "estimate_attitude(offline=True), same defaults: the forward-backward smoother",
        ),
        "VQF": Method(vqf_online, "out", "vqf.VQF.updateBatch, package defaults"),
        "VQF offline": Method(vqf_offline, "out", "vqf.offlineVQF, package defaults"),
    }
    if madgwick_too:
        out["Madgwick"] = Method(madgwick, "out", "ahrs.filters.Madgwick, beta 0.041")
    out["imufusion"] = Method(imufusion_ahrs, "out", "imufusion.Ahrs, default settings")
    if ablations:
        out["EKF 6D"] = Method(
            ours_6d,
            "in",
            "no magnetometer; inclination only",
            scored=("inclination",),
            in_wins=False,
        )
        out["EKF printed"] = Method(
            ours_paper_literal, "in", "model='paper_literal'", in_wins=False
        )
    return out


def run(trials: list[BroadTrial], table: dict[str, Method]) -> tuple[dict, dict]:
    """RMSE ``err[name][metric]`` (list over trials) and wall time ``seconds[name]``."""
    err = {n: {k: [] for _, k in METRICS} for n in table}
    seconds = dict.fromkeys(table, 0.0)
    for trial in trials:
        for n, m in table.items():
            t0 = time.perf_counter()
            q = m.fn(trial)
            seconds[n] += time.perf_counter() - t0
            e = orientation_errors(q, trial.quat, trial.movement)
            for _, k in METRICS:
                err[n][k].append(e[k])
    return err, seconds


def print_tables(trials: list[BroadTrial], table: dict[str, Method], err: dict) -> None:
    """One block per metric: per trial, MEAN, wins among the ``in_wins`` columns."""
    w = max(12, *(len(n) + 2 for n in table))
    for label, key in METRICS:
        names = [n for n, m in table.items() if label in m.scored]
        competing = [table[n].in_wins for n in names]
        print(f"\n{label} RMSE (deg)")
        print(f"{'trial':<36}" + "".join(f"{n:>{w}}" for n in names))
        print(
            f"{'(parameters: in-/out-of-sample)':<36}"
            + "".join(f"{table[n].sample:>{w}}" for n in names)
        )
        rmse = np.array([err[n][key] for n in names])  # (columns, trials)
        for j, trial in enumerate(trials):
            print(f"{trial.name[:35]:<36}" + "".join(f"{v:{w}.2f}" for v in rmse[:, j]))
        print(f"{'MEAN':<36}" + "".join(f"{v:{w}.2f}" for v in rmse.mean(axis=1)))
        main = rmse[np.array(competing)]
        best = main == main.min(axis=0, keepdims=True)
        wins = iter(best.sum(axis=1))
        cells = [f"{next(wins):{w}d}" if c else f"{'-':>{w}}" for c in competing]
        print(f"{f'wins (lowest of {main.shape[0]}; ties: each)':<36}" + "".join(cells))


def head_to_head(err: dict, a: str, b: str) -> str:
    """``a`` against ``b``: trials won by each (lower RMSE) and mean difference, per metric."""
    parts = []
    for label, key in METRICS:
        x, y = np.array(err[a][key]), np.array(err[b][key])
        parts.append(
            f"{label} {int(np.sum(x < y))}:{int(np.sum(y < x))} "
            f"(mean {x.mean():.2f} vs {y.mean():.2f})"
        )
    return f"{a} vs {b}, trials won: " + "; ".join(parts)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--data",
        type=Path,
        help="BROAD folder (default: the one $VRLOCO_DATA or `vrloco data fetch broad` provides)",
    )
    parser.add_argument("--no-madgwick", action="store_true", help="skip ahrs Madgwick (slow)")
    parser.add_argument(
        "--ablations",
        action="store_true",
        help="add EKF 6D and EKF as printed (outside the win counts)",
    )
    args = parser.parse_args()
    if args.data is None:
        try:
            args.data = data_path("broad")
        except DataMissing as err:  # one line naming the command that fetches it
            parser.error(str(err))

    table = methods(not args.no_madgwick, args.ablations)
    files = broad_trials(args.data)
    trials = [load_broad(p) for p in files]
    samples = sum(t.n_samples for t in trials)
    print(f"BROAD, {len(trials)} trials from {args.data}, 9D; RMSE (deg) over the movement phases")
    print("columns (in: in-sample, parameters chosen on these trials; out: out-of-sample):")
    for n, m in table.items():
        print(f"  {n:<13} {m.sample:<4} {m.source}")
    err, seconds = run(trials, table)
    print_tables(trials, table, err)
    print()
    print(head_to_head(err, "EKF", "VQF"))
    print(head_to_head(err, "EKF offline", "VQF offline"))
    for on, off in (("EKF", "EKF offline"), ("VQF", "VQF offline")):
        tot = np.array(err[off]["total_rmse_deg"]) - np.array(err[on]["total_rmse_deg"])
        print(
            f"{off} minus {on}, total RMSE: mean {tot.mean():+.2f} deg, lower on "
            f"{int(np.sum(tot < 0))} of {tot.size} trials"
        )
    w = max(12, *(len(n) + 2 for n in table))
    print(
        f"\n{'wall time per sample (us)':<36}"
        + "".join(f"{1e6 * seconds[n] / samples:{w}.3f}" for n in table)
    )
    print(f"({samples} samples in all, one stream per trial)")


if __name__ == "__main__":
    main()

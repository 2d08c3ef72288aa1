"""Attitude EKF accuracy on real data (BROAD) beside reference filters, same run, same metric.

    python benchmarks/broad_table.py [--data ../shared/data/broad] [--no-madgwick]

Data: Laidig, Caruso, Cereatti, Seel, "BROAD - A Benchmark for Robust Inertial Orientation
Estimation", Data 6(7):72, 2021, CC-BY-4.0 (nine of its 39 trials live in ``shared/data/broad``).

Metric (:func:`estimators.attitude.orientation_errors`, BROAD's own definitions): RMSE in degrees
over the ``movement`` samples of the earth-frame error ``q_est ⊗ conj(q_true)``: total angle,
heading (rotation about the vertical) and inclination. As in BROAD's example code no heading
alignment is applied to 9D estimates: the optical reference is already in the magnetometer's ENU
frame. 6D estimates have no absolute heading; only their inclination is scored.

Filters, each with its library defaults and the data's sampling rate:

* ours: :func:`estimators.attitude.estimate_attitude` with the default :class:`AttitudeParams`
  (one parameter set for all trials); also 6D (no magnetometer) and ``model="paper_literal"``
  (the EKF as seed 000 prints it, bias never estimated).
* VQF (Laidig & Seel 2023): ``vqf.VQF.updateBatch`` (causal) and ``vqf.offlineVQF``.
* ahrs Madgwick (``ahrs.filters.Madgwick``, default gain 0.041) and imufusion (``imufusion.Ahrs``,
  default settings but ``sample_rate``); both return NWU-earth quaternions, turned to ENU by a
  +90 deg rotation about the vertical, as BROAD's example code does for its Madgwick.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from estimators.attitude import estimate_attitude, orientation_errors
from estimators.io_broad import BroadTrial, broad_trials, load_broad
from estimators.rotations import GRAVITY, quat_from_rotvec, quat_multiply

DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "broad"
NWU_TO_ENU = quat_from_rotvec([0.0, 0.0, np.pi / 2])


def ours(t: BroadTrial) -> np.ndarray:
    return estimate_attitude(t.gyr, t.acc, t.mag, t.fs)


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="BROAD folder")
    parser.add_argument("--no-madgwick", action="store_true", help="skip ahrs Madgwick (slow)")
    args = parser.parse_args()

    methods: dict[str, tuple[Callable[[BroadTrial], np.ndarray], str]] = {
        "ours": (ours, "total_rmse_deg"),
        "ours 6D (incl.)": (ours_6d, "inclination_rmse_deg"),
        "ours as printed": (ours_paper_literal, "total_rmse_deg"),
        "VQF": (vqf_online, "total_rmse_deg"),
        "VQF offline": (vqf_offline, "total_rmse_deg"),
        "imufusion": (imufusion_ahrs, "total_rmse_deg"),
    }
    if not args.no_madgwick:
        methods["ahrs Madgwick"] = (madgwick, "total_rmse_deg")

    files = broad_trials(args.data)
    print(f"BROAD, {len(files)} trials from {args.data}; RMSE (deg) over the movement phases")
    names = list(methods)
    print(f"{'trial':<34}" + "".join(f"{n:>17}" for n in names) + f"{'ours head/incl':>17}")
    table = {n: [] for n in names}
    seconds = dict.fromkeys(names, 0.0)
    samples = 0
    for path in files:
        trial = load_broad(path)
        samples += trial.n_samples
        row = f"{trial.name[:33]:<34}"
        for n, (fn, key) in methods.items():
            t0 = time.perf_counter()
            q = fn(trial)
            seconds[n] += time.perf_counter() - t0
            err = orientation_errors(q, trial.quat, trial.movement)
            table[n].append(err[key])
            row += f"{err[key]:17.2f}"
            if n == "ours":
                ours_err = err
        row += f"{ours_err['heading_rmse_deg']:9.2f}/{ours_err['inclination_rmse_deg']:.2f}"
        print(row)
    print(f"{'MEAN':<34}" + "".join(f"{np.mean(table[n]):17.2f}" for n in names))
    print(f"{'samples/s':<34}" + "".join(f"{samples / seconds[n]:17.3g}" for n in names))
    print("columns: total RMSE, except 'ours 6D (incl.)': inclination RMSE of the 6D estimate")


if __name__ == "__main__":
    main()

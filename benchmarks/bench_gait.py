"""Gait detector speed, simulator and Oxford figures, and the eq (17) vs smooth locomotion table.

Run from the repository root::

    python benchmarks/bench_gait.py            # everything
    python benchmarks/bench_gait.py --quick    # speed and table only

Prints:

* the cost of :class:`estimators.steps.zhang2021.StepDetector` per user-sample for the environment's
  shape (B = 256 users x 10 samples per control step at 100 Hz), and for 8 users compiled and with
  its kernel uncompiled (:func:`estimators.kernels.python_reference`);
* F1 (+-0.2 s) and phantom steps on the simulator's scripted motions (``vrloco_env.user.motion`` +
  ``vrloco_env.sensors.imu``), if the environment package is importable;
* the Oxford neck-pouch walk (CC-BY-4.0, Oxford-step-counter/DataSet) with both presets, if
  ``$VRLOCO_DATA`` or the cache holds it (``vrloco data fetch oxford``);
* :func:`agents.experiments.locomotion_table.compare_locomotion`.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from agents.benchmark.step_matching import step_f1
from agents.experiments.locomotion_table import compare_locomotion
from agents.recordings.data import DataMissing, data_path
from estimators.kernels import python_reference
from estimators.rotations import GRAVITY
from estimators.steps import GaitParams, StepDetector, detect_steps
from vrloco_env.user.scripts import SCRIPTS


def bench_speed(b: int = 256, chunk: int = 10, seconds: float = 60.0) -> None:
    fs = 100.0
    rng = np.random.default_rng(0)
    n = int(seconds * fs)
    t = np.arange(n) / fs
    # Stepping at 1.8 Hz for everyone: peaks to exercise the event path.
    bump = 3.0 * np.maximum(0.0, np.cos(np.pi * 1.8 * t)) ** 16
    acc = np.zeros((b, n, 3))
    acc[..., 2] = GRAVITY + bump + 0.02 * rng.standard_normal((b, n))
    det = StepDetector(b, fs)
    det.update(acc[:, :chunk])  # compile / load the cache
    t0 = time.perf_counter()
    for k in range(chunk, n, chunk):
        det.update(acc[:, k : k + chunk])
    el = time.perf_counter() - t0
    per = el / (b * (n - chunk)) * 1e9
    print(
        f"StepDetector.update, B={b}, {chunk} samples/call: {per:.1f} ns per user-sample "
        f"({el / ((n - chunk) / chunk) * 1e6:.0f} us per call)"
    )
    # The detector compiled vs its kernel's pure-Python source (the readable implementation).
    small = acc[:8, :2000]
    timings = {}
    for name, mode in (("numba", contextlib.nullcontext), ("python", python_reference)):
        d = StepDetector(8, fs)
        with mode():
            d.update(small[:, :10])  # compile / load the cache
            t0 = time.perf_counter()
            d.update(small[:, 10:])
        timings[name] = (time.perf_counter() - t0) / small[:, 10:, 0].size * 1e9
    print(
        f"detector: numba {timings['numba']:.1f} ns, python {timings['python']:.0f} ns per "
        f"user-sample (ratio {timings['python'] / timings['numba']:.0f}x)"
    )


def bench_locomotion_speed(b: int = 256, calls: int = 2000) -> None:
    from estimators.locomotion.dead_reckoning import DeadReckoning
    from estimators.locomotion.smooth import SmoothLocomotion

    rng = np.random.default_rng(1)
    steps = (rng.random((calls, b)) < 0.02).astype(float)
    yaw = rng.uniform(-np.pi, np.pi, (calls, b))
    for cls in (DeadReckoning, SmoothLocomotion):
        loco = cls(b)
        t0 = time.perf_counter()
        for k in range(calls):
            loco.update(steps[k], yaw[k], 0.01)
        el = (time.perf_counter() - t0) / calls * 1e6
        print(f"{cls.__name__}.update, B={b}: {el:.0f} us per call ({el / b * 1e3:.0f} ns/user)")


def bench_simulator(users: int = 32) -> None:
    try:
        from vrloco_env.batch_rng import BatchRng
        from vrloco_env.sensors.imu import HeadImu
        from vrloco_env.user import run_script
    except ImportError as err:  # the environment is optional for the estimators
        print(f"simulator figures skipped ({err})")
        return
    print(f"simulator (vrloco_env.user.motion scripts, {users} users, 100 Hz):")
    print(f"  {'script':<16} {'imu':<14} {'true':>6} {'found':>6} {'min F1':>7} {'phantom':>8}")
    cases = [(s, {}) for s in SCRIPTS]
    cases += [("straight", {"cadence": c}) for c in (1.2, 2.2)]
    for name, kw in cases:
        for spec in ("consumer_mems", "ig500n"):
            rng = BatchRng.from_seeds(range(users))
            rec = run_script(name, rng, **kw)
            imu = HeadImu(spec, rng)
            acc = imu.sample(rec.quat, rec.omega, rec.acc).acc
            out = StepDetector(users, 100.0).update(acc)
            f1s, found, true, phantom = [], 0, 0, 0
            for u in range(users):
                det_t = np.sort(out.peak_time[u][np.isfinite(out.peak_time[u])]) + rec.t[0]
                tru = rec.step_times[u]
                f1s.append(step_f1(det_t, tru)[2])
                found += det_t.size
                true += tru.size
                phantom += det_t.size if tru.size == 0 else 0
            label = name + (f"@{kw['cadence']}" if kw else "")
            print(f"  {label:<16} {spec:<14} {true:>6} {found:>6} {min(f1s):>7.3f} {phantom:>8}")


def bench_oxford() -> None:
    from estimators.io.oxford import DEFAULT_RECORDING, load_oxford

    try:
        folder = data_path("oxford")
    except DataMissing as err:
        print(f"Oxford figures skipped ({err})")
        return
    rec = load_oxford(folder)
    n_true = rec.step_times.size
    print(f"Oxford {DEFAULT_RECORDING} (CC-BY-4.0): {n_true} true steps in {rec.duration:.0f} s")
    for name, params in (("head (default)", GaitParams()), ("neck_pouch", GaitParams.neck_pouch())):
        res = detect_steps(rec.t, rec.acc, params=params)
        p, r, f1 = step_f1(res.step_times, rec.step_times, tol=0.2)
        err = 100.0 * (res.step_times.size - n_true) / n_true
        print(
            f"  {name:<15} found {res.step_times.size} ({err:+.1f} %), P {p:.3f} R {r:.3f} "
            f"F1 {f1:.3f}"
        )


def bench_locomotion() -> None:
    print("eq (17) vs smooth locomotion (20 steps, SL 0.7 m, 100 Hz; compare_locomotion):")
    for turn in (0.0, 90.0):
        tab = compare_locomotion(turn_deg=turn)
        print(f"  turn {turn:.0f} deg")
        print(
            f"  {'cadence':>7} {'d_eq17':>7} {'d_smooth':>8} {'err %':>6} {'gap m':>6} "
            f"{'jerk eq17':>10} {'jerk smooth':>11} {'ratio':>7} {'vmax':>5} {'stop s':>6}"
        )
        for k in range(tab["cadence"].size):
            print(
                f"  {tab['cadence'][k]:>7.1f} {tab['distance_eq17'][k]:>7.2f} "
                f"{tab['distance_smooth'][k]:>8.2f} {tab['distance_error_pct'][k]:>6.2f} "
                f"{tab['end_gap'][k]:>6.2f} {tab['rms_jerk_eq17'][k]:>10.0f} "
                f"{tab['rms_jerk_smooth'][k]:>11.1f} {tab['jerk_ratio'][k]:>7.0f} "
                f"{tab['max_speed_smooth'][k]:>5.2f} {tab['stop_time'][k]:>6.2f}"
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="speed and locomotion table only")
    args = ap.parse_args()
    bench_speed()
    bench_locomotion_speed()
    if not args.quick:
        bench_simulator()
        bench_oxford()
    bench_locomotion()


if __name__ == "__main__":
    main()

"""Speed of the attitude EKF beside ahrs' EKF and VQF: samples per second, printed as ratios.

    python benchmarks/bench_attitude.py [--seconds 600] [--repeat 3]

One run on synthetic 9D head-motion data at 100 Hz (values do not matter for speed; they are
realistic so that every branch of the filters runs). Each figure is the best of ``--repeat``
timings after a warm-up call (numba compilation excluded).

Rows:

* ``ahrs.filters.EKF`` (pure Python, one stream): the issue's baseline for "single stream".
* VQF (C++ core): ``VQF.update`` called per sample from Python, ``VQF.updateBatch`` and
  ``offlineVQF`` over a whole recording. ``vqf.BatchVQF`` (many streams at once) is not part of
  the installed vqf 2.1.2, so there is no batched VQF row.
* ours: ``AttitudeEKF.update`` per sample (streaming, B = 1 and B = 1024), ``estimate_attitude``
  offline (one stream) and ``AttitudeEKF.update_batch`` for B = 1, 64, 1024 streams
  (sample-updates/s = B * N / time).

Targets: single stream >= 6x ahrs EKF; batched >= 2,000,000 sample-updates/s at
B = 1024.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np

from estimators.attitude import AttitudeEKF, estimate_attitude
from estimators.rotations import (
    GRAVITY,
    quat_conjugate,
    quat_from_ypr,
    quat_multiply,
    quat_rotate_inverse,
    quat_to_rotvec,
)

FS = 100.0


def head_imu(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n, 3) gyro (rad/s), accelerometer (m/s^2), magnetometer (uT) of a nodding, turning head."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    ypr = np.stack(
        [
            0.8 * np.sin(2 * np.pi * 0.15 * t),
            0.3 * np.sin(2 * np.pi * 0.4 * t),
            0.2 * np.sin(2 * np.pi * 0.3 * t),
        ],
        axis=-1,
    )
    q = quat_from_ypr(ypr)
    w = np.zeros((n, 3))
    w[1:] = quat_to_rotvec(quat_multiply(quat_conjugate(q[:-1]), q[1:])) * FS
    gyr = w + 0.01 + rng.normal(0, 0.002, (n, 3))
    acc = quat_rotate_inverse(q, [0, 0, GRAVITY]) + rng.normal(0, 0.05, (n, 3))
    mag = quat_rotate_inverse(q, [0, 25.0, -43.0]) + rng.normal(0, 0.3, (n, 3))
    return gyr, acc, mag


def best_time(fn: Callable[[], object], repeat: int) -> float:
    """Best wall time (s) of ``repeat`` calls."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=600.0, help="recording length (s)")
    parser.add_argument("--repeat", type=int, default=3, help="timings per row (best kept)")
    args = parser.parse_args()
    n = int(args.seconds * FS)
    gyr, acc, mag = head_imu(n)
    rows: list[tuple[str, float]] = []

    def add(name: str, updates: int, fn: Callable[[], object], repeat: int = args.repeat) -> None:
        fn()  # warm-up (numba compilation, caches)
        rows.append((name, updates / best_time(fn, repeat)))
        print(f"  {name:<44} {rows[-1][1]:12.4g} samples/s", flush=True)

    print(f"attitude speed, {n} samples at {FS:g} Hz per stream (best of {args.repeat})")

    # ahrs' EKF is pure Python: time a short slice.
    from ahrs.filters import EKF

    n_ahrs = min(n, 3000)
    add(
        "ahrs.filters.EKF (1 stream)",
        n_ahrs,
        lambda: EKF(gyr=gyr[:n_ahrs], acc=acc[:n_ahrs], mag=mag[:n_ahrs], frequency=FS),
        repeat=1,
    )

    from vqf import VQF, offlineVQF

    n_loop = min(n, 20000)

    def vqf_per_sample() -> None:
        v = VQF(1 / FS)
        for k in range(n_loop):
            v.update(gyr[k], acc[k], mag[k])

    add("vqf.VQF.update per sample (1 stream)", n_loop, vqf_per_sample)
    add("vqf.VQF.updateBatch (1 stream)", n, lambda: VQF(1 / FS).updateBatch(gyr, acc, mag))
    add("vqf.offlineVQF (1 stream)", n, lambda: offlineVQF(gyr, acc, mag, 1 / FS, {}))

    g1, a1, m1 = gyr[:, None], acc[:, None], mag[:, None]

    def ours_per_sample() -> None:
        ekf = AttitudeEKF(1, FS)
        for k in range(n_loop):
            ekf.update(g1[k], a1[k], m1[k])

    add("ours AttitudeEKF.update per sample (B=1)", n_loop, ours_per_sample)
    add(
        "ours estimate_attitude offline (1 stream)", n, lambda: estimate_attitude(gyr, acc, mag, FS)
    )

    for b in (1, 64, 1024):
        n_b = max(1000, min(n, 2_000_000 // b))
        gb = np.broadcast_to(gyr[:n_b], (b, n_b, 3)).copy()
        ab = np.broadcast_to(acc[:n_b], (b, n_b, 3)).copy()
        mb = np.broadcast_to(mag[:n_b], (b, n_b, 3)).copy()
        add(
            f"ours AttitudeEKF.update_batch (B={b})",
            b * n_b,
            lambda b=b, gb=gb, ab=ab, mb=mb: AttitudeEKF(b, FS).update_batch(gb, ab, mb),
        )

    b, n_s = 1024, 200
    gs = np.ascontiguousarray(np.broadcast_to(gyr[:n_s, None], (n_s, b, 3)))
    as_ = np.ascontiguousarray(np.broadcast_to(acc[:n_s, None], (n_s, b, 3)))
    ms = np.ascontiguousarray(np.broadcast_to(mag[:n_s, None], (n_s, b, 3)))

    def ours_streaming_batch() -> None:
        ekf = AttitudeEKF(b, FS)
        for k in range(n_s):
            ekf.update(gs[k], as_[k], ms[k])

    add(f"ours AttitudeEKF.update per sample (B={b})", b * n_s, ours_streaming_batch)

    rate = dict(rows)
    base = rate["ahrs.filters.EKF (1 stream)"]
    print("\nratios to ahrs.filters.EKF (single stream target >= 6):")
    for name, r in rows:
        print(f"  {name:<44} {r / base:12.1f}x")
    print("\ntargets:")
    single = min(
        rate["ours AttitudeEKF.update per sample (B=1)"],
        rate["ours estimate_attitude offline (1 stream)"],
    )
    batched = rate["ours AttitudeEKF.update_batch (B=1024)"]
    print(f"  single stream, slowest API / ahrs EKF: {single / base:8.1f}x   (target >= 6)")
    print(
        f"  batched B=1024: {batched:12.4g} sample-updates/s  (target >= 2e6): {batched / 2e6:.2f}x"
    )
    vqf_batch = rate["vqf.VQF.updateBatch (1 stream)"]
    ours_offline = rate["ours estimate_attitude offline (1 stream)"]
    print(f"  ours offline / vqf.VQF.updateBatch: {ours_offline / vqf_batch:.2f}x")


if __name__ == "__main__":
    main()

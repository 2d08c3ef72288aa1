"""Speed of the sensor models: ``KinectV2.capture`` and ``HeadImu.sample`` per control step.

    python benchmarks/bench_sensors.py                 # B = 1, 16, 256; Kinect vs git HEAD, IMU
    python benchmarks/bench_sensors.py --ref none      # this tree only
    python benchmarks/bench_sensors.py --ref HEAD~3 --batch 1 256 --repeat 9
    python benchmarks/bench_sensors.py --sensor imu    # only the IMU section

One call is what the environment does per control step (``vrloco_env.users``): M = 3 Kinect
frames of B users, default :class:`~vrloco_env.sensors.kinect.KinectSpec` (two bystanders), users
standing 2.5-3.3 m in front of the sensor with the right forearm held forward and the hand moving.
Each figure is the best, over ``--repeat`` rounds, of the mean time per call in a round of
``--calls`` calls (after a warm-up call, so numba compilation is excluded). The reference
revision's tree is exported from git (``git archive REV``) and its Kinect timed there on the same
input, in a subprocess (:func:`time_revision`); its numbers are different random draws, only the
time is compared.

Targets (with the whole env step at 0.5 ms for B = 1 and ~11 ms for B = 256):
``capture`` <= 0.15 ms at B = 1 and <= 3 ms at B = 256.

IMU section: one ``HeadImu.sample`` call of N = 10 samples (100 Hz IMU, 10 Hz control) for B users
of the ``consumer_mems`` preset with one magnetic dipole, each user turning and walking its own
way, and the call's random draw alone (``BatchRng.normal((10, 27))``), the floor no kernel can go
under. Targets: ``sample`` <= 0.04 ms at B = 1 and <= 0.5 ms at B = 256.
"""

from __future__ import annotations

import argparse
import inspect
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from estimators.rotations import quat_from_ypr  # noqa: E402
from vrloco_env.batch_rng import BatchRng  # noqa: E402
from vrloco_env.sensors import imu, kinect  # noqa: E402

FRAMES = 3  # Kinect frames per control step
TARGETS_MS = {1: 0.15, 256: 3.0}
IMU_SAMPLES = 10  # IMU samples per control step (100 Hz IMU, 10 Hz control)
IMU_TARGETS_MS = {1: 0.04, 256: 0.5}


def users(b: int, m: int, seed: int = 42) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M frames of B users: times (M,) s, joints (B, M, 25, 3) m, hand quats (B, M, 4)."""
    rng = np.random.default_rng(seed)
    pos = np.zeros((b, m, 3))
    pos[..., 0] = rng.uniform(-0.8, 0.0, (b, 1))  # 2.5-3.3 m from the default sensor
    hand = rng.uniform(-0.5, 0.5, (b, 1, 3)) + 0.2 * np.sin(np.arange(m) / 5.0)[:, None]
    joints, quat = kinect.standing_skeleton(
        pos, rng.uniform(-0.3, 0.3, (b, 1)), right_arm="forward", hand_ypr_rad=hand
    )
    return np.arange(m) / 30.0, joints, quat


def time_revision(rev: str, runs: list[tuple[int, int, int]]) -> list[float]:
    """:func:`time_capture` of the Kinect at git revision ``rev`` for each ``(B, calls, repeat)``:
    the revision's tree is exported (``git archive``) to a temporary folder and timed there in a
    subprocess, so its own modules, whatever their layout, are the ones imported."""
    tree = Path(tempfile.mkdtemp(prefix="bench_sensors_"))
    archive = subprocess.run(["git", "archive", rev], cwd=ROOT, check=True, capture_output=True)
    subprocess.run(["tar", "-x", "-C", str(tree)], input=archive.stdout, check=True)
    code = "\n".join(
        [
            "import time",
            "from typing import Any",
            "import numpy as np",
            "from estimators.rotations import quat_from_ypr",
            "from vrloco_env.batch_rng import BatchRng",
            "from vrloco_env.sensors import kinect",
            f"FRAMES = {FRAMES}",
            inspect.getsource(users),
            inspect.getsource(time_capture),
            f"print([time_capture(kinect, b, c, r) for b, c, r in {runs!r}])",
        ]
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tree,
        check=True,
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(tree)},
    )
    return [float(x) for x in out.stdout.strip().splitlines()[-1].strip("[]").split(",")]


def time_capture(module: Any, b: int, calls: int, repeat: int) -> float:
    """Best mean seconds per ``capture`` call of B users (M = 3 frames) with ``module``."""
    sensor = module.KinectV2(module.KinectSpec(), BatchRng.from_seeds(range(b)))
    sensor.reset()
    t, joints, quat = users(b, FRAMES * (calls + 1))
    sl = [slice(FRAMES * i, FRAMES * (i + 1)) for i in range(calls + 1)]
    sensor.capture(t[sl[0]], joints[:, sl[0]], quat[:, sl[0]])  # warm-up / compile
    chunks = [(t[s], joints[:, s], quat[:, s]) for s in sl[1:]]
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for chunk in chunks:
            sensor.capture(*chunk)
        best = min(best, (time.perf_counter() - t0) / calls)
    return best


def head_motion(b: int, n: int) -> tuple[np.ndarray, ...]:
    """N samples of B users at 100 Hz: quaternions (B, N, 4), rates (rad/s), world
    accelerations (m/s^2) and positions (m), each (B, N, 3); user i turns 1 + 0.3 i times as
    fast as user 0."""
    t = (np.arange(n) * 0.01)[None, :, None] * (1.0 + 0.3 * np.arange(b))[:, None, None]
    quat = quat_from_ypr(np.concatenate([np.sin(t), 0.3 * np.cos(t), -0.2 * t], -1))
    omega = np.concatenate([0.5 * np.cos(t), 0.2 + 0 * t, np.sin(3 * t)], -1)
    acc = np.concatenate([np.cos(t), np.sin(t), 0 * t], -1)
    pos = np.concatenate([0.3 * t, 0 * t, 1.6 + 0 * t], -1)
    return quat, omega, acc, pos


def time_imu(b: int, calls: int, repeat: int, what: str) -> float:
    """Best mean seconds per call of ``what`` ("sample" or "draw") for B
    users, N = IMU_SAMPLES samples per call."""
    dipole = imu.MagneticDisturbance.with_field_at((1.0, 0.5, 1.5), field_ut=20.0, distance_m=0.8)
    sensor = imu.HeadImu("consumer_mems", BatchRng.from_seeds(range(b)), disturbances=[dipole])
    motion = head_motion(b, IMU_SAMPLES * (calls + 1))
    sl = [slice(IMU_SAMPLES * i, IMU_SAMPLES * (i + 1)) for i in range(calls + 1)]
    chunks = [tuple(x[:, s] for x in motion) for s in sl]
    if what == "draw":
        draws = (IMU_SAMPLES, imu._kernel.DRAWS_PER_SAMPLE)

        def call(*_: np.ndarray) -> object:
            return sensor.rng.normal(draws)
    else:
        call = getattr(sensor, what)
    call(*chunks[0])  # warm-up / compile
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for chunk in chunks[1:]:
            call(*chunk)
        best = min(best, (time.perf_counter() - t0) / calls)
    return best


def imu_section(batches: list[int], repeat: int, seconds: float) -> None:
    """Print the IMU table: compiled sample and the random draw alone."""
    print(f"HeadImu.sample, N = {IMU_SAMPLES} samples per call, consumer_mems, one dipole")
    print(f"{'B':>5} {'sample ms':>10} {'per user-sample us':>19} {'draw ms':>8} {'target ms':>10}")
    for b in batches:
        rough = time_imu(b, 3, 1, "sample")
        calls = max(5, int(seconds / max(rough, 1e-6)))
        now = time_imu(b, calls, repeat, "sample")
        draw = time_imu(b, calls, repeat, "draw")
        target = IMU_TARGETS_MS.get(b)
        print(
            f"{b:>5} {now * 1e3:>10.4f} {now / (b * IMU_SAMPLES) * 1e6:>19.3f} "
            f"{draw * 1e3:>8.4f}" + (f" {target:>10.2f}" if target else f" {'':>10}")
        )


def kinect_section(args: argparse.Namespace) -> None:
    """Print the Kinect table: this tree against the revision ``args.ref``."""
    ref = None if args.ref.lower() == "none" else args.ref
    print(f"KinectV2.capture, M = {FRAMES} frames per call, default spec (2 bystanders)")
    header = f"{'B':>5} {'this tree ms':>13} {'per user-frame us':>18}"
    if ref is not None:
        header += f" {args.ref + ' ms':>12} {'speed-up':>9}"
    print(header + f" {'target ms':>10}")
    rows = []
    for b in args.batch:
        # About `--seconds` per round: a first rough timing sets the number of calls.
        rough = time_capture(kinect, b, 3, 1)
        calls = max(5, int(args.seconds / max(rough, 1e-6)))
        rows.append((b, calls, time_capture(kinect, b, calls, args.repeat)))
    before = (
        [None] * len(rows)
        if ref is None
        else time_revision(ref, [(b, calls, args.repeat) for b, calls, _ in rows])
    )
    for (b, _, now), then in zip(rows, before, strict=True):
        row = f"{b:>5} {now * 1e3:>13.4f} {now / (b * FRAMES) * 1e6:>18.3f}"
        if then is not None:
            row += f" {then * 1e3:>12.4f} {then / now:>8.1f}x"
        target = TARGETS_MS.get(b)
        print(row + (f" {target:>10.2f}" if target else f" {'':>10}"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, nargs="+", default=[1, 16, 256], help="users B")
    parser.add_argument("--ref", default="HEAD", help="git revision to compare with, or 'none'")
    parser.add_argument("--repeat", type=int, default=5, help="rounds per figure (best kept)")
    parser.add_argument(
        "--seconds", type=float, default=0.5, help="approximate length of one round (s)"
    )
    parser.add_argument(
        "--sensor", choices=("all", "kinect", "imu"), default="all", help="which model to time"
    )
    args = parser.parse_args()
    if args.sensor in ("all", "kinect"):
        kinect_section(args)
    if args.sensor == "all":
        print()
    if args.sensor in ("all", "imu"):
        imu_section(args.batch, args.repeat, args.seconds)


if __name__ == "__main__":
    main()

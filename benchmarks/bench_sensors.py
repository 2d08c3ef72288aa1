"""Speed of the Kinect v2 model: ``KinectV2.capture`` per call, beside a reference revision.

    python benchmarks/bench_sensors.py                 # B = 1, 16, 256; compare with git HEAD
    python benchmarks/bench_sensors.py --ref none      # this tree only
    python benchmarks/bench_sensors.py --ref HEAD~3 --batch 1 256 --repeat 9

One call is what the environment does per control step (``vrloco_env.users``): M = 3 Kinect
frames of B users, default :class:`~vrloco_env.sensors.kinect.KinectSpec` (two bystanders), users
standing 2.5-3.3 m in front of the sensor with the right forearm held forward and the hand moving.
Each figure is the best, over ``--repeat`` rounds, of the mean time per call in a round of
``--calls`` calls (after a warm-up call, so numba compilation is excluded). The reference
revision's ``vrloco_env/sensors/kinect.py`` is loaded from git (``git show REV:path``) into a
private module and timed on the same input; its numbers are different random draws, only the
time is compared.

Targets (issue 5, with the whole env step at 0.5 ms for B = 1 and ~11 ms for B = 256):
``capture`` <= 0.15 ms at B = 1 and <= 3 ms at B = 256.
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from vrloco_env.batch_rng import BatchRng  # noqa: E402
from vrloco_env.sensors import kinect  # noqa: E402

FRAMES = 3  # Kinect frames per control step
TARGETS_MS = {1: 0.15, 256: 3.0}


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


def load_revision(rev: str) -> ModuleType:
    """``vrloco_env/sensors/kinect.py`` at git revision ``rev``, imported as a private module."""
    source = subprocess.run(
        ["git", "show", f"{rev}:vrloco_env/sensors/kinect.py"],
        cwd=ROOT,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    path = Path(tempfile.mkdtemp()) / "kinect_ref.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("kinect_ref", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def time_capture(module: ModuleType, b: int, calls: int, repeat: int) -> float:
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, nargs="+", default=[1, 16, 256], help="users B")
    parser.add_argument("--ref", default="HEAD", help="git revision to compare with, or 'none'")
    parser.add_argument("--repeat", type=int, default=5, help="rounds per figure (best kept)")
    parser.add_argument(
        "--seconds", type=float, default=0.5, help="approximate length of one round (s)"
    )
    args = parser.parse_args()
    ref = None if args.ref.lower() == "none" else load_revision(args.ref)
    print(f"KinectV2.capture, M = {FRAMES} frames per call, default spec (2 bystanders)")
    header = f"{'B':>5} {'this tree ms':>13} {'per user-frame us':>18}"
    if ref is not None:
        header += f" {args.ref + ' ms':>12} {'speed-up':>9}"
    print(header + f" {'target ms':>10}")
    for b in args.batch:
        # About `--seconds` per round: a first rough timing sets the number of calls.
        rough = time_capture(kinect, b, 3, 1)
        calls = max(5, int(args.seconds / max(rough, 1e-6)))
        now = time_capture(kinect, b, calls, args.repeat)
        row = f"{b:>5} {now * 1e3:>13.4f} {now / (b * FRAMES) * 1e6:>18.3f}"
        if ref is not None:
            before = time_capture(ref, b, max(5, calls // 10), args.repeat)
            row += f" {before * 1e3:>12.4f} {before / now:>8.1f}x"
        target = TARGETS_MS.get(b)
        print(row + (f" {target:>10.2f}" if target else f" {'':>10}"))


if __name__ == "__main__":
    main()

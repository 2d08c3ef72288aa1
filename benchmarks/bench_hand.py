"""Speed of the hand pipeline: milliseconds per Kinect frame at B = 1, 16, 256 users.

Run from the repository root::

    python benchmarks/bench_hand.py                # about 30 s
    python benchmarks/bench_hand.py --steps 50 --repeat 3 --batch 1 256

The frames are those the environment feeds the pipeline: ``--steps`` control steps of
``VRLoco-Approach-v0`` (native vector env with B sub-envs, seed 0, random actions) are run once
and every Kinect frame captured (about 3 per step) is recorded. Each row then replays the
recording through a fresh :class:`~estimators.hand.HandPipeline` and prints the best of
``--repeat`` replays as milliseconds per frame (numba compilation excluded: a warm-up replay
comes first):

* ``update``: one compiled call per frame (what the environment calls, M times per step);
* ``update_frames``: one compiled call per control step for its M frames, per frame.

Targets per ``update`` call: <= 0.05 ms at B = 1 and <= 0.6 ms at B = 256 (the
whole env must make >= 2,000 steps/s single and >= 22,000 user-steps/s at B = 256; see
``benchmarks/bench_env.py``). The machine is shared: figures move by 10-30 % between runs, so
take the best of a few.
"""

from __future__ import annotations

import argparse
import gc
import sys
import time
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import vrloco_env  # noqa: F401  (registers the ids)
from estimators.hand import HandPipeline

TARGETS_MS = {1: 0.05, 256: 0.6}  # per update() call
FIELDS = ("body_id", "body_tracked", "joints", "joint_state", "hand_quat")


def record_frames(batch: int, steps: int, seed: int = 0) -> list[tuple[np.ndarray, ...]]:
    """Kinect frames of ``steps`` env steps with B = ``batch``: one (B, M, ...) tuple per step."""
    envs = gym.make_vec("VRLoco-Approach-v0", num_envs=batch)
    kinect = envs.unwrapped.core.users.kinect
    recorded: list[tuple[np.ndarray, ...]] = []
    capture = kinect.capture

    def spy(*args, **kwargs):
        frames = capture(*args, **kwargs)
        recorded.append(tuple(np.array(getattr(frames, f)) for f in FIELDS))
        return frames

    kinect.capture = spy
    envs.reset(seed=seed)
    envs.action_space.seed(seed)
    for _ in range(steps):
        envs.step(envs.action_space.sample())
    envs.close()
    return recorded


Step = tuple[np.ndarray, ...]


def replay_update(pipe: HandPipeline, steps: list[Step]) -> None:
    """``update`` once per frame, frames sliced as the env does (``a[:, t]``)."""
    for step in steps:
        for t in range(step[0].shape[1]):
            pipe.update(*(a[:, t] for a in step))


def replay_update_frames(pipe: HandPipeline, steps: list[Step]) -> None:
    """``update_frames`` once per step."""
    for step in steps:
        pipe.update_frames(*step)


def best_ms_per_frame(
    replay: Callable[[HandPipeline, list[Step]], None], steps: list[Step], repeat: int
) -> float:
    """Best over ``repeat`` replays (after one warm-up) of the wall time per frame, ms."""
    batch = steps[0][0].shape[0]
    frames = sum(step[0].shape[1] for step in steps)
    replay(HandPipeline(batch), steps[:2])  # warm-up: numba compilation or cache load
    best = np.inf
    for _ in range(repeat):
        pipe = HandPipeline(batch)
        gc.collect()
        gc.disable()
        t0 = time.perf_counter()
        replay(pipe, steps)
        elapsed = time.perf_counter() - t0
        gc.enable()
        best = min(best, elapsed / frames * 1e3)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100, help="env steps recorded per B")
    parser.add_argument("--repeat", type=int, default=5, help="replays per row (best kept)")
    parser.add_argument("--batch", type=int, nargs="+", default=[1, 16, 256], help="B values")
    args = parser.parse_args()

    print(f"hand pipeline, ms per Kinect frame (best of {args.repeat}), frames from the env")
    print(f"{'B':>5} {'frames':>7} {'update':>9} {'update_frames':>14} {'target':>7}")
    for b in args.batch:
        steps = record_frames(b, args.steps)
        frames = sum(step[0].shape[1] for step in steps)
        fast = best_ms_per_frame(replay_update, steps, args.repeat)
        multi = best_ms_per_frame(replay_update_frames, steps, args.repeat)
        target = f"{TARGETS_MS[b]:.2f}" if b in TARGETS_MS else "-"
        print(f"{b:>5} {frames:>7} {fast:>9.4f} {multi:>14.4f} {target:>7}")


if __name__ == "__main__":
    main()

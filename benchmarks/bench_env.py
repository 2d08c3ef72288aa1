"""Environment speed beside panda-gym's PandaReach-v3, and a soak test.

Run from the repository root::

    python benchmarks/bench_env.py                 # speed table (about a minute)
    python benchmarks/bench_env.py --soak 100000   # 10^5 random steps: NaN and memory check
    python benchmarks/bench_env.py --techniques    # cost per user-step of every technique
    python benchmarks/bench_env.py --contention    # vector N=64, idle cores and one busy core

Prints steps/s of the single env with random actions and the full pipeline (motion, IMU, Kinect,
attitude EKF, step detector, hand pipeline, locomotion, world), of PandaReach-v3 measured in the
same run, and the aggregate user-steps/s of the native vector env at N = 16, 64, 256, each as a
ratio to PandaReach-v3. Targets: single >= 2x, vector N = 256 >= 20x. ``--techniques`` times
every registered technique (:mod:`vrloco_env.techniques`) per user-step, single env and vector
N = 64, beside the default technique.
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import vrloco_env  # noqa: F401  (registers the ids)


def steps_per_second(env: gym.Env, seconds: float) -> float:
    env.reset(seed=0)
    env.action_space.seed(0)
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        _, _, te, tr, _ = env.step(env.action_space.sample())
        n += 1
        if te or tr:
            env.reset()
    return n / (time.perf_counter() - t0)


def vector_steps_per_second(num_envs: int, seconds: float, **kwargs) -> float:
    envs = gym.make_vec("VRLoco-Approach-v0", num_envs=num_envs, **kwargs)
    envs.reset(seed=0)
    envs.action_space.seed(0)
    envs.step(envs.action_space.sample())  # compile / warm caches
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        envs.step(envs.action_space.sample())
        n += 1
    rate = n * num_envs / (time.perf_counter() - t0)
    envs.close()
    return rate


def speed(seconds: float) -> None:
    try:
        import panda_gym  # noqa: F401

        panda = steps_per_second(gym.make("PandaReach-v3"), seconds)
    except ImportError:
        panda = float("nan")
        print("panda-gym is not installed (pip install -e '.[bench]'): no reference")
    single = steps_per_second(gym.make("VRLoco-Approach-v0"), seconds)
    print(f"{'':28}{'steps/s':>10}{'x PandaReach':>14}")
    print(f"{'PandaReach-v3 (reference)':28}{panda:10.0f}{1.0:14.2f}")
    print(f"{'VRLoco-Approach-v0 single':28}{single:10.0f}{single / panda:14.2f}   target 2x")
    for n in (16, 64, 256):
        rate = vector_steps_per_second(n, seconds)
        note = "   target 20x" if n == 256 else ""
        print(f"{f'vector N={n}':28}{rate:10.0f}{rate / panda:14.2f}{note}")


def best_step_time(env, steps: int = 200, repeats: int = 7) -> float:
    """Seconds per ``env.step`` call: the best of ``repeats`` windows of ``steps`` random steps
    (the minimum filters out the other jobs of a shared machine)."""
    env.reset(seed=0)
    env.action_space.seed(0)
    for _ in range(20):  # warm caches (and compile, the first time)
        env.step(env.action_space.sample())
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(steps):
            out = env.step(env.action_space.sample())
            if np.ndim(out[2]) == 0 and (out[2] or out[3]):
                env.reset()
        best = min(best, (time.perf_counter() - t0) / steps)
    return best


def technique_costs(seconds: float) -> None:
    """Microseconds per user-step of every registered technique, beside the default's."""
    from vrloco_env.techniques import TECHNIQUES

    print(
        f"{'technique':20}{'single us/step':>16}{'x zhang2021':>11}{'N=64 us/user-step':>20}"
        f"{'x zhang2021':>11}"
    )
    base = None
    for name in TECHNIQUES:
        single = 1e6 * best_step_time(gym.make("VRLoco-Approach-v0", technique=name).unwrapped)
        envs = gym.make_vec("VRLoco-Approach-v0", num_envs=64, technique=name)
        vec = 1e6 * best_step_time(envs, steps=20) / 64
        envs.close()
        if base is None:
            base = (single, vec)
        print(f"{name:20}{single:16.0f}{single / base[0]:11.2f}{vec:20.1f}{vec / base[1]:11.2f}")


def _burn() -> None:
    while True:
        pass


def contention(seconds: float) -> None:
    """Vector N = 64 user-steps/s with idle cores and while another process holds one core; the
    parallel builds (threads, with the OpenMP policy of estimators/kernels/batch.py) beside the
    serial builds."""
    import multiprocessing as mp

    import estimators.kernels.batch as parallel

    print(f"OMP_WAIT_POLICY={parallel.os.environ.get('OMP_WAIT_POLICY')}")
    print(f"{'vector N=64':28}{'idle cores':>12}{'one core busy':>15}")
    builds = (("parallel builds", parallel.PARALLEL_MIN_BATCH), ("serial builds", 10**9))
    for label, min_batch in builds:
        parallel.PARALLEL_MIN_BATCH = min_batch
        idle = vector_steps_per_second(64, seconds)
        load = mp.get_context("fork").Process(target=_burn, daemon=True)
        load.start()
        try:
            busy = vector_steps_per_second(64, seconds)
        finally:
            load.terminate()
            load.join()
        print(f"{label:28}{idle:12.0f}{busy:15.0f}")


def soak(steps: int) -> None:
    """Random steps with autoreset: observations stay finite, memory stays flat."""
    envs = gym.make_vec("VRLoco-Approach-v0", num_envs=16)
    envs.reset(seed=0)
    envs.action_space.seed(0)
    rss = []
    done = 0
    while done < steps:
        obs, reward, *_ = envs.step(envs.action_space.sample())
        if not (np.all(np.isfinite(obs)) and np.all(np.isfinite(reward))):
            raise SystemExit(f"non-finite observation or reward after {done} user-steps")
        done += envs.num_envs
        if (done // envs.num_envs) % 500 == 0:
            rss.append(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
    growth = rss[-1] - rss[len(rss) // 4] if len(rss) > 4 else 0.0
    print(
        f"{done} user-steps: all observations finite; peak RSS {rss[-1]:.0f} MiB, "
        f"growth over the last three quarters {growth:.1f} MiB"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=8.0, help="time per measurement")
    parser.add_argument("--soak", type=int, default=0, help="user-steps of the soak test")
    parser.add_argument("--techniques", action="store_true", help="cost of every technique")
    parser.add_argument("--contention", action="store_true", help="speed beside a busy core")
    args = parser.parse_args()
    if args.soak:
        soak(args.soak)
    elif args.contention:
        contention(args.seconds)
    elif args.techniques:
        technique_costs(args.seconds)
    else:
        speed(args.seconds)


if __name__ == "__main__":
    main()

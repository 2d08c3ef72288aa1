"""A learned user's actions in the benchmark: stable-baselines3's ``model.predict`` per row
against :class:`agents.benchmark.policies.LearnedPolicy`'s own per-row pass (the same numbers,
which the script checks), for each shipped user, in one run.

The benchmark evaluates a batch one row at a time, so that an episode's actions do not depend
on how many users it was batched with; what a row costs is what this times.

    python benchmarks/bench_learned_policy.py [--rows 30] [--repeats 20]
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

from agents.benchmark.policies import LearnedPolicy
from agents.learned.users import LEARNED_USERS
from vrloco_env.tasks import env_id


def _best(fn, rows: np.ndarray, repeats: int) -> float:
    """The shortest of ``repeats`` runs of ``fn(rows)`` (s)."""
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn(rows)
        times.append(time.perf_counter() - t)
    return min(times)


def _predict_each(model, rows: np.ndarray) -> list:
    return [model.predict(r, deterministic=True)[0] for r in rows]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=30, help="users per batch (default 30)")
    ap.add_argument("--repeats", type=int, default=20, help="timed repeats, best kept")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    print(f"{'user':<22} {'predict (us/row)':>17} {'LearnedPolicy (us/row)':>23} {'ratio':>6}")
    for name, user in LEARNED_USERS.items():
        env = gym.make(env_id(user.task))
        policy = LearnedPolicy(user.path, env)
        env.close()
        size = policy.model.observation_space.shape[0]
        rows = rng.uniform(-1.0, 1.0, (args.rows, size)).astype(np.float32)
        want = np.stack(_predict_each(policy.model, rows))
        if not np.array_equal(policy._act_rows(rows), want):
            raise SystemExit(f"{name}: the actions differ from model.predict's")
        slow = _best(lambda x, m=policy.model: _predict_each(m, x), rows, args.repeats)
        fast = _best(policy._act_rows, rows, args.repeats)
        n = args.rows
        print(f"{name:<22} {slow / n * 1e6:>17.1f} {fast / n * 1e6:>23.1f} {slow / fast:>5.2f}x")


if __name__ == "__main__":
    main()

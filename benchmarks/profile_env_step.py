"""Where one step of the training env spends its time: cProfile over the vector env's ``step``.

Run from the repository root::

    python benchmarks/profile_env_step.py [--task approach] [--num-envs 32] [--steps 300]

Builds the env a training run builds (:func:`agents.learned.models.env_settings`), warms it up
(the compiled kernels load), then profiles ``--steps`` steps of random actions and prints the
functions with the most time of their own, as shares of the profiled time.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _where(file: str, line: int) -> str:
    """``file:line`` relative to the repository (a builtin: its name only)."""
    path = Path(file)
    if path.is_absolute() and path.is_relative_to(ROOT):
        return f"{path.relative_to(ROOT).as_posix()}:{line}"
    return "builtin" if file == "~" else f"{path.name}:{line}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", default="approach")
    parser.add_argument("--num-envs", type=int, default=32)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--top", type=int, default=8, help="functions to list")
    args = parser.parse_args()

    import numpy as np

    from agents.learned.models import env_settings
    from vrloco_env.vector import VRLocoVectorEnv

    env = VRLocoVectorEnv(args.num_envs, **env_settings(args.task))
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (args.steps + 20, args.num_envs, 5)).astype(np.float32)
    for a in actions[:20]:
        env.step(a)
    profile = cProfile.Profile()
    profile.enable()
    for a in actions[20:]:
        env.step(a)
    profile.disable()
    stats = pstats.Stats(profile)
    total = stats.total_tt
    rows = sorted(stats.stats.items(), key=lambda kv: kv[1][2], reverse=True)[: args.top]
    print(
        f"{args.task}, {args.num_envs} users: {args.steps} steps in {total:.2f} s "
        f"({args.steps * args.num_envs / total:,.0f} user-steps/s under the profiler)"
    )
    for (file, line, name), (_, _, own, _, _) in rows:
        print(f"  {own / total:6.1%}  {name}  ({_where(file, line)})")
    shown = sum(own for _, (_, _, own, _, _) in rows)
    print(f"  {1 - shown / total:6.1%}  the other {len(stats.stats) - len(rows)} functions")


if __name__ == "__main__":
    main()

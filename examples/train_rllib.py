"""Your own RLlib script on vrloco: PPO on the Approach task with two env runners.

    pip install 'vrloco[rllib]'
    python examples/train_rllib.py --iterations 4        # four training iterations, printed

``register_rllib_env()`` registers vrloco's env creator with RLlib (``register_env``) and
``ppo_config(...)`` returns an ordinary ``PPOConfig`` on it, to change as any RLlib config: each
env runner steps one batched :class:`~vrloco_env.vector.VRLocoVectorEnv` of
``num_envs_per_env_runner`` users, seeded from the run's seed, its runner and the user's row, so
that the same seed repeats the run. ``vrloco train --backend rllib`` is this loop with
evaluations, checkpoints and the learning curve (:func:`agents.learned.rllib.train_rllib`).
"""

from __future__ import annotations

import argparse
import logging

import ray

from agents.learned.rllib import ppo_config, register_rllib_env


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=4, help="PPO training iterations")
    parser.add_argument("--env-runners", type=int, default=2, help="RLlib env runners")
    parser.add_argument("--num-envs", type=int, default=8, help="users in each runner's env")
    parser.add_argument("--seed", type=int, default=0, help="the run's seed")
    args = parser.parse_args()

    ray.init(include_dashboard=False, logging_level=logging.WARNING)
    register_rllib_env()
    config = ppo_config(
        "approach",
        num_env_runners=args.env_runners,
        num_envs_per_env_runner=args.num_envs,
        seed=args.seed,
        rollout_fragment_length=256,
    )
    algo = config.build_algo()
    try:
        for i in range(args.iterations):
            result = algo.train()
            runners = result["env_runners"]
            episodes = int(runners.get("num_episodes_lifetime", 0))
            mean = runners.get("episode_return_mean", float("nan"))  # none yet: nan
            print(
                f"iteration {i + 1}: {int(runners['num_env_steps_sampled_lifetime']):,} steps, "
                f"{episodes} episodes finished, mean return {mean:.2f}"
            )
    finally:
        algo.stop()
        ray.shutdown()


if __name__ == "__main__":
    main()

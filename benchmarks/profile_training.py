"""Where a whole training run's time goes: rooms, the env's steps, the update, the evaluations.

Run from the repository root::

    python benchmarks/profile_training.py                      # PPO from scratch on Approach
    python benchmarks/profile_training.py --init agents/learned/users/approach.zip --frame-stack 4

Runs :func:`agents.learned.train.train_ppo` for ``--steps`` environment steps (its
checkpoints, evaluations and learning curve in a temporary folder) and prints its steps per
second and the shares of its wall time spent drawing rooms (each user's reset draws a new one:
:meth:`Task.draw <vrloco_env.tasks.base.Task.draw>`), in the rest of the training users' env
steps, in the evaluations (:func:`~agents.learned.evaluate.run_policy_episodes`), in the PPO
update and elsewhere (the policy's forward pass, SB3's bookkeeping, start-up). A user that
reaches its goal quickly resets often, so a run that goes on from a trained user (``--init``)
draws far more rooms per step than the first iterations of one from scratch, which
``benchmarks/bench_training.py`` times.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import agents.learned.evaluate as evaluate  # first: the trainer's thread settings
import agents.learned.train as train

# isort: split
from bench_training import timed  # this script's folder
from stable_baselines3 import PPO

from vrloco_env.tasks.base import Task


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", default="approach")
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--init", type=Path, help="go on training this model (vrloco train's)")
    parser.add_argument("--frame-stack", type=int, default=1, help="as the model was trained")
    parser.add_argument("--num-envs", type=int, default=32, help="users stepped together")
    parser.add_argument(
        "--rollout-steps", type=int, help="each user's steps per rollout (default: PPO's 256)"
    )
    parser.add_argument("--eval-every", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    spent = dict.fromkeys(("rooms", "eval_rooms", "env", "eval", "update"), 0.0)
    in_eval = [False]
    draw = Task.draw

    def drawn(self, *a, **k):  # a room: the training users' or an evaluation's
        t0 = time.perf_counter()
        try:
            return draw(self, *a, **k)
        finally:
            spent["eval_rooms" if in_eval[0] else "rooms"] += time.perf_counter() - t0

    def evaluated(*a, **k):
        in_eval[0] = True
        try:
            return run_episodes(*a, **k)
        finally:
            in_eval[0] = False

    run_episodes = evaluate.run_policy_episodes
    Task.draw = drawn
    train.run_policy_episodes = evaluated
    timed(train, "run_policy_episodes", spent, "eval")
    timed(train.SB3VecEnv, "step_wait", spent, "env")
    timed(PPO, "train", spent, "update")
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        train.train_ppo(
            args.task,
            steps=args.steps,
            seed=args.seed,
            out_dir=Path(out),
            eval_every=args.eval_every,
            progress=False,
            init=args.init,
            frame_stack=args.frame_stack,
            num_envs=args.num_envs,
            **({} if args.rollout_steps is None else {"n_steps": args.rollout_steps}),
        )
        wall = time.perf_counter() - t0
        steps = json.loads((Path(out) / "learning_curve.json").read_text())[-1]["steps"]
    env = spent["env"] - spent["rooms"]  # the training users' rooms are drawn in their steps
    other = wall - spent["env"] - spent["eval"] - spent["update"]
    print(f"{steps:,} steps in {wall:.1f} s: {steps / wall:,.0f} steps/s")
    for name, s in (
        ("rooms of the training users' resets", spent["rooms"]),
        ("the training users' env steps, rooms apart", env),
        ("evaluations (their rooms included)", spent["eval"]),
        ("PPO update", spent["update"]),
        ("elsewhere (forward pass, start-up)", other),
    ):
        print(f"  {name:44s} {s:7.1f} s  {s / wall:5.1%}")


if __name__ == "__main__":
    main()

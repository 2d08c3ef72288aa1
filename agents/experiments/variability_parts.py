"""Which part of a user population costs a user its episodes: the head's behaviour, or one part of
the agent-side variability.

A ``+population`` user of the benchmark (``goal_seeker+nodders``, :mod:`agents.benchmark.policies`)
differs from the idealised user in two ways: the env moves its head as the population does (gaze,
nods, drift: :mod:`vrloco_env.user.behaviour`), and
:class:`~agents.benchmark.variability.HumanVariability` wraps the policy with the population's
reaction delay, turn overshoot and cadence variation. This experiment plays the same rooms with
each of those on its own, the rest as the idealised user has them:

* ``idealised``: neither (the plain policy, the head straight on the torso);
* ``head``: the population's head behaviour in the env, no variability;
* ``delay``, ``overshoot``, ``cadence``: that part of the population's variability alone (the
  other parts' means and spreads set to zero), the head straight;
* ``variability``: the three parts together, the head straight;
* ``population``: the head and the variability, the benchmark's ``POLICY+POPULATION`` user.

Episode ``i`` of every condition is a single env reset with ``seed + i`` (the same room, start
and goal in every condition) and the policy's randomness from ``default_rng([seed + i, 1])``, as
:func:`agents.benchmark.episodes.run_episode` plays it; the default technique. The variability's
conditions draw the same numbers as the population's
(:class:`~agents.benchmark.variability.HumanVariability` draws a fixed count per user and step
whatever the spreads), so among them only what is switched on differs; a moving head draws from
the env's own stream as well, so with it the sensors' noise is other numbers than the idealised
user's.

For each condition: collision-free success, success, the episodes with a collision, and what
each colliding episode first walked into (a wall, an obstacle, the task's target:
:func:`agents.experiments.collision_sight.solid_walked_into`).

Run: ``python -m agents.experiments.variability_parts --task reach --population nodders
--episodes 100 --seed 2000 [--policy goal_seeker]``.
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

import numpy as np

__all__ = ["CONDITIONS", "PARTS", "condition_params", "variability_parts"]

#: The agent-side variability's parts: the VariabilityParams fields each one sets.
PARTS = {
    "delay": ("reaction_delay_s", "reaction_delay_sd_s"),
    "overshoot": ("overshoot", "overshoot_sd"),
    "cadence": ("cadence_bias_sd", "cadence_jitter_sd"),
}
#: The conditions, in the order they are played and reported.
CONDITIONS = ("idealised", "head", *PARTS, "variability", "population")


def condition_params(population: str, condition: str) -> tuple[bool, Any]:
    """Whether ``condition`` moves the head as ``population`` does, and the agent-side
    variability it wraps the policy with (a
    :class:`~agents.benchmark.variability.VariabilityParams`, or None for none).

    Raises:
        ValueError: an unknown condition (listing them) or population.
    """
    from agents.benchmark.variability import VariabilityParams
    from vrloco_env.user.population import get_population

    if condition not in CONDITIONS:
        raise ValueError(f"condition={condition!r}: choose from {', '.join(CONDITIONS)}")
    get_population(population)  # an unknown name is an error listing the registered ones
    full = VariabilityParams.from_population(population)
    if condition in ("idealised", "head"):
        return condition == "head", None
    if condition in ("variability", "population"):
        return condition == "population", full
    off = {f: 0.0 for part in PARTS.values() for f in part}
    on = {f: getattr(full, f) for f in PARTS[condition]}
    return False, dataclasses.replace(full, **{**off, **on})


def _play(task: str, population: str, condition: str, policy: str, episodes: int, seed: int):
    import gymnasium as gym

    import vrloco_env  # noqa: F401  (registers the ids)
    from agents.benchmark.policies import build_policy
    from agents.benchmark.variability import HumanVariability
    from agents.experiments.collision_sight import solid_kinds, solid_walked_into
    from vrloco_env.tasks import env_id

    head, params = condition_params(population, condition)
    env = gym.make(env_id(task), population=population if head else None)
    user = build_policy(policy, env)
    if params is not None:
        user = HumanVariability(user, params, population=f"{population}_{condition}")
    core = env.unwrapped.core
    step_m = float(env.unwrapped.estimators.step_length)
    first = {"wall": 0, "obstacle": 0, "target": 0}
    success = free = colliding = 0
    for i in range(episodes):
        obs, _ = env.reset(seed=seed + i)
        user.reset(np.random.default_rng([seed + i, 1]))
        layout = core.layouts[0]
        hit = False
        while True:
            before = core.ep.position[0].copy()
            obs, _, terminated, truncated, info = env.step(user.act(obs))
            if info["collision"] and not hit:
                k = solid_walked_into(layout.solids, before, float(info["walk_yaw_deg"]), step_m)
                first[solid_kinds(layout)[k]] += 1
                hit = True
            if terminated or truncated:
                break
        done = bool(info["is_success"])
        success += done
        free += done and not hit
        colliding += hit
    env.close()
    return {
        "collision_free_success": free,
        "success": success,
        "episodes_colliding": colliding,
        "first_walked_into": first,
    }


def variability_parts(
    task: str,
    population: str,
    episodes: int,
    seed: int,
    policy: str = "goal_seeker",
    conditions: tuple[str, ...] = CONDITIONS,
) -> dict[str, Any]:
    """Play ``policy`` (a benchmark policy spec without a ``+population``) on ``episodes``
    episodes from ``seed`` under each of ``conditions`` (module docstring): ``{"task",
    "population", "policy", "episodes", "seeds", "conditions": {condition: {...}}}``, each
    condition's counts of episodes ``collision_free_success``, ``success``,
    ``episodes_colliding`` and ``first_walked_into`` (``{"wall", "obstacle", "target"}``).

    Raises:
        ValueError: ``episodes`` below 1, a policy spec with a population, an unknown condition
            or population.
    """
    if episodes < 1:
        raise ValueError(f"episodes={episodes}: must be >= 1")
    if "+" in policy:
        raise ValueError(
            f"policy={policy!r}: give the policy alone; the conditions add the population"
        )
    for c in conditions:
        condition_params(population, c)  # every name checked before anything is played
    return {
        "task": task,
        "population": population,
        "policy": policy,
        "episodes": episodes,
        "seeds": [seed, seed + episodes - 1],
        "conditions": {c: _play(task, population, c, policy, episodes, seed) for c in conditions},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", default="reach")
    parser.add_argument("--population", default="nodders")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=2000)
    parser.add_argument("--policy", default="goal_seeker", help="the user, without +POPULATION")
    parser.add_argument(
        "--conditions", default=",".join(CONDITIONS), help="comma-separated, of: %(default)s"
    )
    args = parser.parse_args(argv)
    try:
        r = variability_parts(
            args.task,
            args.population,
            args.episodes,
            args.seed,
            args.policy,
            tuple(args.conditions.split(",")),
        )
    except ValueError as err:
        parser.error(str(err))
    print(
        f"{r['task']}, {r['policy']}, {r['population']}'s parts, seeds "
        f"{r['seeds'][0]}-{r['seeds'][1]} ({r['episodes']} episodes each):"
    )
    head = ("condition", "no collision", "success", "colliding")
    print(f"  {head[0]:12s} {head[1]:>12s} {head[2]:>8s} {head[3]:>9s}  first walked into")
    for name, c in r["conditions"].items():
        into = ", ".join(f"{k} {n}" for k, n in c["first_walked_into"].items())
        print(
            f"  {name:12s} {c['collision_free_success']:12d} {c['success']:8d} "
            f"{c['episodes_colliding']:9d}  {into}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Did the user see what it walked into? Each collision of a user's episodes, put down to when
the user's rays last showed the solid it walked into.

The user perceives the room through the observation's rays (a fan of ``ray_count`` rays over
``ray_fov_deg`` from the virtual head, :mod:`vrloco_env.observation`): an obstacle may lie between
two rays, outside the fan, or have been seen a while ago and not since. A user who remembers what
it has seen (the goal seeker keeps a map of every ray hit) can avoid what its rays no longer
show; a user who acts on the last few observations (a learned user with a frame stack) cannot.

Each episode is played as the benchmark plays it (:func:`agents.benchmark.episodes.run_episode`'s
seeding: episode ``i`` is a single env reset with ``seed + i``, the default technique, the env's
head straight on the torso; a ``+population`` suffix of the policy spec adds that population's
agent-side variability only). A *collision* is a run of consecutive blocked steps
(``info["collision"]``), counted once, at its first step ``k``. The solid walked into is the one
of the room's solids (walls, obstacles, the pedestal) nearest to the stretch of a step the body
was about to walk (the estimators' ``step_length`` along ``info["walk_yaw_deg"]`` from its
position). A ray *showed* that solid where its hit point, placed in the room from the true
virtual pose the ray was cast from, lies within ``touch_m`` of it. The collision is then:

* ``last_frame``: shown in the observation the user acted on (the one before step ``k``);
* ``in_memory``: not there, but in another of the last ``frames`` observations (what a
  ``frames``-frame stack holds);
* ``seen_before``: only in observations older than that (a map of the hits would hold it);
* ``never_seen``: by no ray of the episode before step ``k`` (between the rays, or outside the
  fan, all along).

Each collision is also counted by what was walked into (a wall, an obstacle, the task's target,
:attr:`~vrloco_env.world.layout.Layout.solids`), and each colliding episode's first collision on
its own (``first``: the one that cost the episode its collision-free success).

Run: ``python -m agents.experiments.collision_sight --task approach --episodes 200 --seed 1000
[--policy SPEC] [--frames 4]``.
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

__all__ = ["SIGHT", "collision_sight", "ray_hits", "solid_kinds", "solid_walked_into"]

#: The classes of a collision, from the most recently seen to the never seen.
SIGHT = ("last_frame", "in_memory", "seen_before", "never_seen")


def _solid_distances(solids: tuple, points: np.ndarray) -> np.ndarray:
    """Signed distances (S, P) from ``points`` (P, 2) to each solid on its own."""
    from vrloco_env.world.geometry import solid_distance

    return np.stack([solid_distance((s,), points) for s in solids])


def solid_kinds(layout: Any) -> list[str]:
    """What each of ``layout.solids`` is, in their order: ``"wall"``, ``"obstacle"`` or
    ``"target"`` (:attr:`~vrloco_env.world.layout.Layout.solids`)."""
    kinds = ["wall"] * len(layout.walls) + ["obstacle"] * len(layout.obstacles)
    return kinds + ["target"] * (len(layout.solids) - len(kinds))


def solid_walked_into(solids: tuple, before: np.ndarray, walk_yaw_deg: float, step_m: float) -> int:
    """The index of the solid nearest to the stretch of a step the body was about to walk: a
    step length ``step_m`` along ``walk_yaw_deg`` (the room's yaw, deg) from ``before`` (2,),
    where the body stood."""
    yaw = np.deg2rad(walk_yaw_deg)
    way = before + np.linspace(0.0, step_m, 8)[:, None] * [np.cos(yaw), np.sin(yaw)]
    return int(_solid_distances(solids, way).min(axis=1).argmin())


def ray_hits(env: Any, obs: np.ndarray) -> np.ndarray:
    """The room points (H, 2) (m) the rays of ``obs`` hit, for a single env whose state ``obs``
    was just observed from: each ray's range along the virtual heading plus its offset, from the
    virtual body's position (the pose the env casts its rays from). Rays that saw nothing (the
    full range) give no point."""
    from agents.scripted.observation import ray_points

    u = env.unwrapped
    rays = u.observation_spec.decode(obs)["rays"].astype(np.float64)
    yaw = float(u.core.ep.virtual_yaw[0])
    # given each ray's direction in the room (heading plus offset), ray_points places its hit
    # relative to the body in the room's axes
    pts, hit = ray_points(rays[None], yaw + u.core.ray_offsets, float(u.config.ray_range_m))
    return u.core.ep.position[0] + pts[0][hit[0]]


def _shown(env: Any, obs: np.ndarray, solids: tuple, touch_m: float) -> np.ndarray:
    """Which of ``solids`` (S,) a ray of ``obs`` hit (its hit point within ``touch_m``)."""
    pts = ray_hits(env, obs)
    if not pts.size:
        return np.zeros(len(solids), bool)
    return (np.abs(_solid_distances(solids, pts)) <= touch_m).any(axis=1)


def collision_sight(
    task: str,
    episodes: int,
    seed: int,
    policy: str = "goal_seeker",
    frames: int = 4,
    touch_m: float = 0.02,
) -> dict[str, Any]:
    """The collisions of ``policy`` (a benchmark policy spec) on ``episodes`` episodes from
    ``seed``, split by when its rays last showed what it walked into (module docstring):
    ``{"task", "policy", "episodes", "seeds", "frames", "episodes_colliding", "collisions",
    "blocked_steps", "sight": {class: count}, "first": {class: count}, "walked_into": {"wall",
    "obstacle", "target": count}}``.

    Raises:
        ValueError: ``episodes`` or ``frames`` below 1, or ``touch_m`` not positive.
    """
    import gymnasium as gym

    import vrloco_env  # noqa: F401  (registers the ids)
    from agents.benchmark.policies import build_policy
    from vrloco_env.tasks import env_id

    if episodes < 1:
        raise ValueError(f"episodes={episodes}: must be >= 1")
    if frames < 1:
        raise ValueError(f"frames={frames}: must be >= 1")
    if not touch_m > 0.0:
        raise ValueError(f"touch_m={touch_m}: must be > 0 (m)")
    env = gym.make(env_id(task))
    user = build_policy(policy, env)
    core = env.unwrapped.core
    step_m = float(env.unwrapped.estimators.step_length)
    sight, first = dict.fromkeys(SIGHT, 0), dict.fromkeys(SIGHT, 0)
    walked_into = dict.fromkeys(("wall", "obstacle", "target"), 0)
    colliding = blocked_steps = 0
    for i in range(episodes):
        obs, info = env.reset(seed=seed + i)
        user.reset(np.random.default_rng([seed + i, 1]))
        layout = core.layouts[0]
        solids, kinds = layout.solids, solid_kinds(layout)
        # per observation, oldest first: which solids its rays showed, (S,)
        shown = [_shown(env, obs, solids, touch_m)]
        was_blocked, any_hit = False, False
        while True:
            before = core.ep.position[0].copy()
            obs, _, terminated, truncated, info = env.step(user.act(obs))
            hit = bool(info["collision"])
            blocked_steps += hit
            if hit and not was_blocked:  # a new collision: what did the user see of it?
                target = solid_walked_into(solids, before, float(info["walk_yaw_deg"]), step_m)
                walked_into[kinds[target]] += 1
                seen = np.asarray([s[target] for s in shown])  # oldest observation first
                if seen[-1]:
                    kind = "last_frame"
                elif seen[-frames:].any():
                    kind = "in_memory"
                elif seen.any():
                    kind = "seen_before"
                else:
                    kind = "never_seen"
                sight[kind] += 1
                first[kind] += not any_hit
                any_hit = True
            was_blocked = hit
            shown.append(_shown(env, obs, solids, touch_m))
            if terminated or truncated:
                break
        colliding += any_hit
    env.close()
    return {
        "task": task,
        "policy": policy,
        "episodes": episodes,
        "seeds": [seed, seed + episodes - 1],
        "frames": frames,
        "episodes_colliding": colliding,
        "collisions": sum(sight.values()),
        "blocked_steps": int(blocked_steps),
        "sight": sight,
        "first": first,
        "walked_into": walked_into,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", default="approach")
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--policy", default="goal_seeker", help="the user (a policy spec)")
    parser.add_argument("--frames", type=int, default=4, help="the observations a stack holds")
    args = parser.parse_args(argv)
    try:
        r = collision_sight(args.task, args.episodes, args.seed, args.policy, args.frames)
    except ValueError as err:
        parser.error(str(err))
    print(
        f"{r['task']}, {r['policy']}, seeds {r['seeds'][0]}-{r['seeds'][1]}: "
        f"{r['collisions']} collisions ({r['blocked_steps']} blocked steps) in "
        f"{r['episodes_colliding']} of {r['episodes']} episodes, into "
        + ", ".join(f"{k} {n}" for k, n in r["walked_into"].items())
    )
    for name, split in (("every collision", r["sight"]), ("each episode's first", r["first"])):
        print(
            f"  {name}: what was walked into was shown by the rays in the last observation: "
            f"{split['last_frame']}, in another of the last {r['frames']}: {split['in_memory']}, "
            f"only earlier: {split['seen_before']}, never: {split['never_seen']}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Why the hand tasks fail: a user's episodes of Interact or Reach split by how well the
Kinect pipeline tracked the user's hand while the user stood at the goal.

Each episode is played as the benchmark plays it (:func:`agents.benchmark.episodes.run_episode`'s
seeding: episode ``i`` is a single env reset with ``seed + i``, the user idealised, the default
technique; the goal seeker unless another policy spec is given). While the user stands in the
goal region, each step's ``hand_error_deg`` (the angle between the pipeline's hand estimate and
the true hand) is kept; an episode is
*mistracked* where its median exceeds ``flip_deg``: the estimate is not the user's hand (the
tracker expects people to face it, :mod:`vrloco_env.sensors.kinect`; a user turned away is lost
and the pipeline follows whom it sees). The hand hold is measured on the estimate, so a
mistracked episode succeeds only by chance, or where the user is found again: *recovered*
counts the mistracked episodes whose last ``last_steps`` steps at the goal (the hold's end) have
a median error within ``flip_deg``, the estimate the user's own hand again, and
*turned_mistracked_deg* is how far the body turned while at the goal in those episodes (the
median over them of the summed absolute yaw changes). An episode that never reaches the goal
region is *short* where its nearest approach was within ``short_m`` of it: the user stopped
just short, where a walked step would carry it past.

Run: ``python -m agents.experiments.hand_tracking_ceiling --task reach --episodes 100 --seed 1000
[--policy SPEC]``.
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

__all__ = ["hand_tracking_split"]


def hand_tracking_split(
    task: str,
    episodes: int,
    seed: int,
    flip_deg: float = 90.0,
    policy: str = "goal_seeker",
    last_steps: int = 10,
    short_m: float = 0.15,
) -> dict[str, Any]:
    """The split (module docstring) for the user ``policy`` (a benchmark policy spec):
    ``{"episodes", "at_goal", "mistracked", "recovered", "turned_mistracked_deg", "success",
    "success_tracked", "success_mistracked", "short", "short_m", "median_error_deg",
    "nearest_m"}``
    (counts, and per episode the median tracking error at the goal, NaN where it never stood
    there, and the nearest approach to the goal region, 0 where it stood in it)."""
    import gymnasium as gym

    import vrloco_env  # noqa: F401  (registers the ids)
    from agents.benchmark.policies import build_policy
    from estimators.rotations import wrap_angle
    from vrloco_env.tasks import env_id

    env = gym.make(env_id(task))
    user = build_policy(policy, env)
    medians, ends, wins, turned, nearest = [], [], [], [], []
    for i in range(episodes):
        obs, info = env.reset(seed=seed + i)
        user.reset(np.random.default_rng([seed + i, 1]))
        at_goal: list[float] = []
        yaw: list[float] = []  # the body's true yaw at the goal (deg)
        closest = np.inf
        while True:
            obs, _, terminated, truncated, info = env.step(user.act(obs))
            closest = min(closest, max(float(info["distance_to_goal"]), 0.0))
            if info["distance_to_goal"] <= 0.0:
                at_goal.append(float(info["hand_error_deg"]))
                yaw.append(float(info["true_body_yaw_deg"]))
            if terminated or truncated:
                break
        errors = np.asarray(at_goal)
        errors = errors[np.isfinite(errors)]
        medians.append(float(np.median(errors)) if errors.size else np.nan)
        last = np.asarray(at_goal[-last_steps:])
        last = last[np.isfinite(last)]
        ends.append(float(np.median(last)) if last.size else np.nan)
        wins.append(bool(info["is_success"]))
        nearest.append(closest)
        turns = wrap_angle(np.deg2rad(np.diff(np.asarray(yaw))))
        turned.append(float(np.rad2deg(np.abs(turns).sum())))
    env.close()
    med, won, closest_m = np.asarray(medians), np.asarray(wins), np.asarray(nearest)
    stood = closest_m == 0.0  # stood in the goal region at some step
    flipped = np.isfinite(med) & (med > flip_deg)
    found = flipped & (np.asarray(ends) <= flip_deg)  # NaN compares False
    return {
        "task": task,
        "policy": policy,
        "episodes": episodes,
        "seeds": [seed, seed + episodes - 1],
        "at_goal": int(stood.sum()),
        "mistracked": int(flipped.sum()),
        "recovered": int(found.sum()),
        "turned_mistracked_deg": round(float(np.median(np.asarray(turned)[flipped])), 1)
        if flipped.any()
        else None,
        "success": int(won.sum()),
        "success_tracked": int((won & ~flipped).sum()),
        "success_mistracked": int((won & flipped).sum()),
        "short": int((~stood & (closest_m <= short_m)).sum()),
        "short_m": short_m,
        "median_error_deg": [round(m, 1) for m in medians],
        "nearest_m": [round(d, 3) for d in nearest],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", default="reach", choices=("reach", "interact"))
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--policy", default="goal_seeker", help="the user (a policy spec)")
    args = parser.parse_args(argv)
    r = hand_tracking_split(args.task, args.episodes, args.seed, policy=args.policy)
    tracked = r["episodes"] - r["mistracked"]
    print(
        f"{r['task']}, {r['policy']}, seeds {r['seeds'][0]}-{r['seeds'][1]}: at the goal in "
        f"{r['at_goal']} of {r['episodes']} episodes ({r['short']} of the others stopped within "
        f"{r['short_m']:g} m of it); hand mistracked there (median error > 90 "
        f"deg) in {r['mistracked']}, found again by the end in {r['recovered']}, the body "
        f"turning {r['turned_mistracked_deg']} deg there (median); success "
        f"{r['success']}: {r['success_tracked']} of "
        f"{tracked} tracked, {r['success_mistracked']} of {r['mistracked']} mistracked"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Plug your own task into vrloco: turn round, pass a pillar and reach the goal behind you.

    python examples/custom_task.py       # one goal_seeker episode of the task
    python examples/custom_task.py benchmark --tasks turn_around --techniques zhang2021 \\
        --episodes 4 --out out/custom_task

A task is a :class:`~vrloco_env.tasks.base.Task` subclass (the protocol is documented there): its
``draw_layout(room, rng)`` draws one episode's room from the episode's generator, with the
blocks of :mod:`vrloco_env.world`; the base class takes the goal disc from the layout and ends
the episode when the virtual body enters it. ``collision_free_success = True`` makes success
need an episode without a single collision. An optional frozen dataclass, ``Config``, holds
the task's own settings: ``gym.make(..., task_config=get_task("turn_around").Config(
corridor_length=12.0))`` (the class of the module the registry imported).

Tasks are taken by registered name only, not by file path (``vrloco benchmark --tasks
examples/custom_task.py:TurnAround`` is refused with the list of registered names). One
:func:`~vrloco_env.tasks.register_task` line registers it, by its ``"path/file.py:attr"`` (or
``"package.module:attr"``), imported when first used::

    import gymnasium as gym

    import vrloco_env  # noqa: F401  (registers the built-in ids)
    from agents.benchmark import run_benchmark
    from vrloco_env.tasks import register_task

    register_task("turn_around", "examples/custom_task.py:TurnAround")
    env = gym.make("VRLoco-TurnAround-v0")  # gym.make_vec too
    run_benchmark(tasks=["turn_around"], policies=["goal_seeker"], techniques=["zhang2021"],
                  episodes=4, out_dir="out/custom_task")

The ``vrloco`` command cannot register it, so run this file instead, with the same arguments:
it registers the task, then hands its arguments to ``vrloco`` (``agents.cli.main``). The
benchmark's worker processes need the registration too: forked workers inherit it, and spawned
ones (macOS, Windows) run the main script's top level again, where this file registers it (a
script of your own keeps its ``register_task`` line at its top level for the same reason).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vrloco_env.tasks.base import Task
from vrloco_env.world import Cylinder, Layout, RoomConfig, check_rng, finish_layout, no_layout_error


@dataclass(frozen=True)
class TurnAroundConfig:
    """The corridor and its pillar.

    Attributes:
        corridor_length: interior length along x (m).
        corridor_width: interior width along y (m).
        margin: distance from each end wall to the start and to the goal point (m).
        pillar_radius_range: the pillar's radius is drawn in this range (m).
        pillar_lateral_jitter: the pillar's centre is drawn within +- this of the centre line
            (m), less than the smallest radius, so it always blocks the straight way.
    """

    corridor_length: float = 9.0
    corridor_width: float = 2.4
    margin: float = 1.0
    pillar_radius_range: tuple[float, float] = (0.2, 0.4)
    pillar_lateral_jitter: float = 0.15

    def __post_init__(self) -> None:
        lo, hi = self.pillar_radius_range
        if not 0.0 < lo <= hi:
            raise ValueError(f"pillar_radius_range={self.pillar_radius_range}: need 0 < lo <= hi")
        if not 0.0 <= self.pillar_lateral_jitter < lo:
            raise ValueError(
                f"pillar_lateral_jitter={self.pillar_lateral_jitter}: must be in "
                f"[0, pillar_radius_range[0] = {lo})"
            )
        if not 0.0 < 2.0 * self.margin + 2.0 * hi < self.corridor_length:
            raise ValueError("corridor_length must exceed 2 * margin + the pillar's diameter")


class TurnAround(Task):
    """Start facing the near end wall of a corridor; the goal disc is behind, at the far end, and
    a floor-to-ceiling pillar stands on the straight way to it (success: inside the goal disc
    without a single collision)."""

    name = "turn_around"
    description = "turn round, pass the pillar and reach the goal behind you, collision-free"
    Config = TurnAroundConfig
    collision_free_success = True
    per_user_fields = Task.per_user_fields  # no per-user state of its own beyond the goal disc

    def draw_layout(self, room: RoomConfig, rng: np.random.Generator) -> Layout:
        return turn_around_layout(room, rng, self.config)


def turn_around_layout(
    room: RoomConfig, rng: np.random.Generator, task: TurnAroundConfig | None = None
) -> Layout:
    """A TurnAround corridor: interior ``corridor_length`` along x by ``corridor_width``,
    centred on the origin. The start is ``margin`` from the +x end wall, facing it (yaw 0); the
    goal point ``margin`` from the -x end wall, on the centre line, with ``room.goal_radius``.
    The pillar's centre is in the middle third between them.

    Raises:
        RuntimeError: no layout with a collision-free way to the goal in ``room.max_attempts``
            draws (a corridor too narrow for the avatar to pass the pillar).
    """
    cfg, rng = room, check_rng(rng)
    t = TurnAroundConfig() if task is None else task
    half_l, half_w = t.corridor_length / 2.0, t.corridor_width / 2.0
    bounds = (-half_l, half_l, -half_w, half_w)
    start = np.array([half_l - t.margin, 0.0])
    goal = np.array([-half_l + t.margin, 0.0])
    third = (start[0] - goal[0]) / 3.0
    for _ in range(cfg.max_attempts):
        x = float(rng.uniform(goal[0] + third, start[0] - third))  # the middle third of the way
        y = float(rng.uniform(-1.0, 1.0)) * t.pillar_lateral_jitter
        pillar = Cylinder((x, y), float(rng.uniform(*t.pillar_radius_range)), cfg.wall_height)
        layout = finish_layout(cfg, TurnAround.name, bounds, [pillar], start, 0.0, goal, None, None)
        if layout is not None:
            return layout
    raise no_layout_error(cfg, TurnAround.name)


if __name__ in ("__main__", "__mp_main__"):  # run as a script, or a benchmark worker spawned by it
    from vrloco_env.tasks import register_task

    register_task(TurnAround.name, TurnAround)

if __name__ == "__main__":
    import sys

    if len(sys.argv) > 1:  # `vrloco ...` with the task registered
        from agents.cli import main

        sys.exit(main(sys.argv[1:]))

    import gymnasium as gym

    from agents.benchmark.policies import build_policy

    env = gym.make("VRLoco-TurnAround-v0")
    policy = build_policy("goal_seeker", env)
    obs, info = env.reset(seed=0)
    policy.reset()
    start = info["position"]
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        done = terminated or truncated
    print(
        f"TurnAround, goal_seeker: success {bool(info['is_success'])}, "
        f"{info['elapsed_time']:.1f} s, {info['collisions']} collisions"
    )
    print(
        f"  from {np.round(start, 2)} to {np.round(info['position'], 2)}, goal "
        f"{np.round(env.unwrapped.core.task.goal[0], 2)}"
    )
    env.close()

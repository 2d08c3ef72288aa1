"""Ship a trained model as the learned user of its task: the model, its card and its curve in
:mod:`agents.learned.users`, with the held-out evaluation beside the goal seeker's.

Run from the repository root::

    python -m agents.learned.users.ship MODEL.zip --command "vrloco train ..." [--episodes 100]

The model's task comes from the model. The held-out evaluation is the benchmark on seeds
:data:`HELD_OUT_SEED` onwards, or on a later block never used before (``--seed S``, S >=
:data:`HELD_OUT_SEED`; never a training or development seed: training evaluates on seeds 10000 +
its seed, development on :data:`DEV_SEED` onwards), the default technique, the learned user
(the shipped file, what ``ppo`` plays once registered) and the goal seeker, idealised and with
every population of :data:`POPULATIONS`;
the card records that command and, per user and population, the success rate and the collision-free
success rate with their 95 % Wilson intervals, and whether the bar holds: collision-free success >=
:data:`BAR` for the idealised user, and at least the goal seeker's (its point estimate) under every
population. A model that misses a bar is still written (the card says which); register it in
``agents/learned/users/__init__.py`` where the idealised bar holds, or where the task cannot reach
it (then with the limit and the command that shows it, :attr:`LearnedUser.limit
<agents.learned.users.LearnedUser.limit>`), and say in its registry line how it does."""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path
from typing import Any

from agents.benchmark.cell_statistics import wilson_interval
from agents.learned.users import HERE

__all__ = ["BAR", "DEV_SEED", "HELD_OUT_SEED", "POPULATIONS", "held_out_rows", "ship"]

#: First held-out seed of the evaluation.
HELD_OUT_SEED = 100_000
#: First development seed (``--dev``: comparing candidates before one is shipped).
DEV_SEED = 1_000
#: The populations the learned user is compared under (beside the idealised user).
POPULATIONS = ("typical", "nodders", "gaze_scanners")
#: Collision-free success the idealised learned user must reach.
BAR = 0.95


def held_out_rows(
    task: str, model: Path, episodes: int, seed: int = HELD_OUT_SEED, shown_as: str = "ppo"
) -> tuple[str, list[dict[str, Any]]]:
    """The benchmark command and its rows: the learned user ``model`` (``user`` "ppo") and the
    goal seeker on ``task``, idealised and under every population, on ``episodes`` seeds from
    ``seed`` (held-out by default; a development seed to choose between candidates)."""
    from agents.benchmark import run_benchmark

    policies = [str(model), "goal_seeker"]
    for pop in POPULATIONS:
        policies += [f"{model}+{pop}", f"goal_seeker+{pop}"]
    rows = run_benchmark(
        tasks=[task],
        techniques=["zhang2021"],
        policies=policies,
        episodes=episodes,
        seed=seed,
        progress=False,
        print_table=False,
    )
    out_rows = []
    for r in rows:
        n = int(r.get("episodes", episodes))
        base, sep, pop = r["policy"].rpartition("+")
        if not sep or not pop.isidentifier():
            base, pop = r["policy"], ""
        user = "goal_seeker" if base == "goal_seeker" else "ppo"
        out_rows.append(
            {
                "user": user,
                "population": pop or "idealised",
                "episodes": n,
                "success_rate": r["success_rate"],
                "success_ci": list(wilson_interval(round(r["success_rate"] * n), n)),
                "collision_free_success_rate": r["collision_free_success_rate"],
                "collision_free_ci": list(
                    wilson_interval(round(r["collision_free_success_rate"] * n), n)
                ),
            }
        )
    shown = ",".join(p.replace(str(model), shown_as) for p in policies)
    command = (
        f"vrloco benchmark --tasks {task} --techniques zhang2021 --policies {shown} "
        f"--episodes {episodes} --seed {seed}"
    )
    return command, out_rows


def ship(
    model: Path,
    command: str,
    episodes: int = 100,
    choices: str = "",
    name: str | None = None,
    seed: int = HELD_OUT_SEED,
) -> Path:
    """Copy ``model`` (and its folder's learning curve) into :mod:`agents.learned.users` as its
    task's user (``name``: under that name instead, e.g. a second user of the task), evaluate it
    on the held-out seeds from ``seed`` and write its card; returns the card's path."""
    from agents.benchmark.policies import load_ppo

    if seed < HELD_OUT_SEED:
        raise ValueError(
            f"seed={seed}: held-out seeds start at {HELD_OUT_SEED} (lower ones are training "
            "and development seeds)"
        )

    trained = load_ppo(model)
    task = trained.vrloco_env["task"]
    name = task if name is None else name
    if not name.isidentifier():
        raise ValueError(f"name={name!r}: a file name of letters, digits and underscores")
    target = HERE / f"{name}.zip"
    shutil.copyfile(model, target)
    folder = Path(model).parent
    if folder.name == "checkpoints":  # a checkpoint: its run's curve
        folder = folder.parent
    curve = []
    if (folder / "learning_curve.json").is_file():
        curve = [
            {k: round(float(p[k]), 4) for k in ("steps", "success_rate", "collision_rate")}
            for p in json.loads((folder / "learning_curve.json").read_text())
        ]
    if (folder / "learning_curve.png").is_file():
        shutil.copyfile(folder / "learning_curve.png", HERE / f"{name}_curve.png")
    # the command as a user types it: ppo plays the task's user, a second user is its file
    shown_as = "ppo" if name == task else f"agents/learned/users/{target.name}"
    bench, rows = held_out_rows(task, target, episodes, seed=seed, shown_as=shown_as)
    ppo = {r["population"]: r for r in rows if r["user"] == "ppo"}
    seeker = {r["population"]: r for r in rows if r["user"] == "goal_seeker"}
    bar = {
        "idealised_collision_free_success_at_least": BAR,
        "holds_idealised": ppo["idealised"]["collision_free_success_rate"] >= BAR,
        "holds_against_goal_seeker": all(
            ppo[p]["collision_free_success_rate"] >= seeker[p]["collision_free_success_rate"]
            for p in ppo
        ),
    }
    card = {
        "task": task,
        "file": target.name,
        "cell": trained.vrloco_cell,
        "policy": trained.vrloco_policy,
        "reward": {k: v for k, v in vars(trained.vrloco_env["reward"]).items()},
        "train_command": command,
        "choices": choices,
        "development_curve": {
            "seeds": "10000 + the training seed onwards, 32 episodes per point (development)",
            "points": curve,
        },
        "held_out": {"command": bench, "seeds_from": seed, "rows": rows},
        "bar": bar,
    }
    path = target.with_suffix(".json")
    path.write_text(json.dumps(card, indent=2) + "\n")
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("model", type=Path, help="the trained model (.zip)")
    parser.add_argument("--command", help="the vrloco train command that made it (to ship)")
    parser.add_argument("--episodes", type=int, default=100, help="held-out episodes per cell")
    parser.add_argument("--choices", default="", help="the development choices, in a line")
    parser.add_argument(
        "--name", help="ship under this name (default: the task's), e.g. a second user of a task"
    )
    parser.add_argument(
        "--seed",
        type=int,
        help=f"first seed of the evaluation (default {HELD_OUT_SEED}, or {DEV_SEED} with --dev; "
        f"to ship, at least {HELD_OUT_SEED}: a block of held-out seeds no choice has seen)",
    )
    parser.add_argument(
        "--dev",
        action="store_true",
        help=f"only print the evaluation on the development seeds {DEV_SEED} onwards (to choose "
        "between candidates); ship nothing",
    )
    args = parser.parse_args(argv)
    from agents.benchmark.policies import load_ppo

    try:  # a missing or damaged model file: one line
        load_ppo(args.model)
    except ValueError as err:
        print(f"ship: {err}", file=sys.stderr)
        return 2
    if args.dev:
        seed = DEV_SEED if args.seed is None else args.seed
        if seed >= HELD_OUT_SEED:
            parser.error(f"--seed {seed}: held-out seeds ({HELD_OUT_SEED} on) are not for --dev")
        task = load_ppo(args.model).vrloco_env["task"]
        _, rows = held_out_rows(task, args.model, args.episodes, seed=seed)
        print(f"development seeds {seed}-{seed + args.episodes - 1} (in-sample)")
        for r in rows:
            print(
                f"{r['user']:<12} {r['population']:<14} success {r['success_rate']:.2f} "
                f"collision-free {r['collision_free_success_rate']:.2f}"
            )
        return 0
    if not args.command:
        parser.error("--command: give the vrloco train command that made the model (or --dev)")
    seed = HELD_OUT_SEED if args.seed is None else args.seed
    try:
        card = ship(args.model, args.command, args.episodes, args.choices, args.name, seed)
    except ValueError as err:  # a development seed, or a name that is not a file name
        parser.error(str(err))
    print(f"wrote {card}")
    print(json.dumps(json.loads(card.read_text())["bar"], indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

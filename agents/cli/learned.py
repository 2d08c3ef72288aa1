"""``vrloco train`` (a PPO user, stable-baselines3 or RLlib) and ``vrloco evaluate`` (the
benchmark's metrics for a trained model)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def cmd_train(args: argparse.Namespace) -> int:
    from agents.benchmark.backends import BackendError

    seeds = args.seeds if args.seeds is not None else [args.seed]
    common = dict(
        steps=args.steps,
        sensor_preset=args.sensors,
        eval_every=args.eval_every,
        technique=args.technique,
        population=args.population,
        condition=args.condition,
    )
    if args.eval_episodes is not None:
        common["eval_episodes"] = args.eval_episodes
    if args.reward is not None:
        common["reward"] = args.reward
    if args.variability is not None:
        common["variability"] = args.variability
    if args.init is not None:
        if args.backend == "rllib":
            print("vrloco train: --init needs --backend local or ray", file=sys.stderr)
            return 2
        common["init"] = args.init
    for flag, value, key, kept in (  # PPO settings a model given to --init keeps
        ("--rollout-steps", args.rollout_steps, "n_steps", "rollout steps"),
        ("--learning-rate", args.learning_rate, "learning_rate", "learning rate"),
    ):
        if value is None:
            continue
        if args.backend == "rllib":
            print(f"vrloco train: {flag} needs --backend local or ray", file=sys.stderr)
            return 2
        if args.init is not None:
            why = f"--init keeps the model's own {kept}; drop {flag}"
            print(f"vrloco train: {why}", file=sys.stderr)
            return 2
        common[key] = value
    if args.net_arch is not None:
        if args.backend == "rllib":
            print("vrloco train: --net-arch needs --backend local or ray", file=sys.stderr)
            return 2
        if args.init is not None:
            why = "--init keeps the model's own network; drop --net-arch"
            print(f"vrloco train: {why}", file=sys.stderr)
            return 2
        common["policy_kwargs"] = {"net_arch": list(args.net_arch)}
    if args.env_workers != 1:
        if args.backend == "rllib":
            print("vrloco train: --env-workers needs --backend local or ray", file=sys.stderr)
            return 2
        common["env_workers"] = args.env_workers
    if args.imitate_steps is not None and args.imitate is None:
        print("vrloco train: --imitate-steps needs --imitate SCRIPTED_USER", file=sys.stderr)
        return 2
    if args.imitate is not None:
        if args.backend == "rllib":
            print("vrloco train: --imitate needs --backend local or ray", file=sys.stderr)
            return 2
        common["imitate"] = args.imitate
        if args.imitate_steps is not None:
            common["imitate_steps"] = args.imitate_steps
    if args.residual_on is not None:
        if args.backend == "rllib":
            print("vrloco train: --residual-on needs --backend local or ray", file=sys.stderr)
            return 2
        common["residual_on"] = args.residual_on
    if args.address is not None and args.backend == "local":
        print("vrloco train: --address needs --backend ray or rllib", file=sys.stderr)
        return 2
    if args.env_runners is not None and args.backend != "rllib":
        print("vrloco train: --env-runners needs --backend rllib", file=sys.stderr)
        return 2
    if args.backend == "rllib" and (args.frame_stack != 1 or args.recurrent):
        print(
            "vrloco train: --frame-stack and --recurrent need --backend local or ray",
            file=sys.stderr,
        )
        return 2
    mixed = any("," in (v or "") or v == "all" for v in (args.technique, args.population))
    if args.backend == "rllib" and mixed:
        print(
            "vrloco train: a mix of techniques or populations needs --backend local or ray",
            file=sys.stderr,
        )
        return 2
    try:
        if args.backend == "rllib":
            from agents.learned.rllib import train_rllib_seeds

            runners = 2 if args.env_runners is None else args.env_runners
            paths = train_rllib_seeds(
                args.task,
                seeds,
                Path(args.out),
                address=args.address,
                num_env_runners=runners,
                num_envs_per_env_runner=args.num_envs,
                **common,
            )
        else:
            from agents.learned.seeds import train_seeds

            paths = train_seeds(
                args.task,
                seeds,
                Path(args.out),
                backend=args.backend,
                address=args.address,
                num_envs=args.num_envs,
                frame_stack=args.frame_stack,
                recurrent=args.recurrent,
                **common,
            )
    except BackendError as err:  # no Ray cluster, or runs lost: what and where, no traceback
        print(f"vrloco train: {err}", file=sys.stderr)
        return 1
    curve = Path(args.out) / "learning_curve.json"
    if len(paths) == 1:
        print(f"wrote {paths[0]}; learning curve in {curve}")
    else:
        where = "checkpoints" if args.backend == "rllib" else "models"
        print(
            f"wrote {len(paths)} {where} in {Path(args.out)}/seed_*; learning curves (each "
            f"seed, mean and std) in {curve} and {curve.with_suffix('.png')}"
        )
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from agents.benchmark.outputs import WriteError, show_table, write_json
    from agents.learned.evaluate import evaluate_model

    try:
        row = evaluate_model(
            Path(args.model),
            task=args.task,
            episodes=args.episodes,
            seed=args.seed,
            sensor_preset=args.sensors,
            progress=True,
            technique=args.technique,
            population=args.population,
            condition=args.condition,
            allow_mismatch=args.allow_mismatch,
        )
    except ValueError as err:  # not a model, or a contradiction with it: one line, no traceback
        print(f"vrloco evaluate: {err}", file=sys.stderr)
        return 2
    cell = ", ".join(f"{k} {row[k]}" for k in ("task", "technique", "population", "condition"))
    trained = row.get("trained_on")
    if trained:
        print(
            f"cell: {cell}; the model was trained on "
            + ", ".join(f"{k} {v}" for k, v in trained.items())
        )
    else:
        print(f"cell: {cell} (the model's own)")
    show_table([row], args.seed)
    if args.json:
        meta = {"model": str(args.model), "seed": args.seed, "episodes": args.episodes}
        try:
            print(f"wrote {write_json(Path(args.json), [row], meta)}")
        except WriteError as err:  # a full disk: one line
            print(f"vrloco evaluate: {err}", file=sys.stderr)
            return 1
    return 0

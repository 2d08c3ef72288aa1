"""``vrloco experiment ...``: each subcommand reproduces a source paper's experiment (or one of
the project's own) by calling its ``run_*`` function."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def cmd_hand_variance(args: argparse.Namespace) -> int:
    from agents.experiments.hand_variance import run_hand_variance

    run_hand_variance(
        json_path=Path(args.json) if args.json else None, repeats=args.repeats, seed=args.seed
    )
    return 0


def cmd_vio(args: argparse.Namespace) -> int:
    from agents.experiments.vio import run_vio

    try:
        run_vio(
            json_path=Path(args.json) if args.json else None,
            duration=args.duration,
            seed=args.seed,
            out_dir=Path(args.out) if args.out else None,
            workers=args.workers,
        )
    except ValueError as err:  # a bad option value: one clear line, no traceback
        print(f"vrloco experiment vio: {err}", file=sys.stderr)
        return 2
    return 0


def cmd_published(args: argparse.Namespace) -> int:
    from agents.experiments.published.run import run_published

    try:
        run_published(
            json_path=Path(args.json) if args.json else None,
            episodes=args.episodes,
            findings=args.findings.split(",") if args.findings else None,
            dev=args.dev,
        )
    except ValueError as err:
        print(f"vrloco experiment published: {err}", file=sys.stderr)
        return 2
    return 0


def cmd_learned_ranking(args: argparse.Namespace) -> int:
    from agents.experiments.learned_ranking import run_learned_ranking

    try:
        run_learned_ranking(
            episodes=args.episodes,
            adapt_steps=args.adapt,
            dev=args.dev,
            json_path=Path(args.json) if args.json else None,
            adapt_seed=args.adapt_seed,
        )
    except ValueError as err:
        print(f"vrloco experiment learned-ranking: {err}", file=sys.stderr)
        return 2
    return 0


def cmd_locomotion(args: argparse.Namespace) -> int:
    from agents.experiments.locomotion_table import run_locomotion_table

    run_locomotion_table(json_path=Path(args.json) if args.json else None)
    return 0


def cmd_head_motions(args: argparse.Namespace) -> int:
    from agents.experiments.head_motions import run_head_motions

    run_head_motions(
        out_dir=Path(args.out),
        json_path=Path(args.json) if args.json else None,
        users=args.users,
        seed=args.seed,
    )
    return 0


def cmd_step_envelope(args: argparse.Namespace) -> int:
    from agents.experiments.step_envelope import run_step_envelope

    run_step_envelope(
        json_path=Path(args.json) if args.json else None,
        seed=args.seed,
        dev=args.dev,
        users=args.users,
    )
    return 0


def cmd_head_behaviour(args: argparse.Namespace) -> int:
    from agents.experiments.head_behaviour import run_head_behaviour

    try:
        run_head_behaviour(
            json_path=Path(args.json) if args.json else None,
            episodes=args.episodes,
            seed=args.seed,
            out_dir=Path(args.out) if args.out else None,
        )
    except (FileNotFoundError, ValueError) as err:  # no head traces, a bad file: one line
        print(f"vrloco experiment head-behaviour: {err}", file=sys.stderr)
        return 2
    return 0


def cmd_population_sensitivity(args: argparse.Namespace) -> int:
    from agents.experiments.population_sensitivity import run_population_sensitivity

    try:
        run_population_sensitivity(
            json_path=Path(args.json) if args.json else None,
            episodes=args.episodes,
            fields=args.fields.split(",") if args.fields else None,
            out_dir=Path(args.out) if args.out else None,
        )
    except ValueError as err:  # a field that is no choice field: one line
        print(f"vrloco experiment population-sensitivity: {err}", file=sys.stderr)
        return 2
    return 0

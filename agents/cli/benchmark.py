"""``vrloco benchmark``: the grid of simulated users x tasks x techniques, with its errors as one
line each."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def cmd_benchmark(args: argparse.Namespace) -> int:
    from agents.benchmark import run_benchmark
    from agents.benchmark.backends import BackendError
    from agents.benchmark.outputs import WriteError
    from agents.benchmark.resume import FolderBusy

    def names(text: str) -> list[str]:
        return [s.strip() for s in text.split(",") if s.strip()]

    policies = names(args.policies) if args.policies else None
    if args.adapt is not None:
        if not policies or not any(p.split("+")[0] == "ppo" for p in policies):
            print(
                "vrloco benchmark: --adapt needs --policies ppo (or ppo+<population>)",
                file=sys.stderr,
            )
            return 2
        if args.adapt > 0:  # ppo -> ppo@STEPS, its population suffix kept
            policies = [
                f"ppo@{args.adapt}{p[3:]}" if p.split("+")[0] == "ppo" else p for p in policies
            ]
    try:
        run_benchmark(
            tasks=names(args.tasks) if args.tasks else None,
            policies=policies,
            sensors=names(args.sensors) if args.sensors else None,
            techniques=names(args.techniques) if args.techniques else None,
            episodes=args.episodes,
            seed=args.seed,
            workers=args.workers,
            out_dir=Path(args.out) if args.out else None,
            json_path=Path(args.json) if args.json else None,
            batch_size=args.batch_size,
            backend=args.backend,
            address=args.address,
            conditions=names(args.conditions) if args.conditions else None,
            force=args.force,
        )
    except ValueError as err:  # a bad option value: one clear line, no traceback
        print(f"vrloco benchmark: {err}", file=sys.stderr)
        return 2
    except (WriteError, FolderBusy) as err:  # a full disk, another run in --out: one line
        print(f"vrloco benchmark: {err}", file=sys.stderr)
        return 1
    except BackendError as err:  # no Ray cluster, or Ray jobs lost: what and where, no traceback
        kept = (
            f"\nthe finished episodes are kept: rerun with --out {args.out} to resume"
            if args.out and err.partial
            else ""
        )
        print(f"vrloco benchmark: {err}{kept}", file=sys.stderr)
        return 1
    return 0

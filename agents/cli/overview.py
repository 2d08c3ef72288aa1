"""``vrloco demo`` (a synthetic head-IMU trace, as a figure) and ``vrloco techniques`` (the
registered techniques and every stage's implementations)."""

from __future__ import annotations

import argparse
from pathlib import Path


def cmd_demo(args: argparse.Namespace) -> int:
    from agents.experiments.imu_trace import run_imu_trace

    path = run_imu_trace(out_dir=Path(args.out), seed=args.seed, preset=args.sensors)
    print(f"wrote {path}")
    return 0


def cmd_techniques(args: argparse.Namespace) -> int:
    from estimators import stages
    from vrloco_env.config import STAGE_FIELDS, EstimatorConfig
    from vrloco_env.techniques import TECHNIQUES

    base = EstimatorConfig()
    chain = ", ".join(f"{k}={base.label(k)}" for k in STAGE_FIELDS)
    print("techniques (gym.make(..., technique=NAME); vrloco benchmark --techniques A,B):")
    print(f"  each is Zhang 2021's chain but for what it names:\n    {chain}")
    width = max(len(n) for n in TECHNIQUES)
    for name, tech in TECHNIQUES.items():
        e = tech.estimators
        changed = [f"{k}={e.label(k)}" for k in STAGE_FIELDS if getattr(e, k) != getattr(base, k)]
        if e != base and not changed:
            changed = ["stage parameters"]
        what = ", ".join([tech.sensor_preset, *changed])
        print(f"  {name:<{width}}  {what}: {tech.description}")
    print()
    print("stages (EstimatorConfig(FIELD=NAME) or FIELD='package.module:attr' for your own):")
    for field in STAGE_FIELDS:
        registry = getattr(stages, field.upper())
        print(f"  {field} {registry.signature}:")
        for name, text in registry.describe().items():
            print(f"    {name:<18} {text}")
    return 0

"""Drawing a room: its time per task, now and at an earlier revision.

Run from the repository root::

    python benchmarks/bench_rooms.py                       # 100 rooms of each task
    python benchmarks/bench_rooms.py --baseline 078513b    # and the same rooms drawn at 078513b

Every reset of a training or benchmark user draws a new room (its obstacles, then the avatar's
shortest path, :mod:`vrloco_env.world.planning`), one user at a time. This script draws the
rooms of seeds ``seed`` onwards for every task in a fresh process, the kept plans cleared before
each room (so that every room is planned), after one untimed room per task that loads the
compiled kernels (a first, untimed run of each tree compiles them into its cache), and prints
the milliseconds per room and a digest of the paths. With
``--baseline REV`` the same rooms are drawn by a checkout of the git revision ``REV`` (a
temporary worktree) too, the runs alternating (``--repeats`` each, medians), with the ratio and
whether the paths are the same to the last bit.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def child(root: Path, rooms: int, seed: int) -> dict[str, list]:
    """Seconds per room and the paths' digest for every task, drawn by the tree ``root``."""
    sys.path.insert(0, str(root))
    import hashlib

    import numpy as np

    from vrloco_env.tasks import TASKS, make_layout
    from vrloco_env.world import RoomConfig, layout

    out = {}
    for task in TASKS.names():
        make_layout(task, RoomConfig(), np.random.default_rng(seed))  # the kernels load
        digest, spent = hashlib.sha256(), 0.0
        for s in range(seed, seed + rooms):
            layout._PATHS.clear()
            t0 = time.perf_counter()
            room = make_layout(task, RoomConfig(), np.random.default_rng(s))
            spent += time.perf_counter() - t0
            digest.update(np.ascontiguousarray(room.path).tobytes())
        out[task] = [spent / rooms, digest.hexdigest()[:16]]
    return out


def run(root: Path, args: argparse.Namespace) -> dict[str, list]:
    """:func:`child` in a fresh process."""
    cmd = [sys.executable, __file__, "--child", str(root), "--rooms", str(args.rooms)]
    cmd += ["--seed", str(args.seed)]
    out = subprocess.run(cmd, cwd=root, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise SystemExit(f"the run in {root} failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rooms", type=int, default=100, help="rooms of each task")
    parser.add_argument("--seed", type=int, default=0, help="first room's seed")
    parser.add_argument("--baseline", metavar="REV", help="also draw them at this git revision")
    parser.add_argument("--repeats", type=int, default=2, help="runs of each tree")
    parser.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.rooms < 1 or args.repeats < 1:
        parser.error("--rooms and --repeats must be at least 1")
    if args.child is not None:
        print(json.dumps(child(args.child, args.rooms, args.seed)))
        return
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"now": ROOT}
        if args.baseline:
            trees[args.baseline] = Path(tmp) / "baseline"
            subprocess.run(
                ["git", "worktree", "add", "--detach", str(trees[args.baseline]), args.baseline],
                cwd=ROOT,
                check=True,
                capture_output=True,
            )
        try:
            for root in trees.values():  # untimed: fills each tree's kernel cache
                run(root, argparse.Namespace(rooms=1, seed=args.seed))
            runs: dict[str, list[dict]] = {name: [] for name in trees}
            for i in range(args.repeats):
                for name, root in trees.items():
                    runs[name].append(run(root, args))
                    print(f"  run {i + 1} {name} done", flush=True)
        finally:
            if args.baseline:
                subprocess.run(
                    ["git", "worktree", "remove", "--force", str(trees[args.baseline])],
                    cwd=ROOT,
                    check=False,
                    capture_output=True,
                )
    names = list(trees)
    last = args.seed + args.rooms - 1
    print(f"\nms per room (median of {args.repeats}), seeds {args.seed}-{last}")
    print(f"{'task':10s}" + "".join(f"{n:>12s}" for n in names), end="")
    print("   ratio  paths" if len(names) > 1 else "  paths")
    for task in runs["now"][0]:
        ms = [statistics.median(r[task][0] for r in runs[n]) * 1e3 for n in names]
        digests = {r[task][1] for n in names for r in runs[n]}
        line = f"{task:10s}" + "".join(f"{m:12.2f}" for m in ms)
        if len(names) > 1:
            same = "the same" if len(digests) == 1 else "DIFFER"
            line += f"  {ms[1] / ms[0]:5.2f}x  {same}"
        print(line + f" ({sorted(digests)[0]})")


if __name__ == "__main__":
    main()

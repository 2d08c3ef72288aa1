"""The benchmark's first run against a later one: ``vrloco benchmark`` with an empty kernel cache
(every kernel compiled) and again with the cache it left (every kernel loaded), in one run.

    python benchmarks/bench_cold_start.py                 # the default run, cold then warm
    python benchmarks/bench_cold_start.py -- --tasks approach --techniques zhang2021 --episodes 5

Each run is a fresh ``python -m agents.cli benchmark`` process with ``NUMBA_CACHE_DIR`` set to a
new temporary folder, so the cache of this work tree is neither used nor touched. Prints the
wall time of each, their difference (the compiling) and whether the first run announced it.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(cache: Path, out: Path, extra: list[str]) -> tuple[float, str]:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    cmd = [sys.executable, "-m", "agents.cli", "benchmark", "--out", str(out), *extra]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return wall, done.stdout


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("extra", nargs="*", help="options for vrloco benchmark, after --")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "numba_cache"
        cold, out_cold = _run(cache, Path(tmp) / "cold", args.extra)
        warm, out_warm = _run(cache, Path(tmp) / "warm", args.extra)
    said = "compiling kernels" in out_cold
    print(f"vrloco benchmark {' '.join(args.extra)}".rstrip())
    print(f"  cold (empty cache): {cold:7.1f} s   announced compiling: {'yes' if said else 'NO'}")
    print(
        f"  warm (cached):      {warm:7.1f} s   announced compiling: "
        f"{'YES' if 'compiling kernels' in out_warm else 'no'}"
    )
    print(f"  compiling:          {cold - warm:7.1f} s ({(cold - warm) / 60:.1f} min)")


if __name__ == "__main__":
    main()

"""Whether the compiled kernels are already on disk, and how a first run compiles them.

Numba compiles each kernel the first time it is called and keeps the machine code on disk
(``cache=True``, in a folder per version of the kernel sources: :mod:`estimators.numba_cache`),
so only a first run, or the first run after a kernel source changed, pays for compiling. This
module lets a command say so before its progress bar starts (:func:`announce`), and records once a
run has compiled everything (:func:`mark_compiled`): a stamp in that folder, so that any change
that makes numba compile again (a new folder) also makes the announcement come back.

The benchmark compiles in parallel without doing the same work twice: its process plays one
episode of the grid before it forks its workers (:func:`agents.benchmark.run_benchmark`), which
compiles the kernels every cell shares (the user's motion, the sensors, the world, the scripted
user's planner); each worker then starts with those loaded and compiles only the estimators of
the cells it plays, beside the others.

``python benchmarks/bench_cold_start.py`` measures the default run cold (an empty cache) and warm,
in one run.
"""

from __future__ import annotations

import os
from pathlib import Path

from estimators.numba_cache import use_fingerprinted_cache

__all__ = ["COLD_START_MINUTES", "announce", "is_compiled", "mark_compiled"]

#: The default benchmark's compile time on a cold cache, in minutes, on a 2-core machine of the
#: kind the project is developed on (``python benchmarks/bench_cold_start.py``); the
#: announcement quotes it as an order of magnitude.
COLD_START_MINUTES = 2


def _stamp() -> Path | None:
    """The stamp in numba's cache folder, the one of these kernel sources
    (:func:`estimators.numba_cache.use_fingerprinted_cache`); None where there is none."""
    folder = use_fingerprinted_cache()
    return None if folder is None else folder / "vrloco-compiled"


def is_compiled() -> bool:
    """True where a run has compiled the kernels of these sources on this machine."""
    stamp = _stamp()
    return stamp is not None and stamp.exists()


def mark_compiled() -> None:
    """Record that the kernels of these sources are compiled (after a run that used them); a
    cache folder that cannot be written is left as it is (the next run announces again)."""
    stamp = _stamp()
    if stamp is None:
        return
    try:
        stamp.parent.mkdir(parents=True, exist_ok=True)
        stamp.touch()
    except OSError:
        pass


def announce() -> bool:
    """Print, where the kernels are not compiled yet, that this first run compiles them and
    about how long that takes; True where it printed."""
    if is_compiled() or os.environ.get("NUMBA_DISABLE_JIT") == "1":
        return False
    print(
        f"compiling kernels (first run only, about {COLD_START_MINUTES} min on 2 cores; later "
        "runs load them from the cache)",
        flush=True,
    )
    return True

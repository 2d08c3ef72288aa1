"""Whether the compiled kernels are already on disk, and how a first run compiles them.

Numba compiles each kernel the first time it is called and keeps the machine code on disk
(``cache=True``: ``__pycache__`` beside each source, or ``NUMBA_CACHE_DIR``), so only a first run,
or the first run after a kernel's source changed, pays for compiling. This module lets a command
say so before its progress bar starts (:func:`announce`), and records once a run has compiled
everything (:func:`mark_compiled`): a stamp named by a fingerprint of every kernel source, the
Python and numba versions and the processor, so that any change that makes numba recompile also
makes the announcement come back.

The benchmark compiles in parallel without doing the same work twice: its process plays one
episode of the grid before it forks its workers (:func:`agents.benchmark.run_benchmark`), which
compiles the kernels every cell shares (the user's motion, the sensors, the world, the scripted
user's planner); each worker then starts with those loaded and compiles only the estimators of
the cells it plays, beside the others.

``python benchmarks/bench_cold_start.py`` measures the default run cold (an empty cache) and warm,
in one run.
"""

from __future__ import annotations

import hashlib
import os
import platform
import sys
from pathlib import Path

__all__ = ["COLD_START_MINUTES", "announce", "is_compiled", "kernel_fingerprint", "mark_compiled"]

#: The default benchmark's compile time on a cold cache, in minutes, on a 2-core machine of the
#: kind the project is developed on (``python benchmarks/bench_cold_start.py``); the
#: announcement quotes it as an order of magnitude.
COLD_START_MINUTES = 2

_ROOT = Path(__file__).resolve().parents[2]
_PACKAGES = ("estimators", "vrloco_env", "agents")


def _kernel_sources() -> list[Path]:
    """The package sources that hold compiled kernels (``cache=True``), in path order."""
    found = []
    for pkg in _PACKAGES:
        for path in sorted((_ROOT / pkg).rglob("*.py")):
            if b"cache=True" in path.read_bytes():
                found.append(path)
    return found


def kernel_fingerprint() -> str:
    """SHA-256 (hex, 16 characters) of the kernel sources, the Python and numba versions and
    the processor: what numba's cache depends on."""
    import numba

    h = hashlib.sha256()
    h.update(
        repr((sys.version, numba.__version__, platform.machine(), platform.processor())).encode()
    )
    for path in _kernel_sources():
        h.update(str(path.relative_to(_ROOT)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _stamp() -> Path:
    import numba

    folder = (
        Path(numba.config.CACHE_DIR)
        if numba.config.CACHE_DIR
        else (_ROOT / "estimators" / "kernels" / "__pycache__")
    )
    return folder / f"vrloco-compiled-{kernel_fingerprint()}"


def is_compiled() -> bool:
    """True where a run has compiled the kernels of these sources on this machine."""
    return _stamp().exists()


def mark_compiled() -> None:
    """Record that the kernels of these sources are compiled (after a run that used them); a
    cache folder that cannot be written is left as it is (the next run announces again)."""
    stamp = _stamp()
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

"""Numba's on-disk cache, one folder per version of the compiled sources.

Numba keeps a kernel's machine code on disk (``cache=True``) and loads it again while the
kernel's *own* source file is unchanged (its modification time and size). It does not look at
the files a kernel reads from: a cached kernel that calls a compiled helper of another file
keeps the helper's old machine code after the helper's source changes, and returns the old
numbers without a word. Across this project kernels call helpers of other files (the scalar
rotations of :mod:`estimators.kernels.rotations`, the per-user kernels the batch driver wraps),
so a checkout that pulls a change to a helper, and keeps the cache of the run before, would run
the old code.

:func:`use_fingerprinted_cache` therefore points numba's cache at a folder named by
:func:`kernel_fingerprint`: a hash of every package source that holds compiled code
(:func:`kernel_sources`), the Python and numba versions and the processor. A change to any of
those sources starts an empty folder, so every kernel compiles again from the current sources.
The packages call it when they are imported, before any kernel is defined. The folder's parent
is ``NUMBA_CACHE_DIR`` where it is set, else ``.numba_cache`` in a source checkout (the work
tree), else the user's cache folder (``$XDG_CACHE_HOME/vrloco/numba``, by default
``~/.cache/vrloco/numba``). Folders of other fingerprints not used for
:data:`PRUNE_AFTER_DAYS` days are removed.

A kernel must not read a number, tuple or array that a source outside :func:`kernel_sources`
assigns: numba freezes such a value into the machine code, and a change to it would not change
the fingerprint. A module whose constants kernels read says so in a comment that names numba,
which puts it among the sources; the tests check every cached kernel for it.
"""

from __future__ import annotations

import hashlib
import os
import platform
import re
import shutil
import sys
import time
from pathlib import Path

__all__ = [
    "PACKAGES",
    "PRUNE_AFTER_DAYS",
    "ROOT",
    "cache_base",
    "kernel_fingerprint",
    "kernel_sources",
    "use_fingerprinted_cache",
]

#: The folder that holds the packages (a checkout's root, or ``site-packages``).
ROOT = Path(__file__).resolve().parents[1]
#: The project's packages (under :data:`ROOT`), whose compiled sources the fingerprint covers.
PACKAGES = ("estimators", "vrloco_env", "agents")

#: What marks a source as holding compiled code (a kernel, or a helper a kernel calls).
_COMPILED = re.compile(rb"numba|njit|prange|BatchKernel")

#: A cache folder of another fingerprint is removed once it has not been used for this many days
#: (a choice: a kernel's author switching between revisions keeps theirs; about 30 MB each).
PRUNE_AFTER_DAYS = 7.0

_IN_USE: Path | None = None  # the folder this process uses, once chosen


def kernel_sources(root: Path | str = ROOT, packages: tuple[str, ...] = PACKAGES) -> list[Path]:
    """The package sources that hold compiled code (they mention numba, ``njit``, ``prange``
    or ``BatchKernel``), in path order."""
    root = Path(root)
    return [
        path
        for pkg in packages
        for path in sorted((root / pkg).rglob("*.py"))
        if _COMPILED.search(path.read_bytes())
    ]


def kernel_fingerprint(root: Path | str = ROOT, packages: tuple[str, ...] = PACKAGES) -> str:
    """SHA-256 (hex, 16 characters) of :func:`kernel_sources` (paths and contents), the Python
    and numba versions and the processor: what the compiled kernels depend on."""
    import numba

    root = Path(root)
    h = hashlib.sha256()
    h.update(
        repr((sys.version, numba.__version__, platform.machine(), platform.processor())).encode()
    )
    for path in kernel_sources(root, packages):
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def cache_base(root: Path | str = ROOT) -> Path:
    """The folder that holds one cache folder per fingerprint: ``NUMBA_CACHE_DIR`` where set,
    else ``.numba_cache`` beside the packages of a writable source checkout (a
    ``pyproject.toml`` there), else the user's cache folder."""
    root, given = Path(root), os.environ.get("NUMBA_CACHE_DIR")
    if given:
        return Path(given)
    if (root / "pyproject.toml").is_file() and os.access(root, os.W_OK):
        return root / ".numba_cache"
    user = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(user) / "vrloco" / "numba"


def use_fingerprinted_cache(
    root: Path | str = ROOT, packages: tuple[str, ...] = PACKAGES, force: bool = False
) -> Path | None:
    """Point numba's cache at ``cache_base(root) / kernel_fingerprint(root, packages)`` and
    return that folder. Kernels defined after this call cache there; the first call of a process
    chooses the folder and later calls return it (``force``: choose again). Where the folder
    cannot be created, returns None and leaves numba's own choice in place (numba then caches
    beside the sources, or compiles without a cache)."""
    global _IN_USE
    if _IN_USE is not None and not force:
        return _IN_USE
    import numba

    base = cache_base(root)
    folder = base / kernel_fingerprint(root, packages)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        os.utime(folder)  # in use: not pruned by another checkout's process
    except OSError:
        return None
    numba.config.CACHE_DIR = str(folder)
    _IN_USE = folder
    _prune(base, keep=folder)
    return folder


def _prune(base: Path, keep: Path) -> None:
    """Remove the folders of other fingerprints under ``base`` unused for
    :data:`PRUNE_AFTER_DAYS` days (16 hex characters each; nothing else is touched)."""
    cutoff = time.time() - PRUNE_AFTER_DAYS * 86400.0
    try:
        old = [
            p
            for p in base.iterdir()
            if p != keep
            and p.is_dir()
            and re.fullmatch(r"[0-9a-f]{16}", p.name)
            and p.stat().st_mtime < cutoff
        ]
    except OSError:
        return
    for p in old:
        shutil.rmtree(p, ignore_errors=True)

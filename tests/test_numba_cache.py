"""Numba's cache never feeds a kernel old code: a change to any compiled source (a helper in
another file included) compiles every kernel again, and no cached kernel reads a value from a
source the cache's fingerprint does not cover."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import inspect
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
from numba.core.registry import CPUDispatcher

from estimators import numba_cache
from estimators.kernels import BatchKernel

PACKAGES = ("estimators", "vrloco_env", "agents")
HELPER = """
import numba

@numba.njit(cache=True)
def helper(x):
    return x + {add}
"""
CALLER = """
import numba
from pkg.helpers import helper

@numba.njit(cache=True)
def twice_helper(x):
    return 2.0 * helper(x)
"""
PLAY = """
import sys
from estimators.numba_cache import use_fingerprinted_cache
use_fingerprinted_cache(root=sys.argv[1], packages=("pkg",), force=True)
sys.path.insert(0, sys.argv[1])
from pkg.caller import twice_helper
print(twice_helper(1.0))
"""


def _play(root, cache):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    run = subprocess.run(
        [sys.executable, "-c", PLAY, str(root)], env=env, capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr
    return float(run.stdout.split()[-1])


def test_a_changed_helper_in_another_file_compiles_its_caller_again(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "helpers.py").write_text(HELPER.format(add=1.0))
    (pkg / "caller.py").write_text(CALLER)
    cache = tmp_path / "cache"
    first = numba_cache.kernel_fingerprint(tmp_path, ("pkg",))
    assert _play(tmp_path, cache) == 4.0
    assert _play(tmp_path, cache) == 4.0  # from the cache
    # numba's own cache keys the caller on the caller's file alone: it would answer 4.0 again
    (pkg / "helpers.py").write_text(HELPER.format(add=100.0))
    assert _play(tmp_path, cache) == 202.0
    second = numba_cache.kernel_fingerprint(tmp_path, ("pkg",))
    assert (cache / first).is_dir() and (cache / second).is_dir()  # one folder per version


def test_the_fingerprint_follows_compiled_sources_only(tmp_path):
    src = tmp_path / "estimators" / "k.py"
    src.parent.mkdir()
    src.write_text("@numba.njit(cache=True)\ndef f(x):\n    return x\n")
    before = numba_cache.kernel_fingerprint(tmp_path, ("estimators",))
    src.write_text("@numba.njit(cache=True)\ndef f(x):\n    return x + 1\n")
    assert numba_cache.kernel_fingerprint(tmp_path, ("estimators",)) != before
    helper = tmp_path / "estimators" / "h.py"  # a kernel for the batch driver, no numba import
    helper.write_text("def g(x):\n    return x\nk = BatchKernel(g)\n")
    after = numba_cache.kernel_fingerprint(tmp_path, ("estimators",))
    helper.write_text("def g(x):\n    return -x\nk = BatchKernel(g)\n")
    assert numba_cache.kernel_fingerprint(tmp_path, ("estimators",)) != after
    (tmp_path / "estimators" / "plain.py").write_text("x = 1\n")  # no compiled code
    after = numba_cache.kernel_fingerprint(tmp_path, ("estimators",))
    (tmp_path / "estimators" / "plain.py").write_text("x = 2\n")
    assert numba_cache.kernel_fingerprint(tmp_path, ("estimators",)) == after


def test_the_packages_cache_in_the_folder_of_their_fingerprint():
    import numba

    folder = numba_cache.use_fingerprinted_cache()
    assert folder is not None and folder.name == numba_cache.kernel_fingerprint()
    assert os.path.samefile(numba.config.CACHE_DIR, folder)


def test_folders_of_other_fingerprints_are_pruned_once_long_unused(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    stale, recent, other = (
        tmp_path / "0123456789abcdef",
        tmp_path / "fedcba9876543210",
        tmp_path / "notes",
    )
    for p in (stale, recent, other):
        p.mkdir()
    old = time.time() - (numba_cache.PRUNE_AFTER_DAYS + 1) * 86400
    os.utime(stale, (old, old))
    os.utime(other, (old, old))
    import numba

    before = numba.config.CACHE_DIR
    try:
        folder = numba_cache.use_fingerprinted_cache(force=True)
        assert folder.parent == tmp_path
        assert not stale.exists() and recent.exists() and other.exists()
    finally:
        numba.config.CACHE_DIR = before
        numba_cache.use_fingerprinted_cache(force=True)


def _code_names(code) -> set[str]:
    names = set(code.co_names)
    for const in code.co_consts:
        if inspect.iscode(const):
            names |= _code_names(const)
    return names


def _cached_dispatchers():
    """Every cached kernel the compiled sources define (their own and the batch driver's)."""
    found = {}
    for path in numba_cache.kernel_sources():
        rel = path.relative_to(numba_cache.ROOT).with_suffix("")
        name = ".".join(rel.parts).removesuffix(".__init__")
        if name.endswith("__main__") or "rllib" in name:
            continue
        module = importlib.import_module(name)
        for obj in vars(module).values():
            builds = (obj.serial, obj.parallel) if isinstance(obj, BatchKernel) else (obj,)
            for d in builds:
                if isinstance(d, CPUDispatcher) and type(d._cache).__name__ != "NullCache":
                    found[id(d)] = d
    return list(found.values())


def _assigned_in(module: str, name: str, depth: int = 0) -> str | None:
    """The source file whose top level assigns ``name`` (a constant) for ``module``, following
    its ``from ... import`` lines; None where it cannot be found."""
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None or depth > 10:
        return None
    tree = ast.parse(Path(spec.origin).read_text(encoding="utf-8"))
    for node in tree.body:
        targets = []
        if isinstance(node, ast.Assign):
            targets = node.targets
        elif isinstance(node, ast.AnnAssign):
            targets = [node.target]
        for t in targets:
            elts = t.elts if isinstance(t, ast.Tuple) else [t]
            if any(isinstance(e, ast.Name) and e.id == name for e in elts):
                return os.path.realpath(spec.origin)
        if isinstance(node, ast.ImportFrom):
            for alias in node.names:
                if (alias.asname or alias.name) == name:
                    base = node.module or ""
                    if node.level:
                        pkg = (
                            module if spec.submodule_search_locations else module.rpartition(".")[0]
                        )
                        for _ in range(node.level - 1):
                            pkg = pkg.rpartition(".")[0]
                        base = f"{pkg}.{base}" if base else pkg
                    return _assigned_in(base, alias.name, depth + 1)
    return None


def test_cached_kernels_read_nothing_from_outside_the_fingerprint():
    sources = {os.path.realpath(p) for p in numba_cache.kernel_sources()}
    kernels = _cached_dispatchers()
    assert len(kernels) > 50
    problems = []
    for d in kernels:
        f = d.py_func
        where = f"{f.__module__}.{f.__qualname__}"
        if os.path.realpath(inspect.getsourcefile(f)) not in sources:
            problems.append(f"{where}: its source is not fingerprinted")
        names = _code_names(f.__code__)
        for n in names:
            g = f.__globals__.get(n)
            read = [(f.__module__, n, g)]
            if inspect.ismodule(g) and g.__name__.split(".")[0] in PACKAGES:  # module.CONSTANT
                read = [(g.__name__, a, getattr(g, a)) for a in names if hasattr(g, a)]
            for module, name, value in read:
                if isinstance(value, CPUDispatcher):
                    src = os.path.realpath(inspect.getsourcefile(value.py_func))
                    if src not in sources:
                        problems.append(f"{where} calls {name}, compiled in unfingerprinted {src}")
                elif isinstance(value, (bool, int, float, complex, tuple, np.ndarray, np.number)):
                    src = _assigned_in(module, name)
                    if src is None:
                        problems.append(f"{where} reads {name}: where it is assigned is not found")
                    elif src not in sources:
                        problems.append(f"{where} reads {name}, assigned in unfingerprinted {src}")
    assert not problems, textwrap.indent("\n".join(sorted(set(problems))), "  ")

"""The trainer's threads: :mod:`estimators.kernels` is imported before torch, so that torch's
OpenMP runtime starts with the passive wait policy that module sets (``OMP_WAIT_POLICY=PASSIVE``:
idle threads sleep instead of spinning on the cores the env's kernels need). The package
:mod:`agents.learned` imports this module before any of its modules imports torch."""

from __future__ import annotations

import os
import sys

#: torch's OpenMP runtime started before ``OMP_WAIT_POLICY`` was set (see the module docstring).
_TORCH_SPINS = "torch" in sys.modules and "OMP_WAIT_POLICY" not in os.environ

import estimators.kernels  # noqa: E402, F401  (sets OMP_WAIT_POLICY before torch starts)

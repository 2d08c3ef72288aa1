"""Estimators of the vrloco source papers: pure numpy (numba where measured), batched over a
leading dimension of B streams, with no knowledge of the environment.

Modules: :mod:`estimators.rotations` (the one quaternion/Euler module).
"""

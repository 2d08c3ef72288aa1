"""Small runs of every compiled kernel, one module per algorithm family.

Each module defines ``CASES``: name -> a function of no arguments that runs the public API on a
small input covering the kernel's branches and returns its outputs as a dict of arrays (or one
array). ``tests/test_kernels_compiled.py`` plays each case compiled and under
:func:`estimators.kernels.python_reference` and requires the same numbers.
"""

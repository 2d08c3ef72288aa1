"""Simulated users (scripted and learned), the benchmark and the ``vrloco`` command line."""

import estimators  # noqa: F401  (first: numba's cache folder, estimators.numba_cache)

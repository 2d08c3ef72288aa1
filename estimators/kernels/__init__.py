"""What every compiled kernel shares: the batch driver, scalar rotations and named records.

- :mod:`estimators.kernels.batch`: :class:`BatchKernel`, the serial and multi-threaded builds of
  one per-user kernel, chosen by batch size (the one loop over users); :func:`use_threads`.
- :mod:`estimators.kernels.rotations`: scalar quaternion and angle helpers.
- :mod:`estimators.kernels.records`: parameters and per-user state as named record arrays.

An algorithm's kernel lives in its stage package's ``_kernel`` module, beside the Python class that
drives it; its uncompiled ``py_func`` is the readable reference: inside ``with python_reference():``
every kernel runs uncompiled, which is how the tests check each compiled build against its source.
"""

from estimators.kernels.batch import (
    PARALLEL_MIN_BATCH,
    BatchKernel,
    python_reference,
    usable_cores,
    use_threads,
)
from estimators.kernels.records import param_record, record_dtype, state_records

__all__ = [
    "PARALLEL_MIN_BATCH",
    "BatchKernel",
    "param_record",
    "python_reference",
    "record_dtype",
    "state_records",
    "usable_cores",
    "use_threads",
]

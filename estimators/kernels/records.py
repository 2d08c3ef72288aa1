"""Named parameters and state for compiled kernels, as numpy record arrays.

A kernel reads its parameters by name (``p = prm[0]; p["gyro_noise"]``) from a one-element record
built from the parameter dataclass's own fields, so each parameter is written once: in the
dataclass, with its unit, default and check. Per-user state is a (B,) record array whose fields
(scalars or fixed-shape sub-arrays such as a quaternion or a covariance) are named where the
kernel module declares them, next to the code that reads them (``s = state[i]; s["q"][0]``).
Index fields by name (``p["name"]``), not as attributes: numba compiles both, but the uncompiled
``py_func`` gets numpy's plain record elements, which only support indexing (a ``np.recarray``
view would, at several microseconds per kernel call). In a parallel build, take the record
element (``prm[0]``, ``state[i]``) inside the ``prange`` loop: numba cannot hoist it.

Numba types a record by its field names, types and offsets, so renaming or reordering a field
changes the compiled signature: an on-disk cache can never feed stale offsets to new code. A
record argument costs the dispatcher about as little as a plain array (well under a microsecond).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from numbers import Real
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["param_record", "record_dtype", "state_records"]

Shape = tuple[int, ...]


def record_dtype(fields: Mapping[str, Shape]) -> np.dtype:
    """float64 record type: one field per name, shape ``()`` for a scalar, else a sub-array."""
    return np.dtype([(name, np.float64, shape) for name, shape in fields.items()])


def param_record(source: Any = None, exclude: tuple[str, ...] = (), **values: float) -> NDArray:
    """A (1,) float64 record of the numeric fields of a dataclass instance, then ``values``.

    Args:
        source: a dataclass instance; its ``bool``, ``int`` and ``float`` fields (in declaration
            order, booleans as 0.0/1.0) become record fields of the same name. Others (strings,
            nested specs, arrays) are skipped: pass what the kernel needs from them in ``values``.
        exclude: numeric fields of ``source`` the kernel does not read.
        values: further named values (unit conversions, derived constants); a name that is
            also a field of ``source`` replaces the field's value.

    Raises:
        TypeError: ``source`` is not a dataclass instance.
        ValueError: a value is not a finite-or-infinite real number (NaN is refused).
    """
    items: dict[str, float] = {}
    if source is not None:
        if not dataclasses.is_dataclass(source) or isinstance(source, type):
            raise TypeError(f"param_record: source must be a dataclass instance, got {source!r}")
        for f in dataclasses.fields(source):
            v = getattr(source, f.name)
            if f.name not in exclude and isinstance(v, Real):
                items[f.name] = float(v)
    for name, v in values.items():
        if not isinstance(v, Real) or v != v:
            raise ValueError(f"param_record: {name} must be a real number, got {v!r}")
        items[name] = float(v)
    out = np.zeros(1, record_dtype({name: () for name in items}))
    for name, v in items.items():
        out[0][name] = v
    return out


def state_records(fields: Mapping[str, Shape], batch_size: int) -> NDArray:
    """Zeroed (B,) record array of per-user kernel state with the named ``fields``."""
    return np.zeros(batch_size, record_dtype(fields))

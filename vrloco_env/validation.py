"""Range checks for configuration dataclasses: one error format across the project."""

from __future__ import annotations

import math
import numbers

__all__ = ["check_bool", "check_in_range"]


def check_in_range(obj: object, name: str, lo: float, hi: float, unit: str = "",
                   lo_open: bool = False, integer: bool = False) -> None:  # fmt: skip
    """Raise a ValueError naming ``Class.name`` unless the field is a finite real number with
    ``lo <= value <= hi`` (``lo < value`` when ``lo_open``); with ``integer``, an int (a bool,
    a float such as 1.5 or 600.0, or a string such as "600" is not)."""
    v = getattr(obj, name)
    real = isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)
    if integer and not (isinstance(v, numbers.Integral) and not isinstance(v, bool)):
        where = f"{type(obj).__name__}.{name}={v!r}"
        raise ValueError(f"{where}: must be an integer in [{lo:g}, {hi:g}] {unit}".rstrip())
    if not (real and (lo < v if lo_open else lo <= v) and v <= hi):
        bracket = "(" if lo_open else "["
        where = f"{type(obj).__name__}.{name}={v!r}"
        raise ValueError(f"{where}: must be in {bracket}{lo:g}, {hi:g}] {unit}".rstrip())


def check_bool(obj: object, name: str) -> None:
    """Raise a ValueError naming ``Class.name`` unless the field is True or False."""
    v = getattr(obj, name)
    if not isinstance(v, bool):
        raise ValueError(f"{type(obj).__name__}.{name}={v!r}: must be True or False")

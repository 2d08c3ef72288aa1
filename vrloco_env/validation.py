"""Range checks for configuration dataclasses: one error format across the project."""

from __future__ import annotations

import math

__all__ = ["check_in_range"]


def check_in_range(obj: object, name: str, lo: float, hi: float, unit: str = "",
                   lo_open: bool = False) -> None:  # fmt: skip
    """Raise a ValueError naming ``Class.name`` unless the field is a finite real number with
    ``lo <= value <= hi`` (``lo < value`` when ``lo_open``)."""
    v = getattr(obj, name)
    real = isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
    if not (real and (lo < v if lo_open else lo <= v) and v <= hi):
        bracket = "(" if lo_open else "["
        where = f"{type(obj).__name__}.{name}={v!r}"
        raise ValueError(f"{where}: must be in {bracket}{lo:g}, {hi:g}] {unit}".rstrip())

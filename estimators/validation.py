"""Checks for configuration dataclasses: one error format across the project (estimators, env
and agents alike).

Every check raises a ValueError that starts with ``Class.field=value:`` and says what is allowed,
so that a command line reports it in one line.
"""

from __future__ import annotations

import itertools
import math
import numbers

__all__ = ["check_bool", "check_in_range", "check_instance", "check_numbers", "value_repr"]


def value_repr(v: object, limit: int = 80) -> str:
    """``repr(v)`` on one line (an array's rows joined), cut to ``limit`` characters."""
    text = " ".join(repr(v).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _is_real(v: object) -> bool:
    """A finite real number, not a bool (an int too large for a float counts as infinite)."""
    if not isinstance(v, numbers.Real) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(v)
    except OverflowError:
        return False


def _g(x: float) -> str:
    """A bound for a message (bounds may be other fields' values: ints, Fractions, numpy)."""
    return f"{float(x):g}"


def check_in_range(obj: object, name: str, lo: float, hi: float, unit: str = "",
                   lo_open: bool = False, integer: bool = False,
                   allowed: str | None = None) -> None:  # fmt: skip
    """Raise a ValueError naming ``Class.name`` unless the field is a finite real number with
    ``lo <= value <= hi`` (``lo < value`` when ``lo_open``); with ``integer``, an int (a bool,
    a float such as 1.5 or 600.0, or a string such as "600" is not). ``allowed`` replaces the
    message's interval (``"(0, 3 g] m/s^2"`` where a bound is another field)."""
    v = getattr(obj, name)
    if allowed is not None and not (
        _is_real(v) and (lo < v if lo_open else lo <= v) and v <= hi
        and (not integer or isinstance(v, numbers.Integral))
    ):
        raise ValueError(f"{type(obj).__name__}.{name}={value_repr(v)}: must be {allowed}")
    if integer and not (isinstance(v, numbers.Integral) and not isinstance(v, bool)):
        where = f"{type(obj).__name__}.{name}={value_repr(v)}"
        raise ValueError(f"{where}: must be an integer in [{_g(lo)}, {_g(hi)}] {unit}".rstrip())
    if not (_is_real(v) and (lo < v if lo_open else lo <= v) and v <= hi):
        bracket = "(" if lo_open else "["
        where = f"{type(obj).__name__}.{name}={value_repr(v)}"
        raise ValueError(f"{where}: must be in {bracket}{_g(lo)}, {_g(hi)}] {unit}".rstrip())


def check_bool(obj: object, name: str) -> None:
    """Raise a ValueError naming ``Class.name`` unless the field is True or False."""
    v = getattr(obj, name)
    if not isinstance(v, bool):
        raise ValueError(f"{type(obj).__name__}.{name}={value_repr(v)}: must be True or False")


def check_instance(obj: object, name: str, kind: type | tuple[type, ...]) -> None:
    """Raise a ValueError naming ``Class.name`` unless the field is an instance of ``kind``."""
    v = getattr(obj, name)
    if not isinstance(v, kind):
        kinds = kind if isinstance(kind, tuple) else (kind,)
        allowed = " or ".join(k.__name__ for k in kinds)
        where = f"{type(obj).__name__}.{name}={value_repr(v)}"
        raise ValueError(f"{where}: must be of type {allowed}, got {type(v).__name__}")


def check_numbers(obj: object, name: str, lo: float, hi: float, unit: str = "",
                  length: int | None = None, min_length: int = 1,
                  ordered: bool = False) -> None:  # fmt: skip
    """Raise a ValueError naming ``Class.name`` unless the field is a tuple (or list) of finite
    real numbers in ``[lo, hi]``: exactly ``length`` of them if given, else at least
    ``min_length``; with ``ordered``, non-decreasing (a ``(low, high)`` pair)."""
    v = getattr(obj, name)
    if length is not None:
        count = f"{length} numbers"
    else:
        count = f"{min_length} or more numbers" if min_length > 1 else "one or more numbers"
    order = ", low <= high" if ordered else ""
    allowed = f"must be a tuple of {count} in [{_g(lo)}, {_g(hi)}] {unit}".rstrip() + order
    ok = (
        isinstance(v, tuple | list)
        and (len(v) == length if length is not None else len(v) >= min_length)
        and all(_is_real(x) and lo <= x <= hi for x in v)
        and (not ordered or all(a <= b for a, b in itertools.pairwise(v)))
    )
    if not ok:
        raise ValueError(f"{type(obj).__name__}.{name}={value_repr(v)}: {allowed}")

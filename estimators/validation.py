"""Checks for configuration dataclasses and function arguments: one error format across the
project (estimators, env and agents alike).

Every check raises a ValueError that starts with ``Class.field=value:`` (or ``name=value:`` for a
function argument) and says what is allowed, so that a command line reports it in one line. A
number is a real number that is not a bool (numpy scalars count; strings such as ``"1.5"`` do
not); it must be finite unless a check says otherwise.
"""

from __future__ import annotations

import itertools
import math
import numbers

import numpy as np

__all__ = [
    "check_bool",
    "check_choice",
    "check_condition",
    "check_in_range",
    "check_instance",
    "check_numbers",
    "check_value",
    "value_repr",
]


def value_repr(v: object, limit: int = 80) -> str:
    """``repr(v)`` on one line (an array's rows joined), cut to ``limit`` characters."""
    text = " ".join(repr(v).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _is_number(v: object, allow_inf: bool = False) -> bool:
    """A real number, not a bool, not NaN; finite, or +inf where ``allow_inf`` (an int too large
    for a float is neither)."""
    if not isinstance(v, numbers.Real) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(v) or (allow_inf and v == math.inf)
    except OverflowError:
        return False


def _is_whole(v: object) -> bool:
    """An integer (not a bool), or a finite real number with no fractional part (2.0)."""
    if isinstance(v, numbers.Integral):
        return not isinstance(v, bool)
    return _is_number(v) and float(v).is_integer()


def _g(x: float) -> str:
    """A bound for a message (bounds may be other fields' values: ints, Fractions, numpy)."""
    return f"{float(x):g}"


def _interval(lo: float, hi: float, lo_open: bool, hi_open: bool, allow_inf: bool) -> str:
    """``[lo, hi]`` with a round bracket on an open or an infinite (and excluded) side."""
    left = "(" if lo_open or float(lo) == -math.inf else "["
    right = ")" if hi_open or (float(hi) == math.inf and not allow_inf) else "]"
    return f"{left}{_g(lo)}, {_g(hi)}{right}"


def _in(v: float, lo: float, hi: float, lo_open: bool, hi_open: bool) -> bool:
    return (lo < v if lo_open else lo <= v) and (v < hi if hi_open else v <= hi)


def check_value(label: str, v: object, lo: float, hi: float, unit: str = "", *,
                lo_open: bool = False, hi_open: bool = False, integer: bool = False,
                whole: bool = False, allow_inf: bool = False,
                allowed: str | None = None) -> None:  # fmt: skip
    """Raise a ValueError naming ``label`` unless ``v`` is a number with ``lo <= v <= hi``.

    Args:
        label: what the message names (``"Class.field"``, or a function argument's name).
        v: the value.
        lo, hi: the bounds, included unless ``lo_open`` / ``hi_open``; either may be infinite
            (``hi=math.inf``: no upper bound, the message reads ``[lo, inf)``).
        unit: appended to the message's interval.
        integer: the value must be an int (numpy's too; a bool, 1.5, 600.0 or "600" is not).
        whole: the value must be an int or a float with no fractional part (2.0 is accepted).
        allow_inf: +inf is accepted (with ``hi=math.inf``; the message reads ``[lo, inf]``).
        allowed: replaces the message's "in [lo, hi] unit" (``"(0, 3 g] m/s^2"`` where a bound is
            another field).
    """
    ok = _is_number(v, allow_inf) and _in(v, lo, hi, lo_open, hi_open)
    if integer:
        ok = ok and isinstance(v, numbers.Integral)
    if whole:
        ok = ok and _is_whole(v)
    if ok:
        return
    if allowed is None:
        kind = "integer" if integer else "whole number" if whole else "number"
        if float(lo) == -math.inf and float(hi) == math.inf and not allow_inf:
            text = f"a finite {kind}"
        else:
            interval = _interval(lo, hi, lo_open, hi_open, allow_inf)
            article = "an" if integer else "a"
            text = f"in {interval}" if kind == "number" else f"{article} {kind} in {interval}"
        allowed = f"{text} {unit}".rstrip()
    raise ValueError(f"{label}={value_repr(v)}: must be {allowed}")


def check_in_range(obj: object, name: str, lo: float, hi: float, unit: str = "",
                   lo_open: bool = False, integer: bool = False,
                   allowed: str | None = None, *, hi_open: bool = False, whole: bool = False,
                   allow_inf: bool = False) -> None:  # fmt: skip
    """Raise a ValueError naming ``Class.name`` unless the field is a number in ``[lo, hi]``
    (the options as :func:`check_value`)."""
    check_value(f"{type(obj).__name__}.{name}", getattr(obj, name), lo, hi, unit,
                lo_open=lo_open, hi_open=hi_open, integer=integer, whole=whole,
                allow_inf=allow_inf, allowed=allowed)  # fmt: skip


def check_bool(obj: object, name: str) -> None:
    """Raise a ValueError naming ``Class.name`` unless the field is True or False; numpy's
    ``bool_`` is accepted and stored as the Python bool (a frozen dataclass too), so a config
    never holds a numpy scalar."""
    v = getattr(obj, name)
    if not isinstance(v, bool | np.bool_):
        raise ValueError(f"{type(obj).__name__}.{name}={value_repr(v)}: must be True or False")
    if not isinstance(v, bool):
        object.__setattr__(obj, name, bool(v))


def check_choice(obj: object, name: str, choices: tuple[object, ...]) -> None:
    """Raise a ValueError naming ``Class.name`` unless the field is one of ``choices``."""
    v = getattr(obj, name)
    # a bool is not 1 and a numpy array has no single truth value: compare kinds first
    if not any(type(v) is type(c) and v == c for c in choices):
        listed = ", ".join(str(c) for c in choices)
        raise ValueError(f"{type(obj).__name__}.{name}={value_repr(v)}: must be one of {listed}")


def check_condition(obj: object, name: str, ok: bool, allowed: str) -> None:
    """Raise ``Class.name=value: must be <allowed>`` unless ``ok`` (a rule no interval states:
    a bound set by another field, a divisor, a relation between fields)."""
    if not ok:
        v = getattr(obj, name)
        raise ValueError(f"{type(obj).__name__}.{name}={value_repr(v)}: must be {allowed}")


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
                  ordered: bool = False, *, strict: bool = False, lo_open: bool = False,
                  hi_open: bool = False, whole: bool = False) -> None:  # fmt: skip
    """Raise a ValueError naming ``Class.name`` unless the field is a tuple, a list or a 1-D
    array of finite numbers in ``[lo, hi]`` (round where ``lo_open`` / ``hi_open``): exactly
    ``length`` of them if given, else at least ``min_length``; with ``whole``, each an int or a
    float with no fractional part; with ``ordered``, non-decreasing (a ``(low, high)`` pair),
    increasing if also ``strict``."""
    v = getattr(obj, name)
    if length is not None:
        count = f"{length}"
    else:
        count = f"{min_length} or more" if min_length > 1 else "one or more"
    kind = "whole numbers" if whole else "numbers"
    if float(lo) == -math.inf and float(hi) == math.inf:
        where = f"finite {kind}"
    else:
        where = f"{kind} in {_interval(lo, hi, lo_open, hi_open, False)}"
    if not ordered:
        order = ""
    elif length == 2:
        order = ", low < high" if strict else ", low <= high"
    else:
        order = ", increasing" if strict else ", non-decreasing"
    allowed = f"must be a tuple of {count} {where} {unit}".rstrip() + order
    is_seq = isinstance(v, tuple | list) or (isinstance(v, np.ndarray) and v.ndim == 1)
    ok = (
        is_seq
        and (len(v) == length if length is not None else len(v) >= min_length)
        and all(_is_number(x) and _in(x, lo, hi, lo_open, hi_open) for x in v)
        and (not whole or all(_is_whole(x) for x in v))
        and (not ordered or all(a < b if strict else a <= b for a, b in itertools.pairwise(v)))
    )
    if not ok:
        raise ValueError(f"{type(obj).__name__}.{name}={value_repr(v)}: {allowed}")

"""Checks for configuration dataclasses and function arguments: one place for every argument
check of the project (estimators, env and agents alike).

Fields and numbers: every check raises a ValueError that starts with ``Class.field=value:`` (or
``name=value:`` for a function argument) and says what is allowed, so that a command line reports
it in one line. A number is a real number that is not a bool (numpy scalars count; strings such
as ``"1.5"`` do not); it must be finite unless a check says otherwise.

Arrays: the checks of the stages' array arguments (:func:`check_samples`, :func:`check_chunk`,
:func:`check_array`, :func:`check_xyz`, :func:`check_locomotion_update`, ...) return the argument
as float64 of the shape expected, or raise a ValueError naming the argument (and the stage, where
given as ``who``) and the shape or the values allowed.
"""

from __future__ import annotations

import itertools
import math
import numbers

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "check_array",
    "check_batch_size",
    "check_bool",
    "check_choice",
    "check_chunk",
    "check_condition",
    "check_in_range",
    "check_instance",
    "check_locomotion_update",
    "check_mask",
    "check_numbers",
    "check_numeric",
    "check_per_user",
    "check_positions",
    "check_rate",
    "check_samples",
    "check_stage_args",
    "check_step_intervals",
    "check_step_length",
    "check_value",
    "check_xyz",
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


def check_value(
    label: str,
    v: object,
    lo: float,
    hi: float,
    unit: str = "",
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    integer: bool = False,
    whole: bool = False,
    allow_inf: bool = False,
    allowed: str | None = None,
) -> None:
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


def check_in_range(
    obj: object,
    name: str,
    lo: float,
    hi: float,
    unit: str = "",
    lo_open: bool = False,
    integer: bool = False,
    allowed: str | None = None,
    *,
    hi_open: bool = False,
    whole: bool = False,
    allow_inf: bool = False,
) -> None:
    """Raise a ValueError naming ``Class.name`` unless the field is a number in ``[lo, hi]``
    (the options as :func:`check_value`)."""
    check_value(
        f"{type(obj).__name__}.{name}",
        getattr(obj, name),
        lo,
        hi,
        unit,
        lo_open=lo_open,
        hi_open=hi_open,
        integer=integer,
        whole=whole,
        allow_inf=allow_inf,
        allowed=allowed,
    )


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


def check_numbers(
    obj: object,
    name: str,
    lo: float,
    hi: float,
    unit: str = "",
    length: int | None = None,
    min_length: int = 1,
    ordered: bool = False,
    *,
    strict: bool = False,
    lo_open: bool = False,
    hi_open: bool = False,
    whole: bool = False,
) -> None:
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


# ------------------------------------------------------------------------------ stage arguments
def check_batch_size(batch_size: object, who: str = "") -> int:
    """``batch_size`` as an int >= 1, or a ValueError naming it (and ``who``, where given)."""
    check_value(
        f"{who}: batch_size" if who else "batch_size", batch_size, 1, math.inf, integer=True
    )
    return int(batch_size)  # type: ignore[call-overload]


def check_rate(rate: object, name: str = "fs", who: str = "") -> float:
    """A sample rate ``rate`` as a float in (0, 100000] Hz, or a ValueError naming the argument
    ``name`` (and ``who``, where given)."""
    check_value(f"{who}: {name}" if who else name, rate, 0.0, 100_000.0, "Hz", lo_open=True)
    return float(rate)  # type: ignore[arg-type]


def check_stage_args(batch_size: object, fs: object, who: str) -> tuple[int, float]:
    """``batch_size`` as an int >= 1 and ``fs`` as a float in [10, 2000] Hz (the range of the
    step detectors), or a ValueError naming ``who`` and the argument."""
    if isinstance(batch_size, bool) or not isinstance(batch_size, int | np.integer):
        raise ValueError(f"{who}: batch_size must be an integer >= 1, got {batch_size!r}")
    if batch_size < 1:
        raise ValueError(f"{who}: batch_size must be an integer >= 1, got {batch_size!r}")
    try:
        rate = float(fs)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{who}: fs must be a number in [10, 2000] Hz, got {fs!r}") from None
    if not (10.0 <= rate <= 2000.0):
        raise ValueError(f"{who}: fs must be in [10, 2000] Hz, got {fs!r}")
    return int(batch_size), rate


def check_numeric(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """``value`` as a float64 array, or a ValueError naming ``name``."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array") from None


def check_array(a: ArrayLike, name: str, shape: tuple[int, ...], finite: bool = True) -> NDArray:
    """``a`` as float64 of exactly ``shape`` (a -1 entry matches any length), finite unless
    ``finite`` is False, or a ValueError naming ``name``."""
    try:
        arr = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array: {exc}") from None
    if arr.ndim != len(shape) or any(
        s not in (-1, n) for s, n in zip(shape, arr.shape, strict=True)
    ):
        want = "(" + ", ".join("N" if s == -1 else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    if finite and not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or infinite entries")
    return arr


def check_xyz(a: ArrayLike, name: str, shape: tuple[int, ...] | None) -> NDArray[np.float64]:
    """``a`` as a float64 array of 3-vectors (last axis x, y, z), of exactly ``shape`` where
    given, or a ValueError naming ``name``."""
    try:
        arr = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array of 3-vectors: {exc}") from None
    if arr.ndim < 1 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have 3 columns (x, y, z), got shape {arr.shape}")
    if shape is not None and arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape} like gyr, got {arr.shape}")
    return arr


def check_samples(
    gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, batch_size: int, who: str
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None]:
    """The IMU samples of one attitude ``update`` as C-contiguous float64 arrays of shape
    (B, N, 3) (``mag`` may be None).

    Raises:
        ValueError: naming the argument and the shape expected.
    """
    out = []
    shape = None
    for name, value in (("gyr", gyr), ("acc", acc), ("mag", mag)):
        if value is None and name == "mag":
            out.append(None)
            continue
        try:
            arr = np.ascontiguousarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(
                f"{who}.update: {name} must be a float array of shape ({batch_size}, N, 3), got "
                f"{type(value).__name__}"
            ) from None
        if shape is None:
            if arr.ndim != 3 or arr.shape[0] != batch_size or arr.shape[2] != 3:
                raise ValueError(
                    f"{who}.update: {name} must have shape ({batch_size}, N, 3), got {arr.shape}"
                )
            shape = arr.shape
        elif arr.shape != shape:
            raise ValueError(
                f"{who}.update: {name} must have the shape of gyr {shape}, got {arr.shape}"
            )
        out.append(arr)
    return out[0], out[1], out[2]


def check_chunk(
    acc: ArrayLike, gyr: ArrayLike, quat: ArrayLike, batch_size: int, who: str
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The inputs of one step stage's ``update`` as C-contiguous float64 arrays (B, N, 3),
    (B, N, 3) and (B, N, 4) with one N, or a ValueError naming the argument and the shape
    expected."""
    out = []
    n = None
    for name, value, last in (("acc", acc, 3), ("gyr", gyr, 3), ("quat", quat, 4)):
        try:
            arr = np.ascontiguousarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{who}.update: {name} must be a numeric array") from None
        want = f"({batch_size}, {'N' if n is None else n}, {last})"
        if arr.ndim != 3 or arr.shape[0] != batch_size or arr.shape[2] != last:
            raise ValueError(f"{who}.update: {name} must have shape {want}, got {arr.shape}")
        if n is None:
            n = arr.shape[1]
        elif arr.shape[1] != n:
            raise ValueError(f"{who}.update: {name} must have shape {want}, got {arr.shape}")
        out.append(arr)
    return out[0], out[1], out[2]


# ------------------------------------------------------------------------------ locomotion
def check_step_intervals(params: object) -> None:
    """The step-interval fields a step-driven locomotion filter's parameters share:
    ``min_step_interval`` in [0.05, 2] s, ``max_step_interval`` from it to 10 s, and
    ``default_step_interval`` between the two (a ValueError naming the field otherwise)."""
    check_in_range(params, "min_step_interval", 0.05, 2.0, "s")
    lo = float(params.min_step_interval)  # type: ignore[attr-defined]
    check_in_range(
        params, "max_step_interval", lo, 10.0, allowed=f"in [min_step_interval={lo:g}, 10] s"
    )
    hi = float(params.max_step_interval)  # type: ignore[attr-defined]
    between = f"in [min_step_interval={lo:g}, max_step_interval={hi:g}] s"
    check_in_range(params, "default_step_interval", lo, hi, allowed=between)


def check_step_length(step_length: ArrayLike, shape: tuple[int, ...]) -> NDArray[np.float64]:
    """The step length (m), a number or an array broadcast to ``shape``, finite and in [0, 3]."""
    try:
        sl = np.asarray(step_length, dtype=np.float64)
        sl = np.broadcast_to(sl, shape).copy()
    except (TypeError, ValueError):
        raise ValueError(
            f"step_length must be a number or broadcast to shape {shape} (m)"
        ) from None
    if not np.all(np.isfinite(sl)) or np.any(sl < 0.0) or np.any(sl > 3.0):
        raise ValueError("step_length must be finite and in [0, 3] m")
    return sl


def check_per_user(
    value: ArrayLike | None,
    b: int,
    name: str,
    default: float,
    unit: str,
    bounds: tuple[float, float] | None = None,
    allowed: str | None = None,
) -> NDArray[np.float64]:
    """A (B,) float array from a scalar or (B,) input (``default`` where None); NaN and inf are
    rejected, and with ``bounds`` (lo, hi) a value outside them, the ValueError naming ``name``
    and ``unit`` (and the first value outside, against ``allowed``, the range in words, or the
    bounds)."""
    if value is None:
        return np.full(b, default)
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number or a ({b},) array ({unit})") from None
    if a.shape not in ((), (b,)):
        raise ValueError(f"{name} must have shape ({b},) or be a scalar, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or infinite values ({unit})")
    out = np.broadcast_to(a, (b,)).astype(np.float64)
    if bounds is not None:
        outside = (out < bounds[0]) | (out > bounds[1])
        if outside.any():
            where = allowed or f"[{bounds[0]:g}, {bounds[1]:g}]"
            raise ValueError(
                f"{name}={float(out[np.argmax(outside)])!r}: must be in {where} {unit}"
            )
    return out


def check_mask(mask: ArrayLike | None, b: int) -> NDArray[np.bool_]:
    """A (B,) bool ``mask`` of the users to act on (all where None), or a ValueError."""
    if mask is None:
        return np.ones(b, dtype=bool)
    m = np.asarray(mask)
    if m.shape != (b,) or m.dtype != np.bool_:
        raise ValueError(f"mask must be a bool array of shape ({b},), got {m.dtype} {m.shape}")
    return m


def check_positions(position: ArrayLike | None, b: int) -> NDArray[np.float64]:
    """(B, 2) finite positions (m) from ``position`` broadcast to that shape (zeros where None),
    or a ValueError."""
    if position is None:
        return np.zeros((b, 2))
    try:
        p = np.asarray(position, dtype=np.float64)
        p = np.broadcast_to(p, (b, 2)).copy()
    except (TypeError, ValueError):
        raise ValueError(f"position must broadcast to shape ({b}, 2) (m)") from None
    if not np.all(np.isfinite(p)):
        raise ValueError("position contains NaN or infinite values (m)")
    return p


def check_locomotion_update(
    steps: ArrayLike, yaw: ArrayLike, dt: float, bearing: ArrayLike | None, b: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, NDArray[np.float64]]:
    """Validate the arguments of a locomotion ``update`` for B users (shared by the models).

    Returns:
        steps (B,) float (counts >= 0), yaw (B,) rad, dt s, bearing (B,) rad.

    Raises:
        ValueError: a wrong shape, a NaN or infinite value, a negative step count or dt <= 0.
    """
    if (
        bearing is None
        and type(steps) is np.ndarray
        and type(yaw) is np.ndarray
        and steps.dtype == np.float64
        and yaw.dtype == np.float64
        and steps.shape == yaw.shape == (b,)
        and isinstance(dt, float)
        and 0.0 < dt <= 10.0
        and np.isfinite(yaw).all()
        and np.isfinite(steps).all()
        and (steps >= 0.0).all()
    ):  # the common call (an env step), valid: the same checks in a few microseconds
        return steps, yaw, dt, np.zeros(b)
    st = np.asarray(steps)
    if st.dtype == np.bool_:
        st = st.astype(np.float64)
    try:
        st = np.asarray(st, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"steps must be a ({b},) array of step counts") from None
    if st.shape != (b,):
        raise ValueError(f"steps must have shape ({b},) (step counts per user), got {st.shape}")
    if not np.all(np.isfinite(st)) or np.any(st < 0.0):
        raise ValueError("steps must be finite step counts >= 0")
    y = check_per_user(yaw, b, "yaw", 0.0, "rad")
    try:
        dtf = float(dt)
    except (TypeError, ValueError):
        raise ValueError(f"dt must be a number > 0 s, got {dt!r}") from None
    if not (math.isfinite(dtf) and 0.0 < dtf <= 10.0):
        raise ValueError(f"dt must be in (0, 10] s, got {dt!r}")
    br = check_per_user(bearing, b, "bearing", 0.0, "rad")
    return st, y, dtf, br

"""The shared checks of configuration fields and arguments (estimators.validation): what each
accepts, what it rejects, and that the message names the field, the value and the allowed set."""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import pytest

from estimators.validation import (
    check_bool,
    check_choice,
    check_condition,
    check_in_range,
    check_numbers,
    check_value,
)


@dataclass
class Cfg:
    x: object = 0.0


def raises(message: str, check, value, *args, **kwargs) -> None:
    """``check(Cfg(value), "x", *args, **kwargs)`` raises a ValueError matching ``message``."""
    with pytest.raises(ValueError, match=message):
        check(Cfg(value), "x", *args, **kwargs)


def accepts(check, value, *args, **kwargs) -> None:
    check(Cfg(value), "x", *args, **kwargs)


def test_closed_and_open_bounds():
    for v in (0.0, 0.5, 1.0, 1, np.float32(0.25), np.int64(1), Fraction(1, 3)):
        accepts(check_in_range, v, 0.0, 1.0)
    raises(r"^Cfg\.x=1\.5: must be in \[0, 1\] m$", check_in_range, 1.5, 0.0, 1.0, "m")
    raises(r"^Cfg\.x=0\.0: must be in \(0, 1\]$", check_in_range, 0.0, 0.0, 1.0, lo_open=True)
    raises(r"^Cfg\.x=1\.0: must be in \[0, 1\)$", check_in_range, 1.0, 0.0, 1.0, hi_open=True)
    accepts(check_in_range, 0.999, 0.0, 1.0, hi_open=True)
    raises(
        r"^Cfg\.x=-90: must be in \(-90, 90\) deg$",
        check_in_range,
        -90,
        -90,
        90,
        "deg",
        lo_open=True,
        hi_open=True,
    )
    raises(r"^Cfg\.x=nan: must be in \[0, 1\]$", check_in_range, math.nan, 0.0, 1.0)


def test_infinite_upper_bound_message_and_inf_values():
    # no upper bound: any finite number >= lo; inf itself is not a number the field takes
    accepts(check_in_range, 1e300, 0.0, math.inf)
    raises(r"^Cfg\.x=-1: must be in \[0, inf\) s$", check_in_range, -1, 0.0, math.inf, "s")
    raises(r"^Cfg\.x=inf: must be in \[0, inf\) s$", check_in_range, math.inf, 0.0, math.inf, "s")
    raises(r"^Cfg\.x=10+\.\.\.: must be in \[0, inf\)$", check_in_range, 10**400, 0.0, math.inf)
    # allow_inf: inf is a value (a constant bias, no blur effect); the bracket says so
    accepts(check_in_range, math.inf, 0.0, math.inf, lo_open=True, allow_inf=True)
    accepts(check_in_range, np.float64(math.inf), 0.0, math.inf, lo_open=True, allow_inf=True)
    raises(
        r"^Cfg\.x=0\.0: must be in \(0, inf\] px$",
        check_in_range,
        0.0,
        0.0,
        math.inf,
        "px",
        lo_open=True,
        allow_inf=True,
    )
    raises(r"^Cfg\.x=-inf: ", check_in_range, -math.inf, 0.0, math.inf, allow_inf=True)
    raises(r"^Cfg\.x=nan: ", check_in_range, math.nan, 0.0, math.inf, allow_inf=True)
    # both bounds infinite: "finite" is the whole rule
    accepts(check_in_range, -1e9, -math.inf, math.inf)
    raises(
        r"^Cfg\.x=inf: must be a finite number rad$",
        check_in_range,
        math.inf,
        -math.inf,
        math.inf,
        "rad",
    )


def test_bools_and_numeric_strings_are_not_numbers():
    raises(r"^Cfg\.x=True: must be in \[0, 10\]$", check_in_range, True, 0, 10)
    raises(r"^Cfg\.x='1\.5': must be in \[0, 10\]$", check_in_range, "1.5", 0, 10)
    raises(r"^Cfg\.x=None: ", check_in_range, None, 0, 10)
    raises(r"^Cfg\.x=\(True, 2\.0\): must be a tuple", check_numbers, (True, 2.0), 0, 10)
    raises(r"^Cfg\.x=array\(\[ True, False\]\)", check_numbers, np.array([True, False]), 0, 10)
    raises(r"^Cfg\.x=1: must be True or False$", check_bool, 1)
    accepts(check_bool, np.bool_(True))
    cfg = Cfg(np.False_)
    check_bool(cfg, "x")
    assert cfg.x is False  # stored as the Python bool: a config holds no numpy scalar


def test_integers_and_whole_numbers():
    accepts(check_in_range, 3, 1, 10, integer=True)
    accepts(check_in_range, np.int32(3), 1, 10, integer=True)
    raises(
        r"^Cfg\.x=3\.0: must be an integer in \[1, 10\]$", check_in_range, 3.0, 1, 10, integer=True
    )
    raises(r"^Cfg\.x=True: must be an integer", check_in_range, True, 0, 10, integer=True)
    raises(
        r"^Cfg\.x=0: must be an integer in \[1, inf\) frames$",
        check_in_range,
        0,
        1,
        math.inf,
        "frames",
        integer=True,
    )
    # a whole number: an int or a float without a fractional part (a count given as 5.0)
    for v in (5, 5.0, np.float64(5.0), np.int8(5)):
        accepts(check_in_range, v, 0, math.inf, whole=True)
    raises(
        r"^Cfg\.x=2\.5: must be a whole number in \[0, inf\)$",
        check_in_range,
        2.5,
        0,
        math.inf,
        whole=True,
    )
    raises(r"^Cfg\.x=True: must be a whole number", check_in_range, True, 0, 9, whole=True)
    raises(
        r"^Cfg\.x=inf: must be a whole number",
        check_in_range,
        math.inf,
        0,
        math.inf,
        whole=True,
        allow_inf=True,
    )
    accepts(check_numbers, (2.0, 8), 1, math.inf, length=2, ordered=True, whole=True)
    raises(
        r"^Cfg\.x=\(2, 8\.5\): must be a tuple of 2 whole numbers in \[1, inf\), low <= high$",
        check_numbers,
        (2, 8.5),
        1,
        math.inf,
        length=2,
        ordered=True,
        whole=True,
    )


def test_sequences_lengths_and_one_dimensional_arrays():
    accepts(check_numbers, [0.5, 0.6], 0.0, 1.0, length=2)
    accepts(check_numbers, np.array([0.5, 0.6]), 0.0, 1.0, length=2)
    accepts(check_numbers, np.array([1, 2, 3]), -math.inf, math.inf, "m", length=3)
    raises(
        r"^Cfg\.x=array\(\[\[0\.5\], \[0\.6\]\]\): must be a tuple of 2 numbers in \[0, 1\]$",
        check_numbers,
        np.array([[0.5], [0.6]]),
        0.0,
        1.0,
        length=2,
    )
    raises(
        r"^Cfg\.x=\(0\.5,\): must be a tuple of 2 numbers", check_numbers, (0.5,), 0, 1, length=2
    )
    raises(r"^Cfg\.x=\(\): must be a tuple of one or more numbers", check_numbers, (), 0, 1)
    raises(r"^Cfg\.x='ab': must be a tuple", check_numbers, "ab", 0, 1)
    raises(
        r"^Cfg\.x=\(0, nan, 0\): must be a tuple of 3 finite numbers m$",
        check_numbers,
        (0, math.nan, 0),
        -math.inf,
        math.inf,
        "m",
        length=3,
    )
    raises(
        r"^Cfg\.x=\(0\.0, 90\.0\): must be a tuple of 2 numbers in \(0, 180\) deg$",
        check_numbers,
        (0.0, 90.0),
        0.0,
        180.0,
        "deg",
        length=2,
        lo_open=True,
        hi_open=True,
    )
    raises(
        r"^Cfg\.x=\(90\.0, 180\.0\): ",
        check_numbers,
        (90.0, 180.0),
        0.0,
        180.0,
        length=2,
        hi_open=True,
    )


def test_ordering_non_decreasing_and_strict():
    accepts(check_numbers, (1.0, 1.0), 0.0, 5.0, length=2, ordered=True)
    raises(
        r"^Cfg\.x=\(2\.0, 1\.0\): must be a tuple of 2 numbers in \[0, 5\] m, low <= high$",
        check_numbers,
        (2.0, 1.0),
        0.0,
        5.0,
        "m",
        length=2,
        ordered=True,
    )
    # strict: a (near, far) depth range or a cadence band must have width
    accepts(check_numbers, np.array([0.5, 4.5]), 0.0, 10.0, length=2, ordered=True, strict=True)
    raises(
        r"^Cfg\.x=\(1\.0, 1\.0\): must be a tuple of 2 numbers in \[0, 5\] Hz, low < high$",
        check_numbers,
        (1.0, 1.0),
        0.0,
        5.0,
        "Hz",
        length=2,
        ordered=True,
        strict=True,
    )
    raises(r", increasing$", check_numbers, (1, 2, 2), 0, 5, ordered=True, strict=True)
    accepts(check_numbers, (1, 2, 2), 0, 5, ordered=True)


def test_bounds_from_other_fields_and_custom_rules():
    # a bound may be another field's value (an int, a Fraction, numpy) and the message may say so
    raises(
        r"^Cfg\.x=3: must be in \[0, width=2\] px$",
        check_in_range,
        3,
        0,
        Fraction(2),
        allowed="in [0, width=2] px",
    )
    raises(
        r"^Cfg\.x=True: must be in \[0, width=2\] px$",
        check_in_range,
        True,
        0,
        2,
        allowed="in [0, width=2] px",
    )
    raises(
        r"^Cfg\.x=7: must be a divisor of 100$",
        check_condition,
        7,
        100 % 7 == 0,
        "a divisor of 100",
    )
    accepts(check_condition, 5, 100 % 5 == 0, "a divisor of 100")


def test_choices_compare_kinds():
    accepts(check_choice, "ekf", ("ekf", "vqf"))
    raises(r"^Cfg\.x='ml': must be one of ekf, vqf$", check_choice, "ml", ("ekf", "vqf"))
    raises(r"^Cfg\.x=True: must be one of 1, 2$", check_choice, True, (1, 2))
    raises(r"^Cfg\.x=array", check_choice, np.array(["ekf"]), ("ekf",))


def test_function_arguments_are_named_alone():
    check_value("max_range", 5.0, 0.0, 1e6, "m", lo_open=True)
    with pytest.raises(ValueError, match=r"^max_range=0: must be in \(0, 1e\+06\] m$"):
        check_value("max_range", 0, 0.0, 1e6, "m", lo_open=True)
    with pytest.raises(ValueError, match=r"^spacing='30': must be in \(0, 100000\] m$"):
        check_value("spacing", "30", 0.0, 1e5, "m", lo_open=True)

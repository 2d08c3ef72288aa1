"""Eq (17) against the smooth filter on the same step events (agents.experiments.locomotion_table):
the smooth path keeps eq (17)'s distance and removes its jerk."""

from __future__ import annotations

import numpy as np
import pytest

from agents.experiments.locomotion_table import compare_locomotion

SL = 0.7


def test_compare_locomotion_table():
    """Distance within 2 % of eq (17); the smooth path is orders of magnitude less jerky."""
    table = compare_locomotion(cadences=(1.2, 1.7, 2.2), n_steps=20)
    np.testing.assert_allclose(table["distance_eq17"], 20 * SL)
    assert np.all(np.abs(table["distance_error_pct"]) < 2.0)
    assert np.all(table["jerk_ratio"] > 300.0)
    assert np.all(table["rms_jerk_smooth"] < 200.0)  # m/s^3
    assert np.all(table["stop_time"] < 2.5)
    # No burst of speed: at most the catch-up margin above SL x cadence, plus the filter's
    # overshoot (a second-order filter with damping 1/sqrt(2) overshoots a speed step by ~21 %).
    assert np.all(table["max_speed_smooth"] < 1.25 * 1.25 * SL * table["cadence"] + 0.05)
    # With a turn the paths differ only by the timing of the heading along them.
    turned = compare_locomotion(cadences=(1.7,), n_steps=20, turn_deg=90.0)
    assert abs(turned["distance_error_pct"][0]) < 2.0
    assert turned["end_gap"][0] < 1.0


def test_compare_locomotion_bad_inputs():
    with pytest.raises(ValueError, match="cadences"):
        compare_locomotion(cadences=(0.1,))

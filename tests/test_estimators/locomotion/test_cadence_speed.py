"""Cadence-proportional speed (estimators.locomotion.cadence_speed): speed, distance, stopping,
continuity against eq (17), reset, and what its compiled-vs-source case covers."""

from __future__ import annotations

import numpy as np
import pytest
from kernel_cases.steps import CASES as STEP_CASES
from kernel_cases.steps import step_counts

from estimators.locomotion.cadence_speed import CadenceSpeed, CadenceSpeedParams
from estimators.locomotion.dead_reckoning import DeadReckoning
from estimators.registry import StageError
from estimators.stages import LOCOMOTION, Locomotion

SL = 0.7
LATENCY = 0.135  # s, the gait detector's confirmation delay (as compare_locomotion)


def walk_events(n_steps, cadence, fs, total, pre=1.0):
    """Per-update step counts over ``total`` s: heel strikes at ``pre`` + k / cadence, confirmed
    ``LATENCY`` s later, the first step together with the second (as the gait detector)."""
    n = round(total * fs)
    counts = np.zeros(n)
    idx = np.ceil((pre + LATENCY + np.arange(n_steps) / cadence) * fs - 1e-9).astype(int) - 1
    idx[0] = idx[1]
    np.add.at(counts, idx, 1.0)
    return counts


def drive(loco, counts, yaw=0.0, fs=100.0, bearing=None):
    """Run ``loco`` over (B, N) counts; positions (B, N, 2) and speeds (B, N) after each update."""
    b, n = counts.shape
    yaw = np.broadcast_to(np.asarray(yaw, dtype=np.float64), (n, b)) if np.ndim(yaw) < 2 else yaw
    pos, speed = np.empty((b, n, 2)), np.empty((b, n))
    for k in range(n):
        pos[:, k] = loco.update(counts[:, k], np.ascontiguousarray(yaw[k]), 1.0 / fs, bearing)
        speed[:, k] = loco.speed
    return pos, speed


CADENCES = np.array([1.2, 1.7, 2.2])


@pytest.fixture(scope="module")
def walk100():
    """30 steps at each cadence, updates at 100 Hz, 30 s."""
    counts = np.stack([walk_events(30, c, 100.0, 30.0) for c in CADENCES])
    loco = CadenceSpeed(3, SL)
    pos, speed = drive(loco, counts)
    return counts, loco, pos, speed


# ---------------------------------------------------------------------------- steady stepping
def test_steady_stepping_speed_is_sl_times_cadence(walk100):
    counts, _, _, speed = walk100
    t = np.arange(1, counts.shape[1] + 1) / 100.0
    for u, c in enumerate(CADENCES):
        # From the third event on (the cadence known, the ramp done) to the last event.
        events = np.flatnonzero(counts[u]) / 100.0
        mid = (t > events[2] + 0.5) & (t < events[-1])
        # Event times quantised to 10 ms: the interval of two steps is off by at most 1 %.
        np.testing.assert_allclose(speed[u, mid], SL * c, rtol=0.015)
        np.testing.assert_allclose(speed[u, mid].mean(), SL * c, rtol=0.005)


def test_steady_stepping_distance_is_sl_times_steps(walk100):
    _, loco, pos, _ = walk100
    p = CadenceSpeedParams()
    # Module docstring: SL x N up to SL |T / default_step_interval - 1| (the first interval runs
    # at the default cadence), plus the quantisation of the events and the stop timeout.
    bound = SL * np.abs(1.0 / CADENCES / p.default_step_interval - 1.0) + 0.02 * SL * 30
    assert np.all(np.abs(loco.distance - SL * 30) < bound), loco.distance
    np.testing.assert_allclose(np.abs(loco.distance - SL * 30) / (SL * 30), 0.0, atol=0.025)
    # Along the heading (yaw 0): straight east, the path length equals the displacement.
    np.testing.assert_allclose(pos[:, -1, 0], loco.distance, rtol=1e-12)
    np.testing.assert_array_equal(pos[:, -1, 1], 0.0)


def test_control_rate_updates_give_the_same_walk():
    """At the env's 10 Hz the speed still averages SL x cadence and the distance is kept."""
    counts = np.stack([walk_events(30, c, 10.0, 30.0) for c in CADENCES])
    loco = CadenceSpeed(3, SL)
    _, speed = drive(loco, counts, fs=10.0)
    t = np.arange(1, counts.shape[1] + 1) / 10.0
    for u, c in enumerate(CADENCES):
        events = np.flatnonzero(counts[u]) / 10.0
        mid = (t > events[2] + 0.5) & (t < events[-1])
        np.testing.assert_allclose(speed[u, mid].mean(), SL * c, rtol=0.03)
        np.testing.assert_allclose(speed[u, mid], SL * c, rtol=0.12)  # 0.1 s quantisation
    np.testing.assert_allclose(loco.distance, SL * 30, rtol=0.03)


def test_cadence_change_is_followed_within_a_stride_and_a_ramp():
    fs = 100.0
    strikes = np.concatenate([1.0 + np.arange(12) / 1.5, 1.0 + 11 / 1.5 + np.arange(1, 15) / 2.2])
    n = round(20.0 * fs)
    counts = np.zeros((1, n))
    idx = np.ceil((strikes + LATENCY) * fs - 1e-9).astype(int) - 1
    idx[0] = idx[1]
    np.add.at(counts[0], idx, 1.0)
    loco = CadenceSpeed(1, SL)
    _, walking = drive(loco, counts[:, : idx[-1] + 1])
    np.testing.assert_allclose(loco.cadence, 2.2, rtol=0.02)
    np.testing.assert_allclose(loco.step_interval, 1 / 2.2, rtol=0.02)
    _, stopping = drive(loco, counts[:, idx[-1] + 1 :])
    speed = np.concatenate([walking, stopping], axis=1)
    t = np.arange(1, n + 1) / fs
    change = strikes[11] + LATENCY
    p = CadenceSpeedParams()
    before = (t > change - 2.0) & (t < change)
    after = (t > change + p.cadence_window / 2.2 + p.ramp_time + 0.02) & (t < strikes[-1])
    np.testing.assert_allclose(speed[0, before], SL * 1.5, rtol=0.015)
    np.testing.assert_allclose(speed[0, after], SL * 2.2, rtol=0.015)


# ---------------------------------------------------------------------------- stopping
def test_stopping_brings_the_speed_to_zero_within_the_stated_time(walk100):
    counts, loco, pos, speed = walk100
    p = loco.params
    fs = 100.0
    t = np.arange(1, counts.shape[1] + 1) / fs
    for u, c in enumerate(CADENCES):
        last = np.flatnonzero(counts[u])[-1] / fs  # the last event's time stamp
        deadline = last + p.stop_time(1.0 / c) + 1.0 / fs + 1e-9
        assert np.all(speed[u, t >= deadline] == 0.0)
        # ... and not much earlier: full speed until the timeout, then the ramp.
        timeout = last + p.stop_factor / c
        assert np.all(speed[u, (t > last) & (t < timeout - 0.02)] > 0.98 * SL * c)
        assert np.any(speed[u, t > deadline - 0.1] > 0.0)
        settled = pos[u, t >= deadline]
        np.testing.assert_array_equal(settled, np.broadcast_to(settled[0], settled.shape))
    assert np.all(loco.cadence == 0.0) and np.isnan(loco.step_interval).all()
    np.testing.assert_allclose(p.stop_time(1.0 / 1.7), 2.0 / 1.7 + 0.5)
    assert p.stop_time(10.0) == p.stop_factor * p.max_step_interval + p.ramp_time


def test_no_motion_without_steps():
    loco = CadenceSpeed(2, SL, position=[[1.0, 2.0], [-3.0, 0.5]])
    for k in range(300):
        loco.update(np.zeros(2), np.array([0.01 * k, -3.0 + 0.02 * k]), 0.01)
        assert np.all(loco.speed == 0.0)
    np.testing.assert_array_equal(loco.position, [[1.0, 2.0], [-3.0, 0.5]])
    np.testing.assert_array_equal(loco.distance, 0.0)
    assert np.all(loco.cadence == 0.0)


# ---------------------------------------------------------------------------- continuity
def test_speed_is_continuous_and_jerk_bounded_unlike_eq17(walk100):
    counts, loco, pos, speed = walk100
    fs = 100.0
    eq17 = DeadReckoning(3, SL)
    pe = np.stack([eq17.update(counts[:, k], 0.0, 1 / fs) for k in range(counts.shape[1])], 1)
    jerk = np.diff(pos, 3, axis=1) * fs**3
    jerk17 = np.diff(pe, 3, axis=1) * fs**3
    rms = np.sqrt(np.mean(np.sum(jerk**2, -1), 1))
    rms17 = np.sqrt(np.mean(np.sum(jerk17**2, -1), 1))
    assert np.all(rms17 / rms > 1e4), rms17 / rms
    # No jump of speed or acceleration: the largest change is the start from rest to the top
    # speed v (about SL x cadence; SL / default_step_interval for the first interval), whose
    # cubic peaks at 1.5 v / ramp_time of acceleration and 6 v / ramp_time^2 of jerk.
    ramp = loco.params.ramp_time
    top = speed.max(axis=1)
    np.testing.assert_allclose(top, np.maximum(SL * CADENCES, SL / 0.8), rtol=0.015)
    acc = np.diff(speed, axis=1) * fs
    assert np.all(np.abs(acc).max(axis=1) <= 1.5 * top / ramp)
    jrk = np.diff(speed, 2, axis=1) * fs**2
    assert np.all(np.abs(jrk).max(axis=1) <= 6.0 * top / ramp**2)
    assert np.all(speed >= 0.0)


def test_heading_bearing_and_turns():
    fs = 100.0
    counts = np.stack([walk_events(10, 2.0, fs, 10.0)] * 3)
    loco = CadenceSpeed(3, SL)
    pos, _ = drive(loco, counts, yaw=np.pi / 2, bearing=np.array([0.0, np.pi, np.pi / 2]))
    d = loco.distance
    np.testing.assert_allclose(pos[:, -1], [[0, d[0]], [0, -d[1]], [-d[2], 0]], atol=1e-9)
    np.testing.assert_allclose(loco.heading, np.pi / 2)
    # A turn of the yaw across +-pi bends the path without a jump; path length unchanged.
    n = counts.shape[1]
    yaw = np.angle(np.exp(1j * np.linspace(np.pi - 1.0, np.pi + 1.0, n)))
    turning = CadenceSpeed(1, SL)
    pt, _ = drive(turning, counts[:1], yaw=yaw[:, None])
    np.testing.assert_allclose(turning.distance, d[0], rtol=1e-12)
    steps = np.linalg.norm(np.diff(pt[0], axis=0), axis=1)
    np.testing.assert_allclose(steps.sum(), d[0], rtol=1e-3)
    assert np.all(np.abs(turning.heading) <= np.pi)


# ---------------------------------------------------------------------------- reset, kernel
def test_reset_rows_are_independent():
    fs = 100.0
    counts = np.stack([walk_events(20, c, fs, 16.0) for c in (1.4, 1.9, 2.3)])
    n, cut = counts.shape[1], 700
    yaw = np.stack([np.linspace(0, 1, n), np.linspace(0, -2, n), np.zeros(n)], axis=1)
    whole = CadenceSpeed(3, [0.6, 0.7, 0.8])
    pw, sw = drive(whole, counts, yaw=yaw)
    split = CadenceSpeed(3, [0.6, 0.7, 0.8])
    drive(split, counts[:, :cut], yaw=yaw[:cut])
    split.reset(np.array([False, True, False]), position=[4.0, -1.0], heading=0.5)
    np.testing.assert_array_equal(split.position[1], [4.0, -1.0])
    assert split.distance[1] == 0.0 and split.speed[1] == 0.0 and split.heading[1] == 0.5
    ps, ss = drive(split, counts[:, cut:], yaw=yaw[cut:])
    np.testing.assert_array_equal(ps[[0, 2]], pw[[0, 2], cut:])
    np.testing.assert_array_equal(ss[[0, 2]], sw[[0, 2], cut:])
    # The reset user is a fresh one from there (event times differ only in their rounding).
    fresh = CadenceSpeed(1, 0.7, position=[4.0, -1.0], heading=0.5)
    pf, sf = drive(fresh, counts[1:2, cut:], yaw=yaw[cut:, 1:2])
    np.testing.assert_allclose(ps[1], pf[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(ss[1], sf[0], rtol=0, atol=1e-9)
    # Batch rows equal single runs.
    single = CadenceSpeed(1, 0.8)
    p1, _ = drive(single, counts[2:3], yaw=yaw[:, 2:3])
    np.testing.assert_array_equal(p1[0], pw[2])


def test_the_kernel_case_stops_and_restarts():
    """The compiled-vs-source case (``kernel_cases/steps.py``) stops a user for a while (speed
    exactly 0) and starts it again, and releases two steps in one update."""
    speed = STEP_CASES["cadence_speed"]()["speed"]
    assert np.any(speed[60:110, 1] == 0.0) and speed[110:, 1].max() > 0.0
    assert step_counts().max() == 2.0


def test_registry_build_and_protocol():
    loco = LOCOMOTION.build("cadence_speed", 3, 0.7)
    assert isinstance(loco, CadenceSpeed) and isinstance(loco, Locomotion)
    assert loco.batch_size == 3 and loco.params == CadenceSpeedParams()
    np.testing.assert_array_equal(loco.step_length, 0.7)
    custom = LOCOMOTION.build(CadenceSpeedParams(ramp_time=0.2), 2, [0.6, 0.8])
    assert isinstance(custom, CadenceSpeed) and custom.params.ramp_time == 0.2
    np.testing.assert_array_equal(custom.step_length, [0.6, 0.8])
    for _ in range(100):
        loco.update(np.ones(3), 0.0, 0.1)
    assert np.all(loco.distance > 5.0)
    with pytest.raises(StageError, match="step_length"):
        LOCOMOTION.build("cadence_speed", 2, 5.0)


@pytest.mark.parametrize(
    ("field", "value", "allowed"),
    [
        ("ramp_time", 0.0, r"in \[0.05, 3\] s"),
        ("ramp_time", float("nan"), r"in \[0.05, 3\] s"),
        ("stop_factor", 0.5, r"in \[1, 5\]"),
        ("cadence_window", 2.5, r"an integer in \[1, 16\]"),
        ("cadence_window", 0, r"an integer in \[1, 16\]"),
        ("cadence_window", True, r"an integer in \[1, 16\]"),
        ("min_step_interval", 0.01, r"in \[0.05, 2\] s"),
        ("max_step_interval", 0.2, r"in \[min_step_interval=0.285714, 10\] s"),
        ("default_step_interval", 2.0, r"in \[min_step_interval=.*, max_step_interval=1.2\] s"),
        ("ramp_time", "fast", r"in \[0.05, 3\] s"),
    ],
)
def test_bad_params_name_the_field(field, value, allowed):
    with pytest.raises(ValueError, match=rf"CadenceSpeedParams\.{field}=.*must be {allowed}"):
        CadenceSpeedParams(**{field: value})


def test_bad_inputs():
    with pytest.raises(ValueError, match="batch_size"):
        CadenceSpeed(0)
    with pytest.raises(ValueError, match="params must be a CadenceSpeedParams"):
        CadenceSpeed(1, SL, params={"ramp_time": 0.2})
    loco = CadenceSpeed(2)
    with pytest.raises(ValueError, match="yaw contains NaN"):
        loco.update([0, 1], [0.0, np.nan], 0.01)
    with pytest.raises(ValueError, match="steps must be finite step counts >= 0"):
        loco.update([-1, 0], 0.0, 0.01)
    with pytest.raises(ValueError, match="dt must be in"):
        loco.update([0, 0], 0.0, 0.0)
    with pytest.raises(ValueError, match="mask must be a bool array"):
        loco.reset([0, 1])

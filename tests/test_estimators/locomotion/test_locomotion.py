"""Eq (17) dead reckoning and the smooth-locomotion Kalman filter."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.locomotion import (
    SmoothLocomotion,
    SmoothParams,
    make_locomotion,
)
from estimators.locomotion.dead_reckoning import DeadReckoning, dead_reckon
from estimators.stages import Locomotion

SL = 0.7


def walk_events(n_steps: int, cadence: float, fs: float, total: float, pre: float = 1.0):
    """Per-sample step counts over ``total`` s: a bout starting at ``pre`` s, delivered as the
    gait detector does (the first step together with the second)."""
    n = round(total * fs)
    counts = np.zeros(n)
    idx = np.round((pre + np.arange(n_steps) / cadence) * fs).astype(int)
    idx[0] = idx[1]
    np.add.at(counts, idx, 1.0)
    return counts


# ---------------------------------------------------------------------------- eq (17)
def test_eq17_geometry():
    dr = DeadReckoning(3, step_length=[0.7, 0.5, 0.7])
    dr.update([1, 1, 0], [0.0, np.pi / 2, 1.0], 0.01)
    np.testing.assert_allclose(dr.position, [[0.7, 0.0], [0.0, 0.5], [0.0, 0.0]], atol=1e-12)
    dr.update([2, 0, 1], [np.pi, 0.0, 0.0], 0.01, bearing=[0.0, 0.0, np.pi])  # 2 steps; backward
    np.testing.assert_allclose(dr.position, [[-0.7, 0.0], [0.0, 0.5], [-0.7, 0.0]], atol=1e-12)
    np.testing.assert_allclose(dr.distance, [2.1, 0.5, 0.7])
    np.testing.assert_allclose(dr.heading, [np.pi, 0.0, 0.0])
    # Still: no step, no motion, whatever the heading does.
    before = dr.position
    for yaw in np.linspace(-3, 3, 7):
        dr.update(np.zeros(3), yaw, 0.1)
    np.testing.assert_array_equal(dr.position, before)


def test_dead_reckon_offline_forms_agree():
    rng = np.random.default_rng(3)
    n = 200
    yaw = np.cumsum(rng.normal(0, 0.05, n))
    idx = np.sort(rng.choice(n, 30, replace=False))
    idx = np.concatenate([idx, idx[:2]])  # two samples carry two steps
    counts = np.bincount(idx, minlength=n).astype(float)
    p_idx = dead_reckon(idx, yaw, SL)
    p_cnt = dead_reckon(counts, yaw, SL)
    np.testing.assert_allclose(p_idx, p_cnt)
    assert dead_reckon(counts > 0, yaw, SL)[-1].tolist() != p_cnt[-1].tolist()
    # Streaming equals offline, and a batch (B, N) equals its rows.
    dr = DeadReckoning(1, SL)
    stream = np.stack([dr.update(counts[k : k + 1], yaw[k], 0.01)[0] for k in range(n)])
    np.testing.assert_allclose(stream, p_cnt)
    both = dead_reckon(np.stack([counts, counts[::-1].copy()]), np.stack([yaw, yaw]), SL)
    np.testing.assert_allclose(both[0], p_cnt)
    np.testing.assert_allclose(np.linalg.norm(np.diff(p_cnt, axis=0), axis=1).sum(), SL * 32)


def test_eq17_bad_inputs():
    with pytest.raises(ValueError, match="step_length"):
        DeadReckoning(2, step_length=-0.1)
    dr = DeadReckoning(2)
    with pytest.raises(ValueError, match="yaw contains NaN"):
        dr.update([1, 0], [np.nan, 0.0], 0.1)
    with pytest.raises(ValueError, match=r"steps must have shape \(2,\)"):
        dr.update([1, 0, 0], [0.0, 0.0], 0.1)
    with pytest.raises(ValueError, match="steps must be finite step counts >= 0"):
        dr.update([-1, 0], [0.0, 0.0], 0.1)
    with pytest.raises(ValueError, match="dt must be in"):
        dr.update([1, 0], [0.0, 0.0], 0.0)
    with pytest.raises(ValueError, match="yaw must have shape"):
        dr.update([1, 0], [0.0, 0.0, 0.0], 0.1)
    with pytest.raises(ValueError, match="step indices"):
        dead_reckon(np.array([0, 10]), np.zeros(5))
    with pytest.raises(ValueError, match="yaw contains NaN"):
        dead_reckon(np.ones(3), np.array([0.0, np.nan, 0.0]))
    with pytest.raises(ValueError, match="steps must have the shape of yaw"):
        dead_reckon(np.ones(4), np.zeros(5))


# ---------------------------------------------------------------------------- smooth locomotion
def test_smooth_steady_speed_and_no_drift():
    fs = 100.0
    cad = np.array([1.2, 1.8, 2.2])
    counts = np.stack([walk_events(30, c, fs, 40.0) for c in cad])
    n = counts.shape[1]
    loco = SmoothLocomotion(3, SL)
    speed = np.empty((3, n))
    pos = np.empty((3, n, 2))
    for k in range(n):
        pos[:, k] = loco.update(counts[:, k], 0.3, 1 / fs)
        speed[:, k] = loco.speed
    t = np.arange(1, n + 1) / fs
    for u, c in enumerate(cad):
        mid = (t > 1.0 + 12 / c) & (t < 1.0 + 27 / c)  # after the catch-up of the first step
        # SL x cadence, to within the ripple of event times quantised to samples (83-84 samples
        # per step at 1.2 steps/s).
        np.testing.assert_allclose(speed[u, mid], SL * c, rtol=0.04)
        np.testing.assert_allclose(speed[u, mid].mean(), SL * c, rtol=0.01)
        assert np.all(np.abs(np.diff(speed[u])) * fs < 15.0)  # no speed jump (m/s^2)
    # After stopping: speed decays to zero and the position stays put (no drift).
    end_walk = 1.0 + 29 / cad.min() + 3.0
    assert np.all(np.abs(speed[:, t > end_walk]) < 1e-3)
    settled = pos[:, t > end_walk + 1.0]
    assert np.all(np.abs(settled - settled[:, :1]) < 1e-3)
    np.testing.assert_allclose(loco.distance, 30 * SL, rtol=0.02)
    np.testing.assert_allclose(loco.target_distance, 30 * SL)
    direction = pos[:, -1] / np.linalg.norm(pos[:, -1], axis=-1, keepdims=True)
    np.testing.assert_allclose(direction, np.tile([np.cos(0.3), np.sin(0.3)], (3, 1)), atol=1e-6)


def test_smooth_stop_time_constant():
    """Once the reference stops, the speed decays as the documented second-order filter."""
    p = SmoothParams(distance_bandwidth_hz=1.0)
    fs = 200.0
    loco = SmoothLocomotion(1, SL, params=p)
    counts = walk_events(12, 2.0, fs, 12.5)
    v = []
    for c in counts:
        loco.update([c], 0.0, 1 / fs)
        v.append(loco.speed[0])
    v = np.abs(np.asarray(v))
    last = np.flatnonzero(counts)[-1]
    # Past the end of the reference ramp (at most one step interval + catch-up after the last
    # event), the speed envelope falls by e per stop_time_constant (+-30 %, it rings at 1 Hz).
    k0 = last + round(1.0 * fs)
    tc = p.stop_time_constant
    assert np.isclose(tc, 1 / (np.sqrt(0.5) * 2 * np.pi))
    k1 = k0 + round(3 * tc * fs)
    ratio = v[k1 : k1 + round(0.5 * fs)].max() / v[k0 : k0 + round(0.5 * fs)].max()
    assert np.exp(-3 * 1.3) < ratio < np.exp(-3 * 0.7)


def test_smooth_without_steps_never_moves():
    loco = SmoothLocomotion(2, SL, position=[[1.0, 2.0], [-3.0, 0.5]])
    for k in range(500):
        loco.update(np.zeros(2), np.array([0.01 * k, -3.0 + 0.02 * k]), 0.01)
    np.testing.assert_array_equal(loco.position, [[1.0, 2.0], [-3.0, 0.5]])
    assert np.all(loco.distance == 0.0)


def test_smooth_heading_tracks_yaw_across_the_wrap():
    loco = SmoothLocomotion(1, SL)
    yaw = np.pi - 0.3 + 0.6 * np.arange(300) / 300  # crosses +pi -> -pi
    err = []
    for y in yaw:
        loco.update([0.0], [np.angle(np.exp(1j * y))], 0.01)
        err.append(np.angle(np.exp(1j * (loco.heading[0] - y))))
    assert np.max(np.abs(err[50:])) < 0.01  # rad, a 2 rad/s ramp would lag more without omega
    assert np.all(np.abs(loco.heading) <= np.pi)


def test_smooth_batch_equals_single_runs_and_rate_independence():
    fs = 100.0
    counts = np.stack([walk_events(15, c, fs, 14.0) for c in (1.3, 2.0)])
    yaw = np.stack([np.linspace(0, 1, 1400), np.linspace(0, -2, 1400)])
    both = SmoothLocomotion(2, [0.6, 0.8])
    for k in range(1400):
        both.update(counts[:, k], yaw[:, k], 1 / fs)
    for u, sl in enumerate((0.6, 0.8)):
        one = SmoothLocomotion(1, sl)
        for k in range(1400):
            one.update(counts[u : u + 1, k], yaw[u : u + 1, k], 1 / fs)
        np.testing.assert_array_equal(one.position[0], both.position[u])
    # Updating at 10 Hz (the control rate) with the same events gives the same distance.
    coarse = SmoothLocomotion(2, [0.6, 0.8])
    for k in range(0, 1400, 10):
        coarse.update(counts[:, k : k + 10].sum(axis=1), yaw[:, k + 9], 0.1)
    np.testing.assert_allclose(coarse.distance, both.distance, rtol=0.01)


def test_reset_and_protocol():
    for kind in ("eq17", "smooth"):
        loco = make_locomotion(kind, 2, SL)
        assert isinstance(loco, Locomotion)
        for _ in range(200):
            loco.update([1, 1], 0.0, 0.05)
        loco.reset(np.array([True, False]), position=[5.0, 5.0], heading=0.0)
        np.testing.assert_array_equal(loco.position[0], [5.0, 5.0])
        assert loco.distance[0] == 0.0 and loco.distance[1] > 10.0
    with pytest.raises(ValueError, match="unknown locomotion kind"):
        make_locomotion("teleport", 1)


def test_smooth_bad_inputs():
    with pytest.raises(ValueError, match="step_length"):
        SmoothLocomotion(1, step_length=-0.5)
    with pytest.raises(ValueError, match="batch_size"):
        SmoothLocomotion(0)
    loco = SmoothLocomotion(2)
    with pytest.raises(ValueError, match="yaw contains NaN"):
        loco.update([0, 1], [0.0, np.nan], 0.01)
    with pytest.raises(ValueError, match=r"steps must have shape \(2,\)"):
        loco.update(np.zeros((2, 1)), 0.0, 0.01)
    with pytest.raises(ValueError, match="dt must be in"):
        loco.update([0, 0], 0.0, -0.01)
    with pytest.raises(ValueError, match="bearing contains NaN"):
        loco.update([0, 0], 0.0, 0.01, bearing=[np.inf, 0.0])
    with pytest.raises(ValueError, match=r"SmoothParams.distance_bandwidth_hz="):
        SmoothParams(distance_bandwidth_hz=0.0)
    with pytest.raises(ValueError, match=r"SmoothParams.default_step_interval="):
        SmoothParams(default_step_interval=5.0)

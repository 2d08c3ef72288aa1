"""Gait detector (Zhang 2021 eqs 15-16), offline and streaming, and eq (17) fed by it.

The synthetic head: a rigid head turning about the neck pivot with the IMU 9 cm ahead of and
12 cm above it; stepping in place moves the pivot vertically with one zero-mean heel-strike pulse
per step (peak 0.1-0.5 g, so |f| peaks at 1.1-1.5 g; a few cm of head bob) plus a lateral sway;
accelerations by finite differences at 1 kHz, then sampled, biased and noised.
"""

from __future__ import annotations

import numpy as np
import pytest

from agents.benchmark.step_matching import step_f1
from estimators.io.oxford import load_oxford
from estimators.locomotion.dead_reckoning import DeadReckoning
from estimators.rotations import GRAVITY, quat_from_ypr, quat_rotate, quat_rotate_inverse
from estimators.steps import GaitParams, StepDetector, detect_steps

FS = 100.0
UP = 10  # fine-grid oversampling for the physics
IMU_LEVER = np.array([0.09, 0.0, 0.12])  # m, forehead IMU relative to the neck pivot


def synth_head(
    rng: np.random.Generator,
    plan: list[tuple],
    *,
    fs: float = FS,
    peak_g: tuple[float, float] = (1.1, 1.5),
    gestures: tuple[tuple[float, float], ...] = ((0.0, 0.5), (0.0, 0.5), (0.0, 0.5)),
    scan: tuple[float, float] = (0.0, 0.3),
    noise: float = 0.02,
    bias: float = 0.1,
    bias_vec: np.ndarray | None = None,
    double_bump: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Specific force of a forehead IMU.

    Args:
        plan: segments ("stand", seconds) or ("step", n_steps, cadence or (c0, c1)).
        peak_g: range of the per-step |f| peak (g), drawn uniformly.
        gestures: (amplitude deg, frequency Hz) of yaw, pitch, roll head oscillations, always on.
        scan: (amplitude deg, frequency Hz) of an extra yaw scan (looking around).
        noise: white noise std (m/s^2); bias: std of a constant per-axis bias (m/s^2).
        double_bump: if > 0, each heel strike is followed by a second pulse this many s later.

    Returns:
        t (n,) s, acc (n, 3) m/s^2, true heel-strike times (S,) s, and the fine-grid truth
        norm of the specific force (n,) m/s^2 (noise- and bias-free, sampled).
    """
    fine = fs * UP
    # Step schedule.
    t_cursor, strikes, step_spans = 0.0, [], []
    for seg in plan:
        if seg[0] == "stand":
            t_cursor += seg[1]
            continue
        _, n, cad = seg
        c0, c1 = (cad, cad) if np.isscalar(cad) else cad
        for i in range(n):
            c = c0 + (c1 - c0) * i / max(n - 1, 1)
            period = (1.0 / c) * (1.0 + 0.03 * rng.standard_normal())
            step_spans.append((t_cursor, period))
            strikes.append(t_cursor + 0.5 * period)
            t_cursor += period
    duration = t_cursor
    n_fine = round(duration * fine)
    tf = np.arange(n_fine) / fine
    az = np.zeros(n_fine)
    ay = np.zeros(n_fine)
    for k, (t0, period) in enumerate(step_spans):
        m = (tf >= t0) & (tf < t0 + period)
        tau = tf[m] - t0
        amp = rng.uniform(peak_g[0] - 1.0, peak_g[1] - 1.0) * GRAVITY
        sigma = 0.12 * period
        pulse = np.exp(-0.5 * ((tau - 0.5 * period) / sigma) ** 2)
        if double_bump > 0.0:
            pulse = pulse + 0.8 * np.exp(-0.5 * ((tau - 0.5 * period - double_bump) / 0.03) ** 2)
        pulse = (pulse - pulse.mean()) / (pulse.max() - pulse.mean())
        az[m] = amp * pulse
        # Lateral sway: one cycle per two steps, 2 cm.
        ay[m] = 0.02 * (np.pi / period) ** 2 * np.sin(np.pi * (k + tau / period))
    ypr = np.zeros((n_fine, 3))
    for axis, (amp_deg, f) in enumerate(gestures):
        ypr[:, axis] += np.deg2rad(amp_deg) * np.sin(2 * np.pi * f * tf + rng.uniform(0, 6.3))
    ypr[:, 0] += np.deg2rad(scan[0]) * np.sin(2 * np.pi * scan[1] * tf)
    q = quat_from_ypr(ypr)
    lever = quat_rotate(q, IMU_LEVER)
    a_rot = np.gradient(np.gradient(lever, 1.0 / fine, axis=0), 1.0 / fine, axis=0)
    a_world = a_rot + np.stack([np.zeros(n_fine), ay, az], axis=-1)
    f_body = quat_rotate_inverse(q, a_world + np.array([0.0, 0.0, GRAVITY]))
    f_body = f_body[::UP]
    clean_norm = np.linalg.norm(f_body, axis=-1)
    b = rng.normal(0.0, bias, 3) if bias_vec is None else bias_vec
    acc = f_body + b + noise * rng.standard_normal(f_body.shape)
    t = np.arange(acc.shape[0]) / fs
    return t, acc, np.asarray(strikes), clean_norm


def run_stream(acc_batch: np.ndarray, chunk: int = 10, params: GaitParams | None = None):
    """Feed (B, n, 3) through a StepDetector in chunks; return per-user peak times, state, steps."""
    b, n, _ = acc_batch.shape
    det = StepDetector(b, FS, params)
    outs = [det.update(acc_batch[:, i : i + chunk]) for i in range(0, n, chunk)]
    peak = np.concatenate([o.peak_time for o in outs], axis=1)
    state = np.concatenate([o.state for o in outs], axis=1)
    steps = np.concatenate([o.steps for o in outs], axis=1)
    times = [np.sort(p[np.isfinite(p)]) for p in peak]
    return times, state, steps, det


# ---------------------------------------------------------------------------- simulation targets
@pytest.mark.parametrize("cadence", [1.2, 1.7, 2.2, (1.2, 2.2)])
def test_stepping_in_place_f1_with_head_motion(rng, cadence):
    """F1 >= 0.99 at 1.2-2.2 steps/s, |f| peaks 1.1-1.5 g, the head scanning and nodding."""
    users = 3
    plan = [("stand", 3.0), ("step", 30, cadence), ("stand", 4.0)]
    sims = [
        synth_head(rng, plan, gestures=((0.0, 0.5), (8.0, 0.4), (5.0, 0.5)), scan=(30.0, 0.3))
        for _ in range(users)
    ]
    n = min(s[1].shape[0] for s in sims)
    acc = np.stack([s[1][:n] for s in sims])
    times, state, steps, det = run_stream(acc)
    for u in range(users):
        truth = sims[u][2]
        p, r, f1 = step_f1(times[u], truth, tol=0.2)
        assert f1 >= 0.99, (cadence, u, p, r)
        assert steps[u].sum() == times[u].size
        t = sims[u][0][:n]
        # Still before the first step, walking between the second step's confirmation and the
        # last step, still again once gamma_t has passed after the last one.
        assert not state[u, t < truth[0]].any()
        mid = (t > truth[1] + det.latency + 0.05) & (t < truth[-1])
        assert state[u, mid].mean() > 0.99
        late = t > truth[-1] + det.latency + det.params.gamma_t + 0.1
        assert not state[u, late].any()


def test_lightest_steps_at_lowest_cadence(rng):
    """Every step peaking at only 1.1 g, at 1.2 steps/s, with a consumer-grade bias."""
    plan = [("stand", 2.0), ("step", 25, 1.2), ("stand", 2.0)]
    t, acc, truth, _ = synth_head(rng, plan, peak_g=(1.1, 1.1), bias=0.2)
    res = detect_steps(t, acc)
    assert step_f1(res.step_times, truth)[2] >= 0.99


@pytest.mark.parametrize(
    ("gestures", "label"),
    [
        (((40.0, 1.0), (0.0, 0.5), (0.0, 0.5)), "serpentine 40 deg 1 Hz"),
        (((40.0, 0.4), (0.0, 0.5), (0.0, 0.5)), "serpentine 40 deg 0.4 Hz (Zhang 2021 script)"),
        (((0.0, 0.5), (30.0, 0.4), (0.0, 0.5)), "nod 30 deg 0.4 Hz"),
        (((0.0, 0.5), (20.0, 0.5), (0.0, 0.5)), "nod 20 deg 0.5 Hz"),
        (((0.0, 0.5), (10.0, 0.7), (0.0, 0.5)), "nod 10 deg 0.7 Hz"),
        (((0.0, 0.5), (0.0, 0.5), (25.0, 0.5)), "shake 25 deg 0.5 Hz (Zhang 2021 script)"),
        (((0.0, 0.5), (0.0, 0.5), (15.0, 1.0)), "shake 15 deg 1 Hz"),
        (((30.0, 0.6), (10.0, 0.5), (15.0, 0.7)), "all three"),
    ],
)
def test_no_phantom_steps_from_head_motion(rng, gestures, label):
    users = 3
    sims = [synth_head(rng, [("stand", 20.0)], gestures=gestures, bias=0.2) for _ in range(users)]
    acc = np.stack([s[1] for s in sims])
    times, state, _, det = run_stream(acc)
    assert all(tt.size == 0 for tt in times), label
    assert not state.any()
    # The motion is not trivially small: the smoothed norm moves a sizeable part of gamma.
    clean = np.stack([s[3] for s in sims])
    m = det.m
    smooth = np.apply_along_axis(lambda x: np.convolve(x, np.ones(m) / m, "valid"), 1, clean)
    excess = (smooth - clean.mean(axis=1, keepdims=True)).max()
    if "serpentine" not in label:
        assert excess > 0.25 * det.params.gamma, (label, excess)


def test_min_step_interval_removes_double_bumps(rng):
    """A heel strike with a second bump 0.2 s later counts once; without the rule, twice."""
    plan = [("stand", 2.0), ("step", 20, 1.5), ("stand", 2.0)]
    t, acc, truth, _ = synth_head(rng, plan, double_bump=0.2, peak_g=(1.3, 1.4))
    res = detect_steps(t, acc)
    assert step_f1(res.step_times, truth)[2] >= 0.99
    loose = detect_steps(t, acc, min_step_interval=0.0)
    assert loose.step_times.size > 1.5 * truth.size


def test_isolated_bumps_are_not_steps():
    """Eq (16)'s gamma_t: a peak needs a neighbour within gamma_t; a pair gives two steps."""
    n = 800
    base = np.full((3, n), GRAVITY)
    bump = 3.0 * np.exp(-0.5 * (np.arange(-15, 16) / 5.0) ** 2)
    base[0, 200:231] += bump  # one knock
    base[1, 200:231] += bump  # two bumps 0.6 s apart
    base[1, 260:291] += bump
    base[2, 200:231] += bump  # two bumps 2 s apart
    base[2, 400:431] += bump
    det = StepDetector(3, FS)
    out = det.update_norm(base)
    assert out.steps[0].sum() == 0
    assert out.steps[2].sum() == 0
    assert out.steps[1].sum() == 2
    k = np.flatnonzero(out.steps[1])
    assert k.size == 1  # the second peak's confirmation releases both
    assert abs(k[0] - (275 + det.latency * FS)) <= 1
    np.testing.assert_allclose(np.sort(out.peak_time[1, k[0]]), [2.15, 2.75], atol=0.011)


def test_peak_time_accuracy_and_latency(rng):
    plan = [("stand", 2.0), ("step", 30, 1.8), ("stand", 2.0)]
    _, acc, truth, _ = synth_head(rng, plan, noise=0.01, bias=0.0)
    times, _, _, det = run_stream(acc[None], chunk=7)
    assert np.isclose(det.latency, (det.h + 0.5 * (det.m - 1)) / FS)
    assert np.isclose(det.latency, 0.135)
    err = times[0] - truth
    assert np.abs(err).max() < 0.03
    assert np.abs(err.mean()) < 0.01
    # Every step after the first is confirmed exactly `latency` after its estimated peak.
    _, i, p = StepDetector(1, FS).update(acc[None]).events()
    conf = i / FS
    np.testing.assert_allclose(conf[1:] - p[1:], det.latency, atol=1e-9)


def test_bias_is_absorbed_by_the_baseline(rng):
    """A 40 mg offset along gravity: the running baseline follows it; the paper's fixed g fails."""
    plan = [("stand", 3.0), ("step", 30, 1.2), ("stand", 3.0)]
    down = np.array([0.0, 0.0, -0.04 * GRAVITY])  # the norm reads 40 mg low
    t, acc, truth, _ = synth_head(rng, plan, peak_g=(1.1, 1.15), bias_vec=down)
    res = detect_steps(t, acc)
    assert step_f1(res.step_times, truth)[2] >= 0.99
    fixed = detect_steps(t, acc, baseline_tau=0.0)
    assert step_f1(fixed.step_times, truth)[2] < 0.9
    det = StepDetector(1, FS)
    det.update(acc[None])
    assert abs(det.baseline[0] - (GRAVITY - 0.04 * GRAVITY)) < 0.05


# ---------------------------------------------------------------------------- streaming contract
def test_chunking_and_batching_do_not_change_results(rng):
    plan = [("stand", 1.0), ("step", 12, 1.6), ("stand", 1.0)]
    sims = [synth_head(rng, plan) for _ in range(3)]
    n = min(s[1].shape[0] for s in sims)
    acc = np.stack([s[1][:n] for s in sims])
    acc[1, 300:305] = np.nan  # a NaN burst in one user
    ref = run_stream(acc, chunk=n)
    for chunk in (1, 7, 10):
        got = run_stream(acc, chunk=chunk)
        np.testing.assert_array_equal(got[1], ref[1])
        np.testing.assert_array_equal(got[2], ref[2])
    for u in range(3):
        single = run_stream(acc[u : u + 1], chunk=10)
        np.testing.assert_array_equal(single[1][0], ref[1][u])
        np.testing.assert_array_equal(single[0][0], ref[0][u])
    # One (B, 3) sample at a time is the same as chunks too.
    det = StepDetector(3, FS)
    state = np.stack([det.update(acc[:, k]).state[:, 0] for k in range(n)], axis=1)
    np.testing.assert_array_equal(state, ref[1])


def test_a_missing_sample_costs_no_step(rng):
    """A NaN norm takes the last valid one: every true step is still found."""
    plan = [("stand", 1.0), ("step", 6, 2.0), ("stand", 1.5)]
    _, acc, truth, _ = synth_head(rng, plan)
    norm = np.linalg.norm(acc, axis=-1)[None]
    norm[0, 50] = np.nan
    assert StepDetector(1, FS).update_norm(norm).steps.sum() == truth.size


def test_reset_one_user(rng):
    plan = [("stand", 1.0), ("step", 10, 1.6), ("stand", 0.5)]
    sims = [synth_head(rng, plan) for _ in range(2)]
    n = min(s[1].shape[0] for s in sims)
    acc = np.stack([s[1][:n] for s in sims])
    half = n // 2
    det = StepDetector(2, FS)
    det.update(acc[:, :half])
    det.reset(np.array([True, False]))
    out = det.update(acc[:, half:])
    cont = StepDetector(2, FS)
    cont.update(acc[:, :half])
    np.testing.assert_array_equal(out.steps[1], cont.update(acc[:, half:]).steps[1])
    # User 0 is a detector started at the reset: the same steps at the same times, to the bit.
    alone = StepDetector(1, FS).update(acc[:1, half:])
    np.testing.assert_array_equal(out.steps[0], alone.steps[0])
    np.testing.assert_array_equal(out.peak_time[0], alone.peak_time[0])
    assert out.steps[0].sum() > 0


# ---------------------------------------------------------------------------- offline API
def test_offline_irregular_timestamps_and_nan(rng):
    """A phone-like ~405 Hz irregular stream with NaN rows gives the same steps."""
    plan = [("stand", 2.0), ("step", 30, 1.7), ("stand", 3.0)]
    t, acc, truth, _ = synth_head(rng, plan, fs=1000.0)
    keep = np.sort(rng.choice(t.size, size=int(t.size * 0.405), replace=False))
    ti, ai = t[keep] + rng.uniform(0, 1e-4, keep.size), acc[keep].copy()
    ai[rng.choice(keep.size, 40, replace=False)] = np.nan
    res = detect_steps(ti, ai)
    assert step_f1(res.step_times, truth)[2] >= 0.99
    assert res.state.shape == ti.shape
    assert np.all(np.abs(ti[res.step_index] - res.step_times) < 0.01)
    walking = (ti > truth[2]) & (ti < truth[-2])
    assert res.state[walking].all()
    assert not res.state[ti < truth[0] - 0.5].any()
    assert np.all(res.confirm_times >= res.step_times)


def test_eq17_from_detected_steps_matches_true_distance(rng):
    """Detector -> eq (17): the virtual walk is SL x true steps long, along the heading."""
    plan = [("stand", 2.0), ("step", 24, 1.8), ("stand", 2.0)]
    t, acc, truth, _ = synth_head(rng, plan)
    det = StepDetector(1, FS)
    dr = DeadReckoning(1, step_length=0.7)
    yaw = np.deg2rad(60.0)
    for k in range(0, t.size, 10):
        out = det.update(acc[None, k : k + 10])
        dr.update(out.steps.sum(axis=1), yaw, 0.1)
    np.testing.assert_allclose(dr.distance, 0.7 * truth.size)
    np.testing.assert_allclose(dr.position[0], 0.7 * truth.size * np.array([0.5, 0.75**0.5]))


def test_bad_inputs():
    det = StepDetector(2, FS)
    with pytest.raises(ValueError, match="acc must have shape"):
        det.update(np.zeros((3, 10, 3)))
    with pytest.raises(ValueError, match="acc must have shape"):
        det.update(np.zeros((2, 10, 2)))
    with pytest.raises(ValueError, match="norm must be >= 0"):
        det.update_norm(-np.ones((2, 4)))
    with pytest.raises(ValueError, match="batch_size"):
        StepDetector(0, FS)
    with pytest.raises(ValueError, match="fs must be in"):
        StepDetector(1, 5.0)
    with pytest.raises(ValueError, match="mask must be"):
        det.reset(np.array([1, 0]))
    with pytest.raises(ValueError, match=r"GaitParams.gamma="):
        GaitParams(gamma=-1.0)
    with pytest.raises(ValueError, match=r"GaitParams.gamma_t="):
        GaitParams(gamma_t=0.1)
    with pytest.raises(ValueError, match=r"GaitParams.mean_window="):
        GaitParams(mean_window=float("nan"))
    t = np.arange(10) / 100.0
    acc = np.tile([0.0, 0.0, GRAVITY], (10, 1))
    with pytest.raises(ValueError, match=r"t runs backwards: t\[1\]=0.08 < t\[0\]=0.09"):
        detect_steps(t[::-1], acc)
    t_nan = t.copy()
    t_nan[3] = np.nan
    with pytest.raises(ValueError, match="NaN or infinite timestamps"):
        detect_steps(t_nan, acc)
    with pytest.raises(ValueError, match="acc must have shape"):
        detect_steps(t, acc[:, :2])
    with pytest.raises(ValueError, match="at least 2 finite"):
        detect_steps(t, np.full((10, 3), np.nan))
    with pytest.raises(ValueError, match="unknown GaitParams field"):
        detect_steps(t, acc, gama=1.0)
    res = detect_steps(t, acc)  # a still, level sensor: nothing
    assert res.step_times.size == 0 and not res.state.any()


# ---------------------------------------------------------------------------- Oxford (real data)
def test_oxford_step_count_and_f1(real_data):
    """Neck-pouch walk: the count within 3 % of 248 and F1 (+-0.2 s) with the named preset."""
    rec = load_oxford(real_data("oxford"))
    res = detect_steps(rec.t, rec.acc, params=GaitParams.neck_pouch())
    n_true = rec.step_times.size
    assert abs(res.step_times.size - n_true) <= 0.03 * n_true
    precision, recall, f1 = step_f1(res.step_times, rec.step_times, tol=0.2)
    assert f1 >= 0.97, (precision, recall)
    # The head preset counts the pouch's post-walk swing too, but still finds the steps.
    head = detect_steps(rec.t, rec.acc)
    assert step_f1(head.step_times, rec.step_times, tol=0.2)[1] >= 0.97


def test_repeated_timestamps_are_merged_not_refused():
    """A logger that writes two rows for one tick (as in a neck-pouch recording of the Oxford
    dataset): the steps are those of the recording without the repeats."""
    rng = np.random.default_rng(4)
    t = np.arange(2000) / 100.0
    phase = 2 * np.pi * 1.8 * t
    acc = np.stack(
        [np.zeros_like(t), np.zeros_like(t), GRAVITY + 2.5 * np.maximum(np.sin(phase), 0) ** 8], -1
    )
    acc += rng.normal(0, 0.05, acc.shape)
    plain = detect_steps(t, acc)
    dup = np.sort(np.concatenate([np.arange(2000), [300, 301, 900, 1500]]))
    merged = detect_steps(t[dup], acc[dup])
    assert plain.step_times.size > 30  # 1.8 steps/s for 20 s
    np.testing.assert_allclose(merged.step_times, plain.step_times, atol=0.02)

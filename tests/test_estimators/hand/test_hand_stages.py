"""Hand stages (estimators.stages.HAND): yao2023, raw, the One Euro filter and the motion-adaptive
Kalman filter, against the truth of the synthetic Kinect v2 chain (motion model -> KinectV2 ->
HandPipeline)."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

from agents.experiments.hand_variance import (
    DEV_MOVING_SEEDS,
    DEV_STATIC_SEEDS,
    PAPER_ANGLES_DEG,
    simulate_trial,
)
from estimators.hand import (
    HandFrame,
    HandParams,
    KalmanParams,
    OrientationFilter,
    RawHand,
    Yao2023Hand,
    estimate_lag,
    unwrap_angles,
)
from estimators.hand.adaptive import AdaptiveKalmanHand, AdaptiveKalmanHandParams
from estimators.hand.joint_smoothing import OneEuroFilter
from estimators.hand.one_euro import OneEuroHand, OneEuroHandParams
from estimators.registry import StageError
from estimators.rotations import angle_diff
from estimators.stages import HAND, HandStage

FS = 30.0
WARMUP = 30  # frames left out of the statistics (1 s), as agents/experiments/hand_variance.py
#: Held-out seeds: the tuned parameters of the hand filters were chosen on the experiment's
#: development seeds (static 1, 2; moving 101, 102), and it reports static 0, moving 1.
STATIC_SEED, MOVING_SEED = 5, 105
assert STATIC_SEED not in DEV_STATIC_SEEDS and MOVING_SEED not in DEV_MOVING_SEEDS
REPEATS = 3
NAMES = ("raw", "yao2023", "one_euro", "adaptive_kalman")


def simulate(hand_roll, roll_rate, seconds, seed):
    """The chain of ``agents.experiments.hand_variance.simulate_trial``: a list of one (B, M)
    :class:`HandFrame` per control step, and the true wrist angles (B, frames, 3)."""
    trial = simulate_trial(hand_roll, roll_rate, seconds, seed)
    return trial.step_frames(), trial.truth


def run(stage, frames):
    """The stage over every step's frames: (B, frames, 3) angles and (B, frames) validity."""
    out = [stage.update(f) for f in frames]
    return np.concatenate([o[0] for o in out], axis=1), np.concatenate([o[1] for o in out], axis=1)


def rest_variance(ypr):
    """(3,) pooled variance (deg^2) over the static poses: mean over repeats, summed over poses."""
    deg = np.rad2deg(unwrap_angles(ypr[:, WARMUP:], axis=1))
    var = np.nanvar(deg, axis=1, ddof=1)
    return var.reshape(len(PAPER_ANGLES_DEG), REPEATS, 3).mean(axis=1).sum(axis=0)


def motion_errors(ypr, truth):
    """(3,) RMSE vs truth (deg) and the lag (s) on the swept axis."""
    est, tru = ypr[:, WARMUP:], truth[:, WARMUP:]
    err = np.rad2deg(angle_diff(est, tru))
    rmse = np.sqrt(np.nanmean(err**2, axis=(0, 1)))
    axis = int(np.argmax(np.nanstd(tru, axis=(0, 1))))
    lags = [
        estimate_lag(
            unwrap_angles(est[i, :, axis], axis=0), unwrap_angles(tru[i, :, axis], axis=0), FS, 0.5
        )
        for i in range(est.shape[0])
    ]
    return rmse, float(np.mean(lags)), axis


def rmse_deg(ypr, truth):
    """(3,) RMSE vs truth (deg) after the warm-up."""
    err = np.rad2deg(angle_diff(ypr[:, WARMUP:], truth[:, WARMUP:]))
    return np.sqrt(np.nanmean(err**2, axis=(0, 1)))


@pytest.fixture(scope="module")
def static_frames():
    angles = np.deg2rad(np.repeat(np.asarray(PAPER_ANGLES_DEG, float), REPEATS))
    return simulate(angles, None, 10.0, STATIC_SEED)


@pytest.fixture(scope="module")
def moving_frames():
    start = np.deg2rad(np.random.default_rng(MOVING_SEED).uniform(-60, 60, 10))
    return simulate(start, np.full(10, np.deg2rad(90.0)), 10.0, MOVING_SEED)


def build_all(b):
    return {name: HAND.build(name, b, FS) for name in NAMES}


# ---------------------------------------------------------------------------- registry
def test_registry_builds_all_four():
    built = build_all(4)
    assert isinstance(built["yao2023"], Yao2023Hand)
    assert isinstance(built["raw"], RawHand)
    assert isinstance(built["one_euro"], OneEuroHand)
    assert isinstance(built["adaptive_kalman"], AdaptiveKalmanHand)
    assert built["adaptive_kalman"].params == AdaptiveKalmanHandParams()
    for stage in built.values():
        assert isinstance(stage, HandStage)
        assert stage.batch_size == 4
    assert built["one_euro"].params == OneEuroHandParams()
    custom = HAND.build(OneEuroHandParams(min_cutoff=1.0, beta=2.0), 2, FS)
    assert isinstance(custom, OneEuroHand) and custom.params.beta == 2.0
    assert custom.filter.params.rate_hz == FS
    with pytest.raises(StageError, match="batch_size"):
        HAND.build("one_euro", 0, FS)
    with pytest.raises(StageError, match="fs"):
        HAND.build("raw", 2, -1.0)


def test_bad_params_and_frames_raise_value_errors():
    with pytest.raises(ValueError, match=r"OneEuroHandParams\.min_cutoff=0"):
        OneEuroHandParams(min_cutoff=0.0)
    with pytest.raises(ValueError, match=r"OneEuroHandParams\.beta=-1"):
        OneEuroHandParams(beta=-1.0)
    with pytest.raises(ValueError, match=r"OneEuroHandParams\.d_cutoff=nan"):
        OneEuroHandParams(d_cutoff=float("nan"))
    with pytest.raises(ValueError, match=r"OneEuroHandParams\.beta=True"):
        OneEuroHandParams(beta=True)
    with pytest.raises(ValueError, match="params must be a OneEuroHandParams"):
        OneEuroHand(2, FS, params={"beta": 1.0})
    with pytest.raises(ValueError, match=r"AdaptiveKalmanHandParams\.accel_psd=0"):
        AdaptiveKalmanHandParams(accel_psd=0.0)
    with pytest.raises(ValueError, match=r"AdaptiveKalmanHandParams\.max_accel_psd=0\.5"):
        AdaptiveKalmanHandParams(max_accel_psd=0.5)  # below accel_psd
    with pytest.raises(ValueError, match=r"AdaptiveKalmanHandParams\.adapt_time=nan"):
        AdaptiveKalmanHandParams(adapt_time=float("nan"))
    with pytest.raises(ValueError, match="params must be an AdaptiveKalmanHandParams"):
        AdaptiveKalmanHand(2, FS, params={"accel_psd": 1.0})
    frames = synthetic(np.zeros((3, 4, 3)))
    for stage in build_all(2).values():
        with pytest.raises(ValueError, match=r"ypr_raw of shape \(2, M, 3\)"):
            stage.update(frames)
        with pytest.raises(ValueError, match="rows must lie in"):
            stage.reset([5])


# ---------------------------------------------------------------------------- yao2023 and raw
def test_yao2023_and_raw_are_the_pipelines_own_outputs_bit_for_bit():
    """On the hand-variance chain, step by step: the stages give exactly the pipeline's Kalman +
    median and raw angles."""
    for roll, rate, seed in (
        (np.deg2rad([-90.0, 0.0, 45.0]), None, 11),
        (np.deg2rad([-30.0, 10.0, 60.0]), np.deg2rad(90.0), 12),
    ):
        rates = None if rate is None else np.full(3, rate)
        trial = simulate_trial(roll, rates, 3.0, seed)
        frames = trial.step_frames()
        stages = build_all(3)
        ypr, valid = run(stages["yao2023"], frames)
        np.testing.assert_array_equal(ypr, trial.frames.ypr)
        np.testing.assert_array_equal(valid, trial.frames.valid)
        raw, raw_valid = run(stages["raw"], frames)
        np.testing.assert_array_equal(raw, trial.frames.ypr_raw)
        np.testing.assert_array_equal(raw_valid, np.isfinite(raw).all(axis=-1))
        # Copies: the caller may keep them while the frames are reused.
        y0, _ = stages["yao2023"].update(frames[-1])
        assert not np.shares_memory(y0, frames[-1].ypr)


def test_adaptive_kalman_is_the_pipelines_kalman_filter_on_raw_angles():
    """With the pipeline's own Kalman parameters the stage reproduces its Kalman output bit for
    bit through reselections and dropouts (one compiled filter, fed ``ypr_raw``), and any
    chunking of the frames into steps gives the same numbers."""
    roll = np.deg2rad([-30.0, 10.0, 60.0])
    trial = simulate_trial(roll, np.full(3, np.deg2rad(90.0)), 3.0, 13)
    yao2023 = AdaptiveKalmanHandParams(accel_psd=1.0, max_accel_psd=10.0, adapt_time=0.1)
    ypr, valid = run(AdaptiveKalmanHand(3, FS, yao2023), trial.step_frames())
    np.testing.assert_array_equal(ypr, trial.frames.ypr_kalman)
    np.testing.assert_array_equal(valid, trial.frames.valid)
    whole, _ = AdaptiveKalmanHand(3, FS).update(trial.frames)
    steps, _ = run(AdaptiveKalmanHand(3, FS), trial.step_frames())
    np.testing.assert_array_equal(whole, steps)
    direct = OrientationFilter(
        3,
        HandParams(
            kalman=KalmanParams(accel_psd=1.0, max_accel_psd=1000.0, adapt_time=1.0 / 30.0),
            median_window=1,
        ),
    )
    ref = direct.update_angles(
        trial.frames.ypr_raw, trial.frames.quat_valid, trial.frames.reselected
    )
    np.testing.assert_array_equal(whole, ref.ypr_kalman)


def test_adaptive_kalman_beats_raw_at_rest_and_in_motion(static_frames, moving_frames):
    """Held-out seeds: lower RMSE against the truth than raw on every axis, at rest and while the
    hand sweeps at 90 deg/s, with under half a frame of lag; Yao 2023's Kalman + median is worse
    than raw in motion (the median's lag)."""
    static_truth = static_frames[1]
    b = static_truth.shape[0]
    stages = {name: HAND.build(name, b, FS) for name in ("raw", "adaptive_kalman")}
    rest = {n: rmse_deg(run(s, static_frames[0])[0], static_truth) for n, s in stages.items()}
    assert np.all(rest["adaptive_kalman"] < rest["raw"]), rest
    assert rest["adaptive_kalman"][0] < 0.85 * rest["raw"][0], rest  # the mostly white axis
    frames, truth = moving_frames
    stages = build_all(truth.shape[0])
    res = {name: motion_errors(run(s, frames)[0], truth) for name, s in stages.items()}
    (rmse_raw, _, axis), (rmse_ak, lag_ak, _) = res["raw"], res["adaptive_kalman"]
    assert axis == 0
    assert np.all(rmse_ak < rmse_raw), (rmse_ak, rmse_raw)
    assert rmse_ak[axis] < 0.9 * rmse_raw[axis], (rmse_ak, rmse_raw)
    assert lag_ak < 0.5 / FS, lag_ak
    assert res["yao2023"][0][axis] > rmse_raw[axis]  # the documented price of the median


# ---------------------------------------------------------------------------- One Euro vs truth
def test_one_euro_beats_raw_at_rest(static_frames):
    static_frames, truth = static_frames
    b = static_frames[0].ypr.shape[0]
    stages = {name: HAND.build(name, b, FS) for name in ("raw", "yao2023", "one_euro")}
    out = {name: run(s, static_frames)[0] for name, s in stages.items()}
    var = {name: rest_variance(y) for name, y in out.items()}
    reduction = 100.0 * (1.0 - var["one_euro"] / var["raw"])
    # About the forearm (our yaw column, 80 % white noise) half of the variance goes, less than
    # Kalman + median removes (the price of speed); about the bending axes (95 % slow noise)
    # about a tenth (development seeds: 49.6 / 11.2 / 10.0 %).
    assert reduction[0] > 40.0, reduction
    assert np.all(reduction[1:] > 5.0), reduction
    assert reduction[0] < 100.0 * (1.0 - var["yao2023"][0] / var["raw"][0])
    err = {name: rmse_deg(y, truth) for name, y in out.items()}
    assert np.all(err["one_euro"] < err["raw"]), err
    ypr, valid = run(stages["one_euro"], static_frames)
    assert valid[:, WARMUP:].all() and np.isfinite(ypr[:, WARMUP:]).all()
    assert np.all(np.abs(ypr[valid]) <= np.pi)


def test_one_euro_beats_raw_in_motion(moving_frames):
    frames, truth = moving_frames
    stages = build_all(truth.shape[0])
    res = {name: motion_errors(run(s, frames)[0], truth) for name, s in stages.items()}
    (rmse_raw, lag_raw, axis), (rmse_oe, lag_oe, _) = res["raw"], res["one_euro"]
    assert axis == 0  # the sweep about the forearm moves our yaw column (paper's roll)
    # Chosen to stay below 0.97 x raw on the swept axis on the development seeds.
    assert np.all(rmse_oe < 0.99 * rmse_raw), (rmse_oe, rmse_raw)
    # Lag: under half a frame, far below Kalman + median's (the median's frame).
    assert lag_oe < 0.5 / FS, lag_oe
    assert lag_oe < 0.5 * res["yao2023"][1]
    assert lag_raw <= lag_oe + 1e-9
    assert rmse_oe[axis] < res["yao2023"][0][axis]


# ---------------------------------------------------------------------------- One Euro mechanics
def synthetic(ypr_raw, quat_valid=None, reselected=None):
    """A (B, M) HandFrame with the given raw angles and flags (other fields neutral)."""
    ypr_raw = np.asarray(ypr_raw, dtype=np.float64)
    b, m, _ = ypr_raw.shape
    qv = np.ones((b, m), bool) if quat_valid is None else np.asarray(quat_valid, bool)
    rs = np.zeros((b, m), bool) if reselected is None else np.asarray(reselected, bool)
    return HandFrame(
        slot=np.zeros((b, m), np.int64),
        body_id=np.ones((b, m), np.int64),
        reselected=rs,
        has_target=np.ones((b, m), bool),
        joints=np.full((b, m, 25, 3), np.nan),
        joint_state=np.zeros((b, m, 25), np.int8),
        all_inferred=np.zeros((b, m), bool),
        ypr_raw=ypr_raw,
        ypr_kalman=ypr_raw.copy(),
        ypr=ypr_raw.copy(),
        quat_valid=qv,
        singular=np.zeros((b, m), bool),
        valid=np.isfinite(ypr_raw).all(axis=-1),
    )


def noisy_angles(rng, b, m, base=0.3):
    return base + 0.03 * rng.standard_normal((b, m, 3))


def test_one_euro_is_the_shared_filter_in_angular_mode(rng):
    """The stage feeds joint_smoothing.OneEuroFilter (no second implementation); chunking the
    frames into steps of any M changes nothing."""
    x = noisy_angles(rng, 2, 30)
    stage = OneEuroHand(2, FS)
    ref = OneEuroFilter(2, (3,), stage.params.filter_params(FS), angular=True)
    expected = np.stack([ref.update(x[:, t]) for t in range(30)], axis=1)
    whole, _ = stage.update(synthetic(x))
    np.testing.assert_array_equal(whole, expected)
    chunked = OneEuroHand(2, FS)
    parts = [chunked.update(synthetic(x[:, a:b]))[0] for a, b in ((0, 1), (1, 4), (4, 30))]
    np.testing.assert_array_equal(np.concatenate(parts, axis=1), expected)


def test_nan_before_the_first_frame_and_reselection_restarts(rng):
    x = noisy_angles(rng, 2, 40)
    x[:, 20:] -= 1.5  # the new target holds its hand elsewhere
    qv = np.ones((2, 40), bool)
    qv[:, :3] = False  # no usable quaternion yet
    resel = np.zeros((2, 40), bool)
    resel[0, 20] = True  # stream 0 selects a new user at frame 20, stream 1 does not
    qv[0, 20:22] = False  # ... whose first usable quaternion comes at frame 22
    ypr, valid = OneEuroHand(2, FS).update(synthetic(x, qv, resel))
    assert not valid[:, :3].any() and np.isnan(ypr[:, :3]).all()
    # A fresh stream starts at its sample (to the rounding of the output's wrap to (-pi, pi]).
    np.testing.assert_allclose(ypr[:, 3], x[:, 3], rtol=0, atol=1e-15)
    assert valid[:, 3:20].all()
    # Restarted: nothing of the old user's estimate survives, and it starts at its sample.
    assert not valid[0, 20:22].any() and np.isnan(ypr[0, 20:22]).all()
    np.testing.assert_allclose(ypr[0, 22], x[0, 22], rtol=0, atol=1e-15)
    fresh, _ = OneEuroHand(1, FS).update(synthetic(x[:1, 22:]))
    np.testing.assert_array_equal(ypr[0, 22:], fresh[0])
    # Without the restart the filter glides from the old pose (stream 1).
    assert valid[1, 20:].all()
    assert np.all(np.abs(ypr[1, 20] - x[1, 20]) > 0.05)


def test_dropouts_hold_and_leave_the_state_alone(rng):
    x = noisy_angles(rng, 1, 60)
    x[:, 30:] += np.linspace(0.0, 1.0, 30)[None, :, None]  # moving after the gap
    qv = np.ones((1, 60), bool)
    qv[0, 20:26] = False
    garbage = x.copy()
    garbage[0, 20:26] = 3.0  # what a dropout frame holds must not matter
    ypr, valid = OneEuroHand(1, FS).update(synthetic(garbage, qv))
    assert valid.all()
    np.testing.assert_array_equal(ypr[0, 20:26], np.repeat(ypr[0, 19:20], 6, axis=0))
    # Same as a filter that never saw the dropout frames.
    kept = np.concatenate([x[:, :20], x[:, 26:]], axis=1)
    skip, _ = OneEuroHand(1, FS).update(synthetic(kept))
    np.testing.assert_array_equal(ypr[0, 26:], skip[0, 20:])


@pytest.mark.parametrize("cls", [OneEuroHand, AdaptiveKalmanHand])
def test_reset_rows_forgets_only_those_rows(rng, cls):
    x = noisy_angles(rng, 3, 20)
    for rows in ([1], np.array([False, True, False])):
        stage = cls(3, FS)
        stage.update(synthetic(x[:, :10]))
        stage.reset(rows)
        after, valid = stage.update(synthetic(x[:, 10:]))
        whole, _ = cls(3, FS).update(synthetic(x))
        np.testing.assert_array_equal(after[[0, 2]], whole[[0, 2], 10:])
        fresh, _ = cls(1, FS).update(synthetic(x[1:2, 10:]))
        np.testing.assert_array_equal(after[1], fresh[0])
        assert valid.all()
    stage.reset()
    y, v = stage.update(synthetic(np.full((3, 1, 3), np.nan), np.zeros((3, 1), bool)))
    assert not v.any() and np.isnan(y).all()


@pytest.mark.parametrize("cls", [OneEuroHand, AdaptiveKalmanHand])
def test_wraparound_at_180_deg_has_no_jump(cls):
    m = 90
    true = np.pi - 0.5 + np.linspace(0.0, 1.0, m)  # crosses +pi
    x = np.angle(np.exp(1j * true))[None, :, None].repeat(3, axis=2)
    ypr, _ = cls(1, FS).update(synthetic(x))
    err = angle_diff(ypr[0, :, 0], true)
    assert np.max(np.abs(err)) < np.deg2rad(1.0)
    assert np.all(np.abs(ypr) <= np.pi)


def test_raw_validity_follows_the_current_target():
    x = np.zeros((1, 6, 3))
    x[0, :2] = np.nan  # before the target's first quaternion
    x[0, 4] = np.nan  # reselected; the new target has no quaternion yet
    qv = np.array([[False, False, True, False, False, True]])
    ypr, valid = RawHand(1, FS).update(synthetic(x, qv))
    np.testing.assert_array_equal(valid, [[False, False, True, True, False, True]])
    np.testing.assert_array_equal(np.isnan(ypr).all(axis=-1), ~valid)
    # The stack's fields are all of one frame count (a sanity check of the helper).
    assert {getattr(synthetic(x), f.name).shape[:2] for f in fields(HandFrame)} == {(1, 6)}

"""The step-envelope experiment: its synthetic motions, its counting and its two-fold split."""

import json

import numpy as np
import pytest

from agents.cli import main
from agents.experiments.step_envelope import (
    CASES,
    Counts,
    add_squats,
    build_trial,
    count_steps,
    detected_times,
    oxford_halves,
    seed_label,
    tilt_quaternions,
    two_fold_gamma,
)
from estimators.io.oxford import load_oxford
from estimators.rotations import GRAVITY, quat_from_ypr, quat_rotate, quat_rotate_inverse
from estimators.stages import STEPS

SEED = 3000  # seeds 3000 and up: used by this file only
CASE = {c.name: c for c in CASES}


def test_a_squat_moves_the_head_by_its_depth_with_the_exact_second_derivative():
    trial = build_trial(CASE["look at hand, standing"], "ig500n", 1, SEED)  # any standing record
    rec = trial.record
    z0 = rec.pos[..., 2].copy()
    acc0 = rec.acc[..., 2].copy()
    add_squats(rec, depth=0.4, rate=0.4, start=2.0, cycles=2)
    dz = rec.pos[0, :, 2] - z0[0]
    assert dz.min() == pytest.approx(-0.4, abs=1e-3)  # the bottom of each squat
    assert np.all(dz[rec.t < 2.0] == 0.0) and np.all(dz[rec.t > 2.0 + 2 / 0.4] == 0.0)
    # the added acceleration is the second difference of the added position (inside the squats)
    dt = rec.t[1] - rec.t[0]
    fd = (dz[2:] - 2 * dz[1:-1] + dz[:-2]) / dt**2
    da = (rec.acc[0, :, 2] - acc0[0])[1:-1]
    inside = (rec.t[1:-1] > 2.0 + dt) & (rec.t[1:-1] < 2.0 + 5.0 - dt)
    assert np.max(np.abs(fd[inside] - da[inside])) < 1e-3 * np.max(np.abs(da))
    with pytest.raises(ValueError, match="depth"):
        add_squats(rec, depth=0.0, rate=0.4, start=2.0, cycles=2)


def test_squats_without_steps_give_zhang2021_and_nod_robust_almost_no_false_steps():
    """A deep, quick squat lifts |f| above the naive threshold, but its peaks are 2 s apart,
    beyond the 1.2 s bout rule of Zhang 2021 and nod_robust: at most 1 false step a minute."""
    trials = [build_trial(CASE["squat 0.5 m 0.5 Hz"], "consumer_mems", 2, SEED)]
    assert count_steps("threshold", trials).fp > 0  # the squat does reach the |f| threshold
    for name in ("zhang2021", "nod_robust"):
        c = count_steps(name, trials)
        assert c.true_steps == 0 and c.tp == 0 and c.f1 is None
        assert c.fp_per_min <= 1.0, name


def test_tp_and_misses_make_the_true_steps_and_tp_and_fp_the_detections():
    trials = [build_trial(CASE["gaze shifts 70deg, 1.7/s"], "consumer_mems", 2, SEED + 1)]
    n_true = sum(s.size for s in trials[0].record.step_times)
    assert n_true > 40  # 16 s at 1.7 steps/s, two users
    for name in STEPS.names():
        c = count_steps(name, trials)
        n_det = sum(d.size for d in detected_times(name, trials[0]))
        assert c.tp + c.misses == c.true_steps == n_true
        assert c.tp + c.fp == n_det
        assert c.f1 == pytest.approx(2 * c.tp / (c.true_steps + n_det))
        assert c.minutes == pytest.approx(2 * trials[0].record.t.size / 100.0 / 60.0)


def test_steps_below_the_threshold_are_missed_and_steps_above_it_found():
    """Zhang 2021's gamma is 0.07 g: heel strikes peaking at 0.06 g fall under it, 0.10 g clear
    it."""
    soft = count_steps(
        "zhang2021", [build_trial(CASE["light steps 0.06 g, 1.5/s"], "ig500n", 2, SEED + 2)]
    )
    firm = count_steps(
        "zhang2021", [build_trial(CASE["light steps 0.10 g, 1.5/s"], "ig500n", 2, SEED + 2)]
    )
    assert soft.true_steps == firm.true_steps > 40
    assert soft.tp <= 0.2 * soft.true_steps
    assert firm.tp >= 0.95 * firm.true_steps and firm.fp == 0


def test_a_case_is_the_same_for_the_same_seed_bit_for_bit():
    a = build_trial(CASE["gaze shifts 70deg, 1.7/s"], "consumer_mems", 2, SEED + 3)
    b = build_trial(CASE["gaze shifts 70deg, 1.7/s"], "consumer_mems", 2, SEED + 3)
    c = build_trial(CASE["gaze shifts 70deg, 1.7/s"], "consumer_mems", 2, SEED + 4)
    assert np.array_equal(a.imu.acc, b.imu.acc) and np.array_equal(a.record.ypr, b.record.ypr)
    assert not np.array_equal(a.record.ypr, c.record.ypr)


def test_looking_down_reaches_the_published_head_flexion():
    """Lee, Kang & Shin (2015): 33-45 deg of head flexion looking at a phone; the case spans
    30-50 deg (pitch positive: nose down)."""
    rec = build_trial(CASE["look at hand, standing"], "ig500n", 1, SEED).record
    pitch = np.rad2deg(rec.ypr[0, :, 1])
    assert 44.0 < pitch.max() <= 51.0
    assert np.mean(pitch > 30.0) > 0.5


def test_the_tilt_attitude_turns_the_mean_specific_force_upright():
    fs = 100.0
    q_true = quat_from_ypr([0.3, 0.5, -0.4])  # sensor -> world
    f_world = np.array([0.0, 0.0, GRAVITY])
    f = np.tile(quat_rotate_inverse(q_true, f_world), (300, 1))  # the sensor's reading
    q = tilt_quaternions(f, fs)
    up = quat_rotate(q, f)
    np.testing.assert_allclose(up[:, :2], 0.0, atol=1e-9)
    np.testing.assert_allclose(up[:, 2], GRAVITY, rtol=1e-12)


def test_seed_labels():
    assert seed_label((1000, 1001, 1002)) == "held-out"
    assert seed_label((0, 1, 2)) == "development"
    assert seed_label((2, 3, 4)) == "development"  # a development seed makes the set in-sample


def test_counts_of_a_standing_case_are_all_false_steps():
    c = Counts()
    c.add(np.array([]), np.array([1.0, 2.0, 3.0]), minutes=0.5)
    assert (c.tp, c.fp, c.misses, c.f1, c.fp_per_min) == (0, 3, 0, None, 6.0)


def test_the_two_fold_split_uses_disjoint_halves(real_data):
    rec = load_oxford(real_data("oxford"))
    split, _ = oxford_halves(rec.duration, rec.step_times)
    first, second = rec.t < split, rec.t >= split
    assert not np.any(first & second) and np.all(first | second)
    assert abs(first.sum() - second.sum()) < 0.1 * rec.t.size  # halves of the recording
    assert not np.any(np.abs(rec.step_times - split) < 0.2)  # no step straddles the cut
    out = two_fold_gamma(rec.t, rec.acc, rec.step_times)
    folds = out["folds"]
    assert [f["held_out"]["true_steps"] for f in folds] == [
        int(np.sum(rec.step_times >= split)),
        int(np.sum(rec.step_times < split)),
    ]
    for f in folds:  # the chosen gamma is the best on the tuning half, not on the evaluated one
        best = max(f["tuning_f1"].values())
        assert f["tuning_f1"][f"{f['chosen_gamma_g']:.2f}"] == best
        h = f["held_out"]
        assert h["tp"] + h["misses"] == h["true_steps"] and h["tp"] + h["fp"] == h["detected"]
    pooled = out["pooled_held_out"]
    assert pooled["true_steps"] == rec.step_times.size
    assert pooled["f1"] > 0.95


def test_the_cli_refuses_a_negative_seed(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["experiment", "step-envelope", "--seed", "-1"])
    assert exit_.value.code == 2
    assert "--seed" in capsys.readouterr().err


@pytest.mark.slow
def test_the_cli_runs_every_case_and_labels_its_seeds(tmp_path, capsys):
    path = tmp_path / "se.json"
    assert main(["experiment", "step-envelope", "--users", "1", "--dev", "--json", str(path)]) == 0
    out = json.loads(path.read_text())
    assert out["seeds"] == [0, 1, 2] and out["seed_label"] == "development"
    assert "development seeds (0, 1, 2)" in capsys.readouterr().out
    for cases in out["simulated"].values():
        assert set(cases) == set(CASE)
        for name, rows in cases.items():
            for r in rows.values():
                assert r["tp"] + r["misses"] == r["true_steps"]
                assert (r["true_steps"] > 0) == CASE[name].stepping
    if out["oxford"] is not None:
        labels = {k: r["label"] for k, r in out["oxford"]["detectors"].items()}
        assert labels["zhang2021 neck_pouch"].startswith("in-sample")


@pytest.mark.parametrize(
    ("kw", "message"),
    [({"users": 0}, "users=0"), ({"seed": -2}, "seed=-2"), ({"users": 2.5}, "users=2.5")],
)
def test_bad_arguments_are_refused_before_any_work(kw, message):
    from agents.experiments.step_envelope import run_step_envelope

    with pytest.raises(ValueError, match=message):
        run_step_envelope(oxford=None, **kw)

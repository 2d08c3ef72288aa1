"""The helmet-tracking paper's experiment (``vrloco experiment vio``): its parts through the public
API on short walks, and one 15 s run through the command line (slow) whose JSON the claims are
checked on.

Seed 3 is not a calibration seed, so the camera's calibrated noise is held-out there.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from agents.cli import main
from agents.experiments import vio
from vrloco_env.batch_rng import BatchRng

DURATION = 15.0


@pytest.fixture(scope="module")
def result(tmp_path_factory) -> dict:
    path = tmp_path_factory.mktemp("vio") / "vio.json"
    rc = main(
        ["experiment", "vio", "--duration", str(DURATION), "--seed", "3", "--json", str(path)]
    )
    assert rc == 0
    return json.loads(path.read_text())


@pytest.fixture(scope="module")
def short_walk():
    setup = vio.make_setup(5)
    return vio.simulate("walk", 6.0, 5, setup), setup


@pytest.mark.slow
def test_json_has_the_issue_keys(result):
    for cond in ("ideal", "complex"):
        assert {"pos_m", "att_deg", "start_s"} <= set(result["fused"][cond])
    for kind in ("static", "rotation"):
        assert {"pos_m", "att_deg", "pos_at_m", "att_at_deg"} <= set(result["imu_only"][kind])
    for cond in ("ideal", "low_light", "occlusion", "motion_blur", "complex"):
        row = result["visual_only"][cond]
        assert {"pos_m", "att_deg", "pos_clean_m", "availability", "extraction"} <= set(row)
    assert {"fixed", "sage_husa"} <= set(result["adaptive"])
    cfg = result["config"]
    assert cfg["duration_s"] == DURATION and cfg["held_out"]
    assert cfg["imu_rate_hz"] == 1000.0 and cfg["camera_rate_hz"] == 120.0
    # The paper's extraction / matching rates are listed as the model's inputs, not as results.
    assert "extraction" not in result["paper"]["visual_only"]["ideal"]
    assert result["paper"]["camera_inputs"]["ideal"]["extraction"] == 0.95
    # 120 frames/s; the last frames, whose exposure (5 ms late) falls after the run, are dropped.
    frames = result["visual_only"]["ideal"]["frames"]
    assert round(DURATION * 120.0) - 1 <= frames <= round(DURATION * 120.0)


@pytest.mark.slow
def test_calibrated_camera_lands_near_the_paper_on_a_held_out_walk(result):
    """The noise scale was fitted on other seeds; on this one the ideal camera's error is still
    of the paper's size (+-0.05 m, +-1 deg), not the 3-4x smaller error of the uncalibrated one."""
    cam = result["visual_only"]["ideal"]
    assert 0.03 < cam["pos_clean_m"] < 0.08
    assert 0.6 < cam["att_clean_deg"] < 1.6


@pytest.mark.slow
def test_fused_ideal_meets_target_and_beats_the_camera(result):
    fused, cam = result["fused"]["ideal"], result["visual_only"]["ideal"]
    assert fused["pos_m"] < 0.05 and fused["att_deg"] < 1.0
    assert fused["pos_window_max_m"] < 0.05 and fused["att_window_max_deg"] < 1.0
    # Better than the camera alone, even with the camera's gross errors left out.
    assert fused["pos_m"] < cam["pos_clean_m"] and fused["att_deg"] < cam["att_clean_deg"]
    # It starts at the first PnP pose, within the first frames.
    assert fused["start_s"] < 0.1


@pytest.mark.slow
def test_adaptive_filter_beats_fixed_r_after_the_noise_change(result):
    a = result["adaptive"]
    assert a["switch_s"] == pytest.approx(DURATION / 2, abs=0.01)
    assert a["sage_husa"]["pos_m"] < a["fixed"]["pos_m"]
    assert a["sage_husa"]["att_deg"] < a["fixed"]["att_deg"]
    # The noisy camera really is noisier than the tuned R.
    assert a["visual_after_switch"]["pos_clean_m"] > 3 * a["tuned_r"]["position_sigma_m"]


@pytest.mark.slow
def test_imu_only_drift_grows(result):
    for kind in ("static", "rotation"):
        r = result["imu_only"][kind]
        assert r["pos_at_m"][-1] > 4.0 * r["pos_at_m"][0] > 0.0  # at least ~t^1 growth, ~t^2 here
        assert r["att_at_deg"][-1] > r["att_at_deg"][0]
        assert r["pos_m"] >= r["pos_end_m"] and r["att_deg"] >= r["att_end_deg"]


def test_mismatch_makes_the_camera_worse_at_the_same_noise(short_walk):
    """The map, intrinsics and time-offset errors reach the PnP: at the presets' noise the
    ideal camera's pose error grows against the same frames without mismatch."""
    traj, setup = short_walk
    spec = vio.condition_spec("ideal", 1.0)
    exact = vio.make_setup(5, vio.Mismatch.none())
    err = {}
    for name, s in (("exact", exact), ("mismatch", setup)):
        run = vio.capture_visual(traj, spec, BatchRng.from_seeds([0]), s, vio.pnp_params(spec))
        err[name] = vio.visual_stats(run, traj)
    assert err["exact"]["availability"] > 0.9 and err["mismatch"]["availability"] > 0.9
    assert err["mismatch"]["pos_clean_m"] > 1.3 * err["exact"]["pos_clean_m"]
    assert err["mismatch"]["att_clean_deg"] > 1.3 * err["exact"]["att_clean_deg"]


def test_setup_draws_what_the_estimators_are_not_told(short_walk):
    _, setup = short_walk
    nominal = vio.make_setup(5, vio.Mismatch.none())
    assert np.all(nominal.map_landmarks == nominal.landmarks)
    survey = setup.map_landmarks - setup.landmarks
    assert 0.002 < np.sqrt(np.mean(survey**2)) < 0.01  # 5 mm per axis over 96 landmarks
    assert setup.offset_samples == 5
    assert not np.allclose(setup.gyro_matrix, np.eye(3), atol=1e-4)
    # Same seed, same draw; another seed, another.
    again = vio.make_setup(5)
    np.testing.assert_array_equal(again.gyro_matrix, setup.gyro_matrix)
    assert not np.array_equal(vio.make_setup(6).gyro_matrix, setup.gyro_matrix)


def test_fusion_starts_from_the_first_pnp_pose(short_walk):
    traj, setup = short_walk
    spec = vio.condition_spec("ideal")
    run = vio.capture_visual(traj, spec, BatchRng.from_seeds([1]), setup, vio.pnp_params(spec))
    pos, quat, counters = vio.fuse(traj, run, vio.filter_config())
    j0 = int(np.flatnonzero(run.ok)[0])
    s0 = counters["start"]
    assert s0 == run.sample[j0]
    assert np.all(np.isnan(pos[:s0]))
    np.testing.assert_array_equal(pos[s0], run.position[j0])  # the PnP pose, not the truth
    assert np.linalg.norm(pos[s0] - traj.pos[s0]) > 1e-4
    # And it converges: the last second is within the paper's visual bound.
    ep, _ = vio.error_series(pos[-1000:], quat[-1000:], traj.pos[-1000:], traj.quat[-1000:])
    assert np.sqrt(np.mean(ep**2)) < 0.05


def test_pnp_in_worker_threads_equals_pnp_here(short_walk):
    """Two PnP blocks of 600 frames in two threads give the poses of one thread, bit for bit."""
    traj, setup = short_walk
    spec = vio.condition_spec("ideal")
    a, b = (
        vio.capture_visual(
            traj, spec, BatchRng.from_seeds([2]), setup, vio.pnp_params(spec), workers=w
        )
        for w in (1, 2)
    )
    assert a.ok.size >= 719 and a.ok.mean() > 0.9
    np.testing.assert_array_equal(a.ok, b.ok)
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(a.quat, b.quat)


def test_bad_input_is_one_clear_error(capsys):
    assert main(["experiment", "vio", "--duration", "2"]) == 2
    assert "duration" in capsys.readouterr().err
    with pytest.raises(ValueError, match="kind"):
        vio.simulate("jog", 1.0, 0)
    with pytest.raises(ValueError, match=r"Mismatch.time_offset_s=0.2: must be in \[0, 0.05\] s"):
        vio.Mismatch(time_offset_s=0.2)
    with pytest.raises(ValueError, match="pixel_noise_scale"):
        vio.condition_spec("ideal", 0.0)

"""Seed 004's experiment (``vrloco experiment vio``) on a short run, through the command line.

One 15 s run (``main(["experiment", "vio", ...])``, two PnP threads) is shared by the
tests; each test checks a claim of the issue against the JSON it wrote.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from agents.cli import main
from agents.experiments import vio
from vrloco_env.batch_rng import BatchRng
from vrloco_env.head_tracking import PnpParams
from vrloco_env.sensors.head_camera import camera_spec, layout_landmarks
from vrloco_env.tasks import make_layout
from vrloco_env.world import RoomConfig

DURATION = 15.0


@pytest.fixture(scope="module")
def result(tmp_path_factory) -> dict:
    path = tmp_path_factory.mktemp("vio") / "vio.json"
    rc = main(["experiment", "vio", "--duration", str(DURATION), "--seed", "3",
               "--json", str(path)])  # fmt: skip
    assert rc == 0
    return json.loads(path.read_text())


def test_json_has_the_issue_keys(result):
    for cond in ("ideal", "complex"):
        assert {"pos_m", "att_deg"} <= set(result["fused"][cond])
    assert {"static", "rotation"} <= set(result["imu_only"])
    for kind in ("static", "rotation"):
        assert {"pos_m", "att_deg", "pos_at_m", "att_at_deg"} <= set(result["imu_only"][kind])
    for cond in ("ideal", "low_light", "occlusion", "motion_blur", "complex"):
        row = result["visual_only"][cond]
        assert {"pos_m", "att_deg", "availability", "extraction", "matching"} <= set(row)
    assert {"fixed", "sage_husa"} <= set(result["adaptive"])
    assert result["config"]["duration_s"] == DURATION
    assert result["config"]["imu_rate_hz"] == 1000.0 and result["config"]["camera_rate_hz"] == 120.0
    # 120 frames/s over the run, every frame through PnP.
    assert result["visual_only"]["ideal"]["frames"] == round(DURATION * 120.0)
    assert set(result["targets_met"]) >= {"fused_ideal", "fused_complex", "adaptive_beats_fixed"}


def test_fused_ideal_meets_target_and_beats_the_camera(result):
    fused, cam = result["fused"]["ideal"], result["visual_only"]["ideal"]
    assert fused["pos_m"] < 0.05 and fused["att_deg"] < 1.0
    assert fused["pos_window_max_m"] < 0.05 and fused["att_window_max_deg"] < 1.0
    # Better than the camera alone, even with the camera's gross errors left out.
    assert fused["pos_m"] < cam["pos_clean_m"] and fused["att_deg"] < cam["att_clean_deg"]
    # Bounded: the last quarter is not worse than the first beyond noise.
    assert fused["pos_last_m"] < 2.0 * fused["pos_first_m"] + 0.005
    assert result["targets_met"]["fused_ideal"] and result["targets_met"]["fused_ideal_bounded"]


def test_fused_complex_meets_target(result):
    fused, cam = result["fused"]["complex"], result["visual_only"]["complex"]
    assert fused["pos_m"] < 0.1 and fused["att_deg"] < 3.0
    assert fused["pos_window_max_m"] < 0.1 and fused["att_window_max_deg"] < 3.0
    # The camera alone is far from usable there: few frames give a pose.
    assert cam["availability"] < 0.5
    assert fused["pos_m"] < cam["pos_m"]


def test_adaptive_filter_beats_fixed_r_after_the_noise_change(result):
    a = result["adaptive"]
    assert a["switch_s"] == pytest.approx(DURATION / 2, abs=0.01)
    # Same before the switch (both start from the ideal-tuned R) ...
    assert a["sage_husa"]["before_pos_m"] < 0.02 and a["fixed"]["before_pos_m"] < 0.02
    # ... clearly apart after it.
    assert a["sage_husa"]["pos_m"] < 0.5 * a["fixed"]["pos_m"]
    assert a["sage_husa"]["att_deg"] < 0.5 * a["fixed"]["att_deg"]
    # The noisy camera really is noisier than the tuned R.
    assert a["visual_after_switch"]["pos_clean_m"] > 3 * a["tuned_r"]["position_sigma_m"]


def test_imu_only_drift_grows(result):
    for kind in ("static", "rotation"):
        r = result["imu_only"][kind]
        assert r["pos_at_m"][-1] > 4.0 * r["pos_at_m"][0] > 0.0  # at least ~t^1 growth, ~t^2 here
        assert r["att_at_deg"][-1] > r["att_at_deg"][0]
        assert r["pos_m"] >= r["pos_end_m"] and r["att_deg"] >= r["att_end_deg"]
    assert result["imu_only"]["paper_position_check"]["position_from_bias_m"] == pytest.approx(36.0)


def test_extraction_and_matching_rates_near_presets(result):
    v = result["visual_only"]
    assert v["ideal"]["extraction"] == pytest.approx(0.95, abs=0.03)
    assert v["ideal"]["matching"] == pytest.approx(0.90, abs=0.02)
    assert v["low_light"]["extraction"] == pytest.approx(0.70, abs=0.04)
    assert v["occlusion"]["matching"] == pytest.approx(0.60, abs=0.03)
    assert v["occlusion"]["extraction"] < v["ideal"]["extraction"] - 0.15  # the occluder hides some
    assert v["complex"]["matching"] == pytest.approx(0.85 * 0.60, abs=0.04)
    assert v["ideal"]["availability"] > 0.9


def test_complex_camera_combines_low_light_and_occlusion():
    spec = vio.complex_spec()
    low, occ = camera_spec("low_light"), camera_spec("occlusion")
    assert spec.extraction_prob == low.extraction_prob
    assert spec.pixel_noise_px == low.pixel_noise_px
    assert spec.occluder_fraction == occ.occluder_fraction
    assert spec.match_prob == pytest.approx(low.match_prob * occ.match_prob)


def test_pnp_in_worker_threads_equals_pnp_here():
    traj = vio.simulate("walk", 1.5, 5)
    layout = make_layout("approach", RoomConfig(), np.random.default_rng(0)).with_origin((0, 0))
    lm, nrm = layout_landmarks(layout)
    caps = {
        c: vio._capture(traj, vio.condition_spec(c), BatchRng.from_seeds([i]), lm, nrm,
                        PnpParams(), 0)
        for i, c in enumerate(("ideal", "complex"))
    }  # fmt: skip
    here = vio._solve_all(caps, 1)
    there = vio._solve_all(caps, 2)
    for c in caps:
        a, b = vio._assemble(caps[c], here[c]), vio._assemble(caps[c], there[c])
        assert a.ok.size == 180
        np.testing.assert_array_equal(a.ok, b.ok)
        np.testing.assert_array_equal(a.position, b.position)
        np.testing.assert_array_equal(a.quat, b.quat)
    assert vio._assemble(caps["ideal"], here["ideal"]).ok.mean() > 0.9


def test_bad_duration_is_one_clear_error(capsys):
    assert main(["experiment", "vio", "--duration", "2"]) == 2
    assert "duration" in capsys.readouterr().err
    with pytest.raises(ValueError, match="kind"):
        vio.simulate("jog", 1.0, 0)

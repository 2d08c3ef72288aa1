"""The published-findings experiment: its tests decide as stated, and its output has the fields
and ids the scenarios promise."""

import json

import numpy as np
import pytest

from agents.experiments.published.run import decide, run_published
from agents.experiments.published.scenarios import FINDINGS

BY_ID = {f.id: f for f in FINDINGS}
IDS = (
    "tregillus2017_head_tilt",
    "tregillus2016_vr_step",
    "lee2018_steps",
    "lai2020_steering",
    "bruno2017_hip_steering",
    "wip_stop_latency",
)


def test_every_finding_of_the_issue_is_written_down_once():
    assert tuple(f.id for f in FINDINGS) == IDS


def test_a_difference_is_reproduced_only_when_significant_in_the_expected_direction():
    f = BY_ID["tregillus2017_head_tilt"]  # expected: B < A
    rng = np.random.default_rng(0)
    a = rng.normal(20.0, 2.0, 40)
    faster = np.stack([a, a - 3.0 + rng.normal(0, 0.5, 40)])
    slower = np.stack([a, a + 3.0 + rng.normal(0, 0.5, 40)])
    same = np.stack([a, a + rng.normal(0, 0.5, 40)])
    assert decide(f, None, faster)["verdict"] == "reproduced"
    assert decide(f, None, slower)["verdict"] == "not reproduced"
    row = decide(f, None, same)
    assert row["verdict"] == "not reproduced" and row["p"] > 0.05


def test_equivalence_needs_the_tost_inside_the_margin_not_a_failed_difference_test():
    f = BY_ID["lai2020_steering"]  # margin: 10 % of A's development mean
    rng = np.random.default_rng(1)
    dev = np.stack([np.full(20, 20.0), np.full(20, 20.0)])  # margin 2.0 s
    a = rng.normal(20.0, 3.0, 60)
    close = np.stack([a, a + rng.normal(0.0, 0.5, 60)])
    row = decide(f, dev, close)
    assert row["margin"] == pytest.approx(2.0) and row["verdict"] == "reproduced"
    # noisy pairs: no significant difference, yet not shown equivalent either
    noisy = np.stack([a, a + rng.normal(0.0, 12.0, 60)])
    row = decide(f, dev, noisy)
    assert row["verdict"] == "not reproduced" and row["p"] >= 0.05


def test_a_range_is_reproduced_when_the_interval_overlaps_it():
    f = BY_ID["wip_stop_latency"]  # [1/6, 0.28] s
    inside = np.array([[0.2, 0.22, 0.25, 0.21, np.nan]])
    outside = np.array([[0.6, 0.7, 0.65, 0.62]])
    assert decide(f, None, inside)["verdict"] == "reproduced"
    assert decide(f, None, outside)["verdict"] == "not reproduced"
    assert decide(f, None, inside)["n_episodes"] == 4  # the NaN episode left out


def test_the_json_has_every_finding_with_the_promised_fields(tmp_path):
    out = tmp_path / "published.json"
    run_published(
        json_path=out, episodes=2, findings=["wip_stop_latency", "bruno2017_hip_steering"]
    )
    data = json.loads(out.read_text())
    keys = {
        "id",
        "source",
        "study_n",
        "scenario",
        "metric",
        "expected",
        "effect",
        "ci",
        "p",
        "verdict",
    }
    assert [r["id"] for r in data["findings"]] == ["bruno2017_hip_steering", "wip_stop_latency"]
    for r in data["findings"]:
        assert keys <= set(r)
        assert r["verdict"] in ("reproduced", "not reproduced", "not testable")
    assert data["findings"][0]["verdict"] == "not testable" and data["findings"][0]["why"]
    with pytest.raises(ValueError, match="findings: nope unknown; valid ids: tregillus2017"):
        run_published(findings=["nope"])


def test_the_table_names_finding_source_study_size_effect_and_verdict():
    from agents.experiments.published.run import format_table

    row = decide(BY_ID["tregillus2017_head_tilt"], None, np.array([[20.0, 21.0], [19.0, 20.5]]))
    line = format_table([row]).splitlines()[1]
    assert line.split()[:4] == ["tregillus2017_head_tilt", "Tregillus", "CHI", "2017"]
    assert " 24 " in line and "[" in line and line.endswith(row["verdict"])

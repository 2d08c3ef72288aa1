"""Two runs' pairs side by side: verdicts, the metrics either run separates on, counts."""

from __future__ import annotations

import json

import pytest

from agents.benchmark.compare_runs import compare_pairs, load_pairs, main, render


def _pair(name, separates, on_outcome, metrics):
    return {
        "pair": name,
        "technique": name,
        "policy": "goal_seeker",
        "condition": "lab",
        "why": "",
        "separates": separates,
        "on_outcome": on_outcome,
        "tasks": {"approach": metrics},
    }


def _write(folder, pairs):
    folder.mkdir()
    (folder / "pairs.json").write_text(json.dumps(pairs))
    return folder


def test_a_pair_that_stops_separating_shows_its_metrics_in_both_runs(tmp_path, capsys):
    a = _write(
        tmp_path / "a",
        [
            _pair(
                "x",
                True,
                True,
                {
                    "success_rate": {"diff": -0.2, "p": 0.001, "verdict": "for"},
                    "spl": {"diff": 0.0, "p": 0.9, "verdict": None},
                },
            ),
            _pair("only_a", False, False, {}),
        ],
    )
    b = _write(
        tmp_path / "b",
        [
            _pair(
                "x",
                False,
                False,
                {
                    "success_rate": {"diff": -0.05, "p": 0.4, "verdict": None},
                    "spl": {"diff": 0.0, "p": 0.8, "verdict": None},
                },
            ),
        ],
    )
    records = compare_pairs(load_pairs(a), load_pairs(b))
    assert [r["pair"] for r in records] == ["x", "only_a"]
    x = records[0]
    assert [m["metric"] for m in x["metrics"]] == ["approach:success_rate"]  # spl: neither
    assert x["metrics"][0]["a"]["p"] == 0.001 and x["metrics"][0]["b"]["verdict"] is None
    assert records[1]["b"] is None
    text = render(records, "old", "new")
    assert "x: separates yes, on an outcome -> no" in text
    assert "old: 1 of 2 pairs separate, 1 on an outcome" in text
    assert "new: 0 of 1 pairs separate, 0 on an outcome" in text
    assert main([str(a), str(b), "--markdown"]) == 0
    assert "| **x** | separates: yes, on an outcome -> no | | |" in capsys.readouterr().out


def test_a_folder_without_pairs_is_one_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"no pairs\.json"):
        load_pairs(tmp_path)
    (tmp_path / "pairs.json").write_text('{"not": "a list"}')
    with pytest.raises(ValueError, match="expected a list of pairs"):
        load_pairs(tmp_path)

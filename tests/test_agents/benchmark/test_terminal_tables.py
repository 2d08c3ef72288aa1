"""The benchmark's terminal tables at common widths: names kept, values whole, widths honoured."""

from __future__ import annotations

import re

import pytest

from agents.benchmark.collision_causes import COLLISION_CAUSES
from agents.benchmark.discrimination import show_pairs
from agents.benchmark.outputs import ROW_KEYS, show_table, written_summary

POPULATIONS = ("typical", "nodders", "gaze_scanners")
TECHNIQUES = ("zhang2021", "zhang2021_consumer", "threshold_steps", "torso_steering")


def _rows(policies=None):
    rows = []
    policies = policies or [f"goal_seeker+{p}" for p in POPULATIONS]
    for k, (policy, technique) in enumerate((p, t) for p in policies for t in TECHNIQUES):
        row = {key: 0.5 + k / 1000 for key in ROW_KEYS}
        row.update(
            task="approach",
            policy=policy,
            technique=technique,
            condition="beside_metal",
            sensors="consumer_mems",
            episodes=60,
            virtual_jerk_m_s3=532.125 + k,
            vs_baseline={"spl": {"p": 0.001}, "stop_latency_s": {"p": 0.002}},
            collision_causes=dict.fromkeys(COLLISION_CAUSES, 2),
        )
        rows.append(row)
    return rows


def _data_lines(out, rows):
    return [line for line in out.splitlines() if line.strip().startswith("approach")]


@pytest.mark.parametrize("width", [80, 100, 120])
def test_narrow_tables_keep_the_users_and_whole_values(capsys, width):
    rows = _rows()
    show_table(rows, 0, width=width)
    out = capsys.readouterr().out
    assert max(len(line) for line in out.splitlines()) <= width
    assert "…" not in out  # nothing cut mid-value
    lines = _data_lines(out, rows)
    assert len(lines) == 2 * len(rows)  # both tables, one line per row: nothing wrapped
    for line, row in zip(lines, rows + rows, strict=True):
        population = row["policy"].partition("+")[2]
        assert re.search(rf"\b{population}\b", line), line  # the users column is kept
        assert re.search(rf"\b{row['technique']}\b", line), line
    # a starred value keeps its star: SPL in the outcomes (where the width leaves it a column)
    # and stop latency in the walking-in-place table
    spl_shown = any(" SPL " in f" {line} " for line in out.splitlines()[:4])
    for line, row in zip(lines[: len(rows)], rows, strict=True):
        assert (f"{row['spl']:.3f}*" in line) == spl_shown, line
    for line, row in zip(lines[len(rows) :], rows, strict=True):
        assert f"{row['stop_latency_s']:.3f}*" in line, line
    assert spl_shown or width < 100  # at 100 columns and wider the outcomes show SPL
    assert "users: goal_seeker" in out
    if width == 80:
        assert "not shown at this width" in out  # what was left out is named


def test_rows_of_several_policies_show_each_policy(capsys):
    rows = _rows(["goal_seeker+typical", "avoid_manoeuvre"])
    show_table(rows, 0, width=100)
    out = capsys.readouterr().out
    assert "avoid_manoeuvre" in out and "goal_seeker+typical" in out
    assert max(len(line) for line in out.splitlines()) <= 100


def test_piped_output_honours_columns(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "100")
    show_table(_rows(), 0)  # capsys: not a terminal
    out = capsys.readouterr().out
    assert max(len(line) for line in out.splitlines()) <= 100
    assert "compact view for 100 columns" in out
    monkeypatch.delenv("COLUMNS")
    show_table(_rows(), 0)
    out = capsys.readouterr().out
    assert "time to goal (s)" in out and "compact" not in out  # the full table


def test_the_pairs_table_wraps_between_names(capsys):
    metrics = [
        "heading_error_rmse_deg",
        "attitude_rmse_deg",
        "yaw_rate_mismatch_deg_s",
        "phantom_steps_per_min",
    ]
    res = {
        "pair": "zhang2021_consumer (typical, lab)",
        "separates": True,
        "on_outcome": False,
        "metrics": metrics,
        "tasks": {},
    }
    show_pairs([res], width=100)
    out = capsys.readouterr().out
    assert max(len(line) for line in out.splitlines()) <= 100
    for m in metrics:
        assert m in out, m  # every name whole on one line
    assert "zhang2021_consumer (typical, lab): separates yes" in " ".join(out.split())
    assert "1 of 1 pairs separate" in out
    show_pairs([res], width=200)
    out = capsys.readouterr().out
    assert out.splitlines()[1].endswith("┓")  # the table, whole
    assert all(m in out for m in metrics)


def test_written_files_are_summarised_by_kind(tmp_path):
    cells = [f"approach_goal_seeker_{t}" for t in TECHNIQUES]
    paths = [
        tmp_path / "benchmark.csv",
        tmp_path / "benchmark.json",
        tmp_path / "pairs.json",
        *(
            tmp_path / f"{kind}_{c}.png"
            for kind in ("trajectory", "attitude", "gait")
            for c in cells
        ),
        tmp_path / "metrics.png",
    ]
    lines = written_summary(paths)
    assert len(lines) == 7
    assert f"wrote 4 trajectory_*.png in {tmp_path}" in lines
    assert f"wrote benchmark.csv in {tmp_path}" in lines

"""Readers of the real recordings (estimators.io): the Oxford step-counter walk and its foot
switches, and the Kinect CSV reader's errors."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.io import foot_switch_steps, load_oxford, read_kinect_csv
from estimators.rotations import GRAVITY


def test_oxford_reader(real_data):
    rec = load_oxford(real_data("oxford"))
    assert rec.step_times.size == 248
    assert 132.0 < rec.duration < 134.0
    assert rec.acc.shape == (rec.t.size, 3)
    assert np.all(np.diff(rec.t) > 0)
    # A static moment: the norm is near gravity on average over the walk.
    assert abs(np.linalg.norm(rec.acc, axis=1).mean() - GRAVITY) < 0.5
    with pytest.raises(FileNotFoundError):
        load_oxford(real_data("oxford").parent / "no_such_recording")


def test_foot_switch_debounce():
    t = np.arange(12) * 0.09
    right = np.array([0, 1, 1, 0, 1, 1, 0, 0, 0, 0, 1, 1])  # chatter at 0.27-0.36 s
    left = np.zeros(12, dtype=int)
    assert foot_switch_steps(t, right, left, debounce=0.0).size == 3
    np.testing.assert_allclose(foot_switch_steps(t, right, left, debounce=0.3), [0.09, 0.9])
    with pytest.raises(ValueError, match="0/1"):
        foot_switch_steps(t, right * 2, left)


def test_kinect_csv_reader_errors_name_line_and_column(tmp_path, real_data):
    lines = real_data("kinect").read_text().splitlines()

    def edit(line, col, value):  # replace the 1-based field ``col`` of a row
        f = line.split(",")
        f[col - 1] = value
        return ",".join(f)

    cases = {
        "short.csv": ([lines[0], lines[1].rsplit(",", 3)[0] + ","], "line 2: expected 101"),
        "text.csv": ([edit(lines[0], 4, "abc")], "line 1, column 4: not a number"),
        "state.csv": ([lines[0], edit(lines[1], 5, "7")], "line 2, column 5: tracking state"),
        "time.csv": ([lines[1], lines[0]], "line 2, column 1"),
    }
    for name, (rows, msg) in cases.items():
        p = tmp_path / name
        p.write_text("\n".join(rows) + "\n")
        with pytest.raises(ValueError, match=msg):
            read_kinect_csv(p)
    (tmp_path / "empty.csv").write_text("\n")
    with pytest.raises(ValueError, match="no data"):
        read_kinect_csv(tmp_path / "empty.csv")

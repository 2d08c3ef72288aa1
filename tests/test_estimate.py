"""`vrloco estimate` on a recording written from the simulator, and its errors."""

import numpy as np
import pytest

from agents.cli import main
from agents.estimate import read_csv_recording
from vrloco_env.batch_rng import BatchRng
from vrloco_env.motion import run_script
from vrloco_env.sensors.imu import HeadImu, get_imu_spec


@pytest.fixture
def recording(tmp_path):
    rng = BatchRng.from_seeds([4])
    rec = run_script("avoid", rng)
    s = HeadImu(get_imu_spec("ig500n"), rng).sample(rec.quat, rec.omega, rec.acc, rec.pos)
    # Irregular timestamps (a phone-like clock): jitter of +-2 ms around 100 Hz.
    t = rec.t + np.random.default_rng(0).uniform(-0.002, 0.002, rec.t.size)
    table = np.column_stack([t, s.gyr[0], s.acc[0], s.mag[0]])
    path = tmp_path / "walk.csv"
    np.savetxt(path, table, delimiter=",", header="t,gx,gy,gz,ax,ay,az,mx,my,mz", comments="")
    return path, rec


def test_estimate_recovers_steps_and_the_turn_away_and_back(recording, tmp_path):
    path, rec = recording
    assert main(["estimate", str(path), "--out", str(tmp_path / "out")]) == 0
    out = np.genfromtxt(tmp_path / "out" / "walk_estimates.csv", delimiter=",", names=True)
    true_steps = rec.step_times[0].size
    assert abs(out["step"].sum() - true_steps) <= 1
    yaw_true = np.rad2deg(rec.ypr[0, :, 0])
    assert np.abs(out["yaw_deg"] - yaw_true).max() < 3.0  # the 45 deg turn away and back
    assert (tmp_path / "out" / "walk_estimates.png").stat().st_size > 10_000


def test_malformed_csv_names_the_line_and_column(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n0.01,0,0,oops,0,0,9.8\n")
    with pytest.raises(ValueError, match=r"line 3, column 4 \(gz\): cannot read 'oops'"):
        read_csv_recording(bad)
    assert main(["estimate", str(bad), "--out", str(tmp_path)]) == 2
    assert "line 3, column 4 (gz)" in capsys.readouterr().err
    bad.write_text("t,gx,gy,gz,ax,ay\n0,0,0,0,0,0\n")
    with pytest.raises(ValueError, match=r"line 1: missing column.*az"):
        read_csv_recording(bad)
    bad.write_text("t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n0.01,0,0,0,0,0,9.8\n0.005,0,0,0,0,0,9.8\n")
    with pytest.raises(ValueError, match=r"line 4, column 1 \(t\): time 0.005 runs backwards"):
        read_csv_recording(bad)
    # Equal timestamps are one sample (the mean of the rows), said in one line.
    bad.write_text("t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n0.01,0,0,0,0,0,9.6\n0.01,0,0,0,0,0,9.8\n")
    rec = read_csv_recording(bad)
    np.testing.assert_allclose(rec.t, [0.0, 0.01])
    np.testing.assert_allclose(rec.acc[:, 2], [9.8, 9.7])
    assert "1 rows repeat the previous row's timestamp" in capsys.readouterr().err


def test_a_step_length_outside_a_persons_range_is_refused(recording, tmp_path, capsys):
    assert main(["estimate", str(recording), "--out", str(tmp_path), "--step-length", "0"]) == 2
    assert "step_length=0.0: must be in [0.2, 1.5] m" in capsys.readouterr().err


def test_the_oxford_reader_merges_repeated_timestamps_and_refuses_backward_time(tmp_path):
    from estimators.io_oxford import _read_csv

    p = tmp_path / "accelerometer.csv"
    p.write_text("100,1,2,3\n200,1,2,3\n200,3,2,1\n300,0,0,0\n")
    t, v = _read_csv(p, 4)
    np.testing.assert_array_equal(t, [100, 200, 300])
    np.testing.assert_allclose(v[1], [2.0, 2.0, 2.0])
    p.write_text("100,1,2,3\n50,1,2,3\n")
    with pytest.raises(ValueError, match="time runs backwards at row 2"):
        _read_csv(p, 4)

"""`vrloco estimate` on a recording written from the simulator, and its errors."""

import json
import re

import numpy as np
import pytest

from agents.cli import main
from agents.recordings.readers import read_csv_recording
from agents.recordings.units import Units
from estimators.rotations import GRAVITY
from vrloco_env.batch_rng import BatchRng
from vrloco_env.sensors.imu import HeadImu, get_imu_spec
from vrloco_env.user import run_script


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
    bad.write_text(
        "t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n0.01,0,0,0,0,0,9.8\n0.005,0,0,0,0,0,9.8\n"
    )
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
    from estimators.io.oxford import read_accelerometer

    p = tmp_path / "accelerometer.csv"
    p.write_text("100,3,1,2,3\n200,3,1,2,3\n200,3,3,2,1\n300,3,0,0,0\n")
    t, acc, t0 = read_accelerometer(tmp_path)
    assert t0 == 100
    np.testing.assert_allclose(t, [0.0, 100e-9, 200e-9], rtol=1e-12)
    np.testing.assert_allclose(acc[1], [2.0, 2.0, 2.0])  # the two samples at 200 ns, averaged
    p.write_text("100,3,1,2,3\n50,3,1,2,3\n")
    with pytest.raises(ValueError, match="time runs backwards at row 2"):
        read_accelerometer(tmp_path)


# ------------------------------------------------------------------------------------------------
# Silent wrong results turned into warnings or errors, on variants of one simulated walk.
# ------------------------------------------------------------------------------------------------

HEADER = "t,gx,gy,gz,ax,ay,az,mx,my,mz"


@pytest.fixture(scope="module")
def walk():
    """The 'avoid' walk (45 deg away and back, 22 s at 100 Hz): the file's columns and truth."""
    rng = BatchRng.from_seeds([4])
    rec = run_script("avoid", rng)
    s = HeadImu(get_imu_spec("ig500n"), rng).sample(rec.quat, rec.omega, rec.acc, rec.pos)
    table = np.column_stack([rec.t, s.gyr[0], s.acc[0], s.mag[0]])
    return table, rec


def _write(path, table, header=HEADER):
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt="%.9g")
    return path


def _estimate(path, out, capsys):
    """Run ``vrloco estimate``: its exit code, stderr, the estimates table and the summary."""
    code = main(["estimate", str(path), "--out", str(out)])
    std = capsys.readouterr()
    if code != 0:
        return code, std.err, None, None
    summary = json.loads(std.out)
    est = np.genfromtxt(summary["csv"], delimiter=",", names=True)
    return code, std.err, est, summary


def _angle_error_deg(est_deg, true_rad):
    return np.abs((est_deg - np.rad2deg(true_rad) + 180.0) % 360.0 - 180.0)


def test_an_impossible_gyro_sample_is_treated_as_missing_and_said(walk, tmp_path, capsys):
    table, rec = walk
    table = table.copy()
    table[700, 1] = 1e30  # one corrupt sample; read as a rate it tips the attitude over
    code, err, est, _ = _estimate(_write(tmp_path / "spike.csv", table), tmp_path, capsys)
    assert code == 0
    assert "1 of 2200 rows hold values beyond any IMU's range (gyro 1;" in err
    assert "treated them as missing (NaN)" in err and "(line 702)" in err
    assert len(err.strip().splitlines()) == 1
    assert _angle_error_deg(est["roll_deg"], rec.ypr[0, :, 2]).max() < 3.0
    assert _angle_error_deg(est["yaw_deg"], rec.ypr[0, :, 0]).max() < 3.0


def test_a_file_of_mostly_impossible_values_is_an_error(walk, tmp_path):
    table = walk[0].copy()
    table[::2, 4:7] = 1e6  # half the rows and one more
    table[1, 4] = 1e6
    with pytest.raises(ValueError, match=r"1101 of 2200 rows hold values no IMU can read"):
        read_csv_recording(_write(tmp_path / "junk.csv", table))


def test_a_gyro_in_deg_per_s_is_found_read_and_said(walk, tmp_path, capsys):
    table = walk[0].copy()
    table[:, 1:4] = np.degrees(table[:, 1:4])  # this walk never turns faster than 35 deg/s
    assert np.linalg.norm(table[:, 1:4], axis=1).max() < 35.0
    rec = read_csv_recording(_write(tmp_path / "deg.csv", table))
    np.testing.assert_allclose(rec.gyr, walk[0][:, 1:4], rtol=1e-8, atol=1e-12)
    assert rec.units == {"time": "s", "acc": "m/s2", "gyro": "deg/s"}
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert re.search(
        r"read gx, gy, gz in deg/s, as the magnetometer says \(its field turns "
        r"5\d\.\d times slower .*pass --gyro-unit deg/s",
        err,
    )
    # Without a magnetometer, fast turns give deg/s away: many samples beyond 2000 deg/s.
    rng = BatchRng.from_seeds([1])
    rec = run_script("shake", rng)
    s = HeadImu(get_imu_spec("ig500n"), rng).sample(rec.quat, rec.omega, rec.acc, rec.pos)
    six = np.column_stack([rec.t, np.degrees(s.gyr[0]), s.acc[0]])
    got = read_csv_recording(_write(tmp_path / "deg6.csv", six, "t,gx,gy,gz,ax,ay,az"))
    np.testing.assert_allclose(got.gyr, s.gyr[0], rtol=1e-8, atol=1e-12)
    assert re.search(
        r"as the gyro's magnitude says \(\d+ of 2000 samples exceed 35 rad/s",
        capsys.readouterr().err,
    )


def _turn(tmp_path, name, cadence=0.0, rate_deg_s=10.0):
    """A simulated user standing 2 s, turning at ``rate_deg_s`` for 4 s (stepping at
    ``cadence``), standing 2 s: a 6-axis CSV with the gyro in deg/s, and the true final yaw."""
    from vrloco_env.user.motion import Intent, MotionParams, MotionRecord, UserMotion

    rng = BatchRng.from_seeds([4])
    params = MotionParams()
    n = round(params.control_rate_hz)  # control steps per second
    motion = UserMotion(params, rng)
    motion.reset(yaw=0.0)
    turn = Intent(cadence=cadence, turn_rate=np.radians(rate_deg_s))
    rec = MotionRecord.concatenate(
        [motion.advance(i) for i in [Intent()] * 2 * n + [turn] * 4 * n + [Intent()] * 2 * n]
    )
    s = HeadImu(get_imu_spec("ig500n"), rng).sample(rec.quat, rec.omega, rec.acc, rec.pos)
    table = np.column_stack([rec.t, np.degrees(s.gyr[0]), s.acc[0]])
    return _write(tmp_path / f"{name}.csv", table, "t,gx,gy,gz,ax,ay,az"), np.degrees(
        rec.ypr[0, -1, 0]
    )


def _final_yaw(path, out, capsys, *options):
    """``vrloco estimate PATH OPTIONS``: exit code, stderr and the last yaw (deg, None on error)."""
    code = main(["estimate", str(path), "--out", str(out), *options])
    std = capsys.readouterr()
    if code != 0:
        return code, std.err, None
    summary = json.loads(std.out)
    return code, std.err, np.genfromtxt(summary["csv"], delimiter=",", names=True)["yaw_deg"][-1]


def test_a_slow_turn_in_deg_per_s_gives_the_true_yaw_given_or_found_by_the_tilt(tmp_path, capsys):
    path, true_yaw = _turn(tmp_path, "slow")
    assert true_yaw == pytest.approx(40.0, abs=0.5)
    code, err, yaw = _final_yaw(path, tmp_path, capsys, "--gyro-unit", "deg/s")
    assert code == 0 and err == ""
    assert yaw == pytest.approx(true_yaw, abs=2.0)
    # auto: the head's small tilts, carried by the gyro read in rad/s, spin gravity around.
    code, err, yaw = _final_yaw(path, tmp_path, capsys)
    assert code == 0 and yaw == pytest.approx(true_yaw, abs=2.0)
    assert err.count("\n") == 1
    assert "read gx, gy, gz in deg/s, as the accelerometer's tilt says (gravity" in err
    # Told rad/s, it reads rad/s (the user's word) and says in one line that the tilt disagrees.
    code, err, yaw = _final_yaw(path, tmp_path, capsys, "--gyro-unit", "rad/s")
    assert code == 0 and abs(yaw - true_yaw) > 10.0
    assert err.count("\n") == 1
    assert (
        "gx, gy, gz are read in rad/s (given), but the accelerometer's tilt says deg/s "
        "(gravity, carried 4 s at a time"
    ) in err and err.rstrip().endswith("check --gyro-unit")


def test_a_level_turn_in_deg_per_s_with_nothing_to_tell_the_unit_is_an_error(tmp_path, capsys):
    # A level sensor turning at 10 deg/s about the vertical: no magnetometer, no tilt, rates far
    # below 35: rad/s and deg/s fit the data alike, and give 40 deg or 2292 deg of turn.
    t = np.arange(800) / 100.0
    noise = np.random.default_rng(0).normal(0.0, 0.02, (800, 3))
    gyr = np.zeros((800, 3)) + noise * 0.1
    gyr[(t >= 2.0) & (t < 6.0), 2] += 10.0
    acc = np.array([0.0, 0.0, 9.81]) + noise
    path = _write(tmp_path / "level.csv", np.column_stack([t, gyr, acc]), "t,gx,gy,gz,ax,ay,az")
    code, err, _ = _final_yaw(path, tmp_path, capsys)
    assert code == 2 and "Traceback" not in err and err.count("\n") == 1
    assert err.startswith(
        f"vrloco estimate: {path}: cannot tell whether gx, gy, gz are in rad/s "
        "or deg/s: none exceeds 35 rad/s, no magnetometer, and the "
        "accelerometer's tilt fits both"
    )
    # 2 s of the turn in the first 4 s window: 20 rad
    assert re.search(
        r"read as rad/s the gyro turns the sensor 114\d deg within 4 s \(over 10 "
        r"deg\)",
        err,
    )
    assert err.rstrip().endswith("pass --gyro-unit rad/s or --gyro-unit deg/s")
    assert not (tmp_path / "level_estimates.csv").exists()
    code, err, yaw = _final_yaw(path, tmp_path, capsys, "--gyro-unit", "deg/s")
    assert code == 0 and err == "" and yaw == pytest.approx(40.0, abs=1.0)
    rec = read_csv_recording(path, Units(gyro="deg/s"))
    np.testing.assert_allclose(rec.gyr, np.radians(gyr), rtol=1e-8, atol=1e-12)
    # Standing still, both units give the same attitude: no unit needed.
    still = np.column_stack([t, noise * 0.1, acc])
    assert (
        read_csv_recording(_write(tmp_path / "still.csv", still, "t,gx,gy,gz,ax,ay,az")).units[
            "gyro"
        ]
        == "rad/s"
    )


def test_a_magnetometer_against_the_gyro_unit_is_a_warning(walk, tmp_path, capsys):
    table = walk[0]
    path = _write(tmp_path / "rad.csv", table)
    code, err, _ = _final_yaw(path, tmp_path, capsys, "--gyro-unit", "deg/s")
    assert code == 0 and err.count("\n") == 1
    assert re.search(
        r"rad.csv: gx, gy, gz are read in deg/s \(given\), but the magnetometer "
        r"says rad/s \(its field turns (0\.9\d*|1|1\.0\d*) times slower than the "
        r"gyro's numbers say \(1 for rad/s, 57.3 for deg/s\)\); check --gyro-unit",
        err,
    )
    # Found, not given: a few corrupt samples over 35 rad/s make the gyro look like deg/s, and
    # the magnetometer says otherwise.
    spiky = table.copy()
    spiky[::50, 1] = 40.0  # 2 % of the samples: possible in deg/s only
    code, err, _ = _final_yaw(_write(tmp_path / "spiky.csv", spiky), tmp_path, capsys)
    assert code == 0 and err.count("\n") == 2  # what was read, and what disagrees
    assert "read gx, gy, gz in deg/s, as the gyro's magnitude says (44 of 2200 samples" in err
    assert re.search(
        r"gx, gy, gz are read in deg/s \(found\), but the magnetometer says rad/s "
        r"\(its field turns",
        err,
    )
    # In agreement: no line.
    code, err, _ = _final_yaw(path, tmp_path, capsys, "--gyro-unit", "rad/s")
    assert code == 0 and err == ""


def test_time_and_accelerometer_units_are_found_read_and_said_or_given(walk, tmp_path, capsys):
    table = walk[0].copy()
    table[:, 0] *= 1000.0
    ms = _write(tmp_path / "ms.csv", table)
    rec = read_csv_recording(ms)
    np.testing.assert_allclose(rec.t, walk[0][:, 0], rtol=1e-12, atol=1e-12)
    assert rec.units["time"] == "ms"
    assert (
        "ms.csv: read t in ms (its median interval 10 is 100 Hz in ms, 0.1 Hz in s); pass "
        "--time-unit ms to say so"
    ) in capsys.readouterr().err
    assert read_csv_recording(ms, Units(time="ms")).units["time"] == "ms"
    assert capsys.readouterr().err == ""
    with pytest.raises(
        ValueError,
        match=r"ms.csv: read in s \(--time-unit s\), t's median "
        r"interval is 10 s \(0.1 Hz\), but an IMU samples at 5 Hz "
        r"to 10000 Hz: t looks like ms \(--time-unit ms\)",
    ):
        read_csv_recording(ms, Units(time="s"))
    table[:, 0] *= 1e6
    assert read_csv_recording(_write(tmp_path / "ns.csv", table)).units["time"] == "ns"
    assert "ns.csv: read t in ns" in capsys.readouterr().err
    # A median interval of 0.15: 6.7 Hz in s, 6.7 kHz in ms: both IMU rates, so it is asked for.
    slow = walk[0][:200].copy()
    slow[:, 0] = 0.15 * np.arange(200)
    with pytest.raises(
        ValueError,
        match=r"6.667 Hz in s, 6667 Hz in ms; both are IMU rates, so "
        r"the unit cannot be told: pass --time-unit s or ms",
    ):
        read_csv_recording(_write(tmp_path / "slow.csv", slow))
    # An accelerometer in g is read as g (said), with or without a gyro.
    g = walk[0][:, [0, 4, 5, 6]] / [1.0, 9.81, 9.81, 9.81]
    rec = read_csv_recording(_write(tmp_path / "g.csv", g, "t,ax,ay,az"))
    np.testing.assert_allclose(rec.acc, walk[0][:, 4:7] * (GRAVITY / 9.81), rtol=1e-8)
    assert re.search(
        r"g.csv: read ax, ay, az in g \(the median norm of their 1 s means, "
        r"1.00\d*, is gravity in g\); pass --acc-unit g to say so",
        capsys.readouterr().err,
    )
    assert (
        read_csv_recording(_write(tmp_path / "g.csv", g, "t,ax,ay,az"), Units(acc="g")).units["acc"]
        == "g"
    )
    with pytest.raises(
        ValueError,
        match=r"read in m/s2 \(--acc-unit m/s2\), the median norm "
        r"of the specific force averaged over 1 s is 1.00\d* "
        r"m/s\^2, not 0.5 g to 2 g \(gravity\): ax, ay, az "
        r"look like g \(--acc-unit g\)",
    ):
        read_csv_recording(tmp_path / "g.csv", Units(acc="m/s2"))
    # Gravity removed (a phone's linear acceleration): in no unit.
    linear = walk[0][:, [0, 4, 5, 6]] - [0.0, 0.0, 0.0, 9.81]
    with pytest.raises(
        ValueError,
        match=r"the median norm of the specific force averaged over "
        r"1 s is 0.\d+, neither in m/s\^2 nor in g within 0.5 g "
        r"to 2 g \(gravity\): gravity removed",
    ):
        read_csv_recording(_write(tmp_path / "lin.csv", linear, "t,ax,ay,az"))


def test_units_are_checked_by_name_and_fixed_by_the_broad_and_oxford_formats(
    walk, tmp_path, capsys
):
    from agents.recordings.readers import read_recording

    with pytest.raises(
        ValueError,
        match=r"Units.gyro='rpm': must be 'auto' or one of rad/s, "
        r"deg/s",
    ):
        Units(gyro="rpm")
    table, rec = walk
    trial = _broad_file(tmp_path / "sim.h5", table, rec.quat[0])
    with pytest.raises(
        ValueError,
        match=r"sim.h5: a BROAD trial is in rad/s by its format; a "
        r"gyro unit \('deg/s', --gyro-unit\) applies to CSV "
        r"files only",
    ):
        read_recording(trial, Units(gyro="deg/s"))
    assert read_recording(trial, Units(gyro="rad/s")).units["gyro"] == "rad/s"
    assert main(["estimate", str(trial), "--out", str(tmp_path), "--time-unit", "ms"]) == 2
    assert "a time unit ('ms', --time-unit) applies to CSV files only" in capsys.readouterr().err


def test_the_help_states_the_unit_checks_limits():
    from agents.cli import build_parser
    from agents.recordings import units as r

    sub = build_parser()._subparsers._group_actions[0].choices["estimate"]
    text = " ".join(sub.format_help().split())
    lo, hi = r.RATE_RANGE_HZ
    assert f"{lo:g} Hz to {hi / 1000:g} kHz" in text
    assert (
        f"median norm of the {r.ACC_MEAN_S:g} s means is {r.ACC_MEDIAN_RANGE_G[0]:g} g to "
        f"{r.ACC_MEDIAN_RANGE_G[1]:g} g"
    ) in text
    assert f"at least {r.UNIT_MIN_COUNT} samples and 1% exceed 35 rad/s" in text
    assert f"{r.RAD_RATIO_RANGE[0]:g}-{r.RAD_RATIO_RANGE[1]:g} times (rad/s)" in text
    assert f"{r.DEG_RATIO_RANGE[0]:g}-{r.DEG_RATIO_RANGE[1]:g} times (deg/s)" in text
    assert f"through {r.TILT_WINDOW_S:g} s windows" in text
    assert f"at least {r.TILT_RATIO:g} times and {r.TILT_MARGIN_DEG:g} deg less" in text
    assert f"under {r.UNDECIDED_TURN_DEG:g} deg in every {r.TILT_WINDOW_S:g} s window" in text


def test_missing_samples_are_bridged_and_counted(walk, tmp_path, capsys):
    table, rec = walk
    table = table.copy()
    table[800:850, 1:7] = np.nan  # half a second without gyro and accelerometer
    table[1500, 7] = np.nan
    code, err, est, _ = _estimate(_write(tmp_path / "holes.csv", table), tmp_path, capsys)
    assert code == 0
    assert (
        "51 of 2200 rows have missing values (NaN: acc 50, gyro 50, mag 1); the longest run "
        "of missing rows lasts 0.5 s from t = 8.01 s (line 802)"
    ) in err
    assert abs(est["step"].sum() - rec.step_times[0].size) <= 1
    # The turn at 30 deg/s goes on unseen for 0.5 s; the field gives the heading back within 1 s.
    err_deg = _angle_error_deg(est["yaw_deg"], rec.ypr[0, :, 0])
    assert err_deg.max() < 6.0
    assert np.delete(err_deg, np.s_[800:950]).max() < 2.0


def test_a_gap_in_the_timestamps_is_said_and_a_huge_one_refused(walk, tmp_path, capsys):
    table, rec = walk
    table = table.copy()
    table[1200:, 0] += 3600.0  # an hour without samples after 12 s
    code, err, est, _ = _estimate(_write(tmp_path / "gap.csv", table), tmp_path, capsys)
    assert code == 0
    assert (
        "1 gap(s) in the timestamps longer than 10 sample intervals; the longest lasts "
        "3600.01 s, after t = 12 s (line 1201)"
    ) in err
    assert abs(est["step"].sum() - rec.step_times[0].size) <= 2
    # The attitude is re-found after the gap from gravity and the field, not lost to it.
    assert _angle_error_deg(est["yaw_deg"], rec.ypr[0, :, 0])[1300:].max() < 2.0
    table[1200:, 0] += 86400.0
    with pytest.raises(ValueError, match=r"the longest lasts 9000\d.* over the 6 h limit"):
        read_csv_recording(_write(tmp_path / "days.csv", table))


def test_a_row_with_an_extra_field_names_its_line(tmp_path):
    p = tmp_path / "extra.csv"
    p.write_text("t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n0.01,0,0,0,0,0,9,8\n")
    with pytest.raises(ValueError, match=r"line 3: 8 fields, but the header has 7; a comma inside"):
        read_csv_recording(p)
    p.write_text("t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n0.01,0,0,0,0,0\n")
    with pytest.raises(ValueError, match=r"line 3: 6 fields, but the header has 7"):
        read_csv_recording(p)
    p.write_text("t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\nnan,0,0,0,0,0,9.8\n")
    with pytest.raises(ValueError, match=r"line 3, column 1 \(t\): time nan is not a finite"):
        read_csv_recording(p)
    p.write_text("t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8,\n0.01,0,0,0,0,0,9.8,,\n")  # trailing commas
    np.testing.assert_allclose(read_csv_recording(p).acc[:, 2], [9.8, 9.8])


def test_a_spreadsheets_byte_order_mark_and_utf16_are_read(walk, tmp_path):
    text = _write(tmp_path / "plain.csv", walk[0][:300]).read_text()
    for name, data in (("bom", b"\xef\xbb\xbf" + text.encode()), ("u16", text.encode("utf-16"))):
        p = tmp_path / f"{name}.csv"
        p.write_bytes(data)
        rec = read_csv_recording(p)
        np.testing.assert_allclose(rec.acc, walk[0][:300, 4:7], rtol=1e-8)


def test_binary_and_unmarked_utf16_files_are_refused_by_name(walk, tmp_path):
    text = _write(tmp_path / "plain.csv", walk[0][:50]).read_text()
    for name, data in (
        ("bin", bytes(range(256)) * 4),
        ("u16le", text.encode("utf-16-le")),
        ("latin", "t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8 \xb5T\n".encode("latin-1")),
    ):
        p = tmp_path / f"{name}.csv"
        p.write_bytes(data)
        with pytest.raises(ValueError, match=rf"{name}.csv: not a UTF-8 text CSV"):
            read_csv_recording(p)


# ------------------------------------------------------------------------------------------------
# Output: no attitude without a gyro; comparison with the ground truth a file carries.
# ------------------------------------------------------------------------------------------------


def test_accelerometer_only_data_has_no_attitude_output_but_steps(walk, tmp_path, capsys):
    table, rec = walk
    path = _write(tmp_path / "acc.csv", table[:, [0, 4, 5, 6]], "t,ax,ay,az")
    code, err, est, _ = _estimate(path, tmp_path, capsys)
    assert code == 0
    assert err.count("\n") == 1 and "no gyroscope: no attitude" in err
    assert est.dtype.names == ("t", "walking", "step", "x", "y")
    assert abs(est["step"].sum() - rec.step_times[0].size) <= 1
    np.testing.assert_allclose(est["y"], 0.0)  # along +x
    # A gyro written as all-NaN columns is no gyro either.
    nan_gyro = table.copy()
    nan_gyro[:, 1:4] = np.nan
    assert read_csv_recording(_write(tmp_path / "ng.csv", nan_gyro)).gyr is None


def _broad_file(path, table, quat):
    import h5py

    n = table.shape[0]
    with h5py.File(path, "w") as f:
        f["imu_gyr"], f["imu_acc"], f["imu_mag"] = table[:, 1:4], table[:, 4:7], table[:, 7:10]
        f["opt_quat"], f["opt_pos"] = quat, np.zeros((n, 3))
        f["movement"] = np.arange(n) >= 100
        f.attrs["sampling_rate"] = 100.0
    return path


def test_a_broad_trial_is_compared_with_its_reference_attitude(walk, tmp_path, capsys):
    table, rec = walk
    quat = rec.quat[0].copy()
    quat[150:160] = np.nan  # markers lost
    code, _, _, out = _estimate(_broad_file(tmp_path / "sim.h5", table, quat), tmp_path, capsys)
    assert code == 0 and out["has_attitude"]
    ref = out["attitude_vs_reference"]
    assert ref["samples"] == 2200 - 100 - 10
    assert 0.0 < ref["inclination_rmse_deg"] <= ref["total_rmse_deg"] < 2.0


def _oxford_folder(folder, t, acc, step_times):
    """An Oxford step-counter recording: ns timestamps, accuracy flag, one pulse per step."""
    folder.mkdir()
    ns = np.round(1e15 + t * 1e9).astype(np.int64)
    with open(folder / "accelerometer.csv", "w") as f:
        for k in range(t.size):
            f.write(f"{ns[k]},3,{acc[k, 0]:.6f},{acc[k, 1]:.6f},{acc[k, 2]:.6f}\n")
    rows = [(0.0, 0, 0)]
    for k, ts in enumerate(step_times):  # feet alternate; the switch closes at the heel strike
        rows += [(ts, 1 - k % 2, k % 2), (ts + 0.1, 0, 0)]
    with open(folder / "stepcounter.csv", "w") as f:
        for ts, right, left in rows:
            f.write(f"{1_000_000_000_000_000 + round(ts * 1e9)},{right},{left}\n")
    return folder


def test_an_oxford_recording_is_compared_with_its_foot_switches(walk, tmp_path, capsys):
    table, rec = walk
    truth = rec.step_times[0]
    fake = np.sort(np.concatenate([truth[3:], [0.5]]))  # 3 steps missed, one invented
    folder = _oxford_folder(tmp_path / "ox", table[:, 0], table[:, 4:7], fake)
    code, err, _, out = _estimate(folder, tmp_path, capsys)
    assert code == 0 and not out["has_attitude"] and "no gyroscope" in err
    ref = out["steps_vs_foot_switches"]
    detected = out["steps"]
    assert ref["true_steps"] == fake.size
    assert ref["true_positives"] + ref["misses"] == fake.size
    assert ref["true_positives"] + ref["false_positives"] == detected
    assert ref["misses"] >= 1 and ref["false_positives"] >= 3  # the invented one, the missed ones
    assert ref["f1"] == pytest.approx(2 * ref["true_positives"] / (fake.size + detected), abs=1e-4)
    # Without stepcounter.csv: the steps alone, no comparison.
    (folder / "stepcounter.csv").unlink()
    code, _, _, out = _estimate(folder, tmp_path, capsys)
    assert code == 0 and "steps_vs_foot_switches" not in out and out["steps"] == detected


def test_the_real_recordings_are_compared_with_their_ground_truth(real_data, tmp_path, capsys):
    trial = real_data("broad") / "02_undisturbed_slow_rotation_B.hdf5"
    code, err, _, out = _estimate(trial, tmp_path, capsys)
    assert code == 0 and err == ""
    ref = out["attitude_vs_reference"]
    assert ref["samples"] > 30_000
    assert 0.2 < ref["inclination_rmse_deg"] < 1.0 and ref["total_rmse_deg"] < 2.5
    code, _, _, out = _estimate(real_data("oxford"), tmp_path, capsys)
    assert code == 0
    ref = out["steps_vs_foot_switches"]
    assert ref["true_steps"] == 248  # the data README
    assert ref["f1"] > 0.95 and ref["true_positives"] > 235


def test_the_readers_refuse_non_data_files_by_name_and_skip_a_bom(tmp_path, capsys):
    from estimators.io.kinect import read_kinect_csv
    from estimators.io.oxford import read_accelerometer

    junk = bytes(range(256)) * 2
    for name in ("junk.hdf5", "junk.mat"):
        (tmp_path / name).write_bytes(junk)
        assert main(["estimate", str(tmp_path / name), "--out", str(tmp_path)]) == 2
        assert f"{name}: not a readable" in capsys.readouterr().err
    (tmp_path / "k.csv").write_bytes(junk)
    with pytest.raises(ValueError, match=r"k.csv: not a text CSV"):
        read_kinect_csv(tmp_path / "k.csv")
    row = "0," + ",".join(["0.1,0.2,1.5,2"] * 25) + ",\n"
    (tmp_path / "k.csv").write_bytes(b"\xef\xbb\xbf" + row.encode())
    assert read_kinect_csv(tmp_path / "k.csv").t.size == 1
    ox = tmp_path / "ox"
    ox.mkdir()
    (ox / "accelerometer.csv").write_bytes(b"\xef\xbb\xbf100,3,0,0,9.8\n200,3,0,0,9.8\n")
    np.testing.assert_allclose(read_accelerometer(ox)[0], [0.0, 1e-7])


def test_offline_estimate_smooths_the_attitude_of_a_csv(walk, tmp_path, capsys):
    table, rec = walk
    path = _write(tmp_path / "walk.csv", table)
    code, _, online, summary_on = _estimate(path, tmp_path / "on", capsys)
    assert code == 0 and summary_on["offline"] is False
    assert main(["estimate", str(path), "--out", str(tmp_path / "off"), "--offline"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["offline"] is True and summary["has_attitude"]
    offline = np.genfromtxt(summary["csv"], delimiter=",", names=True)
    np.testing.assert_array_equal(offline["step"], online["step"])  # steps do not change
    err = {}
    for name, est in (("online", online), ("offline", offline)):
        err[name] = max(
            _angle_error_deg(est[f"{a}_deg"], rec.ypr[0, :, k]).max()
            for k, a in enumerate(("yaw", "pitch", "roll"))
        )
    assert err["offline"] < 3.0  # the 45 deg turn away and back
    assert not np.array_equal(offline["yaw_deg"], online["yaw_deg"])

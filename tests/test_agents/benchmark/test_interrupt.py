"""Ctrl-C keeps what was done: the benchmark's finished cells, the trained model and its curve,
and stops within seconds."""

import json
import signal
import subprocess
import sys
import time

import pytest

from agents.benchmark import run_benchmark

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")


def _interrupt_after(argv: list[str], seconds: float) -> tuple[int, str, float]:
    """Run ``vrloco argv``, send SIGINT after ``seconds``; return the exit code, the output and
    how long it took to stop."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "agents.cli", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    time.sleep(seconds)
    assert proc.poll() is None, proc.communicate()[0]
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=120)
    return proc.returncode, out, time.monotonic() - sent


@pytest.mark.slow
def test_ctrl_c_stops_the_benchmark_in_seconds(tmp_path):
    code, out, took = _interrupt_after(
        ["benchmark", "--episodes", "40", "--workers", "2", "--out", str(tmp_path / "b")], 12.0
    )
    assert code == 130 and took < 10.0, (took, out)
    assert "interrupted:" in out and "Traceback" not in out


@pytest.mark.slow
def test_ctrl_c_stops_training_and_keeps_the_model(tmp_path):
    code, out, took = _interrupt_after(
        [
            "train",
            "--steps",
            "100000000",
            "--num-envs",
            "4",
            "--eval-every",
            "4096",
            "--out",
            str(tmp_path),
        ],
        20.0,
    )
    assert code == 130 and took < 10.0, (took, out)
    assert "interrupted after" in out and "Traceback" not in out
    assert (tmp_path / "ppo_approach_final.zip").is_file()
    assert isinstance(json.loads((tmp_path / "learning_curve.json").read_text()), list)


def test_an_interrupted_grid_writes_the_cells_that_finished(tmp_path):
    plugin = tmp_path / "impatient.py"
    plugin.write_text(
        "class Impatient:\n"
        "    def __init__(self, env):\n"
        "        pass\n"
        "    def reset(self, rng=None, rows=None):\n"
        "        raise KeyboardInterrupt  # as Ctrl-C would, while this cell runs\n"
        "    def act(self, obs):\n"
        "        raise AssertionError\n"
    )
    with pytest.raises(KeyboardInterrupt):
        run_benchmark(
            tasks=["approach"],
            policies=["goal_seeker", f"{plugin}:Impatient"],
            techniques=["zhang2021"],
            episodes=1,
            workers=1,
            progress=False,
            print_table=False,
            out_dir=tmp_path / "out",
        )
    rows = json.loads((tmp_path / "out" / "benchmark.json").read_text())["rows"]
    assert [r["policy"] for r in rows] == ["goal_seeker"]


def test_an_interrupted_grid_resumes_where_it_stopped(tmp_path, capsys):
    """The finished episodes are kept in the output folder; a rerun runs only the rest and gives
    the table of an uninterrupted run. An unreadable resume file is reported and rerun."""
    marker = tmp_path / "interrupted-once"
    plugin = tmp_path / "flaky.py"
    plugin.write_text(
        "from pathlib import Path\n"
        "import numpy as np\n"
        f"MARK = Path({str(marker)!r})\n"
        "class Flaky:\n"
        "    def __init__(self, env):\n"
        "        pass\n"
        "    def reset(self, rng=None, rows=None):\n"
        "        if not MARK.exists():\n"
        "            MARK.touch()\n"
        "            raise KeyboardInterrupt  # Ctrl-C while this cell runs, the first time\n"
        "    def act(self, obs):\n"
        "        return -np.ones(5, np.float32)\n"
    )
    kw = dict(
        tasks=["approach"],
        policies=["goal_seeker", f"{plugin}:Flaky"],
        techniques=["zhang2021"],
        episodes=2,
        workers=1,
        progress=False,
        print_table=False,
    )
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        run_benchmark(**kw, out_dir=out)
    assert "rerun with the same --out to resume: 2 episodes kept" in capsys.readouterr().out
    (out / ".resume" / "garbage.pkl").write_bytes(b"not a pickle")
    rows = run_benchmark(**kw, out_dir=out)
    said = capsys.readouterr().out
    assert "resuming: 2 of 4 episodes found" in said and "skipping unreadable" in said
    assert not (out / ".resume").exists()  # complete: nothing left to resume
    assert rows == run_benchmark(**kw)  # the same table as a run that was never interrupted

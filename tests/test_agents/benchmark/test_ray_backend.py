"""``vrloco benchmark --backend ray``: the local backend's rows from Ray tasks on a local Ray
instance (started here with 2 CPUs), failed jobs named by cell and seed while the rest is kept,
a lost worker retried, clear errors for an unreachable address and for Ray not installed."""

import logging
import math
import sys
import time

import pytest

from agents.benchmark import run_benchmark
from agents.cli import main

NEEDS_RAY = "the Ray backend needs Ray: pip install 'vrloco[ray]'"

QUIET = {"progress": False, "print_table": False}
TINY = {
    "tasks": ["approach"],
    "techniques": ["zhang2021"],
    "episodes": 2,
    "seed": 4,
    "batch_size": 2,
    "workers": 2,
    **QUIET,
}

PLUGIN = """\
import os
import pathlib

import numpy as np

MARK = pathlib.Path(__file__).with_suffix(".crashed")


class Stand:
    def __init__(self, env):
        self.n = env.action_space.shape[0]

    def reset(self, rng=None, rows=None):
        pass

    def act(self, obs):
        return -np.ones(self.n, np.float32)


class Boom(Stand):
    def reset(self, rng=None, rows=None):
        raise RuntimeError("boom in reset")


class Crash(Stand):  # its worker process dies on every try
    def reset(self, rng=None, rows=None):
        os._exit(1)


class CrashOnce(Stand):  # its worker process dies on the first episode ever played
    def reset(self, rng=None, rows=None):
        if not MARK.exists():
            MARK.write_text("crashed")
            os._exit(1)
"""


@pytest.fixture(scope="module")
def ray_local():
    ray = pytest.importorskip("ray", reason=NEEDS_RAY)
    ray.init(num_cpus=2, include_dashboard=False, logging_level=logging.WARNING)
    yield ray
    ray.shutdown()


@pytest.fixture
def plugin(tmp_path):
    path = tmp_path / "users.py"
    path.write_text(PLUGIN)
    return path


def _nan_free(rows):
    """Rows comparable with ==: NaN as None."""
    return [
        {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in r.items()}
        for r in rows
    ]


def test_ray_tasks_give_the_local_rows(ray_local):
    kw = {**TINY, "policies": ["goal_seeker", "avoid_manoeuvre+human"], "episodes": 3}
    local = run_benchmark(**{**kw, "workers": 1})
    ray_rows = run_benchmark(**kw, backend="ray")
    assert len(ray_rows) == 2
    assert _nan_free(ray_rows) == _nan_free(local)


def test_a_failed_job_is_named_by_cell_and_seed_and_the_rest_is_kept(
    ray_local, plugin, tmp_path, capsys
):
    from agents.benchmark.backends import BackendError

    out = tmp_path / "out"
    boom, crash = f"{plugin}:Boom", f"{plugin}:Crash"
    with pytest.raises(BackendError, match=r"2 of 3 Ray jobs failed") as err:
        run_benchmark(**TINY, policies=["goal_seeker", boom, crash], out_dir=out, backend="ray")
    lines = str(err.value).splitlines()
    assert f"  cell (approach, {boom}, zhang2021) seeds 4-5: RuntimeError: boom in reset" in lines
    assert any(
        s.startswith(
            f"  cell (approach, {crash}, zhang2021) seeds 4-5: WorkerCrashedError after 2 retries"
        )
        for s in lines
    )
    assert err.value.partial
    assert not (out / "benchmark.csv").exists()  # no table from a part of the grid
    capsys.readouterr()
    # the seeker's cell finished: a rerun of it resumes every episode and runs nothing
    rows = run_benchmark(**TINY, policies=["goal_seeker"], out_dir=out, backend="ray")
    assert "resuming: 2 of 2 episodes" in capsys.readouterr().out
    assert _nan_free(rows) == _nan_free(run_benchmark(**TINY, policies=["goal_seeker"]))


def test_a_lost_worker_is_retried(ray_local, plugin):
    crash = f"{plugin}:CrashOnce"
    rows = run_benchmark(**TINY, policies=[crash], backend="ray")
    assert plugin.with_suffix(".crashed").exists()  # a worker did die, and the task ran again
    assert _nan_free(rows) == _nan_free(run_benchmark(**{**TINY, "workers": 1}, policies=[crash]))


def test_an_unreachable_address_is_named_at_once(tmp_path, capsys):
    pytest.importorskip("ray", reason=NEEDS_RAY)
    from agents.benchmark.backends import BackendError

    t0 = time.perf_counter()
    with pytest.raises(BackendError, match=r"cannot reach a Ray cluster at 127\.0\.0\.1:1"):
        run_benchmark(**TINY, policies=["goal_seeker"], backend="ray", address="127.0.0.1:1")
    assert time.perf_counter() - t0 < 10.0
    assert (
        main(
            [
                "benchmark",
                "--backend",
                "ray",
                "--address",
                "127.0.0.1:1",
                "--episodes",
                "1",
                "--out",
                str(tmp_path),
            ]
        )
        == 1
    )
    err = capsys.readouterr().err
    assert err.startswith("vrloco benchmark: cannot reach a Ray cluster at 127.0.0.1:1")
    assert "Traceback" not in err


def test_without_ray_the_error_says_how_to_install_it(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` now fails
    with pytest.raises(ValueError, match=r"pip install 'vrloco\[ray\]'"):
        run_benchmark(**TINY, policies=["goal_seeker"], backend="ray")
    assert main(["benchmark", "--backend", "ray", "--episodes", "1"]) == 2
    assert "pip install 'vrloco[ray]'" in capsys.readouterr().err


def test_bad_backend_options_are_rejected(capsys):
    with pytest.raises(ValueError, match="backend must be 'local' or 'ray', got 'dask'"):
        run_benchmark(**TINY, policies=["goal_seeker"], backend="dask")
    with pytest.raises(ValueError, match="needs backend 'ray'"):
        run_benchmark(**TINY, policies=["goal_seeker"], address="auto")
    assert main(["benchmark", "--address", "auto"]) == 2
    assert "needs backend 'ray'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["benchmark", "--backend", "dask"])
    assert "invalid choice: 'dask'" in capsys.readouterr().err

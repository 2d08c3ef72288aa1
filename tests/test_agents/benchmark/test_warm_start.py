"""A first run says it compiles the kernels, compiles the shared ones once before its workers
fork, and a later run says nothing."""

from __future__ import annotations

import pytest

from agents.benchmark import run as benchmark
from agents.benchmark import run_benchmark, warm_start

KW = dict(
    tasks=["approach"],
    policies=["goal_seeker"],
    techniques=["zhang2021"],
    episodes=2,
    progress=False,
    print_table=False,
)


@pytest.fixture
def stamp(tmp_path, monkeypatch):
    """The compiled-kernels stamp in a folder of its own (no run has marked it yet)."""
    path = tmp_path / "cache" / "vrloco-compiled"
    monkeypatch.setattr(warm_start, "_stamp", lambda: path)
    return path


def test_a_first_run_announces_compiling_before_it_plays_and_a_later_run_does_not(
    stamp, capsys, monkeypatch
):
    played = []
    real_job = benchmark._job
    monkeypatch.setattr(
        benchmark, "_job", lambda job: played.append(capsys.readouterr().out) or real_job(job)
    )
    run_benchmark(**KW, workers=1)
    assert "compiling kernels (first run only, about" in played[0]  # before any episode
    assert stamp.exists()
    played.clear()
    run_benchmark(**KW, workers=1)
    assert "compiling kernels" not in played[0] + capsys.readouterr().out


def test_a_cold_run_with_workers_compiles_the_shared_kernels_here_before_forking(
    stamp, monkeypatch
):
    order = []
    monkeypatch.setattr(
        benchmark, "_compile_shared_kernels", lambda job: order.append(("here", job[0][0][0].task))
    )
    real = benchmark._run_jobs

    def run_jobs(*args, **kwargs):
        order.append(("workers",))
        yield from real(*args, **kwargs)

    monkeypatch.setattr(benchmark, "_run_jobs", run_jobs)
    run_benchmark(**KW, workers=2)
    assert order[:2] == [("here", "approach"), ("workers",)]
    order.clear()
    run_benchmark(**KW, workers=2)  # compiled: straight to the workers
    assert order == [("workers",)]

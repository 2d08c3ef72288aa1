"""Benchmark metrics against hand-made ground truth, and the benchmark on a tiny grid."""

import csv
import dataclasses
import json
import math

import numpy as np
import pytest

from agents.benchmark import ROW_KEYS, check_policy_name, run_benchmark
from agents.benchmark.episodes import run_batched, run_cell_batched, run_cell_episode
from agents.benchmark.grid import Cell
from agents.benchmark.metrics import EpisodeStats, spl, summarize
from agents.benchmark.step_matching import match_step_counts
from agents.cli import main


def episode(success, collisions, walked, shortest, elapsed=10.0, true=(), det=(), att=(), hand=()):
    n = max(len(true), len(att), len(hand), 1)
    return EpisodeStats(
        seed=0,
        success=success,
        collisions=collisions,
        steps=n,
        elapsed_s=elapsed,
        walked_m=walked,
        shortest_m=shortest,
        true_counts=np.asarray(true or [0] * n, np.int64),
        detected_counts=np.asarray(det or [0] * n, np.int64),
        attitude_error_deg=np.asarray(att or [0.0] * n),
        hand_error_deg=np.asarray(hand or [np.nan] * n),
        heading_error_deg=np.zeros(n),
    )


# --------------------------------------------------------------------------- metrics


def test_spl_follows_anderson_et_al():
    # success, a detour twice the shortest path, a failure
    assert spl([1, 1, 0], [2.0, 4.0, 3.0], [2.0, 8.0, 1.0]) == pytest.approx((1 + 0.5 + 0) / 3)
    # a walk shorter than the "shortest" path (an upper bound) counts as 1, not more
    assert spl([1], [5.0], [4.0]) == 1.0
    with pytest.raises(ValueError, match="shortest must be finite and > 0"):
        spl([1], [0.0], [1.0])
    with pytest.raises(ValueError, match="one length"):
        spl([1, 0], [1.0], [1.0])


def test_step_matching_on_counts():
    # true steps at control steps 1 and 4; one detection at 2 (late by one), none for 4
    assert match_step_counts([0, 1, 0, 0, 1, 0], [0, 0, 1, 0, 0, 0]) == (1, 0, 1)
    # a detection 3 steps late matches with late=3, not with late=2
    t, d = [1, 0, 0, 0], [0, 0, 0, 1]
    assert match_step_counts(t, d, late=2) == (0, 1, 1)
    assert match_step_counts(t, d, late=3) == (1, 0, 0)
    # a bout's first step reported with the second: two detections at once
    assert match_step_counts([1, 0, 0, 0, 0, 1], [0, 0, 0, 0, 0, 2], late=5) == (2, 0, 0)
    # one-to-one: two detections cannot share a true step
    assert match_step_counts([0, 1, 0], [0, 2, 0]) == (1, 1, 0)
    with pytest.raises(ValueError, match="non-negative integers"):
        match_step_counts([0, -1], [0, 0])


def test_summarize_rates_and_errors():
    eps = [
        episode(True, 0, 6.0, 5.0, elapsed=8.0, true=[1, 0, 1], det=[0, 1, 1], att=[1, 1, 1]),
        episode(True, 2, 10.0, 5.0, elapsed=12.0, att=[2.0], hand=[4.0]),
        episode(False, 1, 3.0, 5.0, att=[3.0], hand=[np.nan]),
        episode(False, 0, 1.0, 4.0, att=[0.0], hand=[6.0]),
    ]
    row = summarize(eps)
    assert row["episodes"] == 4
    assert row["success_rate"] == 0.5
    assert row["collision_rate"] == 0.5
    assert row["collision_free_success_rate"] == 0.25
    assert row["spl"] == pytest.approx((5 / 6 + 5 / 10) / 4)
    assert row["time_to_goal_s"] == pytest.approx(10.0)  # successful episodes only
    assert row["path_length_ratio"] == pytest.approx((6 / 5 + 10 / 5) / 2)
    assert row["step_f1"] == 1.0  # both true steps found within the window
    assert row["attitude_rmse_deg"] == pytest.approx(np.sqrt((1 + 1 + 1 + 4 + 9 + 0) / 6))
    assert row["hand_error_deg"] == pytest.approx(5.0)  # NaN steps have no estimate
    assert row["hand_coverage"] == pytest.approx(2 / 6)
    assert row["mean_collisions"] == pytest.approx(0.75)


def test_a_cell_without_steps_has_no_step_scores():
    """A user who never walks in place (a head-tilt technique) and a detector that reports
    nothing leave nothing to score: NaN, where one missed or phantom step scores 0."""
    still = [episode(True, 0, 5.0, 5.0, true=[0, 0, 0], det=[0, 0, 0]) for _ in range(2)]
    row = summarize(still)
    assert all(np.isnan(row[k]) for k in ("step_precision", "step_recall", "step_f1"))
    missed = summarize([*still, episode(True, 0, 5.0, 5.0, true=[1, 0, 0], det=[0, 0, 0])])
    assert (missed["step_recall"], missed["step_f1"]) == (0.0, 0.0)
    phantom = summarize([*still, episode(True, 0, 5.0, 5.0, true=[0, 0, 0], det=[0, 1, 0])])
    assert (phantom["step_precision"], phantom["step_f1"]) == (0.0, 0.0)


# --------------------------------------------------------------------------- the benchmark


def test_a_tiny_benchmark_writes_its_outputs_and_ignores_the_worker_count(tmp_path):
    kw = {
        "tasks": ["approach"],
        "policies": ["goal_seeker"],
        "sensors": ["ig500n"],
        "episodes": 2,
        "seed": 5,
        "progress": False,
        "print_table": False,
    }
    one = run_benchmark(**kw, workers=1, out_dir=tmp_path / "one", json_path=tmp_path / "r.json")
    two = run_benchmark(**kw, workers=2)
    assert one == two
    (row,) = one
    assert tuple(row) == ROW_KEYS
    assert row["task"] == "approach" and row["episodes"] == 2
    assert row["success_rate"] == 1.0 and row["collision_rate"] == 0.0  # the seeker on 5, 6
    assert 0.5 < row["spl"] <= 1.0
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["rows"][0]["collision_free_success_rate"] == 1.0
    assert set(data["rows"][0]) == set(ROW_KEYS)
    assert data == json.loads((tmp_path / "one" / "benchmark.json").read_text())
    with (tmp_path / "one" / "benchmark.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 1 and float(rows[0]["spl"]) == pytest.approx(row["spl"])
    for kind in ("trajectory", "attitude", "gait"):
        png = tmp_path / "one" / f"{kind}_approach_goal_seeker_zhang2021.png"
        assert png.stat().st_size > 10_000


def _same_episode(a, b) -> None:
    """Two EpisodeStats of one episode agree in every number, to the bit."""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.name == "trace":
            assert (x is None) == (y is None)
            for k in () if x is None else (k for k in x if k != "layout"):
                np.testing.assert_array_equal(x[k], y[k], err_msg=f"trace {k}")
        elif isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=f.name)
        else:
            assert x == y, f.name


@pytest.mark.parametrize(
    "cell",
    [
        Cell("approach", "goal_seeker+human"),
        Cell("avoid", "avoid_manoeuvre", "zhang2021_consumer"),
        Cell("interact", "goal_seeker", "smooth"),
        Cell("approach", "goal_seeker", "madgwick", "beside_metal"),
    ],
    ids=lambda c: c.label,
)
def test_batched_episodes_are_the_single_env_episodes(cell):
    """Users of a batch end at their own step and take the cell's next seed: 5 episodes on 2
    users give each episode exactly what it gives alone (its trace and room too)."""
    seeds = [3, 4, 5, 6, 7]
    trace = [True, False, False, True, False]
    batched = run_cell_batched(cell, seeds, trace, batch_size=2)
    assert len({stats.steps for stats, _ in batched}) > 1  # the users did not end together
    for (stats, info), seed, tr in zip(batched, seeds, trace, strict=True):
        alone, alone_info = run_cell_episode(cell, seed, trace=tr)
        assert stats.seed == seed
        _same_episode(stats, alone)
        assert info["shortest_path"] == alone_info["shortest_path"]
        np.testing.assert_array_equal(info["position"], alone_info["position"])
        if tr:
            assert stats.trace["layout"] == alone.trace["layout"]


def test_a_batch_sheds_its_finished_users_and_still_gives_the_single_env_episodes(
    monkeypatch, tmp_path
):
    """Once no episode is left to claim, the users whose episode ended leave the batch (the env
    and the policy drop them) and the rest go on as alone; a user's batched policy that cannot
    drop users (no ``take_users``) keeps the whole batch, idle users and all."""
    from vrloco_env.vector import VRLocoVectorEnv

    sizes = []
    take = VRLocoVectorEnv.take_users

    def counted(env, rows):
        take(env, rows)
        sizes.append(env.num_envs)

    monkeypatch.setattr(VRLocoVectorEnv, "take_users", counted)
    cell = Cell("avoid", "goal_seeker+human", "smooth")
    seeds, trace = [3, 4, 5, 6, 7, 8], [False, True, False, False, False, True]
    batched = run_cell_batched(cell, seeds, trace, batch_size=4)
    assert sizes and sizes == sorted(sizes, reverse=True) and sizes[-1] >= 1
    for (stats, _), seed, tr in zip(batched, seeds, trace, strict=True):
        _same_episode(stats, run_cell_episode(cell, seed, trace=tr)[0])

    plugin = tmp_path / "my_batched_user.py"
    plugin.write_text(
        "from agents.benchmark.policies import build_policy\n"
        "class Seeker:  # batched, but it cannot drop users\n"
        "    batched = True\n"
        "    def __init__(self, env):\n"
        "        self.inner = build_policy('goal_seeker', env)\n"
        "    def reset(self, rng=None, rows=None):\n"
        "        self.inner.reset(rng, rows)\n"
        "    def act(self, obs):\n"
        "        return self.inner.act(obs)\n"
    )
    sizes.clear()
    mine = Cell("avoid", f"{plugin}:Seeker")
    batched = run_cell_batched(mine, seeds[:4], batch_size=2)
    assert sizes == []
    for (stats, _), seed in zip(batched, seeds, strict=False):
        _same_episode(stats, run_cell_episode(mine, seed)[0])


def test_cells_sharing_an_env_mix_in_one_batch():
    """Users move from one cell's episodes to another's (a scripted user, the same with human
    variability, a second scripted user) and each episode is still the single env's."""
    cells = [
        Cell("avoid", "goal_seeker"),
        Cell("avoid", "goal_seeker+human"),
        Cell("avoid", "avoid_manoeuvre"),
    ]
    episodes = [(c, seed, False) for seed in (1, 2) for c in cells]
    batched = run_batched(episodes, batch_size=2)
    for (cell, seed, _), (stats, _) in zip(episodes, batched, strict=True):
        _same_episode(stats, run_cell_episode(cell, seed)[0])
    with pytest.raises(ValueError, match="share one task, technique, population and condition"):
        run_batched([(cells[0], 1, False), (Cell("approach", "goal_seeker"), 1, False)])


def test_a_job_shared_by_workers_plays_each_claimed_episode_as_alone(monkeypatch):
    """A worker that joins a running job plays only the episodes nobody has claimed, each with
    the numbers it gives alone; once every episode is claimed, a helper returns at once."""
    import multiprocessing

    import agents.benchmark.jobs as bm

    cell = Cell("avoid", "goal_seeker", "zhang2021")
    episodes = [(cell, i, 20 + i, False) for i in range(5)]
    claimed = multiprocessing.Array("q", 2)
    claimed[1] = 2  # another worker took the job's first two episodes
    monkeypatch.setattr(bm, "_CLAIMED", claimed)
    done = bm._job((episodes, 2, 1))
    assert [(c, i) for c, i, _, _ in done] == [(cell, 2), (cell, 3), (cell, 4)]
    assert claimed[1] == 5 and claimed[0] == 0  # all claimed, the other job's untouched
    for _, i, stats, _ in done:
        _same_episode(stats, run_cell_episode(cell, 20 + i)[0])
    assert bm._job((episodes, 2, 1)) == []


def test_local_workers_with_helpers_play_every_episode_once():
    from agents.benchmark.run import _run_jobs, _split_jobs

    cells = [Cell("approach", "goal_seeker"), Cell("avoid", "goal_seeker")]
    jobs = _split_jobs(cells, 3, 7, False, 2, 2)
    played = [(c, i) for done in _run_jobs(jobs, 2, False) for c, i, _, _ in done]
    assert sorted(played, key=str) == sorted(((c, i) for c in cells for i in range(3)), key=str)


_AFTER_THREADS = """
import numba
import numpy as np

import estimators.kernels.batch as batch
from agents.benchmark import run_benchmark
from vrloco_env.vector import VRLocoVectorEnv

batch.PARALLEL_MIN_BATCH = 2  # even the grid's batches of 2 users run on numba's threads
env = VRLocoVectorEnv(2, task="approach")
env.reset(seed=[0, 1])
env.step(np.zeros((2, env.single_action_space.shape[0]), np.float32))
print("threads:", numba.threading_layer())
kw = {"tasks": ["approach", "avoid"], "policies": ["goal_seeker"], "techniques": ["zhang2021"],
      "episodes": 2, "seed": 5, "progress": False, "print_table": False}
print("same table:", run_benchmark(**kw, workers=2) == run_benchmark(**kw, workers=1))
"""


def test_each_local_worker_gets_its_share_of_the_cores():
    import os

    import numba

    from agents.benchmark.jobs import _worker_threads

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert _worker_threads(1) == min(cores, numba.config.NUMBA_NUM_THREADS)
    assert _worker_threads(cores) == 1  # as many workers as cores: serial kernels
    assert _worker_threads(4 * cores) == 1


def test_local_workers_start_in_a_process_whose_kernels_ran_threads():
    """A child forked from a process whose kernels ran on OpenMP threads dies when its own
    kernels do: after such a step, the grid's workers are spawned instead (they start afresh,
    serial again below their batch threshold) and give the same table."""
    import subprocess
    import sys

    run = subprocess.run(
        [sys.executable, "-c", _AFTER_THREADS], capture_output=True, text=True, timeout=600
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "threads: omp" in run.stdout and "same table: True" in run.stdout, run.stdout


def test_the_batched_and_the_one_at_a_time_grid_give_one_table():
    kw = {
        "tasks": ["approach", "avoid"],
        "policies": ["goal_seeker", "avoid_manoeuvre+human"],
        "techniques": ["zhang2021"],
        "episodes": 3,
        "seed": 2,
        "progress": False,
        "print_table": False,
        "workers": 1,
    }
    assert run_benchmark(**kw, batch_size=2) == run_benchmark(**kw, batch_size=0)


def test_bad_benchmark_options_are_rejected_clearly(capsys):
    with pytest.raises(ValueError, match="task='fly'"):
        run_benchmark(tasks=["fly"], progress=False)
    with pytest.raises(ValueError, match="episodes must be an integer >= 1"):
        run_benchmark(episodes=0, progress=False)
    with pytest.raises(ValueError, match="workers must be an integer >= 1"):
        run_benchmark(workers=0, progress=False)
    with pytest.raises(ValueError, match="batch_size must be an integer >= 0"):
        run_benchmark(batch_size=-1, progress=False)
    with pytest.raises(ValueError, match="batch_size must be an integer >= 1"):
        run_cell_batched(Cell("approach", "goal_seeker"), [0], batch_size=0)
    assert check_policy_name("goal_seeker+human") == "goal_seeker+human"
    with pytest.raises(ValueError, match="policy='robot'"):
        check_policy_name("robot")
    assert main(["benchmark", "--sensors", "iphone"]) == 2
    assert "iphone" in capsys.readouterr().err


def test_step_times_are_matched_within_0_2_s():
    from agents.benchmark.step_matching import match_step_times

    true = [1.0, 1.6, 2.2, 2.8]
    detected = [1.05, 1.78, 2.41, 2.79, 3.5]  # 2.41 is 0.21 s late: a miss and a false step
    assert match_step_times(true, detected) == (3, 2, 1)
    assert match_step_times([], []) == (0, 0, 0)


# --------------------------------------------------------------------------- an open benchmark


def test_cells_take_techniques_and_a_users_own_policy(tmp_path):
    plugin = tmp_path / "my_user.py"
    plugin.write_text(
        "import numpy as np\n"
        "class Stand:\n"
        "    def __init__(self, env):\n"
        "        self.n = env.action_space.shape[0]\n"
        "    def reset(self, rng=None, rows=None):\n"
        "        pass\n"
        "    def act(self, obs):\n"
        "        return -np.ones(self.n, np.float32)\n"
    )
    rows = run_benchmark(
        tasks=["avoid"],
        policies=["goal_seeker", f"{plugin}:Stand"],
        techniques=["zhang2021", "smooth"],
        episodes=1,
        seed=3,
        workers=1,
        progress=False,
        print_table=False,
    )
    assert [(r["policy"], r["technique"]) for r in rows] == [  # grouped by technique
        ("goal_seeker", "zhang2021"),
        (f"{plugin}:Stand", "zhang2021"),
        ("goal_seeker", "smooth"),
        (f"{plugin}:Stand", "smooth"),
    ]
    stand = [r for r in rows if r["policy"].endswith(":Stand")]
    assert all(r["success_rate"] == 0.0 and r["collision_rate"] == 0.0 for r in stand)
    assert all(r["sensors"] == "ig500n" for r in rows)


def test_unknown_policies_and_techniques_are_named():
    with pytest.raises(ValueError, match="technique='nope': unknown"):
        run_benchmark(techniques=["nope"], progress=False)
    with pytest.raises(ValueError, match="no such model file"):
        check_policy_name("absent.zip")
    with pytest.raises(ValueError, match="cannot import"):
        check_policy_name("no_such_pkg.users:Walker")


def test_the_table_fits_a_narrow_terminal(capsys):
    from agents.benchmark import show_table
    from agents.benchmark.collision_causes import COLLISION_CAUSES

    row = {k: 0.5 for k in ROW_KEYS}
    row.update(
        task="approach",
        policy="goal_seeker+human",
        technique="zhang2021_consumer",
        condition="lab",
        sensors="consumer_mems",
        episodes=40,
        vs_baseline={"spl": {"p": 0.001}},
        collision_causes=dict.fromkeys(COLLISION_CAUSES, 2),
    )
    show_table([row], 0, width=80)
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert max(len(line) for line in lines) <= 80
    assert "human" in out and "zhang2021_consumer" in out  # names are not cut
    assert "users: goal_seeker with the population shown" in out
    assert "compact view" in out
    show_table([row], 0, width=200)
    out = capsys.readouterr().out
    assert "time to goal" in out and "not shown at this width: collision causes" in out
    show_table([row], 0, width=260)
    out = capsys.readouterr().out
    assert "2/2/2/2/2" in out
    assert "0.500*" in out and "differs from zhang2021" in out  # the SPL marked, and why


def test_walking_in_place_measures_against_a_hand_made_episode():
    """One bout (intent in steps 10-29, heel strikes at 1.2-3.0 s), the virtual body moving
    0.05 m a step from 1.5 s to 3.4 s, then 0.1 m of drift while standing, a heading error that
    grows 1 deg while standing and a true head turn of 10 deg the view does not follow."""
    from agents.benchmark.cell_statistics import wilson_interval
    from agents.benchmark.wip_measures import motion_measures

    n, dt = 100, 0.1
    t_end = dt * np.arange(1, n + 1)
    intent = np.zeros(n, bool)
    intent[10:30] = True
    moved = np.zeros(n)
    moved[14:34] = 0.05
    moved[70:80] = 0.01
    pos = np.stack([np.cumsum(moved), np.zeros(n)], -1)
    true_moved = np.zeros(n)
    true_moved[12:31] = 0.9 / 19
    true_pos = np.stack([np.cumsum(true_moved), np.zeros(n)], -1)
    strikes = np.full((n, 2), np.inf)
    strikes[12:31:6, 0] = [1.2, 1.8, 2.4, 3.0]
    heading_error = np.zeros(n)
    heading_error[80:90] = 0.1 * np.arange(1, 11)
    heading_error[90:] = 1.0
    true_ypr = np.zeros((n, 3))
    true_ypr[50:60, 0] = np.arange(1, 11)
    true_ypr[60:, 0] = 10.0
    steps = {
        "intent_walk": intent,
        "elapsed_time": t_end,
        "position": pos,
        "true_position": true_pos,
        "true_step_times": strikes,
        "heading_error_deg": heading_error,
        "virtual_yaw": np.zeros(n),
        "true_ypr": true_ypr,
    }
    m = motion_measures(steps, (0.0, 0.0))
    assert m["start_latency_s"] == pytest.approx(1.5 - 1.2)
    assert m["stop_latency_s"] == pytest.approx(3.4 - 3.0)
    assert m["stop_overshoot_m"] == pytest.approx(20 * 0.05 - 0.9)
    standing_min = (10 + 41) * dt / 60  # before the bout, and from 3 s after its last strike
    assert m["standing_min"] == pytest.approx(standing_min)
    assert m["false_motion_m_per_min"] == pytest.approx(0.1 / standing_min)
    # drift while standing still: 51 standing steps, 50 differences within them
    assert m["yaw_drift_deg_per_min"] == pytest.approx(1.0 / (50 * dt / 60))
    assert m["yaw_rate_mismatch_deg_s"] == pytest.approx(np.sqrt(10 * 10.0**2 / 99))
    assert m["virtual_jerk_m_s3"] > 0
    assert math.isnan(m["steering_error_deg"])  # no walking direction in the info
    # walking 10 deg off the torso across the +-180 deg seam, then 30 deg off; 90 deg off while
    # the body stands does not count
    walk, body = np.full(n, 90.0), np.zeros(n)
    walk[14:24], body[14:24] = 175.0, -175.0
    walk[24:34] = 0.0
    walk[70:80] = 30.0
    m = motion_measures({**steps, "walk_yaw_deg": walk, "true_body_yaw_deg": body}, (0.0, 0.0))
    assert m["steering_error_deg"] == pytest.approx(np.sqrt((10 * 10.0**2 + 10 * 30.0**2) / 30))
    lo, hi = wilson_interval(38, 40)
    assert lo == pytest.approx(0.8347, abs=1e-3) and hi == pytest.approx(0.9862, abs=1e-3)
    assert wilson_interval(0, 10)[0] == 0.0


def test_each_collision_of_a_hand_made_episode_gets_its_cause():
    """Five collisions, one per cause: a detected step far from every heel strike, a collision
    after the user meant to stop, a 15 deg heading error, walking 20 deg off the torso's facing,
    and one with sensing as perfect sensing would be."""
    from agents.benchmark.collision_causes import COLLISION_CAUSES, collision_causes

    n, dt = 100, 0.1
    t_end = dt * np.arange(1, n + 1)
    intent = np.ones(n, bool)
    intent[40:45] = False
    strikes = np.full((n, 2), np.inf)
    strikes[::5, 0] = t_end[::5] - 0.05  # a heel strike every 0.5 s
    detected = np.full((n, 2), np.inf)
    detected[5::5, 0] = t_end[:-5:5] - 0.04  # each reported a control step later, 10 ms off
    detected[20, 1] = 1.8  # no heel strike within 0.2 s (1.55 and 2.05): a phantom step
    heading = np.zeros(n)
    heading[60] = 15.0
    walk, body = np.zeros(n), np.zeros(n)
    walk[75] = 20.0
    hit = np.zeros(n, bool)
    hit[[22, 42, 60, 75, 90]] = True
    steps = {
        "collision": hit,
        "elapsed_time": t_end,
        "intent_walk": intent,
        "heading_error_deg": heading,
        "true_step_times": strikes,
        "detected_step_times": detected,
        "walk_yaw_deg": walk,
        "true_body_yaw_deg": body,
    }
    assert collision_causes(steps) == dict.fromkeys(COLLISION_CAUSES, 1)
    # the phantom step is out of the window 1 s later; without the steering keys, no steering
    hit[:] = False
    hit[[31, 75]] = True
    del steps["walk_yaw_deg"]
    assert collision_causes(steps) == {**dict.fromkeys(COLLISION_CAUSES, 0), "policy": 2}


def test_the_step_log_gives_each_users_steps_across_growth_and_forgetting():
    """The batched runner's log of info arrays: a user's rows from a step on are the arrays it
    was given, past the log's growth (64 steps at first) and after its first steps are dropped;
    an info array that changes shape is an error, not a silent cast."""
    from agents.benchmark.episodes import _StepLog

    rng = np.random.default_rng(0)
    given = [{"a": rng.normal(size=3), "b": rng.integers(0, 9, size=(3, 2))} for _ in range(150)]
    log = _StepLog(("a", "b"))
    for info in given[:100]:
        log.append(info)
    got = log.user(1, 70)
    np.testing.assert_array_equal(got["a"], [g["a"][1] for g in given[70:100]])
    np.testing.assert_array_equal(got["b"], [g["b"][1] for g in given[70:100]])
    assert got["b"].dtype == given[0]["b"].dtype
    log.forget(60)
    for info in given[100:]:
        log.append(info)
    assert len(log) == 90
    np.testing.assert_array_equal(log.user(2, 10)["a"], [g["a"][2] for g in given[70:]])
    with pytest.raises(RuntimeError, match="info\\['a'\\] changed"):
        log.append({"a": np.zeros(4), "b": given[0]["b"]})

"""The head-behaviour experiment: simulated heads, the held-out split, distances and the JSON."""

import json

import numpy as np
import pytest

from agents.cli import main
from agents.experiments.head_behaviour import (
    CONDITIONS,
    distances,
    is_held_out,
    run_head_behaviour,
    simulate_heads,
)
from agents.recordings.head_motion_stats import (
    STATS_KEYS,
    head_motion_samples,
    head_motion_stats,
)
from agents.recordings.head_traces import dataset_files, read_head_traces
from vrloco_env.user.population import population_names

SEED = 4100  # seeds 4100 and up: used by this file only


def test_held_out_files_are_the_odd_video_numbers():
    assert [is_held_out(f"{n}.txt") for n in (0, 1, 7, 16, 33, 40, 41)] == [
        False,
        True,
        True,
        False,
        True,
        False,
        True,
    ]


def test_a_standing_idealised_head_never_moves_and_a_walking_one_turns_with_the_body():
    yaw, pitch, rate = simulate_heads("idealised", "standing", 2, SEED, max_steps=120)
    assert rate == 10.0 and [y.size for y in yaw] == [120, 120]
    for y, p in zip(yaw, pitch, strict=True):
        assert np.ptp(y) == 0.0 and np.ptp(p) == 0.0
    yaw, pitch, _ = simulate_heads("idealised", "walking", 2, SEED, max_steps=120)
    # the goal seeker turns the body (and the straight head with it) toward the goal
    assert max(np.ptp(np.unwrap(y)) for y in yaw) > np.deg2rad(10.0)
    with pytest.raises(ValueError, match="condition='running'"):
        simulate_heads("idealised", "running", 1, SEED)


def test_distances_of_a_sample_to_itself_are_zero_and_relative_differences_signed():
    t = np.arange(601) / 10.0
    yaw = np.deg2rad(40.0 * np.floor(t / 4.0))  # a 40 deg jump every 4 s: 400 deg/s
    a = head_motion_samples(yaw, np.zeros_like(t), times=t)
    b = head_motion_samples(yaw * 0.625, np.zeros_like(t), times=t)  # 25 deg jumps
    d = distances(a, a)
    assert d["yaw_speed_ks"] == 0.0 and d["interval_ks"] == 0.0
    assert d["relative"]["turns_per_min"] == [0.0, 0.0, 0.0, None]  # no 60 deg turn: undefined
    d = distances(b, a)
    assert d["relative"]["turn_amplitude_p25_p50_p75"] == pytest.approx([-0.375] * 3)
    assert d["relative"]["turns_per_min"] == [0.0, 0.0, -1.0, None]  # 25 deg: not >= 30
    assert d["relative"]["yaw_speed_p50_p75_p90_p95_p99"][:2] == [None, None]  # real p50 = 0
    assert d["relative"]["yaw_speed_p50_p75_p90_p95_p99"][4] == pytest.approx(-0.375)
    assert d["relative"]["interval_cv"] is None  # the real cv is 0
    # 15 of 600 sample pairs turn, at 250 against 400 deg/s: the CDFs differ by 15/600 between
    assert d["yaw_speed_ks"] == pytest.approx(15 / 600) and d["interval_ks"] == 0.0


def test_a_tiny_run_writes_the_json_and_its_real_statistics_are_those_of_the_files(
    tmp_path, real_data
):
    folder = real_data("head_traces")
    out = tmp_path / "hb.json"
    run_head_behaviour(json_path=out, episodes=1, seed=SEED, max_steps=150)
    result = json.loads(out.read_text())
    assert (tmp_path / "head_behaviour.png").is_file()
    assert set(result) == {"populations", "real", "distances", "split", "settings"}
    names = population_names()
    assert list(result["populations"]) == list(names) == list(result["distances"])
    datasets = list(dataset_files(folder))
    assert list(result["real"]) == datasets
    for name in names:
        assert list(result["populations"][name]) == list(CONDITIONS)
        for cond in CONDITIONS:
            s = result["populations"][name][cond]
            assert s is None or list(s) == list(STATS_KEYS)
            per = result["distances"][name][cond]
            assert list(per) == datasets
            for d in per.values():
                assert d is None or (
                    set(d) == {"yaw_speed_ks", "interval_ks", "relative"}
                    and list(d["relative"]) == list(STATS_KEYS)
                )
    # the idealised user standing: a head that never moves
    still = result["populations"]["idealised"]["standing"]
    assert still["still_fraction"] == 1.0 and still["turns_per_min"] == [0.0] * 4
    # the real statistics are head_motion_stats of the held-out files' viewings, pooled; the
    # viewings left out are exactly those it rejects
    for ds, paths in dataset_files(folder).items():
        split = result["split"][ds]
        assert split["held_out"] == [p.name for p in paths if int(p.stem) % 2 == 1]
        assert split["tuning"] == [p.name for p in paths if int(p.stem) % 2 == 0]
        left_out = {(e["file"], e["line"]) for e in split["excluded_viewings"]}
        times, yaw, pitch, rejected = [], [], [], set()
        for name in split["held_out"]:
            f = read_head_traces(folder / name)
            for v, (t, p, y) in enumerate(f.viewings()):
                try:
                    head_motion_stats(y, p, times=t)
                except ValueError:
                    rejected.add((name, f.pitch_line(v)))
                    continue
                times.append(t)
                yaw.append(y)
                pitch.append(p)
        assert rejected == left_out
        assert result["real"][ds] == head_motion_stats(yaw, pitch, times=times).to_json()
    assert len(result["split"]["lo2017"]["excluded_viewings"]) >= 1  # pitch beyond 90 deg


def test_the_command_line_checks_its_options_and_names_a_missing_data_folder(
    tmp_path, monkeypatch, capsys
):
    with pytest.raises(SystemExit) as exit_info:
        main(["experiment", "head-behaviour", "--episodes", "0"])
    assert exit_info.value.code == 2
    assert "--episodes: 0 must be >= 1" in capsys.readouterr().err
    monkeypatch.setenv("VRLOCO_DATA", str(tmp_path))
    assert main(["experiment", "head-behaviour", "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("vrloco experiment head-behaviour: head traces not found at")
    assert "VRLOCO_DATA" in err and len(err.strip().splitlines()) == 1

"""The default run's grids and the pair analysis over a run's rows."""

import json
import math

import pytest

from agents.benchmark import run_benchmark
from agents.benchmark.discrimination import (
    OUTCOMES,
    PAIRS,
    Pair,
    pair_results,
    show_pairs,
    write_pairs,
)
from agents.benchmark.grid import DEFAULT_GRIDS, Cell, Grid
from agents.benchmark.paired import BINARY_METRICS, MEAN_METRICS


def _row(technique, policy, task="approach", condition="lab", **tests):
    """A row whose paired tests against the baseline are ``tests`` (metric: (diff, p))."""
    vs = {m: {"p": 1.0, "diff": 0.0, "n": 20} for m in (*BINARY_METRICS, *MEAN_METRICS)}
    for m, (diff, p) in tests.items():
        vs[m] = {"p": p, "diff": diff, "n": 20}
    return {
        "task": task,
        "policy": policy,
        "technique": technique,
        "condition": condition,
        "vs_baseline": vs,
    }


def test_a_pair_separates_only_in_its_expected_direction():
    pair = Pair("threshold_steps", "goal_seeker+typical", (("phantom_steps_per_min", +1),))
    rows = [
        _row(
            "threshold_steps", "goal_seeker+typical", "approach", phantom_steps_per_min=(-2.0, 1e-4)
        ),  # significant, the wrong way
        _row(
            "threshold_steps", "goal_seeker+typical", "avoid", phantom_steps_per_min=(3.0, 0.02)
        ),  # the right way, not significant
    ]
    (res,) = pair_results(rows, (pair,))
    assert not res["separates"] and res["metrics"] == []
    assert res["tasks"]["approach"]["phantom_steps_per_min"]["verdict"] == "against"
    assert res["tasks"]["avoid"]["phantom_steps_per_min"]["verdict"] is None
    rows.append(
        _row(
            "threshold_steps", "goal_seeker+typical", "doorway", phantom_steps_per_min=(3.0, 0.009)
        )
    )
    (res,) = pair_results(rows, (pair,))
    assert res["separates"] and res["metrics"] == ["doorway:phantom_steps_per_min"]
    assert not res["on_outcome"]


@pytest.mark.parametrize("better", [True, False])
def test_outcomes_count_in_the_direction_of_better_or_worse(better):
    pair = Pair("x", "goal_seeker+typical", (), better=better)
    for metric, sign in OUTCOMES.items():
        diff = 0.1 * sign * (1 if better else -1)  # the expected way
        (res,) = pair_results([_row("x", "goal_seeker+typical", **{metric: (diff, 1e-3)})], (pair,))
        assert res["on_outcome"] and res["metrics"] == [f"approach:{metric}"], metric
        (res,) = pair_results(
            [_row("x", "goal_seeker+typical", **{metric: (-diff, 1e-3)})], (pair,)
        )
        assert not res["separates"], metric


def test_pairs_match_their_cells_by_policy_and_condition(tmp_path, capsys):
    pair = Pair(
        "madgwick",
        "goal_seeker+typical",
        (("heading_error_rmse_deg", +1),),
        condition="beside_metal",
    )
    lab = _row("madgwick", "goal_seeker+typical", heading_error_rmse_deg=(1.0, 1e-5))
    assert pair_results([lab], (pair,)) == []  # the lab row is not the pair's scenario
    metal = _row(
        "madgwick",
        "goal_seeker+typical",
        condition="beside_metal",
        heading_error_rmse_deg=(1.0, 1e-5),
        spl=(math.nan, math.nan),
    )
    (res,) = pair_results([lab, metal], (pair,))
    assert res["separates"] and res["pair"] == "madgwick (goal_seeker+typical, beside_metal)"
    show_pairs([res])
    out = capsys.readouterr().out
    assert "1 of 1 pairs separate, 0 on an outcome" in out
    path = write_pairs(tmp_path / "pairs.json", [res])
    data = json.loads(path.read_text())  # NaN written as null: strict JSON
    assert data[0]["tasks"]["approach"]["spl"]["p"] is None


def test_every_pair_has_its_scenario_in_the_default_run():
    cells = {c for g in DEFAULT_GRIDS for c in g.cells()}
    for pair in PAIRS:
        for technique in ("zhang2021", pair.technique):
            found = [
                c
                for c in cells
                if c.technique == technique
                and c.policy == pair.policy
                and c.condition == pair.condition
            ]
            assert found, (pair.name, technique)
        assert all(m in MEAN_METRICS or m in BINARY_METRICS for m, _ in pair.signature)


def test_grids_run_as_one_and_replace_the_axes():
    g = Grid(("approach",), ("goal_seeker",), ("zhang2021", "smooth"))
    assert g.cells() == [
        Cell("approach", "goal_seeker", "zhang2021"),
        Cell("approach", "goal_seeker", "smooth"),
    ]
    shared = Grid(("approach",), ("goal_seeker",), ("zhang2021",))
    rows = run_benchmark(
        grids=[g, shared], episodes=1, seed=4, workers=1, progress=False, print_table=False
    )
    assert [r["technique"] for r in rows] == ["zhang2021", "smooth"]  # the shared cell ran once
    assert rows[1]["vs_baseline"]["spl"]["n"] == 1
    with pytest.raises(ValueError, match="grids replaces tasks"):
        run_benchmark(grids=[g], tasks=["avoid"], progress=False)
    with pytest.raises(ValueError, match="techniques must name at least one entry"):
        run_benchmark(grids=[Grid(("approach",), ("goal_seeker",), ())], progress=False)
    with pytest.raises(ValueError, match="policy='robot'"):
        run_benchmark(grids=[Grid(("approach",), ("robot",), ("zhang2021",))], progress=False)

"""The learned-ranking experiment: ranks, verdicts and disagreements read from the benchmark's
rows and paired tests, and one tiny run through the real benchmark."""

import json

import pytest

import agents.learned  # noqa: F401  (before torch: see its docs)
from agents.experiments import learned_ranking
from agents.experiments.learned_ranking import rank, run_learned_ranking


def test_ranks_share_the_better_place_on_ties():
    assert rank({"a": 0.9, "b": 1.0, "c": 0.9, "d": 0.5}) == {"a": 2, "b": 1, "c": 2, "d": 4}


def _row(task, policy, technique, value, p=None, diff=0.0):
    vs = None if p is None else {"collision_free_success_rate": {"p": p, "diff": diff, "n": 50}}
    return {
        "task": task,
        "policy": policy,
        "technique": technique,
        "episodes": 50,
        "collision_free_success_rate": value,
        "success_rate": value,
        "collision_rate": 1 - value,
        "stop_overshoot_m": float("nan") if technique == "smooth" else 0.1,
        "vs_baseline": vs,
    }


def test_the_rankings_their_tests_and_where_they_disagree(monkeypatch, tmp_path, capsys):
    from agents.learned.users import LEARNED_USERS

    monkeypatch.delitem(LEARNED_USERS, "interact")  # a task without a shipped user

    values = {  # scripted, learned, adapted, any technique
        "zhang2021": (0.80, 0.90, 0.90, 0.95),
        "smooth": (0.40, 0.88, 0.96, 0.95),
        "nod_robust": (0.78, 0.70, 0.92, 0.90),
    }
    tests = {  # (p, diff) against the baseline, per user kind
        "smooth": [(0.001, -0.4), (0.9, -0.02), (0.2, 0.06), (1.0, 0.0)],
        "nod_robust": [(0.8, -0.02), (0.005, -0.2), (0.5, 0.02), (0.5, -0.05)],
    }
    any_user = f"{LEARNED_USERS['avoid_any_technique'].path}+typical"
    policies = ["goal_seeker+typical", "ppo+typical", "ppo@1000+typical", any_user]

    def fake_benchmark(**kw):
        assert kw["policies"] == policies and kw["tasks"] == ["avoid"]
        assert kw["seed"] == learned_ranking.REPORT_SEED
        rows = []
        for t, vals in values.items():
            for k, pol in enumerate(policies):
                p, d = tests[t][k] if t in tests else (None, 0.0)
                rows.append(_row("avoid", pol, t, vals[k], p, d))
        return rows

    monkeypatch.setattr("agents.benchmark.run_benchmark", fake_benchmark)
    out = tmp_path / "r.json"
    result = run_learned_ranking(
        episodes=50,
        adapt_steps=1000,
        tasks=["interact", "avoid"],
        techniques=list(values),
        json_path=out,
        progress=False,
    )
    assert json.loads(out.read_text()) == result
    assert result["tasks"]["avoid"]["techniques"]["smooth"]["scripted"]["stop_overshoot_m"] is None
    assert result["skipped"] == {"interact": "no shipped learned user"}
    avoid = result["tasks"]["avoid"]["techniques"]
    assert [avoid[t]["scripted"]["rank"] for t in values] == [1, 3, 2]
    assert [avoid[t]["adapted"]["rank"] for t in values] == [3, 1, 2]
    assert avoid["smooth"]["scripted"]["verdict"] == "worse"
    assert avoid["nod_robust"]["learned"]["verdict"] == "worse"
    assert avoid["smooth"]["adapted"]["verdict"] == "same"
    assert avoid["zhang2021"]["learned"]["verdict"] == "baseline"
    assert avoid["smooth"]["scripted"]["ci"][0] < 0.40 < avoid["smooth"]["scripted"]["ci"][1]
    found = {(d["technique"], *d["users"]) for d in result["tasks"]["avoid"]["disagreements"]}
    assert ("smooth", "scripted", "adapted") in found  # rank 3 -> 1 and worse -> same
    assert ("nod_robust", "scripted", "learned") in found  # same -> worse
    assert ("zhang2021", "scripted", "learned") not in found  # rank 1 both
    assert avoid["smooth"]["any technique"]["rank"] == 1  # ties share the better rank
    assert avoid["smooth"]["any technique"]["policy"] == "avoid_any_technique+typical"
    tau = result["tasks"]["avoid"]["tau"]
    assert tau["scripted/adapted"] == pytest.approx(-1.0)
    table = capsys.readouterr().out
    assert "| avoid | smooth | 0.40 (3) - | 0.88 (2) | 0.96 (1) | 0.95 (1) |" in table
    assert "interact: not played (no shipped learned user)" in table


def test_another_adaptation_seed_plays_another_adapted_user(monkeypatch):
    played = []

    def fake_benchmark(**kw):
        played.extend(kw["policies"])
        return [
            _row("avoid", pol, t, v, None, 0.0)
            for t, v in (("zhang2021", 0.5), ("threshold_steps", 0.6))
            for pol in played
        ]

    monkeypatch.setattr("agents.benchmark.run_benchmark", fake_benchmark)
    result = run_learned_ranking(
        adapt_steps=1000,
        adapt_seed=2,
        tasks=["avoid"],
        techniques=["zhang2021", "threshold_steps"],
        progress=False,
    )
    assert "ppo@1000:2+typical" in played
    assert result["settings"]["adapt_seed"] == 2
    assert result["settings"]["command"].endswith("--adapt 1000 --adapt-seed 2")


def test_bad_settings_are_named(monkeypatch):
    from agents.learned.users import LEARNED_USERS

    monkeypatch.delitem(LEARNED_USERS, "interact")  # a task without a shipped user
    with pytest.raises(ValueError, match="episodes=1: must be an integer >= 2"):
        run_learned_ranking(episodes=1)
    with pytest.raises(ValueError, match="adapt_steps=0"):
        run_learned_ranking(adapt_steps=0)
    with pytest.raises(ValueError, match="adapt_seed=-1: must be an integer >= 0"):
        run_learned_ranking(adapt_seed=-1)
    with pytest.raises(ValueError, match="none has a shipped learned user"):
        run_learned_ranking(tasks=["interact"], episodes=2)


@pytest.mark.slow  # adapts the shipped Avoid user to two techniques, then plays 2 episodes each
def test_a_tiny_ranking_through_the_benchmark(monkeypatch, tmp_path):
    monkeypatch.setenv("VRLOCO_ADAPT_CACHE", str(tmp_path / "cache"))
    result = run_learned_ranking(
        episodes=2,
        adapt_steps=8192,
        dev=True,
        tasks=["avoid"],
        techniques=["zhang2021", "smooth"],
        workers=1,
        progress=False,
    )
    cells = result["tasks"]["avoid"]["techniques"]["smooth"]
    assert set(cells) == {"scripted", "learned", "adapted", "any technique"}
    assert cells["adapted"]["policy"] == "ppo@8192+typical"
    for c in cells.values():
        assert 0.0 <= c["value"] <= 1.0 and c["p"] is not None


def test_the_readmes_ranking_is_the_committed_runs():
    """The README's table is docs/results/learned_ranking.json (the command's output) as
    written: per technique, Avoid's users then Approach's, each user's collision-free success,
    its rank and the worse-than-baseline mark."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[3]
    result = json.loads((root / "docs/results/learned_ranking.json").read_text())
    assert result["settings"]["seed"] == learned_ranking.REPORT_SEED
    readme = (root / "README.md").read_text()
    section = readme[readme.index("## Learned users") : readme.index("## Plug in your own")]
    mark = {"better": " +", "worse": " -"}
    columns = [
        ("avoid", ("scripted", "learned", "adapted", "any technique")),
        ("approach", ("scripted", "learned", "adapted", "any technique")),
    ]
    for technique in result["tasks"]["avoid"]["techniques"]:
        shown = []
        for task, users in columns:
            cells = result["tasks"][task]["techniques"][technique]
            shown += [
                f"{cells[u]['value']:.2f} ({cells[u]['rank']}){mark.get(cells[u]['verdict'], '')}"
                for u in users
            ]
        assert f"| {technique} | {' | '.join(shown)} |" in section

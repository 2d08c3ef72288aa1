"""The population-sensitivity experiment: the choice fields, the collapsed populations, the
registry restored, and the JSON on a small grid of a few episodes."""

import dataclasses
import inspect
import json
import re

import pytest

from agents.benchmark.grid import DEFAULT_GRIDS, Grid
from agents.experiments import population_sensitivity as ps
from vrloco_env.user.population import (
    CHOICE_FIELDS,
    POPULATIONS,
    RANGE_FIELDS,
    Population,
)

#: One pair's cells (nod_robust against zhang2021 with nodding users), few episodes: a fast run.
SMALL_GRID = (Grid(("approach",), ("goal_seeker+nodders",), ("zhang2021", "nod_robust")),)


def _attribute_docs() -> dict[str, str]:
    """Each attribute's text in :class:`Population`'s docstring, by name."""
    doc = inspect.getdoc(Population)
    section = doc.split("Attributes:", 1)[1]
    parts = re.split(r"^    (\w+(?:,\s+\w+)*):", section, flags=re.MULTILINE)
    docs = {}
    for names, text in zip(parts[1::2], parts[2::2], strict=True):
        for name in re.split(r",\s+", names):
            docs[name] = " ".join(text.split())
    return docs


def test_choice_fields_are_exactly_the_range_fields_whose_docs_call_them_a_choice():
    docs = _attribute_docs()
    assert set(RANGE_FIELDS) <= set(docs)

    def labelled_choice(text: str) -> bool:
        # a choice, not labelled a fit, a source or a bound (scan_amplitude_deg is a fit with
        # one population "a choice at the wide end"; wip_turn_deg_per_step is a bound)
        return "choice" in text.lower() and not re.search(r"\bA (fit|source|bound)\b", text)

    assert CHOICE_FIELDS == tuple(f for f in RANGE_FIELDS if labelled_choice(docs[f]))
    assert "scan_amplitude_deg" not in CHOICE_FIELDS and "nod_rate_hz" in CHOICE_FIELDS
    for f in CHOICE_FIELDS:
        for p in POPULATIONS.values():
            lo, hi = getattr(p, f)
            assert isinstance(lo, float) and isinstance(hi, float) and lo <= hi


def test_collapsed_populations_have_the_intended_range_and_nothing_else_changed():
    assert ps.grid_populations(DEFAULT_GRIDS) == ("typical", "nodders", "gaze_scanners")
    for name in ps.grid_populations(DEFAULT_GRIDS):
        p = POPULATIONS[name]
        for field in CHOICE_FIELDS:
            lo, hi = getattr(p, field)
            for end, want in (("lo", lo), ("hi", hi)):
                c = ps.collapse(p, field, end)
                if lo == hi:
                    assert c is p
                    continue
                assert c.name == ps.derived_name(name, field, end) == f"{name}__{field}__{end}"
                assert getattr(c, field) == (want, want)
                assert c.name.isidentifier()  # a policy's +<population> suffix must be
                for f in dataclasses.fields(Population):
                    if f.name not in ("name", field):
                        assert getattr(c, f.name) == getattr(p, f.name), (field, f.name)
    idle = dataclasses.replace(POPULATIONS["typical"], nod_rate_hz=(0.0, 0.0))
    assert ps.collapse(idle, "nod_rate_hz", "hi") is idle  # (0, 0) stays as it is
    with pytest.raises(ValueError, match="scan_amplitude_deg"):
        ps.collapse(idle, "scan_amplitude_deg", "lo")  # a fit, not a choice
    with pytest.raises(ValueError, match="end='mid'"):
        ps.collapse(idle, "nod_rate_hz", "mid")


def test_the_populations_are_restored_even_when_the_run_raises():
    before = dict(POPULATIONS)
    copy = ps.collapse(POPULATIONS["nodders"], "nod_rate_hz", "hi")
    with pytest.raises(RuntimeError, match="boom"), ps.registered([copy]):
        assert POPULATIONS[copy.name] is copy
        del POPULATIONS["typical"]  # whatever the block does to the dict
        raise RuntimeError("boom")
    assert POPULATIONS == before and list(POPULATIONS) == list(before)
    taken = dataclasses.replace(POPULATIONS["human"], name="typical")
    with pytest.raises(ValueError, match="'typical' is registered already"), ps.registered([taken]):
        pass
    assert POPULATIONS == before


def test_a_run_with_a_failing_benchmark_restores_the_populations(monkeypatch):
    import agents.benchmark

    before = dict(POPULATIONS)
    seen = []

    def fail(**kwargs):
        seen.append([p for g in kwargs["grids"] for p in g.policies])
        seen.append(set(POPULATIONS) - set(before))
        raise RuntimeError("the grid failed")

    monkeypatch.setattr(agents.benchmark, "run_benchmark", fail)
    copies = {"nodders": ps.collapse(POPULATIONS["nodders"], "nod_rate_hz", "lo")}
    with pytest.raises(RuntimeError, match="the grid failed"):
        ps._run_row(SMALL_GRID, copies, 1, 1)
    assert seen == [["goal_seeker+nodders__nod_rate_hz__lo"], {"nodders__nod_rate_hz__lo"}]
    assert POPULATIONS == before


def test_the_json_has_the_stated_structure_and_the_workers_see_the_collapsed_users(
    tmp_path, capsys, monkeypatch
):
    import agents.benchmark.resume

    # the sources as they are now: an edit elsewhere in the tree while this runs changes nothing
    fingerprint = agents.benchmark.resume.source_fingerprint()
    monkeypatch.setattr(agents.benchmark.resume, "source_fingerprint", lambda: fingerprint)
    path = tmp_path / "s.json"
    # two workers: the benchmark's pool forks here and must see the derived populations
    result = ps.run_population_sensitivity(
        json_path=path,
        episodes=2,
        fields=["nod_rate_hz"],
        out_dir=tmp_path / "rows",
        workers=2,
        grids=SMALL_GRID,
    )
    assert json.loads(path.read_text()) == json.loads(json.dumps(result))
    data = json.loads(path.read_text())
    assert set(data) == {"reference", "rows", "settings"}
    pair = "nod_robust (goal_seeker+nodders)"
    assert [(r["field"], r["end"]) for r in data["rows"]] == [
        ("nod_rate_hz", "lo"),
        ("nod_rate_hz", "hi"),
    ]
    assert data["rows"][0]["values"] == {"nodders": [0.1, 0.1]}
    assert data["rows"][1]["values"] == {"nodders": [0.25, 0.25]}
    for row in [data["reference"], *data["rows"]]:
        assert {"field", "end", "values", "separate", "on_outcome", "pairs"} <= set(row)
        assert list(row["pairs"]) == [pair]
        verdict = row["pairs"][pair]
        assert set(verdict) == {"separates", "on_outcome", "metrics"}
        assert isinstance(verdict["separates"], bool) and isinstance(verdict["metrics"], list)
        assert row["separate"] == int(verdict["separates"])
        assert row["on_outcome"] == int(verdict["on_outcome"])
    assert data["settings"]["seeds"] == [0, 1] and data["settings"]["pairs_of"] == 1
    # the collapsed nod rate reached the users (in the workers): the two ends' numbers differ
    rows = {
        r: json.loads((tmp_path / "rows" / f"{r}.json").read_text())["benchmark_rows"]
        for r in ("reference", "nod_rate_hz__lo", "nod_rate_hz__hi")
    }
    assert [r["policy"] for r in rows["nod_rate_hz__hi"]] == [
        "goal_seeker+nodders__nod_rate_hz__hi"
    ] * 2
    numbers = {
        k: [{m: x for m, x in r.items() if m != "policy"} for r in v] for k, v in rows.items()
    }
    assert numbers["nod_rate_hz__lo"] != numbers["nod_rate_hz__hi"]
    out = capsys.readouterr().out
    table = out[: out.index("wrote")]
    assert max(len(line) for line in table.splitlines()) <= ps.WIDTH
    assert "nod_rate_hz    hi" in table and "reference" in table
    # a rerun with the same folder reuses every row
    again = ps.run_population_sensitivity(
        episodes=2, fields=["nod_rate_hz"], out_dir=tmp_path / "rows", grids=SMALL_GRID
    )
    assert again["rows"] == result["rows"]
    assert "reused" in capsys.readouterr().err


def test_differs_names_each_changed_verdict():
    ref = {
        "pairs": {
            "a (u)": {"separates": True, "on_outcome": False},
            "b (u)": {"separates": False, "on_outcome": False},
        }
    }
    row = {
        "pairs": {
            "a (u)": {"separates": False, "on_outcome": False},
            "b (u)": {"separates": True, "on_outcome": True},
        }
    }
    assert ps._differs(row, ref) == ["a (u): yes->no", "b (u): no->yes", "b (u): outcome no->yes"]


def test_unknown_fields_are_refused():
    with pytest.raises(ValueError, match="'bogus' is no choice field"):
        ps.run_population_sensitivity(fields=["bogus"], grids=SMALL_GRID)
    with pytest.raises(ValueError, match="episodes=0"):
        ps.run_population_sensitivity(episodes=0, grids=SMALL_GRID)


def test_the_command_refuses_an_unknown_field_in_one_line(capsys):
    from agents.cli import main

    assert main(["experiment", "population-sensitivity", "--fields", "glance_s,bogus"]) == 2
    err = capsys.readouterr().err
    assert "'bogus' is no choice field" in err and "Traceback" not in err

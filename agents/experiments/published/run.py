"""``vrloco experiment published``: the findings of :mod:`~agents.experiments.published.scenarios`
played on the development and the reporting seeds, with the test each states.

Each testable finding plays its cells (two techniques, or one technique under two populations;
one technique for a range) on the same seeds, episode ``i`` of each with seed ``i`` as the
benchmark plays it (:func:`agents.benchmark.episodes.run_episode`), so the per-episode values
pair. The development seeds set an equivalence margin stated as a rule on them; the reporting
seeds give every reported figure.

Outputs: a table on stdout (finding, source, N of the study, our effect and interval, p,
verdict) and, with ``json_path``, ``{"findings": [{"id", "source", "study_n", "scenario",
"metric", "expected", "effect", "ci", "p", "verdict", "n_episodes", "margin", "means", "why"}],
"settings": {...}}``; ``verdict`` is ``"reproduced"``, ``"not reproduced"`` or ``"not testable"``.

Run: ``vrloco experiment published [--json F] [--episodes N]``.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from agents.benchmark.cell_statistics import bootstrap_interval
from agents.benchmark.metrics import EpisodeStats
from agents.benchmark.paired import episode_values, wilcoxon_p
from agents.benchmark.step_matching import match_step_counts, match_step_times
from agents.experiments.published.scenarios import (
    ALPHA,
    DEV_SEEDS,
    FINDINGS,
    REPORT_SEEDS,
    Finding,
)

__all__ = ["METRICS", "decide", "format_table", "metric_values", "run_published"]

#: The per-episode metrics a finding can name.
METRICS = ("completion_time_s", "step_accuracy", "stop_latency_s")


def metric_values(e: EpisodeStats, metric: str, horizon_s: float) -> float:
    """One episode's value of ``metric``:

    * ``completion_time_s``: the episode's time when it succeeded, else the horizon (s);
    * ``step_accuracy``: steps detected at their true heel strike over the steps performed plus
      the phantom steps, ``tp / (tp + fn + fp)`` (NaN without a step either way);
    * ``stop_latency_s``: the walking-in-place stop latency
      (:func:`agents.benchmark.wip_measures.motion_measures`; NaN without a complete bout).
    """
    if metric == "completion_time_s":
        return float(e.elapsed_s) if e.success else float(horizon_s)
    if metric == "step_accuracy":
        if e.true_step_times is not None and e.detected_step_times is not None:
            tp, fp, fn = match_step_times(e.true_step_times, e.detected_step_times)
        else:
            tp, fp, fn = match_step_counts(e.true_counts, e.detected_counts, 2, 2)
        total = tp + fp + fn
        return tp / total if total else math.nan
    if metric == "stop_latency_s":
        return float(episode_values(e)["stop_latency_s"])
    raise ValueError(f"metric={metric!r}: unknown; valid names: {', '.join(METRICS)}")


def _cells(f: Finding) -> list[tuple[str, str | None, str]]:
    """The finding's cells as (technique, population, policy)."""
    if f.conditions:
        out = []
        for pop in f.conditions:
            policy = f.policy if pop is None else f"{f.policy.split('+')[0]}+{pop}"
            out.append((f.techniques[0], pop, policy))
        return out
    return [(t, f.population, f.policy) for t in f.techniques]


def _play(f: Finding, seeds: Sequence[int]) -> np.ndarray:
    """(cells, episodes) metric values of the finding's cells on ``seeds``."""
    import gymnasium as gym

    from agents.benchmark.episodes import run_episode
    from agents.benchmark.policies import build_policy
    from vrloco_env.tasks import env_id

    rows = []
    for technique, population, policy in _cells(f):
        env = gym.make(env_id(f.task), technique=technique, population=population)
        try:
            horizon = env.spec.max_episode_steps * env.unwrapped.core.dt
            user = build_policy(policy, env)
            values = [
                metric_values(run_episode(env, user, s, name=policy)[0], f.metric, horizon)
                for s in seeds
            ]
        finally:
            env.close()
        rows.append(values)
    return np.asarray(rows, dtype=np.float64)


def _tost_p(d: np.ndarray, margin: float) -> float:
    """The TOST p-value of paired differences ``d`` against (-margin, margin): the larger of the
    two one-sided t-tests' (mean > -margin, mean < margin)."""
    lower = stats.ttest_1samp(d, -margin, alternative="greater").pvalue
    upper = stats.ttest_1samp(d, margin, alternative="less").pvalue
    return float(max(lower, upper))


def decide(f: Finding, dev: np.ndarray, report: np.ndarray) -> dict[str, Any]:
    """The finding's row from its development and reporting values ((cells, episodes) each)."""
    row: dict[str, Any] = {
        "id": f.id,
        "source": f.source,
        "study_n": f.study_n,
        "scenario": f.scenario,
        "metric": f.metric,
        "expected": f.expected,
        "effect": None,
        "ci": None,
        "p": None,
        "verdict": "not testable",
        "n_episodes": int(report.shape[1]),
        "margin": None,
        "means": [float(np.nanmean(r)) for r in report if np.isfinite(r).any()],
        "why": "",
    }
    if f.untestable is not None:
        row["why"], row["n_episodes"] = f.untestable, 0
        return row
    if f.test == "range":
        x = report[0][np.isfinite(report[0])]
        lo, hi = f.range
        row["effect"] = float(np.mean(x)) if x.size else None
        row["ci"] = list(bootstrap_interval(x))
        row["n_episodes"] = int(x.size)
        if not x.size:
            row["verdict"], row["why"] = "not testable", "no complete walking bout to measure"
            return row
        overlaps = bool(row["ci"][0] <= hi and row["ci"][1] >= lo)
        row["verdict"] = "reproduced" if overlaps else "not reproduced"
        row["why"] = (
            f"the mean's 95 % interval {'overlaps' if overlaps else 'misses'} [{lo:.3g}, {hi:.3g}]"
        )
        return row
    a, b = report
    ok = np.isfinite(a) & np.isfinite(b)
    d = (b - a)[ok]
    row["n_episodes"] = int(d.size)
    row["effect"] = float(np.mean(d))
    row["ci"] = list(bootstrap_interval(d))
    if f.test == "difference":
        p = float(wilcoxon_p(d))
        row["p"] = p
        want = -1.0 if f.expected == "B < A" else 1.0
        hit = bool(p < ALPHA and np.sign(row["effect"]) == want)
        row["verdict"] = "reproduced" if hit else "not reproduced"
        row["why"] = f"Wilcoxon p = {p:.3g}, B - A = {row['effect']:+.3g}" + (
            "" if hit else " (not significant in the expected direction)"
        )
        return row
    if f.margin_fraction and "A's mean" in f.margin:
        margin = f.margin_fraction * float(np.nanmean(dev[0]))
    else:
        margin = f.margin_fraction
    row["margin"] = margin
    p = _tost_p(d, margin)
    row["p"] = p
    hit = bool(p < ALPHA)
    row["verdict"] = "reproduced" if hit else "not reproduced"
    row["why"] = f"TOST p = {p:.3g} against +-{margin:.3g} ({f.margin})"
    return row


def run_published(
    json_path: Path | None = None,
    episodes: int | None = None,
    findings: Sequence[str] | None = None,
    dev: bool = False,
) -> list[dict[str, Any]]:
    """Play every finding (or those named) and print the table; write the JSON if asked.

    Args:
        episodes: reporting episodes per cell (default: all of :data:`REPORT_SEEDS`); fewer
            for a quick look (the development seeds are always all played).
        findings: ids to play (default: all).
        dev: play the development seeds in place of the reporting ones (in-sample: what the
            scenarios were chosen on), labelled so in the output.
    """
    if episodes is not None and (
        isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 2
    ):
        raise ValueError(f"episodes={episodes!r}: must be an integer >= 2")
    ids = [f.id for f in FINDINGS]
    chosen = list(FINDINGS)
    if findings is not None:
        bad = [x for x in findings if x not in ids]
        if bad:
            raise ValueError(f"findings: {', '.join(bad)} unknown; valid ids: {', '.join(ids)}")
        chosen = [f for f in FINDINGS if f.id in findings]
    pool = DEV_SEEDS if dev else REPORT_SEEDS
    report_seeds = pool if episodes is None else pool[:episodes]
    print(
        f"{'development (in-sample)' if dev else 'reporting (held-out)'} seeds "
        f"{report_seeds[0]}-{report_seeds[-1]}"
    )
    rows = []
    for f in chosen:
        if f.untestable is not None:
            rows.append(decide(f, np.zeros((1, 0)), np.zeros((1, 0))))
            continue
        margins_from = _play(f, DEV_SEEDS) if f.test == "equivalence" else np.zeros((2, 0))
        rows.append(decide(f, margins_from, _play(f, report_seeds)))
    print(format_table(rows))
    if json_path is not None:
        settings = {
            "dev_seeds": [DEV_SEEDS[0], DEV_SEEDS[-1]],
            "report_seeds": [report_seeds[0], report_seeds[-1]],
            "seeds_are": "development (in-sample)" if dev else "reporting (held-out)",
            "alpha": ALPHA,
        }
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps({"findings": rows, "settings": settings}, indent=2))
        print(f"wrote {json_path}")
    return rows


def _num(x: Any) -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.3g}"


def _short_source(source: str) -> str:
    """``Tregillus CHI 2017`` for ``Tregillus, Al Zayer & Folmer, CHI 2017``."""
    plain = re.sub(r"\s*\([^)]*\)", "", source)  # without its parentheses
    first = plain.split(",")[0].split(" & ")[0]
    venue = plain.rsplit(",", 1)[1].strip() if "," in plain else ""
    return f"{first} {venue}".strip()


def format_table(rows: Sequence[dict[str, Any]]) -> str:
    """The findings as a text table: finding, source, N of the study, our effect and its
    interval, p, verdict; each finding's scenario, expected direction and reason below."""
    lines = [f"{'finding':<24} {'source':<28} {'N':>3} {'effect [95% CI]':<26} {'p':>7}  verdict"]
    for r in rows:
        ci = r["ci"]
        eff = "-" if r["effect"] is None else f"{_num(r['effect'])} [{_num(ci[0])}, {_num(ci[1])}]"
        n = "-" if r["study_n"] is None else str(r["study_n"])
        lines.append(
            f"{r['id']:<24} {_short_source(r['source'])[:28]:<28} {n:>3} {eff:<26} "
            f"{_num(r['p']):>7}  {r['verdict']}"
        )
    lines.append("")
    for r in rows:
        expected = f"expected {r['expected']}; " if r["expected"] else ""
        lines.append(f"{r['id']}: {r['source']}; {r['scenario']}; {expected}{r['why']}")
    return "\n".join(lines)

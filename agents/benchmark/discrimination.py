"""Discriminating power: the technique pairs a benchmark run should tell apart, and whether it does.

Each :class:`Pair` names a technique, the users and room in which it should differ from the
baseline technique (``zhang2021``), the direction it should differ in and why. A run's rows carry
each cell's paired tests against the baseline on the same seeds (``vs_baseline``,
:mod:`agents.benchmark.paired`); :func:`pair_results` reads them: a pair *separates* where one of
its signature metrics or one outcome (success, collisions, SPL, time to goal) differs at p <
:data:`agents.benchmark.paired.ALPHA` in the expected direction, in at least one task. A difference
in the unexpected direction is reported too (``against``), never counted.

Caveat on the many comparisons: a pair is tested on several metrics in several tasks, each at
p < 0.01 with no correction (the p-values are in the output for a reader who wants Holm or
Bonferroni); requiring the expected direction halves the chance of a spurious hit.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents.benchmark.conditions import DEFAULT_CONDITION
from agents.benchmark.outputs import json_safe, terminal_console
from agents.benchmark.paired import ALPHA

__all__ = ["OUTCOMES", "PAIRS", "Pair", "pair_results", "show_pairs", "write_pairs"]

#: The outcome metrics, each with the sign of "better" (+1: higher is better).
OUTCOMES = {"success_rate": +1, "collision_rate": -1, "spl": +1, "time_to_goal_s": -1}


@dataclass(frozen=True)
class Pair:
    """A technique the benchmark should tell apart from the baseline, and where.

    Attributes:
        technique: the technique compared with the baseline (a registered name).
        policy: the users it is compared with (a benchmark policy, e.g. ``goal_seeker+nodders``).
        signature: the metrics it should differ on, each with its expected sign (+1: the
            technique's value higher than the baseline's).
        better: whether the technique should do better than the baseline on the outcomes
            (False: worse).
        condition: the physical room (:mod:`agents.benchmark.conditions`).
        why: the mechanism, in words.
    """

    technique: str
    policy: str
    signature: tuple[tuple[str, int], ...]
    better: bool = False
    condition: str = DEFAULT_CONDITION
    why: str = ""

    @property
    def name(self) -> str:
        where = "" if self.condition == DEFAULT_CONDITION else f", {self.condition}"
        return f"{self.technique} ({self.policy}{where})"


#: The pairs the default run (:data:`agents.benchmark.DEFAULT_GRIDS`) should separate.
PAIRS = (
    Pair(
        "zhang2021_as_printed",
        "goal_seeker+typical",
        (
            ("yaw_drift_deg_per_min", +1),
            ("heading_error_rmse_deg", +1),
            ("yaw_rate_mismatch_deg_s", +1),
        ),
        why="the EKF as printed does not estimate the gyro bias: the heading drifts",
    ),
    Pair(
        "zhang2021_consumer",
        "goal_seeker+typical",
        (
            ("heading_error_rmse_deg", +1),
            ("attitude_rmse_deg", +1),
            ("yaw_drift_deg_per_min", +1),
            ("yaw_rate_mismatch_deg_s", +1),
        ),
        why="a consumer MEMS IMU: more gyro bias, noise and magnetometer error",
    ),
    Pair(
        "threshold_steps",
        "goal_seeker+typical",
        (("phantom_steps_per_min", +1), ("false_motion_m_per_min", +1)),
        why="a naive |f| peak picker counts head bob, nods and glances as steps",
    ),
    Pair(
        "nod_robust",
        "goal_seeker+nodders",
        (("phantom_steps_per_min", -1), ("false_motion_m_per_min", -1)),
        better=True,
        why="steps from world-vertical force, gated by head rotation: nods are not steps",
    ),
    Pair(
        "torso_steering",
        "goal_seeker+gaze_scanners",
        (("steering_error_deg", -1), ("heading_error_rmse_deg", -1), ("path_length_ratio", -1)),
        better=True,
        why="head steering walks where the head looks; the torso keeps the body's line",
    ),
    Pair(
        "smooth",
        "goal_seeker+typical",
        (("virtual_jerk_m_s3", -1), ("stop_latency_s", +1)),
        why="the smooth-locomotion paper's filter spreads each step: less jerk, a later stop",
    ),
    Pair(
        "madgwick",
        "goal_seeker+typical",
        (
            ("heading_error_rmse_deg", +1),
            ("yaw_drift_deg_per_min", +1),
            ("yaw_rate_mismatch_deg_s", +1),
        ),
        condition="beside_metal",
        why="an ungated magnetometer follows the cabinet's field; Zhang 2021's EKF gates it",
    ),
)


def _hit(test: dict[str, Any] | None, sign: int) -> str | None:
    """``"for"`` (p < ALPHA in the direction ``sign``), ``"against"`` (the other way) or None."""
    if test is None or test.get("p") is None or test.get("diff") is None:
        return None
    p, diff = test["p"], test["diff"]
    if not (math.isfinite(p) and math.isfinite(diff)) or p >= ALPHA or diff == 0:
        return None
    return "for" if (diff > 0) == (sign > 0) else "against"


def pair_results(rows: list[dict[str, Any]], pairs: tuple[Pair, ...] = PAIRS) -> list[dict]:
    """Whether each pair separates in ``rows`` (a benchmark run's rows, with ``vs_baseline``).

    Returns:
        One dict per pair whose cells are in the rows: ``pair``, ``technique``, ``policy``,
        ``condition``, ``why``, ``tasks`` (per task: ``{metric: {"diff", "p", "expected",
        "verdict"}}`` over the signature and outcome metrics, ``verdict`` "for", "against" or
        None), ``separates`` (some metric "for" in some task), ``on_outcome`` (some outcome
        metric "for"), ``metrics`` (the metrics "for", as ``task:metric``).
    """
    out = []
    for pair in pairs:
        found = [
            r
            for r in rows
            if r["technique"] == pair.technique
            and r["policy"] == pair.policy
            and r.get("condition", DEFAULT_CONDITION) == pair.condition
            and r.get("vs_baseline")
        ]
        if not found:
            continue
        sign_better = 1 if pair.better else -1
        expected = [*pair.signature, *((m, s * sign_better) for m, s in OUTCOMES.items())]
        tasks: dict[str, dict] = {}
        hits, outcome_hit = [], False
        for r in found:
            tests = r["vs_baseline"]
            per: dict[str, dict] = {}
            for metric, sign in expected:
                t = tests.get(metric)
                verdict = _hit(t, sign)
                t = t or {}
                per[metric] = {
                    "diff": t.get("diff"),
                    "p": t.get("p"),
                    "expected": "+" if sign > 0 else "-",
                    "verdict": verdict,
                }
                if verdict == "for":
                    hits.append(f"{r['task']}:{metric}")
                    outcome_hit = outcome_hit or metric in OUTCOMES
            tasks[r["task"]] = per
        out.append(
            {
                "pair": pair.name,
                "technique": pair.technique,
                "policy": pair.policy,
                "condition": pair.condition,
                "why": pair.why,
                "tasks": tasks,
                "separates": bool(hits),
                "on_outcome": outcome_hit,
                "metrics": hits,
            }
        )
    return out


def show_pairs(results: list[dict], baseline: str = "zhang2021", width: int | None = None) -> None:
    """The pairs: each pair's metrics that differ from ``baseline`` in the expected direction,
    and a count of the pairs that separate (on an outcome). ``width``: the console's columns
    (None: :func:`agents.benchmark.outputs.terminal_console`'s choice). A console narrower than
    :data:`_TABLE_WIDTH` gets one paragraph per pair, wrapped between words, never inside a
    metric's name."""
    from rich.table import Table

    if not results:
        return
    console = terminal_console(width)
    title = (
        f"discriminating power: each technique vs {baseline} (paired, p < {ALPHA}, "
        "expected direction)"
    )
    rows = []
    for res in results:
        against = [
            f"{task}:{m}"
            for task, per in res["tasks"].items()
            for m, v in per.items()
            if v["verdict"] == "against"
        ]
        rows.append(
            (
                res["pair"],
                "yes" if res["separates"] else "NO",
                "yes" if res["on_outcome"] else "no",
                ", ".join(res["metrics"]) or "–",
                ", ".join(against) or "–",
            )
        )
    if console.width < _TABLE_WIDTH:
        console.print(title, overflow="fold")
        for pair, sep, out, differs, against in rows:
            console.print(
                f"- {pair}: separates {sep}, on an outcome {out}; differs on: "
                f"{differs}; against expectation: {against}"
            )
    else:
        table = Table(title=title)
        for head in (
            "technique (users, room)",
            "separates",
            "on outcome",
            "differs on",
            "against expectation",
        ):
            table.add_column(head)
        for r in rows:
            table.add_row(*r)
        console.print(table)
    n_sep = sum(r["separates"] for r in results)
    n_out = sum(r["on_outcome"] for r in results)
    console.print(
        f"{n_sep} of {len(results)} pairs separate, {n_out} on an outcome (success, "
        "collisions, SPL or time to goal)"
    )


#: Consoles at least this wide get the pairs as a table (narrower: a paragraph per pair).
_TABLE_WIDTH = 160


def write_pairs(path: Path, results: list[dict]) -> Path:
    """The pair results as JSON (NaN as null)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(json_safe(results), indent=2) + os.linesep)
    return path

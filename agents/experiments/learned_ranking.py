"""``vrloco experiment learned-ranking``: the default grid's techniques ranked by three kinds of
user side by side — the scripted goal seeker, the task's shipped learned user, and that user
adapted to each technique by the same fine-tuning budget, and where the task has one, its user
trained on every technique at once (``<task>_any_technique``) — each with the typical
population's head behaviour and variability, as the default grid plays its users.

One benchmark run per task (:func:`agents.benchmark.run_benchmark`) plays every (user,
technique) cell on the same seeds, so episode ``i`` of every technique is the same room and the
same user, and each technique's collision-free success is compared with the baseline technique's
(``zhang2021``) episode by episode: the exact McNemar test of the benchmark's paired tests
(:mod:`agents.benchmark.paired`). Within each (task, user) the techniques are ranked by
collision-free success (ties share the better rank). Two rankings *disagree* on a technique where
its rank moves by two or more places or its paired verdict against the baseline (better, worse
or no difference at p < :data:`~agents.benchmark.paired.ALPHA`) changes; Kendall's tau-b
(``scipy.stats.kendalltau``) summarises each pair of rankings. Each technique's stop overshoot
(m) and collision rate are kept beside its rank to say why a ranking moved.

Only the default grid's tasks with a shipped learned user (:mod:`agents.learned.users`) are
played; the others are listed with the reason. The reporting seeds start at
:data:`REPORT_SEED`, which no development choice of the learned users or of the techniques
played (their development seeds are 1000-1159 and the training evaluation's 10001+); ``--dev``
plays the development seeds from :data:`DEV_SEED` instead.

An adapted user is one fine-tuning run, seeded (``--adapt-seed``, 0 by default); running the
ranking again with other seeds shows how much of the adapted column is the seed's.

Run: ``vrloco experiment learned-ranking [--json F] [--episodes N] [--adapt STEPS]
[--adapt-seed S] [--dev]``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from agents.benchmark.cell_statistics import wilson_interval
from agents.benchmark.paired import ALPHA

__all__ = ["DEV_SEED", "REPORT_SEED", "USERS", "format_table", "rank", "run_learned_ranking"]

#: The first reporting seed (held out from every development choice).
REPORT_SEED = 200_000
#: The first development seed (``--dev``).
DEV_SEED = 1_000
#: The three kinds of user, each a benchmark policy (``{steps}``: the adaptation budget, with
#: ``:SEED`` after it for a seed other than 0).
USERS = (
    ("scripted", "goal_seeker+typical"),
    ("learned", "ppo+typical"),
    ("adapted", "ppo@{steps}+typical"),
)
#: A task's user for any technique is registered as ``<task>`` + this
#: (:mod:`agents.learned.users`); where there is one it is ranked too.
ANY_TECHNIQUE = "_any_technique"
#: The ranked metric.
METRIC = "collision_free_success_rate"


def rank(values: dict[str, float]) -> dict[str, int]:
    """Competition ranks of ``values`` (higher is better; equal values share the better rank)."""
    return {k: 1 + sum(w > v for w in values.values()) for k, v in values.items()}


def _verdict(test: dict[str, Any] | None) -> str:
    """``"better"``, ``"worse"`` or ``"same"``: a paired test against the baseline at ALPHA."""
    if not test or not math.isfinite(test.get("p", math.nan)) or test["p"] >= ALPHA:
        return "same"
    return "better" if test["diff"] > 0 else "worse"


def run_learned_ranking(
    episodes: int = 60,
    adapt_steps: int = 200_000,
    dev: bool = False,
    json_path: Path | None = None,
    tasks: Sequence[str] | None = None,
    techniques: Sequence[str] | None = None,
    workers: int = 2,
    progress: bool = True,
    adapt_seed: int = 0,
) -> dict[str, Any]:
    """Play the ranking (module docstring), print its table, write ``json_path``.

    Args:
        episodes: episodes per cell (>= 2).
        adapt_steps: the adapted user's fine-tuning budget per technique (>= 1).
        adapt_seed: the fine-tuning's random seed (>= 0).
        dev: the development seeds instead of the reporting seeds.
        tasks: the tasks (default: the default grid's).
        techniques: the techniques (default: the default grid's; the first is the baseline).

    Returns:
        ``{"tasks": {task: {"techniques": {technique: {user: {"value", "ci", "rank", "diff",
        "p", "verdict", "success_rate", "collision_rate", "stop_overshoot_m"}}}, "tau": {"a/b":
        tau}, "disagreements": [...]}}, "skipped": {task: why}, "settings": {...}}``.

    Raises:
        ValueError: a bad ``episodes``, ``adapt_steps`` or ``adapt_seed``, or no task with a
            shipped user.
    """
    from scipy.stats import kendalltau

    from agents.benchmark import run_benchmark
    from agents.benchmark.grid import DEFAULT_TASKS, DEFAULT_TECHNIQUES
    from agents.benchmark.outputs import json_safe
    from agents.learned.users import LEARNED_USERS

    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 2:
        raise ValueError(f"episodes={episodes!r}: must be an integer >= 2")
    if isinstance(adapt_steps, bool) or not isinstance(adapt_steps, int) or adapt_steps < 1:
        raise ValueError(f"adapt_steps={adapt_steps!r}: must be an integer >= 1")
    if isinstance(adapt_seed, bool) or not isinstance(adapt_seed, int) or adapt_seed < 0:
        raise ValueError(f"adapt_seed={adapt_seed!r}: must be an integer >= 0")
    budget = f"{adapt_steps}:{adapt_seed}" if adapt_seed else f"{adapt_steps}"
    tasks = list(DEFAULT_TASKS if tasks is None else tasks)
    techniques = list(DEFAULT_TECHNIQUES if techniques is None else techniques)
    skipped = {t: "no shipped learned user" for t in tasks if t not in LEARNED_USERS}
    played = [t for t in tasks if t not in skipped]
    if not played:
        raise ValueError(f"tasks {', '.join(tasks)}: none has a shipped learned user")
    seed = DEV_SEED if dev else REPORT_SEED
    out: dict[str, Any] = {}
    for task in played:
        users = [(kind, spec.format(steps=budget)) for kind, spec in USERS]
        shown = {spec: spec for _, spec in users}
        second = f"{task}{ANY_TECHNIQUE}"
        if second in LEARNED_USERS:  # the task's user for any technique, played as it is
            spec = f"{LEARNED_USERS[second].path}+typical"
            users.append(("any technique", spec))
            shown[spec] = f"{second}+typical"
        rows = run_benchmark(
            tasks=[task],
            techniques=techniques,
            policies=[spec for _, spec in users],
            episodes=episodes,
            seed=seed,
            workers=workers,
            progress=progress,
            print_table=False,
        )
        by = {(r["policy"], r["technique"]): r for r in rows}
        table: dict[str, dict[str, Any]] = {t: {} for t in techniques}
        ranks: dict[str, dict[str, int]] = {}
        for kind, spec in users:
            values = {t: by[(spec, t)][METRIC] for t in techniques}
            ranks[kind] = rank(values)
            for t in techniques:
                r = by[(spec, t)]
                n = int(r.get("episodes", episodes))
                test = (r.get("vs_baseline") or {}).get(METRIC)
                table[t][kind] = {
                    "policy": shown[spec],
                    "value": values[t],
                    "ci": list(wilson_interval(round(values[t] * n), n)),
                    "rank": ranks[kind][t],
                    "diff": None if test is None else test["diff"],
                    "p": None if test is None else test["p"],
                    "verdict": "baseline" if t == techniques[0] else _verdict(test),
                    "success_rate": r["success_rate"],
                    "collision_rate": r["collision_rate"],
                    "stop_overshoot_m": r.get("stop_overshoot_m"),
                }
        kinds = [k for k, _ in users]
        tau = {}
        disagreements = []
        for i, a in enumerate(kinds):
            for b in kinds[i + 1 :]:
                ra = [ranks[a][t] for t in techniques]
                rb = [ranks[b][t] for t in techniques]
                result = kendalltau(ra, rb)
                tau[f"{a}/{b}"] = None if math.isnan(result.statistic) else result.statistic
                for t in techniques:
                    moved = abs(ranks[a][t] - ranks[b][t]) >= 2
                    turned = table[t][a]["verdict"] != table[t][b]["verdict"]
                    if moved or turned:
                        disagreements.append(
                            {
                                "technique": t,
                                "users": [a, b],
                                "ranks": [ranks[a][t], ranks[b][t]],
                                "verdicts": [table[t][a]["verdict"], table[t][b]["verdict"]],
                                "values": [table[t][a]["value"], table[t][b]["value"]],
                                "stop_overshoot_m": [
                                    table[t][a]["stop_overshoot_m"],
                                    table[t][b]["stop_overshoot_m"],
                                ],
                            }
                        )
        out[task] = {
            "users": dict((k, shown[spec]) for k, spec in users),
            "techniques": table,
            "tau": tau,
            "disagreements": disagreements,
        }
    result = {
        "tasks": out,
        "skipped": skipped,
        "settings": {
            "episodes": episodes,
            "seed": seed,
            "seeds": "development" if dev else "reporting (held-out)",
            "adapt_steps": adapt_steps,
            "adapt_seed": adapt_seed,
            "users": dict(USERS),
            "metric": METRIC,
            "alpha": ALPHA,
            "command": _command(episodes, adapt_steps, dev, adapt_seed),
        },
    }
    result = json_safe(result)  # NaN (no stop to measure, no ranking to compare): null
    print(format_table(result))
    if json_path is not None:
        Path(json_path).write_text(json.dumps(result, indent=2, allow_nan=False) + "\n")
    return result


def _command(episodes: int, adapt_steps: int, dev: bool, adapt_seed: int = 0) -> str:
    seed = f" --adapt-seed {adapt_seed}" if adapt_seed else ""
    dev_seeds = " --dev" if dev else ""
    return (
        f"vrloco experiment learned-ranking --episodes {episodes} --adapt {adapt_steps}"
        + seed
        + dev_seeds
    )


def format_table(result: dict[str, Any]) -> str:
    """The ranking as a Markdown table: per task and technique, each user's collision-free
    success, its rank in brackets and a mark where it differs from the baseline (``+`` better,
    ``-`` worse at p < ALPHA); then Kendall's tau and the disagreements."""
    mark = {"better": " +", "worse": " -"}
    users = list(dict.fromkeys(u for res in result["tasks"].values() for u in res["users"]))
    lines = [
        "| task | technique | " + " | ".join(users) + " |",
        "|---|---|" + "---|" * len(users),
    ]
    notes = []
    for task, res in result["tasks"].items():
        for t, cells in res["techniques"].items():
            parts = [
                f"{cells[u]['value']:.2f} ({cells[u]['rank']}){mark.get(cells[u]['verdict'], '')}"
                if u in cells
                else "-"
                for u in users
            ]
            lines.append(f"| {task} | {t} | " + " | ".join(parts) + " |")
        taus = ", ".join(
            f"{k} {'n/a' if v is None else format(v, '.2f')}" for k, v in res["tau"].items()
        )
        notes.append(f"{task}: Kendall's tau {taus}")
        for d in res["disagreements"]:
            a, b = d["users"]
            notes.append(
                f"  {d['technique']}: rank {d['ranks'][0]} by {a}, {d['ranks'][1]} by {b}; "
                f"vs baseline {d['verdicts'][0]} / {d['verdicts'][1]}"
            )
    for task, why in result["skipped"].items():
        notes.append(f"{task}: not played ({why})")
    return "\n".join([*lines, "", *notes])

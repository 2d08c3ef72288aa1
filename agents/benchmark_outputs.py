"""The benchmark's outputs: the row schema (:data:`ROW_KEYS`), the table printed to the terminal
(:func:`show_table`) and the CSV and JSON files (:func:`write_csv`, :func:`write_json`)."""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from agents.collision_causes import COLLISION_CAUSES
from agents.conditions import DEFAULT_CONDITION
from agents.paired import ALPHA, BINARY_METRICS, MEAN_METRICS
from agents.wip_measures import MOTION_KEYS, PLAY_AREA_KEYS

__all__ = ["BASELINE_TECHNIQUE", "ROW_KEYS", "json_safe", "show_table", "write_csv", "write_json"]

#: The technique every other one is compared with, episode by episode (:mod:`agents.paired`).
BASELINE_TECHNIQUE = "seed000"

#: Keys of every row of the CSV/JSON output, in order.
ROW_KEYS = (
    "task",
    "policy",
    "technique",
    "condition",
    "sensors",
    "episodes",
    "success_rate",
    "collision_rate",
    "collision_free_success_rate",
    "spl",
    "time_to_goal_s",
    "path_length_ratio",
    "step_precision",
    "step_recall",
    "step_f1",
    "attitude_rmse_deg",
    "heading_error_rmse_deg",
    "hand_error_deg",
    "hand_coverage",
    "mean_collisions",
    "hand_tracking_availability",
    "start_latency_s",
    "stop_latency_s",
    "stop_overshoot_m",
    "false_motion_m_per_min",
    "phantom_steps_per_min",
    "missed_steps_per_min",
    "yaw_drift_deg_per_min",
    "yaw_rate_mismatch_deg_s",
    "virtual_jerk_m_s3",
    "steering_error_deg",
    *PLAY_AREA_KEYS,
    "collision_causes",
    "vs_baseline",
    *(f"{k}_ci" for k in ("success_rate", "collision_rate", "spl", "time_to_goal_s",
                          "hand_tracking_availability", "phantom_steps_per_min",
                          "missed_steps_per_min", *MOTION_KEYS, *PLAY_AREA_KEYS)),
)


def _fmt(v: Any, digits: int = 3) -> str:
    if isinstance(v, dict):  # collision causes, in COLLISION_CAUSES order
        return "/".join(str(v[c]) for c in COLLISION_CAUSES)
    if v is None:
        return "–"
    if isinstance(v, float):
        return "–" if math.isnan(v) else f"{v:.{digits}f}"
    return str(v)


#: The table's columns (row key, heading); :data:`_COMPACT` those kept on a narrow terminal.
_COLUMNS = (("task", "task"), ("policy", "policy"), ("technique", "technique"),
            ("sensors", "sensors"), ("episodes", "n"),
            ("success_rate", "success"), ("collision_rate", "collision"),
            ("collision_free_success_rate", "coll.-free succ."), ("spl", "SPL"),
            ("time_to_goal_s", "time to goal (s)"), ("path_length_ratio", "path ratio"),
            ("step_f1", "step F1"), ("attitude_rmse_deg", "attitude RMSE (°)"),
            ("hand_error_deg", "hand err (°)"),
            ("collision_causes", "collision causes"))  # fmt: skip
_COMPACT = ("task", "policy", "technique", "success_rate", "collision_rate", "spl", "step_f1",
            "attitude_rmse_deg")  # fmt: skip
_COMPACT_HEADS = {"success_rate": "succ.", "collision_rate": "coll.", "step_f1": "F1",
                  "attitude_rmse_deg": "att. (°)"}  # fmt: skip
#: Narrower terminals than this get the compact table (the files keep every column).
_FULL_WIDTH = 180
#: The second table's columns: how walking in place felt (row key, heading).
_WIP_COLUMNS = (("task", "task"), ("policy", "policy"), ("technique", "technique"),
                ("heading_error_rmse_deg", "heading err (°)"),
                ("start_latency_s", "start lat. (s)"), ("stop_latency_s", "stop lat. (s)"),
                ("stop_overshoot_m", "overshoot (m)"),
                ("false_motion_m_per_min", "false motion (m/min)"),
                ("phantom_steps_per_min", "phantom /min"), ("missed_steps_per_min", "missed /min"),
                ("yaw_drift_deg_per_min", "yaw drift (°/min)"),
                ("yaw_rate_mismatch_deg_s", "yaw-rate mism. (°/s)"),
                ("virtual_jerk_m_s3", "jerk (m/s³)"),
                ("steering_error_deg", "steering err (°)"),
                ("hand_tracking_availability", "hand avail."),
                ("boundary_violations", "boundary viol."))  # fmt: skip
_WIP_COMPACT = ("task", "technique", "heading_error_rmse_deg", "stop_latency_s",
                "false_motion_m_per_min", "phantom_steps_per_min", "yaw_drift_deg_per_min",
                "virtual_jerk_m_s3")  # fmt: skip


def show_table(rows: list[dict[str, Any]], seed: int, width: int | None = None,
               baseline: str = BASELINE_TECHNIQUE) -> None:
    """The rows as a table fitted to the terminal (``width``: its columns, None to ask it); a
    value that differs from ``baseline``'s in the same task, policy and condition at p <
    :data:`ALPHA` (the row's ``vs_baseline``) is marked ``*``. The condition gets a column
    where some row is not in the default one."""
    from rich.console import Console

    console = Console(width=width) if width is not None else Console()
    if width is None and not console.is_terminal:  # a pipe or a file: the full table
        console = Console(width=200)
    compact = console.width < _FULL_WIDTH
    cols = [(k, _COMPACT_HEADS.get(k, h)) for k, h in _COLUMNS if k in _COMPACT] if compact else (
        list(_COLUMNS))  # fmt: skip
    if any(r.get("condition", DEFAULT_CONDITION) != DEFAULT_CONDITION for r in rows):
        at = [k for k, _ in cols].index("technique") + 1
        cols.insert(at, ("condition", "condition"))
    seeds = f"seeds {seed}..{seed + rows[0]['episodes'] - 1}"
    marked = _print_table(console, rows, cols, f"vrloco benchmark: outcomes ({seeds})", compact)
    wip = [c for c in _WIP_COLUMNS if not compact or c[0] in _WIP_COMPACT]
    if any(k == "condition" for k, _ in cols):
        wip.insert([k for k, _ in wip].index("technique") + 1, ("condition", "condition"))
    marked |= _print_table(console, rows, wip, f"walking in place ({seeds})", compact)
    if not compact:
        console.print("collision causes: " + "/".join(c.replace("_", " ")
                                                      for c in COLLISION_CAUSES))  # fmt: skip
    if marked:
        console.print(f"* differs from {baseline} (same task, policy, condition and seeds) at "
                      f"p < {ALPHA}: exact McNemar test for rates, Wilcoxon signed-rank for means "
                      "(agents.paired)")  # fmt: skip
    if compact:
        console.print(f"(a compact view for {console.width} columns: every column is in the "
                      "CSV and JSON files)")  # fmt: skip


def _print_table(console: Any, rows: list[dict[str, Any]], cols: list, title: str,
                 compact: bool) -> bool:  # fmt: skip
    """Print one table of ``rows``; True where some value is marked as differing."""
    from rich.table import Table

    table = Table(title=title, pad_edge=False, padding=(0, 1) if not compact else (0, 0))
    for key, head in cols:
        left = key in ("task", "policy", "technique", "condition", "sensors")
        table.add_column(head, justify="left" if left else "right", overflow="fold")
    marked = False
    for r in rows:
        cells = []
        for k, _ in cols:
            text = _fmt(r[k], 1 if k in ("time_to_goal_s",) else 3)
            test = (r.get("vs_baseline") or {}).get(k)
            if test is not None and test["p"] is not None and test["p"] < ALPHA:
                text, marked = text + "*", True
            cells.append(text)
        table.add_row(*cells)
    console.print(table)
    return marked


def json_safe(v: Any) -> Any:
    """JSON-safe value: NaN becomes null, an interval a list."""
    if isinstance(v, tuple | list):
        return [json_safe(x) for x in v]
    if isinstance(v, dict):
        return {k: json_safe(x) for k, x in v.items()}
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, np.generic):
        return json_safe(v.item())
    return v


def write_json(path: Path, rows: list[dict[str, Any]], meta: dict[str, Any]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {"rows": [{k: json_safe(v) for k, v in r.items()} for r in rows], "config": meta}
    path.write_text(json.dumps(data, indent=2) + os.linesep)
    return path


def write_csv(path: Path, rows: list[dict[str, Any]]) -> Path:
    """One column per metric; an interval ``<key>_ci`` as ``<key>_ci_low`` and ``_ci_high``, the
    collision causes as ``collision_causes_<cause>``, the paired test against the baseline as
    ``p_vs_baseline_<metric>`` (its p-value)."""
    def columns_of(k: str) -> tuple[str, ...]:
        if k.endswith("_ci"):
            return f"{k}_low", f"{k}_high"
        if k == "collision_causes":
            return tuple(f"{k}_{cause}" for cause in COLLISION_CAUSES)
        if k == "vs_baseline":
            return tuple(f"p_vs_baseline_{m}" for m in (*BINARY_METRICS, *MEAN_METRICS))
        return (k,)

    columns = [c for k in ROW_KEYS for c in columns_of(k)]
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        for r in rows:
            flat: dict[str, Any] = {}
            for k in ROW_KEYS:
                if k.endswith("_ci"):
                    flat[f"{k}_low"], flat[f"{k}_high"] = r[k]
                elif k == "collision_causes":
                    for cause in COLLISION_CAUSES:
                        flat[f"{k}_{cause}"] = None if r[k] is None else r[k][cause]
                elif k == "vs_baseline":
                    for m in (*BINARY_METRICS, *MEAN_METRICS):
                        flat[f"p_vs_baseline_{m}"] = None if r[k] is None else r[k][m]["p"]
                else:
                    flat[k] = r[k]
            w.writerow({k: ("" if json_safe(v) is None else v) for k, v in flat.items()})
    return path

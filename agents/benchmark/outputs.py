"""The benchmark's outputs: the row schema (:data:`ROW_KEYS`), the table printed to the terminal
(:func:`show_table`) and the CSV and JSON files (:func:`write_csv`, :func:`write_json`)."""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from agents.benchmark.collision_causes import COLLISION_CAUSES
from agents.benchmark.conditions import DEFAULT_CONDITION
from agents.benchmark.paired import ALPHA, BINARY_METRICS, MEAN_METRICS
from agents.benchmark.wip_measures import MOTION_KEYS, PLAY_AREA_KEYS

__all__ = [
    "BASELINE_TECHNIQUE",
    "ROW_KEYS",
    "WriteError",
    "atomic_path",
    "json_safe",
    "show_table",
    "terminal_console",
    "write_csv",
    "write_json",
    "written_summary",
]

#: The technique every other one is compared with, episode by episode
#: (:mod:`agents.benchmark.paired`).
BASELINE_TECHNIQUE = "zhang2021"

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
    *(
        f"{k}_ci"
        for k in (
            "success_rate",
            "collision_rate",
            "spl",
            "time_to_goal_s",
            "hand_tracking_availability",
            "phantom_steps_per_min",
            "missed_steps_per_min",
            *MOTION_KEYS,
            *PLAY_AREA_KEYS,
        )
    ),
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
_COLUMNS = (
    ("task", "task"),
    ("policy", "policy"),
    ("technique", "technique"),
    ("sensors", "sensors"),
    ("episodes", "n"),
    ("success_rate", "success"),
    ("collision_rate", "collision"),
    ("collision_free_success_rate", "coll.-free succ."),
    ("spl", "SPL"),
    ("time_to_goal_s", "time to goal (s)"),
    ("path_length_ratio", "path ratio"),
    ("step_f1", "step F1"),
    ("attitude_rmse_deg", "attitude RMSE (°)"),
    ("hand_error_deg", "hand err (°)"),
    ("collision_causes", "collision causes"),
)
_COMPACT = (
    "success_rate",
    "collision_rate",
    "spl",
    "time_to_goal_s",
    "step_f1",
    "attitude_rmse_deg",
)
#: The compact tables' short headings, and what each means (printed under the tables).
_COMPACT_HEADS = {
    "success_rate": "succ.",
    "collision_rate": "coll.",
    "time_to_goal_s": "time",
    "step_f1": "F1",
    "attitude_rmse_deg": "att.°",
    "heading_error_rmse_deg": "head.°",
    "stop_latency_s": "stop",
    "false_motion_m_per_min": "false",
    "phantom_steps_per_min": "phant.",
    "yaw_drift_deg_per_min": "drift",
    "virtual_jerk_m_s3": "jerk",
}
_LEGEND = {
    "success_rate": "success rate",
    "collision_rate": "episodes with a collision",
    "time_to_goal_s": "time to goal (s)",
    "step_f1": "step F1",
    "attitude_rmse_deg": "attitude RMSE (deg)",
    "heading_error_rmse_deg": "heading error RMSE (deg)",
    "stop_latency_s": "stop latency (s)",
    "false_motion_m_per_min": "false motion (m/min)",
    "phantom_steps_per_min": "phantom steps/min",
    "yaw_drift_deg_per_min": "yaw drift (deg/min)",
    "virtual_jerk_m_s3": "jerk (m/s^3)",
}
#: The columns that name a row (left-aligned, never dropped to fit).
_NAME_KEYS = ("task", "policy", "technique", "condition", "sensors")
#: Narrower terminals than this get the compact table (the files keep every column).
_FULL_WIDTH = 180
#: The second table's columns: how walking in place felt (row key, heading).
_WIP_COLUMNS = (
    ("task", "task"),
    ("policy", "policy"),
    ("technique", "technique"),
    ("heading_error_rmse_deg", "heading err (°)"),
    ("start_latency_s", "start lat. (s)"),
    ("stop_latency_s", "stop lat. (s)"),
    ("stop_overshoot_m", "overshoot (m)"),
    ("false_motion_m_per_min", "false motion (m/min)"),
    ("phantom_steps_per_min", "phantom /min"),
    ("missed_steps_per_min", "missed /min"),
    ("yaw_drift_deg_per_min", "yaw drift (°/min)"),
    ("yaw_rate_mismatch_deg_s", "yaw-rate mism. (°/s)"),
    ("virtual_jerk_m_s3", "jerk (m/s³)"),
    ("steering_error_deg", "steering err (°)"),
    ("hand_tracking_availability", "hand avail."),
    ("boundary_violations", "boundary viol."),
)
_WIP_COMPACT = (
    "heading_error_rmse_deg",
    "stop_latency_s",
    "false_motion_m_per_min",
    "phantom_steps_per_min",
    "yaw_drift_deg_per_min",
    "virtual_jerk_m_s3",
)


def terminal_console(width: int | None = None) -> Any:
    """A rich console ``width`` columns wide; None: the terminal's width, or, when the output is
    a pipe or a file, ``COLUMNS`` where it is set and else 200 (the full tables)."""
    from rich.console import Console

    if width is not None:
        return Console(width=width)
    console = Console()
    if console.is_terminal:
        return console
    columns = os.environ.get("COLUMNS", "")
    return Console(width=int(columns) if columns.isdigit() and int(columns) > 0 else 200)


def _users(rows: list[dict[str, Any]]) -> tuple[dict[str, str], str | None]:
    """Each row's policy as the ``users`` column shows it, and the policy the rows share (None
    where they differ): rows of one policy show only its population (``typical``; ``–`` for
    none), so that a narrow table keeps who the users were."""
    bases = {r["policy"].partition("+")[0] for r in rows}
    if len(bases) != 1:
        return {r["policy"]: r["policy"] for r in rows}, None
    return {r["policy"]: r["policy"].partition("+")[2] or "–" for r in rows}, bases.pop()


def show_table(
    rows: list[dict[str, Any]],
    seed: int,
    width: int | None = None,
    baseline: str = BASELINE_TECHNIQUE,
) -> None:
    """The rows as two tables fitted to the terminal (``width``: its columns; None: the
    terminal's, or ``COLUMNS`` when piped, see :func:`terminal_console`).

    A value that differs from ``baseline``'s in the same task, policy and condition at p <
    :data:`ALPHA` (the row's ``vs_baseline``) is marked ``*``. The condition gets a column where
    some row is not in the default one. Narrower than :data:`_FULL_WIDTH` columns, the tables
    keep the names (task, users, technique, condition) and as many of the compact measures as
    fit without wrapping a value; the columns left out are named (every column is in the CSV,
    the JSON and the report).
    """
    console = terminal_console(width)
    compact = console.width < _FULL_WIDTH
    users, policy = _users(rows)
    names = [
        ("task", "task"),
        ("policy", "users" if compact else "policy"),
        ("technique", "technique"),
    ]
    if any(r.get("condition", DEFAULT_CONDITION) != DEFAULT_CONDITION for r in rows):
        names.append(("condition", "condition"))
    if compact:
        outcome = [(k, _COMPACT_HEADS.get(k, h)) for k, h in _COLUMNS if k in _COMPACT]
        wip = [(k, _COMPACT_HEADS.get(k, h)) for k, h in _WIP_COLUMNS if k in _WIP_COMPACT]
    else:
        outcome = [c for c in _COLUMNS if c[0] not in _NAME_KEYS]
        wip = [c for c in _WIP_COLUMNS if c[0] not in _NAME_KEYS]
        names.insert(3, ("sensors", "sensors"))
    shown = {**{r["policy"]: r["policy"] for r in rows}, **(users if compact else {})}
    seeds = f"seeds {seed}..{seed + rows[0]['episodes'] - 1}"
    left_out: list[str] = []
    marked = False
    for title, measures in (
        (f"vrloco benchmark: outcomes ({seeds})", outcome),
        (f"walking in place ({seeds})", wip),
    ):
        m, dropped = _print_table(console, rows, names, measures, title, compact, shown)
        marked |= m
        left_out += dropped
    if compact and policy is not None:
        console.print(f"users: {policy} with the population shown")
    if compact:
        console.print(
            "; ".join(
                f"{h}: {_LEGEND[k]}"
                for k, h in (*outcome, *wip)
                if k in _LEGEND and h not in left_out
            )
        )
    else:
        console.print(
            "collision causes: " + "/".join(c.replace("_", " ") for c in COLLISION_CAUSES)
        )
    if marked:
        console.print(
            f"* differs from {baseline} (same task, policy, condition and seeds) at "
            f"p < {ALPHA}: exact McNemar test for rates, Wilcoxon signed-rank for means "
            "(agents.benchmark.paired)"
        )
    if compact or left_out:
        view = "a compact view" if compact else "a view"
        more = f"; not shown at this width: {', '.join(left_out)}" if left_out else ""
        console.print(
            f"({view} for {console.width} columns{more}: every column is in "
            "benchmark.csv, benchmark.json and report.html)"
        )


def _print_table(
    console: Any,
    rows: list[dict[str, Any]],
    names: list,
    measures: list,
    title: str,
    compact: bool,
    shown: dict[str, str],
) -> tuple[bool, list[str]]:
    """Print one table of ``rows``: the ``names`` columns, then as many of ``measures`` as fit
    the console without wrapping a value (dropped from the right). True where some shown value
    is marked as differing, and the headings of the measures left out."""
    from rich import box
    from rich.measure import Measurement
    from rich.table import Table

    def cell(r: dict[str, Any], k: str) -> tuple[str, bool]:
        if k == "policy":
            return shown[r[k]], False
        text = _fmt(r[k], 1 if k in ("time_to_goal_s",) else 3)
        test = (r.get("vs_baseline") or {}).get(k)
        star = test is not None and test["p"] is not None and test["p"] < ALPHA
        return text + ("*" if star else ""), star

    keep = list(measures)
    while True:
        table = Table(
            title=title,
            pad_edge=False,
            padding=(0, 1),
            collapse_padding=compact,
            box=box.SIMPLE_HEAD if compact else box.HEAVY_HEAD,
        )
        for key, head in (*names, *keep):
            left = key in _NAME_KEYS
            table.add_column(head, justify="left" if left else "right", no_wrap=True)
        marked = False
        for r in rows:
            cells = [cell(r, k) for k, _ in (*names, *keep)]
            marked |= any(star for _, star in cells)
            table.add_row(*(text for text, _ in cells))
        natural = Measurement.get(console, console.options.update_width(10_000), table).maximum
        fits = natural <= console.width
        if fits or not keep:
            break
        keep.pop()
    console.print(table)
    return marked, [head for k, head in measures if (k, head) not in keep]


def written_summary(paths: list[Path]) -> list[str]:
    """One line per kind of written file: the per-cell figures (``trajectory_<cell>.png``) as
    one kind with their count, every other file by its name, grouped by folder."""
    kinds: dict[tuple[Path, str], list[Path]] = {}
    for p in map(Path, paths):
        head, sep, _ = p.stem.partition("_")
        kind = f"{head}_*{p.suffix}" if sep else p.name
        kinds.setdefault((p.parent, kind), []).append(p)
    lines = []
    for (folder, kind), found in kinds.items():
        what = found[0].name if len(found) == 1 else f"{len(found)} {kind}"
        lines.append(f"wrote {what} in {folder}")
    return lines


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


class WriteError(RuntimeError):
    """An output file could not be written (a full disk, no permission): ``path`` the file,
    ``reason`` the system's word for why."""

    def __init__(self, path: Path | str, reason: OSError | str) -> None:
        self.path = Path(path)
        self.reason = (reason.strerror or str(reason)) if isinstance(reason, OSError) else reason
        super().__init__(f"cannot write {self.path}: {self.reason}")


@contextlib.contextmanager
def atomic_path(path: Path | str) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to, renamed onto ``path`` when the ``with``
    block ends without an error and removed otherwise, so that ``path`` is never left
    half-written; an OSError (a full disk) becomes a :class:`WriteError` naming ``path``."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        yield tmp
        os.replace(tmp, path)
    except OSError as err:
        raise WriteError(path, err) from None
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)


def write_json(path: Path, rows: list[dict[str, Any]], meta: dict[str, Any]) -> Path:
    """The rows (NaN as null) and the run's ``meta`` as ``{"rows": [...], "config": meta}``,
    written atomically (:func:`atomic_path`)."""
    data = {"rows": [{k: json_safe(v) for k, v in r.items()} for r in rows], "config": meta}
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data, indent=2) + os.linesep)
    return path


def write_csv(path: Path, rows: list[dict[str, Any]]) -> Path:
    """One column per metric; an interval ``<key>_ci`` as ``<key>_ci_low`` and ``_ci_high``, the
    collision causes as ``collision_causes_<cause>``, the paired test against the baseline as
    ``p_vs_baseline_<metric>`` (its p-value). Written atomically (:func:`atomic_path`)."""

    def columns_of(k: str) -> tuple[str, ...]:
        if k.endswith("_ci"):
            return f"{k}_low", f"{k}_high"
        if k == "collision_causes":
            return tuple(f"{k}_{cause}" for cause in COLLISION_CAUSES)
        if k == "vs_baseline":
            return tuple(f"p_vs_baseline_{m}" for m in (*BINARY_METRICS, *MEAN_METRICS))
        return (k,)

    columns = [c for k in ROW_KEYS for c in columns_of(k)]
    with atomic_path(path) as tmp, tmp.open("w", newline="") as f:
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

"""The benchmark's report: one run in one self-contained HTML page, ``report.html``.

:func:`write_report` writes a page that opens with no network (its style and script inline, the
figures as base64 PNG, the rooms as inline SVG):

* the run's configuration: its grids, seeds, episodes per cell, workers, batch size, baseline;
* the outcome and walking-in-place tables, one row per cell and a column per measure of
  :data:`~agents.benchmark.outputs.ROW_KEYS` (:data:`OUTCOME_COLUMNS`, :data:`WIP_COLUMNS`),
  sorted by a click on a heading; a value that differs from the baseline technique's at
  p < :data:`~agents.benchmark.paired.ALPHA` (the row's ``vs_baseline``) is marked ``*`` as on the
  terminal, and a value's tooltip gives its 95 % interval and its paired test;
* the discriminating-power table (:mod:`agents.benchmark.discrimination`);
* the figures the run wrote (:mod:`agents.benchmark.figures`);
* per cell, the replays of its episodes that keep a trace (the first :data:`REPLAY_EPISODES`,
  :func:`agents.benchmark.run._split_jobs`): the true path (perfect sensing) and the virtual body's
  over the room, walls and obstacles from the episode's layout, animated with a play/pause
  button and a time slider, each collision marked in the colour of its cause
  (:func:`collision_events`, the rule of :mod:`agents.benchmark.collision_causes`).

Size: the figures are re-encoded as PNGs of :data:`PNG_COLOURS` colours, and a replay keeps at
most :data:`MAX_FRAMES` frames (positions in centimetres, times in centiseconds), so that the
default run's 20 cells give a page of a few megabytes.
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.benchmark.collision_causes import COLLISION_CAUSES, collision_causes
from agents.benchmark.figures import cell_name
from agents.benchmark.outputs import BASELINE_TECHNIQUE, atomic_path, json_safe
from agents.benchmark.paired import ALPHA

if TYPE_CHECKING:
    from agents.benchmark.grid import Cell
    from agents.benchmark.metrics import EpisodeStats

__all__ = [
    "MAX_FRAMES",
    "OUTCOME_COLUMNS",
    "REPLAY_EPISODES",
    "WIP_COLUMNS",
    "collision_events",
    "replay_data",
    "report_html",
    "write_report",
]

#: The first episodes of each cell that keep their trace when the run has an output folder,
#: each replayed in the report (the figures draw the first).
REPLAY_EPISODES = 3
#: The most frames a replay keeps (a longer episode is sampled at every k-th control step, its
#: last step always kept; collisions keep their own times and places).
MAX_FRAMES = 300
#: Colours of the re-encoded figures (a palette PNG: about a quarter of matplotlib's size).
PNG_COLOURS = 64

#: The columns that name a row: (row key, heading).
NAME_COLUMNS = (
    ("task", "task"),
    ("policy", "policy"),
    ("technique", "technique"),
    ("condition", "condition"),
    ("sensors", "sensors"),
)
#: The outcome table's measures: (row key, heading, decimals, meaning).
OUTCOME_COLUMNS = (
    ("episodes", "n", 0, "episodes in the cell"),
    ("success_rate", "success", 3, "success rate"),
    ("collision_rate", "collision", 3, "share of episodes with a collision"),
    (
        "collision_free_success_rate",
        "coll.-free succ.",
        3,
        "share of episodes that succeed with no collision",
    ),
    ("spl", "SPL", 3, "success weighted by path length (Anderson et al. 2018)"),
    ("time_to_goal_s", "time to goal (s)", 1, "mean time of the successful episodes (s)"),
    ("path_length_ratio", "path ratio", 3, "walked / shortest path, successful episodes"),
    ("step_precision", "step prec.", 3, "detected steps matched to a true heel strike"),
    ("step_recall", "step recall", 3, "true heel strikes matched to a detected step"),
    ("step_f1", "step F1", 3, "F1 of the step matching (+-0.2 s)"),
    ("attitude_rmse_deg", "attitude RMSE (°)", 3, "head attitude error, RMS (deg)"),
    ("hand_error_deg", "hand err (°)", 3, "mean hand orientation error (deg)"),
    ("hand_coverage", "hand cov.", 3, "share of control steps with a hand estimate"),
    ("mean_collisions", "collisions/ep.", 3, "collisions per episode"),
    (
        "collision_causes",
        "collision causes",
        None,
        "collisions by cause: " + "/".join(c.replace("_", " ") for c in COLLISION_CAUSES),
    ),
)
#: The walking-in-place table's measures: (row key, heading, decimals, meaning).
WIP_COLUMNS = (
    ("heading_error_rmse_deg", "heading err (°)", 3, "virtual minus true head yaw, RMS (deg)"),
    ("start_latency_s", "start lat. (s)", 3, "first true heel strike to the body moving (s)"),
    ("stop_latency_s", "stop lat. (s)", 3, "last true heel strike to the body stopping (s)"),
    ("stop_overshoot_m", "overshoot (m)", 3, "distance moved after the user stopped (m)"),
    ("false_motion_m_per_min", "false motion (m/min)", 3, "virtual metres per minute standing"),
    ("phantom_steps_per_min", "phantom /min", 3, "detected steps with no true heel strike"),
    ("missed_steps_per_min", "missed /min", 3, "true heel strikes never detected"),
    ("yaw_drift_deg_per_min", "yaw drift (°/min)", 3, "virtual yaw drift standing still"),
    (
        "yaw_rate_mismatch_deg_s",
        "yaw-rate mism. (°/s)",
        3,
        "virtual minus true head yaw rate, RMS (deg/s)",
    ),
    ("virtual_jerk_m_s3", "jerk (m/s³)", 3, "virtual body jerk (m/s^3)"),
    (
        "steering_error_deg",
        "steering err (°)",
        3,
        "walking direction minus true torso direction, RMS (deg)",
    ),
    ("hand_tracking_availability", "hand avail.", 3, "share of steps with hand tracking"),
    (
        "boundary_violations",
        "boundary viol.",
        3,
        "times per episode the user left the 2 x 2 m play area",
    ),
    ("min_boundary_m", "min boundary (m)", 3, "closest approach to the play area's edge (m)"),
)
#: Each collision cause's colour (as in ``collision_causes.png``).
CAUSE_COLOURS = {
    "phantom_step": "#d62728",
    "stop_latency": "#ff7f0e",
    "heading_error": "#9467bd",
    "steering": "#2ca02c",
    "policy": "#999999",
}
#: The trace keys :func:`collision_events` reads.
_CAUSE_KEYS = (
    "elapsed_time",
    "intent_walk",
    "heading_error_deg",
    "true_step_times",
    "detected_step_times",
    "walk_yaw_deg",
    "true_body_yaw_deg",
)


def write_report(
    path: Path | str,
    rows: list[dict[str, Any]],
    meta: dict[str, Any],
    pairs: list[dict[str, Any]],
    cells: Sequence[Cell],
    results: dict[tuple[Cell, int], EpisodeStats],
    figures: Sequence[Path | str],
    baseline: str = BASELINE_TECHNIQUE,
) -> Path:
    """Write :func:`report_html` to ``path`` atomically
    (:func:`agents.benchmark.outputs.atomic_path`: a full disk is a WriteError naming it).

    Returns:
        ``path``.
    """
    path = Path(path)
    text = report_html(rows, meta, pairs, cells, results, figures, baseline)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


def report_html(
    rows: list[dict[str, Any]],
    meta: dict[str, Any],
    pairs: list[dict[str, Any]],
    cells: Sequence[Cell],
    results: dict[tuple[Cell, int], EpisodeStats],
    figures: Sequence[Path | str],
    baseline: str = BASELINE_TECHNIQUE,
) -> str:
    """The report of a run as one HTML page (see the module docstring).

    Args:
        rows: the benchmark rows (:data:`~agents.benchmark.outputs.ROW_KEYS`).
        meta: the run's configuration (``seed``, ``episodes``, ``workers``, ``batch_size``,
            ``grids``), as in ``benchmark.json``.
        pairs: :func:`agents.benchmark.discrimination.pair_results` of the rows.
        cells: the rows' cells, in the rows' order.
        results: ``(cell, episode index)`` -> the episode's stats; those with a trace are
            replayed.
        figures: the run's files; its PNGs are embedded (``<kind>_<cell label>.png`` with their
            cell, the others with the run).
        baseline: the technique the rows are compared with.
    """
    if len(cells) != len(rows):
        raise ValueError(f"cells must hold one cell per row ({len(rows)}), got {len(cells)}")
    pngs = [Path(f) for f in figures if Path(f).suffix == ".png"]
    per_cell: list[list[Path]] = []
    for c in cells:
        names = {f"{kind}_{c.label}.png" for kind in ("trajectory", "attitude", "gait")}
        per_cell.append([p for p in pngs if p.name in names])
    of_cells = {p for found in per_cell for p in found}
    run_figures = [p for p in pngs if p not in of_cells]

    replays: dict[str, dict] = {}
    sections = []
    for k, (c, row) in enumerate(zip(cells, rows, strict=True)):
        blocks = []
        for i in range(meta["episodes"]):
            st = results.get((c, i))
            if st is None or st.trace is None:
                continue
            key = f"c{k}e{i}"
            replays[key] = replay_data(st)
            blocks.append(_replay_block(key, st))
        sections.append(_cell_section(k, row, blocks, per_cell[k]))

    seeds = f"{meta['seed']}..{meta['seed'] + meta['episodes'] - 1}"
    body = [
        "<header><h1>vrloco benchmark report</h1>",
        f"<p>{len(rows)} cell{'s' if len(rows) != 1 else ''}, {meta['episodes']} episode"
        f"{'s' if meta['episodes'] != 1 else ''} each (seeds {seeds}); baseline "
        f"<code>{_e(baseline)}</code></p>",
        '<nav><a href="#config">configuration</a> · <a href="#outcomes">outcomes</a> · '
        '<a href="#wip">walking in place</a> · <a href="#pairs">discriminating power</a> · '
        '<a href="#figures">figures</a> · <a href="#replays">replays</a></nav></header>',
        _config_section(meta, baseline, len(rows)),
        _table_section("outcomes", f"Outcomes (seeds {seeds})", rows, OUTCOME_COLUMNS, baseline),
        _table_section("wip", f"Walking in place (seeds {seeds})", rows, WIP_COLUMNS, baseline),
        _pairs_section(pairs, baseline),
        _figures_section(run_figures),
        '<section id="replays"><h2>Replays</h2>',
        _replay_legend(),
        *sections,
        "</section>",
    ]
    data = json.dumps(replays, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    return "\n".join(
        [
            "<!DOCTYPE html>",
            '<html lang="en"><head><meta charset="utf-8">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            "<title>vrloco benchmark report</title>",
            f"<style>{_CSS}</style></head><body>",
            *body,
            f'<script id="replay-data" type="application/json">{data}</script>',
            f"<script>{_JS}</script>",
            "</body></html>",
            "",
        ]
    )


# --------------------------------------------------------------------------- replays


def collision_events(trace: dict[str, Any]) -> list[tuple[int, str]]:
    """Each collision of a traced episode: ``(control step index, cause)``, the cause by the rule
    of :func:`agents.benchmark.collision_causes.collision_causes` (the episode's causes counted are
    these causes counted)."""
    hit = np.asarray(trace["collision"], dtype=bool).ravel()
    steps = {k: trace[k] for k in _CAUSE_KEYS}
    events = []
    for k in np.flatnonzero(hit):
        one = np.zeros(hit.size, dtype=bool)
        one[k] = True
        counts = collision_causes({**steps, "collision": one})
        events.append((int(k), next(c for c in COLLISION_CAUSES if counts[c])))
    return events


def replay_data(stats: EpisodeStats) -> dict[str, Any]:
    """What a replay of a traced episode needs, as JSON-ready numbers: frame times ``t``
    (centiseconds), the virtual body's and the true positions ``v`` and ``r`` (flat x, y pairs,
    centimetres) and headings ``vy`` and ``ry`` (degrees, counter-clockwise from +x; the true
    one is the virtual minus the heading error), at most :data:`MAX_FRAMES` frames from the
    start; ``c``, each collision as ``[time, x, y, cause index]`` (the cause's index in
    :data:`~agents.benchmark.collision_causes.COLLISION_CAUSES`)."""
    tr = stats.trace
    if tr is None:
        raise ValueError("stats has no trace: run the episode with trace=True")
    pos = np.asarray(tr["position"], dtype=np.float64)
    true = np.asarray(tr["true_position"], dtype=np.float64)
    t = np.asarray(tr["elapsed_time"], dtype=np.float64)
    yaw = np.rad2deg(np.asarray(tr["virtual_yaw"], dtype=np.float64))
    true_yaw = yaw - np.asarray(tr["heading_error_deg"], dtype=np.float64)
    lead = len(pos) - len(t)  # 1 where the start is prepended to the paths
    if lead not in (0, 1) or len(true) != len(pos):
        raise ValueError(f"trace of {len(t)} steps with {len(pos)} and {len(true)} positions")
    if lead:
        t = np.concatenate([[0.0], t])
        yaw, true_yaw = (np.concatenate([a[:1], a]) for a in (yaw, true_yaw))
    n = len(pos)
    stride = max(1, math.ceil(n / (MAX_FRAMES - 1)))
    idx = np.unique(np.concatenate([np.arange(0, n, stride), [n - 1]]))

    def cm(a: np.ndarray) -> list[int]:
        return np.rint(a * 100.0).astype(np.int64).ravel().tolist()

    hits = [
        [round(float(t[k + lead]) * 100), *cm(pos[k + lead]), COLLISION_CAUSES.index(cause)]
        for k, cause in collision_events(tr)
    ]
    return {
        "t": cm(t[idx]),
        "v": cm(pos[idx]),
        "r": cm(true[idx]),
        "vy": np.rint(yaw[idx]).astype(np.int64).tolist(),
        "ry": np.rint(true_yaw[idx]).astype(np.int64).tolist(),
        "c": hits,
    }


def _room_svg(layout: Any, paths: Sequence[np.ndarray] = ()) -> tuple[str, str]:
    """A layout's ``viewBox`` (y up: the SVG's y is minus the room's), widened to hold ``paths``
    ((N, 2) points, m), and its walls, obstacles, target and goal as SVG elements (metres)."""
    from vrloco_env.world import Box

    parts = []
    solids = [("wall", s) for s in layout.walls] + [("obstacle", s) for s in layout.obstacles]
    if layout.target is not None:
        solids.append(("target", layout.target))
    for kind, s in solids:
        if isinstance(s, Box):
            c, sn = math.cos(s.yaw), math.sin(s.yaw)
            hx, hy = s.half_extents
            corners = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
            pts = corners @ np.array([[c, sn], [-sn, c]]) + np.asarray(s.center)
            points = " ".join(f"{x:.3f},{-y:.3f}" for x, y in pts)
            parts.append(f'<polygon class="{kind}" points="{points}"/>')
        else:
            parts.append(
                f'<circle class="{kind}" cx="{s.center[0]:.3f}" '
                f'cy="{-s.center[1]:.3f}" r="{s.radius:.3f}"/>'
            )
    if layout.goal_line is not None:
        (x0, y0), (x1, y1) = layout.goal_line
        parts.append(
            f'<line class="goal" x1="{x0:.3f}" y1="{-y0:.3f}" x2="{x1:.3f}" '
            f'y2="{-y1:.3f}"><title>end line</title></line>'
        )
    else:
        parts.append(
            f'<circle class="goal" cx="{layout.goal[0]:.3f}" cy="{-layout.goal[1]:.3f}" '
            f'r="{layout.goal_radius:.3f}"><title>goal</title></circle>'
        )
    wall = 2.0 * min(min(w.half_extents) for w in layout.walls) if layout.walls else 0.2
    m = 1.5 * wall
    xmin, xmax, ymin, ymax = layout.bounds
    xmin, ymin, xmax, ymax = xmin - m, ymin - m, xmax + m, ymax + m
    for a in paths:  # a true path is never blocked: it may leave the room
        a = np.asarray(a, dtype=np.float64)
        a = a[np.isfinite(a).all(axis=1)]
        if a.size:
            xmin, ymin = np.minimum([xmin, ymin], a.min(axis=0) - 0.2)
            xmax, ymax = np.maximum([xmax, ymax], a.max(axis=0) + 0.2)
    box = f"{xmin:.3f} {-ymax:.3f} {xmax - xmin:.3f} {ymax - ymin:.3f}"
    return box, "".join(parts)


def _replay_block(key: str, st: EpisodeStats) -> str:
    """One episode's replay: its summary, the room (the script draws the paths) and controls."""
    box, room = _room_svg(st.trace["layout"], (st.trace["position"], st.trace["true_position"]))
    outcome = "success" if st.success else "failure"
    n = st.collisions
    return (
        f'<figure class="replay" data-key="{key}"><figcaption>seed {st.seed} · {outcome} · '
        f"{n} collision{'s' if n != 1 else ''} · {st.elapsed_s:.1f} s</figcaption>"
        f'<svg class="room" viewBox="{box}" preserveAspectRatio="xMidYMid meet" role="img">'
        f'<g class="static">{room}</g><g class="dyn"></g></svg>'
        '<div class="ctl"><button type="button" class="play">play</button>'
        '<input type="range" class="slider" min="0" max="0" value="0" step="1" '
        'aria-label="time">'
        '<select class="speed" aria-label="speed"><option value="1">1x</option>'
        '<option value="2" selected>2x</option><option value="4">4x</option></select>'
        '<span class="time"></span></div></figure>'
    )


def _replay_legend() -> str:
    causes = "".join(
        f'<span class="sw" style="background:{CAUSE_COLOURS[c]}"></span>{_e(c.replace("_", " "))} '
        for c in COLLISION_CAUSES
    )
    return (
        '<p class="legend"><span class="ln true"></span>true path (perfect sensing) '
        '<span class="ln virt"></span>virtual body (estimated); the dots with a line: where '
        "each is and faces; collisions by cause: " + causes + "(the rule of "
        "<code>agents.benchmark.collision_causes</code>). Walls and obstacles grey, the goal "
        "green.</p>"
    )


def _cell_section(k: int, row: dict[str, Any], blocks: list[str], figures: list[Path]) -> str:
    name = cell_name(row)
    causes = row.get("collision_causes")
    summary = (
        f"all {row['episodes']} episodes: success {_fmt(row['success_rate'], 3)}, "
        f"collision {_fmt(row['collision_rate'], 3)}, SPL {_fmt(row['spl'], 3)}"
    )
    if causes is not None and any(causes.values()):
        summary += ", collisions by cause: " + ", ".join(
            f"{c.replace('_', ' ')} {n}" for c, n in causes.items() if n
        )
    out = [
        f'<section class="cell" id="cell-{k}"><h3>{_e(name)}</h3>',
        f'<p class="summary">{_e(summary)}</p>',
    ]
    if blocks:
        out.append('<div class="replays">' + "".join(blocks) + "</div>")
    else:
        out.append("<p>No episode of this cell kept its trace.</p>")
    if figures:
        imgs = "".join(_img(p) for p in figures)
        out.append(
            f"<details><summary>figures of episode 0 ({len(figures)})</summary>{imgs}</details>"
        )
    out.append("</section>")
    return "".join(out)


# --------------------------------------------------------------------------- tables


def _e(text: Any) -> str:
    return html.escape(str(text), quote=True)


def _fmt(v: Any, digits: int | None) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    if isinstance(v, dict):
        return "/".join(str(v[c]) for c in COLLISION_CAUSES)
    if isinstance(v, float) and digits is not None:
        return f"{v:.{digits}f}"
    return str(v)


def _num(v: Any) -> str:
    """A value's sort key for the script: a number, or empty for none."""
    if isinstance(v, dict):
        return str(sum(v.values()))
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        return ""
    return repr(float(v))


def _config_section(meta: dict[str, Any], baseline: str, n_cells: int) -> str:
    seed, episodes = meta["seed"], meta["episodes"]
    items = [
        ("episodes per cell", episodes),
        ("seeds", f"{seed}..{seed + episodes - 1} (episode i is seeded {seed} + i)"),
        ("cells", n_cells),
        ("baseline", baseline),
        ("workers", meta.get("workers", "–")),
        ("batch size", meta.get("batch_size", "–")),
        ("replayed", f"the first {REPLAY_EPISODES} episodes of each cell"),
    ]
    dl = "".join(f"<dt>{_e(k)}</dt><dd>{_e(v)}</dd>" for k, v in items)
    grids = "".join(
        f"<tr><td>{g}</td>"
        + "".join(
            f"<td>{_e(', '.join(map(str, grid.get(axis, ()))))}</td>"
            for axis in ("tasks", "policies", "techniques", "conditions")
        )
        + "</tr>"
        for g, grid in enumerate(meta.get("grids", []), 1)
    )
    return (
        f'<section id="config"><h2>Configuration</h2><dl>{dl}</dl>'
        '<table class="grids"><thead><tr><th>grid</th><th>tasks</th><th>policies</th>'
        f"<th>techniques</th><th>conditions</th></tr></thead><tbody>{grids}</tbody></table>"
        "</section>"
    )


def _tooltip(row: dict[str, Any], key: str, baseline: str) -> str:
    parts = []
    ci = row.get(f"{key}_ci")
    if ci is not None:
        lo, hi = json_safe(ci)
        if lo is not None and hi is not None:
            parts.append(f"95 % interval {lo:.4g} to {hi:.4g}")
    test = (row.get("vs_baseline") or {}).get(key)
    if test is not None and test.get("p") is not None:
        diff = test.get("diff")
        d = "" if diff is None or not math.isfinite(diff) else f"difference {diff:+.4g}, "
        parts.append(f"vs {baseline}: {d}p = {test['p']:.3g} (n = {test.get('n')})")
    if key == "collision_causes" and isinstance(row.get(key), dict):
        parts.append(", ".join(f"{c.replace('_', ' ')} {n}" for c, n in row[key].items()))
    return "; ".join(parts)


def _table_section(
    sid: str, title: str, rows: list[dict[str, Any]], columns: tuple, baseline: str
) -> str:
    head = "".join(f'<th class="name">{_e(h)}</th>' for _, h in NAME_COLUMNS) + "".join(
        f'<th class="num" title="{_e(meaning)}">{_e(h)}</th>' for _, h, _, meaning in columns
    )
    body = []
    marked = False
    for k, r in enumerate(rows):
        cells = []
        for key, _ in NAME_COLUMNS:
            text = _e(r.get(key, "–"))
            if key == "technique":
                text = f'<a href="#cell-{k}">{text}</a>'
            cells.append(f'<td class="name">{text}</td>')
        for key, _, digits, _ in columns:
            v = r.get(key)
            test = (r.get("vs_baseline") or {}).get(key)
            star = test is not None and test.get("p") is not None and test["p"] < ALPHA
            marked |= star
            tip = _tooltip(r, key, baseline)
            hover = f' title="{_e(tip)}"' if tip else ""
            cls = "num star" if star else "num"
            cells.append(
                f'<td class="{cls}" data-v="{_num(v)}"{hover}>{_e(_fmt(v, digits))}'
                f"{'*' if star else ''}</td>"
            )
        body.append(f'<tr data-cell="{k}">' + "".join(cells) + "</tr>")
    legend = [
        f"* differs from {baseline} (same task, policy, condition and seeds) at p < "
        f"{ALPHA}: exact McNemar test for rates, Wilcoxon signed-rank for means "
        "(agents.benchmark.paired)" + ("" if marked else "; no value here does")
    ]
    if any(key == "collision_causes" for key, *_ in columns):
        legend.append(
            "collision causes: " + "/".join(c.replace("_", " ") for c in COLLISION_CAUSES)
        )
    legend.append(
        "click a heading to sort; hover a value for its 95 % interval and its test "
        "against the baseline, a heading for its meaning"
    )
    notes = "".join(f'<p class="note">{_e(x)}</p>' for x in legend)
    return (
        f'<section id="{sid}"><h2>{_e(title)}</h2><div class="scroll">'
        f'<table class="sortable data"><thead><tr>{head}</tr></thead><tbody>'
        + "".join(body)
        + f"</tbody></table></div>{notes}</section>"
    )


def _pairs_section(pairs: list[dict[str, Any]], baseline: str) -> str:
    if not pairs:
        return (
            '<section id="pairs"><h2>Discriminating power</h2><p>No technique pair of '
            "<code>agents.benchmark.discrimination</code> has its cells in this "
            "run.</p></section>"
        )
    rows = []
    for res in pairs:
        against = [
            f"{task}:{m}"
            for task, per in res["tasks"].items()
            for m, v in per.items()
            if v["verdict"] == "against"
        ]
        tip = "; ".join(
            f"{task}:{m} {v['expected']} diff {_fmt(v['diff'], 4)} p {_fmt(v['p'], 4)}"
            for task, per in res["tasks"].items()
            for m, v in per.items()
        )
        rows.append(
            f'<tr><td class="name">{_e(res["pair"])}</td><td>{_e(res["why"])}</td>'
            f'<td data-v="{int(res["separates"])}">{"yes" if res["separates"] else "NO"}</td>'
            f'<td data-v="{int(res["on_outcome"])}">{"yes" if res["on_outcome"] else "no"}</td>'
            f'<td title="{_e(tip)}">{_e(", ".join(res["metrics"]) or "–")}</td>'
            f"<td>{_e(', '.join(against) or '–')}</td></tr>"
        )
    n_sep = sum(r["separates"] for r in pairs)
    n_out = sum(r["on_outcome"] for r in pairs)
    return (
        '<section id="pairs"><h2>Discriminating power</h2>'
        f"<p>Each technique vs {_e(baseline)} (paired, p &lt; {ALPHA}, expected direction)"
        '</p><div class="scroll"><table class="sortable data"><thead><tr>'
        "<th>technique (users, room)</th><th>why</th><th>separates</th><th>on outcome</th>"
        "<th>differs on</th><th>against expectation</th></tr></thead><tbody>"
        + "".join(rows)
        + "</tbody></table></div>"
        f'<p class="note">{n_sep} of {len(pairs)} pairs separate, {n_out} on an outcome '
        "(success, collisions, SPL or time to goal)</p></section>"
    )


def _figures_section(figures: list[Path]) -> str:
    if not figures:
        return '<section id="figures"><h2>Figures</h2><p>No figure.</p></section>'
    return (
        '<section id="figures"><h2>Figures</h2>' + "".join(_img(p) for p in figures) + "</section>"
    )


def _img(path: Path) -> str:
    """A PNG as an ``<img>`` with its data inline (:data:`PNG_COLOURS` colours)."""
    from PIL import Image

    with Image.open(path) as im:
        small = im.convert("RGB").quantize(
            PNG_COLOURS, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE
        )
    buf = io.BytesIO()
    small.save(buf, format="PNG")
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return (
        f'<figure class="fig"><img alt="{_e(path.name)}" src="data:image/png;base64,{data}">'
        f"<figcaption>{_e(path.name)}</figcaption></figure>"
    )


# --------------------------------------------------------------------------- style, script

_CSS = """
body{font:14px/1.4 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0 1.5em 3em;
color:#222;background:#fff}
header{border-bottom:1px solid #ccc;margin-bottom:1em}
h1{font-size:1.6em;margin:.6em 0 .2em}h2{font-size:1.3em;margin:1.4em 0 .4em;
border-bottom:1px solid #eee}h3{font-size:1.05em;margin:1.2em 0 .2em}
nav a{color:#1f5fa8}code{font-size:.95em}
dl{display:grid;grid-template-columns:max-content auto;gap:.1em 1em;margin:.4em 0}
dt{color:#555}dd{margin:0}
.scroll{overflow-x:auto;max-width:100%}
table{border-collapse:collapse;font-size:12.5px;margin:.3em 0}
th,td{padding:2px 6px;border-bottom:1px solid #e4e4e4;white-space:nowrap}
th.num{white-space:normal;min-width:3.5em;max-width:6.5em}
thead th{background:#f2f4f7;position:sticky;top:0;text-align:left;vertical-align:bottom}
table.sortable thead th{cursor:pointer;user-select:none}
th.sorted-asc::after{content:" \\25B2";font-size:.8em}
th.sorted-desc::after{content:" \\25BC";font-size:.8em}
td.num,th.num{text-align:right;font-variant-numeric:tabular-nums}
td.star{font-weight:600;color:#a3140e}
tbody tr:nth-child(even){background:#fafbfc}tbody tr:hover{background:#eef4ff}
table.grids td{white-space:normal}
.note{color:#555;font-size:12px;margin:.2em 0}
.fig{display:inline-block;margin:.3em .6em .3em 0;vertical-align:top}
.fig img{max-width:100%;border:1px solid #eee}
.fig figcaption{font-size:11px;color:#666}
.replays{display:flex;flex-wrap:wrap;gap:14px}
.replay{margin:0;width:400px;border:1px solid #ddd;border-radius:4px;padding:6px;background:#fcfcfc}
.replay figcaption{font-size:12px;color:#333;margin-bottom:3px}
.replay svg{width:100%;height:auto;max-height:380px;background:#fff;display:block}
.ctl{display:flex;align-items:center;gap:6px;margin-top:4px;font-size:12px}
.ctl .slider{flex:1}.ctl .time{min-width:7.5em;text-align:right;font-variant-numeric:tabular-nums}
.wall{fill:#8c8c8c}.obstacle{fill:#9a9a9a}.target{fill:#a0785a}
circle.goal{fill:none;stroke:#2ca02c;stroke-width:2;stroke-dasharray:5 3;
vector-effect:non-scaling-stroke}
line.goal{stroke:#2ca02c;stroke-width:2;stroke-dasharray:6 4;vector-effect:non-scaling-stroke}
.full{fill:none;stroke-width:1;vector-effect:non-scaling-stroke;opacity:.35}
.trail{fill:none;vector-effect:non-scaling-stroke;stroke-linejoin:round}
.true-path{stroke:#333}.virt-path{stroke:#d62728}
.trail.true-path{stroke-width:3.5;opacity:.45}.trail.virt-path{stroke-width:1.6}
.face{stroke-width:2;vector-effect:non-scaling-stroke}
.hit{stroke:#000;stroke-width:.8;vector-effect:non-scaling-stroke}
.hit.later{opacity:.22}
.legend .sw{display:inline-block;width:.8em;height:.8em;border-radius:50%;margin:0 .2em 0 .5em;
border:1px solid #000;vertical-align:-1px}
.legend .ln{display:inline-block;width:1.6em;height:0;margin:0 .3em 0 .6em;vertical-align:middle}
.ln.true{border-top:3px solid rgba(51,51,51,.55)}.ln.virt{border-top:2px solid #d62728}
details summary{cursor:pointer;color:#1f5fa8;margin:.4em 0}
"""

_JS = r"""
(function () {
  "use strict";
  var CAUSES = %CAUSES%;
  var COLOURS = %COLOURS%;

  function sortValue(td) {
    var v = td.getAttribute("data-v");
    if (v === null) return td.textContent.trim().toLowerCase();
    return v === "" ? null : parseFloat(v);
  }
  function sortBy(table, col, th) {
    var asc = !th.classList.contains("sorted-asc");
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (h) {
      h.classList.remove("sorted-asc", "sorted-desc");
    });
    th.classList.add(asc ? "sorted-asc" : "sorted-desc");
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = sortValue(a.cells[col]), y = sortValue(b.cells[col]);
      if (x === null && y === null) return 0;
      if (x === null) return 1;  /* no value: last either way */
      if (y === null) return -1;
      var d = typeof x === "number" && typeof y === "number" ? x - y
        : String(x).localeCompare(String(y));
      return asc ? d : -d;
    });
    rows.forEach(function (r) { body.appendChild(r); });
  }
  Array.prototype.forEach.call(document.querySelectorAll("table.sortable"), function (table) {
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th, col) {
      th.addEventListener("click", function () { sortBy(table, col, th); });
    });
  });

  function el(name, attrs, parent) {  /* an SVG element, in the namespace of the page's own */
    var e = document.createElementNS(parent.namespaceURI, name);
    for (var k in attrs) e.setAttribute(k, attrs[k]);
    parent.appendChild(e);
    return e;
  }
  function pts(flat, n) {  /* the first n points, "x,-y ..." in metres */
    var out = [];
    for (var i = 0; i < n; i++) out.push(flat[2 * i] / 100 + "," + (-flat[2 * i + 1] / 100));
    return out.join(" ");
  }

  function Replay(fig, d) {
    var svg = fig.querySelector("svg"), dyn = fig.querySelector(".dyn");
    var slider = fig.querySelector(".slider"), button = fig.querySelector(".play");
    var speed = fig.querySelector(".speed"), label = fig.querySelector(".time");
    var n = d.t.length, end = d.t[n - 1] / 100;
    var vb = svg.viewBox.baseVal, arrow = 0.04 * Math.max(vb.width, vb.height);
    el("polyline", {"class": "full true-path", points: pts(d.r, n)}, dyn);
    el("polyline", {"class": "full virt-path", points: pts(d.v, n)}, dyn);
    var trailTrue = el("polyline", {"class": "trail true-path"}, dyn);
    var trailVirt = el("polyline", {"class": "trail virt-path"}, dyn);
    var hits = d.c.map(function (c) {
      var m = el("circle", {"class": "hit", cx: c[1] / 100, cy: -c[2] / 100,
                            r: 0.012 * Math.max(vb.width, vb.height),
                            fill: COLOURS[c[3]]}, dyn);
      el("title", {}, m).textContent = "collision at " + (c[0] / 100).toFixed(1) + " s: "
        + CAUSES[c[3]].replace(/_/g, " ");
      return {t: c[0] / 100, node: m};
    });
    function marker(size, colour) {
      var g = el("g", {}, dyn);
      return {line: el("line", {"class": "face", stroke: colour}, g),
              dot: el("circle", {r: size * Math.max(vb.width, vb.height), fill: colour}, g)};
    }
    var mv = marker(0.016, "#d62728"), mt = marker(0.011, "#333");  /* the true one on top */
    function place(m, flat, yaw, i) {
      var x = flat[2 * i] / 100, y = -flat[2 * i + 1] / 100, a = yaw[i] * Math.PI / 180;
      m.dot.setAttribute("cx", x); m.dot.setAttribute("cy", y);
      m.line.setAttribute("x1", x); m.line.setAttribute("y1", y);
      m.line.setAttribute("x2", x + arrow * Math.cos(a));
      m.line.setAttribute("y2", y - arrow * Math.sin(a));
    }
    var frame = 0, playing = false, clock = 0, last = 0, timer = null;
    slider.max = String(n - 1);
    function show(i) {
      frame = i;
      slider.value = String(i);
      var now = d.t[i] / 100;
      trailTrue.setAttribute("points", pts(d.r, i + 1));
      trailVirt.setAttribute("points", pts(d.v, i + 1));
      place(mt, d.r, d.ry, i); place(mv, d.v, d.vy, i);
      hits.forEach(function (h) { h.node.classList.toggle("later", h.t > now + 1e-9); });
      label.textContent = "t = " + now.toFixed(1) + " / " + end.toFixed(1) + " s";
    }
    function tick() {  /* 25 times a second: the episode's clock advances by speed x real time */
      if (!playing) return;
      var now = performance.now();
      clock += (now - last) / 1000 * parseFloat(speed.value);
      last = now;
      var i = frame;
      while (i < n - 1 && d.t[i + 1] / 100 <= clock) i++;
      if (i !== frame) show(i);
      if (i >= n - 1) { stop(); return; }
      timer = setTimeout(tick, 40);
    }
    function stop() { playing = false; clearTimeout(timer); button.textContent = "play"; }
    button.addEventListener("click", function () {
      if (playing) { stop(); return; }
      if (frame >= n - 1) show(0);
      playing = true; last = performance.now(); clock = d.t[frame] / 100;
      button.textContent = "pause";
      timer = setTimeout(tick, 40);
    });
    slider.addEventListener("input", function () { stop(); show(parseInt(slider.value, 10)); });
    show(n - 1);  /* the whole episode first; play starts it over */
  }

  var data = JSON.parse(document.getElementById("replay-data").textContent);
  Array.prototype.forEach.call(document.querySelectorAll("figure.replay"), function (fig) {
    Replay(fig, data[fig.getAttribute("data-key")]);
  });
  document.body.setAttribute("data-ready", "1");
})();
""".replace("%CAUSES%", json.dumps(list(COLLISION_CAUSES))).replace(
    "%COLOURS%", json.dumps([CAUSE_COLOURS[c] for c in COLLISION_CAUSES])
)

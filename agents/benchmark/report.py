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

The page's style sheet, script and collision colours are in
:mod:`agents.benchmark.report_assets`, the replays' data and blocks in
:mod:`agents.benchmark.report_replays`; this module assembles the page (its tables, sections and
figures) and re-exports their public names.
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

from agents.benchmark.collision_causes import COLLISION_CAUSES
from agents.benchmark.figures import cell_name
from agents.benchmark.outputs import BASELINE_TECHNIQUE, atomic_path, json_safe
from agents.benchmark.paired import ALPHA
from agents.benchmark.report_assets import _CSS, _JS, CAUSE_COLOURS
from agents.benchmark.report_replays import (
    MAX_FRAMES,
    REPLAY_EPISODES,
    _replay_block,
    collision_events,
    replay_data,
)

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


# --------------------------------------------------------------------------- cells


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

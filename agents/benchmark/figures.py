"""The benchmark's figures: of one episode per cell (the analogues of Zhang 2021's Figs. 2-5: the
true and virtual paths over the room, the head attitude, truth vs estimate, and the gait, true
heel strikes vs detected steps; :func:`draw_cell`) and of the whole grid (the metrics with their
intervals, the collisions by cause, the latency distributions; :func:`draw_grid`), each written
atomically: a file is whole or absent, and a full disk is a
:class:`~agents.benchmark.outputs.WriteError` naming it."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.benchmark.conditions import DEFAULT_CONDITION
from agents.benchmark.metrics import EpisodeStats

if TYPE_CHECKING:
    from agents.benchmark.grid import Cell

__all__ = ["GRID_METRICS", "draw_cell", "draw_grid"]


def _save(fig: Any, path: Path) -> None:
    """Write ``fig`` as a PNG to ``path`` atomically (:func:`agents.benchmark.outputs.atomic_path`:
    a full disk is a WriteError naming ``path``), and close it."""
    import matplotlib.pyplot as plt

    from agents.benchmark.outputs import atomic_path

    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=100, format="png")
    finally:
        plt.close(fig)


def _draw_room(ax: Any, layout: Any) -> None:
    """Walls, obstacles, the Interact pedestal and the goal region of a layout (local frame)."""
    from matplotlib.patches import Circle, Polygon

    from vrloco_env.world import Box

    solids = [*layout.walls, *layout.obstacles]
    if layout.target is not None:
        solids.append(layout.target)
    for s in solids:
        if isinstance(s, Box):
            c, sn = math.cos(s.yaw), math.sin(s.yaw)
            hx, hy = s.half_extents
            corners = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
            pts = corners @ np.array([[c, sn], [-sn, c]]) + np.asarray(s.center)
            ax.add_patch(Polygon(pts, closed=True, color="0.55", lw=0))
        else:
            ax.add_patch(Circle(s.center, s.radius, color="0.55", lw=0))
    if layout.goal_line is not None:
        (x0, y0), (x1, y1) = layout.goal_line
        ax.plot([x0, x1], [y0, y1], "--", color="tab:green", lw=1.5, label="end line")
    else:
        ax.add_patch(
            Circle(
                layout.goal, layout.goal_radius, fill=False, color="tab:green", lw=1.5, label="goal"
            )
        )
    xmin, xmax, ymin, ymax = layout.bounds
    t = 2.0 * min(min(w.half_extents) for w in layout.walls) if layout.walls else 0.2
    ax.set_xlim(xmin - 1.5 * t, xmax + 1.5 * t)
    ax.set_ylim(ymin - 1.5 * t, ymax + 1.5 * t)
    ax.set_aspect("equal", adjustable="box")


def draw_cell(out_dir: Path, cell: Cell, stats: EpisodeStats) -> list[Path]:
    """The three figures of one episode (needs ``stats.trace``): paths over the room
    (Zhang 2021 Figs. 4/5), head attitude truth vs estimate (Fig. 3), gait (Fig. 2).

    Returns:
        The written files.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tr = stats.trace
    if tr is None:
        raise ValueError("stats has no trace: run the episode with trace=True")
    title = f"{cell.task}, {cell.policy}, {cell.technique_name}, seed {stats.seed}"
    outcome = "success" if stats.success else "failure"
    written = []

    fig, ax = plt.subplots(figsize=(7.5, 6.5), constrained_layout=True)
    _draw_room(ax, tr["layout"])
    ax.plot(*tr["true_position"].T, color="0.2", lw=2.5, alpha=0.5, label="true steps and heading")
    ax.plot(
        *tr["position"].T, "o-", color="tab:red", ms=2.5, lw=1.0, label="virtual body (estimated)"
    )
    ax.plot(*tr["position"][0], "s", color="k", ms=6, label="start")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"Paths: {title} ({outcome}, {stats.collisions} collisions)", fontsize=9)
    ax.legend(fontsize=7, loc="best")
    written.append(out_dir / f"trajectory_{cell.label}.png")
    _save(fig, written[-1])

    t = tr["elapsed_time"]
    true = np.rad2deg(np.unwrap(np.deg2rad(tr["true_ypr"]), axis=0))
    est = np.rad2deg(np.unwrap(np.deg2rad(tr["est_ypr"]), axis=0))
    fig, axes = plt.subplots(3, 1, figsize=(9, 6.5), sharex=True, constrained_layout=True)
    for k, (ax, name) in enumerate(zip(axes, ("yaw", "pitch", "roll"), strict=True)):
        ax.plot(t, true[:, k], color="0.6", lw=2.2, label="truth")
        ax.plot(t, est[:, k], color="k", lw=0.8, label="estimate")
        ax.set_ylabel(f"{name} (deg)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("time (s)")
    axes[0].set_title(f"Head attitude: {title}", fontsize=9)
    written.append(out_dir / f"attitude_{cell.label}.png")
    _save(fig, written[-1])

    fig, ax = plt.subplots(figsize=(9, 3.6), constrained_layout=True)
    times = tr["true_step_times"]
    det_t = (
        stats.detected_step_times
        if stats.detected_step_times is not None
        else np.repeat(t, stats.detected_counts)
    )
    ax.step(
        np.concatenate([[0.0], np.sort(times)]),
        np.arange(times.size + 1),
        where="post",
        color="tab:red",
        label=f"true heel strikes ({times.size})",
    )
    ax.step(
        np.concatenate([[0.0], det_t]),
        np.arange(det_t.size + 1),
        where="post",
        color="tab:blue",
        label=f"detected steps ({det_t.size})",
    )
    ax.plot(times, np.zeros_like(times) - 0.5, "|", color="tab:red", ms=8)
    ax.plot(det_t, np.zeros_like(det_t) - 1.2, "|", color="tab:blue", ms=8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("steps so far")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title(f"Gait: {title}", fontsize=9)
    written.append(out_dir / f"gait_{cell.label}.png")
    _save(fig, written[-1])
    return written


#: The metrics drawn per cell by :func:`draw_grid` (row key, axis label), each with its 95 %
#: interval where the row has one.
GRID_METRICS = (
    ("success_rate", "success rate"),
    ("collision_rate", "collision rate"),
    ("spl", "SPL"),
    ("time_to_goal_s", "time to goal (s)"),
    ("start_latency_s", "start latency (s)"),
    ("stop_latency_s", "stop latency (s)"),
    ("stop_overshoot_m", "stop overshoot (m)"),
    ("false_motion_m_per_min", "false motion (m/min)"),
    ("phantom_steps_per_min", "phantom steps (/min)"),
    ("yaw_drift_deg_per_min", "yaw drift standing (deg/min)"),
    ("yaw_rate_mismatch_deg_s", "yaw-rate mismatch (deg/s)"),
    ("virtual_jerk_m_s3", "virtual jerk (m/s³)"),
    ("steering_error_deg", "steering error (deg)"),
    ("hand_tracking_availability", "hand tracking availability"),
)


def cell_name(row: dict[str, Any]) -> str:
    """A row's name in the figures: task · policy · technique (· condition outside the default)."""
    where = row.get("condition", DEFAULT_CONDITION)
    return f"{row['task']} · {row['policy']} · {row['technique']}" + (
        "" if where == DEFAULT_CONDITION else f" · {where}"
    )


def draw_grid(
    out_dir: Path, rows: list[dict[str, Any]], episodes: dict[str, list[EpisodeStats]]
) -> list[Path]:
    """The figures of the whole grid: every metric of :data:`GRID_METRICS` per cell with its
    95 % interval (``metrics.png``), the collisions of each cell by cause
    (``collision_causes.png``) and the distributions of the start and stop latencies over each
    cell's episodes (``latency.png``).

    Args:
        out_dir: folder for the figures.
        rows: the benchmark rows.
        episodes: each row's episodes, by :func:`cell_name` of the row.

    Returns:
        The written files.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from agents.benchmark.collision_causes import COLLISION_CAUSES

    names = [cell_name(r) for r in rows]
    y = np.arange(len(rows))
    height = 0.6 + 0.22 * len(rows)
    written = []

    cols = 3
    lines = math.ceil(len(GRID_METRICS) / cols)
    fig, axes = plt.subplots(
        lines,
        cols,
        figsize=(15, height * lines),
        sharey=True,
        constrained_layout=True,
        squeeze=False,
    )
    for ax, (key, label) in zip(axes.flat, GRID_METRICS, strict=False):
        v = np.array([np.nan if r.get(key) is None else r[key] for r in rows], dtype=float)
        ci = [r.get(f"{key}_ci") for r in rows]
        lo = np.array([np.nan if c is None or c[0] is None else c[0] for c in ci], dtype=float)
        hi = np.array([np.nan if c is None or c[1] is None else c[1] for c in ci], dtype=float)
        err = np.stack(
            [np.where(np.isfinite(lo), v - lo, 0.0), np.where(np.isfinite(hi), hi - v, 0.0)]
        )
        ax.barh(
            y,
            np.nan_to_num(v),
            xerr=np.clip(np.nan_to_num(err), 0.0, None),
            color="tab:blue",
            alpha=0.7,
            ecolor="k",
            capsize=2,
        )
        for i in np.flatnonzero(~np.isfinite(v)):
            ax.text(0.0, i, " n/a", va="center", fontsize=7, color="0.4")
        ax.set_xlabel(label, fontsize=8)
        ax.grid(axis="x", alpha=0.3)
    for ax in axes.flat[len(GRID_METRICS) :]:
        ax.set_visible(False)
    for ax in axes[:, 0]:
        ax.set_yticks(y, names, fontsize=7)
        ax.invert_yaxis()
    fig.suptitle(
        "Benchmark metrics per cell (bars: mean or rate; whiskers: 95 % interval)", fontsize=10
    )
    written.append(out_dir / "metrics.png")
    _save(fig, written[-1])

    fig, ax = plt.subplots(figsize=(9, height + 0.8), constrained_layout=True)
    left = np.zeros(len(rows))
    colours = ("tab:red", "tab:orange", "tab:purple", "tab:green", "0.6")
    for cause, colour in zip(COLLISION_CAUSES, colours, strict=True):
        n = np.array(
            [
                0 if r.get("collision_causes") is None else r["collision_causes"][cause]
                for r in rows
            ],
            dtype=float,
        )
        ax.barh(y, n, left=left, color=colour, label=cause.replace("_", " "))
        left += n
    ax.set_yticks(y, names, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("collisions (all episodes of the cell)")
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("Collisions by cause", fontsize=10)
    written.append(out_dir / "collision_causes.png")
    _save(fig, written[-1])

    fig, axes = plt.subplots(1, 2, figsize=(12, height + 0.8), sharey=True, constrained_layout=True)
    for ax, key, label in zip(
        axes,
        ("start_latency_s", "stop_latency_s"),
        ("start latency (s)", "stop latency (s)"),
        strict=True,
    ):
        for i, name in enumerate(names):
            vals = np.array([e.motion[key] for e in episodes[name] if e.motion is not None])
            vals = vals[np.isfinite(vals)]
            if vals.size:
                jitter = (np.arange(vals.size) % 7 - 3) * 0.05
                ax.plot(vals, i + jitter, "o", ms=2.5, alpha=0.6, color="tab:blue")
                ax.plot([np.median(vals)] * 2, [i - 0.35, i + 0.35], color="k", lw=1.5)
        ax.set_xlabel(f"{label}, per episode (bar: median)", fontsize=8)
        ax.grid(axis="x", alpha=0.3)
    axes[0].set_yticks(y, names, fontsize=7)
    axes[0].invert_yaxis()
    fig.suptitle("Start and stop latency distributions", fontsize=10)
    written.append(out_dir / "latency.png")
    _save(fig, written[-1])
    return written

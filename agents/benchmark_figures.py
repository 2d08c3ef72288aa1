"""The benchmark's figures of one episode per cell (the analogues of seed 000's Figs. 2-5): the
true and virtual paths over the room, the head attitude (truth vs estimate) and the gait (true
heel strikes vs detected steps)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.metrics import EpisodeStats

if TYPE_CHECKING:
    from agents.benchmark import Cell

__all__ = ["draw_cell"]


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
        ax.add_patch(Circle(layout.goal, layout.goal_radius, fill=False, color="tab:green",
                            lw=1.5, label="goal"))  # fmt: skip
    xmin, xmax, ymin, ymax = layout.bounds
    t = 2.0 * min(min(w.half_extents) for w in layout.walls) if layout.walls else 0.2
    ax.set_xlim(xmin - 1.5 * t, xmax + 1.5 * t)
    ax.set_ylim(ymin - 1.5 * t, ymax + 1.5 * t)
    ax.set_aspect("equal", adjustable="box")


def draw_cell(out_dir: Path, cell: Cell, stats: EpisodeStats) -> list[Path]:
    """The three figures of one episode (needs ``stats.trace``): paths over the room
    (seed 000 Figs. 4/5), head attitude truth vs estimate (Fig. 3), gait (Fig. 2).

    Returns:
        The written files.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tr = stats.trace
    if tr is None:
        raise ValueError("stats has no trace: run the episode with trace=True")
    out_dir.mkdir(parents=True, exist_ok=True)
    title = f"{cell.task}, {cell.policy}, {cell.technique_name}, seed {stats.seed}"
    outcome = "success" if stats.success else "failure"
    written = []

    fig, ax = plt.subplots(figsize=(7.5, 6.5), constrained_layout=True)
    _draw_room(ax, tr["layout"])
    ax.plot(*tr["true_position"].T, color="0.2", lw=2.5, alpha=0.5,
            label="true steps and heading")  # fmt: skip
    ax.plot(*tr["position"].T, "o-", color="tab:red", ms=2.5, lw=1.0,
            label="virtual body (estimated)")  # fmt: skip
    ax.plot(*tr["position"][0], "s", color="k", ms=6, label="start")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"Paths: {title} ({outcome}, {stats.collisions} collisions)", fontsize=9)
    ax.legend(fontsize=7, loc="best")
    written.append(out_dir / f"trajectory_{cell.label}.png")
    fig.savefig(written[-1], dpi=100)
    plt.close(fig)

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
    fig.savefig(written[-1], dpi=100)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(9, 3.6), constrained_layout=True)
    times = tr["true_step_times"]
    det_t = stats.detected_step_times if stats.detected_step_times is not None else np.repeat(
        t, stats.detected_counts
    )
    ax.step(np.concatenate([[0.0], np.sort(times)]), np.arange(times.size + 1), where="post",
            color="tab:red", label=f"true heel strikes ({times.size})")  # fmt: skip
    ax.step(np.concatenate([[0.0], det_t]), np.arange(det_t.size + 1), where="post",
            color="tab:blue", label=f"detected steps ({det_t.size})")  # fmt: skip
    ax.plot(times, np.zeros_like(times) - 0.5, "|", color="tab:red", ms=8)
    ax.plot(det_t, np.zeros_like(det_t) - 1.2, "|", color="tab:blue", ms=8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("steps so far")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title(f"Gait: {title}", fontsize=9)
    written.append(out_dir / f"gait_{cell.label}.png")
    fig.savefig(written[-1], dpi=100)
    plt.close(fig)
    return written

"""The task pictures: each task's room for one seeded reset, drawn into
``img/tasks/<task>.png``."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from agents.reference_pages.common import PICTURE_DPI, PICTURE_SEED


def picture_layout(name: str) -> tuple[Any, str]:
    """The room of ``env.reset(seed=PICTURE_SEED)`` for task ``name`` with the default
    configuration (the env draws its room from its ``np_random``, as here) and its caption."""
    from vrloco_env.tasks import get_task, make_layout
    from vrloco_env.world import RoomConfig

    layout = make_layout(name, RoomConfig(), np.random.default_rng(PICTURE_SEED))
    config = get_task(name).Config()
    xmin, xmax, ymin, ymax = layout.bounds
    if layout.goal_line is not None:
        goal = "the end line (green, dashed)"
    elif hasattr(config, "standoff_range") and hasattr(config, "band_half_width"):
        goal = (
            "the standing band, the goal region (orange, dashed), with the disc the planned "
            "path ends in (green circle)"
        )
    else:
        goal = "the goal region (green circle)"
    pedestal = ", the pedestal in dark grey" if layout.target is not None else ""
    caption = (
        f'The room of `gym.make("{_env_id_of(name)}").reset(seed={PICTURE_SEED})` with the '
        f"default configuration: {xmax - xmin:.1f} m x {ymax - ymin:.1f} m inside the walls, "
        f"{len(layout.obstacles)} solids of `Layout.obstacles` in grey{pedestal}, the start "
        f"(black square, arrow: the start heading), {goal}, and the planned collision-free path "
        "(dotted, "
        f"{layout.shortest_path_length:.1f} m)."
    )
    return layout, caption


def _env_id_of(name: str) -> str:
    from vrloco_env.tasks import env_id

    return env_id(name)


def picture_paths() -> list[str]:
    """The pictures' paths, relative to the output folder, one per registered task."""
    from vrloco_env.tasks import task_names

    return [f"img/tasks/{name}.png" for name in task_names()]


def write_pictures(out: Path) -> list[Path]:
    """Draw each task's room (:func:`picture_layout`) into ``out/img/tasks/<task>.png``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from agents.benchmark.figures import _draw_room
    from vrloco_env.tasks import get_task, task_names

    written = []
    for name, rel in zip(task_names(), picture_paths(), strict=True):
        layout, _ = picture_layout(name)
        xmin, xmax, ymin, ymax = layout.bounds
        height = min(max(4.2 * (ymax - ymin) / (xmax - xmin), 1.4), 4.2) + 0.8
        fig, ax = plt.subplots(figsize=(5.6, height))
        _draw_room(ax, layout)
        if layout.target is not None:
            _draw_target(ax, layout, get_task(name).Config())
        ax.plot(*np.asarray(layout.path).T, ":", color="tab:blue", lw=1.5, label="planned path")
        x, y, yaw = layout.start
        ax.plot(x, y, "s", color="k", ms=6, label="start")
        ax.annotate(
            "",
            (x + 0.8 * math.cos(yaw), y + 0.8 * math.sin(yaw)),
            (x, y),
            arrowprops={"arrowstyle": "->", "color": "k", "lw": 1.5},
        )
        ax.set_xlabel("x (m)", fontsize=8)
        ax.set_ylabel("y (m)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.set_title(f"{_env_id_of(name)}, reset(seed={PICTURE_SEED})", fontsize=9)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        path = out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(
            path, dpi=PICTURE_DPI, format="png", bbox_inches="tight", metadata={"Software": None}
        )
        plt.close(fig)
        written.append(path)
    return written


def _draw_target(ax: Any, layout: Any, config: Any) -> None:
    """The pedestal of a layout in a darker grey, and, for a config with a standing band
    (``standoff_range``, ``band_half_width``: Reach), the band in front of its +x face."""
    from matplotlib.patches import Polygon

    box = layout.target
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    rot = np.array([[c, s], [-s, c]])
    hx, hy = box.half_extents
    corners = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
    ax.add_patch(
        Polygon(
            corners @ rot + np.asarray(box.center),
            closed=True,
            color="0.25",
            lw=0,
            label="pedestal",
        )
    )
    if hasattr(config, "standoff_range") and hasattr(config, "band_half_width"):
        near, far = (hx + layout.avatar_radius + g for g in config.standoff_range)
        w = config.band_half_width
        band = np.array([[near, -w], [far, -w], [far, w], [near, w]])
        ax.add_patch(
            Polygon(
                band @ rot + np.asarray(box.center),
                closed=True,
                fill=False,
                color="tab:orange",
                lw=1.2,
                ls="--",
                label="standing band (body centre)",
            )
        )

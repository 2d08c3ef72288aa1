"""The replays of the benchmark's report page (:mod:`agents.benchmark.report`): per traced
episode, what its player needs as JSON-ready numbers (:func:`replay_data`), each collision with
its cause (:func:`collision_events`, the rule of :mod:`agents.benchmark.collision_causes`), and its
block of the page: the room as inline SVG (walls, obstacles, target, goal) with the controls that
the page's script drives (:mod:`agents.benchmark.report_assets`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.benchmark.collision_causes import COLLISION_CAUSES, collision_causes

if TYPE_CHECKING:
    from agents.benchmark.metrics import EpisodeStats

__all__ = ["MAX_FRAMES", "REPLAY_EPISODES", "collision_events", "replay_data"]

#: The first episodes of each cell that keep their trace when the run has an output folder,
#: each replayed in the report (the figures draw the first).
REPLAY_EPISODES = 3
#: The most frames a replay keeps (a longer episode is sampled at every k-th control step, its
#: last step always kept; collisions keep their own times and places).
MAX_FRAMES = 300
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

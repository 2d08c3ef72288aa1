"""Simulated heads beside real ones: the head-motion statistics of every user population,
standing and walking in place, and of people watching 360-degree videos in a headset.

This measures the registered populations (:mod:`vrloco_env.user.population`); it changes none
of their parameters. Every statistic is :mod:`agents.recordings.head_motion_stats`'s, at 10 Hz.

**Simulated heads.** For each registered population, ``episodes`` users (seeds ``seed`` to
``seed + episodes - 1``) in one native vector env of ``VRLoco-Approach-v0`` with that population
(:data:`ROOM`: a 16 x 16 m room with the goal at least 12 m from the start and obstacles at the
default room's density, so that a walk lasts more than the statistics' 10 s minimum), in two
conditions run apart:

* ``standing`` — the user never walks (walk action -1, no turn, hands still) for the whole
  60 s episode: what the population's head does on its own while standing and looking around
  (gaze at the goal, looks around, nods; glances come only while stepping), as during a
  dwell. Approach, not Interact or Reach, because those tasks' dwell makes the user look down
  at the hand, which stops looking around.
* ``walking`` — the goal seeker (:class:`agents.scripted.GoalSeeker`, with the population's
  agent-side variability, ``goal_seeker+<population>``) walks in place to the goal, turning its
  body toward it first; the episode ends at the goal or after 60 s. Episodes shorter than 10 s
  are left out and counted (``settings.excluded_episodes``).

The head is the true head of ``info["true_ypr"]``: yaw and pitch **in the world** (the
physical room), once per control step (10 Hz). The world frame, not the head on the torso,
because the real traces are headset orientations in the tracking frame: they hold the body's
turns (on a swivel chair or standing) as well as the neck's, and cannot be split.

**Real heads** (:mod:`agents.recordings.head_traces`, in ``$VRLOCO_DATA/head_traces`` only, never
downloaded: no licence is stated): Corbillon et al. 2017, Lo et al. 2017 and Wu et al. 2017 (ACM
MMSys 2017), people **seated or standing, freely viewing 360-degree videos: nobody walked**. They
bound idle looking around from above and give a shape to gaze shifts (sizes, speeds, intervals);
they are no truth for walking in place. Split per dataset by video number (:func:`is_held_out`):
even numbers are the tuning files the populations' looking around was calibrated on (the
shape of its turns, with the rate bounded; :mod:`vrloco_env.user.population`, simulated on
seeds 1000-1299; this experiment's default seeds are 0-15), **odd numbers are held out**, and only
the held-out files are reported here (corbillon2017: 1, 3, 5; lo2017: 7, 9, 11, 13, 15; wu2017:
33, 35, 37, 39, 41). A viewing the statistics reject (lo2017 has three with a pitch beyond
+-90 deg, one of them held out) is left out and listed
(``split.<dataset>.excluded_viewings``). About 70 % of the Corbillon and Wu samples lie on a
0.01 rad (0.57 deg) grid (the rest were interpolated by the aggregation), so at 10 Hz one
quantum is 5.7 deg/s: 22-49 % of their sample pairs do not move at all and their yaw-speed
distributions step at 5.7 deg/s (Lo et al.'s are not quantised).

**Distances**, per population, condition and dataset: the two-sample Kolmogorov-Smirnov
statistic (:func:`scipy.stats.ks_2samp`) of the |yaw speed| samples and of the inter-turn
intervals (None where either side has none), and for every statistic the relative difference
``(simulated - real) / |real|`` (element-wise for lists; None where the real value is 0 or
either is None).

Output: ``{"populations": {NAME: {"standing": S, "walking": S}}, "real": {DATASET: S},
"distances": {NAME: {CONDITION: {DATASET: D}}}, "split": {DATASET: {...}}, "settings": {...}}``,
each S :meth:`agents.recordings.head_motion_stats.HeadMotionStats.to_json` (None where no trace was
left); a compact table on stdout; a figure ``head_behaviour.png`` (yaw-speed distributions, turn
rates) in ``out_dir``.

Run: ``vrloco experiment head-behaviour [--json F] [--episodes N] [--seed S] [--out DIR]``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from agents.recordings.head_motion_stats import (
    STATS_KEYS,
    TURN_CLASSES_DEG,
    HeadMotionSamples,
    head_motion_samples,
    prepare_traces,
)
from agents.recordings.head_traces import dataset_files, head_traces_folder, read_head_traces
from vrloco_env.world import RoomConfig

__all__ = [
    "CONDITIONS",
    "DEFAULT_EPISODES",
    "ROOM",
    "distances",
    "format_tables",
    "is_held_out",
    "real_samples",
    "run_head_behaviour",
    "simulate_heads",
]

CONDITIONS = ("standing", "walking")
DEFAULT_EPISODES = 16
HORIZON_STEPS = 600  # 60 s at the 10 Hz control rate
RATE_HZ = 10.0
#: The room of both conditions: 16 x 16 m, 4x the default area with 4x its obstacles, the goal
#: at least 12 m away (an engineering choice for walks longer than 10 s).
ROOM = RoomConfig(
    room_width=16.0,
    room_depth=16.0,
    n_obstacles_min=16,
    n_obstacles_max=28,
    min_start_goal_distance=12.0,
)
REAL_NOTE = (
    "free viewing of 360-degree videos, seated or standing: not walking; held-out "
    "files (odd video numbers)"
)


def is_held_out(path: str | Path) -> bool:
    """A head-trace file is held out when its video number is odd (even: tuning)."""
    return int(Path(path).stem) % 2 == 1


def simulate_heads(
    population: str, condition: str, episodes: int, seed: int, max_steps: int = HORIZON_STEPS
) -> tuple[list[NDArray[np.float64]], list[NDArray[np.float64]], float]:
    """True head yaw and pitch in the world (rad) of ``episodes`` users of ``population``
    standing or walking (see the module docstring), one array per episode cut at its end.

    Returns:
        ``(yaw, pitch, rate_hz)``: per-episode traces and the control rate they are sampled at.
    """
    from gymnasium.vector import AutoresetMode

    from agents.benchmark.policies import build_policy
    from vrloco_env.actions import ACTION_SIZE
    from vrloco_env.vector import VRLocoVectorEnv

    if condition not in CONDITIONS:
        raise ValueError(f"condition={condition!r}: must be one of {', '.join(CONDITIONS)}")
    env = VRLocoVectorEnv(
        episodes,
        task="approach",
        population=population,
        room=ROOM,
        max_episode_steps=max_steps,
        autoreset_mode=AutoresetMode.DISABLED,
    )
    try:
        obs, _ = env.reset(seed=seed)
        policy = None
        if condition == "walking":
            policy = build_policy(f"goal_seeker+{population}", env)
            policy.reset([np.random.default_rng([seed + i, 1]) for i in range(episodes)], None)
        stand = np.zeros((episodes, ACTION_SIZE), np.float32)
        stand[:, 0] = -1.0  # walk <= 0: stand still
        ypr: list[NDArray[np.float64]] = []
        length = np.zeros(episodes, np.intp)
        running = np.ones(episodes, bool)
        while running.any():
            action = stand if policy is None else np.asarray(policy.act(obs), np.float32)
            obs, _, terminated, truncated, info = env.step(action)
            ypr.append(info["true_ypr"][:, :2].copy())
            length[running] += 1
            running &= ~(terminated | truncated)
        rate_hz = 1.0 / env.core.dt
    finally:
        env.close()
    head = np.deg2rad(np.stack(ypr, axis=1))  # (B, steps, [yaw, pitch])
    yaw = [head[i, : length[i], 0] for i in range(episodes)]
    pitch = [head[i, : length[i], 1] for i in range(episodes)]
    return yaw, pitch, rate_hz


def real_samples(paths: list[Path]) -> tuple[HeadMotionSamples | None, list[dict[str, Any]]]:
    """The pooled samples of every viewing in ``paths`` that the statistics accept, and the
    viewings they reject (``{"file", "line", "reason"}``, the line of the viewing's pitch)."""
    times, yaw, pitch, excluded = [], [], [], []
    for path in paths:
        f = read_head_traces(path)
        for v, (t, p, y) in enumerate(f.viewings()):
            try:
                prepare_traces(y, p, times=t, resample_hz=RATE_HZ)
            except ValueError as err:
                excluded.append({"file": path.name, "line": f.pitch_line(v), "reason": str(err)})
                continue
            times.append(t)
            yaw.append(y)
            pitch.append(p)
    if not yaw:
        return None, excluded
    return head_motion_samples(yaw, pitch, times=times, resample_hz=RATE_HZ), excluded


def _relative(sim: Any, real: Any) -> Any:
    if isinstance(real, list):
        if sim is None:
            return [None] * len(real)
        return [_relative(s, r) for s, r in zip(sim, real, strict=True)]
    if sim is None or real is None or real == 0:
        return None
    return (sim - real) / abs(real)


def distances(sim: HeadMotionSamples, real: HeadMotionSamples) -> dict[str, Any]:
    """KS statistics of |yaw speed| and of the intervals, and every statistic's relative
    difference (see the module docstring)."""
    from scipy.stats import ks_2samp

    def ks(a: NDArray, b: NDArray) -> float | None:
        if a.size == 0 or b.size == 0:
            return None
        return float(ks_2samp(a, b, method="asymp").statistic)

    s, r = sim.stats().to_json(), real.stats().to_json()
    return {
        "yaw_speed_ks": ks(sim.yaw_speed, real.yaw_speed),
        "interval_ks": ks(sim.intervals, real.intervals),
        "relative": {k: _relative(s[k], r[k]) for k in STATS_KEYS},
    }


def run_head_behaviour(
    json_path: Path | None = None,
    episodes: int = DEFAULT_EPISODES,
    seed: int = 0,
    out_dir: Path | None = None,
    populations: tuple[str, ...] | None = None,
    max_steps: int = HORIZON_STEPS,
    traces_folder: Path | None = None,
) -> dict[str, Any]:
    """Simulate every population standing and walking, read the held-out real traces, compare;
    print the tables, write the JSON (``json_path``) and the figure (``out_dir``, else beside
    the JSON; neither: no figure).

    Args:
        episodes: users per population and condition (>= 1).
        seed: the first episode's seed (>= 0).
        populations: the populations (default: every registered one).
        max_steps: the episodes' horizon (control steps, >= 100: 10 s).
        traces_folder: the head traces (default
            :func:`agents.recordings.head_traces.head_traces_folder`).

    Raises:
        ValueError: a bad argument, naming it.
        FileNotFoundError: no head traces (naming the folder and ``VRLOCO_DATA``).
    """
    from vrloco_env.user.population import get_population, population_names

    for name, value, lo in (
        ("episodes", episodes, 1),
        ("seed", seed, 0),
        ("max_steps", max_steps, 100),
    ):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < lo:
            raise ValueError(f"run_head_behaviour: {name}={value!r} must be an integer >= {lo}")
    names = tuple(populations) if populations is not None else population_names()
    for name in names:
        get_population(name)
    files = dataset_files(traces_folder if traces_folder is not None else head_traces_folder())

    real: dict[str, HeadMotionSamples | None] = {}
    split: dict[str, Any] = {}
    for ds, paths in files.items():
        held = [p for p in paths if is_held_out(p)]
        real[ds], excluded = real_samples(held)
        split[ds] = {
            "held_out": [p.name for p in held],
            "tuning": [p.name for p in paths if not is_held_out(p)],
            "excluded_viewings": excluded,
        }

    sim: dict[str, dict[str, HeadMotionSamples | None]] = {}
    short: dict[str, dict[str, int]] = {}
    for name in names:
        sim[name], short[name] = {}, {}
        for cond in CONDITIONS:
            yaw, pitch, rate = simulate_heads(name, cond, episodes, seed, max_steps)
            keep = [i for i, y in enumerate(yaw) if (y.size - 1) / rate >= 10.0]
            short[name][cond] = len(yaw) - len(keep)
            sim[name][cond] = None
            if keep:
                sim[name][cond] = head_motion_samples(
                    [yaw[i] for i in keep],
                    [pitch[i] for i in keep],
                    rate_hz=rate,
                    resample_hz=RATE_HZ,
                )

    def js(s: HeadMotionSamples | None) -> dict[str, Any] | None:
        return None if s is None else s.stats().to_json()

    def dist(s: HeadMotionSamples | None, r: HeadMotionSamples | None) -> dict | None:
        return None if s is None or r is None else distances(s, r)

    result: dict[str, Any] = {
        "populations": {n: {c: js(sim[n][c]) for c in CONDITIONS} for n in names},
        "real": {ds: js(s) for ds, s in real.items()},
        "distances": {
            n: {c: {ds: dist(sim[n][c], r) for ds, r in real.items()} for c in CONDITIONS}
            for n in names
        },
        "split": split,
        "settings": {
            "rate_hz": RATE_HZ,
            "episodes": episodes,
            "seeds": [seed, seed + episodes - 1],
            "horizon_s": max_steps / RATE_HZ,
            "task": "approach",
            "room_m": [ROOM.room_width, ROOM.room_depth],
            "head": "true head yaw and pitch in the world (info['true_ypr'])",
            "excluded_episodes": short,
            "real": REAL_NOTE,
            "split_rule": "per dataset: odd video numbers held out (reported), even for tuning",
        },
    }
    print(format_tables(result))
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(result, indent=2))
        print(f"wrote {json_path}")
    figure_dir = (
        out_dir if out_dir is not None else (json_path.parent if json_path is not None else None)
    )
    if figure_dir is not None:
        path = plot_head_behaviour(sim, real, Path(figure_dir))
        print(f"wrote {path}")
    return result


def _fmt(v: Any, spec: str = ".0f") -> str:
    return "-" if v is None else format(v, spec)


def format_tables(result: dict[str, Any]) -> str:
    """The statistics of every source and the KS distances, as text."""
    head = (
        f"{'source':<30}{'yaw speed p50/90/99':>21}{'turns/min >=10/30/60':>22}"
        f"{'amp p50':>8}{'iv p50':>7}{'iv cv':>6}{'still':>6}{'pitch':>6}{'nods':>6}"
    )

    def row(label: str, s: dict[str, Any] | None) -> str:
        if s is None:
            return f"{label:<30}  (no trace of 10 s or more)"
        v, t = s["yaw_speed_p50_p75_p90_p95_p99"], s["turns_per_min"]
        amp, iv = s["turn_amplitude_p25_p50_p75"], s["interval_p10_p25_p50_p75_p90"]
        speeds = f"{v[0]:.1f}/{v[2]:.0f}/{v[4]:.0f}"
        turns = f"{t[0]:.1f}/{t[2]:.1f}/{t[3]:.1f}"
        return (
            f"{label:<30}{speeds:>21}{turns:>22}{_fmt(amp and amp[1]):>8}"
            f"{_fmt(iv and iv[2], '.1f'):>7}{_fmt(s['interval_cv'], '.2f'):>6}"
            f"{s['still_fraction']:>6.2f}{s['pitch_range_5_95_deg']:>6.0f}"
            f"{s['nods_per_min']:>6.1f}"
        )

    lines = [
        "Head-motion statistics at 10 Hz (deg/s, deg, s; world-frame head). Real: "
        + REAL_NOTE
        + ".",
        head,
    ]
    for name, conds in result["populations"].items():
        for cond, s in conds.items():
            lines.append(row(f"{name} {cond}", s))
    for ds, s in result["real"].items():
        lines.append(row(f"{ds} (held-out)", s))
    datasets = list(result["real"])
    lines += [
        "",
        "KS distance, |yaw speed| / inter-turn intervals, vs held-out real:",
        f"{'':<30}" + "".join(f"{ds:>16}" for ds in datasets),
    ]
    for name, conds in result["distances"].items():
        for cond, per in conds.items():
            cells = "".join(
                f"{'-':>16}"
                if d is None
                else f"{_fmt(d['yaw_speed_ks'], '.2f') + ' / ' + _fmt(d['interval_ks'], '.2f'):>16}"
                for d in per.values()
            )
            lines.append(f"{name + ' ' + cond:<30}{cells}")
    return "\n".join(lines)


def plot_head_behaviour(
    sim: dict[str, dict[str, HeadMotionSamples | None]],
    real: dict[str, HeadMotionSamples | None],
    out_dir: Path,
) -> Path:
    """``head_behaviour.png``: per condition, the |yaw speed| distribution and a histogram of
    each trace's rate of turns of at least 10 deg, every population beside the real datasets;
    and turns per minute by amplitude of every source."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    colours = {n: plt.get_cmap("tab10")(k % 10) for k, n in enumerate(sim)}
    real_styles = [("black", "--"), ("dimgray", "-."), ("darkgray", ":")]
    real_items = [
        (f"{ds} (real, held-out)", s, real_styles[k % 3])
        for k, (ds, s) in enumerate(real.items())
        if s is not None
    ]
    fig, axes = plt.subplots(2, 3, figsize=(17, 9))
    q = np.linspace(0.0, 100.0, 201)
    bins = np.arange(0.0, 62.0, 2.0)
    for col, cond in enumerate(CONDITIONS):
        ax, hx = axes[0, col], axes[1, col]
        top = 0.0
        items = [(n, conds[cond], (colours[n], "-")) for n, conds in sim.items()]
        for label, s, (colour, style) in items + real_items:
            if s is None:
                continue
            lw = 2.0 if "real" in label else 1.3
            ax.plot(
                np.percentile(s.yaw_speed, q), q / 100.0, style, color=colour, lw=lw, label=label
            )
            rates = np.clip(s.turn_rates(), 0.0, 60.0)
            share, _ = np.histogram(rates, bins=bins)
            share = share / rates.size
            hx.stairs(share, bins, color=colour, linestyle=style, lw=lw, label=label)
            if rates.any():  # a source that never turns (a spike at 0) does not set the scale
                top = max(top, share.max())
        ax.set(
            xscale="symlog",
            xlim=(0, 500),
            xlabel="|yaw speed| (deg/s)",
            ylabel="share of samples at or below",
            title=f"|yaw speed|: simulated {cond} vs real viewing",
        )
        ax.legend(fontsize=7, loc="lower right")  # a fixed place: "best" is slow to find
        hx.set(
            ylim=(0, 1.15 * top if top > 0 else 1.0),
            xlabel="turns of >= 10 deg per minute, per trace (clipped at 60)",
            ylabel="share of traces",
            title=f"turn rate per trace: simulated {cond} vs real",
        )
        hx.legend(fontsize=7, loc="upper right")
    ax = axes[0, 2]
    sources = [
        (f"{n} {c}", s, colours[n], "//" if c == "walking" else None)
        for n, conds in sim.items()
        for c, s in conds.items()
    ]
    sources += [(label, s, colour, None) for label, s, (colour, _) in real_items]
    sources = [x for x in sources if x[1] is not None]
    width = 0.8 / max(len(sources), 1)
    for k, (label, s, colour, hatch) in enumerate(sources):
        ax.bar(
            np.arange(len(TURN_CLASSES_DEG)) + k * width,
            s.stats().turns_per_min,
            width,
            color=colour,
            hatch=hatch,
            edgecolor="white",
            label=label,
        )
    ax.set_xticks(
        np.arange(len(TURN_CLASSES_DEG)) + 0.4 - width / 2,
        [f">= {c:.0f} deg" for c in TURN_CLASSES_DEG],
    )
    ax.set(ylabel="turns per minute", title="turns by amplitude (hatched: walking)")
    ax.legend(fontsize=6, ncol=2, loc="upper right")
    axes[1, 2].axis("off")
    axes[1, 2].text(
        0.0,
        0.95,
        "Real: head traces of people seated or standing, freely\n"
        "viewing 360-degree videos (nobody walked): Corbillon et al.,\n"
        "Lo et al., Wu et al., ACM MMSys 2017 (via 360VidStr).\n"
        "Held-out files only (odd video numbers).\n\n"
        "Simulated: true head yaw and pitch in the world,\n"
        "10 Hz, Approach room 16 x 16 m; standing = never walks,\n"
        "walking = goal seeker walking in place to the goal.",
        va="top",
        fontsize=9,
        transform=axes[1, 2].transAxes,
    )
    fig.suptitle(
        "Head motion: simulated populations vs people freely viewing 360-degree video (not walking)"
    )
    fig.tight_layout()
    path = out_dir / "head_behaviour.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path

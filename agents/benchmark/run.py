"""``vrloco benchmark``: simulated users x tasks x techniques over seeded episodes.

A technique (:mod:`vrloco_env.techniques`) is a sensor preset plus one choice per estimation
stage; ``--sensors`` is a shorthand for Zhang 2021's chain on each IMU preset. Every cell of the
grid (task, policy, technique) runs ``episodes`` episodes; episode ``i`` of every cell is seeded
``seed + i`` (the env's ``reset(seed=...)``; the policy draws from ``default_rng([seed + i, 1])``),
so the same episode index meets the same room in every cell, and an episode's numbers depend on
nothing else: not on the worker processes, the batch it ran in, or the backend.

Jobs (:func:`_split_jobs`): the cells that share a task and a technique run together as users of
one native vector env (:func:`agents.benchmark.episodes.run_batched`, ``batch_size`` users;
``batch_size=0`` runs every episode alone in a single env,
:func:`agents.benchmark.episodes.run_cell_episode`). They run in a
``concurrent.futures.ProcessPoolExecutor`` of ``workers`` processes (1: in this process) or, with
``backend="ray"``, as Ray tasks (:mod:`agents.benchmark.backends`), under one progress bar. A local
worker claims a job's episodes one by one from a counter the workers share, so that a worker with no
job left to start joins one still running (:func:`agents.benchmark.jobs._job`): the workers end
together. Finished episodes are kept in ``<out>/.resume`` (:mod:`agents.benchmark.resume`) until the
grid is complete, so an interrupted run resumes; an output folder holds one run at a time, and one
run's files alone (:class:`agents.benchmark.run_folder.RunFolder`).
:func:`agents.benchmark.metrics.summarize` turns each cell into a row, compared with the baseline
technique's (:mod:`agents.benchmark.paired`): a table on the terminal, a CSV and a JSON file
(:mod:`agents.benchmark.outputs`), and the figures (:mod:`agents.benchmark.figures`: for the first
episode of each cell the true and virtual paths over the room, the head attitude, the gait; for the
grid every metric, the collision causes and the latencies), all in one page with each cell's first
episodes replayed (:mod:`agents.benchmark.report`, ``report.html``).

Policies: ``goal_seeker``, ``avoid_manoeuvre``, ``reactive_avoider`` (:mod:`agents.scripted`),
``+<population>`` for a human population (:mod:`vrloco_env.user.population`), a stable-baselines3
``.zip`` or ``module:attr`` (:mod:`agents.benchmark.policies`). The default run is
:data:`agents.benchmark.grid.DEFAULT_GRIDS`; after its table comes the discriminating-power table of
the technique pairs whose cells the run holds (:mod:`agents.benchmark.discrimination`, also
``pairs.json``).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from agents.benchmark import warm_start
from agents.benchmark.conditions import DEFAULT_CONDITION, get_condition
from agents.benchmark.discrimination import pair_results, show_pairs, write_pairs
from agents.benchmark.episodes import DEFAULT_BATCH_SIZE, run_cell_episode
from agents.benchmark.figures import cell_name, draw_cell, draw_grid
from agents.benchmark.grid import (
    DEFAULT_EPISODES,
    DEFAULT_GRIDS,
    DEFAULT_POLICIES,
    DEFAULT_TASKS,
    DEFAULT_TECHNIQUES,
    Cell,
    Grid,
)
from agents.benchmark.jobs import _init_worker, _job, _pool_context, _worker_threads
from agents.benchmark.metrics import (
    EpisodeStats,
    summarize,
)
from agents.benchmark.outputs import (
    BASELINE_TECHNIQUE,
    ROW_KEYS,
    atomic_path,
    show_table,
    write_csv,
    write_json,
    written_summary,
)
from agents.benchmark.paired import compare_values, episode_values
from agents.benchmark.policies import check_policy
from agents.benchmark.report import REPLAY_EPISODES, write_report
from agents.benchmark.resume import (
    EpisodeStore,
    cell_inputs,
    episode_key,
    source_fingerprint,
)
from agents.benchmark.run_folder import RunFolder
from agents.benchmark.step_matching import step_window
from vrloco_env.tasks import get_task

__all__ = [
    "BASELINE_TECHNIQUE",
    "ROW_KEYS",
    "run_benchmark",
    "show_table",
    "step_window",
]


def technique_for_preset(preset: str) -> Any:
    """Zhang 2021's chain on the IMU ``preset`` (the ``--sensors`` shorthand): the registered
    technique if one is exactly that, else an unregistered one named ``zhang2021_<preset>``."""
    from vrloco_env.config import EstimatorConfig
    from vrloco_env.sensors.imu import get_imu_spec
    from vrloco_env.techniques import TECHNIQUES, Technique

    get_imu_spec(preset)  # raises with the valid names
    for tech in TECHNIQUES.values():
        if tech.sensor_preset == preset and tech.estimators == EstimatorConfig():
            return tech.name
    return Technique(f"zhang2021_{preset}", f"Zhang 2021's chain on {preset}", preset)


def check_policy_name(name: str) -> str:
    """``name`` if it names a policy (:func:`agents.benchmark.policies.check_policy`), else a
    ValueError."""
    return check_policy(name)


# --------------------------------------------------------------------------- the grid


def run_benchmark(
    tasks: Sequence[str] | None = None,
    policies: Sequence[str] | None = None,
    sensors: Sequence[str] | None = None,
    episodes: int = DEFAULT_EPISODES,
    seed: int = 0,
    workers: int = 2,
    out_dir: Path | str | None = None,
    json_path: Path | str | None = None,
    progress: bool = True,
    print_table: bool = True,
    techniques: Sequence[Any] | None = None,
    batch_size: int = DEFAULT_BATCH_SIZE,
    backend: str = "local",
    address: str | None = None,
    baseline: str = BASELINE_TECHNIQUE,
    conditions: Sequence[str] | None = None,
    grids: Sequence[Grid] | None = None,
    force: bool = False,
) -> list[dict[str, Any]]:
    """Run the grid (or grids) and write the outputs.

    Without any of ``tasks``, ``policies``, ``sensors``, ``techniques``, ``conditions`` and
    ``grids`` it runs the default run, :data:`DEFAULT_GRIDS`. Given some of the first five, it
    runs their one grid, the axes not given taken from :data:`DEFAULT_TASKS`,
    :data:`DEFAULT_POLICIES`, :data:`DEFAULT_TECHNIQUES` and the default condition.

    Args:
        tasks: registered task names (:mod:`vrloco_env.tasks`).
        policies: scripted users, optionally with ``+<population>``
            (:mod:`agents.benchmark.policies`).
        sensors: IMU presets (``ig500n``, ``consumer_mems``): shorthand for Zhang 2021's chain on
            each, added to ``techniques``.
        techniques: registered technique names, ``"module:attr"`` strings or
            :class:`~vrloco_env.techniques.Technique` objects. Without ``sensors`` and
            ``techniques``: :data:`DEFAULT_TECHNIQUES`.
        grids: several grids run as one (each cell once), instead of the five arguments above.
        episodes: episodes per cell (>= 1).
        seed: episode ``i`` is seeded ``seed + i``.
        workers: worker processes (>= 1; 1 runs in this process).
        batch_size: users stepped together in the native vector env (>= 1), each job a cell's
            batch of seeds (:func:`agents.benchmark.episodes.run_batched`); 0 runs every episode
            alone in a single env (:func:`agents.benchmark.episodes.run_cell_episode`). The results
            are the same either way.
        out_dir: folder for ``benchmark.csv``, ``benchmark.json``, ``pairs.json``, the
            figures and ``report.html``, and for the finished episodes of an interrupted run
            (``.resume``), one run at a time (:class:`agents.benchmark.run_folder.RunFolder`): a
            folder holding another run's files is refused (None: no files).
        force: remove another run's files from ``out_dir`` first instead of refusing it.
        json_path: also write the JSON here.
        progress: show a progress bar.
        print_table: print the table.
        backend: ``"local"`` (a process pool of ``workers`` here) or ``"ray"``: every job a Ray
            task (:func:`agents.benchmark.backends.run_jobs_ray`; ``workers`` then only sizes the
            jobs). The rows are the same either way.
        address: with ``"ray"``: the cluster, ``"auto"`` or ``"HOST:PORT"``; None: a running
            cluster of this machine where there is one, else a new local Ray instance.
        conditions: physical-room conditions (:mod:`agents.benchmark.conditions`), each a grid axis.
        baseline: the technique every other one is compared with, episode by episode, in the
            same task, policy and condition (:func:`agents.benchmark.paired.paired_p_values`; the
            row's ``vs_baseline``, None for the baseline itself or where it is not in the grid).

    Returns:
        One dict per cell with :data:`ROW_KEYS`, grouped by technique.

    Raises:
        ValueError: an unknown task, policy, technique or preset, or a bad count; an unknown
            backend, an address without ``"ray"``, ``"ray"`` without Ray installed.
        agents.benchmark.backends.BackendError: no Ray cluster at ``address``, or Ray jobs
            that failed (raised once the other jobs have finished; with ``out_dir`` their
            episodes are kept for a rerun to resume).
        ValueError: ``out_dir`` holds another run's files and not ``force``.
        agents.benchmark.run_folder.FolderBusy: another run is writing to ``out_dir``.
        agents.benchmark.outputs.WriteError: an output could not be written (a full disk),
            naming the file; the folder keeps its earlier files.
    """
    from vrloco_env.techniques import canonical_name, get_technique

    baseline = canonical_name(baseline)
    axes = (tasks, policies, sensors, techniques, conditions)
    if grids is not None and any(a is not None for a in axes):
        raise ValueError(
            "grids replaces tasks, policies, sensors, techniques and conditions: "
            "give one or the other"
        )
    if grids is None:
        if all(a is None for a in axes):
            grids = DEFAULT_GRIDS
        else:
            if sensors is None and techniques is None:
                techniques = DEFAULT_TECHNIQUES
            grids = [
                Grid(
                    tuple(DEFAULT_TASKS if tasks is None else tasks),
                    tuple(DEFAULT_POLICIES if policies is None else policies),
                    (*(technique_for_preset(s) for s in sensors or ()), *(techniques or ())),
                    tuple((DEFAULT_CONDITION,) if conditions is None else conditions),
                )
            ]
    grids = list(grids)
    if not grids:
        raise ValueError("grids must hold at least one Grid")
    for g in grids:
        _check_grid(g)
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 0:
        raise ValueError(
            f"batch_size must be an integer >= 0 (0: one episode at a time), got {batch_size!r}"
        )
    if backend not in ("local", "ray"):
        raise ValueError(f"backend must be 'local' or 'ray', got {backend!r}")
    if address is not None and backend != "ray":
        raise ValueError(f"address={address!r} needs backend 'ray' (--backend ray)")
    if backend == "ray":
        from agents.benchmark.backends import import_ray

        import_ray()  # not installed: the install hint, before any work

    cells = list(dict.fromkeys(c for g in grids for c in g.cells()))
    _adapt_users(cells)
    keys = {} if out_dir is None else _episode_keys(cells, episodes, seed, True)
    meta = {
        "seed": seed,
        "episodes": episodes,
        "workers": workers,
        "batch_size": batch_size,
        "grids": [
            {
                "tasks": list(g.tasks),
                "policies": list(g.policies),
                "techniques": [get_technique(t).name for t in g.techniques],
                "conditions": list(g.conditions),
            }
            for g in grids
        ],
    }
    how = {
        "workers": workers,
        "batch_size": batch_size,
        "progress": progress,
        "print_table": print_table,
        "backend": backend,
        "address": address,
        "baseline": baseline,
        "json_path": json_path,
    }
    if out_dir is None:
        return _play(cells, keys, meta, None, **how)
    with RunFolder(out_dir, *_run_identity(cells, episodes, seed), force=force) as folder:
        return _play(cells, keys, meta, folder, **how)


def _adapt_users(cells: list[Cell]) -> None:
    """Adapt the shipped user to every cell that plays it adapted (``ppo@STEPS``), here and
    before any episode, one cell after the other (cached: a rerun reuses them), so that the
    workers only load them."""
    from agents.benchmark.episodes import _env
    from agents.benchmark.policies import SHIPPED, _split, adaptation, adapted_path

    for c in cells:
        base, suffix = _split(c.policy)
        if not base.startswith(SHIPPED + "@"):
            continue
        steps, seed = adaptation(c.policy)
        if steps > 0:
            env = _env(c.task, c.technique, c.population, c.condition)
            adapted_path(env, steps, suffix, seed)


def _play(
    cells: list[Cell],
    keys: dict[tuple[Cell, int], str],
    meta: dict[str, Any],
    folder: RunFolder | None,
    *,
    workers: int,
    batch_size: int,
    progress: bool,
    print_table: bool,
    backend: str,
    address: str | None,
    baseline: str,
    json_path: Path | str | None,
) -> list[dict[str, Any]]:
    """Play the grid's episodes that ``folder``'s ``.resume`` lacks, keeping each job's there
    as it finishes; then the rows, the tables and the outputs (see :func:`run_benchmark`)."""
    episodes, seed = meta["episodes"], meta["seed"]
    store = None if folder is None else EpisodeStore(folder.path / ".resume")
    results: dict[tuple[Cell, int], EpisodeStats] = {}
    infos: dict[tuple[Cell, int], dict] = {}
    if store is not None:
        found = store.load()
        for ci, key in keys.items():
            if key in found:
                results[ci], infos[ci] = found[key]
        if results:
            print(f"resuming: {len(results)} of {len(keys)} episodes found in {store.folder}")
    jobs = _split_jobs(cells, episodes, seed, folder is not None, batch_size, workers, set(results))
    base = {(c.task, c.policy, c.condition): c for c in cells if c.technique_name == baseline}
    rows_of = _CellRows(episodes, results, infos, base)
    interrupted = False
    try:
        rows_of.add(list(results))  # resumed episodes
        if jobs and warm_start.announce() and backend == "local" and workers > 1:
            _compile_shared_kernels(jobs[0])
        for done in _run_jobs(jobs, workers, progress, backend, address):
            for cell, index, stats, reset_info in done:
                results[(cell, index)], infos[(cell, index)] = stats, reset_info
            if store is not None:
                store.save({keys[(c, i)]: (st, ri) for c, i, st, ri in done})
            rows_of.add([(c, i) for c, i, _, _ in done])  # while the other jobs run
    except KeyboardInterrupt:  # Ctrl-C: keep the cells that finished
        interrupted = True
    all_cells = cells
    cells = [c for c in cells if all((c, i) in results for i in range(episodes))]
    if interrupted:
        print(
            f"interrupted: {len(cells)} of {len(all_cells)} cells finished; writing those"
            + (
                ""
                if store is None
                else f" (rerun with the same --out to resume: "
                f"{len(results)} episodes kept in {store.folder})"
            )
        )

    rows = []
    order = {name: k for k, name in enumerate(dict.fromkeys(c.technique_name for c in cells))}
    cells = sorted(cells, key=lambda c: order[c.technique_name])  # grouped by technique
    for c in cells:
        row = {
            "task": c.task,
            "policy": c.policy,
            "technique": c.technique_name,
            "condition": c.condition,
            "sensors": c.sensors,
            **rows_of.summary(c),
            "vs_baseline": rows_of.versus(c),
        }
        rows.append({k: _round(row[k]) for k in ROW_KEYS})
    pairs = pair_results(rows) if baseline == BASELINE_TECHNIQUE else []
    if print_table and rows:
        show_table(rows, seed, baseline=baseline)
        show_pairs(pairs, baseline)
    written = []
    if folder is not None:
        written = folder.replace(
            lambda out: _write_outputs(out, rows, meta, pairs, cells, results, baseline)
        )
    if json_path is not None:
        written.append(write_json(Path(json_path), rows, meta))
    for line in written_summary(written):
        print(line)
    if interrupted:
        raise KeyboardInterrupt
    warm_start.mark_compiled()
    if store is not None:
        store.clear()  # the grid is complete: nothing to resume
    return rows


def _compile_shared_kernels(job: tuple) -> None:
    """Play ``job``'s first episode alone in this process, unrecorded, before the local workers
    fork: that compiles the kernels every cell shares (the user's motion, the sensors, the world,
    the scripted user's planner) once, so that each worker starts with them loaded and compiles
    only the estimators of its own cells, beside the others (:mod:`agents.benchmark.warm_start`).
    One user, so the serial builds the workers use, and no thread pool that would make them
    spawn."""
    cell, _, seed, _ = job[0][0]
    run_cell_episode(cell, seed, False)


def _write_outputs(
    out: Path,
    rows: list[dict[str, Any]],
    meta: dict[str, Any],
    pairs: list,
    cells: list[Cell],
    results: dict,
    baseline: str = BASELINE_TECHNIQUE,
) -> list[Path]:
    """The run's files in ``out``: the CSV, the JSON, ``pairs.json`` where there are pairs, the
    figures of each cell's first episode and of the grid, and ``report.html``
    (:func:`agents.benchmark.report.write_report`: all of these in one page, with each cell's traced
    episodes replayed)."""
    written = [
        write_csv(out / "benchmark.csv", rows),
        write_json(out / "benchmark.json", rows, meta),
    ]
    if pairs:
        with atomic_path(out / "pairs.json") as tmp:
            write_pairs(tmp, pairs)
        written.append(out / "pairs.json")
    for c in cells:
        written += draw_cell(out, c, results[(c, 0)])
    if rows:
        written += draw_grid(
            out,
            rows,
            {
                cell_name(row): [results[(c, i)] for i in range(meta["episodes"])]
                for c, row in zip(cells, rows, strict=True)
            },
        )
    written.append(
        write_report(out / "report.html", rows, meta, pairs, cells, results, written, baseline)
    )
    return written


def _run_identity(cells: list[Cell], episodes: int, seed: int) -> tuple[str, str]:
    """The run's identity in its output folder (its cells, episodes and first seed: the same
    command gives the same one) and a few words on it
    (:class:`agents.benchmark.run_folder.RunFolder`)."""
    names = [[c.task, c.policy, c.technique_name, c.condition] for c in cells]
    run = hashlib.sha256(json.dumps([names, episodes, seed]).encode()).hexdigest()[:16]
    techniques = list(dict.fromkeys(c.technique_name for c in cells))
    shown = ", ".join(techniques[:4]) + (", ..." if len(techniques) > 4 else "")
    return run, (
        f"{len(cells)} cell{'s' if len(cells) > 1 else ''} of {shown}; {episodes} "
        f"episode{'s' if episodes > 1 else ''} from seed {seed}"
    )


class _CellRows:
    """The statistics of each cell's row, worked out as soon as the cell's episodes (and its
    baseline's, for the paired comparison) are all in, so that the main process does them while
    the workers play the other cells (or when asked for, if not yet).

    Args:
        episodes: episodes per cell.
        results, infos: the grid's ``(cell, index)`` -> stats and reset info, as they come in.
        base: ``(task, policy, condition)`` -> the baseline technique's cell.
    """

    def __init__(self, episodes: int, results: dict, infos: dict, base: dict) -> None:
        self.episodes, self.results, self.infos, self.base = episodes, results, infos, base
        self.count: dict[Cell, int] = {}  # episodes in, per cell
        self._summary: dict[Cell, dict] = {}
        self._versus: dict[Cell, dict] = {}
        self._values: dict[tuple, list] = {}  # (cell, late, early) -> its episodes' values
        self.waiting: list[Cell] = []  # finished cells whose baseline is not

    def add(self, played: list[tuple[Cell, int]]) -> None:
        """Count the episodes ``played`` in; work out the rows they complete."""
        for c, _ in played:
            self.count[c] = self.count.get(c, 0) + 1
            if self.count[c] == self.episodes:
                self.summary(c)
                self.waiting.append(c)
        for c in [c for c in self.waiting if self._ready(c)]:
            self.waiting.remove(c)
            self.versus(c)

    def window(self, c: Cell) -> tuple[int, int]:
        """The cell's step-matching window (:func:`step_window`)."""
        st = self.results[(c, 0)]
        return step_window(self.infos[(c, 0)], st.elapsed_s / max(st.steps, 1))

    def summary(self, c: Cell) -> dict:
        """The cell's :func:`summarize` (all its episodes must be in)."""
        if c not in self._summary:
            self._summary[c] = summarize(self._episodes(c), *self.window(c))
        return self._summary[c]

    def versus(self, c: Cell) -> dict | None:
        """The paired comparison with the cell's baseline
        (:func:`agents.benchmark.paired.paired_p_values`; None for the baseline itself, or where it
        is not in the grid or not finished)."""
        ref = self.base.get((c.task, c.policy, c.condition))
        if ref is None or ref is c or not self._ready(c):
            return None
        if c not in self._versus:
            self._versus[c] = compare_values(self._values_of(ref, c), self._values_of(c, c))
        return self._versus[c]

    def _episodes(self, c: Cell) -> list[EpisodeStats]:
        return [self.results[(c, i)] for i in range(self.episodes)]

    def _ready(self, c: Cell) -> bool:
        ref = self.base.get((c.task, c.policy, c.condition))
        return ref is None or self.count.get(ref, 0) == self.episodes

    def _values_of(self, c: Cell, window_of: Cell) -> list:
        """``c``'s episodes' values (:func:`agents.benchmark.paired.episode_values`) in the
        step-matching window of ``window_of`` (:func:`agents.benchmark.paired.paired_p_values` uses
        the compared cell's for both), each worked out once."""
        late, early = self.window(window_of)
        key = (c, late, early)
        if key not in self._values:
            self._values[key] = [episode_values(e, late, early) for e in self._episodes(c)]
        return self._values[key]


def _check_grid(grid: Grid) -> None:
    """A clear error for an empty axis, an unknown name or a repeated one."""
    from vrloco_env.techniques import get_technique

    for name in ("tasks", "policies", "techniques", "conditions"):
        if not getattr(grid, name):
            raise ValueError(f"{name} must name at least one entry")
    for t in grid.tasks:
        get_task(t)  # raises with the registered names
    for p in grid.policies:
        check_policy_name(p)
    for k in grid.conditions:
        get_condition(k, "conditions")  # raises with the registered names
    if len(set(grid.conditions)) != len(grid.conditions):
        raise ValueError(f"conditions must not repeat a name, got {', '.join(grid.conditions)}")
    names = [get_technique(t).name for t in grid.techniques]  # raises with the valid names
    if len(set(names)) != len(names):
        raise ValueError(f"techniques must not repeat a name, got {', '.join(names)}")


def _episode_keys(
    cells: list[Cell], episodes: int, seed: int, figures: bool
) -> dict[tuple[Cell, int], str]:
    """The resume key of every episode of the grid (:func:`agents.benchmark.resume.episode_key`,
    with each cell's :func:`agents.benchmark.resume.cell_inputs`)."""
    from vrloco_env.techniques import get_technique

    fp = source_fingerprint()
    inputs = cell_inputs(cells)
    return {
        (c, i): episode_key(
            fp,
            c.task,
            c.policy,
            get_technique(c.technique),
            seed + i,
            figures and i < REPLAY_EPISODES,
            c.condition,
            inputs[c],
        )
        for c in cells
        for i in range(episodes)
    }


def _split_jobs(
    cells: list[Cell],
    episodes: int,
    seed: int,
    figures: bool,
    batch_size: int,
    workers: int,
    skip: set[tuple[Cell, int]] = frozenset(),  # type: ignore[assignment]
) -> list[tuple]:
    """The grid's jobs. One episode per job for ``batch_size`` 0; else the episodes of the cells
    that share a task, a technique and a population (one vector env), taken episode index by
    episode index across those cells, in jobs of about four batches, cut smaller where there
    would be fewer jobs than workers. A ``module:attr`` policy's cells form groups of their own.
    With ``figures`` the first :data:`agents.benchmark.report.REPLAY_EPISODES` episodes of each cell
    keep their trace (the figures draw the first, the report replays them all)."""

    def ep(c: Cell, i: int) -> tuple[Cell, int, int, bool]:
        return (c, i, seed + i, figures and i < REPLAY_EPISODES)

    if batch_size == 0:
        return [([ep(c, i)], 0) for c in cells for i in range(episodes) if (c, i) not in skip]
    groups: dict[tuple, list[Cell]] = {}
    for c in cells:  # a user's own policy gets jobs of its own: it may not take batches
        own = c.policy if ":" in c.policy else ""
        groups.setdefault((c.task, c.technique_name, c.population, c.condition, own), []).append(c)
    per_job = 4 * batch_size
    total = max(1, len(cells) * episodes - len(skip))
    per_job = max(1, min(per_job, math.ceil(total / workers)))
    jobs = []
    for members in groups.values():
        order = [ep(c, i) for i in range(episodes) for c in members if (c, i) not in skip]
        for lo in range(0, len(order), per_job):
            jobs.append((order[lo : lo + per_job], batch_size))
    return jobs


def _run_jobs(
    jobs: list, workers: int, progress: bool, backend: str = "local", address: str | None = None
):
    """Yield each job's ``[(cell, index, stats, reset_info), ...]`` as it finishes, in any order,
    with a progress bar over the episodes: in ``workers`` local processes, or for ``backend``
    ``"ray"`` as Ray tasks on the cluster at ``address``
    (:func:`agents.benchmark.backends.run_jobs_ray`)."""
    if backend == "ray":
        from agents.benchmark.backends import run_jobs_ray

        yield from run_jobs_ray(jobs, address, progress)
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    columns = (
        "[progress.description]{task.description}",
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
    )
    with Progress(*columns, disable=not progress, transient=False) as bar:
        task = bar.add_task("episodes", total=sum(len(job[0]) for job in jobs))
        if not jobs:
            return
        if workers == 1 or len(jobs) == 1:
            for job in jobs:
                done = _job(job)
                yield done
                bar.advance(task, len(done))
            return
        n_workers = min(workers, len(jobs))
        context = _pool_context()
        claimed = context.Array("q", len(jobs))  # episodes claimed per job, all 0
        pool = ProcessPoolExecutor(
            max_workers=n_workers,
            mp_context=context,
            initializer=_init_worker,
            initargs=(claimed, _worker_threads(n_workers)),
        )
        try:
            # every batched job once, then helpers: a worker with nothing left to start joins
            # the jobs still running, the last started first (a finished one returns at once)
            shared = [(*job, k) if job[1] else job for k, job in enumerate(jobs)]
            helpers = [job for job in shared[::-1] if job[1]] * (n_workers - 1)
            futures = [pool.submit(_job, job) for job in shared + helpers]
            for f in as_completed(futures):
                done = f.result()
                yield done
                bar.advance(task, len(done))
        except BaseException:  # Ctrl-C (or an error): stop the workers now, not after the grid
            for process in list(getattr(pool, "_processes", {}).values()):
                process.terminate()
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown()


def _round(v: Any) -> Any:
    """Metrics to 10 significant digits (an interval's ends too): the printed figures, and a
    guard against last-bit differences of summed floats."""
    if isinstance(v, tuple):
        return tuple(_round(x) for x in v)
    if isinstance(v, float) and math.isfinite(v):
        return float(f"{v:.10g}")
    return v

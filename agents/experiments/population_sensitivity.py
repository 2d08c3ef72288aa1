"""How the benchmark's discriminating-power verdicts depend on the populations' chosen ranges.

The user populations (:mod:`vrloco_env.user.population`) hold ``(lo, hi)`` ranges that no
evidence sets, labelled choices in their docs (:data:`vrloco_env.user.population.CHOICE_FIELDS`:
how often users glance, look around and nod, how long a glance lasts, how far they look down,
the stride's head yaw, the step impact, the drift of stepping in place). This experiment reruns
the default benchmark with each of those ranges pinned to either end and reports which technique
pairs still separate.

For each choice field and each end (``lo``, ``hi``), every population the default grid uses
(:data:`agents.benchmark.grid.DEFAULT_GRIDS`: ``typical``, ``nodders``, ``gaze_scanners``) is
replaced by a copy whose range for that field is ``(lo, lo)`` or ``(hi, hi)`` of its own range
(:func:`collapse`; a population whose range is already one value stays as it is). The copy is
registered for the run under a derived name (``typical__nod_rate_hz__lo``, :func:`derived_name`)
and the grid's policies name it (``goal_seeker+typical__nod_rate_hz__lo``), inside
:func:`registered`, which always restores :data:`~vrloco_env.user.population.POPULATIONS`. A name
of its own keeps the envs the benchmark keeps per process, by population name, apart from the
registered population's. Each user draws every range field from the same uniform number
whatever its range (:class:`vrloco_env.user.behaviour.GazeBehaviour`), so a collapsed field
changes that field's values and nothing else the users draw.

Each row is the default grid on the default benchmark's seeds (``0`` to ``episodes - 1``; 60 by
default, the benchmark's reporting seeds) through :func:`agents.benchmark.run_benchmark`, and its
verdicts are :func:`agents.benchmark.discrimination.pair_results` of its rows, as the benchmark's
``pairs.json``; the unmodified populations give the reference row. Nothing is tuned on this
experiment.

The local workers of :func:`~agents.benchmark.run_benchmark` fork from this process and so see
the derived populations; where the benchmark would spawn them instead (a process that has
started numba's threads, :func:`agents.benchmark.jobs._pool_context`), a run plays in this
process (one worker).

Outputs: a table on stdout (100 columns: field, end, the values used per population, the pairs
that separate and that separate on an outcome, the pairs whose verdicts differ from the
reference row); ``json_path``: ``{"reference": R, "rows": [R, ...], "settings": {...}}``, each R
``{"field", "end", "values": {population: [lo, hi]}, "separate", "on_outcome", "pairs": {pair:
{"separates", "on_outcome", "metrics"}}, "differs"}`` (the reference's field and end None, its
values and differs empty); ``out_dir`` (default: a new temporary folder): one JSON file per row
with the benchmark's rows and full pair results, reused by a rerun with the same ``out_dir``,
sources and settings.

Run: ``vrloco experiment population-sensitivity [--json F] [--episodes N] [--fields a,b]
[--out DIR]``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import sys
import tempfile
import textwrap
import time
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

from agents.benchmark.discrimination import PAIRS, Pair, pair_results
from agents.benchmark.grid import DEFAULT_EPISODES, DEFAULT_GRIDS, Grid
from agents.benchmark.outputs import json_safe
from vrloco_env.user.population import CHOICE_FIELDS, POPULATIONS, Population, get_population

__all__ = [
    "ENDS",
    "SEED",
    "collapse",
    "derived_name",
    "format_table",
    "grid_populations",
    "registered",
    "run_population_sensitivity",
]

#: The ends a choice range collapses to.
ENDS = ("lo", "hi")
#: The first episode's seed: the default benchmark's (its reporting seeds).
SEED = 0
#: The table's width in columns.
WIDTH = 100


def derived_name(population: str, field: str, end: str) -> str:
    """The name a population collapsed at ``field``'s ``end`` is registered under (an
    identifier, as a policy's ``+<population>`` suffix must be)."""
    return f"{population}__{field}__{end}"


def collapse(population: Population, field: str, end: str) -> Population:
    """``population`` with ``field``'s range ``(lo, hi)`` collapsed to ``(lo, lo)`` (``end``
    ``"lo"``) or ``(hi, hi)`` (``"hi"``), named :func:`derived_name`; ``population`` itself where
    the range is one value already (``(0, 0)``: the field does nothing for it).

    Raises:
        ValueError: a field not in :data:`~vrloco_env.user.population.CHOICE_FIELDS`, or an end
            not in :data:`ENDS`.
    """
    if field not in CHOICE_FIELDS:
        raise ValueError(f"field={field!r}: must be one of {', '.join(CHOICE_FIELDS)}")
    if end not in ENDS:
        raise ValueError(f"end={end!r}: must be one of {', '.join(ENDS)}")
    lo, hi = getattr(population, field)
    if lo == hi:
        return population
    value = lo if end == "lo" else hi
    return dataclasses.replace(
        population, name=derived_name(population.name, field, end), **{field: (value, value)}
    )


def _suffix(policy: str) -> str | None:
    """A policy spec's registered ``+<population>``, else None."""
    base, sep, suffix = policy.rpartition("+")
    return suffix if sep and base and suffix in POPULATIONS else None


def grid_populations(grids: Sequence[Grid] = DEFAULT_GRIDS) -> tuple[str, ...]:
    """The populations the grids' policies name (``+<population>``), in order of first use."""
    names = (_suffix(p) for g in grids for p in g.policies)
    return tuple(dict.fromkeys(n for n in names if n is not None))


@contextlib.contextmanager
def registered(populations: Iterable[Population]) -> Iterator[None]:
    """Register ``populations`` in :data:`~vrloco_env.user.population.POPULATIONS` under their
    names for the ``with`` block; the dict is restored afterwards, also where the block raises.

    Raises:
        ValueError: a name already registered for another definition (checked before any is
            registered).
    """
    populations = list(populations)
    for p in populations:
        if p.name in POPULATIONS and POPULATIONS[p.name] != p:
            raise ValueError(f"population {p.name!r} is registered already, as another one")
    saved = dict(POPULATIONS)
    try:
        for p in populations:
            POPULATIONS[p.name] = p
        yield
    finally:
        POPULATIONS.clear()
        POPULATIONS.update(saved)


def _rename(policy: str, names: dict[str, str]) -> str:
    """``policy`` with its ``+<population>`` replaced as ``names`` says."""
    suffix = _suffix(policy)
    if suffix is None or suffix not in names:
        return policy
    return f"{policy.rpartition('+')[0]}+{names[suffix]}"


def _local_workers(workers: int) -> int:
    """``workers`` where the benchmark's pool would fork from this process (the workers then see
    the populations registered here), else 1 (play in this process)."""
    from agents.benchmark.jobs import _pool_context

    return workers if _pool_context().get_start_method() == "fork" else 1


def _run_row(
    grids: Sequence[Grid], copies: dict[str, Population], episodes: int, workers: int
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The benchmark rows of ``grids`` with each population of ``copies`` (original name ->
    copy) in place of the original, and the pair results under the original pairs' names."""
    from agents.benchmark import run_benchmark

    names = {k: p.name for k, p in copies.items() if p.name != k}
    run_grids = [
        dataclasses.replace(g, policies=tuple(_rename(p, names) for p in g.policies)) for g in grids
    ]
    pairs = [dataclasses.replace(pair, policy=_rename(pair.policy, names)) for pair in PAIRS]
    original: dict[str, Pair] = {p.name: o for p, o in zip(pairs, PAIRS, strict=True)}
    with registered(p for k, p in copies.items() if p.name != k):
        rows = run_benchmark(
            grids=run_grids,
            episodes=episodes,
            seed=SEED,
            workers=_local_workers(workers),
            progress=False,
            print_table=False,
        )
        results = pair_results(rows, tuple(pairs))
    for r in results:
        pair = original[r["pair"]]
        r["pair"], r["policy"] = pair.name, pair.policy
    return rows, results


def _row_key(grids: Sequence[Grid], copies: dict[str, Population], episodes: int) -> str:
    """What a row's results depend on: the package's sources, the grids, the populations used
    (their definitions) and the episodes."""
    from agents.benchmark.resume import source_fingerprint

    text = repr(
        (
            source_fingerprint(),
            [repr(g) for g in grids],
            sorted((k, repr(p)) for k, p in copies.items()),
            episodes,
            SEED,
        )
    )
    return hashlib.sha256(text.encode()).hexdigest()


def _summary(
    field: str | None,
    end: str | None,
    values: dict[str, list[float]],
    results: list[dict[str, Any]],
) -> dict[str, Any]:
    """A row of the JSON (see the module docstring), without ``differs``."""
    return {
        "field": field,
        "end": end,
        "values": values,
        "separate": sum(r["separates"] for r in results),
        "on_outcome": sum(r["on_outcome"] for r in results),
        "pairs": {
            r["pair"]: {
                "separates": r["separates"],
                "on_outcome": r["on_outcome"],
                "metrics": list(r["metrics"]),
            }
            for r in results
        },
    }


def _differs(row: dict[str, Any], reference: dict[str, Any]) -> list[str]:
    """The pairs whose verdicts differ from the reference's: ``"pair: yes->no"`` (separates),
    ``"pair: outcome no->yes"`` (separates on an outcome)."""

    def yn(v: bool) -> str:
        return "yes" if v else "no"

    out = []
    for name, ref in reference["pairs"].items():
        got = row["pairs"].get(name)
        if got is None:
            continue
        if got["separates"] != ref["separates"]:
            out.append(f"{name}: {yn(ref['separates'])}->{yn(got['separates'])}")
        if got["on_outcome"] != ref["on_outcome"]:
            out.append(f"{name}: outcome {yn(ref['on_outcome'])}->{yn(got['on_outcome'])}")
    return out


def run_population_sensitivity(
    json_path: Path | None = None,
    episodes: int = DEFAULT_EPISODES,
    fields: Sequence[str] | None = None,
    out_dir: Path | None = None,
    workers: int = 2,
    grids: Sequence[Grid] = DEFAULT_GRIDS,
) -> dict[str, Any]:
    """Run the reference and every (field, end) row, print the table, write the JSON.

    Args:
        json_path: write the result here (see the module docstring).
        episodes: episodes per cell (>= 1; seeds ``0`` to ``episodes - 1``).
        fields: the choice fields to collapse (default: every one of
            :data:`~vrloco_env.user.population.CHOICE_FIELDS`, in that order).
        out_dir: the folder for each row's benchmark rows and pair results, reused by a rerun
            with the same sources and settings (default: a new temporary folder).
        workers: the benchmark's worker processes (>= 1).
        grids: the grids each row runs (default: the default benchmark's).

    Returns:
        ``{"reference": R, "rows": [R, ...], "settings": {...}}`` (the JSON's content).

    Raises:
        ValueError: a bad argument, naming it.
    """
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes={episodes!r}: must be an integer >= 1")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers={workers!r}: must be an integer >= 1")
    fields = tuple(CHOICE_FIELDS if fields is None else fields)
    for f in fields:
        if f not in CHOICE_FIELDS:
            raise ValueError(
                f"fields: {f!r} is no choice field; the choice fields are "
                f"{', '.join(CHOICE_FIELDS)}"
            )
    if not fields or len(set(fields)) != len(fields):
        raise ValueError(f"fields={','.join(fields)!r}: must name at least one field, each once")
    grids = list(grids)
    pops = grid_populations(grids)
    if not pops:
        raise ValueError("grids: no policy names a population (+<population>)")
    base = {n: get_population(n) for n in pops}
    out = Path(tempfile.mkdtemp(prefix="vrloco-sensitivity-")) if out_dir is None else out_dir
    out.mkdir(parents=True, exist_ok=True)

    plan: list[tuple[str | None, str | None, dict[str, Population]]] = [(None, None, base)]
    plan += [(f, e, {n: collapse(p, f, e) for n, p in base.items()}) for f in fields for e in ENDS]
    done: dict[str, tuple[list, list]] = {}  # row key -> (rows, pair results)
    summaries = []
    for k, (field, end, copies) in enumerate(plan):
        label = "reference" if field is None else f"{field}__{end}"
        key = _row_key(grids, copies, episodes)
        path = out / f"{label}.json"
        try:
            stored = json.loads(path.read_text()) if path.is_file() else None
        except (OSError, ValueError):  # unreadable or not JSON: run the row again
            stored = None
        start = time.monotonic()
        if key in done:  # no population changed: the reference's
            rows, results = done[key]
            how = "same populations as the reference"
        elif stored is not None and stored.get("key") == key:
            rows, results = stored["benchmark_rows"], stored["pairs"]
            how = f"reused {path}"
        else:
            rows, results = _run_row(grids, copies, episodes, workers)
            how = f"{time.monotonic() - start:.0f} s"
            path.write_text(
                json.dumps(
                    json_safe(
                        {
                            "key": key,
                            "field": field,
                            "end": end,
                            "populations": {n: repr(p) for n, p in copies.items()},
                            "benchmark_rows": rows,
                            "pairs": results,
                        }
                    ),
                    indent=1,
                )
            )
        done.setdefault(key, (rows, results))
        values = {n: list(getattr(p, field)) for n, p in copies.items()} if field else {}
        summaries.append(_summary(field, end, values, results))
        print(
            f"population-sensitivity: {k + 1}/{len(plan)} {label} ({how})",
            file=sys.stderr,
            flush=True,
        )
    reference, rows = summaries[0], summaries[1:]
    reference["differs"] = []
    for row in rows:
        row["differs"] = _differs(row, reference)
    result = {
        "reference": reference,
        "rows": rows,
        "settings": {
            "episodes": episodes,
            "seeds": [SEED, SEED + episodes - 1],
            "grids": [dataclasses.asdict(g) for g in grids],
            "default_grid": grids == list(DEFAULT_GRIDS),
            "populations": list(pops),
            "fields": list(fields),
            "ends": list(ENDS),
            "out_dir": str(out),
            "pairs_of": len(reference["pairs"]),
            "note": "seeds from 0 are the benchmark's reporting seeds; nothing is tuned on this "
            "experiment; verdicts as agents.benchmark.discrimination.pair_results",
        },
    }
    print(format_table(result))
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(json_safe(result), indent=2))
        print(f"wrote {json_path}")
    return result


def _short(pair: str) -> str:
    """A pair's technique, its name's first word."""
    return pair.split(" ", 1)[0]


def _value(v: float) -> str:
    return f"{v:g}"


def format_table(result: dict[str, Any], width: int = WIDTH) -> str:
    """The result as a table ``width`` columns wide (the last column wrapped)."""
    settings, reference = result["settings"], result["reference"]
    pops = settings["populations"]
    n_pairs = settings["pairs_of"]
    seeds = settings["seeds"]
    cols = (15, 4, 18, 5, 5)  # field, end, values, separate, on outcome
    rest = max(20, width - sum(cols))
    grid = "the default benchmark grid" if settings["default_grid"] else "the given grid"
    intro = (
        f"Population sensitivity: {grid} on seeds {seeds[0]}-{seeds[1]} "
        f"(the benchmark's reporting seeds; nothing is tuned on this experiment), each "
        f"choice range collapsed to its low or high end in every population; values: "
        f"{'/'.join(pops)}; sep and out: pairs that separate (on an outcome) of {n_pairs}; "
        f"differs: verdicts unlike the reference row's (outcome: on an outcome)."
    )
    lines = textwrap.wrap(intro, width)
    head = (
        f"{'field':<{cols[0]}}{'end':<{cols[1]}}{'values':<{cols[2]}}{'sep':>{cols[3]}}"
        f"{'out':>{cols[4]}}  differs"
    )
    lines += [head, "-" * width]

    def add(field: str, end: str, values: str, row: dict[str, Any], differs: list[str]) -> None:
        text = ", ".join(differs) or "-"
        wrapped = textwrap.wrap(text, rest - 2, break_on_hyphens=False) or ["-"]
        lines.append(
            f"{field:<{cols[0]}}{end:<{cols[1]}}{values:<{cols[2]}}"
            f"{row['separate']:>{cols[3]}}{row['on_outcome']:>{cols[4]}}  {wrapped[0]}"
        )
        lines.extend(" " * (sum(cols) + 2) + w for w in wrapped[1:])

    add("reference", "-", "as defined", reference, [])
    for row in result["rows"]:
        values = "/".join(_value(row["values"][p][0]) for p in pops)
        differs = [_short(d) + d[d.index(":") :] for d in row["differs"]]
        add(row["field"], row["end"], values, row, differs)
    lines.append("")
    lines.append("reference verdicts (separates / on an outcome):")
    ref = [
        f"{_short(name)} {'yes' if v['separates'] else 'no'}/{'yes' if v['on_outcome'] else 'no'}"
        for name, v in reference["pairs"].items()
    ]
    lines += textwrap.wrap(", ".join(ref), width, initial_indent="  ", subsequent_indent="  ")
    return "\n".join(lines)

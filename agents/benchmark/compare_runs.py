"""Two benchmark runs side by side: each technique pair's verdict and the metrics it rests on.

``python -m agents.benchmark.compare_runs A B`` reads ``pairs.json`` from the two output folders
(for example the same grid and seeds on two versions of the code) and prints, for every pair of
either run, whether it separates (and on an outcome) in each, then every metric on which either
run finds a difference in the expected direction at the benchmark's threshold, with the paired
mean difference and p-value of each run. ``--markdown`` prints a Markdown table for the docs.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

__all__ = ["compare_pairs", "load_pairs", "main"]


def load_pairs(folder: str | Path) -> dict[str, dict[str, Any]]:
    """``pairs.json`` of a benchmark output folder, by pair name; a clear error if absent."""
    path = Path(folder) / "pairs.json"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no pairs.json (is {folder} a benchmark output folder?)")
    entries = json.loads(path.read_text(encoding="utf-8"))
    if not isinstance(entries, list) or not all(
        isinstance(e, dict) and "pair" in e for e in entries
    ):
        raise ValueError(f"{path}: expected a list of pairs, each with a 'pair' name")
    return {e["pair"]: e for e in entries}


def _fmt(x: float | None) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{x:+.3g}"


def _p(x: float | None) -> str:
    return "–" if x is None else (f"{x:.1e}" if x < 1e-3 else f"{x:.3f}")


def compare_pairs(a: dict[str, dict], b: dict[str, dict]) -> list[dict[str, Any]]:
    """One record per pair in either run: its verdicts in both and the metrics where either
    run's verdict is ``"for"`` or ``"against"`` (the expected direction or its opposite)."""
    out = []
    for name in [*a, *(k for k in b if k not in a)]:
        pa, pb = a.get(name), b.get(name)
        metrics = []
        tasks = sorted({*(pa or {}).get("tasks", {}), *(pb or {}).get("tasks", {})})
        for task in tasks:
            ma = (pa or {}).get("tasks", {}).get(task, {})
            mb = (pb or {}).get("tasks", {}).get(task, {})
            for key in [*ma, *(k for k in mb if k not in ma)]:
                va, vb = ma.get(key, {}), mb.get(key, {})
                if not (va.get("verdict") or vb.get("verdict")):
                    continue
                metrics.append(
                    {
                        "metric": f"{task}:{key}",
                        "a": {k: va.get(k) for k in ("diff", "p", "verdict")},
                        "b": {k: vb.get(k) for k in ("diff", "p", "verdict")},
                    }
                )
        out.append(
            {
                "pair": name,
                "a": None
                if pa is None
                else {"separates": pa["separates"], "on_outcome": pa["on_outcome"]},
                "b": None
                if pb is None
                else {"separates": pb["separates"], "on_outcome": pb["on_outcome"]},
                "metrics": metrics,
            }
        )
    return out


def _verdict(v: dict | None) -> str:
    if v is None:
        return "absent"
    if not v["separates"]:
        return "no"
    return "yes, on an outcome" if v["on_outcome"] else "yes"


def _mark(v: dict) -> str:
    return {"for": "", "against": " (against)", None: " (n.s.)"}[v.get("verdict")]


def render(records: list[dict], label_a: str, label_b: str, markdown: bool = False) -> str:
    """The comparison as plain text or a Markdown table."""
    lines = []
    if markdown:
        lines += [
            f"| pair | metric | {label_a}: diff (p) | {label_b}: diff (p) |",
            "|---|---|---|---|",
        ]
    for r in records:
        head = f"{_verdict(r['a'])} -> {_verdict(r['b'])}"
        if markdown:
            lines.append(f"| **{r['pair']}** | separates: {head} | | |")
        else:
            lines.append(f"{r['pair']}: separates {head}")
        for m in r["metrics"]:
            cells = [f"{_fmt(v['diff'])} ({_p(v['p'])}){_mark(v)}" for v in (m["a"], m["b"])]
            if markdown:
                lines.append(f"| | {m['metric']} | {cells[0]} | {cells[1]} |")
            else:
                row = f"    {m['metric']:<40} {label_a}: {cells[0]:<28} {label_b}: {cells[1]}"
                lines.append(row)
    for label, key in ((label_a, "a"), (label_b, "b")):
        present = [r[key] for r in records if r[key] is not None]
        n_sep = sum(v["separates"] for v in present)
        n_out = sum(v["separates"] and v["on_outcome"] for v in present)
        lines.append(f"{label}: {n_sep} of {len(present)} pairs separate, {n_out} on an outcome")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m agents.benchmark.compare_runs", description=__doc__.splitlines()[0]
    )
    parser.add_argument("a", help="the first run's output folder (holding pairs.json)")
    parser.add_argument("b", help="the second run's output folder")
    parser.add_argument("--labels", default="A,B", help="names of the two runs (default: A,B)")
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = parser.parse_args(argv)
    labels = args.labels.split(",")
    if len(labels) != 2 or not all(labels):
        parser.error(f"--labels {args.labels!r}: give two names separated by a comma")
    try:
        records = compare_pairs(load_pairs(args.a), load_pairs(args.b))
    except (OSError, ValueError) as err:
        parser.exit(2, f"error: {err}\n")
    print(render(records, *labels, markdown=args.markdown))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The generated reference pages of the documentation site, written from the live registries.

``python -m agents.reference_pages [--out docs]`` writes:

* ``tasks/index.md`` — every registered task (:data:`vrloco_env.tasks.TASKS`) in one table, and
  what the tasks share (the room, the reward and environment configuration);
* ``tasks/<task>.md`` — one page per task: its Gymnasium id, what the user must do, the
  observation (every field with its entries, shape, dtype, bounds, scale and meaning), the action,
  the reward terms, success, termination and truncation, the task's configuration dataclass, its
  ``info`` keys, and a picture of its room for one reset (``img/tasks/<task>.png``);
* ``techniques.md`` — every registered technique (:data:`vrloco_env.techniques.TECHNIQUES`, the
  list ``vrloco techniques`` prints) with its stages, every stage registry of
  :mod:`estimators.stages`, and the IMU presets;
* ``populations.md`` — the user populations (:data:`vrloco_env.user.population.POPULATIONS`, each
  field with its value per population and the note its docstring gives), the physical-room
  conditions of the benchmark (:data:`agents.benchmark.conditions.CONDITIONS`), the head camera's
  imaging conditions (:data:`vrloco_env.sensors.camera.CONDITIONS`) and the scripted users
  (:data:`agents.scripted.POLICIES`).

The prose comes from the docstrings, class attributes and dataclass fields of the code it
describes, so a page changes when the code does. Where no docstring states a rule (the reward sum,
termination and truncation, which :meth:`vrloco_env.core.LocoCore.step` computes; Interact's hand
hold; a few task ``info`` keys), the text is written here from the code, names the code it
describes and takes its numbers from the live configuration defaults. The output is deterministic:
registries keep their registration order, other lists are sorted, and no page holds a date. The
pictures use a fixed seed, matplotlib's ``Agg`` backend and no PNG metadata.
``tests/test_agents/test_reference_pages.py`` regenerates the pages and compares them with the
committed ones.

Modules: :mod:`~agents.reference_pages.common` (the command, the header, the pictures' seed,
the source papers), :mod:`~agents.reference_pages.docstrings` (reading docstrings),
:mod:`~agents.reference_pages.markdown` (Markdown text and tables), one module per page family
(:mod:`~agents.reference_pages.tasks`, :mod:`~agents.reference_pages.techniques`,
:mod:`~agents.reference_pages.populations`), :mod:`~agents.reference_pages.pictures` (the task
pictures); this module writes them all (:func:`pages`, :func:`write_pages`, :func:`main`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from agents.reference_pages.common import (
    COMMAND,
    HEADER,
    PICTURE_DPI,
    PICTURE_SEED,
    SEED_PAPERS,
)
from agents.reference_pages.pictures import picture_paths, write_pictures
from agents.reference_pages.populations import populations_page
from agents.reference_pages.tasks import task_page, tasks_index
from agents.reference_pages.techniques import techniques_page

__all__ = [
    "COMMAND",
    "HEADER",
    "PICTURE_DPI",
    "PICTURE_SEED",
    "SEED_PAPERS",
    "main",
    "pages",
    "picture_paths",
    "populations_page",
    "task_page",
    "tasks_index",
    "techniques_page",
    "write_pages",
    "write_pictures",
]


def pages() -> dict[str, str]:
    """Every generated Markdown page: path relative to the docs folder -> text."""
    from vrloco_env.tasks import task_names

    out = {"tasks/index.md": tasks_index()}
    for name in task_names():
        out[f"tasks/{name}.md"] = task_page(name)
    out["techniques.md"] = techniques_page()
    out["populations.md"] = populations_page()
    return out


def write_pages(out: Path) -> list[Path]:
    """Write :func:`pages` under ``out``; returns the written files."""
    written = []
    for rel, text in pages().items():
        path = out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
        written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog=COMMAND, description="Write the generated reference pages and the task pictures."
    )
    parser.add_argument("--out", type=Path, default=Path("docs"), help="docs folder (docs)")
    parser.add_argument("--no-pictures", action="store_true", help="write the Markdown only")
    args = parser.parse_args(argv)
    written = write_pages(args.out)
    if not args.no_pictures:
        written += write_pictures(args.out)
    for path in written:
        print(path)
    return 0

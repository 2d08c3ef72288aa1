"""Docstring text as Markdown (Sphinx roles as code, lists, literal blocks), configuration
values as code, pipe tables and the page layout."""

from __future__ import annotations

import dataclasses
import re
import textwrap
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from agents.reference_pages.common import HEADER
from agents.reference_pages.docstrings import doc_paragraphs, field_docs


def _roles(text: str, config: Any = None) -> str:
    """Sphinx roles and reST literals as Markdown code; ``:attr:`Config.field``` of the task's
    ``config`` class also gets the field's default."""

    def role(m: re.Match) -> str:
        target = m.group(2) or m.group(3)
        shown = m.group(1) if m.group(2) else target
        if shown.startswith("~"):
            shown = shown[1:].rsplit(".", 1)[-1]
        code = f"`{shown}`"
        parts = target.lstrip("~").split(".")
        if config is not None and len(parts) >= 2 and parts[-2] == config.__name__:
            defaults = {f.name: f.default for f in dataclasses.fields(config)}
            if parts[-1] in defaults:
                code += f" (default {_value(defaults[parts[-1]])})"
        return code

    text = re.sub(r":[a-z]+:`(?:([^`<]+?) <([^`>]+)>|([^`]+))`", role, text)
    return text.replace("``", "`")


def _escape_html(text: str) -> str:
    """``<`` outside code spans as ``&lt;`` (Markdown would take ``<name>`` for a tag)."""
    parts = text.split("`")
    for i in range(0, len(parts), 2):
        parts[i] = parts[i].replace("<", "&lt;")
    return "`".join(parts)


def to_md(text: str, config: Any = None) -> str:
    """One paragraph of docstring text as one line of Markdown."""
    return _escape_html(_roles(" ".join(text.split()), config))


def md_blocks(text: str, config: Any = None) -> list[str]:
    """The paragraphs of a docstring as Markdown blocks: bullet and numbered lists kept as lists,
    ``::`` literal blocks as fenced code, other paragraphs on one line each."""
    out: list[str] = []
    literal = False
    for block in doc_paragraphs(text):
        if literal:
            out.append("```python\n" + textwrap.dedent(block) + "\n```")
            literal = False
            continue
        lines = block.splitlines()
        if re.match(r"\s*([*-]|\d+\.) ", lines[0]):
            items: list[str] = []
            for line in lines:
                m = re.match(r"([*-]|\d+\.) (.*)", line)
                if m and not line.startswith(" "):
                    items.append(("-" if m.group(1) in "*-" else m.group(1)) + " " + m.group(2))
                else:
                    items[-1] += " " + line.strip()
            out.append("\n".join(to_md(i, config) for i in items))
        else:
            text_line = to_md(block, config)
            if text_line.endswith("::"):
                text_line = text_line[:-1]
                literal = True
            out.append(text_line)
    return out


def _value(value: Any) -> str:
    """A configuration value as code (numbers with ``g`` formatting)."""
    return f"`{_plain(value)}`"


def _plain(value: Any) -> str:
    if isinstance(value, bool | np.bool_):
        return str(bool(value))
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        text = f"{float(value):.6g}"
        return text if re.search(r"[.einf]", text) else text + ".0"
    if isinstance(value, tuple):
        inner = ", ".join(_plain(v) for v in value)
        return f"({inner},)" if len(value) == 1 else f"({inner})"
    if isinstance(value, str):
        return repr(value)
    if dataclasses.is_dataclass(value):
        return f"{type(value).__name__}(...)"
    return repr(value)


def _default(f: dataclasses.Field) -> str:
    if f.default is not dataclasses.MISSING:
        return _value(f.default)
    if f.default_factory is not dataclasses.MISSING:
        made = f.default_factory()
        if dataclasses.is_dataclass(made):
            return f"`{type(made).__name__}()`"
        return _value(made)
    return "required"


def _type_name(f: dataclasses.Field) -> str:
    return f"`{f.type if isinstance(f.type, str) else getattr(f.type, '__name__', f.type)}`"


def _cell(text: Any) -> str:
    """Text for a pipe-table cell: one line, ``|`` escaped outside code spans (inside them
    Python-Markdown's table splitter leaves it alone)."""
    parts = " ".join(str(text).split()).split("`")
    for i in range(0, len(parts), 2):
        parts[i] = parts[i].replace("|", "\\|")
    return "`".join(parts)


def md_table(headers: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    """A GitHub-style pipe table."""
    lines = ["| " + " | ".join(_cell(h) for h in headers) + " |", "|" + "---|" * len(headers)]
    for row in rows:
        lines.append("| " + " | ".join(_cell(c) if str(c) else " " for c in row) + " |")
    return "\n".join(lines)


def make_page(blocks: Iterable[str]) -> str:
    """A page: the header line, then the blocks separated by blank lines."""
    return "\n\n".join([HEADER, *(b.rstrip() for b in blocks if b)]) + "\n"


def _config_table(cls: type, config: Any = None) -> str:
    """Field, type, default and meaning of every field of a dataclass."""
    docs = field_docs(cls)
    rows = [
        (f"`{f.name}`", _type_name(f), _default(f), to_md(docs.get(f.name, ""), config))
        for f in dataclasses.fields(cls)
    ]
    return md_table(("field", "type", "default", "meaning"), rows)


def qualname(obj: Any) -> str:
    return f"{obj.__module__}.{obj.__qualname__}"

"""Reading the code's docstrings: paragraphs, first sentences, ``* name — text`` bullets,
Google-style sections and the documentation of each dataclass field."""

from __future__ import annotations

import ast
import inspect
import itertools
import re
import sys
import textwrap
from typing import Any

_SECTION = re.compile(
    r"^(Args|Arguments|Returns|Raises|Attributes|Yields|Examples?|Notes|Class attributes[^:]*):$"
)


# ------------------------------------------------------------------------------ docstrings
def _doc(obj: Any) -> str:
    """``obj``'s docstring, dedented ("" without one)."""
    return inspect.getdoc(obj) or ""


def _module_doc(obj: Any) -> str:
    """The docstring of the module that defines ``obj``."""
    return _doc(sys.modules[obj.__module__])


def doc_paragraphs(text: str) -> list[str]:
    """The blank-line separated blocks of ``text``, without Google-style sections."""
    kept = []
    for line in text.splitlines():
        if _SECTION.match(line.strip()) and not line.startswith(" "):
            break
        kept.append(line)
    blocks = re.split(r"\n\s*\n", "\n".join(kept).strip())
    return [b for b in blocks if b.strip()]


def _first(text: str) -> str:
    """The first paragraph of ``text``, on one line."""
    paragraphs = doc_paragraphs(text)
    return " ".join(paragraphs[0].split()) if paragraphs else ""


def _sentence(text: str) -> str:
    """The first sentence of a one-line text (up to the first ". " after a word of 3 letters)."""
    m = re.search(r"(?<=[a-z)\]`0-9]{3})\.(\s|$)", text)
    return text[: m.start() + 1] if m else text


def _bullets(text: str) -> dict[str, str]:
    """The ``* ``name`` — text`` (or ``* ``name``: text``) bullets of a docstring: name -> text
    on one line, in order."""
    found: dict[str, str] = {}
    key = None
    for line in text.splitlines():
        m = re.match(r"\* (?:``([^`]+)``|([a-z][\w ]*?))(?: —|:) (.*)", line)
        if m:
            key = m.group(1) or m.group(2)
            found[key] = m.group(3)
        elif key is not None and line.startswith("  ") and line.strip():
            found[key] += " " + line.strip()
        else:
            key = None
    return found


def _section(text: str, name: str) -> dict[str, str]:
    """The entries of a Google-style section (``Attributes:``) of a docstring: name -> text on
    one line; an entry ``a, b, c: text`` gives each of its names the text."""
    lines = text.splitlines()
    try:
        start = next(i for i, line in enumerate(lines) if line.strip() == f"{name}:")
    except StopIteration:
        return {}
    base = len(lines[start]) - len(lines[start].lstrip())
    entries: list[str] = []
    indent = None
    for line in lines[start + 1 :]:
        if not line.strip():
            continue
        depth = len(line) - len(line.lstrip())
        if depth <= base:
            break
        if indent is None:
            indent = depth
        if depth == indent:
            entries.append(line.strip())
        elif entries:
            entries[-1] += " " + line.strip()
    found: dict[str, str] = {}
    for entry in entries:
        m = re.match(r"([\w]+(?:,\s*[\w]+)*):\s*(.*)", entry)
        if m:
            for field_name in re.split(r",\s*", m.group(1)):
                found[field_name] = m.group(2)
    return found


def field_docs(cls: type) -> dict[str, str]:
    """What each field of a dataclass is: its ``Attributes:`` entry, or the string literal after
    its definition in the class body."""
    docs = _section(_doc(cls), "Attributes")
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError):
        return docs
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    for node, after in itertools.pairwise(body):
        if (
            isinstance(node, ast.AnnAssign)
            and isinstance(node.target, ast.Name)
            and isinstance(after, ast.Expr)
            and isinstance(after.value, ast.Constant)
            and isinstance(after.value.value, str)
        ):
            docs.setdefault(node.target.id, " ".join(after.value.value.split()))
    return docs

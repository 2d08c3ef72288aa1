"""The markdown reference of the stage protocols, ``docs/protocols.md``.

:func:`protocol_reference` renders, for every stage of :mod:`estimators.stages`, each member's
signature and docstring, how the environment calls it, and the output contract that
:class:`estimators.checked.CheckedStage` enforces, from the same classes and constants, so the
documentation is the check. Regenerate with ``python -m estimators.stage_docs >
docs/protocols.md``.
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Callable
from typing import Any

from estimators.registry import Registry, call_text, is_method, protocol_member, protocol_members
from estimators.stages import (
    ANGLE_TOLERANCE_RAD,
    ATTITUDE,
    HAND,
    LOCOMOTION,
    POSITION_BOUND_M,
    QUAT_NORM_TOLERANCE,
    STEERING,
    STEPS,
)

__all__ = ["protocol_reference"]


_REGENERATE = ".venv/bin/python -m estimators.stage_docs > docs/protocols.md"


def _annotation(value: Any) -> str:
    if value is inspect.Parameter.empty:
        return ""
    return value if isinstance(value, str) else inspect.formatannotation(value)


def _signature_text(function: Callable[..., Any]) -> str:
    signature = inspect.signature(function)
    params = []
    for p in list(signature.parameters.values())[1:]:  # without self
        text = p.name + (f": {_annotation(p.annotation)}" if _annotation(p.annotation) else "")
        if p.default is not inspect.Parameter.empty:
            text += f" = {p.default!r}"
        params.append(text)
    returns = _annotation(signature.return_annotation)
    return f"({', '.join(params)})" + (f" -> {returns}" if returns else "")


def _doc(obj: Any) -> str:
    """``obj``'s docstring on one line, its Sphinx roles as code."""
    text = " ".join((inspect.getdoc(obj) or "").split())
    return re.sub(r":[a-z]+:`~?([^`]+)`", r"`\1`", text)


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def _stage_reference(registry: Registry) -> list[str]:
    protocol, contract = registry.protocol, registry.contract
    built_in = ", ".join(f"`{k}` ({v})" for k, v in registry.describe().items())
    lines = [
        f"## `{registry.stage}`: `{protocol.__module__}.{protocol.__name__}`",
        "",
        _doc(protocol),
        "",
        f"Built as {contract.factory}. Built in: {built_in}.",
        "",
        "Members (each must exist; each method must accept the call shown):",
        "",
    ]
    annotations: dict[str, Any] = {}
    for base in reversed(protocol.__mro__):
        annotations.update(inspect.get_annotations(base))
    for name in protocol_members(protocol):
        obj = protocol_member(protocol, name)
        if isinstance(obj, property):
            returns = _annotation(inspect.signature(obj.fget).return_annotation)
            lines.append(f"- `{name}` (property) `-> {returns}`: {_doc(obj)}")
        elif is_method(obj):
            called = contract.calls.get(name)
            how = f", called as `{call_text(name, called)}`" if called else ""
            lines.append(f"- `{name}{_signature_text(obj)}`{how}: {_doc(obj)}")
        else:
            lines.append(f"- `{name}: {_annotation(annotations.get(name))}` (attribute)")
    if contract.notes:
        lines += ["", contract.notes]
    lines += [
        "",
        f"`update` returns {contract.returns}. For a plug-in, every step:",
        "",
        "| output | shape | kind | meaning | rules |",
        "|---|---|---|---|---|",
    ]
    for out in contract.outputs:
        shape = "(" + ", ".join(map(str, out.shape)) + ("," if len(out.shape) == 1 else "") + ")"
        rules = "; ".join(r.text for r in contract.rules if r.output == out.name) or "-"
        lines.append(
            f"| `{out.name}` | {shape} | {out.kind} | {_cell(out.meaning)} | {_cell(rules)} |"
        )
    lines += ["", "Optional members:", ""]
    lines += [f"- `{member}`: {meaning}" for member, meaning in contract.optional]
    return lines


def protocol_reference() -> str:
    """The markdown reference of every stage protocol (``docs/protocols.md``): each member's
    signature and docstring, how the environment calls it, and the output contract that
    :class:`CheckedStage` enforces, rendered from the same classes and constants."""
    lines = [
        "# Stage protocols",
        "",
        "<!-- Generated from estimators/stages.py; do not edit. Regenerate with:",
        f"     {_REGENERATE} -->",
        "",
        "What a plug-in for each estimation stage must have and return, exactly as the "
        "environment checks it. A stage field of `EstimatorConfig` takes a registered name, "
        '`"package.module:attr"` or `"path/to/file.py:attr"` naming a class or factory, a '
        "class or factory itself, or an object with a `build(...)` method. Every stage is "
        "batched over B users and streaming.",
        "",
        "When a plug-in is built (`gym.make`), it must have every member listed for its "
        "stage, and each method must accept the call the environment makes; the error names "
        "what is missing. A plug-in that is not one of the package's own stages is then wrapped "
        "once in `estimators.checked.CheckedStage`, which checks every result of `update` "
        "against its stage's table: first the structure and each output's shape, then the "
        "rules, in order. A broken rule is a `StageError` naming the stage, the plug-in, the "
        "first offending user and sample (or frame), its value and the rule; an exception "
        "inside `reset` or `update` is a `StageError` naming the stage and the plug-in.",
        "",
        "Sizes: B users, N IMU samples of one control step, M Kinect frames of one control "
        "step. Tolerances: `QUAT_NORM_TOLERANCE` = "
        f"{QUAT_NORM_TOLERANCE:g}, `ANGLE_TOLERANCE_RAD` = {ANGLE_TOLERANCE_RAD:g} rad, "
        f"`POSITION_BOUND_M` = {POSITION_BOUND_M:g} m.",
        "",
        "Examples, one working plug-in per stage, each run by `tests/test_examples.py`: "
        "`examples/custom_estimator.py` (attitude), `examples/custom_steps.py`, "
        "`examples/custom_hand.py`, `examples/custom_steering.py`, "
        "`examples/custom_locomotion.py`.",
    ]
    for registry in (ATTITUDE, STEPS, HAND, STEERING, LOCOMOTION):
        lines += ["", *_stage_reference(registry)]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":  # python -m estimators.stage_docs > docs/protocols.md
    import sys

    from estimators import stage_docs

    sys.stdout.write(stage_docs.protocol_reference())

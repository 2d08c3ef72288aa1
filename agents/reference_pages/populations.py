"""The populations page, ``populations.md``: the user populations field by field, the
benchmark's physical-room conditions, the head camera's imaging conditions and the scripted
users."""

from __future__ import annotations

import dataclasses
import re
import sys
from typing import Any

import numpy as np

from agents.reference_pages.docstrings import (
    _bullets,
    _doc,
    _first,
    _module_doc,
    doc_paragraphs,
    field_docs,
)
from agents.reference_pages.markdown import (
    _plain,
    _value,
    make_page,
    md_blocks,
    md_table,
    qualname,
    to_md,
)


def _range(value: Any) -> str:
    if isinstance(value, tuple) and len(value) == 2 and value[0] == value[1]:
        return _plain(value[0])
    if isinstance(value, tuple) and len(value) == 2:
        return f"{_plain(value[0])} – {_plain(value[1])}"
    return _plain(value).strip("'")


def _kind(doc: str) -> str:
    """What a population field's note says its value is: a source, a fit, a bound or a
    choice (as it words it), or "" where it does not say."""
    kinds = re.findall(r"\b(?:[Aa]n?|engineering) (source|fit|bound|choice)", doc)
    return ", ".join(dict.fromkeys(kinds))


def _populations() -> list[str]:
    import vrloco_env.user.population as population
    from agents.benchmark.variability import VariabilityParams
    from vrloco_env.user.population import POPULATIONS, Population

    names = list(POPULATIONS)
    docs = field_docs(Population)
    agent = field_docs(VariabilityParams)
    overview = [
        (
            f"`{n}`",
            to_md(p.description),
            "yes" if p.moves_head else "no",
            "yes" if p.gaze else "no",
            "yes" if p.variability else "no",
        )
        for n, p in POPULATIONS.items()
    ]
    rows = []
    for f in dataclasses.fields(Population):
        if f.name in ("name", "description"):
            continue
        values = [_range(getattr(POPULATIONS[n], f.name)) for n in names]
        doc = docs.get(f.name, "")
        if f.name in agent and "VariabilityParams" in doc:  # the agent side's own field docs
            doc = f"{agent[f.name].rstrip('.')}; {doc}"
        rows.append((f"`{f.name}`", *values, _kind(doc), to_md(doc)))
    bullets = _bullets(_doc(population))
    return [
        "## Populations",
        to_md(_first(_doc(population))) + " `gym.make(id, population=NAME)` sets the env side; "
        'a policy spec `"<policy>+NAME"` (`vrloco benchmark --policies goal_seeker+NAME`) sets '
        "the agent-side variability, and the env side too where the population moves the head.",
        "How the values were chosen, and what they were calibrated against: "
        "[population evidence](populations-evidence.md).",
        md_table(
            (
                "population",
                "description",
                "env side (head, body)",
                "adds `head_on_torso`",
                "agent-side variability",
            ),
            overview,
        ),
        "\n".join(f"- `{k}`: {to_md(v)}" for k, v in bullets.items() if k in POPULATIONS),
        "### Fields",
        "A `lo – hi` value is a uniform range drawn per user and episode; a single number is the "
        "same for every user. *Kind* is what the field's note calls its value (a source, a fit, "
        "a bound or a choice), where it says; the note is the field's docstring in "
        "`vrloco_env/user/population.py`.",
        md_table(("field", *(f"`{n}`" for n in names), "kind", "evidence or choice"), rows),
    ]


def _conditions() -> list[str]:
    import agents.benchmark.conditions as conditions
    from vrloco_env.sensors.camera.spec import LIGHTING as CAMERA
    from vrloco_env.sensors.camera.spec import CameraSpec

    notes = _bullets(_doc(conditions))
    rows = []
    for name, c in conditions.CONDITIONS.items():
        dipoles = []
        for d in c.magnetic_disturbances:
            text = (
                f"dipole at ({', '.join(f'{v:g}' for v in d.position)}) m, moment "
                f"{float(np.linalg.norm(d.moment)):.3g} A m^2"
            )
            if any(d.velocity):
                text += (
                    f", moving at ({', '.join(f'{v:g}' for v in d.velocity)}) m/s "
                    f"from {d.moving[0]:g} s to {d.moving[1]:g} s"
                )
            dipoles.append(text)
        default = " (default)" if name == conditions.DEFAULT_CONDITION else ""
        rows.append(
            (
                f"`{name}`{default}",
                to_md(c.description),
                "; ".join(dipoles) or "none",
                to_md(notes.get(name, "")),
            )
        )
    ideal = CameraSpec(name="ideal")
    camera_docs = field_docs(CameraSpec)
    changed: list[str] = []
    camera_rows = []
    for name in sorted(CAMERA):
        spec = CAMERA[name]
        diffs = [
            f.name
            for f in dataclasses.fields(CameraSpec)
            if f.name != "name" and getattr(spec, f.name) != getattr(ideal, f.name)
        ]
        changed += [d for d in diffs if d not in changed]
        camera_rows.append(
            (
                f"`{name}`",
                ", ".join(
                    f"`{d}` = {_value(getattr(spec, d))} (ideal {_value(getattr(ideal, d))})"
                    for d in diffs
                )
                or "the default `CameraSpec`",
            )
        )
    return [
        "## Conditions",
        "### Physical room (`vrloco benchmark --conditions`)",
        to_md(_first(_doc(conditions))) + " " + to_md(doc_paragraphs(_doc(conditions))[1]),
        md_table(("condition", "description", "magnetic disturbances", "evidence or choice"), rows),
        "### Head camera imaging conditions (lighting)",
        "`SensorConfig(head_camera=camera_spec(NAME))` (`vrloco_env.sensors.camera.spec`), "
        'used with `pose_source="visual_inertial"` and by `vrloco experiment vio`. '
        + to_md(_first(_doc(CameraSpec)))
        + " "
        + to_md(_first(_module_doc(CameraSpec))),
        md_table(("condition", "fields that differ from the default `CameraSpec`"), camera_rows),
        "\n".join(f"- `{k}`: {to_md(camera_docs.get(k, ''))}" for k in sorted(changed)),
    ]


def _policies() -> list[str]:
    import agents.benchmark.policies as policies
    from agents.scripted import POLICIES

    rows = [
        (f"`{name}`", f"`{qualname(cls)}`", to_md(_first(_doc(cls))))
        for name, cls in POLICIES.items()
    ]
    return [
        "## Scripted policies",
        to_md(_first(_doc(sys.modules["agents.scripted"]))),
        md_table(("policy", "class", "what it does"), rows),
        "`vrloco benchmark --policies` (`agents.benchmark.policies`) takes these and more. "
        + md_blocks("\n\n".join(doc_paragraphs(_doc(policies))[1:]))[0],
        *md_blocks("\n\n".join(doc_paragraphs(_doc(policies))[1:]))[1:],
    ]


def populations_page() -> str:
    """The Markdown page of the populations, the conditions and the scripted policies."""
    return make_page(
        [
            "# Populations, conditions and scripted users",
            "Who walks (the simulated human's head and body, and the agent-side variability), "
            "where (the physical room and the camera's light) and how a scripted user decides.",
            *_populations(),
            *_conditions(),
            *_policies(),
        ]
    )

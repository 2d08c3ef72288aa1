"""The techniques page, ``techniques.md``: every registered technique with its stages, every
stage registry with the papers its entries implement, and the IMU presets."""

from __future__ import annotations

import dataclasses
import re
from typing import Any

from agents.reference_pages.common import SEED_PAPERS
from agents.reference_pages.docstrings import (
    _doc,
    _first,
    _module_doc,
    _sentence,
    doc_paragraphs,
    field_docs,
)
from agents.reference_pages.markdown import make_page, md_blocks, md_table, qualname, to_md


def _papers(description: str, factory: Any) -> str:
    """The papers a stage implements: the seed papers its registry entry, its class or the first
    paragraph of its module name, then the first citation of its module's ``Source:`` paragraph
    or a parenthesised citation in the module's opening paragraphs."""
    module = _module_doc(factory)
    text = " ".join([description, _first(_doc(factory)), _first(module)])
    found = [
        f"seed {n} ({SEED_PAPERS.get(n, 'a source paper')})"
        for n in sorted(set(re.findall(r"\b[Ss]eed (\d{3})", text)))
    ]
    paragraphs = [" ".join(p.split()) for p in doc_paragraphs(module)]
    source = next((p for p in paragraphs if re.match(r"Sources?: ", p)), None)
    cite = None
    if source is not None:
        cite = source.split(": ", 1)[1].split("; ")[0]
    else:
        for p in paragraphs[:2]:
            m = re.search(r"\(([A-Z]\. [^()]*?\b(?:19|20)\d\d)\b", p)
            if m:
                cite = m.group(1)
                break
    if cite is not None and cite.split(",")[0].split()[-1] not in " ".join(found):
        year = re.search(r"\b(?:19|20)\d\d\b", cite)
        cite = cite[: year.end()] if year else cite
        found.append(cite + ")" * (cite.count("(") - cite.count(")")))
    return "; ".join(to_md(f) for f in found) or "—"


def _stage_table(field: str) -> list[str]:
    from estimators import stages
    from vrloco_env.config import EstimatorConfig

    registry = getattr(stages, field.upper())
    default = getattr(EstimatorConfig(), field)
    rows = []
    for name, description in registry.describe().items():
        factory = registry.factory(name)
        kind = "class" if isinstance(factory, type) else "factory"
        sentence = to_md(_sentence(_first(_doc(factory))))
        what = (
            sentence
            if sentence.lower().startswith(description.lower())
            else (to_md(description) + ". " + sentence)
        )
        mark = " (default)" if name == default else ""
        rows.append(
            (
                f"`{name}`{mark}",
                f"`{qualname(factory)}` ({kind})",
                what,
                _papers(description, factory),
            )
        )
    protocol = registry.protocol
    return [
        f"### `{field}`",
        f"`EstimatorConfig({field}=NAME)`; built as `factory{registry.signature}`; protocol "
        f"`{qualname(protocol)}`: {to_md(_first(_doc(protocol)))}",
        md_table(("name", "class", "what it is", "paper"), rows),
    ]


def _iron_fields() -> list[str]:
    """The fields of :class:`~vrloco_env.sensors.imu.spec.ImuSpec` beside its name and its three
    sensors: the magnetometer's calibration residuals."""
    from vrloco_env.sensors.imu.spec import ImuSpec, SensorSpec

    return [
        f.name
        for f in dataclasses.fields(ImuSpec)
        if f.name != "name" and f.type not in ("SensorSpec", SensorSpec)
    ]


def _imu_tables() -> tuple[str, str]:
    """The presets' sensors (one row per preset and sensor) and their magnetic calibration."""
    from vrloco_env.sensors.imu.spec import PRESETS, ImuSpec, SensorSpec

    numeric = [f.name for f in dataclasses.fields(SensorSpec) if f.name not in ("label", "unit")]
    sensors = [f.name for f in dataclasses.fields(ImuSpec) if f.type in ("SensorSpec", SensorSpec)]
    iron = _iron_fields()
    rows, iron_rows = [], []
    for name in sorted(PRESETS):
        spec = PRESETS[name]
        for sensor in sensors:
            s = getattr(spec, sensor)
            rows.append((f"`{name}`", sensor, s.unit, *(f"{getattr(s, k):.4g}" for k in numeric)))
        iron_rows.append((f"`{name}`", *(f"{getattr(spec, k):.4g}" for k in iron)))
    return (
        md_table(("preset", "sensor", "unit", *numeric), rows),
        md_table(("preset", *iron), iron_rows),
    )


def techniques_page() -> str:
    """The Markdown page of the techniques and the stage registries."""
    import vrloco_env.techniques as techniques
    from estimators import stages
    from vrloco_env.config import POSE_SOURCES, STAGE_FIELDS, EnvConfig, EstimatorConfig
    from vrloco_env.sensors.imu.spec import ImuSpec, SensorSpec

    base = EstimatorConfig()
    rows = []
    for name, tech in techniques.TECHNIQUES.items():
        e = tech.estimators
        cells = []
        for field in STAGE_FIELDS:
            label = f"`{e.label(field)}`"
            cells.append(f"**{label}**" if getattr(e, field) != getattr(base, field) else label)
        preset = f"`{tech.sensor_preset}`"
        if tech.sensor_preset != techniques.TECHNIQUES[techniques.DEFAULT_TECHNIQUE].sensor_preset:
            preset = f"**{preset}**"
        other = [
            f.name
            for f in dataclasses.fields(EstimatorConfig)
            if f.name not in STAGE_FIELDS and getattr(e, f.name) != getattr(base, f.name)
        ]
        extra = f" (also changes {', '.join(other)})" if other else ""
        default = " (default)" if name == techniques.DEFAULT_TECHNIQUE else ""
        rows.append(
            (
                f"`{name}`{default}",
                preset,
                *cells,
                f"{e.step_length:g} m",
                to_md(tech.description) + extra,
            )
        )
    pose_doc = field_docs(EnvConfig)["pose_source"]
    papers = md_table(("seed", "paper"), [(f"seed {k}", v) for k, v in SEED_PAPERS.items()])
    blocks = [
        "# Techniques",
        *md_blocks(_doc(techniques)),
        "`vrloco techniques` prints the same list (`agents/cli/overview.py`). A technique is a "
        "sensor preset plus one choice per estimation stage; the stages in **bold** differ from "
        f"the default technique, `{techniques.DEFAULT_TECHNIQUE}`. To write a stage of your own, "
        "see [the stage protocols](protocols.md).",
        "## Registered techniques",
        md_table(("technique", "sensor preset", *STAGE_FIELDS, "step length", "description"), rows),
        "The pose source is not part of a technique: it is `EnvConfig.pose_source` "
        f"({', '.join(f'`{p}`' for p in POSE_SOURCES)}; `gym.make(id, pose_source=NAME)`), "
        + to_md(pose_doc),
        "## Stage registries",
        to_md(_first(_doc(stages))) + " Each stage field of `EstimatorConfig` takes a name below, "
        '`"package.module:attr"` naming your own class or factory, or an object with a '
        "`build(...)` method ([stage protocols](protocols.md)). The papers are the ones the "
        "stage's registry entry and docstrings cite; the project's source papers (\"seed NNN\"):",
        papers,
    ]
    for field in STAGE_FIELDS:
        blocks += _stage_table(field)
    sensor_docs, imu_docs = field_docs(SensorSpec), field_docs(ImuSpec)
    sensor_table, iron_table = _imu_tables()
    blocks += [
        "## IMU presets",
        "`sensor_preset=NAME` or `SensorConfig(imu=NAME)` (`vrloco_env.sensors.imu.spec.PRESETS`"
        f"). {to_md(_first(_doc(ImuSpec)))} Per sensor, in the sensor's unit "
        "(`vrloco_env/sensors/imu/spec.py` gives the datasheet or estimate behind each value):",
        sensor_table,
        "\n".join(
            f"- `{k}`: {to_md(v)}" for k, v in sensor_docs.items() if k not in ("label", "unit")
        ),
        "The magnetometer's calibration residuals, drawn per user at reset:",
        iron_table,
        "\n".join(f"- `{k}`: {to_md(imu_docs.get(k, ''))}" for k in _iron_fields()),
    ]
    return make_page(blocks)

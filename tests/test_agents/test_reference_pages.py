"""The generated reference pages (:mod:`agents.reference_pages`): the committed pages under
``docs/`` are exactly what the generator writes from the live registries, every registered task,
technique, stage, population, condition and scripted policy is on them, and each task picture is
a small valid PNG."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import pytest

from agents import reference_pages as rp

DOCS = Path(__file__).resolve().parents[2] / "docs"
REGENERATE = f"run `.venv/bin/{rp.COMMAND}` from the repository root to regenerate them"
MAX_PICTURE_BYTES = 60 * 1024


@pytest.fixture(scope="module")
def generated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The pages and pictures, written into a fresh folder by the command's own entry point."""
    out = tmp_path_factory.mktemp("docs")
    assert rp.main(["--out", str(out)]) == 0
    return out


def _markdown(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): p.read_text(encoding="utf-8")
        for p in sorted(folder.rglob("*.md"))
    }


def test_committed_pages_are_the_generated_ones(generated: Path) -> None:
    pages = _markdown(generated)
    assert set(pages) == set(rp.pages())
    missing = [rel for rel in pages if not (DOCS / rel).is_file()]
    assert not missing, f"generated pages missing from docs/: {missing}; {REGENERATE}"
    stale = [rel for rel, text in pages.items() if (DOCS / rel).read_text(encoding="utf-8") != text]
    assert not stale, f"docs/ pages differ from the generator's: {stale}; {REGENERATE}"
    for rel, text in pages.items():
        assert text.startswith(rp.HEADER + "\n"), rel


def test_pages_are_deterministic(generated: Path) -> None:
    assert rp.pages() == _markdown(generated)


def test_every_registered_name_appears(generated: Path) -> None:
    from agents.benchmark.conditions import CONDITIONS
    from agents.scripted import POLICIES
    from estimators import stages
    from vrloco_env.config import STAGE_FIELDS
    from vrloco_env.sensors.camera.spec import LIGHTING as CAMERA
    from vrloco_env.sensors.imu.spec import PRESETS
    from vrloco_env.tasks import env_id, task_names
    from vrloco_env.techniques import TECHNIQUES
    from vrloco_env.user.population import POPULATIONS

    pages = _markdown(generated)
    index = pages["tasks/index.md"]
    for name in task_names():
        assert f"`{env_id(name)}`" in index and f"({name}.md)" in index, name
        assert f"`{env_id(name)}`" in pages[f"tasks/{name}.md"], name
        assert f"../img/tasks/{name}.png" in pages[f"tasks/{name}.md"], name
    techniques = pages["techniques.md"]
    for name in TECHNIQUES:
        assert f"| `{name}`" in techniques, name
    for field in STAGE_FIELDS:
        for name in getattr(stages, field.upper()).names():
            assert f"| `{name}`" in techniques, (field, name)
    for name in PRESETS:
        assert f"| `{name}`" in techniques, name
    assert "(protocols.md)" in techniques
    populations = pages["populations.md"]
    for names in (POPULATIONS, CONDITIONS, CAMERA, POLICIES):
        for name in names:
            assert f"| `{name}`" in populations, name
    assert "(populations-evidence.md)" in populations


def _png_size(data: bytes) -> tuple[int, int]:
    """Width and height of a PNG, after checking its signature and every chunk's CRC."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG signature"
    at, kinds = 8, []
    while at < len(data):
        (length,) = struct.unpack(">I", data[at : at + 4])
        kind, body = data[at + 4 : at + 8], data[at + 8 : at + 8 + length]
        (crc,) = struct.unpack(">I", data[at + 8 + length : at + 12 + length])
        assert zlib.crc32(kind + body) == crc, f"bad CRC in a {kind!r} chunk"
        kinds.append(kind)
        at += 12 + length
    assert kinds[0] == b"IHDR" and kinds[-1] == b"IEND" and b"IDAT" in kinds
    width, height = struct.unpack(">II", data[16:24])
    return width, height


@pytest.mark.parametrize("folder", ["committed", "generated"])
def test_pictures_are_small_valid_pngs(folder: str, generated: Path) -> None:
    root = DOCS if folder == "committed" else generated
    for rel in rp.picture_paths():
        path = root / rel
        assert path.is_file(), f"{path} is missing; {REGENERATE}"
        data = path.read_bytes()
        width, height = _png_size(data)
        assert 100 <= width <= 1000 and 100 <= height <= 1000, (rel, width, height)
        assert len(data) <= MAX_PICTURE_BYTES, (rel, len(data))

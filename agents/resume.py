"""Finished episodes of a benchmark grid, kept on disk so that an interrupted run resumes.

While ``vrloco benchmark`` runs, every finished job (a batch of episodes) is written to
``<out>/.resume/<job>.pkl``; a rerun with the same ``--out`` loads them and runs only the
episodes that are missing, then removes the folder once the grid is complete. An episode is
found again only under the same key: its task, policy, technique (the full definition),
seed, whether it keeps a trace, and a fingerprint of the package's source files, so results of
other code or other settings are never mixed in. The batch size and the worker count are not
part of the key: they do not change an episode's numbers.

A file that cannot be read (a run killed mid-write, a file from another version) is reported in
one line and its episodes run again; writes go to a temporary file first and are renamed into
place, so a crash never leaves a half-written result under a valid name.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import shutil
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from agents.conditions import DEFAULT_CONDITION

__all__ = ["EpisodeStore", "episode_key", "source_fingerprint"]

_PACKAGES = ("estimators", "vrloco_env", "agents")


def source_fingerprint() -> str:
    """SHA-256 (hex, 16 characters) of every ``.py`` file of the three packages, in path order."""
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for pkg in _PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            h.update(str(path.relative_to(root)).encode())
            h.update(path.read_bytes())
    return h.hexdigest()[:16]


def episode_key(fingerprint: str, task: str, policy: str, technique: Any, seed: int,
                trace: bool, condition: str = DEFAULT_CONDITION) -> str:  # fmt: skip
    """The key of one episode (see the module docstring); ``technique`` a Technique object,
    ``condition`` the physical room's (:mod:`agents.conditions`; the default adds nothing)."""
    where = () if condition == DEFAULT_CONDITION else (condition,)
    text = repr((fingerprint, task, policy, repr(technique), int(seed), bool(trace), *where))
    return hashlib.sha256(text.encode()).hexdigest()


class EpisodeStore:
    """The ``.resume`` folder of an output folder.

    Args:
        folder: where the job files live (created on the first save).
    """

    def __init__(self, folder: Path | str) -> None:
        self.folder = Path(folder)

    def load(self) -> dict[str, Any]:
        """Every readable episode: key -> the job's stored value. Unreadable files are reported
        and skipped."""
        found: dict[str, Any] = {}
        if not self.folder.is_dir():
            return found
        for path in sorted(self.folder.glob("*.pkl")):
            try:
                with path.open("rb") as f:
                    entries = pickle.load(f)
                if not isinstance(entries, dict) or not all(isinstance(k, str) for k in entries):
                    raise ValueError("not a dict of episodes")
            except Exception as err:  # a truncated, foreign or corrupt file: run those again
                print(f"resume: skipping unreadable {path} ({type(err).__name__}: {err}); its "
                      "episodes run again")  # fmt: skip
                continue
            found.update(entries)
        return found

    def save(self, entries: dict[str, Any]) -> Path:
        """Write one job's episodes (key -> value) atomically; the file's path."""
        self.folder.mkdir(parents=True, exist_ok=True)
        name = hashlib.sha256("".join(sorted(entries)).encode()).hexdigest()[:24]
        path = self.folder / f"{name}.pkl"
        tmp = path.with_suffix(".tmp")
        with tmp.open("wb") as f:
            pickle.dump(entries, f, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, path)
        return path

    def clear(self) -> None:
        """Remove the folder (the grid is complete)."""
        shutil.rmtree(self.folder, ignore_errors=True)


def missing(keys: Iterable[str], found: dict[str, Any]) -> list[str]:
    """The keys not in ``found``."""
    return [k for k in keys if k not in found]

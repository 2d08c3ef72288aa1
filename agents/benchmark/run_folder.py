"""One run at a time in a benchmark output folder, each run's files alone (:class:`RunFolder`).

:class:`RunFolder` holds ``<out>/.lock`` (an ``fcntl.flock``: a second run into the folder is
refused, naming the holder's pid; a lock whose holder died is free again) and records in
``<out>/.run.json`` which run wrote the folder's files. A run refuses a folder holding another
run's results unless forced, which removes those files first; a run writes its files into
``<out>/.writing`` and then renames them into place, removing what its own previous write left
that this one does not, so the folder holds one write of one run. The finished episodes kept for
resuming live beside them in ``<out>/.resume`` (:mod:`agents.benchmark.resume`).
"""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["OUTPUT_NAME", "FolderBusy", "RunFolder"]

#: The names of the files a run writes into its folder: those that ``--force`` may remove.
OUTPUT_NAME = re.compile(
    r"(benchmark\.csv|benchmark\.json|pairs\.json|report\.html|metrics\.png|"
    r"collision_causes\.png|latency\.png|"
    r"(trajectory|attitude|gait)_[A-Za-z0-9_-]+\.png)\Z"
)


class FolderBusy(RuntimeError):
    """Another run holds the output folder; the message names the folder and its pid."""


class RunFolder:
    """One run's hold on its output folder, as a context manager.

    Entering takes ``<folder>/.lock`` or raises :class:`FolderBusy`; then, where the folder
    holds the files of another run (``.run.json`` names another run, or the benchmark's files
    are there without a record), it raises a ValueError saying so, unless ``force``, which
    removes those files first (only names of :data:`OUTPUT_NAME`; ``.resume`` stays: its
    entries are keyed by everything that shapes them). :meth:`replace` writes the run's files.

    Args:
        folder: the output folder (created if need be).
        run: the run's identity (the same command gives the same one).
        about: a few words on the run, for the record and the refusal of another run.
        force: replace another run's files.
    """

    LOCK, RECORD, STAGING = ".lock", ".run.json", ".writing"

    def __init__(self, folder: Path | str, run: str, about: str, force: bool = False) -> None:
        self.path = Path(folder)
        self.run, self.about, self.force = run, about, force
        self._fd: int | None = None
        self._previous: set[str] = set()

    def __enter__(self) -> RunFolder:
        from agents.benchmark.outputs import WriteError

        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise WriteError(self.path, err) from None
        self._lock()
        try:
            self._claim()
        except OSError as err:  # a file of the other run that cannot be removed
            self._unlock()
            raise WriteError(Path(err.filename or self.path), err) from None
        except BaseException:
            self._unlock()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self._unlock()

    def _lock(self) -> None:
        from agents.benchmark.outputs import WriteError

        lock = self.path / self.LOCK
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as err:
            raise WriteError(lock, err) from None
        try:
            _try_lock(fd)
        except OSError as err:
            if err.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                os.close(fd)
                raise WriteError(lock, err) from None
            try:
                os.lseek(fd, 0, os.SEEK_SET)
                holder = os.read(fd, 32).decode(errors="replace").strip() or "unknown"
            except OSError:  # Windows: a locked byte cannot be read
                holder = "unknown"
            os.close(fd)
            raise FolderBusy(
                f"{self.path} is in use by another vrloco benchmark (pid "
                f"{holder}); wait for it to end, or give another --out"
            ) from None
        os.ftruncate(fd, 0)
        os.lseek(fd, 0, os.SEEK_SET)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._fd = fd

    def _unlock(self) -> None:
        if self._fd is not None:
            _unlock(self._fd)  # before closing: forked workers share the lock
            os.close(self._fd)
            self._fd = None

    def _claim(self) -> None:
        """Refuse (or, forced, remove) another run's files; forget a dead run's staging."""
        shutil.rmtree(self.path / self.STAGING, ignore_errors=True)
        record = self._record()
        theirs = {
            p.name for p in self.path.iterdir() if OUTPUT_NAME.match(p.name) and not p.is_dir()
        }
        if record is not None and record["run"] == self.run:
            self._previous = set(record["files"]) | theirs
            return
        if record is not None:
            theirs |= {n for n in record["files"] if (self.path / n).exists()}
        if not theirs:
            return
        if not self.force:
            whose = (
                f"another run's results ({record['about']}, written {record['written']})"
                if record is not None
                else "benchmark results with no record of their run"
            )
            raise ValueError(
                f"--out {self.path} holds {whose}; give another --out, or --force "
                "to remove them and write this run's"
            )
        for name in sorted(theirs):
            (self.path / name).unlink(missing_ok=True)
        (self.path / self.RECORD).unlink(missing_ok=True)

    def _record(self) -> dict[str, Any] | None:
        """The folder's record of its run, or None where there is none or it is malformed."""
        try:
            record = json.loads((self.path / self.RECORD).read_text())
        except (OSError, ValueError):
            return None
        if not (
            isinstance(record, dict)
            and all(isinstance(record.get(k), str) for k in ("run", "about", "written"))
            and isinstance(record.get("files"), list)
            and all(isinstance(n, str) and OUTPUT_NAME.match(n) for n in record["files"])
        ):
            return None
        return record

    def replace(self, write: Callable[[Path], list[Path]]) -> list[Path]:
        """The run's files: ``write(folder)`` writes them into a staging folder (an error there
        leaves the folder as it was); they are then renamed into the folder, the files of this
        run's previous write that this one lacks are removed, and the record is updated.

        Returns:
            The written files, in the folder.

        Raises:
            WriteError: a file could not be written (a full disk), naming it.
        """
        from agents.benchmark.outputs import WriteError, atomic_path

        stage = self.path / self.STAGING
        shutil.rmtree(stage, ignore_errors=True)
        try:
            stage.mkdir()
            try:
                staged = write(stage)
            except WriteError as err:  # name the file as it would have been
                raise WriteError(self.path / err.path.name, err.reason) from None
            names = [p.name for p in staged]
            record = {
                "run": self.run,
                "about": self.about,
                "files": sorted(names),
                "written": time.strftime("%Y-%m-%d %H:%M:%S"),
            }
            with atomic_path(stage / self.RECORD) as tmp:
                tmp.write_text(json.dumps(record, indent=1) + "\n")
            for p in staged:
                os.replace(p, self.path / p.name)
            for name in self._previous - set(names):
                (self.path / name).unlink(missing_ok=True)
            os.replace(stage / self.RECORD, self.path / self.RECORD)
        except OSError as err:
            where = Path(err.filename) if isinstance(err.filename, str) else self.path
            raise WriteError(
                self.path / where.name if where.parent == stage else where, err
            ) from None
        finally:
            shutil.rmtree(stage, ignore_errors=True)
        self._previous = set(names)
        return [self.path / n for n in names]


def _try_lock(fd: int) -> None:
    """An exclusive lock on ``fd``'s file, or an OSError (EAGAIN, EACCES) where it is held."""
    try:
        import fcntl
    except ImportError:  # Windows
        import msvcrt

        msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
        return
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)


def _unlock(fd: int) -> None:
    try:
        import fcntl
    except ImportError:  # Windows
        import msvcrt

        os.lseek(fd, 0, os.SEEK_SET)
        msvcrt.locking(fd, msvcrt.LK_UNLCK, 1)
        return
    fcntl.flock(fd, fcntl.LOCK_UN)

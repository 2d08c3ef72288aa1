"""A reader for the real head traces of people watching 360-degree videos in a headset.

The files are the aggregation "A large dataset of 360 video user behaviour" (github 360VidStr),
in ``$VRLOCO_DATA/head_traces`` (never copied into the repository, never downloaded by
``vrloco data fetch``: the aggregation states no licence). One file per video, named by its
number:

* line 1: the sample times (s, 10 Hz from 0);
* then two lines per viewing: head pitch, then head yaw (rad, yaw wrapped at +-pi; the
  aggregation dropped roll). A viewing may be shorter than the times line: it is sampled at the
  first of those times.

Three of the aggregated datasets are here (:data:`DATASETS`, by file number): Corbillon, De
Simone & Simon, "360-degree video head movement dataset", ACM MMSys 2017 (files 0-6, Razer OSVR
HDK2); Lo, Fan, Lee, Huang, Hsu & Chen, "360 video viewing dataset in head-mounted virtual
reality", ACM MMSys 2017 (7-16, Oculus DK2); Wu, Tan, Wang & Yang, "A dataset for exploring user
behaviors in VR spherical video streaming", ACM MMSys 2017 (33-41, no 38; HTC Vive). The viewers
sat or stood and explored freely; nobody walked: these are traces of looking around, not of
walking (in place or otherwise). Credit the datasets wherever their figures are reported.

The folder is found by :func:`agents.recordings.data.data_path` (:func:`head_traces_folder`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from agents.recordings.data import data_folder, data_path

__all__ = [
    "DATASETS",
    "HeadTraceFile",
    "data_folder",
    "dataset_files",
    "dataset_of",
    "head_traces_folder",
    "read_head_traces",
]

#: The datasets in the folder: name -> (citation, file numbers).
DATASETS: dict[str, tuple[str, tuple[int, ...]]] = {
    "corbillon2017": ("Corbillon, De Simone & Simon, ACM MMSys 2017", tuple(range(0, 7))),
    "lo2017": ("Lo, Fan, Lee, Huang, Hsu & Chen, ACM MMSys 2017", tuple(range(7, 17))),
    "wu2017": ("Wu, Tan, Wang & Yang, ACM MMSys 2017", tuple(n for n in range(33, 42) if n != 38)),
}


def head_traces_folder() -> Path:
    """``head_traces/`` in ``$VRLOCO_DATA`` (:func:`agents.recordings.data.data_path`).

    Raises:
        FileNotFoundError: it is not there, or VRLOCO_DATA is not set (one line saying so).
    """
    return data_path("head_traces")


def dataset_of(path: str | Path) -> str:
    """The dataset a head-trace file belongs to, by its number.

    Raises:
        ValueError: a file name that is not ``<number>.txt`` of one of :data:`DATASETS`.
    """
    p = Path(path)
    if p.suffix == ".txt" and p.stem.isdigit():
        n = int(p.stem)
        for name, (_, numbers) in DATASETS.items():
            if n in numbers:
                return name
    allowed = "; ".join(f"{k}: {v[1][0]}-{v[1][-1]}" for k, v in DATASETS.items())
    raise ValueError(
        f"{str(p)!r}: not a head-trace file of a known dataset (<number>.txt, {allowed})"
    )


def dataset_files(folder: str | Path | None = None) -> dict[str, list[Path]]:
    """The head-trace files present in ``folder`` (default :func:`head_traces_folder`), per
    dataset of :data:`DATASETS`, sorted by number.

    Raises:
        FileNotFoundError: the folder is missing (naming it and ``VRLOCO_DATA``).
    """
    folder = Path(folder) if folder is not None else head_traces_folder()
    if not folder.is_dir():
        raise FileNotFoundError(
            f"head traces not found at {str(folder)!r} (set VRLOCO_DATA to the folder holding "
            "head_traces/)"
        )
    return {
        name: [folder / f"{n}.txt" for n in numbers if (folder / f"{n}.txt").is_file()]
        for name, (_, numbers) in DATASETS.items()
    }


@dataclass(frozen=True)
class HeadTraceFile:
    """The viewings of one video.

    Attributes:
        path: the file.
        times: the sample times (s), (T,).
        pitch: head pitch (rad), (V, T): one row per viewing, NaN after the viewing's end.
        yaw: head yaw (rad, wrapped at +-pi), (V, T), likewise.
        lengths: samples of each viewing, (V,).
    """

    path: Path
    times: NDArray[np.float64]
    pitch: NDArray[np.float64]
    yaw: NDArray[np.float64]
    lengths: NDArray[np.intp]

    @property
    def dataset(self) -> str:
        """The dataset (:func:`dataset_of`)."""
        return dataset_of(self.path)

    @staticmethod
    def pitch_line(v: int) -> int:
        """The 1-based line of viewing ``v``'s pitch (its yaw is on the next line)."""
        return 2 + 2 * v

    def viewings(self) -> Iterator[tuple[NDArray, NDArray, NDArray]]:
        """``(times, pitch, yaw)`` of each viewing, cut to its length."""
        for v, n in enumerate(self.lengths):
            yield self.times[:n], self.pitch[v, :n], self.yaw[v, :n]


def read_head_traces(path: str | Path) -> HeadTraceFile:
    """Read one head-trace file (see the module docstring for the layout).

    Raises:
        ValueError: malformed content, one line naming the file, the line (1-based) and what is
            wrong: a token that is not a number, a non-finite value, times that do not increase,
            an odd number of viewing lines, a pitch and yaw line of different lengths, a viewing
            longer than the times line or shorter than two samples.
        FileNotFoundError: no such file.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{str(path)!r}: no such head-trace file")
    lines = path.read_text().splitlines()
    while lines and not lines[-1].strip():
        lines.pop()

    def fail(line: int, what: str) -> ValueError:
        return ValueError(f"{path}:{line}: {what}")

    def parse(line: int) -> NDArray[np.float64]:
        text = lines[line - 1]
        try:
            values = np.array(text.split(), dtype=np.float64)
        except ValueError:
            for col, token in enumerate(text.split(), start=1):
                try:
                    float(token)
                except ValueError:
                    raise fail(line, f"value {col} {token!r} is not a number") from None
            raise
        if values.size == 0:
            raise fail(line, "empty line: every line holds numbers separated by spaces")
        bad = ~np.isfinite(values)
        if bad.any():
            col = int(np.argmax(bad)) + 1
            raise fail(line, f"value {col} is {values[col - 1]}: every value must be finite")
        return values

    if len(lines) < 3:
        raise fail(
            len(lines) or 1,
            f"{len(lines)} line(s): a file holds the times and at least "
            "one viewing (a pitch and a yaw line)",
        )
    if len(lines) % 2 == 0:
        raise fail(
            len(lines),
            f"{len(lines)} lines: after the times line come two lines per "
            "viewing (pitch, yaw), so the count must be odd",
        )
    times = parse(1)
    if times.size < 2 or (np.diff(times) <= 0).any():
        j = int(np.argmax(np.diff(times) <= 0)) + 2 if times.size >= 2 else 1
        raise fail(1, f"the times must increase strictly (value {j} does not)")
    n_view = (len(lines) - 1) // 2
    pitch = np.full((n_view, times.size), np.nan)
    yaw = np.full((n_view, times.size), np.nan)
    lengths = np.zeros(n_view, np.intp)
    for v in range(n_view):
        lp = HeadTraceFile.pitch_line(v)
        p, y = parse(lp), parse(lp + 1)
        if p.size != y.size:
            raise fail(
                lp + 1,
                f"{y.size} yaw values after {p.size} pitch values on line {lp}: "
                "a viewing's two lines have one value per sample each",
            )
        if p.size > times.size:
            raise fail(lp, f"{p.size} values, more than the {times.size} sample times of line 1")
        if p.size < 2:
            raise fail(lp, f"{p.size} value(s): a viewing needs at least two samples")
        pitch[v, : p.size], yaw[v, : y.size], lengths[v] = p, y, p.size
    return HeadTraceFile(path, times, pitch, yaw, lengths)

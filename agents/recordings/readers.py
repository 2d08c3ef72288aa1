"""The readers of ``vrloco estimate``'s inputs: a CSV file (:func:`read_csv_recording`), a BROAD
trial or an Oxford step-counter folder (:func:`read_recording`, by what the path is); each
returns the recording checked (:func:`agents.recordings.checks.check_recording`).
"""

from __future__ import annotations

import codecs
import csv
import io
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from agents.recordings.checks import check_recording
from agents.recordings.record import GYRO, MAGNETOMETER, OPTIONAL, REQUIRED, Recording, warn
from agents.recordings.units import Units
from estimators.steps.zhang2021 import GaitParams

__all__ = ["read_csv_recording", "read_recording"]


def _decode(path: Path) -> str:
    """The file's text: UTF-8 (a BOM skipped) or UTF-16 with a BOM; otherwise a ValueError."""
    raw = path.read_bytes()
    utf16 = raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE))
    try:
        text = raw.decode("utf-16" if utf16 else "utf-8-sig")
    except UnicodeDecodeError as err:
        raise ValueError(
            f"{path}: not a UTF-8 text CSV (byte {err.start} cannot be decoded as "
            f"{'UTF-16' if utf16 else 'UTF-8'}: binary data or another encoding); save it as "
            "a UTF-8 CSV"
        ) from None
    if "\x00" in text:
        raise ValueError(
            f"{path}: not a UTF-8 text CSV (it holds NUL bytes: binary data, or UTF-16 without "
            "a byte-order mark); save it as a UTF-8 CSV"
        )
    return text


def _parse_csv(path: Path) -> tuple[list[str], NDArray[np.float64], NDArray[np.int64]]:
    """The columns used, their values (rows, columns) and each row's line in the file."""
    reader = csv.reader(io.StringIO(_decode(path), newline=""))
    try:
        header = [h.strip() for h in next(reader, [])]
        if not header:
            raise ValueError(f"{path}: the file is empty; expected a header row")
        missing = [c for c in REQUIRED if c not in header]
        if missing:
            hint = ""
            if len(header) == 1 and any(s in header[0] for s in ";\t"):
                hint = "; the header has no commas: the file must be comma-separated"
            raise ValueError(
                f"{path}, line 1: missing column(s) {', '.join(missing)}; a CSV needs "
                f"{', '.join(REQUIRED)} (and optionally {', '.join(OPTIONAL)}){hint}"
            )
        for group in (GYRO, MAGNETOMETER):
            have = [c for c in group if c in header]
            if have and len(have) < 3:
                raise ValueError(
                    f"{path}, line 1: column(s) {', '.join(c for c in group if c not in have)} "
                    f"missing; give all of {', '.join(group)} or none"
                )
        cols = [c for c in (*REQUIRED, *OPTIONAL) if c in header]
        twice = [c for c in cols if header.count(c) > 1]
        if twice:
            raise ValueError(f"{path}, line 1: column(s) {', '.join(twice)} appear twice")
        where = [header.index(c) for c in cols]
        rows: list[list[float]] = []
        lines: list[int] = []
        for row in reader:
            line = reader.line_num
            if not row or all(not x.strip() for x in row):
                continue
            while len(row) > len(header) and not row[-1].strip():
                row = row[:-1]  # trailing commas
            if len(row) != len(header):
                more = len(row) > len(header)
                raise ValueError(
                    f"{path}, line {line}: {len(row)} fields, but the header has "
                    f"{len(header)}" + ("; a comma inside a value?" if more else "")
                )
            values = []
            for name, j in zip(cols, where, strict=True):
                try:
                    values.append(float(row[j]))
                except ValueError:
                    raise ValueError(
                        f"{path}, line {line}, column {j + 1} ({name}): cannot read "
                        f"{row[j][:40]!r} as a number"
                    ) from None
            rows.append(values)
            lines.append(line)
    except csv.Error as err:
        raise ValueError(
            f"{path}, line {reader.line_num}: not a readable CSV row ({err})"
        ) from None
    if len(rows) < 2:
        raise ValueError(f"{path}: needs at least 2 data rows, found {len(rows)}")
    data = np.asarray(rows, dtype=np.float64)
    line_no = np.asarray(lines, dtype=np.int64)
    t = data[:, 0]
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(
            f"{path}, line {line_no[bad[0]]}, column {where[0] + 1} (t): time {t[bad[0]]} is not "
            "a finite number (s)"
        )
    bad = np.flatnonzero(np.diff(t) < 0)
    if bad.size:
        raise ValueError(
            f"{path}, line {line_no[bad[0] + 1]}, column {where[0] + 1} (t): time "
            f"{t[bad[0] + 1]} runs backwards after {t[bad[0]]}; timestamps must not decrease (s)"
        )
    return cols, data, line_no


def read_csv_recording(path: Path, units: Units | None = None) -> Recording:
    """Read and check the documented CSV format (see the module doc), its columns in ``units``
    (default: each found from the data).

    Raises:
        ValueError: one line naming the file (and the line and column where there is one): not
            a UTF-8/UTF-16 text file, a missing column, a malformed row, time running
            backwards, units that cannot be found or do not fit the data, or a recording that is
            mostly impossible values.
    """
    path = Path(path)
    cols, data, line = _parse_csv(path)
    t = data[:, 0]
    repeated = int(np.sum(np.diff(t) == 0))
    if repeated:  # rows sharing a timestamp are one sample: their mean (NaN where one is NaN)
        t_u, first, inverse = np.unique(t, return_index=True, return_inverse=True)
        counts = np.bincount(inverse)
        with np.errstate(invalid="ignore"):
            data = np.stack([np.bincount(inverse, weights=v) / counts for v in data.T], -1)
        data[:, 0] = t_u
        line = line[first]
        warn(
            path,
            f"{repeated} rows repeat the previous row's timestamp; merged them into "
            "the mean of the rows sharing it",
        )
    get = {c: data[:, k] for k, c in enumerate(cols)}

    def xyz(names: tuple[str, ...]) -> NDArray[np.float64] | None:
        return np.stack([get[c] for c in names], -1) if names[0] in get else None

    rec = Recording(
        path.stem,
        data[:, 0],
        xyz(("ax", "ay", "az")),
        xyz(GYRO),
        xyz(MAGNETOMETER),
        GaitParams(),
        line=line,
    )
    return check_recording(rec, path, units)


def _format_units(path: Path, units: Units | None, kind: str) -> Units:
    """The fixed units of a BROAD trial or an Oxford recording (s, m/s^2, rad/s); a ValueError
    where ``units`` gives another (those are for CSV files)."""
    fixed = Units(time="s", acc="m/s2", gyro="rad/s")
    for name, value in (units or Units()).given().items():
        if value != getattr(fixed, name):
            raise ValueError(
                f"{path}: {kind} is in {getattr(fixed, name)} by its format; a {name} unit "
                f"({value!r}, --{name}-unit) applies to CSV files only"
            )
    return fixed


def read_recording(path: Path, units: Units | None = None) -> Recording:
    """A recording from a CSV file, a BROAD trial or an Oxford folder (see the module doc).

    ``units``: the CSV columns' units (default: each found from the data); a BROAD trial and an
    Oxford recording have theirs by their format (a different unit given is an error).
    """
    path = Path(path)
    if units is not None and not isinstance(units, Units):
        raise ValueError(f"units={units!r}: must be a Units (or None for 'auto' throughout)")
    if path.is_dir():
        from estimators.io.oxford import load_oxford, read_accelerometer

        if not (path / "accelerometer.csv").is_file():
            raise ValueError(
                f"{path}: a folder, but not an Oxford step-counter recording (no "
                "accelerometer.csv); give a CSV file, a BROAD trial (.hdf5/.mat) or an Oxford "
                "recording's folder"
            )
        if (path / "stepcounter.csv").is_file():
            ox = load_oxford(path)
            t, acc, ref_steps = ox.t, ox.acc, ox.step_times
        else:
            t, acc, _ = read_accelerometer(path)
            ref_steps = None
        fixed = _format_units(path, units, "an Oxford step-counter recording")
        rec = Recording(path.name, t, acc, None, None, GaitParams.neck_pouch(), ref_steps=ref_steps)
        return check_recording(rec, path, fixed)
    if not path.is_file():
        raise ValueError(f"{path}: no such file or folder")
    if path.suffix.lower() in (".hdf5", ".h5", ".mat"):
        from estimators.io.broad import load_broad

        fixed = _format_units(path, units, "a BROAD trial")
        trial = load_broad(path)
        t = np.arange(trial.acc.shape[0]) / trial.fs
        rec = Recording(
            trial.name,
            t,
            trial.acc,
            trial.gyr,
            trial.mag,
            GaitParams(),
            ref_quat=trial.quat,
            ref_mask=trial.movement,
        )
        return check_recording(rec, path, fixed)
    return read_csv_recording(path, units)

"""Reader for the Oxford step-counter recordings (ground truth for the gait detector).

Data: "Oxford-step-counter/DataSet" (Brajdic and Harle's successors at the University of
Oxford), licence CC-BY-4.0; credit it wherever its figures are reported. One recording directory
holds (see ``../shared/data/README.md``):

* ``accelerometer.csv``: ``t_ns, accuracy, ax, ay, az`` — timestamps in nanoseconds (the
  phone's monotonic clock), the Android accuracy flag, and the specific force in m/s^2 (a Bosch
  BMI160 at about 405 Hz, irregularly spaced);
* ``stepcounter.csv``: ``t_ns, right, left`` — foot-contact switches under each foot (0/1),
  polled at about 11 Hz on the same clock.

Ground truth: a step is a rising edge (0 -> 1) of either switch. Debounce: a rising edge less
than ``debounce`` seconds after the previous counted rising edge *of the same foot* is ignored
(switch chatter); a single poll is never dropped, because at ~11 Hz a brief real contact lasts
one or two polls. The default 0.3 s is about half the shortest interval between two steps of one
foot (a stride, ~0.9 s here) and keeps every edge of the neck-pouch walk: 248 steps in 133 s.

Times are returned in seconds from the first accelerometer sample. The switches are polled, so a
true step time is known to within one polling interval (~0.09 s) and lags the contact by up to
that; F1 with a +-0.2 s tolerance absorbs this.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "DEFAULT_RECORDING",
    "OxfordRecording",
    "foot_switch_steps",
    "load_oxford",
    "read_accelerometer",
]

#: The neck-pouch walk kept in ``../shared/data/oxford_steps``.
DEFAULT_RECORDING = "Pixel_Jamie_Hard_NeckPouch_1"


@dataclass
class OxfordRecording:
    """One Oxford recording.

    Attributes:
        t: accelerometer sample times (s from the first sample), (n,), strictly increasing (rows
            of the file sharing a timestamp are merged into their mean).
        acc: specific force (m/s^2, phone frame), (n, 3).
        switch_t: foot-switch poll times (s, same clock), (m,).
        right, left: foot-switch states (0/1) at those polls, (m,) int8.
        step_times: debounced true step times (s), sorted, (S,).
        t0_ns: the first accelerometer timestamp (ns), the origin of every time above.
    """

    t: NDArray[np.float64]
    acc: NDArray[np.float64]
    switch_t: NDArray[np.float64]
    right: NDArray[np.int8]
    left: NDArray[np.int8]
    step_times: NDArray[np.float64]
    t0_ns: int

    @property
    def duration(self) -> float:
        """Length of the accelerometer record (s)."""
        return float(self.t[-1] - self.t[0])


def _read_csv(path: Path, n_cols: int) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Integer nanosecond timestamps and the float columns after them."""
    if not path.is_file():
        raise FileNotFoundError(f"Oxford step data file not found: {path}")
    kw = {"delimiter": ",", "encoding": "utf-8-sig"}  # a spreadsheet's byte-order mark is skipped
    try:
        t_ns = np.loadtxt(path, usecols=0, dtype=np.int64, ndmin=1, **kw)
        vals = np.loadtxt(path, usecols=range(1, n_cols), dtype=np.float64, ndmin=2, **kw)
    except ValueError as err:  # UnicodeDecodeError included: binary data
        raise ValueError(
            f"{path}: expected {n_cols} comma-separated numeric columns ({err})"
        ) from None
    if t_ns.size < 2:
        raise ValueError(f"{path}: needs at least 2 rows, got {t_ns.size}")
    if np.any(np.diff(t_ns) < 0):
        k = int(np.argmax(np.diff(t_ns) < 0))
        raise ValueError(f"{path}: time runs backwards at row {k + 2}")
    if np.any(np.diff(t_ns) == 0):  # rows sharing a timestamp are one sample: their mean
        t_ns, inverse = np.unique(t_ns, return_inverse=True)
        counts = np.bincount(inverse)
        vals = np.stack([np.bincount(inverse, weights=v) / counts for v in vals.T], -1)
    return t_ns, vals


def foot_switch_steps(
    t: NDArray[np.float64],
    right: NDArray[np.integer],
    left: NDArray[np.integer],
    debounce: float = 0.3,
) -> NDArray[np.float64]:
    """Step times (s) from polled foot switches: debounced rising edges of either foot.

    Args:
        t: poll times (s), (m,), increasing.
        right, left: switch states (0/1) at those polls, (m,).
        debounce: minimum time (s) between two counted rising edges of the same foot, >= 0.

    Returns:
        Sorted step times (s), (S,).
    """
    if debounce < 0.0:
        raise ValueError(f"debounce must be >= 0 s, got {debounce!r}")
    times = []
    for sw in (right, left):  # two feet
        s = np.asarray(sw)
        if s.shape != t.shape or not np.all((s == 0) | (s == 1)):
            raise ValueError("foot switches must be 0/1 arrays with one value per poll time")
        rise = t[1:][np.diff(s.astype(np.int8)) > 0]
        kept: list[float] = []
        for r in rise:  # edges of one foot, a few hundred
            if not kept or r - kept[-1] >= debounce:
                kept.append(float(r))
        times.append(np.asarray(kept))
    return np.sort(np.concatenate(times))


def read_accelerometer(folder: str | Path) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """The accelerometer of one recording directory alone (no foot switches needed).

    Returns:
        ``(t, acc, t0_ns)``: sample times (s from the first sample), (n,), strictly increasing;
        the specific force (m/s^2), (n, 3); the first timestamp (ns).

    Raises:
        FileNotFoundError: no ``accelerometer.csv``.
        ValueError: a malformed file (see :func:`load_oxford`).
    """
    acc_ns, acc_vals = _read_csv(Path(folder) / "accelerometer.csv", 5)
    if acc_vals.shape[1] != 4:
        raise ValueError("accelerometer.csv needs 5 columns: t_ns, accuracy, ax, ay, az")
    t0 = int(acc_ns[0])
    return (acc_ns - t0) * 1e-9, acc_vals[:, 1:4].copy(), t0


def load_oxford(folder: str | Path, debounce: float = 0.3) -> OxfordRecording:
    """Read one recording directory (``accelerometer.csv`` and ``stepcounter.csv``).

    Args:
        folder: the recording directory, e.g. ``../shared/data/oxford_steps/`` +
            :data:`DEFAULT_RECORDING`.
        debounce: see :func:`foot_switch_steps` (s).

    Raises:
        FileNotFoundError: a file is missing.
        ValueError: a malformed file (column count, non-numeric values, non-increasing time,
            switch values other than 0/1).
    """
    folder = Path(folder)
    t, acc, t0 = read_accelerometer(folder)
    sw_ns, sw_vals = _read_csv(folder / "stepcounter.csv", 3)
    if sw_vals.shape[1] != 2:
        raise ValueError("stepcounter.csv needs 3 columns: t_ns, right, left")
    sw_t = (sw_ns - t0) * 1e-9
    right = sw_vals[:, 0]
    left = sw_vals[:, 1]
    steps = foot_switch_steps(sw_t, right, left, debounce)
    return OxfordRecording(
        t=t,
        acc=acc,
        switch_t=sw_t,
        right=right.astype(np.int8),
        left=left.astype(np.int8),
        step_times=steps,
        t0_ns=t0,
    )

"""Reader of BROAD recordings (Berlin Robust Orientation Estimation Assessment Dataset).

Laidig, Caruso, Cereatti, Seel, "BROAD - A Benchmark for Robust Inertial Orientation Estimation",
Data 6(7):72, 2021 (CC-BY-4.0). Each trial is an ``.hdf5`` file (h5py) or a MATLAB v5 ``.mat``
file (``scipy.io.loadmat``) with the same keys: ``imu_gyr`` rad/s, ``imu_acc`` m/s^2, ``imu_mag``
uT (all (N, 3), sensor frame), ``opt_quat`` (N, 4) ``[w, x, y, z]`` optical ground truth of the
IMU, sensor -> ENU earth frame (NaN where markers were lost), ``opt_pos`` (N, 3) m, ``movement``
(N,) bool (uint8 in .mat) marking the motion phases that are scored, and the sampling rate
(285.714 Hz; ``attrs['sampling_rate']`` in hdf5, ``sampling_rate`` in .mat).

This module only reads files; it knows nothing of the environment.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = ["BroadTrial", "broad_trials", "load_broad"]

_KEYS = ("imu_gyr", "imu_acc", "imu_mag", "opt_quat", "opt_pos", "movement")
_SUFFIXES = (".hdf5", ".h5", ".mat")


@dataclass(frozen=True)
class BroadTrial:
    """One BROAD trial.

    Attributes:
        name: file stem, e.g. ``"02_undisturbed_slow_rotation_B"``.
        fs: sampling rate, Hz.
        gyr: (N, 3) angular rate, rad/s, sensor frame.
        acc: (N, 3) specific force, m/s^2, sensor frame.
        mag: (N, 3) magnetic field, uT, sensor frame.
        quat: (N, 4) ground-truth quaternions ``[w, x, y, z]``, sensor -> ENU (NaN rows: lost).
        pos: (N, 3) ground-truth position, m.
        movement: (N,) bool, the samples BROAD scores.
    """

    name: str
    fs: float
    gyr: NDArray[np.float64]
    acc: NDArray[np.float64]
    mag: NDArray[np.float64]
    quat: NDArray[np.float64]
    pos: NDArray[np.float64]
    movement: NDArray[np.bool_]

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.gyr.shape[0])


def _read_hdf5(path: Path) -> tuple[dict[str, NDArray], float]:
    import h5py

    try:
        f = h5py.File(path, "r")
    except OSError as err:
        raise ValueError(f"{path.name}: not a readable HDF5 file ({err})") from None
    with f:
        missing = [k for k in _KEYS if k not in f]
        if missing:
            raise ValueError(f"{path.name}: not a BROAD trial, missing keys {missing}")
        if not all(isinstance(f[k], h5py.Dataset) for k in _KEYS):
            raise ValueError(f"{path.name}: not a BROAD trial, {list(_KEYS)} must be datasets")
        data = {k: np.asarray(f[k][()]) for k in _KEYS}
        if "sampling_rate" not in f.attrs:
            raise ValueError(f"{path.name}: missing attribute 'sampling_rate'")
        fs = _number(path, f.attrs["sampling_rate"])
    return data, fs


def _number(path: Path, value: object) -> float:
    """The sampling rate as a float, or a ValueError naming the file."""
    try:
        return float(np.asarray(value, dtype=np.float64).reshape(()))
    except (TypeError, ValueError):
        raise ValueError(f"{path.name}: sampling_rate must be one number, got {value!r}") from None


def _read_mat(path: Path) -> tuple[dict[str, NDArray], float]:
    from scipy.io import loadmat

    try:
        m = loadmat(path, squeeze_me=True)
    except Exception as err:  # scipy raises ValueError, MatReadError, TypeError... on non-MAT data
        raise ValueError(f"{path.name}: not a readable MATLAB file ({err})") from None
    missing = [k for k in (*_KEYS, "sampling_rate") if k not in m]
    if missing:
        raise ValueError(f"{path.name}: not a BROAD trial, missing keys {missing}")
    return {k: np.asarray(m[k]) for k in _KEYS}, _number(path, m["sampling_rate"])


def load_broad(path: str | Path) -> BroadTrial:
    """Read one BROAD trial from an ``.hdf5`` or ``.mat`` file.

    Args:
        path: the trial file.

    Returns:
        The trial, float64 arrays (C-contiguous) and a boolean ``movement``.

    Raises:
        FileNotFoundError: no such file.
        ValueError: not an HDF5/MAT file, unknown extension, missing keys, non-numeric data or
            inconsistent shapes.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"BROAD trial not found: {path}")
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise ValueError(f"{path.name}: BROAD trials are {_SUFFIXES} files, got {suffix!r}")
    data, fs = _read_hdf5(path) if suffix != ".mat" else _read_mat(path)
    try:
        arr = {k: np.ascontiguousarray(data[k], dtype=np.float64) for k in _KEYS if k != "movement"}
    except (TypeError, ValueError):
        numeric = list(_KEYS[:5])
        raise ValueError(f"{path.name}: not a BROAD trial, {numeric} must be numeric") from None
    n = arr["imu_gyr"].shape[0]
    for k, cols in (
        ("imu_gyr", 3),
        ("imu_acc", 3),
        ("imu_mag", 3),
        ("opt_quat", 4),
        ("opt_pos", 3),
    ):
        if arr[k].shape != (n, cols):
            raise ValueError(f"{path.name}: {k} must have shape ({n}, {cols}), got {arr[k].shape}")
    movement = np.asarray(data["movement"]).reshape(-1).astype(bool)
    if movement.shape != (n,):
        raise ValueError(f"{path.name}: movement must have {n} entries, got {movement.shape}")
    if not (np.isfinite(fs) and fs > 0):
        raise ValueError(f"{path.name}: sampling_rate must be > 0 Hz, got {fs}")
    return BroadTrial(
        name=path.stem,
        fs=fs,
        gyr=arr["imu_gyr"],
        acc=arr["imu_acc"],
        mag=arr["imu_mag"],
        quat=arr["opt_quat"],
        pos=arr["opt_pos"],
        movement=movement,
    )


def broad_trials(folder: str | Path) -> list[Path]:
    """The BROAD trial files in ``folder``, sorted by name (one per trial stem; hdf5 preferred).

    Raises:
        FileNotFoundError: the folder does not exist.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"BROAD folder not found: {folder}")
    by_stem: dict[str, Path] = {}
    for p in sorted(folder.iterdir()):
        if p.suffix.lower() in _SUFFIXES and (p.stem not in by_stem or p.suffix != ".mat"):
            by_stem[p.stem] = p
    return [by_stem[k] for k in sorted(by_stem)]

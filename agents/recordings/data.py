"""The real recordings: where they come from, how they arrive, and the one place that finds them.

Three public sets can be fetched (``vrloco data fetch NAME``), each file from its canonical
source at a pinned commit and checked against a pinned SHA-256 (:data:`DATASETS`):

* ``broad``: nine trials of BROAD, Laidig, Caruso, Cereatti & Seel, "BROAD - A Benchmark for
  Robust Inertial Orientation Estimation", Data 6(7):72, 2021 (github.com/dlaidig/broad),
  CC-BY-4.0;
* ``oxford``: one walk with the phone in a neck pouch from the Oxford step counter dataset
  (github.com/Oxford-step-counter/DataSet), CC-BY-4.0;
* ``kinect``: one Kinect v2 skeleton recording from Microsoft's LabanotationSuite
  (github.com/microsoft/LabanotationSuite), MIT.

The hashes were computed from copies of the published files (the project's development copies,
laid out as below), not from a download made by this module.

``head_traces`` (the 360VidStr aggregation of three ACM MMSys 2017 head-movement datasets) states
no licence of its own, so it is never downloaded: it is found only in ``$VRLOCO_DATA``.

Where data is found (:func:`data_path`), in order:

1. ``$VRLOCO_DATA``, a folder laid out as the data folder: ``broad/*.hdf5|.mat``,
   ``oxford_steps/Pixel_Jamie_Hard_NeckPouch_1/*.csv``, ``kinect_laban/Ges01_wavehand.csv``,
   ``head_traces/*.txt``; a set counts as there when all its files are;
2. the download cache (:func:`cache_folder`): ``$VRLOCO_CACHE``, else ``pooch.os_cache("vrloco")``
   (``~/.cache/vrloco`` on Linux), with the same layout. A file reaches its name there only after
   its hash was checked: pooch downloads to a temporary file in the same folder and renames it
   when the hash matches, and deletes it otherwise.

Downloads go to the canonical URLs, or to ``BASE/RELPATH`` for a base URL given as
``base_url`` or ``$VRLOCO_DATA_URL`` (a mirror, or a local server in the tests), where RELPATH is
the file's path in the layout above.

Errors, each one line: an unknown name lists the names (:class:`ValueError`); a set not found
names the folders looked in and the command that fetches it (:class:`DataMissing`, a
:class:`FileNotFoundError`); a failed download names the file and its URL, a hash mismatch also
the expected and the received SHA-256, and a cache folder that cannot be written names the folder
(:class:`FetchError`).
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

__all__ = [
    "DATASETS",
    "DataMissing",
    "Dataset",
    "FetchError",
    "cache_folder",
    "data_folder",
    "data_path",
    "fetch",
    "get_dataset",
    "located",
    "mirror_url",
]

#: Seconds without data after which a download is abandoned.
TIMEOUT_S = 60.0

_BROAD = "https://github.com/dlaidig/broad/raw/afbaa4d75c4cd7c8ca76b8145b1812312d87fb7f"
_OXFORD = (
    "https://github.com/Oxford-step-counter/DataSet/raw/c4121c5aa8d830a9f12de8f599043c234a4e192c"
    "/optimisation/data/Pixel_Jamie_Hard_NeckPouch_1"
)
_LABAN = (
    "https://github.com/microsoft/LabanotationSuite/raw/a1b332af8e99eb95da7e23368e58f837f207fbfe"
    "/GestureAuthoringTools/LabanEditor/data_input"
)


@dataclass(frozen=True)
class DataFile:
    """One file of a set.

    Attributes:
        relpath: its path in the data folder's layout (``broad/02_....hdf5``).
        sha256: its SHA-256, hex.
        size: its size, bytes.
        url: its canonical URL (a pinned commit).
    """

    relpath: str
    sha256: str
    size: int
    url: str


@dataclass(frozen=True)
class Dataset:
    """A set of real recordings.

    Attributes:
        name: the name given to ``vrloco data`` and :func:`data_path`.
        title: what it is, in a few words.
        path: what the readers take, relative to a data folder (a folder or a file).
        licence: its licence (SPDX id where there is one).
        citation: whom to credit.
        source: its home page.
        files: the files fetched, empty for a set that is not downloaded.
        why_not_fetched: for a set with no files, why.
    """

    name: str
    title: str
    path: str
    licence: str
    citation: str
    source: str
    files: tuple[DataFile, ...] = field(default=())
    why_not_fetched: str = ""

    @property
    def fetchable(self) -> bool:
        return bool(self.files)

    def in_folder(self, root: Path) -> bool:
        """Whether ``root`` holds the whole set (every file; a set without files: its folder)."""
        if not self.files:
            return (root / self.path).is_dir()
        return all((root / f.relpath).is_file() for f in self.files)


# (file name, SHA-256, bytes) of the nine BROAD trials; trial 21 is its .mat, the others .hdf5
_BROAD_TRIALS = (
    (
        "02_undisturbed_slow_rotation_B.hdf5",
        "33ed3432ece89cfbd8c5c069a176106a05dad019302759353244c71d70d7e5f5",
        3926925,
    ),
    (
        "07_undisturbed_fast_rotation_B.hdf5",
        "bff6444d38b836482040a328d6060741816ed0150cf2640db94550c6a796b3d8",
        4080123,
    ),
    (
        "11_undisturbed_slow_translation_B.hdf5",
        "ea4ecb8a27d040cecdfb97cdee45023ea461e065bfc402ce7fe6a7c9a0f325e0",
        3710735,
    ),
    (
        "16_undisturbed_fast_translation_B.hdf5",
        "eebc009755c4fc53c49369a19bae942cf093342a13a51a1ca0eeb23b2cc74abc",
        3994996,
    ),
    (
        "21_undisturbed_fast_combined.mat",
        "cb7be66ffc50d7d2b23abaf72a85a76925ea2db36a3fd575998811fcf68c219a",
        4043263,
    ),
    (
        "25_disturbed_tapping_B.hdf5",
        "d6d9b55c5c84821eaaae96d93cc857b852af24fcb7c93a5fa98b7e6c1e9cae5d",
        3651796,
    ),
    (
        "27_disturbed_phone_vibration_B.hdf5",
        "9041093636cd2c2e992651f4cd7f7f25c4b585971fd5d4821b020ca3c5d15dff",
        3684968,
    ),
    (
        "30_disturbed_stationary_magnet_C.hdf5",
        "a4e14a8671c7d0a38c4d41c1883ea2ea471937dfe61ad1bdbee042cea3040808",
        3962196,
    ),
    (
        "33_disturbed_attached_magnet_2cm.hdf5",
        "b81855b453629e023635d966f77c87cd17b195c919888d725b57b1cca037962d",
        3316402,
    ),
)
_OXFORD_FILES = (
    (
        "accelerometer.csv",
        "43a53351d01e6b8d8e491e56002c612f6bc1d634b91c23b5b7e8bbb96528708b",
        2735577,
    ),
    ("stepcounter.csv", "3284bd8d22d14e4d1f893b7f2c6bc6fadbefeecc7e75c0df6216990e53fa1ca5", 30975),
)
_LABAN_SHA256 = "3f1677de9a0e7b1ce61d899300b96f1e162351b84f1a4d69f0ab9e0901a6e7cd"

#: The sets, by name.
DATASETS: dict[str, Dataset] = {
    "broad": Dataset(
        name="broad",
        title="BROAD, nine IMU trials with optical ground truth",
        path="broad",
        licence="CC-BY-4.0",
        citation=(
            'Laidig, Caruso, Cereatti & Seel, "BROAD - A Benchmark for Robust Inertial '
            'Orientation Estimation", Data 6(7):72, 2021'
        ),
        source="https://github.com/dlaidig/broad",
        files=tuple(
            DataFile(
                f"broad/{stem}",
                sha256,
                size,
                f"{_BROAD}/{'data_mat' if stem.endswith('.mat') else 'data_hdf5'}/{stem}",
            )
            for stem, sha256, size in _BROAD_TRIALS
        ),
    ),
    "oxford": Dataset(
        name="oxford",
        title="Oxford step counter, a neck-pouch walk with foot switches",
        path="oxford_steps/Pixel_Jamie_Hard_NeckPouch_1",
        licence="CC-BY-4.0",
        citation="Oxford step counter dataset (Oxford-step-counter/DataSet on GitHub)",
        source="https://github.com/Oxford-step-counter/DataSet",
        files=tuple(
            DataFile(
                f"oxford_steps/Pixel_Jamie_Hard_NeckPouch_1/{stem}",
                sha256,
                size,
                f"{_OXFORD}/{stem}",
            )
            for stem, sha256, size in _OXFORD_FILES
        ),
    ),
    "kinect": Dataset(
        name="kinect",
        title="Kinect v2 skeleton of a waving hand",
        path="kinect_laban/Ges01_wavehand.csv",
        licence="MIT",
        citation="Microsoft LabanotationSuite, Ges01_wavehand.csv",
        source="https://github.com/microsoft/LabanotationSuite",
        files=(
            DataFile(
                "kinect_laban/Ges01_wavehand.csv",
                _LABAN_SHA256,
                114790,
                f"{_LABAN}/Ges01_wavehand.csv",
            ),
        ),
    ),
    "head_traces": Dataset(
        name="head_traces",
        title="head orientation of people viewing 360-degree video",
        path="head_traces",
        licence="none stated (published for research)",
        citation=(
            "Corbillon, De Simone & Simon; Lo et al.; Wu et al., ACM MMSys 2017, via the "
            "360VidStr aggregation"
        ),
        source="the 360VidStr aggregation (github 360VidStr)",
        why_not_fetched=(
            "not downloadable: the 360VidStr aggregation states no licence; set VRLOCO_DATA to "
            "the folder holding head_traces/"
        ),
    ),
}


class DataMissing(FileNotFoundError):
    """A set of recordings is in neither ``$VRLOCO_DATA`` nor the cache."""


class FetchError(RuntimeError):
    """A download failed, did not match its hash, or could not be written; nothing was kept."""


def get_dataset(name: str) -> Dataset:
    """The set called ``name``.

    Raises:
        ValueError: an unknown name (listing the names).
    """
    try:
        return DATASETS[name]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown dataset {name!r}: the datasets are {', '.join(DATASETS)}"
        ) from None


def data_folder() -> Path | None:
    """``$VRLOCO_DATA`` (a folder laid out as the data folder), or None where it is unset."""
    env = os.environ.get("VRLOCO_DATA")
    return Path(env).expanduser() if env else None


def cache_folder() -> Path:
    """The download cache: ``$VRLOCO_CACHE``, else ``pooch.os_cache("vrloco")``."""
    env = os.environ.get("VRLOCO_CACHE")
    if env:
        return Path(env).expanduser()
    import pooch

    return Path(pooch.os_cache("vrloco"))


def _cache_problem(ds: Dataset, root: Path) -> str | None:
    """Why the cached copy of ``ds`` cannot be used (a file of the wrong size), or None."""
    for f in ds.files:
        size = (root / f.relpath).stat().st_size
        if size != f.size:
            return (
                f"{root / f.relpath} is {size} bytes, {f.size} expected: run "
                f"`vrloco data fetch {ds.name}` to download it again"
            )
    return None


def located(name: str) -> tuple[str, Path] | None:
    """Where the set ``name`` is: ``("VRLOCO_DATA", root)`` or ``("cache", root)``, or None.

    Raises:
        ValueError: an unknown name.
    """
    ds = get_dataset(name)
    env = data_folder()
    if env is not None and ds.in_folder(env):
        return "VRLOCO_DATA", env
    if ds.fetchable:
        cache = cache_folder()
        if ds.in_folder(cache):
            return "cache", cache
    return None


def data_path(name: str) -> Path:
    """What the readers take for the set ``name`` (its folder, or its file), from
    ``$VRLOCO_DATA`` where that holds the whole set, else from the download cache.

    Raises:
        ValueError: an unknown name (listing the names).
        DataMissing: the set is in neither place (one line naming both and the command that
            fetches it); a cached file of the wrong size (naming it).
    """
    ds = get_dataset(name)
    where = located(name)
    if where is not None:
        kind, root = where
        problem = _cache_problem(ds, root) if kind == "cache" else None
        if problem is not None:
            raise DataMissing(problem)
        return root / ds.path
    env = data_folder()
    if not ds.fetchable:
        at = f"at {str(env / ds.path)!r}" if env is not None else "(VRLOCO_DATA is not set)"
        raise DataMissing(f"{ds.name.replace('_', ' ')} not found {at}: {ds.why_not_fetched}")
    looked = f"in neither VRLOCO_DATA={str(env)!r} nor" if env is not None else "not in"
    raise DataMissing(
        f"{ds.name} ({ds.title}) is {looked} the cache {str(cache_folder())!r}: "
        f"run `vrloco data fetch {ds.name}`"
    )


def mirror_url(given: str | None = None, origin: str = "base_url") -> str | None:
    """The mirror to download from: ``given``, else ``$VRLOCO_DATA_URL``, else None (the
    canonical URLs).

    Raises:
        ValueError: a value that is not an http(s) URL (naming ``origin``, or
            VRLOCO_DATA_URL).
    """
    if not given:
        origin, given = "VRLOCO_DATA_URL", os.environ.get("VRLOCO_DATA_URL")
    if not given:
        return None
    if not given.startswith(("http://", "https://")) or given.endswith("://"):
        raise ValueError(f"{origin}={given!r} is not an http:// or https:// URL")
    return given.rstrip("/")


def _check_writable(folder: Path) -> None:
    """Create ``folder`` if need be and write a file in it.

    Raises:
        FetchError: it cannot be created or written (naming it).
    """
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as err:
        raise FetchError(
            f"cannot write to the data cache {str(folder)!r}: {err.strerror or err} (set "
            "VRLOCO_CACHE to a writable folder)"
        ) from None


class _HashingDownloader:
    """pooch's HTTP(S) downloader, remembering the SHA-256 of what it received."""

    def __init__(self, progressbar: bool):
        import pooch

        self.inner = pooch.HTTPDownloader(progressbar=progressbar, timeout=TIMEOUT_S)
        self.received: str | None = None

    def __call__(self, url: str, output_file: str, pooch_: object) -> None:
        import pooch

        self.received = None
        self.inner(url, output_file, pooch_)
        self.received = pooch.file_hash(output_file, alg="sha256")


@contextlib.contextmanager
def _quiet_pooch() -> Iterator[None]:
    """pooch's own log lines are replaced by this module's report."""
    import pooch

    logger = pooch.get_logger()
    level = logger.level
    logger.setLevel("WARNING")
    try:
        yield
    finally:
        logger.setLevel(level)


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__


def _reason(err: Exception) -> str:
    """What went wrong in a download, in a few words."""
    import re

    import requests

    if isinstance(err, requests.HTTPError) and err.response is not None:
        return f"HTTP {err.response.status_code} {err.response.reason}"
    if isinstance(err, requests.Timeout):
        return f"no answer for {TIMEOUT_S:.0f} s"
    if isinstance(err, requests.exceptions.ChunkedEncodingError):
        inner = err.args[0] if err.args else err
        first = inner.args[0] if isinstance(inner, Exception) and inner.args else inner
        return f"the connection broke off: {_one_line(Exception(first))}"
    found = re.search(r"\[Errno -?\d+\][^'\")]*", str(err))
    if isinstance(err, requests.ConnectionError) and found:
        return f"cannot connect: {found.group(0).strip()}"
    return _one_line(err)


def fetch(
    name: str,
    base_url: str | None = None,
    progressbar: bool = False,
    report: Callable[[str], None] | None = None,
) -> Path:
    """Download the set ``name`` into the cache (the files not already there with the pinned
    hash) and return :func:`data_path`'s answer for it in the cache.

    Args:
        name: a fetchable set (``broad``, ``oxford``, ``kinect``).
        base_url: download ``BASE/RELPATH`` instead of the canonical URLs (default
            ``$VRLOCO_DATA_URL``).
        progressbar: a progress bar per file (tqdm, on stderr).
        report: called with one line per file (``"downloaded broad/02_...hdf5"`` or
            ``"verified ..."``).

    Raises:
        ValueError: an unknown name, a set that is not downloadable (saying why), a bad base URL.
        FetchError: a download broke off or failed, a file did not match its SHA-256 (naming
            the file, expected and received hash), or the cache cannot be written (naming it).
            Nothing partial is kept under a file's name; a rerun fetches what is missing.
    """
    import pooch
    import requests

    ds = get_dataset(name)
    if not ds.fetchable:
        raise ValueError(f"{ds.name}: {ds.why_not_fetched}")
    mirror = mirror_url(base_url)
    root = cache_folder()
    for f in ds.files:
        _check_writable((root / f.relpath).parent)
    with _quiet_pooch():
        for f in ds.files:
            url = f"{mirror}/{f.relpath}" if mirror else f.url
            target = root / f.relpath
            existed = target.is_file()
            downloader = _HashingDownloader(progressbar)
            try:
                pooch.retrieve(
                    url,
                    known_hash=f"sha256:{f.sha256}",
                    fname=target.name,
                    path=target.parent,
                    downloader=downloader,
                )
            except ValueError as err:
                got = downloader.received
                if got is not None and got != f.sha256:
                    raise FetchError(
                        f"{f.relpath}: SHA-256 mismatch for the download from {url}: expected "
                        f"{f.sha256}, got {got}; it was not kept"
                    ) from None
                raise FetchError(
                    f"{f.relpath}: download from {url} failed: {_one_line(err)}"
                ) from None
            except requests.exceptions.RequestException as err:
                raise FetchError(
                    f"{f.relpath}: download from {url} failed ({_reason(err)}); "
                    f"nothing partial was kept: run `vrloco data fetch {ds.name}` "
                    "again"
                ) from None
            except OSError as err:
                space = " (the disk is full)" if err.errno == errno.ENOSPC else ""
                raise FetchError(
                    f"cannot write to the data cache {str(target.parent)!r}: "
                    f"{err.strerror or _one_line(err)}{space}; nothing partial was kept (set "
                    "VRLOCO_CACHE to another folder)"
                ) from None
            if report is not None:
                fresh = downloader.received is not None
                verb = "downloaded" if fresh else "verified"
                if fresh and existed:
                    verb = "replaced (hash mismatch)"
                report(f"{verb} {f.relpath}")
    return root / ds.path

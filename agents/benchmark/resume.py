"""The benchmark's output folder across runs: the finished episodes kept so that an interrupted
run resumes (:class:`EpisodeStore`, under the keys of :func:`episode_key`). One run at a time in
the folder, each run's files alone, is :mod:`agents.benchmark.run_folder`
(:class:`~agents.benchmark.run_folder.RunFolder`, re-exported here with
:class:`~agents.benchmark.run_folder.FolderBusy`).

Resume. While ``vrloco benchmark`` runs, every finished job (a batch of episodes) is written to
``<out>/.resume/<job>.npz``; a rerun with the same ``--out`` loads them and runs only the
episodes that are missing, then removes the folder once the grid is complete. An episode is
found again only under the same key: its task, policy, technique (the full definition),
condition, seed, whether it keeps a trace, a fingerprint of the package's source files
(:func:`source_fingerprint`) and one of the cell's own inputs (:func:`cell_inputs`: the
definitions of its condition and population, a ``.zip`` model's bytes, and the source of every
plug-in module the cell names and of the modules they import from their own folder or package),
so results of other code or other settings are never mixed in. The batch size and the worker
count are not part of the key: they do not change an episode's numbers.

An entry holds its numbers as arrays and its structure as JSON in one ``.npz`` file, read with
``allow_pickle=False`` and rebuilt from a fixed set of types, each field checked against its
annotation (:func:`decode_episodes`), so a file in ``.resume`` never runs code. Anything else
there (a truncated write, a crafted or foreign file, a right-size file of the wrong structure,
a ``.pkl`` of an older vrloco, which is never opened) is reported in one line and its episodes
run again; writes go to a temporary file first and are renamed into place.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import os
import re
import shutil
import sys
import sysconfig
import types
import typing
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from agents.benchmark.conditions import DEFAULT_CONDITION
from agents.benchmark.run_folder import FolderBusy, RunFolder
from estimators.numba_cache import PACKAGES as _PACKAGES
from estimators.numba_cache import ROOT as _ROOT

__all__ = [
    "EpisodeStore",
    "FolderBusy",
    "RunFolder",
    "cell_inputs",
    "decode_episodes",
    "encode_episodes",
    "episode_key",
    "source_fingerprint",
]


def source_fingerprint() -> str:
    """SHA-256 (hex, 16 characters) of every ``.py`` file of the three packages, in path order."""
    h = hashlib.sha256()
    for pkg in _PACKAGES:
        for path in sorted((_ROOT / pkg).rglob("*.py")):
            h.update(str(path.relative_to(_ROOT)).encode())
            h.update(path.read_bytes())
    return h.hexdigest()[:16]


def episode_key(
    fingerprint: str,
    task: str,
    policy: str,
    technique: Any,
    seed: int,
    trace: bool,
    condition: str = DEFAULT_CONDITION,
    inputs: str = "",
) -> str:
    """The key of one episode (see the module docstring); ``technique`` a Technique object,
    ``condition`` the physical room's (:mod:`agents.benchmark.conditions`; the default adds
    nothing), ``inputs`` the cell's :func:`cell_inputs` (empty adds nothing)."""
    where = () if condition == DEFAULT_CONDITION else (condition,)
    extra = (inputs,) if inputs else ()
    what = re.sub(r" at 0x[0-9a-fA-F]+", "", repr(technique))  # an object's address varies
    text = repr((fingerprint, task, policy, what, int(seed), bool(trace), *where, *extra))
    return hashlib.sha256(text.encode()).hexdigest()


# --------------------------------------------------------------------------- plug-in inputs


def cell_inputs(cells: Iterable[Any]) -> dict[Any, str]:
    """Each cell's inputs beyond its names and the package's sources, as SHA-256 (hex): the
    definitions of its condition and population, the bytes of a ``.zip`` policy, and the source
    of the plug-ins it names (its task, a ``module:attr`` or ``path/file.py:attr`` policy or
    technique, the technique's stages and parameter objects): every module imported in this
    process whose file lies in a plug-in's package (its top-level package's folder) or, for a
    plug-in module outside a package, in that module's folder, except installed packages (the
    standard library, ``site-packages``) and this project's packages (:func:`source_fingerprint`
    covers those). Importing a plug-in here is what the run does anyway: it is imported before
    the keys are made, so that what it imports at import time is in its cell's inputs."""
    cells = list(cells)
    parts = {c: _cell_parts(c) for c in cells}  # imports every plug-in first
    files = _module_files()
    digests: dict[Path, str] = {}

    def digest(path: Path) -> str:
        if path not in digests:
            try:
                digests[path] = hashlib.sha256(path.read_bytes()).hexdigest()
            except OSError as err:
                digests[path] = f"unreadable ({err.strerror})"
        return digests[path]

    out = {}
    for c, (texts, roots, blobs) in parts.items():
        lines = list(texts)
        for root in sorted(roots):
            lines += [f"{f.relative_to(root)} {digest(f)}" for f in files if f.is_relative_to(root)]
        lines += [f"{p} {digest(p)}" for p in sorted(blobs)]
        out[c] = hashlib.sha256("\n".join(lines).encode()).hexdigest()
    return out


def _cell_parts(cell: Any) -> tuple[list[str], set[Path], set[Path]]:
    """A cell's configuration texts, its plug-ins' root folders and its model files."""
    from agents.benchmark.conditions import get_condition
    from agents.benchmark.policies import SHIPPED
    from agents.learned.users import LEARNED_USERS
    from estimators import stages
    from estimators.registry import load_attr
    from vrloco_env.config import STAGE_FIELDS
    from vrloco_env.tasks import get_task
    from vrloco_env.techniques import TECHNIQUES, get_technique
    from vrloco_env.user.population import POPULATIONS

    texts = [repr(get_condition(cell.condition))]
    origins: list[Any] = [get_task(cell.task)]
    blobs: set[Path] = set()
    base, sep, suffix = cell.policy.rpartition("+")
    if sep and base and suffix in POPULATIONS:
        texts.append(repr(POPULATIONS[suffix]))
    else:
        base = cell.policy
    if base.endswith(".zip"):
        blobs.add(Path(base).resolve())
    elif base.split("@")[0] == SHIPPED and cell.task in LEARNED_USERS:
        blobs.add(LEARNED_USERS[cell.task].path)
    elif ":" in base:
        origins += [base, load_attr(base, "policy")]
    tech = get_technique(cell.technique)
    if isinstance(cell.technique, str) and cell.technique not in TECHNIQUES:
        origins.append(cell.technique)
    origins.append(tech)
    for f in dataclasses.fields(tech.estimators):
        value = getattr(tech.estimators, f.name)
        if f.name in STAGE_FIELDS:
            value = getattr(stages, f.name.upper()).factory(value)  # imports a plug-in
        origins.append(value)
    roots = {r for o in origins for r in _roots(o)}
    return texts, roots, blobs


def _roots(origin: Any) -> list[Path]:
    """The folders whose modules a plug-in stands for: for ``path/file.py:attr`` the file's
    folder; for a module (named by ``package.module:attr``, or the module of an object) its
    top-level package's folder, or a lone module's folder. Nothing for installed modules and
    this project's packages."""
    if isinstance(origin, str):
        module = origin.rpartition(":")[0]
        if module.endswith(".py"):
            return _own([Path(module).expanduser().resolve().parent])
    else:
        module = getattr(origin, "__module__", None)
        if not isinstance(module, str):
            module = type(origin).__module__
    top = sys.modules.get(module.partition(".")[0])
    if top is None:
        return []
    paths = getattr(top, "__path__", None)
    if paths is not None:
        return _own([Path(p).resolve() for p in paths])
    file = getattr(top, "__file__", None)
    return _own([Path(file).resolve().parent]) if file else []


def _own(folders: list[Path]) -> list[Path]:
    """``folders`` less installed ones and this project's packages."""
    project = [_ROOT / p for p in _PACKAGES]
    return [
        f for f in folders if not _installed(f) and not any(f.is_relative_to(p) for p in project)
    ]


def _installed(path: Path) -> bool:
    """Whether ``path`` lies in an installed package's folder or the standard library."""
    if {"site-packages", "dist-packages"} & set(path.parts):
        return True
    return any(path.is_relative_to(p) for p in _stdlib())


@functools.cache
def _stdlib() -> tuple[Path, ...]:
    paths = sysconfig.get_paths()
    return tuple(Path(paths[k]).resolve() for k in ("stdlib", "platstdlib") if k in paths)


def _module_files() -> list[Path]:
    """The files of the modules imported in this process (resolved), but those of installed
    packages and this project's."""
    files = {
        Path(f).resolve()
        for m in list(sys.modules.values())
        if isinstance(f := getattr(m, "__file__", None), str)
    }
    return sorted(f for f in files if _own([f]))


# --------------------------------------------------------------------------- stored episodes


class BadEntry(ValueError):
    """A ``.resume`` file that is not a valid entry; the message says what is wrong."""


def _classes() -> dict[str, type]:
    """The only types an entry may hold besides numbers, strings, containers and arrays."""
    from agents.benchmark.metrics import EpisodeStats
    from vrloco_env.world.geometry import Box, Cylinder
    from vrloco_env.world.layout import Layout

    return {c.__name__: c for c in (EpisodeStats, Layout, Box, Cylinder)}


def encode_episodes(entries: dict[str, Any]) -> dict[str, np.ndarray]:
    """A job's episodes (key -> ``(EpisodeStats, reset_info)``) as the members of an ``.npz``
    file: ``tree``, UTF-8 JSON of their structure, and ``b0``, ``b1``, ... the arrays' contents,
    one flat array per dtype. In the JSON, Python numbers stay numbers (``repr``: exact),
    containers and the types of :func:`_classes` are tagged, and each NumPy array or scalar is
    ``{"array": i}`` or ``{"scalar": i}``, ``arrays[i]`` giving its blob, offset and shape."""
    classes = _classes()
    blobs: dict[str, list[np.ndarray]] = {}
    sizes: dict[str, int] = {}
    table: list[list[Any]] = []

    def enc(v: Any) -> Any:
        if isinstance(v, np.ndarray | np.generic):
            a = np.asarray(v)
            if a.dtype.kind not in "biuf":
                raise TypeError(f"cannot keep a {a.dtype} array in .resume")
            dtype = a.dtype.str
            blobs.setdefault(dtype, []).append(a.ravel())
            table.append([list(blobs).index(dtype), sizes.get(dtype, 0), list(a.shape)])
            sizes[dtype] = sizes.get(dtype, 0) + a.size
            return {"array" if isinstance(v, np.ndarray) else "scalar": len(table) - 1}
        if v is None or isinstance(v, bool | int | float | str):
            return v
        if isinstance(v, tuple | list):
            return {type(v).__name__: [enc(x) for x in v]}
        if isinstance(v, dict):
            if not all(isinstance(k, str) for k in v):
                raise TypeError("cannot keep a dict with keys other than strings in .resume")
            return {"dict": {k: enc(x) for k, x in v.items()}}
        name = type(v).__name__
        if classes.get(name) is type(v):
            return {
                "object": [name, {f.name: enc(getattr(v, f.name)) for f in dataclasses.fields(v)}]
            }
        raise TypeError(f"cannot keep a {name} in .resume")

    doc = {"episodes": enc(entries), "arrays": table}
    members = {"tree": np.frombuffer(json.dumps(doc).encode(), np.uint8)}
    for k, parts in enumerate(blobs.values()):
        members[f"b{k}"] = np.concatenate(parts)
    return members


def decode_episodes(members: Any) -> dict[str, Any]:
    """The inverse of :func:`encode_episodes` (``members``: name -> array, an open ``.npz``),
    checked: every tag, array and object field against its annotation, then each episode
    (:func:`_check_episode`). A BadEntry says what is wrong."""
    classes = _classes()
    hints = {name: typing.get_type_hints(cls) for name, cls in classes.items()}
    names = set(getattr(members, "files", members))
    if "tree" not in names:
        raise BadEntry("no structure in it")
    tree = members["tree"]
    if tree.dtype != np.uint8 or tree.ndim != 1:
        raise BadEntry(f"its structure is {_describe(tree)}")
    try:
        doc = json.loads(tree.tobytes().decode("utf-8"))
    except ValueError as err:
        raise BadEntry(f"its structure is not JSON ({err})") from None
    if not (
        isinstance(doc, dict)
        and doc.keys() == {"episodes", "arrays"}
        and isinstance(doc["arrays"], list)
    ):
        raise BadEntry("its structure is not that of an entry")
    blobs: dict[int, np.ndarray] = {}

    def array(i: Any, where: str) -> np.ndarray:
        ok = isinstance(i, int) and not isinstance(i, bool) and 0 <= i < len(doc["arrays"])
        spec = doc["arrays"][i] if ok else None
        if not (
            isinstance(spec, list)
            and len(spec) == 3
            and isinstance(spec[2], list)
            and all(_natural(x) for x in (spec[0], spec[1], *spec[2]))
        ):
            raise BadEntry(f"{where}: array {str(i)[:20]} is not described")
        b, offset, shape = spec
        if b not in blobs:
            if f"b{b}" not in names:
                raise BadEntry(f"{where}: array {i}'s contents are missing")
            blobs[b] = members[f"b{b}"]
            if blobs[b].ndim != 1 or blobs[b].dtype.kind not in "biuf":
                raise BadEntry(f"{where}: contents {_describe(blobs[b])}")
        n = math.prod(shape)
        if offset + n > blobs[b].size:
            raise BadEntry(f"{where}: array {i} beyond its contents")
        return blobs[b][offset : offset + n].reshape(shape).copy()

    def dec(node: Any, where: str) -> Any:
        if node is None or isinstance(node, bool | int | float | str):
            return node
        if not (isinstance(node, dict) and len(node) == 1):
            raise BadEntry(f"{where}: an untagged {type(node).__name__}")
        ((tag, body),) = node.items()
        if tag == "array":
            return array(body, where)
        if tag == "scalar":
            a = array(body, where)
            if a.ndim != 0:
                raise BadEntry(f"{where}: a scalar of shape {a.shape}")
            return a[()]
        if tag in ("tuple", "list") and isinstance(body, list):
            items = [dec(x, f"{where}[{i}]") for i, x in enumerate(body)]
            return tuple(items) if tag == "tuple" else items
        if tag == "dict" and isinstance(body, dict):
            return {k: dec(x, f"{where}[{k!r}]") for k, x in body.items()}
        if tag == "object" and isinstance(body, list) and len(body) == 2:
            name, fields = body
            cls = classes.get(name) if isinstance(name, str) else None
            if cls is None or not isinstance(fields, dict):
                raise BadEntry(f"{where}: not a stored type ({str(name)[:40]!r})")
            annotated = hints[name]
            if fields.keys() != annotated.keys():
                raise BadEntry(f"{where}: {name} with fields {sorted(fields)}")
            values = {k: dec(x, f"{where}.{k}") for k, x in fields.items()}
            for k, v in values.items():
                if not _conforms(v, annotated[k]):
                    raise BadEntry(f"{name}.{k}: {_describe(v)} is not {annotated[k]}")
            return cls(**values)
        raise BadEntry(f"{where}: unknown tag {str(tag)[:40]!r}")

    entries = dec(doc["episodes"], "entry")
    if not isinstance(entries, dict) or not entries:
        raise BadEntry(f"entry: {_describe(entries)}, not a dict of episodes")
    for key, value in entries.items():
        if not re.fullmatch(r"[0-9a-f]{64}", key):
            raise BadEntry(f"key {key[:70]!r} is not an episode key")
        _check_episode(value)
    return entries


def _natural(x: Any) -> bool:
    return isinstance(x, int) and not isinstance(x, bool) and x >= 0


def _check_episode(value: Any) -> None:
    """A BadEntry unless ``value`` is ``(EpisodeStats, reset_info)`` as the runners give them:
    per-step arrays of one length, the trace's arrays and room, the measures the rows read."""
    from agents.benchmark.collision_causes import COLLISION_CAUSES
    from agents.benchmark.metrics import TRACE_KEYS, EpisodeStats
    from agents.benchmark.wip_measures import MOTION_KEYS, PLAY_AREA_KEYS
    from vrloco_env.world.layout import Layout

    if not (isinstance(value, tuple) and len(value) == 2):
        raise BadEntry(f"an episode is {_describe(value)}, not (stats, reset info)")
    st, info = value
    if not isinstance(st, EpisodeStats) or not isinstance(info, dict):
        raise BadEntry(f"an episode is ({_describe(st)}, {_describe(info)})")
    for k in ("step_report_delay_s", "shortest_path"):
        if not _conforms(info.get(k), float):
            raise BadEntry(f"reset info {k}: {_describe(info.get(k))}")
    if st.steps < 1 or st.collisions < 0:
        raise BadEntry(f"EpisodeStats.steps={st.steps}, collisions={st.collisions}")
    for k in (
        "true_counts",
        "detected_counts",
        "attitude_error_deg",
        "hand_error_deg",
        "heading_error_deg",
    ):
        if getattr(st, k).shape != (st.steps,):
            raise BadEntry(f"EpisodeStats.{k} of shape {getattr(st, k).shape}, not ({st.steps},)")
    for k in ("true_step_times", "detected_step_times"):
        if getattr(st, k) is not None and getattr(st, k).ndim != 1:
            raise BadEntry(f"EpisodeStats.{k} of shape {getattr(st, k).shape}")
    if st.trace is not None:
        if set(st.trace) != {*TRACE_KEYS, "layout"} or not isinstance(st.trace["layout"], Layout):
            raise BadEntry(f"EpisodeStats.trace with keys {sorted(st.trace)}")
        tails = {
            "position": (2,),
            "true_position": (2,),
            "true_ypr": (3,),
            "est_ypr": (3,),
            "true_step_times": None,
            "elapsed_time": None,
        }
        for k, tail in tails.items():
            a = st.trace[k]
            ok = (
                isinstance(a, np.ndarray)
                and a.dtype == np.float64
                and (a.shape[1:] == tail if tail else a.ndim == 1)
            )
            if not ok:
                raise BadEntry(f"EpisodeStats.trace[{k!r}]: {_describe(a)}")
        for k in (
            "virtual_yaw",
            "heading_error_deg",
            "collision",
            "intent_walk",
            "walk_yaw_deg",
            "true_body_yaw_deg",
            "detected_step_times",
        ):  # one entry per control step
            a = st.trace[k]
            ok = (
                isinstance(a, np.ndarray)
                and a.dtype == np.float64
                and a.shape[:1] == (st.steps,)
                and a.ndim == (2 if k == "detected_step_times" else 1)
            )
            if not ok:
                raise BadEntry(f"EpisodeStats.trace[{k!r}]: {_describe(a)}")
    for k, need in (
        ("motion", MOTION_KEYS),
        ("play_area", PLAY_AREA_KEYS),
        ("causes", COLLISION_CAUSES),
    ):
        d = getattr(st, k)
        if d is not None and not set(need) <= set(d):
            raise BadEntry(f"EpisodeStats.{k} without {sorted(set(need) - set(d))}")


def _conforms(value: Any, hint: Any) -> bool:
    """Whether ``value`` is of the annotated type ``hint`` (an int where a float is expected, as
    in Python's numeric tower; an array of the annotated dtype)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is Any:
        return True
    if hint is type(None):
        return value is None
    if origin in (types.UnionType, typing.Union):
        return any(_conforms(value, a) for a in args)
    if origin is np.ndarray:
        dtype = typing.get_args(args[1])[0] if len(args) == 2 else None
        return isinstance(value, np.ndarray) and (dtype is None or value.dtype == dtype)
    if origin is tuple:
        if not isinstance(value, tuple):
            return False
        if len(args) == 2 and args[1] is Ellipsis:
            return all(_conforms(v, args[0]) for v in value)
        return len(value) == len(args) and all(map(_conforms, value, args))
    if origin is dict:
        return isinstance(value, dict) and all(
            _conforms(k, args[0]) and _conforms(v, args[1]) for k, v in value.items()
        )
    if isinstance(value, bool | np.bool_):
        return hint is bool
    if hint is float:
        return isinstance(value, int | float | np.integer | np.floating)
    if hint is int:
        return isinstance(value, int | np.integer)
    return isinstance(hint, type) and isinstance(value, hint)


def _describe(v: Any) -> str:
    if isinstance(v, np.ndarray):
        return f"a {v.dtype} array of shape {v.shape}"
    if isinstance(v, tuple | list):
        return f"a {type(v).__name__} of {len(v)}"
    return f"a {type(v).__name__}"


class EpisodeStore:
    """The ``.resume`` folder of an output folder.

    Args:
        folder: where the job files live (created on the first save).
    """

    def __init__(self, folder: Path | str) -> None:
        self.folder = Path(folder)
        self._warned = False

    def load(self) -> dict[str, Any]:
        """Every valid episode: key -> ``(EpisodeStats, reset_info)``. Any other file is reported
        in one line and skipped: only ``.npz`` files are opened, with ``allow_pickle=False``."""
        found: dict[str, Any] = {}
        if not self.folder.is_dir():
            return found
        for path in sorted(self.folder.iterdir()):
            try:
                found.update(self._read(path))
            except Exception as err:  # nothing here runs code: whatever fails, those run again
                why = str(err) if isinstance(err, BadEntry) else f"{type(err).__name__}: {err}"
                print(f"resume: skipping unreadable {path} ({why[:300]}); its episodes run again")
        return found

    @staticmethod
    def _read(path: Path) -> dict[str, Any]:
        if path.suffix != ".npz" or not path.is_file():
            raise BadEntry("not an .npz entry of this version of vrloco; left unopened")
        with np.load(path, allow_pickle=False) as z:
            return decode_episodes(z)

    def save(self, entries: dict[str, Any]) -> Path | None:
        """Write one job's episodes (key -> ``(EpisodeStats, reset_info)``) atomically; the
        file's path, or None where it could not be written (said once, in one line: the run
        goes on, but could not resume those episodes)."""
        members = encode_episodes(entries)
        name = hashlib.sha256("".join(sorted(entries)).encode()).hexdigest()[:24]
        path = self.folder / f"{name}.npz"
        tmp = self.folder / f".{name}.{os.getpid()}.tmp"
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            with tmp.open("wb") as f:
                np.savez(f, **members)
            os.replace(tmp, path)
        except OSError as err:
            tmp.unlink(missing_ok=True)
            if not self._warned:
                self._warned = True
                print(
                    f"resume: cannot keep finished episodes in {self.folder} "
                    f"({err.strerror or err}); an interrupted run would run them again"
                )
            return None
        return path

    def clear(self) -> None:
        """Remove the folder (the grid is complete)."""
        shutil.rmtree(self.folder, ignore_errors=True)


def missing(keys: Iterable[str], found: dict[str, Any]) -> list[str]:
    """The keys not in ``found``."""
    return [k for k in keys if k not in found]

"""The benchmark's output folder across runs: resume keys that cover every input of an episode,
resume entries that cannot run code and are checked when read, one run per folder, and one
line (no traceback) for a full disk or a folder in use."""

import dataclasses
import errno
import importlib
import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from agents.benchmark import run_benchmark
from agents.benchmark.episodes import run_cell_batched, run_cell_episode
from agents.benchmark.grid import Cell
from agents.benchmark.resume import EpisodeStore
from agents.cli import main

TINY = {
    "tasks": ["approach"],
    "techniques": ["zhang2021"],
    "episodes": 1,
    "workers": 1,
    "progress": False,
    "print_table": False,
}


def _fresh(folder: Path) -> None:
    """Forget the modules imported from ``folder``, as a new process would not have them."""
    for name, module in list(sys.modules.items()):
        file = getattr(module, "__file__", None)
        if file and Path(file).resolve().is_relative_to(folder.resolve()):
            del sys.modules[name]
    importlib.invalidate_caches()


def _same_episode(a, b) -> None:
    """Two episodes agree in every number, to the bit, and in every type."""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.name == "trace":
            assert (x is None) == (y is None)
            for k in () if x is None else x:
                if k == "layout":
                    assert x[k] == y[k]
                else:
                    assert x[k].dtype == y[k].dtype
                    np.testing.assert_array_equal(x[k], y[k], err_msg=f"trace {k}")
        elif isinstance(x, np.ndarray):
            assert x.dtype == y.dtype, f.name
            np.testing.assert_array_equal(x, y, err_msg=f.name)
        elif isinstance(x, dict):
            assert {k: (type(v), repr(v)) for k, v in x.items()} == {
                k: (type(v), repr(v)) for k, v in y.items()
            }, f.name
        else:
            assert type(x) is type(y) and x == y, f.name


@pytest.fixture
def keep_resume(monkeypatch):
    """The ``.resume`` folder stays after a complete run (as after Ctrl-C), so that the next
    run shows which episodes it finds; the package's sources count as unchanged meanwhile (an
    edit of them changes every key, :func:`agents.benchmark.resume.source_fingerprint`)."""
    import agents.benchmark.run

    monkeypatch.setattr(EpisodeStore, "clear", lambda self: None)
    monkeypatch.setattr(sys, "dont_write_bytecode", True)  # each edit is read from its source
    sources = agents.benchmark.run.source_fingerprint()
    monkeypatch.setattr(agents.benchmark.run, "source_fingerprint", lambda: sources)


# --------------------------------------------------------------------------- resume keys


def test_an_edited_plugin_or_a_module_it_imports_runs_again(
    tmp_path, monkeypatch, capsys, keep_resume
):
    """A ``path/file.py:attr`` user and a ``package.module:attr`` user, each walking at the
    cadence its helper module sets: editing a helper, or the plug-in file itself, runs that
    user's cell again (with other numbers) and resumes every other cell."""
    plugins = tmp_path / "plugins"  # a folder of files, and a package in a folder of its own
    (plugins / "files").mkdir(parents=True)
    (plugins / "packages" / "walkpkg").mkdir(parents=True)
    monkeypatch.syspath_prepend(str(plugins / "files"))
    monkeypatch.syspath_prepend(str(plugins / "packages"))
    user = (
        "import numpy as np\n"
        "from {helper} import WALK\n"
        "TURN = {turn}\n"
        "class Walker:\n"
        "    def __init__(self, env):\n"
        "        self.n = env.action_space.shape[-1]\n"
        "    def reset(self, rng=None, rows=None):\n"
        "        pass\n"
        "    def act(self, obs):\n"
        "        return np.array([WALK, TURN] + [0.0] * (self.n - 2), np.float32)\n"
    )
    files, package = plugins / "files", plugins / "packages" / "walkpkg"
    (files / "walker.py").write_text(user.format(helper="walk_speed", turn=0.3))
    (files / "walk_speed.py").write_text("WALK = 0.8\n")
    (package / "__init__.py").write_text("")
    (package / "users.py").write_text(user.format(helper="walkpkg.speed", turn=-0.3))
    (package / "speed.py").write_text("WALK = 0.8\n")
    by_file, by_package = f"{files / 'walker.py'}:Walker", "walkpkg.users:Walker"
    kw = {**TINY, "policies": ["goal_seeker", by_file, by_package], "out_dir": tmp_path / "out"}

    def run(edit: tuple[Path, str] | None, found: int) -> dict:
        if edit is not None:
            edit[0].write_text(edit[1])
        _fresh(plugins)
        capsys.readouterr()
        rows = run_benchmark(**kw)
        said = capsys.readouterr().out
        assert (
            (f"resuming: {found} of 3 episodes" in said) if found else ("resuming" not in said)
        ), said
        return {r["policy"]: r for r in rows}

    first = run(None, 0)
    assert run(None, 3) == first  # nothing edited: every episode found
    slower = run((files / "walk_speed.py", "WALK = 0.45\n"), 2)  # the file plug-in's helper
    assert slower[by_file] != first[by_file]
    assert slower[by_package] == first[by_package] and slower["goal_seeker"] == first["goal_seeker"]
    pkg = run((package / "speed.py", "WALK = 0.45\n"), 2)  # a module of the plug-in's package
    assert pkg[by_package] != first[by_package] and pkg[by_file] == slower[by_file]
    turned = run((files / "walker.py", user.format(helper="walk_speed", turn=0.6)), 2)  # itself
    assert turned[by_file] != slower[by_file] and turned[by_package] == pkg[by_package]


def test_a_changed_model_condition_or_population_changes_the_keys(tmp_path, monkeypatch):
    """A ``.zip`` policy's bytes, a condition's and a population's definitions are inputs."""
    from agents.benchmark.conditions import CONDITIONS, Condition
    from agents.benchmark.run import _episode_keys
    from vrloco_env.user.population import POPULATIONS

    model = tmp_path / "user.zip"
    model.write_bytes(b"a model")
    cells = [
        Cell("approach", str(model)),
        Cell("approach", "goal_seeker+nodders"),
        Cell("approach", "goal_seeker", "zhang2021", "beside_metal"),
    ]

    def keys() -> list[str]:
        return list(_episode_keys(cells, 2, 0, False).values())

    before = keys()
    assert keys() == before and len(set(before)) == 6
    model.write_bytes(b"another model")
    after_zip = keys()
    assert after_zip[:2] != before[:2] and after_zip[2:] == before[2:]
    monkeypatch.setitem(
        POPULATIONS, "nodders", dataclasses.replace(POPULATIONS["nodders"], nod_rate_hz=(0.3, 0.4))
    )
    after_population = keys()
    assert after_population[2:4] != after_zip[2:4] and after_population[4:] == after_zip[4:]
    cabinet = CONDITIONS["beside_metal"]
    monkeypatch.setitem(
        CONDITIONS,
        "beside_metal",
        Condition("beside_metal", cabinet.description, cabinet.magnetic_disturbances * 2),
    )
    assert keys()[4:] != after_population[4:] and keys()[:4] == after_population[:4]


# --------------------------------------------------------------------------- stored episodes


def test_stored_episodes_come_back_bit_for_bit_from_a_file_without_pickles(tmp_path):
    """Episodes of the single and the batched runner, with a trace and its room, through an
    entry file read with ``allow_pickle=False``: every number, dtype and type the same."""
    from agents.benchmark.resume import EpisodeStore

    single = [
        run_cell_episode(Cell(t, "goal_seeker"), 3, trace=True)
        for t in ("approach", "avoid", "interact", "doorway", "reach")
    ]
    batched = run_cell_batched(
        Cell("avoid", "goal_seeker+human", "smooth"), [4, 5], [True, False], batch_size=2
    )
    entries = {f"{i:064x}": e for i, e in enumerate(single + batched)}
    store = EpisodeStore(tmp_path / ".resume")
    path = store.save(entries)
    assert path is not None and path.suffix == ".npz"
    with np.load(path, allow_pickle=False) as z:
        assert all(z[name].dtype != object for name in z.files)
    found = store.load()
    assert list(found) == list(entries)
    for key, (stats, info) in entries.items():
        _same_episode(stats, found[key][0])
        assert found[key][1].keys() == info.keys()
        for k, v in info.items():
            assert type(found[key][1][k]) is type(v)
            np.testing.assert_array_equal(found[key][1][k], v)


class _Marker:
    """A pickle that creates a file when it is loaded."""

    def __init__(self, path: Path) -> None:
        self.path = str(path)

    def __reduce__(self):
        return (open, (self.path, "w"))


def test_a_crafted_file_in_resume_never_runs_code(tmp_path, capsys):
    marker = tmp_path / "code-ran"
    out = tmp_path / "shared"
    (out / ".resume").mkdir(parents=True)
    evil = pickle.dumps({"0" * 64: _Marker(marker)})
    (out / ".resume" / f"{'ab' * 12}.pkl").write_bytes(evil)  # an older vrloco's entry name
    (out / ".resume" / "entry.npz").write_bytes(evil)  # a pickle under an entry's name
    with (out / ".resume" / "objects.npz").open("wb") as f:  # an object array inside an npz
        tree = {"episodes": {"dict": {"0" * 64: {"array": 0}}}, "arrays": [[0, 0, [1]]]}
        np.savez(
            f,
            tree=np.frombuffer(json.dumps(tree).encode(), np.uint8),
            b0=np.array([_Marker(marker)], dtype=object),
        )
    rows = run_benchmark(**TINY, policies=["goal_seeker"], out_dir=out)
    said = capsys.readouterr().out
    assert not marker.exists()
    for name in (f"{'ab' * 12}.pkl", "entry.npz", "objects.npz"):
        (line,) = [s for s in said.splitlines() if name in s]
        assert line.startswith("resume: skipping unreadable") and "run again" in line
    assert rows == run_benchmark(**TINY, policies=["goal_seeker"])


def _rewrite(path: Path, change) -> None:
    """Rewrite an entry file: ``change(tree)`` edits its structure (``{"episodes": ...,
    "arrays": [[blob, offset, shape], ...]}``)."""
    with np.load(path, allow_pickle=False) as z:
        members = {k: z[k] for k in z.files}
    tree = json.loads(members.pop("tree").tobytes())
    change(tree)
    with path.open("wb") as f:
        np.savez(f, tree=np.frombuffer(json.dumps(tree).encode(), np.uint8), **members)


def test_corrupt_resume_entries_are_named_and_run_again(tmp_path, capsys, keep_resume):
    """A truncated entry, one of the right size but another structure, one whose array has the
    wrong dtype and shape, and an older vrloco's pickle of the wrong structure: each named in one
    line, its episodes run again, the table that of a run that never stopped."""
    kw = {**TINY, "policies": ["goal_seeker", "avoid_manoeuvre"], "episodes": 2, "batch_size": 0}
    out = tmp_path / "out"
    clean = run_benchmark(**kw, out_dir=out)
    files = sorted((out / ".resume").glob("*.npz"))
    assert len(files) == 4  # one per episode
    files[0].write_bytes(files[0].read_bytes()[: files[0].stat().st_size // 2])

    def three(tree):  # (stats, reset info, one more): right size, wrong structure
        (value,) = tree["episodes"]["dict"].values()
        value["tuple"].append(1)

    def floats(tree):  # the step counts read from the float blob, 3 of them
        (value,) = tree["episodes"]["dict"].values()
        stats = value["tuple"][0]["object"][1]
        counts = tree["arrays"][stats["true_counts"]["array"]]
        counts[:] = [tree["arrays"][stats["attitude_error_deg"]["array"]][0], 0, [3]]

    _rewrite(files[1], three)
    _rewrite(files[2], floats)
    with np.load(files[3], allow_pickle=False) as z:
        key = next(iter(json.loads(z["tree"].tobytes())["episodes"]["dict"]))
    (out / ".resume" / f"{'cd' * 12}.pkl").write_bytes(pickle.dumps({key: (1, 2, 3)}))
    capsys.readouterr()
    rows = run_benchmark(**kw, out_dir=out)
    said = capsys.readouterr().out
    assert "resuming: 1 of 4 episodes" in said
    for path in (*files[:3], out / ".resume" / f"{'cd' * 12}.pkl"):
        (line,) = [s for s in said.splitlines() if path.name in s]
        assert line.startswith("resume: skipping unreadable") and line.endswith("run again")
    assert "Traceback" not in said
    assert rows == clean


# --------------------------------------------------------------------------- one run, one folder


def _bench(*args: str) -> list[str]:
    return [
        "benchmark",
        "--tasks",
        "approach",
        "--policies",
        "goal_seeker",
        "--episodes",
        "1",
        "--workers",
        "1",
        *args,
    ]


def test_a_folder_holding_another_runs_results_is_refused_unless_forced(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(_bench("--techniques", "zhang2021", "--out", str(out))) == 0
    mine = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    capsys.readouterr()
    assert main(_bench("--techniques", "zhang2021,smooth", "--out", str(out))) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"vrloco benchmark: --out {out} holds another run's results")
    assert "--force" in line
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == mine  # untouched
    assert main(_bench("--techniques", "smooth", "--out", str(out), "--force")) == 0
    names = {p.name for p in out.iterdir()}
    assert "trajectory_approach_goal_seeker_smooth.png" in names
    assert not any("zhang2021" in n for n in names)  # the other run's files are gone
    rows = json.loads((out / "benchmark.json").read_text())["rows"]
    assert [r["technique"] for r in rows] == ["smooth"]
    legacy = tmp_path / "legacy"  # results written without a record of their run
    legacy.mkdir()
    (legacy / "benchmark.csv").write_text("task\n")
    capsys.readouterr()
    assert main(_bench("--out", str(legacy))) == 2
    assert "no record of their run" in capsys.readouterr().err
    assert (legacy / "benchmark.csv").read_text() == "task\n"


_HOLD = """
import fcntl, os, sys, time
os.makedirs(sys.argv[1], exist_ok=True)
with open(os.path.join(sys.argv[1], ".lock"), "w") as lock:  # as a run holds its folder
    fcntl.flock(lock, fcntl.LOCK_EX)
    lock.write(f"{os.getpid()}\\n")
    lock.flush()
    print("held", flush=True)
    time.sleep(60)
"""


@pytest.mark.skipif(sys.platform == "win32", reason="fcntl")
def test_a_folder_another_run_is_writing_to_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    holder = subprocess.Popen(
        [sys.executable, "-c", _HOLD, str(out)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout.readline().strip() == "held"
        assert main(_bench("--out", str(out))) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err
        assert str(out) in err and f"pid {holder.pid}" in err
        assert not (out / "benchmark.csv").exists()
    finally:
        holder.kill()
        holder.wait()
    from agents.benchmark.resume import RunFolder

    with RunFolder(out, "mine", "this run"):  # a dead holder's lock is free
        assert (out / ".lock").read_text().strip() == str(os.getpid())


def test_a_full_disk_while_writing_ends_in_one_line_and_keeps_the_earlier_files(
    tmp_path, capsys, monkeypatch
):
    import csv

    import matplotlib.figure

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    out = tmp_path / "out"
    assert main(_bench("--out", str(out))) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    for target, name, failing in (
        (matplotlib.figure.Figure, "savefig", "trajectory_"),
        (csv.DictWriter, "writeheader", "benchmark.csv"),
    ):
        with monkeypatch.context() as m:
            m.setattr(target, name, full)
            capsys.readouterr()
            assert main(_bench("--out", str(out))) == 1
        (line,) = capsys.readouterr().err.splitlines()
        assert line.startswith(f"vrloco benchmark: cannot write {out / failing}")
        assert line.endswith(os.strerror(errno.ENOSPC))
        after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
        assert after == before  # no half-written file, no file of the failed write
        assert sorted(p.name for p in out.iterdir() if p.is_dir()) == [".resume"]

"""`vrloco data` and :mod:`agents.recordings.data`: fetching the real recordings from a local HTTP
server that serves the development copies (../shared/data), and finding them afterwards.

The server listens on 127.0.0.1 on an ephemeral port, in a thread, for the length of one test;
it can serve a file corrupted (one byte changed) or cut off (the connection closed halfway).
"""

from __future__ import annotations

import errno
import hashlib
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote

import pytest

from agents.cli import main
from agents.recordings import data

SHARED = Path(__file__).resolve().parents[4] / "shared" / "data"
KINECT = "kinect_laban/Ges01_wavehand.csv"
OXFORD_ACC = "oxford_steps/Pixel_Jamie_Hard_NeckPouch_1/accelerometer.csv"

pytestmark = pytest.mark.timeout(120)


class _Server:
    """A local HTTP server over ``root``; ``faults[relpath]`` is ``"corrupt"`` or ``"drop"``."""

    def __init__(self, root: Path):
        self.faults: dict[str, str] = {}
        self.requests: list[str] = []
        server = self

        class Handler(SimpleHTTPRequestHandler):
            def __init__(self, *a, **kw):
                super().__init__(*a, directory=str(root), **kw)

            def log_message(self, *a):  # quiet
                pass

            def do_GET(self):
                rel = unquote(self.path.split("?")[0].lstrip("/"))
                server.requests.append(rel)
                fault = server.faults.get(rel)
                if fault is None:
                    return super().do_GET()
                body = bytearray((root / rel).read_bytes())
                if fault == "corrupt":
                    body[len(body) // 2] ^= 0xFF
                self.send_response(200)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                if fault == "drop":  # half the promised bytes, then the connection closes
                    self.wfile.write(bytes(body[: len(body) // 2]))
                    self.wfile.flush()
                    self.close_connection = True
                    return None
                self.wfile.write(bytes(body))
                return None

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join(timeout=10)


@pytest.fixture
def server(monkeypatch):
    if not SHARED.is_dir():
        pytest.skip(
            f"the development copies of the recordings are not at {SHARED} (they are "
            "served to the fetch tests)"
        )
    for var in ("http_proxy", "https_proxy", "HTTP_PROXY", "HTTPS_PROXY", "ALL_PROXY", "all_proxy"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("NO_PROXY", "127.0.0.1,localhost")
    with _Server(SHARED) as srv:
        yield srv


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache, and no VRLOCO_DATA: only what is fetched can be found."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("VRLOCO_CACHE", str(folder))
    monkeypatch.delenv("VRLOCO_DATA", raising=False)
    monkeypatch.delenv("VRLOCO_DATA_URL", raising=False)
    return folder


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if p.is_file()) if folder.exists() else []


def test_the_pinned_files_are_the_ones_the_readers_use():
    """Every fetchable set lists the files of its layout, once, with a SHA-256 and a size, and
    a canonical https URL at a pinned commit; the readers' path lies inside the set."""
    assert set(data.DATASETS) == {"broad", "oxford", "kinect", "head_traces"}
    broad = data.DATASETS["broad"].files
    assert [f.relpath.split("/")[1][:2] for f in broad] == [
        "02",
        "07",
        "11",
        "16",
        "21",
        "25",
        "27",
        "30",
        "33",
    ]
    for ds in data.DATASETS.values():
        if not ds.fetchable:
            assert ds.name == "head_traces" and "no licence" in ds.why_not_fetched
            continue
        assert len({f.relpath for f in ds.files}) == len(ds.files)
        for f in ds.files:
            assert f.relpath == ds.path or f.relpath.startswith(ds.path + "/")
            assert len(f.sha256) == 64 and int(f.sha256, 16) >= 0 and f.size > 0
            assert f.url.startswith("https://github.com/") and f.url.endswith(
                f.relpath.rsplit("/", 1)[1]
            )
            assert len(f.url.split("/raw/")[1].split("/")[0]) == 40  # a commit, not a branch


def test_fetch_from_a_local_server_lands_each_set_in_the_cache_with_its_hash(server, cache, capsys):
    """`vrloco data fetch broad oxford kinect` from the server: every file arrives in the cache
    with the bytes served, the command names where and the licence and citation, and the
    finder then answers from the cache; a second fetch downloads nothing."""
    assert main(["data", "fetch", "broad", "oxford", "kinect", "--url", server.url]) == 0
    out = capsys.readouterr().out
    for name in ("broad", "oxford", "kinect"):
        ds = data.DATASETS[name]
        assert f"{name}: {cache / ds.path}" in out
        assert f"licence {ds.licence}; cite: {ds.citation}" in out
        for f in ds.files:
            assert f"downloaded {f.relpath}" in out
            assert _sha256(cache / f.relpath) == _sha256(SHARED / f.relpath) == f.sha256
        assert data.data_path(name) == cache / ds.path
    assert sorted(server.requests) == sorted(
        f.relpath for n in ("broad", "oxford", "kinect") for f in data.DATASETS[n].files
    )
    assert _leftovers(cache) == sorted(
        Path(f.relpath).name for n in ("broad", "oxford", "kinect") for f in data.DATASETS[n].files
    )  # no temporary file left behind
    server.requests.clear()
    assert main(["data", "fetch", "kinect", "--url", server.url]) == 0
    assert f"verified {KINECT}" in capsys.readouterr().out and server.requests == []
    assert main(["data", "where", "kinect"]) == 0
    assert capsys.readouterr().out.strip() == str(cache / KINECT)


def test_a_corrupted_download_is_refused_and_nothing_is_kept(server, cache, monkeypatch, capsys):
    """A file whose bytes do not match the pinned hash: one error naming the file, the expected
    and the received SHA-256; nothing under its name (nor a temporary) in the cache."""
    server.faults[KINECT] = "corrupt"
    body = bytearray((SHARED / KINECT).read_bytes())
    body[len(body) // 2] ^= 0xFF
    got = hashlib.sha256(body).hexdigest()
    expected = data.DATASETS["kinect"].files[0].sha256
    with pytest.raises(data.FetchError) as info:
        data.fetch("kinect", base_url=server.url)
    msg = str(info.value)
    assert KINECT in msg and f"expected {expected}" in msg and f"got {got}" in msg
    assert "\n" not in msg
    assert not (cache / KINECT).exists() and _leftovers(cache) == []
    with pytest.raises(data.DataMissing, match=r"vrloco data fetch kinect"):
        data.data_path("kinect")
    # the command: one line on stderr, exit 1; VRLOCO_DATA_URL is the same setting as --url
    monkeypatch.setenv("VRLOCO_DATA_URL", server.url)
    assert main(["data", "fetch", "kinect"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("vrloco data fetch: kinect_laban/Ges01_wavehand.csv: SHA-256 mismatch")
    assert len(err.strip().splitlines()) == 1 and _leftovers(cache) == []


def test_a_dropped_connection_keeps_nothing_and_a_rerun_succeeds(server, cache):
    """The server closes the connection halfway through a file: an error naming the file and
    its URL; no partial file is kept or found; once the server behaves, a rerun fetches it."""
    server.faults[OXFORD_ACC] = "drop"
    with pytest.raises(data.FetchError) as info:
        data.fetch("oxford", base_url=server.url)
    msg = str(info.value)
    assert msg.startswith(
        f"{OXFORD_ACC}: download from {server.url}/{OXFORD_ACC} failed (the connection broke off: "
    )
    assert "vrloco data fetch oxford" in msg and "\n" not in msg
    assert not (cache / OXFORD_ACC).exists()
    assert all(not name.startswith("tmp") for name in _leftovers(cache))
    with pytest.raises(data.DataMissing, match=r"vrloco data fetch oxford"):
        data.data_path("oxford")
    del server.faults[OXFORD_ACC]
    path = data.fetch("oxford", base_url=server.url)
    assert data.data_path("oxford") == path == cache / data.DATASETS["oxford"].path
    for f in data.DATASETS["oxford"].files:
        assert _sha256(cache / f.relpath) == f.sha256
    assert _leftovers(cache) == ["accelerometer.csv", "stepcounter.csv"]


def test_a_truncated_file_in_the_cache_is_not_used_and_a_fetch_replaces_it(server, cache):
    """A cached file cut short (by anything but this module): the finder refuses it, naming it;
    a fetch checks the hash and downloads it again."""
    path = data.fetch("kinect", base_url=server.url)
    full = path.read_bytes()
    path.write_bytes(full[: len(full) // 3])
    with pytest.raises(
        data.DataMissing,
        match=r"Ges01_wavehand\.csv is 38263 bytes, 114790 "
        r"expected: run `vrloco data fetch kinect`",
    ):
        data.data_path("kinect")
    lines = []
    data.fetch("kinect", base_url=server.url, report=lines.append)
    assert lines == [f"replaced (hash mismatch) {KINECT}"] and path.read_bytes() == full


def test_a_missing_set_names_the_places_and_the_command(cache, tmp_path, monkeypatch, capsys):
    """Absent everywhere: one line naming the cache (and VRLOCO_DATA where set) and the command
    that fetches the set; the head traces, never fetched, name VRLOCO_DATA."""
    with pytest.raises(data.DataMissing) as info:
        data.data_path("broad")
    assert str(info.value) == (
        f"broad (BROAD, nine IMU trials with optical ground truth) is not in the cache "
        f"{str(cache)!r}: run `vrloco data fetch broad`"
    )
    monkeypatch.setenv("VRLOCO_DATA", str(tmp_path / "mine"))
    (tmp_path / "mine" / "broad").mkdir(parents=True)  # a folder without the trials
    with pytest.raises(data.DataMissing, match=r"in neither VRLOCO_DATA='.*mine' nor the cache"):
        data.data_path("broad")
    with pytest.raises(
        data.DataMissing,
        match=r"head traces not found at '.*head_traces': not "
        r"downloadable: .* set VRLOCO_DATA",
    ):
        data.data_path("head_traces")
    monkeypatch.delenv("VRLOCO_DATA")
    with pytest.raises(data.DataMissing, match=r"VRLOCO_DATA is not set"):
        data.data_path("head_traces")
    assert main(["data", "where", "oxford"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("vrloco data where: oxford (") and "`vrloco data fetch oxford`" in err
    assert len(err.strip().splitlines()) == 1


def test_vrloco_data_is_looked_in_first_and_list_says_where_each_set_is(
    cache, tmp_path, monkeypatch, capsys
):
    """A set in VRLOCO_DATA is found there; `vrloco data list` says, for each set, where it is
    (or the command that fetches it), its licence and citation."""
    mine = tmp_path / "mine"
    (mine / "kinect_laban").mkdir(parents=True)
    (mine / KINECT).write_text("1,2\n")
    monkeypatch.setenv("VRLOCO_DATA", str(mine))
    assert data.data_path("kinect") == mine / KINECT
    assert main(["data", "list"]) == 0
    out = capsys.readouterr().out
    assert f"in VRLOCO_DATA: {mine / KINECT}" in out
    assert "absent: `vrloco data fetch broad`" in out
    assert "absent: `vrloco data fetch oxford`" in out
    assert "absent: not downloadable: the 360VidStr aggregation states no licence" in out
    for ds in data.DATASETS.values():
        assert f"licence {ds.licence}" in out and f"cite: {ds.citation}" in out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["data", "fetch", "nope"],
            "vrloco data fetch: unknown dataset 'nope': the datasets are broad, oxford, kinect, "
            "head_traces",
        ),
        (["data", "fetch", "kinect", "nope"], "unknown dataset 'nope'"),  # checked before work
        (["data", "where", "nope"], "vrloco data where: unknown dataset 'nope'"),
        (
            ["data", "fetch", "head_traces"],
            "vrloco data fetch: head_traces: not downloadable: the 360VidStr aggregation states no "
            "licence; set VRLOCO_DATA to the folder holding head_traces/",
        ),
        (
            ["data", "fetch", "kinect", "--url", "127.0.0.1:8000"],
            "vrloco data fetch: --url='127.0.0.1:8000' is not an http:// or https:// URL",
        ),
    ],
)
def test_bad_names_and_urls_are_one_line_before_any_download(cache, argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not cache.exists()  # nothing was attempted
    with pytest.raises(ValueError, match=r"unknown dataset 'x': the datasets are broad, oxford"):
        data.data_path("x")
    with pytest.raises(ValueError, match=r"^head_traces: not downloadable: the 360VidStr "):
        data.fetch("head_traces")
    assert not cache.exists()


def test_a_bad_vrloco_data_url_and_a_missing_file_on_the_server_are_named(
    server, cache, monkeypatch
):
    monkeypatch.setenv("VRLOCO_DATA_URL", "file:///tmp")
    with pytest.raises(ValueError, match=r"VRLOCO_DATA_URL='file:///tmp' is not an http"):
        data.fetch("kinect")
    with pytest.raises(
        data.FetchError,
        match=rf"{KINECT}: download from {server.url}/nothing/"
        rf"{KINECT} failed \(HTTP 404 File not found\)",
    ):
        data.fetch("kinect", base_url=f"{server.url}/nothing")
    assert _leftovers(cache) == []


def test_a_cache_folder_that_cannot_be_written_is_named(server, tmp_path, monkeypatch, capsys):
    """A cache path that cannot be a folder (a file is in the way): one error naming it, exit 1,
    before any download."""
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.setenv("VRLOCO_CACHE", str(blocker / "cache"))
    monkeypatch.delenv("VRLOCO_DATA", raising=False)
    folder = blocker / "cache" / "kinect_laban"
    with pytest.raises(
        data.FetchError,
        match=rf"cannot write to the data cache '{folder}': Not a "
        r"directory \(set VRLOCO_CACHE",
    ):
        data.fetch("kinect", base_url=server.url)
    assert main(["data", "fetch", "kinect", "--url", server.url]) == 1
    err = capsys.readouterr().err
    assert err.startswith("vrloco data fetch: cannot write to the data cache")
    assert server.requests == []


def test_a_read_only_cache_folder_is_named(server, cache):
    cache.mkdir()
    cache.chmod(0o500)
    try:
        if _writable(cache):
            pytest.skip(
                "this user writes to read-only folders (root): the read-only case is "
                "covered by the file-in-the-way test"
            )
        with pytest.raises(data.FetchError, match=rf"cannot write to the data cache '{cache}"):
            data.fetch("kinect", base_url=server.url)
    finally:
        cache.chmod(0o700)


def _writable(folder: Path) -> bool:
    try:
        (folder / "probe").write_text("")
    except OSError:
        return False
    (folder / "probe").unlink()
    return True


def test_a_full_disk_mid_download_is_named_and_leaves_nothing(server, cache, monkeypatch):
    """The disk fills while a file is written: one error naming the cache folder and the cause,
    and neither the file nor its temporary remains."""
    import pooch

    real_call = pooch.HTTPDownloader.__call__

    def fill_up(self, url, output_file, pooch_):
        with open(output_file, "wb") as out:
            out.write(b"x" * 1000)
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pooch.HTTPDownloader, "__call__", fill_up)
    with pytest.raises(
        data.FetchError,
        match=r"cannot write to the data cache '.*kinect_laban'"
        r": No space left on device \(the disk is full\); nothing",
    ):
        data.fetch("kinect", base_url=server.url)
    assert _leftovers(cache) == []
    monkeypatch.setattr(pooch.HTTPDownloader, "__call__", real_call)
    assert data.fetch("kinect", base_url=server.url) == cache / KINECT

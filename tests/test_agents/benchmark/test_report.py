"""The benchmark's report.html: one self-contained page per run that renders in a browser with
no script error, shows every cell's row, and replays each cell's first episodes with every
collision marked by its cause (the causes the rows count)."""

import json
import re
import shutil
import subprocess
from collections import Counter
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from agents.benchmark import run_benchmark
from agents.benchmark.collision_causes import COLLISION_CAUSES
from agents.benchmark.figures import cell_name
from agents.benchmark.outputs import ROW_KEYS
from agents.benchmark.report import (
    CAUSE_COLOURS,
    MAX_FRAMES,
    NAME_COLUMNS,
    OUTCOME_COLUMNS,
    REPLAY_EPISODES,
    WIP_COLUMNS,
)

#: Avoid with Zhang 2021's chain and the smooth filter, seeds 0-2: both collide (Zhang 2021 once,
#: a phantom step; smooth 29 times, phantom steps and stop latency), and every episode of a
#: cell is replayed, so the replays' collisions are all the row counts.
RUN = {
    "tasks": ["avoid"],
    "techniques": ["zhang2021", "smooth"],
    "episodes": REPLAY_EPISODES,
    "seed": 0,
    "workers": 1,
    "progress": False,
    "print_table": False,
}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A tiny run's rows and its report."""
    out = tmp_path_factory.mktemp("report")
    rows = run_benchmark(**RUN, out_dir=out)
    return rows, out / "report.html"


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    pytest.skip("no chromium on PATH: .ci/setup installs Debian's (apt-get install -y chromium)")


def _dump_dom(page: Path, profile: Path, *flags: str) -> tuple[str, str]:
    """The DOM of ``page`` after its scripts ran, in headless Chromium, and what the browser
    logged (the page's console messages are lines with ``:CONSOLE``)."""
    done = subprocess.run(
        [
            _chromium(),
            "--headless=new",
            "--disable-gpu",
            "--no-sandbox",
            "--no-first-run",
            f"--user-data-dir={profile}",
            "--enable-logging=stderr",
            "--v=0",
            *flags,
            "--dump-dom",
            page.resolve().as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=180,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout, done.stderr


def _console(log: str) -> list[str]:
    """The page's console messages and uncaught errors in Chromium's log."""
    return [line for line in log.splitlines() if ":CONSOLE" in line or "Uncaught" in line]


class _Elements(HTMLParser):
    """Every element as ``[tag, attributes, ids of the sections around it, its own text]``."""

    def __init__(self, text: str) -> None:
        super().__init__(convert_charrefs=True)
        self.found: list[list] = []
        self._sections: list[str] = []
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = {k: v or "" for k, v in attrs}
        if tag == "section":
            self._sections.append(a.get("id", ""))
        self.found.append([tag, a, tuple(self._sections), ""])

    def handle_endtag(self, tag):
        if tag == "section":
            self._sections.pop()

    def handle_data(self, data):
        if self.found:
            self.found[-1][3] += data

    def select(self, tag: str, cls: str = "", section: str = "") -> list[list]:
        return [
            e
            for e in self.found
            if e[0] == tag
            and (not cls or cls in e[1].get("class", "").split())
            and (not section or section in e[2])
        ]

    def table(self, section: str) -> list[list[str]]:
        """The texts of each body row's cells in the table of ``section``."""
        rows: list[list[str]] = []
        for tag, attrs, where, text in self.found:
            if section not in where:
                continue
            if tag == "tr" and "data-cell" in attrs:
                rows.append([])
            elif tag == "td" and rows:
                rows[-1].append(text.strip())
            elif tag == "a" and rows:
                rows[-1][-1] += text.strip()
        return rows


def _replays(text: str) -> dict:
    (data,) = re.findall(
        r'<script id="replay-data" type="application/json">(.*?)</script>', text, flags=re.S
    )
    return json.loads(data.replace("<\\/", "</"))


# --------------------------------------------------------------------------- without a browser


def test_the_tables_show_every_measure_of_a_row():
    shown = {k for k, _ in NAME_COLUMNS} | {c[0] for c in (*OUTCOME_COLUMNS, *WIP_COLUMNS)}
    measures = {k for k in ROW_KEYS if not k.endswith("_ci") and k != "vs_baseline"}
    assert measures == shown  # the intervals and tests are in each value's tooltip


def test_the_report_needs_no_network_and_stays_small(run):
    rows, page = run
    text = page.read_text(encoding="utf-8")
    assert "http://" not in text and "https://" not in text
    assert "<link" not in text and "@import" not in text
    for ref in re.findall(r"""\b(?:src|href)\s*=\s*["']([^"']*)""", text):
        assert ref.startswith(("data:image/png;base64,", "#")), ref  # inline data, in-page links
    assert len(re.findall(r'src="data:image/png', text)) == 3 * len(rows) + 3  # every figure
    assert len(text) < 200_000 * len(rows)  # the default run's 20 cells: a few MB


def test_the_replays_hold_each_cells_collisions_by_cause(run):
    """Every episode is replayed here, so the collisions the replays mark are the row's, cause
    by cause; each replay starts where the episode does and keeps at most MAX_FRAMES frames."""
    rows, page = run
    data = _replays(page.read_text(encoding="utf-8"))
    assert sorted(data) == sorted(
        f"c{k}e{i}" for k in range(len(rows)) for i in range(REPLAY_EPISODES)
    )
    for k, row in enumerate(rows):
        causes = Counter(
            COLLISION_CAUSES[c[3]] for i in range(REPLAY_EPISODES) for c in data[f"c{k}e{i}"]["c"]
        )
        assert {c: causes[c] for c in COLLISION_CAUSES} == row["collision_causes"]
        for i in range(REPLAY_EPISODES):
            d = data[f"c{k}e{i}"]
            n = len(d["t"])
            assert 2 <= n <= MAX_FRAMES and d["t"][0] == 0 and np.all(np.diff(d["t"]) > 0)
            assert len(d["v"]) == len(d["r"]) == 2 * n and len(d["vy"]) == len(d["ry"]) == n
            assert d["v"][:2] == d["r"][:2]  # the true and the virtual body start together
    assert sum(sum(r["collision_causes"].values()) for r in rows) > 0  # the check has teeth


def test_a_stored_trace_of_the_wrong_length_is_refused():
    """A ``.resume`` entry whose trace keeps a per-step array of another length than the
    episode's steps is named as bad, never handed to the report."""
    import dataclasses

    from agents.benchmark.episodes import run_cell_episode
    from agents.benchmark.grid import Cell
    from agents.benchmark.resume import BadEntry, decode_episodes, encode_episodes

    stats, info = run_cell_episode(Cell("approach", "goal_seeker"), 3, trace=True)
    decode_episodes(encode_episodes({"a" * 64: (stats, info)}))  # as run: accepted
    for key in ("collision", "detected_step_times", "virtual_yaw"):
        trace = {**stats.trace, key: stats.trace[key][:-1]}
        bad = dataclasses.replace(stats, trace=trace)
        with pytest.raises(BadEntry, match=f"trace\\['{key}'\\]"):
            decode_episodes(encode_episodes({"a" * 64: (bad, info)}))


# --------------------------------------------------------------------------- in a browser


def test_the_report_renders_in_chromium_with_every_cell(run, tmp_path):
    rows, page = run
    dom, log = _dump_dom(page, tmp_path / "profile")
    assert not _console(log), _console(log)
    assert re.search(r'<body[^>]*data-ready="1"', dom), "the page's script did not finish"
    el = _Elements(dom)
    for section in ("outcomes", "wip"):
        shown = el.table(section)
        assert [r[:3] for r in shown] == [[r["task"], r["policy"], r["technique"]] for r in rows]
    for shown, row in zip(el.table("outcomes"), rows, strict=True):
        assert shown[6].rstrip("*") == f"{row['success_rate']:.3f}"  # the "success" column
    cells = el.select("section", "cell")
    assert [e[1]["id"] for e in cells] == [f"cell-{k}" for k in range(len(rows))]
    for k, row in enumerate(rows):
        sec = f"cell-{k}"
        (title,) = el.select("h3", section=sec)
        assert title[3] == cell_name(row)
        assert len(el.select("figure", "replay", sec)) == REPLAY_EPISODES
        # filled in by the script: the paths, the clock, the collisions in their cause's colour
        assert len(el.select("polyline", "trail", sec)) == 2 * REPLAY_EPISODES
        for _, _, _, text in el.select("span", "time", sec):  # the whole episode shown
            assert re.fullmatch(r"t = (\d+\.\d) / \1 s", text), text
        fills = Counter(e[1]["fill"] for e in el.select("circle", "hit", sec))
        assert {c: fills[CAUSE_COLOURS[c]] for c in COLLISION_CAUSES} == row["collision_causes"]


def test_the_replays_play_and_the_tables_sort_in_chromium(run, tmp_path):
    """Play pressed on the first replay runs its clock (2x real time, in Chromium's virtual
    time); a click on the outcomes table's "success" heading sorts its rows by success."""
    rows, page = run
    probe = """<script>
    var fig = document.querySelector("figure.replay");
    fig.querySelector(".play").click();
    var th = document.querySelectorAll("#outcomes thead th")[6];
    th.click();
    setTimeout(function () {
      var order = Array.prototype.map.call(document.querySelectorAll("#outcomes tbody tr"),
        function (tr) { return tr.cells[6].getAttribute("data-v"); });
      document.body.setAttribute("data-probe", JSON.stringify({
        time: fig.querySelector(".time").textContent, frame: fig.querySelector(".slider").value,
        button: fig.querySelector(".play").textContent, heading: th.textContent,
        sorted: th.className, order: order}));
    }, 1000);
    </script></body>"""
    text = page.read_text(encoding="utf-8")
    played = tmp_path / "played.html"
    played.write_text(text[: text.rindex("</body>")] + probe + "</html>", encoding="utf-8")
    dom, log = _dump_dom(played, tmp_path / "profile", "--virtual-time-budget=5000")
    assert not _console(log), _console(log)
    (found,) = re.findall(r'data-probe="([^"]*)"', dom)
    probe = json.loads(found.replace("&quot;", '"'))
    assert probe["heading"] == "success"
    t = float(re.match(r"t = (\d+\.\d) /", probe["time"]).group(1))
    assert 1.0 <= t <= 2.1 and int(probe["frame"]) > 0 and probe["button"] == "pause"
    assert "sorted-asc" in probe["sorted"].split()
    assert [float(v) for v in probe["order"]] == sorted(r["success_rate"] for r in rows)

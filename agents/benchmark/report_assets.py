"""The static assets of the benchmark's report page (:mod:`agents.benchmark.report`): its style
sheet (:data:`_CSS`), its script (:data:`_JS`: the sortable tables and the replays' player) and
the collision causes' colours (:data:`CAUSE_COLOURS`), which the script and the legend share.
"""

from __future__ import annotations

import json

from agents.benchmark.collision_causes import COLLISION_CAUSES

__all__ = ["CAUSE_COLOURS"]

#: Each collision cause's colour (as in ``collision_causes.png``).
CAUSE_COLOURS = {
    "phantom_step": "#d62728",
    "stop_latency": "#ff7f0e",
    "heading_error": "#9467bd",
    "steering": "#2ca02c",
    "policy": "#999999",
}

_CSS = """
body{font:14px/1.4 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0 1.5em 3em;
color:#222;background:#fff}
header{border-bottom:1px solid #ccc;margin-bottom:1em}
h1{font-size:1.6em;margin:.6em 0 .2em}h2{font-size:1.3em;margin:1.4em 0 .4em;
border-bottom:1px solid #eee}h3{font-size:1.05em;margin:1.2em 0 .2em}
nav a{color:#1f5fa8}code{font-size:.95em}
dl{display:grid;grid-template-columns:max-content auto;gap:.1em 1em;margin:.4em 0}
dt{color:#555}dd{margin:0}
.scroll{overflow-x:auto;max-width:100%}
table{border-collapse:collapse;font-size:12.5px;margin:.3em 0}
th,td{padding:2px 6px;border-bottom:1px solid #e4e4e4;white-space:nowrap}
th.num{white-space:normal;min-width:3.5em;max-width:6.5em}
thead th{background:#f2f4f7;position:sticky;top:0;text-align:left;vertical-align:bottom}
table.sortable thead th{cursor:pointer;user-select:none}
th.sorted-asc::after{content:" \\25B2";font-size:.8em}
th.sorted-desc::after{content:" \\25BC";font-size:.8em}
td.num,th.num{text-align:right;font-variant-numeric:tabular-nums}
td.star{font-weight:600;color:#a3140e}
tbody tr:nth-child(even){background:#fafbfc}tbody tr:hover{background:#eef4ff}
table.grids td{white-space:normal}
.note{color:#555;font-size:12px;margin:.2em 0}
.fig{display:inline-block;margin:.3em .6em .3em 0;vertical-align:top}
.fig img{max-width:100%;border:1px solid #eee}
.fig figcaption{font-size:11px;color:#666}
.replays{display:flex;flex-wrap:wrap;gap:14px}
.replay{margin:0;width:400px;border:1px solid #ddd;border-radius:4px;padding:6px;background:#fcfcfc}
.replay figcaption{font-size:12px;color:#333;margin-bottom:3px}
.replay svg{width:100%;height:auto;max-height:380px;background:#fff;display:block}
.ctl{display:flex;align-items:center;gap:6px;margin-top:4px;font-size:12px}
.ctl .slider{flex:1}.ctl .time{min-width:7.5em;text-align:right;font-variant-numeric:tabular-nums}
.wall{fill:#8c8c8c}.obstacle{fill:#9a9a9a}.target{fill:#a0785a}
circle.goal{fill:none;stroke:#2ca02c;stroke-width:2;stroke-dasharray:5 3;
vector-effect:non-scaling-stroke}
line.goal{stroke:#2ca02c;stroke-width:2;stroke-dasharray:6 4;vector-effect:non-scaling-stroke}
.full{fill:none;stroke-width:1;vector-effect:non-scaling-stroke;opacity:.35}
.trail{fill:none;vector-effect:non-scaling-stroke;stroke-linejoin:round}
.true-path{stroke:#333}.virt-path{stroke:#d62728}
.trail.true-path{stroke-width:3.5;opacity:.45}.trail.virt-path{stroke-width:1.6}
.face{stroke-width:2;vector-effect:non-scaling-stroke}
.hit{stroke:#000;stroke-width:.8;vector-effect:non-scaling-stroke}
.hit.later{opacity:.22}
.legend .sw{display:inline-block;width:.8em;height:.8em;border-radius:50%;margin:0 .2em 0 .5em;
border:1px solid #000;vertical-align:-1px}
.legend .ln{display:inline-block;width:1.6em;height:0;margin:0 .3em 0 .6em;vertical-align:middle}
.ln.true{border-top:3px solid rgba(51,51,51,.55)}.ln.virt{border-top:2px solid #d62728}
details summary{cursor:pointer;color:#1f5fa8;margin:.4em 0}
"""

_JS = r"""
(function () {
  "use strict";
  var CAUSES = %CAUSES%;
  var COLOURS = %COLOURS%;

  function sortValue(td) {
    var v = td.getAttribute("data-v");
    if (v === null) return td.textContent.trim().toLowerCase();
    return v === "" ? null : parseFloat(v);
  }
  function sortBy(table, col, th) {
    var asc = !th.classList.contains("sorted-asc");
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (h) {
      h.classList.remove("sorted-asc", "sorted-desc");
    });
    th.classList.add(asc ? "sorted-asc" : "sorted-desc");
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = sortValue(a.cells[col]), y = sortValue(b.cells[col]);
      if (x === null && y === null) return 0;
      if (x === null) return 1;  /* no value: last either way */
      if (y === null) return -1;
      var d = typeof x === "number" && typeof y === "number" ? x - y
        : String(x).localeCompare(String(y));
      return asc ? d : -d;
    });
    rows.forEach(function (r) { body.appendChild(r); });
  }
  Array.prototype.forEach.call(document.querySelectorAll("table.sortable"), function (table) {
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th, col) {
      th.addEventListener("click", function () { sortBy(table, col, th); });
    });
  });

  function el(name, attrs, parent) {  /* an SVG element, in the namespace of the page's own */
    var e = document.createElementNS(parent.namespaceURI, name);
    for (var k in attrs) e.setAttribute(k, attrs[k]);
    parent.appendChild(e);
    return e;
  }
  function pts(flat, n) {  /* the first n points, "x,-y ..." in metres */
    var out = [];
    for (var i = 0; i < n; i++) out.push(flat[2 * i] / 100 + "," + (-flat[2 * i + 1] / 100));
    return out.join(" ");
  }

  function Replay(fig, d) {
    var svg = fig.querySelector("svg"), dyn = fig.querySelector(".dyn");
    var slider = fig.querySelector(".slider"), button = fig.querySelector(".play");
    var speed = fig.querySelector(".speed"), label = fig.querySelector(".time");
    var n = d.t.length, end = d.t[n - 1] / 100;
    var vb = svg.viewBox.baseVal, arrow = 0.04 * Math.max(vb.width, vb.height);
    el("polyline", {"class": "full true-path", points: pts(d.r, n)}, dyn);
    el("polyline", {"class": "full virt-path", points: pts(d.v, n)}, dyn);
    var trailTrue = el("polyline", {"class": "trail true-path"}, dyn);
    var trailVirt = el("polyline", {"class": "trail virt-path"}, dyn);
    var hits = d.c.map(function (c) {
      var m = el("circle", {"class": "hit", cx: c[1] / 100, cy: -c[2] / 100,
                            r: 0.012 * Math.max(vb.width, vb.height),
                            fill: COLOURS[c[3]]}, dyn);
      el("title", {}, m).textContent = "collision at " + (c[0] / 100).toFixed(1) + " s: "
        + CAUSES[c[3]].replace(/_/g, " ");
      return {t: c[0] / 100, node: m};
    });
    function marker(size, colour) {
      var g = el("g", {}, dyn);
      return {line: el("line", {"class": "face", stroke: colour}, g),
              dot: el("circle", {r: size * Math.max(vb.width, vb.height), fill: colour}, g)};
    }
    var mv = marker(0.016, "#d62728"), mt = marker(0.011, "#333");  /* the true one on top */
    function place(m, flat, yaw, i) {
      var x = flat[2 * i] / 100, y = -flat[2 * i + 1] / 100, a = yaw[i] * Math.PI / 180;
      m.dot.setAttribute("cx", x); m.dot.setAttribute("cy", y);
      m.line.setAttribute("x1", x); m.line.setAttribute("y1", y);
      m.line.setAttribute("x2", x + arrow * Math.cos(a));
      m.line.setAttribute("y2", y - arrow * Math.sin(a));
    }
    var frame = 0, playing = false, clock = 0, last = 0, timer = null;
    slider.max = String(n - 1);
    function show(i) {
      frame = i;
      slider.value = String(i);
      var now = d.t[i] / 100;
      trailTrue.setAttribute("points", pts(d.r, i + 1));
      trailVirt.setAttribute("points", pts(d.v, i + 1));
      place(mt, d.r, d.ry, i); place(mv, d.v, d.vy, i);
      hits.forEach(function (h) { h.node.classList.toggle("later", h.t > now + 1e-9); });
      label.textContent = "t = " + now.toFixed(1) + " / " + end.toFixed(1) + " s";
    }
    function tick() {  /* 25 times a second: the episode's clock advances by speed x real time */
      if (!playing) return;
      var now = performance.now();
      clock += (now - last) / 1000 * parseFloat(speed.value);
      last = now;
      var i = frame;
      while (i < n - 1 && d.t[i + 1] / 100 <= clock) i++;
      if (i !== frame) show(i);
      if (i >= n - 1) { stop(); return; }
      timer = setTimeout(tick, 40);
    }
    function stop() { playing = false; clearTimeout(timer); button.textContent = "play"; }
    button.addEventListener("click", function () {
      if (playing) { stop(); return; }
      if (frame >= n - 1) show(0);
      playing = true; last = performance.now(); clock = d.t[frame] / 100;
      button.textContent = "pause";
      timer = setTimeout(tick, 40);
    });
    slider.addEventListener("input", function () { stop(); show(parseInt(slider.value, 10)); });
    show(n - 1);  /* the whole episode first; play starts it over */
  }

  var data = JSON.parse(document.getElementById("replay-data").textContent);
  Array.prototype.forEach.call(document.querySelectorAll("figure.replay"), function (fig) {
    Replay(fig, data[fig.getAttribute("data-key")]);
  });
  document.body.setAttribute("data-ready", "1");
})();
""".replace("%CAUSES%", json.dumps(list(COLLISION_CAUSES))).replace(
    "%COLOURS%", json.dumps([CAUSE_COLOURS[c] for c in COLLISION_CAUSES])
)

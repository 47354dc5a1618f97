"""The HTML shell of a report: one self-contained file (plotly.js inline, no network).

Figures are stored as JSON in ``<script type="application/json">`` elements and drawn by a
few lines of JavaScript: eagerly on load, or on demand (``lazy``: a candidate's 3-D view in a
ranking). Meshes shared by figures (robot links, the object) are stored once (``kg-meshes``)
and placed by the script where a trace lists ``kgInstances``
(:func:`~kinegrasp_env.toolkit.report.plotly.instanced_mesh`). When every eager figure is
drawn the page sets ``window.kgReady`` to ``performance.now()`` (milliseconds since
navigation start) and ``window.kgRendered`` counts drawn figures; the browser test reads
both. Tables with class ``kg-sortable`` sort by a click on a column header.
"""

from __future__ import annotations

import html
from dataclasses import dataclass

from kinegrasp_env.toolkit.report.plotly import MeshLibrary, figure_json, plotly_js

STYLE = """
body { font-family: Helvetica, Arial, sans-serif; margin: 16px 24px; color: #222; }
h1 { font-size: 20px; margin: 0 0 4px 0; } h2 { font-size: 16px; margin: 18px 0 6px 0; }
.kg-headline { font-size: 15px; margin: 4px 0 10px 0; }
.kg-row { display: flex; flex-wrap: wrap; gap: 12px; }
.kg-plot { border: 1px solid #ddd; border-radius: 4px; }
.kg-note { background: #fff8e1; border-left: 4px solid #f0b400; padding: 6px 10px;
  margin: 8px 0; font-size: 13px; }
table { border-collapse: collapse; font-size: 13px; }
th, td { border-bottom: 1px solid #e4e4e4; padding: 3px 10px; text-align: right; }
th { background: #f2f2f6; } td.kg-text, th.kg-text { text-align: left; }
table.kg-sortable { width: 100%; }
table.kg-sortable th { cursor: pointer; user-select: none; }
table.kg-sortable th[data-dir="asc"]::after { content: " \\25B2"; }
table.kg-sortable th[data-dir="desc"]::after { content: " \\25BC"; }
pre.kg-command { background: #f6f6f6; padding: 8px; white-space: pre-wrap;
  word-break: break-all; font-size: 12px; }
button.kg-show { font-size: 12px; }
footer { color: #888; font-size: 11px; margin-top: 18px; }
"""

SCRIPT = """
window.kgRendered = 0;
let kgLibrary = null;
function kgDecode(spec) {
  const raw = atob(spec.bdata);
  const bytes = new Uint8Array(raw.length);
  for (let n = 0; n < raw.length; n++) { bytes[n] = raw.charCodeAt(n); }
  const types = {f4: Float32Array, f8: Float64Array, u4: Uint32Array, i4: Int32Array};
  return new types[spec.dtype](bytes.buffer);
}
function kgMeshes() {
  if (kgLibrary === null) {
    const element = document.getElementById("kg-meshes");
    const raw = element ? JSON.parse(element.textContent) : {};
    kgLibrary = {};
    Object.keys(raw).forEach(function (key) {
      kgLibrary[key] = {v: kgDecode(raw[key].v), f: kgDecode(raw[key].f)};
    });
  }
  return kgLibrary;
}
function kgPlace(trace) {
  const library = kgMeshes();
  let nv = 0, nf = 0;
  trace.kgInstances.forEach(function (item) {
    nv += library[item[0]].v.length / 3; nf += library[item[0]].f.length / 3;
  });
  const x = new Float32Array(nv), y = new Float32Array(nv), z = new Float32Array(nv);
  const i = new Uint32Array(nf), j = new Uint32Array(nf), k = new Uint32Array(nf);
  let ov = 0, of = 0;
  trace.kgInstances.forEach(function (item) {
    const v = library[item[0]].v, f = library[item[0]].f, m = item[1];
    for (let a = 0; a < v.length / 3; a++) {
      const px = v[3 * a], py = v[3 * a + 1], pz = v[3 * a + 2];
      x[ov + a] = m[0] * px + m[1] * py + m[2] * pz + m[3];
      y[ov + a] = m[4] * px + m[5] * py + m[6] * pz + m[7];
      z[ov + a] = m[8] * px + m[9] * py + m[10] * pz + m[11];
    }
    for (let b = 0; b < f.length / 3; b++) {
      i[of + b] = f[3 * b] + ov; j[of + b] = f[3 * b + 1] + ov; k[of + b] = f[3 * b + 2] + ov;
    }
    ov += v.length / 3; of += f.length / 3;
  });
  delete trace.kgInstances;
  Object.assign(trace, {x: x, y: y, z: z, i: i, j: j, k: k});
}
function kgRender(div) {
  if (div.dataset.rendered) { return Promise.resolve(); }
  div.dataset.rendered = "1";
  const fig = JSON.parse(document.getElementById(div.dataset.fig).textContent);
  fig.data.forEach(function (trace) { if (trace.kgInstances) { kgPlace(trace); } });
  const config = {responsive: true, displaylogo: false};
  return Plotly.newPlot(div, fig.data, fig.layout, config).then(function () {
    window.kgRendered += 1;
  });
}
function kgToggle(button) {
  const row = document.getElementById(button.dataset.detail);
  const hidden = row.style.display === "none";
  row.style.display = hidden ? "" : "none";
  button.textContent = hidden ? "hide 3-D" : "show 3-D";
  if (hidden) { row.querySelectorAll("div.kg-plot").forEach(kgRender); }
}
function kgSort(th) {
  const table = th.closest("table");
  const column = Array.prototype.indexOf.call(th.parentNode.children, th);
  const dir = th.dataset.dir === "asc" ? "desc" : "asc";
  table.querySelectorAll("th").forEach(function (h) { delete h.dataset.dir; });
  th.dataset.dir = dir;
  const body = table.tBodies[0];
  const rows = Array.from(body.querySelectorAll("tr.kg-item"));
  const key = function (row) {
    const cell = row.children[column];
    const value = cell.dataset.value;
    return value === undefined ? cell.textContent : parseFloat(value);
  };
  rows.sort(function (a, b) {
    const x = key(a), y = key(b);
    const order = (typeof x === "number" && typeof y === "number")
      ? (isNaN(x) - isNaN(y)) || x - y : String(x).localeCompare(String(y));
    return dir === "asc" ? order : -order;
  });
  rows.forEach(function (row) {
    body.appendChild(row);
    const detail = row.dataset.detail && document.getElementById(row.dataset.detail);
    if (detail) { body.appendChild(detail); }
  });
}
document.addEventListener("DOMContentLoaded", function () {
  document.querySelectorAll("table.kg-sortable th").forEach(function (th) {
    th.addEventListener("click", function () { kgSort(th); });
  });
  const eager = Array.from(document.querySelectorAll("div.kg-plot:not([data-lazy])"));
  Promise.all(eager.map(kgRender)).then(function () { window.kgReady = performance.now(); });
});
"""


@dataclass
class Figure:
    """A figure placed on the page.

    Attributes:
        key: unique id (letters, digits, dashes); figure: plotly dict; width, height: CSS
        sizes (e.g. ``"100%"``, ``"520px"``); lazy: drawn on demand only.
    """

    key: str
    figure: dict
    width: str = "100%"
    height: str = "480px"
    lazy: bool = False

    def div(self) -> str:
        lazy = " data-lazy" if self.lazy else ""
        return (f'<div class="kg-plot" id="plot-{self.key}" data-fig="fig-{self.key}"{lazy} '
                f'style="width: {self.width}; height: {self.height};"></div>')

    def data(self) -> str:
        return (f'<script type="application/json" id="fig-{self.key}">'
                f"{figure_json(self.figure)}</script>")


def esc(text) -> str:
    return html.escape(str(text), quote=True)


def settings_table(settings: dict) -> str:
    rows = "".join(f'<tr><td class="kg-text">{esc(k)}</td><td class="kg-text">{esc(v)}</td>'
                   "</tr>" for k, v in settings.items())
    return f"<table>{rows}</table>"


def command_block(command: str) -> str:
    return f'<pre class="kg-command">{esc(command)}</pre>'


def note(text: str) -> str:
    return f'<div class="kg-note">{esc(text)}</div>'


def page(title: str, body: str, figures: list[Figure], library: MeshLibrary | None = None,
         footer: str = "") -> str:
    """The whole HTML document: ``body`` (HTML holding each figure's ``div()``), the
    figures' JSON, the shared meshes, plotly.js and the page script, inline."""
    data = "\n".join(f.data() for f in figures)
    if library is not None and library.meshes:
        data += (f'\n<script type="application/json" id="kg-meshes">'
                 f"{figure_json(library.to_json())}</script>")
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f"<title>{esc(title)}</title>\n<style>{STYLE}</style>\n"
            f'<script type="text/javascript">{plotly_js()}</script>\n'
            f"<script>{SCRIPT}</script>\n</head>\n<body>\n{body}\n{data}\n"
            f"<footer>{esc(footer)}</footer>\n</body>\n</html>\n")

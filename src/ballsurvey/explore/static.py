"""The static page: a self-contained HTML file (Bokeh's JavaScript inlined) with the map, hover
values, the launch panel and, for a slice small enough, each launch's path precomputed over one
theta cycle, under a Content-Security-Policy that names each of its scripts by hash.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import xarray as xr

from ..classify.labels import CORNER_KINDS, LABELS
from ..classify.observer import theta_maxima
from ..gallery import LAUNCH_KEYS
from ..limits import CLASSIFY_INT_RANGES, InputError, step_count
from .document import _h, _legend, _map_figure, _path_figures, _title, panel_spec, require_bokeh
from .launch import (
    RunSettings,
    _short,
    _unit,
    integrate_launch,
    launch_at,
    open_lazily,
    run_settings,
)
from .view import View, launch_columns, make_view

#: the static page precomputes paths for a shown slice of at most this many launches
MAX_HTML_PATHS = 1024
#: the largest slice a static page holds (hover and launch panel)
MAX_HTML_LAUNCHES = 250_000
#: most cycles of a star drawn on the static page (the classifier's largest max_star_points)
MAX_STAR_POINTS = CLASSIFY_INT_RANGES["max_star_points"][1]
#: most integration steps the static page's paths may take in all (about a minute of one core)
MAX_HTML_STEPS = 10**8
#: theta periods each launch of the static page is integrated for (one whole cycle from its
#: first theta maximum)
CYCLE_SPAN = 2.3
#: samples of the one theta cycle kept per launch in the static page
CYCLE_SAMPLES = 120


def one_cycle(traj: xr.Dataset, max_points: int = CYCLE_SAMPLES):
    """x, y (m) of the path from its first theta maximum to the next (None without two)."""
    mx = theta_maxima(traj.theta.values)
    if len(mx) < 2:
        return None
    idx = np.unique(np.linspace(mx[0], mx[1], min(max_points, mx[1] - mx[0] + 1)).round()
                    .astype(int))
    return traj.x.values[idx], traj.y.values[idx]


def orbit_turn(stored: dict) -> tuple[float, int]:
    """(turn per cycle (deg), cycles to draw) for a one-cycle path turned about the orbit
    centre: one orbit (360 deg of net turn), p cycles for a star {p/q}, at most 60."""
    turn = stored.get("turn_per_cycle_deg", math.nan)
    if not math.isfinite(turn):
        return 0.0, 1
    if stored.get("star_points", 0) and stored["star_points"] > 0:
        return turn, int(min(stored["star_points"], MAX_STAR_POINTS))
    return turn, int(min(60, math.ceil(360.0 / max(abs(turn), 6.0)))) if abs(turn) > 1e-9 else 4


# ---------------------------------------------------------------------------------------------
# the static page
_STATIC_TAP_JS = """
let k = -1;
if (kind === 'grid') {
  if (cb_obj.x == null) { return; }
  let i = 0, j = 0;
  const near = (v, t) => v.reduce((b, w, q) => Math.abs(w - t) < Math.abs(v[b] - t) ? q : b, 0);
  i = near(xs, cb_obj.x);
  j = near(ys, cb_obj.y);
  k = j * xs.length + i;
  marker.data = {x: [xs[i]], y: [ys[j]]};
} else {
  const sel = cb_obj.indices;
  if (!sel || sel.length == 0) { return; }
  k = sel[0];
}
const F = fields.data, fmt = (v, f) => {
  if (v == null || !isFinite(v)) { return '-'; }
  let t = f[0] == 'f' ? v.toFixed(f[1]) : String(Number(v.toPrecision(f[1])));
  return (Number(t) == 0 && t[0] == '-') ? t.slice(1) : t;
};
const word = (table, v) => (v >= 0 && v < table.length) ? table[v] : '(not written)';
const esc = (t) => String(t).replace(/[&<>"'`]/g, (c) => `&#${c.charCodeAt(0)};`);
let rows = '';
for (const [key, text, units, f] of spec) {
  if (!(key in F)) { continue; }
  const v = F[key][k];
  const shown = key == 'label' ? word(words, v) :
    key == 'corner_kind' ? word(corners, v) : fmt(v, f);
  rows += `<tr><td>${esc(text)}</td><td>${esc(units)}</td>` +
    `<td class='bs-map' data-field='${esc(key)}'>${esc(shown)}</td></tr>`;
}
const g6 = (v) => String(Number(Number(v).toPrecision(6)));
let head = '';
if (kind === 'grid') {
  const i = k % xs.length, j = Math.floor(k / xs.length);
  head = esc(`${xname} = ${g6(xs[i])} ${xunit}, ${yname} = ${g6(ys[j])} ${yunit}` +
    (fixed ? ', ' + fixed : ''));
} else {
  head = esc(F.name[k] + ': ' +
    launch_keys.map(([c, nm, u]) => `${nm} = ${g6(F[c][k])} ${u}`).join(', '));
}
info.text = `<div class='bs-launch'><h3 style='margin:0'>${esc(word(words, F.label[k]))}</h3>` +
  `<p>${head}</p><table><tr><th>field</th><th>units</th><th>map</th></tr>${rows}</table></div>`;
const c = cyc.data, a = c.start[k], n = c.count[k];
if (n == 0) { path.data = {x: [], y: []}; start.data = {x: [], y: []}; return; }
const px = flat.data.px[0].slice(a, a + n), py = flat.data.py[0].slice(a, a + n);
const turn = c.turn[k] * Math.PI / 180, reps = c.reps[k];
const x0 = px[0], y0 = py[0], x1 = px[n - 1], y1 = py[n - 1];
let cx = 0, cy = 0, shift = Math.abs(turn) < 1e-6;
if (!shift) {  // the orbit centre: (I - R) c = P1 - R P0
  const co = Math.cos(turn), si = Math.sin(turn);
  const bx = x1 - (co * x0 - si * y0), by = y1 - (si * x0 + co * y0);
  const a11 = 1 - co, a12 = si, a21 = -si, a22 = 1 - co, det = a11 * a22 - a12 * a21;
  cx = (a22 * bx - a12 * by) / det; cy = (a11 * by - a21 * bx) / det;
}
const X = [], Y = [];
for (let r = 0; r < reps; r++) {
  const co = Math.cos(r * turn), si = Math.sin(r * turn);
  for (let m = 0; m < n; m++) {
    if (shift) { X.push(px[m] + r * (x1 - x0)); Y.push(py[m] + r * (y1 - y0)); }
    else { const dx = px[m] - cx, dy = py[m] - cy;
           X.push(cx + co * dx - si * dy); Y.push(cy + si * dx + co * dy); }
  }
}
path.data = {x: X, y: Y};
start.data = {x: [x0], y: [y0]};
"""


#: the static page's Content-Security-Policy; SCRIPTS: the SHA-256 of each of its own scripts.
#: Bokeh compiles the page's CustomJS callbacks with `new Function` ('unsafe-eval'); no other
#: script runs: no inline event handler, no javascript: URL, no script added to the page, nothing
#: fetched from anywhere.
CSP = ("default-src 'none'; script-src SCRIPTS 'unsafe-eval'; style-src 'unsafe-inline'; "
       "img-src data: blob:; font-src data:; base-uri 'none'; form-action 'none'; "
       "object-src 'none'")


def with_csp(page: str) -> str:
    """A page written by Bokeh's `file_html` with `CSP` as its first element in <head>, naming
    by hash each inline script the page holds (its data blocks, type application/json, are not
    scripts)."""
    import base64
    import hashlib
    import re

    hashes = []
    for attrs, body in re.findall(r"<script\b([^>]*)>(.*?)</script>", page, flags=re.S):
        kind = re.search(r"""type\s*=\s*["']?([^"' >]+)""", attrs)
        if kind and kind.group(1).lower() not in ("text/javascript", "module"):
            continue
        digest = hashlib.sha256(body.encode("utf-8")).digest()
        hashes.append(f"'sha256-{base64.b64encode(digest).decode()}'")
    policy = CSP.replace("SCRIPTS", " ".join(dict.fromkeys(hashes)) or "'none'")
    at = page.find('<meta charset="utf-8">')
    head = at + len('<meta charset="utf-8">') if at >= 0 else page.index("<head>") + len("<head>")
    return (page[:head] + f'\n    <meta http-equiv="Content-Security-Policy" content="{policy}">'
            + page[head:])


def page_steps(view: View, settings: RunSettings) -> int:
    """Integration steps `precompute_cycles` takes for the launches of a view read into memory
    (each integrated for CYCLE_SPAN of its stored theta periods, at most the map's T)."""
    period = np.ravel(view.ds["theta_period_s"].values) if "theta_period_s" in view.ds else []
    return sum(step_count(min(settings.T, CYCLE_SPAN * p), settings.dt) for p in period
               if math.isfinite(p) and p > 0)


def precompute_cycles(ds: xr.Dataset, view: View, progress=None) -> dict:
    """For each launch k of the view: one theta cycle of its path (integrated again for about
    two theta periods with the map's settings), the turn per cycle (deg) and the cycles to
    draw. Columns: start, count (into px, py: m, float32), turn, reps."""
    settings = run_settings(ds)
    n = view.ds.sizes["launch"] if view.points else view.ds.sizes[view.x] * view.ds.sizes[view.y]
    px, py, start, count, turn, reps = [], [], [], [], [], []
    at = 0
    for k in range(n):
        info = launch_at(ds, view.where(k))
        period = info["stored"].get("theta_period_s", math.nan)
        cyc = None
        if math.isfinite(period) and period > 0:
            T = min(settings.T, CYCLE_SPAN * period)
            try:
                traj = integrate_launch(ds, info["launch"], info["ball"], T=T,
                                        n_out=max(200, int(4 * CYCLE_SAMPLES * T / period)),
                                        settings=settings)
                cyc = one_cycle(traj)
            except (InputError, ValueError):
                cyc = None
        tu, rp = orbit_turn(info["stored"])
        m = 0 if cyc is None else len(cyc[0])
        if m:
            px.append(cyc[0])
            py.append(cyc[1])
        start.append(at)
        count.append(m)
        turn.append(tu)
        reps.append(rp)
        at += m
        if progress:
            progress(k + 1, n)

    def cat(v):
        return np.concatenate(v).astype(np.float32) if v else np.zeros(0, np.float32)
    return {"px": cat(px), "py": cat(py), "start": np.array(start, np.int32),
            "count": np.array(count, np.int32), "turn": np.array(turn),
            "reps": np.array(reps, np.int32)}


def write_html(path, out, x=None, y=None, at=None, max_paths: int = MAX_HTML_PATHS,
               progress=None) -> dict:
    """Write the static page for the map at `path` to `out` (an .html file, Bokeh inlined).
    Returns {"launches": launches in the slice shown, "paths": whether paths were precomputed}."""
    require_bokeh()
    with open_lazily(path) as ds:  # closed after: a later open of the file must not fail
        return _write_html(ds, path, out, x, y, at, max_paths, progress)


def _write_html(ds, path, out, x, y, at, max_paths, progress) -> dict:
    from bokeh.embed import file_html
    from bokeh.layouts import column, row
    from bokeh.models import ColumnDataSource, CustomJS, Div, TapTool
    from bokeh.resources import INLINE

    s = run_settings(ds)  # a map whose launches cannot be integrated again: refused first
    view = make_view(ds, x, y, at)
    n = ds.sizes["launch"] if view.points else ds.sizes[view.x] * ds.sizes[view.y]
    if n > MAX_HTML_LAUNCHES:
        raise InputError(f"the slice shown has {n} launches; a static page holds at most "
                         f"{MAX_HTML_LAUNCHES}: draw shorter axes (--x, --y) or use the app "
                         "(without --html), which reads each slice as it is shown")
    fig, parts = _map_figure(view, _title(ds, path))
    # the page draws whole theta cycles, from the first theta maximum (not the launch point)
    fp, _, srcs = _path_figures("first theta maximum (whole cycles drawn from here)")
    here = view.loaded()
    work = page_steps(here, s) if n <= max_paths else 0
    with_paths = n <= max_paths and work <= MAX_HTML_STEPS
    fields_src = ColumnDataSource(launch_columns(here), name="fields")
    cyc = precompute_cycles(here.ds, here, progress) if with_paths else {
        k: np.zeros(n, np.int32) for k in ("start", "count", "reps")} | {
        "px": np.zeros(0, np.float32), "py": np.zeros(0, np.float32), "turn": np.zeros(n)}
    csrc = ColumnDataSource({"start": cyc["start"], "count": cyc["count"], "turn": cyc["turn"],
                             "reps": cyc["reps"]})
    flat = ColumnDataSource({"px": [cyc["px"]], "py": [cyc["py"]]})
    info = Div(text="<p>Click a launch: its label and fields" + (
        ", and its path: one theta cycle integrated again with the map's settings, turned about "
        "the orbit centre once per cycle" if with_paths else
        f" (paths are precomputed for slices of at most {max_paths} launches; this one has "
        f"{n}: `ballsurvey explore` integrates any launch on click)" if n > max_paths else
        f" (paths are precomputed where they take at most {MAX_HTML_STEPS:.0e} steps in all; "
        f"this slice's take {work:.2g}: `ballsurvey explore` integrates any launch on click)")
        + ".</p>",
        width=460, name="launch")
    grid = parts.get("grid", {"xs": [], "ys": []})
    js = CustomJS(args=dict(kind="points" if view.points else "grid",
                            xs=[float(v) for v in grid["xs"]], ys=[float(v) for v in grid["ys"]],
                            marker=parts["marker"], info=info, fields=fields_src, cyc=csrc,
                            flat=flat, path=srcs["path"], start=srcs["start"],
                            spec=panel_spec(), words=list(LABELS), corners=list(CORNER_KINDS),
                            xname=_short(view.x), yname=_short(view.y),
                            xunit=_unit(view.x), yunit=_unit(view.y), fixed=view.fixed_text(),
                            launch_keys=[(k, _short(k), _unit(k)) for k in LAUNCH_KEYS]),
                  code=_STATIC_TAP_JS)
    if view.points:
        fig.add_tools(TapTool(renderers=[parts["renderer"]]))
        parts["points"].selected.js_on_change("indices", js)
    else:
        fig.js_on_event("tap", js)
    legend = Div(text=_legend(parts))
    fixed = Div(text=_h(view.fixed_text()))
    foot = Div(text=f"<p style='font-size:11px'>Map {_h(Path(str(path)).name)}: {_h(s.method)}, "
                    f"step {s.dt:g} s, T = {s.T:g} s. Written by ballsurvey explore --html.</p>",
               name="footer")
    page = row(column(fig, legend, fixed, foot), column(info, fp))
    text = with_csp(file_html(page, INLINE, title=f"ballsurvey: {_title(ds, path)}"))
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(text, encoding="utf-8")
    return {"launches": n, "paths": with_paths}

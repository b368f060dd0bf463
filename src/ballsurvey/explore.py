"""Explore a stored map in the browser: point at a launch, see the path behind it.

`serve` runs a local Bokeh server app on 127.0.0.1: the map drawn as `plot` draws it (the same
label colours and the exact-polygon curves n_sides = 3, 4), a selector for the axes drawn and a
slider for every other axis of a grid, hover values, and a click that integrates the launch
again with the map's own method, step, duration, ball and classifier thresholds (the map's
global attributes) and draws its path and theta(t) beside the label and fields, stored and
integrated again. The path downloads as CSV and the launch as a `[[points]]` entry of a spec.
A map is opened lazily: only the slice shown is read from the file.

`write_html` writes a self-contained static page (Bokeh's JavaScript inlined, so it opens
offline): the map with hover values and, for a shown slice of at most `MAX_HTML_PATHS` launches,
each launch's path precomputed over one theta cycle; a click draws that cycle turned about the
orbit centre once per cycle, which is the path (each cycle is the one before it turned by the net
turn per cycle about the orbit centre).

Bokeh is an optional dependency (`pip install 'ballsurvey[explore]'`), imported only here.
Units: angles in degrees, rates in rad/s, lengths in m, times in s.
"""
from __future__ import annotations

import html
import io
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from .axes import AXES
from .ball import Ball
from .classify.labels import CORNER_KINDS, LABELS, Thresholds
from .classify.observer import theta_maxima
from .compose import METHODS
from .gallery import BALL_KEYS, LAUNCH_KEYS
from .integrate.outcome import FORMULATIONS
from .integrate.tableaus import FIXED_STEP
from .limits import CLASSIFY_INT_RANGES, InputError, RunError, replay_steps, step_count
from .plot import (
    EXACT_POLYGON_DASH,
    EXACT_POLYGON_LEVELS,
    LABEL_COLOURS,
    crossing_text,
    curve_crossings,
    drawn_axes,
    exact_polygon_field,
)

INSTALL_HINT = "pip install 'ballsurvey[explore]'"
#: the static page precomputes paths for a shown slice of at most this many launches
MAX_HTML_PATHS = 1024
#: the largest slice a static page holds (hover and launch panel)
MAX_HTML_LAUNCHES = 250_000
#: most cycles of a star drawn on the static page (the classifier's largest max_star_points)
MAX_STAR_POINTS = CLASSIFY_INT_RANGES["max_star_points"][1]
#: samples kept along a clicked launch's path (about; fixed steps take a divisor of the steps)
PATH_SAMPLES = 4000
#: most integration steps the static page's paths may take in all (about a minute of one core)
MAX_HTML_STEPS = 10**8
#: theta periods each launch of the static page is integrated for (one whole cycle from its
#: first theta maximum)
CYCLE_SPAN = 2.3
#: samples of the one theta cycle kept per launch in the static page
CYCLE_SAMPLES = 120
#: the widest image drawn for an axis whose values are not evenly spaced (pixels)
MAX_PIXELS = 2000
#: fields shown on hover and in the launch panel: name -> (text, units, printf format)
FIELDS = {
    "n_sides": ("n_sides", "", "%.4f"),
    "turn_per_cycle_deg": ("turn per cycle", "deg", "%.3f"),
    "theta_period_s": ("theta period", "s", "%.4f"),
    "side_m": ("side", "m", "%.4g"),
    "roundness": ("roundness", "", "%.3g"),
    "closure_m": ("closure per circuit", "m", "%.3g"),
    "theta_min_deg": ("theta min", "deg", "%.2f"),
    "theta_max_deg": ("theta max", "deg", "%.2f"),
}
HOVER_FIELDS = ("n_sides", "turn_per_cycle_deg", "theta_period_s", "closure_m")


def require_bokeh() -> None:
    """InputError (one line naming the extra) when Bokeh is not installed."""
    try:
        import bokeh  # noqa: F401
    except ImportError:
        raise InputError(f"explore needs Bokeh, which is not installed: {INSTALL_HINT}") from None


def _short(axis: str) -> str:
    return axis[:-4] if axis.endswith("_deg") else axis


def _unit(axis: str) -> str:
    return AXES[axis].text_units if axis in AXES else ""


def axis_text(axis: str) -> str:
    """'theta0 (deg)', 'chidot0 (rad/s)': an axis name as the CLI writes it, with its units."""
    return f"{_short(axis)} ({_unit(axis)})" if _unit(axis) else _short(axis)


def value_text(axis: str, value: float) -> str:
    """'thetadot0 = 0 rad/s': an axis value as the CLI writes it, in plain text (a Bokeh Div
    shows matplotlib's mathtext as it is, dollars and all)."""
    return f"{_short(axis)} = {value:g} {_unit(axis)}".rstrip()


# ---------------------------------------------------------------------------------------------
# how the map was run: what a click integrates with
@dataclass(frozen=True)
class RunSettings:
    """The map's own run settings (global attributes `run_*`, `classify_*`, `ball_*`)."""

    T: float  #: duration (s)
    dt: float  #: step used (s; the adaptive pair's first trial step)
    method: str
    rtol: float
    atol: float
    thresholds: Thresholds
    ball: Ball
    note: str = ""  #: how the integration differs from the map's, when it must


def run_settings(ds: xr.Dataset) -> RunSettings:
    """The map's method, step, duration, tolerances, classifier thresholds and ball, checked by a
    spec's rules (`sweep.spec.map_settings`) and by the steps a click may take
    (`limits.replay_steps`): InputError, one line, before any work."""
    from .sweep.spec import map_settings

    src = str(ds.encoding.get("source", "map"))
    m = map_settings(ds.attrs, src)
    method, note = m.method, ""
    if not m.recorded:
        note = ("the map records no method or step: this launch is integrated with "
                f"{method}, step {m.dt:g} s")
    if method not in METHODS:  # an adaptive pair on SIMD lanes, or quadrature: dopri5
        how = ("computes one theta cycle, no path" if method == "quadrature"
               else "integrates ensembles only")
        note = (f"the map's {method} {how}: this launch is integrated with dopri5 at the map's "
                f"rtol and atol")
        method = "dopri5"
    try:
        replay_steps(m.T, m.dt, method in FIXED_STEP, "attribute run_dt_s",
                     "explore integrates launches again")
    except InputError as exc:
        raise InputError(f"{src}: {exc}") from None
    return RunSettings(T=m.T, dt=m.dt, method=method, rtol=m.rtol, atol=m.atol,
                       thresholds=m.thresholds, ball=m.ball, note=note)


def path_samples(T: float, dt: float, method: str, target: int = PATH_SAMPLES) -> int:
    """Samples of a path: for a fixed-step method one more than the largest divisor (at most
    `target`) of the map's step count, so that `simulate` takes the map's own step."""
    if method not in FIXED_STEP:
        return target + 1
    n = step_count(T, dt)
    d = max(k for k in range(1, min(n, target) + 1) if n % k == 0)
    return d + 1 if d >= target // 4 else target + 1


# ---------------------------------------------------------------------------------------------
# launches of a map
def open_lazily(path) -> xr.Dataset:
    """A map opened without reading its variables: a slice is read when it is drawn."""
    from .api import open_map

    return open_map(path, load=False)


def is_points(ds: xr.Dataset) -> bool:
    return "launch" in ds.label.dims


def _word(var: str, code) -> str:
    table = {"label": LABELS, "corner_kind": CORNER_KINDS, "formulation": FORMULATIONS}[var]
    c = int(code)
    return table[c] if 0 <= c < len(table) else "(not written)"


def launch_at(ds: xr.Dataset, where) -> dict:
    """One launch of a map: `where` is {dim: index} over a grid's dimensions or a launch index of
    a points map. Returns {"launch": simulate's launch keywords (deg, rad/s), "ball": the ball's
    values where the map varies them (SI), "name": a points map's name or None, "stored": the
    map's fields at that launch (label words as words)}."""
    one = ds.isel(where) if isinstance(where, dict) else ds.isel(launch=int(where))
    launch = {k: float(one[k].values) for k in LAUNCH_KEYS if k in one.variables}
    ball = {k: float(one[k].values) for k in BALL_KEYS if k in one.coords}
    stored = {}
    for k, v in one.data_vars.items():
        if v.ndim == 0:
            stored[k] = _word(k, v.values) if k in ("label", "corner_kind", "formulation") \
                else float(v.values)
    name = str(one["name"].values) if "name" in one.variables else None
    return {"launch": launch, "ball": ball, "name": name, "stored": stored}


def integrate_launch(ds: xr.Dataset, launch: dict, ball: dict | None = None,
                     T: float | None = None, n_out: int | None = None,
                     settings: RunSettings | None = None) -> xr.Dataset:
    """`simulate` one launch of a map with the map's method, step, tolerances, thresholds and
    ball (`ball`: values the map varies, SI); T (s) defaults to the map's duration."""
    from .simulate import simulate

    s = settings or run_settings(ds)
    T = s.T if T is None else T
    b = Ball(**{**s.ball.as_dict(), **ball}) if ball else s.ball
    return simulate(**launch, T=T, dt=s.dt, ball=b, n_out=n_out or path_samples(T, s.dt, s.method),
                    method=s.method, thresholds=s.thresholds, rtol=s.rtol, atol=s.atol)


PATH_COLUMNS = (("time", "t_s", 1.0), ("x", "x_m", 1.0), ("y", "y_m", 1.0),
                ("theta", "theta_deg", 180 / math.pi), ("chi", "chi_deg", 180 / math.pi),
                ("phi", "phi_deg", 180 / math.pi), ("thetadot", "thetadot_rad_s", 1.0),
                ("chidot", "chidot_rad_s", 1.0), ("phidot", "phidot_rad_s", 1.0),
                ("energy", "energy_J", 1.0))


def path_csv(traj: xr.Dataset) -> str:
    """A `simulate` trajectory as CSV text: time (s), x, y (m), angles (deg), rates (rad/s),
    energy (J); a header line names each column with its units."""
    cols = [np.asarray(traj[v].values, dtype=float) * f for v, _, f in PATH_COLUMNS]
    buf = io.StringIO()
    np.savetxt(buf, np.column_stack(cols), delimiter=",", fmt="%.10g",
               header=",".join(h for _, h, _ in PATH_COLUMNS), comments="")
    return buf.getvalue()


def points_entry(info: dict, name: str) -> str:
    """A `[[points]]` table for a spec that launches this launch again (ball values the map
    varies go in the spec's [ball] table: they are written as a comment)."""
    lines = ["[[points]]", f"name = {json.dumps(name)}"]
    lines += [f"{k} = {info['launch'][k]!r}" for k in LAUNCH_KEYS if k in info["launch"]]
    if info["ball"]:
        lines.append("# ball: " + ", ".join(f"{k} = {v!r}" for k, v in info["ball"].items()))
    return "\n".join(lines) + "\n"


def launch_name(info: dict, axes) -> str:
    """A points name for a grid launch: the values of the axes drawn ('theta0=2,chidot0=4')."""
    if info["name"]:
        return info["name"]
    vals = {**info["launch"], **info["ball"]}
    return ",".join(f"{a[:-4] if a.endswith('_deg') else a}={vals[a]:g}" for a in axes
                    if a in vals) or "launch"


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
# the slice shown
def axis_pixels(vals: np.ndarray, max_px: int = MAX_PIXELS):
    """(low edge, high edge, value index of each pixel) of an axis drawn as image pixels: one
    pixel per value when the values are evenly spaced, else pixels at the smallest spacing
    (at most `max_px`), each showing its nearest value."""
    vals = np.asarray(vals, dtype=float)
    order = np.argsort(vals)
    s = vals[order]
    if s.size == 1:
        w = 0.5 * max(abs(s[0]) * 0.1, 1e-3)
        return s[0] - w, s[0] + w, order
    d = np.diff(s)
    if np.allclose(d, d[0], rtol=1e-6, atol=0):
        return s[0] - d[0] / 2, s[-1] + d[0] / 2, order
    lo, hi = s[0] - d.min() / 2, s[-1] + d.min() / 2
    n = int(min(max_px, math.ceil((hi - lo) / d.min())))
    centres = lo + (np.arange(n) + 0.5) * (hi - lo) / n
    mid = 0.5 * (s[1:] + s[:-1])
    return lo, hi, order[np.searchsorted(mid, centres)]


@dataclass
class View:
    """What is shown of a map: a grid's axes drawn across (x) and up (y) with every other axis
    at one index, or a points map's launches on two launch axes."""

    ds: xr.Dataset
    x: str
    y: str
    index: dict  #: grid: {other dim: index}

    @property
    def points(self) -> bool:
        return is_points(self.ds)

    def where(self, k: int):
        """`launch_at`'s `where` of launch k of the view (grid: k = j * nx + i, j up)."""
        if self.points:
            return int(k)
        nx = self.ds.sizes[self.x]
        return {**self.index, self.y: int(k) // nx, self.x: int(k) % nx}

    def panel(self) -> xr.Dataset:
        """The slice shown, read from the file (grid: dims (y, x); points: the launches)."""
        if self.points:
            return self.ds.load()
        return self.ds.isel(self.index).transpose(self.y, self.x).load()

    def loaded(self) -> View:
        """This view over the slice shown, read into memory (for work on every launch)."""
        if self.points:
            return View(self.ds.load(), self.x, self.y, {})
        return View(self.ds.isel(self.index).load(), self.x, self.y, {})

    def fixed_text(self) -> str:
        if self.points:
            return ""
        return ", ".join(value_text(d, float(self.ds[d].values[i]))
                         for d, i in self.index.items())

    def nearest(self, xv: float, yv: float) -> int:
        """k of the grid launch nearest to the point (xv, yv) in axis units."""
        i = int(np.argmin(np.abs(self.ds[self.x].values - xv)))
        j = int(np.argmin(np.abs(self.ds[self.y].values - yv)))
        return j * self.ds.sizes[self.x] + i


def make_view(ds: xr.Dataset, x: str | None = None, y: str | None = None,
              at: dict | None = None) -> View:
    """The first view of a map: axes x, y (default: for a grid the axes `plot` draws,
    `plot.drawn_axes`; for a points map the two launch axes with most values), other grid axes
    at `at` (values in axis units) or their first value. InputError for axes the map does not
    have."""
    from .api import select

    at = dict(at or {})
    if is_points(ds):
        if at:
            raise InputError("--at fixes an axis of a grid; this map holds named points")
        choices = point_axes(ds)
        ranked = sorted(choices, key=lambda a: -len(np.unique(ds[a].values)))
        for a in (x, y):
            if a is not None and a not in choices:
                raise InputError(f"{a!r} is not a launch axis of this map; axes: "
                                 f"{', '.join(choices)}")
        x = x or next(a for a in ranked if a != y)
        y = y or next(a for a in ranked if a != x)
        if x == y:
            raise InputError(f"--x and --y are the same axis ({x})")
        return View(ds, x, y, {})
    dims = list(ds.label.dims)
    for a in (x, y):
        if a is not None and a not in dims:
            raise InputError(f"{a!r} is not an axis of this map; axes: {', '.join(dims)}")
    if x is not None and x == y:
        raise InputError(f"--x and --y are the same axis ({x})")
    if len(dims) < 2:
        raise InputError("explore draws maps with at least two axes; this one has "
                         f"{len(dims)}: use 'query'")
    x, y = drawn_axes(ds, x, y, at)
    for k in at:
        if k in (x, y):
            raise InputError(f"--at {k}: {k} is an axis drawn; --at fixes one of the others")
    select(ds, **at)  # InputError for a value off the grid (lazy: nothing is read)
    index = {}
    for d in dims:
        if d in (x, y):
            continue
        vals = np.asarray(ds[d].values, dtype=float)
        index[d] = int(np.argmin(np.abs(vals - at[d]))) if d in at else 0
    return View(ds, x, y, index)


def point_axes(ds: xr.Dataset) -> list[str]:
    return [k for k in LAUNCH_KEYS if k in ds.variables and ds[k].dims == ("launch",)]


def grid_images(view: View) -> dict:
    """Image arrays of the slice shown (rows up, pixels resampled for uneven axes), the pixel
    edges (x0, x1, y0, y1), the exact-polygon curves {n_sides: (x, y)}, the label codes present
    and the axes' values."""
    p = view.panel()
    xs, ys = p[view.x].values.astype(float), p[view.y].values.astype(float)
    x0, x1, ix = axis_pixels(xs)
    y0, y1, iy = axis_pixels(ys)
    lab = p.label.values.astype(float)
    lab[(lab < 0) | (lab >= len(LABELS))] = np.nan
    grid = {"label": lab, "xv": np.broadcast_to(xs[None, :], lab.shape),
            "yv": np.broadcast_to(ys[:, None], lab.shape)}
    for k in HOVER_FIELDS:
        grid[k] = p[k].values.astype(float) if k in p else np.full(lab.shape, np.nan)
    images = {k: np.ascontiguousarray(v[np.ix_(iy, ix)]) for k, v in grid.items()}
    curves = {}
    ns = exact_polygon_field(p, view.x, view.y)
    if ns is not None:
        from bokeh.plotting.contour import contour_data

        ox, oy = np.argsort(xs), np.argsort(ys)
        lines = contour_data(xs[ox], ys[oy], ns[np.ix_(oy, ox)], list(EXACT_POLYGON_LEVELS),
                             want_fill=False, want_line=True).line_data
        curves = {float(lv): (np.asarray(lx), np.asarray(ly))
                  for lv, lx, ly in zip(lines.levels, lines.xs, lines.ys) if len(lx)}
    present = sorted({int(v) for v in np.unique(lab[np.isfinite(lab)])})
    crossings = {} if ns is None else curve_crossings(ns, p.label.transpose(view.y,
                                                                            view.x).values)
    return {"images": images, "edges": (x0, x1, y0, y1), "curves": curves, "present": present,
            "xs": xs, "ys": ys, "crossings": crossings}


def point_columns(view: View) -> dict:
    """Columns of a points map's scatter: the axes drawn, colour, label word, name, fields."""
    p = view.panel()
    codes = p.label.values.astype(int)
    cols = {"x": p[view.x].values.astype(float), "y": p[view.y].values.astype(float),
            "label": [_word("label", c) for c in codes],
            "color": [LABEL_COLOURS.get(_word("label", c), "#ffffff") for c in codes],
            "name": [str(n) for n in p["name"].values] if "name" in p.variables
            else [str(i) for i in range(codes.size)]}
    for k in HOVER_FIELDS:
        cols[k] = p[k].values.astype(float) if k in p else np.full(codes.size, np.nan)
    return cols


# ---------------------------------------------------------------------------------------------
# the launch panel's text
def _fmt(k: str, v) -> str:
    if isinstance(v, str):
        return v
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    text = (FIELDS[k][2] if k in FIELDS else "%.4g") % v
    return text[1:] if text.startswith("-") and float(text) == 0 else text  # no "-0.00"


def _h(text) -> str:
    """Text from outside (a name, a file name, an attribute, a message quoting one) as HTML
    text: every character HTML or an attribute gives a meaning to is an entity."""
    return html.escape(str(text), quote=True).replace("`", "&#96;")


def launch_html(info: dict, again: xr.Dataset | None = None, note: str = "",
                timing: str = "") -> str:
    """The launch panel: the launch, its label and fields as stored in the map and, when given,
    as integrated again; `note` (a warning) and `timing` below."""
    launch = {**info["launch"], **info["ball"]}
    head = ", ".join(value_text(k, v) for k, v in launch.items())
    s = info["stored"]
    a = again.attrs if again is not None else {}
    rows = [("label", "", "label"), ("corner kind", "", "corner_kind")]
    rows += [(text, units, k) for k, (text, units, _) in FIELDS.items()]
    cells = "".join(
        f"<tr><td>{_h(text)}</td><td>{_h(units)}</td><td class='bs-map' data-field='{_h(k)}'>"
        f"{_h(_fmt(k, s.get(k)))}</td>"
        + (f"<td class='bs-again' data-field='{_h(k)}'>{_h(_fmt(k, a.get(k)))}</td>" if a else "")
        + "</tr>" for text, units, k in rows if k in s or k in a)
    title = s.get("label", "?") if not a or a.get("label") == s.get("label") else \
        f"{s.get('label', '?')} (integrated again: {a.get('label')})"
    name = f"{info['name']}: " if info["name"] else ""
    col = "<th>integrated again</th>" if a else ""
    extra = f"<p style='color:#a33'>{_h(note)}</p>" if note else ""
    extra += f"<p style='color:#555'>{_h(timing)}</p>" if timing else ""
    return (f"<div class='bs-launch'><h3 style='margin:0'>{_h(title)}</h3><p>{_h(name + head)}</p>"
            f"<table><tr><th>field</th><th>units</th><th>map</th>{col}</tr>{cells}</table>"
            f"{extra}</div>")


def panel_spec() -> list:
    """The launch panel's rows for the static page's JavaScript: [key, text, units, format]
    with format [kind, digits] ('f': fixed, 'g': significant), as `launch_html` lays them."""
    rows = [["label", "label", "", None], ["corner_kind", "corner kind", "", None]]
    return rows + [[k, text, units, [fmt[-1], int(fmt[2:-1])]]
                   for k, (text, units, fmt) in FIELDS.items()]


def launch_columns(view: View) -> dict:
    """Per-launch columns of a view read into memory (`View.loaded`), in launch order k: label
    and corner kind codes, the panel's fields, and a points map's names and launch values."""
    p = view.ds
    if not view.points:
        p = p.transpose(view.y, view.x)
    cols = {k: np.ravel(p[k].values) for k in ("label", "corner_kind", *FIELDS) if k in p}
    if view.points:
        cols["name"] = [str(v) for v in p["name"].values]
        cols.update({k: np.ravel(p[k].values) for k in LAUNCH_KEYS})
    return cols


def legend_html(present, curves=(), crossings=None) -> str:
    """The map's legend: a swatch per label code in `present`, and the exact-polygon curves
    drawn (`curves`: their n_sides levels), with the other labels each runs through
    (`crossings`, from `plot.curve_crossings`)."""
    items = "".join(
        f"<span style='display:inline-block;margin-right:10px'><span style='display:inline-block;"
        f"width:12px;height:12px;background:{LABEL_COLOURS[LABELS[c]]};border:1px solid #666;"
        f"vertical-align:middle'></span> {LABELS[c].replace('_', '-')}</span>" for c in present)
    lines = [text + (f" ({crossing_text(lv, crossings[lv])})" if lv in (crossings or {}) else "")
             for lv, text in ((4.0, "solid line: exact square (n = 4)"),
                              (3.0, "dashed line: exact triangle (n = 3)")) if lv in curves]
    if lines:
        items += f"<span>&nbsp;{', '.join(lines)}</span>"
    return f"<div style='font-size:12px'>{items}</div>"


# ---------------------------------------------------------------------------------------------
# Bokeh: the pieces shared by the app and the static page
_DOWNLOAD_JS = """
const text = src.data[key][0];
if (!text) { return; }
const blob = new Blob([text], {type: mime});
const a = document.createElement('a');
a.href = URL.createObjectURL(blob);
a.download = src.data['stem'][0] + ext;
document.body.appendChild(a); a.click(); a.remove();
"""


def _map_figure(view: View, title: str):
    from bokeh.models import ColumnDataSource, CustomJSHover, HoverTool, LinearColorMapper
    from bokeh.plotting import figure

    fig = figure(width=560, height=480, title=title, tools="pan,wheel_zoom,box_zoom,reset,save",
                 x_axis_label=axis_text(view.x), y_axis_label=axis_text(view.y),
                 name="map")
    marker = ColumnDataSource({"x": [], "y": []}, name="marker")
    words = CustomJSHover(args={"words": list(LABELS)},
                          code="return isNaN(value) ? '(not written)' : words[value];")
    fmt = {f"@{k}": "printf" for k in (*HOVER_FIELDS, "xv", "yv", "x", "y")}
    tips = [(axis_text(view.x), "@xv{%.6g}"), (axis_text(view.y), "@yv{%.6g}")] \
        if not view.points else [("name", "@name"), (axis_text(view.x), "@x{%.6g}"),
                                 (axis_text(view.y), "@y{%.6g}")]
    tips.append(("label", "@image{custom}" if not view.points else "@label"))
    tips += [(f"{FIELDS[k][0]} ({FIELDS[k][1]})" if FIELDS[k][1] else FIELDS[k][0],
              f"@{k}{{{FIELDS[k][2]}}}") for k in HOVER_FIELDS]
    parts = {}
    if view.points:
        src = ColumnDataSource(point_columns(view), name="points")
        r = fig.scatter("x", "y", source=src, color="color", line_color="#333", size=14,
                        nonselection_alpha=1.0)
        parts.update(points=src)
    else:
        g = grid_images(view)
        x0, x1, y0, y1 = g["edges"]
        src = ColumnDataSource({k: [v] for k, v in g["images"].items()} | {"image": [
            g["images"]["label"]]}, name="image")
        cmap = LinearColorMapper(palette=[LABEL_COLOURS[w] for w in LABELS], low=-0.5,
                                 high=len(LABELS) - 0.5, nan_color="#ffffff")
        r = fig.image("image", source=src, x=x0, y=y0, dw=x1 - x0, dh=y1 - y0,
                      color_mapper=cmap)
        fmt["@image"] = words
        lines = {}
        for lv in EXACT_POLYGON_LEVELS:
            lx, ly = g["curves"].get(lv, ([], []))
            lines[lv] = ColumnDataSource({"x": lx, "y": ly})
            fig.line("x", "y", source=lines[lv], color="black", line_width=1.5,
                     line_dash=EXACT_POLYGON_DASH[lv])
        parts.update(image=src, glyph=r.glyph, lines=lines, grid=g)
        fig.x_range.range_padding = fig.y_range.range_padding = 0
    fig.add_tools(HoverTool(renderers=[r], tooltips=tips, formatters=fmt))
    fig.scatter("x", "y", source=marker, marker="circle_x", size=16, fill_color=None,
                line_color="black", line_width=2)
    parts.update(marker=marker, renderer=r)
    return fig, parts


def _legend(parts: dict) -> str:
    """The legend of a map figure made by `_map_figure`: the labels drawn, the curves."""
    if "points" in parts:
        words = parts["points"].data["label"]
        return legend_html(sorted({LABELS.index(w) for w in words if w in LABELS}))
    return legend_html(parts["grid"]["present"], parts["grid"]["curves"],
                       parts["grid"].get("crossings"))


def _path_figures(start_text="launch point"):
    """The path and theta(t) figures; `start_text` names the black triangle."""
    from bokeh.models import ColumnDataSource
    from bokeh.plotting import figure

    path = ColumnDataSource({"x": [], "y": []}, name="path")
    start = ColumnDataSource({"x": [], "y": []}, name="start")
    theta = ColumnDataSource({"t": [], "theta": []}, name="theta")
    fp = figure(width=440, height=400, title="path of the centre of mass", match_aspect=True,
                x_axis_label="x (m)", y_axis_label="y (m)", tools="pan,wheel_zoom,reset,save",
                name="path_figure")
    fp.line("x", "y", source=path, color="#4477aa", line_width=1.5)
    fp.scatter("x", "y", source=start, marker="triangle", size=10, color="black",
               legend_label=start_text)
    fp.add_layout(fp.legend[0], "below")  # under the plot, clear of the path
    fp.legend.label_text_font_size = "9pt"
    ft = figure(width=440, height=200, title="tilt theta(t)", x_axis_label="t (s)",
                y_axis_label="theta (deg)", tools="pan,wheel_zoom,reset,save")
    ft.line("t", "theta", source=theta, color="black")
    return fp, ft, {"path": path, "start": start, "theta": theta}


def _title(ds: xr.Dataset, path) -> str:
    return f"{ds.attrs.get('title', Path(str(path)).stem)} ({Path(str(path)).name})"


# ---------------------------------------------------------------------------------------------
# the server app
def build_document(doc, ds: xr.Dataset, path, x=None, y=None, at=None) -> None:
    """Fill a Bokeh document with the app for map `ds` (its file name `path`)."""
    from bokeh.events import Tap
    from bokeh.layouts import column, row
    from bokeh.models import (
        Button,
        ColumnDataSource,
        CustomJS,
        CustomJSTickFormatter,
        Div,
        PreText,
        Select,
        Slider,
        TapTool,
    )

    settings = run_settings(ds)
    view = make_view(ds, x, y, at)
    fig, parts = _map_figure(view, _title(ds, path))
    fp, ft, srcs = _path_figures()
    fixed = Div(text=_h(view.fixed_text()), name="fixed")
    legend = Div(text=_legend(parts), name="legend")
    info_div = Div(text="<p>Click a launch on the map: it is integrated again with the map's "
                        f"{_h(settings.method)}, step {settings.dt:g} s, for {settings.T:g} s.</p>",
                   width=460, name="launch")
    toml = PreText(text="", width=460, name="toml")
    downloads = ColumnDataSource({"csv": [""], "toml": [""], "stem": ["launch"]},
                                 name="downloads")
    b_csv = Button(label="download path (CSV)", name="download_csv")
    b_csv.js_on_click(CustomJS(args=dict(src=downloads, key="csv", mime="text/csv", ext=".csv"),
                               code=_DOWNLOAD_JS))
    b_toml = Button(label="download [[points]] entry (TOML)", name="download_toml")
    b_toml.js_on_click(CustomJS(args=dict(src=downloads, key="toml", mime="text/plain",
                                          ext=".toml"), code=_DOWNLOAD_JS))

    def show_launch(k: int) -> None:
        where = view.where(k)
        info = launch_at(ds, where)
        xv = info["launch"].get(view.x, info["ball"].get(view.x))
        yv = info["launch"].get(view.y, info["ball"].get(view.y))
        parts["marker"].data = {"x": [xv], "y": [yv]}
        t0 = time.perf_counter()
        try:
            traj = integrate_launch(ds, info["launch"], info["ball"], settings=settings)
        except (InputError, ValueError) as exc:
            info_div.text = launch_html(info, note=f"cannot integrate it again: {exc}")
            return
        took = time.perf_counter() - t0
        srcs["path"].data = {"x": traj.x.values, "y": traj.y.values}
        srcs["start"].data = {"x": traj.x.values[:1], "y": traj.y.values[:1]}
        srcs["theta"].data = {"t": traj.time.values, "theta": np.degrees(traj.theta.values)}
        how = (f"step {traj.attrs['dt_s']:g} s" if settings.method in FIXED_STEP else
               f"rtol {settings.rtol:g}, atol {settings.atol:g}")
        timing = (f"Integrated again in {took:.2f} s ({settings.method}, {how}, "
                  f"T = {settings.T:g} s).")
        info_div.text = launch_html(info, traj, settings.note, timing)
        name = launch_name(info, (view.x, view.y))
        entry = points_entry(info, name)
        toml.text = entry
        stem = "".join(c if c.isalnum() or c in "-_." else "_" for c in name)
        downloads.data = {"csv": [path_csv(traj)], "toml": [entry], "stem": [stem]}

    if view.points:
        def on_select(attr, old, new):
            if new:
                show_launch(new[0])
        parts["points"].selected.on_change("indices", on_select)
        fig.add_tools(TapTool(renderers=[parts["renderer"]]))
    else:
        def on_tap(event):
            if event.x is None or event.y is None:
                return
            show_launch(view.nearest(event.x, event.y))
        fig.on_event(Tap, on_tap)

    def redraw() -> None:
        if view.points:
            parts["points"].data = point_columns(view)
        else:
            g = grid_images(view)
            x0, x1, y0, y1 = g["edges"]
            parts["image"].data = {k: [v] for k, v in g["images"].items()} | {
                "image": [g["images"]["label"]]}
            gl = parts["glyph"]
            gl.x, gl.y, gl.dw, gl.dh = x0, y0, x1 - x0, y1 - y0
            for lv, src in parts["lines"].items():
                lx, ly = g["curves"].get(lv, ([], []))
                src.data = {"x": lx, "y": ly}
            legend.text = legend_html(g["present"], g["curves"], g["crossings"])
            fixed.text = _h(view.fixed_text())
        fig.xaxis.axis_label, fig.yaxis.axis_label = axis_text(view.x), axis_text(view.y)
        parts["marker"].data = {"x": [], "y": []}

    axis_choices = point_axes(ds) if view.points else list(ds.label.dims)
    sel_x = Select(title="across", value=view.x, options=axis_choices, width=150, name="x_axis")
    sel_y = Select(title="up", value=view.y, options=axis_choices, width=150, name="y_axis")
    sliders = {}

    def on_axes(attr, old, new):
        nx, ny = sel_x.value, sel_y.value
        if nx == ny:  # swap: the other select takes the axis given up
            (sel_y if attr == "x" else sel_x).value = old
            return
        if not view.points:
            new_index = {d: (sliders[d].value if d in sliders else 0)
                         for d in ds.label.dims if d not in (nx, ny)}
            view.index = new_index
        view.x, view.y = nx, ny
        for d, s in sliders.items():
            s.visible = d not in (nx, ny)
        redraw()

    sel_x.on_change("value", lambda a, o, n: on_axes("x", o, n))
    sel_y.on_change("value", lambda a, o, n: on_axes("y", o, n))
    if not view.points:
        for d in ds.label.dims:
            vals = [float(v) for v in ds[d].values]
            if len(vals) < 2:
                continue
            s = Slider(start=0, end=len(vals) - 1, step=1, value=view.index.get(d, 0),
                       title=axis_text(d), width=300, visible=d not in (view.x, view.y),
                       format=CustomJSTickFormatter(args={"vals": vals},
                                                    code="return String(vals[tick]);"),
                       name=f"slider_{d}")

            def on_slide(attr, old, new, d=d):
                if d not in (view.x, view.y):
                    view.index[d] = int(new)
                    redraw()
            s.on_change("value_throttled", on_slide)
            sliders[d] = s
    left = column(fig, legend, fixed, row(sel_x, sel_y), *sliders.values())
    right = column(info_div, fp, ft, row(b_csv, b_toml), toml)
    doc.add_root(row(left, right))
    doc.title = f"ballsurvey explore: {Path(str(path)).name}"


def host_names(names, port: int) -> list[str]:
    """--allow-host values as HOST:PORT (lower case; PORT: `port` where a name gives none);
    InputError for anything that is not a host name or address with an optional port."""
    import re

    out = []
    for name in names:
        m = re.fullmatch(r"(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+)(?::(\d{1,5}))?", str(name).strip())
        if not m or (m.group(2) and not 1 <= int(m.group(2)) <= 65535):
            raise InputError(f"--allow-host: {name!r} is not a host name with an optional "
                             "port (NAME or NAME:PORT)")
        out.append(f"{m.group(1).lower()}:{m.group(2) or port}")
    return list(dict.fromkeys(out))


def _answer_only(tornado_app, hosts) -> None:
    """Make the Bokeh server's Tornado application answer only requests whose Host header is
    one of `hosts` (HOST:PORT): any other, or none, gets 403 and nothing of the app (a page
    whose name was rebound to 127.0.0.1 cannot reach it)."""
    from tornado.web import RequestHandler

    allowed = {h.lower() for h in hosts}

    class Refused(RequestHandler):
        def prepare(self):
            self.set_status(403)
            self.set_header("Content-Type", "text/plain; charset=utf-8")
            self.finish("ballsurvey explore answers only " + ", ".join(sorted(allowed)) + "\n")

    find = tornado_app.find_handler

    def find_handler(request, **kw):
        if request.headers.get("Host", "").strip().lower() not in allowed:
            return tornado_app.get_handler_delegate(request, Refused)
        return find(request, **kw)

    tornado_app.find_handler = find_handler


def serve(path, port: int = 5006, open_browser: bool = True, x=None, y=None, at=None,
          ready=print, allow_hosts=()) -> None:
    """Serve the app for the map at `path` on http://127.0.0.1:`port`/ until Ctrl-C (which
    raises KeyboardInterrupt). The map and the axes are checked first (InputError); the
    kernels are compiled (or read from the cache) before the address is printed.

    Only requests for Host 127.0.0.1:`port` or localhost:`port` are answered, and websockets
    only from pages of those origins; `allow_hosts` (HOST:PORT, `host_names`) adds others."""
    require_bokeh()
    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.server.server import Server

    ds = open_lazily(path)
    view = make_view(ds, x, y, at)
    settings = run_settings(ds)
    info = launch_at(ds, view.where(0))
    try:  # compile now, not at the first click
        integrate_launch(ds, info["launch"], info["ball"], T=min(settings.T, 10 * settings.dt),
                         n_out=2, settings=settings)
    except (InputError, ValueError):
        pass
    app = Application(FunctionHandler(lambda doc: build_document(doc, ds, path, x, y, at)))
    hosts = [f"127.0.0.1:{port}", f"localhost:{port}", *allow_hosts]
    try:
        server = Server({"/": app}, port=port, address="127.0.0.1", num_procs=1,
                        allow_websocket_origin=hosts)
    except OSError as exc:
        raise RunError(f"cannot listen on 127.0.0.1:{port} ({exc.strerror or exc}): give "
                       "another --port") from None
    _answer_only(server._tornado, hosts)
    server.start()
    url = f"http://127.0.0.1:{port}/"
    ready(f"ballsurvey explore: serving {path} at {url} (Ctrl-C stops)")
    if open_browser:
        import webbrowser

        server.io_loop.add_callback(webbrowser.open, url)
    try:
        server.io_loop.start()
    finally:
        server.stop()


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

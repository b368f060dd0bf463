"""The Bokeh document: the launch panel's text and the legend (text from outside escaped,
`_h`), the map figure and the path figures shared by the app and the static page, and the app's
document (`build_document`), which integrates a clicked launch again.

Bokeh is imported only inside the functions that draw (`require_bokeh` names the extra).
"""
from __future__ import annotations

import html
import math
import time
from pathlib import Path

import numpy as np
import xarray as xr

from ..classify.labels import LABELS
from ..integrate.tableaus import FIXED_STEP
from ..limits import InputError
from ..plot import (
    EXACT_POLYGON_DASH,
    EXACT_POLYGON_LEVELS,
    LABEL_COLOURS,
    crossing_text,
)
from .launch import (
    axis_text,
    integrate_launch,
    launch_at,
    launch_name,
    path_csv,
    points_entry,
    run_settings,
    value_text,
)
from .view import FIELDS, HOVER_FIELDS, View, grid_images, make_view, point_axes, point_columns

INSTALL_HINT = "pip install 'ballsurvey[explore]'"


def require_bokeh() -> None:
    """InputError (one line naming the extra) when Bokeh is not installed."""
    try:
        import bokeh  # noqa: F401
    except ImportError:
        raise InputError(f"explore needs Bokeh, which is not installed: {INSTALL_HINT}") from None


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
# the app's document
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

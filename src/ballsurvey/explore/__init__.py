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

The modules, each importing only those above it in this list:

    launch     one launch of a map: the map's run settings, its values, integrated again
    view       the slice shown: axes drawn, image arrays, curves, scatter and panel columns
    document   the Bokeh document: launch panel, legend, figures, the app (text escaped: `_h`)
    server     the Bokeh server on 127.0.0.1 and its Host and Origin checks (`--allow-host`)
    static     the static page and its Content-Security-Policy

Every name is also a name of this package, for reading; a limit is changed in the module that
uses it (`explore.static.MAX_HTML_STEPS`).
"""
from __future__ import annotations

from .document import (
    INSTALL_HINT,
    _h,
    build_document,
    launch_html,
    legend_html,
    panel_spec,
    require_bokeh,
)
from .launch import (
    PATH_COLUMNS,
    PATH_SAMPLES,
    RunSettings,
    axis_text,
    integrate_launch,
    is_points,
    launch_at,
    launch_name,
    open_lazily,
    path_csv,
    path_samples,
    points_entry,
    run_settings,
    value_text,
)
from .server import host_names, serve
from .static import (
    CSP,
    CYCLE_SAMPLES,
    CYCLE_SPAN,
    MAX_HTML_LAUNCHES,
    MAX_HTML_PATHS,
    MAX_HTML_STEPS,
    MAX_STAR_POINTS,
    one_cycle,
    orbit_turn,
    page_steps,
    precompute_cycles,
    with_csp,
    write_html,
)
from .view import (
    FIELDS,
    HOVER_FIELDS,
    MAX_PIXELS,
    View,
    axis_pixels,
    grid_images,
    launch_columns,
    make_view,
    point_axes,
    point_columns,
)

__all__ = [
    "CSP", "CYCLE_SAMPLES", "CYCLE_SPAN", "FIELDS", "HOVER_FIELDS", "INSTALL_HINT",
    "MAX_HTML_LAUNCHES", "MAX_HTML_PATHS", "MAX_HTML_STEPS", "MAX_PIXELS", "MAX_STAR_POINTS",
    "PATH_COLUMNS", "PATH_SAMPLES", "RunSettings", "View", "_h", "axis_pixels", "axis_text",
    "build_document", "grid_images", "host_names", "integrate_launch", "is_points", "launch_at",
    "launch_columns", "launch_html", "launch_name", "legend_html", "make_view", "one_cycle",
    "open_lazily", "orbit_turn", "page_steps", "panel_spec", "path_csv", "path_samples",
    "point_axes", "point_columns", "points_entry", "precompute_cycles", "require_bokeh",
    "run_settings", "serve", "value_text", "with_csp", "write_html",
]

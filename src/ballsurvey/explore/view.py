"""The slice of a map shown: the axes drawn across and up with every other axis at one index
(`View`, `make_view`), read from the file as image arrays and exact-polygon curves (a grid) or
scatter columns (a points map), and the per-launch columns of the launch panel.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import xarray as xr

from ..classify.labels import LABELS
from ..gallery import LAUNCH_KEYS
from ..limits import InputError
from ..plot import (
    EXACT_POLYGON_LEVELS,
    LABEL_COLOURS,
    curve_crossings,
    drawn_axes,
    exact_polygon_field,
)
from .launch import _word, is_points, value_text

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
    from ..api import select

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

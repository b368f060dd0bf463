"""Plots: regime maps of a stored sweep, and single paths drawn like the paper's figures.

Figures are made with matplotlib's object API (`matplotlib.figure.Figure`) and written to files:
importing this module changes no global matplotlib state (no backend is chosen), so it is safe in
notebooks; `plot_map` and `plot_path` return the file written.
"""
from __future__ import annotations

import math
import textwrap

import numpy as np
import xarray as xr
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from .axes import AXES
from .ball import Ball
from .classify.labels import LABELS, SHAPES
from .classify.observer import theta_maxima
from .limits import InputError
from .physics import euler

#: one colour per label word: shapes from Paul Tol's bright and muted qualitative schemes (told
#: apart with each common colour-vision deficiency), statuses in greys and browns, hatched on maps
LABEL_COLOURS = {
    "circle": "#4477aa", "near_straight": "#66ccee", "triangle": "#228833", "square": "#ee6677",
    "ngon": "#ccbb44", "star": "#aa3377", "rosette": "#44aa99",
    "unresolved": "#dddddd", "blew_up": "#000000", "singular": "#555555", "flat_face": "#997755",
    "lift_off": "#bbbbbb", "slipping": "#888888", "inaccurate": "#ee7733",
}
#: line colours of the path figure's panels (Okabe and Ito's colour-blind-safe set)
LINE_COLOURS = {"chidot": "#0072b2", "phidot": "#e69f00", "friction": "#d55e00",
                "normal": "#009e73", "corner": "#cc3311", "spin": "#000000"}
AXIS_TEXT = {k: ax.plot_label for k, ax in AXES.items()}
#: figures are written in these formats, chosen by the output file's suffix
FIGURE_SUFFIXES = (".png", ".pdf", ".svg")
#: the words for corner kinds printed beside a polygon or star (other shapes print none: a
#: circle, a line or a rosette has no corners to speak of)
#: a path whose theta varies less than this (deg) is drawn in one colour, its theta named
STEADY_THETA_DEG = 0.5
STEADY_COLOUR = "#21918c"  # viridis at its middle
CORNER_WORDS = {"rounded": "rounded corners", "cusp": "cusped corners",
                "loop": "looped corners"}


def axis_value_text(axis: str, value: float) -> str:
    """'$\\dot\\phi_0$ = -3 rad/s', '$\\theta_0$ = 5 deg': the axis's plot symbol, its value and
    units (matplotlib mathtext, as on the axes)."""
    label = AXES[axis].plot_label if axis in AXES else axis
    symbol = label.split(" (")[0]
    unit = AXES[axis].text_units if axis in AXES else ""
    return f"{symbol} = {value:g} {unit}".rstrip()


def ball_text(attrs: dict) -> str:
    """Which ball a map or a path is of, from its attributes (`ball_a`, `ball_c`, `ball_M`):
    "the paper's ball (a = 25.4 mm, c = 2.9 mm, M = 98.4 g)", or "ball: a = ..." for another;
    an axis of the map that varies the ball is named instead of its value."""
    paper = Ball.paper()
    vals, parts = {}, []
    for k, unit, scale in (("a", "mm", 1e3), ("c", "mm", 1e3), ("M", "g", 1e3)):
        v = attrs.get(f"ball_{k}")
        try:
            vals[k] = float(v)
        except (TypeError, ValueError):
            parts.append(f"{k} varies")
            continue
        parts.append(f"{k} = {vals[k] * scale:.4g} {unit}")
    same = all(math.isclose(vals.get(k, math.nan), getattr(paper, k), rel_tol=1e-9)
               for k in ("a", "c", "M"))
    same = same and all(math.isclose(float(attrs.get(f"ball_{k}", math.nan)), getattr(paper, k),
                                     rel_tol=1e-9) for k in ("A", "B", "cut_height"))
    return ("the paper's ball (" if same else "ball: ") + ", ".join(parts) + (")" if same else "")


def shape_text(fields: dict) -> str:
    """A launch's shape in words, from its label and fields (a path's attrs or a map row):
    'square, n = 3.998, rounded corners', 'star {5/2}, n = 2.500, cusped corners', 'circle'.
    n is given where the path has a turn per cycle; the corner kind only for polygons and stars,
    the shapes whose corners the classifier judged."""
    label = str(fields.get("label", "?"))
    text = label.replace("_", " ")
    p, q = fields.get("star_points"), fields.get("star_step")
    if label == "star" and _finite(p) and _finite(q) and p > 0:
        text += f" {{{int(p)}/{int(q)}}}"
    n = fields.get("n_sides")
    if label in SHAPES and label not in ("circle", "near_straight") and _finite(n):
        text += f", n = {float(n):.3f}"
    kind = str(fields.get("corner_kind", ""))
    if label in ("triangle", "square", "ngon", "star") and kind in CORNER_WORDS:
        text += f", {CORNER_WORDS[kind]}"
    return text


def _finite(v) -> bool:
    try:
        return math.isfinite(float(v))
    except (TypeError, ValueError):
        return False


def figure_format(out) -> str:
    """'png', 'pdf' or 'svg': the format a figure file's suffix names (InputError otherwise)."""
    from pathlib import Path

    suffix = Path(out).suffix.lower()
    if suffix not in FIGURE_SUFFIXES:
        raise InputError(f"{out}: a figure file ends in {', '.join(FIGURE_SUFFIXES)}")
    return suffix[1:]


def _save(fig: Figure, out, dpi: int = 110):
    """Write a figure in the format its file's suffix names (.png, .pdf or .svg)."""
    suffix = "." + figure_format(out)
    extra = {"pil_kwargs": {"optimize": True}} if suffix == ".png" else {}
    fig.savefig(out, dpi=dpi, format=suffix[1:], **extra)
    return out


def _select(ds: xr.Dataset, x: str, y: str, at: dict, facet: str | None) -> xr.Dataset:
    from .api import select

    for k in at:
        if k in (x, y, facet):
            role = "facet axis" if k == facet else "axis drawn " + ("across" if k == x else "up")
            raise InputError(f"--at {k}: {k} is the {role}; --at fixes one of the other axes "
                             f"({', '.join(d for d in ds.label.dims if d not in (x, y, facet))})")
    ds = select(ds, **at)
    keep = {x, y} | ({facet} if facet else set())
    for d in list(ds.dims):
        if d not in keep:
            if ds.sizes[d] != 1:
                raise InputError(f"axis {d} has {ds.sizes[d]} values: fix one with --at "
                                 f"{d}=VALUE or draw it as facets with --facet {d}")
            ds = ds.isel({d: 0})
    return ds


def default_axes(ds: xr.Dataset, exclude=(), need: int = 2) -> tuple[str, ...]:
    """The first two axes of a grid, in the map's own order of dimensions (theta0_deg,
    thetadot0, chidot0, phidot0, then ball axes), that hold more than one value and are not in
    `exclude`: the first drawn across, the second up (`need`: how many are wanted). Grid sizes
    do not matter, so two maps of one plane are drawn the same way round."""
    dims = [d for d in ds.label.dims if d not in exclude and ds.sizes[d] > 1]
    if len(dims) < need:
        besides = (f" besides the facet and fixed axes ({', '.join(sorted(exclude))})"
                   if exclude else "")
        raise InputError(f"a regime map needs two axes with more than one value{besides}")
    return tuple(dims[:need])


def drawn_axes(ds: xr.Dataset, x: str | None = None, y: str | None = None,
               at: dict | None = None, facet: str | None = None) -> tuple[str, str]:
    """The axes a map is drawn over, across and up: `x` and `y` where given, the others from
    `default_axes` (the map's first axes with more than one value, in its own order, leaving
    out `facet` and, where enough are left, the axes `at` fixes). Used by `plot` and
    `explore`, so both draw a map the same way round."""
    if x is not None and y is not None:
        return x, y
    taken = ({facet} if facet else set()) | {a for a in (x, y) if a}
    need = (x is None) + (y is None)
    try:  # the axes --at fixes are not drawn, where others are left to draw
        free = default_axes(ds, exclude=taken | set(at or {}), need=need)
    except InputError:  # too few left: the caller says which axis --at fixes that is drawn
        free = default_axes(ds, exclude=taken, need=need)
    return (x, free[0]) if x else (free[0], y or free[1])


#: n_sides of the exact-polygon curves drawn over a map: the exact triangle and square
EXACT_POLYGON_LEVELS = (3.0, 4.0)
#: how each curve is drawn, by `plot` and `explore` alike: the triangle dashed, the square solid
EXACT_POLYGON_DASH = {3.0: "dashed", 4.0: "solid"}
#: the word of the polygon each exact curve closes
EXACT_POLYGON_WORDS = {3.0: "triangle", 4.0: "square"}


def exact_polygon_field(panel: xr.Dataset, x: str, y: str) -> np.ndarray | None:
    """n_sides on the (y, x) grid of a 2-D panel, NaN outside n_sides < 6, for the curves
    n_sides = 3 and 4 (`EXACT_POLYGON_LEVELS`); None where no curve can be drawn: no n_sides
    variable, an axis with fewer than 3 values, fewer than 4 such values or no triangle or
    square launch."""
    if "n_sides" not in panel or min(panel.sizes[x], panel.sizes[y]) < 3:
        return None
    ns = np.asarray(panel.n_sides.transpose(y, x).values, dtype=float)
    poly = np.isin(panel.label.transpose(y, x).values, [LABELS.index("triangle"),
                                                         LABELS.index("square")])
    ns = np.where(np.isfinite(ns) & (ns < 6), ns, np.nan)
    return ns if np.isfinite(ns).sum() >= 4 and poly.any() else None


def curve_crossings(ns: np.ndarray, lab: np.ndarray) -> dict:
    """{n_sides level: words} for each exact-polygon curve of `exact_polygon_field` `ns` that
    runs through the region of another label on the label codes `lab` (same grid): the words
    of the labels on both sides of the curve's crossings between neighbouring grid points, other
    than the polygon's own (n = 4 runs through `circle` where a rounded square stays within 5 %
    of a circle, and the eye sees a circle)."""
    out = {}
    lab = np.asarray(lab, dtype=float)
    for lv, word in EXACT_POLYGON_WORDS.items():
        d = ns - lv
        found = set()
        for a, b, la, lb in ((d[:, :-1], d[:, 1:], lab[:, :-1], lab[:, 1:]),
                             (d[:-1, :], d[1:, :], lab[:-1, :], lab[1:, :])):
            with np.errstate(invalid="ignore"):
                # the curve passes between the two (or through one of them)
                cross = (a * b <= 0) & ((a != 0) | (b != 0)) & (la == lb) & np.isfinite(la)
            found |= {LABELS[int(c)] for c in np.unique(la[cross]) if 0 <= c < len(LABELS)}
        found.discard(word)
        if found:
            out[lv] = sorted(found, key=LABELS.index)
    return out


def crossing_text(level: float, words) -> str:
    """What a map says where the exact polygon `level` runs through other labels' regions."""
    return (f"also through {' and '.join(words)}: n={int(level)} there, but the path reads "
            f"as {' or '.join(words)}")


def plot_map(ds: xr.Dataset, out=None, x: str | None = None, y: str | None = None,
             at: dict | None = None, facet: str | None = None, contours: bool = True):
    """Draw a regime map: one colour per label over axes x (across) and y (up).

    Parameters
    ----------
    ds : xarray.Dataset
        A map (`ballsurvey.open_map`, `ballsurvey.sweep`).
    out : str or path, optional
        The file to write: .png, .pdf or .svg (None: return the Figure).
    x, y : str, optional
        The axes drawn across and up (default: the map's first two axes with more than one
        value, in its own order of dimensions, whatever the grid sizes).
    at : dict, optional
        One value for each other axis, e.g. ``{"phidot0": -3}`` (within half a grid step).
    facet : str, optional
        One panel per value of this axis.
    contours : bool
        Draw the exact n = 3 and n = 4 curves.

    Returns
    -------
    The file written, or with `out` None the matplotlib Figure (shown by a notebook as it is).
    """
    if out is None:
        return map_figure(ds, x, y, at, facet, contours)
    figure_format(out)
    return _save(map_figure(ds, x, y, at, facet, contours), out)


def map_figure(ds: xr.Dataset, x: str | None = None, y: str | None = None,
               at: dict | None = None, facet: str | None = None,
               contours: bool = True) -> Figure:
    """The figure `plot_map` writes (a matplotlib `Figure`, not yet saved)."""
    if "label" not in ds:
        raise InputError("the file has no 'label' variable (not a ballsurvey map?)")
    if "launch" in ds.dims:
        raise InputError("this file holds named points, not a grid: use 'query' to list them")
    if facet is not None and facet in (x, y):
        raise InputError(f"--facet {facet} is also the axis drawn "
                         f"{'across (--x)' if facet == x else 'up (--y)'}: facet by another axis")
    x, y = drawn_axes(ds, x, y, at, facet)
    if x == y:
        raise InputError(f"--x and --y are the same axis ({x})")
    for a in (x, y) + ((facet,) if facet else ()):
        if a not in ds.dims:
            raise InputError(f"{a!r} is not an axis of this map; axes: {', '.join(ds.dims)}")
    sel = _select(ds, x, y, at or {}, facet)
    panels = [sel] if facet is None else [sel.isel({facet: i}) for i in range(sel.sizes[facet])]
    ncol = min(3, len(panels))
    nrow = math.ceil(len(panels) / ncol)
    fig = Figure(figsize=(5.2 * ncol + 1.8, 4.4 * nrow), layout="constrained")
    axes = fig.subplots(nrow, ncol, squeeze=False)
    cmap = ListedColormap([LABEL_COLOURS[w] for w in LABELS])
    norm = BoundaryNorm(np.arange(-0.5, len(LABELS) + 0.5), cmap.N)
    present = set()
    drew_contours = False
    crossings = {}
    for ax, panel in zip(axes.flat, panels):
        lab = panel.label.transpose(y, x).values.astype(float)
        lab[lab < 0] = np.nan
        present |= set(int(v) for v in np.unique(lab[np.isfinite(lab)]))
        xs, ys = panel[x].values, panel[y].values
        ax.pcolormesh(xs, ys, lab, cmap=cmap, norm=norm, shading="nearest")
        ns = exact_polygon_field(panel, x, y) if contours else None
        if ns is not None:
            cs = ax.contour(xs, ys, ns, levels=list(EXACT_POLYGON_LEVELS), colors="k",
                            linewidths=1.0,
                            linestyles=[EXACT_POLYGON_DASH[lv] for lv in EXACT_POLYGON_LEVELS])
            ax.clabel(cs, fmt={3.0: "n=3", 4.0: "n=4"}, fontsize=8)
            drew_contours = True
            for lv, words in curve_crossings(ns, lab).items():
                crossings.setdefault(lv, set()).update(words)
        ax.set_xlabel(AXIS_TEXT.get(x, x))
        ax.set_ylabel(AXIS_TEXT.get(y, y))
        if facet:
            ax.set_title(axis_value_text(facet, float(panel[facet])), fontsize=10)
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    fixed = [axis_value_text(d, float(sel[d])) for d in ds.label.dims
             if d not in (x, y, facet) and d in sel.coords]
    fig.suptitle(ds.attrs.get("title", "regime map") + "\n" + ", ".join([ball_text(ds.attrs)]
                                                                         + fixed), fontsize=11)
    shapes = [Patch(facecolor=LABEL_COLOURS[w], label=w.replace("_", "-"))
              for i, w in enumerate(LABELS) if w in SHAPES and i in present]
    status = [Patch(facecolor=LABEL_COLOURS[w], edgecolor="k", hatch="//",
                    label=w.replace("_", " "))
              for i, w in enumerate(LABELS) if w not in SHAPES and i in present]
    handles = shapes + ([Patch(visible=False, label="status:")] + status if status else [])
    if drew_contours:
        from matplotlib.lines import Line2D

        for lv, text in ((3.0, "exact triangle (n=3)"), (4.0, "exact square (n=4)")):
            if lv in crossings:  # where the exact curve runs through another label's region
                words = sorted(crossings[lv], key=LABELS.index)
                text += "\n" + "\n".join(textwrap.wrap(crossing_text(lv, words), 30))
            handles.append(Line2D([], [], color="k", lw=1.0, ls=EXACT_POLYGON_DASH[lv],
                                  label=text))
    fig.legend(handles=handles, loc="outside right center", title="path shape", fontsize=9)
    return fig


# ----------------------------------------------------------------------------------------------
def path_diagnostics(ds: xr.Dataset, ball: Ball) -> dict:
    """Heading rate of the path (rad/s), friction ratio |F_h|/N and normal force N (N) along a
    `simulate` trajectory (its `friction_ratio` and `normal_force` variables where it has them)."""
    if "friction_ratio" in ds and "normal_force" in ds:
        fric, normal = ds.friction_ratio.values, ds.normal_force.values
    else:
        p, tu = ball.nondim_params(), ball.time_unit
        n = ds.sizes["time"]
        fric, normal = np.empty(n), np.empty(n)
        for k in range(n):
            u = np.array([ds.x.values[k] / ball.a, ds.y.values[k] / ball.a, ds.theta.values[k],
                          ds.chi.values[k], ds.phi.values[k], ds.thetadot.values[k] * tu,
                          ds.chidot.values[k] * tu, ds.phidot.values[k] * tu])
            fx, fy, nn, *_ = euler.contact(u, p)
            fric[k] = math.hypot(fx, fy) / nn if nn > 0 else np.inf
            normal[k] = nn * ball.M * ball.g
    vx = np.gradient(ds.x.values, ds.time.values)
    vy = np.gradient(ds.y.values, ds.time.values)
    heading = np.unwrap(np.arctan2(vy, vx))
    psid = np.gradient(heading, ds.time.values)
    return {"heading_rate": psid, "friction_ratio": fric, "normal_N": normal}


def corner_indices(ds: xr.Dataset, heading_rate: np.ndarray | None = None) -> np.ndarray:
    """The samples where theta is at a minimum: the corners, where the path turns (a launch with
    thetadot0 = 0 that starts at its lowest tilt starts on a corner, so sample 0 counts).
    `heading_rate` is not used (kept for callers that pass it)."""
    th = ds.theta.values
    mins = theta_maxima(-th)
    starts_low = len(th) > 2 and th[1] > th[0] and float(ds.thetadot.values[0]) == 0.0
    return np.concatenate([[0], mins]).astype(int) if starts_low else mins.astype(int)


def cycles_per_orbit(attrs: dict) -> float:
    """Theta cycles in one orbit (360 deg of net turn): p for a star {p/q}, 360/|turn per
    cycle| otherwise; NaN without a turn."""
    turn = attrs.get("turn_per_cycle_deg")
    if attrs.get("label") == "star" and _finite(attrs.get("star_points")):
        return float(attrs["star_points"])
    return 360.0 / abs(float(turn)) if _finite(turn) and float(turn) != 0 else math.nan


def is_steady(attrs: dict) -> bool:
    """A circle whose theta stays within the classifier's steady tolerance
    (`Thresholds.steady_theta_tol_deg`, 0.5 deg): it has no theta cycle to speak of, so no turn
    per cycle either."""
    from .classify.labels import Thresholds

    lo, hi = attrs.get("theta_min_deg"), attrs.get("theta_max_deg")
    return (attrs.get("label") == "circle" and _finite(lo) and _finite(hi)
            and float(hi) - float(lo) < Thresholds().steady_theta_tol_deg)


def orbit_window(attrs: dict, T: float, orbits: float = 3.0, max_cycles: int = 36) -> float:
    """A duration (s) that shows `orbits` orbits of a launch, an orbit being 360 deg of net turn:
    p theta cycles for a star {p/q}, 360/|turn per cycle| cycles otherwise; at most `max_cycles`
    cycles (a near-straight path turns little) and at most T. T when the launch has no theta
    period or no turn (a steady circle)."""
    period, per_orbit = attrs.get("theta_period_s"), cycles_per_orbit(attrs)
    if not (_finite(period) and float(period) > 0 and _finite(per_orbit)) or is_steady(attrs):
        return T
    cycles = min(orbits * per_orbit, max_cycles)
    return float(min(T, cycles * float(period)))


def envelope(t: np.ndarray, v: np.ndarray, bins: int = 2000) -> tuple[np.ndarray, np.ndarray]:
    """Decimate a dense series for drawing without losing its extremes: per bin of samples, the
    minimum and the maximum in time order (a line through them touches every peak)."""
    n = len(v)
    if n <= 2 * bins:
        return t, v
    edges = np.linspace(0, n, bins + 1).astype(int)
    ti, vi = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        i, j = a + int(np.argmin(v[a:b])), a + int(np.argmax(v[a:b]))
        for k in sorted({i, j}):
            ti.append(t[k])
            vi.append(v[k])
    return np.asarray(ti), np.asarray(vi)


def spin_about_axis(theta, chidot, phidot):
    """The ball's spin about its symmetry axis, omega_eta = phidot - chidot sin(theta) (rad/s;
    theta in rad): the component of the angular velocity along the axis. Unlike chidot and
    phidot, which grow large as the axis nears the vertical (the Euler angles are singular at
    theta = +-90 deg), it stays bounded: it is the physical spin."""
    return np.asarray(phidot) - np.asarray(chidot) * np.sin(np.asarray(theta))


def _dense_rates(ds: xr.Dataset, ball: Ball, max_samples: int = 1_000_001):
    """Time, the rates chidot, phidot and theta (rad) at every integration step of the launch
    `ds` was made from (the rate spikes near theta = 90 deg last a few ms: a coarse trajectory
    misses their tops); `ds` itself when it cannot be integrated again (no launch in its
    attributes) or is dense."""
    a = ds.attrs
    keys = ("theta0_deg", "thetadot0", "chidot0", "phidot0")
    t = ds.time.values
    dt = float(a.get("dt_s", 0) or 0)
    coarse = len(t) > 1 and dt > 0 and (t[1] - t[0]) > 1.5 * dt
    if coarse and all(k in a for k in keys) and a.get("method", "rk4") != "dopri5":
        from .simulate import simulate

        T = float(t[-1] - t[0])
        n_out = int(min(max_samples, round(T / dt) + 1))
        try:
            dense = simulate(*(float(a[k]) for k in keys), T=T, dt=dt,
                             chi0_deg=float(a.get("chi0_deg", 0.0)), ball=ball, n_out=n_out,
                             method=str(a.get("method", "rk4")))
            return (dense.time.values + t[0], dense.chidot.values, dense.phidot.values,
                    dense.theta.values)
        except (InputError, ValueError):
            pass
    return t, ds.chidot.values, ds.phidot.values, ds.theta.values


def plot_path(ds: xr.Dataset, out=None, ball: Ball | None = None, title: str | None = None,
              panels: str = "all", dpi: int = 100, show=()):
    """Draw one launch like the paper's figures.

    Left: the path of the centre of mass coloured by theta, its corners (theta minima) and its
    start marked, the shape in the title. Right: theta(t); chidot and phidot(t) at every
    integration step on a symmetric-log scale (linear within +-10 rad/s, so the ordinary motion
    and their spikes near theta = 90 deg both show), and the spin about the symmetry axis
    `spin_about_axis` (the spikes of chidot and phidot come from the Euler angles, singular at
    theta = +-90 deg, not from the ball, whose spin about its axis stays bounded); friction
    ratio |F_h|/N and normal force N(t). Written as PNG, PDF or SVG by the suffix of `out`.

    Parameters
    ----------
    ds : xarray.Dataset
        A trajectory from `ballsurvey.simulate` (or a time slice of one).
    out : str or path
        The file to write (.png, .pdf or .svg).
    ball : Ball, optional
        The ball the launch was integrated for (default: the paper's).
    title : str, optional
        The figure's title (default: the launch and the ball).
    panels : {"all", "path"}
        "path": only the path, in a small figure (the launch and ball above it).
    dpi : int
        Resolution of a PNG (dots per inch; the full figure is 11 x 7.5 in).
    show : sequence of str
        Body points drawn beside the centre of mass (`draw_body_points`: face, probe, contact;
        the paper's Fig. 4a).

    Returns
    -------
    The file written, or with `out` None the matplotlib Figure (shown by a notebook as it is).
    """
    fig = path_figure(ds, ball, title, panels, show)
    if out is None:
        return fig
    figure_format(out)
    return _save(fig, out, dpi=dpi)


def path_figure(ds: xr.Dataset, ball: Ball | None = None, title: str | None = None,
                panels: str = "all", show=()) -> Figure:
    """The figure `plot_path` writes (a matplotlib `Figure`, not yet saved)."""
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D
    from matplotlib.ticker import MaxNLocator

    ball = ball or Ball.paper()
    diag = path_diagnostics(ds, ball)
    t = ds.time.values
    x, y, th = ds.x.values, ds.y.values, np.degrees(ds.theta.values)
    if panels not in ("all", "path"):
        raise InputError(f"panels: 'all' or 'path', got {panels!r}")
    only_path = panels == "path"
    fig = Figure(figsize=(3.6, 4.3) if only_path else (11, 7.5), layout="constrained")
    gs = fig.add_gridspec(1, 1) if only_path else fig.add_gridspec(3, 2, width_ratios=[1.25, 1])
    ax = fig.add_subplot(gs[:, 0])
    pts = np.stack([x, y], 1)
    segs = np.stack([pts[:-1], pts[1:]], 1)
    if np.ptp(th) < STEADY_THETA_DEG:
        # theta (nearly) constant: one colour and its value, not a colour scale of its rounding
        # noise
        lc = LineCollection(segs, colors=[STEADY_COLOUR], linewidths=1.6,
                            label=rf"centre of mass ($\theta$ = {th.mean():.2f} deg throughout)")
        ax.add_collection(lc)
    else:
        lc = LineCollection(segs, cmap="viridis", linewidths=1.6,
                            label=r"centre of mass (colour: $\theta$)")
        lc.set_array(0.5 * (th[1:] + th[:-1]))
        ax.add_collection(lc)
        fig.colorbar(lc, ax=ax, label=r"$\theta$ (deg)", shrink=0.7,
                     location="bottom" if only_path else "right",
                     aspect=30 if only_path else 20, format="%g")
    # corners only where the classifier judged corners (polygons and stars)
    a = ds.attrs
    has_corners = a.get("label") in ("triangle", "square", "ngon", "star")
    ci = corner_indices(ds) if has_corners else np.zeros(0, dtype=int)
    if len(ci):
        ax.plot(x[ci], y[ci], "o", ms=6, mfc="none", mec=LINE_COLOURS["corner"], mew=1.4,
                label=r"corner ($\theta$ minimum)", zorder=3)
    ax.plot(x[0], y[0], "k^", ms=7, label="start", zorder=3)
    draw_body_points(ax, ds, show)
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    # few enough ticks that labels such as -0.075 never run into each other
    ax.xaxis.set_major_locator(MaxNLocator(nbins=4 if only_path else 6))
    ax.yaxis.set_major_locator(MaxNLocator(nbins=6 if only_path else 8))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(shape_text(a), fontsize=11)
    if only_path:
        ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.08), ncol=2, fontsize=7,
                  frameon=False, borderaxespad=0.0)
        fig.suptitle(title or launch_title(a), fontsize=7)
        return fig
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.08), ncol=2, fontsize=8, frameon=False)
    ax1 = fig.add_subplot(gs[0, 1])
    ax1.plot(t, th, "k", lw=1)
    if len(ci):
        ax1.plot(t[ci], th[ci], "o", ms=4, mfc="none", mec=LINE_COLOURS["corner"])
    ax1.set_ylabel(r"$\theta$ (deg)")
    ax2 = fig.add_subplot(gs[1, 1], sharex=ax1)
    td, chid, phid, thd = _dense_rates(ds, ball)
    ax2.plot(*envelope(td, phid), color=LINE_COLOURS["phidot"], lw=1.0, label=r"$\dot\phi$",
             zorder=2)
    ax2.plot(*envelope(td, chid), color=LINE_COLOURS["chidot"], lw=1.0, ls=(0, (4, 1.5)),
             label=r"$\dot\chi$", zorder=3)
    ax2.plot(*envelope(td, spin_about_axis(thd, chid, phid)), color=LINE_COLOURS["spin"], lw=1.2,
             label="spin about the axis\n" + r"$\omega_\eta = \dot\phi - \dot\chi\sin\theta$",
             zorder=4)
    ax2.set_yscale("symlog", linthresh=10.0, linscale=1.0)
    ax2.axhline(0.0, color="0.6", lw=0.5, zorder=1)
    ax2.set_ylabel("rate (rad/s)\nlinear to $\\pm$10, then log", fontsize=9)
    ax2.legend(loc="lower left", bbox_to_anchor=(1.0, 0.0), fontsize=8, frameon=False,
               borderaxespad=0.2)
    ax3 = fig.add_subplot(gs[2, 1], sharex=ax1)
    ax4 = ax3.twinx()
    # N dashed with open circles, |F_h|/N solid: told apart where they cross or lie on top
    normal_style = dict(color=LINE_COLOURS["normal"], lw=1.2, ls=(0, (4, 1.5)), marker="o",
                        ms=4, mfc="none", markevery=(0.05, 0.1))
    ax4.plot(t, diag["normal_N"], **normal_style)
    ax4.set_ylabel("N (N), dashed", color=LINE_COLOURS["normal"])
    ax3.plot(t, diag["friction_ratio"], color=LINE_COLOURS["friction"], lw=1)
    ax3.set_zorder(ax4.get_zorder() + 1)  # |F|/N in front of N
    ax3.patch.set_visible(False)
    ax3.set_ylabel(r"$|F_h|/N$, solid", color=LINE_COLOURS["friction"])
    ax3.set_xlabel("t (s)")
    # a constant one is named with its value, and the two constants are drawn apart (|F_h|/N at
    # a third of the panel's height, N at two thirds) instead of on top of each other
    ratio_text, normal_text = r"$|F_h|/N$", "N"
    if _constant(diag["friction_ratio"]):
        ratio_text += f" = {np.nanmean(diag['friction_ratio']):.4g} throughout"
    if _constant(diag["normal_N"]):
        normal_text += f" = {np.nanmean(diag['normal_N']):.4g} N throughout"
    ax3.legend(handles=[Line2D([], [], color=LINE_COLOURS["friction"], lw=1, label=ratio_text),
                        Line2D([], [], label=normal_text, **{**normal_style, "markevery": None})],
               loc="lower left", bbox_to_anchor=(1.12, 0.0), fontsize=8, frameon=False)
    for axis, values, floor, at in ((ax1, th, 0.5, 0.5), (ax3, diag["friction_ratio"], None, 1 / 3),
                                    (ax4, diag["normal_N"], None, 2 / 3)):
        _no_noise_scale(axis, values, floor, at)
    fig.suptitle(title or launch_title(a), fontsize=11)
    return fig


def _constant(values, rel: float = 1e-3) -> bool:
    """Whether a panel's quantity is constant to `rel` of its size (a steady launch)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return v.size > 0 and float(np.ptp(v)) <= rel * max(float(np.abs(v).max()), 1e-300)


def _no_noise_scale(ax, values, half_span=None, at: float = 0.5) -> None:
    """A panel of a quantity that hardly changes (a steady launch) drawn on a sensible scale:
    plain tick labels (no offset like 1e-5+2.4e1) and a span of 2 half_span (default: 5 % of the
    value) with its mean at the fraction `at` of the height, so rounding noise is not blown up
    into a band (and two such quantities on twin axes can be drawn apart)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return
    mid = float(v.mean())
    h = half_span if half_span is not None else 0.05 * max(abs(mid), 1e-12)
    if np.ptp(v) < h:
        ax.set_ylim(mid - 2 * h * at, mid + 2 * h * (1 - at))
    ax.ticklabel_format(axis="y", useOffset=False, style="plain")


def launch_title(attrs: dict) -> str:
    """A path figure's title: the launch in the symbols of the axes, its duration, the ball."""
    parts = [axis_value_text(k, float(attrs[k])) for k in ("theta0_deg", "thetadot0",
                                                              "chidot0", "phidot0")
             if _finite(attrs.get(k))]
    if _finite(attrs.get("chi0_deg")) and float(attrs["chi0_deg"]) != 0.0:
        parts.append(axis_value_text("chi0_deg", float(attrs["chi0_deg"])))
    ball = ball_text(attrs)
    if _finite(attrs.get("rolling_resistance")) and float(attrs["rolling_resistance"]) > 0.0:
        ball += f", rolling resistance mu_r = {float(attrs['rolling_resistance']):.3g}"
    return ", ".join(parts) + "\n" + ball


# ----------------------------------------------------------------------------------------------
#: body points `path --show` draws: name -> (x, y variables of `simulate`, colour, legend)
BODY_POINTS = {"face": ("x_face", "y_face", "tab:blue", "centre of the flat face"),
               "probe": ("x_tip", "y_tip", "black", "tip of the probe"),
               "contact": ("x_contact", "y_contact", "tab:gray", "contact point")}


def draw_body_points(ax, ds: xr.Dataset, show=()) -> None:
    """Paths of body points of a `simulate` Dataset on the plane's axes (Fig. 4a: centre of
    mass, centre of the flat face, tip of the probe); show: names of BODY_POINTS."""
    for name in show:
        if name not in BODY_POINTS:
            raise InputError(f"show: unknown body point {name!r}; known: "
                             f"{', '.join(BODY_POINTS)}")
        xv, yv, colour, text = BODY_POINTS[name]
        ax.plot(ds[xv].values, ds[yv].values, color=colour, lw=0.8, label=text, zorder=1)


def plot_forces(ds: xr.Dataset, out=None, t_range=None, title: str | None = None) -> Figure:
    """The net force (N; friction Fx, Fy and the vertical Fz = N - M g) and the torque about G
    (N m) against time, the paper's Figs. 4b, 7b and 10, from a `simulate` Dataset; t_range:
    (start, stop) in s. Returns the Figure; writes it to `out` when given."""
    if t_range is not None:
        ds = ds.sel(time=slice(*t_range))
    t = ds.time.values
    fig = Figure(figsize=(8, 5.5), layout="constrained")
    axf, axt = fig.subplots(2, 1, sharex=True)
    for k, colour in (("Fx", "tab:blue"), ("Fy", "tab:orange"), ("Fz", "tab:green")):
        axf.plot(t, ds[k].values, color=colour, lw=1.2, label=k.replace("F", "F_"))
    axf.set_ylabel("net force (N)")
    for k, colour in (("tau_x", "tab:blue"), ("tau_y", "tab:orange"), ("tau_z", "tab:green")):
        axt.plot(t, ds[k].values, color=colour, lw=1.2, label=k)
    axt.set_ylabel("torque about G (N m)")
    axt.set_xlabel("t (s)")
    for ax in (axf, axt):
        ax.axhline(0.0, color="0.7", lw=0.6, zorder=0)
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False)
    if title:
        fig.suptitle(title, fontsize=11)
    if out is not None:
        fig.savefig(out, dpi=110)
    return fig

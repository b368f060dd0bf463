"""Plots: regime maps of a stored sweep, and single paths drawn like the paper's figures.

Figures are made with matplotlib's object API (`matplotlib.figure.Figure`) and written to files:
importing this module changes no global matplotlib state (no backend is chosen), so it is safe in
notebooks; `plot_map` and `plot_path` return the file written.
"""
from __future__ import annotations

import math

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

#: one colour per label word: shapes in saturated colours, statuses in greys / muted tones
LABEL_COLOURS = {
    "circle": "#4477aa", "near_straight": "#66ccee", "triangle": "#228833", "square": "#ee6677",
    "ngon": "#ccbb44", "star": "#aa3377", "rosette": "#44aa99",
    "unresolved": "#dddddd", "blew_up": "#000000", "singular": "#555555", "flat_face": "#997755",
    "lift_off": "#bbbbbb", "slipping": "#888888", "inaccurate": "#ee7733",
}
AXIS_TEXT = {k: ax.plot_label for k, ax in AXES.items()}


def axis_value_text(axis: str, value: float) -> str:
    """'phidot0 = -3 rad/s', 'theta0 = 5 deg'."""
    name = axis[:-4] if axis.endswith("_deg") else axis
    unit = AXES[axis].text_units if axis in AXES else ""
    return f"{name} = {value:g} {unit}".rstrip()


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


def default_axes(ds: xr.Dataset, exclude=()) -> tuple[str, str]:
    """The two longest axes of a grid (not those in `exclude`), the first drawn across."""
    dims = sorted((d for d in ds.label.dims if d not in exclude), key=lambda d: -ds.sizes[d])
    if len(dims) < 2 or ds.sizes[dims[1]] < 2:
        besides = f" besides the facet axis {', '.join(exclude)}" if exclude else ""
        raise InputError(f"a regime map needs two axes with more than one value{besides}")
    return dims[1], dims[0]


def plot_map(ds: xr.Dataset, out=None, x: str | None = None, y: str | None = None,
             at: dict | None = None, facet: str | None = None, contours: bool = True):
    """Categorical map of `label` over axes x (across) and y (up); facets along `facet`.

    Returns the file written to `out`, or with out None the matplotlib Figure (shown by a
    notebook as it is)."""
    if "label" not in ds:
        raise InputError("the file has no 'label' variable (not a ballsurvey map?)")
    if "launch" in ds.dims:
        raise InputError("this file holds named points, not a grid: use 'query' to list them")
    if facet is not None and facet in (x, y):
        raise InputError(f"--facet {facet} is also the axis drawn "
                         f"{'across (--x)' if facet == x else 'up (--y)'}: facet by another axis")
    if x is None or y is None:  # the longest axes left after the facet and the axis given
        dx, dy = default_axes(ds, exclude={facet} if facet else ())
        x = x or (dx if dx != y else dy)
        y = y or (dy if dy != x else dx)
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
    for ax, panel in zip(axes.flat, panels):
        lab = panel.label.transpose(y, x).values.astype(float)
        lab[lab < 0] = np.nan
        present |= set(int(v) for v in np.unique(lab[np.isfinite(lab)]))
        xs, ys = panel[x].values, panel[y].values
        ax.pcolormesh(xs, ys, lab, cmap=cmap, norm=norm, shading="nearest")
        if contours and "n_sides" in panel and min(len(xs), len(ys)) >= 3:
            ns = panel.n_sides.transpose(y, x).values
            poly = np.isin(panel.label.transpose(y, x).values, [LABELS.index("triangle"),
                                                                 LABELS.index("square")])
            ns = np.where(np.isfinite(ns) & (ns < 6), ns, np.nan)
            if np.isfinite(ns).sum() >= 4 and poly.any():
                cs = ax.contour(xs, ys, ns, levels=[3.0, 4.0], colors="k", linewidths=1.0)
                ax.clabel(cs, fmt={3.0: "n=3", 4.0: "n=4"}, fontsize=8)
                drew_contours = True
        ax.set_xlabel(AXIS_TEXT.get(x, x))
        ax.set_ylabel(AXIS_TEXT.get(y, y))
        if facet:
            ax.set_title(axis_value_text(facet, float(panel[facet])), fontsize=10)
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    fixed = [axis_value_text(d, float(sel[d])) for d in ds.label.dims
             if d not in (x, y, facet) and d in sel.coords]
    fig.suptitle(ds.attrs.get("title", "regime map") + ("\n" + ", ".join(fixed) if fixed else ""),
                 fontsize=11)
    shapes = [Patch(facecolor=LABEL_COLOURS[w], label=w.replace("_", "-"))
              for i, w in enumerate(LABELS) if w in SHAPES and i in present]
    status = [Patch(facecolor=LABEL_COLOURS[w], edgecolor="k", hatch="//",
                    label=w.replace("_", " "))
              for i, w in enumerate(LABELS) if w not in SHAPES and i in present]
    handles = shapes + ([Patch(visible=False, label="status:")] + status if status else [])
    if drew_contours:
        from matplotlib.lines import Line2D

        handles.append(Line2D([], [], color="k", lw=1.0,
                              label="exact triangle (n=3)\nand square (n=4)"))
    fig.legend(handles=handles, loc="outside right center", title="path shape", fontsize=9)
    if out is None:  # a notebook: the Figure itself
        return fig
    fig.savefig(out, dpi=110)
    return out


# ----------------------------------------------------------------------------------------------
def path_diagnostics(ds: xr.Dataset, ball: Ball) -> dict:
    """Heading rate of the path, friction ratio and normal force along a `simulate` trajectory."""
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


def corner_indices(ds: xr.Dataset, heading_rate: np.ndarray) -> np.ndarray:
    """Per theta cycle (between successive theta maxima), the sample of peak |heading rate|."""
    mx = theta_maxima(ds.theta.values)
    return np.array([a + int(np.argmax(np.abs(heading_rate[a:b]))) for a, b in zip(mx, mx[1:])
                     if b > a + 1], dtype=int)


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


def _dense_rates(ds: xr.Dataset, ball: Ball, max_samples: int = 1_000_001):
    """Time and the rates chidot, phidot at every integration step of the launch `ds` was made
    from (spin spikes near theta = 90 deg last a few ms: a coarse trajectory misses their tops);
    `ds` itself when it cannot be integrated again (no launch in its attributes) or is dense."""
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
            return dense.time.values + t[0], dense.chidot.values, dense.phidot.values
        except (InputError, ValueError):
            pass
    return t, ds.chidot.values, ds.phidot.values


def plot_path(ds: xr.Dataset, out=None, ball: Ball | None = None, title: str | None = None,
              show=()):
    """One launch like the paper's figures: path coloured by theta with corners marked and the
    label in the title; theta(t); chidot and phidot (t) at every integration step, drawn through
    their extremes so the spin spikes near theta = 90 deg keep their height; friction ratio and
    normal force (t). Legends sit outside the data; no line hides another. show: body points
    drawn beside the centre of mass (`draw_body_points`: face, probe, contact). Returns the
    file written to `out`, or with out None the matplotlib Figure (for a notebook)."""
    from matplotlib.collections import LineCollection

    ball = ball or Ball.paper()
    diag = path_diagnostics(ds, ball)
    t = ds.time.values
    x, y, th = ds.x.values, ds.y.values, np.degrees(ds.theta.values)
    fig = Figure(figsize=(11, 7.5), layout="constrained")
    gs = fig.add_gridspec(3, 2, width_ratios=[1.25, 1])
    ax = fig.add_subplot(gs[:, 0])
    pts = np.stack([x, y], 1)
    segs = np.stack([pts[:-1], pts[1:]], 1)
    lc = LineCollection(segs, cmap="viridis", linewidths=1.6)
    lc.set_array(0.5 * (th[1:] + th[:-1]))
    ax.add_collection(lc)
    fig.colorbar(lc, ax=ax, label=r"$\theta$ (deg)", shrink=0.7)
    ci = corner_indices(ds, diag["heading_rate"])
    if len(ci):
        ax.plot(x[ci], y[ci], "o", ms=5, mfc="none", mec="crimson", label="corners", zorder=3)
    ax.plot(x[0], y[0], "k^", ms=7, label="start", zorder=3)
    draw_body_points(ax, ds, show)
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    a = ds.attrs
    label = a.get("label", "?")
    extra = f", n = {a['n_sides']:.3f}" if isinstance(a.get("n_sides"), float) and \
        math.isfinite(a["n_sides"]) else ""
    ax.set_title(f"{label}{extra}, corners {a.get('corner_kind', '?')}", fontsize=11)
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.08), ncol=2, fontsize=8, frameon=False)
    ax1 = fig.add_subplot(gs[0, 1])
    ax1.plot(t, th, "k", lw=1)
    ax1.set_ylabel(r"$\theta$ (deg)")
    ax2 = fig.add_subplot(gs[1, 1], sharex=ax1)
    td, chid, phid = _dense_rates(ds, ball)
    ax2.plot(*envelope(td, phid), color="tab:orange", lw=2.2, alpha=0.75, label=r"$\dot\phi$",
             zorder=2)
    ax2.plot(*envelope(td, chid), color="tab:blue", lw=0.9, label=r"$\dot\chi$", zorder=3)
    ax2.set_ylabel("rate (rad/s)")
    ax2.legend(loc="lower left", bbox_to_anchor=(1.0, 0.0), fontsize=8, frameon=False,
               borderaxespad=0.2)
    ax3 = fig.add_subplot(gs[2, 1], sharex=ax1)
    ax4 = ax3.twinx()
    ax4.plot(t, diag["normal_N"], color="tab:blue", lw=1.8, alpha=0.6)
    ax4.set_ylabel("N (N)", color="tab:blue")
    ax3.plot(t, diag["friction_ratio"], color="tab:red", lw=1)
    ax3.set_zorder(ax4.get_zorder() + 1)  # |F|/N in front of N
    ax3.patch.set_visible(False)
    ax3.set_ylabel(r"$|F_h|/N$", color="tab:red")
    ax3.set_xlabel("t (s)")
    fig.suptitle(title or (rf"$\theta_0$ = {a.get('theta0_deg')} deg, $\dot\theta_0$ = "
                           rf"{a.get('thetadot0')}, $\dot\chi_0$ = {a.get('chidot0')}, "
                           rf"$\dot\phi_0$ = {a.get('phidot0'):.4g} rad/s, T = {a.get('T_s')} s"),
                 fontsize=11)
    if out is None:  # a notebook: the Figure itself
        return fig
    fig.savefig(out, dpi=110)
    return out


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

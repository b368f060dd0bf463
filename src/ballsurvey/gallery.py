"""Gallery: sample paths behind each label of a stored map, integrated again, to check labels by
eye.

For every label found in a map, up to K launches are drawn at random (seeded), integrated again
from their stored launch conditions with the map's ball and duration, and drawn in small panels
titled with the launch, the label and the fields it was decided on (n_sides, turn per cycle,
roundness, corner kind). The panel shows about one orbit (360 deg of net turn) or the whole run.
"""
from __future__ import annotations

import math

import numpy as np
import xarray as xr

from .axes import LAUNCH_AXES
from .ball import Ball
from .classify.labels import CORNER_KINDS, LABELS
from .store import decode_label, launches

LAUNCH_KEYS = LAUNCH_AXES + ("chi0_deg",)
BALL_KEYS = ("a", "c", "M", "A", "B", "g", "cut_height")  #: a map's ball_* attributes


def map_ball(ds: xr.Dataset) -> Ball:
    """The ball a map was computed with (its global attributes)."""
    kw = {k: float(ds.attrs[f"ball_{k}"]) for k in BALL_KEYS if f"ball_{k}" in ds.attrs}
    return Ball(**kw) if kw else Ball.paper()


def sample_launches(ds: xr.Dataset, per_label: int = 4, seed: int = 0,
                    labels=None) -> list[dict]:
    """Up to `per_label` launches per label word present in the map (or in `labels`), seeded.

    Each row: the launch conditions (SI, deg where named), the stored label and fields."""
    if "label" not in ds:
        raise ValueError("the file has no 'label' variable (not a ballsurvey map?)")
    if per_label < 1:
        raise ValueError(f"--per-label must be >= 1, got {per_label}")
    flat = launches(ds)
    words = decode_label(flat.label.values)
    rng = np.random.default_rng(seed)
    rows = []
    for word in (labels or LABELS):
        idx = np.flatnonzero(words == word)
        if idx.size == 0:
            continue
        for i in np.sort(rng.choice(idx, size=min(per_label, idx.size), replace=False)):
            row = {"label": word}
            for k in LAUNCH_KEYS + BALL_KEYS:
                if k in flat.coords:
                    row[k] = float(np.broadcast_to(flat[k].values, words.shape)[i])
            for k in ("n_sides", "turn_per_cycle_deg", "roundness", "theta_period_s",
                      "theta_max_deg"):
                if k in flat:
                    row[k] = float(flat[k].values[i])
            if "corner_kind" in flat:
                row["corner_kind"] = CORNER_KINDS[int(flat.corner_kind.values[i])]
            rows.append(row)
    return rows


def draw_gallery(ds: xr.Dataset, out, per_label: int = 4, seed: int = 0, T: float | None = None,
                 dt: float | None = None, labels=None, ball: Ball | None = None) -> list[dict]:
    """Draw the gallery PNG; returns the sampled rows with the label of the re-integration
    (`label_again`). T, dt: duration and step (s) of each integration, by default the map's;
    ball: the ball integrated (default: the map's own, `map_ball`)."""
    from matplotlib.figure import Figure

    from .simulate import simulate

    rows = sample_launches(ds, per_label, seed, labels)
    if not rows:
        raise ValueError("the map has no labelled launches")
    base = ball or map_ball(ds)
    T_run = float(T if T is not None else ds.attrs.get("run_T_s", 20.0))
    dt = float(dt if dt is not None else ds.attrs.get("run_dt_s", 1e-4))
    words = list(dict.fromkeys(r["label"] for r in rows))
    ncol = max(sum(r["label"] == w for r in rows) for w in words)
    fig = Figure(figsize=(2.6 * ncol, 2.9 * len(words)), layout="constrained")
    axes = fig.subplots(len(words), ncol, squeeze=False)
    for ax in axes.ravel():
        ax.set_axis_off()
    col = {w: 0 for w in words}
    for r in rows:
        ball_kw = {k: r[k] for k in BALL_KEYS if k in r}
        ball = Ball(**{**base.as_dict(), **ball_kw}) if ball_kw else base
        launch = {k: r[k] for k in LAUNCH_KEYS if k in r}
        sim = simulate(**launch, T=T_run, dt=dt, ball=ball, n_out=4001)
        r["label_again"] = sim.attrs["label"]
        x, y, t = sim.x.values, sim.y.values, sim.time.values
        turn, period = sim.attrs.get("turn_per_cycle_deg"), sim.attrs.get("theta_period_s")
        if turn and period and math.isfinite(turn) and math.isfinite(period) and abs(turn) > 1e-3:
            cycles = 360.0 / abs(turn)  # one orbit; a star {p/q} closes after p cycles
            if sim.attrs.get("star_points", 0) > 0:
                cycles = sim.attrs["star_points"]
            t_show = min(T_run, 1.15 * period * cycles)
            t_show = max(t_show, min(T_run, 3 * period))
            keep = t <= t_show
            x, y = x[keep], y[keep]
        ax = axes[words.index(r["label"]), col[r["label"]]]
        col[r["label"]] += 1
        ax.set_axis_on()
        ax.plot(x * 100, y * 100, lw=0.7)
        ax.plot(x[:1] * 100, y[:1] * 100, "o", ms=3, color="k")
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=6)
        again = "" if r["label_again"] == r["label"] else f" (again: {r['label_again']})"
        ax.set_title(
            f"{r['label']}{again}\n"
            f"θ0={r.get('theta0_deg', 0):.4g}° θ̇0={r.get('thetadot0', 0):.3g} "
            f"χ̇0={r.get('chidot0', 0):.4g} φ̇0={r.get('phidot0', 0):.4g}\n"
            f"n={r.get('n_sides', math.nan):.3f} turn={r.get('turn_per_cycle_deg', math.nan):.1f}° "
            f"round={r.get('roundness', math.nan):.3f} {r.get('corner_kind', '')}",
            fontsize=6.5)
    fig.suptitle(f"{ds.attrs.get('title', 'map')}: sample paths per label, integrated again for "
                 f"{T_run:g} s (x, y in cm; dot: start; rates in rad/s)", fontsize=9)
    fig.savefig(out, dpi=110)
    return rows

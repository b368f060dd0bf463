"""Gallery: sample paths behind each label of a stored map, integrated again, to check labels by
eye.

For every label found in a map, up to K launches are drawn at random (seeded) and integrated again
from their stored launch conditions with the map's own settings, read from its attributes: the ball
(`ball_*`), duration, method, step, tolerances, observer spacing, period mode (`run_*`) and
classifier thresholds (`classify_*`, the spec's [classify] table). The label of that run is the
map's own label computed again (`label_again`), so a panel says "again: ..." only where the map
and a fresh run of its own settings disagree. Each panel draws the whole run (T seconds of the
path, every orbit of it, so a path that does not close shows its precession), titled with the
launch, the label and the fields it was decided on (n_sides, turn per cycle, roundness, corner
kind).
"""
from __future__ import annotations

import math

import numpy as np
import xarray as xr

from .axes import LAUNCH_AXES
from .ball import Ball
from .classify.labels import CORNER_KINDS, LABELS
from .compose import METHODS, survey
from .integrate.tableaus import FIXED_STEP
from .limits import replay_steps, step_count, steps
from .store import decode_label, launches

LAUNCH_KEYS = LAUNCH_AXES + ("chi0_deg",)
BALL_KEYS = ("a", "c", "M", "A", "B", "g", "cut_height")  #: a map's ball_* attributes
#: most samples drawn per panel (a fixed-step path is sampled on a divisor of its step count)
MAX_DRAWN = 20001


def _checked(ds: xr.Dataset):
    """The map's settings by a spec's rules (`sweep.spec.map_settings`; InputError)."""
    from .sweep.spec import map_settings as checked

    return checked(ds.attrs, str(ds.encoding.get("source", "map")))


def map_ball(ds: xr.Dataset) -> Ball:
    """The ball a map was computed with (its global attributes)."""
    return _checked(ds).ball


def map_settings(ds: xr.Dataset) -> dict:
    """The run and classifier settings a map was made with, from its `run_*` and `classify_*`
    attributes (defaults of a spec where a map lacks one): T (s), dt (s, as asked), method, rtol,
    atol, observe_every, cycles (period mode; 0: the whole T) and `thresholds`."""
    m = _checked(ds)
    return {"T": m.T, "dt": m.dt_requested, "method": m.method, "rtol": m.rtol, "atol": m.atol,
            "observe_every": m.observe_every, "cycles": m.cycles if m.mode == "period" else 0,
            "thresholds": m.thresholds}


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
                row["corner_kind"] = str(decode_label(flat.corner_kind.values[i], CORNER_KINDS))
            rows.append(row)
    return rows


def _label_again(rows: list[dict], base: Ball, s: dict) -> list[str]:
    """The rows' labels from a fresh run with the map's settings (one batch, as a sweep runs)."""
    n = len(rows)
    table = {k: np.array([r.get(k, 0.0) for r in rows], dtype=float) for k in LAUNCH_KEYS}
    for k, v in base.as_dict().items():
        table[k] = np.array([r.get(k, v) for r in rows], dtype=float)
    f = survey(table, T=s["T"], dt=s["dt"], method=s["method"], rtol=s["rtol"], atol=s["atol"],
               observe_every=s["observe_every"], cycles=s["cycles"], thresholds=s["thresholds"],
               parallel=n > 1)
    return [LABELS[int(c)] for c in f["label"]]


def _drawn_samples(T: float, dt: float, fixed: bool) -> int:
    """Samples of a drawn path: for a fixed step, n_out - 1 divides the map's step count (so the
    drawing keeps the map's step); otherwise (or with no such divisor) 4001 or more."""
    if not fixed:
        return MAX_DRAWN
    steps = step_count(T, dt)
    for stride in range(max(1, math.ceil(steps / (MAX_DRAWN - 1))), steps + 1):
        if steps % stride == 0:
            if steps // stride >= 2000:
                return steps // stride + 1
            break
    return 4001


def _orbit_s(attrs: dict) -> float:
    """Duration (s) of one orbit of a drawn path: 360 deg of net turn (a star {p/q}: p cycles),
    at least two theta cycles; inf where the run has no turn per cycle."""
    turn, period = attrs.get("turn_per_cycle_deg"), attrs.get("theta_period_s")
    if not (turn and period and math.isfinite(turn) and math.isfinite(period)) or abs(turn) < 1e-3:
        return math.inf
    cycles = attrs["star_points"] if attrs.get("star_points", 0) > 0 else 360.0 / abs(turn)
    return period * max(cycles, 2.0)


def draw_gallery(ds: xr.Dataset, out, per_label: int = 4, seed: int = 0, T: float | None = None,
                 dt: float | None = None, labels=None, ball: Ball | None = None) -> list[dict]:
    """Draw the gallery PNG; returns the sampled rows with the label of the re-integration
    (`label_again`, with the map's own settings: `map_settings`) and the duration drawn
    (`drawn_s`, s). T, dt: duration and step (s) of
    each integration, by default the map's. Each panel draws the whole T; a map made with a method
    `simulate` does not offer (dop853, the lanes' pair) is drawn with dopri5 at the map's
    tolerances, its label still computed with the map's method.
    ball: the ball integrated (default: the map's own, `map_ball`)."""
    from matplotlib.figure import Figure

    from .simulate import simulate

    s = map_settings(ds)
    if T is not None:
        s["T"] = float(T)
    if dt is not None:
        s["dt"] = float(dt)
    steps(s["T"], s["dt"], "--T", "dt")
    replay_steps(s["T"], s["dt"], s["method"] in FIXED_STEP, "the map's step (attribute "
                 "run_dt_s_requested)", "gallery integrates launches again")
    rows = sample_launches(ds, per_label, seed, labels)
    if not rows:
        raise ValueError("the map has no labelled launches")
    base = ball or map_ball(ds)
    for r, again in zip(rows, _label_again(rows, base, s)):
        r["label_again"] = again
    draw_method = s["method"] if s["method"] in METHODS else "dopri5"
    n_out = _drawn_samples(s["T"], s["dt"], draw_method not in ("dopri5", "adaptive"))
    words = list(dict.fromkeys(r["label"] for r in rows))
    ncol = max(sum(r["label"] == w for r in rows) for w in words)
    fig = Figure(figsize=(max(2.6 * ncol, 7.0), 2.9 * len(words) + 0.3), layout="constrained")
    axes = fig.subplots(len(words), ncol, squeeze=False)
    for ax in axes.ravel():
        ax.set_axis_off()
    col = {w: 0 for w in words}
    for r in rows:
        ball_kw = {k: r[k] for k in BALL_KEYS if k in r}
        ball = Ball(**{**base.as_dict(), **ball_kw}) if ball_kw else base
        launch = {k: r[k] for k in LAUNCH_KEYS if k in r}
        sim = simulate(**launch, T=s["T"], dt=s["dt"], ball=ball, n_out=n_out,
                       method=draw_method, rtol=s["rtol"], atol=s["atol"],
                       thresholds=s["thresholds"])
        x, y = sim.x.values, sim.y.values
        r["drawn_s"] = float(sim.time.values[-1])
        one = sim.time.values <= _orbit_s(sim.attrs)
        ax = axes[words.index(r["label"]), col[r["label"]]]
        col[r["label"]] += 1
        ax.set_axis_on()
        ax.plot(x * 100, y * 100, lw=0.4, color="0.7")
        ax.plot(x[one] * 100, y[one] * 100, lw=0.7, color="C0")
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
    if s["method"] in ("dopri5", "adaptive"):
        how = f"{s['method']}, rtol {s['rtol']:g}, atol {s['atol']:g}"
    elif s["method"] in METHODS:
        how = f"{s['method']}, dt {s['dt']:g} s"
    else:  # the lanes' pair: tolerances; the observer reads each step
        how = (f"{s['method']}, rtol {s['rtol']:g}, observed on each step; drawn with "
               f"{draw_method}")
    if s["cycles"]:
        how += f"; labels after {s['cycles']} theta cycles"
    fig.suptitle(f"{ds.attrs.get('title', 'map')}: sample paths per label, labelled again with "
                 f"the map's settings\n({how}, its [classify] thresholds)\ngrey: the whole "
                 f"{s['T']:g} s; blue: the first orbit (x, y in cm; dot: start; rates in rad/s)",
                 fontsize=8)
    fig.savefig(out, dpi=110)
    return rows

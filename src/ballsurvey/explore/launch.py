"""One launch of a map: how the map was run (what a click integrates with), its launch values
and stored fields, the launch integrated again, its path as CSV and as a spec's `[[points]]`
entry; axis names and values as text.

Units: angles in degrees, rates in rad/s, lengths in m, times in s.
"""
from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass

import numpy as np
import xarray as xr

from ..axes import AXES
from ..ball import Ball
from ..classify.labels import CORNER_KINDS, LABELS, Thresholds
from ..compose import METHODS
from ..gallery import BALL_KEYS, LAUNCH_KEYS
from ..integrate.outcome import FORMULATIONS
from ..integrate.tableaus import FIXED_STEP
from ..limits import InputError, replay_steps, step_count

#: samples kept along a clicked launch's path (about; fixed steps take a divisor of the steps)
PATH_SAMPLES = 4000


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
    from ..sweep.spec import map_settings

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
    from ..api import open_map

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
    from ..simulate import simulate

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

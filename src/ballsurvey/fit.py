"""Launch conditions fitted to a measured track (the paper's Sec. VI: a filmed ball reproduced by
guessing its launch).

A track is a table of times t (s) with the centre of mass x, y (m), or the probe's tip and base
x_tip, y_tip, x_base, y_base (m, a probe of known length), and optionally the tilt theta_deg (deg)
and the precession rate chidot (rad/s), as the paper read them off its probe. `fit_track` finds
the launch at the first sample (theta0_deg, thetadot0, chidot0, phidot0, chi0_deg, x0, y0) whose
integrated motion best reproduces it:

1. a global start: a survey of the launch box (theta0, thetadot0, chidot0 on a grid; phidot0 from
   the track's initial speed, both signs) on the ensemble kernel over the first seconds, each
   launch integrated once with chi0 = 0 at the origin and then turned and moved onto the track
   in closed form (the motion is the same under a turn about the vertical and a shift);
2. a local refinement by scipy's least_squares (trust-region reflective, Jacobian by forward
   differences, all its launches in one kernel call): the best N_STARTS survey launches a few
   iterations over the first START_T seconds (where a launch a grid step off still keeps the
   track's phase), then the best N_CARRIED of those over a window doubled until it holds the
   whole track;
3. uncertainties from the Jacobian at the optimum: covariance s^2 (J^T J)^-1, s^2 the residual
   variance per degree of freedom.

Residuals are weighted by nominal measurement errors (POSITION_SIGMA_M, THETA_SIGMA_DEG,
CHIDOT_SIGMA) so channels of different units can be mixed; the uncertainties rescale by the
residual itself, so they do not depend on those nominal values when one channel is used.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import limits
from .ball import Ball
from .compose import run_tracks, run_trajectory
from .integrate.outcome import OK
from .physics.fast import S_CHD, S_CHI, S_TH, S_X, S_Y
from .simulate import body_points, simulate
from .units import StepPlan, launch_state

#: the launch the fit returns, in order, with units
PARAMS = ("theta0_deg", "thetadot0", "chidot0", "phidot0", "chi0_deg", "x0", "y0")
UNITS = {"theta0_deg": "deg", "thetadot0": "rad/s", "chidot0": "rad/s", "phidot0": "rad/s",
         "chi0_deg": "deg", "x0": "m", "y0": "m"}
#: nominal measurement errors that weight the residual channels
POSITION_SIGMA_M = 1e-4
THETA_SIGMA_DEG = 0.1
CHIDOT_SIGMA = 0.05
#: the launch box of the global survey: theta0 (deg), thetadot0, chidot0 (rad/s)
BOX = {"theta0_deg": (-30.0, 89.0), "thetadot0": (-4.0, 4.0), "chidot0": (-30.0, 30.0)}
#: tilts (deg) the survey adds near the vertical, where paths change fast with theta0
NEAR_VERTICAL = (87.0, 88.0, 89.5, 89.9)
#: grid of the survey inside the box
GRID = {"theta0_deg": 31, "thetadot0": 9, "chidot0": 61}
#: the survey's window (s), step (s) and sample spacing (s)
SURVEY_T = 1.5
SURVEY_DT = 1e-3
SURVEY_EVERY = 0.01
#: share of the survey window a launch must stay on the Euler chart to be judged
SURVEY_VALID = 1.0
#: the refinement's RK4 step (s): the model is sampled every step and interpolated to the track
FIT_DT = 5e-4
#: survey launches refined over the first START_T seconds, and how many of them are carried
#: on to the whole track
N_STARTS = 24
START_T = 0.5
N_CARRIED = 3
#: track checks: fewest samples, shortest duration (s), largest sample interval (s), largest
#: speed (m/s), largest extent (m): beyond them the track is not a rolling ball in s and m
MIN_SAMPLES = 20
#: most samples a track may have (600 s at 300 per second is 180 000)
MAX_SAMPLES = 200_000
MIN_DURATION_S = 0.2
MAX_INTERVAL_S = 0.1
MAX_SPEED = 5.0
MAX_EXTENT_M = 20.0
#: the largest |theta_deg| a track may hold (deg): 90 and its measurement noise
MAX_THETA_DEG = 95.0
#: the longest track (s)
MAX_DURATION_S = 600.0
#: duration (s) of the run that labels the fitted launch (or the track's, if longer)
LABEL_T = 20.0


@dataclass
class Track:
    """A measured track; t in s from the first sample (t_start: its time in the file, s).
    Arrays are None where the file has no such column."""

    t: np.ndarray
    t_start: float = 0.0
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    theta_deg: np.ndarray | None = None
    chidot: np.ndarray | None = None
    x_tip: np.ndarray | None = None
    y_tip: np.ndarray | None = None
    x_base: np.ndarray | None = None
    y_base: np.ndarray | None = None
    probe_m: float | None = None
    source: str = "track"

    @property
    def probe(self) -> bool:
        return self.x_tip is not None


PROBE_COLUMNS = ("x_tip", "y_tip", "x_base", "y_base")


def make_track(t, x=None, y=None, *, theta_deg=None, chidot=None, x_tip=None, y_tip=None,
               x_base=None, y_base=None, probe_m=None, source="track") -> Track:
    """A checked Track from arrays (the rules of `read_track`); InputError, one line, if not."""
    def arr(name, v):
        if v is None:
            return None
        a = np.asarray(v, dtype=float).ravel()
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise limits.InputError(f"{source}: column {name} has a missing or non-finite value "
                                    f"at sample {bad[0] + 1}")
        return a

    t = arr("t", t)
    if t is None:
        raise limits.InputError(f"{source}: needs a column t (s)")
    cols = {k: arr(k, v) for k, v in dict(x=x, y=y, theta_deg=theta_deg, chidot=chidot,
                                          x_tip=x_tip, y_tip=y_tip, x_base=x_base,
                                          y_base=y_base).items()}
    for k, v in cols.items():
        if v is not None and v.size != t.size:
            raise limits.InputError(f"{source}: column {k} has {v.size} values, t has {t.size}")
    have_g = cols["x"] is not None and cols["y"] is not None
    have_p = all(cols[k] is not None for k in PROBE_COLUMNS)
    if (cols["x"] is None) != (cols["y"] is None):
        raise limits.InputError(f"{source}: give both x and y (m) of the centre of mass")
    if any(cols[k] is not None for k in PROBE_COLUMNS) and not have_p:
        raise limits.InputError(f"{source}: the probe needs all of {', '.join(PROBE_COLUMNS)}")
    if have_g == have_p:
        raise limits.InputError(f"{source}: give the centre of mass (x, y) or the probe "
                                f"({', '.join(PROBE_COLUMNS)}), one of them")
    if have_p:
        if probe_m is None:
            raise limits.InputError(f"{source}: a probe track needs the probe's length "
                                    "(--probe-m, m)")
        probe_m = limits.number("probe_m", probe_m, positive=True, hi=1.0)
    elif probe_m is not None:
        raise limits.InputError(f"{source}: the probe's length (--probe-m) goes with a track of "
                                f"the probe ({', '.join(PROBE_COLUMNS)}); this one has x, y")
    if t.size < MIN_SAMPLES:
        raise limits.InputError(f"{source}: {t.size} samples is too short a track; a fit needs "
                                f"at least {MIN_SAMPLES}")
    steps = np.diff(t)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        raise limits.InputError(f"{source}: t must increase; sample {bad[0] + 2} (t = "
                                f"{t[bad[0] + 1]:g}) does not come after the one before")
    span = t[-1] - t[0]
    if span < MIN_DURATION_S:
        raise limits.InputError(f"{source}: the track lasts {span:g} s; a fit needs at least "
                                f"{MIN_DURATION_S:g} s (t is in s)")
    if span > MAX_DURATION_S:
        raise limits.InputError(f"{source}: the track lasts {span:g} s, more than "
                                f"{MAX_DURATION_S:g} s (is t in ms? t is in s)")
    if np.median(steps) > MAX_INTERVAL_S:
        raise limits.InputError(f"{source}: samples are {np.median(steps):g} s apart (median); "
                                f"a fit needs at most {MAX_INTERVAL_S:g} s (is t in ms? t is "
                                "in s)")
    gap = int(np.argmax(steps))
    if steps[gap] > MAX_INTERVAL_S:
        raise limits.InputError(f"{source}: sample {gap + 2} (t = {t[gap + 1]:g} s) comes "
                                f"{steps[gap]:g} s after the one before; a fit needs samples at "
                                f"most {MAX_INTERVAL_S:g} s apart (cut the track at the gap)")
    if t.size > MAX_SAMPLES:
        raise limits.InputError(f"{source}: {t.size} samples; a fit takes at most {MAX_SAMPLES} "
                                "(keep every k-th row: 300 per second is plenty)")
    for px, py in (("x", "y"), ("x_tip", "y_tip"), ("x_base", "y_base")):
        if cols[px] is None:
            continue
        extent = max(np.ptp(cols[px]), np.ptp(cols[py]))
        speed = np.median(np.hypot(np.diff(cols[px]), np.diff(cols[py])) / steps)
        if extent > MAX_EXTENT_M or speed > MAX_SPEED:
            raise limits.InputError(
                f"{source}: {px}, {py} move {speed:g} m/s over {extent:g} m; a rolling ball "
                f"stays below {MAX_SPEED:g} m/s and {MAX_EXTENT_M:g} m (are they in mm? x, y "
                "are in m)")
    # a tilt read near the vertical may pass 90 deg by its noise
    if cols["theta_deg"] is not None and np.any(np.abs(cols["theta_deg"]) > MAX_THETA_DEG):
        raise limits.InputError(f"{source}: theta_deg must stay within +-{MAX_THETA_DEG:g} deg "
                                "(is it in deg?)")
    if cols["chidot"] is not None and np.any(np.abs(cols["chidot"]) > limits.MAX_RATE):
        raise limits.InputError(f"{source}: chidot beyond {limits.MAX_RATE:g} rad/s")
    return Track(t=t - t[0], t_start=float(t[0]), probe_m=probe_m, source=source, **cols)


def read_track(path, probe_m: float | None = None) -> Track:
    """Read a track CSV: a header row and columns t (s), x, y (m) or x_tip, y_tip, x_base,
    y_base (m, with probe_m), optionally theta_deg (deg) and chidot (rad/s); other columns are
    ignored. InputError (one line) for a file that is not such a track."""
    import pandas as pd

    p = limits.regular_file(path, "track (a CSV file)")
    try:
        df = pd.read_csv(p, skipinitialspace=True)
    except (ValueError, UnicodeDecodeError, pd.errors.ParserError) as exc:
        raise limits.InputError(f"{path}: not a CSV table ({str(exc).splitlines()[0]})") from None
    df.columns = [str(c).strip() for c in df.columns]
    twice = sorted({c for c in df.columns if list(df.columns).count(c) > 1})
    if twice:
        raise limits.InputError(f"{path}: column {twice[0]!r} appears more than once")
    cols = {}
    for name in ("t", "x", "y", "theta_deg", "chidot") + PROBE_COLUMNS:
        if name in df:
            v = pd.to_numeric(df[name], errors="coerce")
            cols[name] = v.to_numpy(dtype=float)
    if "t" not in cols:
        raise limits.InputError(f"{path}: needs a header with a column t (s); found "
                                f"{', '.join(map(str, df.columns)) or 'none'}")
    return make_track(cols.pop("t"), probe_m=probe_m, source=str(path), **cols)


# --- the model ------------------------------------------------------------------------------

def _channels(track: Track) -> list[str]:
    out = ["x_tip", "y_tip", "x_base", "y_base"] if track.probe else ["x", "y"]
    return out + [k for k in ("theta_deg", "chidot") if getattr(track, k) is not None]


def _sigma(name: str) -> float:
    return {"theta_deg": THETA_SIGMA_DEG, "chidot": CHIDOT_SIGMA}.get(name, POSITION_SIGMA_M)


def _model_local(traj: np.ndarray, ball: Ball, probe_m: float | None) -> dict:
    """Channels of sampled fast states (n_t, N_FAST, n) launched at chi0 = 0 from the origin:
    positions (m) before the turn and shift, theta (deg), chidot (rad/s)."""
    a, tu = ball.a, ball.time_unit
    gx, gy = traj[:, S_X] * a, traj[:, S_Y] * a
    out = {"theta_deg": np.degrees(traj[:, S_TH]), "chidot": traj[:, S_CHD] / tu}
    if probe_m is None:
        out["x"], out["y"] = gx, gy
    else:
        pts = body_points(gx, gy, traj[:, S_TH], traj[:, S_CHI], ball, probe_m)
        for k in ("x_tip", "y_tip", "x_base", "y_base"):
            out[k] = pts[k]
    return out


def _place(local: dict, chi0_deg, x0, y0) -> dict:
    """Turn the positions by chi0 about the origin and shift them by (x0, y0)."""
    c, s = np.cos(np.radians(chi0_deg)), np.sin(np.radians(chi0_deg))
    out = dict(local)
    for px, py in (("x", "y"), ("x_tip", "y_tip"), ("x_base", "y_base")):
        if px in local:
            out[px] = c * local[px] - s * local[py] + x0
            out[py] = s * local[px] + c * local[py] + y0
    return out


def _integrate(dyn: np.ndarray, ball: Ball, T: float, dt: float, every: int):
    """Fast-state samples of launches dyn (4, n) = theta0_deg, thetadot0, chidot0, phidot0 from
    chi0 = 0 at the origin: (times (s), traj (n_t, N_FAST, n), ok (n,): ran to the end, valid
    (n_t, n): the samples before a launch stopped (the Euler chart's edge, or non-finite))."""
    tu = ball.time_unit
    plan = StepPlan(T, dt, tu, multiple=every)
    n_rec = plan.n_steps // every + 1
    y0 = launch_state(dyn[0], dyn[1], dyn[2], dyn[3], tu)
    p = np.repeat(ball.nondim_params().reshape(3, 1), dyn.shape[1], axis=1)
    res = run_tracks(y0, p, plan, every, n_rec, parallel=dyn.shape[1] > 16)  # one block: serial
    traj = res.traj
    t_nd = np.arange(n_rec) * plan.dt_nd * every
    with np.errstate(invalid="ignore"):
        valid = (np.isnan(res.t_stop) | (t_nd[:, None] < res.t_stop - plan.dt_nd * every))
        valid &= np.isfinite(traj[:, S_X]) & np.isfinite(traj[:, S_Y])
        ok = (res.outcome == OK) & valid.all(axis=0)
    return t_nd * tu, traj, ok, valid


def _fallback_traj(q, ball: Ball, T: float, dt: float, n_t: int) -> np.ndarray:
    """One launch's samples through `run_trajectory`, which integrates again in the fixed frame
    a launch that meets the Euler chart's singularity (near-vertical)."""
    tu = ball.time_unit
    plan = StepPlan(T, dt, tu, multiple=n_t - 1)
    y0 = launch_state(q[0], q[1], q[2], q[3], tu)[:, 0]
    res = run_trajectory(y0, ball.nondim_params(), plan, "rk4", n_out=n_t)
    return res.traj[:, :, None]


class _Model:
    """Residuals and Jacobian of one track's fit over its first T seconds."""

    def __init__(self, track: Track, ball: Ball, T: float):
        self.track, self.ball = track, ball
        m = track.t <= T + 1e-12
        self.idx = np.flatnonzero(m)
        self.T = float(track.t[self.idx[-1]])
        self.names = _channels(track)
        self.data = {k: getattr(track, k)[self.idx] for k in self.names}
        self.cache: dict = {}

    def _run(self, dyn: np.ndarray) -> list[dict]:
        times, traj, ok, _ = _integrate(dyn, self.ball, self.T, FIT_DT, 1)
        out = []
        for j in range(dyn.shape[1]):
            tr = traj[:, :, j:j + 1]
            if not ok[j]:
                tr = _fallback_traj(dyn[:, j], self.ball, self.T, FIT_DT, times.size)
            loc = _model_local(tr, self.ball, self.track.probe_m)
            tt = self.track.t[self.idx]
            out.append({k: np.interp(tt, times, v[:, 0]) for k, v in loc.items()})
        return out

    def residual_of(self, placed: dict) -> np.ndarray:
        r = np.concatenate([(placed[k] - self.data[k]) / _sigma(k) for k in self.names])
        # a sample exactly at the vertical has no Euler angles: far off, not NaN
        return np.nan_to_num(r, nan=1e8, posinf=1e8, neginf=-1e8)

    def fun(self, q: np.ndarray) -> np.ndarray:
        key = q.tobytes()
        if key not in self.cache:
            self.cache = {key: self._run(q[:4].reshape(4, 1))[0]}
        return self.residual_of(_place(self.cache[key], *q[4:]))

    def jac(self, q: np.ndarray) -> np.ndarray:
        h = 1e-7 * np.maximum(1.0, np.abs(q[:4]))
        dyn = np.repeat(q[:4].reshape(4, 1), 5, axis=1)
        dyn[np.arange(4), np.arange(1, 5)] += h
        runs = self._run(dyn)
        self.cache = {q.tobytes(): runs[0]}
        r0 = self.residual_of(_place(runs[0], *q[4:]))
        cols = [(self.residual_of(_place(runs[k + 1], *q[4:])) - r0) / h[k] for k in range(4)]
        # chi0, x0, y0 turn and shift the positions: their columns in closed form
        loc, rad = runs[0], math.radians(q[4])
        c, s = math.cos(rad), math.sin(rad)
        dchi, dx, dy = {}, {}, {}
        for k in self.names:
            z = np.zeros(self.idx.size)
            dchi[k], dx[k], dy[k] = z, z, z
        for px, py in (("x", "y"), ("x_tip", "y_tip"), ("x_base", "y_base")):
            if px in self.names:
                one, zero = np.ones(self.idx.size), np.zeros(self.idx.size)
                dchi[px] = (-s * loc[px] - c * loc[py]) * math.pi / 180
                dchi[py] = (c * loc[px] - s * loc[py]) * math.pi / 180
                dx[px], dx[py], dy[px], dy[py] = one, zero, zero, one
        for d in (dchi, dx, dy):
            cols.append(np.concatenate([d[k] / _sigma(k) for k in self.names]))
        return np.column_stack(cols)


# --- the global start -----------------------------------------------------------------------

def _centre_of_probe(track: Track, ball: Ball):
    """G's horizontal position from the probe: G = base + (c + a - h) (base - tip) / L (the
    probe lies on the symmetry axis, its base at the flat face's centre)."""
    k = (ball.c + ball.a - ball.cut_height) / track.probe_m
    return (track.x_base + k * (track.x_base - track.x_tip),
            track.y_base + k * (track.y_base - track.y_tip))


def initial_velocity(track: Track, ball: Ball, window_s: float = 0.1):
    """(x0, y0, vx0, vy0) of G at the first sample (m, m/s): a quadratic least-squares fit over
    the first window_s seconds (at least 5 samples)."""
    gx, gy = (track.x, track.y) if not track.probe else _centre_of_probe(track, ball)
    n = max(5, int(np.searchsorted(track.t, window_s)))
    t = track.t[:n]
    cx = np.polynomial.polynomial.polyfit(t, gx[:n], 2)
    cy = np.polynomial.polynomial.polyfit(t, gy[:n], 2)
    return cx[0], cy[0], cx[1], cy[1]


def survey_launches(track: Track, ball: Ball, box=None, grid=None) -> np.ndarray:
    """The survey's launches (4, n): theta0_deg, thetadot0, chidot0 on the grid of the box
    (narrowed to the track's own first theta_deg and chidot when it has them), and phidot0 from
    the initial speed of G, |v| = sqrt(((a phidot - c chidot) cos th)^2 + ((a - c sin th)
    thetadot)^2) (Eqs. 6-7), with both signs."""
    box = {**BOX, **(box or {})}
    grid = {**GRID, **(grid or {})}
    axes = {k: np.linspace(*box[k], grid[k]) for k in box}
    flat = math.degrees(ball.flat_face_theta_rad)
    th = np.union1d(axes["theta0_deg"], [t for t in NEAR_VERTICAL if t >= box["theta0_deg"][0]])
    axes["theta0_deg"] = th[th > flat]
    if track.theta_deg is not None:
        th = float(np.median(track.theta_deg[:3]))
        axes["theta0_deg"] = np.unique(np.clip(th + np.linspace(-3, 3, 7), flat + 0.1, 89.9))
    if track.chidot is not None:
        ch = float(np.median(track.chidot[:3]))
        axes["chidot0"] = ch + np.linspace(-1.5, 1.5, 13)
    th, thd, chd = (g.ravel() for g in np.meshgrid(axes["theta0_deg"], axes["thetadot0"],
                                                  axes["chidot0"], indexing="ij"))
    _, _, vx, vy = initial_velocity(track, ball)
    v2 = vx * vx + vy * vy
    a, c = ball.a, ball.c
    sth, cth = np.sin(np.radians(th)), np.cos(np.radians(th))
    w = (a - c * sth) * thd
    u = np.sqrt(np.maximum(v2 - w * w, 0.0))
    phd = [(c * chd + sign * u / cth) / a for sign in (1.0, -1.0)]
    keep = np.concatenate([np.abs(p) <= limits.MAX_RATE for p in phd])
    return np.stack([np.tile(th, 2), np.tile(thd, 2), np.tile(chd, 2),
                     np.concatenate(phd)])[:, keep]


def _align(loc: dict, data: dict, names, w: dict, valid: np.ndarray):
    """Best turn chi0 (deg) and shift (x0, y0) of each launch's positions onto the data, in
    closed form (2-D Procrustes without reflection, over each launch's valid samples), and the
    weighted misfit left, scaled to all the samples (a launch that left the Euler chart part
    way is judged by its mean misfit before)."""
    pos = [(px, py) for px, py in (("x", "y"), ("x_tip", "y_tip"), ("x_base", "y_base"))
           if px in names]
    wt = np.concatenate([valid] * len(pos)).astype(float)
    n = wt.sum(0)

    def clean(v):
        return np.where(wt > 0, v, 0.0)

    mx = clean(np.concatenate([loc[px] for px, _ in pos]))
    my = clean(np.concatenate([loc[py] for _, py in pos]))
    dx = np.concatenate([data[px] for px, _ in pos])[:, None]
    dy = np.concatenate([data[py] for _, py in pos])[:, None]
    mcx, mcy = mx.sum(0) / n, my.sum(0) / n
    dcx, dcy = (wt * dx).sum(0) / n, (wt * dy).sum(0) / n
    ax, ay, bx, by = wt * (mx - mcx), wt * (my - mcy), wt * (dx - dcx), wt * (dy - dcy)
    ang = np.arctan2((ax * by - ay * bx).sum(0), (ax * bx + ay * by).sum(0))
    c, s = np.cos(ang), np.sin(ang)
    x0, y0 = dcx - (c * mcx - s * mcy), dcy - (s * mcx + c * mcy)
    cost = ((c * ax - s * ay - bx) ** 2 + (s * ax + c * ay - by) ** 2).sum(0) / POSITION_SIGMA_M**2
    for k in ("theta_deg", "chidot"):
        if k in names:
            r = np.where(valid, (loc[k] - data[k][:, None]) / w[k], 0.0)
            cost = cost + (r * r).sum(0)
    return np.degrees(ang), x0, y0, cost * wt.shape[0] / n


def survey(track: Track, ball: Ball, *, box=None, grid=None, T: float = SURVEY_T,
           batch: int = 4096) -> np.ndarray:
    """The global survey: every launch of `survey_launches` over the first T seconds of the
    track on the ensemble kernel, aligned in closed form; returns rows (7, n) of launches
    (PARAMS order) and their misfit (n,), best first."""
    dyn = survey_launches(track, ball, box, grid)
    T = min(T, float(track.t[-1]))
    every = max(1, int(round(SURVEY_EVERY / SURVEY_DT)))
    names = _channels(track)
    w = {k: _sigma(k) for k in names}
    launches, costs = [], []
    for lo in range(0, dyn.shape[1], batch):
        part = dyn[:, lo:lo + batch]
        times, traj, ok, valid = _integrate(part, ball, T, SURVEY_DT, every)
        data = {k: np.interp(times, track.t, getattr(track, k)) for k in names}
        loc = _model_local(traj, ball, track.probe_m)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            chi0, x0, y0, cost = _align(loc, data, names, w, valid)
        # a launch that left the Euler chart (near the vertical) within the first half of the
        # window, or blew up: out; later, judged by its mean misfit (the refinement integrates
        # it again in the fixed frame)
        enough = valid.sum(0) >= SURVEY_VALID * valid.shape[0]
        cost = np.where(enough & np.isfinite(cost), cost, np.inf)
        launches.append(np.vstack([part, chi0, x0, y0]))
        costs.append(cost)
    launches, costs = np.hstack(launches), np.concatenate(costs)
    order = np.argsort(costs, kind="stable")
    return launches[:, order], costs[order]


# --- the fit --------------------------------------------------------------------------------

def _bounds(ball: Ball):
    flat = math.degrees(ball.flat_face_theta_rad)
    r = limits.MAX_RATE
    lo = [flat + 1e-3, -r, -r, -r, -np.inf, -np.inf, -np.inf]
    hi = [89.9, r, r, r, np.inf, np.inf, np.inf]
    return np.array(lo), np.array(hi)


def _refine(model: _Model, q0: np.ndarray, ball: Ball, max_nfev: int):
    from scipy.optimize import least_squares

    lo, hi = _bounds(ball)
    q0 = np.clip(q0, lo + 1e-9, hi - 1e-9)
    return least_squares(model.fun, q0, jac=model.jac, bounds=(lo, hi), x_scale="jac",
                         method="trf", max_nfev=max_nfev, xtol=1e-12, ftol=1e-12, gtol=1e-12)


def fit_track(track, ball: Ball | None = None, *, probe_m: float | None = None, box=None,
              grid=None, n_starts: int = N_STARTS, label_T: float = LABEL_T) -> dict:
    """Fit the launch that best reproduces a measured track.

    Parameters
    ----------
    track : Track, str, Path, dict or pandas.DataFrame
        A `Track` (`make_track`), a CSV file (`read_track`), or columns by name (t, x, y or
        x_tip, y_tip, x_base, y_base, optionally theta_deg, chidot; the rules of `make_track`).
    ball : Ball, optional
        The ball (default: the paper's).
    probe_m : float, optional
        Probe length (m) for a CSV track given by its probe's tip and base.
    box, grid : dict, optional
        The survey's launch box ``{name: (lo, hi)}`` and grid sizes ``{name: n}`` for
        theta0_deg (deg), thetadot0 and chidot0 (rad/s); defaults `BOX`, `GRID`.
    n_starts : int
        Survey launches refined locally over the first START_T seconds (the best N_CARRIED of
        them are carried on to the whole track).
    label_T : float
        Duration (s) of the run that labels the fitted launch (the track's if longer).

    Returns
    -------
    dict
        theta0_deg (deg), thetadot0, chidot0, phidot0 (rad/s), chi0_deg (deg), x0, y0 (m) at the
        first sample, each with ``_err`` (one standard deviation from the Jacobian); rms_m, the
        root-mean-square position residual per coordinate (m); label, the label of the fitted
        launch; and t_start (s), n_samples, cost, survey_launches, seconds.
    """
    import time

    t_wall = time.perf_counter()
    ball = ball or Ball.paper()
    if isinstance(track, (str, Path)):
        track = read_track(track, probe_m=probe_m)
    elif not isinstance(track, Track):  # a mapping of columns or a pandas DataFrame
        cols = {str(k): np.asarray(track[k], dtype=float) for k in track.keys()
                if str(k) in ("t", "x", "y", "theta_deg", "chidot") + PROBE_COLUMNS}
        if "t" not in cols:
            raise limits.InputError("track: needs a column t (s)")
        track = make_track(cols.pop("t"), probe_m=probe_m, **cols)
    if track.probe and track.probe_m is None:
        raise limits.InputError("a probe track needs probe_m (m)")
    starts, costs = survey(track, ball, box=box, grid=grid)
    n_survey = costs.size
    if not np.isfinite(costs[0]):
        raise limits.InputError(f"{track.source}: no launch of the survey box stays on the "
                                "Euler chart over the track; widen the box")
    T_full = float(track.t[-1])
    picked = [starts[:, j] for j in range(min(n_starts, costs.size)) if np.isfinite(costs[j])]
    # the starts refined a little over a short window, where a launch a grid step away still
    # keeps the track's phase; the best few taken on over windows doubled to the whole track
    T = min(START_T, T_full)
    model = _Model(track, ball, T)
    fits = sorted((_refine(model, q, ball, 12) for q in picked), key=lambda r: r.cost)
    best = None
    for r in fits[:N_CARRIED]:
        T, x = min(START_T, T_full), r.x
        while T < T_full:
            T = min(2 * T, T_full)
            model = _Model(track, ball, T)
            r = _refine(model, x, ball, 60 if T == T_full else 25)
            x = r.x
        if best is None or r.cost < best.cost:
            best, best_model = r, model
    model = best_model
    q = best.x
    J = best.jac
    m, n = J.shape
    dof = max(m - n, 1)
    s2 = 2.0 * best.cost / dof
    cov = np.linalg.pinv(J.T @ J) * s2
    err = np.sqrt(np.maximum(np.diag(cov), 0.0))
    placed = _place(model.cache[q.tobytes()], *q[4:]) if q.tobytes() in model.cache else None
    if placed is None:
        model.fun(q)
        placed = _place(model.cache[q.tobytes()], *q[4:])
    pos = [k for k in model.names if k not in ("theta_deg", "chidot")]
    rms = float(np.sqrt(np.mean(np.concatenate([(placed[k] - model.data[k]) ** 2
                                                for k in pos]))))
    lab = simulate(q[0], q[1], q[2], q[3], T=max(label_T, T_full), chi0_deg=q[4], x0=q[5],
                   y0=q[6], ball=ball, n_out=2001).attrs["label"]
    out = {}
    for k, v, e in zip(PARAMS, q, err):
        out[k], out[k + "_err"] = float(v), float(e)
    # the heading is an angle: reported in (-180, 180] deg (the fit may wander a few turns)
    out["chi0_deg"] = float(-((-out["chi0_deg"] + 180.0) % 360.0 - 180.0)) + 0.0
    out.update(rms_m=rms, label=lab, t_start=track.t_start, n_samples=int(track.t.size),
               cost=float(2 * best.cost), survey_launches=int(n_survey),
               seconds=time.perf_counter() - t_wall)
    return out


def fitted_track(fit: dict, track: Track, ball: Ball | None = None) -> dict:
    """The fitted launch's channels at the track's times (positions in m, theta in deg,
    chidot in rad/s), for plots and checks."""
    ball = ball or Ball.paper()
    q = np.array([fit[k] for k in PARAMS])
    model = _Model(track, ball, float(track.t[-1]))
    model.fun(q)
    return _place(model.cache[q.tobytes()], *q[4:])


def plot_fit(track: Track, fit: dict, out=None, ball: Ball | None = None):
    """Track and fitted launch overlaid: the path in the plane (m), and theta (deg) and chidot
    (rad/s) against time where the track has them. Returns the matplotlib Figure; writes it
    to `out` (PNG) if given."""
    from matplotlib.figure import Figure  # the object API: no global matplotlib state

    model = fitted_track(fit, track, ball)
    extra = [k for k in ("theta_deg", "chidot") if getattr(track, k) is not None]
    fig = Figure(figsize=(6 + 4 * len(extra), 5.5), layout="constrained")
    axs = fig.subplots(1, 1 + len(extra), squeeze=False)
    ax = axs[0, 0]
    pairs = [("x_tip", "y_tip", "probe tip"), ("x_base", "y_base", "probe base")] \
        if track.probe else [("x", "y", "centre of mass")]
    for (px, py, what), col in zip(pairs, ("C0", "C2")):
        ax.plot(getattr(track, px), getattr(track, py), ".", ms=2, color=col,
                label=f"track: {what}")
        ax.plot(model[px], model[py], "-", lw=1, color="k" if col == "C0" else "C3",
                label=f"fit: {what}")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=8)
    ax.set_title(f"fit: {fit['label']}, rms {fit['rms_m'] * 1e3:.3f} mm", fontsize=10)
    for axe, k in zip(axs[0, 1:], extra):
        axe.plot(track.t, getattr(track, k), ".", ms=2, label="track")
        axe.plot(track.t, model[k], "k-", lw=1, label="fit")
        axe.set_xlabel("t since the first sample (s)")
        axe.set_ylabel({"theta_deg": "theta (deg)", "chidot": "chidot (rad/s)"}[k])
        axe.legend(fontsize=8)
    # two short lines: one long one ran off a one-panel figure at both edges
    angles = ", ".join(f"{k} {fit[k]:.4g}" for k in PARAMS[:5] if k.endswith("_deg"))
    rates = ", ".join(f"{k} {fit[k]:.4g}" for k in PARAMS[:5] if not k.endswith("_deg"))
    fig.suptitle(f"{angles} (deg)\n{rates} (rad/s)", fontsize=9)
    if out is not None:
        fig.savefig(out, dpi=120)
    return fig

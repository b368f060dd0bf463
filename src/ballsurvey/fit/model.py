"""The fit's model: the launch's parameters (PARAMS), the channels a launch predicts at a track's
times (integrated on the ensemble kernel, again in the fixed frame near the vertical, or with
the rolling resistance), their weighted residuals and Jacobian (`_Model`), the parameters'
bounds, the launch's heading, and the fitted launch's channels (`fitted_track`)."""
from __future__ import annotations

import math

import numpy as np

from .. import limits
from ..ball import Ball
from ..compose import run_resisted_trajectory, run_tracks, run_trajectory
from ..integrate.outcome import OK
from ..physics.fast import N_FAST, S_CHD, S_CHI, S_TH, S_X, S_Y
from ..simulate import body_points
from ..units import StepPlan, launch_state
from .track import POSITION_PAIRS, Track

#: the launch the fit returns, in order, with units
PARAMS = ("theta0_deg", "thetadot0", "chidot0", "phidot0", "chi0_deg", "x0", "y0")
UNITS = {"theta0_deg": "deg", "thetadot0": "rad/s", "chidot0": "rad/s", "phidot0": "rad/s",
         "chi0_deg": "deg", "x0": "m", "y0": "m", "rolling_resistance": "(dimensionless)"}
#: the extra parameter a fit of a slowing ball (`fit_track(slowing=True)`) returns after PARAMS:
#: the rolling-resistance coefficient mu_r (dimensionless, `simulate`'s rolling_resistance)
SLOWING = "rolling_resistance"
#: nominal measurement errors that weight the residual channels
POSITION_SIGMA_M = 1e-4
THETA_SIGMA_DEG = 0.1
CHIDOT_SIGMA = 0.05
#: the refinement's RK4 step (s): the model is sampled every step and interpolated to the track
FIT_DT = 5e-4


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
        with np.errstate(invalid="ignore"):  # a launch that blew up: NaN, judged as such
            pts = body_points(gx, gy, traj[:, S_TH], traj[:, S_CHI], ball, probe_m)
        for k in ("x_tip", "y_tip", "x_base", "y_base"):
            out[k] = pts[k]
    return out


def _place(local: dict, chi0_deg, x0, y0) -> dict:
    """Turn the positions by chi0 about the origin and shift them by (x0, y0)."""
    c, s = np.cos(np.radians(chi0_deg)), np.sin(np.radians(chi0_deg))
    out = dict(local)
    for px, py in POSITION_PAIRS:
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


def _integrate_resisted(dyn: np.ndarray, ball: Ball, t: np.ndarray):
    """`_integrate` for launches dyn (5, n) that slow: theta0_deg, thetadot0, chidot0, phidot0
    and the rolling-resistance coefficient, each by `compose.run_resisted_trajectory`, sampled
    at the times t (s) themselves: (t, traj (n_t, N_FAST, n), ok (n,))."""
    tu = ball.time_unit
    traj = np.empty((t.size, N_FAST, dyn.shape[1]))
    ok = np.empty(dyn.shape[1], dtype=bool)
    for j in range(dyn.shape[1]):
        y0 = launch_state(dyn[0, j], dyn[1, j], dyn[2, j], dyn[3, j], tu)[:, 0]
        res = run_resisted_trajectory(y0, ball.nondim_params(), dyn[4, j], t[-1] / tu,
                                      t_out=t / tu)
        traj[:, :, j] = res.traj
        ok[j] = res.outcome[0] == OK and bool(np.isfinite(res.traj[:, :S_Y + 1]).all())
    return t, traj, ok


def _dyn_index(slowing: bool) -> list[int]:
    """Where the integration's parameters stand in a fitted launch (PARAMS, then SLOWING): the
    tilt and three rates, and with slowing the rolling-resistance coefficient."""
    return [0, 1, 2, 3, 7] if slowing else [0, 1, 2, 3]


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

    def __init__(self, track: Track, ball: Ball, T: float, slowing: bool = False):
        self.track, self.ball, self.slowing = track, ball, slowing
        # the parameters the integration takes (the rest turn and shift its positions)
        self.dyn = _dyn_index(slowing)
        m = track.t <= T + 1e-12
        self.idx = np.flatnonzero(m)
        self.T = float(track.t[self.idx[-1]])
        self.names = _channels(track)
        self.data = {k: getattr(track, k)[self.idx] for k in self.names}
        self.cache: dict = {}

    def _run(self, dyn: np.ndarray) -> list[dict]:
        if self.slowing:
            times, traj, ok = _integrate_resisted(dyn, self.ball, self.track.t[self.idx])
        else:
            times, traj, ok, _ = _integrate(dyn, self.ball, self.T, FIT_DT, 1)
        out = []
        for j in range(dyn.shape[1]):
            tr = traj[:, :, j:j + 1]
            if not ok[j] and not self.slowing:  # the resisted run is in the fixed frame already
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
            self.cache = {key: self._run(q[self.dyn].reshape(-1, 1))[0]}
        return self.residual_of(_place(self.cache[key], *q[4:7]))

    def jac(self, q: np.ndarray) -> np.ndarray:
        nd = len(self.dyn)
        h = 1e-7 * np.maximum(1.0, np.abs(q[self.dyn]))
        dyn = np.repeat(q[self.dyn].reshape(nd, 1), nd + 1, axis=1)
        dyn[np.arange(nd), np.arange(1, nd + 1)] += h
        runs = self._run(dyn)
        self.cache = {q.tobytes(): runs[0]}
        r0 = self.residual_of(_place(runs[0], *q[4:7]))
        cols = [(self.residual_of(_place(runs[k + 1], *q[4:7])) - r0) / h[k] for k in range(nd)]
        slowing_col = cols[4:]  # the coefficient's column goes last, after chi0, x0, y0
        cols = cols[:4]
        # chi0, x0, y0 turn and shift the positions: their columns in closed form
        loc, rad = runs[0], math.radians(q[4])
        c, s = math.cos(rad), math.sin(rad)
        dchi, dx, dy = {}, {}, {}
        for k in self.names:
            z = np.zeros(self.idx.size)
            dchi[k], dx[k], dy[k] = z, z, z
        for px, py in POSITION_PAIRS:
            if px in self.names:
                one, zero = np.ones(self.idx.size), np.zeros(self.idx.size)
                dchi[px] = (-s * loc[px] - c * loc[py]) * math.pi / 180
                dchi[py] = (c * loc[px] - s * loc[py]) * math.pi / 180
                dx[px], dx[py], dy[px], dy[py] = one, zero, zero, one
        for d in (dchi, dx, dy):
            cols.append(np.concatenate([d[k] / _sigma(k) for k in self.names]))
        return np.column_stack(cols + slowing_col)


def _bounds(ball: Ball, slowing: bool = False):
    flat = math.degrees(ball.flat_face_theta_rad)
    r = limits.MAX_RATE
    lo = [flat + 1e-3, -r, -r, -r, -np.inf, -np.inf, -np.inf] + [0.0] * slowing
    hi = [89.9, r, r, r, np.inf, np.inf, np.inf] + [limits.MAX_ROLLING_RESISTANCE] * slowing
    return np.array(lo), np.array(hi)


def heading_deg(q, ball: Ball) -> float:
    """Direction (deg, counter-clockwise from x) of G's velocity at the launch q (PARAMS order):
    chi0 + atan2(w, u), u = (a phidot0 - c chidot0) cos theta0 along xi = (cos chi0, sin chi0),
    w = (a - c sin theta0) thetadot0 along the normal to xi (Eqs. 6-7)."""
    th = math.radians(q[0])
    u = (ball.a * q[3] - ball.c * q[2]) * math.cos(th)
    w = (ball.a - ball.c * math.sin(th)) * q[1]
    return _wrap_deg(q[4] + math.degrees(math.atan2(w, u)))


def _wrap_deg(a: float) -> float:
    """An angle in (-180, 180] deg."""
    return float(-((-a + 180.0) % 360.0 - 180.0)) + 0.0


def fitted_track(fit: dict, track: Track, ball: Ball | None = None, times=None) -> dict:
    """The fitted launch's channels (positions in m, theta in deg, chidot in rad/s) at the
    track's times, or at `times` (s from the first sample; e.g. a dense grid for a plot)."""
    ball = ball or Ball.paper()
    slowing = SLOWING in fit
    q = np.array([fit[k] for k in PARAMS + (SLOWING,) * slowing])
    T = float(track.t[-1])
    if slowing:
        grid = np.linspace(0.0, T, max(int(round(T / FIT_DT)), 1) + 1)
        times_, traj, _ = _integrate_resisted(q[_dyn_index(True)].reshape(-1, 1), ball, grid)
    else:
        times_, traj, ok, _ = _integrate(q[:4].reshape(4, 1), ball, T, FIT_DT, 1)
        if not ok[0]:
            traj = _fallback_traj(q[:4], ball, T, FIT_DT, times_.size)
    loc = _model_local(traj, ball, track.probe_m)
    at = track.t if times is None else np.asarray(times, dtype=float)
    return _place({k: np.interp(at, times_, v[:, 0]) for k, v in loc.items()}, *q[4:7])

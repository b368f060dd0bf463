"""The global start: a survey of the launch box on the ensemble kernel over the track's first
seconds, each launch turned and moved onto the track in closed form (`survey`), and the survey's
launches picked for refinement, one a basin."""
from __future__ import annotations

import math

import numpy as np

from .. import limits
from ..ball import Ball
from .model import POSITION_SIGMA_M, _channels, _integrate, _model_local, _sigma
from .track import POSITION_PAIRS, Track

#: the launch box of the global survey: theta0 (deg), thetadot0, chidot0 (rad/s)
BOX = {"theta0_deg": (-30.0, 89.0), "thetadot0": (-4.0, 4.0), "chidot0": (-30.0, 30.0)}
#: tilts (deg) the survey adds near the vertical, where paths change fast with theta0
NEAR_VERTICAL = (87.0, 88.0, 89.5, 89.9)
#: grid of the survey inside the box
GRID = {"theta0_deg": 31, "thetadot0": 9, "chidot0": 61}
#: the survey's window (s), step (s) and sample spacing (s)
SURVEY_T = 1.5
SURVEY_DT = 2e-3
SURVEY_EVERY = 0.01
#: share of the survey window a launch must stay on the Euler chart to be judged
SURVEY_VALID = 1.0
#: the survey's best launches always refined; then one a basin, scanning this many
N_BEST = 8
PICK_SCAN = 20_000


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
    pos = [(px, py) for px, py in POSITION_PAIRS
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


def _pick_starts(starts: np.ndarray, costs: np.ndarray, n: int, box, grid) -> list:
    """The survey's launches to refine: the N_BEST best, then the best of each further basin
    (a launch more than a grid step from every one picked, in theta0, thetadot0 or chidot0, or
    with the other sign of phidot0), n in all."""
    box, grid = {**BOX, **(box or {})}, {**GRID, **(grid or {})}
    step = np.array([(box[k][1] - box[k][0]) / max(grid[k] - 1, 1) * 1.01
                     for k in ("theta0_deg", "thetadot0", "chidot0")])
    picked: list[int] = []
    for j in np.flatnonzero(np.isfinite(costs))[:PICK_SCAN]:
        if len(picked) >= n:
            break
        if len(picked) >= N_BEST:
            p = starts[:4, picked]
            near = np.all(np.abs(p[:3] - starts[:3, j:j + 1]) <= step[:, None], axis=0) & \
                (np.sign(p[3]) == np.sign(starts[3, j]))
            if near.any():
                continue
        picked.append(int(j))
    return [starts[:, j] for j in picked]

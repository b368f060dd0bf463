"""Inverse search: the launch condition whose path closes as an exact n-gon.

The net turn per theta cycle comes from the quadrature of the conserved quantities
(`quadrature.py`: no time stepping), so it is a cheap, smooth function of any one launch variable.
`find_launch` scans a bracket for sign changes of |turn(v)| - 360/n, refines each by bisection to
1e-12 relative, and checks the result by integrating it (closure error of the path).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .ball import Ball
from .quadrature import launch_cycle
from .simulate import simulate

SOLVABLE = ("chidot0", "theta0_deg", "phidot0")
DEFAULT_BRACKETS = {"chidot0": (-30.0, 30.0), "theta0_deg": (-30.0, 85.0), "phidot0": (-30.0, 30.0)}


class NoSolution(ValueError):
    """No launch in the bracket gives the asked n."""


@dataclass
class Solution:
    variable: str
    value: float
    n_sides: float
    turn_per_cycle_deg: float
    theta_period_s: float
    closure_m: float
    label: str


def _turn(launch: dict, var: str, v: float, ball: Ball) -> float:
    kw = dict(launch)
    kw[var] = v
    try:
        q = launch_cycle(kw["theta0_deg"], kw["thetadot0"], kw["chidot0"], kw["phidot0"], ball)
    except (ValueError, ZeroDivisionError, FloatingPointError):
        return math.nan
    return math.nan if q is None else q["turn_per_cycle_deg"]


def find_launch(n: int, launch: dict, solve: str = "chidot0", bracket=None, ball: Ball | None = None,
                scan: int = 240, check: bool = True) -> list[Solution]:
    """Values of `solve` in `bracket` for which the net turn per cycle is exactly 360/n deg.

    launch: theta0_deg, thetadot0, chidot0, phidot0 (deg, rad/s); the one named by `solve` is
    replaced. Raises NoSolution (saying the range of n seen) when the bracket holds none."""
    if solve not in SOLVABLE:
        raise ValueError(f"--solve must be one of {', '.join(SOLVABLE)}, got {solve!r}")
    if n < 3:
        raise ValueError(f"n must be >= 3, got {n}")
    ball = ball or Ball.paper()
    lo, hi = bracket or DEFAULT_BRACKETS[solve]
    if not lo < hi:
        raise ValueError(f"bracket must have lo < hi, got {lo}, {hi}")
    target = 360.0 / n
    vs = np.linspace(lo, hi, scan)
    g = np.array([abs(_turn(launch, solve, v, ball)) - target for v in vs])
    roots = []
    for i in range(scan - 1):
        a, b, ga, gb = vs[i], vs[i + 1], g[i], g[i + 1]
        if not (np.isfinite(ga) and np.isfinite(gb)) or (ga > 0) == (gb > 0):
            continue
        if abs(ga) > 90 or abs(gb) > 90:  # the folded turn jumped through 180 deg: not a root
            continue
        for _ in range(100):
            m = 0.5 * (a + b)
            gm = abs(_turn(launch, solve, m, ball)) - target
            if not np.isfinite(gm):
                break
            if (gm > 0) == (ga > 0):
                a, ga = m, gm
            else:
                b = m
            if abs(b - a) <= 1e-12 * max(1.0, abs(m)):
                break
        roots.append(0.5 * (a + b))
    if not roots:
        finite = g[np.isfinite(g)] + target
        seen = (f"n from {360 / finite.max():.3f} to {360 / max(finite.min(), 1e-9):.3f}"
                if finite.size else "no oscillating launches")
        raise NoSolution(f"no {solve} in [{lo:g}, {hi:g}] gives n = {n} ({seen}, other variables "
                         f"{ {k: v for k, v in launch.items() if k != solve} })")
    out = []
    for r in roots:
        kw = dict(launch)
        kw[solve] = r
        turn = _turn(launch, solve, r, ball)
        sol = Solution(solve, r, 360.0 / abs(turn), turn, math.nan, math.nan, "")
        if check:
            q = launch_cycle(kw["theta0_deg"], kw["thetadot0"], kw["chidot0"], kw["phidot0"], ball)
            T = min(60.0, (n + 2) * q["theta_period_s"] + 1.0)
            ds = simulate(**kw, T=T, ball=ball, n_out=2001)
            sol.theta_period_s = q["theta_period_s"]
            sol.closure_m = ds.attrs.get("closure_m", math.nan)
            sol.label = ds.attrs["label"]
        out.append(sol)
    return out


def trace(n: int, theta0_values, launch: dict, bracket=None, ball: Ball | None = None) -> list:
    """The curve of exact n-gons across theta0: for each theta0_deg, every chidot0 in the bracket
    that closes the path (rows of (theta0_deg, chidot0))."""
    rows = []
    for th in theta0_values:
        kw = dict(launch, theta0_deg=float(th))
        try:
            sols = find_launch(n, kw, "chidot0", bracket, ball, scan=120, check=False)
        except NoSolution:
            continue
        rows += [(float(th), s.value) for s in sols]
    return rows

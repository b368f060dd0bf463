"""Inverse search: the launch condition whose path closes as an exact n-gon.

The net turn per theta cycle comes from the quadrature of the conserved quantities
(`quadrature.py`: no time stepping), so it is a cheap, smooth function of any one launch variable;
where the quadrature cannot resolve a cycle (theta max within a hair of 90 deg) an adaptive
integration stands in. `find_launch` scans a bracket for sign changes of |turn(v)| - 360/n, refines
each by bisection to 1e-12 relative, and integrates every root: a root is a solution only if its
integrated path is the shape (`shape_of_root`): labelled that polygon (so without loops the eye
sees, with its corners where the polygon has them), or a rounded polygon the labeller calls a
circle (within +-5 % of one circle, no loops) whose n lobes still show; it is printed with the
closure error of its path.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .ball import Ball, tilt_error
from .quadrature import launch_cycle
from .simulate import simulate

SOLVABLE = ("chidot0", "theta0_deg", "phidot0")
DEFAULT_BRACKETS = {"chidot0": (-30.0, 30.0), "theta0_deg": (-30.0, 85.0), "phidot0": (-30.0, 30.0)}


class NoSolution(ValueError):
    """No launch in the bracket gives the asked n."""


@dataclass
class Solution:
    """A root of the turn per cycle and what its integrated path is."""

    variable: str  #: the solved launch variable
    value: float  #: its value (deg for theta0_deg, else rad/s)
    n_sides: float  #: 360 / |turn per cycle| of the integrated path
    turn_per_cycle_deg: float
    theta_period_s: float
    closure_m: float  #: how far a corner drifts per circuit (m)
    label: str  #: the integrated path's label word
    roundness: float = math.nan  #: radial spread / mean radius about the orbit centre
    corner_kind: str = ""
    shape: str = ""  #: what the path is: 'square', 'rounded square', ... ('' if not the shape)


#: the integration that checks every root and stands in where the quadrature cannot resolve a
#: cycle: the adaptive pair at a tight tolerance (the fixed-frame form takes over near 90 deg)
CHECK_RTOL, CHECK_ATOL = 1e-10, 1e-13
SHAPE_OF_N = {3: "triangle", 4: "square"}
#: a root labelled circle whose roundness is at least this (its n lobes spread the path by at
#: least +-0.5 % of its radius, about a line's width in a drawn path) is a rounded polygon
MIN_ROUNDED = 0.01


def _launch_with(launch: dict, var: str, v: float) -> dict:
    kw = dict(launch)
    kw[var] = float(v)
    return kw


def _integrated(kw: dict, ball: Ball, T: float):
    return simulate(**kw, T=T, ball=ball, method="dopri5", rtol=CHECK_RTOL, atol=CHECK_ATOL,
                    dt=1e-3)


def _turn(launch: dict, var: str, v: float, ball: Ball) -> float:
    """|Net turn per cycle| (deg) at launch[var] = v: quadrature, else integration; NaN if neither
    resolves a cycle (a steady launch, or one outside the model)."""
    kw = _launch_with(launch, var, v)
    if tilt_error(kw["theta0_deg"], math.degrees(ball.flat_face_theta_rad)):
        return math.nan  # outside the model (on the flat face, or at 90 deg): no value here
    try:
        q = launch_cycle(kw["theta0_deg"], kw["thetadot0"], kw["chidot0"], kw["phidot0"], ball)
    except (ValueError, ZeroDivisionError, FloatingPointError):
        return math.nan
    if q is not None:
        return abs(q["turn_per_cycle_deg"])
    try:  # the cycle passes too near the vertical for the quadrature: integrate it
        a = _integrated(kw, ball, T=8.0).attrs
    except ValueError:
        return math.nan
    if a["label"] in ("blew_up", "singular", "inaccurate", "unresolved", "flat_face"):
        return math.nan
    return abs(a["turn_per_cycle_deg"])


def polygon_name(n: int) -> str:
    """'triangle', 'square', else 'n-gon'."""
    return SHAPE_OF_N.get(n, f"{n}-gon")


def shape_of_root(n: int, attrs: dict) -> str:
    """What an integrated root (simulate's attrs) is, as asked for n sides: the polygon's name if
    the labeller calls it that polygon ('square'); 'rounded square' if it calls it a circle but
    the path has n visible lobes and no loops (roundness at least MIN_ROUNDED); '' otherwise
    (a ring of loops, a star, a line, a status word, another n)."""
    label, n_sides = attrs["label"], attrs["n_sides"]
    if not (math.isfinite(n_sides) and round(n_sides) == n):
        return ""
    if label == SHAPE_OF_N.get(n, "ngon"):
        return polygon_name(n)
    if (label == "circle" and attrs.get("corner_kind") != "loop"
            and attrs.get("roundness", 0.0) >= MIN_ROUNDED):
        return "rounded " + polygon_name(n)
    return ""


def find_launch(n: int, launch: dict, solve: str = "chidot0", bracket=None,
                ball: Ball | None = None, scan: int = 240, check: bool = True,
                rejected: list | None = None) -> list[Solution]:
    """Values of `solve` in `bracket` for which the net turn per cycle is exactly 360/n deg.

    launch: theta0_deg, thetadot0, chidot0, phidot0 (deg, rad/s); the one named by `solve` is
    replaced. The turn comes from the quadrature, or from integration where the quadrature cannot
    resolve the cycle (theta max within a hair of 90 deg); a sign change is bracketed only between
    two scan points where the turn is known. Each root is refined by bisection to 1e-12 relative
    and, with `check`, integrated (adaptive, rtol 1e-10): a root whose integrated path is not the
    asked shape (`shape_of_root`: a ring of loops, or a path within a line's width of a circle)
    is not returned but appended to `rejected`; a rounded polygon the labeller calls a circle is
    returned with `shape` 'rounded square' etc. Raises NoSolution (saying the range of n seen)
    when none is left.
    """
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
    g = np.array([_turn(launch, solve, v, ball) - target for v in vs])
    roots = []
    for i in range(scan - 1):
        a, b, ga, gb = vs[i], vs[i + 1], g[i], g[i + 1]
        if not (np.isfinite(ga) and np.isfinite(gb)) or (ga > 0) == (gb > 0):
            continue
        if abs(ga) > 90 or abs(gb) > 90:  # the folded turn jumped through 180 deg: not a root
            continue
        for _ in range(100):
            m = 0.5 * (a + b)
            gm = _turn(launch, solve, m, ball) - target
            if not np.isfinite(gm):
                break
            if (gm > 0) == (ga > 0):
                a, ga = m, gm
            else:
                b = m
            if abs(b - a) <= 1e-12 * max(1.0, abs(m)):
                break
        if abs(b - a) <= 1e-9 * max(1.0, abs(a)):  # converged on solid ground only
            roots.append(0.5 * (a + b))
    out = []
    for r in roots:
        kw = _launch_with(launch, solve, r)
        turn = _turn(launch, solve, r, ball)
        sol = Solution(solve, r, 360.0 / turn, turn, math.nan, math.nan, "")
        if check:
            q = launch_cycle(kw["theta0_deg"], kw["thetadot0"], kw["chidot0"], kw["phidot0"], ball)
            period = q["theta_period_s"] if q else 1.0
            T = min(60.0, (n + 2) * period + 1.0)
            a = _integrated(kw, ball, T).attrs
            sol.theta_period_s = a["theta_period_s"]
            sol.closure_m = a["closure_m"]
            sol.label = a["label"]
            sol.n_sides = a["n_sides"]
            sol.turn_per_cycle_deg = a["turn_per_cycle_deg"]
            sol.roundness = a["roundness"]
            sol.corner_kind = a["corner_kind"]
            sol.shape = shape_of_root(n, a)
            if not sol.shape:
                if rejected is not None:
                    rejected.append(sol)
                continue
        out.append(sol)
    if not out:
        finite = g[np.isfinite(g)] + target
        seen = (f"n from {360 / finite.max():.3f} to {360 / max(finite.min(), 1e-9):.3f}"
                if finite.size else "no oscillating launches")
        why = (f"; {len(roots)} root(s) of the turn integrate as another shape "
               f"({', '.join(f'{s.value:.6g}: {s.label} {s.corner_kind}' for s in rejected or [])})"
               if roots else "")
        unit = "deg" if solve == "theta0_deg" else "rad/s"
        at = ", ".join(f"{k} = {v:g} {'deg' if k.endswith('_deg') else 'rad/s'}"
                       for k, v in launch.items() if k != solve)
        raise NoSolution(f"no {solve} in [{lo:g}, {hi:g}] {unit} gives n = {n} at {at} "
                         f"({seen}{why})")
    return out


def trace(n: int, theta0_values, launch: dict, bracket=None, ball: Ball | None = None,
          check: bool = True) -> list[tuple[float, Solution]]:
    """The curve of exact n-gons across theta0: for each theta0_deg, every chidot0 in the bracket
    that closes the path and (with `check`) integrates as that shape: rows of
    (theta0_deg, Solution)."""
    rows = []
    for th in theta0_values:
        kw = dict(launch, theta0_deg=float(th))
        try:
            sols = find_launch(n, kw, "chidot0", bracket, ball, scan=120, check=check)
        except NoSolution:
            continue
        rows += [(float(th), s) for s in sols]
    return rows

"""Theta range, theta period and turn per cycle from the three conserved quantities, by quadrature.

Non-dimensional (a = g = M = 1). With Routh's integral R, Jellett's J and the energy E fixed by the
launch (docs/physics.md section 6; Eqs. 11-12), every rate is a function of theta alone:

    w_eta(th)  = R / sqrt(A B + A cos^2 th + B (sin th - c)^2)
    chidot(th) = (B w_eta (sin th - c) - J) / (A cos^2 th)          (Jellett, L_G . r_GP = J)
    phidot(th) = w_eta + chidot sin th
    thetadot^2 = F(th) = 2 (E - U(th)) / (A + 1 - 2 c sin th + c^2)  (energy)

with U the energy at thetadot = 0. The tilt oscillates between the roots theta_min < theta_max of F
around theta0, and

    period = 2 int dth / sqrt(F),     turn per cycle = 2 int chidot(th) dth / sqrt(F)

over [theta_min, theta_max]. The substitution th = m + h sin(u) removes the inverse square-root
end singularities, and Gauss-Legendre in u converges fast. No time stepping: an independent check
of the integrators and of the period map.

Near the vertical. The Jellett term makes F -> -infinity as theta -> 90 deg (unless J meets the
spin exactly), so theta_max stays below 90 deg; but for the best squares at theta0 above about
10 deg it comes within a fraction of a degree, where chidot ~ 1/cos^2(theta) makes a narrow
spike in the integrand. The turning points are therefore searched up to the vertical itself,
and the number of quadrature panels is doubled until the period and the turn agree to
`QUAD_RTOL` between two counts; a launch that has not converged at `MAX_PANELS` gives None, as does
one that oscillates through +-90 deg: the caller integrates those instead.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from .ball import Ball
from .physics.euler import accelerations, energy, jellett, routh

QUAD_RTOL = 1e-8  #: agreement of period and turn between successive panel counts (the
#: integrand near the turning points carries rounding noise of about 1e-10 relative)
PANEL_NODES, MAX_PANELS = 200, 512  #: Gauss-Legendre nodes per panel; most panels tried


@cache
def _nodes(panels: int):
    """Composite Gauss-Legendre on [-1, 1]: `panels` equal panels of PANEL_NODES nodes each."""
    x, w = np.polynomial.legendre.leggauss(PANEL_NODES)
    edges = np.linspace(-1.0, 1.0, panels + 1)
    half = 0.5 * np.diff(edges)
    mid = 0.5 * (edges[1:] + edges[:-1])
    return (mid[:, None] + half[:, None] * x).ravel(), (half[:, None] * w).ravel()


@dataclass(frozen=True)
class CycleQuadrature:
    theta_min: float  # rad
    theta_max: float  # rad
    period: float  # non-dimensional time
    turn: float  # rad, unfolded change of chi per theta cycle

    def si(self, ball: Ball) -> dict:
        return {"theta_min_deg": math.degrees(self.theta_min),
                "theta_max_deg": math.degrees(self.theta_max),
                "theta_period_s": self.period * ball.time_unit,
                # the path's turn is chi's change up to whole turns (the direction of motion
                # also winds relative to chi within a cycle), folded as the classifier's is
                "turn_per_cycle_deg": (math.degrees(self.turn) + 180.0) % 360.0 - 180.0,
                "chi_change_per_cycle_deg": math.degrees(self.turn)}


def _rates(th, R, J, c, A, B):
    """(w_eta, chidot, phidot) at tilt th from Routh's and Jellett's integrals R and J, inverted
    (the forward formulas: physics.euler.routh, jellett)."""
    s, co = np.sin(th), np.cos(th)
    w = R / np.sqrt(A * B + A * co * co + B * (s - c) ** 2)
    chd = (B * w * (s - c) - J) / (A * co * co)
    phd = w + chd * s
    return w, chd, phd


def _F(th, E, R, J, c, A, B):
    """(thetadot^2, chidot) at tilt th: the energy (physics.euler.energy) at thetadot = 0 is the
    effective potential, and the thetadot^2 coefficient of the kinetic energy is
    (A + 1 - 2 c s + c^2) / 2."""
    s, co = np.sin(th), np.cos(th)
    _, chd, phd = _rates(th, R, J, c, A, B)
    u = energy(s, co, 0.0, chd, phd, c, A, B)
    return 2 * (E - u) / (A + 1 - 2 * c * s + c * c), chd


def _root(f, a, b):
    """Bisection for the sign change of f between a (f > 0) and b (f <= 0)."""
    fa = f(a)
    for _ in range(200):
        m = 0.5 * (a + b)
        if m == a or m == b:
            break
        if (f(m) > 0) == (fa > 0):
            a = m
        else:
            b = m
    return 0.5 * (a + b)


def cycle_by_quadrature(theta0: float, thetadot0: float, chidot0: float, phidot0: float,
                        params) -> CycleQuadrature | None:
    """Non-dimensional launch -> the theta cycle by quadrature; None for a steady launch (no
    oscillation) or one whose tilt would reach +-90 deg (outside the Euler chart)."""
    c, A, B = (float(v) for v in params)
    s0, c0 = math.sin(theta0), math.cos(theta0)
    args = (s0, c0, thetadot0, chidot0, phidot0, c, A, B)
    E, J, R = energy(*args), jellett(*args), routh(*args)

    def f(th):
        return float(_F(np.array(th), E, R, J, c, A, B)[0])

    lim = 0.5 * math.pi * (1.0 - 1e-13)  # the vertical, less a hair (cos is 2e-13 there)
    step = math.radians(0.25)
    if thetadot0 == 0.0:
        thdd = accelerations(s0, c0, 0.0, chidot0, phidot0, c, A, B)[0]
        if abs(thdd) < 1e-13:
            return None  # steady
        eps = 1e-7 * (1 if thdd > 0 else -1)
        start = theta0 + eps
        if f(start) <= 0:
            return None
    else:
        start = theta0
    ends = []
    for direction in (-1, 1):
        a = start
        while True:
            b = a + direction * step
            if abs(b) >= lim:
                b = math.copysign(lim, b)
                if abs(a) >= lim or not f(b) <= 0:
                    return None  # theta would reach the vertical
            if f(b) <= 0:
                ends.append(_root(f, a, b))
                break
            a = b
    lo, hi = ends
    if thetadot0 == 0.0:  # theta0 itself is the turning point on its side
        lo, hi = (theta0, hi) if start > theta0 else (lo, theta0)
    m, h = 0.5 * (hi + lo), 0.5 * (hi - lo)

    def integrals(n):
        x, wts = _nodes(n)
        u = 0.5 * math.pi * x
        th = m + h * np.sin(u)
        F, chd = _F(th, E, R, J, c, A, B)
        jac = h * np.cos(u) * 0.5 * math.pi
        good = F > 0
        inv = np.where(good, jac / np.sqrt(np.where(good, F, 1.0)), 0.0)
        return 2 * float(np.sum(wts * inv)), 2 * float(np.sum(wts * inv * chd))

    n = 2
    period, turn = integrals(n)
    while True:
        n *= 2
        if n > MAX_PANELS:
            return None  # the spike near the vertical is not resolved
        p2, t2 = integrals(n)
        done = (abs(p2 - period) <= QUAD_RTOL * abs(p2)
                and abs(t2 - turn) <= QUAD_RTOL * max(abs(t2), 1e-3))
        period, turn = p2, t2
        if done:
            return CycleQuadrature(lo, hi, period, turn)


def launch_cycle(theta0_deg, thetadot0, chidot0, phidot0, ball: Ball | None = None) -> dict | None:
    """SI launch (deg, rad/s) -> theta range (deg), period (s), the path's turn per cycle folded
    into (-180, 180] (deg, as the classifier's `turn_per_cycle_deg`) and chi's own change per
    cycle (deg, unfolded: the turn plus whole turns)."""
    ball = ball or Ball.paper()
    tu = ball.time_unit
    q = cycle_by_quadrature(math.radians(theta0_deg), thetadot0 * tu, chidot0 * tu, phidot0 * tu,
                            ball.nondim_params())
    return None if q is None else q.si(ball)

"""Per-cycle figures of launches whose tilt passes within 1.5 deg of the vertical, against
independent references: the quadrature (turn per cycle, theta max; no time stepping) and a
DOP853 integration of the fixed-frame form at rtol 1e-12 (scipy), densely sampled, for the
path's own roundness about its orbit centre.

    python benchmarks/near_vertical.py [--n 40] [--seed 1] [--lo 88.5] [--hi 89.99]

Launches are drawn at random (paper's ball; theta0 50-70 deg, thetadot0 +-2, chidot0 +-13,
phidot0 +-10 rad/s) and kept where the quadrature's theta max lies in [lo, hi] deg. For each map
setting (full rk4 map; the big map's period mode with dop853 and 4 ms samples; rk4 period mode)
it prints the largest error in turn per cycle (deg), theta max (deg) and roundness, over the
launches the setting labels with a shape.
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.integrate import solve_ivp

from ballsurvey.ball import Ball
from ballsurvey.classify.labels import LABELS, SHAPES, fold_deg
from ballsurvey.compose import classify, run_launches
from ballsurvey.physics import fixed
from ballsurvey.physics.euler import N_EULER
from ballsurvey.quadrature import cycle_by_quadrature
from ballsurvey.units import StepPlan, fields_to_si, launch_state

SETTINGS = {
    "rk4 full (dt 1e-4)": dict(method="rk4", dt=1e-4, cycles=0),
    "dop853 period (dt 1e-3)": dict(method="dop853", dt=1e-3, cycles=2),
    "rk4 period (dt 1e-4)": dict(method="rk4", dt=1e-4, cycles=2),
}


def draw(n, seed, lo, hi, ball):
    """n launches (deg, rad/s) whose quadrature theta max is in [lo, hi] deg, with the
    quadrature's turn per cycle (deg) and theta max (deg)."""
    rng = np.random.default_rng(seed)
    tu, p = ball.time_unit, ball.nondim_params()
    rows = []
    while len(rows) < n:
        th, td = rng.uniform(50, 70), rng.uniform(-2, 2)
        cd, pd = rng.uniform(-13, 13), rng.uniform(-10, 10)
        q = cycle_by_quadrature(math.radians(th), td * tu, cd * tu, pd * tu, p)
        if q is None:
            continue
        qs = q.si(ball)
        if lo <= qs["theta_max_deg"] <= hi and qs["theta_max_deg"] - qs["theta_min_deg"] > 2:
            rows.append((th, td, cd, pd, qs["turn_per_cycle_deg"], qs["theta_max_deg"],
                         qs["theta_period_s"]))
    return np.array(rows)


def reference_roundness(th, td, cd, pd, ball, cycles=6):
    """Spread over mean of the path's distance from its orbit centre, from a DOP853 run of the
    fixed-frame form at rtol 1e-12: the centre is the circle through the theta maxima (each
    cycle is the last one turned about it), the distances from 20 000 samples."""
    tu, p = ball.time_unit, ball.nondim_params()
    u = np.zeros(N_EULER)
    u[2], u[5], u[6], u[7] = math.radians(th), td * tu, cd * tu, pd * tu
    v0 = fixed.euler_to_fixed(u)
    c, A, B = p

    def f(t, v):
        out = np.empty(fixed.N_FIXED)
        fixed.rhs(v, p, out)
        return out

    def ez_rate(t, v):  # theta max <=> e_z (= -sin theta) minimum
        return f(t, v)[fixed.EZ]
    ez_rate.direction = 1.0
    q = cycle_by_quadrature(math.radians(th), td * tu, cd * tu, pd * tu, p)
    T = q.period * (cycles + 0.5)
    sol = solve_ivp(f, (0, T), v0, method="DOP853", rtol=1e-12, atol=1e-14, events=ez_rate,
                    dense_output=True)
    ev = sol.y_events[0][:, :2]
    if len(ev) < 3:
        return math.nan
    # centre: least-squares circle through the maxima
    M = np.column_stack([2 * ev[:, 0], 2 * ev[:, 1], np.ones(len(ev))])
    sol_c = np.linalg.lstsq(M, (ev ** 2).sum(1), rcond=None)[0]
    t = np.linspace(0, T, 20000)
    xy = sol.sol(t)[:2]
    r = np.hypot(xy[0] - sol_c[0], xy[1] - sol_c[1])
    return (r.max() - r.min()) / (0.5 * (r.max() + r.min()))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--lo", type=float, default=88.5)
    ap.add_argument("--hi", type=float, default=89.99)
    ap.add_argument("--T", type=float, default=10.0)
    ap.add_argument("--no-roundness", action="store_true")
    a = ap.parse_args(argv)
    ball = Ball.paper()
    tu, p = ball.time_unit, ball.nondim_params()
    rows = draw(a.n, a.seed, a.lo, a.hi, ball)
    th, td, cd, pd, q_turn, q_thmax, q_period = rows.T
    rnd = (np.full(len(th), np.nan) if a.no_roundness else
           np.array([reference_roundness(*r[:4], ball) for r in rows]))
    print(f"{len(th)} launches, quadrature theta max {q_thmax.min():.3f}-{q_thmax.max():.3f} deg, "
          f"reference roundness {np.nanmin(rnd):.4f}-{np.nanmax(rnd):.4f}")
    y0 = launch_state(th, td, cd, pd, tu)
    params = np.repeat(p[:, None], len(th), 1)
    for name, kw in SETTINGS.items():
        t0 = time.perf_counter()
        res = run_launches(y0, params, StepPlan(a.T, kw["dt"], tu), kw["method"], rtol=1e-9,
                           cycles=kw["cycles"])
        f = fields_to_si(classify(res, ball.flat_face_theta_rad), ball.a, tu, ball.M)
        wall = time.perf_counter() - t0
        shape = np.array([LABELS[k] in SHAPES for k in f["label"]])
        dturn = np.abs(fold_deg(f["turn_per_cycle_deg"] - q_turn))[shape]
        dth = np.abs(f["theta_max_deg"] - q_thmax)[shape]
        drnd = np.abs(f["roundness"] - rnd)[shape]
        worst = int(np.nanargmax(np.where(shape, np.abs(fold_deg(f["turn_per_cycle_deg"]
                                                                 - q_turn)), -1)))
        print(f"{name:26s} shapes {shape.sum():3d}/{len(th)}  turn err max {np.nanmax(dturn):.2e} "
              f"median {np.nanmedian(dturn):.1e} deg | theta max err max {np.nanmax(dth):.2e} deg"
              f" | roundness err max {np.nanmax(drnd) if drnd.size else math.nan:.3f}"
              f" | worst turn: theta0 {th[worst]:.4f} thetadot0 {td[worst]:.4f} chidot0 "
              f"{cd[worst]:.4f} phidot0 {pd[worst]:.4f} ({wall:.1f} s)")


if __name__ == "__main__":
    main()

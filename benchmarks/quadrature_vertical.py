"""The quadrature kernel near the vertical: turn per cycle and theta max of launches whose tilt
swings up to within a fraction of a degree of +90 deg, against two references, with another git
revision's kernel beside today's when --against is given.

    python benchmarks/quadrature_vertical.py [--n 300] [--seed 0] [--lo 89.5] [--hi 89.99]
                                             [--circles | --below [--at-rest]] [--varied]
                                             [--against REV]

Launches (the paper's ball) are drawn near the vertical: theta0 85-89.99 deg, half of them with
thetadot0 in +-0.5 rad/s, chidot0 +-13 and phidot0 +-10 rad/s (swings of about 1 to 6 deg); or,
with --circles, on steady circles at 88-89.99 deg nudged in tilt rate (swings from 0.7 deg, the
smallest the kernel does there: it leaves smaller ones to the integrator). Kept are the first n
that today's kernel does (status done) with theta max in [lo, hi] deg. References:
- "mp": the same launch from its invariants at 40 digits (mpmath): E, J and R from their
  definitions at the launch, the turning points as roots of thetadot^2 = F(theta), the turn per
  cycle as 2 times the integral of chidot dt over the rising half cycle (tanh-sinh quadrature,
  with the substitution theta = m + h sin s). Its own error estimate is printed.
- "fixed": the fixed-frame integration (no singularity at the vertical) by adaptive DOPRI5 at
  rtol 1e-12 with the stepping observer, a different formulation and time stepping.
Printed per bin of theta max: the launches, the largest |turn per cycle| error of each kernel
against mp (and how many over 1e-6 deg) and against fixed, and the largest theta max error
against mp; then how far the two references are apart. --below does the same near -90 deg: the
launches' theta min in [-hi, -lo] deg, each run 15 s (the fixed frame's turn needs two cycles;
near -90 deg it is the less reliable of the two references); with --at-rest the launches are at
rest in theta at theta0 in [-hi, -lo] deg with chidot0 and phidot0 +-30 rad/s (long swings up
from a slowly turning end). --varied: each launch with its own ball, non-dimensional c in
0.05-0.5 and A, B in 0.3-0.7 (the paper's: 0.11, 0.38, 0.42 about).
"""
from __future__ import annotations

import argparse
import subprocess
import tempfile
from pathlib import Path

import mpmath as mp
import numpy as np
from quadrature_kernel import _module

from ballsurvey.ball import Ball
from ballsurvey.classify import cycle
from ballsurvey.classify import observer as ob
from ballsurvey.classify.labels import fold_deg
from ballsurvey.compose import FALLBACK_H_INIT, FALLBACK_H_MAX, STEP_OBSERVER, classify
from ballsurvey.integrate import outcome as oc
from ballsurvey.integrate.adaptive import integrate_adaptive
from ballsurvey.units import launch_state

BALL = Ball.paper()
TU = BALL.time_unit
P = BALL.nondim_params()
ROOT = Path(__file__).resolve().parents[1]
REL = "src/ballsurvey/classify/cycle.py"


def draw(n: int, lo: float, hi: float, rng, circles: bool = False,
         below: bool = False, varied: bool = False,
         at_rest: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """((4, n) launches (deg, rad/s), (3, n) non-dimensional ball parameters) today's kernel
    does, theta max in [lo, hi] deg (below: -theta min, from theta0 -89.99 to -80 deg, the same
    rates). circles: on a steady circle (tilt 88-89.99 deg, precession +-(1-10) sqrt(g/a)) with
    a tilt rate of 1e-4 to 0.3 rad/s, the smallest swings the kernel does near the vertical.
    varied: each launch's ball drawn (c 0.05-0.5, A and B 0.3-0.7); else the paper's.
    at_rest (with below): launched at rest in theta at theta0 -hi..-lo deg, chidot0 and phidot0
    +-30 rad/s: swings from theta min = theta0 up to tens of degrees."""
    rows, pars = np.empty((4, 0)), np.empty((3, 0))
    while rows.shape[1] < n:
        m = 200_000
        if varied:
            par = np.array([rng.uniform(0.05, 0.5, m), rng.uniform(0.3, 0.7, m),
                            rng.uniform(0.3, 0.7, m)])
        else:
            par = np.repeat(P[:, None], m, 1)
        c, A, B = par
        if circles:
            th_c = rng.uniform(88.0, 89.99, m)
            om = rng.choice([-1.0, 1.0], m) * rng.uniform(1.0, 10.0, m)
            s = np.sin(np.radians(th_c))
            w = (c + ((B - A) * s + c * (1 - c * s)) * om ** 2) / ((B + 1 - c * s) * om)
            cand = np.array([th_c, rng.choice([-1.0, 1.0], m) * 10 ** rng.uniform(-4, -0.5, m),
                             om / TU, w / TU])  # Eq. (28): physics.steady.spin_for_circle
        elif at_rest:
            cand = np.array([-rng.uniform(lo, hi, m), np.zeros(m), rng.uniform(-30.0, 30.0, m),
                             rng.uniform(-30.0, 30.0, m)])
        else:
            tilt = rng.uniform(-89.99, -80.0, m) if below else rng.uniform(85.0, 89.99, m)
            cand = np.array([tilt,
                             rng.uniform(-0.5, 0.5, m) * (rng.random(m) < 0.5),
                             rng.uniform(-13.0, 13.0, m), rng.uniform(-10.0, 10.0, m)])
        obs, st = cycle.cycles_by_quadrature(launch_state(*cand, TU), par, 3.0 / TU)
        end = -np.degrees(obs[ob.O_TH_MIN]) if below else np.degrees(obs[ob.O_TH_MAX])
        keep = (st == cycle.DONE) & (end >= lo) & (end <= hi)
        rows = np.concatenate([rows, cand[:, keep]], axis=1)
        pars = np.concatenate([pars, par[:, keep]], axis=1)
    return rows[:, :n], pars[:, :n]


def mp_cycle(th0, thd0, chd0, phd0, guess_lo, guess_hi, params=P):
    """(turn per cycle rad, theta_min, theta_max rad, the quadrature's error estimate) at 40
    digits, of the non-dimensional launch, from the definitions of the energy, Jellett's and
    Routh's integrals (docs/physics.md section 6), near the kernel's turning points (guesses: the
    roots are bracketed around them)."""
    c, A, B = (mp.mpf(float(v)) for v in params)
    th0, thd0, chd0, phd0 = (mp.mpf(float(v)) for v in (th0, thd0, chd0, phd0))

    def kinetic(s, co, thd, chd, phd):
        w_eta = phd - chd * s
        return (A * (thd ** 2 + chd ** 2 * co ** 2) + B * w_eta ** 2
                + (phd - c * chd) ** 2 * co ** 2 + (1 - 2 * c * s + c ** 2) * thd ** 2) / 2

    s0, c0 = mp.sin(th0), mp.cos(th0)
    E = kinetic(s0, c0, thd0, chd0, phd0) - c * s0
    w0 = phd0 - chd0 * s0
    J = B * w0 * (s0 - c) - A * chd0 * c0 ** 2
    R = w0 * mp.sqrt(A * B + A * c0 ** 2 + B * (s0 - c) ** 2)

    def rates(th):  # (chidot, thetadot^2): Routh's and Jellett's integrals solved at rest in theta
        s, co = mp.sin(th), mp.cos(th)
        w = R / mp.sqrt(A * B + A * co ** 2 + B * (s - c) ** 2)
        chd = (B * w * (s - c) - J) / (A * co ** 2)
        return chd, 2 * (E + c * s - kinetic(s, co, 0, chd, w + chd * s)) / (
            A + 1 - 2 * c * s + c ** 2)

    def F(th):
        return rates(th)[1]

    def root(guess):
        x, d = mp.mpf(float(guess)), mp.mpf("1e-9")
        while True:
            a, b = x - d, min(x + d, mp.pi / 2 - mp.mpf("1e-30"))
            if F(a) * F(b) <= 0:
                return mp.findroot(F, (a, b), solver="anderson")
            d *= 4

    lo, hi = root(guess_lo), root(guess_hi)
    m, h = (lo + hi) / 2, (hi - lo) / 2

    def chd_dt_ds(s):
        chd, f = rates(m + h * mp.sin(s))
        return chd * h * mp.cos(s) / mp.sqrt(f) if f > 0 else mp.mpf(0)

    cuts = [-mp.pi / 2, -mp.pi / 4, 0, mp.pi / 4, 3 * mp.pi / 8, 7 * mp.pi / 16, mp.pi / 2]
    half, err = mp.quad(chd_dt_ds, cuts, error=True)
    return 2 * half, lo, hi, err


def turns_deg(obs, ref) -> np.ndarray:
    """Turn per cycle (deg) as a map labels it, from a kernel's observer slots."""
    quad = np.full_like(ref.formulation, oc.QUADRATURE)
    return classify(ref._replace(obs=obs, formulation=quad),
                    BALL.flat_face_theta_rad)["turn_per_cycle_deg"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--lo", type=float, default=89.5, help="least theta max (deg)")
    ap.add_argument("--hi", type=float, default=89.99, help="largest theta max (deg)")
    ap.add_argument("--against", help="git revision of a kernel to print beside today's")
    ap.add_argument("--circles", action="store_true",
                    help="launches on steady circles near the vertical, nudged in tilt rate")
    ap.add_argument("--below", action="store_true",
                    help="near -90 deg: --lo and --hi bound -theta_min, theta0 -89.99 to -80 deg")
    ap.add_argument("--varied", action="store_true",
                    help="each launch with its own ball: c 0.05-0.5, A and B 0.3-0.7")
    ap.add_argument("--at-rest", action="store_true",
                    help="with --below: launched at rest in theta at theta0 from -hi to -lo deg, "
                         "chidot0 and phidot0 +-30 rad/s (swings up to tens of degrees)")
    args = ap.parse_args()
    if args.n < 1 or not args.lo < args.hi < 90.0:
        ap.error("need --n >= 1 and --lo < --hi < 90")
    mp.mp.dps = 40
    if args.below and args.circles:
        ap.error("--below draws no circles")
    if args.at_rest and not args.below:
        ap.error("--at-rest goes with --below")
    rows, p = draw(args.n, args.lo, args.hi, np.random.default_rng(args.seed), args.circles,
                   args.below, args.varied, args.at_rest)
    y0 = launch_state(*rows, TU)
    T = (15.0 if args.below else 3.0) / TU  # (swings from -90 deg run long)
    kernels = {"today": cycle}
    if args.against:
        text = subprocess.run(["git", "show", f"{args.against}:{REL}"], cwd=ROOT, check=True,
                              capture_output=True, text=True).stdout
        kernels[args.against] = _module(text, "cycle_against", Path(tempfile.mkdtemp()))
    ref = integrate_adaptive(y0, p, T, 1e-12, 1e-15, fixed_frame=True, observer=STEP_OBSERVER,
                             n_slots=ob.N_OBS, h_init=FALLBACK_H_INIT,
                             h_max=FALLBACK_H_MAX / 10, parallel=False)
    fixed = classify(ref, BALL.flat_face_theta_rad)["turn_per_cycle_deg"]
    got, records = {}, {}
    for name, mod in kernels.items():
        obs, st = records[name] = mod.cycles_by_quadrature(y0, p, T, parallel=False)
        end = -np.degrees(obs[ob.O_TH_MIN]) if args.below else np.degrees(obs[ob.O_TH_MAX])
        got[name] = (turns_deg(obs, ref), end, st == cycle.DONE)
    obs_today = records["today"][0]
    mp_turn, mp_tmax, mp_err = (np.empty(y0.shape[1]) for _ in range(3))
    for i in range(y0.shape[1]):
        turn, lo, hi, err = mp_cycle(*y0[[2, 5, 6, 7], i], obs_today[ob.O_TH_MIN, i],
                                 obs_today[ob.O_TH_MAX, i], p[:, i])
        mp_turn[i] = float(fold_deg(np.array([float(mp.degrees(turn))]))[0])
        mp_tmax[i] = -float(mp.degrees(lo)) if args.below else float(mp.degrees(hi))
        mp_err[i] = float(mp.degrees(2 * err))
    swing = np.degrees(obs_today[ob.O_TH_MAX] - obs_today[ob.O_TH_MIN])
    name_end = "-theta min" if args.below else "theta max"
    ball = "balls drawn per launch" if args.varied else "the paper's ball"
    print(f"{y0.shape[1]} launches near the vertical ({ball}, seed {args.seed}), {name_end} "
          f"{args.lo}-{args.hi} deg, swings {swing.min():.2f}-{swing.max():.2f} deg; errors in "
          "deg against mp (40 digits) and the fixed frame (rtol 1e-12)")
    edges = [args.lo] + [e for e in (89.8, 89.9, 89.95) if args.lo < e < args.hi] + [args.hi]
    for a, b in zip(edges[:-1], edges[1:]):
        m = (mp_tmax >= a) & (mp_tmax <= b)
        if not m.any():
            continue
        print(f"  {name_end} {a:.2f}-{b:.2f} deg: {m.sum()} launches")
        for name, (turn, tmax, done) in got.items():
            k = m & done
            if not k.any():
                print(f"    {name:>12}: does none of them")
                continue
            e_mp = np.abs(fold_deg(turn - mp_turn))[k]
            e_fx = np.nanmax(np.abs(fold_deg(turn - fixed))[k])
            e_th = np.abs(tmax - mp_tmax)[k].max()
            print(f"    {name:>12}: does {k.sum()}, turn per cycle {np.nanmax(e_mp):.1e} (mp; "
                  f"over 1e-6: {np.sum(e_mp > 1e-6)}) {e_fx:.1e} (fixed), {name_end} "
                  f"{e_th:.1e} (mp)")
    apart = np.nanmax(np.abs(fold_deg(fixed - mp_turn)))
    print(f"  the references apart: turn per cycle {apart:.1e} deg; mp's own error estimate at "
          f"most {np.nanmax(mp_err):.0e} deg")


if __name__ == "__main__":
    main()

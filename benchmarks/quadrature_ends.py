"""How far F's rounding leaves the quadrature's turning points, and what that does to its turn per
cycle: the figures behind `classify/cycle.py: END_SPREAD_LIMIT`.

    python benchmarks/quadrature_ends.py [--n 300] [--seed 0]

Two kinds of launches, n each (the paper's ball): the headline map's box (theta0 -20..60 deg,
chidot0 +-12, phidot0 +-8 rad/s, a third with thetadot0 up to +-1 rad/s), and small swings near
a steady circle (tilt -20..80 deg, precession +-(1..10) in units of sqrt(g/a), launched 1e-4 to
0.3 deg off the circle's tilt; most have no turning point the quadrature finds and are left to
the integrator anyway). For each launch: the quadrature kernel's record with the refusal
switched off (a stand-alone copy of cycle.py with END_SPREAD_LIMIT = inf) and on, and a
reference, the fixed-frame integration at rtol 1e-12 (another formulation, time stepping).
Printed per bin of the turning points' uncertainty against the half-range, f_noise / |F'| / h
(the kernel's own measure): the launches, how many the kernel refuses, and the largest
turn-per-cycle error of those it would do without the refusal and of those it does.
"""
from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import numpy as np
from quadrature_kernel import _module

from ballsurvey.ball import Ball
from ballsurvey.classify import cycle
from ballsurvey.classify import observer as ob
from ballsurvey.classify.labels import fold_deg
from ballsurvey.compose import FALLBACK_H_INIT, FALLBACK_H_MAX, STEP_OBSERVER, classify
from ballsurvey.integrate import outcome as oc
from ballsurvey.integrate.adaptive import integrate_adaptive
from ballsurvey.physics.euler import jellett, kinetic, routh
from ballsurvey.physics.steady import spin_for_circle
from ballsurvey.units import launch_state

BALL = Ball.paper()
TU = BALL.time_unit
P = BALL.nondim_params()


def launches(n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """(launches (4, 2n): theta0 deg, thetadot0, chidot0, phidot0 rad/s; kind (2n,))."""
    c, A, B = P
    rows, kind = [], []
    for _ in range(n):
        td = rng.uniform(-1, 1) if rng.random() < 1 / 3 else 0.0
        rows.append((rng.uniform(-20, 60), td, rng.uniform(-12, 12), rng.uniform(-8, 8)))
        kind.append(0)
    for k, (lo, hi, om_lo, om_hi) in enumerate(((-20.0, 80.0, 1.0, 10.0),), start=1):
        while sum(1 for x in kind if x == k) < n:
            th_c = rng.uniform(lo, hi)
            om = rng.choice([-1.0, 1.0]) * rng.uniform(om_lo, om_hi)
            w = spin_for_circle(math.radians(th_c), om, c, A, B)
            th0 = th_c + rng.choice([-1.0, 1.0]) * 10 ** rng.uniform(-4, math.log10(0.3))
            if not (math.isfinite(w) and abs(th0) < 89.999):
                continue
            rows.append((th0, 0.0, om / TU, w / TU))
            kind.append(k)
    return np.array(rows).T, np.array(kind)


def spread(y0: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """f_noise / |F'| / h at the worse turning point of each launch, as the kernel measures it."""
    c, A, B = P
    out = np.full(y0.shape[1], np.nan)
    for i in range(y0.shape[1]):
        if not (np.isfinite(lo[i]) and np.isfinite(hi[i]) and hi[i] > lo[i]):
            continue
        args = (math.sin(y0[2, i]), math.cos(y0[2, i]), y0[5, i], y0[6, i], y0[7, i], c, A, B)
        kin = kinetic(*args)
        E, J, R = kin - c * args[0], jellett(*args), routh(*args)
        f_noise = cycle.ROOT_NOISE * 2.2e-16 * (kin + c * abs(args[0]))
        inv = cycle._constants(E, J, R, c, A, B)
        slope = min(abs(cycle._F_dF(t, inv)[1]) for t in (lo[i], hi[i]))
        out[i] = f_noise / slope / (0.5 * (hi[i] - lo[i]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if args.n < 1:
        ap.error("--n must be at least 1")
    rows, kind = launches(args.n, np.random.default_rng(args.seed))
    y0 = launch_state(*rows, TU)
    p = np.repeat(P[:, None], y0.shape[1], 1)
    T = 3.0 / TU
    limit = cycle.END_SPREAD_LIMIT
    # the kernel without the limit: a stand-alone copy of cycle.py with it at infinity, as
    # quadrature_kernel.py builds its copies
    text = Path(cycle.__file__).read_text()
    line = f"END_SPREAD_LIMIT = {limit!r}\n"
    if line not in text:
        raise SystemExit(f"cycle.py has no line {line.strip()!r} to replace")
    with tempfile.TemporaryDirectory() as tmp:
        loose = _module(text.replace(line, "END_SPREAD_LIMIT = math.inf\n"), "cycle_no_limit",
                        Path(tmp))
        obs_free, st_free = loose.cycles_by_quadrature(y0, p, T, parallel=False)
    obs, st = cycle.cycles_by_quadrature(y0, p, T, parallel=False)
    ref = integrate_adaptive(y0, p, T, 1e-12, 1e-15, fixed_frame=True, observer=STEP_OBSERVER,
                             n_slots=ob.N_OBS, h_init=FALLBACK_H_INIT,
                             h_max=FALLBACK_H_MAX / 10, parallel=False)
    want = classify(ref, BALL.flat_face_theta_rad)
    quad = np.full_like(ref.formulation, oc.QUADRATURE)
    got = classify(ref._replace(obs=obs_free, formulation=quad), BALL.flat_face_theta_rad)
    err = np.abs(fold_deg(got["turn_per_cycle_deg"] - want["turn_per_cycle_deg"]))
    s = spread(y0, obs_free[ob.O_TH_MIN], obs_free[ob.O_TH_MAX])
    done_free, done = st_free == cycle.DONE, st == cycle.DONE
    print(f"{y0.shape[1]} launches (box, steady-circle swings: {args.n} each), seed "
          f"{args.seed}; END_SPREAD_LIMIT = {limit:g}; turn per cycle against the fixed frame "
          f"at rtol 1e-12")
    edges = [0.0] + [10.0 ** e for e in range(-14, -2)] + [math.inf]
    for a, b in zip(edges[:-1], edges[1:]):
        m = done_free & np.isfinite(err) & (s >= a) & (s < b)
        if not m.any():
            continue
        kept = m & done
        worst = f"{err[kept].max():.1e} deg" if kept.any() else "-"
        kinds = [int((m & (kind == k)).sum()) for k in range(2)]
        print(f"  spread [{a:.0e}, {b:.0e}): {m.sum():4d} launches (kinds {kinds}), refused "
              f"{(m & ~done).sum():4d}; turn error without the limit {err[m].max():.1e} deg, of "
              f"those done {worst}")


if __name__ == "__main__":
    main()

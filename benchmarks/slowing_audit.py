"""How well `fit_track(slowing=True)` (`ballsurvey fit --slowing`) recovers balls that slow.

Tracks come from scipy's solve_ivp (DOP853, rtol 1e-11) on the fixed-frame Newton-Euler equations
with the rolling-resistance couple written apart from the engine (`ballsurvey.synthetic`,
`resisted_newton_euler`): the centre of mass x, y at 30 frames/s for 3 s with 0.2 mm of Gaussian
noise a coordinate, each launch with the coefficient that takes about `--loss` of its speed a
second: (E(0) - E(T)) / (2 T K) = loss, E the energy, K the mean kinetic energy over the track
(K goes as the speed squared; the speed itself swings through each theta cycle). Each regime's
launch is jittered at random as benchmarks/fit_recovery.py does (theta0 +-2 deg, thetadot0
+-0.3 rad/s, chidot0 and phidot0 +-4 %, any heading, x0, y0 within 5 cm) for each track.

Printed: a row per track (the rms residual over the noise, each parameter's z = (estimate -
truth) / sigma), then the share of all the estimates within 2 and 3 of their stated standard
deviations (the 2-sigma coverage should be near 95 %), and with --plain the same tracks fitted
without the slowing for comparison.

    python benchmarks/slowing_audit.py [--per 2] [--seed 0] [--loss 0.03] [--plain]
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from fit_recovery import jitter  # benchmarks/fit_recovery.py, beside this script

from ballsurvey.ball import Ball
from ballsurvey.fit import PARAMS, SLOWING, fit_track, make_track
from ballsurvey.synthetic import fixed_frame_states, resisted_energy_and_power, synthetic_track

REGIMES = {
    "square (Fig. 12a)": dict(theta0_deg=-5.0, thetadot0=0.0, chidot0=4.05, phidot0=-3.0),
    "triangle (Fig. 12b)": dict(theta0_deg=-10.0, thetadot0=0.0, chidot0=2.3, phidot0=-2.5),
    "circle (Fig. 9a)": dict(theta0_deg=20.0, thetadot0=0.0, chidot0=10.0, phidot0=-2.9),
    "circle (Fig. 9c)": dict(theta0_deg=40.0, thetadot0=0.0, chidot0=5.0, phidot0=-7.5),
}
FPS, T, NOISE_M = 30.0, 3.0, 2e-4
#: a first guess of the coefficient, rescaled to the loss asked for from its own track
MU_GUESS = 5e-4


def speed_loss(kw: dict, mu: float) -> float:
    """Share of its speed launch kw loses a second with coefficient mu (module docstring)."""
    ball = Ball.paper()
    p = ball.nondim_params()
    t = np.arange(int(T * FPS) + 1) / FPS
    v = fixed_frame_states(**kw, t=t, ball=ball, rolling_resistance=mu)
    e = np.array([resisted_energy_and_power(r, *p, mu)[0] for r in v])
    kinetic = e - (1.0 + p[0] * v[:, 4])  # V = M g (a + c e_z)
    return (e[0] - e[-1]) / (2 * T * kinetic.mean())


def slowing_track(kw: dict, loss: float, seed: int):
    """The noisy track of launch kw slowing by about `loss` a second, and its coefficient."""
    mu = MU_GUESS * loss / speed_loss(kw, MU_GUESS)
    tr = synthetic_track(**kw, T=T, fps=FPS, noise_m=NOISE_M, seed=seed, rolling_resistance=mu)
    return tr, mu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--per", type=int, default=2, help="tracks per regime")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--loss", type=float, default=0.03, help="speed lost a second (share)")
    ap.add_argument("--plain", action="store_true",
                    help="also fit each track without the slowing, for comparison")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    names = PARAMS + (SLOWING,)
    fits = {True: [], False: []} if args.plain else {True: []}
    print(f"{len(REGIMES) * args.per} tracks: {FPS:g} frames/s, {T:g} s, noise {NOISE_M * 1e3:g} "
          f"mm, speed loss {args.loss:.0%}/s\n")
    print("| track | mu_r | fit | rms / noise | " + " | ".join(f"z {k}" for k in names)
          + " | s |")
    print("|" + "---|" * (len(names) + 5))
    for regime, base in REGIMES.items():
        for j in range(args.per):
            kw = jitter(base, rng)
            tr, mu = slowing_track(kw, args.loss, seed=int(rng.integers(1 << 30)))
            truth = dict(kw, **{SLOWING: mu})
            track = make_track(tr["t"], tr["x"], tr["y"], source=regime)
            for slowing in fits:
                t0 = time.perf_counter()
                fit = fit_track(track, slowing=slowing)
                sec = time.perf_counter() - t0
                keys = names if slowing else PARAMS
                z = {k: (fit[k] - truth[k]) / fit[f"{k}_err"] for k in keys}
                if "chi0_deg" in z:  # an angle: the nearest turn
                    d = (fit["chi0_deg"] - truth["chi0_deg"] + 180.0) % 360.0 - 180.0
                    z["chi0_deg"] = d / fit["chi0_deg_err"]
                fits[slowing].append(z)
                print(f"| {regime} {j + 1} | {mu:.3g} | {'slowing' if slowing else 'plain'} | "
                      f"{fit['rms_m'] / NOISE_M:.2f} | "
                      + " | ".join(f"{z[k]:+.2f}" if k in z else "" for k in names)
                      + f" | {sec:.1f} |", flush=True)
    print()
    for slowing, zs in fits.items():
        allz = np.abs(np.array([v for z in zs for v in z.values()]))
        print(f"{'fit --slowing' if slowing else 'fit (plain)  '}: {np.mean(allz < 2):.1%} of "
              f"{allz.size} estimates within 2 sigma, {np.mean(allz < 3):.1%} within 3 sigma, "
              f"largest |z| {allz.max():.1f}")


if __name__ == "__main__":
    main()

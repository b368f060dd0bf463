"""The fixed-step maps' observer: the step observer at each launch's own spans against the sampling
observer every `observe_every` steps, on the same RK4 steps: cost above the bare kernel and
accuracy against the quadrature (an independent formulation: every launch from its invariants).

Launches: a spec's (default the square map, 1845 launches, T = 20 s, dt = 1e-4 s). The three
kernels (bare: no observer; sampling; steps) are timed in turns, best of `--repeats`, warm, on
numba's threads, so the machine's noise hits them alike. Accuracy: the labelled fields of both
observers (the map's fixed-frame fallback included) against `method = "quadrature"` on the same
launches, over those with a shape that the Euler chart carried. Needs only ballsurvey:

    python benchmarks/step_observer_span.py [--spec sweeps/square-map.toml] [--repeats 3]

`--random N` draws N launches instead (theta0 -20..80 deg, thetadot0 -3..3, chidot0 -12..12,
phidot0 -8..8 rad/s; `--seed`, `--T` s, `--period`: two theta cycles, at most T), RK4 at dt =
1e-4 s, and compares both observers on every step (`observe_every` 1) with the quadrature.
"""
from __future__ import annotations

import argparse
import time

import numba
import numpy as np

from ballsurvey.ball import Ball
from ballsurvey.classify.labels import CODE, SHAPES
from ballsurvey.classify.observer import N_OBS
from ballsurvey.compose import (
    FIXED_STEP_OBSERVER,
    OBSERVER,
    classify,
    launch_arrays,
    near_vertical_fallback,
    run_launches,
    stop_target,
)
from ballsurvey.integrate import ensemble
from ballsurvey.sweep.plan import launch_table
from ballsurvey.sweep.spec import load_spec
from ballsurvey.units import StepPlan, launch_state

FIELDS = (("turn_per_cycle_deg", "deg", False), ("theta_max_deg", "deg", False),
          ("theta_min_deg", "deg", False), ("roundness", "", False),
          ("theta_period_s", "relative", True), ("corner_sharpness", "relative", True),
          ("n_sides", "relative", True))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default="sweeps/square-map.toml")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--random", type=int, default=0, metavar="N")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--T", type=float, default=6.0)
    ap.add_argument("--period", action="store_true")
    args = ap.parse_args()
    if args.random < 0 or not args.T > 0:
        ap.error("--random must be at least 1 and --T above 0")
    if not args.random and (args.period or args.T != 6.0 or args.seed != 1):
        ap.error("--seed, --T and --period go with --random (a spec has its own T and mode)")
    stop = 0
    if args.random:
        ball = Ball.paper()
        rng = np.random.default_rng(args.seed)
        n = args.random
        y0 = launch_state(rng.uniform(-20, 80, n), rng.uniform(-3, 3, n),
                          rng.uniform(-12, 12, n), rng.uniform(-8, 8, n), ball.time_unit)
        p = np.repeat(ball.nondim_params()[:, None], n, 1)
        flat, method, every, block = ball.flat_face_theta_rad, "rk4", 1, 64
        plan = StepPlan(args.T, 1e-4, ball.time_unit)
        stop = stop_target(2) if args.period else 0
        args.spec = f"{n} random launches (seed {args.seed}, T {args.T} s" + (
            ", period mode)" if args.period else ")")
    else:
        spec = load_spec(args.spec)
        y0, p, tu, flat = launch_arrays(launch_table(spec, 0, spec.n_launches))
        plan = StepPlan(spec.T, spec.dt, tu)
        method, every, block = spec.method, spec.observe_every, spec.block

    def run(observer, n_slots):
        return ensemble.integrate(y0, p, plan.dt_nd, plan.n_steps, method,
                                  observer=observer, n_slots=n_slots, block=block,
                                  observe_every=every, stop_after=stop)

    kernels = {"bare kernel": (OBSERVER, 0), f"sampling, every {every} steps": (OBSERVER, N_OBS),
               "steps, own spans (the map's)": (FIXED_STEP_OBSERVER, N_OBS)}
    for observer, n_slots in kernels.values():  # compile or load
        ensemble.integrate(y0[:, :2], p[:, :2], plan.dt_nd, 10, method, observer=observer,
                           n_slots=n_slots)
    best = {k: np.inf for k in kernels}
    results = {}
    for _ in range(args.repeats):
        for name, (observer, n_slots) in kernels.items():
            t = time.perf_counter()
            results[name] = run(observer, n_slots)
            best[name] = min(best[name], time.perf_counter() - t)
    print(f"{args.spec}: {y0.shape[1]} launches x {plan.n_steps} {method} steps, "
          f"{numba.get_num_threads()} numba threads, best of {args.repeats}")
    bare = best["bare kernel"]
    for name, t in best.items():
        extra = "" if name == "bare kernel" or stop else (
            f"  (+{100 * (t / bare - 1):.0f} % of the bare)")  # period mode: the bare runs to T
        print(f"  {name:32s} {t:6.2f} s{extra}")

    q = classify(run_launches(y0, p, plan, "quadrature", cycles=2 if stop else 0), flat)
    labelled = {}
    for name in list(kernels)[1:]:
        res = results[name]
        near_vertical_fallback(y0, p, plan.T_nd, res, stop_after=stop)
        labelled[name] = classify(res, flat)
    first = next(iter(labelled.values()))
    shaped = np.isin(first["label"], [CODE[w] for w in SHAPES]) & (first["formulation"] == 0)
    if not shaped.any():
        print("against the quadrature: no launch has a shape in the Euler chart (T too short "
              "for two theta cycles?): nothing to compare")
        return
    print(f"against the quadrature, {shaped.sum()} launches with a shape in the Euler chart "
          f"(largest difference):")
    print(f"  {'':24s}" + "".join(f"{n.split(',')[0]:>12s}" for n in labelled))
    for field, unit, rel in FIELDS:
        row = []
        for f in labelled.values():
            d = np.abs(f[field] - q[field])[shaped]
            if rel:
                d = d / np.abs(q[field][shaped])
            row.append(f"{np.nanmax(d):12.2g}")
        print(f"  {field + (' (' + unit + ')' if unit else ''):24s}" + "".join(row))
    for name, f in labelled.items():
        same = np.mean(f["label"] == q["label"])
        spc = f["samples_per_cycle"][shaped]
        print(f"  {name.split(',')[0]}: labels as the quadrature's on {100 * same:.2f} %, "
              f"points a theta cycle {np.nanmin(spc):.0f} (least) {np.nanmedian(spc):.0f} "
              f"(median)")


if __name__ == "__main__":
    main()

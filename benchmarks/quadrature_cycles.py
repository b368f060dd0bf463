"""Where the quadrature kernel's time goes, launch by launch, counted by the CPU's cycle counter:
the turning points (the search and Newton's method), the Clenshaw-Curtis levels until the period
and turn converge, the path at the level before (rates, cumulative integrals, the heading's
variation) and the rest (the orbit's centre and radii, the count of maxima, the slots).

`classify/cycle.py` is compiled again from a temporary copy, uncached, with counters between
its phases (as `quadrature_kernel.py` builds its copies); each launch's four counts come back in
its first observer slots (so the copy's fields are for timing only). The same launches through
the kernel as shipped, for scale. One thread, serially. Launches: a random sample of the
headline map's box (thetadot0 = 0; `--tilt-rate`: a third with a rate of up to 3 rad/s, where
both turning points are searched). Needs only ballsurvey:

    python benchmarks/quadrature_cycles.py [--launches 20000] [--tilt-rate]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from cycle_counter import patched
from quadrature_kernel import _module

from ballsurvey.ball import Ball
from ballsurvey.classify import cycle
from ballsurvey.units import launch_state

PATCHES = (
    ("    s0, c0 = math.sin(th0), math.cos(th0)\n",
     "    cy0 = rdtsc()\n    s0, c0 = math.sin(th0), math.cos(th0)\n"),
    # (led by a newline: the same line indented deeper solves a small swing's end again)
    ("\n    m, h = 0.5 * (hi + lo), 0.5 * (hi - lo)\n",
     "\n    cy1 = rdtsc()\n    m, h = 0.5 * (hi + lo), 0.5 * (hi - lo)\n"),
    ("    per_fine, turn_fine = per, turn\n",
     "    cy2 = rdtsc()\n    per_fine, turn_fine = per, turn\n"),
    ("    period, dchi = 2.0 * per_fine, 2.0 * turn_fine\n",
     "    cy3 = rdtsc()\n    period, dchi = 2.0 * per_fine, 2.0 * turn_fine\n"),
    ("    obs[ob.O_TH_STEP, i] = math.pi * (hi - lo) / (2.0 * n)\n    return DONE\n",
     "    obs[ob.O_TH_STEP, i] = math.pi * (hi - lo) / (2.0 * n)\n    cy4 = rdtsc()\n"
     "    obs[0, i] = cy1 - cy0\n    obs[1, i] = cy2 - cy1\n    obs[2, i] = cy3 - cy2\n"
     "    obs[3, i] = cy4 - cy3\n    obs[4, i] = level\n    return DONE\n"),
)
PHASES = ("turning points", "levels", "path", "the rest")


def counted_module(folder: Path):
    """cycle.py with the counters, as `quadrature_kernel.py` builds a stand-alone copy."""
    return _module(patched(Path(cycle.__file__).read_text(), PATCHES), "cycle_counted", folder)


def _timed(counted, y0, p, T, tabs) -> dict:
    """{"counted"|"shipped": (best seconds of 3, obs, status)}: each kernel serially on y0."""
    n = y0.shape[1]
    out = {}
    for name, mod in (("counted", counted), ("shipped", cycle)):
        obs, status = np.empty((cycle.ob.N_OBS, n)), np.zeros(n, dtype=np.int8)
        mod._block(y0[:, :2], p[:, :2], T, 2, 1e-8, *tabs, 0, 2, obs, status)  # compiled
        best = np.inf
        for _ in range(3):
            t = time.perf_counter()
            mod._block(y0, p, T, 2, 1e-8, *tabs, 0, n, obs, status)
            best = min(best, time.perf_counter() - t)
        out[name] = (best, obs.copy(), status.copy())
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--launches", type=int, default=20000)
    ap.add_argument("--tilt-rate", action="store_true")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if args.launches < 1:
        ap.error("--launches must be at least 1")
    ball = Ball.paper()
    rng = np.random.default_rng(args.seed)
    n = args.launches
    thd = np.where(rng.random(n) < 1 / 3, rng.uniform(-3, 3, n), 0.0) if args.tilt_rate else 0.0
    y0 = launch_state(rng.uniform(-20, 60, n), thd, rng.uniform(-12, 12, n),
                      rng.uniform(-8, 8, n), ball.time_unit)
    p = np.repeat(ball.nondim_params()[:, None], n, 1)
    T = 20.0 / ball.time_unit
    tabs = cycle.tables()
    with tempfile.TemporaryDirectory() as tmp:
        out = _timed(counted_module(Path(tmp)), y0, p, T, tabs)
    t_c, obs, status = out["counted"]
    done = status == cycle.DONE
    phases = obs[:4, done]
    total = phases.sum(axis=0).mean()
    rate = " (a third with a tilt rate)" if args.tilt_rate else ""
    print(f"{n} launches of the headline box{rate}, one thread: the shipped kernel "
          f"{1e6 * out['shipped'][0] / n:.2f} us a launch, the counted copy "
          f"{1e6 * t_c / n:.2f} us ({total / (t_c / n) / 1e9:.2f} GHz counter); "
          f"{done.mean():.2%} done by quadrature")
    for k, name in enumerate(PHASES):
        v = phases[k].mean()
        print(f"  {name:15s} {v:6.0f} cycles a launch ({100 * v / total:.0f} %)")
    path_level = obs[4, done].astype(int)
    levels = ", ".join(f"N = {cycle.FIRST_N << (k + 1)}: {int((path_level == k).sum())}"
                       for k in np.unique(path_level))
    print(f"  converged at ({levels} launches), the path taken at the level before")


if __name__ == "__main__":
    main()

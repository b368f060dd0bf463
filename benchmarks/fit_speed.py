"""Time to fit a 3 s track at 300 frames/s (the paper's square, Fig. 12a, its centre of mass
from scipy's DOP853 on the fixed-frame equations, 0.2 mm noise), beside the same track fitted by
a baseline `fit.py` from git (default: the revision before status, ambiguity and mismatch were
added), back to back in this process, best of --repeat each. Prints both, their ratio and the
load average, so a figure taken on a busy machine says so.

    python benchmarks/fit_speed.py [--repeat 3] [--base 333b3ed]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
import types
from pathlib import Path

from ballsurvey.fit import fit_track, make_track
from ballsurvey.synthetic import synthetic_track

ROOT = Path(__file__).resolve().parents[1]


def base_module(rev: str):
    """The fit module as it was at git revision `rev`, loaded inside the installed package (its
    relative imports resolve to today's neighbours)."""
    src = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:src/ballsurvey/fit.py"],
                         check=True, capture_output=True, text=True).stdout
    mod = types.ModuleType("ballsurvey._fit_base")
    mod.__package__ = "ballsurvey"
    mod.__file__ = f"{rev}:src/ballsurvey/fit.py"
    sys.modules[mod.__name__] = mod
    exec(compile(src, mod.__file__, "exec"), mod.__dict__)
    return mod


def best_of(fn, n):
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--base", default="333b3ed", help="git revision of the baseline fit.py")
    args = ap.parse_args()
    tr = synthetic_track(-5.0, 0.0, 4.05, -3.0, chi0_deg=40.0, T=3.0, fps=300, noise_m=2e-4,
                         seed=11)
    track = make_track(tr["t"], tr["x"], tr["y"])
    base = base_module(args.base)
    btrack = base.make_track(tr["t"], tr["x"], tr["y"])
    fit_track(track)  # compile or load the kernels outside the timings
    base.fit_track(btrack)
    print(f"load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())} "
          f"({os.cpu_count()} CPUs)")
    t_new, fit = best_of(lambda: fit_track(track), args.repeat)
    t_base, bfit = best_of(lambda: base.fit_track(btrack), args.repeat)
    print(f"fit of a 3 s track at 300 frames/s ({track.t.size} samples), best of "
          f"{args.repeat}:")
    print(f"  this tree        {t_new:6.2f} s  status {fit['status']}, theta0 "
          f"{fit['theta0_deg']:.3f} +- {fit['theta0_deg_err']:.3f} deg")
    print(f"  base {args.base:10s} {t_base:6.2f} s  theta0 {bfit['theta0_deg']:.3f} +- "
          f"{bfit['theta0_deg_err']:.3f} deg")
    print(f"  ratio            {t_new / t_base:6.2f}x")
    print(f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()

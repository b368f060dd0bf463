"""The quadrature kernel (`classify/cycle.py`) against the same file at another git revision, side
by side in one process: the same launches (a random sample of the headline map's box, a third of
them with a tilt rate when --tilt-rate), each kernel run serially on one thread, alternately,
best of --repeats by the thread's CPU time (a shared machine steals wall time, less CPU time).
Prints microseconds a launch for both, their ratio, and how far the two records differ (the
largest relative difference in period, turn, theta range and radii from the orbit centre over
the launches both did, and the launches whose status differs):

    python benchmarks/quadrature_kernel.py --against b532d69 [--launches 40000] [--repeats 7]

The revision's file is compiled from a temporary copy (no disk cache), as is today's, so both
pay the same compiler and neither reads a stale cache.
"""
from __future__ import annotations

import argparse
import importlib.util
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ballsurvey.bench import headline_spec
from ballsurvey.classify import observer as ob
from ballsurvey.compose import launch_arrays
from ballsurvey.sweep.plan import launch_table
from ballsurvey.sweep.spec import load_spec

ROOT = Path(__file__).resolve().parents[1]
REL = "src/ballsurvey/classify/cycle.py"


def _module(text: str, name: str, folder: Path):
    """cycle.py's text as a stand-alone module: absolute imports, numba's own njit, no cache."""
    # `from .._jit import ..., njit` (whatever else a revision takes from it): numba's njit,
    # the rest from the package
    text = re.sub(r"from \.\._jit import (?:([\w, ]+), )?njit",
                  lambda m: "from numba import njit" + (
                      f"\nfrom ballsurvey._jit import {m.group(1)}" if m.group(1) else ""), text)
    text = (text.replace("from ..physics", "from ballsurvey.physics")
            .replace("from . import observer", "from ballsurvey.classify import observer")
            .replace("from .trig import", "from ballsurvey.classify.trig import")
            .replace("cache=True", "cache=False"))
    path = folder / f"{name}.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--against", required=True, help="git revision of the baseline kernel")
    ap.add_argument("--launches", type=int, default=40000)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--tilt-rate", action="store_true",
                    help="a third of the launches with thetadot0 in [-2, 2] rad/s")
    args = ap.parse_args()
    import numba

    numba.set_num_threads(1)
    old_text = subprocess.run(["git", "show", f"{args.against}:{REL}"], cwd=ROOT, check=True,
                              capture_output=True, text=True).stdout
    n = 100
    spec = load_spec("headline.toml", text=headline_spec(n, method="quadrature", out="x.nc"))
    y0, params, tu, _ = launch_arrays(launch_table(spec, 0, n ** 3))
    rng = np.random.default_rng(0)
    pick = np.sort(rng.choice(n ** 3, args.launches, replace=False))
    y0, params = np.ascontiguousarray(y0[:, pick]), np.ascontiguousarray(params[:, pick])
    if args.tilt_rate:
        y0[5] = np.where(np.arange(y0.shape[1]) % 3 == 0,
                         rng.uniform(-2, 2, y0.shape[1]) * tu, 0.0)
    T = 20.0 / tu
    with tempfile.TemporaryDirectory() as tmp:
        kernels = {"baseline": _module(old_text, "cycle_baseline", Path(tmp)),
                   "today": _module((ROOT / REL).read_text(), "cycle_today", Path(tmp))}
        out = {k: m.cycles_by_quadrature(y0, params, T, stop_after=2, parallel=False)
               for k, m in kernels.items()}
        best = dict.fromkeys(kernels, np.inf)
        for _ in range(args.repeats):
            for k, m in kernels.items():
                t = time.thread_time()
                m.cycles_by_quadrature(y0, params, T, stop_after=2, parallel=False)
                best[k] = min(best[k], time.thread_time() - t)
    us = {k: v / y0.shape[1] * 1e6 for k, v in best.items()}
    print(f"{y0.shape[1]} launches of the headline box, one thread, best of {args.repeats} "
          f"(CPU time):")
    print(f"  baseline ({args.against}): {us['baseline']:.2f} us a launch")
    print(f"  today: {us['today']:.2f} us a launch ({us['baseline'] / us['today']:.2f}x)")
    (o1, s1), (o2, s2) = out["baseline"], out["today"]
    both = (s1 == 0) & (s2 == 0)
    worst, where = 0.0, ""
    for name in ("O_C_DUR", "O_C_RAW", "O_TH_MIN", "O_TH_MAX", "O_C_RMIN", "O_C_RMAX"):
        a, b = o1[getattr(ob, name), both], o2[getattr(ob, name), both]
        rel = np.abs(a - b) / np.maximum(np.abs(a), np.abs(b))
        rel = rel[np.isfinite(rel)]
        if rel.size and rel.max() > worst:
            worst, where = rel.max(), name
    print(f"  period, turn, theta range and radii: largest relative difference {worst:.1e}"
          + (f" ({where})" if where else "") + f"; status differs on {(s1 != s2).sum()} launches")

if __name__ == "__main__":
    main()

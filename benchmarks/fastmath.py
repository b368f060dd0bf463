"""What LLVM's fast-math flags would buy the kernels of `ballsurvey bench` (4096 launches x 2000
RK4 steps, dt = 1e-4 s, a sample every 4 steps), measured, not kept.

The package compiles every kernel without fast-math (ensemble.py says why: a launch's bits must
not depend on where it sits in a SIMD block, and FMA contraction or reassociation may treat the
vector body and the scalar remainder differently). This asks what that costs. Each variant runs
`run_bench` in a fresh process whose `ballsurvey._jit.njit` adds `fastmath=FLAGS` to every jitted
function of the package (they are all made through it, so the physics that the kernels inline
gets the flags too), with its own numba and kernel caches in a temporary directory, never the
user's. Variants run in turns, `--rounds` times, so the machine's noise hits them alike; the
first round compiles (bench times after its own warm-up). Needs only ballsurvey:

    python benchmarks/fastmath.py [--flags contract] [--flags fast] [--rounds 2]

"fast" is every LLVM fast-math flag (numba's fastmath=True).
"""
from __future__ import annotations

import argparse
import ast
import os
import subprocess
import sys
import tempfile

_CHILD = """
import sys
flags = sys.argv[1]
import ballsurvey._jit as J
if flags != "none":
    fm = True if flags == "fast" else set(flags.split(","))
    plain = J.njit

    def njit(*, cache=False, **options):
        options.setdefault("fastmath", fm)
        return plain(cache=cache, **options)

    J.njit = njit
from ballsurvey.bench import run_bench
print(repr(run_bench(repeats=3, out=lambda *a: None)))
"""


def _run(flags: str, cache: str) -> dict:
    env = dict(os.environ, BALLSURVEY_CACHE_DIR=os.path.join(cache, "kernels"),
               NUMBA_CACHE_DIR=os.path.join(cache, "numba"))
    r = subprocess.run([sys.executable, "-c", _CHILD, flags], env=env, capture_output=True,
                       text=True, check=True)
    return ast.literal_eval(r.stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--flags", action="append",
                    help="LLVM fast-math flags, comma-separated, or 'fast' (repeatable; "
                         "default: contract and fast)")
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args(argv)
    variants = ["none"] + (args.flags or ["contract", "fast"])
    best: dict = {}
    with tempfile.TemporaryDirectory(prefix="ballsurvey-fastmath-") as tmp:
        for r in range(args.rounds):
            for v in variants:
                got = _run(v, os.path.join(tmp, v.replace(",", "_")))
                print(f"round {r + 1}  {v:<24} with observer {got['ensemble_with_observer']:.3e}"
                      f"  bare {got['ensemble_bare']:.3e}  naive {got['naive']:.3e} IC-steps/s",
                      flush=True)
                for key in ("ensemble_with_observer", "ensemble_bare", "naive"):
                    best.setdefault(v, {})[key] = max(best.get(v, {}).get(key, 0.0), got[key])
    base = best["none"]
    print(f"\nbest of {args.rounds} rounds (IC-steps/s; in brackets: times the same kernel "
          f"without fast-math, then times the naive loop without fast-math)")
    print(f"  {'fastmath':<24}{'with observer':>30}{'bare kernel':>30}")
    for v in variants:
        cells = []
        for key in ("ensemble_with_observer", "ensemble_bare"):
            x = best[v][key]
            cells.append(f"{x:.3e} ({x / base[key]:.2f}x, {x / base['naive']:.1f}x)")
        print(f"  {v:<24}{cells[0]:>30}{cells[1]:>30}")


if __name__ == "__main__":
    main()

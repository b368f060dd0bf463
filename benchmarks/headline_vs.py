"""The headline map (`ballsurvey bench --headline N`) of this checkout against a frozen copy of
another commit's code, back to back on the same machine: each round runs both, in fresh
processes, in turns, so machine noise falls on both alike.

    python benchmarks/headline_vs.py --ref REF [--n 40] [--rounds 3]

REF is any git revision; its source tree is checked out (git worktree, detached) into a
temporary folder and imported from there (PYTHONPATH=<that folder>/src) by this same Python, so
both use the same numba, numpy and dependencies. Prints, for each, the best wall time, the
integration's own time, and the label agreement with full RK4 integration that `bench
--headline` measures, then the ratio of the best wall times.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def headline(src: Path, n: int, sample: int) -> dict:
    """One `bench --headline n` in a fresh process importing ballsurvey from src."""
    env = dict(os.environ, PYTHONPATH=str(src))
    code = ("import json; from ballsurvey.bench import run_headline; "
            f"r = run_headline(n={n}, sample={sample}, out=lambda s: None); "
            "print(json.dumps({'wall': r['wall_s'], 'integrate': r['times']['integrate'], "
            "'agree': 100 * r['agreement']}))")
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"headline from {src} failed: {r.stderr.strip().splitlines()[-1:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", required=True, help="git revision to compare against")
    ap.add_argument("--n", type=int, default=40, help="the map is n^3 launches (default 40)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--sample", type=int, default=1000,
                    help="launches checked against full RK4 integration")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "ref"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(base),
                        args.ref], check=True)
        try:
            sources = {f"ref {args.ref}": base / "src", "this checkout": ROOT / "src"}
            for src in sources.values():  # compile or load the kernels, untimed
                headline(src, 4, 10)
            best = {k: None for k in sources}
            for _ in range(args.rounds):
                for name, src in sources.items():
                    r = headline(src, args.n, args.sample)
                    if best[name] is None or r["wall"] < best[name]["wall"]:
                        best[name] = r
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base)],
                           check=False)
    print(f"headline {args.n}^3 map, best of {args.rounds} rounds (each round both, in turns; "
          f"fresh processes)")
    for name, r in best.items():
        print(f"  {name:28s} wall {r['wall']:6.2f} s  integrate {r['integrate']:6.2f} s  "
              f"labels agree with full RK4: {r['agree']:.1f} %")
    ref, new = best[f"ref {args.ref}"], best["this checkout"]
    print(f"  speed-up: wall {ref['wall'] / new['wall']:.2f}x, integrate "
          f"{ref['integrate'] / new['integrate']:.2f}x")


if __name__ == "__main__":
    main()

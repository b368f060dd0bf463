"""The first `ballsurvey sweep` after an install, cold: every numba cache empty.

    python benchmarks/first_run.py [--spec sweeps/quick.toml] [--ref REF] [--rounds 1]

Each run is a fresh process (`python -m ballsurvey sweep SPEC -v`) in a fresh temporary folder,
with NUMBA_CACHE_DIR (numba's cache of the package's functions) and BALLSURVEY_CACHE_DIR (the
generated kernel modules and their numba cache) pointing at empty folders inside it, so nothing
compiled before is found: what a new user meets after `pip install`. Prints the wall time of the
whole command, its CPU time (user + system: on a busy machine the wall time also counts the
waits for a core), and the seconds the sweep itself reports as compiling kernels.

--ref REF: the same, in turns, with a frozen checkout of another git revision (git worktree,
detached, imported from there by this same Python), so both figures come from one command on
the same machine; the ratio of the best wall times is printed last. --busy S: every core spins
for S seconds before each run, as an install does (the load average then reads above 1 while the
cores are idle). --one-thread: also this
checkout with NUMBA_NUM_THREADS=1, where the fixed-frame fallback is compiled in the run's own
process after its kernel instead of in a helper process beside it. The load average before
each run is printed with it: other work on the machine inflates the wall times.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def first_run(src: Path, spec: Path, threads: int | None = None) -> dict:
    """One cold `ballsurvey sweep spec -v` importing ballsurvey from src (threads: numba's)."""
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(Path(tmp) / "numba"),
                   BALLSURVEY_CACHE_DIR=str(Path(tmp) / "kernels"))
        if threads:
            env["NUMBA_NUM_THREADS"] = str(threads)
        load = os.getloadavg()[0]
        r0 = os.times()
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "ballsurvey", "sweep", str(spec), "-v"],
                           env=env, cwd=tmp, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        r1 = os.times()
    if r.returncode != 0:
        raise SystemExit(f"sweep from {src} failed: {(r.stderr or r.stdout).strip()[-500:]}")
    m = re.search(r"\(([\d.]+) s of it compiling kernels\)", r.stdout + r.stderr)
    return {"wall": wall, "cpu": (r1.children_user - r0.children_user)
            + (r1.children_system - r0.children_system),
            "compile": float(m.group(1)) if m else float("nan"), "load": load}


def busy(seconds: float) -> None:
    """Every core of this machine spinning for `seconds` (one process each)."""
    spin = f"import time\nt = time.time()\nwhile time.time() - t < {seconds}: pass"
    procs = [subprocess.Popen([sys.executable, "-c", spin]) for _ in range(os.cpu_count() or 1)]
    for p in procs:
        p.wait()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default=str(ROOT / "sweeps" / "quick.toml"))
    ap.add_argument("--ref", help="git revision to run the same against")
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--one-thread", action="store_true",
                    help="also this checkout with one numba thread (no helper process: the "
                         "fallback compiles in the run's own process, after its kernel)")
    ap.add_argument("--busy", type=float, default=0.0, metavar="S",
                    help="before each run, keep every core busy for S seconds (spinning "
                         "processes), as an install does: the run then starts on idle cores "
                         "with a load average above 1")
    args = ap.parse_args()
    spec = Path(args.spec).resolve()
    with tempfile.TemporaryDirectory() as tmp:
        sources = {"this checkout": ROOT / "src"}
        if args.ref:
            base = Path(tmp) / "ref"
            subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q",
                            str(base), args.ref], check=True)
            sources = {f"ref {args.ref}": base / "src", **sources}
        variants = {k: (src, None) for k, src in sources.items()}
        if args.one_thread:
            variants["this checkout, 1 thread"] = (ROOT / "src", 1)
        try:
            runs = {k: [] for k in variants}
            for _ in range(args.rounds):
                for name, (src, threads) in variants.items():
                    if args.busy > 0:
                        busy(args.busy)
                    runs[name].append(r := first_run(src, spec, threads))
                    print(f"  {name:30s} wall {r['wall']:6.1f} s  cpu {r['cpu']:6.1f} s  "
                          f"compiling {r['compile']:6.1f} s  (load average {r['load']:.1f} "
                          f"before)", flush=True)
        finally:
            if args.ref:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                                str(base)], check=False)
    print(f"first sweep of {spec.name}, cold (empty caches), best of {args.rounds}, "
          f"{os.cpu_count()} cores")
    best = {k: min(v, key=lambda r: r["wall"]) for k, v in runs.items()}
    for name, r in best.items():
        print(f"  {name:30s} wall {r['wall']:6.1f} s  cpu {r['cpu']:6.1f} s  "
              f"compiling {r['compile']:6.1f} s")
    if args.ref:
        ref, new = best[f"ref {args.ref}"], best["this checkout"]
        print(f"  speed-up: wall {ref['wall'] / new['wall']:.2f}x, cpu "
              f"{ref['cpu'] / new['cpu']:.2f}x")


if __name__ == "__main__":
    main()

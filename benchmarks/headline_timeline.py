"""Where the headline map's time goes in the sweep: each named function's calls, wall time and
thread CPU time, by thread, for one `bench --headline`-sized sweep (after a warm-up sweep),
and then the same sweep with the part writer's work (labels, part files, netCDF slabs) stubbed
out, to show what that work costs the kernel calls beside it:

    python benchmarks/headline_timeline.py [--method quadrature] [--n 100] [--chunk 8192]

The stubbed sweep fails at its assembly (there are no parts to assemble): only its kernel
calls and its wall time up to then are printed. Figures for timing only.
"""
from __future__ import annotations

import argparse
import collections
import functools
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from ballsurvey import compose, store
from ballsurvey.ball import Ball
from ballsurvey.bench import headline_spec
from ballsurvey.classify import cycle
from ballsurvey.sweep import compute, engine, load_spec, run_sweep

EVENTS: list = []
CPU: dict = collections.defaultdict(float)


def _timed(owner, name, tag):
    f = getattr(owner, name)

    @functools.wraps(f)
    def g(*a, **k):
        t, c = time.perf_counter(), time.thread_time()
        try:
            return f(*a, **k)
        finally:
            who = (tag, threading.current_thread().name)
            CPU[who] += time.thread_time() - c
            EVENTS.append((who, t, time.perf_counter()))
    setattr(owner, name, g)


def _sweep(tmp: Path, n: int, method: str, chunk: int) -> tuple[float, bool]:
    text = headline_spec(n, method=method, out=str(tmp / f"h{n}.nc"))
    spec = load_spec(tmp / "h.toml", text=text.replace("chunk = 8192", f"chunk = {chunk}"))
    t0 = time.perf_counter()
    try:
        run_sweep(spec, command="timeline", progress=False, force=True, parallel=True,
                  notice=lambda line: None)
        ok = True
    except Exception:  # noqa: BLE001 - the stubbed sweep cannot assemble
        ok = False
    return time.perf_counter() - t0, ok


def _kernel_calls() -> tuple[int, float]:
    calls = [(a, b) for (tag, _), a, b in EVENTS if tag == "kernel"]
    return len(calls), sum(b - a for a, b in calls)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--method", default="quadrature")
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--chunk", type=int, default=8192)
    args = ap.parse_args()
    _timed(cycle, "cycles_by_quadrature", "kernel")
    _timed(compute, "survey_run", "survey_run (kernel and fallback)")
    _timed(compute, "fields_of", "labels (fields_of)")
    _timed(engine, "_write_part", "part files (_write_part)")
    _timed(store.MapWriter, "put", "netCDF slabs (MapWriter.put)")
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        _sweep(tmp, 4, args.method, args.chunk)
        compose.warm_fallback(Ball.paper().nondim_params())
        EVENTS.clear()
        CPU.clear()
        wall, _ = _sweep(tmp, args.n, args.method, args.chunk)
        print(f"{args.n}^3 launches, {args.method}, chunk {args.chunk}: wall {wall:.2f} s")
        count = collections.Counter(who for who, _, _ in EVENTS)
        span = collections.defaultdict(float)
        for who, a, b in EVENTS:
            span[who] += b - a
        for who in sorted(span):
            print(f"  {who[0]:34s} {who[1]:20s} {count[who]:4d} calls  wall {span[who]:.3f} s"
                  f"  CPU {CPU[who]:.3f} s")
        k, s = _kernel_calls()
        if k:
            print(f"  kernel calls: {k}, {s:.2f} s in all")
        # the part writer's work stubbed out
        engine._write_part = lambda *a, **k: None
        store.MapWriter.put = lambda *a, **k: None
        stub = {"label": lambda m: np.zeros(m, np.int8), "n_sides": lambda m: np.zeros(m)}
        engine.fields_of = compute.fields_of = (
            lambda r: {v: f(compute.n_launches(r)) for v, f in stub.items()})
        EVENTS.clear()
        wall, ok = _sweep(tmp, args.n, args.method, args.chunk)
        k, s = _kernel_calls()
        print(f"the part writer's work stubbed out: wall {wall:.2f} s up to the failed assembly, "
              f"kernel calls: {k}, {s:.2f} s in all")


if __name__ == "__main__":
    main()

"""Where a fixed-step map's observations spend their time inside the kernel, counted by the CPU's
own cycle counter (LLVM's readcyclecounter: the time-stamp counter, at its fixed rate).

The map's kernel (`integrate/ensemble.py`, `run_block_steps`) is built again in memory, uncached,
from its own source with counters added around each observation pass and, inside it, around the
state's conversion to the fixed frame with its rate, the observer's step and its span; the
totals of each block come back in the run's t_stop (so the copy's fields are for timing only:
numba's on-disk cache is never touched). The copy's numbers are the map's (same source, same
launches); the counters add a few tens of cycles each. Then, for scale, the same kernel without
the counters and the bare kernel (no observer), timed on the same launches. One thread, so the
cycles are one core's. Needs only ballsurvey:

    python benchmarks/observation_cycles.py [--spec sweeps/square-map.toml] [--launches 640]
"""
from __future__ import annotations

import argparse
import time
import types

import numba
import numpy as np
from cycle_counter import patched

from ballsurvey.classify.observer import N_OBS
from ballsurvey.compose import FIXED_STEP_OBSERVER, OBSERVER, launch_arrays
from ballsurvey.integrate import ensemble
from ballsurvey.sweep.plan import launch_table
from ballsurvey.sweep.spec import load_spec
from ballsurvey.units import StepPlan

#: (text in the kernel's source, what it becomes): the counters
PATCHES = (
    ("    next_min = n_steps\n    for i in range(m):\n"
     "        next_min = min(next_min, n_next[i])\n",
     "    next_min = n_steps\n    for i in range(m):\n"
     "        next_min = min(next_min, n_next[i])\n"
     "    acc_pass = 0\n    acc_conv = 0\n    acc_step = 0\n    acc_span = 0\n"
     "    n_obs_count = 0\n    n_pass = 0\n    cyc_start = rdtsc()\n"),
    ("        if kk >= next_min:\n            next_min = n_steps\n",
     "        if kk >= next_min:\n            cyc0 = rdtsc()\n            next_min = n_steps\n"),
    ("                if alive[i] and n_next[i] <= kk:\n",
     "                if alive[i] and n_next[i] <= kk:\n                    cyc1 = rdtsc()\n"),
    ("                    step(obs_l, i,",
     "                    cyc2 = rdtsc()\n                    step(obs_l, i,"),
    ("                    w = span(obs_l, i, ya[i], fa[i], vb, fb)\n",
     "                    cyc3 = rdtsc()\n"
     "                    w = span(obs_l, i, ya[i], fa[i], vb, fb)\n"
     "                    cyc4 = rdtsc()\n                    acc_conv += cyc2 - cyc1\n"
     "                    acc_step += cyc3 - cyc2\n                    acc_span += cyc4 - cyc3\n"
     "                    n_obs_count += 1\n"),
    ("            if n_alive == 0:\n                break\n",
     "            acc_pass += rdtsc() - cyc0\n            n_pass += 1\n"
     "            if n_alive == 0:\n                break\n"
     "    if m >= 7:\n        t_stop[0] = acc_pass\n        t_stop[1] = acc_conv\n"
     "        t_stop[2] = acc_step\n        t_stop[3] = acc_span\n        t_stop[4] = n_obs_count\n"
     "        t_stop[5] = n_pass\n        t_stop[6] = rdtsc() - cyc_start\n"),
)
NAMES = ("observation passes", "conversion + rate", "observer step", "observer span",
         "observations", "passes", "kernel")


def counted_kernel(method: str):
    """run_parallel_steps of a copy of the map's kernel module with the counters, in memory."""
    source = patched(ensemble._steps_module_source(method).replace("cache=True", "cache=False"),
                     PATCHES)
    mod = types.ModuleType("counted_steps")
    exec(compile(source, "<counted_steps>", "exec"), mod.__dict__)
    for key, fn in FIXED_STEP_OBSERVER._asdict().items():
        setattr(mod, key, fn)
    return mod.run_parallel_steps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default="sweeps/square-map.toml")
    ap.add_argument("--launches", type=int, default=640, help="the spec's first N (640)")
    args = ap.parse_args()
    spec = load_spec(args.spec)
    if spec.method not in ensemble.FIXED_STEP:
        raise SystemExit(f"{args.spec}: method {spec.method!r} is not a fixed-step one")
    n = min(args.launches, spec.n_launches)
    y0, p, tu, _ = launch_arrays(launch_table(spec, 0, n))
    plan = StepPlan(spec.T, spec.dt, tu)
    numba.set_num_threads(1)
    block = 64
    run = counted_kernel(spec.method)

    def counted():
        obs = np.full((N_OBS, n), np.nan)
        t_stop = np.full(n, np.nan)
        run(y0, p, plan.dt_nd, plan.n_steps, block, 1e-3, max(1, spec.observe_every), obs,
            np.empty_like(y0), 0, np.zeros(n, dtype=np.int8), t_stop)
        return t_stop

    def timed(observer, n_slots):
        t = time.perf_counter()
        ensemble.integrate(y0, p, plan.dt_nd, plan.n_steps, spec.method, observer=observer,
                           n_slots=n_slots, block=block, observe_every=spec.observe_every)
        return time.perf_counter() - t

    counted()  # compiled
    t = time.perf_counter()
    t_stop = counted()
    wall = time.perf_counter() - t
    tot = t_stop[: n // block * block].reshape(-1, block)[:, :7].sum(axis=0)
    for observer, n_slots in ((FIXED_STEP_OBSERVER, N_OBS), (OBSERVER, 0)):  # load
        ensemble.integrate(y0[:, :2], p[:, :2], plan.dt_nd, 10, spec.method,
                           observer=observer, n_slots=n_slots)
    t_map, t_bare = timed(FIXED_STEP_OBSERVER, N_OBS), timed(OBSERVER, 0)
    whole = n // block * block
    print(f"{args.spec}: {whole} launches x {plan.n_steps} {spec.method} steps, one thread; "
          f"counter {tot[6] / wall / 1e9:.2f} GHz")
    obs_n, passes = tot[4], tot[5]
    print(f"  observations {obs_n:.0f} ({obs_n / whole:.0f} a launch), passes over a block "
          f"{passes:.0f} (one every {plan.n_steps * whole / block / passes:.1f} steps)")
    print(f"  observation passes: {100 * tot[0] / tot[6]:.1f} % of the counted kernel's cycles, "
          f"{tot[0] / obs_n:.0f} cycles an observation, of which:")
    for k in (1, 2, 3):
        print(f"    {NAMES[k]:22s} {tot[k] / obs_n:6.0f} cycles ({100 * tot[k] / tot[0]:.0f} %)")
    print(f"  the map's kernel {t_map:.2f} s, the bare kernel {t_bare:.2f} s "
          f"(+{100 * (t_map / t_bare - 1):.0f} %), the counted copy {wall:.2f} s")


if __name__ == "__main__":
    main()

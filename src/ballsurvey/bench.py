"""Benchmark: the ensemble kernel against a naive one-launch-at-a-time numba loop, same launches.

Prints IC-steps per second (launches x steps / wall time) for each and their ratio. Both are
compiled and warmed before timing; each timing is the best of `repeats` on this (shared, noisy)
machine, so compare the ratio, not the absolute figures, across machines.
"""
from __future__ import annotations

import re
import time

import numba
import numpy as np

from .ball import Ball
from .classify.observer import N_OBS
from .compose import BESIDE, CUDA_METHODS, OBSERVER, in_line, phases_text
from .integrate import ensemble, naive
from .integrate.tableaus import FIXED_STEP
from .physics.fast import fast_state
from .units import StepPlan, launch_state


def _best(fn, repeats):
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def _kernel_launches(n_launches: int, seed: int):
    """The kernel benchmarks' launches: theta0 -10..30 deg, chidot0 1..12 rad/s, phidot0 = -3,
    seeded. Returns (ball, fast states, params, theta0, chidot0, phidot0 (non-dimensional))."""
    ball = Ball.paper()
    tu = ball.time_unit
    rng = np.random.default_rng(seed)
    th0 = np.radians(rng.uniform(-10, 30, n_launches))
    chd0 = rng.uniform(1, 12, n_launches) * tu
    phd0 = np.full(n_launches, -3.0 * tu)
    zeros = np.zeros(n_launches)
    y0 = fast_state(zeros, zeros, th0, zeros, zeros, zeros, chd0, phd0)
    params = np.repeat(ball.nondim_params()[:, None], n_launches, 1)
    return ball, y0, params, th0, chd0, phd0


def run_bench_cuda(n_launches: int = 1 << 20, n_steps: int = 2000, dt: float = 1e-4,
                   repeats: int = 3, observe_every: int = 4, seed: int = 0, out=print) -> dict:
    """IC-steps/s of the CUDA kernel with the observer on, and its agreement with the CPU kernel
    on the first 256 launches (same launches as `run_bench`)."""
    from .integrate import cuda

    ball, y0, params, _, _, _ = _kernel_launches(n_launches, seed)
    tu = ball.time_unit
    kw = dict(observer=OBSERVER, n_slots=N_OBS, observe_every=observe_every)
    cuda.integrate(y0[:, :4], params[:, :4], dt / tu, 2, **kw)  # compile
    res = {}

    def run():
        res["r"] = cuda.integrate(y0, params, dt / tu, n_steps, **kw)

    t = _best(run, repeats)
    cpu = ensemble.integrate(y0[:, :256], params[:, :256], dt / tu, n_steps, **kw)
    diff_m = float(np.abs(res["r"].y_end[:2, :256] - cpu.y_end[:2]).max() * ball.a)
    rate = n_launches * n_steps / t
    out(f"ballsurvey bench --backend cuda: {n_launches} launches x {n_steps} RK4 steps "
        f"(dt = {dt} s), observer every {observe_every}, best of {repeats} (transfers included)")
    out(f"  CUDA kernel + observer: {rate:.3e} IC-steps/s ({t:.3f} s)")
    out(f"  largest |position difference| against the CPU kernel (256 launches): {diff_m:.2e} m")
    return {"cuda_with_observer": rate, "seconds": t, "max_position_difference_m": diff_m}


def run_bench(n_launches: int = 4096, n_steps: int = 2000, dt: float = 1e-4, repeats: int = 3,
              block: int = 64, observe_every: int = 4, seed: int = 0, out=print) -> dict:
    ball, y0, params, th0, chd0, phd0 = _kernel_launches(n_launches, seed)
    tu = ball.time_unit
    zeros = np.zeros(n_launches)
    u0 = np.ascontiguousarray(np.stack([zeros, zeros, th0, zeros, zeros, zeros, chd0, phd0], 1))
    pn = np.ascontiguousarray(params.T)
    u_end = np.empty_like(u0)
    dt_nd = dt / tu
    # warm up (compile) on a few launches
    ensemble.integrate(y0[:, :4], params[:, :4], dt_nd, 2, observer=OBSERVER, n_slots=N_OBS)
    naive.naive_ensemble(u0[:4], pn[:4], dt_nd, 2, u_end[:4])

    res = {}

    def ens(observer):
        res["y_end"] = ensemble.integrate(y0, params, dt_nd, n_steps, block=block,
                                          observer=OBSERVER, n_slots=N_OBS if observer else 0,
                                          observe_every=observe_every).y_end

    t_obs = _best(lambda: ens(True), repeats)
    t_bare = _best(lambda: ens(False), repeats)
    t_naive = _best(lambda: naive.naive_ensemble(u0, pn, dt_nd, n_steps, u_end), repeats)
    work = n_launches * n_steps
    diff_m = float(np.abs(res["y_end"][:2].T - u_end[:, :2]).max() * ball.a)
    figures = {
        "ensemble_with_observer": work / t_obs,
        "ensemble_bare": work / t_bare,
        "naive": work / t_naive,
    }
    out(f"ballsurvey bench: {n_launches} launches x {n_steps} RK4 steps (dt = {dt} s), "
        f"{numba.get_num_threads()} numba threads, best of {repeats}")
    out(f"  {'kernel':<34}{'IC-steps/s':>14}{'vs naive':>10}")
    labels = {"ensemble_with_observer": f"ensemble + observer (every {observe_every})",
              "ensemble_bare": "ensemble, no observer",
              "naive": "naive (one launch at a time)"}
    for key, rate in figures.items():
        out(f"  {labels[key]:<34}{rate:>14.3e}{rate / figures['naive']:>9.1f}x")
    out(f"  largest |position difference| ensemble vs naive after {n_steps} steps: {diff_m:.2e} m")
    figures["max_position_difference_m"] = diff_m
    return figures


MAP_SPEC = """
title = "bench map {n}x{n}"
[launch]
theta0_deg = {{start = -10.0, stop = 30.0, num = {n}}}
thetadot0 = 0.0
chidot0 = {{start = 1.0, stop = 12.0, num = {n}}}
phidot0 = -3.0
[run]
T = {T}
dt = {dt}
[output]
file = "{out}"
"""


def run_map_bench(n: int = 64, T: float = 20.0, dt: float = 1e-4, naive_sample: int = 128,
                  out=print) -> dict:
    """Wall time of an n x n (theta0, chidot0) sweep through the whole engine (integrate,
    classify, write netCDF) against the naive loop's time for the same map, estimated from
    `naive_sample` of its launches (the naive loop only integrates: no classification, no file)."""
    import tempfile
    from pathlib import Path

    from .sweep import load_spec, run_sweep

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "map.toml"
        path.write_text(MAP_SPEC.format(n=n, T=T, dt=dt, out=Path(tmp) / "map.nc"))
        spec = load_spec(path)
        warm = load_spec(path, text=MAP_SPEC.format(n=2, T=dt * 4, dt=dt, out=Path(tmp) / "w.nc"))
        run_sweep(warm, command="bench warm-up", progress=False, parallel=True)
        t = time.perf_counter()
        run_sweep(spec, command="bench", progress=False, parallel=True)
        wall = time.perf_counter() - t
    ball = Ball.paper()
    p, tu = ball.nondim_params(), ball.time_unit
    m = min(naive_sample, n * n)
    th = np.radians(np.linspace(-10, 30, n))
    chd = np.linspace(1, 12, n)
    TH, CHD = (g.ravel() for g in np.meshgrid(th, chd, indexing="ij"))
    pick = np.linspace(0, n * n - 1, m).astype(int)
    z = np.zeros(m)
    u0 = np.ascontiguousarray(np.stack([z, z, TH[pick], z, z, z, CHD[pick] * tu,
                                        np.full(m, -3.0 * tu)], 1))
    pn = np.ascontiguousarray(np.repeat(p[None, :], m, 0))
    u_end = np.empty_like(u0)
    steps = max(1, int(np.ceil(T / dt - 1e-9)))
    naive.naive_ensemble(u0[:2], pn[:2], dt / tu, 2, u_end[:2])
    t = time.perf_counter()
    naive.naive_ensemble(u0, pn, dt / tu, steps, u_end)
    naive_est = (time.perf_counter() - t) * (n * n) / m
    out(f"ballsurvey map bench: {n} x {n} launches, T = {T} s, dt = {dt} s ({steps} RK4 steps), "
        f"{numba.get_num_threads()} numba threads")
    out(f"  sweep engine (integrate + classify + netCDF): {wall:8.2f} s  "
        f"{n * n / wall:10.1f} launches/s")
    out(f"  naive loop, estimated from {m} launches:      {naive_est:8.2f} s  "
        f"{n * n / naive_est:10.1f} launches/s")
    out(f"  ratio naive / engine: {naive_est / wall:.1f}x")
    return {"wall_s": wall, "naive_estimate_s": naive_est}


def run_spec_bench(path, out=print) -> dict:
    """A spec's sweep end to end in this process (a fresh one: kernels come from the on-disk
    cache), against the bare kernel on the same launches and steps: no observer, no fallback, no
    labels, no file. Full-length runs (no period mode) of a fixed-step method."""
    import tempfile
    from dataclasses import replace
    from pathlib import Path

    from .compose import TIMES, launch_arrays, start_numba
    from .limits import InputError
    from .sweep import load_spec, run_sweep
    from .sweep.plan import launch_table

    spec = load_spec(path)
    if spec.method not in FIXED_STEP or spec.mode != "full" or spec.backend != "cpu":
        raise InputError(f"{path}: bench --spec times full-length runs of a fixed-step method "
                         f"({', '.join(FIXED_STEP)}) on the cpu backend; this spec has method "
                         f"{spec.method!r}, mode {spec.mode!r}, backend {spec.backend!r}")
    # numba's start (its CPU target: once a process, whatever runs first pays it) before both,
    # as `ballsurvey sweep` starts it before its run; timed and printed apart
    t_numba = start_numba()
    TIMES.clear()
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        run_sweep(replace(spec, output=Path(tmp) / "map.nc"), command="bench", progress=False,
                  notice=lambda line: None)
        wall = time.perf_counter() - t
    y0, params, tu, _ = launch_arrays(launch_table(spec, 0, spec.n_launches))
    plan = StepPlan(spec.T, spec.dt, tu)

    def bare(n=None, n_steps=plan.n_steps):
        ensemble.integrate(y0[:, :n], params[:, :n], plan.dt_nd, n_steps, spec.method,
                           observer=OBSERVER, n_slots=0, block=spec.block,
                           observe_every=spec.observe_every)

    bare(2, 10)  # its kernel loaded from the disk cache untimed: the kernel alone is timed
    t_bare = _best(bare, 1)
    n = spec.n_launches
    out(f"ballsurvey spec bench: {path}: {n} launches, T = {spec.T} s, dt = {spec.dt} s "
        f"({plan.n_steps} {spec.method} steps each), observer every {spec.observe_every} steps, "
        f"{numba.get_num_threads()} numba threads")
    out(f"  numba's start (its CPU target, once a process), before both: {t_numba:.2f} s")
    out(f"  sweep, end to end (this fresh process): {wall:8.2f} s")
    out(f"    of which {phases_text(TIMES)}, the rest {wall - in_line(TIMES):.2f} s")
    out(f"  bare kernel, same launches and steps:   {t_bare:8.2f} s")
    out(f"  ratio sweep / bare kernel: {wall / t_bare:.2f}x (with numba's start in the sweep: "
        f"{(wall + t_numba) / t_bare:.2f}x)")
    return {"wall_s": wall, "bare_s": t_bare, "ratio": wall / t_bare, "numba_start_s": t_numba,
            "times": dict(TIMES)}


def _same_maps(a, b) -> bool:
    """Every data variable of two map files equal, bit for bit (NaN equal to NaN)."""
    import xarray as xr

    with xr.open_dataset(a) as da, xr.open_dataset(b) as db:
        if set(da.data_vars) != set(db.data_vars):
            return False
        for name in da.data_vars:
            x, y = da[name].values, db[name].values
            nan_ok = x.dtype.kind in "fc"
            if x.shape != y.shape or not np.array_equal(x, y, equal_nan=nan_ok):
                return False
    return True


def _cores() -> int:
    """Cores this process may run on (its CPU affinity where the system tells it)."""
    import os

    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


#: the phases of a run that are kernel work (`compose.TIMES`, as `sweep -v` prints them)
KERNEL_PHASES = ("integrate", "near-vertical fallback", "integrator fallback", "label")
#: launches per axis of the spec whose fresh-process sweep measures the fixed cost (2^3 = 8)
PROBE_N = 2


def _phase_times(stderr: str) -> dict:
    """{phase: seconds} from the 'where the time went' line of `sweep -v` (names of letters,
    spaces, hyphens and apostrophes each followed by its seconds: numba start, integrate,
    near-vertical fallback, label; dask cluster start, workers' first call, closing)."""
    line = next((ln for ln in stderr.splitlines() if "where the time went:" in ln), "")
    return {k: float(v) for k, v in re.findall(r"(?:: |, |; )([a-z][a-z' -]*) (\d+\.\d+) s",
                                                line)}


def _amdahl(t1: float, f: float, p: int) -> float:
    """The most p threads can gain on a run of t1 seconds of which f does not shrink:
    t1 / (f + (t1 - f) / p)."""
    return t1 / (f + max(t1 - f, 0.0) / p)


def run_scaling(path=None, threads: int | None = None, workers: int | None = None, *,
                headline: int | None = None, T: float = 20.0, method: str = "dop853",
                out=print) -> dict:
    """A spec's sweep end to end, each run a fresh `ballsurvey sweep -v` process: on 1 numba
    thread, on `threads` (default: every core this process may use) in one process, and on a
    local dask cluster of `workers` one-thread processes (default: as many as threads; left out,
    with a line, when dask is not installed). A run of each of the last two first, and one of
    the fixed cost's sweep, untimed, so that every timed run finds its kernels in the disk
    cache.

    path: the spec (TOML); or headline: N, the `bench --headline` map of N^3 launches
    (`headline_spec`: to T (s), by `method` with its `HEADLINE_RUN` settings) written as a spec
    in a temporary folder.

    Prints the fixed cost per process (the wall time of a fresh process sweeping the
    `HEADLINE_SPEC` map at N = `PROBE_N`, 8 launches, with the spec's method where the headline
    has settings for it, else dop853, on 1 and on `threads` threads, with numba's start and its
    kernels' time); per run the wall time,
    CPU use, the kernels' time (`sweep -v`: `KERNEL_PHASES`; on dask each worker's on average),
    the rest (wall minus kernels), and the speed-up against 1 thread on wall and on kernel time;
    dask's cluster start and workers' first call; the most `threads` threads could gain with
    that fixed cost; and whether the maps are the same, bit for bit."""
    import importlib.util
    import os
    import resource
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    from . import limits
    from .limits import InputError, RunError
    from .sweep import load_spec

    for name, value in (("--threads", threads), ("--workers", workers)):
        if value is not None:
            limits.workers(value, name)  # at least 1, at most limits.MAX_WORKERS
    if (path is None) == (headline is None):
        raise InputError("bench --scaling: give a spec file (.toml) or --headline [N]")
    if path is not None:
        spec = load_spec(path)
        if spec.backend != "cpu":
            raise InputError(f"{path}: bench --scaling times the cpu backend; this spec has "
                             f"backend {spec.backend!r}")
    threads = threads or _cores()
    workers = workers or threads
    runs = {"1 thread, one process": (1, [])}
    if threads > 1:
        runs[f"{threads} threads, one process"] = (threads, [])
    has_dask = importlib.util.find_spec("distributed") is not None
    dask_run = f"--workers {workers} (dask, 1 thread each)"
    if has_dask:
        runs[dask_run] = (1, ["--workers", str(workers)])
    rows, probe = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        if headline is not None:
            path = Path(tmp) / "headline.toml"
            path.write_text(headline_spec(headline, T=T, method=method,
                                          out=Path(tmp) / "headline.nc"))
            spec = load_spec(path)
        title = (f"the headline map, N = {headline}" if headline is not None else str(path))
        probe_method = spec.method if spec.method in HEADLINE_RUN else "dop853"
        probe_path = Path(tmp) / "probe.toml"
        probe_path.write_text(headline_spec(PROBE_N, method=probe_method, T=spec.T,
                                            out=Path(tmp) / "probe.nc"))

        def sweep(spec_path, name, n_threads, extra):
            env = dict(os.environ, NUMBA_NUM_THREADS=str(n_threads))
            target = Path(tmp) / f"run{len(rows)}.nc"
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            t = time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "ballsurvey", "sweep", str(spec_path),
                                "-o", str(target), "--force", "-v", "--no-progress", *extra],
                               env=env, capture_output=True, text=True)
            wall = time.perf_counter() - t
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            if r.returncode != 0:
                last = (r.stderr.strip().splitlines() or ["(no message)"])[-1]
                raise RunError(f"the run '{name}' failed: {last}")
            cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
            return {"wall_s": wall, "cpu_s": cpu, "file": target,
                    "phases": _phase_times(r.stderr)}

        for name, (n_threads, extra) in list(runs.items())[-2:]:  # fill the caches, untimed
            sweep(path, name, n_threads, extra)
        sweep(probe_path, "fixed cost", threads, [])  # its kernels too (another mode, method)
        for n_threads in sorted({1, threads}):
            probe[n_threads] = sweep(probe_path, "fixed cost", n_threads, [])
        for name, (n_threads, extra) in runs.items():
            rows[name] = sweep(path, name, n_threads, extra)
        files = [row.pop("file") for row in rows.values()]
        same = all(_same_maps(files[0], f) for f in files[1:])
    for name, row in rows.items():
        # in one process the labels are made beside the integration; a dask worker makes them
        # after it, on its own path
        row["kernels_s"] = sum(row["phases"].get(k, 0.0) for k in KERNEL_PHASES
                               if k != BESIDE or name == dask_run)
        row["rest_s"] = row["wall_s"] - row["kernels_s"]
    one = rows["1 thread, one process"]
    out(f"ballsurvey scaling bench: {title}: {spec.n_launches} launches, T = {spec.T} s, "
        f"method {spec.method}, mode {spec.mode}; {_cores()} cores here; each run a fresh "
        f"`ballsurvey sweep -v` process with warm caches")
    for row in probe.values():
        row.pop("file")
        row["kernels_s"] = sum(row["phases"].get(k, 0.0) for k in KERNEL_PHASES)
    fixed = ", ".join(f"{v['wall_s']:.2f} s on {k} thread{'s' if k > 1 else ''} (numba start "
                      f"{v['phases'].get('numba start', float('nan')):.2f} s, kernels "
                      f"{v['kernels_s']:.2f} s)" for k, v in probe.items())
    out(f"  fixed cost per process (a fresh process sweeping {PROBE_N ** 3} launches, the "
        f"headline map's settings at N = {PROBE_N}, {probe_method}): {fixed}")
    out(f"  {'run':38s}{'wall (s)':>9s}{'CPU':>6s}{'kernels (s)':>12s}{'rest (s)':>9s}"
        f"{'speed-up: wall':>16s}{'kernels':>9s}")
    for name, row in rows.items():
        # kernel times print to 0.01 s: a ratio of two under that is rounding, not a speed-up
        k_ratio = (f"{one['kernels_s'] / row['kernels_s']:8.1f}x"
                   if min(one["kernels_s"], row["kernels_s"]) >= 0.01 else f"{'-':>9s}")
        out(f"  {name:38s}{row['wall_s']:9.2f}{100 * row['cpu_s'] / row['wall_s']:5.0f}%"
            f"{row['kernels_s']:12.2f}{row['rest_s']:9.2f}"
            f"{one['wall_s'] / row['wall_s']:15.1f}x{k_ratio}")
    out("  kernels: integrate + near-vertical fallback, as `sweep -v` prints them, and on dask the "
        "labels too (each worker's on average; in one process the labels are made beside the "
        "integration); rest: wall minus kernels (numba's start included)")
    if has_dask:
        ph = rows[dask_run]["phases"]
        start, first, close = (ph.get(k, float("nan")) for k in (
            "dask cluster start", "workers' first call", "closing"))
        out(f"  dask: cluster start {start:.2f} s, the workers' first call (imports, kernels "
            f"loaded) {first:.2f} s, closing the cluster {close:.2f} s")
    else:
        out("  (--workers left out: dask is not installed; pip install 'ballsurvey[dask]')")
    if threads > 1:
        f = probe[threads]["wall_s"]
        out(f"  with this fixed cost ({f:.2f} s), {threads} threads can at best give "
            f"{_amdahl(one['wall_s'], f, threads):.1f}x on this map (kernels scaling perfectly)")
    out(f"  the {len(rows)} maps are the same, bit for bit: {'yes' if same else 'NO'}")
    return {"runs": rows, "fixed_cost": probe, "same": same}


def headline_spec(n: int, *, T: float = 20.0, method: str = "dop853", backend: str = "cpu",
                  out, **run) -> str:
    """The headline map's spec (`HEADLINE_SPEC`) as TOML text: n^3 launches, T (s), the method's
    `HEADLINE_RUN` settings (run: those to replace: dt, observe_every, rtol), chunk 8192 on the
    CPU (the backend's default chunk otherwise), the map written to `out`."""
    from .sweep.spec import DEFAULT_CHUNK

    settings = {**HEADLINE_RUN[method], **{k: v for k, v in run.items() if v is not None}}
    chunk = 8192 if backend == "cpu" else DEFAULT_CHUNK[backend]
    return HEADLINE_SPEC.format(n=n, T=T, out=out, method=method, backend=backend, chunk=chunk,
                                **settings)

HEADLINE_SPEC = """
title = "headline {n}^3 map"
[launch]
theta0_deg = {{start = -20.0, stop = 60.0, num = {n}}}
thetadot0 = 0.0
chidot0 = {{start = -12.0, stop = 12.0, num = {n}}}
phidot0 = {{start = -8.0, stop = 8.0, num = {n}}}
[run]
T = {T}
dt = {dt}
method = "{method}"
rtol = {rtol}
observe_every = {observe_every}
backend = "{backend}"
mode = "period"
cycles = 2
chunk = {chunk}
[output]
file = "{out}"
variables = ["label", "n_sides"]
"""


#: the headline map's settings by method: RK4's step and observer sample spacing
#: (dt * observe_every), or DOP853's tolerance and first trial step (its observer reads each step);
#: quadrature's rtol and dt are its fallback integrator's (dop853)
HEADLINE_RUN = {"rk4": dict(dt=2e-4, observe_every=4, rtol=1e-9),
                "dop853": dict(dt=1e-3, observe_every=4, rtol=1e-9),
                "quadrature": dict(dt=1e-3, observe_every=4, rtol=1e-9)}
#: the method `bench --headline --method quadrature` times beside it, in the same command
HEADLINE_BASELINE = {"quadrature": "dop853"}


def _headline_map(n, T, method, backend, run, tmp, target):
    """Sweep the headline map once (after a warm-up sweep): (wall s, CPU s, TIMES, labels, spec)."""
    import resource
    from pathlib import Path

    import xarray as xr

    from .compose import TIMES, warm_fallback
    from .sweep import load_spec, run_sweep

    path = Path(tmp) / f"headline-{method}.toml"
    path.write_text(headline_spec(n, T=T, method=method, backend=backend, out=target, **run))
    spec = load_spec(path)
    warm = load_spec(path, text=headline_spec(2, T=run["dt"] * 8, method=method,
                                              backend=backend, out=Path(tmp) / "w.nc", **run))
    run_sweep(warm, command="bench warm-up", progress=False, force=True, parallel=True)
    warm_fallback(Ball.paper().nondim_params())
    TIMES.clear()
    ru0 = resource.getrusage(resource.RUSAGE_SELF)
    t0 = time.perf_counter()
    run_sweep(spec, command="bench --headline", progress=None, force=True, parallel=True)
    wall = time.perf_counter() - t0
    times = dict(TIMES)
    ru1 = resource.getrusage(resource.RUSAGE_SELF)
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    with xr.open_dataset(target) as ds:
        labels = ds.label.values.ravel()
    return wall, cpu, times, labels, spec


def run_headline(n: int = 100, T: float = 20.0, method: str = "dop853", dt: float | None = None,
                 observe_every: int | None = None, rtol: float | None = None, sample: int = 1000,
                 sample_dt: float = 1e-4, out_file=None, out=print, seed: int = 0,
                 backend: str = "cpu", baseline: str | None = "") -> dict:
    """An n^3 (theta0, chidot0, phidot0) map at T in period mode: wall time and peak memory, then
    label agreement on `sample` random launches against full fixed-step integration to T at
    sample_dt (the accuracy report shows every label converged from 1e-3 s down). method, dt,
    observe_every, rtol: the map's run settings (None: HEADLINE_RUN's for the method). backend:
    where the map's kernel runs (cuda: fixed-step methods; the reference stays on the CPU).
    baseline: another method whose map is swept right after, in the same process, with its own
    HEADLINE_RUN settings, its figures and agreement printed beside and the ratio of wall times
    ("": HEADLINE_BASELINE's for the method, None: none)."""
    import resource
    import tempfile
    from pathlib import Path

    from .compose import classify, run_launches
    from .sweep.engine import launch_table

    run = dict(HEADLINE_RUN[method])
    run.update({k: v for k, v in dict(dt=dt, observe_every=observe_every, rtol=rtol).items()
                if v is not None})
    dt = run["dt"]
    if baseline == "":
        baseline = HEADLINE_BASELINE.get(method)
    # the baseline runs where it can: dop853 only on the CPU
    base_backend = backend if baseline in CUDA_METHODS else "cpu"
    maps = {}
    with tempfile.TemporaryDirectory() as tmp:
        target = Path(out_file) if out_file else Path(tmp) / "headline.nc"
        maps[method] = _headline_map(n, T, method, backend, run, tmp, target)
        peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        if baseline:
            maps[baseline] = _headline_map(n, T, baseline, base_backend,
                                           dict(HEADLINE_RUN[baseline]), tmp,
                                           Path(tmp) / "baseline.nc")
    spec = maps[method][4]
    size = maps[method][3].size
    rng = np.random.default_rng(seed)
    pick = np.sort(rng.choice(size, size=min(sample, size), replace=False))
    ball = Ball.paper()
    tu = ball.time_unit
    rows = [launch_table(spec, int(i), int(i) + 1) for i in pick]
    col = {k: np.concatenate([r[k] for r in rows]) for k in rows[0]}
    y0 = launch_state(col["theta0_deg"], col["thetadot0"], col["chidot0"], col["phidot0"], tu)
    params = np.repeat(ball.nondim_params()[:, None], len(pick), 1)
    t1 = time.perf_counter()
    res = run_launches(y0, params, StepPlan(T, sample_dt, tu))
    t_full = time.perf_counter() - t1
    ref = classify(res, ball.flat_face_theta_rad)["label"]
    agree = {m: float(np.mean(ref == v[3][pick])) for m, v in maps.items()}
    wall, cpu, times = maps[method][:3]
    est_full = t_full * size / len(pick)
    threads = numba.get_num_threads()

    def how(m, r):
        return (f"{m} at dt = {r['dt']} s" if m in FIXED_STEP else f"{m} at rtol {r['rtol']:g}"
                if m != "quadrature" else
                f"{m} (integrator fallback: dop853 at rtol {r['rtol']:g})")

    out(f"ballsurvey headline: {n}^3 = {n ** 3} launches, T = {T} s, period mode (2 cycles), "
        f"{how(method, run)}, " + (f"observer every {dt * run['observe_every']:g} s, "
                                   if method in FIXED_STEP else "") +
        f"{threads} numba threads" + (", on the GPU" if backend == "cuda" else ""))
    for m, (w, c, t, _, _) in maps.items():
        lead = "  " if m == method else (f"  baseline, {how(m, HEADLINE_RUN[m])}"
                                         + (" on the CPU" if base_backend != backend else "")
                                         + ", same run: ")
        out(f"{lead}wall time {w:.1f} s ({n ** 3 / w:.0f} launches/s), CPU use "
            f"{100 * c / w:.0f} % ({c / w / threads:.0%} of {threads} threads)"
            + (f", peak memory {peak_mb:.0f} MB" if m == method else ""))
        out(f"    of which {phases_text(t, 1)}, the rest (launch tables, parts, netCDF) "
            f"{w - in_line(t):.1f} s")
        out(f"    labels agree with full integration (T = {T} s, dt = {sample_dt} s) on "
            f"{len(pick)} random launches: {100 * agree[m]:.1f} %")
    if baseline:
        out(f"  speed-up of {method} over {baseline}: {maps[baseline][0] / wall:.1f}x (wall time)")
    out(f"  full integration of the whole map would take about {est_full / 60:.0f} min "
        f"({est_full / wall:.0f}x)")
    return {"wall_s": wall, "cpu_s": cpu, "peak_mb": peak_mb, "agreement": agree[method],
            "full_estimate_s": est_full, "method": method, "backend": backend, "times": times,
            "baseline": ({"method": baseline, "wall_s": maps[baseline][0],
                          "agreement": agree[baseline], "times": maps[baseline][2]}
                         if baseline else None), **run}


def run_period_bench(n: int = 40, T: float = 20.0, dt: float = 1e-4, out=print) -> dict:
    """Period mode against full integration on an n x n (theta0, chidot0) map at phidot0 = -3:
    wall times and label agreement; `periodic_path` against `simulate` on the paper's launches
    (largest position difference over T); and the quadrature's time per launch."""
    from .compose import classify, run_launches
    from .paper import FIGURES
    from .period import periodic_path
    from .quadrature import launch_cycle
    from .simulate import simulate

    ball = Ball.paper()
    tu, p = ball.time_unit, ball.nondim_params()
    th, cd = np.meshgrid(np.linspace(-10, 30, n), np.linspace(1, 12, n), indexing="ij")
    y0 = launch_state(th.ravel(), 0.0, cd.ravel(), -3.0, tu)
    params = np.repeat(p[:, None], n * n, 1)
    for cycles in (0, 2):  # compile both
        run_launches(y0[:, :2], params[:, :2], StepPlan(0.01, dt, tu), cycles=cycles)

    def labels(cycles):
        return classify(run_launches(y0, params, StepPlan(T, dt, tu), cycles=cycles),
                        ball.flat_face_theta_rad)["label"]

    t = time.perf_counter()
    full = labels(0)
    t_full = time.perf_counter() - t
    t = time.perf_counter()
    per = labels(2)
    t_per = time.perf_counter() - t
    agree = float(np.mean(full == per))
    out(f"period mode vs full T = {T} s on a {n} x {n} map (dt = {dt} s): {t_per:.2f} s against "
        f"{t_full:.2f} s ({t_full / t_per:.1f}x), labels agree on {100 * agree:.2f} %")
    worst = 0.0
    for name in ("fig7", "fig9a", "fig12a", "fig12b"):
        kw = {k: v for k, v in FIGURES[name].items() if k != "T_fig"}
        a = simulate(**kw, T=T, n_out=2001)
        b = periodic_path(**kw, T=T, n_out=2001)
        worst = max(worst, float(np.hypot(a.x - b.x, a.y - b.y).max()))
    out(f"periodic_path vs simulate to T = {T} s on Figs. 7, 9a, 12a, 12b: largest position "
        f"difference {worst:.1e} m")
    sq = FIGURES["fig12a"]
    launch_cycle(sq["theta0_deg"], 0.0, sq["chidot0"], sq["phidot0"])
    t = time.perf_counter()
    for k in range(20):
        launch_cycle(sq["theta0_deg"] + k, 0.0, sq["chidot0"], sq["phidot0"])
    out(f"quadrature: {1e3 * (time.perf_counter() - t) / 20:.1f} ms per launch")
    return {"t_full_s": t_full, "t_period_s": t_per, "agreement": agree, "path_dev_m": worst}

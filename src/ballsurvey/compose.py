"""The layer that composes integrators and the classifier (above integrate/ and classify/).

It hands the streaming observer to the integrators, decides when a launch stops early (period
mode asks the observer), which launches are done again near the vertical, by quadrature or in the
fixed frame (the fallback policy, with the run's thresholds), and what a run's outcome means as a
label word.

* `run_launches`: fast-state launches through a fixed-step tableau or the adaptive pair, observed,
  with the near-vertical fallback; returns the integrator's `Result` (observer record, outcome, stop
  time, formulation).
* `classify`: a Result -> labels and fields (non-dimensional; `units.fields_to_si` makes them SI).
* `survey`: SI launches -> SI fields (the sweep engine's chunk, `refine`).
* `prefetch_fallback`: with empty caches, the near-vertical fallback compiled in a helper process
  beside a run's own compilation.
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .ball import flat_face_theta_of, nondim_params_of
from .classify import cycle
from .classify.labels import CODE, Thresholds, label_fields
from .classify.observer import (
    N_OBS,
    O_DE,
    O_E0,
    O_TH_MAX,
    O_TH_MIN,
    block_close,
    block_open,
    block_record,
    cycles_done,
    observe,
)
from .classify.step_observer import observe_start, observe_step, step_span
from .integrate import ensemble, lanes
from .integrate import outcome as oc
from .integrate.adaptive import integrate_adaptive, trajectory_adaptive
from .integrate.binding import Observer, StepObserver
from .integrate.tableaus import ADAPTIVE, FIXED_STEP, LANE_ADAPTIVE
from .units import StepPlan, fields_to_si, launch_state

#: seconds spent in this process, by part (integrate, near-vertical fallback, label): `sweep -v`
#: prints them; a dask worker keeps its own
TIMES: Counter = Counter()
#: the phase a sweep in this process runs beside the integration (in its part writer's thread)
BESIDE = "label"


def phases_text(times: dict, digits: int = 2, per: float = 1.0, beside: bool = True) -> str:
    """'integrate 4.70 s, ..., label 0.20 s (beside the integration)': `TIMES` as a run in this
    process spent them (each divided by `per`; beside False: a dask worker's, whose labels are
    made in line)."""
    return ", ".join(f"{k} {v / per:.{digits}f} s"
                     + (" (beside the integration)" if beside and k == BESIDE else "")
                     for k, v in times.items())


def in_line(times: dict) -> float:
    """Seconds of `times` on a sweep's own path in this process: all but `BESIDE`."""
    return sum(v for k, v in times.items() if k != BESIDE)

#: the classifier's streaming observer, as the integrators take it
OBSERVER = Observer(record=observe, done=cycles_done, block_open=block_open,
                    block_record=block_record, block_close=block_close)
#: the same record from an adaptive integration's accepted steps (the map's dop853 on SIMD lanes)
STEP_OBSERVER = StepObserver(start=observe_start, step=observe_step, done=cycles_done)
#: the step observer of the fixed-step maps: fed every so many steps, as far as its span allows
FIXED_STEP_OBSERVER = STEP_OBSERVER._replace(span=step_span)
#: methods for one trajectory (`run_trajectory`, `simulate`)
METHODS = tuple(FIXED_STEP) + tuple(ADAPTIVE)
#: the map method with no time stepping: each launch's cycle by quadrature from its invariants
#: (`classify.cycle`), the launches it cannot do integrated by `QUADRATURE_FALLBACK`
QUADRATURE = "quadrature"
QUADRATURE_FALLBACK = "dop853"
#: methods for a map (`run_launches`): those, the adaptive pairs on SIMD lanes, and quadrature
MAP_METHODS = METHODS + tuple(LANE_ADAPTIVE) + (QUADRATURE,)
#: the methods a map can run on the GPU (backend "cuda")
CUDA_METHODS = tuple(FIXED_STEP) + (QUADRATURE,)
FALLBACK_RTOL = 1e-10
FALLBACK_ATOL = 1e-12
FALLBACK_H_INIT = 1e-3  #: the fixed-frame re-run's first trial step (non-dimensional)
#: the fixed-frame re-run's longest step (non-dimensional; 5.3 ms for the paper's ball): the
#: observer sees each accepted step, and a slow launch (a ball rocking a hair from the upright)
#: would otherwise take a handful of steps a theta cycle, too few to see its shape
FALLBACK_H_MAX = 0.1
#: the fixed-frame re-run of a parallel run runs its launches in parallel (numba threads) from
#: this many on (a map's units hand it a few each: the square map's 91 near-vertical launches
#: integrated so in units of 128 took 0.55-0.67 s on one thread, 0.42-0.51 s on two); a serial
#: run (a small map, a dask worker) never compiles the parallel driver, and the results are the
#: same
FALLBACK_PARALLEL_MIN = 2
#: a launch that blew up after its tilt passed this (rad) is taken to have met the Euler chart's
#: singularity (chidot ~ 1 / cos theta outruns the fixed step), not a step too large
NEAR_SINGULAR_THETA = math.radians(80.0)
#: a launch whose tilt passes this (rad) is integrated again in the fixed frame, adaptively:
#: above it the Euler chart's fixed step loses accuracy (chidot ~ 1 / cos theta; RK4 at
#: dt = 1e-4 s errs by up to 3e-3 deg of turn per cycle at 89.9 deg, against 3e-6 below)
NEAR_VERTICAL_THETA = math.radians(88.5)
#: the label word each failed outcome gives
FAILURE_LABEL = {oc.NONFINITE: "blew_up", oc.CHART_SINGULAR: "singular",
                 oc.STEP_BUDGET: "unresolved", oc.STEP_UNDERFLOW: "blew_up"}


def stop_target(cycles: int) -> int:
    """What `observer.done` is asked for in period mode: cycles complete theta cycles are
    cycles + 1 theta maxima; 0: run to T."""
    return cycles + 1 if cycles > 0 else 0


def needs_fallback(res: oc.Result, thresholds: Thresholds = Thresholds()) -> np.ndarray:
    """Launches (bool mask) of an Euler-angle run that met the chart's singularity, ran out of
    steps or underflowed the step, or that blew up or drifted in energy by more than
    thresholds.max_energy_drift after |theta| passed NEAR_SINGULAR_THETA: the Euler chart's
    failures (there chidot ~ 1 / cos theta outruns the step). Drift or blow-up at low tilt is the
    step's fault and stays reported as such."""
    euler = res.formulation == oc.EULER_ANGLES
    if not euler.any():  # quadrature, the fixed frame: nothing to test
        return euler
    obs, out = res.obs, res.outcome
    with np.errstate(invalid="ignore"):
        tilt = np.maximum(np.abs(obs[O_TH_MAX]), np.abs(obs[O_TH_MIN]))
        bad_num = (out == oc.NONFINITE) | (obs[O_DE] / np.abs(obs[O_E0])
                                           > thresholds.max_energy_drift)
    chart = np.isin(out, (oc.CHART_SINGULAR, oc.STEP_BUDGET, oc.STEP_UNDERFLOW))
    with np.errstate(invalid="ignore"):
        near_vertical = tilt > NEAR_VERTICAL_THETA
    return euler & (chart | near_vertical | (bad_num & (tilt > NEAR_SINGULAR_THETA)))


#: the fallback's integration settings, one set for a map's launches and a single trajectory
FALLBACK = dict(rtol=FALLBACK_RTOL, atol=FALLBACK_ATOL, observer=OBSERVER, n_slots=N_OBS,
                fixed_frame=True, h_init=FALLBACK_H_INIT, h_max=FALLBACK_H_MAX)


def _fixed_frame(y0, params, T_nd, *, parallel, stop_after=0) -> oc.Result:
    """The fallback's integration of a map's launches: adaptive, in the fixed frame, with the
    step observer on each accepted step (a single trajectory's re-run keeps FALLBACK's sampling
    observer, which its samples need)."""
    return integrate_adaptive(y0, params, T_nd, parallel=parallel, stop_after=stop_after,
                              **dict(FALLBACK, observer=STEP_OBSERVER))


#: the per-launch fields of a `Result` that a re-run of some of its launches replaces
PER_LAUNCH = ("obs", "outcome", "t_stop", "formulation", "n_steps", "y_end")


def _replace_launches(res: oc.Result, idx, part: oc.Result) -> None:
    """Launches idx of `res` (in place) become the launches of `part`, in order."""
    for name in PER_LAUNCH:
        getattr(res, name)[..., idx] = getattr(part, name)


def _quadrature_result(obs, n_state: int, T_nd: float) -> oc.Result:
    """The quadrature's records obs (N_OBS, n) as a `Result`: outcome OK, formulation
    QUADRATURE, no stop time, no steps, no final state."""
    n = obs.shape[1]
    return oc.Result(obs=obs, outcome=np.full(n, oc.OK, dtype=np.int8),
                     t_stop=np.full(n, np.nan),
                     formulation=np.full(n, oc.QUADRATURE, dtype=np.int8),
                     y_end=np.full((n_state, n), np.nan), n_steps=np.zeros(n, dtype=np.int64),
                     t=np.array([float(T_nd)]), traj=np.empty((0, n)))


def near_vertical_fallback(y0, params, T_nd, res: oc.Result, *, thresholds=Thresholds(),
                           parallel=True, stop_after=0) -> np.ndarray:
    """Do again, in place in `res`, the launches of an Euler-angle run that `needs_fallback`
    names; returns their indices. First from their invariants by quadrature (`classify.cycle`,
    formulation QUADRATURE: no chart and no step, turn per cycle within 1e-6 deg up to a tilt of
    89.8 deg and 2e-6 deg to 89.99 (docs/accuracy.md), microseconds a launch, so serially: a map
    hands it a few launches a chunk); those it cannot do (tilt through the vertical, launched
    steady, not converged, turning points its rounding leaves uncertain) integrated adaptively
    in the fixed frame (formulation FIXED_FRAME)."""
    bad = np.flatnonzero(needs_fallback(res, thresholds))
    if not bad.size:
        return bad
    await_prefetch()
    obs, status = cycle.cycles_by_quadrature(y0[:, bad], params[:, bad], T_nd,
                                             stop_after=stop_after,
                                             steady_tol=thresholds.steady_rate_tol,
                                             parallel=False)
    done = status == cycle.DONE
    _replace_launches(res, bad[done], _quadrature_result(obs[:, done], y0.shape[0], T_nd))
    if res.by_steps is not None:  # the quadrature's record reads as the Euler chart's
        res.by_steps[bad[done]] = False
    rest = bad[~done]
    if rest.size:
        _replace_launches(res, rest, _fixed_frame(
            y0[:, rest], params[:, rest], T_nd,
            parallel=parallel and rest.size >= FALLBACK_PARALLEL_MIN, stop_after=stop_after))
    return bad


def start_numba() -> float:
    """numba's CPU target started (its registries of typing and lowering, which import
    scipy.linalg for numba's linear algebra: about 0.25 s), as the first kernel call of a process
    would: once here, the kernels' times (`TIMES`) leave it out. Returns its seconds."""
    t = time.perf_counter()
    try:
        from numba.core.registry import cpu_target

        cpu_target.target_context.refresh()
    except (ImportError, AttributeError):  # numba's internals moved: the first call does it
        pass
    return time.perf_counter() - t


def _two_launches(params_col):
    """(fast states, params) of two short launches (10 and 20 deg, spinning) of one ball: what
    the warm-ups below compile their kernels on."""
    from .physics.fast import fast_state

    y0 = fast_state(0.0, 0.0, np.radians([10.0, 20.0]), 0.0, 0.0, 0.0, 1.0, -1.0)
    return y0, np.repeat(np.asarray(params_col, dtype=float).reshape(3, 1), 2, axis=1)


def warm_fallback(params_col, parallels=(True, False), quadrature: bool = True) -> None:
    """Compile (or load from the disk cache) the fallback kernels (the near-vertical fallback's:
    the serial quadrature and the fixed-frame re-run, parallel and serial (`parallels`); with
    `quadrature`, the quadrature map's integrator too) on two short launches: a benchmark's
    warm-up run rarely has a launch that needs them, and their first compilation would be
    timed as fallback."""
    y0, p = _two_launches(params_col)
    warm_near_vertical(params_col)
    for parallel in parallels:
        _fixed_frame(y0, p, 1e-3, parallel=parallel)
        if quadrature:
            lanes.integrate_observed(y0, p, 1e-3, observer=STEP_OBSERVER, n_slots=N_OBS,
                                     method=QUADRATURE_FALLBACK, parallel=parallel,
                                     stop_after=3)


def warm_near_vertical(params_col) -> None:
    """Compile (or load from the disk cache) the kernel that does most near-vertical launches of
    a fixed-step or dopri5 map: the serial quadrature (`near_vertical_fallback`)."""
    cycle.cycles_by_quadrature(*_two_launches(params_col), 1.0, parallel=False)


#: the helper process compiling the near-vertical fallback beside this one (`prefetch_fallback`)
_HELPER: list = []
#: the longest wait (s) for that helper; past it the fallback is compiled here
HELPER_WAIT_S = 600.0


def cached_on_disk(disp) -> bool:
    """Whether numba's disk cache holds code of the jitted function `disp` compiled from these
    sources (its index, read as numba reads it, `_jit.py`); True where that cannot be told (no
    disk cache, or numba's internals not as expected)."""
    try:
        return bool(disp._cache._cache_file._load_index())
    except (AttributeError, OSError):
        return True


#: how long (s) `idle_core` watches the cores' idle time
IDLE_SAMPLE_S = 0.25


def _cpu_ticks(cpus) -> tuple[int, int] | None:
    """(idle, all) clock ticks of the given CPUs since boot, from /proc/stat (None elsewhere)."""
    try:
        lines = Path("/proc/stat").read_text().splitlines()
    except OSError:
        return None
    idle = total = 0
    for line in lines:
        name, _, rest = line.partition(" ")
        if name.startswith("cpu") and name[3:].isdigit() and int(name[3:]) in cpus:
            ticks = [int(x) for x in rest.split()]
            idle += ticks[3] + ticks[4]  # idle, iowait
            total += sum(ticks[:8])  # user .. steal (guest time is within user)
    return (idle, total) if total else None


def idle_cores(before, after, n_cpus: int) -> float:
    """Cores' worth of idle time between two `_cpu_ticks` readings of n_cpus CPUs."""
    d_idle, d_total = after[0] - before[0], after[1] - before[1]
    return n_cpus * d_idle / d_total if d_total > 0 else float(n_cpus)


def idle_core() -> bool:
    """Whether this machine has a core to spare besides this process's: over IDLE_SAMPLE_S, the
    CPUs this process may use were idle for at least 1.75 cores' worth (this process waits
    meanwhile: its own core counts as idle). Measured, not the load average: that still counts
    for a minute the work that just ended (an install, the last command). Where /proc/stat
    cannot be read, the load average of the last minute below the cores less one."""
    try:
        cpus = os.sched_getaffinity(0)
    except (AttributeError, OSError):
        return True
    before = _cpu_ticks(cpus)
    if before is None:
        try:
            return os.getloadavg()[0] < len(cpus) - 1
        except (AttributeError, OSError):
            return True
    time.sleep(IDLE_SAMPLE_S)
    after = _cpu_ticks(cpus)
    return after is None or idle_cores(before, after, len(cpus)) >= 1.75


def prefetch_fallback() -> None:
    """Start compiling the near-vertical fallback (`warm_near_vertical`: the serial quadrature)
    in a helper process when numba's disk cache does not hold it (the first run after an install
    or an edit of the kernels): there it compiles on another core while this process compiles
    the fixed-step kernel, and `near_vertical_fallback` waits for it, then loads the kernel from
    the disk cache. The fallback is about half of a fixed-step map's first compilation
    (benchmarks/first_run.py); the fixed-frame re-run, for the rare launch the quadrature cannot
    do, is compiled where it is needed. Not started with one numba thread, nor where no core is
    idle (`idle_core`): there the two compilations would only take turns on the same cores, and
    the helper's own start and its share of the work (the physics, which both compile) make the
    run slower; `stop_prefetch` ends a helper whose work the run did not need."""
    import numba

    if _HELPER or numba.get_num_threads() < 2 or cached_on_disk(cycle._block):
        return
    if not idle_core():  # asked only where there is something to compile
        return
    root = str(Path(__file__).resolve().parent.parent)  # the folder that holds ballsurvey/
    path = os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))
    code = ("from ballsurvey.ball import Ball; from ballsurvey.compose import warm_near_vertical; "
            "warm_near_vertical(Ball.paper().nondim_params())")
    _HELPER.append(subprocess.Popen([sys.executable, "-c", code],
                                    env=dict(os.environ, PYTHONPATH=path),
                                    stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                    stderr=subprocess.DEVNULL))


def await_prefetch() -> None:
    """Wait for the helper of `prefetch_fallback`, if one runs (at most HELPER_WAIT_S)."""
    while _HELPER:
        helper = _HELPER.pop()
        try:
            helper.wait(timeout=HELPER_WAIT_S)
        except subprocess.TimeoutExpired:
            helper.kill()
            helper.wait()


def stop_prefetch() -> None:
    """End the helper of `prefetch_fallback`, if one still runs (its work was not needed)."""
    while _HELPER:
        helper = _HELPER.pop()
        helper.kill()
        helper.wait()


def run_launches(y0, params, plan: StepPlan, method="rk4", *, rtol=1e-9, atol=1e-12, block=64,
                 observe_every=4, parallel=True, fallback=True, cycles=0,
                 thresholds: Thresholds = Thresholds(), backend: str = "cpu") -> oc.Result:
    """Integrate fast-state launches for plan.T_nd, observed; returns the integrators' Result.

    method: a fixed-step tableau (plan.n_steps steps of plan.dt_nd; the step observer at each
    launch's own spans, observe_every the cadence of the kernel's checks), "dopri5"/"adaptive"
    (rtol, atol; first trial step plan.h_init_nd; the step observer on each accepted step) or
    "dop853" (the pair on SIMD lanes, in the fixed frame: `lanes.integrate_observed`, with the
    step observer on each accepted step, and no fallback, which it never needs). cycles > 0
    (period mode): each launch stops once the observer has seen that many complete theta
    cycles; T is then the longest it may run.
    fallback: launches `needs_fallback` names (with `thresholds`) are done again, by quadrature
    or in the fixed frame (`near_vertical_fallback`). method "quadrature": no time stepping
    (`by_quadrature`). backend "cuda": the fixed-step kernel or the quadrature on the GPU
    (`integrate.cuda`); the near-vertical fallback of the few launches that need it runs on the
    CPU."""
    bad = ~(np.isfinite(y0).all(axis=0) & np.isfinite(params).all(axis=0))
    if bad.any():  # the kernels would read it alike only by chance (the quadrature ignores chi)
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"launch {k}: its state or ball is not finite ({bad.sum()} launches)")
    stop = stop_target(cycles)
    t0 = time.perf_counter()
    fb0 = TIMES["integrator fallback"]  # by_quadrature's fallback, counted apart
    if method == QUADRATURE:
        res = by_quadrature(y0, params, plan, rtol=rtol, atol=atol, block=block,
                            parallel=parallel, stop=stop, thresholds=thresholds, backend=backend)
    elif backend == "cuda":
        from .integrate import cuda

        if method not in FIXED_STEP:
            raise ValueError(f"backend cuda runs the fixed-step methods, not {method!r}")
        res = cuda.integrate(y0, params, plan.dt_nd, plan.n_steps, method, observer=OBSERVER,
                             n_slots=N_OBS, observe_every=observe_every, stop_after=stop)
    elif method in FIXED_STEP:
        res = ensemble.integrate(y0, params, plan.dt_nd, plan.n_steps, method,
                                 observer=FIXED_STEP_OBSERVER, n_slots=N_OBS, block=block,
                                 observe_every=observe_every, parallel=parallel, stop_after=stop)
    elif method in ADAPTIVE:
        res = integrate_adaptive(y0, params, plan.T_nd, rtol, atol, observer=STEP_OBSERVER,
                                 n_slots=N_OBS, h_init=plan.h_init_nd, parallel=parallel,
                                 tableau=ADAPTIVE[method], stop_after=stop)
    elif method in LANE_ADAPTIVE:
        res = lanes.integrate_observed(y0, params, plan.T_nd, rtol, atol,
                                       observer=STEP_OBSERVER, n_slots=N_OBS, method=method,
                                       lanes=block, h_init=plan.h_init_nd, parallel=parallel,
                                       stop_after=stop)
    else:
        raise ValueError(f"unknown method {method!r}; known: {', '.join(MAP_METHODS)}")
    t1 = time.perf_counter()
    TIMES["integrate"] += t1 - t0 - (TIMES["integrator fallback"] - fb0)
    if fallback:
        near_vertical_fallback(y0, params, plan.T_nd, res, thresholds=thresholds,
                               parallel=parallel, stop_after=stop)
        TIMES["near-vertical fallback"] += time.perf_counter() - t1
    return res


def by_quadrature(y0, params, plan: StepPlan, *, rtol=1e-9, atol=1e-12, block=64,
                  parallel=True, stop=0, thresholds: Thresholds = Thresholds(),
                  backend: str = "cpu") -> oc.Result:
    """Launches by quadrature (`classify.cycle`): the observer's record of each from its
    invariants, formulation QUADRATURE; those it cannot do (tilt through the vertical, launched
    steady, quadrature not converged, turning points F's rounding leaves uncertain) integrated
    by QUADRATURE_FALLBACK at rtol, atol in the fixed frame (their formulation says so;
    `TIMES['integrator fallback']`). backend "cuda": the quadrature runs on the GPU, one thread
    a launch (`integrate.cuda.per_launch`), its fallback on the CPU."""
    if backend == "cuda":
        from .integrate import cuda

        obs, status = cuda.per_launch(cycle.cycle_one, y0, params, plan.T_nd, stop,
                                      thresholds.steady_rate_tol, cycle.tables(),
                                      n_scratch=cycle.N_SCRATCH, n_node=cycle.N_NODE,
                                      n_points=cycle.ROW, n_slots=N_OBS)
    else:
        obs, status = cycle.cycles_by_quadrature(y0, params, plan.T_nd, stop_after=stop,
                                                 steady_tol=thresholds.steady_rate_tol,
                                                 block=block, parallel=parallel)
    res = _quadrature_result(obs, y0.shape[0], plan.T_nd)
    bad = np.flatnonzero(status != cycle.DONE)
    if bad.size:
        t0 = time.perf_counter()
        r2 = lanes.integrate_observed(y0[:, bad], params[:, bad], plan.T_nd, rtol, atol,
                                      observer=STEP_OBSERVER, n_slots=N_OBS,
                                      method=QUADRATURE_FALLBACK, lanes=block,
                                      h_init=plan.h_init_nd, stop_after=stop,
                                      # one group of lanes runs on one thread: waking the
                                      # others for it cost 1-3 ms a chunk (0.2-0.7 s of a
                                      # headline map's chunks of a few launches each)
                                      parallel=parallel and bad.size > block)
        _replace_launches(res, bad, r2)
        TIMES["integrator fallback"] += time.perf_counter() - t0
    return res


def run_trajectory(y0_col, params_col, plan: StepPlan, method="rk4", *, n_out=2001, rtol=1e-9,
                   atol=1e-12, thresholds: Thresholds = Thresholds()) -> oc.Result:
    """One launch with its trajectory at n_out evenly spaced times: fixed step, on steps
    (plan.multiple must be n_out - 1); adaptive, from the pair's dense output. With the
    fixed-frame fallback (at the same times)."""
    y0 = np.asarray(y0_col, dtype=float).reshape(-1, 1)
    p = np.asarray(params_col, dtype=float).reshape(3, 1)
    if method in FIXED_STEP:
        res = ensemble.integrate(y0, p, plan.dt_nd, plan.n_steps, method, observer=OBSERVER,
                                 n_slots=N_OBS, block=1, observe_every=1, n_rec=n_out,
                                 stride=plan.n_steps // (n_out - 1), parallel=False)
        res = res._replace(traj=res.traj[:, :, 0])
    elif method in ADAPTIVE:
        res = trajectory_adaptive(y0[:, 0], p[:, 0], plan.T_nd, rtol, atol, observer=OBSERVER,
                                  n_slots=N_OBS, t_out=np.linspace(0.0, plan.T_nd, n_out),
                                  h_init=plan.h_init_nd, tableau=ADAPTIVE[method])
    else:
        raise ValueError(f"unknown method {method!r}; known: {', '.join(METHODS)}")
    if needs_fallback(res, thresholds)[0]:
        res = trajectory_adaptive(y0[:, 0], p[:, 0], plan.T_nd, t_out=res.t, **FALLBACK)
    return res


def run_resisted_trajectory(y0_col, params_col, rolling_resistance: float, T_nd: float, *,
                            t_out, method="dopri5", rtol=FALLBACK_RTOL,
                            atol=FALLBACK_ATOL) -> oc.Result:
    """One launch with the rolling resistance mu_r = rolling_resistance (> 0;
    `physics.fixed.rhs_resisted_tuple`): the fixed-frame form by the adaptive pair `method`
    (with the fallback's first and longest step, so the observer sees each theta cycle), its
    trajectory at the times t_out (non-dimensional) from the pair's dense output."""
    p = np.append(np.asarray(params_col, dtype=float).ravel()[:3], float(rolling_resistance))
    return trajectory_adaptive(np.asarray(y0_col, dtype=float).ravel(), p, T_nd, rtol, atol,
                               observer=OBSERVER, n_slots=N_OBS, t_out=t_out, fixed_frame=True,
                               h_init=FALLBACK_H_INIT, h_max=FALLBACK_H_MAX,
                               tableau=ADAPTIVE[method])


def classify(res: oc.Result, flat_face_theta, thresholds: Thresholds = Thresholds(),
             variables=None) -> dict:
    """Labels and fields of a run (non-dimensional), with its `formulation` and `t_stop_s`;
    variables: the names wanted (None: all; `label_fields`)."""
    failure = np.full(res.outcome.shape, -1, dtype=np.int64)
    chart_free = res.formulation == oc.FIXED_FRAME
    if res.by_steps is not None:
        chart_free = chart_free | res.by_steps
    for code, word in FAILURE_LABEL.items():
        failure[res.outcome == code] = CODE[word]
    f = label_fields(res.obs, flat_face_theta, thresholds,
                     chart_free=chart_free, failure=failure,
                     variables=variables)
    if variables is None or "formulation" in variables:
        f["formulation"] = res.formulation.astype(np.int8)
    if variables is None or "t_stop_s" in variables:
        f["t_stop_s"] = res.t_stop
    return f


def launch_arrays(table: dict):
    """SI launch table (`sweep.plan.launch_table`: 1-D theta0_deg, thetadot0, chidot0, phidot0,
    chi0_deg and the ball's a, c, M, A, B, g, cut_height; g and a common) -> (fast states,
    non-dimensional params, time unit (s), flat-face tilt (rad) per launch)."""
    a = table["a"]
    tu = math.sqrt(float(np.ravel(a)[0]) / float(np.ravel(table["g"])[0]))
    params = nondim_params_of(a, table["c"], table["M"], table["A"], table["B"])
    flat = flat_face_theta_of(a, table["cut_height"])
    y0 = launch_state(table["theta0_deg"], table["thetadot0"], table["chidot0"],
                      table["phidot0"], tu, chi0_deg=table["chi0_deg"])
    return y0, params, tu, flat


class SurveyRun(NamedTuple):
    """Launches integrated and observed, not yet labelled (`survey_fields` labels them)."""

    res: oc.Result
    flat: np.ndarray
    a: np.ndarray
    tu: float
    M: np.ndarray
    thresholds: Thresholds


def survey_run(table: dict, *, T: float, dt: float, method: str = "rk4", rtol=1e-9,
               atol=1e-12, block=64, observe_every=4, cycles=0,
               thresholds: Thresholds = Thresholds(), parallel=True,
               backend: str = "cpu") -> SurveyRun:
    """The integration half of `survey` (the kernels: they release the GIL)."""
    y0, params, tu, flat = launch_arrays(table)
    res = run_launches(y0, params, StepPlan(T, dt, tu), method, rtol=rtol, atol=atol,
                       block=block, observe_every=observe_every, parallel=parallel,
                       cycles=cycles, thresholds=thresholds, backend=backend)
    return SurveyRun(res, flat, table["a"], tu, table["M"], thresholds)


def survey_fields(run: SurveyRun, variables=None) -> dict:
    """The labelling half of `survey` (numpy, on one core): SI fields of a `survey_run`
    (variables: the names wanted, None: all)."""
    t0 = time.perf_counter()
    out = fields_to_si(classify(run.res, run.flat, run.thresholds, variables), run.a, run.tu,
                       run.M)
    TIMES["label"] += time.perf_counter() - t0
    return out


def survey(table: dict, *, T: float, dt: float, method: str = "rk4", rtol=1e-9, atol=1e-12,
           block=64, observe_every=4, cycles=0, thresholds: Thresholds = Thresholds(),
           parallel=True, backend: str = "cpu") -> dict:
    """SI launches -> SI fields. table: 1-D arrays theta0_deg, thetadot0, chidot0, phidot0,
    chi0_deg and the ball's a, c, M, A, B, g, cut_height per launch (g and a common)."""
    return survey_fields(survey_run(table, T=T, dt=dt, method=method, rtol=rtol, atol=atol,
                                    block=block, observe_every=observe_every, cycles=cycles,
                                    thresholds=thresholds, parallel=parallel,
                                    backend=backend))


def warm_up() -> None:
    """Compile the serial fixed-step kernel (a dask worker, before its first chunk)."""
    y = launch_state(5.7, 0.0, 1.0, -1.0, 1.0)
    ensemble.integrate(y, np.array([[0.1], [0.4], [0.4]]), 1e-3, 2,
                       observer=FIXED_STEP_OBSERVER, n_slots=N_OBS, parallel=False)


def warm_up_fallback() -> None:
    """Compile the near-vertical fallback (the serial quadrature and the parallel fixed-frame
    re-run), so that a timing that follows excludes its compilation."""
    y0 = launch_state(np.full(2, 5.7), 0.0, 1.0, -1.0, 1.0)
    params = np.repeat(np.array([[0.1], [0.4], [0.4]]), 2, 1)
    warm_near_vertical(params[:, 0])
    _fixed_frame(y0, params, 0.01, parallel=True, stop_after=stop_target(2))


def run_tracks(y0, params, plan: StepPlan, stride: int, n_rec: int, *,
               parallel=True) -> oc.Result:
    """Many launches with their trajectories, in one call of the fixed-step RK4 ensemble kernel:
    n_rec samples, one every `stride` steps (Result.traj is (n_rec, N_FAST, n)). No observer
    and no fixed-frame fallback: a launch that meets the Euler chart's singularity is frozen
    there (outcome CHART_SINGULAR), which a fit reads as a launch far from its track."""
    return ensemble.integrate(np.asarray(y0, dtype=float), np.asarray(params, dtype=float),
                              plan.dt_nd, plan.n_steps, "rk4", observer=OBSERVER, n_slots=0,
                              block=16, n_rec=n_rec, stride=stride, parallel=parallel)

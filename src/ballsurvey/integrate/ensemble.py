"""Fixed-step explicit Runge-Kutta over an ensemble of launches (numba), structure of arrays.

Layout: the state of all launches is `y[var, launch]` (float64). Launches are cut into blocks;
`prange` runs blocks on all cores. Inside a block each variable is a fresh local 1-D array, so LLVM
can prove the rows do not alias and vectorises the loop over launches (measured: it does not when
the rows are slices of one 2-D array).

The state is the fast Euler state of `physics/fast.py`: sin and cos of theta and chi ride next to
the angles, so the right-hand side is pure arithmetic: no scalar library calls, which would stop
vectorisation (this numba has no SVML).

The observer is handed in (`binding.Observer`: record a sample, say when a launch is done); the
kernel knows nothing of what it computes. The block kernel hands it each sample of the whole block
at once (`block_record`, with the state rows themselves), so that the observer can vectorise its
own per-sample work over the launches as the step is (`classify/observer.py`); the period-mode
kernel, whose lanes sample at their own counts, records launch by launch (`record`). The kernel's
own verdict on each launch (an outcome code of `outcome.py` and the time it stopped) is returned
beside the observer's record.

The method is data: `make_kernels(method, observer)` writes the stage expressions from the Butcher
coefficients into one kernel source (as scipy's rk.py keeps one stepper for every tableau) and
compiles it. Every launch's arithmetic is independent of its neighbours, of the block size and of
the thread count (no fastmath, no FMA contraction, no cross-lane reductions), so results are
bit-identical however a sweep is chunked or threaded.

All non-dimensional (lengths / a, times / sqrt(a/g)).
"""
from __future__ import annotations

from functools import cache

import numpy as np

from ..physics.fast import N_FAST
from ..physics.fixed import N_FIXED
from .binding import Observer, StepObserver, bind
from .outcome import EULER_ANGLES, Result
from .tableaus import FIXED_STEP, Tableau, stage_source, step_constants

# pieces of the block kernels' source (before .format: {load} is each state row's load)
_BLOCK_OPEN = """    m = hi - lo
{load}
    pc = params[0, lo:hi].copy()
    pa = params[1, lo:hi].copy()
    pb = params[2, lo:hi].copy()
    alive = np.ones(m, dtype=np.bool_)
    n_obs = obs.shape[0]
"""
# validity is checked every observe_every steps (and at the last): a non-finite value persists,
# and the singular threshold cos_min is far inside the range where the step still works
_CHECK = """        if (n + 1) % observe_every == 0 or n + 1 == n_steps:
            for i in range(m):
                if alive[i]:
                    if not math.isfinite(r0[i] + r1[i] + r5[i] + r6[i] + r7[i]):
                        alive[i] = False
                        status[i] = NONFINITE
                        t_stop[i] = t + dt
                    elif r9[i] < cos_min:
                        alive[i] = False
                        status[i] = CHART_SINGULAR
                        t_stop[i] = t + dt
"""
_BLOCK_CLOSE = """    for k in range(n_obs):
        for i in range(m):
            obs[k, lo + i] = obs_l[k, i]
    for i in range(m):
        outcome[lo + i] = status[i]
        t_stop_out[lo + i] = t_stop[i]
"""

_TEMPLATE = '''
def run_block(y0, params, dt, n_steps, lo, hi, cos_min, observer_on, observe_every, obs, traj,
              stride, y_end, stop_after, outcome, t_stop_out):
''' + _BLOCK_OPEN + '''    obs_l = np.full((n_obs, m), np.nan)
    lanes = block_open(obs_l)
    status = np.zeros(m, dtype=np.int8)
    t_stop = np.full(m, np.nan)
    n_rec = traj.shape[0]
    t_seen = 0.0
{consts}
    for n in range(n_steps + 1):
        t = n * dt
        if n_rec > 0 and n % stride == 0 and n // stride < n_rec:
            rec = n // stride
            for i in range(m):
{record}
        if observer_on and (n % observe_every == 0 or n == n_steps):
            block_record(lanes, obs_l, alive, n == 0, t, t - t_seen, r0, r1, r2, r8, r9, r3,
                         r5, r6, r7, pc, pa, pb)
            if stop_after > 0:
                for i in range(m):
                    if alive[i] and done(obs_l, i, stop_after):
                        alive[i] = False  # period mode: enough theta cycles seen
            t_seen = t
            if stop_after > 0 and n_rec == 0:
                n_alive = 0
                for i in range(m):
                    if alive[i]:
                        n_alive += 1
                if n_alive == 0:
                    break
        if n == n_steps:
            break
{step}
''' + _CHECK + '''    for i in range(m):
{store}
    block_close(lanes, obs_l)
''' + _BLOCK_CLOSE


_REFILL = '''
def run_refill(y0, params, dt, n_steps, lo, hi, lanes, cos_min, observe_every, obs, y_end,
               stop_after, outcome, t_stop_out):
    """Period mode: launches lo..hi-1 through `lanes` SIMD lanes; a lane whose launch is done
    (or failed, or reached n_steps) takes the next launch at once, each lane counting its own
    steps, so no lane idles while a slow launch finishes its cycles. Per launch the arithmetic
    is run_block's, step for step (the same observation and check cadence on its own count)."""
    m = min(lanes, hi - lo)
{alloc}
    pc = np.empty(m)
    pa = np.empty(m)
    pb = np.empty(m)
    idx = np.full(m, -1, dtype=np.int64)
    k = np.zeros(m, dtype=np.int64)
    t_seen = np.zeros(m)
    n_obs = obs.shape[0]
    obs_l = np.full((n_obs, m), np.nan)
    nxt = lo
    active = 0
{consts}
    while True:
        for i in range(m):
            while True:  # settle lane i: check, observe, finish and refill as needed
                if idx[i] < 0:
                    if nxt >= hi:
                        break
                    j = nxt
                    nxt += 1
{load_lane}
                    pc[i] = params[0, j]
                    pa[i] = params[1, j]
                    pb[i] = params[2, j]
                    idx[i] = j
                    k[i] = 0
                    t_seen[i] = 0.0
                    for q in range(n_obs):
                        obs_l[q, i] = np.nan
                    active += 1
                kk = k[i]
                cadence = kk % observe_every == 0 or kk == n_steps
                status = 0
                if kk > 0 and cadence:
                    if not math.isfinite(r0[i] + r1[i] + r5[i] + r6[i] + r7[i]):
                        status = NONFINITE
                    elif r9[i] < cos_min:
                        status = CHART_SINGULAR
                finished = status != 0
                if not finished and cadence:
                    t = kk * dt
                    thdd, chdd, phdd = accelerations(r8[i], r9[i], r5[i], r6[i], r7[i],
                                                     pc[i], pa[i], pb[i])
                    record(obs_l, i, kk == 0, t, t - t_seen[i], r0[i], r1[i], r2[i], r8[i],
                           r9[i], r3[i], r5[i], r6[i], r7[i], thdd, chdd, phdd, pc[i], pa[i],
                           pb[i], math.nan, math.nan, math.nan)
                    t_seen[i] = t
                    finished = done(obs_l, i, stop_after)
                if not finished and kk == n_steps:
                    finished = True
                if not finished:
                    break
                j = idx[i]
                for q in range(n_obs):
                    obs[q, j] = obs_l[q, i]
{store_lane}
                outcome[j] = status
                t_stop_out[j] = (kk - 1) * dt + dt if status != 0 else math.nan
                idx[i] = -1
                active -= 1
        if active == 0:
            break
{step}
        for i in range(m):
            k[i] += 1
'''


_STEP = '''        # the step, in place: only the state rows are stored, so LLVM vectorises it
        for i in range(m):
            c = pc[i]
            A = pa[i]
            B = pb[i]
            s0 = ({tuple_r})
{stages}
{update}'''


def _kernel_source(tab: Tableau) -> str:
    v = range(N_FAST)
    stages, update = stage_source(tab, N_FAST, " " * 12, lane="[i]")
    consts = step_constants(tab, " " * 4)
    step = _STEP.format(tuple_r=", ".join(f"r{q}[i]" for q in v), stages=stages, update=update)
    refill = _REFILL.format(
        alloc="\n".join(f"    r{q} = np.zeros(m)" for q in v),
        load_lane="\n".join(f"                    r{q}[i] = y0[{q}, j]" for q in v),
        store_lane="\n".join(f"                y_end[{q}, j] = r{q}[i]" for q in v), step=step,
        consts=consts)
    return refill + _TEMPLATE.format(
        load="\n".join(f"    r{q} = y0[{q}, lo:hi].copy()" for q in v),
        record="\n".join(f"                traj[rec, {q}, lo + i] = r{q}[i]" for q in v),
        step=step,
        store="\n".join(f"        y_end[{q}, lo + i] = r{q}[i]" for q in v),
        consts=consts,
    )


# The same step fed to a step observer (`binding.StepObserver`): each launch is observed at its
# own cadence, every so many steps (as many as the observer's `span` allows), with the
# fixed-frame state and its rate at the two ends of that span, from which the observer builds
# its interpolants. The validity checks stay on the observe_every cadence.
_OBSERVE_LANE = """
{fast}
{ind}observed_fixed_from_fast_into(ev, vb)
{ind}kb = rhs_tuple(({tuple_vb}), pc[i], pa[i], pb[i])
{ind}for q in range(NV):
{ind}    fb[q] = kb[q]"""

_STEPS_TEMPLATE = """
def _next_observation(k, span, dt, n_steps):
    # the step count of a launch's next observation after step k: span / dt steps on (at least
    # one), at most the run's last; a long span ends on a multiple of OBSERVE_GRID steps, so that
    # a block's launches are observed together (one pass over the block a grid point, not one a
    # launch)
    if not span < (n_steps - k) * dt:
        return n_steps
    ahead = int(span / dt)
    if ahead >= 2 * OBSERVE_GRID:
        return (k + ahead) // OBSERVE_GRID * OBSERVE_GRID
    return min(n_steps, k + max(1, ahead))


def run_block_steps(y0, params, dt, n_steps, lo, hi, cos_min, observe_every, obs, y_end,
                    stop_after, outcome, t_stop_out):
""" + _BLOCK_OPEN + """    # each launch's slots side by side in memory
    obs_l = np.full((m, n_obs), np.nan).T
    status = np.zeros(m, dtype=np.int8)
    t_stop = np.full(m, np.nan)
    ya = np.empty((m, NV))
    fa = np.empty((m, NV))
    ev = np.empty(N_FAST)
    vb = np.empty(NV)
    fb = np.empty(NV)
    n_prev = np.zeros(m, dtype=np.int64)
    n_next = np.zeros(m, dtype=np.int64)
    stored = np.zeros(m, dtype=np.bool_)  # y_end written where the launch stopped
    for i in range(m):
{observe_i}
        start(obs_l, i, vb, fb, pc[i], pa[i], pb[i])
        for q in range(NV):
            ya[i, q] = vb[q]
            fa[i, q] = fb[q]
        # the first observation one step on: theta's local frequency, which paces the spans
        # (`span`), is read from the change of e_z over a span, and a first span paced by the
        # launch's rates alone can pass a good part of a theta cycle where thetadot0 is large
        n_next[i] = _next_observation(0, 0.0, dt, n_steps)
    next_min = n_steps
    for i in range(m):
        next_min = min(next_min, n_next[i])
{consts}
    for n in range(n_steps):
        t = n * dt
{step}
""" + _CHECK + """        kk = n + 1
        if kk % observe_every == 0 or kk == n_steps:
            for i in range(m):
                if not alive[i] and not stored[i]:  # failed here: its state where it stopped
                    stored[i] = True
{stored_now}
        if kk >= next_min:
            next_min = n_steps
            n_alive = 0
            for i in range(m):
                if alive[i] and n_next[i] <= kk:
{observe_i_deep}
                    step(obs_l, i, n_prev[i] * dt, (kk - n_prev[i]) * dt, ya[i], fa[i], vb, fb,
                         pc[i], pa[i], pb[i], kk == n_steps)
                    w = span(obs_l, i, ya[i], fa[i], vb, fb)
                    for q in range(NV):
                        ya[i, q] = vb[q]
                        fa[i, q] = fb[q]
                    n_prev[i] = kk
                    n_next[i] = _next_observation(kk, w, dt, n_steps)
                    if stop_after > 0 and done(obs_l, i, stop_after):
                        alive[i] = False  # period mode: enough theta cycles seen
                        stored[i] = True  # its state where it stopped, as in run_refill
{store_deep}
                if alive[i]:
                    n_alive += 1
                    next_min = min(next_min, n_next[i])
            if n_alive == 0:
                break
    for i in range(m):
        if not stored[i]:
{store_deep12}
""" + _BLOCK_CLOSE + """

def run_parallel_steps(y0, params, dt, n_steps, block, cos_min, observe_every, obs, y_end,
                       stop_after, outcome, t_stop):
    n = y0.shape[1]
    nblocks = (n + block - 1) // block
    for bi in nb.prange(nblocks):
        lo = bi * block
        run_block_steps(y0, params, dt, n_steps, lo, min(n, lo + block), cos_min,
                        observe_every, obs, y_end, stop_after, outcome, t_stop)
"""


def _steps_source(tab: Tableau) -> str:
    v = range(N_FAST)
    stages, update = stage_source(tab, N_FAST, " " * 12, lane="[i]")
    step = _STEP.format(tuple_r=", ".join(f"r{q}[i]" for q in v), stages=stages, update=update)
    tuple_vb = ", ".join(f"vb[{q}]" for q in range(N_FIXED))

    def observe(ind):
        return _OBSERVE_LANE.format(ind=ind, tuple_vb=tuple_vb,
                                    fast="\n".join(f"{ind}ev[{q}] = r{q}[i]" for q in v))

    return _STEPS_TEMPLATE.format(
        load="\n".join(f"    r{q} = y0[{q}, lo:hi].copy()" for q in v),
        observe_i=observe(" " * 8), observe_i_deep=observe(" " * 20), step=step,
        store_deep="\n".join(f"{' ' * 24}y_end[{q}, lo + i] = r{q}[i]" for q in v),
        store_deep12="\n".join(f"{' ' * 12}y_end[{q}, lo + i] = r{q}[i]" for q in v),
        stored_now="\n".join(f"{' ' * 20}y_end[{q}, lo + i] = r{q}[i]" for q in v),
        consts=step_constants(tab, " " * 4))


_PARALLEL = '''
def run_parallel(y0, params, dt, n_steps, block, cos_min, observer_on, observe_every, obs, traj,
                 stride, y_end, stop_after, outcome, t_stop):
    n = y0.shape[1]
    nblocks = (n + block - 1) // block
    for bi in nb.prange(nblocks):
        lo = bi * block
        run_block(y0, params, dt, n_steps, lo, min(n, lo + block), cos_min, observer_on,
                  observe_every, obs, traj, stride, y_end, stop_after, outcome, t_stop)


def run_parallel_refill(y0, params, dt, n_steps, block, groups, cos_min, observe_every, obs,
                        y_end, stop_after, outcome, t_stop):
    n = y0.shape[1]
    size = (n + groups - 1) // groups
    for g in nb.prange(groups):
        lo = g * size
        if lo < n:
            run_refill(y0, params, dt, n_steps, lo, min(n, lo + size), block, cos_min,
                       observe_every, obs, y_end, stop_after, outcome, t_stop)

'''


_HEADER = """# generated by ballsurvey.integrate.ensemble from a Butcher tableau; do not edit
import math
import numba as nb
import numpy as np
from ballsurvey._jit import njit
from ballsurvey.integrate.outcome import CHART_SINGULAR, NONFINITE
from ballsurvey.physics.euler import accelerations
from ballsurvey.physics.fast import fast_rhs

# the observer, handed in by ballsurvey.integrate.binding.bind before anything is compiled
record = None
done = None
block_open = None
block_record = None
block_close = None
"""

_STEPS_HEADER = """# generated by ballsurvey.integrate.ensemble from a Butcher tableau; do not edit
import math
import numba as nb
import numpy as np
from ballsurvey._jit import njit
from ballsurvey.integrate.outcome import CHART_SINGULAR, NONFINITE
from ballsurvey.physics.fast import N_FAST, fast_rhs, observed_fixed_from_fast_into
from ballsurvey.physics.fixed import N_FIXED as NV, rhs_tuple

OBSERVE_GRID = {grid}

# the step observer, handed in by ballsurvey.integrate.binding.bind before anything is compiled
start = None
step = None
span = None
done = None
"""


def _kernel_module_source(method: str) -> str:
    body = _kernel_source(FIXED_STEP[method]) + _PARALLEL
    # cached with the package's digest-stamped cache (_jit.py), like the functions they inline
    cached = "\n@njit(nogil=True, error_model='numpy', cache=True)"
    body = body.replace("\ndef run_block(", cached + "\ndef run_block(")
    body = body.replace("\ndef run_refill(", cached + "\ndef run_refill(")
    body = body.replace("\ndef run_parallel_refill(",
                        "\n@njit(parallel=True, nogil=True, error_model='numpy', cache=True)"
                        "\ndef run_parallel_refill(")
    # the parallel driver is cached too (numba picks the thread count at run time; results are
    # bit-identical for any count, tested across processes): a new process skips its compile
    body = body.replace("\ndef run_parallel(",
                        "\n@njit(parallel=True, nogil=True, error_model='numpy', cache=True)"
                        "\ndef run_parallel(")
    return _HEADER + body


#: the steps on whose multiples a step-observed launch's long observer steps end
OBSERVE_GRID = 16


def _steps_module_source(method: str) -> str:
    body = _steps_source(FIXED_STEP[method])
    body = body.replace("\ndef _next_observation(",
                        "\n@njit(nogil=True, error_model='numpy', cache=True)"
                        "\ndef _next_observation(")
    body = body.replace("\ndef run_block_steps(",
                        "\n@njit(nogil=True, error_model='numpy', cache=True)"
                        "\ndef run_block_steps(")
    body = body.replace("\ndef run_parallel_steps(",
                        "\n@njit(parallel=True, nogil=True, error_model='numpy', cache=True)"
                        "\ndef run_parallel_steps(")
    return _STEPS_HEADER.format(grid=OBSERVE_GRID) + body


def kernel_module_source(method: str) -> str:
    """The generated kernel module's text for a fixed-step method named in FIXED_STEP."""
    if method not in FIXED_STEP:
        raise ValueError(f"unknown method {method!r}; known: {', '.join(FIXED_STEP)}")
    return _kernel_module_source(method)


@cache
def make_kernels(method: str, observer: Observer):
    """(run_parallel, run_block, run_parallel_refill, run_refill) for a fixed-step method named
    in FIXED_STEP, fed `observer`.

    The kernel source is generated from the tableau and bound to the observer by
    `binding.bind`: a module file in the cache directory named by a hash of its text, of the
    observer's identity and of `_jit.SOURCE_DIGEST` (the sources of physics/, integrate/,
    classify/ and the versions), so numba can cache the compiled block kernel across processes,
    and an edit to any function the kernel inlines (euler.py, the observer, ...) gives a new module
    instead of a stale one; its cached functions are also stamped with that digest (see
    `ballsurvey._jit`). run_parallel spreads blocks over numba's threads (prange); `integrate`
    runs the same blocks on the calling thread (for dask workers, which must not nest parallel
    kernels) by calling run_block from Python, block after block, with the GIL released: a
    jitted serial driver would cost a compilation of its own (numba compiles a callee into each
    caller again; about a second). Both run the same block kernel, so their results are
    identical; likewise run_parallel_refill and run_refill (one group) in period mode.
    """
    if None in (observer.block_open, observer.block_record, observer.block_close):
        raise ValueError("the fixed-step ensemble kernel needs an observer with block_open, "
                         "block_record and block_close (binding.Observer)")
    mod = bind(f"rk_{method}", kernel_module_source(method), observer, inline_record=True)
    return mod.run_parallel, mod.run_block, mod.run_parallel_refill, mod.run_refill


@cache
def make_step_kernels(method: str, observer: StepObserver):
    """(run_parallel_steps, run_block_steps) for a fixed-step method named in FIXED_STEP, fed a
    step observer with a `span` (bound and cached as `make_kernels` does)."""
    if method not in FIXED_STEP:
        raise ValueError(f"unknown method {method!r}; known: {', '.join(FIXED_STEP)}")
    if observer.span is None:
        raise ValueError("the fixed-step kernel needs a step observer with a span")
    mod = bind(f"rk_steps_{method}", _steps_module_source(method), observer)
    return mod.run_parallel_steps, mod.run_block_steps


def refill_groups(n: int, lanes: int, parallel: bool) -> int:
    """How many groups a refill kernel's queue of n launches is cut into: several per numba
    thread (so that none waits long for another), none smaller than its lane count; 1 serial.
    The count never changes a result: each launch's arithmetic is its own."""
    if not parallel:
        return 1
    import numba

    return min(max(1, -(-n // int(lanes))), 8 * numba.get_num_threads())


def integrate(y0, params, dt, n_steps, method="rk4", *, observer: Observer | StepObserver,
              n_slots: int, block=64, cos_min=1e-3, observe_every=1, n_rec=0, stride=1,
              parallel=True, stop_after=0) -> Result:
    """Plain-array entry point.

    y0: (N_FAST, n) fast states; params: (3, n) non-dimensional (c, A, B) per launch; dt, n_steps:
    non-dimensional step and count. A sampling `observer` (n_slots slots per launch) sees every
    `observe_every`-th step and the last; n_slots = 0: no observer. A `StepObserver` (with a
    `span`) sees each launch at its own cadence, as its span allows, the fixed-frame state and
    rate at both ends of each span (`run_block_steps`; no samples kept, Result.by_steps all
    True); observe_every is then only the cadence of the checks below. n_rec, stride: keep n_rec
    samples, one every `stride` steps. stop_after > 0: a launch stops once
    `observer.done(obs, i, stop_after)`. A launch whose state turns non-finite, or whose cos(theta)
    drops below cos_min (the Euler form's singularity), is frozen at its last good state, with
    outcome NONFINITE or CHART_SINGULAR and its stop time. In period mode (stop_after > 0, no
    samples kept) a lane whose launch is done takes the next one (`run_refill`); y_end is then each
    launch's state where it stopped.
    """
    y0 = np.ascontiguousarray(y0, dtype=np.float64)
    params = np.ascontiguousarray(params, dtype=np.float64)
    n = y0.shape[1]
    if y0.shape[0] != N_FAST or params.shape != (3, n):
        raise ValueError(f"need y0 ({N_FAST}, n) and params (3, n); got {y0.shape}, {params.shape}")
    obs = np.full((max(int(n_slots), 1), n), np.nan)
    traj = np.full((n_rec, N_FAST, n), np.nan)
    y_end = np.empty_like(y0)
    outcome = np.zeros(n, dtype=np.int8)
    t_stop = np.full(n, np.nan)
    block = int(block)

    def by_blocks(par, run_block, args):
        if parallel:
            par(y0, params, float(dt), int(n_steps), block, *args)
        else:
            for lo in range(0, n, block):
                run_block(y0, params, float(dt), int(n_steps), lo, min(n, lo + block), *args)

    def result(t, **kw) -> Result:
        return Result(obs=obs[:n_slots], outcome=outcome, t_stop=t_stop,
                      formulation=np.full(n, EULER_ANGLES, dtype=np.int8), y_end=y_end,
                      n_steps=np.full(n, int(n_steps), dtype=np.int64), t=t, traj=traj, **kw)

    if isinstance(observer, StepObserver):
        if n_rec > 0:
            raise ValueError("a step observer keeps no samples (n_rec must be 0)")
        by_blocks(*make_step_kernels(method, observer),
                  (float(cos_min), max(1, int(observe_every)), obs, y_end, int(stop_after),
                   outcome, t_stop))
        return result(np.empty(0), by_steps=np.ones(n, dtype=bool))
    par, run_block, par_refill, run_refill = make_kernels(method, observer)
    if stop_after > 0 and n_rec == 0 and n_slots > 0 and n > 0:
        # period mode: lanes refill from a queue (`run_refill`); groups of launches spread
        # over the threads, several per thread so that none waits long for another
        args = (float(cos_min), max(1, int(observe_every)), obs, y_end, int(stop_after),
                outcome, t_stop)
        if parallel:
            par_refill(y0, params, float(dt), int(n_steps), block,
                       refill_groups(n, block, parallel), *args)
        else:
            run_refill(y0, params, float(dt), int(n_steps), 0, n, block, *args)
        return result(np.empty(0))
    stride = max(1, int(stride))
    by_blocks(par, run_block, (float(cos_min), n_slots > 0, max(1, int(observe_every)), obs,
                               traj, stride, y_end, int(stop_after), outcome, t_stop))
    return result(np.arange(n_rec) * (float(dt) * stride))

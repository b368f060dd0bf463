"""Adaptive Runge-Kutta over an ensemble with every SIMD lane on its own step size.

The fixed-step kernel (`ensemble.py`) shares one step among the launches of a block; the scalar
adaptive kernel (`adaptive.py`) gives each launch its own step but runs one launch at a time. Here
the launches of a block advance together through the same stage arithmetic, each lane with its own
time t and step h: after the stages, each lane accepts or rejects its trial step by a mask (a
select, no branch), so LLVM vectorises the whole step across lanes. A lane that reaches T, or
stops on a failure, keeps flowing through the arithmetic with its state held; a block ends when its
last lane ends.

Formulation: the fixed-frame Newton-Euler state (`physics/fixed.py`), pure arithmetic and regular
at theta = +-90 deg, so launches passing near the vertical need no chart change and no fallback.
The fast Euler view of the end state is returned beside it (chi and phi on their principal
branches).

Method: an embedded pair given as data (`tableaus.LaneTableau`, Dormand-Prince 8(5,3)); the source
of one step is written out from its coefficients. Error control as in Hairer's DOP853: scaled
norms n5, n3 of the two estimates over the 11 state variables with scale atol + rtol max(|y|,
|y_new|), err = |h| n5 / sqrt(11 (n5 + 0.01 n3)), step factor SAFETY err^(-1/8) clipped to
[MIN_FACTOR, MAX_FACTOR] (at most 1 after a rejection). err^(-1/8) is taken as three square roots,
which vectorise where a power would be a library call per lane.

Every lane's arithmetic is its own (no fastmath, no cross-lane reduction), so results are
bit-identical whatever the block size or thread count. All non-dimensional.
"""
from __future__ import annotations

import math
from functools import cache

import numpy as np

from .._jit import njit
from ..physics import fixed
from ..physics.fast import N_FAST, fast_from_fixed_into, fixed_from_fast_into
from .binding import StepObserver, bind
from .ensemble import refill_groups
from .outcome import FIXED_FRAME, OK, Result
from .tableaus import LANE_ADAPTIVE, LaneTableau

SAFETY = 0.9  #: factor on the optimal step
MIN_FACTOR = 0.2  #: smallest step change in one go
MAX_FACTOR = 10.0  #: largest step growth in one go (Hairer's DOP853 default)
STEP_FLOOR = 1e-14  #: steps below STEP_FLOOR max(T, 1) are underflow
CHECK_EVERY = 16  #: sweeps of the block between checks for failures and finished lanes

NV = fixed.N_FIXED

_TEMPLATE = '''
@njit(nogil=True, error_model='numpy', cache=True)
def run_block(v0, params, T, rtol, atol, h0, max_steps, lo, hi, v_end, n_acc_out, status_out,
              t_out):
    m = hi - lo
{load}
    pc = params[0, lo:hi].copy()
    pa = params[1, lo:hi].copy()
    pb = params[2, lo:hi].copy()
    floor = STEP_FLOOR * max(T, 1.0)
    # the trial loop touches only the state rows, the parameters, tl and hl: with one array
    # more LLVM keeps it scalar (measured: a live-flag row or the step counters in it cost the
    # vectorisation). So a retired lane's time is +inf (its time reached is kept in t_fail), an
    # accepted trial leaves a positive next step and a rejected one a negative, and the counters
    # are kept from that after the loop
    tl = np.zeros(m)
    t_prev = np.zeros(m)
    t_fail = np.zeros(m)
    hl = np.full(m, min(max(h0, 1e3 * floor), T))  # a first step far above the floor
    live = np.ones(m, dtype=np.bool_)
    nacc = np.zeros(m, dtype=np.int64)
    ntry = np.zeros(m, dtype=np.int64)  # trial steps, for the budget
    status = np.zeros(m, dtype=np.int8)
    sweep = 0
    while True:
        sweep += 1
        for i in range(m):
            t_prev[i] = tl[i]
        # one trial step on every lane: the arithmetic is shared, accept/reject is a select
{trial_loop}
        if sweep % CHECK_EVERY == 0:
            n_live = 0
            for i in range(m):
                if live[i]:
                    if not math.isfinite({finite}):
                        status[i] = NONFINITE
                    elif tl[i] >= T:
                        live[i] = False
                    elif hl[i] < floor:
                        status[i] = STEP_UNDERFLOW
                    elif ntry[i] >= max_steps:
                        status[i] = STEP_BUDGET
                    else:
                        n_live += 1
                    if status[i] != 0:
                        live[i] = False
                        t_fail[i] = tl[i]
                        tl[i] = math.inf  # off in every later trial
            if n_live == 0:
                break
    for i in range(m):
{store}
        n_acc_out[lo + i] = nacc[i]
        status_out[lo + i] = status[i]
        t_out[lo + i] = t_fail[i] if status[i] != 0 else tl[i]


@njit(parallel=True, nogil=True, error_model='numpy', cache=True)
def run_parallel(v0, params, T, rtol, atol, h0, max_steps, block, v_end, n_acc, status, t_out):
    n = v0.shape[1]
    nblocks = (n + block - 1) // block
    for bi in nb.prange(nblocks):
        lo = bi * block
        run_block(v0, params, T, rtol, atol, h0, max_steps, lo, min(n, lo + block), v_end,
                  n_acc, status, t_out)


@njit(nogil=True, error_model='numpy', cache=True)
def run_serial(v0, params, T, rtol, atol, h0, max_steps, block, v_end, n_acc, status, t_out):
    n = v0.shape[1]
    nblocks = (n + block - 1) // block
    for bi in range(nblocks):
        lo = bi * block
        run_block(v0, params, T, rtol, atol, h0, max_steps, lo, min(n, lo + block), v_end,
                  n_acc, status, t_out)
'''

_HEADER = """# generated by ballsurvey.integrate.lanes from an embedded pair; do not edit
import math
import numba as nb
import numpy as np
from ballsurvey._jit import njit
from ballsurvey.integrate.outcome import NONFINITE, STEP_BUDGET, STEP_UNDERFLOW
from ballsurvey.physics.fixed import rhs_tuple

SAFETY = {safety!r}
MIN_FACTOR = {min_factor!r}
MAX_FACTOR = {max_factor!r}
STEP_FLOOR = {step_floor!r}
CHECK_EVERY = {check_every!r}
"""


def _terms(coefs, name, q):
    return " + ".join(f"{float(w)!r} * {name}{j}[{q}]" for j, w in coefs)


#: one trial step on lane i, shared by both kernels: the step to take (up to T), the stages,
#: the two error norms, accept or reject, and the next step's factor
_TRIAL = """            c = pc[i]
            A = pa[i]
            B = pb[i]
            tt = tl[i]
            on = tt < T  # a lane at T idles until it is retired; a lane off has tt = +inf
            rem = T - tt
            last = hl[i] >= rem
            hh = rem if last else hl[i]
            hh = hh if on else 0.0
            s0 = ({tuple_r})
{stages}
            n5 = 0.0
            n3 = 0.0
{norms}
            den = n5 + 0.01 * n3
            err = hh * n5 / math.sqrt(den * {nv}.0) if den > 0.0 else 0.0
            ok = on and err <= 1.0
            r8th = math.sqrt(math.sqrt(math.sqrt(err)))
            fac = SAFETY / r8th if err > 0.0 else MAX_FACTOR
            fac = MIN_FACTOR if not (fac >= MIN_FACTOR) else fac
            fac = MAX_FACTOR if fac > MAX_FACTOR else fac
            fac = 1.0 if (not ok) and fac > 1.0 else fac"""


#: the trial loop of both kernels, and after it the step counters, kept from the sign of the next
#: step (negative: rejected), with what a kernel does on an accepted step (`on_accept`)
_TRIAL_LOOP = """        for i in range(m):
{trial}
{select}
            tl[i] = (T if last else tt + hh) if ok else tt
            hl[i] = (hh * fac if ok else -(hh * fac)) if on else hl[i]
{after_trial}        for i in range(m):
            if t_prev[i] < T:  # the lane was on
                ntry[i] += 1
                if hl[i] > 0.0:
                    nacc[i] += 1
{on_accept}
                else:
                    hl[i] = -hl[i]"""


def _step_parts(tab: LaneTableau, ind: str, k0: str) -> tuple[str, str, str]:
    """Source of one trial step on lane i (stages from k0, the two error norms, the accepted
    state y0..y10) written out from the pair's coefficients; k0: the expression of the slope at
    the step's start."""
    v = range(NV)
    lines = [f"{ind}k0 = {k0}"]
    for s in range(1, tab.stages):
        terms = [(j, tab.a[s, j]) for j in range(s) if tab.a[s, j] != 0.0]
        comps = ", ".join(f"s0[{q}] + hh * ({_terms(terms, 'k', q)})" for q in v)
        lines.append(f"{ind}s{s} = ({comps})")
        lines.append(f"{ind}k{s} = rhs_tuple(s{s}, c, A, B)")
    b = [(j, w) for j, w in enumerate(tab.b) if w != 0.0]
    e5 = [(j, w) for j, w in enumerate(tab.e5) if w != 0.0]
    e3 = [(j, w) for j, w in enumerate(tab.e3) if w != 0.0]
    norms = []
    for q in v:
        norms.append(f"{ind}y{q} = s0[{q}] + hh * ({_terms(b, 'k', q)})")
        norms.append(f"{ind}w = atol + rtol * max(abs(s0[{q}]), abs(y{q}))")
        norms.append(f"{ind}e = ({_terms(e5, 'k', q)}) / w")
        norms.append(f"{ind}n5 += e * e")
        if e3:
            norms.append(f"{ind}e = ({_terms(e3, 'k', q)}) / w")
            norms.append(f"{ind}n3 += e * e")
    select = "\n".join(f"{ind}r{q}[i] = y{q} if ok else s0[{q}]" for q in v)
    return "\n".join(lines), "\n".join(norms), select


def _check_pair(tab: LaneTableau) -> None:
    if tab.error_exponent != -1.0 / 8.0:
        # the factor err^(-1/8) is three square roots; another exponent would need a power call
        raise ValueError(f"the lane kernel needs an error exponent of -1/8, not {tab.name}'s")


def _header() -> str:
    return _HEADER.format(safety=SAFETY, min_factor=MIN_FACTOR, max_factor=MAX_FACTOR,
                          step_floor=STEP_FLOOR, check_every=CHECK_EVERY)


def kernel_module_source(tab: LaneTableau) -> str:
    """The generated kernel module's text for a pair of LANE_ADAPTIVE."""
    _check_pair(tab)
    v = range(NV)
    stages, norms, select = _step_parts(tab, " " * 12, "rhs_tuple(s0, c, A, B)")
    trial = _TRIAL.format(tuple_r=", ".join(f"r{q}[i]" for q in v), stages=stages, norms=norms,
                          nv=NV)
    body = _TEMPLATE.format(
        load="\n".join(f"    r{q} = v0[{q}, lo:hi].copy()" for q in v),
        trial_loop=_TRIAL_LOOP.format(trial=trial, select=select, after_trial="", on_accept=""),
        finite=" + ".join(f"r{q}[i]" for q in v),
        store="\n".join(f"        v_end[{q}, lo + i] = r{q}[i]" for q in v))
    return _header() + body


_OBSERVED = """
@njit(nogil=True, error_model='numpy', cache=True)
def run_group(u0, params, T, rtol, atol, h0, max_steps, lo, hi, lanes, stop_after, obs, v_end,
              n_acc_out, status_out, t_out):
    # launches lo..hi-1 through `lanes` lanes: a lane whose launch ends takes the next at once
    m = min(lanes, hi - lo)
{alloc}
    pc = np.full(m, params[0, lo])
    pa = np.full(m, params[1, lo])
    pb = np.full(m, params[2, lo])
    floor = STEP_FLOOR * max(T, 1.0)
    # as in run_block, the trial loop touches only the state rows, the parameters, tl and hl (so
    # LLVM vectorises it): a lane with no launch has time +inf, a rejected trial leaves a negative
    # next step, and the step's two ends and slopes are kept around it
    tl = np.full(m, np.inf)
    t_prev = np.zeros(m)
    hl = np.zeros(m)
    runs = T > 0.0  # a lane with a launch steps (T = 0: the launch is its only sample)
    idx = np.full(m, -1, dtype=np.int64)
    nacc = np.zeros(m, dtype=np.int64)
    ntry = np.zeros(m, dtype=np.int64)
    n_obs = obs.shape[0]
    obs_l = np.full((m, n_obs), np.nan).T  # each lane's slots side by side in memory
    ev = np.empty(N_FAST)
    vv = np.empty(NV)
    dv = np.empty(NV)
    ya = np.empty(NV)
    fa = np.empty(NV)
    yb = np.empty(NV)
    fb = np.empty(NV)
    pp = np.empty(3)
    nxt = lo
    active = 0
    while True:
        for i in range(m):  # refill idle lanes from the queue; the launch is its first sample
            if idx[i] < 0 and nxt < hi:
                j = nxt
                nxt += 1
                for q in range(N_FAST):
                    ev[q] = u0[q, j]
                fixed_from_fast_into(ev, vv)
                for q in range(3):
                    pp[q] = params[q, j]
                pc[i] = pp[0]
                pa[i] = pp[1]
                pb[i] = pp[2]
                s0 = ({tuple_vv})
                k0 = rhs_tuple(s0, pp[0], pp[1], pp[2])
{load}
                for q in range(NV):
                    dv[q] = k0[q]
                start(obs_l, i, vv, dv, pp[0], pp[1], pp[2])
                tl[i] = 0.0
                hl[i] = min(max(h0, 1e3 * floor), T)
                nacc[i] = 0
                ntry[i] = 0
                idx[i] = j
                active += 1
        if active == 0:
            break
        for i in range(m):  # the step's start: time and state
            t_prev[i] = tl[i]
{keep}
        # one trial step on every lane, run_block's
{trial_loop}
        # the observer on each accepted step (its two ends and slopes), checks, and finished
        # launches
        for i in range(m):
            if idx[i] < 0:
                continue
            status = 0
            finished = not runs
            if runs:
                if not math.isfinite({finite}):
                    status = NONFINITE
                elif hl[i] < floor:
                    status = STEP_UNDERFLOW
                elif ntry[i] >= max_steps:
                    status = STEP_BUDGET
            if status == 0 and tl[i] > t_prev[i]:
{ends}
                step(obs_l, i, t_prev[i], tl[i] - t_prev[i], ya, fa, yb, fb, pc[i], pa[i], pb[i],
                     tl[i] >= T)
                if stop_after > 0 and done(obs_l, i, stop_after):
                    finished = True
            if status != 0 or finished or tl[i] >= T:
                j = idx[i]
                for q in range(n_obs):
                    obs[q, j] = obs_l[q, i]
{store}
                n_acc_out[j] = nacc[i]
                status_out[j] = status
                t_out[j] = tl[i]
                tl[i] = math.inf  # off until the lane takes another launch
                idx[i] = -1
                active -= 1


@njit(parallel=True, nogil=True, error_model='numpy', cache=True)
def run_parallel(u0, params, T, rtol, atol, h0, max_steps, lanes, groups, stop_after, obs,
                 v_end, n_acc, status, t_out):
    n = u0.shape[1]
    size = (n + groups - 1) // groups
    for g in nb.prange(groups):
        lo = g * size
        if lo < n:
            run_group(u0, params, T, rtol, atol, h0, max_steps, lo, min(n, lo + size), lanes,
                      stop_after, obs, v_end, n_acc, status, t_out)


@njit(nogil=True, error_model='numpy', cache=True)
def run_serial(u0, params, T, rtol, atol, h0, max_steps, lanes, groups, stop_after, obs,
               v_end, n_acc, status, t_out):
    run_group(u0, params, T, rtol, atol, h0, max_steps, 0, u0.shape[1], lanes, stop_after,
              obs, v_end, n_acc, status, t_out)
"""

_OBSERVED_HEADER = """
from ballsurvey.integrate.outcome import NONFINITE, STEP_BUDGET, STEP_UNDERFLOW
from ballsurvey.physics.fast import N_FAST, fixed_from_fast_into

NV = {nv!r}

# the step observer, handed in by ballsurvey.integrate.binding.bind before anything is compiled
start = None
step = None
done = None
"""


def observed_module_source(tab: LaneTableau) -> str:
    """The generated module of the observed lane kernel (`integrate_observed`) for a pair of
    LANE_ADAPTIVE."""
    _check_pair(tab)
    v = range(NV)
    ind = " " * 12
    stages, norms, select = _step_parts(tab, ind, "rhs_tuple(s0, c, A, B)")
    keep = "\n".join(f"{ind}o{q}[i] = r{q}[i]" for q in v)
    # an accepted step's slopes, at its start (the last one's end) and at its end, in a loop of
    # their own over every lane (a select keeps a rejected lane's): LLVM vectorises it, where
    # one right-hand side per accepted step in the counters' loop would stay scalar
    ind3 = " " * 12
    after_trial = (
        "        for i in range(m):  # the slope at each lane's new state\n"
        f"{ind3}kn = rhs_tuple((" + ", ".join(f"r{q}[i]" for q in v) + "), pc[i], pa[i], pb[i])\n"
        f"{ind3}acc = (t_prev[i] < T) & (hl[i] > 0.0)\n"
        + "".join(f"{ind3}g{q}[i] = f{q}[i] if acc else g{q}[i]\n"
                  f"{ind3}f{q}[i] = kn[{q}] if acc else f{q}[i]\n" for q in v))
    ind4 = " " * 16
    ends = "\n".join(f"{ind4}ya[{q}] = o{q}[i]\n{ind4}fa[{q}] = g{q}[i]\n"
                     f"{ind4}yb[{q}] = r{q}[i]\n{ind4}fb[{q}] = f{q}[i]" for q in v)
    body = _OBSERVED.format(
        alloc="\n".join(f"    r{q} = np.zeros(m)\n    f{q} = np.zeros(m)\n    o{q} = np.zeros(m)"
                        f"\n    g{q} = np.zeros(m)" for q in v),
        tuple_vv=", ".join(f"vv[{q}]" for q in v),
        load="\n".join(f"                r{q}[i] = vv[{q}]\n                f{q}[i] = k0[{q}]"
                       for q in v),
        trial_loop=_TRIAL_LOOP.format(
            trial=_TRIAL.format(tuple_r=", ".join(f"r{q}[i]" for q in v), stages=stages,
                                norms=norms, nv=NV),
            select=select, after_trial=after_trial, on_accept=""),
        keep=keep,
        finite=" + ".join(f"r{q}[i]" for q in v), ends=ends,
        store="\n".join(f"                v_end[{q}, j] = r{q}[i]" for q in v))
    return _header() + _OBSERVED_HEADER.format(nv=NV) + body


jit = njit(cache=True, nogil=True, error_model="numpy")  # stamped cache: _jit.py


@jit
def fixed_columns(y, v):
    """Each fast Euler column of y (N_FAST, n) as a fixed-frame state into v (N_FIXED, n)."""
    for j in range(y.shape[1]):
        fixed_from_fast_into(y[:, j], v[:, j])


@jit
def fast_columns(v, y):
    """Fast Euler view of each fixed-frame column (chi, phi on their principal branches); NaN
    where the axis is vertical and the chart has no view."""
    out = np.empty(y.shape[0])
    for j in range(v.shape[1]):
        if fast_from_fixed_into(v[:, j], 0.0, 0.0, out):
            for q in range(y.shape[0]):
                y[q, j] = out[q]


@cache
def make_kernels(method: str):
    """(run_parallel, run_serial) of the lane kernel for a pair named in LANE_ADAPTIVE, compiled
    from a generated module cached like the ensemble kernels (`binding.bind`)."""
    if method not in LANE_ADAPTIVE:
        raise ValueError(f"unknown lane method {method!r}; known: {', '.join(LANE_ADAPTIVE)}")
    mod = bind(f"lanes_{method}", kernel_module_source(LANE_ADAPTIVE[method]), None)
    return mod.run_parallel, mod.run_serial


def _checked(y0, params, T, rtol, atol):
    """Contiguous float64 launches and parameters, and their count, or one line on bad input."""
    y0 = np.ascontiguousarray(y0, dtype=np.float64)
    params = np.ascontiguousarray(params, dtype=np.float64)
    n = y0.shape[1]
    if y0.shape[0] != N_FAST or params.shape != (3, n):
        raise ValueError(f"need y0 ({N_FAST}, n) and params (3, n); got {y0.shape}, {params.shape}")
    if not (T >= 0.0 and np.isfinite(T)):
        raise ValueError(f"T must be finite and >= 0, got {T}")
    if not (0.0 <= rtol < 1.0 and 0.0 < atol < math.inf):
        raise ValueError(f"need 0 <= rtol < 1 and finite atol > 0, got rtol={rtol}, atol={atol}")
    return y0, params, n


def integrate_lanes(y0, params, T, rtol=1e-9, atol=1e-12, *, method="dop853", block=64,
                    h_init=1e-3, max_steps=10_000_000, parallel=True) -> Result:
    """Integrate n launches to time T (non-dimensional), each lane its own adaptive step.

    y0: (N_FAST, n) fast Euler states; params: (3, n) non-dimensional (c, A, B). Returns a
    `Result` with y_end the fast Euler view of the final fixed-frame state (chi and phi in
    (-pi, pi]), n_steps the accepted steps, formulation FIXED_FRAME, and the final fixed-frame
    state itself in `traj` (shape (N_FIXED, n)); no observer. outcome: OK, NONFINITE,
    STEP_UNDERFLOW or STEP_BUDGET (max_steps trial steps), with t_stop the time reached."""
    y0, params, n = _checked(y0, params, T, rtol, atol)
    if not (0.0 < h_init < math.inf):
        raise ValueError(f"h_init must be finite and > 0, got {h_init}")
    v0 = np.empty((NV, n))
    fixed_columns(y0, v0)
    v_end = np.empty_like(v0)
    n_acc = np.zeros(n, dtype=np.int64)
    status = np.zeros(n, dtype=np.int8)
    t_end = np.zeros(n)
    par, ser = make_kernels(method)
    block = max(1, int(block))
    if parallel:
        import numba

        # enough blocks for every thread (the block size never changes a result)
        block = max(1, min(block, -(-n // (2 * numba.get_num_threads()))))
    if n > 0:
        (par if parallel else ser)(v0, params, float(T), float(rtol), float(atol), float(h_init),
                                   int(max_steps), block, v_end, n_acc, status, t_end)
    y_end = np.full((N_FAST, n), np.nan)
    fast_columns(v_end, y_end)
    return Result(obs=np.empty((0, n)), outcome=status,
                  t_stop=np.where(status != OK, t_end, np.nan),
                  formulation=np.full(n, FIXED_FRAME, dtype=np.int8), y_end=y_end,
                  n_steps=n_acc, t=np.array([float(T)]), traj=v_end)



@cache
def make_observed_kernels(method: str, observer: StepObserver):
    """(run_parallel, run_serial) of the observed lane kernel for a pair named in LANE_ADAPTIVE,
    bound to the step observer `observer` (`binding.bind`)."""
    if method not in LANE_ADAPTIVE:
        raise ValueError(f"unknown lane method {method!r}; known: {', '.join(LANE_ADAPTIVE)}")
    mod = bind(f"lanes_obs_{method}", observed_module_source(LANE_ADAPTIVE[method]), observer,
               inline_record=True)
    return mod.run_parallel, mod.run_serial


def integrate_observed(y0, params, T, rtol=1e-9, atol=1e-12, *, observer: StepObserver,
                       n_slots: int, method="dop853", lanes=64, h_init=1e-3,
                       max_steps=10_000_000, parallel=True, stop_after=0) -> Result:
    """`integrate_lanes` with a step observer: `observer.start` sees each launch's fixed-frame
    state and rate at t = 0, `observer.step` each accepted step (its start time and length, the
    states and rates at both ends: what the step's cubic Hermite interpolant is made of), so the
    observer's cost follows the steps. T = 0: the launch is observed and nothing stepped (h_init
    is then not read).

    Lanes refill from a queue: a lane whose launch reaches T, fails, or (stop_after > 0, period
    mode) has `observer.done(obs, i, stop_after)` takes the next launch at once. Each launch's
    arithmetic is its own, so results are bit-identical for any lane count and thread count, and
    its steps are exactly `integrate_lanes`'s. Returns a `Result`: obs (n_slots, n), outcome,
    t_stop (time reached where the run failed), formulation FIXED_FRAME, y_end (Euler view of
    the last state, principal branches), n_steps accepted, traj the last fixed-frame state."""
    y0, params, n = _checked(y0, params, T, rtol, atol)
    if T > 0.0 and not (0.0 < h_init < math.inf):  # T = 0 takes no step: the launch is all
        raise ValueError(f"h_init must be finite and > 0, got {h_init}")
    obs = np.full((max(int(n_slots), 1), n), np.nan)
    v_end = np.full((NV, n), np.nan)
    n_acc = np.zeros(n, dtype=np.int64)
    status = np.zeros(n, dtype=np.int8)
    t_end = np.zeros(n)
    par, ser = make_observed_kernels(method, observer)
    lanes = max(1, int(lanes))
    groups = refill_groups(n, lanes, parallel)
    if n > 0:
        (par if parallel else ser)(y0, params, float(T), float(rtol), float(atol), float(h_init),
                                   int(max_steps), lanes, groups, int(stop_after), obs, v_end,
                                   n_acc, status, t_end)
    y_end = np.full((N_FAST, n), np.nan)
    fast_columns(v_end, y_end)
    return Result(obs=obs[:n_slots], outcome=status,
                  t_stop=np.where(status != OK, t_end, np.nan),
                  formulation=np.full(n, FIXED_FRAME, dtype=np.int8), y_end=y_end,
                  n_steps=n_acc, t=np.array([float(T)]), traj=v_end)

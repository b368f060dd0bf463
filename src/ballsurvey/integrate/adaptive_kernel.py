"""Template of the adaptive kernel module (bound to an observer by `binding.bind`; see adaptive.py).

Never imported as itself: `adaptive.make_kernels` writes this text, with the observer's identity,
into a module in the cache directory and sets `record` and `done` there (a sampling observer),
or `start`, `step` and `done` (a step observer: OBSERVE_STEPS is then True in the text, and each
accepted step's fixed-frame states and rates at its two ends are handed to `step`). Imports are
absolute for that reason.

Dormand-Prince with FSAL and its dense output, one launch per call, its own step size. Error
control: RMS over the checked variables of err / (atol + rtol max(|y|, |y_new|)); the step-size rule
h <- h min(MAX_FACTOR, max(MIN_FACTOR, SAFETY err^exponent)), exponent = -1 / (error order + 1)
(from the tableau, as scipy's rk.py). All non-dimensional.
"""
import math

import numba as nb
import numpy as np

from ballsurvey._jit import njit
from ballsurvey.integrate.outcome import CHART_SINGULAR, NONFINITE, OK, STEP_BUDGET, STEP_UNDERFLOW
from ballsurvey.physics import fixed
from ballsurvey.physics.fast import (
    N_FAST,
    S_CHD,
    S_CHI,
    S_CTH,
    S_PHD,
    S_PHI,
    fast_from_fixed_into,
    fast_rhs_into,
    fixed_from_fast_into,
    observed_fixed_from_fast_into,
)

# the observer, handed in by ballsurvey.integrate.binding.bind before anything is compiled
record = None
done = None
start = None
step = None
#: a step observer is bound (the text is written with True by `adaptive.make_kernels`)
OBSERVE_STEPS = False

SAFETY = 0.9  #: factor on the optimal step
MIN_FACTOR = 0.2  #: smallest step change in one go
MAX_FACTOR = 5.0  #: largest step growth in one go
STEP_FLOOR = 1e-14  #: steps below STEP_FLOOR max(T, 1) are underflow
#: cos theta below which the fixed-frame Euler view is not shown to the observer
VIEW_MIN_COS = 1e-6

jit = njit(cache=True, nogil=True, error_model="numpy")  # stamped cache: _jit.py


@jit
def _fixed_view(y, p, v, f):
    """The fixed-frame state v (its body vector b left 0: a step observer reads e, w and G) of the
    fast Euler state y, and its rate f."""
    observed_fixed_from_fast_into(y, v)
    fixed.rhs(v, p, f)


@jit
def _record_fast(obs, i, first, t, dt, y, k, p):
    record(obs, i, first, t, dt, y[0], y[1], y[2], y[8], y[9], y[3], y[5], y[6], y[7],
           k[5], k[6], k[7], p[0], p[1], p[2], math.nan, math.nan, math.nan)


@jit
def _stages(y, h, a, k, yt, yn, p, fixed_form):
    """Stages 1.. of one trial step from y (k[0] holds f(y)); yn: the new solution."""
    ns = k.shape[0]
    nv = y.shape[0]
    for s in range(1, ns):
        for q in range(nv):
            acc = 0.0
            for j in range(s):
                acc += a[s, j] * k[j, q]
            yt[q] = y[q] + h * acc
        if s == ns - 1:
            for q in range(nv):
                yn[q] = yt[q]
        if fixed_form:
            fixed.rhs(yt, p, k[s])
        else:
            fast_rhs_into(yt, p, k[s])


@jit
def _error(y, yn, k, berr, h, rtol, atol, n_check):
    """RMS of the scaled error estimate over the first n_check variables."""
    err = 0.0
    for q in range(n_check):
        e = 0.0
        for j in range(k.shape[0]):
            e += berr[j] * k[j, q]
        sc = atol + rtol * max(abs(y[q]), abs(yn[q]))
        err += (h * e / sc) ** 2
    return math.sqrt(err / n_check)


@jit
def _dense(y, k, dense, h, x, out):
    """The pair's continuous extension at t + x h (0 <= x <= 1) of the step from y with stages k."""
    for q in range(y.shape[0]):
        acc = 0.0
        for s in range(k.shape[0]):
            xp = 1.0
            w = 0.0
            for j in range(dense.shape[1]):
                xp *= x
                w += dense[s, j] * xp
            acc += k[s, q] * w
        out[q] = y[q] + h * acc


@jit
def adaptive_one(y0, p, T, tol, tab, obs, i, fixed_form, max_steps, traj, t_rec, t_out, y_last,
                 stop_after):
    """One launch; fixed_form: integrate the fixed-frame state (physics/fixed.py).

    tol = (rtol, atol, h_init, cos_min, error exponent); tab = (a, b, b_err, dense) of the pair.
    Output, one of: t_out (m,) non-empty: traj (m, N_FAST) gets the (Euler view of the) state at
    those times (increasing, in [0, T]) from the pair's dense output; else traj (cap, N_FAST),
    t_rec (cap,) get the state at the start and at each accepted step while there is room (cap may
    be 0). y_last (N_FAST,): the final (Euler view of the) state. Returns (accepted steps,
    outcome, time reached)."""
    rtol, atol, h_init, cos_min, err_exp, h_max = tol[0], tol[1], tol[2], tol[3], tol[4], tol[5]
    a, b, berr, dense = tab
    ns = b.shape[0]
    nv = fixed.N_FIXED if fixed_form else N_FAST
    # error measured on every fixed-frame variable, or on the Euler state's x, y, angles and
    # rates (its first 8 slots; the sin/cos copies are redundant)
    n_check = nv if fixed_form else 8
    y = np.empty(nv)
    ev = np.empty(N_FAST)  # the Euler view the observer sees
    ek = np.empty(N_FAST)
    k = np.empty((ns, nv))
    yt = np.empty(nv)
    yn = np.empty(nv)
    eo = np.empty(N_FAST)  # the Euler view at an output time
    for q in range(N_FAST):
        ev[q] = y0[q]
    # `first` is the run-time n_acc == 0 at every record call, never a literal True or False:
    # numba compiles the observer once per literal value it is called with
    n_acc = 0
    # a step observer's fixed-frame state and rate at the last accepted step's end (ya, fa) and
    # at the new one's (yb, fb)
    ya = np.empty(fixed.N_FIXED)
    fa = np.empty(fixed.N_FIXED)
    yb = np.empty(fixed.N_FIXED)
    fb = np.empty(fixed.N_FIXED)
    if fixed_form:
        fixed_from_fast_into(y0, y)
        fixed.rhs(y, p, k[0])
        if OBSERVE_STEPS:
            ya[:] = y
            fa[:] = k[0]
            start(obs, i, ya, fa, p[0], p[1], p[2])
        else:
            fast_rhs_into(ev, p, ek)
            _record_fast(obs, i, n_acc == 0, 0.0, 0.0, ev, ek, p)
    else:
        for q in range(nv):
            y[q] = y0[q]
        fast_rhs_into(y, p, k[0])
        if OBSERVE_STEPS:
            _fixed_view(y, p, ya, fa)
            start(obs, i, ya, fa, p[0], p[1], p[2])
        else:
            _record_fast(obs, i, n_acc == 0, 0.0, 0.0, y, k[0], p)
    t = 0.0
    h = min(h_init, T, h_max)
    status = OK
    n_out = t_out.shape[0]
    cap = traj.shape[0] if n_out == 0 else 0
    if cap > 0:
        for q in range(N_FAST):
            traj[0, q] = ev[q]
        t_rec[0] = 0.0
    j_out = 0
    while j_out < n_out and t_out[j_out] <= 0.0:
        for q in range(N_FAST):
            traj[j_out, q] = ev[q]
        j_out += 1
    while t < T:
        if n_acc >= max_steps:
            status = STEP_BUDGET
            break
        if t + h > T:
            h = T - t
        _stages(y, h, a, k, yt, yn, p, fixed_form)
        err = _error(y, yn, k, berr, h, rtol, atol, n_check)
        if not math.isfinite(err):
            if h < STEP_FLOOR * max(T, 1.0):
                status = NONFINITE
                break
            h *= MIN_FACTOR
            continue
        if err <= 1.0:
            t_new = t + h if t + h < T else T
            while j_out < n_out and t_out[j_out] <= t_new:  # output times inside this step
                _dense(y, k, dense, h, (t_out[j_out] - t) / h, yt)
                if fixed_form:
                    dtq = t_out[j_out] - t
                    if fast_from_fixed_into(yt, ev[S_CHI] + dtq * ev[S_CHD],
                                            ev[S_PHI] + dtq * ev[S_PHD], eo):
                        for q in range(N_FAST):
                            traj[j_out, q] = eo[q]
                else:
                    for q in range(N_FAST):
                        traj[j_out, q] = yt[q]
                j_out += 1
            t_old = t
            t = t_new
            for q in range(nv):
                y[q] = yn[q]
                k[0, q] = k[ns - 1, q]  # FSAL
            n_acc += 1
            if n_acc < cap:
                t_rec[n_acc] = t
            if OBSERVE_STEPS:
                if not fixed_form and y[S_CTH] < cos_min:
                    status = CHART_SINGULAR
                    break
                if fixed_form:
                    yb[:] = y
                    fb[:] = k[0]
                else:
                    _fixed_view(y, p, yb, fb)
                step(obs, i, t_old, t - t_old, ya, fa, yb, fb, p[0], p[1], p[2], t >= T)
                ya[:] = yb
                fa[:] = fb
                if fixed_form and fast_from_fixed_into(
                        y, ev[S_CHI] + h * ev[S_CHD], ev[S_PHI] + h * ev[S_PHD], eo):
                    ev[:] = eo
                elif not fixed_form:
                    ev[:] = y
            elif fixed_form:
                # the Euler view, chi and phi on the branches nearest their predicted values
                if fast_from_fixed_into(y, ev[S_CHI] + h * ev[S_CHD], ev[S_PHI] + h * ev[S_PHD],
                                        ev):
                    fast_rhs_into(ev, p, ek)
                    if ev[S_CTH] > VIEW_MIN_COS:
                        psid, fric, normal = fixed.path_kinematics(y, k[0], p[0])
                        record(obs, i, n_acc == 0, t, h, ev[0], ev[1], ev[2], ev[8], ev[9], ev[3],
                               ev[5], ev[6], ev[7], ek[5], ek[6], ek[7], p[0], p[1], p[2],
                               psid, fric, normal)
            else:
                if y[S_CTH] < cos_min:
                    status = CHART_SINGULAR
                    break
                for q in range(N_FAST):
                    ev[q] = y[q]
                _record_fast(obs, i, n_acc == 0, t, h, y, k[0], p)
            if n_acc < cap:
                for q in range(N_FAST):
                    traj[n_acc, q] = ev[q]
            if stop_after > 0 and done(obs, i, stop_after):
                break  # period mode: the observer has seen enough
            fac = (MAX_FACTOR if err == 0.0
                   else min(MAX_FACTOR, max(MIN_FACTOR, SAFETY * err ** err_exp)))
            h = min(h * fac, h_max)
        else:
            h *= max(MIN_FACTOR, SAFETY * err ** err_exp)
            if h < STEP_FLOOR * max(T, 1.0):
                status = STEP_UNDERFLOW
                break
    if fixed_form:
        if not fast_from_fixed_into(y, ev[S_CHI], ev[S_PHI], ev):
            ev[:] = math.nan
    else:
        for q in range(N_FAST):
            ev[q] = y[q]
    for q in range(N_FAST):
        y_last[q] = ev[q]
    return n_acc, status, t


@njit(parallel=True, nogil=True, error_model="numpy", cache=True)  # cached: see ensemble.py
def run_parallel(y0, params, T, tol, tab, obs, fixed_form, max_steps, n_steps, y_end,
                 stop_after, outcome, t_stop):
    """adaptive_one on every launch (column) of y0, params, spread over numba's threads. Each
    launch is handed over as adaptive_one is called from Python (`adaptive.run_serial`, one
    launch's trajectory): contiguous columns and a signed index, so one compilation of it serves
    all three."""
    for i in nb.prange(y0.shape[1]):
        empty, t_empty = np.empty((0, N_FAST)), np.empty(0)
        y_last = np.empty(N_FAST)
        n_steps[i], st, t = adaptive_one(y0[:, i].copy(), params[:, i].copy(), T, tol, tab, obs,
                                         np.int64(i), fixed_form, max_steps, empty, t_empty,
                                         t_empty, y_last, stop_after)
        y_end[:, i] = y_last
        outcome[i] = st
        t_stop[i] = t if st != OK else math.nan

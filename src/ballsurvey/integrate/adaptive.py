"""Adaptive embedded Runge-Kutta (the pairs of tableaus.py, Dormand-Prince 5(4)) per launch.

* `integrate_adaptive`: every launch has its own step size (prange over launches, one scalar driver
  each), so a launch's result never depends on which launches share its batch. The observer is fed
  at every accepted step.
* `fixed_frame=True`: the same driver on the Euler-free Newton-Euler state (physics/fixed.py), for
  launches whose tilt reaches the Euler form's singularity (|theta| -> 90 deg). Each accepted step
  is shown to the observer through the Euler view (physics/fast.py: `fast_from_fixed_into`), with
  the path's heading rate, friction demand and normal force computed without the chart
  (`fixed.path_kinematics`).

The kernels are in adaptive_kernel.py, a template bound to the observer handed in (binding.py).
All non-dimensional.
"""
from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np

from ..physics.fast import N_FAST
from .binding import Observer, StepObserver, bind
from .outcome import EULER_ANGLES, FIXED_FRAME, OK, Result
from .tableaus import ADAPTIVE, DOPRI5, EmbeddedTableau

__all__ = ["ADAPTIVE", "DOPRI5", "integrate_adaptive", "trajectory_adaptive", "make_kernels"]

#: accepted steps one launch may take before it stops with outcome STEP_BUDGET
MAX_STEPS = 50_000_000


@cache
def make_kernels(observer: Observer | StepObserver):
    """The adaptive kernel module (adaptive_kernel.py) bound to `observer`: a sampling one
    (`record` on each accepted step, in the Euler view) or a step observer (`start`, and `step`
    with each accepted step's fixed-frame states and rates at its two ends)."""
    text = (Path(__file__).parent / "adaptive_kernel.py").read_text()
    if isinstance(observer, StepObserver):
        marker = "OBSERVE_STEPS = False"
        assert text.count(marker) == 1
        return bind("adaptive_steps", text.replace(marker, "OBSERVE_STEPS = True"),
                    observer._replace(span=None))
    return bind("adaptive", text, observer)


def _tol(tableau, rtol, atol, h_init, cos_min, h_max=np.inf):
    return np.array([rtol, atol, h_init, cos_min, tableau.error_exponent, h_max],
                    dtype=np.float64)


def _tab(tableau):
    return (tableau.a, tableau.b, tableau.b_err, tableau.dense)


def run_serial(mod, y0, params, T, tol, tab, obs, fixed_form, max_steps, n_steps, y_end,
               stop_after, outcome, t_stop) -> None:
    """`run_parallel`'s work on the calling thread: the kernel module's adaptive_one called from
    here on each launch (it releases the GIL), with the argument types `run_parallel` gives it,
    so no serial driver of its own is compiled (each driver compiles adaptive_one into itself
    again: about a second)."""
    empty, t_empty = np.empty((0, N_FAST)), np.empty(0)
    y_last = np.empty(N_FAST)
    for i in range(y0.shape[1]):
        n_steps[i], st, t = mod.adaptive_one(
            np.ascontiguousarray(y0[:, i]), np.ascontiguousarray(params[:, i]), T, tol, tab,
            obs, i, fixed_form, max_steps, empty, t_empty, t_empty, y_last, stop_after)
        y_end[:, i] = y_last
        outcome[i] = st
        t_stop[i] = t if st != OK else np.nan


def integrate_adaptive(y0, params, T, rtol=1e-9, atol=1e-12, *, observer: Observer, n_slots: int,
                       fixed_frame=False, cos_min=1e-3, h_init=1e-3, max_steps=MAX_STEPS,
                       parallel=True, tableau: EmbeddedTableau = DOPRI5, stop_after=0,
                       h_max=np.inf) -> Result:
    """Adaptive integration of fast-state launches y0 (N_FAST, n) for non-dimensional time T.

    fixed_frame: integrate the Euler-free form (no singularity at theta = 90 deg); the observer
    and y_end see the Euler view. stop_after > 0: a launch stops once
    `observer.done(obs, i, stop_after)`.
    """
    y0 = np.ascontiguousarray(y0, dtype=np.float64)
    params = np.ascontiguousarray(params, dtype=np.float64)
    n = y0.shape[1]
    obs = np.full((n_slots, n), np.nan)
    steps = np.zeros(n, dtype=np.int64)
    y_end = np.full((N_FAST, n), np.nan)
    outcome = np.zeros(n, dtype=np.int8)
    t_stop = np.full(n, np.nan)
    mod = make_kernels(observer)
    args = (y0, params, float(T), _tol(tableau, float(rtol), float(atol), float(h_init),
                                       float(cos_min), float(h_max)),
            _tab(tableau), obs, bool(fixed_frame), int(max_steps), steps, y_end,
            int(stop_after), outcome, t_stop)
    if parallel:
        mod.run_parallel(*args)
    else:
        run_serial(mod, *args)
    form = FIXED_FRAME if fixed_frame else EULER_ANGLES
    return Result(obs=obs, outcome=outcome, t_stop=t_stop,
                  formulation=np.full(n, form, dtype=np.int8), y_end=y_end, n_steps=steps,
                  t=np.empty(0), traj=np.empty((0, N_FAST)),
                  by_steps=np.full(n, isinstance(observer, StepObserver)))


def trajectory_adaptive(y0_col, params_col, T, rtol=1e-9, atol=1e-12, *, observer: Observer,
                        n_slots: int, t_out=None, fixed_frame=False, cos_min=1e-3, h_init=1e-3,
                        max_steps=MAX_STEPS, tableau: EmbeddedTableau = DOPRI5,
                        h_max=np.inf) -> Result:
    """One launch with its trajectory kept: Result with t (m,) and traj (m, N_FAST), the other
    fields of shape (1,) / (n_slots, 1). In the fixed-frame form the states are the Euler view.

    t_out (increasing, in [0, T]): the samples are the state at those times, from the pair's dense
    output (rows after an early stop stay NaN). None: the samples are the accepted steps (not
    evenly spaced); a first pass counts them, so the buffer is exactly as long as the trajectory
    (the integration is deterministic: the second pass takes the same steps)."""
    y0_col = np.ascontiguousarray(y0_col, dtype=np.float64)
    params_col = np.ascontiguousarray(params_col, dtype=np.float64)
    mod = make_kernels(observer)
    tol = _tol(tableau, float(rtol), float(atol), float(h_init), float(cos_min), float(h_max))
    dense = t_out is not None
    # times a rounding past T (a fixed-step run's last sample) are taken at T
    t_out = np.minimum(np.asarray(t_out if dense else np.empty(0), dtype=np.float64), float(T))
    cap = t_out.size
    out = ()
    for _ in range(1 if dense else 2):
        obs = np.full((n_slots, 1), np.nan)
        traj = np.full((cap, N_FAST), np.nan)
        t_rec = np.full(0 if dense else cap, np.nan)
        y_last = np.empty(N_FAST)
        out = mod.adaptive_one(y0_col, params_col, float(T), tol, _tab(tableau), obs, 0,
                               bool(fixed_frame), int(max_steps), traj, t_rec, t_out, y_last, 0)
        cap = out[0] + 1
    n_acc, status, t = out
    form = FIXED_FRAME if fixed_frame else EULER_ANGLES
    return Result(obs=obs, outcome=np.array([status], dtype=np.int8),
                  t_stop=np.array([t if status else np.nan]),
                  formulation=np.array([form], dtype=np.int8), y_end=y_last[:, None],
                  n_steps=np.array([n_acc]), t=t_out if dense else t_rec, traj=traj)

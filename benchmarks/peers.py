"""Peers on ballsurvey's ensemble work-precision problem, timed in the same run as ballsurvey.

    python -m venv /tmp/peers && /tmp/peers/bin/pip install -e . -r benchmarks/requirements.txt
    /tmp/peers/bin/python benchmarks/peers.py [--launches 256] [--repeats 3]

The problem is `ballsurvey.accuracy.square_launches`: launches around the paper's square, T = 20 s,
final position error against `ballsurvey.accuracy.ensemble_reference`. Every peer integrates the
same fixed-frame equations (`ballsurvey.physics.fixed.rhs`, regular at the vertical), so that
comparison is between integrators, not formulations:

- numbalsoda's DOP853 (Hairer's Fortran-derived C++), one launch per call, launches spread over
  all threads by numba prange; the right-hand side a numba cfunc: the same fixed-frame equations
  ("fixed"), and the paper's Euler-angle equations (`ballsurvey.physics.euler.rhs`, "euler"), the
  form a user would write from the paper, singular at the vertical;
- scipy's solve_ivp DOP853 on a sample of launches (pure Python stepping; per-launch rate);
- ballsurvey's DOP853 in the SIMD-lane kernel (`ballsurvey.integrate.lanes`), for the ratio.
"""
from __future__ import annotations

import argparse

import numba as nb
import numpy as np

from ballsurvey.accuracy import best_of, ensemble_reference, square_launches
from ballsurvey.integrate.lanes import fixed_columns, integrate_lanes
from ballsurvey.physics import euler, fixed

RTOLS = (1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11)


def numbalsoda_runner(form: str):
    """prange over launches of numbalsoda's dop853; form "fixed": the fixed-frame state (11
    variables); "euler": the paper's Euler-angle state (8 variables, sin and cos taken in the
    right-hand side), as one would write it from the paper."""
    from numbalsoda import dop853, lsoda_sig

    nv = 11 if form == "fixed" else 8
    if form == "fixed":
        @nb.cfunc(lsoda_sig)
        def f(t, u, du, p):
            fixed.rhs(nb.carray(u, (11,)), nb.carray(p, (3,)), nb.carray(du, (11,)))
    else:
        @nb.cfunc(lsoda_sig)
        def f(t, u, du, p):
            euler.rhs(nb.carray(u, (8,)), nb.carray(p, (3,)), nb.carray(du, (8,)))

    ptr = f.address

    @nb.njit(parallel=True)
    def run(v0, params, T, rtol, atol, out, ok):
        t_eval = np.array([0.0, T])
        for j in nb.prange(v0.shape[1]):
            usol, success = dop853(ptr, v0[:, j].copy(), t_eval, data=params[:, j].copy(),
                                   rtol=rtol, atol=atol, mxstep=10_000_000)
            for q in range(nv):
                out[q, j] = usol[1, q]
            ok[j] = success

    return run


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--launches", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scipy-sample", type=int, default=4)
    a = ap.parse_args(argv)
    y0, p, T, ball = square_launches(a.launches)
    n = y0.shape[1]
    xy_ref, gap = ensemble_reference(y0, p, T)
    v0 = np.empty((11, n))
    fixed_columns(y0, v0)

    def err_m(xy):
        e = np.hypot(*(xy - xy_ref[:, :xy.shape[1]])) * ball.a
        return float(np.median(e)), float(e.max())

    u0 = np.ascontiguousarray(y0[:8])  # the Euler-angle state: the fast state's first 8 rows
    rows = []
    runs = {form: numbalsoda_runner(form) for form in ("fixed", "euler")}
    start = {"fixed": v0, "euler": u0}
    out = {form: np.empty_like(start[form]) for form in runs}
    ok = np.zeros(n, dtype=np.bool_)
    for form, run in runs.items():  # compile
        run(start[form][:, :2], p[:, :2], 0.01, 1e-6, 1e-9, out[form][:, :2], ok[:2])
    integrate_lanes(y0[:, :2], p[:, :2], 0.01, 1e-6, 1e-9)
    for rtol in RTOLS:
        for form, run in runs.items():
            _, t = best_of(lambda rtol=rtol, run=run, form=form: run(
                start[form], p, T, rtol, rtol * 1e-3, out[form], ok), a.repeats)
            rows.append((f"numbalsoda dop853 {form}", rtol, *err_m(out[form][:2]), n / t,
                         bool(ok.all())))
        res, t = best_of(lambda rtol=rtol: integrate_lanes(y0, p, T, rtol, rtol * 1e-3), a.repeats)
        rows.append(("ballsurvey dop853", rtol, *err_m(res.traj[:2]), n / t,
                     bool((res.outcome == 0).all())))
    try:
        from scipy.integrate import solve_ivp

        m = a.scipy_sample
        for rtol in (1e-6, 1e-9):
            def sp(rtol=rtol):
                xy = np.empty((2, m))
                for j in range(m):
                    s = solve_ivp(lambda t, v, j=j: _rhs_np(v, p[:, j]), (0.0, T), v0[:, j],
                                  method="DOP853", rtol=rtol, atol=rtol * 1e-3)
                    xy[:, j] = s.y[:2, -1]
                return xy

            xy, t = best_of(sp, 1)
            rows.append(("scipy solve_ivp dop853", rtol, *err_m(xy), m / t, True))
    except ImportError:
        pass
    print(f"peers on {n} launches around the square, T = {T * ball.time_unit:g} s, "
          f"{nb.get_num_threads()} threads, best of {a.repeats}; "
          f"reference gap {gap * ball.a:.1e} m")
    print(f"  {'integrator':<26}{'rtol':>7}{'median err (m)':>16}{'max err (m)':>13}"
          f"{'launches/s':>12}  all ok")
    for name, rtol, med, mx, rate, good in rows:
        print(f"  {name:<26}{rtol:>7.0e}{med:>16.2e}{mx:>13.2e}{rate:>12.0f}  {good}")


def _rhs_np(v, p):
    out = np.empty(11)
    fixed.rhs(v, p, out)
    return out


if __name__ == "__main__":
    main()

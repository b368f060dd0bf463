"""Benchmark: the ensemble kernel against a naive one-launch-at-a-time numba loop, same launches.

Prints IC-steps per second (launches x steps / wall time) for each and their ratio. Both are
compiled and warmed before timing; each timing is the best of `repeats` on this (shared, noisy)
machine, so compare the ratio, not the absolute figures, across machines.
"""
from __future__ import annotations

import time

import numba
import numpy as np

from .ball import Ball
from .integrate import ensemble, naive


def _best(fn, repeats):
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def run_bench(n_launches: int = 4096, n_steps: int = 2000, dt: float = 1e-4, repeats: int = 3,
              block: int = 64, observe_every: int = 4, seed: int = 0, out=print) -> dict:
    ball = Ball.paper()
    p, tu = ball.nondim_params(), ball.time_unit
    rng = np.random.default_rng(seed)
    th0 = np.radians(rng.uniform(-10, 30, n_launches))
    chd0 = rng.uniform(1, 12, n_launches) * tu
    phd0 = np.full(n_launches, -3.0 * tu)
    zeros = np.zeros(n_launches)
    y0 = ensemble.fast_state(zeros, zeros, th0, zeros, zeros, zeros, chd0, phd0)
    params = np.repeat(p[:, None], n_launches, 1)
    u0 = np.ascontiguousarray(np.stack([zeros, zeros, th0, zeros, zeros, zeros, chd0, phd0], 1))
    pn = np.ascontiguousarray(params.T)
    u_end = np.empty_like(u0)
    dt_nd = dt / tu
    # warm up (compile) on a few launches
    ensemble.integrate(y0[:, :4], params[:, :4], dt_nd, 2)
    naive.naive_ensemble(u0[:4], pn[:4], dt_nd, 2, u_end[:4])

    res = {}

    def ens(observer):
        res["y_end"] = ensemble.integrate(y0, params, dt_nd, n_steps, block=block,
                                          observer=observer, observe_every=observe_every)[0]

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

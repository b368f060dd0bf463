"""One entry point for integrating launches: fixed-step or adaptive, with the singular fallback.

Launches whose tilt reaches the Euler form's singularity (|theta| -> 90 deg), or that blew up or
lost energy accuracy after passing 80 deg, are integrated again
in the fixed-frame (Euler-free) form with the adaptive pair at tight tolerance, so no launch ends
with a label computed from a broken chart: its observer record is replaced and marked
ST_FIXED_FRAME (stored as `formulation = fixed_frame`).
"""
from __future__ import annotations

import math

import numpy as np

from ..classify.labels import Thresholds
from ..classify.observer import (O_DE, O_E0, O_STATUS, O_TH_MAX, O_TH_MIN, ST_NONFINITE,
                                 ST_SINGULAR)
from . import ensemble
from .adaptive import ADAPTIVE, integrate_adaptive
from .tableaus import FIXED_STEP

METHODS = tuple(FIXED_STEP) + tuple(ADAPTIVE)
FALLBACK_RTOL = 1e-10
FALLBACK_ATOL = 1e-12
#: a launch that blew up after its tilt passed this (rad) is taken to have met the Euler chart's
#: singularity (chidot ~ 1 / cos theta outruns the fixed step), not a step too large
NEAR_SINGULAR_THETA = math.radians(80.0)


def needs_fallback(obs, max_energy_drift: float = Thresholds.max_energy_drift) -> np.ndarray:
    """Launches (bool mask) flagged singular, or that blew up or drifted in energy by more than
    max_energy_drift after |theta| passed NEAR_SINGULAR_THETA: the Euler chart's failures (there
    chidot ~ 1 / cos theta outruns the step). Drift or blow-up at low tilt is the step's fault
    and stays reported as such."""
    with np.errstate(invalid="ignore"):
        tilt = np.maximum(np.abs(obs[O_TH_MAX]), np.abs(obs[O_TH_MIN]))
        bad_num = (obs[O_STATUS] == ST_NONFINITE) | (obs[O_DE] / np.abs(obs[O_E0])
                                                     > max_energy_drift)
        return (obs[O_STATUS] == ST_SINGULAR) | (bad_num & (tilt > NEAR_SINGULAR_THETA))


def fixed_frame_fallback(y0, params, T_nd, obs, parallel=True, stop_after_maxima=0) -> np.ndarray:
    """Re-run in the fixed frame the launches `needs_fallback` names; returns their indices."""
    bad = np.flatnonzero(needs_fallback(obs))
    if bad.size:
        o2, _, _ = integrate_adaptive(y0[:, bad], params[:, bad], T_nd, FALLBACK_RTOL, FALLBACK_ATOL,
                                      fixed_frame=True, parallel=parallel and bad.size > 1,
                                      stop_after_maxima=stop_after_maxima)
        obs[:, bad] = o2
    return bad


def run_launches(y0, params, T_nd, dt_nd, method="rk4", *, rtol=1e-9, atol=1e-12, block=64,
                 observe_every=4, parallel=True, fallback=True, cycles=0) -> np.ndarray:
    """Integrate fast-state launches for non-dimensional time T_nd; returns the observer slots.

    method: a fixed-step tableau (dt_nd is the step; T_nd must be a whole number of steps) or
    "dopri5"/"adaptive" (rtol, atol; dt_nd is the first trial step).
    cycles > 0 (period mode): each launch stops once it has completed that many theta cycles
    (cycles + 1 theta maxima); T_nd is then the longest it may run."""
    stop = cycles + 1 if cycles > 0 else 0
    if method in FIXED_STEP:
        n_steps = max(1, int(round(T_nd / dt_nd)))
        _, obs, _ = ensemble.integrate(y0, params, T_nd / n_steps, n_steps, method, block=block,
                                       observe_every=observe_every, parallel=parallel,
                                       stop_after_maxima=stop)
    elif method in ADAPTIVE:
        obs, _, _ = integrate_adaptive(y0, params, T_nd, rtol, atol, h_init=dt_nd,
                                       parallel=parallel, tableau=ADAPTIVE[method],
                                       stop_after_maxima=stop)
    else:
        raise ValueError(f"unknown method {method!r}; known: {', '.join(METHODS)}")
    if fallback:
        fixed_frame_fallback(y0, params, T_nd, obs, parallel=parallel, stop_after_maxima=stop)
    return obs

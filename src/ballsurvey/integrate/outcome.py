"""What an integrator says about each launch, apart from what its observer recorded.

Every integrator returns, per launch, an `outcome` code (int8), the time it stopped early (NaN
when it ran to the end or its observer said it was done) and the `formulation` it integrated
(int8). The layer that composes integrators and observers (`ballsurvey.compose`) turns these into
a fallback decision and into label words.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: outcome codes (int8)
OK = 0  #: ran to T, or its observer said it was done
NONFINITE = 1  #: the state turned NaN or inf
CHART_SINGULAR = 2  #: cos theta fell below cos_min: the Euler chart's singularity (Euler form only)
STEP_BUDGET = 3  #: the adaptive pair used up its step budget before T
STEP_UNDERFLOW = 4  #: the adaptive pair's step fell below its floor before T
OUTCOMES = ("ok", "nonfinite", "chart_singular", "step_budget", "step_underflow")

#: formulation codes (int8), as stored in `formulation` (`euler_angles fixed_frame quadrature`;
#: quadrature: no integration, the launch's cycle from its invariants, `classify.cycle`)
EULER_ANGLES = 0
FIXED_FRAME = 1
QUADRATURE = 2
FORMULATIONS = ("euler_angles", "fixed_frame", "quadrature")


class Result(NamedTuple):
    """What an integrator returns for n launches.

    obs (n_slots, n): the observer's record; outcome (n,) int8; t_stop (n,): non-dimensional time
    of an early stop (NaN if none); formulation (n,) int8; y_end (N_FAST, n): the final (fast
    Euler view of the) state; n_steps (n,): steps taken (fixed step: the planned count);
    t (m,), traj: kept samples (ensemble: (m, N_FAST, n); one adaptive launch: (m, N_FAST));
    by_steps (n,) bool or None: launches whose record a step observer made from an Euler-angle
    integration (its heading's turn is read chart-free, as a fixed-frame run's is).
    """

    obs: np.ndarray
    outcome: np.ndarray
    t_stop: np.ndarray
    formulation: np.ndarray
    y_end: np.ndarray
    n_steps: np.ndarray
    t: np.ndarray
    traj: np.ndarray
    by_steps: np.ndarray | None = None

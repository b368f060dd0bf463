"""Launch conditions fitted to a measured track (the paper's Sec. VI: a filmed ball reproduced by
guessing its launch).

A track is a table of times t (s) with the centre of mass x, y (m), or the probe's tip and base
x_tip, y_tip, x_base, y_base (m, a probe of known length), and optionally the tilt theta_deg (deg)
and the precession rate chidot (rad/s), as the paper read them off its probe. `fit_track` finds
the launch at the first sample (theta0_deg, thetadot0, chidot0, phidot0, chi0_deg, x0, y0) whose
integrated motion best reproduces it:

1. a global start: a survey of the launch box (theta0, thetadot0, chidot0 on a grid; phidot0 from
   the track's initial speed, both signs) on the ensemble kernel over the first seconds, each
   launch integrated once with chi0 = 0 at the origin and then turned and moved onto the track
   in closed form (the motion is the same under a turn about the vertical and a shift);
2. a local refinement by scipy's least_squares (trust-region reflective, Jacobian by forward
   differences, all its launches in one kernel call): the best N_STARTS survey launches a few
   iterations over the first START_T seconds (where a launch a grid step off still keeps the
   track's phase), then the best N_CARRIED of those over a window doubled until it holds the
   whole track;
3. uncertainties from the Jacobian at the optimum: covariance s^2 (J^T J)^-1, s^2 the residual
   variance per degree of freedom.

Residuals are weighted by nominal measurement errors (POSITION_SIGMA_M, THETA_SIGMA_DEG,
CHIDOT_SIGMA) so channels of different units can be mixed; the uncertainties rescale by the
residual itself, so they do not depend on those nominal values when one channel is used.

The package by concern: `track` (a track and its checks), `reader` (track files), `model`
(the predicted channels, residuals and Jacobian), `survey` (the global start), `stats` (noise,
residual tests, covariance), `status` (how far to trust a fit), `engine` (`fit_track`) and
`figure` (`plot_fit`).
"""
from .engine import LABEL_T, N_CARRIED, N_STARTS, SLOWING_START, START_T, fit_track
from .figure import plot_fit
from .model import (
    CHIDOT_SIGMA,
    FIT_DT,
    PARAMS,
    POSITION_SIGMA_M,
    SLOWING,
    THETA_SIGMA_DEG,
    UNITS,
    fitted_track,
    heading_deg,
)
from .reader import read_track
from .stats import _covariance, noise_estimate, residual_tests
from .status import _undetermined
from .survey import BOX, GRID, initial_velocity, survey, survey_launches
from .track import (
    COLUMNS,
    LENGTH_UNITS,
    POSITION_PAIRS,
    PROBE_COLUMNS,
    TIME_UNITS,
    Track,
    make_track,
)

__all__ = [
    "PARAMS", "UNITS", "SLOWING", "SLOWING_START", "POSITION_SIGMA_M", "THETA_SIGMA_DEG",
    "CHIDOT_SIGMA", "BOX", "GRID", "FIT_DT", "N_STARTS", "START_T", "N_CARRIED", "LABEL_T",
    "Track", "PROBE_COLUMNS", "COLUMNS", "POSITION_PAIRS", "LENGTH_UNITS", "TIME_UNITS",
    "make_track", "read_track", "initial_velocity", "survey_launches", "survey",
    "noise_estimate", "residual_tests", "heading_deg", "fit_track", "fitted_track", "plot_fit",
    "_covariance", "_undetermined",
]

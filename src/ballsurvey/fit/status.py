"""How far to trust a fit: the thresholds of its status (ok, ambiguous, mismatch, failed), whether
two launches are the same, whether the track fixes the launch, the run that labels a launch and
where it leaves the rolling model."""
from __future__ import annotations

import math

import numpy as np

from ..ball import Ball
from ..simulate import simulate
from .model import PARAMS
from .survey import BOX

#: an alternative launch fits within the noise when its chi^2 exceeds the best's by less than
#: the ALT_LEVEL quantile of chi^2 with 7 degrees of freedom (21.7 at 0.997), and differs from
#: the best by more than SAME_SIGMAS of its standard deviations (and SAME_FLOOR)
ALT_LEVEL = 0.997
SAME_SIGMAS = 5.0
SAME_FLOOR = np.array([0.05, 0.005, 0.005, 0.005])
#: the model's resolution (m): misfits below it are never called a mismatch or a failure
RESOLUTION_M = 1e-5
#: mismatch: the rms exceeds the noise by MISFIT_Z of their joint spread, or the residuals'
#: runs or lag-1 autocorrelation are STRUCTURE_Z from white noise
MISFIT_Z = 3.0
STRUCTURE_Z = 4.0
#: failed: the rms is FAIL_RATIO times the noise, or above it (MISFIT_Z) by FAIL_FRACTION of the
#: track's extent, or
#: thetadot0, chidot0 beyond the survey's box by BOX_MARGIN of its half-width
FAIL_RATIO = 20.0
FAIL_FRACTION = 0.05
BOX_MARGIN = 0.5
#: a standard deviation wider than WIDE_SHARE of the survey box's span (theta0, thetadot0,
#: chidot0), WIDE_PHIDOT (rad/s) or WIDE_CHI_DEG (deg): the track does not fix the launch
WIDE_SHARE = 0.1
WIDE_PHIDOT = 3.0
WIDE_CHI_DEG = 30.0
#: a Jacobian condition number above it: the track does not separate the parameters
MAX_CONDITION = 1e8


def _same_launch(qa, qb, tol) -> bool:
    d = np.abs(np.asarray(qa[:4]) - np.asarray(qb[:4]))
    return bool(np.all(d <= tol))


def _undetermined(err, box) -> dict:
    """The parameters whose standard deviation spans more than WIDE_SHARE of the survey's box
    (theta0, thetadot0, chidot0), more than WIDE_PHIDOT rad/s (phidot0) or WIDE_CHI_DEG (chi0):
    over such a span the motion changes, so a linear uncertainty cannot describe it and other
    launches fit as well. Returns {name: sigma}."""
    box = {**BOX, **(box or {})}
    wide = {k: WIDE_SHARE * (box[k][1] - box[k][0]) for k in box}
    wide.update(phidot0=WIDE_PHIDOT, chi0_deg=WIDE_CHI_DEG)
    return {k: float(err[PARAMS.index(k)]) for k in PARAMS if k in wide
            and err[PARAMS.index(k)] > wide[k]}


def _label_run(q, ball: Ball, T: float, rolling_resistance: float = 0.0):
    return simulate(q[0], q[1], q[2], q[3], T=T, chi0_deg=q[4], x0=q[5], y0=q[6], ball=ball,
                    n_out=2001, rolling_resistance=rolling_resistance)


def _model_problems(ds, T_track: float, ball: Ball) -> list[str]:
    """Where the launch leaves the rolling model over the track's time: the flat face on the
    table, lift-off (N <= 0) or slipping (|F_h|/N above the classifier's mu)."""
    from ..classify.labels import Thresholds

    on = ds.time.values <= T_track + 1e-9
    out = []
    flat = math.degrees(ball.flat_face_theta_rad)
    th = ds.theta_deg.values[on]
    if np.nanmin(th) < flat:
        t = float(ds.time.values[on][np.nanargmin(th)])
        out.append(f"the flat face reaches the table (theta {np.nanmin(th):.1f} deg < "
                   f"{flat:.1f} deg at t = {t:.2f} s)")
    n = ds.normal_force.values[on]
    if np.nanmin(n) <= 0:
        out.append(f"the ball lifts off (normal force {np.nanmin(n):.3g} N)")
    mu = Thresholds().mu
    fr = ds.friction_ratio.values[on]
    fr = fr[np.isfinite(fr)]  # infinite where the ball has lifted off: said above
    if fr.size and fr.max() > mu:
        out.append(f"it would slip (friction |F_h|/N up to {fr.max():.2f}, above mu = "
                   f"{mu:g})")
    return out

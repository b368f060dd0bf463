"""The fit itself (`fit_track`): the survey, the best starts refined over windows doubled to the
whole track, the uncertainties from the Jacobian and the status (the steps: the package's
docstring)."""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import limits
from ..ball import Ball
from .model import PARAMS, SLOWING, _bounds, _Model, _place, _wrap_deg, heading_deg
from .reader import read_track
from .stats import NOISE_SPREAD, _angle_err, _covariance, noise_estimate, residual_tests
from .status import (
    ALT_LEVEL,
    BOX_MARGIN,
    FAIL_FRACTION,
    FAIL_RATIO,
    MAX_CONDITION,
    MISFIT_Z,
    RESOLUTION_M,
    SAME_FLOOR,
    SAME_SIGMAS,
    STRUCTURE_Z,
    _label_run,
    _model_problems,
    _same_launch,
    _undetermined,
)
from .survey import BOX, _pick_starts, survey
from .track import COLUMNS, POSITION_PAIRS, Track, make_track

#: where the slowing fit's coefficient starts (the order of a ball on a table, docs/physics.md)
SLOWING_START = 1e-3
#: survey launches refined over the first START_T seconds, and how many of them are carried
#: on to the whole track
N_STARTS = 24
START_T = 0.5
N_CARRIED = 3
#: duration (s) of the run that labels the fitted launch (or the track's, if longer)
LABEL_T = 20.0
#: refined starts carried on to the whole track: those within CARRY_FACTOR of the best cost over
#: the first START_T seconds, one a basin (SAME_BASIN: theta0 deg, thetadot0, chidot0, phidot0)
CARRY_FACTOR = 25.0
SAME_BASIN = np.array([1.0, 0.2, 0.2, 0.2])


def _refine(model: _Model, q0: np.ndarray, ball: Ball, max_nfev: int):
    from scipy.optimize import least_squares

    lo, hi = _bounds(ball, model.slowing)
    q0 = np.clip(q0, lo + 1e-9, hi - 1e-9)
    return least_squares(model.fun, q0, jac=model.jac, bounds=(lo, hi), x_scale="jac",
                         method="trf", max_nfev=max_nfev, xtol=1e-12, ftol=1e-12, gtol=1e-12)


def _as_track(track, probe_m) -> Track:
    if isinstance(track, (str, Path)):
        track = read_track(track, probe_m=probe_m)
    elif not isinstance(track, Track):  # a mapping of columns or a pandas DataFrame
        cols = {str(k): np.asarray(track[k], dtype=float) for k in track.keys()
                if str(k) in COLUMNS}
        if "t" not in cols:
            raise limits.InputError("track: needs a column t (s)")
        track = make_track(cols.pop("t"), probe_m=probe_m, drop_missing=True, **cols)
    if track.probe and track.probe_m is None:
        raise limits.InputError("a probe track needs probe_m (m)")
    return track


def _origin(track: Track) -> tuple[float, float]:
    """The track's first position (m): the fit works relative to it, so a track far from the
    origin loses no digits to it."""
    px, py = ("x", "y") if not track.probe else ("x_base", "y_base")
    return float(getattr(track, px)[0]), float(getattr(track, py)[0])


def _shifted(track: Track, ox: float, oy: float) -> Track:
    cols = {}
    for px, py in POSITION_PAIRS:
        if getattr(track, px) is not None:
            cols[px], cols[py] = getattr(track, px) - ox, getattr(track, py) - oy
    return replace(track, **cols)


def _carry(model_short: _Model, track: Track, ball: Ball, r, T_full: float):
    """One refined start taken on over windows doubled until they hold the whole track."""
    T, x, model = min(START_T, T_full), r.x, model_short
    while T < T_full:
        T = min(2 * T, T_full)
        model = _Model(track, ball, T, model_short.slowing)
        r = _refine(model, x, ball, 60 if T == T_full else 25)
        x = r.x
    return r, model


def fit_track(track, ball: Ball | None = None, *, probe_m: float | None = None, box=None,
              grid=None, n_starts: int = N_STARTS, label_T: float = LABEL_T,
              slowing: bool = False) -> dict:
    """Fit the launch that best reproduces a measured track, and say how far to trust it.

    Parameters
    ----------
    track : Track, str, Path, dict or pandas.DataFrame
        A `Track` (`make_track`), a track file (`read_track`), or columns by name (t, x, y or
        x_tip, y_tip, x_base, y_base, optionally theta_deg, chidot; the rules of `make_track`,
        rows with a non-finite value dropped).
    ball : Ball, optional
        The ball (default: the paper's).
    probe_m : float, optional
        Probe length (m) for a track given by its probe's tip and base.
    box, grid : dict, optional
        The survey's launch box ``{name: (lo, hi)}`` and grid sizes ``{name: n}`` for
        theta0_deg (deg), thetadot0 and chidot0 (rad/s); defaults `BOX`, `GRID`.
    n_starts : int
        Survey launches refined locally over the first START_T seconds (the best of each
        distinct basin, up to N_CARRIED, carried on to the whole track).
    label_T : float
        Duration (s) of the run that labels the fitted launch (the track's if longer).
    slowing : bool
        Fit a ball that slows: the model has the rolling resistance (`simulate`'s
        rolling_resistance), its coefficient fitted with the launch (from SLOWING_START, within
        0 to 1). The survey is of the rolling model without it; the refinement integrates each
        launch in the fixed frame by dopri5 (rtol 1e-10), slower than the plain fit.

    Returns
    -------
    dict
        theta0_deg (deg), thetadot0, chidot0, phidot0 (rad/s), chi0_deg (deg), x0, y0 (m) at the
        first sample, each with ``_err`` (one standard deviation); rms_m, the root-mean-square
        position residual per coordinate (m); label, the label of the fitted launch; status:
        "ok", "ambiguous" (other launches fit within the noise: ``alternatives``, each with its
        launch, rms_m, label and delta_chi2), "mismatch" (the model does not explain the track:
        ``evidence``) or "failed" (``reasons``); heading_deg (and _err): the direction of G's
        velocity at the first sample in the track's axes (deg); noise_m, the tracking noise
        estimated from the track alone (m); notes (list of str); n_dropped, dropped_t (s);
        and t_start (s), n_samples, cost, survey_launches, seconds. With slowing, also
        rolling_resistance and rolling_resistance_err (dimensionless).
    """
    import time

    from scipy.stats import chi2

    t_wall = time.perf_counter()
    ball = ball or Ball.paper()
    track = _as_track(track, probe_m)
    ox, oy = _origin(track)
    rel = _shifted(track, ox, oy)
    starts, costs = survey(rel, ball, box=box, grid=grid)
    n_survey = costs.size
    if not np.isfinite(costs[0]):
        raise limits.InputError(f"{track.source}: no launch of the survey box stays on the "
                                "Euler chart over the track; widen the box")
    T_full = float(track.t[-1])
    picked = _pick_starts(starts, costs, n_starts, box, grid)
    if slowing:
        picked = [np.append(q, SLOWING_START) for q in picked]
    names = PARAMS + (SLOWING,) * slowing
    mu_r = (lambda v: float(v[7])) if slowing else (lambda v: 0.0)
    # the starts refined a little over a short window, where a launch a grid step away still
    # keeps the track's phase; the best of each distinct basin taken on over windows doubled to
    # the whole track
    T = min(START_T, T_full)
    model = _Model(rel, ball, T, slowing)
    fits = sorted((_refine(model, q, ball, 12) for q in picked), key=lambda r: r.cost)
    carried = []
    for r in fits:
        if len(carried) >= N_CARRIED or r.cost > CARRY_FACTOR * fits[0].cost:
            break
        if not any(_same_launch(r.x, c.x, SAME_BASIN) for c in carried):
            carried.append(r)
    ends = [_carry(model, rel, ball, r, T_full) for r in carried]
    ends.sort(key=lambda e: e[0].cost)
    best, model = ends[0]
    q = best.x
    J = best.jac
    m, n = J.shape
    dof = max(m - n, 1)
    s2 = 2.0 * best.cost / dof
    cov, cond, floor = _covariance(J, s2)
    err = np.sqrt(np.maximum(np.diag(cov), 0.0))
    notes: list[str] = []
    if np.any(err < 0.999 * floor):
        notes.append("some standard deviations fell below what the noise allows for one "
                     "parameter alone; raised to that floor")
        err = np.maximum(err, floor)
    if cond > MAX_CONDITION:
        weak = [names[k] for k in range(n) if err[k] > 0.5 * (abs(q[k]) + floor[k] * 1e3)]
        notes.append(f"the track does not separate the parameters (Jacobian condition number "
                     f"{cond:.2g})" + (f": {', '.join(weak)} are barely fixed" if weak else ""))
    if q.tobytes() not in model.cache:
        model.fun(q)
    placed = _place(model.cache[q.tobytes()], *q[4:7])
    pos = [k for k in model.names if k not in ("theta_deg", "chidot")]
    res = {k: placed[k] - model.data[k] for k in pos}
    rms = float(np.sqrt(np.mean(np.concatenate(list(res.values())) ** 2)))

    # --- is it the only launch that fits? ----------------------------------------------------
    alternatives = []
    limit = chi2.ppf(ALT_LEVEL, n)
    for r, mod in ends[1:]:
        d_chi2 = 2.0 * (r.cost - best.cost) / s2
        if d_chi2 > limit or _same_launch(r.x, q, np.maximum(SAME_SIGMAS * err[:4], SAME_FLOOR)):
            continue
        if any(_same_launch(r.x, a["q"], SAME_BASIN) for a in alternatives):
            continue
        if r.x.tobytes() not in mod.cache:
            mod.fun(r.x)
        pl = _place(mod.cache[r.x.tobytes()], *r.x[4:7])
        rms_a = float(np.sqrt(np.mean(np.concatenate([pl[k] - mod.data[k] for k in pos]) ** 2)))
        alternatives.append({"q": r.x, "rms_m": rms_a, "delta_chi2": float(d_chi2)})

    # --- does the track fix the launch at all? ----------------------------------------------
    undetermined = _undetermined(err, box)
    if undetermined:
        notes.append("the track does not fix the launch: " + ", ".join(
            f"{k} +- {v:.3g}" for k, v in undetermined.items()) + " span motions of other "
            "kinds, so the standard deviations are not meaningful and other launches fit as well")

    # --- does the model explain the track? ---------------------------------------------------
    noise, n_diff = noise_estimate(rel)
    noise_eff = math.hypot(noise, RESOLUTION_M)
    ratio = rms / noise_eff
    sd_ratio = math.sqrt(NOISE_SPREAD**2 / max(n_diff, 1) + 1.0 / (2.0 * max(
        sum(v.size for v in res.values()) - n, 1)))
    tests = residual_tests(res)
    evidence = {"rms_over_noise": ratio, "rms_over_noise_z": (ratio - 1.0) / sd_ratio, **tests}
    structured = rms > RESOLUTION_M and (tests["runs_z"] < -STRUCTURE_Z
                                         or tests["autocorrelation_z"] > STRUCTURE_Z)
    ds = _label_run(np.r_[q[:5], 0.0, 0.0], ball, max(label_T, T_full), mu_r(q))
    lab = ds.attrs["label"]
    reasons = []
    extent = max(np.ptp(model.data[k]) for k in pos)
    misfit = evidence["rms_over_noise_z"] > MISFIT_Z
    if rms > RESOLUTION_M and (ratio > FAIL_RATIO or (misfit and rms > FAIL_FRACTION * extent)):
        reasons.append(f"the best launch misses the track: rms {rms * 1e3:.3g} mm, "
                       f"{ratio:.1f} times the noise ({noise * 1e3:.2g} mm), "
                       f"{100 * rms / extent:.2g} % of the track's extent")
    reasons += _model_problems(ds, T_full, ball)
    box_ = {**BOX, **(box or {})}
    for k, i in (("thetadot0", 1), ("chidot0", 2)):
        lo, hi = box_[k]
        half = 0.5 * (hi - lo)
        if q[i] < lo - BOX_MARGIN * half or q[i] > hi + BOX_MARGIN * half:
            reasons.append(f"{k} {q[i]:.3g} rad/s lies far outside the survey's box "
                           f"({lo:g}..{hi:g})")
    lo_b, hi_b = _bounds(ball, slowing)
    at = [PARAMS[k] for k in range(4) if min(q[k] - lo_b[k], hi_b[k] - q[k]) < 1e-6]
    if at:
        reasons.append(f"{', '.join(at)} at the model's limit")
    if reasons:
        status = "failed"
    elif misfit or structured:
        status = "mismatch"
        widen = math.sqrt((1 + min(max(tests["autocorrelation"], 0.0), 0.95))
                          / (1 - min(max(tests["autocorrelation"], 0.0), 0.95)))
        err = err * widen
        cov = cov * widen**2
        notes.append(f"the model does not explain the track (rms {ratio:.2f} times the noise; "
                     f"runs z {tests['runs_z']:.1f}, autocorrelation "
                     f"{tests['autocorrelation']:.2f}): "
                     f"the standard deviations are widened by the residuals' correlation (x "
                     f"{widen:.2f}) and are a lower bound")
    elif alternatives or undetermined:
        status = "ambiguous"
    else:
        status = "ok"

    out = {}
    q_abs = q.copy()
    q_abs[5] += ox
    q_abs[6] += oy
    for k, v, e in zip(names, q_abs, err):
        out[k], out[k + "_err"] = float(v), float(e)
    # the heading is an angle: reported in (-180, 180] deg (the fit may wander a few turns)
    out["chi0_deg"] = _wrap_deg(out["chi0_deg"])
    out.update(rms_m=rms, label=lab, status=status)
    if alternatives or status == "ambiguous":
        alts = []
        for a in alternatives:
            qa = a["q"]
            alt = {k: float(v) for k, v in zip(PARAMS, qa)}
            alt["chi0_deg"] = _wrap_deg(alt["chi0_deg"])
            alt["x0"] += ox
            alt["y0"] += oy
            alt.update(rms_m=a["rms_m"], delta_chi2=a["delta_chi2"],
                       label=_label_run(np.r_[qa[:5], 0.0, 0.0], ball,
                                        max(label_T, T_full), mu_r(qa)).attrs["label"],
                       heading_deg=heading_deg(qa, ball))
            alts.append(alt)
        out["alternatives"] = alts
    if status == "mismatch":
        out["evidence"] = evidence
    if status == "failed":
        out["reasons"] = reasons
    out.update(heading_deg=heading_deg(q, ball),
               heading_deg_err=_angle_err(lambda v: heading_deg(v, ball), q, cov),
               noise_m=noise, rms_over_noise=ratio, notes=notes,
               n_dropped=int(track.dropped_t.size + track.dropped_untimed),
               dropped_t=[float(v) for v in track.dropped_t], condition=cond,
               t_start=track.t_start, n_samples=int(track.t.size), cost=float(2 * best.cost),
               survey_launches=int(n_survey), seconds=time.perf_counter() - t_wall)
    return out

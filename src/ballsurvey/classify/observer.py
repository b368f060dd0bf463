"""Streaming observer: per-launch reductions updated after every step, no trajectory kept.

The observer is a column `obs[:, i]` of float64 slots per launch (names below). `observe` is fed the
state and its accelerations at each sample; it tracks

* theta extrema, the invariants' drift (energy, Jellett, Routh), friction demand |F_h|/N and min N;
* theta maxima (events where thetadot turns from + to -): the first and last event's time, heading
  chi and centre position, and the previous one (for the chord between successive maxima).
  Events are located between the two samples that bracket them, on cubic Hermite interpolants
  built from each sample's values and rates, chart-free: the root of the rate of sin(theta) (the
  vertical component of the symmetry axis), theta from sin(theta) and the length of the axis's
  horizontal part, G's position from its velocity. Near the vertical chi swings by half a turn
  within milliseconds, so chi read at an event is ill-conditioned; the path's heading psi (the
  direction of G's velocity) is smooth there, and over a cycle both turn by the same angle to
  whole turns (the reduced state repeats), so chi's change between events is taken to the
  nearest value that agrees with psi's. The folded change of psi between events is summed too:
  a chart-free net turn that does not shrink with the chord;
* the rotation of the chord between successive theta maxima, folded into (-pi, pi] and summed:
  a second, chart-free measure of the net turn (it is what the fixed-frame integration uses);
* per theta cycle (between successive maxima): the peak heading rate of the path, the total
  absolute and signed turning, the smallest and mean speed, and the winding of the velocity
  relative to the ball's heading (a loop corner); the last complete cycle's values are kept;
* the orbit centre: the fixed point of the rigid motion that maps one theta cycle onto the next
  (rotation by the change of chi over the cycle about that point, which carries one theta maximum
  onto the next). Once it is known (second maximum), the smallest and largest distance of the path
  from it over each later cycle: since every cycle is a rotated copy, these bound the path over a
  whole orbit, and their spread over their mean is the path's roundness;
* theta minima (thetadot turning from - to +), where the path turns: the distance between
  successive minima is the corner-to-corner side of the polygon;
* |thetadot| and |thetadot'| at launch: a launch at rest in theta with no theta acceleration sits
  on a steady circle;
* the samples seen per theta cycle and the largest change of theta between samples (too few
  samples a cycle, and the path's shape cannot be seen: the labeller says `unresolved`).

Over one theta cycle the reduced state (theta, thetadot, chidot, phidot) returns to itself, so the
path repeats rotated by the change of chi over the cycle: the net turn per cycle is
(chi_last - chi_first) / (cycles), with no atan2 in the hot loop.

All non-dimensional. Used by the ensemble kernel and, on stored samples, by `observe_samples`.
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit
from ..physics.euler import accelerations, energy, heading_velocity, jellett, normal_force, routh

# slot names, in order; the index constants below are generated from this one list
SLOTS = (
    "theta_min", "theta_max",
    "e0", "j0", "r0", "de_max", "dj_max", "dr_max",
    "friction_max", "normal_min",
    "n_max", "t_first", "chi_first", "x_first", "y_first",
    "t_last", "chi_last", "x_last", "y_last", "x_prev", "y_prev",
    "acc_psid_max", "acc_turn_abs", "acc_v_min", "acc_v_int", "acc_quarter_turns",
    "cyc_psid_max", "cyc_turn_abs", "cyc_v_min", "cyc_v_mean", "cyc_winding", "cyc_duration",
    "p_thd", "p_t", "p_chi", "p_x", "p_y", "p_quadrant",
    "chord_rot_sum", "chord_rot_n", "chord_ang",
    "acc_turn_signed", "cyc_raw_turn",
    "rc_x", "rc_y", "acc_r_min", "acc_r_max", "cyc_r_min", "cyc_r_max",
    "n_min", "xm_last", "ym_last", "cyc_side",
    "thd0", "thdd0",
    "p_sth", "p_cth", "p_chd", "p_u", "p_w", "p_psid", "psi_last",
    "acc_nsamp", "cyc_nsamp", "hd_sum", "hd_n", "p_phd", "th_step_max", "p_th",
    "p_ax", "p_ay", "p_ezdd", "p_speed",
)
N_OBS = len(SLOTS)
(O_TH_MIN, O_TH_MAX, O_E0, O_J0, O_R0, O_DE, O_DJ, O_DR, O_FRIC, O_NMIN,
 O_NMAX, O_T1, O_CHI1, O_X1, O_Y1, O_TL, O_CHIL, O_XL, O_YL, O_XP, O_YP,
 O_A_PSID, O_A_TURN, O_A_VMIN, O_A_VINT, O_A_QUART,
 O_C_PSID, O_C_TURN, O_C_VMIN, O_C_VMEAN, O_C_WIND, O_C_DUR,
 O_P_THD, O_P_T, O_P_CHI, O_P_X, O_P_Y, O_P_QUAD,
 O_CR_SUM, O_CR_N, O_CR_ANG, O_A_RAW, O_C_RAW,
 O_RC_X, O_RC_Y, O_A_RMIN, O_A_RMAX, O_C_RMIN, O_C_RMAX,
 O_NMIN_EV, O_XM, O_YM, O_C_SIDE,
 O_THD0, O_THDD0,
 O_P_STH, O_P_CTH, O_P_CHD, O_P_U, O_P_W, O_P_PSID, O_PSIL,
 O_A_NSAMP, O_C_NSAMP, O_HD_SUM, O_HD_N, O_P_PHD, O_TH_STEP, O_P_TH,
 O_P_AX, O_P_AY, O_P_EZDD, O_P_SPEED) = range(N_OBS)

jit = njit(cache=True, nogil=True, error_model="numpy")  # stamped cache: _jit.py


@jit
def _quadrant(u, w):
    """Quadrant 0..3 of the vector (u, w), counter-clockwise from +u."""
    if w >= 0.0:
        return 0.0 if u > 0.0 else 1.0
    return 2.0 if u <= 0.0 else 3.0


@jit
def _wrap(a):
    """a folded into [-pi, pi)."""
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@jit
def _hermite(tau, f0, f1, m0, m1):
    """The cubic Hermite interpolant through f0, f1 with slopes m0, m1 (per unit tau) at tau."""
    t2 = tau * tau
    t3 = t2 * tau
    return ((2.0 * t3 - 3.0 * t2 + 1.0) * f0 + (t3 - 2.0 * t2 + tau) * m0
            + (3.0 * t2 - 2.0 * t3) * f1 + (t3 - t2) * m1)


#: bisections that locate a theta extremum inside a sample interval (2^-48 of it)
LOCATE_ITERATIONS = 48
#: the path's speed (units of sqrt(g a)) below which its heading at a theta maximum is not
#: trusted (a ball rocking in a plane stops there): the heading chi is used alone
HEADING_SPEED_MIN = 1e-3


@jit
def _locate(obs, i, t, x, y, sth, cth, chi, thd, chd, phd, u, w, psid, c, A, B):
    """A theta extremum between the previous sample and this one, located on the cubic Hermite
    interpolants of the sample pair, chart-free (valid through the vertical).

    The extremum is the root of the rate of sin(theta), cos(theta) thetadot (the vertical
    component of the symmetry axis's rate: smooth where the Euler chart is not), interpolated
    with its own rate (from theta's acceleration at the two samples, computed here: events are
    rare, samples are many); there theta is read from sin(theta), interpolated with its rate, and
    the length of the axis's horizontal part q = cos(theta) (cos chi, sin chi), itself
    interpolated with its rate.
    Returns (tau, t, theta, chi, x, y, psi, speed) at the extremum: chi on the branch of the
    previous sample's, G's position from its velocity, the path's heading psi (the direction of
    G's velocity, smooth near the vertical where chi swings by half a turn within milliseconds)
    and G's speed."""
    t0 = obs[O_P_T, i]
    h = t - t0
    s0, s1 = obs[O_P_STH, i], sth
    c0 = obs[O_P_CTH, i]
    m0 = c0 * obs[O_P_THD, i] * h
    m1 = cth * thd * h
    # the rate changes sign over [0, 1] (thetadot did): bisect its interpolant
    lo, hi = 0.0, 1.0
    g_lo = m0
    thd0, chd0 = obs[O_P_THD, i], obs[O_P_CHD, i]
    # the second derivative of sin(theta) at both samples
    thdd0 = accelerations(s0, c0, thd0, chd0, obs[O_P_PHD, i], c, A, B)[0]
    thdd1 = accelerations(s1, cth, thd, chd, phd, c, A, B)[0]
    n0 = (c0 * thdd0 - s0 * thd0 * thd0) * h * h
    n1 = (cth * thdd1 - sth * thd * thd) * h * h
    for _ in range(LOCATE_ITERATIONS):
        mid = 0.5 * (lo + hi)
        g = _hermite(mid, m0, m1, n0, n1)
        if (g > 0.0) == (g_lo > 0.0):
            lo, g_lo = mid, g
        else:
            hi = mid
    tau = 0.5 * (lo + hi)
    s_ev = _hermite(tau, s0, s1, m0, m1)
    chi0 = obs[O_P_CHI, i]
    cc0, sc0, cc1, sc1 = math.cos(chi0), math.sin(chi0), math.cos(chi), math.sin(chi)
    qx = _hermite(tau, c0 * cc0, cth * cc1, (-s0 * thd0 * cc0 - c0 * chd0 * sc0) * h,
                  (-sth * thd * cc1 - cth * chd * sc1) * h)
    qy = _hermite(tau, c0 * sc0, cth * sc1, (-s0 * thd0 * sc0 + c0 * chd0 * cc0) * h,
                  (-sth * thd * sc1 + cth * chd * cc1) * h)
    th_ev = math.atan2(s_ev, math.sqrt(qx * qx + qy * qy))
    chi_ev = chi0 + _wrap(math.atan2(qy, qx) - chi0)
    u0, w0 = obs[O_P_U, i], obs[O_P_W, i]
    x_ev = _hermite(tau, obs[O_P_X, i], x, (u0 * cc0 - w0 * sc0) * h, (u * cc1 - w * sc1) * h)
    y_ev = _hermite(tau, obs[O_P_Y, i], y, (u0 * sc0 + w0 * cc0) * h, (u * sc1 + w * cc1) * h)
    psi0 = chi0 + math.atan2(w0, u0)
    dpsi = _wrap(chi + math.atan2(w, u) - psi0)
    psi_ev = psi0 + _hermite(tau, 0.0, dpsi, obs[O_P_PSID, i] * h, psid * h)
    speed = min(math.sqrt(u0 * u0 + w0 * w0), math.sqrt(u * u + w * w))
    return tau, t0 + tau * h, th_ev, chi_ev, x_ev, y_ev, psi_ev, speed


@jit
def start_record(obs, i, th, e, jel, rou, fric, normal, speed, thd, thdd):
    """Launch i's slots at its first sample: tilt th, the invariants e, jel, rou, friction demand
    and normal force, G's speed, and thetadot, thetaddot (the launch's steadiness)."""
    obs[O_TH_MIN, i] = th
    obs[O_TH_MAX, i] = th
    obs[O_E0, i], obs[O_J0, i], obs[O_R0, i] = e, jel, rou
    obs[O_DE, i] = obs[O_DJ, i] = obs[O_DR, i] = 0.0
    obs[O_FRIC, i] = fric
    obs[O_NMIN, i] = normal
    obs[O_NMAX, i] = 0.0
    for k in range(O_T1, O_YP + 1):
        obs[k, i] = math.nan
    obs[O_A_PSID, i] = 0.0
    obs[O_A_TURN, i] = 0.0
    obs[O_A_VMIN, i] = speed
    obs[O_A_VINT, i] = 0.0
    obs[O_A_QUART, i] = 0.0
    for k in range(O_C_PSID, O_C_DUR + 1):
        obs[k, i] = math.nan
    obs[O_CR_SUM, i] = 0.0
    obs[O_CR_N, i] = 0.0
    obs[O_CR_ANG, i] = math.nan
    obs[O_A_RAW, i] = 0.0
    obs[O_C_RAW, i] = math.nan
    for k in range(O_RC_X, O_C_SIDE + 1):
        obs[k, i] = math.nan
    obs[O_NMIN_EV, i] = 0.0
    obs[O_THD0, i] = abs(thd)
    obs[O_THDD0, i] = abs(thdd)
    obs[O_PSIL, i] = math.nan
    obs[O_A_NSAMP, i] = 0.0
    obs[O_HD_SUM, i] = 0.0
    obs[O_HD_N, i] = 0.0
    obs[O_TH_STEP, i] = 0.0
    obs[O_C_NSAMP, i] = math.nan


@jit
def on_minimum(obs, i, th_ev, xm, ym):
    """A theta minimum (thetadot turning from - to +, where the path turns: a corner) at G's
    position (xm, ym): theta's least value, and the distance from the last minimum (a side)."""
    obs[O_TH_MIN, i] = min(obs[O_TH_MIN, i], th_ev)
    if obs[O_NMIN_EV, i] >= 1.0:
        obs[O_C_SIDE, i] = math.hypot(xm - obs[O_XM, i], ym - obs[O_YM, i])
    obs[O_XM, i], obs[O_YM, i] = xm, ym
    obs[O_NMIN_EV, i] += 1.0


@jit
def on_maximum(obs, i, t_ev, th_ev, chi_ev, x_ev, y_ev, psi_ev, speed_ev, psid, speed):
    """A theta maximum (thetadot turning from + to -) located at time t_ev with tilt th_ev,
    heading chi_ev (on the branch of the observer's chi), G at (x_ev, y_ev), the path's heading
    psi_ev and speed speed_ev there: closes the cycle that the accumulators hold (its per-cycle
    values, the orbit centre, the chord's and the heading's turn) and starts the next with the
    path's heading rate psid and speed at the point where the new cycle's accumulators begin."""
    obs[O_TH_MAX, i] = max(obs[O_TH_MAX, i], th_ev)
    if speed_ev > HEADING_SPEED_MIN:
        if obs[O_NMAX, i] >= 1.0 and math.isfinite(obs[O_PSIL, i]):
            # the heading turns by chi's change over a cycle, to whole turns (the reduced
            # state repeats); chi, read at the located time near the vertical, can be off
            # by much of its swing there: its change is taken to the nearest value that
            # agrees with the path heading's, which is smooth
            dchi = chi_ev - obs[O_CHIL, i]
            dpsi = psi_ev - obs[O_PSIL, i]
            chi_ev = obs[O_CHIL, i] + dchi + _wrap(dpsi - dchi)
            # the heading's turn folded, summed: a chart-free net turn that, unlike
            # the chord's, does not depend on the chord's length
            obs[O_HD_SUM, i] += _wrap(dpsi)
            obs[O_HD_N, i] += 1.0
        obs[O_PSIL, i] = psi_ev
    else:
        obs[O_PSIL, i] = math.nan
    if obs[O_NMAX, i] == 0.0:
        obs[O_T1, i], obs[O_CHI1, i], obs[O_X1, i], obs[O_Y1, i] = t_ev, chi_ev, x_ev, y_ev
    else:  # the accumulators hold one complete cycle
        obs[O_C_PSID, i] = obs[O_A_PSID, i]
        obs[O_C_TURN, i] = obs[O_A_TURN, i]
        obs[O_C_VMIN, i] = obs[O_A_VMIN, i]
        dur = t_ev - obs[O_TL, i]
        obs[O_C_VMEAN, i] = obs[O_A_VINT, i] / dur
        obs[O_C_WIND, i] = obs[O_A_QUART, i] / 4.0
        obs[O_C_DUR, i] = dur
        obs[O_C_RAW, i] = obs[O_A_RAW, i]
        obs[O_C_NSAMP, i] = obs[O_A_NSAMP, i]
        obs[O_XP, i], obs[O_YP, i] = obs[O_XL, i], obs[O_YL, i]
        if math.isfinite(obs[O_RC_X, i]):  # the centre was known for the whole cycle
            obs[O_C_RMIN, i] = obs[O_A_RMIN, i]
            obs[O_C_RMAX, i] = obs[O_A_RMAX, i]
        # orbit centre: fixed point of the rotation by d_chi that maps the last maximum
        # onto this one, C = (I - R)^-1 (P_ev - R P_last)
        dchi = chi_ev - obs[O_CHIL, i]
        cd, sd = math.cos(dchi), math.sin(dchi)
        bx = x_ev - (cd * obs[O_XL, i] - sd * obs[O_YL, i])
        by = y_ev - (sd * obs[O_XL, i] + cd * obs[O_YL, i])
        det = 2.0 * (1.0 - cd)
        if det > 0.0:
            obs[O_RC_X, i] = ((1.0 - cd) * bx - sd * by) / det
            obs[O_RC_Y, i] = (sd * bx + (1.0 - cd) * by) / det
    if obs[O_NMAX, i] >= 1.0:
        ang = math.atan2(y_ev - obs[O_YL, i], x_ev - obs[O_XL, i])
        if obs[O_NMAX, i] >= 2.0:
            rot = ang - obs[O_CR_ANG, i]
            rot -= 2.0 * math.pi * math.floor((rot + math.pi) / (2.0 * math.pi))
            obs[O_CR_SUM, i] += rot
            obs[O_CR_N, i] += 1.0
        obs[O_CR_ANG, i] = ang
    obs[O_TL, i], obs[O_CHIL, i], obs[O_XL, i], obs[O_YL, i] = t_ev, chi_ev, x_ev, y_ev
    obs[O_NMAX, i] += 1.0
    obs[O_A_PSID, i] = abs(psid)
    obs[O_A_TURN, i] = 0.0
    obs[O_A_RAW, i] = 0.0
    obs[O_A_VMIN, i] = speed
    obs[O_A_VINT, i] = 0.0
    obs[O_A_QUART, i] = 0.0
    obs[O_A_NSAMP, i] = 0.0
    obs[O_A_RMIN, i] = math.inf
    obs[O_A_RMAX, i] = -math.inf


@jit
def observe(obs, i, first, t, dt, x, y, th, sth, cth, chi, thd, chd, phd, thdd, chdd, phdd, c, A, B,
            psid_in=math.nan, fric_in=math.nan, normal_in=math.nan):
    """Update launch i's slots with one sample (time t, step dt since the previous sample).

    psid_in, fric_in, normal_in: the path's heading rate, |F_h|/N and N/(M g) computed without
    the Euler chart (fixed-frame integration near theta = 90 deg); NaN: compute them here."""
    # --- speeds in the frame turning with the heading chi (Eqs. 6-7) and their rates -----------
    u, w = heading_velocity(sth, cth, thd, chd, phd, c)
    v2 = u * u + w * w
    speed = math.sqrt(v2)
    if math.isfinite(psid_in):
        psid, fric, normal = psid_in, fric_in, normal_in
    else:
        a1 = 1.0 - c * sth
        ud = (phdd - c * chdd) * cth - (phd - c * chd) * sth * thd
        wd = -c * cth * thd * thd + a1 * thdd
        psid = chd + (u * wd - w * ud) / v2 if v2 > 0.0 else chd  # heading rate of the path
        ah_par = ud - w * chd
        ah_perp = wd + u * chd
        normal = normal_force(sth, cth, thd, thdd, c)  # N / (M g), Eq. (20)
        fric = (math.sqrt(ah_par * ah_par + ah_perp * ah_perp) / normal if normal > 0.0
                else math.inf)
    # --- invariants -----------------------------------------------------------------------------
    e = energy(sth, cth, thd, chd, phd, c, A, B)
    jel = jellett(sth, cth, thd, chd, phd, c, A, B)
    rou = routh(sth, cth, thd, chd, phd, c, A, B)
    quad = _quadrant(u, w)
    if first:
        start_record(obs, i, th, e, jel, rou, fric, normal, speed, thd, thdd)
    else:
        obs[O_TH_MIN, i] = min(obs[O_TH_MIN, i], th)
        obs[O_TH_MAX, i] = max(obs[O_TH_MAX, i], th)
        obs[O_DE, i] = max(obs[O_DE, i], abs(e - obs[O_E0, i]))
        obs[O_DJ, i] = max(obs[O_DJ, i], abs(jel - obs[O_J0, i]))
        obs[O_DR, i] = max(obs[O_DR, i], abs(rou - obs[O_R0, i]))
        obs[O_FRIC, i] = max(obs[O_FRIC, i], fric)
        obs[O_NMIN, i] = min(obs[O_NMIN, i], normal)
        # per-cycle accumulators (rectangle rule over the previous interval)
        obs[O_A_PSID, i] = max(obs[O_A_PSID, i], abs(psid))
        obs[O_A_TURN, i] += abs(psid) * dt
        obs[O_A_RAW, i] += psid * dt
        obs[O_A_VMIN, i] = min(obs[O_A_VMIN, i], speed)
        obs[O_A_VINT, i] += speed * dt
        dq = quad - obs[O_P_QUAD, i]
        if dq > 2.0:
            dq -= 4.0
        elif dq < -2.0:
            dq += 4.0
        if abs(dq) < 2.0:  # a jump of two quadrants passes through v = 0: a cusp, not a turn
            obs[O_A_QUART, i] += dq
        # distance from the orbit centre (NaN until it is known: min/max then stay NaN-free);
        # a square root, not hypot: a library call on every sample (measured: 18 % of the
        # observer's cost), and these distances are far from overflow
        rx, ry = x - obs[O_RC_X, i], y - obs[O_RC_Y, i]
        r = math.sqrt(rx * rx + ry * ry)
        if r < obs[O_A_RMIN, i]:
            obs[O_A_RMIN, i] = r
        if r > obs[O_A_RMAX, i]:
            obs[O_A_RMAX, i] = r
        # --- theta minimum: thetadot turns from - to + (where the path turns: a corner) -------
        obs[O_A_NSAMP, i] += 1.0
        obs[O_TH_STEP, i] = max(obs[O_TH_STEP, i], abs(th - obs[O_P_TH, i]))
        if obs[O_P_THD, i] < 0.0 and thd >= 0.0:
            _, _, th_ev, _, xm, ym, _, _ = _locate(obs, i, t, x, y, sth, cth, chi, thd, chd,
                                                   phd, u, w, psid, c, A, B)
            on_minimum(obs, i, th_ev, xm, ym)
        # --- theta maximum: thetadot turns from + to - ----------------------------------------
        # (one between the launch and the first sample after it is not a cycle's start: the
        # launch's own sample can sit within 1e-7 deg of the vertical, where its Euler rates,
        # and so the path's heading read there, are rounding; the first cycle starts at the next)
        if obs[O_P_THD, i] > 0.0 and thd <= 0.0:
            _, t_ev, th_ev, chi_ev, x_ev, y_ev, psi_ev, speed_ev = _locate(
                obs, i, t, x, y, sth, cth, chi, thd, chd, phd, u, w, psid, c, A, B)
            if obs[O_NMAX, i] > 0.0 or obs[O_A_NSAMP, i] > 1.0:
                on_maximum(obs, i, t_ev, th_ev, chi_ev, x_ev, y_ev, psi_ev, speed_ev, psid,
                           speed)
            else:
                obs[O_TH_MAX, i] = max(obs[O_TH_MAX, i], th_ev)
    obs[O_P_THD, i] = thd
    obs[O_P_T, i] = t
    obs[O_P_CHI, i] = chi
    obs[O_P_X, i] = x
    obs[O_P_Y, i] = y
    obs[O_P_QUAD, i] = quad
    obs[O_P_STH, i] = sth
    obs[O_P_CTH, i] = cth
    obs[O_P_CHD, i] = chd
    obs[O_P_U, i] = u
    obs[O_P_W, i] = w
    obs[O_P_PSID, i] = psid
    obs[O_P_PHD, i] = phd
    obs[O_P_TH, i] = th


@jit
def cycles_done(obs, i, target):
    """Period mode: launch i has seen `target` theta maxima (target - 1 complete cycles)."""
    return obs[O_NMAX, i] >= target


def theta_maxima(theta) -> np.ndarray:
    """Indices of the discrete theta maxima of stored samples (the post-hoc twin of the
    observer's thetadot sign change)."""
    th = np.asarray(theta)
    return np.flatnonzero((th[1:-1] > th[:-2]) & (th[1:-1] >= th[2:])) + 1


@jit
def observe_samples(t, x, y, theta, chi, thd, chd, phd, params):
    """Run the observer over stored samples of one trajectory (post-hoc classification).

    Arrays are non-dimensional Euler-state samples; returns the observer column (N_OBS,).
    """
    obs = np.empty((N_OBS, 1))
    c, A, B = params[0], params[1], params[2]
    for n in range(t.shape[0]):
        sth, cth = math.sin(theta[n]), math.cos(theta[n])
        thdd, chdd, phdd = accelerations(sth, cth, thd[n], chd[n], phd[n], c, A, B)
        dt = t[n] - t[n - 1] if n > 0 else 0.0
        observe(obs, 0, n == 0, t[n], dt, x[n], y[n], theta[n], sth, cth, chi[n], thd[n], chd[n],
                phd[n], thdd, chdd, phdd, c, A, B)
    return obs[:, 0]

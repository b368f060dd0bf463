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

`observe` takes one launch's sample; `block_record` a whole block's (the fixed-step ensemble
kernel's), with the same arithmetic in the same order, so each launch's slots are the same to
the bit: the per-sample quantities and accumulators in one vectorised pass over the launches, the
events (rare: two a theta cycle) launch by launch.

All non-dimensional. Used by the ensemble kernels and, on stored samples, by `observe_samples`.
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
    "p_ax", "p_ay", "p_ezdd", "p_speed", "span_rate2",
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
 O_P_AX, O_P_AY, O_P_EZDD, O_P_SPEED, O_SPAN_W2) = range(N_OBS)

jit = njit(cache=True, nogil=True, error_model="numpy")  # stamped cache: _jit.py
#: for the per-sample arithmetic: numba inlines it into every caller, so that `record_block`'s
#: pass over the launches is one call-free loop (LLVM's inliner leaves it a call there)
jit_inline = njit(cache=True, nogil=True, error_model="numpy", inline="always")


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


#: the slots every sample after the first updates before its events: the running extrema, drift
#: maxima and per-cycle sums (`_accumulated`'s order)
ACCUMULATED = (O_TH_MIN, O_TH_MAX, O_DE, O_DJ, O_DR, O_FRIC, O_NMIN,
               O_A_PSID, O_A_TURN, O_A_RAW, O_A_VMIN, O_A_VINT, O_A_QUART, O_A_RMIN, O_A_RMAX,
               O_A_NSAMP, O_TH_STEP)
N_ACC = len(ACCUMULATED)
#: the slots that hold the previous sample, which the next one's accumulators and events read
PREVIOUS = (O_P_THD, O_P_T, O_P_CHI, O_P_X, O_P_Y, O_P_QUAD, O_P_STH, O_P_CTH, O_P_CHD, O_P_U,
            O_P_W, O_P_PSID, O_P_PHD, O_P_TH)


@jit_inline
def _slots(a, i, rows):
    """(a[rows[0], i], ..., a[rows[16], i]): 17 slots of column i, in the order of rows."""
    return (a[rows[0], i], a[rows[1], i], a[rows[2], i], a[rows[3], i], a[rows[4], i],
            a[rows[5], i], a[rows[6], i], a[rows[7], i], a[rows[8], i], a[rows[9], i],
            a[rows[10], i], a[rows[11], i], a[rows[12], i], a[rows[13], i], a[rows[14], i],
            a[rows[15], i], a[rows[16], i])


@jit_inline
def _copy_slots(dst, rows_dst, i_dst, src, rows_src, i_src):
    """dst[rows_dst[q], i_dst] = src[rows_src[q], i_src] for each q."""
    for q in range(len(rows_dst)):
        dst[rows_dst[q], i_dst] = src[rows_src[q], i_src]


@jit_inline
def _sample(sth, cth, thd, chd, phd, thdd, chdd, phdd, c, A, B, psid_in, fric_in, normal_in):
    """One sample's derived quantities: (u, w, speed, psid, fric, normal, e, jel, rou, quad),
    G's velocity in the frame turning with the heading chi (Eqs. 6-7) and its speed, the path's
    heading rate, friction demand |F_h|/N and N/(M g) (psid_in, fric_in, normal_in where those
    are finite), the three invariants and the quadrant of (u, w). Pure arithmetic, no calls."""
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
    e = energy(sth, cth, thd, chd, phd, c, A, B)
    jel = jellett(sth, cth, thd, chd, phd, c, A, B)
    rou = routh(sth, cth, thd, chd, phd, c, A, B)
    return u, w, speed, psid, fric, normal, e, jel, rou, _quadrant(u, w)


@jit_inline
def _accumulated(acc, e0, j0, r0, p_quad, rc_x, rc_y, p_th, dt, x, y, th, e, jel, rou, fric,
                 normal, psid, speed, quad):
    """The `ACCUMULATED` slots acc after one more sample (not the first; dt since the last):
    branch-free arithmetic on values, so that a loop over launches vectorises. e0, j0, r0,
    p_quad, rc_x, rc_y, p_th: the launch's E0, J0, R0, P_QUAD, RC_X, RC_Y and P_TH slots."""
    (th_min, th_max, de, dj, dr, fric_max, n_min, a_psid, a_turn, a_raw, a_vmin, a_vint,
     quart, r_min, r_max, nsamp, th_step) = acc
    # per-cycle accumulators (rectangle rule over the previous interval)
    dq = quad - p_quad
    if dq > 2.0:
        dq -= 4.0
    elif dq < -2.0:
        dq += 4.0
    if abs(dq) < 2.0:  # a jump of two quadrants passes through v = 0: a cusp, not a turn
        quart += dq
    # distance from the orbit centre (NaN until it is known: min/max then stay NaN-free);
    # a square root, not hypot: a library call on every sample (measured: 18 % of the
    # observer's cost), and these distances are far from overflow
    rx, ry = x - rc_x, y - rc_y
    r = math.sqrt(rx * rx + ry * ry)
    if r < r_min:
        r_min = r
    if r > r_max:
        r_max = r
    return (min(th_min, th), max(th_max, th), max(de, abs(e - e0)), max(dj, abs(jel - j0)),
            max(dr, abs(rou - r0)), max(fric_max, fric), min(n_min, normal),
            max(a_psid, abs(psid)), a_turn + abs(psid) * dt, a_raw + psid * dt,
            min(a_vmin, speed), a_vint + speed * dt, quart, r_min, r_max, nsamp + 1.0,
            max(th_step, abs(th - p_th)))


@jit
def _events(obs, i, t, x, y, sth, cth, chi, thd, chd, phd, u, w, psid, speed, c, A, B):
    """The theta extremum between launch i's previous sample (its P_ slots) and this one, if
    thetadot changed sign: located, and handed to `on_minimum` or `on_maximum`, which read (and
    reset) the accumulators this sample has already updated."""
    # --- theta minimum: thetadot turns from - to + (where the path turns: a corner) -----------
    if obs[O_P_THD, i] < 0.0 and thd >= 0.0:
        _, _, th_ev, _, xm, ym, _, _ = _locate(obs, i, t, x, y, sth, cth, chi, thd, chd,
                                               phd, u, w, psid, c, A, B)
        on_minimum(obs, i, th_ev, xm, ym)
    # --- theta maximum: thetadot turns from + to - --------------------------------------------
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


@jit
def observe(obs, i, first, t, dt, x, y, th, sth, cth, chi, thd, chd, phd, thdd, chdd, phdd, c, A, B,
            psid_in=math.nan, fric_in=math.nan, normal_in=math.nan):
    """Update launch i's slots with one sample (time t, step dt since the previous sample).

    psid_in, fric_in, normal_in: the path's heading rate, |F_h|/N and N/(M g) computed without
    the Euler chart (fixed-frame integration near theta = 90 deg); NaN: compute them here."""
    u, w, speed, psid, fric, normal, e, jel, rou, quad = _sample(
        sth, cth, thd, chd, phd, thdd, chdd, phdd, c, A, B, psid_in, fric_in, normal_in)
    if first:
        start_record(obs, i, th, e, jel, rou, fric, normal, speed, thd, thdd)
    else:
        acc = _accumulated(_slots(obs, i, ACCUMULATED), obs[O_E0, i], obs[O_J0, i],
                           obs[O_R0, i], obs[O_P_QUAD, i], obs[O_RC_X, i], obs[O_RC_Y, i],
                           obs[O_P_TH, i], dt, x, y, th, e, jel, rou, fric, normal, psid, speed,
                           quad)
        for q in range(N_ACC):
            obs[ACCUMULATED[q], i] = acc[q]
        _events(obs, i, t, x, y, sth, cth, chi, thd, chd, phd, u, w, psid, speed, c, A, B)
    (obs[O_P_THD, i], obs[O_P_T, i], obs[O_P_CHI, i], obs[O_P_X, i], obs[O_P_Y, i],
     obs[O_P_QUAD, i], obs[O_P_STH, i], obs[O_P_CTH, i], obs[O_P_CHD, i], obs[O_P_U, i],
     obs[O_P_W, i], obs[O_P_PSID, i], obs[O_P_PHD, i], obs[O_P_TH, i]) = (
        thd, t, chi, x, y, quad, sth, cth, chd, u, w, psid, phd, th)


# --- a block of launches at once (the fixed-step ensemble kernel) --------------------------------
#: launches a chunk of `block_open`'s lane state holds: its rows are this long, a constant, so
#: that LLVM knows where each row lies and vectorises a pass over the launches without checking
#: each row it writes against every other array it reads (too many checks: it would not)
CHUNK = 64
#: rows of a chunk of lane state: the `ACCUMULATED` slots (rows 0..N_ACC-1, same order), the
#: `PREVIOUS` slots (same order), the PREVIOUS slots as the sample before this one left them
#: (for the event pass), this sample's speed, and 1.0 while the launch is alive (0.0 after:
#: its slots are then in obs)
L_ACC = tuple(range(N_ACC))
L_PREV = tuple(range(N_ACC, N_ACC + len(PREVIOUS)))
L_BEFORE = tuple(range(N_ACC + len(PREVIOUS), N_ACC + 2 * len(PREVIOUS)))
(L_P_THD, L_P_T, L_P_CHI, L_P_X, L_P_Y, L_P_QUAD, L_P_STH, L_P_CTH, L_P_CHD, L_P_U,
 L_P_W, L_P_PSID, L_P_PHD, L_P_TH) = L_PREV
L_B_THD = L_BEFORE[0]
L_SPEED = N_ACC + 2 * len(PREVIOUS)
L_ALIVE = L_SPEED + 1
N_LANE_ROWS = L_ALIVE + 1


@jit
def block_open(obs):
    """The lane state of a block of launches whose slots are obs's columns: for `block_record`,
    which keeps the slots every sample touches there while their launches are alive, and
    `block_close`, which writes them back. None alive yet."""
    m = obs.shape[1]
    lanes = np.empty(((m + CHUNK - 1) // CHUNK, N_LANE_ROWS, CHUNK))
    lanes[:, L_ALIVE, :] = 0.0
    return lanes


@jit
def _lane_out(lanes, obs, alive, m):
    """Each of the m launches that the lane state holds alive and `alive` does not: its slots
    written from the lane state to obs, where they stay."""
    for i in range(m):
        ch, j = divmod(i, CHUNK)
        if lanes[ch, L_ALIVE, j] == 1.0 and not alive[i]:
            lane = lanes[ch]
            _copy_slots(obs, ACCUMULATED, i, lane, L_ACC, j)
            _copy_slots(obs, PREVIOUS, i, lane, L_PREV, j)
            lanes[ch, L_ALIVE, j] = 0.0


@jit
def block_close(lanes, obs):
    """Every launch's slots in obs: those still in the lane state written back."""
    m = obs.shape[1]
    _lane_out(lanes, obs, np.zeros(m, dtype=np.bool_), m)


@jit
def block_record(lanes, obs, alive, first, t, dt, x, y, th, sth, cth, chi, thd, chd, phd, c, A,
                 B):
    """`observe` for a block of launches at once: one sample (time t, dt since the last) of
    every launch i with alive[i], its state in the rows x[i], y[i], ... and its parameters in
    c[i], A[i], B[i]; lanes: `block_open(obs)`. After `block_close`, each launch's slots are as
    `observe` leaves them, bit for bit.

    The slots that every sample reads and writes live in the lane state, CHUNK launches a row:
    one pass over a chunk's launches does the per-sample work that has no branch of consequence
    (the sample's quantities, the accumulators, the previous sample's slots) with no call, and
    LLVM vectorises it; then, for the few launches whose thetadot changed sign, the event work
    (`_events`, which reads and resets those accumulators) on their column of obs, launch by
    launch."""
    m = x.shape[0]
    if first:
        for i in range(m):
            if alive[i]:
                thdd, chdd, phdd = accelerations(sth[i], cth[i], thd[i], chd[i], phd[i], c[i],
                                                 A[i], B[i])
                observe(obs, i, True, t, dt, x[i], y[i], th[i], sth[i], cth[i], chi[i], thd[i],
                        chd[i], phd[i], thdd, chdd, phdd, c[i], A[i], B[i])
                ch, j = divmod(i, CHUNK)
                lane = lanes[ch]
                _copy_slots(lane, L_ACC, j, obs, ACCUMULATED, i)
                _copy_slots(lane, L_PREV, j, obs, PREVIOUS, i)
                lanes[ch, L_ALIVE, j] = 1.0
        return
    n_out = 0  # launches stopped since the last sample
    for ch in range(lanes.shape[0]):
        lo = ch * CHUNK
        for j in range(min(CHUNK, m - lo)):
            n_out += np.int64(lanes[ch, L_ALIVE, j] > np.float64(alive[np.uint64(lo + j)]))
    if n_out > 0:
        _lane_out(lanes, obs, alive, m)
    for ch in range(lanes.shape[0]):
        lane = lanes[ch]
        lo = ch * CHUNK
        n_events = 0
        for j in range(min(CHUNK, m - lo)):
            # unsigned: numba then adds no check for a negative index, and LLVM sees the rows
            # read at consecutive addresses (not gathered)
            i = np.uint64(lo + j)
            thdd, chdd, phdd = accelerations(sth[i], cth[i], thd[i], chd[i], phd[i], c[i], A[i],
                                             B[i])
            u, w, speed, psid, fric, normal, e, jel, rou, quad = _sample(
                sth[i], cth[i], thd[i], chd[i], phd[i], thdd, chdd, phdd, c[i], A[i], B[i],
                math.nan, math.nan, math.nan)
            (lane[0, j], lane[1, j], lane[2, j], lane[3, j], lane[4, j], lane[5, j], lane[6, j],
             lane[7, j], lane[8, j], lane[9, j], lane[10, j], lane[11, j], lane[12, j],
             lane[13, j], lane[14, j], lane[15, j], lane[16, j]) = _accumulated(
                _slots(lane, j, L_ACC), obs[O_E0, i], obs[O_J0, i], obs[O_R0, i],
                lane[L_P_QUAD, j], obs[O_RC_X, i], obs[O_RC_Y, i], lane[L_P_TH, j], dt, x[i],
                y[i], th[i], e, jel, rou, fric, normal, psid, speed, quad)
            for q in range(len(PREVIOUS)):
                lane[L_BEFORE[q], j] = lane[L_PREV[q], j]
            (lane[L_P_THD, j], lane[L_P_T, j], lane[L_P_CHI, j], lane[L_P_X, j], lane[L_P_Y, j],
             lane[L_P_QUAD, j], lane[L_P_STH, j], lane[L_P_CTH, j], lane[L_P_CHD, j],
             lane[L_P_U, j], lane[L_P_W, j], lane[L_P_PSID, j], lane[L_P_PHD, j],
             lane[L_P_TH, j]) = (thd[i], t, chi[i], x[i], y[i], quad, sth[i], cth[i], chd[i], u,
                                 w, psid, phd[i], th[i])
            lane[L_SPEED, j] = speed
            # thetadot's sign changed, or one of them is zero, or their product underflows: the
            # launches with an event and a few more (checked one by one below), none missed
            n_events += np.int64(lane[L_B_THD, j] * thd[i] <= 0.0)
        if n_events == 0:
            continue
        for j in range(min(CHUNK, m - lo)):
            i = lo + j
            b_thd = lane[L_B_THD, j]
            if lane[L_ALIVE, j] == 1.0 and ((b_thd < 0.0 and thd[i] >= 0.0)
                                            or (b_thd > 0.0 and thd[i] <= 0.0)):
                # the event work on obs: this sample's accumulators, the previous sample
                _copy_slots(obs, ACCUMULATED, i, lane, L_ACC, j)
                _copy_slots(obs, PREVIOUS, i, lane, L_BEFORE, j)
                _events(obs, i, t, x[i], y[i], sth[i], cth[i], chi[i], thd[i], chd[i], phd[i],
                        lane[L_P_U, j], lane[L_P_W, j], lane[L_P_PSID, j], lane[L_SPEED, j],
                        c[i], A[i], B[i])
                _copy_slots(lane, L_ACC, j, obs, ACCUMULATED, i)


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

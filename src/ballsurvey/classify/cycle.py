"""The classifier's record of each launch from its invariants, by quadrature over one theta cycle.

No time stepping. With the energy E, Jellett's J and Routh's R fixed by the launch, every rate is a
function of theta alone (docs/physics.md section 6), theta oscillates between the roots
theta_min < theta_max of thetadot^2 = F(theta), and each theta cycle repeats the last one turned by
the turn per cycle about the orbit centre. So one half cycle, from theta_min up to theta_max, holds
everything the labels need; the other half is its mirror image (theta(t) is symmetric about its
extrema: the path is mirror-symmetric about the line through G at a theta extremum, across the
heading there).

Turning points. From the launch (a turning point itself when thetadot0 = 0: the sign of
thetaddot0 says which), F is followed outward until it changes sign (a tilt that reaches the
vertical, +-90 deg less 1e-13, is left to the integrator): each probe steps to the extrapolated
root of q = F cos^2 / |theta - theta0| (launch at a turning point: no root there) or of q = F
cos^2 (`_turning_point`; F grows as 1 / cos^2 towards the vertical, F cos^2 has the same roots
and bends far less), and the root is solved by Newton's method on F cos^2 with F's exact
derivative F' = 2 thetaddot(theta, thetadot = sqrt F), from q's root interpolated through the
search's last three points, kept inside the bracket by bisection, until F is within its rounding
of 0 or a Newton step is rounding-sized (x is then the root to rounding, whichever sign F's
rounding gave it; near the vertical, also short against the distance to it). Evaluations a
turning point, headline launches (`benchmarks/turning_points.py`): 3.9 of F and 3.5 of F and F'
(on F itself: 2.9 and 5.8).

Quadrature. With theta = m + h sin s (m, h: the middle and half-range), s in [-pi/2, pi/2] runs the
rising half cycle, dt/ds = h cos s / sqrt(F) is smooth (its value at the ends, sqrt(h /
|thetaddot|), is the limit) and so is every integrand below. They are integrated by Clenshaw-Curtis
quadrature on N + 1 Chebyshev-Lobatto points in s (spectral for smooth integrands, and the points
cluster at the turning points, where the tilt's approach to the vertical makes the integrands' only
sharp feature), N = 16, 32, ..., 512, nested (each level reuses the last's points) until the period
and the turn of two successive levels agree to `QUAD_RTOL` and `TURN_TOL` (relative; absolute in rad
for a turn under 1 rad); not converged at 512: left to the integrator, as is a swing whose turning
points F's rounding leaves uncertain (`END_SPREAD_LIMIT`). The points so near an end that F's
rounding is over END_DIFF_RTOL of F, and near enough that the errors it leaves there would add
up (`_diff_reach`: at an end where the tilt turns slowly), take F from its difference from the
energy at the end, free of cancellation (`_F_about`), instead of F as computed, a difference of
terms of the energy's size. Each level's new points
take their rates in a loop free of calls, which runs in SIMD lanes (as does the path's per-point
algebra: sines, cosines and arctangents in those loops are `trig`'s, plain arithmetic); the
numbers are those of one point at a time. The period and turn are the last level's; the path is
taken at the level before (its period and turn agree with the last's to those tolerances): there
the cumulative integrals (Chebyshev integration matrix) give, at every point, the time, the
heading chi (from chidot) and G's position (from its velocity, in the heading frame turned by
chi).

From them, per launch, the observer's slots (`observer.SLOTS`) are filled as the stepping observer
would fill them after the same number of theta maxima, so the one labeller (`labels.label_fields`)
labels either: theta range, period and turn per cycle (exact, not differenced between events),
chord and side (G at the extrema: the side is the distance between G at theta_min and its mirror
image), the orbit centre (fixed point of the rotation by the turn that maps one minimum onto the
next), the least and largest distance from it over the half cycle (= over the whole orbit), and
over the cycle the peak path heading rate, the total absolute heading change (the variation of the
path's heading over the points), the least and mean speed, the velocity's winding relative to the
heading (from the sign of the forward speed at the two turning points: the velocity stays in one
half-plane over each half cycle), the least normal force and the largest friction demand (functions
of theta alone). Extrema over the points are refined by the parabola through the best point and its
two neighbours (the functions are even about the turning points, so an extremum there is exact).
The invariants do not drift (0 is recorded). The count of theta maxima in T (capped at the period
mode's target) comes from the time of the first maximum after the launch.

Status per launch (`DONE`, or why the integrator must do it): `STEADY` (|thetadot0| and
|thetaddot0| below the classifier's steady_rate_tol), `VERTICAL` (theta reaches +-90 deg),
`UNCONVERGED` (the quadrature did not converge, F was not positive where it must be, or F's
rounding leaves the turning points too uncertain against the swing: `END_SPREAD_LIMIT`).
"""
from __future__ import annotations

import math
from functools import cache

import numba as nb
import numpy as np
from numba import uintp

from .._jit import alive, borrow, fetch_add, njit
from ..physics.euler import accelerations, heading_velocity, jellett, kinetic, normal_force, routh
from . import observer as ob
from .trig import atan2, sincos, sincos_shift  # by name: `integrate.cuda.device_twin`

jit = njit(cache=True, nogil=True, error_model="numpy")  # stamped cache: _jit.py
#: functions that take arrays, called per launch: inlined in numba's IR, so that passing an
#: array costs no reference-count update (an atomic instruction) per call
jit_inline = njit(cache=True, nogil=True, error_model="numpy", inline="always")

#: status codes per launch
DONE, STEADY, VERTICAL, UNCONVERGED = 0, 1, 2, 3
STATUSES = ("done", "steady", "vertical", "unconverged")
#: Clenshaw-Curtis levels: N = FIRST_N, 2 FIRST_N, ... MAX_N intervals over the half cycle
FIRST_N, LEVELS = 16, 6
MAX_N = FIRST_N << (LEVELS - 1)
#: agreement of the period (relative) and of the half cycle's turn (relative, absolute in rad
#: below 1 rad) between two successive levels. The turn's is wider: near the vertical chidot
#: reaches 1e3 and the rounding of F close to the turning points leaves the turn 1e-10 to 1e-9
#: of noise (at 5e-10, 1-5 of 300 launches with theta max 89.5-89.99 deg do not converge by
#: N = MAX_N; at 5e-9 all do, within 1.5e-7 deg: `benchmarks/quadrature_vertical.py`)
QUAD_RTOL, TURN_TOL = 1e-9, 5e-9
#: a swing whose end comes within VERTICAL_CLOSE (rad, 0.01 deg) of +-90 deg takes the turn's
#: agreement at TURN_TOL_CLOSE: there chidot's peak at the end converges slowly with N, and
#: on turns of a cycle or more TURN_TOL let 1.3-1.6e-6 deg through (swings from within 4e-4
#: deg of -90 deg)
VERTICAL_CLOSE, TURN_TOL_CLOSE = math.radians(0.01), 5e-10
#: the largest uncertainty of a turning point that F's rounding leaves (f_noise / |F'| there), as
#: a fraction of the half-range h, at which the quadrature is trusted: a small swing (F small
#: everywhere) near a steady circle. With F as computed at every point, past 1e-11 the ends'
#: points spoilt the integrals (3.2e-6 deg for a 0.38 deg swing at 3 deg of tilt; beyond 1e-10,
#: 2.5e-5 to 6.6e-3 deg). With F about the ends (`_F_about`, `_root_about`), against the fixed
#: frame at rtol 1e-12 with the limit off (`benchmarks/quadrature_ends.py --n 300`, seed 0;
#: swings down to 1e-4 deg): under 1e-8, 1e-10 deg; 1e-8 to 1e-5, 9.9e-9 deg; 1e-5 to 1e-4,
#: 3.8e-8 deg; 1e-4 to 1e-3, 2.5e-7 deg; beyond, 1.8e-6 deg. A launch past it goes to the
#: integrator: 86 of the headline map's 1e6 launches (11 082 with the limit at 1e-11)
END_SPREAD_LIMIT = 1e-05
#: past END_SPREAD_PLAIN, a swing is taken only where F about the ends covers it (both ends
#: slow) and it keeps to tilts within SMALL_SWING_TILT (rad) of the horizontal. F is then small
#: everywhere, and the launch's own invariants, rounded, perturb it by up to a quarter of the
#: uncertainty, relatively: a small swing near a steady circle hardly feels that (its period
#: hardly depends on its energy), but a swing of 0.1-1.7 deg at -88 to -89.9 deg whose F is
#: 1e-8 of the energy's terms was 1.4e-6 to 1.2e-4 deg off against 40 digits (an adversarial
#: search; away from the vertical, 136 small swings of the same search were within 2.2e-8 deg)
END_SPREAD_PLAIN, SMALL_SWING_TILT = 1e-11, math.radians(85.0)
#: a swing with an end within 1 deg of the vertical that takes F about a slow end takes a level
#: only where the sums with F as computed converge too: there `_F_about` loses digits, and
#: an adversarial search found swings from within 0.01 deg of -90 deg 1e-6 to 4.5e-5 deg off
#: without that gate (the integrator's with it)
GATE_TILT = math.radians(89.0)
#: an end's points take F from its difference about the end (`_F_about`) where F's rounding
#: is over END_DIFF_RTOL of it and their sum's share of the integrals' rounding error would be
#: over END_DIFF_TOL (`_diff_reach`). Near an end F as computed is off by a constant of its
#: rounding, the end's uncertainty sigma (f_noise / |F'|, a fraction of the half-range h) in
#: units of h: at a distance x its relative error is sigma h / x. The points come as close as
#: x_j ~ h (pi j / N)^4 / 3 at level N and their weights go as j / N^2, so the error of the
#: points beyond a distance X is about sigma sqrt(h / X) / 5 of an integral, whatever the
#: level: nothing for the headline's ends (sigma 1e-16 to 1e-13) at N = 32, but 2.1e-6 deg of
#: turn per cycle, against 40 digits, for a launch at rest at -89.94 deg (swing to 45.6 deg,
#: sigma 9e-14) converged at N = 256 (2.9e-9 deg with F about that end)
END_DIFF_RTOL, END_DIFF_TOL = 1e-12, 5e-12
#: the vertical less a hair: a tilt whose F is still positive there goes through it
TILT_LIMIT = 0.5 * math.pi * (1.0 - 1e-13)
#: first step of the outward search for a turning point, its largest and its least (rad)
SEARCH_STEP, SEARCH_STEP_MAX, SEARCH_STEP_MIN = math.radians(2.0), math.radians(8.0), 1e-9
#: a predicted step reaches this far past the extrapolated root, to bracket it in one probe; at
#: most PREDICT_STEP_MAX (rad)
PREDICT_OVERSHOOT, PREDICT_STEP_MAX = 1.5, math.radians(30.0)
#: a turning point takes the end's terms (`_end_at`) of the last point its search evaluated
#: where that is within END_REUSE of it (a Newton step of rounding size), relative to the tilt
#: and to the distance from the vertical: 1e-14 rad 3.5e-8 rad below the vertical moved the
#: end's chidot and thetaddot by 2-3e-7 and let a turn through 3.7e-5 deg off (an adversarial
#: search against 40 digits: 14 of 1.2 million launches within 0.1 deg of the vertical changed
#: status; with the distance, none, and the turn within 2e-13 deg of the terms evaluated again)
END_REUSE = 1e-14
#: F within this many of its rounding units (eps times the energy's terms) of 0 is a root
ROOT_NOISE = 16.0
#: a launch at rest in theta starts its search this far inside (rad); F there is taken to be
#: positive without evaluating it where F's slope times that distance is START_MARGIN times F's
#: rounding (f_noise: ROOT_NOISE units) or more
START_OFFSET, START_MARGIN = 1e-9, 1e3
#: doubles in a SIMD vector (AVX-512; the padding of the loops over points, `_lanes`)
LANES = 8
#: the scratch rows' length (scr's and node's, here and on a GPU): MAX_N + 1 points padded to
#: whole vectors, so that every row starts as the first does relative to the cache lines: the
#: cumulative integrals' vector loads and stores (`_cumulate`) split no more lines than the first
#: row's (3 % of the kernel's time against rows of MAX_N + 1). (The loops padded to whole
#: vectors, `_lanes`, run over at most MAX_N / 2 + 1 points.)
ROW = (MAX_N + LANES) // LANES * LANES
#: per-point scratch columns
_TAU, _CHD, _PHD, _THD, _STH, _CTH, _TAUP = range(7)
N_SCRATCH = 7
#: per-point rows of the path's scratch (`cycle_one`'s node): s, dt/ds, chidot dt/ds, u, w dt/ds,
#: |path heading rate|, speed, friction demand, normal force, chi, x, y, two work rows, w
(_SS, _TAU_C, _CHD_TAU, _U, _W_TAU, _PSID, _SPEED, _FRIC, _NORM, _CHI, _X, _Y, _FX, _FY,
 _W) = range(15)
N_NODE = 15
#: the path's inputs per point (chidot, phidot, thetadot, sin and cos theta), in rows that are
#: free until the cumulative integrals
_IN_CHD, _IN_PHD, _IN_THD, _IN_STH, _IN_CTH = _CHI, _X, _Y, _FX, _FY
#: the extrema the observer's slots take over the path's points (`_extremum`): slot, row of
#: node, sign (+1: largest, -1: least)
_EXT_SLOTS = (ob.O_C_RMIN, ob.O_C_RMAX, ob.O_FRIC, ob.O_NMIN, ob.O_C_PSID, ob.O_C_VMIN)
_EXT_ROWS = (_FX, _FX, _FRIC, _NORM, _PSID, _SPEED)
_EXT_SIGNS = (-1.0, 1.0, 1.0, -1.0, 1.0, -1.0)
#: node's rows as the level stage's work rows: sin, cos, h cos s, chidot, phidot, F, thetadot,
#: dt/ds of the level's new points
_WS, _WC, _WH, _WCHD, _WPHD, _WF, _WTHD, _WTAU = range(8)


@cache
def tables():
    """(s, sin s, cos s at the finest level's MAX_N + 1 points; weights (LEVELS, MAX_N + 1):
    level L's Clenshaw-Curtis weights in s at the finest level's indices (0 elsewhere);
    cumulative integration matrices of the levels below the finest (the path is never taken at
    the finest), flat (each by columns), and their offsets).
    Level L's point j is the finest level's point j * (MAX_N >> (L + log2 FIRST_N)).

    At x_j = -cos(pi j / n) (s = pi x / 2), T_k(x_j) = (-1)^k cos(pi k j / n), so a function's
    Chebyshev coefficients from its values are a cosine transform (the interpolation matrix's
    inverse in closed form: no matrix to invert); its integral's coefficients are numpy's
    `chebint` of them, summed (every T_k is 1 at x = 1) for the weights, evaluated at the points
    for the cumulative matrices."""
    from numpy.polynomial import chebyshev as ch

    k = np.arange(MAX_N + 1)
    s = -0.5 * math.pi * np.cos(math.pi * k / MAX_N)
    s[MAX_N // 2] = 0.0
    weights = np.zeros((LEVELS, MAX_N + 1))
    mats, offsets = [], np.zeros(LEVELS + 1, dtype=np.int64)
    for L in range(LEVELS):
        n = FIRST_N << L
        j = np.arange(n + 1)
        halve = np.where((j == 0) | (j == n), 0.5, 1.0)
        # coefficients from values: c_k = (2 / n) h_k sum_j h_j (-1)^k cos(pi k j / n) f_j
        # (h: 1/2 at the ends), the angle reduced mod 2 pi before the cosine
        vinv = (2.0 / n) * ((-1.0) ** j * halve)[:, None] * halve[None, :] * np.cos(
            math.pi * (np.outer(j, j) % (2 * n)) / n)
        integ = ch.chebint(vinv, lbnd=-1.0, axis=0) * (0.5 * math.pi)
        weights[L, ::MAX_N // n] = integ.sum(axis=0)
        size = 0
        if L < LEVELS - 1:
            # the product by numpy's own loop (einsum, unoptimised), not BLAS: a BLAS product's
            # rounding depends on its thread count (OPENBLAS_NUM_THREADS, OMP_NUM_THREADS), and
            # every launch by quadrature would follow it in the last bits
            q = np.einsum("ij,jk->ik", ch.chebvander(-np.cos(math.pi * j / n), n + 1), integ,
                          optimize=False)
            q[0] = 0.0
            mats.append(q.T.ravel())  # by columns (`_cumulate`)
            size = q.size
        offsets[L + 1] = offsets[L] + size
    return (s, np.sin(s), np.cos(s), weights, np.concatenate(mats), offsets)


@jit
def _constants(E, J, R, c, A, B):
    """The launch's constants its rates at a tilt are computed from (`_rates_at`): (E, R, c, A,
    B, D+, D-, q+, q-), with q+- = sqrt(A B + B (+-1 - c)^2) (Routh's root at the vertical, +-90
    deg) and D+- = B R (+-1 - c) / q+- - J (Jellett's numerator there)."""
    qp = math.sqrt(A * B + B * (1.0 - c) ** 2)
    qm = math.sqrt(A * B + B * (1.0 + c) ** 2)
    return E, R, c, A, B, B * R * (1.0 - c) / qp - J, -B * R * (1.0 + c) / qm - J, qp, qm


@jit
def _rates_at(sth, cth, inv):
    """(chidot, phidot, F = thetadot^2) at the tilt whose sine and cosine are sth, cth, from the
    launch's constants inv (`_constants`; E: the energy less M g a). Free of calls: the level and
    path loops evaluate it for many points at once (SIMD lanes).

    chidot = (B w (sin - c) - J) / (A cos^2) (Jellett's integral solved for it, w from Routh's)
    is taken about the nearer vertical p = +-1 (the sign of sin): there the numerator is D_p, a
    launch constant, plus a multiple of 1 - p sin = cos^2 / (1 + p sin), which cancels against
    the cos^2 below (docs/physics.md section 6). Near the vertical the plain form's numerator is
    a difference of terms far larger than itself, whose rounding, over cos^2, is a noise from
    point to point in chidot that puts the turn per cycle up to 1.3e-6 deg off; here D_p's
    rounding is one perturbation of J for the whole launch (1e-14 deg of turn)."""
    E, R, c, A, B, d_p, d_m, q_p, q_m = inv
    c2 = cth * cth
    sq = math.sqrt(A * B + A * c2 + B * (sth - c) ** 2)
    w = R / sq
    p = 1.0 if sth >= 0.0 else -1.0
    d = d_p if sth >= 0.0 else d_m
    q1 = q_p if sth >= 0.0 else q_m
    ps1 = 1.0 + p * sth
    x = B * p * (p + sth - 2.0 * c) - A * ps1  # (q1^2 - sq^2) / (1 - p sin)
    qq = q1 * (q1 + sq)
    chd = ((d * ps1 * sq * qq + B * R * c2 * ((p - c) * x - p * qq))
           / (A * c2 * ps1 * sq * qq))
    chc = chd * cth  # chidot cos(theta): bounded at the vertical
    phd = w + chd * sth
    # the energy at thetadot = 0 (`kinetic` less c sin theta) from w and chidot cos(theta),
    # not from phidot - chidot sin(theta), which loses |chidot| ulps near the vertical
    fwd = w * cth + chc * (sth - c)  # (phidot - c chidot) cos(theta)
    u = 0.5 * (A * chc * chc + B * w * w + fwd * fwd) - c * sth
    return chd, phd, 2.0 * (E - u) / (A + 1.0 - 2.0 * c * sth + c * c)


@jit
def _rates(th, inv):
    """(sin, cos, chidot, phidot, F = thetadot^2) at tilt th (`_rates_at`)."""
    sth, cth = math.sin(th), math.cos(th)
    chd, phd, f = _rates_at(sth, cth, inv)
    return sth, cth, chd, phd, f


@jit
def _F(th, inv):
    return _rates(th, inv)[4]


@jit
def _F_dF(th, inv):
    """F, its derivative 2 thetaddot(th, thetadot = sqrt F) (thetaddot depends on thetadot^2
    only), tan th, and the end's terms (`_end_at`) had th been the turning point."""
    sth, cth, chd, phd, f = _rates(th, inv)
    thdd = accelerations(sth, cth, math.sqrt(max(f, 0.0)), chd, phd, inv[2], inv[3], inv[4])[0]
    return f, 2.0 * thdd, sth / cth, (sth, cth, chd, phd, thdd)


@jit
def _root(a, b, x, f_noise, inv):
    """The sign change of F between a (F > 0) and b (F <= 0), from x inside: Newton kept in the
    bracket by bisection, until F is within f_noise (its rounding) of 0 or the step is
    rounding. Returns (the root, the end's terms there: `_root_end`; those of the last point
    evaluated are `_end_at`'s with thetadot^2 = F, within F's rounding of 0, where thetaddot
    depends on thetadot^2 only)."""
    for _ in range(200):
        f, df, tn, end = _F_dF(x, inv)
        # Newton's step on F cos^2 (the same roots; its derivative over cos^2 is F' - 2 F tan):
        # F's 1 / cos^2 growth towards the vertical bends F, and Newton's method on F itself
        # creeps in from a far start
        df -= 2.0 * f * tn
        if abs(f) <= f_noise:  # a root to F's own rounding: one Newton step more is the best
            nx = x - f / df if df != 0.0 else x
            return _root_end(nx if min(a, b) <= nx <= max(a, b) else x, x, end, inv)
        if f > 0.0:
            a = x
        else:
            b = x
        nx = x - f / df if df != 0.0 else 0.5 * (a + b)
        lo, hi = min(a, b), max(a, b)
        # a Newton step this short leaves an error of order its square times F'' / F': x is
        # the root to rounding, whichever side of it F's rounding put x (a step out of the
        # bracket here would start bisecting from its far end, some 50 steps back to x). F''
        # / F' is of order 1, but 3 / (pi/2 - |x|) near the vertical (F ~ -1 / cos^2): there
        # the step must also be short against the distance to the vertical, or a root within
        # 1e-8 rad of it ends 1e-12 rad steps up to 1e-9 rad short (Newton from the steep side)
        if abs(nx - x) <= min(1e-12 * max(1.0, abs(x)), 1e-4 * (0.5 * math.pi - abs(x))):
            return _root_end(nx if lo <= nx <= hi else x, x, end, inv)
        if not (lo < nx < hi and math.isfinite(nx)):
            nx = 0.5 * (a + b)
        if nx == x or abs(b - a) <= 4e-16 * max(1.0, abs(x)):
            return _root_end(nx, x, end, inv)
        x = nx
    return x, _end_at(x, inv)


@jit
def _root_end(root, x, end, inv):
    """(root, the end's terms there): those evaluated at x where x is within END_REUSE of the
    root, relative to the tilt and to its distance from the vertical (the terms' own scale
    there: chidot grows as 1 / cos^2), else evaluated at the root (a slow end, whose last
    Newton step is long, or one a hair from the vertical)."""
    if abs(root - x) <= END_REUSE * min(max(1.0, abs(x)), 0.5 * math.pi - abs(x)):
        return root, end
    return root, _end_at(root, inv)


@jit
def _turning_point(start, d, ref, q_start, f_noise, inv):
    """The first root of F from start (F > 0 there) in direction d (+-1), and the end's terms
    there (`_root`); NaN where the tilt reaches the vertical.

    The search follows q = F cos^2 / |theta - ref| when ref is a root of F itself (the launch at
    a turning point: q has no root there, and is linear in theta where F cos^2 is a parabola),
    else q = F cos^2 (ref NaN); q_start is q at start. F grows as 1 / cos^2 towards the vertical;
    F cos^2, with the same roots, bends far less. Each probe's step is the linear extrapolation
    of q's last two values to its root, overshot by PREDICT_OVERSHOOT (at most
    PREDICT_STEP_MAX); where q does not fall, the step doubles from SEARCH_STEP (at most
    SEARCH_STEP_MAX). The root is then solved (`_root`) from q's inverse quadratic
    interpolation through the last three points (linear through the bracket's ends where that
    falls outside it)."""
    deflate = math.isfinite(ref)
    a, qa, step = start, q_start, SEARCH_STEP
    p, qp = math.nan, math.nan  # the point before a
    while True:
        b = a + d * step
        vertical = abs(b) >= TILT_LIMIT
        if vertical:
            b = d * TILT_LIMIT
        _, cb, _, _, fb = _rates(b, inv)
        if vertical and fb > 0.0:
            return math.nan, (0.0, 0.0, 0.0, 0.0, 0.0)
        qb = fb * cb * cb
        if deflate:
            qb /= abs(b - ref)
        if fb <= 0.0:
            lo, hi = min(a, b), max(a, b)
            # q's root: inverse quadratic interpolation through the last three points, else
            # linear through the bracket's ends, else its middle
            x = math.nan
            if math.isfinite(qp) and qp != qa and qp != qb and qa != qb:
                x = (p * qa * qb / ((qp - qa) * (qp - qb)) + a * qp * qb / ((qa - qp) * (qa - qb))
                     + b * qp * qa / ((qb - qp) * (qb - qa)))
            if not lo < x < hi:
                x = a + (b - a) * (qa / (qa - qb)) if qa - qb > 0.0 else 0.5 * (a + b)
            if not lo < x < hi:
                x = 0.5 * (a + b)
            return _root(a, b, x, f_noise, inv)
        if qa > qb:  # q falls: its root lies about qb / (qa - qb) steps further on
            step = min(PREDICT_STEP_MAX, max(SEARCH_STEP_MIN,
                                             PREDICT_OVERSHOOT * step * qb / (qa - qb)))
        else:
            step = min(2.0 * step, SEARCH_STEP_MAX)
        p, qp = a, qa
        a, qa = b, qb


@jit
def _end_of(sth, cth, inv):
    """The terms of a turning point the quadrature takes, from its sine and cosine: (sin, cos,
    chidot, phidot, thetaddot at thetadot = 0)."""
    chd, phd, _ = _rates_at(sth, cth, inv)
    return sth, cth, chd, phd, accelerations(sth, cth, 0.0, chd, phd, inv[2], inv[3], inv[4])[0]


@jit
def _end_at(th, inv):
    """`_end_of` the turning point th."""
    return _end_of(math.sin(th), math.cos(th), inv)


@jit
def _energy_terms(sth, cth, chd, inv):
    """(q, w, chidot cos, (phidot - c chidot) cos) at the tilt whose sine and cosine are sth,
    cth, chidot chd there: the terms of the energy at rest in theta (`_rates_at`) that
    `_F_about` takes differences of."""
    _, R, c, A, B, _, _, _, _ = inv
    sq = math.sqrt(A * B + A * cth * cth + B * (sth - c) ** 2)
    w = R / sq
    chc = chd * cth
    return sq, w, chc, w * cth + chc * (sth - c)


@jit
def _end_terms(th, inv):
    """(sin, cos, q, w, chidot cos, (phidot - c chidot) cos) at the end th (`_energy_terms`)."""
    sth, cth = math.sin(th), math.cos(th)
    sq, w, chc, fwd = _energy_terms(sth, cth, _rates_at(sth, cth, inv)[0], inv)
    return sth, cth, sq, w, chc, fwd


@jit
def _F_about(sth, cth, chd, dx, end, inv):
    """F at the tilt end + dx (sine and cosine sth, cth; chidot chd there) from its difference
    from the end's energy at rest in theta: F = 2 (u(end) - u(theta)) / (A + 1 - 2 c sin + c^2)
    with u - u(end) summed from the differences of its terms, each a product of differences
    computed without cancellation (sin(end + dx) - sin(end) = cos(end) sin dx - 2 sin(end)
    sin^2(dx/2), and so on; `end` from `_end_terms`). F as `_rates_at` computes it is E - u,
    two terms of the energy's size: near an end where F turns slowly (|F'| small) that
    difference is off by its rounding, all points the same way, and the turn per cycle by up
    to 2e-6 deg near -90 deg. This one is off by rounding relative to the terms' differences,
    of order |dx| times their slopes: relatively, the same at every distance from the end.
    (The energy it takes is u(end), which differs from the launch's by the rounding that
    leaves the end uncertain: the same launch, perturbed in the last bits.)"""
    _, _, c, A, B, _, _, _, _ = inv
    s_e, c_e, sq_e, w_e, chc_e, fwd_e = end
    sh, ch = sincos(0.5 * dx)
    sx, vx = 2.0 * sh * ch, 2.0 * sh * sh  # sin dx, 1 - cos dx
    ds = c_e * sx - s_e * vx
    dc = -s_e * sx - c_e * vx
    sq, w, chc, fwd = _energy_terms(sth, cth, chd, inv)
    dsq = (A * (cth + c_e) * dc + B * (sth + s_e - 2.0 * c) * ds) / (sq + sq_e)
    dw = -w * dsq / sq_e
    # chidot cos = (B w (sin - c) - J) / (A cos): the numerator's difference, then the ratio's
    dchc = (B * (dw * (sth - c) + w_e * ds) / A - chc_e * dc) / cth
    dfwd = dw * cth + w_e * dc + dchc * (sth - c) + chc_e * ds
    du = 0.5 * (A * dchc * (chc + chc_e) + B * dw * (w + w_e) + dfwd * (fwd + fwd_e)) - c * ds
    return -2.0 * du / (A + 1.0 - 2.0 * c * sth + c * c)


@jit
def _diff_reach(spread, f_noise, a, h):
    """How far from an end (rad) its points take F from `_F_about`: where F's rounding, about
    2 eps E / (a x) of it at a distance x (f_noise / ROOT_NOISE * 2 / (a x)), is over
    END_DIFF_RTOL, and within h (spread / END_DIFF_TOL)^2 of the end (spread: the end's
    uncertainty over h), beyond which the points' errors sum to about END_DIFF_TOL / 5 of an
    integral; at most the half-range h (the half nearer the end)."""
    return min(h, f_noise / ROOT_NOISE * 2.0 / (END_DIFF_RTOL * a),
               h * (spread / END_DIFF_TOL) ** 2)


@jit_inline
def _set_about(node, p, dx, end, inv):
    """Level point p's F, thetadot and dt/ds (node's work rows) from `_F_about` the end."""
    f = _F_about(node[_WS, p], node[_WC, p], node[_WCHD, p], dx, end, inv)
    thd = math.sqrt(f)
    node[_WF, p], node[_WTHD, p], node[_WTAU, p] = f, thd, node[_WH, p] / thd


@jit
def _root_about(t, e, end, h, inv):
    """The turning point near t solved again by Newton's method on F about the other end e
    (`_F_about`; `end`: its terms); NaN where it moves by more than a hundredth of the
    half-range h (F's rounding leaves it uncertain by at most END_SPREAD_LIMIT of h)."""
    x = t
    for _ in range(8):
        sth, cth, chd, phd, _ = _rates(x, inv)
        g = _F_about(sth, cth, chd, x - e, end, inv)
        thdd = accelerations(sth, cth, math.sqrt(max(g, 0.0)), chd, phd, inv[2], inv[3],
                             inv[4])[0]
        if thdd == 0.0:
            break
        dx = 0.5 * g / thdd  # F' = 2 thetaddot
        x -= dx
        if not abs(x - t) <= 0.01 * h:
            return math.nan
        if abs(dx) <= 1e-16 * abs(x):
            break
    return x


@jit_inline
def _set_ends(scr, end_lo, end_hi, h):
    """scr's columns of the ends (0 and MAX_N) from their terms (`_end_at`): dt/ds's limit
    sqrt(h / |thetaddot|), the rates, sin and cos."""
    for k in (0, MAX_N):
        sth, cth, chd, phd, thdd = end_lo if k == 0 else end_hi
        tau = math.sqrt(h / abs(thdd))
        scr[_TAU, k], scr[_CHD, k], scr[_PHD, k] = tau, chd, phd
        scr[_THD, k], scr[_STH, k], scr[_CTH, k] = 0.0, sth, cth
        scr[_TAUP, k] = tau


@jit_inline
def _level_sums(weights, L, n, stride, scr, tau_row):
    """(half period, half turn) of level L (n intervals, every stride-th point of the finest)
    from dt/ds in scr's row tau_row and chidot in row _CHD."""
    per, turn = 0.0, 0.0
    r = uintp(tau_row)
    for j in range(uintp(n + 1)):
        k = j * uintp(stride)
        wt = weights[L, k] * scr[r, k]
        per += wt
        turn += wt * scr[_CHD, k]
    return per, turn


@jit
def _lanes(count):
    """count rounded up to whole vectors of LANES doubles (unsigned): a loop of SIMD lanes
    that runs over them has no scalar remainder. The level stage's 15 points at N = 16 took 8
    in lanes and 7 one at a time, which cost more than the 8."""
    return uintp((count + LANES - 1) // LANES * LANES)


@jit
def _agree(per, turn, per0, turn0, turn_tol):
    """Two levels' period and turn agree to QUAD_RTOL and turn_tol."""
    return (abs(per - per0) <= QUAD_RTOL * per
            and abs(turn - turn0) <= turn_tol * max(1.0, abs(turn)))


@jit_inline
def _extremum(node, f, n, sign):
    """Row f of node: its extremum over points 0..n (sign +1: largest, -1: least), refined on
    the parabola through the best point and its two neighbours (their s in row _SS); at an end
    point its value there (f is even about the ends). Unsigned indices (`_cumulate`)."""
    fr, un, one = uintp(f), uintp(n), uintp(1)
    j = uintp(0)
    best = sign * node[fr, 0]
    for k in range(one, un + one):
        if sign * node[fr, k] > best:
            best, j = sign * node[fr, k], k
    fj = node[fr, j]
    if j == 0 or j == un:
        return fj
    x0, x1, x2 = node[_SS, j - one], node[_SS, j], node[_SS, j + one]
    d01 = (fj - node[fr, j - one]) / (x1 - x0)
    d12 = (node[fr, j + one] - fj) / (x2 - x1)
    a = (d12 - d01) / (x2 - x0)
    if sign * a >= 0.0:
        return fj
    xs = 0.5 * (x0 + x1) - d01 / (2.0 * a)
    if not (x0 <= xs <= x2):
        return fj
    v = node[fr, j - one] + d01 * (xs - x0) + a * (xs - x0) * (xs - x1)
    return max(fj, v) if sign > 0 else min(fj, v)


@jit_inline
def _cumulate(qm, off, n, node, f, out):
    """Row out of node: at each point j, the integral of row f from the first point to point j
    (the level's matrix, stored by columns, at qm[off:]). Each sum runs in the order of k, as a
    row-by-row product would, but the inner loop runs over j: independent sums, which
    vectorise. The indices are unsigned (`uintp`): numba adds no negative-index wraparound to
    them, which would keep the loop from vectorising."""
    m, o, fr = uintp(n + 1), uintp(out), uintp(f)
    for j in range(m):
        node[o, j] = 0.0
    for k in range(m):
        fk = node[fr, k]
        col = uintp(off) + k * m
        for j in range(m):
            node[o, j] += qm[col + j] * fk


@jit_inline
def _cumulate_pair(qm, off, n, node, f1, out1, f2, out2):
    """`_cumulate` of rows f1 and f2 into out1 and out2 in one pass over the matrix: each
    column is loaded once for both (the same sums, in the same order)."""
    m, o1, o2, r1, r2 = uintp(n + 1), uintp(out1), uintp(out2), uintp(f1), uintp(f2)
    for j in range(m):
        node[o1, j] = 0.0
        node[o2, j] = 0.0
    for k in range(m):
        g1, g2 = node[r1, k], node[r2, k]
        col = uintp(off) + k * m
        for j in range(m):
            q = qm[col + j]
            node[o1, j] += q * g1
            node[o2, j] += q * g2


@jit_inline
def cycle_one(th0, thd0, chd0, phd0, c, A, B, T, stop_after, steady_tol, s_all, sin_s, cos_s,
              weights, qm, offsets, scr, node, obs, i):
    """Launch i (non-dimensional tilt, rates) -> its observer slots obs[:, i]; returns a status.
    scr (N_SCRATCH, ROW) and node (N_NODE, ROW): scratch."""
    s0, c0 = math.sin(th0), math.cos(th0)
    # the energy less its constant M g a: F is a small difference near the turning points
    kin = kinetic(s0, c0, thd0, chd0, phd0, c, A, B)
    E = kin - c * s0
    scale = kin + c * abs(s0)  # the size of the terms F is a difference of
    J = jellett(s0, c0, thd0, chd0, phd0, c, A, B)
    R = routh(s0, c0, thd0, chd0, phd0, c, A, B)
    thdd0 = accelerations(s0, c0, thd0, chd0, phd0, c, A, B)[0]
    if abs(thd0) < steady_tol and abs(thdd0) < steady_tol:
        return STEADY
    f_noise = ROOT_NOISE * 2.2e-16 * scale
    inv = _constants(E, J, R, c, A, B)
    # --- turning points ----------------------------------------------------------------------
    if thd0 == 0.0:
        d = 1.0 if thdd0 > 0.0 else -1.0
        start = th0 + d * START_OFFSET
        # F there is about its slope 2 |thdd0| times START_OFFSET: positive beyond doubt where
        # that is START_MARGIN times F's rounding, else checked
        if (2.0 * abs(thdd0) * START_OFFSET <= START_MARGIN * f_noise
                and not _F(start, inv) > 0.0):
            return UNCONVERGED
        # F vanishes at th0 with slope 2 thdd0: q = F cos^2 / |theta - th0| starts at
        # 2 |thdd0| cos^2 th0
        other, end_other = _turning_point(start, d, th0, 2.0 * abs(thdd0) * c0 * c0, f_noise,
                                          inv)
        if not math.isfinite(other):
            return VERTICAL
        end_th0 = _end_of(s0, c0, inv)  # the launch's end, from its own sine and cosine
        lo, hi = (th0, other) if d > 0.0 else (other, th0)
        tp_lo, tp_hi = (end_th0, end_other) if d > 0.0 else (end_other, end_th0)
    else:
        f0 = _F(th0, inv)
        if not f0 > 0.0:
            return UNCONVERGED
        lo, tp_lo = _turning_point(th0, -1.0, math.nan, f0 * c0 * c0, f_noise, inv)
        hi, tp_hi = _turning_point(th0, 1.0, math.nan, f0 * c0 * c0, f_noise, inv)
        if not (math.isfinite(lo) and math.isfinite(hi)):
            return VERTICAL
    m, h = 0.5 * (hi + lo), 0.5 * (hi - lo)
    if not h > 0.0:
        return UNCONVERGED
    s_m, c_m = math.sin(m), math.cos(m)  # theta = m + h sin s: `sincos_shift`
    turn_tol = TURN_TOL if 0.5 * math.pi - max(-lo, hi) > VERTICAL_CLOSE else TURN_TOL_CLOSE
    # --- nested Clenshaw-Curtis levels until period and turn converge --------------------------
    per_prev, turn_prev = math.nan, math.nan
    per_pp, turn_pp = math.nan, math.nan  # the last level's sums with F as computed (`gated`)
    level = -1
    for L in range(LEVELS):
        n = FIRST_N << L
        stride = MAX_N // n
        if L == 0:  # the ends: the turning points, where dt/ds is its limit
            _set_ends(scr, tp_lo, tp_hi, h)
            # how far F's rounding leaves each turning point, f_noise / |F'| (|F'| = 2
            # |thetaddot| = 2 h / tau^2 there), against the half-range h: past
            # `END_SPREAD_LIMIT` the integrator's; F from its difference about that end at the
            # points near enough for its rounding to matter (`_F_about`, `_diff_reach`)
            a_lo = 2.0 * h / (scr[_TAU, 0] * scr[_TAU, 0])
            a_hi = 2.0 * h / (scr[_TAU, MAX_N] * scr[_TAU, MAX_N])
            spread_lo, spread_hi = f_noise / (a_lo * h), f_noise / (a_hi * h)
            if not max(spread_lo, spread_hi) <= END_SPREAD_LIMIT:
                return UNCONVERGED
            reach_lo = _diff_reach(spread_lo, f_noise, a_lo, h)
            reach_hi = _diff_reach(spread_hi, f_noise, a_hi, h)
            covered = reach_lo >= h and reach_hi >= h  # F about the ends meets in the middle
            # past END_SPREAD_PLAIN, only a swing that F about the ends covers (both ends slow)
            # and that keeps SMALL_SWING_TILT from the vertical
            if (not max(spread_lo, spread_hi) <= END_SPREAD_PLAIN
                    and not (covered and max(-lo, hi) <= SMALL_SWING_TILT)):
                return UNCONVERGED
            # an end's terms (`_end_terms`) are computed when a point first comes within its
            # reach (at the finer levels only, for most ends)
            end_lo = end_hi = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
            have_lo = have_hi = False
            if covered:
                # the ends' differences meet in the middle (a small swing): each takes the
                # energy at its own end, and the two ends, roots of F as computed, differ in it
                # by F's rounding, a jump in the integrands there of up to END_SPREAD_LIMIT of
                # them. So one end is solved again as the root of F about the other (the launch,
                # where it is an end: its energy is the launch's)
                if thd0 == 0.0 and th0 == hi:
                    lo = _root_about(lo, hi, _end_terms(hi, inv), h, inv)
                else:
                    hi = _root_about(hi, lo, _end_terms(lo, inv), h, inv)
                m, h = 0.5 * (hi + lo), 0.5 * (hi - lo)
                if not h > 0.0:
                    return UNCONVERGED
                s_m, c_m = math.sin(m), math.cos(m)
                reach_lo = reach_hi = h
                _set_ends(scr, _end_at(lo, inv), _end_at(hi, inv), h)
            # within GATE_TILT of the vertical `_F_about` loses digits (its chidot cos term is a
            # difference over cos theta): a level is taken there only when the sums with F as
            # computed converge too
            # (the finest level's nearest point to an end: theta - lo = h (1 + sin s), below)
            nearest = h * cos_s[1] * cos_s[1] / (1.0 - sin_s[1])
            gated = max(reach_lo, reach_hi) >= nearest and max(-lo, hi) > GATE_TILT
            first, step, count = stride, stride, n - 1
        else:  # the points between the last level's
            first, step, count = stride, 2 * stride, n // 2
        # the new interior points' rates, in a loop free of calls (SIMD lanes; sines and
        # cosines by `trig`), in node's rows; F must be positive at each. (Indices unsigned
        # here and below, `uintp`: numba adds no negative-index wraparound to them, which would
        # turn the loops' loads into gathers or keep them from vectorising.)
        # The loop runs over whole vectors (`_lanes`): the lanes past the last point repeat it
        first, step, last = uintp(first), uintp(step), uintp(count - 1)
        for p in range(_lanes(count)):  # gathered first: strided loads keep a loop scalar
            k = first + min(p, last) * step
            node[_WS, p] = h * sin_s[k]
            node[_WH, p] = h * cos_s[k]
        for p in range(_lanes(count)):
            sth, cth = sincos_shift(s_m, c_m, node[_WS, p])
            node[_WS, p], node[_WC, p] = sth, cth
            chd, phd, f = _rates_at(sth, cth, inv)
            thd = math.sqrt(f)
            node[_WCHD, p], node[_WPHD, p], node[_WF, p] = chd, phd, f
            node[_WTHD, p], node[_WTAU, p] = thd, node[_WH, p] / thd
        if gated:  # dt/ds from F as computed, kept for the gate's sums
            for p in range(uintp(count)):
                scr[_TAUP, first + p * step] = node[_WTAU, p]
        # F about a slow end (`_F_about`) at the points within its reach: the first points
        # (s rising) from lo, the last from hi
        for p in range(uintp(count)):
            k = first + p * step
            # theta - lo = h (1 + sin s) = h cos^2 s / (1 - sin s): no cancellation
            x = h * cos_s[k] * cos_s[k] / (1.0 - sin_s[k])
            if not x <= reach_lo:
                break
            if not have_lo:
                end_lo, have_lo = _end_terms(lo, inv), True
            _set_about(node, p, x, end_lo, inv)
        for q in range(uintp(count)):
            p = uintp(count) - uintp(1) - q
            k = first + p * step
            x = h * cos_s[k] * cos_s[k] / (1.0 + sin_s[k])
            if not x <= reach_hi:
                break
            if not have_hi:
                end_hi, have_hi = _end_terms(hi, inv), True
            _set_about(node, p, -x, end_hi, inv)
        for p in range(uintp(count)):
            if not node[_WF, p] > 0.0:
                return UNCONVERGED
            k = first + p * step
            scr[_TAU, k], scr[_CHD, k] = node[_WTAU, p], node[_WCHD, p]
            scr[_PHD, k], scr[_THD, k] = node[_WPHD, p], node[_WTHD, p]
            scr[_STH, k], scr[_CTH, k] = node[_WS, p], node[_WC, p]
        per, turn = _level_sums(weights, L, n, stride, scr, _TAU)
        per_p, turn_p = per, turn
        if gated:
            per_p, turn_p = _level_sums(weights, L, n, stride, scr, _TAUP)
        if (L > 0 and _agree(per, turn, per_prev, turn_prev, turn_tol)
                and (not gated or _agree(per_p, turn_p, per_pp, turn_pp, turn_tol))):
            level = L
            break
        per_prev, turn_prev = per, turn
        per_pp, turn_pp = per_p, turn_p
    if level < 0 or not (math.isfinite(per) and math.isfinite(turn)):
        return UNCONVERGED
    # --- the path at the level before (its period and turn agree with this one's to
    # QUAD_RTOL): every point's rates, then the cumulative integrals -------------------------
    per_fine, turn_fine = per, turn
    level -= 1
    n = FIRST_N << level
    stride = MAX_N // n
    un, ustride = uintp(n), uintp(stride)
    # the level's points, gathered into rows for a loop free of calls, over whole vectors (the
    # lanes past the last point repeat it: `_lanes`)
    for j in range(_lanes(n + 1)):
        k = min(j, un) * ustride
        node[_SS, j], node[_TAU_C, j], node[_W_TAU, j] = s_all[k], scr[_TAU, k], cos_s[k]
        node[_IN_CHD, j], node[_IN_PHD, j], node[_IN_THD, j] = scr[_CHD, k], scr[_PHD, k], \
            scr[_THD, k]
        node[_IN_STH, j], node[_IN_CTH, j] = scr[_STH, k], scr[_CTH, k]
    for j in range(_lanes(n + 1)):  # SIMD lanes
        tau, chd, phd = node[_TAU_C, j], node[_IN_CHD, j], node[_IN_PHD, j]
        thd, sth, cth = node[_IN_THD, j], node[_IN_STH, j], node[_IN_CTH, j]
        thdd, chdd, phdd = accelerations(sth, cth, thd, chd, phd, c, A, B)
        u, w = heading_velocity(sth, cth, thd, chd, phd, c)
        v2 = u * u + w * w
        a1 = 1.0 - c * sth
        ud = (phdd - c * chdd) * cth - (phd - c * chd) * sth * thd
        wd = -c * cth * thd * thd + a1 * thdd
        psid = chd + (u * wd - w * ud) / v2 if v2 > 0.0 else chd
        ah_par, ah_perp = ud - w * chd, wd + u * chd
        normal = normal_force(sth, cth, thd, thdd, c)
        fric = (math.sqrt(ah_par * ah_par + ah_perp * ah_perp) / normal if normal > 0.0
                else math.inf)
        node[_CHD_TAU, j] = chd * tau
        node[_U, j] = u
        node[_W_TAU, j] = a1 * h * node[_W_TAU, j]  # w dt/ds = a' dtheta/ds on the rising half
        node[_W, j] = w
        node[_PSID, j] = abs(psid)
        node[_SPEED, j] = math.sqrt(v2)
        node[_FRIC, j] = fric
        node[_NORM, j] = normal
    off = offsets[level]
    _cumulate(qm, off, n, node, _CHD_TAU, _CHI)
    for j in range(un + 1):
        sc, cc = sincos(node[_CHI, j])
        node[_FX, j] = node[_U, j] * cc * node[_TAU_C, j] - node[_W_TAU, j] * sc
        node[_FY, j] = node[_U, j] * sc * node[_TAU_C, j] + node[_W_TAU, j] * cc
    _cumulate_pair(qm, off, n, node, _FX, _X, _FY, _Y)
    period, dchi = 2.0 * per_fine, 2.0 * turn_fine
    v_int = 0.0
    for j in range(un + 1):
        v_int += weights[level, j * ustride] * node[_TAU_C, j] * node[_SPEED, j]
    # the path heading's total absolute change over the half cycle: its variation over the
    # points, psi = chi + the velocity's direction in the heading frame (exact where psi is
    # monotone between points; a quadrature of |psidot| would miss the spikes at a cusp)
    for j in range(un + 1):  # psi at each point (rows _FX, _FY are free until the radii)
        node[_FX, j] = node[_CHI, j] + atan2(node[_W, j], node[_U, j])
    for j in range(uintp(1), un + 1):  # |its change| from each point to the next, in lanes
        dpsi = node[_FX, j] - node[_FX, j - uintp(1)]
        node[_FY, j] = abs(dpsi - 2.0 * math.pi * math.floor((dpsi + math.pi) / (2.0 * math.pi)))
    t_turn = 0.0
    for j in range(uintp(1), un + 1):
        t_turn += node[_FY, j]
    # --- the orbit: G at theta_max, the next minimum (the mirror of the first), the centre -----
    xm, ym = node[_X, n], node[_Y, n]
    ex, ey = math.cos(node[_CHI, n]), math.sin(node[_CHI, n])
    along = xm * ex + ym * ey
    bx, by = 2.0 * along * ex, 2.0 * along * ey  # G at the next minimum (G at the first: 0)
    cd, sd = math.cos(dchi), math.sin(dchi)
    det = 2.0 * (1.0 - cd)
    if det > 0.0:
        rcx = ((1.0 - cd) * bx - sd * by) / det
        rcy = (sd * bx + (1.0 - cd) * by) / det
    else:
        rcx = rcy = math.nan
    for j in range(un + 1):
        node[_FX, j] = math.sqrt((node[_X, j] - rcx) ** 2 + (node[_Y, j] - rcy) ** 2)
    # --- theta maxima within T (period mode: at most stop_after) -----------------------------
    if thd0 == 0.0:
        t1 = period if th0 == hi else 0.5 * period
    else:
        # time from theta_min up to the launch: the cumulative time interpolated at the
        # launch's s (barycentric, Chebyshev-Lobatto)
        _cumulate(qm, off, n, node, _TAU_C, _FY)
        s_l = math.asin(max(-1.0, min(1.0, (th0 - m) / h)))
        num = den = 0.0
        t_l = math.nan
        for j in range(n + 1):
            dx = s_l - node[_SS, j]
            wb = (-1.0 if j % 2 else 1.0) * (0.5 if j == 0 or j == n else 1.0)
            if dx == 0.0:
                t_l = node[_FY, j]
                break
            num += wb / dx * node[_FY, j]
            den += wb / dx
        if not math.isfinite(t_l):
            t_l = num / den
        t1 = 0.5 * period - t_l if thd0 > 0.0 else t_l + 0.5 * period
    n_max = 0.0
    if t1 <= T:
        n_max = math.floor((T - t1) / period) + 1.0
    if stop_after > 0:
        n_max = min(n_max, float(stop_after))
    n_cyc = max(n_max - 1.0, 0.0)
    # --- the observer's slots -----------------------------------------------------------------
    # (the slots not written here hold NaN from the caller: `_block`, `cuda.per_launch`)
    obs[ob.O_TH_MIN, i], obs[ob.O_TH_MAX, i] = lo, hi
    obs[ob.O_E0, i], obs[ob.O_J0, i], obs[ob.O_R0, i] = E + 1.0, J, R
    obs[ob.O_DE, i] = obs[ob.O_DJ, i] = obs[ob.O_DR, i] = 0.0
    # the extrema over the points, in one loop: one copy of `_extremum`'s code (its six copies,
    # inlined, took 3 s of the kernel's 13 s compilation). Radii are in row _FX (still)
    for q in range(6):
        obs[_EXT_SLOTS[q], i] = _extremum(node, _EXT_ROWS[q], n, _EXT_SIGNS[q])
    obs[ob.O_NMAX, i] = n_max
    obs[ob.O_T1, i], obs[ob.O_CHI1, i] = t1, 0.0
    obs[ob.O_TL, i] = t1 + n_cyc * period
    obs[ob.O_CHIL, i] = n_cyc * dchi
    # G at two successive maxima: at theta_max, and its image by the cycle's rotation
    obs[ob.O_XP, i], obs[ob.O_YP, i] = xm, ym
    obs[ob.O_XL, i] = rcx + cd * (xm - rcx) - sd * (ym - rcy)
    obs[ob.O_YL, i] = rcy + sd * (xm - rcx) + cd * (ym - rcy)
    obs[ob.O_C_TURN, i] = 2.0 * t_turn
    obs[ob.O_C_VMEAN, i] = 2.0 * v_int / period
    # the velocity's winding relative to the heading: it stays in the half-plane of thetadot's
    # sign over each half cycle, so the forward speeds at the turning points decide it
    u_lo, u_hi = node[_U, 0], node[_U, n]
    wind = -1.0 if u_lo < 0.0 < u_hi else (1.0 if u_hi < 0.0 < u_lo else 0.0)
    obs[ob.O_C_WIND, i] = wind
    obs[ob.O_C_DUR, i] = period
    obs[ob.O_C_RAW, i] = dchi + 2.0 * math.pi * wind
    wrapped = dchi - 2.0 * math.pi * math.floor((dchi + math.pi) / (2.0 * math.pi))
    obs[ob.O_CR_N, i] = max(n_max - 2.0, 0.0)
    obs[ob.O_CR_SUM, i] = obs[ob.O_CR_N, i] * wrapped
    obs[ob.O_HD_N, i] = n_cyc
    obs[ob.O_HD_SUM, i] = n_cyc * wrapped
    obs[ob.O_RC_X, i], obs[ob.O_RC_Y, i] = rcx, rcy
    obs[ob.O_C_SIDE, i] = 2.0 * abs(along)
    obs[ob.O_NMIN_EV, i] = n_max
    obs[ob.O_THD0, i], obs[ob.O_THDD0, i] = abs(thd0), abs(thdd0)
    # points a cycle: the level's, both halves; theta's largest step between them to match
    obs[ob.O_C_NSAMP, i] = 2.0 * n
    obs[ob.O_TH_STEP, i] = math.pi * (hi - lo) / (2.0 * n)
    return DONE


#: launches whose slots `_block` gathers in its own buffer before copying them out, row by row:
#: one cache line a slot (a buffer of 64 launches, 37 kB beside the scratch rows, made the kernel
#: 6 % slower)
SLOT_BLOCK = 8


@jit
def _block(y0, params, T, stop_after, steady_tol, tabs_s_a, sin_s_a, cos_s_a, weights_a, qm_a,
           offsets_a, lo, hi, obs, status):
    """Launches lo..hi into obs[:, lo:hi] and status[lo:hi]. Each launch's slots are a column of
    obs, whose rows lie the call's number of launches apart: at a power of two (a call of 8192
    launches) the column's N_OBS cache lines all fall in one set of the caches, which holds a
    dozen, and writing them cost the kernel half its time again (2.66 against 1.60 us a
    launch). So a launch writes its slots into a buffer of SLOT_BLOCK launches (a cache line a
    row), copied into obs row by row once the launches are done. The slots `cycle_one` leaves
    unwritten stay NaN from the buffer's start; a launch not done has all its slots set to
    NaN. The arrays go to `cycle_one` as views that own nothing (`borrow`): each array passed to
    a function inlined in numba's IR costs a reference-count update (an atomic add and a call)
    at each inlined call, 6 % of the kernel's time."""
    scr_a = np.empty((N_SCRATCH, ROW))
    node_a = np.empty((N_NODE, ROW))
    buf_a = np.full((ob.N_OBS, SLOT_BLOCK), math.nan)  # slots no launch writes stay NaN
    scr, node, buf = borrow(scr_a), borrow(node_a), borrow(buf_a)
    tabs_s, sin_s, cos_s = borrow(tabs_s_a), borrow(sin_s_a), borrow(cos_s_a)
    weights, qm, offsets = borrow(weights_a), borrow(qm_a), borrow(offsets_a)
    for b0 in range(lo, hi, SLOT_BLOCK):
        b1 = min(hi, b0 + SLOT_BLOCK)
        for i in range(b0, b1):
            k = i - b0
            st = cycle_one(y0[2, i], y0[5, i], y0[6, i], y0[7, i], params[0, i], params[1, i],
                           params[2, i], T, stop_after, steady_tol, tabs_s, sin_s, cos_s,
                           weights, qm, offsets, scr, node, buf, k)
            status[i] = st
            if st != DONE:  # obs comes uninitialised (`cycles_by_quadrature`)
                for q in range(ob.N_OBS):
                    buf[q, k] = math.nan
        # unsigned indices (`_cumulate`): with signed ones numba's negative-index wraparound
        # makes each row's copy a scatter, 3 % of the kernel's time
        ub0, m = uintp(b0), uintp(b1 - b0)
        for q in range(ob.N_OBS):
            for k in range(m):
                obs[q, ub0 + k] = buf[q, k]
    alive((scr_a, node_a, buf_a, tabs_s_a, sin_s_a, cos_s_a, weights_a, qm_a, offsets_a))


@njit(parallel=True, nogil=True, error_model="numpy", cache=True)
def _run_parallel(y0, params, T, stop_after, steady_tol, s, sin_s, cos_s, weights, qm, offsets,
                  block, threads, obs, status):
    """Blocks of `block` successive launches shared out among `threads` threads (numba's number,
    passed in: read here it would keep the function from numba's cache) as they come free
    (an atomic counter): numba's prange would give each thread an equal, fixed share, and a
    sweep's part writer, running beside the kernel, slows one of them while the other waits
    (the headline sweep: 1.40-1.51 s so, 1.35-1.40 s shared out). Which thread does a block
    never changes its launches' results."""
    n = y0.shape[1]
    nblocks = (n + block - 1) // block
    counter = np.zeros(1, dtype=np.int64)
    for _ in nb.prange(threads):
        while True:
            bi = fetch_add(counter, 1)
            if bi >= nblocks:
                break
            lo = bi * block
            _block(y0, params, T, stop_after, steady_tol, s, sin_s, cos_s, weights, qm, offsets,
                   lo, min(n, lo + block), obs, status)


def cycles_by_quadrature(y0, params, T, *, stop_after=0, steady_tol=1e-8, block=64,
                         parallel=True):
    """Fast-state launches y0 (N_FAST, n), params (3, n), non-dimensional T -> (obs (N_OBS, n),
    status (n,) int8). stop_after > 0 (period mode): at most that many theta maxima are
    counted. A launch whose status is not DONE has NaN slots: integrate it."""
    y0 = np.ascontiguousarray(y0, dtype=np.float64)
    params = np.ascontiguousarray(params, dtype=np.float64)
    n = y0.shape[1]
    obs = np.empty((ob.N_OBS, n))  # every slot of every launch is written (`_block`)
    status = np.zeros(n, dtype=np.int8)
    if n:
        tabs = tables()
        if parallel:
            _run_parallel(y0, params, float(T), int(stop_after), float(steady_tol), *tabs,
                          max(1, int(block)), nb.get_num_threads(), obs, status)
        else:  # the block kernel itself, GIL released: no serial driver to compile
            _block(y0, params, float(T), int(stop_after), float(steady_tol), *tabs, 0, n, obs,
                   status)
    return obs, status

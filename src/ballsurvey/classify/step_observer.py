"""Step observer: the observer's record from each accepted step of an adaptive integration.

The sampling observer (`observer.observe`) is fed the state at evenly spaced samples, so its cost
follows the sampling (hundreds of samples a theta cycle at the maps' 4 ms) however few steps the
integrator takes. This one is fed each accepted step of a fixed-frame integration
(`physics/fixed.py` state, with its rate at both ends: what the step's cubic Hermite
interpolant is made of), and fills the same slots, so `labels.label_fields` reads its record
unchanged. Its cost follows the steps (about fifteen a theta cycle for DOP853 at rtol 1e-9):

* theta extrema are roots of e_z' (sin theta = -e_z, chart-free), found from the sign of e_z' at
  the step's two ends and located on the quintic Hermite interpolant of e_z (values, rates e_z'
  and accelerations e_z'' at both ends); the axis, G's position and G's velocity are read from
  their quintic interpolants there, and the cycle is closed as the sampling observer closes it
  (`on_maximum`, `on_minimum`). A step with an extremum is split there, so each cycle's sums end
  at the event;
* per piece of a step (the whole step, or its parts either side of an extremum) G's velocity and
  acceleration at POINTS evenly spaced points after the piece's start come from the cubic
  Hermite interpolant of G's velocity (values x', y', slopes a_G at both ends), G's position
  from that of x, y:
  - the distance rolled: Simpson's 3/8 rule on the speed (the interpolant's error, not the
    rule's, bounds it);
  - the heading's turn: Simpson's 3/8 rule on the heading rate and on its absolute value, while
    the speed stays within a factor of two over the piece's points and the velocity turns by
    less than a quarter turn between them; elsewhere (a loop, or a cusp where the speed passes
    near zero) the piece is cut into SUBPIECES and the angles between successive velocities
    summed. A velocity reversing between two sub-points (over CUSP_FLIP) passed through, or next
    to, zero speed: its half turn counts in the signed turn but not in the absolute one;
  - the peak heading rate and the least speed over the piece's points (and its sub-points where
    it was cut);
  - the distance from the orbit centre at each point (its least and largest values:
    roundness);
* at each step's end: the invariants' drift, the friction demand |F_h|/N and N/(M g) (exact
  there: the state's rate is the right-hand side); inside the step, from the quintic
  interpolants of e_z, x and y (whose second derivatives are cubics), N/(M g) = 1 + c e_z'' at
  its least (a dip towards lift-off can be narrower than a step) and |F_h|/N = |a_G|/N there
  and at each point of the pieces (its peaks fall between step ends); and the change of sin theta
  (theta's largest change between points, from below: the observer's aliasing guard); theta
  itself at the launch, at its extrema and at the run's last step, beyond which it cannot reach.

Points: each piece counts POINTS towards `samples_per_cycle`. The heading chi at a theta maximum
is kept within half a turn of the last maximum's (then set to agree with the path's heading, as
the sampling observer does): chi's whole turns between maxima are not counted, and the labels of
a fixed-frame run do not read them (they take the net turn from the path's heading).
All non-dimensional; used by the observed lane kernel (`integrate/lanes.py`).
"""
from __future__ import annotations

import math

from .._jit import njit
from ..physics.fixed import EX, EY, EZ, FX, FY, WX, WY, WZ, centre_acceleration, invariants
from . import observer as ob

jit = njit(cache=True, nogil=True, error_model="numpy")  # stamped cache: _jit.py

#: points of each piece of a step (the whole step, or its parts either side of a theta extremum)
#: where the path is looked at, after the piece's start
POINTS = 3
#: sub-pieces a piece is cut into where the path may turn fast (a loop, a cusp)
SUBPIECES = 8
#: a theta extremum is located to this fraction of its step (Illinois iterations, at most
#: LOCATE_MAX)
LOCATE_TOL = 1e-13
LOCATE_MAX = 60
#: the velocity turning by more than this (a quarter turn) between two sub-points reverses
#: through, or next to, zero speed: a cusp, whose flip of the heading is left out of the absolute
#: turn (a ball rocking along a line turns only there: the labeller's retraced line), as the
#: sampling observer leaves out a jump of two quadrants
CUSP_FLIP = 0.5 * math.pi
#: the largest rounding error (non-dimensional acceleration) let into the second derivatives of
#: the quintic interpolants, which divide the values' difference by the step squared
CUBIC_NOISE = 1e-7
EPS = 2.0 ** -52


@jit
def _kinematics(y, f, c):
    """G's velocity, acceleration, speed and heading rate, e_z'', |F_h|/N and N/(M g) at a
    state y with rate f."""
    vx, vy = f[FX], f[FY]
    ax, ay, ezdd = centre_acceleration(y, f, c)
    s2 = vx * vx + vy * vy
    psid = (vx * ay - vy * ax) / s2 if s2 > 0.0 else 0.0
    normal = 1.0 + c * ezdd
    fric = math.sqrt(ax * ax + ay * ay) / normal if normal > 0.0 else math.inf
    return ax, ay, ezdd, math.sqrt(s2), psid, fric, normal


@jit
def _tilt(y):
    """(theta, cos theta) of a fixed-frame state: sin theta = -e_z."""
    cth = math.sqrt(y[EX] * y[EX] + y[EY] * y[EY])
    return math.atan2(-y[EZ], cth), cth


#: the observer's step (`step_span`): the angle the symmetry axis or G's velocity may turn in it
STEP_ANGLE = 0.35
#: ... and at most this fraction of the theta period, once a cycle has been seen
STEP_CYCLE_FRACTION = 1.0 / 18.0
#: G's speed (units of sqrt(g a)) below which its velocity's turning rate is read against this
#: speed instead (a cusp: the velocity reverses through zero)
SPAN_SPEED_FLOOR = 1e-2
#: a step that holds a predicted theta extremum ends this far past it (its share of the step)
EXTREMUM_OVERSHOOT = 1.05
#: the least change of e_z over a span from which theta's local frequency is read, and the
#: least range of theta (rad) whose cycles pace the spans (below: rounding, a steady circle,
#: whose flips of e_z' pace nothing)
FREQUENCY_MIN_DEZ = 1e-10
CYCLE_MIN_RANGE = 1e-9
#: the tilt (rad) above which a step's end counts towards theta's extremes, and from which a
#: span tilting towards the vertical is at most half the time to reach it at its rate
TILT_WATCH = math.radians(80.0)
TILT_WATCH_SIN = math.sin(TILT_WATCH)
TILT_WATCH_COS2 = math.cos(TILT_WATCH) ** 2
#: above this tilt (60 deg) the ball's angular speed bounds a span's pace too, and a span takes
#: HIGH_TILT_SHARE of what the rates allow (measured on 2000 random launches, 6 s: the worst
#: turn per cycle against the quadrature 2.1e-4 deg without, 1.7e-5 deg with)
SPIN_WATCH_COS2 = math.cos(math.radians(60.0)) ** 2
#: below it, the ball's spin may turn by STEP_ANGLE / sqrt(SPIN_SHARE2) in a span
SPIN_SHARE2 = 0.5 ** 2
HIGH_TILT_SHARE = 0.5


@jit
def step_span(obs, i, ya, fa, yb, fb):
    """The longest observer step (non-dimensional time) for launch i after a step from the state
    ya (rate fa) to yb (rate fb): in it the symmetry axis (rate |e'|) and G's velocity
    (|a_G| / |v_G|) turn by at most STEP_ANGLE, and theta's oscillation (its local angular
    frequency, from e_z'' = -w^2 (e_z - centre) at the step's two ends) advances by at most
    STEP_ANGLE (above 60 deg of tilt the ball's angular speed too, and half of it all); a theta
    cycle, once one has been seen, is cut into at least 1 / STEP_CYCLE_FRACTION steps; a theta
    extremum predicted within reach falls near a step's end; and a launch tilting towards the
    vertical above TILT_WATCH is seen on its way. For a kernel whose own steps are short (fixed
    step), which observes every so many of them (benchmarks/step_observer_span.py measures the
    records against the sampling observer and the quadrature)."""
    # the rates squared: one square root for the three
    rate2 = fb[EX] * fb[EX] + fb[EY] * fb[EY] + fb[EZ] * fb[EZ]
    ax, ay, speed = obs[ob.O_P_AX, i], obs[ob.O_P_AY, i], obs[ob.O_P_SPEED, i]
    floor = max(speed, SPAN_SPEED_FLOOR)
    rate2 = max(rate2, (ax * ax + ay * ay) / (floor * floor))
    cth2 = yb[EX] * yb[EX] + yb[EY] * yb[EY]
    # the ball's own spin: theta's nutation under a fast spin is as fast as the spin, and a
    # near-steady launch shows it in none of the rates above; at high tilt it sets the pace (a
    # launch passing 85 deg read its theta maximum 2.5e-3 deg off without it)
    spin2 = yb[WX] * yb[WX] + yb[WY] * yb[WY] + yb[WZ] * yb[WZ]
    rate2 = max(rate2, spin2 if cth2 < SPIN_WATCH_COS2 else spin2 * SPIN_SHARE2)
    ezdd = obs[ob.O_P_EZDD, i]
    dez = yb[EZ] - ya[EZ]
    if abs(dez) > FREQUENCY_MIN_DEZ:  # below it, rounding (a steady circle): no frequency
        w2 = -(ezdd - _axis_acceleration(ya, fa)[2]) / dez
        if w2 > 0.0 and w2 < math.inf:
            obs[ob.O_SPAN_W2, i] = w2
    w2 = obs[ob.O_SPAN_W2, i]
    if w2 > rate2:  # NaN until known
        rate2 = w2
    span = STEP_ANGLE / math.sqrt(rate2) if rate2 > 0.0 else math.inf
    if cth2 < SPIN_WATCH_COS2:
        span *= HIGH_TILT_SHARE
    n_cyc = obs[ob.O_NMAX, i] - 1.0
    if n_cyc >= 1.0 and obs[ob.O_TH_MAX, i] - obs[ob.O_TH_MIN, i] > CYCLE_MIN_RANGE:
        span = min(span, STEP_CYCLE_FRACTION * (obs[ob.O_TL, i] - obs[ob.O_T1, i]) / n_cyc)
    # a theta extremum ahead (e_z' = 0, predicted from e_z' and e_z''): the step that holds it
    # should end just past it, where the interpolants' error vanishes (it grows as (u (1 - u))^3
    # inside a step), not near its middle
    ahead = -fb[EZ] / ezdd if ezdd != 0.0 else -1.0
    if 0.0 < ahead < 2.0 * span:
        span = EXTREMUM_OVERSHOOT * ahead if ahead <= span else 0.5 * ahead
    # tilting towards the vertical above TILT_WATCH: at most half the time to reach it at the
    # present rate (pi/2 - |theta| >= cos theta, |theta'| = |e_z'| / cos theta), so that the
    # observer sees the tilt a launch reaches before the Euler chart fails there
    if cth2 < TILT_WATCH_COS2 and yb[EZ] * fb[EZ] > 0.0:
        span = min(span, 0.5 * cth2 / abs(fb[EZ]))
    return span


@jit
def observe_start(obs, i, y, f, c, A, B):
    """Launch i's slots at its start: fixed-frame state y and its rate f."""
    ax, ay, ezdd, speed, psid, fric, normal = _kinematics(y, f, c)
    e, jel, rou = invariants(y, f, c, A, B)
    th, cth = _tilt(y)
    # theta's rates from sin theta = -e_z: cos theta th' = -e_z', and its derivative
    thd = -f[EZ] / cth if cth > 0.0 else math.inf
    thdd = (-ezdd + math.sin(th) * thd * thd) / cth if cth > 0.0 else math.inf
    ob.start_record(obs, i, th, e, jel, rou, fric, normal, speed, thd, thdd)
    obs[ob.O_P_AX, i], obs[ob.O_P_AY, i], obs[ob.O_P_EZDD, i] = ax, ay, ezdd
    obs[ob.O_P_SPEED, i], obs[ob.O_P_PSID, i], obs[ob.O_P_TH, i] = speed, psid, -y[EZ]


@jit
def _point(u, h, xa, ya, vxa, vya, axa, aya, xb, yb, vxb, vyb, axb, ayb):
    """G's velocity, acceleration (per unit time) and position at u in [0, 1] of a step of
    length h, from the cubic Hermite interpolants of G's velocity (slopes: the accelerations)
    and position (slopes: the velocities)."""
    u2 = u * u
    u3 = u2 * u
    h00 = 2.0 * u3 - 3.0 * u2 + 1.0
    h01 = 1.0 - h00
    h10 = u3 - 2.0 * u2 + u
    h11 = u3 - u2
    d00 = 6.0 * (u2 - u) / h
    d10 = 3.0 * u2 - 4.0 * u + 1.0
    d11 = 3.0 * u2 - 2.0 * u
    vx = h00 * vxa + h01 * vxb + h * (h10 * axa + h11 * axb)
    vy = h00 * vya + h01 * vyb + h * (h10 * aya + h11 * ayb)
    ax = d00 * (vxa - vxb) + d10 * axa + d11 * axb
    ay = d00 * (vya - vyb) + d10 * aya + d11 * ayb
    px = h00 * xa + h01 * xb + h * (h10 * vxa + h11 * vxb)
    py = h00 * ya + h01 * yb + h * (h10 * vya + h11 * vyb)
    return vx, vy, ax, ay, px, py


@jit
def _rate(vx, vy, ax, ay):
    """(speed squared, heading rate) of a velocity and acceleration."""
    s2 = vx * vx + vy * vy
    return s2, ((vx * ay - vy * ax) / s2 if s2 > 0.0 else 0.0)


@jit
def _radius(obs, i, px, py):
    """Track the least and largest distance of G from the orbit centre (NaN until it is known:
    then nothing changes)."""
    rx, ry = px - obs[ob.O_RC_X, i], py - obs[ob.O_RC_Y, i]
    r2 = rx * rx + ry * ry
    lo, hi = obs[ob.O_A_RMIN, i], obs[ob.O_A_RMAX, i]
    if r2 < lo * lo:
        obs[ob.O_A_RMIN, i] = math.sqrt(r2)
    if r2 > hi * abs(hi):  # hi is -inf at a cycle's start
        obs[ob.O_A_RMAX, i] = math.sqrt(r2)


@jit
def _quintic(u):
    """Weights of the quintic Hermite interpolant on [0, 1] at u, for (p0, p0' h, p0'' h^2, p1,
    p1' h, p1'' h^2), and of its derivative (per unit u)."""
    u2 = u * u
    u3 = u2 * u
    u4 = u3 * u
    u5 = u4 * u
    w = (1.0 - 10.0 * u3 + 15.0 * u4 - 6.0 * u5, u - 6.0 * u3 + 8.0 * u4 - 3.0 * u5,
         0.5 * u2 - 1.5 * u3 + 1.5 * u4 - 0.5 * u5, 10.0 * u3 - 15.0 * u4 + 6.0 * u5,
         -4.0 * u3 + 7.0 * u4 - 3.0 * u5, 0.5 * u3 - u4 + 0.5 * u5)
    d = (-30.0 * u2 + 60.0 * u3 - 30.0 * u4, 1.0 - 18.0 * u2 + 32.0 * u3 - 15.0 * u4,
         u - 4.5 * u2 + 6.0 * u3 - 2.5 * u4, 30.0 * u2 - 60.0 * u3 + 30.0 * u4,
         -12.0 * u2 + 28.0 * u3 - 15.0 * u4, 1.5 * u2 - 4.0 * u3 + 2.5 * u4)
    return w, d


@jit
def _combine(w, h, p0, d0, a0, p1, d1, a1):
    """A quintic Hermite combination with weights w of values, rates and accelerations."""
    return (w[0] * p0 + w[3] * p1) + h * (w[1] * d0 + w[4] * d1) + h * h * (w[2] * a0 + w[5] * a1)


@jit
def _axis_acceleration(y, f):
    """e'' = wdot x e + w x edot of a fixed-frame state y with rate f."""
    ex, ey, ez = y[EX], y[EY], y[EZ]
    wx, wy, wz = y[WX], y[WY], y[WZ]
    return ((f[WY] * ez - f[WZ] * ey) + (wy * f[EZ] - wz * f[EY]),
            (f[WZ] * ex - f[WX] * ez) + (wz * f[EX] - wx * f[EZ]),
            (f[WX] * ey - f[WY] * ex) + (wx * f[EY] - wy * f[EX]))


@jit
def _accel_cubic(h, eza, ezb, pa, pb, qa, qb):
    """(a1, a2, a3): the second derivative of a quintic Hermite interpolant (of e_z, x or y) over
    a step of length h (values eza, ezb, rates pa, pb, accelerations qa, qb at its ends), qa +
    a1 u + a2 u^2 + a3 u^3 at u in [0, 1]. Where the values' rounding, amplified by 1/h^2, could
    reach CUBIC_NOISE (a very short step: the last one, cut to end at T), the straight line
    between qa and qb."""
    if 360.0 * EPS * max(abs(eza), abs(ezb)) > CUBIC_NOISE * h * h:
        return qb - qa, 0.0, 0.0
    d = (ezb - eza) / (h * h)
    a1 = 60.0 * d - (36.0 * pa + 24.0 * pb) / h - 9.0 * qa + 3.0 * qb
    a2 = -180.0 * d + (96.0 * pa + 84.0 * pb) / h + 18.0 * qa - 12.0 * qb
    a3 = 120.0 * d - 60.0 * (pa + pb) / h - 10.0 * qa + 10.0 * qb
    return a1, a2, a3


@jit
def _least_ezdd(qa, qb, a1, a2, a3):
    """(u, e_z'') at the least of the cubic qa + a1 u + a2 u^2 + a3 u^3 over [0, 1] (qb at u = 1):
    at an end or where its derivative, a quadratic, vanishes."""
    best_u, best = 0.0, qa
    if qb < best:
        best_u, best = 1.0, qb
    # roots of a1 + 2 a2 u + 3 a3 u^2 (the stable form of the quadratic formula)
    qa_, qb_, qc_ = 3.0 * a3, 2.0 * a2, a1
    disc = qb_ * qb_ - 4.0 * qa_ * qc_
    if disc >= 0.0:
        q = -0.5 * (qb_ + math.copysign(math.sqrt(disc), qb_))
        for r in ((q / qa_ if qa_ != 0.0 else -1.0), (qc_ / q if q != 0.0 else -1.0)):
            if 0.0 < r < 1.0:
                v = qa + r * (a1 + r * (a2 + r * a3))
                if v < best:
                    best_u, best = r, v
    return best_u, best


@jit
def _friction(u, c, q, c1, c2, c3, ax, x1, x2, x3, ay, y1, y2, y3):
    """|F_h|/N = |a_G|/N at u in [0, 1] of a step, from the cubics of e_z'', a_x and a_y
    (`_accel_cubic`; q, ax, ay: their values at the step's start); inf where N <= 0."""
    normal = 1.0 + c * (q + u * (c1 + u * (c2 + u * c3)))
    gx = ax + u * (x1 + u * (x2 + u * x3))
    gy = ay + u * (y1 + u * (y2 + u * y3))
    return math.sqrt(gx * gx + gy * gy) / normal if normal > 0.0 else math.inf


@jit
def _event(obs, i, kind, t0, h, ya, fa, yb, fb, axa, aya, ezdda, axb, ayb, ezddb):
    """The theta extremum in a step whose ends' e_z' have opposite signs: located on the quintic
    Hermite interpolant of e_z (values, rates, accelerations at both ends: the root of its
    rate), with the axis, G's position and velocity read from their quintic interpolants there.
    Returns (u, theta, chi, x, y, vx, vy) at it (u in [0, 1] of the step)."""
    pa, pb = fa[EZ], fb[EZ]
    # regula falsi with the Illinois rule on e_z'(u) h, bracketed by the step's ends (e_z'(0) h
    # = pa h, e_z'(1) h = pb h): superlinear, and never leaves the bracket
    lo, hi = 0.0, 1.0
    f_lo, f_hi = pa * h, pb * h
    u = 0.5
    side = 0
    for _ in range(LOCATE_MAX):
        u_last = u
        u = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not (lo < u < hi):
            u = 0.5 * (lo + hi)
        if abs(u - u_last) <= LOCATE_TOL:
            break
        _, d = _quintic(u)
        rate = (d[0] * ya[EZ] + d[3] * yb[EZ]) + h * (d[1] * pa + d[4] * pb) + h * h * (
            d[2] * ezdda + d[5] * ezddb)
        if rate == 0.0:
            break
        if (rate < 0.0) == (f_lo < 0.0):
            lo, f_lo = u, rate
            if side == -1:
                f_hi *= 0.5
            side = -1
        else:
            hi, f_hi = u, rate
            if side == 1:
                f_lo *= 0.5
            side = 1
        if hi - lo <= LOCATE_TOL:
            break
    w, d = _quintic(u)
    exa, eya, _ = _axis_acceleration(ya, fa)
    exb, eyb, _ = _axis_acceleration(yb, fb)
    ex = _combine(w, h, ya[EX], fa[EX], exa, yb[EX], fb[EX], exb)
    ey = _combine(w, h, ya[EY], fa[EY], eya, yb[EY], fb[EY], eyb)
    ez = _combine(w, h, ya[EZ], fa[EZ], ezdda, yb[EZ], fb[EZ], ezddb)
    px = _combine(w, h, ya[FX], fa[FX], axa, yb[FX], fb[FX], axb)
    py = _combine(w, h, ya[FY], fa[FY], aya, yb[FY], fb[FY], ayb)
    vx = _combine(d, h, ya[FX], fa[FX], axa, yb[FX], fb[FX], axb) / h
    vy = _combine(d, h, ya[FY], fa[FY], aya, yb[FY], fb[FY], ayb) / h
    return (u, math.atan2(-ez, math.sqrt(ex * ex + ey * ey)), math.atan2(-ex, ey), px, py, vx,
            vy)


@jit
def observe_step(obs, i, t0, h, ya, fa, yb, fb, c, A, B, last):
    """Update launch i's slots with one accepted step from t0 to t0 + h: states ya, yb and their
    rates fa, fb at its two ends (module docstring); last: the run's last step."""
    xa, y_a, xb, y_b = ya[FX], ya[FY], yb[FX], yb[FY]
    vxa, vya, vxb, vyb = fa[FX], fa[FY], fb[FX], fb[FY]
    axa, aya, ezdda = obs[ob.O_P_AX, i], obs[ob.O_P_AY, i], obs[ob.O_P_EZDD, i]
    axb, ayb, ezddb, sb_end, psidb_end, fric, normal = _kinematics(yb, fb, c)
    # --- a theta extremum in the step: e_z' changes sign (sin theta = -e_z) -------------------
    pa, pb = fa[EZ], fb[EZ]
    kind = 0  # +1: theta maximum (e_z' from - to +), -1: minimum
    if pa < 0.0 and pb >= 0.0:
        kind = 1
    elif pa > 0.0 and pb <= 0.0:
        kind = -1
    # e_z'' and G's horizontal acceleration inside the step (N/(M g) = 1 + c e_z'', |F_h|/N =
    # |a_G|/N): the cubics of the quintic interpolants of e_z, x and y
    c1, c2, c3 = _accel_cubic(h, ya[EZ], yb[EZ], pa, pb, ezdda, ezddb)
    x1, x2, x3 = _accel_cubic(h, xa, xb, vxa, vxb, axa, axb)
    y1, y2, y3 = _accel_cubic(h, y_a, y_b, vya, vyb, aya, ayb)
    tau = 1.0
    if kind != 0:
        tau, th_ev, chi_ev, x_ev, y_ev, vx_ev, vy_ev = _event(
            obs, i, kind, t0, h, ya, fa, yb, fb, axa, aya, ezdda, axb, ayb, ezddb)
    # --- the step's pieces: [0, tau] and, after an extremum, [tau, 1] -------------------------
    u0 = 0.0
    sa, psa = obs[ob.O_P_SPEED, i], obs[ob.O_P_PSID, i]
    vax, vay = vxa, vya
    n_pieces = 2 if kind != 0 else 1
    for piece in range(n_pieces):
        u1 = tau if piece == 0 else 1.0
        dur = (u1 - u0) * h
        # POINTS evenly spaced points of the piece after its start: speed, heading rate,
        # distance from the orbit centre; the velocities kept for the heading's turn
        v_int = sa  # Simpson's 3/8 rule: weights 1, 3, 3, 1 over 8
        r_int = psa
        a_int = abs(psa)
        slow, fast = sa, sa
        peak = abs(psa)
        pvx, pvy = vax, vay
        smooth = True
        for k in range(1, POINTS + 1):
            if k == POINTS and u1 == 1.0:  # the step's end: exact
                vx, vy, px, py, s2, ps = vxb, vyb, xb, y_b, sb_end * sb_end, psidb_end
            else:
                u = u0 + (u1 - u0) * k / POINTS
                vx, vy, qax, qay, px, py = _point(u, h, xa, y_a, vxa, vya, axa, aya, xb, y_b,
                                                  vxb, vyb, axb, ayb)
                s2, ps = _rate(vx, vy, qax, qay)
                # the friction demand here (its peak can fall between steps' ends)
                fric = max(fric, _friction(u, c, ezdda, c1, c2, c3, axa, x1, x2, x3, aya, y1, y2,
                                           y3))
            sp = math.sqrt(s2)
            wt = 1.0 if k == POINTS else 3.0
            v_int += wt * sp
            r_int += wt * ps
            a_int += wt * abs(ps)
            slow = min(slow, sp)
            fast = max(fast, sp)
            peak = max(peak, abs(ps))
            smooth = smooth and pvx * vx + pvy * vy > 0.0
            pvx, pvy = vx, vy
            _radius(obs, i, px, py)
        obs[ob.O_A_VINT, i] += dur * 0.125 * v_int
        if smooth and 4.0 * slow * slow > fast * fast:
            # the speed stays within a factor of two and the heading turns by less than a
            # quarter turn between points: the heading rate is smooth over the piece (its poles,
            # where the interpolated velocity vanishes, lie far from it), and Simpson's rule
            # integrates it
            rot = dur * 0.125 * r_int
            var = dur * 0.125 * a_int
        else:  # a loop or a cusp inside: the angles between SUBPIECES + 1 velocities
            rot = 0.0
            var = 0.0
            pvx, pvy = vax, vay
            for k in range(1, SUBPIECES + 1):
                qx, qy, qax, qay, _, _ = _point(u0 + (u1 - u0) * k / SUBPIECES, h, xa, y_a, vxa,
                                                vya, axa, aya, xb, y_b, vxb, vyb, axb, ayb)
                d = math.atan2(pvx * qy - pvy * qx, pvx * qx + pvy * qy)
                rot += d
                if abs(d) <= CUSP_FLIP:  # a reversal is a cusp, not a turn
                    var += abs(d)
                pvx, pvy = qx, qy
                s2, ps = _rate(qx, qy, qax, qay)
                slow = min(slow, math.sqrt(s2))
                peak = max(peak, abs(ps))
        obs[ob.O_A_RAW, i] += rot
        obs[ob.O_A_TURN, i] += var
        obs[ob.O_A_PSID, i] = max(obs[ob.O_A_PSID, i], peak)
        obs[ob.O_A_VMIN, i] = min(obs[ob.O_A_VMIN, i], slow)
        obs[ob.O_A_NSAMP, i] += POINTS
        if piece == 0 and kind != 0:  # the extremum at tau closes a cycle or marks a corner
            if kind > 0:
                if obs[ob.O_NMAX, i] >= 1.0:  # chi on the branch of the last maximum's
                    chi_ev = obs[ob.O_CHIL, i] + ob._wrap(chi_ev - obs[ob.O_CHIL, i])
                ob.on_maximum(obs, i, t0 + tau * h, th_ev, chi_ev, x_ev, y_ev,
                              math.atan2(vy_ev, vx_ev), math.sqrt(vx_ev * vx_ev + vy_ev * vy_ev),
                              ps, sp)
            else:
                ob.on_minimum(obs, i, th_ev, x_ev, y_ev)
        u0 = u1
        sa, psa, vax, vay = sp, ps, pvx, pvy
    # --- at the step's end: invariants, forces, theta --------------------------------------------
    e, jel, rou = invariants(yb, fb, c, A, B)
    obs[ob.O_DE, i] = max(obs[ob.O_DE, i], abs(e - obs[ob.O_E0, i]))
    obs[ob.O_DJ, i] = max(obs[ob.O_DJ, i], abs(jel - obs[ob.O_J0, i]))
    obs[ob.O_DR, i] = max(obs[ob.O_DR, i], abs(rou - obs[ob.O_R0, i]))
    obs[ob.O_FRIC, i] = max(obs[ob.O_FRIC, i], fric)
    obs[ob.O_NMIN, i] = min(obs[ob.O_NMIN, i], normal)
    # the least normal force inside the step (a brief dip towards lift-off, narrower than a
    # step), on the interpolant of e_z'' (N / (M g) = 1 + c e_z''), and the friction demand there
    u_n, ezdd_n = _least_ezdd(ezdda, ezddb, c1, c2, c3)
    if 0.0 < u_n < 1.0:
        obs[ob.O_NMIN, i] = min(obs[ob.O_NMIN, i], 1.0 + c * ezdd_n)
        obs[ob.O_FRIC, i] = max(obs[ob.O_FRIC, i], _friction(u_n, c, ezdda, c1, c2, c3, axa, x1,
                                                             x2, x3, aya, y1, y2, y3))
    # theta between extrema: only the run's end can be beyond those located, or a step's end
    # above TILT_WATCH before the next extremum (a launch that fails near the vertical there: the
    # map's near-vertical fallback reads the tilt reached)
    if last or abs(yb[EZ]) > TILT_WATCH_SIN:
        th, _ = _tilt(yb)
        obs[ob.O_TH_MIN, i] = min(obs[ob.O_TH_MIN, i], th)
        obs[ob.O_TH_MAX, i] = max(obs[ob.O_TH_MAX, i], th)
    # theta's largest change between points, from sin theta's (no larger than theta's)
    obs[ob.O_TH_STEP, i] = max(obs[ob.O_TH_STEP, i], abs(yb[EZ] + obs[ob.O_P_TH, i]) / POINTS)
    obs[ob.O_P_AX, i], obs[ob.O_P_AY, i], obs[ob.O_P_EZDD, i] = axb, ayb, ezddb
    obs[ob.O_P_SPEED, i], obs[ob.O_P_PSID, i], obs[ob.O_P_TH, i] = sb_end, psidb_end, -yb[EZ]

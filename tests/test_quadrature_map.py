"""The map method `quadrature` (classify/cycle.py: each launch's classifier record from its three
conserved quantities, no time stepping), judged against references that share none of its code:
the numpy quadrature module (`ballsurvey.quadrature`: Gauss-Legendre panels, turning points by
bisection), DOP853 on the fixed-frame form at rtol 1e-13 (the lanes kernel and its step
observer), scipy's DOP853 on the fixed-frame form (a path's own roundness), and full RK4 for the
labels."""
from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest

import ballsurvey.quadrature as qmod
from ballsurvey.ball import Ball
from ballsurvey.classify import cycle
from ballsurvey.classify import observer as ob
from ballsurvey.classify.labels import LABELS, fold_deg
from ballsurvey.compose import classify, run_launches
from ballsurvey.integrate.outcome import FIXED_FRAME, QUADRATURE
from ballsurvey.physics.fast import N_FAST
from ballsurvey.units import StepPlan, fields_to_si, launch_state

BALL = Ball.paper()
TU = BALL.time_unit
P = BALL.nondim_params()

#: launches whose theta max (quadrature) lies between 89.9 and 89.995 deg, with theta min far
#: below (the regime of the best squares)
NEAR_VERTICAL = [
    (75.2368, -1.9093, -6.3962, 4.8384),  # 89.916
    (76.4287, 1.2262, 3.7759, -2.9690),  # 89.962
    (64.5561, -0.3515, 10.0448, -7.7995),  # 89.988
    (62.8909, -0.8611, -8.7889, 6.8518),  # 89.981
    (53.2928, 0.2588, 2.1678, -1.6947),  # 89.995
    (65.9130, -0.4482, 3.7000, -2.9000),  # 89.953
    (67.9958, 2.08, 12.0271, -9.2848),  # 89.955, a near-circle
]


def _box(n, seed):
    """n launches of the headline map's box, a third of them with a tilt rate."""
    rng = np.random.default_rng(seed)
    th, cd, pd = rng.uniform(-20, 60, n), rng.uniform(-12, 12, n), rng.uniform(-8, 8, n)
    td = np.where(np.arange(n) % 3 == 0, rng.uniform(-2, 2, n), 0.0)
    return np.column_stack([th, td, cd, pd])


LAUNCHES = np.concatenate([_box(40, 11), np.array(NEAR_VERTICAL)])


def _fields(method, launches=LAUNCHES, T=20.0, **kw):
    th, td, cd, pd = np.asarray(launches, dtype=float).T
    y0 = launch_state(th, td, cd, pd, TU)
    params = np.repeat(P[:, None], len(th), 1)
    res = run_launches(y0, params, StepPlan(T, kw.pop("dt", 1e-3), TU), method, **kw)
    return fields_to_si(classify(res, BALL.flat_face_theta_rad), BALL.a, TU, BALL.M)


@pytest.fixture(scope="module")
def quad():
    return _fields("quadrature", cycles=2)


@pytest.fixture(scope="module")
def dop853_tight():
    return _fields("dop853", cycles=2, rtol=1e-13, atol=1e-16)


def _module(launch):
    """The numpy module's cycle at the tighter of 1e-10 and 1e-9 agreement between panel counts
    that converges (its integrand's rounding noise stops 1e-10 near the vertical)."""
    saved = qmod.QUAD_RTOL, qmod.MAX_PANELS
    try:
        for rtol in (1e-10, 1e-9):
            qmod.QUAD_RTOL, qmod.MAX_PANELS = rtol, 1024
            r = qmod.launch_cycle(*launch, BALL)
            if r is not None:
                return r
    finally:
        qmod.QUAD_RTOL, qmod.MAX_PANELS = saved
    return None


def test_every_test_launch_is_done_by_quadrature_up_to_89_99_deg(quad):
    assert (quad["formulation"] == QUADRATURE).all()
    assert np.nanmax(quad["theta_max_deg"]) > 89.99


def test_turn_theta_range_and_period_against_the_quadrature_module(quad):
    used = 0
    for i, launch in enumerate(LAUNCHES):
        r = _module(tuple(launch))
        if r is None:
            continue
        used += 1
        assert abs(fold_deg(quad["turn_per_cycle_deg"][i] - r["turn_per_cycle_deg"])) < 1e-6, i
        assert abs(quad["theta_max_deg"][i] - r["theta_max_deg"]) < 1e-6, i
        assert abs(quad["theta_min_deg"][i] - r["theta_min_deg"]) < 1e-6, i
        assert abs(quad["theta_period_s"][i] / r["theta_period_s"] - 1) < 1e-8, i
    assert used >= 30


def test_every_field_against_the_fixed_frame_integration(quad, dop853_tight):
    d = dop853_tight
    assert (d["formulation"] == FIXED_FRAME).all()
    assert [LABELS[k] for k in quad["label"]] == [LABELS[k] for k in d["label"]]
    assert np.array_equal(quad["n_theta_cycles"], d["n_theta_cycles"])
    # to the integration's own accuracy at rtol 1e-13 (events located on its interpolants),
    # which reads the turn 1.4e-6 deg off where theta max passes 89.99 deg (the module is the
    # judge there: test above)
    below = quad["theta_max_deg"] < 89.99
    assert below.sum() >= len(LAUNCHES) - 2
    dturn = np.abs(fold_deg(quad["turn_per_cycle_deg"] - d["turn_per_cycle_deg"]))
    assert dturn[below].max() < 1e-6 and dturn.max() < 1e-5
    assert np.nanmax(np.abs(quad["theta_max_deg"] - d["theta_max_deg"])) < 1e-6
    assert np.nanmax(np.abs(quad["theta_min_deg"] - d["theta_min_deg"])) < 1e-6
    assert np.nanmax(np.abs(quad["roundness"] - d["roundness"])) < 1e-4
    for name, rtol in (("theta_period_s", 1e-8), ("side_m", 1e-6), ("chord_m", 1e-6),
                       ("closure_m", 1e-3),
                       # peaks the step observer reads at three points a step
                       ("min_normal_force_ratio", 1e-3), ("max_friction_ratio", 1e-2),
                       ("corner_sharpness", 1e-2), ("turn_monotonicity", 2e-2)):
        a, b = quad[name], d[name]
        assert np.array_equal(np.isnan(a), np.isnan(b)), name
        ok = ~np.isnan(a)
        assert np.all(np.abs(a[ok] - b[ok]) <= rtol * np.abs(b[ok]) + 1e-12), name
    assert np.array_equal(quad["loops_per_cycle"], d["loops_per_cycle"], equal_nan=True)
    assert np.array_equal(quad["corner_kind"], d["corner_kind"])


def test_roundness_of_a_near_circle_past_89_9_deg_is_the_paths_own(quad):
    from test_near_vertical import _reference_roundness

    i = len(LAUNCHES) - 1  # (67.9958, 2.08, 12.0271, -9.2848): the path's own 0.007
    ref = _reference_roundness(*NEAR_VERTICAL[-1], cycles=5)
    assert abs(quad["roundness"][i] - ref) < 1e-4, (quad["roundness"][i], ref)


def test_labels_agree_with_full_rk4(quad):
    rk4 = _fields("rk4", dt=1e-4, cycles=0)
    assert [LABELS[k] for k in quad["label"]] == [LABELS[k] for k in rk4["label"]]


def test_what_the_quadrature_cannot_do_goes_to_the_integrator():
    launches = np.array([
        (89.999, 0.0, 0.0, 0.0),  # no spin: rocks through the upright position (slowly)
        (45.0, 0.0, 0.0, 0.0),  # no spin, falls from 45 deg through the upright position
        (20.0, 0.5, 5.0, -3.0),  # an ordinary launch beside them
    ])
    th, td, cd, pd = launches.T
    y0 = launch_state(th, td, cd, pd, TU)
    params = np.repeat(P[:, None], len(th), 1)
    _, status = cycle.cycles_by_quadrature(y0, params, 4.0 / TU)
    assert [cycle.STATUSES[s] for s in status] == ["vertical", "vertical", "done"]
    q = _fields("quadrature", launches, T=4.0, cycles=2)
    d = _fields("dop853", launches, T=4.0, cycles=2)
    assert list(q["formulation"]) == [FIXED_FRAME, FIXED_FRAME, QUADRATURE]
    assert np.array_equal(q["label"], d["label"])
    assert LABELS[q["label"][1]] == "near_straight"


def test_a_steady_launch_goes_to_the_integrator():
    from ballsurvey.physics.steady import spin_for_circle

    th0, omega = 24.0, -3.23
    phd = spin_for_circle(math.radians(th0), omega * TU, *P) / TU
    launch = np.array([(th0, 0.0, omega, phd)])
    q = _fields("quadrature", launch, T=4.0, cycles=2)
    assert q["formulation"][0] == FIXED_FRAME and LABELS[q["label"][0]] == "circle"


def test_quadrature_tables_integrate_smooth_functions_to_rounding():
    """Each level's Clenshaw-Curtis weights and cumulative matrix against closed-form integrals
    over s in [-pi/2, pi/2]: cos s (antiderivative sin s + 1), e^s and a polynomial of the
    level's degree (exact for the rule)."""
    s, _, _, weights, qm, offsets = cycle.tables()
    for L in range(cycle.LEVELS):
        n = cycle.FIRST_N << L
        sl = s[:: cycle.MAX_N // n]
        w = weights[L, :: cycle.MAX_N // n]
        assert np.all(weights[L][np.arange(cycle.MAX_N + 1) % (cycle.MAX_N // n) != 0] == 0.0)
        assert abs(w @ np.cos(sl) - 2.0) < 1e-14
        assert abs(w @ np.exp(sl) - 2.0 * math.sinh(math.pi / 2)) < 1e-14
        x = 2.0 * sl / math.pi  # T_n(x) integrates exactly: int_-1^1 T_n = 2 / (1 - n^2), n even
        assert abs(w @ np.cos(n * np.arccos(np.clip(x, -1, 1))) * 2.0 / math.pi
                   - 2.0 / (1.0 - n * n)) < 1e-13
        if L == cycle.LEVELS - 1:
            assert offsets[L + 1] == offsets[L]  # the path is never taken at the finest level
            continue
        q = qm[offsets[L]:offsets[L + 1]].reshape(n + 1, n + 1).T  # stored by columns
        assert np.abs(q @ np.cos(sl) - (np.sin(sl) + 1.0)).max() < 1e-14
        assert np.abs(q @ np.exp(sl) - (np.exp(sl) - math.exp(-math.pi / 2))).max() < 1e-14


def _against_the_fixed_frame(launches, T_s, stop_after=0):
    """(status, labelled fields by quadrature, the same by the fixed-frame integration at rtol
    1e-12) of launches (theta0 deg, thetadot0, chidot0, phidot0 rad/s), the paper's ball, to
    T_s seconds (a launch not done has NaN fields by quadrature)."""
    from ballsurvey.compose import FALLBACK_H_INIT, FALLBACK_H_MAX, STEP_OBSERVER
    from ballsurvey.integrate.adaptive import integrate_adaptive

    th, td, cd, pd = np.array(launches).T
    y0 = launch_state(th, td, cd, pd, TU)
    p = np.repeat(P[:, None], len(th), 1)
    T = T_s / TU
    obs, status = cycle.cycles_by_quadrature(y0, p, T, stop_after=stop_after, parallel=False)
    ref = integrate_adaptive(y0, p, T, 1e-12, 1e-15, fixed_frame=True, observer=STEP_OBSERVER,
                             n_slots=ob.N_OBS, h_init=FALLBACK_H_INIT, h_max=FALLBACK_H_MAX / 10,
                             stop_after=stop_after, parallel=False)
    res = ref._replace(obs=obs, formulation=np.full_like(ref.formulation, QUADRATURE))
    got, want = (classify(r, BALL.flat_face_theta_rad) for r in (res, ref))
    return status, got, want


def test_small_swings_near_steady_circles_against_the_fixed_frame():
    """A swing of a fraction of a degree near a steady circle, or near the vertical: F is small
    everywhere, and as computed (a difference of terms of the energy's size) its rounding left
    the turning points uncertain against the half-range and spoilt the integrals (turn per
    cycle off by 1e-5 to 3e-3 deg). With F about the ends (`cycle._F_about`), and one end solved
    again about the other (`cycle._root_about`: else the two halves take energies that differ
    by F's rounding, 3.4e-7 deg off), each is done and within 1e-7 deg of the fixed frame at
    rtol 1e-12 in turn per cycle (2.9e-8 deg at most), as are ordinary swings; the one near the
    vertical, past `cycle.SMALL_SWING_TILT`, goes to the integrator."""
    from ballsurvey.physics.steady import spin_for_circle

    c, A, B = P
    cases = []
    for th_c in (5.0, 25.0, 45.0):
        for om in (2.0, -3.0):
            w = spin_for_circle(math.radians(th_c), om, c, A, B) / TU
            for dth, td in ((0.3, 0.0), (0.05, 0.0), (0.0, 0.05), (3.0, 0.0)):
                cases.append((th_c + dth, td, om / TU, w))
    # a 0.38 deg swing at 3 deg of tilt, its ends uncertain by 5e-11 of the half-range (F as
    # computed: 3.2e-6 deg off); near the vertical, a swing of 0.002 deg (2.9e-3 deg off)
    cases.append((2.8575846541882304, 0.0, 7.25673986722872, 4.843819979010653))
    cases.append((89.5144929820436, 0.0, 45.29307705053058, 5.774471326444537))
    cases += [(-5.0, 0.0, 4.05, -3.0), (30.0, 0.0, 3.75, -3.0), (20.0, 0.5, -6.0, 4.0)]
    status, got, want = _against_the_fixed_frame(cases, 20.0, stop_after=3)
    near = np.arange(len(cases)) == len(cases) - 4  # the 0.002 deg swing at 89.5 deg
    assert (status[~near] == cycle.DONE).all() and status[near] == cycle.UNCONVERGED
    err = np.abs(fold_deg(got["turn_per_cycle_deg"] - want["turn_per_cycle_deg"]))[~near]
    assert err.max() < 1e-7, err


def test_chidot_about_the_vertical_is_jellett_s_form(monkeypatch):
    """The kernel's heading rate, taken about the nearer vertical (`cycle._rates_at`), is
    Jellett's integral solved for chidot, (B w (sin - c) - J) / (A cos^2) with w = R / q from
    Routh's: the kernel's own code run at 50 digits (mpmath's sqrt in its `math`) against that
    form, at tilts from -89.999 to 89.999 deg and invariants of either sign, within 1e-40."""
    import types

    import mpmath as mp

    monkeypatch.setattr(cycle, "math", types.SimpleNamespace(sqrt=mp.sqrt))
    with mp.workdps(50):  # (mpmath's precision is global: restored on leaving)
        c, A, B = (mp.mpf(float(v)) for v in P)
        for th_deg in (-89.999, -60.0, -3.0, 0.0, 2.0, 45.0, 89.9, 89.999):
            th = mp.radians(th_deg)
            s, co = mp.sin(th), mp.cos(th)
            for J, R in ((mp.mpf("0.7"), mp.mpf("-1.3")), (mp.mpf("-2.1"), mp.mpf("0.4"))):
                inv = cycle._constants.py_func(mp.mpf("0.5"), J, R, c, A, B)
                got = cycle._rates_at.py_func(s, co, inv)[0]
                w = R / mp.sqrt(A * B + A * co ** 2 + B * (s - c) ** 2)
                want = (B * w * (s - c) - J) / (A * co ** 2)
                assert abs(got - want) <= mp.mpf("1e-40") * abs(want), (th_deg, got, want)


#: launches (theta0 deg, thetadot0, chidot0, phidot0 rad/s) whose tilt swings up to 89.93-89.99
#: deg, where chidot's plain Jellett form puts the turn per cycle 1.2-1.6e-6 deg off (its
#: numerator's rounding, over cos^2 theta)
VERTICAL_TURNS = [(89.05259846491997, 0.20054961664324467, -5.067874823695653, 3.3699488631539953),
                  (89.01431219417056, 0.0, -10.245402887915466, 7.196268787488464),
                  (89.25892964594948, -0.37535512055898324, -4.41952666322584, 2.5975138048048247),
                  (89.34763806854359, -0.2069228361232487, 12.307590663620879, -5.712770983735043),
                  (88.6426463525203, -0.35125906989126643, 9.144117083936603, -6.6182795483329055),
                  (89.51054477309766, 0.4909143126041172, -12.509076157689403, 4.302791150039827)]


def test_turn_per_cycle_near_the_vertical_against_the_fixed_frame():
    """Turn per cycle within 2.5e-7 deg of the fixed frame at rtol 1e-12 (itself within 1e-10
    deg of a 40-digit quadrature of the same launches, `benchmarks/quadrature_vertical.py`), and
    theta max within 1e-9 deg, on launches that swing up to 89.93-89.99 deg."""
    status, got, want = _against_the_fixed_frame(VERTICAL_TURNS, 3.0)
    assert (status == cycle.DONE).all()
    assert (got["theta_max_deg"] > 89.93).all()
    err = np.abs(fold_deg(got["turn_per_cycle_deg"] - want["turn_per_cycle_deg"]))
    assert err.max() < 2.5e-7, err
    assert np.abs(got["theta_max_deg"] - want["theta_max_deg"]).max() < 1e-9


#: launches at rest in theta a few hundredths of a degree above -90 deg, whose tilt turns there
#: slowly (|F'| 2.6e-4 and 3.1e-4): F's rounding, over the distance to the end, put the turn
#: per cycle 1.4e-6 deg off with F as computed there (`cycle._F_about`)
SLOW_ENDS = [(-89.83024262205952, 0.0, -4.649167240429254, -2.601499699847225),
             (-89.92408074743075, 0.0, 10.3064745465913, -1.3629759959813708)]


def test_a_slowly_turning_end_near_minus_90_deg_against_the_fixed_frame():
    """Turn per cycle within 5e-7 deg of the fixed frame at rtol 1e-12 (within 1.3e-7 deg of a
    40-digit quadrature on such launches, `benchmarks/quadrature_vertical.py --below`), theta
    min within 1e-9 deg."""
    status, got, want = _against_the_fixed_frame(SLOW_ENDS, 15.0)
    assert (status == cycle.DONE).all()
    err = np.abs(fold_deg(got["turn_per_cycle_deg"] - want["turn_per_cycle_deg"]))
    assert err.max() < 5e-7, err
    assert np.abs(got["theta_min_deg"] - want["theta_min_deg"]).max() < 1e-9


#: launches whose tilt swings down to within 0.01-0.07 deg of -90 deg and turns slowly there
#: (theta0 deg, thetadot0, chidot0, phidot0 rad/s; non-dimensional c, A, B). The first two, with
#: a tilt rate, have an end Newton's method found, uncertain by F's rounding over |F'|; F as
#: computed put their turn per cycle 1.8e-6 and 1.5e-6 deg off (found by a search among 60 000
#: such launches). The last two: their sums with F as computed do not converge, and within 1 deg
#: of the vertical (`cycle.GATE_TILT`) that leaves them to the integrator
SLOW_END_LAUNCHES = [
    ((-89.93815094249743, 0.006108417653791441, -3.2956729951534207, -2.1935367062552436),
     tuple(P)),
    ((-89.97216340673903, 0.008192398817339836, 7.250363011688677, -0.08969717301560998),
     (0.496607734289293, 0.35089823863182024, 0.5554120531470285)),
    ((-89.98699611, -0.0, -3.91584767, 7.6426736), tuple(P))]


def _against_40_digits(monkeypatch, launch, params):
    """(status, |turn per cycle error| deg, largest theta range error rad) of launch (theta0 deg,
    thetadot0, chidot0, phidot0 rad/s; non-dimensional c, A, B) by quadrature to 15 s, against
    the same launch's integrals at 40 digits (mpmath: invariants from their definitions,
    turning points as roots, tanh-sinh quadrature; `benchmarks/quadrature_vertical.py`'s
    reference); the errors are None for a launch not done."""
    return _state_against_40_digits(monkeypatch, launch_state(*(np.array([v]) for v in launch),
                                                             TU), params)


def _state_against_40_digits(monkeypatch, y0, params):
    """`_against_40_digits` of a launch given as its fast state y0 (N_FAST, 1), non-dimensional."""
    import mpmath as mp

    monkeypatch.syspath_prepend(os.path.join(os.path.dirname(__file__), "..", "benchmarks"))
    from quadrature_vertical import mp_cycle

    obs, status = cycle.cycles_by_quadrature(y0, np.array(params)[:, None], 15.0 / TU,
                                             parallel=False)
    if status[0] != cycle.DONE:
        return status[0], None, None
    lo, hi = obs[ob.O_TH_MIN, 0], obs[ob.O_TH_MAX, 0]
    with mp.workdps(40):
        turn, mlo, mhi, _ = (float(v) for v in mp_cycle(*y0[[2, 5, 6, 7], 0], lo, hi, params))
    got = obs[ob.O_C_RAW, 0] - 2.0 * math.pi * obs[ob.O_C_WIND, 0]
    err = abs(fold_deg(np.array([math.degrees(got - turn)]))[0])
    return status[0], err, max(abs(lo - mlo), abs(hi - mhi))


def test_a_turning_point_a_hair_below_the_vertical_keeps_no_stale_end(monkeypatch):
    """A launch whose theta_max lies 3.5e-8 rad below the vertical, Newton's last step there 4e-15
    rad: the end's terms of the step's start, 4e-15 rad off, differ from the root's by 1e-7 to
    3e-7 (chidot grows as 1 / cos^2), which put the turn per cycle 3.7e-5 deg off (an
    adversarial search). Either the integrator's, or within 1e-6 deg of 40 digits."""
    y0 = np.zeros((N_FAST, 1))
    y0[[2, 5, 6, 7], 0] = [1.5705089405580916, 0.1339239191833472, -1.4487501538211227,
                           1.2223151224076514]  # non-dimensional
    status, err, th_err = _state_against_40_digits(monkeypatch, y0, tuple(P))
    assert status in (cycle.DONE, cycle.UNCONVERGED)
    if status == cycle.DONE:
        assert err < 1e-6, err
        assert th_err < math.radians(1e-10)


def test_slowly_turning_ends_near_minus_90_deg_against_40_digits(monkeypatch):
    """Turn per cycle within 1e-7 deg, theta range within 1e-10 deg, of the same launch's
    integrals at 40 digits (`_against_40_digits`); the launches whose sums with F as computed
    do not converge go to the integrator."""
    for i, (launch, params) in enumerate(SLOW_END_LAUNCHES):
        status, err, th_err = _against_40_digits(monkeypatch, launch, params)
        if i > 0:
            assert status == cycle.UNCONVERGED, launch
            continue
        assert status == cycle.DONE
        assert err < 1e-7, (launch, err)
        assert th_err < math.radians(1e-10)


#: launched at rest at -89.94 to -89.95 deg, swinging up to 46-58 deg (the paper's ball): the
#: launch's end turns slowly (|F'| 0.004) and its root is uncertain by 1e-13 of the half-range;
#: the levels converge at N = 256, whose points come within 5e-10 rad of that end. With F as
#: computed there they were 2.8e-6, 2.1e-6 and 1.4e-6 deg off (a search among 3000 such launches)
AT_REST_NEAR_MINUS_90 = [(-89.9480448251246, 0.0, 28.697033060468314, -25.775976156644123),
                         (-89.9388138816216, 0.0, 28.262725218307146, -24.38569181600731),
                         (-89.9437640712382, 0.0, -28.750500810990264, 25.917470838083574)]


def test_long_swings_from_rest_near_minus_90_deg_against_40_digits(monkeypatch):
    """Turn per cycle within 5e-8 deg of the same launch's integrals at 40 digits
    (`_against_40_digits`): the finest levels' points nearest a slowly turning end take F from
    its difference about the end wherever their errors would add up (`cycle._diff_reach`), not
    only where the end is uncertain by over 1e-13 of the swing."""
    for launch in AT_REST_NEAR_MINUS_90:
        status, err, _ = _against_40_digits(monkeypatch, launch, tuple(P))
        assert status == cycle.DONE, launch
        assert err < 5e-8, (launch, err)


def _kernel_invariants(y):
    """(args, E, J, R, f_noise) of fast state y as `cycle.cycle_one` makes them (E less M g a)."""
    from ballsurvey.physics.euler import jellett, kinetic, routh

    c, A, B = P
    args = (math.sin(y[2]), math.cos(y[2]), y[5], y[6], y[7], c, A, B)
    kin = kinetic(*args)
    return (args, kin - c * args[0], jellett(*args), routh(*args),
            cycle.ROOT_NOISE * 2.2e-16 * (kin + c * abs(args[0])))


def _brentq_end(args, start, d, xtol, rtol):
    """The first root of the numpy module's own F (`ballsurvey.quadrature._F`) from start in
    direction d: bracketed by steps of 0.5 deg up to the vertical less a hair, then brentq."""
    from scipy.optimize import brentq

    from ballsurvey.physics.euler import energy, jellett, routh

    c, A, B = P
    E, J, R = energy(*args), jellett(*args), routh(*args)

    def f(x):
        return float(qmod._F(np.array(x), E, R, J, c, A, B)[0])
    lim = 0.5 * math.pi * (1.0 - 1e-13)  # cycle.TILT_LIMIT
    a = b = start
    while f(b) > 0.0:
        a, b = b, d * min(lim, d * b + math.radians(0.5))
    return brentq(f, a, b, xtol=xtol, rtol=rtol)


#: launches of the headline box at rest in theta (theta0 deg, chidot0, phidot0 rad/s) whose far
#: turning point Newton's method reached to rounding with F's rounding on the wrong side: the
#: next step left the bracket and bisection ran from its far end (48-60 evaluations of F)
ROUNDING_SIDE = [(-11.11111111111111, -7.393939393939394, 7.353535353535355),
                 (2.6262626262626263, -0.6060606060606055, -1.6969696969696964),
                 (-7.878787878787879, 4.727272727272727, -4.444444444444445),
                 (-18.383838383838384, -0.1212121212121211, 0.24242424242424399),
                 (47.07070707070707, -0.1212121212121211, 0.08080808080808133),
                 (-9.494949494949495, 0.6060606060606055, -0.08080808080808044)]


def test_a_turning_point_at_rounding_stops_there(monkeypatch):
    """The far turning point of each launch against scipy's brentq on the numpy module's own F
    (within 1e-12 rad), found in at most 24 evaluations of F and its derivative."""
    from ballsurvey.physics.euler import accelerations

    calls = []
    f_df = cycle._F_dF
    monkeypatch.setattr(cycle, "_F_dF", lambda *a: calls.append(a[0]) or f_df(*a))
    monkeypatch.setattr(cycle, "_root", cycle._root.py_func)
    for th_deg, cd, pd in ROUNDING_SIDE:
        y = launch_state(th_deg, 0.0, cd, pd, TU)[:, 0]
        args, E, J, R, f_noise = _kernel_invariants(y)
        thdd = accelerations(*args)[0]
        d = 1.0 if thdd > 0.0 else -1.0
        calls.clear()
        got = cycle._turning_point.py_func(y[2] + d * cycle.START_OFFSET, d, y[2],
                                           2.0 * abs(thdd), f_noise,
                                           cycle._constants(E, J, R, *P))[0]
        want = _brentq_end(args, y[2] + d * 1e-7, d, xtol=1e-15, rtol=1e-15)
        assert abs(got - want) < 1e-12, (th_deg, got, want)
        assert len(calls) <= 24, (th_deg, len(calls))


#: launches (theta0 deg, thetadot0, chidot0, phidot0 rad/s) whose spin nearly meets Jellett's J at
#: the vertical (phidot0 solved for it, then nudged), so that theta_max lies 1e-12 to 1e-9 rad
#: below 90 deg, where F ~ -1 / cos^2 theta: Newton's steps from the steep side fell under 1e-12
#: rad while still up to 1e-9 rad short of the root, and a step past the vertical's end of the
#: bracket was taken for F's rounding (the kernel hands these launches to the integrator)
AT_THE_VERTICAL = [(53.2928, 0.2588, 2.1678, -1.6963485111653727),  # 8e-12 rad below
                   (67.9958, 0.0, 12.0271, -9.337310351155578),  # 9e-11 rad below
                   (75.2368, -1.9093, -6.3962, 4.954932264725052),  # 9e-10 rad below
                   (62.8909, 0.0, -8.7889, 6.838124369946133)]  # 1e-12 rad below


def test_a_turning_point_a_hair_below_the_vertical_against_brentq():
    """theta_max of each launch against scipy's brentq on the numpy module's own F (within 1e-13
    rad: F's slope there, 1e10 to 1e13, leaves the root no rounding to speak of)."""
    from ballsurvey.physics.euler import accelerations

    lim = 0.5 * math.pi * (1.0 - 1e-13)  # the vertical, less a hair (cycle.TILT_LIMIT)
    for launch in AT_THE_VERTICAL:
        y = launch_state(*launch, TU)[:, 0]
        args, E, J, R, f_noise = _kernel_invariants(y)
        inv = cycle._constants(E, J, R, *P)
        if y[5] == 0.0:  # at rest in theta: the launch is theta_min
            thdd = accelerations(*args)[0]
            assert thdd > 0.0
            got = cycle._turning_point(y[2] + cycle.START_OFFSET, 1.0, y[2], 2.0 * abs(thdd),
                                       f_noise, inv)[0]
        else:
            got = cycle._turning_point(y[2], 1.0, math.nan, cycle._F(y[2], inv), f_noise,
                                       inv)[0]
        want = _brentq_end(args, y[2] + 1e-7, 1.0, xtol=1e-16, rtol=8.9e-16)
        assert 0.0 < lim - want < 1e-9, launch
        assert abs(got - want) < 1e-13, (launch, got, want)


def test_results_do_not_depend_on_block_or_threads():
    import numba

    th, td, cd, pd = LAUNCHES.T
    # and 300 launches of the headline box more: blocks shared out among the threads as they
    # come free, slot buffers of SLOT_BLOCK launches copied out; among them a few without spin,
    # which tip through the vertical (not done: the integrator's)
    rng = np.random.default_rng(5)
    m = 300
    spin = np.arange(m) % 61 != 7
    th = np.concatenate([th, rng.uniform(-20, 60, m)])
    td = np.concatenate([td, np.where(rng.random(m) < 0.3, rng.uniform(-3, 3, m), 0.0)])
    cd = np.concatenate([cd, rng.uniform(-12, 12, m) * spin])
    pd = np.concatenate([pd, rng.uniform(-8, 8, m) * spin])
    y0 = launch_state(th, td, cd, pd, TU)
    params = np.repeat(P[:, None], len(th), 1)
    a, sa = cycle.cycles_by_quadrature(y0, params, 20 / TU, stop_after=3, block=64)
    runs = [cycle.cycles_by_quadrature(y0, params, 20 / TU, stop_after=3, block=b)
            for b in (1, 7, 1000)]
    runs.append(cycle.cycles_by_quadrature(y0, params, 20 / TU, stop_after=3, parallel=False))
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        runs.append(cycle.cycles_by_quadrature(y0, params, 20 / TU, stop_after=3, block=16))
    finally:
        numba.set_num_threads(threads)
    for b, sb in runs:
        assert np.array_equal(a, b, equal_nan=True) and np.array_equal(sa, sb)
    assert 0 < (sa != cycle.DONE).sum() < 20
    # period mode counts at most stop_after maxima; a full run every maximum within T
    full, _ = cycle.cycles_by_quadrature(y0, params, 20 / TU)
    done = sa == cycle.DONE
    assert done[:len(LAUNCHES)].all() and np.isnan(a[:, ~done]).all()
    assert (a[ob.O_NMAX, done] <= 3).all() and (full[ob.O_NMAX, done] >= a[ob.O_NMAX, done]).all()


def test_a_quadrature_sweep_counts_its_fallbacks_and_matches_dop853(tmp_path):
    import subprocess
    import sys

    import xarray as xr

    spec = """
title = "by quadrature"
[launch]
theta0_deg = [10.0, 24.0, 45.0]
thetadot0 = 0.0
chidot0 = [-3.23, 0.0, 3.0]
phidot0 = [-3.0, 0.0]
[run]
T = 4.0
dt = 1e-3
method = "{method}"
mode = "period"
[output]
file = "{out}"
"""
    maps = {}
    for method in ("quadrature", "dop853"):
        path = tmp_path / f"{method}.toml"
        path.write_text(spec.format(method=method, out=tmp_path / f"{method}.nc"))
        r = subprocess.run([sys.executable, "-m", "ballsurvey", "sweep", str(path),
                            "--no-progress"], capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr
        maps[method] = (r.stdout + r.stderr, xr.load_dataset(tmp_path / f"{method}.nc"))
    out, q = maps["quadrature"]
    _, d = maps["dop853"]
    n_fallback = int((q.formulation.values == FIXED_FRAME).sum())
    # (45, 0, 0, 0) rocks through the upright position: at least it goes to the integrator
    assert n_fallback >= 1 and (q.formulation.values == QUADRATURE).sum() >= 6
    assert (f"integrated (dop853) where the quadrature cannot go (tilt through the vertical, "
            f"launched steady, a swing too small to resolve, not converged): {n_fallback}") in out
    assert q.formulation.attrs["flag_meanings"] == "euler_angles fixed_frame quadrature"
    assert np.array_equal(q.label.values, d.label.values)


def test_quadrature_tables_do_not_depend_on_blas_threads():
    # the cumulative integration matrices came from a BLAS product, whose rounding followed
    # OPENBLAS_NUM_THREADS (and OMP_NUM_THREADS, which dask's import sets to 1): every launch
    # by quadrature then differed in its last bits between a sweep and a dask worker
    code = ("import hashlib; from ballsurvey.classify import cycle; "
            "print(hashlib.sha256(b''.join(a.tobytes() for a in cycle.tables())).hexdigest())")
    digests = set()
    for threads in ("1", "2", "3"):
        env = dict(os.environ, OPENBLAS_NUM_THREADS=threads, OMP_NUM_THREADS=threads)
        r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                           text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        digests.add(r.stdout.strip())
    assert len(digests) == 1, digests

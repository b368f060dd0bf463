"""The step observer (`classify.step_observer`): the observer's record from each accepted step of
the DOP853 lanes, judged against independent computations: the Euler forms of the invariants,
finite differences of an integrated trajectory, and the sampling observer on fixed-step RK4 in
the Euler form (another method, another formulation, samples every 1e-4 s)."""
import math

import numpy as np
import pytest

from ballsurvey.ball import Ball
from ballsurvey.classify.labels import CODE, SHAPES, Thresholds
from ballsurvey.classify.observer import N_OBS
from ballsurvey.compose import OBSERVER, classify, near_vertical_fallback, run_launches, stop_target
from ballsurvey.integrate import ensemble
from ballsurvey.integrate.adaptive import integrate_adaptive
from ballsurvey.physics import euler, fixed
from ballsurvey.units import StepPlan, launch_state

BALL = Ball.paper()
TU = BALL.time_unit
P = BALL.nondim_params()


def _random_fixed_states(n, seed):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        u = np.zeros(euler.N_EULER)
        u[euler.TH] = rng.uniform(-1.2, 1.45)
        u[euler.CHI] = rng.uniform(-math.pi, math.pi)
        u[euler.PHI] = rng.uniform(-math.pi, math.pi)
        u[euler.THD], u[euler.CHD], u[euler.PHD] = rng.normal(0.0, 0.8, 3)
        out.append((u, fixed.euler_to_fixed(u)))
    return out


def test_fixed_frame_invariants_equal_the_euler_forms():
    c, A, B = P
    for u, v in _random_fixed_states(50, seed=3):
        dv = np.empty(fixed.N_FIXED)
        fixed.rhs(v, P, dv)
        e, j, r = fixed.invariants(v, dv, c, A, B)
        sth, cth = math.sin(u[euler.TH]), math.cos(u[euler.TH])
        args = (sth, cth, u[euler.THD], u[euler.CHD], u[euler.PHD], c, A, B)
        assert e == pytest.approx(euler.energy(*args), rel=1e-12, abs=1e-12)
        assert j == pytest.approx(euler.jellett(*args), rel=1e-12, abs=1e-12)
        assert r == pytest.approx(euler.routh(*args), rel=1e-12, abs=1e-12)


def _rk4(v, h, n):
    """n classical RK4 steps of the fixed-frame form (a reference independent of the code under
    test)."""
    k = [np.empty(fixed.N_FIXED) for _ in range(4)]
    for _ in range(n):
        fixed.rhs(v, P, k[0])
        fixed.rhs(v + 0.5 * h * k[0], P, k[1])
        fixed.rhs(v + 0.5 * h * k[1], P, k[2])
        fixed.rhs(v + h * k[2], P, k[3])
        v = v + h / 6.0 * (k[0] + 2 * k[1] + 2 * k[2] + k[3])
    return v


def test_centre_acceleration_is_the_rate_of_the_centre_velocity():
    # a_G and e_z'' against central differences of x', y' and e_z' along an integrated path
    c = P[0]
    d = 1e-4
    for _, v in _random_fixed_states(20, seed=5):
        rates = []
        for s in (-1, 1):
            w = _rk4(v.copy(), s * d / 10, 10)
            dw = np.empty(fixed.N_FIXED)
            fixed.rhs(w, P, dw)
            rates.append(dw)
        dv = np.empty(fixed.N_FIXED)
        fixed.rhs(v, P, dv)
        ax, ay, ezdd = fixed.centre_acceleration(v, dv, c)
        num = (rates[1] - rates[0]) / (2 * d)
        scale = 1.0 + np.abs(num[[fixed.FX, fixed.FY, fixed.EZ]]).max()
        assert abs(ax - num[fixed.FX]) < 1e-6 * scale
        assert abs(ay - num[fixed.FY]) < 1e-6 * scale
        assert abs(ezdd - num[fixed.EZ]) < 1e-6 * scale


@pytest.fixture(scope="module")
def box():
    """300 launches of the headline map's box in period mode (two cycles): the sampling observer
    on RK4 at dt = 1e-4 s (every step), the step observer on the DOP853 lanes at rtol 1e-9, the
    map's RK4 at dt = 1e-4 s (the step observer at each launch's own spans) and the quadrature."""
    rng = np.random.default_rng(21)
    n = 300
    y0 = launch_state(rng.uniform(-20, 60, n), 0.0, rng.uniform(-12, 12, n),
                      rng.uniform(-8, 8, n), TU)
    p = np.repeat(P[:, None], n, 1)
    plan = StepPlan(20.0, 1e-4, TU)
    res = ensemble.integrate(y0, p, plan.dt_nd, plan.n_steps, "rk4", observer=OBSERVER,
                             n_slots=N_OBS, observe_every=1, stop_after=stop_target(2))
    near_vertical_fallback(y0, p, plan.T_nd, res, stop_after=stop_target(2))
    runs = {"sampling": res}
    for method in ("dop853", "rk4", "quadrature"):
        runs[method] = run_launches(y0, p, plan, method, cycles=2)
    runs["dopri5"] = run_launches(y0, p, plan, "dopri5", rtol=1e-10, cycles=2)
    # the same pair and steps with the sampling observer on each accepted step
    res = integrate_adaptive(y0, p, plan.T_nd, 1e-10, 1e-12, observer=OBSERVER, n_slots=N_OBS,
                             h_init=plan.h_init_nd, stop_after=stop_target(2))
    near_vertical_fallback(y0, p, plan.T_nd, res, stop_after=stop_target(2))
    runs["dopri5 sampled"] = res
    return {k: classify(r, BALL.flat_face_theta_rad) for k, r in runs.items()}


def test_dopri5_map_by_steps_matches_its_samples_and_the_quadrature(box):
    # the map's dopri5 (rtol 1e-10) hands each accepted step to the step observer: the labels of
    # the sampling observer on the same steps; against the quadrature, on the launches the Euler
    # chart carried, measured: turn 8e-8 deg, theta extrema 7e-8 deg, roundness 1e-8 (the samples
    # at the pair's steps read the roundness to 1e-3: a few points a corner)
    new, old, q = box["dopri5"], box["dopri5 sampled"], box["quadrature"]
    assert np.array_equal(new["label"], old["label"])
    # (the quadrature's own launches: one it leaves to the integrator is no reference)
    shaped = (np.isin(new["label"], [CODE[w] for w in SHAPES]) & (new["formulation"] == 0)
              & (q["formulation"] == 2))
    assert shaped.sum() > 200
    assert np.abs(new["turn_per_cycle_deg"] - q["turn_per_cycle_deg"])[shaped].max() < 5e-7
    for v in ("theta_max_deg", "theta_min_deg"):
        assert np.abs(new[v] - q[v])[shaped].max() < 5e-7, v
    assert np.abs(new["roundness"] - q["roundness"])[shaped].max() < 1e-6
    assert np.abs(old["roundness"] - q["roundness"])[shaped].max() > 1e-5  # what it replaced
    assert np.allclose(new["theta_period_s"][shaped], q["theta_period_s"][shaped], rtol=1e-8)


@pytest.fixture(scope="module")
def box_pair(box):
    return box["sampling"], box["dop853"]


def test_the_fixed_step_map_by_steps_matches_dense_samples_and_the_quadrature(box):
    # the map's RK4 fed to the step observer at spans of about 1/18 of a theta cycle (a tenth of
    # an RK4 step's cost each) against the sampling observer on every step: the same labels;
    # against the quadrature, on the launches the Euler chart carried (measured: period 1.5e-8
    # relative, turn 1.8e-6 deg, theta max and min 1e-7 deg, roundness 6e-7, chord 6e-7 relative;
    # the sampling observer: 5e-10, 4e-7 deg, 4e-8 deg, 1.5e-4, 6e-7)
    ref, new, q = box["sampling"], box["rk4"], box["quadrature"]
    assert np.array_equal(ref["label"], new["label"])
    euler_chart = new["formulation"] == 0
    shaped = (np.isin(ref["label"], [CODE[w] for w in SHAPES]) & euler_chart
              & (q["formulation"] == 2))  # the quadrature's own launches
    assert shaped.sum() > 200
    assert np.allclose(new["theta_period_s"][shaped], q["theta_period_s"][shaped], rtol=5e-8)
    assert np.abs(new["turn_per_cycle_deg"] - q["turn_per_cycle_deg"])[shaped].max() < 5e-6
    for v in ("theta_max_deg", "theta_min_deg"):
        assert np.abs(new[v] - q[v])[shaped].max() < 3e-7, v
    assert np.abs(new["roundness"] - q["roundness"])[shaped].max() < 3e-6
    assert np.allclose(new["chord_m"][shaped], q["chord_m"][shaped], rtol=3e-6, atol=1e-9)
    # the forces, against the samples (measured 1.3e-4 and 2.8e-6 relative, as DOP853's step
    # observer: the bounds of test_step_observer_labels_and_fields_match_dense_rk4)
    assert np.allclose(new["max_friction_ratio"], ref["max_friction_ratio"], rtol=5e-4)
    assert np.allclose(new["min_normal_force_ratio"], ref["min_normal_force_ratio"], rtol=2e-5)
    # three points a span and one at each extremum: 35 a cycle at the least (measured), far
    # above the classifier's floor of 20
    assert (new["samples_per_cycle"][shaped] >= 30).all()


def test_step_observer_labels_and_fields_match_dense_rk4(box_pair):
    ref, new = box_pair
    assert np.array_equal(ref["label"], new["label"])
    shaped = np.isin(ref["label"], [CODE[w] for w in SHAPES])
    assert shaped.sum() > 200
    # figures the labels are built from, over launches with a shape. Bounds: the cubic
    # interpolant's error over DOP853 steps of ~30 ms (about 2e-5 of a swing; see
    # test_lanes_observed), and, for the sampled extremes, RK4's own samples every 1e-4 s
    both = shaped & np.isfinite(ref["turn_per_cycle_deg"])
    assert np.abs(new["turn_per_cycle_deg"] - ref["turn_per_cycle_deg"])[both].max() < 1e-3
    assert np.abs(new["theta_max_deg"] - ref["theta_max_deg"])[shaped].max() < 1e-4
    assert np.abs(new["theta_min_deg"] - ref["theta_min_deg"])[shaped].max() < 1e-4
    assert np.abs(new["roundness"] - ref["roundness"])[shaped].max() < 2e-3
    # the period: DOP853's own error at rtol 1e-9 bounds it (against the quadrature, 7e-7
    # relative on these launches, as with the sampling observer on the same steps; RK4 at
    # dt = 1e-4 s is within 2e-8)
    assert np.allclose(new["theta_period_s"][shaped], ref["theta_period_s"][shaped], rtol=2e-6)
    assert np.allclose(new["chord_m"][shaped], ref["chord_m"][shaped], rtol=1e-4, atol=1e-6)
    # the corner: its kind, its sharpness (peak over mean heading rate) and loops per cycle
    assert np.array_equal(new["corner_kind"][shaped], ref["corner_kind"][shaped])
    assert np.array_equal(new["loops_per_cycle"][shaped], ref["loops_per_cycle"][shaped])
    # sharpness decides `star` against a threshold of 4: close where it is near it, and on the
    # same side everywhere (at a near-cusp the peak rate is huge and ill-conditioned: the speed
    # nearly vanishes there)
    a, b = new["corner_sharpness"][shaped], ref["corner_sharpness"][shaped]
    near = b < 2 * Thresholds().star_sharpness_min
    assert np.allclose(a[near], b[near], rtol=2e-2)
    assert np.array_equal(a >= Thresholds().star_sharpness_min,
                          b >= Thresholds().star_sharpness_min)
    # the forces the validity checks read (at step ends, at three points a piece and at the
    # normal force's least inside a step: a peak between points is missed by its curvature over
    # a sixth of a step, under 5e-4)
    assert np.allclose(new["max_friction_ratio"], ref["max_friction_ratio"], rtol=5e-4)
    assert np.allclose(new["min_normal_force_ratio"], ref["min_normal_force_ratio"], rtol=2e-5)
    # and enough points a cycle to pass the sampling floor: three a step
    assert (new["samples_per_cycle"][shaped] >= 20).all()


def test_a_run_of_no_time_observes_the_launch_alone():
    # T = 0 (the API allows it): no step, the launch its only point, as the sampling observer
    # on RK4 sees it (the Euler form's forces at the launch)
    th0 = np.array([10.0, 40.0])
    y0 = launch_state(th0, 0.3, 5.0, -2.0, TU)
    p = np.repeat(P[:, None], 2, 1)
    ref = classify(run_launches(y0, p, StepPlan(0.0, 1e-4, TU), "rk4", observe_every=1),
                   BALL.flat_face_theta_rad)
    res = run_launches(y0, p, StepPlan(0.0, 1e-4, TU), "dop853")
    new = classify(res, BALL.flat_face_theta_rad)
    assert (res.n_steps == 0).all()
    assert (new["label"] == CODE["unresolved"]).all()
    assert np.allclose(new["theta_min_deg"], th0, rtol=0, atol=1e-12)
    assert np.allclose(new["theta_max_deg"], th0, rtol=0, atol=1e-12)
    assert np.allclose(new["max_friction_ratio"], ref["max_friction_ratio"], rtol=1e-12)
    assert np.allclose(new["min_normal_force_ratio"], ref["min_normal_force_ratio"], rtol=1e-12)


def test_a_ball_rocking_along_a_line_is_near_straight():
    # no spin (chidot0 = phidot0 = 0): the ball rocks in a vertical plane and G runs back and
    # forth along a line, its velocity reversing through zero once a cycle. That reversal is a
    # cusp, not a turn, so the cycle turns by less than a quarter turn and the retraced line is
    # `near_straight` (docs/labels.md), as the sampling observer on RK4 (and its fixed-frame
    # run through the vertical) has it
    th0 = np.array([10.0, 30.0, 50.0, 70.0])
    y0 = launch_state(th0, 0.5, 0.0, 0.0, TU)
    p = np.repeat(P[:, None], th0.size, 1)
    ref = classify(run_launches(y0, p, StepPlan(3.0, 1e-4, TU), "rk4", observe_every=1,
                                cycles=2), BALL.flat_face_theta_rad)
    new = classify(run_launches(y0, p, StepPlan(3.0, 1e-3, TU), "dop853", cycles=2),
                   BALL.flat_face_theta_rad)
    assert (ref["label"] == CODE["near_straight"]).all()
    assert np.array_equal(new["label"], ref["label"])
    # a line: the chord between theta maxima is a rounding-sized part of the distance rolled
    assert (new["chord_m"] < 1e-4).all()  # in radii (classify is non-dimensional)


def _line_turn_per_cycle_deg(theta0, chidot0, phidot0):
    """From the integrated path (RK4, 1e-4 s, every step kept): a ball rocking through the
    upright runs out from the centre and back once a theta cycle (maximum to maximum), each
    cycle on the other side of the centre; the direction from the cycle's start to its farthest
    point turns by 180 deg plus the line's own turn. Returns (the line's median turn per cycle,
    the largest chord between maxima over the distance rolled in the cycle)."""
    from ballsurvey.classify.observer import theta_maxima
    from ballsurvey.simulate import simulate

    ds = simulate(theta0, 0.0, chidot0, phidot0, T=20.0, n_out=200001)
    x, y = ds.x.values, ds.y.values
    peaks = theta_maxima(ds.theta.values)[1:]
    tips, retrace = [], []
    for i, j in zip(peaks[:-1], peaks[1:]):
        far = i + np.argmax(np.hypot(x[i:j] - x[i], y[i:j] - y[i]))
        tips.append(math.atan2(y[far] - y[i], x[far] - x[i]))
        rolled = np.hypot(np.diff(x[i:j + 1]), np.diff(y[i:j + 1])).sum()
        retrace.append(math.hypot(x[j] - x[i], y[j] - y[i]) / rolled)
    d = np.degrees(np.diff(tips)) - 180.0
    d = (d + 180.0) % 360.0 - 180.0
    return float(np.median(np.abs(d))), max(retrace)


def test_a_rocking_line_that_turns_slowly_is_near_straight_on_both_observers():
    # a ball rocking through the upright with a little precession or spin: G runs out and back
    # along a line that turns a little each cycle. The sampling observer on RK4 called it
    # near_straight or rosette by whether the hairpin's swing of heading fell between two
    # samples; the step observer resolves every hairpin and called all of them rosette. The
    # word now follows the line's turn per cycle, as for any path: under near_straight's turn
    # (5.73 deg) the line is near_straight, above it the cycles are petals of a rosette (or the
    # points of a star), on both observers. The line's turn is measured on the path here
    from ballsurvey.classify.labels import LABELS, line_turn_deg

    launches = [(30.0, 0.01, 0.0), (10.0, 0.05, 0.01), (60.0, 0.02, 0.05), (10.0, 0.2, 0.0),
                (30.0, 0.5, 0.05), (60.0, 0.5, 0.05)]
    limit = line_turn_deg(Thresholds())
    assert abs(limit - 5.732) < 1e-3
    turns = []
    for launch in launches:
        turn, retrace = _line_turn_per_cycle_deg(*launch)
        # the slowly turning lines here are retraced (back within 3 % of the distance rolled
        # of their start each cycle), so the rule in question decides them; the faster ones
        # here drift further and are named by the other rules (wider petals, with a hole in
        # the middle, are a rosette however slowly they turn)
        assert (retrace < 0.03) == (turn < limit), (launch, turn, retrace)
        turns.append(turn)
    assert min(abs(t - limit) for t in turns) > 1.0, turns  # none on the fence
    rows = np.array(launches)
    y0 = launch_state(rows[:, 0], 0.0, rows[:, 1], rows[:, 2], TU)
    p = np.repeat(P[:, None], len(rows), 1)
    rk4 = classify(run_launches(y0, p, StepPlan(20.0, 1e-4, TU), "rk4"),
                   BALL.flat_face_theta_rad)["label"]
    dop = classify(run_launches(y0, p, StepPlan(20.0, 1e-3, TU), "dop853", cycles=2),
                   BALL.flat_face_theta_rad)["label"]
    for launch, turn, a, b in zip(launches, turns, rk4, dop):
        words = (LABELS[a], LABELS[b])
        assert a == b, (launch, turn, words)
        if turn < limit:
            assert words[0] == "near_straight", (launch, turn, words)
        else:
            assert words[0] in ("rosette", "star"), (launch, turn, words)


def test_a_dip_of_the_normal_force_inside_a_step_is_seen():
    # a fast-spinning launch whose normal force dips to just below zero (lift-off) for a moment
    # shorter than a DOP853 step: the least N / (M g) on the step's interpolant, against the
    # sampling observer on RK4 at every 1e-5 s (its samples' miss of the dip: under 1e-7)
    s = 1.1054
    y0 = launch_state(-13.009281083241618, -7.090800924781462, s * 37.83075335940548,
                      s * -71.88735115643672, TU)
    p = P[:, None].copy()
    ref = classify(run_launches(y0, p, StepPlan(2.0, 1e-5, TU), "rk4", observe_every=1,
                                cycles=2), BALL.flat_face_theta_rad)
    n_ref = ref["min_normal_force_ratio"][0]
    assert -2e-3 < n_ref < 0.0
    assert ref["label"][0] == CODE["lift_off"]
    for rtol in (1e-9, 1e-10, 1e-12):
        new = classify(run_launches(y0, p, StepPlan(2.0, 1e-3, TU), "dop853", cycles=2,
                                    rtol=rtol), BALL.flat_face_theta_rad)
        assert abs(new["min_normal_force_ratio"][0] - n_ref) < 2e-5
        assert new["label"][0] == CODE["lift_off"]


def test_the_friction_demand_peaks_between_step_ends_are_seen():
    # a fast-spinning launch: its peak |F_h|/N falls between DOP853's step ends (read there alone
    # it was 3.5e-3 low at rtol 1e-9 and 1e-11); against the sampling observer on RK4 at every
    # 1e-5 s (within 1e-7 of it at 1e-4 s)
    y0 = launch_state(10.648994166242737, 8.898963422899591, 37.263219638069415,
                      -26.77096652618802, TU)
    p = P[:, None].copy()
    ref = classify(run_launches(y0, p, StepPlan(2.0, 1e-5, TU), "rk4", observe_every=1,
                                cycles=2), BALL.flat_face_theta_rad)["max_friction_ratio"][0]
    for rtol in (1e-9, 1e-11, 1e-12):
        new = classify(run_launches(y0, p, StepPlan(2.0, 1e-3, TU), "dop853", cycles=2,
                                    rtol=rtol), BALL.flat_face_theta_rad)["max_friction_ratio"][0]
        assert abs(new - ref) < 5e-4 * ref


def test_a_very_short_step_adds_no_rounding_to_the_forces():
    # a run of 1e-12 s is one step of that length (as short as a last step cut to end at T can
    # be): the forces inside it are those at its ends, as RK4's sampling observer has them, not
    # the rounding of the values' difference over the step squared
    rng = np.random.default_rng(8)
    n = 6
    y0 = launch_state(rng.uniform(-20, 60, n), rng.uniform(-2, 2, n), rng.uniform(-12, 12, n),
                      rng.uniform(-8, 8, n), TU)
    p = np.repeat(P[:, None], n, 1)
    ref = classify(run_launches(y0, p, StepPlan(1e-12, 1e-4, TU), "rk4", observe_every=1),
                   BALL.flat_face_theta_rad)
    new = classify(run_launches(y0, p, StepPlan(1e-12, 1e-3, TU), "dop853"),
                   BALL.flat_face_theta_rad)
    assert np.array_equal(new["label"], ref["label"])
    assert (new["label"] == CODE["unresolved"]).all()
    for f in ("max_friction_ratio", "min_normal_force_ratio"):
        assert np.allclose(new[f], ref[f], rtol=1e-9)


def _rk4_and_quadrature(launches, T, cycles=0):
    """Labelled fields of launches (theta0 deg, thetadot0, chidot0, phidot0 rad/s) over T s: the
    map's RK4 at dt = 1e-4 s (the step observer at its own spans) and the quadrature."""
    y0 = launch_state(*np.asarray(launches).T, TU)
    p = np.repeat(P[:, None], y0.shape[1], 1)
    plan = StepPlan(T, 1e-4, TU)
    return [classify(run_launches(y0, p, plan, m, cycles=cycles), BALL.flat_face_theta_rad)
            for m in ("rk4", "quadrature")]


def test_fixed_step_map_by_steps_at_high_tilt_and_through_the_vertical():
    # two launches whose theta passes 85-87 deg under a fast spin: spans paced by the rates alone
    # read the first one's theta maximum 2.5e-3 deg off and the second's turn 3e-4 deg off (the
    # sampling observer: 1e-10); and one that comes within 0.012 deg of the vertical in its first
    # span and blew up before the observer had seen its tilt, so it was labelled `blew_up`
    # instead of going to the near-vertical fallback (where the quadrature does it: a rosette)
    new, q = _rk4_and_quadrature([(79.0770, 2.1980, -11.3123, -2.4558),
                                  (78.1421, 2.3945, 0.5209, 6.0253),
                                  (15.335, -2.939, 0.113, -0.095)], 6.0)
    assert np.array_equal(new["label"], q["label"])
    assert list(new["formulation"]) == [0, 0, 2]
    assert np.abs(new["theta_max_deg"] - q["theta_max_deg"])[:2].max() < 1e-6
    assert np.abs(new["turn_per_cycle_deg"] - q["turn_per_cycle_deg"])[:2].max() < 1e-5


def test_fixed_step_map_by_steps_under_a_fast_spin():
    # near-steady launches under a fast spin (|phidot0| 10-62 rad/s): their theta nutates as fast
    # as the ball spins, which none of the path's rates shows, and spans paced by them lost theta
    # cycles (a period of 5.87 s for 2.66 s, `circle` for `near_straight`) or points (19.9 a
    # cycle: `unresolved`); the quadrature gives the truth
    new, q = _rk4_and_quadrature(
        [(22.850621046564243, 1e-4, -0.7642259031893238, -41.90078483331993),
         (1.7045789486647713, 1e-6, 0.5000156414460322, 62.131087215453256),
         (11.345267884210408, 1e-6, -3.1390214536162984, -10.295819619321705)], 20.0, cycles=2)
    assert np.array_equal(new["label"], q["label"])
    assert np.allclose(new["theta_period_s"], q["theta_period_s"], rtol=1e-6)


def test_fixed_step_map_by_steps_reads_the_first_extremum_of_a_launch_with_a_tilt_rate():
    # thetadot0 far from 0: theta's frequency, which paces the spans, is read from e_z's change
    # over a span, so a first span paced by the launch's rates alone passed a good part of a
    # theta cycle and read the first theta minimum 3.2e-5, 4.7e-6 and 4.5e-6 deg off (the
    # sampling observer: under 1e-6); the first observation is now one step on
    new, q = _rk4_and_quadrature([(39.22223678, -1.49818063, -1.18332212, -7.75617681),
                                  (16.95079638, -2.21916254, -1.03717658, 7.79351161),
                                  (25.53978855, -1.81089962, -0.10516507, 6.99150379)], 6.0)
    assert np.array_equal(new["label"], q["label"])
    for v in ("theta_min_deg", "theta_max_deg"):
        assert np.abs(new[v] - q[v]).max() < 1e-6, (v, np.abs(new[v] - q[v]))

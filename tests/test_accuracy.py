"""The adaptive pair, the near-vertical fallback, and the stiff and extreme cases: each is either
integrated accurately (invariants held to a stated tolerance) or flagged with a clear status."""
from dataclasses import replace

import numpy as np
import pytest

from ballsurvey.accuracy import Case, label_agreement, near_vertical_check, work_precision
from ballsurvey.ball import Ball
from ballsurvey.classify import observer as ob
from ballsurvey.classify.labels import CODE
from ballsurvey.compose import OBSERVER, classify, run_launches
from ballsurvey.integrate import ensemble
from ballsurvey.integrate import outcome as oc
from ballsurvey.integrate.adaptive import integrate_adaptive
from ballsurvey.integrate.tableaus import DOPRI5, FIXED_STEP
from ballsurvey.simulate import simulate
from ballsurvey.units import StepPlan, launch_state

B = Ball.paper()
TU = B.time_unit
P = B.nondim_params()


@pytest.mark.parametrize("tab,b,order", [(DOPRI5, DOPRI5.b, 5),
                                         (DOPRI5, DOPRI5.b - DOPRI5.b_err, 4)]
                         + [(t, t.b, t.order) for t in FIXED_STEP.values()])
def test_butcher_order_conditions(tab, b, order):
    a, c = tab.a, tab.c
    assert np.allclose(a.sum(1), c)
    conds = [(1, b.sum(), 1.0)]
    conds += [(2, b @ c, 1 / 2)]
    conds += [(3, b @ c**2, 1 / 3), (3, b @ a @ c, 1 / 6)]
    conds += [(4, b @ c**3, 1 / 4), (4, (b * c) @ a @ c, 1 / 8), (4, b @ a @ c**2, 1 / 12),
              (4, b @ a @ a @ c, 1 / 24)]
    conds += [(5, b @ c**4, 1 / 5), (5, b @ a @ a @ a @ c, 1 / 120), (5, b @ a @ c**3, 1 / 20)]
    for k, got, want in conds:
        if k <= order:
            assert got == pytest.approx(want, abs=1e-12), (k, got, want)
    # and the next order fails (the method is not of higher order than it says)
    assert any(abs(got - want) > 1e-6 for k, got, want in conds if k == order + 1) or order >= 5


def _y0(th, cd, pd, tdd=0.0):
    return launch_state(np.atleast_1d(th), np.atleast_1d(tdd), np.atleast_1d(cd),
                        np.atleast_1d(pd), TU)


def adaptive(y0, params, T, rtol, atol, **kw):
    return integrate_adaptive(y0, params, T, rtol, atol, observer=OBSERVER, n_slots=ob.N_OBS, **kw)


def labels(res):
    return classify(res, B.flat_face_theta_rad)


def test_adaptive_error_follows_tolerance_and_matches_rk4():
    y0 = _y0(-5.0, 4.05, -3.0)
    ref = ensemble.integrate(y0, P[:, None], 2e-5 / TU, 250000, observer=OBSERVER,
                             n_slots=ob.N_OBS, parallel=False).y_end[:2, 0]  # 5 s
    errs = []
    for rtol in (1e-6, 1e-9):
        ye = adaptive(y0, P[:, None], 5.0 / TU, rtol, rtol * 1e-3, parallel=False).y_end
        errs.append(np.hypot(*(ye[:2, 0] - ref)) * B.a)
    assert errs[1] < 1e-8
    assert 30 < errs[0] / errs[1] < 1e5  # about 1000x for 1000x tighter tolerance


def test_adaptive_launch_does_not_depend_on_its_batch():
    y0 = _y0([-5.0, 20.0, -10.0, 30.0], [4.05, 10.0, 2.3, 3.75], [-3.0, -2.9, -2.5, -3.0])
    params = np.repeat(P[:, None], 4, 1)
    r = adaptive(y0, params, 5.0 / TU, 1e-8, 1e-11)
    r1 = adaptive(y0[:, 2:3], params[:, 2:3], 5.0 / TU, 1e-8, 1e-11, parallel=False)
    assert np.array_equal(r1.obs[:, 0], r.obs[:, 2], equal_nan=True)
    assert np.array_equal(r1.y_end[:, 0], r.y_end[:, 2], equal_nan=True)
    assert r1.n_steps[0] == r.n_steps[2] and r1.outcome[0] == r.outcome[2]


def test_near_vertical_launches_take_the_quadrature_or_the_fixed_frame_and_match_it():
    # (30 deg, 3.75, -3) comes within 0.05 deg of theta = 90 deg: fixed-step RK4 blows up in the
    # Euler form, and the driver does it again from its invariants by quadrature. (60 deg, 5
    # rad/s of tilt, no spin) tilts through the vertical, where the quadrature cannot go: the
    # fixed frame integrates it. Both judged against the fixed-frame integration at rtol 1e-11
    # (another formulation, time stepping, no chart)
    y0 = _y0([30.0, 60.0], [3.75, 0.0], [-3.0, 0.0], [0.0, 5.0])
    p = np.repeat(P[:, None], 2, 1)
    got = labels(run_launches(y0, p, StepPlan(10, 2e-4, TU)))
    ref = labels(adaptive(y0, p, 10 / TU, 1e-11, 1e-14, fixed_frame=True, h_max=0.1,
                          parallel=False))
    assert list(got["formulation"]) == [oc.QUADRATURE, oc.FIXED_FRAME]
    assert np.array_equal(got["label"], ref["label"])
    assert abs(got["theta_max_deg"][0] - ref["theta_max_deg"][0]) < 1e-6
    assert got["n_sides"][0] == pytest.approx(ref["n_sides"][0], rel=1e-6)
    # in the fixed frame the chord-based turn is used; the chi-based one agrees for the quadrature
    assert got["chord_turn_per_cycle_deg"][0] == pytest.approx(got["turn_per_cycle_deg"][0],
                                                               abs=1e-6)


def test_no_spin_rocks_along_a_line_in_the_fixed_frame():
    ds = simulate(-6.0, 0.0, 0.0, 0.0, T=10.0)
    assert ds.attrs["formulation"] == "fixed_frame"
    assert (ds.attrs["label"], ds.attrs["corner_kind"]) == ("near_straight", "cusp")
    assert float(np.abs(ds.x).max()) < 1e-9  # it rolls along y only (chi0 = 0)
    assert ds.attrs["energy_drift"] < 1e-9


@pytest.mark.parametrize("theta0", [-6.0, 80.0, 85.0, 89.0, 89.9])
def test_a_line_rocked_back_and_forth_has_no_turn_per_cycle(theta0):
    """No spin: the ball rocks along a line (judged from the path: it keeps to the y axis). A
    line has no turn per cycle; near the vertical the fields gave -135 deg (n = 2.67) or -180
    deg (n = 2) for launches a hair apart (review). They are not given."""
    ds = simulate(theta0, 0.0, 0.0, 0.0, T=3.0)
    assert float(np.abs(ds.x).max()) < 1e-6 * max(1e-3, float(np.abs(ds.y).max()))
    a = ds.attrs
    assert a["label"] == "near_straight", a["label"]
    for k in ("n_sides", "turn_per_cycle_deg", "closure_m", "chord_turn_per_cycle_deg"):
        assert np.isnan(a[k]), (k, a[k])


def test_theta0_within_1_deg_of_90():
    ds = simulate(89.2, 0.0, 2.0, -3.0, T=5.0)
    assert ds.attrs["energy_drift"] < 1e-8 and ds.attrs["label"] not in ("blew_up", "singular")


def test_high_spin_is_flagged_lift_off_by_physics_not_numerics():
    # chidot0 = 200 rad/s: the normal force turns negative (the ball would jump); a tight adaptive
    # run agrees, so the flag is physical
    for kw in (dict(), dict(method="dopri5", rtol=1e-11, atol=1e-14)):
        ds = simulate(10.0, 0.0, 200.0, -3.0, T=1.0, **kw)
        assert ds.attrs["label"] == "lift_off"
        assert ds.attrs["min_normal_force_ratio"] < 0


@pytest.mark.parametrize("c_over_a", [1e-5 / 0.0254, 0.5])
def test_nearly_symmetric_and_heavily_biased_balls(c_over_a):
    # c -> 0 and c = a/2: integrated accurately; the energy drift is truncation error (it falls by
    # at least 16 per halving of dt) and the label does not change with dt
    ball = replace(B, c=c_over_a * B.a, cut_height=0.0)
    runs = [simulate(20.0, 0.0, 4.0, -3.0, T=10.0, ball=ball, dt=dt).attrs for dt in (2e-4, 1e-4)]
    assert runs[1]["energy_drift"] < 1e-6
    assert runs[0]["energy_drift"] / runs[1]["energy_drift"] > 12 or runs[1]["energy_drift"] < 1e-13
    assert runs[0]["label"] == runs[1]["label"]
    assert runs[1]["label"] not in ("blew_up", "singular", "inaccurate")
    assert runs[1]["n_sides"] == pytest.approx(runs[0]["n_sides"], rel=1e-5)


def test_long_run_holds_invariants_and_label():
    ds = simulate(-5.0, 0.0, 4.05, -3.0, T=200.0, dt=1e-4, n_out=201)
    assert ds.attrs["label"] == "square"
    assert ds.attrs["energy_drift"] < 1e-8
    assert ds.attrs["routh_drift"] < 1e-9 and ds.attrs["jellett_drift"] < 1e-9


def test_dt_too_large_is_caught():
    # Fig. 7 (theta stays below 30 deg) with steps far too large for chidot = 23 rad/s
    a = simulate(-5.0, 0.0, 23.0, -3.0, T=5.0, dt=0.05, n_out=101).attrs
    assert a["label"] == "inaccurate" and a["energy_drift"] > 1e-4
    y0 = _y0(-5.0, 23.0, -3.0)
    res = run_launches(y0, P[:, None], StepPlan(5.0, 0.5, TU))  # 0.5 s steps: the state overflows
    f = labels(res)
    assert res.outcome[0] == oc.NONFINITE and f["label"][0] == CODE["blew_up"]


def test_work_precision_rows_and_label_agreement():
    case = Case("fig12a", -5.0, 0.0, 4.05, -3.0, T=3.0)
    rows = work_precision(case, dts=(1e-3, 5e-4), rtols=(1e-6, 1e-9))
    rk = [r for r in rows if r["method"] == "rk4"]
    dp = [r for r in rows if r["method"] == "dopri5"]
    assert rk[1]["pos_err_m"] < rk[0]["pos_err_m"] / 8  # fourth order: about 16x
    assert dp[1]["pos_err_m"] < dp[0]["pos_err_m"]
    assert all(r["label"] == "square" for r in rows)
    agree = label_agreement(dts=(5e-4,), rtols=(1e-8,), n=3, T=8.0)
    assert all(v == 1.0 for v in agree.values())


def test_launches_grazing_the_vertical_get_the_labels_of_their_neighbours():
    # chidot0 = 3.5 rad/s, phidot0 = -3: theta_max 89.6..89.98 deg. RK4 in the Euler form loses
    # energy accuracy there (chidot ~ 1/cos theta); the driver re-integrates in the fixed frame,
    # where heading rate, friction and normal force are computed without the chart
    th0 = np.array([-10.0, -5.0, -4.0, -3.0, -2.0, -1.0, 3.0])
    y0 = _y0(th0, np.full(7, 3.5), np.full(7, -3.0))
    f = labels(run_launches(y0, np.repeat(P[:, None], 7, 1), StepPlan(20, 1e-4, TU)))
    assert np.all(f["label"] == CODE["square"]), f["label"]
    assert f["formulation"][3:5].all()  # the two that pass within 0.05 deg of vertical
    assert np.all(np.diff(f["n_sides"]) > 0)  # n varies smoothly with theta0
    assert np.all(f["max_friction_ratio"] < 0.09)


def test_adaptive_trajectory_at_the_requested_times():
    # simulate's adaptive path is sampled at n_out evenly spaced times from the pair's dense output
    # (before: every accepted step, in a 192 MB buffer); it agrees with fine RK4 on the same times
    ds = simulate(-5.0, 0.0, 4.05, -3.0, T=3.0, method="dopri5", rtol=1e-10, atol=1e-13,
                  n_out=301)
    ref = simulate(-5.0, 0.0, 4.05, -3.0, T=3.0, dt=1e-5, n_out=301)
    assert ds.sizes["time"] == 301 and np.allclose(ds.time.values, ref.time.values, rtol=1e-12)
    assert float(np.abs(ds.x - ref.x).max()) < 1e-8 and float(np.abs(ds.y - ref.y).max()) < 1e-8
    assert float(np.abs(ds.theta - ref.theta).max()) < 1e-7


def test_fixed_frame_path_is_sampled_like_the_fixed_step_one():
    # a launch through theta = 90 deg: the fixed-frame re-run gives the same n_out times as the
    # RK4 run would, with phi recovered from the body vector
    ds = simulate(26.0, 0.0, 3.75, -3.0, T=3.0, dt=2e-4, n_out=301)
    assert ds.attrs["formulation"] == "fixed_frame" and ds.sizes["time"] == 301
    assert np.allclose(np.diff(ds.time.values), 0.01, rtol=1e-9)
    assert not np.isnan(ds[["x", "y", "theta", "chi", "phi"]].to_array()).any()


def test_near_the_vertical_every_setting_puts_launches_in_the_quadratures_n_region():
    """theta0 80-89.9 deg, where the best squares pass: the per-cycle figures of full and period
    runs (rk4, dop853) are judged against the quadrature, an independent formulation with no
    time stepping. Every launch must land in the quadrature's n-region (round n), and the full
    run's turn per cycle, averaged over many cycles, must be far inside a degree."""
    r = near_vertical_check(n=24)
    assert r["launches"] >= 12
    for name in ("rk4 full", "rk4 period", "dop853 period", "quadrature period"):
        assert r[name]["same_n"] == r["launches"], (name, r)
    assert r["rk4 full"]["turn_deg"] < 0.01, r
    # the map by quadrature: every launch labelled as full RK4 labels it, and its turn as the
    # numpy quadrature's to that module's own accuracy
    assert r["quadrature period"]["same_label"] == r["n"] == 24, r
    assert r["quadrature period"]["turn_deg"] < 1e-5, r

"""DOP853 on SIMD lanes with the step observer (`lanes.integrate_observed` with
`classify.step_observer`, sweep method "dop853").

Judged against independent integrations: the steps against `integrate_lanes` (the kernel without
an observer), the observer's record and the labels against the fixed-step RK4 kernel in the Euler
form (another method, another formulation), and near the vertical against the scalar fixed-frame
Dormand-Prince 5(4) fallback.
"""
import math

import numpy as np
import pytest

from ballsurvey.ball import Ball
from ballsurvey.classify import observer as ob
from ballsurvey.classify.labels import CODE
from ballsurvey.classify.observer import N_OBS
from ballsurvey.compose import STEP_OBSERVER, classify, run_launches
from ballsurvey.integrate.lanes import integrate_lanes, integrate_observed
from ballsurvey.integrate.outcome import FIXED_FRAME, NONFINITE, OK
from ballsurvey.paper import FIGURES
from ballsurvey.units import StepPlan, launch_state

BALL = Ball.paper()
TU = BALL.time_unit


def _random_launches(n, seed):
    """The headline map's launch box (theta0 -20..60 deg, chidot0 -12..12, phidot0 -8..8 rad/s)."""
    rng = np.random.default_rng(seed)
    y0 = launch_state(rng.uniform(-20, 60, n), 0.0, rng.uniform(-12, 12, n),
                      rng.uniform(-8, 8, n), TU)
    return y0, np.repeat(BALL.nondim_params()[:, None], n, 1)


@pytest.fixture(scope="module")
def box():
    return _random_launches(300, seed=11)


def _observed(y0, p, T_s, **kw):
    return integrate_observed(y0, p, T_s / TU, 1e-9, 1e-12, observer=STEP_OBSERVER,
                              n_slots=N_OBS, **kw)


def test_observed_steps_are_the_lane_kernels(box):
    # carrying the slope from one step to the next (for the interpolant) changes no bit
    y0, p = box[0][:, :40], box[1][:, :40]
    obs = _observed(y0, p, 2.0)
    bare = integrate_lanes(y0, p, 2.0 / TU, 1e-9, 1e-12)
    assert (obs.outcome == OK).all() and (obs.formulation == FIXED_FRAME).all()
    assert np.array_equal(obs.traj, bare.traj)
    assert np.array_equal(obs.n_steps, bare.n_steps)


def test_observer_record_matches_the_rk4_kernel_on_the_papers_launches():
    """The step observer reads cubic Hermite interpolants of G's velocity and position inside
    DOP853 steps of h ~ 30 ms, and locates events on quintic ones; over a theta oscillation of
    angular frequency w ~ 10 rad/s the cubic's error is about (h w)^4 / 384 ~ 2e-5 of a
    variable's swing, and (h w)^3 / 72 ~ 4e-4 of a slope's: the bounds below are those
    estimates with a factor 3-5 of room, against RK4 samples every 1e-4 s."""
    names = ("fig7", "fig9a", "fig12a", "fig12b")
    f = [FIGURES[k] for k in names]
    y0 = launch_state(np.array([x["theta0_deg"] for x in f]), 0.0,
                      np.array([x["chidot0"] for x in f]), np.array([x["phidot0"] for x in f]),
                      TU)
    p = np.repeat(BALL.nondim_params()[:, None], len(f), 1)
    plan = StepPlan(6.0, 1e-4, TU)
    ref = run_launches(y0, p, plan, "rk4", observe_every=1)  # samples every 1e-4 s
    new = run_launches(y0, p, plan, "dop853", observe_every=1)
    w_nd = 10.0 * TU  # the theta oscillation's angular frequency, non-dimensional
    dt_ev = 3 * 2e-5 / w_nd  # event times: value error over the rate it crosses zero at
    # theta maxima: time, heading, position at the events (interpolated between samples);
    # positions and headings move by about one unit per unit time
    for slot, tol in ((ob.O_T1, dt_ev), (ob.O_TL, dt_ev), (ob.O_XL, dt_ev), (ob.O_YL, dt_ev),
                      (ob.O_TH_MAX, 3 * 2e-5), (ob.O_TH_MIN, 3 * 2e-5)):
        assert np.abs(new.obs[slot] - ref.obs[slot]).max() < tol, ob.SLOTS[slot]
    # the heading chi at the maxima, to whole turns (the step observer does not count chi's
    # turns between maxima: the chart-free labels read the path's heading instead)
    for slot in (ob.O_CHI1, ob.O_CHIL):
        d = new.obs[slot] - ref.obs[slot]
        assert np.abs(d - 2 * np.pi * np.round(d / (2 * np.pi))).max() < dt_ev, ob.SLOTS[slot]
    for slot in (ob.O_FRIC, ob.O_NMIN, ob.O_C_PSID):  # from the interpolant's slope
        assert np.allclose(new.obs[slot], ref.obs[slot], rtol=5 * 4e-4, atol=0), ob.SLOTS[slot]
    assert np.array_equal(new.obs[ob.O_NMAX], ref.obs[ob.O_NMAX])
    a = classify(ref, BALL.flat_face_theta_rad)
    b = classify(new, BALL.flat_face_theta_rad)
    assert np.array_equal(a["label"], b["label"])
    assert np.abs(a["turn_per_cycle_deg"] - b["turn_per_cycle_deg"]).max() < math.degrees(dt_ev)
    # the energy the observer reads off the interpolant stays well inside the classifier's
    # 1e-4 threshold for `inaccurate` (the estimate: 2e-5)
    assert np.nanmax(b["energy_drift"]) < 5e-5


def test_period_mode_labels_agree_with_full_rk4(box):
    y0, p = box
    ref = classify(run_launches(y0, p, StepPlan(20.0, 1e-4, TU), "rk4"),
                   BALL.flat_face_theta_rad)["label"]
    # the headline's settings: rtol 1e-9, two theta cycles
    res = run_launches(y0, p, StepPlan(20.0, 1e-3, TU), "dop853", cycles=2)
    lab = classify(res, BALL.flat_face_theta_rad)["label"]
    assert np.mean(lab == ref) >= 0.99
    # period mode stops each launch soon after its third theta maximum
    assert np.nanmax(res.obs[ob.O_TL] * TU) < 6.0
    assert (res.obs[ob.O_NMAX][res.outcome == OK] >= 3).all()


def test_observed_bit_identical_across_lanes_and_threads(box):
    y0, p = box[0][:, :50], box[1][:, :50]
    base = _observed(y0, p, 20.0, stop_after=3)
    for kw in (dict(lanes=1), dict(lanes=7), dict(lanes=64, parallel=False)):
        other = _observed(y0, p, 20.0, stop_after=3, **kw)
        assert np.array_equal(other.obs, base.obs, equal_nan=True), kw
        assert np.array_equal(other.traj, base.traj, equal_nan=True), kw


def test_observed_near_the_vertical_needs_no_fallback():
    # tilts that reach the vertical: the Euler kernel needs its fixed-frame fallback there
    y0 = launch_state(np.array([89.2, 60.0, 45.0]), 0.0, np.array([2.0, 0.5, 0.3]),
                      np.array([-3.0, -0.5, 0.0]), TU)
    p = np.repeat(BALL.nondim_params()[:, None], 3, 1)
    plan = StepPlan(8.0, 1e-4, TU)
    ref = run_launches(y0, p, plan, "rk4", cycles=2)
    new = run_launches(y0, p, plan, "dop853", cycles=2)
    assert (new.outcome == OK).all()
    a = classify(ref, BALL.flat_face_theta_rad)
    b = classify(new, BALL.flat_face_theta_rad)
    assert not np.isin(b["label"], [CODE["singular"], CODE["blew_up"]]).any()
    assert np.array_equal(a["label"], b["label"])
    both = np.isfinite(a["theta_period_s"])
    assert np.allclose(a["theta_period_s"][both], b["theta_period_s"][both], rtol=1e-5)


def test_observed_failures_stay_in_their_lane(box):
    y0, p = box[0][:, :20].copy(), box[1][:, :20]
    good = _observed(y0, p, 5.0, stop_after=3)
    y0[5, 4] = np.nan
    res = _observed(y0, p, 5.0, stop_after=3)
    assert res.outcome[4] == NONFINITE
    keep = np.arange(20) != 4
    assert np.array_equal(res.obs[:, keep], good.obs[:, keep], equal_nan=True)


def test_observed_refuses_bad_settings(box):
    y0, p = box[0][:, :2], box[1][:, :2]
    for kw in (dict(h_init=0.0), dict(h_init=math.nan)):
        with pytest.raises(ValueError, match="h_init"):
            _observed(y0, p, 1.0, **kw)
    with pytest.raises(ValueError, match="method"):
        run_launches(y0, p, StepPlan(1.0, 1e-3, TU), "dop9")


def test_sweep_method_dop853(tmp_path):
    import xarray as xr

    from ballsurvey.sweep import load_spec, run_sweep

    spec = tmp_path / "s.toml"
    spec.write_text(f"""
title = "dop853 map"
[launch]
theta0_deg = {{start = -5.0, stop = 20.0, num = 3}}
thetadot0 = 0.0
chidot0 = {{start = 3.0, stop = 5.0, num = 2}}
phidot0 = -3.0
[run]
T = 6.0
dt = 1e-3
method = "dop853"
mode = "period"
[output]
file = "{tmp_path / 'm.nc'}"
""")
    run_sweep(load_spec(spec), command="test", progress=False)
    ds = xr.open_dataset(tmp_path / "m.nc")
    assert ds.attrs["run_method"] == "dop853"
    assert (ds.formulation.values == FIXED_FRAME).all()
    assert ds.label.size == 6
    # one launch per chunk: the same bits
    spec.write_text(spec.read_text().replace('mode = "period"', 'mode = "period"\nchunk = 1')
                    .replace("m.nc", "m1.nc"))
    run_sweep(load_spec(spec), command="test", progress=False)
    one = xr.open_dataset(tmp_path / "m1.nc")
    for name in ("label", "turn_per_cycle_deg", "theta_period_s", "energy_drift"):
        assert np.array_equal(one[name].values, ds[name].values, equal_nan=True), name


def test_headline_bench_runs_either_method():
    from ballsurvey.bench import run_headline

    for method in ("dop853", "rk4"):
        lines = []
        r = run_headline(n=3, T=3.0, method=method, sample=6, out=lines.append)
        assert r["method"] == method and f"{method} at" in lines[0]
        # 6 of the 27 launches, labelled again by full RK4 at dt 1e-4 s to T: no
        # disagreement expected on so few (the box's disagreement rate is about 0.2 %)
        assert r["agreement"] == 1.0 and r["wall_s"] > 0
    # by quadrature, with the dop853 map swept beside it in the same run and the speed-up printed
    lines = []
    r = run_headline(n=3, T=3.0, method="quadrature", sample=6, out=lines.append)
    assert r["agreement"] == 1.0 and r["baseline"]["method"] == "dop853"
    assert r["baseline"]["agreement"] == 1.0
    assert any(line.startswith("  baseline, dop853 at rtol 1e-09, same run") for line in lines)
    assert any("speed-up of quadrature over dop853" in line for line in lines)

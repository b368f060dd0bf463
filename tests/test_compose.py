"""The layer that composes integrators and the classifier: outcomes apart from the observer's
record, the fallback policy with the run's thresholds, one units boundary. Each test named
`test_defect_*` pins a defect of the old layout (integrators writing their status into the
observer's slots) that the golden maps (tests/test_golden.py) could not show."""
from functools import partial

import numpy as np
import pytest

from ballsurvey import compose
from ballsurvey.ball import Ball
from ballsurvey.classify.labels import CODE, LABELS, Thresholds
from ballsurvey.classify.observer import N_OBS
from ballsurvey.integrate import outcome as oc
from ballsurvey.integrate.adaptive import integrate_adaptive
from ballsurvey.simulate import simulate
from ballsurvey.sweep import load_spec
from ballsurvey.sweep.engine import compute_chunk
from ballsurvey.units import StepPlan, fields_to_si, launch_state

B = Ball.paper()
TU = B.time_unit
P = B.nondim_params()


def _near_vertical():
    # tilts through theta = 90 deg: RK4 in the Euler chart meets its singularity, and the
    # quadrature cannot follow it (status VERTICAL), so the fallback integrates it in the fixed
    # frame
    return launch_state(60.0, 5.0, 0.0, 0.0, TU)


def test_defect_failed_fixed_frame_rerun_is_stored_as_fixed_frame(monkeypatch):
    # before: a fixed-frame re-run that failed kept the Euler run's `formulation = euler_angles`
    # (the observer's status slot carried both facts) and was labelled `singular`
    monkeypatch.setattr(compose, "integrate_adaptive", partial(integrate_adaptive, max_steps=20))
    res = compose.run_launches(_near_vertical(), P[:, None], StepPlan(3.0, 2e-4, TU))
    assert res.formulation[0] == oc.FIXED_FRAME
    assert res.outcome[0] == oc.STEP_BUDGET and 0 < res.t_stop[0] < 3.0 / TU
    f = compose.classify(res, B.flat_face_theta_rad)
    assert f["formulation"][0] == 1 and LABELS[f["label"][0]] == "unresolved"


def test_defect_fixed_frame_out_of_steps_or_underflow_is_not_singular():
    # before: both were reported `singular`, though the fixed frame has no singularity
    res = integrate_adaptive(_near_vertical(), P[:, None], 3.0 / TU, observer=compose.OBSERVER,
                             n_slots=N_OBS, fixed_frame=True, max_steps=50, parallel=False)
    assert res.outcome[0] == oc.STEP_BUDGET
    assert LABELS[compose.classify(res, B.flat_face_theta_rad)["label"][0]] == "unresolved"
    under = res._replace(outcome=np.array([oc.STEP_UNDERFLOW], dtype=np.int8))
    assert LABELS[compose.classify(under, B.flat_face_theta_rad)["label"][0]] == "blew_up"
    ok = integrate_adaptive(_near_vertical(), P[:, None], 3.0 / TU, observer=compose.OBSERVER,
                            n_slots=N_OBS, fixed_frame=True, parallel=False)
    assert ok.outcome[0] == oc.OK and np.isnan(ok.t_stop[0])
    assert LABELS[compose.classify(ok, B.flat_face_theta_rad)["label"][0]] not in (
        "singular", "unresolved", "blew_up")


SPEC = """
title = "fallback threshold"
[[points]]
name = "grazing"
theta0_deg = -5.0
thetadot0 = 0.0
chidot0 = 3.2
phidot0 = -3.0
[run]
T = 20.0
dt = 1e-3
{classify}
[output]
file = "x.nc"
"""


@pytest.mark.parametrize("classify,formulation", [("", 2),
                                                  ("[classify]\nmax_energy_drift = 1e-3", 0)])
def test_defect_fallback_uses_the_spec_thresholds(tmp_path, classify, formulation):
    # (-5 deg, 3.2, -3) reaches 88.2 deg (under NEAR_VERTICAL_THETA, which would send it to the
    # fallback whatever the thresholds); RK4 at 1e-3 s drifts 1.8e-4 in energy there.
    # The default max_energy_drift (1e-4) sends it to the fallback (the quadrature does it); a
    # spec that allows 1e-3 keeps it in the Euler form (before: the fallback always used the
    # class default)
    text = SPEC.format(classify=classify)
    path = tmp_path / "s.toml"
    path.write_text(text)
    spec = load_spec(path)
    f = compute_chunk(spec.text, str(path), 0, 1, parallel=False)
    assert f["formulation"][0] == formulation
    res = compose.run_launches(launch_state(-5.0, 0.0, 3.2, -3.0, TU), P[:, None],
                               StepPlan(20.0, 1e-3, TU), fallback=False)
    assert compose.needs_fallback(res)[0]
    assert not compose.needs_fallback(res, Thresholds(max_energy_drift=1e-3))[0]
    # the same record from a run outside the Euler chart (the fixed frame, quadrature) is that
    # run's own: never sent to the fallback
    for other in (oc.FIXED_FRAME, oc.QUADRATURE):
        moved = res._replace(formulation=np.full_like(res.formulation, other))
        assert not compose.needs_fallback(moved).any()


def test_defect_simulate_fields_are_si_like_the_map(tmp_path):
    # before: `simulate` returned jellett_drift and routh_drift non-dimensional, the map SI.
    # Same launch, same step (T / 2000 for both); simulate's sampling observer sees every step,
    # the map's step observer its own spans, so the figures agree to the observers' difference
    text = """
[[points]]
name = "fig12a"
theta0_deg = -5.0
thetadot0 = 0.0
chidot0 = 4.05
phidot0 = -3.0
[run]
T = 2.0
dt = 1e-3
observe_every = 1
[output]
file = "x.nc"
"""
    path = tmp_path / "s.toml"
    path.write_text(text)
    spec = load_spec(path)
    m = compute_chunk(spec.text, str(path), 0, 1, parallel=False)
    a = simulate(-5.0, 0.0, 4.05, -3.0, T=2.0, dt=1e-3, n_out=2001).attrs
    # (measured: period and side 1e-8, n_sides and friction 3e-6, closure 9e-7 m)
    for name in ("theta_period_s", "side_m", "n_sides", "max_friction_ratio"):
        assert a[name] == pytest.approx(float(m[name][0]), rel=1e-5), name
    assert a["closure_m"] == pytest.approx(float(m["closure_m"][0]), abs=3e-6)
    # the drifts are the largest over other instants (within a factor 1.2-4.2 of each other
    # here); the units the defect dropped are factors of 3e4 (Jellett's M a^3 / t_unit) and 800
    # (Routh's M a^2 / t_unit)
    for name in ("jellett_drift", "routh_drift", "energy_drift"):
        assert 0.1 < a[name] / float(m[name][0]) < 10.0, name
    assert a["jellett_drift"] > 0 and a["routh_drift"] > 0


def test_step_plan_owns_the_step_count():
    plan = StepPlan(3.0, 2e-4, TU)
    assert plan.n_steps == 15000 and plan.dt_used_s == 3.0 / 15000
    assert plan.dt_nd == 3.0 / TU / 15000
    assert StepPlan(3.0, 7e-4, TU).n_steps == 4286  # ceil: the step used is never above dt
    sim = StepPlan(3.0, 2e-4, TU, multiple=2000)
    assert sim.n_steps == 16000 and sim.n_steps % 2000 == 0
    assert StepPlan(1e-4, 1e-3, TU).n_steps == 1


def test_fields_to_si_uses_one_table():
    f = {"side_m": np.array([2.0]), "theta_period_s": np.array([3.0]),
         "jellett_drift": np.array([1.0]), "routh_drift": np.array([1.0]),
         "t_stop_s": np.array([np.nan]), "n_sides": np.array([4.0])}
    si = fields_to_si(f, B.a, TU, B.M)
    assert si["side_m"][0] == 2.0 * B.a and si["theta_period_s"][0] == 3.0 * TU
    assert si["jellett_drift"][0] == pytest.approx(B.M * B.a**3 / TU)
    assert si["routh_drift"][0] == pytest.approx(B.M * B.a**2 / TU)
    assert si["n_sides"][0] == 4.0 and np.isnan(si["t_stop_s"][0])


def test_period_mode_stop_asks_the_observer():
    res = compose.run_launches(launch_state(-5.0, 0.0, 4.05, -3.0, TU), P[:, None],
                               StepPlan(20.0, 2e-4, TU), cycles=2)
    f = compose.classify(res, B.flat_face_theta_rad)
    assert f["n_theta_cycles"][0] == 2 and res.outcome[0] == oc.OK
    assert CODE[LABELS[f["label"][0]]] == CODE["square"]


@pytest.mark.parametrize("method", ["rk4", "dopri5", "dop853", "quadrature"])
def test_a_launch_that_is_not_finite_is_refused_by_every_method(method):
    # a NaN heading or an infinite position left the quadrature (which the path's turn and
    # shape do not depend on) with a shape and dopri5 with `ok`, while rk4 said `blew_up`
    y0 = launch_state(np.full(3, 10.0), 0.0, 4.0, -3.0, TU, chi0_deg=np.array([0.0, np.nan, 0.0]),
                      y0=np.array([0.0, 0.0, np.inf]))
    p = np.repeat(P[:, None], 3, 1)
    with pytest.raises(ValueError, match="launch 1: its state or ball is not finite"):
        compose.run_launches(y0, p, StepPlan(1.0, 2e-4, TU), method)

"""Beyond brute force: quadrature from the conserved quantities, the period map, inverse search."""
import subprocess
import sys

import numpy as np
import pytest

from ballsurvey.ball import Ball
from ballsurvey.compose import classify, run_launches
from ballsurvey.find import NoSolution, find_launch, trace
from ballsurvey.period import periodic_path
from ballsurvey.quadrature import launch_cycle
from ballsurvey.simulate import simulate
from ballsurvey.units import StepPlan, launch_state

B = Ball.paper()
TU = B.time_unit


def test_quadrature_agrees_with_the_integrator_on_random_launches():
    rng = np.random.default_rng(7)
    worst = {"theta_period_s": 0.0, "turn_per_cycle_deg": 0.0, "theta_max_deg": 0.0}
    checked = 0
    while checked < 12:
        launch = (rng.uniform(-20, 60), rng.uniform(-2, 2), rng.uniform(-12, 12),
                  rng.uniform(-8, 8))
        q = launch_cycle(*launch)
        if q is None or q["theta_max_deg"] > 88:
            continue
        a = simulate(*launch, T=10.0, dt=1e-4).attrs
        if (a["label"] in ("inaccurate", "blew_up", "unresolved")
                or a["formulation"] != "euler_angles"):
            continue
        worst["theta_period_s"] = max(worst["theta_period_s"],
                                      abs(q["theta_period_s"] / a["theta_period_s"] - 1))
        worst["turn_per_cycle_deg"] = max(worst["turn_per_cycle_deg"],
                                          abs(q["turn_per_cycle_deg"] - a["turn_per_cycle_deg"]))
        worst["theta_max_deg"] = max(worst["theta_max_deg"],
                                     abs(q["theta_max_deg"] - a["theta_max_deg"]))
        checked += 1
    assert worst["theta_period_s"] < 1e-6, worst
    assert worst["turn_per_cycle_deg"] < 1e-3, worst
    assert worst["theta_max_deg"] < 1e-4, worst


def test_quadrature_of_the_steady_circle_is_none(fig4):
    launch, _ = fig4
    assert launch_cycle(launch["theta0_deg"], 0.0, launch["chidot0"], launch["phidot0"]) is None


@pytest.mark.parametrize("case", [(-5.0, 0.0, 4.05, -3.0, 0.0), (-5.0, 0.0, 23.0, -3.0, 190.0),
                                  (20.0, 0.0, 10.0, -2.9, 0.0), (-10.0, 0.0, 2.3, -2.5, 0.0)])
def test_period_map_path_matches_full_integration(case):
    th, td, cd, pd, chi0 = case
    full = simulate(th, td, cd, pd, 20.0, chi0_deg=chi0, n_out=2001)
    per = periodic_path(th, td, cd, pd, 20.0, chi0_deg=chi0, n_out=2001)
    assert per.attrs["label"] == full.attrs["label"]
    assert float(np.hypot(full.x - per.x, full.y - per.y).max()) < 1e-6  # m, over 20 s
    assert float(np.abs(full.theta - per.theta).max()) < 1e-5
    assert per.attrs["window_s"] <= 2.0  # integrated 2 s of 20


def test_period_mode_labels_match_full_integration_on_a_map():
    n = 12
    th, cd = np.meshgrid(np.linspace(-10, 30, n), np.linspace(1, 12, n), indexing="ij")
    y0 = launch_state(th.ravel(), 0.0, cd.ravel(), -3.0, TU)
    params = np.repeat(B.nondim_params()[:, None], n * n, 1)
    plan = StepPlan(20, 1e-4, TU)
    full = classify(run_launches(y0, params, plan), B.flat_face_theta_rad)
    per = classify(run_launches(y0, params, plan, cycles=2), B.flat_face_theta_rad)
    assert np.array_equal(full["label"], per["label"])
    both = np.isfinite(full["n_sides"]) & np.isfinite(per["n_sides"])
    assert np.allclose(full["n_sides"][both], per["n_sides"][both], rtol=1e-4)
    assert np.all(per["n_theta_cycles"][both] == 2)


def test_find_square_and_triangle():
    sq = [s for s in find_launch(4, dict(theta0_deg=-5.0, thetadot0=0.0, chidot0=0.0,
                                         phidot0=-3.0), bracket=(1.0, 10.0))]
    assert len(sq) == 1
    s = sq[0]
    assert s.value == pytest.approx(4.0526, abs=1e-3)  # the paper's Fig. 12a uses 4.05
    assert abs(s.n_sides - 4) < 4e-6  # 1e-6 relative
    assert s.label == "square" and s.closure_m < 1e-6
    tri = find_launch(3, dict(theta0_deg=-10.0, thetadot0=0.0, chidot0=0.0, phidot0=-2.5),
                      bracket=(0.5, 5.0))
    assert tri[0].label == "triangle" and abs(tri[0].n_sides - 3) < 3e-6


def test_find_says_when_there_is_no_solution():
    with pytest.raises(NoSolution, match="no chidot0 in"):
        find_launch(4, dict(theta0_deg=-5.0, thetadot0=0.0, chidot0=0.0, phidot0=-3.0),
                    bracket=(10.0, 20.0), check=False)
    r = subprocess.run([sys.executable, "-m", "ballsurvey", "find", "--shape", "square",
                        "--theta0-deg", "-5", "--phidot0", "-3", "--bracket", "10", "20"],
                       capture_output=True, text=True)
    assert r.returncode == 1 and "no solution" in r.stderr
    said = [line for line in r.stderr.splitlines() if "no solution" in line]
    assert len(said) == 1 and "{" not in r.stderr
    assert "at theta0_deg = -5 deg, thetadot0 = 0 rad/s, phidot0 = -3 rad/s" in r.stderr


def test_trace_of_exact_squares():
    rows = trace(4, [-5.0, 5.0, 15.0], dict(theta0_deg=0.0, thetadot0=0.0, chidot0=0.0,
                                            phidot0=-3.0), bracket=(1.0, 10.0))
    assert len(rows) == 3
    for th0, sol in rows:
        q = launch_cycle(th0, 0.0, sol.value, -3.0)
        assert abs(q["turn_per_cycle_deg"]) == pytest.approx(90.0, abs=1e-6)


def test_refined_map_agrees_with_the_full_grid_at_a_fraction_of_the_cost():
    from ballsurvey.refine import compare_with_full

    r = compare_with_full(n_coarse=9, levels=2, T=8.0, out=lambda s: None)  # 33 x 33
    assert r["agreement"] >= 0.99  # a region thinner than a coarse cell can be missed
    assert r["integrated"] < 0.6 * r["full"]  # 46 % measured; 14 % on a 129 x 129 map

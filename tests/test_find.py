"""`find` along the whole n = 4 curve, checked against an independent measure: the fixed-frame
form (no Euler chart) integrated at rtol 1e-12, its turn per cycle read off the rotation of the
chord between successive theta maxima of the stored path, and the root solved by secant."""
import subprocess
import sys

import numpy as np
import pytest

from ballsurvey import Ball
from ballsurvey.classify.observer import N_OBS
from ballsurvey.compose import OBSERVER
from ballsurvey.find import find_launch, trace
from ballsurvey.integrate.adaptive import trajectory_adaptive
from ballsurvey.physics.fast import S_TH, S_X, S_Y
from ballsurvey.units import launch_state

BALL = Ball.paper()


def _fixed_frame_turn(theta0_deg, chidot0, phidot0, T=4.0):
    """|Net turn per theta cycle| (deg) from the rotation of the chord between successive upward
    crossings of the mid-range tilt (well conditioned, unlike the flat maxima), fixed-frame form."""
    tu = BALL.time_unit
    y0 = launch_state(theta0_deg, 0.0, chidot0, phidot0, tu)
    r = trajectory_adaptive(y0[:, 0], BALL.nondim_params(), T / tu, 1e-12, 1e-14,
                            observer=OBSERVER, n_slots=N_OBS, fixed_frame=True, h_init=1e-4)
    t, s = r.t, r.traj
    th, x, y = s[:, S_TH], s[:, S_X], s[:, S_Y]
    level = 0.5 * (th.min() + th.max())
    i = np.flatnonzero((th[:-1] < level) & (th[1:] >= level))
    pts = []
    for k in i[(i >= 1) & (i + 2 < th.size)]:  # cubic through four steps: time of the crossing
        tt = t[k - 1:k + 3] - t[k]
        roots = np.roots(np.polyfit(tt, th[k - 1:k + 3] - level, 3))
        tc = [r.real for r in roots if abs(r.imag) < 1e-12 and 0 <= r.real <= tt[2]][0]
        pts.append([np.polyval(np.polyfit(tt, v[k - 1:k + 3], 3), tc) for v in (x, y)])
    d = np.diff(np.array(pts), axis=0)
    ang = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    rot = (np.diff(ang) + 180.0) % 360.0 - 180.0
    return abs(float(np.median(rot)))


def _secant_root(theta0_deg, phidot0, a, b, target=90.0):
    fa = _fixed_frame_turn(theta0_deg, a, phidot0) - target
    fb = _fixed_frame_turn(theta0_deg, b, phidot0) - target
    for _ in range(8):
        c = b - fb * (b - a) / (fb - fa)
        a, fa = b, fb
        b, fb = c, _fixed_frame_turn(theta0_deg, c, phidot0) - target
        if abs(b - a) < 1e-7:
            break
    return b


@pytest.mark.parametrize("theta0", [26.0, 55.0])
def test_find_square_near_the_vertical_matches_fixed_frame_integration(theta0):
    sols = find_launch(4, dict(theta0_deg=theta0, thetadot0=0.0, chidot0=0.0, phidot0=-3.0))
    assert len(sols) == 1 and sols[0].label == "square"
    root = sols[0].value
    ref = _secant_root(theta0, -3.0, root - 0.01, root + 0.01)
    assert abs(root - ref) < 1e-6  # the issue asks 1e-4 rad/s; measured 5e-9
    # the best squares here pass within a degree of the vertical: what broke find before
    assert 89.0 < _theta_max(theta0, root) < 90.0


def _theta_max(theta0, chidot0):
    from ballsurvey.quadrature import launch_cycle

    return launch_cycle(theta0, 0.0, chidot0, -3.0)["theta_max_deg"]


def test_trace_follows_the_square_curve_to_60_deg():
    rows = trace(4, np.linspace(-10.0, 60.0, 8), dict(theta0_deg=0.0, thetadot0=0.0, chidot0=0.0,
                                                       phidot0=-3.0), bracket=(1.0, 10.0))
    assert [th for th, _ in rows] == pytest.approx(list(np.linspace(-10.0, 60.0, 8)))
    for _th, s in rows:
        assert s.label == "square" and abs(s.n_sides - 4.0) < 1e-5 and s.closure_m < 1e-6
    # chidot0 falls steadily along the curve (3.42 rad/s at 60 deg)
    assert np.all(np.diff([s.value for _, s in rows]) < 0)


def test_find_cli_reports_roots_that_are_not_the_shape():
    r = subprocess.run([sys.executable, "-m", "ballsurvey", "find", "--shape", "square",
                        "--theta0-deg", "26", "--phidot0", "-3"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("chidot0 = 3.7503") and "square" in lines[0]
    assert all(ln.startswith("not a solution") for ln in lines[1:])


@pytest.mark.parametrize("launch, whole_turns", [((-5.0, 0.0, 4.05, -3.0), 1),
                                                 ((-10.0, 0.0, 2.3, -2.5), 0),
                                                 ((-8.0, 0.0, -2.0, 0.0), -1)])
def test_turn_per_cycle_is_the_paths_turn_and_chi_changes_by_it_plus_whole_turns(launch,
                                                                                  whole_turns):
    """The classifier's turn per cycle is the path's heading turn folded into (-180, 180]; chi
    itself (integrated, read between successive theta minima) changes by the quadrature's
    chi_change_per_cycle_deg, which is that turn plus whole turns (+360 deg for Fig. 12a's square,
    -360 for the pentagram)."""
    import ballsurvey
    from ballsurvey.quadrature import launch_cycle

    q = launch_cycle(*launch)
    ds = ballsurvey.simulate(*launch, T=3.0, n_out=30001)
    th, chi = ds.theta.values, ds.chi.values
    k = np.nonzero((th[1:-1] < th[:-2]) & (th[1:-1] <= th[2:]))[0] + 1  # theta minima
    chi_changes = np.degrees(np.diff(chi[k]))
    assert len(chi_changes) >= 3
    assert np.allclose(chi_changes, q["chi_change_per_cycle_deg"], atol=0.1), chi_changes
    assert abs(ds.attrs["turn_per_cycle_deg"] - q["turn_per_cycle_deg"]) < 0.05
    assert -180 < ds.attrs["turn_per_cycle_deg"] <= 180
    assert q["chi_change_per_cycle_deg"] - q["turn_per_cycle_deg"] == pytest.approx(
        360.0 * whole_turns, abs=1e-9)

"""The rolling resistance (a couple -mu_r N a u opposing the rolling, docs/physics.md) judged from
equations written apart from physics/ (`ballsurvey.synthetic.resisted_newton_euler`: Newton-Euler
in the fixed frame as one 6x6 linear system for the angular acceleration and the table's
reaction), integrated by scipy's DOP853; the initial state is built here from Eq. (3). And
coefficient 0 gives the numbers stored from the code before the model existed, bit for bit.

tests/data/golden_simulate.npz: every variable of `simulate` for three launches (the paper's
square by RK4 and by dopri5, and a near-vertical launch that takes the fixed-frame fallback),
written before the rolling resistance was added (commit 333b3ed); tests/data/golden_fixed_rhs.npz:
the fixed-frame right-hand side on 200 random states (p = 0.3, 0.4, 0.45), from the same code.
Regenerate the first (only when a result is meant to change, and say why in the commit):
    python tests/test_rolling_resistance.py
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from ballsurvey.ball import Ball
from ballsurvey.limits import InputError
from ballsurvey.physics import fixed
from ballsurvey.simulate import simulate
from ballsurvey.synthetic import (
    resisted_energy_and_power,
    resisted_newton_euler,
    resisted_rate,
    synthetic_track,
)

DATA = Path(__file__).resolve().parent / "data"
SQUARE = dict(theta0_deg=-5.0, thetadot0=0.0, chidot0=4.05, phidot0=-3.0)  # the paper's Fig. 12a
GOLDEN_CASES = {
    "fig12a_rk4": dict(SQUARE, T=2.0),
    "fig12a_dopri5": dict(SQUARE, T=2.0, method="dopri5"),
    "near_vertical_rk4": dict(theta0_deg=26.0, thetadot0=0.0, chidot0=3.75, phidot0=-3.0, T=3.0),
}


# --- an independent run ----------------------------------------------------------------------

def launch(theta0_deg, thetadot0, chidot0, phidot0, ball):
    """The fixed-frame state of a launch at the origin with chi0 = phi0 = 0, non-dimensional:
    axis e = (0, cos th, -sin th), xi = (1, 0, 0), w = -thetadot xi + chidot z + phidot e."""
    tu = ball.time_unit
    th = math.radians(theta0_deg)
    e = np.array([0.0, math.cos(th), -math.sin(th)])
    xi = np.array([1.0, 0.0, 0.0])
    w = (-thetadot0 * xi + chidot0 * np.array([0.0, 0.0, 1.0]) + phidot0 * e) * tu
    return np.concatenate([[0.0, 0.0], e, xi, w])


def independent_run(kw, ball, mu, T, n):
    """scipy DOP853 on the equations above, with the energy dissipated integrated beside them
    (the state's last slot is the integral of the couple's power)."""
    c, A, B = ball.nondim_params()
    tu = ball.time_unit

    def f(_, y):
        return np.append(resisted_rate(y[:11], c, A, B, mu),
                         resisted_energy_and_power(y[:11], c, A, B, mu)[1])

    t = np.linspace(0.0, T / tu, n)
    sol = solve_ivp(f, (0.0, t[-1]), np.append(launch(**kw, ball=ball), 0.0), method="DOP853",
                    rtol=1e-11, atol=1e-13, t_eval=t)
    assert sol.success
    return t * tu, sol.y.T


# --- coefficient 0: today's numbers, bit for bit ---------------------------------------------

def test_fixed_rhs_is_bit_for_bit_without_the_couple():
    g = np.load(DATA / "golden_fixed_rhs.npz")
    out, out0 = np.empty_like(g["out"]), np.empty_like(g["out"])
    p0 = np.append(g["p"], 0.0)
    for k, v in enumerate(g["V"]):
        fixed.rhs(v, g["p"], out[k])
        fixed.rhs(v, p0, out0[k])
    assert np.array_equal(out, g["out"])
    assert np.array_equal(out0, g["out"])


@pytest.mark.parametrize("name", sorted(GOLDEN_CASES))
def test_simulate_with_coefficient_zero_is_bit_for_bit(name):
    g = np.load(DATA / "golden_simulate.npz")
    ds = simulate(**GOLDEN_CASES[name], n_out=101, rolling_resistance=0.0)
    keys = sorted(k.split("/", 1)[1] for k in g.files if k.startswith(name + "/"))
    assert keys == sorted(list(ds.data_vars) + ["time"])
    for k in keys:
        got = ds.time.values if k == "time" else ds[k].values
        assert np.array_equal(got, g[f"{name}/{k}"], equal_nan=True), k
    assert ds.attrs["rolling_resistance"] == 0.0


# --- the resisted equations ------------------------------------------------------------------

def test_resisted_rate_matches_newton_euler(random_euler_states, p):
    c, A, B = p
    for mu in (0.003, 0.05):
        pm = np.array([c, A, B, mu])
        for u in random_euler_states(40, seed=7):
            v = fixed.euler_to_fixed(u)
            dv = np.empty(fixed.N_FIXED)
            fixed.rhs(v, pm, dv)
            want = resisted_rate(v, c, A, B, mu)
            assert np.allclose(dv, want, rtol=1e-10, atol=1e-10 * (1 + np.abs(want).max()))
            # the couple changes the angular acceleration by a part of the couple's size
            assert not np.allclose(dv[8:], resisted_rate(v, c, A, B, 0.0)[8:], rtol=1e-6,
                                   atol=1e-6 * mu)
            # the table's force and torque about G: M a_G (with N), -s x R + tau
            fx, fy, n, tx, ty, tz = fixed.contact_fixed(v, pm)
            _, r, uu = resisted_newton_euler(v, c, A, B, mu)
            s = c * v[2:5] + np.array([0.0, 0.0, 1.0])
            tau = np.cross(-s, r) - mu * r[2] * uu
            assert np.allclose([fx, fy, n], r, rtol=1e-10, atol=1e-10)
            assert np.allclose([tx, ty, tz], tau, rtol=1e-10, atol=1e-10)


def test_energy_falls_as_the_couple_dissipates():
    """Along the independent integration E(t) - E(0) equals the integral of tau . w (the model
    itself), and simulate's resisted trajectory follows that integration: its path, its energy
    and the rate of its energy, dE/dt = tau . w, at every sample."""
    ball = Ball.paper()
    c, A, B = ball.nondim_params()
    mu, T, n = 0.004, 3.0, 1501
    t, y = independent_run(SQUARE, ball, mu, T, n)
    e = np.array([resisted_energy_and_power(r[:11], c, A, B, mu)[0] for r in y])
    power = np.array([resisted_energy_and_power(r[:11], c, A, B, mu)[1] for r in y])
    lost = e[0] - e[-1]
    assert lost > 0.02 * (e[0] - 1.0 - c * y[0, 4])  # a real part of the kinetic energy goes
    assert np.all(power <= 0.0)
    assert np.allclose(e - e[0], y[:, 11], rtol=0, atol=1e-9 * e[0])

    ds = simulate(**SQUARE, T=T, n_out=n, rolling_resistance=mu)
    assert ds.attrs["method"] == "dopri5" and ds.attrs["formulation"] == "fixed_frame"
    assert ds.attrs["label"] != "inaccurate"
    a = ball.a
    assert np.allclose(ds.time.values, t, rtol=0, atol=1e-12)
    assert np.abs(ds.x.values - y[:, 0] * a).max() < 1e-7  # m
    assert np.abs(ds.y.values - y[:, 1] * a).max() < 1e-7
    unit = ball.M * ball.g * a  # J
    e_sim = ds.energy.values / unit
    assert np.abs(e_sim - e).max() < 1e-6 * lost
    # dE/dt of simulate's samples (five-point central differences, error O(dt^4): 1e-5 of the
    # power at 2 ms, where it turns fastest: the corners) against the couple's power
    dt_nd = (t[1] - t[0]) / ball.time_unit
    de = (e_sim[:-4] - 8 * e_sim[1:-3] + 8 * e_sim[3:-1] - e_sim[4:]) / (12 * dt_nd)
    assert np.abs(de - power[2:-2]).max() < 1e-4 * np.abs(power).max()


def test_coefficient_slows_the_ball_more():
    speeds = []
    for mu in (0.001, 0.004):
        ds = simulate(**SQUARE, T=3.0, n_out=61, rolling_resistance=mu)
        e = ds.energy.values
        speeds.append(e[0] - e[-1])
    assert 0.0 < speeds[0] < speeds[1]


@pytest.mark.parametrize("bad", [-0.001, math.nan, 2.0, "0.1"])
def test_bad_coefficient_is_refused(bad):
    with pytest.raises(InputError, match="rolling_resistance"):
        simulate(**SQUARE, T=0.1, rolling_resistance=bad)


# --- the command line ------------------------------------------------------------------------

def test_path_and_animate_integrate_with_the_rolling_resistance(tmp_path, capsys, monkeypatch):
    import sys

    from ballsurvey.cli import main

    sim = sys.modules["ballsurvey.simulate"]  # the module (the package's name is the function)

    made = []

    def spy(*args, **kw):
        ds = simulate(*args, **kw)
        made.append(ds)
        return ds

    monkeypatch.setattr(sim, "simulate", spy)
    launch = ["--theta0-deg", "-5", "--chidot0", "4.05", "--phidot0", "-3", "--T", "0.5"]
    assert main(["path", *launch, "--n-out", "101", "--rolling-resistance", "0.02",
                 "-o", str(tmp_path / "p.png")]) == 0
    assert main(["animate", *launch, "--fps", "4", "--speed", "1", "--rolling-resistance",
                 "0.02", "-o", str(tmp_path / "a.gif")]) == 0
    assert (tmp_path / "p.png").stat().st_size > 0 and (tmp_path / "a.gif").stat().st_size > 0
    for ds in made:
        assert ds.attrs["rolling_resistance"] == 0.02
        e = ds.energy.values
        assert e[-1] < e[0] * (1 - 1e-3)
    assert len(made) == 2
    capsys.readouterr()
    for cmd in (["path", *launch, "-o", str(tmp_path / "q.png")],
                ["animate", *launch, "-o", str(tmp_path / "q.gif")]):
        assert main(cmd + ["--rolling-resistance", "-0.1"]) == 2
        err = capsys.readouterr().err
        assert "--rolling-resistance: must be >= 0" in err and err.count("\n") == 1


# --- fit --slowing ---------------------------------------------------------------------------

def test_fit_slowing_recovers_a_ball_that_slows(tmp_path, capsys):
    """A track of the paper's square slowing by about 3 % of its speed a second (made by the
    6x6 equations, not the engine), filmed at 30 frames/s with 0.2 mm of noise: `fit --slowing`
    brings the residual to the noise and finds the launch and the coefficient within 3 of their
    stated standard deviations."""
    import json

    from ballsurvey.cli import main

    mu, noise, fps = 4e-4, 2e-4, 30
    truth = dict(SQUARE, chi0_deg=0.0, x0=0.0, y0=0.0, rolling_resistance=mu)
    tr = synthetic_track(**SQUARE, T=3.0, fps=fps, noise_m=noise, seed=5, rolling_resistance=mu)
    # the premise: the speed falls about 3 % a second, and the track leaves the path of the
    # same launch without the couple by far more than the noise
    t = tr["t"]
    speed = np.hypot(np.diff(tr["x"]), np.diff(tr["y"])) * fps
    slope, v0 = np.polyfit(t[1:], speed, 1)
    assert 0.02 < -slope / v0 < 0.04
    plain = synthetic_track(**SQUARE, T=3.0, fps=fps)
    assert np.hypot(tr["x"] - plain["x"], tr["y"] - plain["y"]).max() > 20 * noise
    path = tmp_path / "slowing.csv"
    path.write_text("t,x,y\n" + "\n".join(f"{a:.5f},{b:.7f},{c:.7f}"
                                          for a, b, c in zip(t, tr["x"], tr["y"])) + "\n")
    capsys.readouterr()
    assert main(["fit", str(path), "--slowing", "--format", "json"]) == 0
    fit = json.loads(capsys.readouterr().out)
    assert 0.8 * noise < fit["rms_m"] < 1.25 * noise
    for k, v in truth.items():
        assert abs(fit[k] - v) < 3 * fit[f"{k}_err"], (k, fit[k], fit[f"{k}_err"])
    assert fit["rolling_resistance_err"] < 0.1 * mu  # the coefficient is measured, not guessed


if __name__ == "__main__":  # regenerate the stored simulate arrays
    stored = {}
    for case, kw in GOLDEN_CASES.items():
        ds = simulate(**kw, n_out=101)
        stored.update({f"{case}/{k}": v.values for k, v in ds.data_vars.items()})
        stored[f"{case}/time"] = ds.time.values
    np.savez_compressed(DATA / "golden_simulate.npz", **stored)

"""The rolling resistance (a couple -mu_r N a u opposing the rolling, docs/physics.md) judged from
equations written afresh here: Newton-Euler in the fixed frame as one 6x6 linear system for the
angular acceleration and the table's reaction, integrated by scipy's DOP853. And coefficient 0
gives the numbers stored from the code before the model existed, bit for bit.

tests/data/golden_simulate.npz: every variable of `simulate` for three launches (the paper's
square by RK4 and by dopri5, and a near-vertical launch that takes the fixed-frame fallback),
written before the rolling resistance was added; tests/data/golden_fixed_rhs.npz: the
fixed-frame right-hand side on 200 random states (p = 0.3, 0.4, 0.45), from the same code.
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

DATA = Path(__file__).resolve().parent / "data"
EPS = fixed.ROLLING_EPS  # the regularisation the docs state: u = w_h / sqrt(|w_h|^2 + eps^2)
SQUARE = dict(theta0_deg=-5.0, thetadot0=0.0, chidot0=4.05, phidot0=-3.0)  # the paper's Fig. 12a
GOLDEN_CASES = {
    "fig12a_rk4": dict(SQUARE, T=2.0),
    "fig12a_dopri5": dict(SQUARE, T=2.0, method="dopri5"),
    "near_vertical_rk4": dict(theta0_deg=26.0, thetadot0=0.0, chidot0=3.75, phidot0=-3.0, T=3.0),
}


# --- the equations, afresh (non-dimensional: a = g = M = 1) ----------------------------------

def skew(a):
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def newton_euler(v, c, A, B, mu):
    """(wdot, R) of the fixed-frame state v = (x, y, e, b, w): rolling a_G = wdot x s +
    w x (c w x e) with s = c e + z from the contact point P to G; M a_G = R - M g z;
    I_G wdot + w x I_G w = r_GP x R + tau, r_GP = -s, tau = -mu R_z u (R_z = N)."""
    e, w = v[2:5], v[8:11]
    z = np.array([0.0, 0.0, 1.0])
    s = c * e + z
    ig = A * np.eye(3) + (B - A) * np.outer(e, e)
    u = np.array([w[0], w[1], 0.0]) / math.sqrt(w[0] ** 2 + w[1] ** 2 + EPS ** 2)
    m = np.zeros((6, 6))
    rhs = np.zeros(6)
    # a_G - R = -z:  -[s]x wdot - R = -z - w x (c w x e)
    m[:3, :3] = -skew(s)
    m[:3, 3:] = -np.eye(3)
    rhs[:3] = -z - np.cross(w, c * np.cross(w, e))
    # I_G wdot - (-s) x R + mu u R_z = -w x I_G w
    m[3:, :3] = ig
    m[3:, 3:] = skew(s) + mu * np.outer(u, z)
    rhs[3:] = -np.cross(w, ig @ w)
    sol = np.linalg.solve(m, rhs)
    return sol[:3], sol[3:], u


def energy_and_power(v, c, A, B, mu):
    e, w = v[2:5], v[8:11]
    s = c * e + np.array([0.0, 0.0, 1.0])
    ig = A * np.eye(3) + (B - A) * np.outer(e, e)
    vg = np.cross(w, s)
    energy = 0.5 * w @ ig @ w + 0.5 * vg @ vg + (1.0 + c * e[2])
    _, r, u = newton_euler(v, c, A, B, mu)
    return energy, -mu * r[2] * (u @ w)


def rate(v, c, A, B, mu):
    e, b, w = v[2:5], v[5:8], v[8:11]
    wdot, _, _ = newton_euler(v, c, A, B, mu)
    vg = np.cross(w, c * e + np.array([0.0, 0.0, 1.0]))
    return np.concatenate([vg[:2], np.cross(w, e), np.cross(w, b), wdot])


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
        return np.append(rate(y[:11], c, A, B, mu), energy_and_power(y[:11], c, A, B, mu)[1])

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
            want = rate(v, c, A, B, mu)
            assert np.allclose(dv, want, rtol=1e-10, atol=1e-10 * (1 + np.abs(want).max()))
            # the couple changes the angular acceleration by a part of the couple's size
            assert not np.allclose(dv[8:], rate(v, c, A, B, 0.0)[8:], rtol=1e-6, atol=1e-6 * mu)
            # the table's force and torque about G: M a_G (with N), -s x R + tau
            fx, fy, n, tx, ty, tz = fixed.contact_fixed(v, pm)
            _, r, uu = newton_euler(v, c, A, B, mu)
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
    e = np.array([energy_and_power(r[:11], c, A, B, mu)[0] for r in y])
    power = np.array([energy_and_power(r[:11], c, A, B, mu)[1] for r in y])
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

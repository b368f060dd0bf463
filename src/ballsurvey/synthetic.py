"""Synthetic measured tracks, made by other code than the engine's kernels: scipy's solve_ivp
(DOP853) on the fixed-frame Newton-Euler form (`physics.fixed`), which has no Euler angles, so a
fit of such a track with the Euler-angle kernel tests the fit against an independent model.

The probe's tip and base and the centre of mass are read from the integrated symmetry axis e and
G's position with the truncated ball's geometry (G at height a + c e_z, the face's centre
(c + a - cut_height) from G along -e, the tip probe_m further), as a camera above the table sees
them.

With a rolling resistance mu_r > 0 the states come from equations written here afresh, apart
from `physics.fixed`: Newton-Euler in the fixed frame as one 6x6 linear system for the angular
acceleration and the table's reaction R, with the couple -mu_r R_z a u (u = w_h /
sqrt(|w_h|^2 + ROLLING_EPS^2), w_h the horizontal part of w) in the torque balance
(`resisted_newton_euler`).
"""
from __future__ import annotations

import math

import numpy as np

from .ball import Ball
from .physics import fixed


def _skew(a):
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def resisted_newton_euler(v, c, A, B, mu_r):
    """(wdot, R, u) of the fixed-frame state v = (x, y, e, b, w), non-dimensional (a = g = M =
    1): rolling gives a_G = wdot x s + w x (c w x e) with s = c e + z_hat from the contact point
    P to G; M a_G = R - M g z_hat; I_G wdot + w x I_G w = r_GP x R + tau_r with r_GP = -s,
    I_G = A 1 + (B - A) e e^T and the couple tau_r = -mu_r R_z u (R_z = N). Six linear
    equations in wdot and R, solved as they stand."""
    e, w = v[2:5], v[8:11]
    z = np.array([0.0, 0.0, 1.0])
    s = c * e + z
    ig = A * np.eye(3) + (B - A) * np.outer(e, e)
    u = np.array([w[0], w[1], 0.0]) / math.sqrt(w[0] ** 2 + w[1] ** 2 + fixed.ROLLING_EPS ** 2)
    m = np.zeros((6, 6))
    rhs = np.zeros(6)
    m[:3, :3] = -_skew(s)  # a_G - R = -z:  -[s]x wdot - R = -z - w x (c w x e)
    m[:3, 3:] = -np.eye(3)
    rhs[:3] = -z - np.cross(w, c * np.cross(w, e))
    m[3:, :3] = ig  # I_G wdot + [s]x R + mu_r u R_z = -w x I_G w
    m[3:, 3:] = _skew(s) + mu_r * np.outer(u, z)
    rhs[3:] = -np.cross(w, ig @ w)
    sol = np.linalg.solve(m, rhs)
    return sol[:3], sol[3:], u


def resisted_rate(v, c, A, B, mu_r):
    """dv/dt of the fixed-frame state with the couple (`resisted_newton_euler`)."""
    e, b, w = v[2:5], v[5:8], v[8:11]
    wdot, _, _ = resisted_newton_euler(v, c, A, B, mu_r)
    vg = np.cross(w, c * e + np.array([0.0, 0.0, 1.0]))
    return np.concatenate([vg[:2], np.cross(w, e), np.cross(w, b), wdot])


def resisted_energy_and_power(v, c, A, B, mu_r):
    """(E, P): kinetic + potential energy of the fixed-frame state, and the power of the couple
    tau_r . w (non-dimensional)."""
    e, w = v[2:5], v[8:11]
    s = c * e + np.array([0.0, 0.0, 1.0])
    ig = A * np.eye(3) + (B - A) * np.outer(e, e)
    vg = np.cross(w, s)
    energy = 0.5 * w @ ig @ w + 0.5 * vg @ vg + (1.0 + c * e[2])
    _, r, u = resisted_newton_euler(v, c, A, B, mu_r)
    return energy, -mu_r * r[2] * (u @ w)


def fixed_frame_states(theta0_deg, thetadot0, chidot0, phidot0, chi0_deg, x0, y0, t,
                       ball: Ball, rtol=1e-11, atol=1e-13, rolling_resistance=0.0) -> np.ndarray:
    """Fixed-frame states (n, N_FIXED), non-dimensional, at times t (s from the launch), by
    solve_ivp's DOP853 on `physics.fixed.rhs`, or with rolling_resistance mu_r > 0 on
    `resisted_rate` (module docstring)."""
    from scipy.integrate import solve_ivp

    tu, a = ball.time_unit, ball.a
    u = np.array([x0 / a, y0 / a, math.radians(theta0_deg), math.radians(chi0_deg), 0.0,
                  thetadot0 * tu, chidot0 * tu, phidot0 * tu])
    v0 = fixed.euler_to_fixed(u)
    p = ball.nondim_params()
    buf = np.empty(fixed.N_FIXED)

    def f(_, v):
        if rolling_resistance:
            return resisted_rate(v, *p, rolling_resistance)
        fixed.rhs(v, p, buf)
        return buf.copy()

    t_nd = np.asarray(t, dtype=float) / tu
    sol = solve_ivp(f, (0.0, t_nd[-1]), v0, method="DOP853", t_eval=t_nd, rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"solve_ivp failed: {sol.message}")
    return sol.y.T


def synthetic_track(theta0_deg, thetadot0, chidot0, phidot0, *, chi0_deg=0.0, x0=0.0, y0=0.0,
                    T=3.0, fps=300.0, noise_m=0.0, noise_theta_deg=0.0, noise_chidot=0.0,
                    probe_m=None, ball: Ball | None = None, seed=0,
                    rolling_resistance=0.0) -> dict:
    """A track as a camera would give it: columns t (s), x, y (m, centre of mass; or x_tip,
    y_tip, x_base, y_base with probe_m), theta_deg (deg) and chidot (rad/s), sampled at fps for
    T seconds, with Gaussian noise of the given standard deviations.

    chidot is read from the axis as the camera reads it: the rate of the heading of e's
    horizontal part. rolling_resistance: the ball slows by the couple of that coefficient
    (module docstring)."""
    ball = ball or Ball.paper()
    t = np.arange(int(round(T * fps)) + 1) / fps
    v = fixed_frame_states(theta0_deg, thetadot0, chidot0, phidot0, chi0_deg, x0, y0, t, ball,
                           rolling_resistance=rolling_resistance)
    a, c, h = ball.a, ball.c, ball.cut_height
    e = v[:, fixed.EX:fixed.EZ + 1]
    e = e / np.linalg.norm(e, axis=1, keepdims=True)
    w = v[:, fixed.WX:fixed.WZ + 1]
    gx, gy = v[:, fixed.FX] * a, v[:, fixed.FY] * a
    rng = np.random.default_rng(seed)
    out = {"t": t}
    horiz = np.hypot(e[:, 0], e[:, 1])
    out["theta_deg"] = np.degrees(np.arctan2(-e[:, 2], horiz))
    edot = np.cross(w, e)  # de/dt = w x e (non-dimensional)
    out["chidot"] = (e[:, 0] * edot[:, 1] - e[:, 1] * edot[:, 0]) / horiz**2 / ball.time_unit
    if probe_m is None:
        out["x"], out["y"] = gx, gy
    else:
        d_face = c + a - h
        for name, d in (("base", d_face), ("tip", d_face + probe_m)):
            out[f"x_{name}"], out[f"y_{name}"] = gx - d * e[:, 0], gy - d * e[:, 1]
    for k in out:
        if k == "t":
            continue
        sd = {"theta_deg": noise_theta_deg, "chidot": noise_chidot}.get(k, noise_m)
        if sd:
            out[k] = out[k] + rng.normal(0.0, sd, t.size)
    return out

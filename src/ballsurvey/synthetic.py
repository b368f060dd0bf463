"""Synthetic measured tracks, made by other code than the engine's kernels: scipy's solve_ivp
(DOP853) on the fixed-frame Newton-Euler form (`physics.fixed`), which has no Euler angles, so a
fit of such a track with the Euler-angle kernel tests the fit against an independent model.

The probe's tip and base and the centre of mass are read from the integrated symmetry axis e and
G's position with the truncated ball's geometry (G at height a + c e_z, the face's centre
(c + a - cut_height) from G along -e, the tip probe_m further), as a camera above the table sees
them.
"""
from __future__ import annotations

import math

import numpy as np

from .ball import Ball
from .physics import fixed


def fixed_frame_states(theta0_deg, thetadot0, chidot0, phidot0, chi0_deg, x0, y0, t,
                       ball: Ball, rtol=1e-11, atol=1e-13) -> np.ndarray:
    """Fixed-frame states (n, N_FIXED), non-dimensional, at times t (s from the launch), by
    solve_ivp's DOP853 on `physics.fixed.rhs`."""
    from scipy.integrate import solve_ivp

    tu, a = ball.time_unit, ball.a
    u = np.array([x0 / a, y0 / a, math.radians(theta0_deg), math.radians(chi0_deg), 0.0,
                  thetadot0 * tu, chidot0 * tu, phidot0 * tu])
    v0 = fixed.euler_to_fixed(u)
    p = ball.nondim_params()
    buf = np.empty(fixed.N_FIXED)

    def f(_, v):
        fixed.rhs(v, p, buf)
        return buf.copy()

    t_nd = np.asarray(t, dtype=float) / tu
    sol = solve_ivp(f, (0.0, t_nd[-1]), v0, method="DOP853", t_eval=t_nd, rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"solve_ivp failed: {sol.message}")
    return sol.y.T


def synthetic_track(theta0_deg, thetadot0, chidot0, phidot0, *, chi0_deg=0.0, x0=0.0, y0=0.0,
                    T=3.0, fps=300.0, noise_m=0.0, noise_theta_deg=0.0, noise_chidot=0.0,
                    probe_m=None, ball: Ball | None = None, seed=0) -> dict:
    """A track as a camera would give it: columns t (s), x, y (m, centre of mass; or x_tip,
    y_tip, x_base, y_base with probe_m), theta_deg (deg) and chidot (rad/s), sampled at fps for
    T seconds, with Gaussian noise of the given standard deviations.

    chidot is read from the axis as the camera reads it: the rate of the heading of e's
    horizontal part."""
    ball = ball or Ball.paper()
    t = np.arange(int(round(T * fps)) + 1) / fps
    v = fixed_frame_states(theta0_deg, thetadot0, chidot0, phidot0, chi0_deg, x0, y0, t, ball)
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

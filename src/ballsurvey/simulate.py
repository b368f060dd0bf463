"""Single-launch API: one launch in SI units in, an xarray Dataset with its trajectory out.

A single launch is a chunk of one through the same ensemble kernel a sweep uses, with a trajectory
kept; it is labelled by the same observer and labeller, so a path and a map agree.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import xarray as xr

from . import limits
from .ball import Ball, tilt_error
from .classify.labels import CORNER_KINDS, LABELS, Thresholds
from .compose import METHODS, classify, run_resisted_trajectory, run_trajectory
from .integrate.outcome import FORMULATIONS
from .integrate.tableaus import ADAPTIVE, FIXED_STEP
from .physics.euler import contact, energy
from .physics.fast import S_CHD, S_CHI, S_CTH, S_PHD, S_PHI, S_STH, S_TH, S_THD, S_X, S_Y
from .physics.fixed import contact_fixed, euler_to_fixed
from .units import StepPlan, fields_to_si, launch_state

#: default probe length (m): the paper does not give its wire's length; one ball radius puts the
#: tip's path of Fig. 4a clearly outside the flat face's, as the paper draws it
PROBE_M = 0.0254


def body_points(x, y, theta, chi, ball: Ball, probe_m: float = PROBE_M) -> dict:
    """Points of the ball in the fixed frame (m) from G's position and the Euler angles (rad).

    The symmetry axis is eta = (-cos th sin chi, cos th cos chi, -sin th) (Eq. 3); G sits at
    height a - c sin th above the table (the contact point on the sphere), c from the
    geometric centre C along +eta. The flat face (a cap of height `cut_height` cut off on the
    -eta side) has its centre at C - (a - cut_height) eta; the probe stands on that centre
    along -eta, its base there and its tip probe_m further. The contact point is below C.

    Returns a dict of arrays: x_face, y_face, z_face, x_base, y_base, z_base (the probe's base,
    the face's centre), x_tip, y_tip, z_tip, x_contact, y_contact (its z is 0).
    """
    x, y, th, ch = (np.asarray(v, dtype=float) for v in (x, y, theta, chi))
    sth, cth, sch, cch = np.sin(th), np.cos(th), np.sin(ch), np.cos(ch)
    ex, ey, ez = -cth * sch, cth * cch, -sth
    a, c, h = ball.a, ball.c, ball.cut_height
    zg = a - c * sth
    out = {}
    for name, d in (("face", c + a - h), ("base", c + a - h), ("tip", c + a - h + probe_m),
                    ("contact", c)):
        out[f"x_{name}"], out[f"y_{name}"] = x - d * ex, y - d * ey
        if name != "contact":
            out[f"z_{name}"] = zg - d * ez
    return out


def contact_forces(s: np.ndarray, ball: Ball, rolling_resistance: float = 0.0) -> np.ndarray:
    """Net force on the ball (N) and torque about G (N m) along fast states s (n, N_FAST):
    columns Fx, Fy (friction, Eqs. 16-19), Fz = N - M g (Eq. 20), N, tau_x, tau_y, tau_z
    (Eqs. 21-24). With a rolling resistance mu_r > 0, those of the resisted equations
    (`physics.fixed.contact_fixed`), the torque with the rolling resistance's couple."""
    p = ball.nondim_params()
    out = np.empty((s.shape[0], 7))
    if rolling_resistance:
        p = np.append(p, float(rolling_resistance))
    for k, r in enumerate(s):
        if rolling_resistance:
            fx, fy, n, tx, ty, tz = contact_fixed(euler_to_fixed(r[:8]), p)
        else:
            fx, fy, n, tx, ty, tz = contact(r[:8], p)
        out[k] = fx, fy, n - 1.0, n, tx, ty, tz
    weight = ball.M * ball.g
    out[:, :4] *= weight
    out[:, 4:] *= weight * ball.a
    return out


def check_launch(theta0_deg, T, dt, ball: Ball) -> None:
    """Raise ValueError (one line, naming the input) for launches the model cannot take."""
    theta0_deg = limits.number("theta0_deg", theta0_deg)
    limits.steps(T, dt)
    problem = tilt_error(theta0_deg, math.degrees(ball.flat_face_theta_rad))
    if problem:
        raise limits.InputError(f"theta0_deg: {problem}")


def check_simulate_inputs(theta0_deg, thetadot0, chidot0, phidot0, T, dt, chi0_deg=0.0, x0=0.0,
                          y0=0.0, ball: Ball | None = None, n_out=2001, method="rk4", rtol=1e-9,
                          atol=1e-12) -> None:
    """Every input of `simulate` by the shared rules of `ballsurvey.limits` (InputError)."""
    for name, v in (("thetadot0", thetadot0), ("chidot0", chidot0), ("phidot0", phidot0),
                    ("chi0_deg", chi0_deg)):
        limits.launch_value(name, v)
    for name, v in (("x0", x0), ("y0", y0)):
        limits.number(name, v)
    check_launch(theta0_deg, T, dt, ball or Ball.paper())
    limits.samples(n_out)
    if method not in METHODS:
        raise limits.InputError(f"method: unknown method {method!r}; known: {', '.join(METHODS)}")
    limits.tolerances(rtol, atol)


def _sample_times(t: np.ndarray, T: float, n: int) -> np.ndarray:
    """The sample times: k T / (n - 1) computed so (0.005, not 0.004999999999999999) where the
    samples are evenly spaced over T, as the fixed-step and dense-output samples are; `t` as it
    came where it is not (a run that stopped early)."""
    even = (np.arange(len(t)) * float(T)) / (n - 1) if n > 1 else t
    if len(t) == n and np.allclose(even, t, rtol=0, atol=1e-9 * max(1.0, float(T))):
        return even
    return t


def simulate(theta0_deg: float, thetadot0: float, chidot0: float, phidot0: float, T: float,
             dt: float = 1e-4, chi0_deg: float = 0.0, x0: float = 0.0, y0: float = 0.0,
             ball: Ball | None = None, n_out: int = 2001, method: str = "rk4",
             thresholds: Thresholds | None = None, rtol: float = 1e-9,
             atol: float = 1e-12, probe_m: float = PROBE_M,
             rolling_resistance: float = 0.0) -> xr.Dataset:
    """Integrate one launch and return its trajectory, labelled like a map's launch.

    Parameters
    ----------
    theta0_deg : float
        Initial tilt of the symmetry axis (deg): 0 has the axis horizontal, positive tips the
        centre of mass down (its height is a - c sin theta); |theta0| < 90 and the flat face
        off the table (theta0 above -31.8 deg for the paper's ball).
    thetadot0 : float
        Initial rate of tilt (rad/s).
    chidot0 : float
        Initial rate of heading, the precession rate (rad/s).
    phidot0 : float
        Initial spin rate (rad/s).
    T : float
        Duration (s).
    dt : float
        Fixed-step methods: the largest step (s); the step used is T/N for the smallest N >=
        T/dt that is a multiple of n_out - 1, so the samples fall exactly on steps. Adaptive:
        the first trial step is T / ceil(T/dt).
    chi0_deg : float
        Initial heading (deg).
    x0 : float
        Initial x of the centre of mass (m).
    y0 : float
        Initial y of the centre of mass (m).
    ball : Ball, optional
        The ball (default: the paper's truncated billiard ball).
    n_out : int
        Samples kept, evenly spaced from 0 to T.
    method : str
        rk4, rk38, ssprk3, heun (fixed step) or dopri5 / adaptive (with rtol, atol; samples from
        the pair's dense output).
    thresholds : Thresholds, optional
        The classifier's thresholds (default: `Thresholds()`).
    rtol : float
        Relative tolerance of the adaptive method.
    atol : float
        Absolute tolerance of the adaptive method.
    probe_m : float
        Length (m) of the probe on the flat face, along the symmetry axis (0: its tip is the
        face's centre).
    rolling_resistance : float
        The rolling-resistance coefficient mu_r (dimensionless, 0 to 1): a couple of magnitude
        mu_r N a opposing the rolling (docs/physics.md, "Rolling resistance"); 0 (the default):
        the rolling model without it, as the paper has it. Above 0 the launch is integrated in
        the fixed frame by the adaptive pair (dopri5 with rtol, atol, whatever `method` names a
        fixed-step one: attrs method says which), the energy falls as the couple dissipates it,
        and the label is not marked inaccurate for that fall.

    Returns
    -------
    xarray.Dataset
        On `time` (s): x, y (m); theta_deg, chi_deg, phi_deg (deg) and the same angles theta,
        chi, phi in rad (as the equations use them); thetadot, chidot, phidot (rad/s); energy
        (J); friction_ratio (|F_h|/N: the launch slips where it exceeds mu) and normal_force
        (N, lifts off where <= 0); the body points (m) of `body_points`: x_face .. z_face, the
        probe's x_base .. z_base and x_tip .. z_tip, x_contact, y_contact; the net force Fx,
        Fy, Fz (= N - M g) (N) and the torque about G tau_x, tau_y, tau_z (N m) of
        `contact_forces`. Its attrs hold the label, the classifier's fields in SI
        (as in a map), the launch, the method and step used, and the ball (`ball_a`, ...).

    Notes
    -----
    A launch whose tilt reaches 90 deg (the Euler form's singularity) is integrated again in the
    fixed-frame form (attrs formulation = "fixed_frame"), with the map's fallback settings. At a
    sample where the symmetry axis is within 1e-9 rad of the vertical the Euler angles and their
    rates are not defined: that sample's angles, rates, energy, body points and forces are NaN
    (the centre's x, y and the label's fields are not affected).
    Inputs are checked by the rules of `ballsurvey.limits`: a bad one raises InputError.

    Examples
    --------
    >>> ds = ballsurvey.simulate(theta0_deg=-5, thetadot0=0, chidot0=4.05, phidot0=-3, T=20)
    >>> ds.attrs["label"], round(ds.attrs["n_sides"], 2)   # the paper's Fig. 12a
    ('square', 4.0)
    """
    ball = ball or Ball.paper()
    check_simulate_inputs(theta0_deg, thetadot0, chidot0, phidot0, T, dt, chi0_deg, x0, y0, ball,
                          n_out, method, rtol, atol)
    probe_m = limits.number("probe_m", probe_m, lo=0.0, hi=1.0)
    mu_r = limits.rolling_resistance(rolling_resistance)
    tu, a = ball.time_unit, ball.a
    th = thresholds or Thresholds()
    p = ball.nondim_params()
    y_init = launch_state(theta0_deg, thetadot0, chidot0, phidot0, tu, chi0_deg=chi0_deg, x0=x0,
                          y0=y0, length_unit=a)
    if mu_r > 0.0:  # the resisted equations: fixed frame, adaptive; energy falls by design
        method = method if method in ADAPTIVE else "dopri5"
        th = dataclasses.replace(th, max_energy_drift=math.inf)
    fixed = method in FIXED_STEP
    plan = StepPlan(T, dt, tu, multiple=n_out - 1 if fixed else 1)
    if mu_r > 0.0:
        res = run_resisted_trajectory(y_init[:, 0], p, mu_r, plan.T_nd,
                                      t_out=np.linspace(0.0, plan.T_nd, n_out), method=method,
                                      rtol=rtol, atol=atol)
    else:
        res = run_trajectory(y_init[:, 0], p, plan, method, n_out=n_out, rtol=rtol, atol=atol,
                             thresholds=th)
    t_nd, s = res.t, res.traj
    formulation = FORMULATIONS[int(res.formulation[0])]
    dt_used = plan.dt_nd * tu if fixed else math.nan
    e = np.array([energy(r[S_STH], r[S_CTH], r[S_THD], r[S_CHD], r[S_PHD], *p) for r in s])
    forces = contact_forces(s, ball, mu_r)  # Fx, Fy, Fz, N (N), tau_x, tau_y, tau_z (N m)
    with np.errstate(divide="ignore", invalid="ignore"):
        fric = np.where(forces[:, 3] > 0.0, np.hypot(forces[:, 0], forces[:, 1]) / forces[:, 3],
                        np.inf)
    f = fields_to_si(classify(res, ball.flat_face_theta_rad, th), a, tu, ball.M)

    def var(values, units, long_name):
        return ("time", values, {"units": units, "long_name": long_name})

    ds = xr.Dataset(
        {
            "x": var(s[:, S_X] * a, "m", "x of the centre of mass"),
            "y": var(s[:, S_Y] * a, "m", "y of the centre of mass"),
            "theta": var(s[:, S_TH], "rad", "tilt of the symmetry axis (Euler angle theta)"),
            "chi": var(s[:, S_CHI], "rad", "heading of the horizontal axis xi (Euler angle chi)"),
            "phi": var(s[:, S_PHI], "rad", "spin angle about the symmetry axis (Euler angle phi)"),
            "thetadot": var(s[:, S_THD] / tu, "rad s-1", "rate of theta"),
            "chidot": var(s[:, S_CHD] / tu, "rad s-1", "rate of chi (precession)"),
            "phidot": var(s[:, S_PHD] / tu, "rad s-1", "rate of phi (spin)"),
            "theta_deg": var(np.degrees(s[:, S_TH]), "degree", "tilt theta in degrees"),
            "chi_deg": var(np.degrees(s[:, S_CHI]), "degree", "heading chi in degrees"),
            "phi_deg": var(np.degrees(s[:, S_PHI]), "degree", "spin angle phi in degrees"),
            "energy": var(e * ball.M * ball.g * a, "J",
                          "kinetic plus potential energy, Eqs. (11)-(12)"),
            "friction_ratio": var(fric, "1", "friction demand |F_h|/N (slips where above mu)"),
            "normal_force": var(forces[:, 3], "N",
                                "normal force of the table N, Eq. (20) (lifts off where <= 0)"),
        },
        coords={"time": ("time", _sample_times(t_nd * tu, T, n_out),
                         {"units": "s", "long_name": "time", "standard_name": "time"})},
    )
    pts = body_points(ds.x.values, ds.y.values, ds.theta.values, ds.chi.values, ball, probe_m)
    where = {"face": "the centre of the flat face", "base": "the probe's base (the face's centre)",
             "tip": "the probe's tip", "contact": "the contact point"}
    for k, v in pts.items():
        ds[k] = var(v, "m", f"{k[0]} of {where[k.split('_')[1]]}")
    # contact_forces' columns; its fourth, the normal force N, is the variable normal_force
    for k, (j, units, long_name) in {
            "Fx": (0, "N", "net force along x (friction), Eqs. (16)-(19)"),
            "Fy": (1, "N", "net force along y (friction), Eqs. (16)-(19)"),
            "Fz": (2, "N", "net vertical force N - M g, Eq. (20)"),
            "tau_x": (4, "N m", "torque about G along x, Eqs. (21)-(24)"),
            "tau_y": (5, "N m", "torque about G along y, Eqs. (21)-(24)"),
            "tau_z": (6, "N m", "torque about G along z, Eqs. (21)-(24)")}.items():
        ds[k] = var(forces[:, j], units, long_name)
    label = LABELS[int(f.pop("label")[0])]
    kind = CORNER_KINDS[int(f.pop("corner_kind")[0])]
    f.pop("formulation")
    f.pop("t_stop_s")
    ds.attrs.update({k: v[0].item() for k, v in f.items()})
    ds.attrs.update(label=label, corner_kind=kind, dt_s=dt_used, method=method,
                    formulation=formulation, theta0_deg=theta0_deg, thetadot0=thetadot0,
                    chidot0=chidot0, phidot0=phidot0, chi0_deg=chi0_deg, T_s=T,
                    probe_m=probe_m, rolling_resistance=mu_r)
    if method in ADAPTIVE:
        ds.attrs.update(rtol=rtol, atol=atol)
    ds.attrs.update({f"ball_{k}": v for k, v in ball.as_dict().items()})
    return ds

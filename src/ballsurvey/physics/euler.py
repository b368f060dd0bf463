"""Equations of motion in Euler angles, non-dimensional (a = g = M = 1).

State u = (x, y, theta, chi, phi, thetadot, chidot, phidot) (paper Eq. 43). Built from the
corrected equations (docs/physics.md): Eqs. (6)-(7), (13)-(15) in the form (B1)-(B5).
Parameters p = (c, A, B) from `Ball.nondim_params`.

Every function here is a jitted scalar function of plain floats so the ensemble kernel can inline
it.
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit, sqrt

# indices into the Euler-angle state vector (paper Eq. 43)
X, Y, TH, CHI, PHI, THD, CHD, PHD = range(8)
N_EULER = 8

jit = njit(cache=True, nogil=True, error_model="numpy")  # stamped cache: _jit.py


@jit
def accelerations(sth, cth, thd, chd, phd, c, A, B):
    """(thetaddot, chiddot, phiddot) from Eq. (B1) and the 2x2 system (B2)-(B5).

    Takes sin(theta) and cos(theta) rather than theta so callers can carry them as state.
    Singular only at cos(theta) = 0 (det Gamma = cos^2 theta [...], docs/physics.md section 7).
    """
    a1 = 1.0 - c * sth  # a' = a - c sin(theta)
    thdd = cth / (A + 1.0 - 2.0 * c * sth + c * c) * (
        c * thd * thd + ((B - A) * sth + c * a1) * chd * chd - (B + a1) * phd * chd + c
    )
    c2 = cth * cth
    g11 = (A + c * c) * c2 + B * sth * sth
    g12 = -B * sth - c * c2
    g22 = B + c2
    h1 = cth * (-(2.0 * (B - A - c * c) * sth + c) * thd * chd + (B - c * sth) * thd * phd)
    h2 = cth * ((B - 2.0 * c * sth + 1.0) * thd * chd + sth * thd * phd)
    det = g11 * g22 - g12 * g12
    chdd = (g22 * h1 - g12 * h2) / det
    phdd = (g11 * h2 - g12 * h1) / det
    return thdd, chdd, phdd


@jit
def heading_velocity(sth, cth, thd, chd, phd, c):
    """(u, w): G's velocity along xi (horizontal, heading chi) and along the horizontal normal
    to xi, Eqs. (6)-(7) in the frame turning with chi."""
    return (phd - c * chd) * cth, (1.0 - c * sth) * thd


@jit
def centre_velocity(sth, cth, sch, cch, thd, chd, phd, c):
    """(xdot, ydot) of the centre of mass G, Eqs. (6)-(7) (Eq. 7 with its dots restored)."""
    u, w = heading_velocity(sth, cth, thd, chd, phd, c)
    return u * cch - w * sch, u * sch + w * cch


@jit
def normal_force(sth, cth, thd, thdd, c):
    """N / (M g) = 1 + zddot of G (z_G = a - c sin theta), Eq. (20)."""
    return 1.0 + c * (sth * thd * thd - cth * thdd)


@jit
def rhs(u, p, out):
    """du/dt for the 8-component Euler-angle state (paper Eqs. 43-44)."""
    c, A, B = p[0], p[1], p[2]
    sth, cth = math.sin(u[TH]), math.cos(u[TH])
    sch, cch = math.sin(u[CHI]), math.cos(u[CHI])
    thd, chd, phd = u[THD], u[CHD], u[PHD]
    out[X], out[Y] = centre_velocity(sth, cth, sch, cch, thd, chd, phd, c)
    out[TH], out[CHI], out[PHI] = thd, chd, phd
    out[THD], out[CHD], out[PHD] = accelerations(sth, cth, thd, chd, phd, c, A, B)


@jit
def kinetic(sth, cth, thd, chd, phd, c, A, B):
    """T, the kinetic energy of Eq. (11)."""
    w_eta = phd - chd * sth
    t = 0.5 * A * (thd * thd + chd * chd * cth * cth) + 0.5 * B * w_eta * w_eta
    return t + 0.5 * ((phd - c * chd) ** 2 * cth * cth + (1.0 - 2.0 * c * sth + c * c) * thd * thd)


@jit
def energy(sth, cth, thd, chd, phd, c, A, B):
    """E = T + V, Eqs. (11)-(12) (V = M g (a - c sin theta), corrected)."""
    return kinetic(sth, cth, thd, chd, phd, c, A, B) + (1.0 - c * sth)


@jit
def jellett(sth, cth, thd, chd, phd, c, A, B):
    """Jellett's integral J = L_G . r_GP (docs/physics.md section 6); L_G from Eq. (2), r_GP from
    Eq. (5).

    In the (xi, eta, zeta) frame r_GP = (0, a sin(theta) - c, -a cos(theta)).
    """
    w_eta = phd - chd * sth
    return B * w_eta * (sth - c) - A * chd * cth * cth


@jit
def routh(sth, cth, thd, chd, phd, c, A, B):
    """Routh's integral w_eta sqrt(A B + A M a^2 cos^2 th + B M (a sin th - c)^2)
    (docs/physics.md)."""
    w_eta = phd - chd * sth
    return w_eta * sqrt(A * B + A * cth * cth + B * (sth - c) ** 2)


@jit
def contact(u, p):
    """Contact force and torque about G, non-dimensional (force / M g, torque / M g a).

    Returns (Fx, Fy, N, tau_x, tau_y, tau_z): friction Fx = M xddot, Fy = M yddot (Eqs. 16-19),
    normal N = M (g + zddot) (Eq. 20 and N - M g = F_z), torque Eqs. (21)-(24).
    """
    c, A, B = p[0], p[1], p[2]
    sth, cth = math.sin(u[TH]), math.cos(u[TH])
    sch, cch = math.sin(u[CHI]), math.cos(u[CHI])
    thd, chd, phd = u[THD], u[CHD], u[PHD]
    thdd, chdd, phdd = accelerations(sth, cth, thd, chd, phd, c, A, B)
    a1 = 1.0 - c * sth
    xdd = ((phdd - c * chdd) * cth * cch - (phd - c * chd) * (sth * cch * thd + cth * sch * chd)
           + c * cth * sch * thd * thd - a1 * (sch * thdd + cch * thd * chd))
    ydd = ((phdd - c * chdd) * cth * sch + (phd - c * chd) * (-sth * sch * thd + cth * cch * chd)
           - c * cth * cch * thd * thd + a1 * (cch * thdd - sch * thd * chd))
    n = normal_force(sth, cth, thd, thdd, c)
    tau_x = -n * c * cth * cch - ydd * (-1.0 + c * sth)
    tau_y = xdd * (-1.0 + c * sth) - n * c * cth * sch
    tau_z = c * cth * (ydd * sch + xdd * cch)
    return xdd, ydd, n, tau_x, tau_y, tau_z


def invariants(u: np.ndarray, p: np.ndarray) -> tuple[float, float, float]:
    """(energy, Jellett, Routh) of one Euler state, non-dimensional."""
    sth, cth = math.sin(u[TH]), math.cos(u[TH])
    args = (sth, cth, u[THD], u[CHD], u[PHD], p[0], p[1], p[2])
    return energy(*args), jellett(*args), routh(*args)

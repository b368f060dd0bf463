"""The fast Euler state the kernels integrate: the Euler-angle state with sin and cos of theta and
chi carried beside the angles (their derivatives are products with thetadot and chidot), so the
right-hand side is pure arithmetic, with no scalar library calls (which stop LLVM vectorising).

    fast state: x, y, theta, chi, phi, thetadot, chidot, phidot, sin th, cos th, sin chi, cos chi

Non-dimensional (lengths / a, times / sqrt(a/g)). The formulas are those of `euler.py`.
"""
from __future__ import annotations

import numpy as np

from .._jit import njit
from .euler import accelerations, centre_velocity
from .fixed import BX, BY, BZ, FX, FY, axis_spin_into, euler_to_fixed_into, fixed_to_euler_scalars

N_FAST = 12
(S_X, S_Y, S_TH, S_CHI, S_PHI, S_THD, S_CHD, S_PHD,
 S_STH, S_CTH, S_SCH, S_CCH) = range(N_FAST)

jit = njit(cache=True, nogil=True, error_model="numpy")  # stamped cache: _jit.py


def fast_state(x, y, theta, chi, phi, thetadot, chidot, phidot) -> np.ndarray:
    """Build the (N_FAST, n) fast state from non-dimensional launch arrays (broadcast)."""
    cols = np.broadcast_arrays(*[np.asarray(v, dtype=np.float64)
                                 for v in (x, y, theta, chi, phi, thetadot, chidot, phidot)])
    n = cols[0].size
    s = np.empty((N_FAST, n))
    for k, col in enumerate(cols):
        s[k] = col.ravel()
    s[S_STH], s[S_CTH] = np.sin(s[S_TH]), np.cos(s[S_TH])
    s[S_SCH], s[S_CCH] = np.sin(s[S_CHI]), np.cos(s[S_CHI])
    return s


@jit
def fast_rhs(s, c, A, B):
    """Right-hand side on the fast state tuple: Eqs. (6)-(7) and (B1)-(B5), pure arithmetic."""
    sth, cth, sch, cch = s[S_STH], s[S_CTH], s[S_SCH], s[S_CCH]
    thd, chd, phd = s[S_THD], s[S_CHD], s[S_PHD]
    xd, yd = centre_velocity(sth, cth, sch, cch, thd, chd, phd, c)
    thdd, chdd, phdd = accelerations(sth, cth, thd, chd, phd, c, A, B)
    return (xd, yd, thd, chd, phd, thdd, chdd, phdd,
            cth * thd, -sth * thd, cch * chd, -sch * chd)


@jit
def fast_rhs_into(y, p, out):
    """fast_rhs on an array state y (N_FAST,), parameters p = (c, A, B), into out."""
    r = fast_rhs((y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7], y[8], y[9], y[10], y[11]),
                 p[0], p[1], p[2])
    for q in range(N_FAST):
        out[q] = r[q]


@jit
def fixed_from_fast_into(y, out):
    """Fast Euler state y -> fixed-frame state in `out` (`fixed.euler_to_fixed_into`)."""
    euler_to_fixed_into(y[S_X], y[S_Y], y[S_STH], y[S_CTH], y[S_SCH], y[S_CCH], y[S_PHI],
                        y[S_THD], y[S_CHD], y[S_PHD], out)


@jit
def observed_fixed_from_fast_into(y, out):
    """`fixed_from_fast_into` without the body vector b (left 0): an observer of the path and
    the axis reads e, w and G only, and b would cost the sine and cosine of phi."""
    axis_spin_into(y[S_X], y[S_Y], y[S_STH], y[S_CTH], y[S_SCH], y[S_CCH], y[S_THD], y[S_CHD],
                   y[S_PHD], out)
    out[BX] = 0.0
    out[BY] = 0.0
    out[BZ] = 0.0


@jit
def fast_from_fixed_into(v, chi_ref, phi_ref, out):
    """Fixed-frame state v -> fast Euler state in `out` (`fixed.fixed_to_euler_scalars`: chi and
    phi on the branches nearest the refs). Returns False, leaving `out` alone, where the chart
    is degenerate (the axis vertical)."""
    ok, th, ch, ph, thd, chd, phd, sth, cth, sch, cch = fixed_to_euler_scalars(v, chi_ref, phi_ref)
    if not ok:
        return False
    out[S_X], out[S_Y], out[S_TH], out[S_CHI], out[S_PHI] = v[FX], v[FY], th, ch, ph
    out[S_THD], out[S_CHD], out[S_PHD] = thd, chd, phd
    out[S_STH], out[S_CTH], out[S_SCH], out[S_CCH] = sth, cth, sch, cch
    return True

"""Equations of motion without Euler angles (Newton-Euler in the fixed frame), non-dimensional.

State v = (x, y, e_x, e_y, e_z, b_x, b_y, b_z, w_x, w_y, w_z): G's horizontal position, the symmetry
axis e (= eta, pointing from C towards G), a body-fixed unit vector b normal to e (b = xi when
phi = 0), and the angular velocity w, all in the fixed frame Oxyz.

Derivation (independent of the paper's Lagrangian one): with s = r_PG = c e + a z_hat the vector
from the contact point P to G, rolling gives v_G = w x s and a_G = wdot x s + w x (c w x e). The
reaction R at P satisfies M a_G = R - M g z_hat, and dL_G/dt = I_G wdot + w x (I_G w) = -s x R.
Eliminating R:

    [I_G + M (|s|^2 1 - s s^T)] wdot = -w x (I_G w) - M s x (c w x (w x e) + g z_hat).

The matrix is the inertia about the contact point, positive definite for every orientation, so this
form has no singularity at theta = +-90 deg.
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit
from .euler import CHD, CHI, N_EULER, PHD, PHI, TH, THD, X, Y

N_FIXED = 11
FX, FY, EX, EY, EZ, BX, BY, BZ, WX, WY, WZ = range(N_FIXED)

jit = njit(cache=True, nogil=True, error_model="numpy")  # stamped cache: _jit.py


@jit
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@jit
def rhs(v, p, out):
    """dv/dt for the fixed-frame state array v, parameters p = (c, A, B), into out; with a
    fourth parameter mu_r = p[3] (not 0), the rolling resistance's torque too
    (`rhs_resisted_tuple`)."""
    vt = (v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], v[9], v[10])
    if p.shape[0] > 3 and p[3] != 0.0:
        d = rhs_resisted_tuple(vt, p[0], p[1], p[2], p[3])
    else:
        d = rhs_tuple(vt, p[0], p[1], p[2])
    for q in range(N_FIXED):
        out[q] = d[q]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")  # inlined as rhs_tuple is
def _contact_inertia_cofactors(ex, ey, ez, c, A, B):
    """The inertia about the contact point K = A 1 + (B - A) e e^T + |s|^2 1 - s s^T (s = c e +
    z_hat) as its cofactors and determinant (c00, c01, c02, c11, c12, c22, det): K^-1 r is
    (c00 r0 + c01 r1 + c02 r2, c01 r0 + c11 r1 + c12 r2, c02 r0 + c12 r1 + c22 r2) / det
    (K is symmetric positive definite)."""
    sx, sy, sz = c * ex, c * ey, c * ez + 1.0
    s2 = sx * sx + sy * sy + sz * sz
    d = B - A
    k00 = A + d * ex * ex + s2 - sx * sx
    k11 = A + d * ey * ey + s2 - sy * sy
    k22 = A + d * ez * ez + s2 - sz * sz
    k01 = d * ex * ey - sx * sy
    k02 = d * ex * ez - sx * sz
    k12 = d * ey * ez - sy * sz
    c00 = k11 * k22 - k12 * k12
    c01 = k02 * k12 - k01 * k22
    c02 = k01 * k12 - k02 * k11
    c11 = k00 * k22 - k02 * k02
    c12 = k01 * k02 - k00 * k12
    c22 = k00 * k11 - k01 * k01
    det = k00 * c00 + k01 * c01 + k02 * c02
    return c00, c01, c02, c11, c12, c22, det


# inlined by numba itself: LLVM's inliner finds it too big, and a call in a loop over launches stops
# the loop vectorising (measured: the SIMD-lane kernel's step loop stayed scalar)
@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def rhs_tuple(v, c, A, B):
    """dv/dt for the fixed-frame state (module docstring), on a tuple of plain floats and returned
    as one: pure arithmetic, so a kernel that loops over launches can vectorise it."""
    ex, ey, ez = v[EX], v[EY], v[EZ]
    wx, wy, wz = v[WX], v[WY], v[WZ]
    sx, sy, sz = c * ex, c * ey, c * ez + 1.0  # s = c e + z_hat
    d = B - A
    ew = ex * wx + ey * wy + ez * wz
    lx, ly, lz = A * wx + d * ew * ex, A * wy + d * ew * ey, A * wz + d * ew * ez  # I_G w
    gx, gy, gz = _cross(wx, wy, wz, lx, ly, lz)
    wex, wey, wez = _cross(wx, wy, wz, ex, ey, ez)  # w x e = edot
    qx, qy, qz = _cross(wx, wy, wz, wex, wey, wez)  # w x (w x e)
    qx, qy, qz = c * qx, c * qy, c * qz + 1.0
    tx, ty, tz = _cross(sx, sy, sz, qx, qy, qz)
    r0, r1, r2 = -gx - tx, -gy - ty, -gz - tz
    c00, c01, c02, c11, c12, c22, det = _contact_inertia_cofactors(ex, ey, ez, c, A, B)
    vx, vy = centre_velocity(v, c)
    bx, by, bz = _cross(wx, wy, wz, v[BX], v[BY], v[BZ])
    return (vx, vy, wex, wey, wez, bx, by, bz,
            (c00 * r0 + c01 * r1 + c02 * r2) / det,
            (c01 * r0 + c11 * r1 + c12 * r2) / det,
            (c02 * r0 + c12 * r1 + c22 * r2) / det)


#: the rolling resistance's regularisation (non-dimensional angular speed, in units of
#: sqrt(g / a): 0.0197 rad/s for the paper's ball): the torque's direction is
#: w_h / sqrt(|w_h|^2 + ROLLING_EPS^2), so it turns smoothly through a standstill of the rolling
ROLLING_EPS = 1e-3


@jit
def rolling_direction(wx, wy):
    """(u_x, u_y) = w_h / sqrt(|w_h|^2 + ROLLING_EPS^2): the regularised unit vector of the
    rolling part w_h = (w_x, w_y, 0) of the angular velocity."""
    inv = 1.0 / math.sqrt(wx * wx + wy * wy + ROLLING_EPS * ROLLING_EPS)
    return wx * inv, wy * inv


@jit
def rhs_resisted_tuple(v, c, A, B, mu_r):
    """`rhs_tuple` with the rolling resistance: a couple tau_r = -mu_r N a u (u from
    `rolling_direction`, N the normal force) on the ball, opposing its rolling.

    With tau_r added, K wdot = r + tau_r, where K wdot0 = r is the motion without it
    (`rhs_tuple`). N = M (g + c e_z'') depends on wdot through e_z'' = (wdot x e + w x
    edot)_z; N is linear in wdot, so the system stays linear: with k = K^-1 u,
    wdot = wdot0 - mu_r N k and N = N0 / (1 + mu_r c (k x e)_z), N0 the normal force of wdot0
    (non-dimensional: N / (M g), tau_r / (M g a)). The rest of the rate (G's velocity, edot,
    bdot) is kinematic and does not change."""
    d = rhs_tuple(v, c, A, B)
    ex, ey, ez = v[EX], v[EY], v[EZ]
    wx, wy = v[WX], v[WY]
    ux, uy = rolling_direction(wx, wy)
    c00, c01, c02, c11, c12, c22, det = _contact_inertia_cofactors(ex, ey, ez, c, A, B)
    kx, ky, kz = (c00 * ux + c01 * uy) / det, (c01 * ux + c11 * uy) / det, (
        c02 * ux + c12 * uy) / det
    # N0 = 1 + c e_z'' of the motion without the couple (`centre_acceleration`)
    ezdd = (d[WX] * ey - d[WY] * ex) + (wx * d[EY] - wy * d[EX])
    n = (1.0 + c * ezdd) / (1.0 + mu_r * c * (kx * ey - ky * ex))
    m = mu_r * n
    return (d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7],
            d[WX] - m * kx, d[WY] - m * ky, d[WZ] - m * kz)


@jit
def rolling_torque(v, dv, c, mu_r):
    """(tau_x, tau_y, tau_z, power): the rolling resistance's couple tau_r = -mu_r N a u
    (`rhs_resisted_tuple`) on a fixed-frame state with its rate dv, and the power it
    dissipates tau_r . w (<= 0), non-dimensional (/ M g a, / M g a sqrt(g / a))."""
    _, _, ezdd = centre_acceleration(v, dv, c)
    ux, uy = rolling_direction(v[WX], v[WY])
    m = mu_r * (1.0 + c * ezdd)
    tx, ty = -m * ux, -m * uy
    return tx, ty, 0.0, tx * v[WX] + ty * v[WY]


@jit
def contact_fixed(v, p):
    """The table's force and torque about G on a fixed-frame state, non-dimensional (force /
    M g, torque / M g a), as `euler.contact` gives them (Fx, Fy, N, tau_x, tau_y, tau_z) but
    chart-free and with the rolling resistance of p[3] where p has it: the reaction
    R = M a_G + M g z_hat at the contact point P (a_G from `centre_acceleration`), its torque
    about G -s x R (s = c e + z_hat, from P to G), plus the couple tau_r."""
    dv = np.empty(N_FIXED)
    rhs(v, p, dv)
    c = p[0]
    ax, ay, ezdd = centre_acceleration(v, dv, c)
    rz = 1.0 + c * ezdd
    sx, sy, sz = c * v[EX], c * v[EY], c * v[EZ] + 1.0
    tx, ty, tz = _cross(sx, sy, sz, ax, ay, rz)
    if p.shape[0] > 3 and p[3] != 0.0:
        rx, ry, rzz, _ = rolling_torque(v, dv, c, p[3])
        return ax, ay, rz, rx - tx, ry - ty, rzz - tz
    return ax, ay, rz, -tx, -ty, -tz


def energy(v: np.ndarray, p: np.ndarray) -> float:
    """Kinetic + potential energy of a fixed-frame state (non-dimensional)."""
    c, A, B = p
    e, w = v[EX:EZ + 1], v[WX:WZ + 1]
    s = c * e + np.array([0.0, 0.0, 1.0])
    vg = np.cross(w, s)
    ew = e @ w
    rot = 0.5 * (A * (w @ w - ew * ew) + B * ew * ew)
    return rot + 0.5 * vg @ vg + (1.0 + c * e[2])


#: |cos theta| below which the Euler angles are not read from a fixed-frame state (chart edge)
CHART_MIN_COS = 1e-9


@jit
def centre_velocity(v, c):
    """(xdot, ydot) of G: v_G = w x s with s = c e + z_hat (module docstring)."""
    vx, vy, _ = _cross(v[WX], v[WY], v[WZ], c * v[EX], c * v[EY], c * v[EZ] + 1.0)
    return vx, vy


@jit
def centre_acceleration(v, dv, c):
    """(a_x, a_y, e_z'') from a fixed-frame state and its rate: G's horizontal acceleration
    a_G = wdot x s + c w x edot and the axis's vertical acceleration e_z'' = (wdot x e + w x
    edot)_z; G's vertical acceleration is c e_z'' (z_G = 1 + c e_z), so N / (M g) = 1 + c e_z''."""
    ex, ey, ez = v[EX], v[EY], v[EZ]
    wx, wy, wz = v[WX], v[WY], v[WZ]
    sx, sy, sz = c * ex, c * ey, c * ez + 1.0
    edx, edy, edz = dv[EX], dv[EY], dv[EZ]
    ax = (dv[WY] * sz - dv[WZ] * sy) + c * (wy * edz - wz * edy)
    ay = (dv[WZ] * sx - dv[WX] * sz) + c * (wz * edx - wx * edz)
    ezdd = (dv[WX] * ey - dv[WY] * ex) + (wx * edy - wy * edx)
    return ax, ay, ezdd


@jit
def path_kinematics(v, dv, c):
    """Heading rate of the path, |F_h|/N and N/(M g) from a fixed-frame state and its rate,
    with no Euler chart: v_G = w x s, a_G = wdot x s + w x (c w x e), N / (M g) = 1 + a_G,z."""
    vx, vy = centre_velocity(v, c)
    ax, ay, ezdd = centre_acceleration(v, dv, c)
    v2 = vx * vx + vy * vy
    psid = (vx * ay - vy * ax) / v2 if v2 > 0.0 else 0.0
    normal = 1.0 + c * ezdd
    fric = math.sqrt(ax * ax + ay * ay) / normal if normal > 0.0 else math.inf
    return psid, fric, normal


@jit
def invariants(v, dv, c, A, B):
    """(energy, Jellett, Routh) of a fixed-frame state, non-dimensional, with G's velocity read
    from the state's rate dv (x', y', and c e_z' vertically): E = rotational + translational +
    potential (1 + c e_z); Jellett's J = L_G . r_GP = -L_G . s with L_G = A w + (B - A)(e.w) e;
    Routh's (e.w) sqrt(A B + A |e_h|^2 + B (e_z + c)^2). The same integrals as the Euler forms in
    `euler.py` (there sin theta = -e_z, omega_eta = e.w)."""
    ex, ey, ez = v[EX], v[EY], v[EZ]
    wx, wy, wz = v[WX], v[WY], v[WZ]
    ew = ex * wx + ey * wy + ez * wz
    ww = wx * wx + wy * wy + wz * wz
    vx, vy, vz = dv[FX], dv[FY], c * dv[EZ]
    e = 0.5 * (A * (ww - ew * ew) + B * ew * ew + vx * vx + vy * vy + vz * vz) + 1.0 + c * ez
    jel = -(A * (c * ew + wz) + (B - A) * ew * (c + ez))
    eh2 = ex * ex + ey * ey
    rou = ew * math.sqrt(A * B + A * eh2 + B * (ez + c) * (ez + c))
    return e, jel, rou


@jit
def euler_to_fixed_into(x, y, sth, cth, sch, cch, ph, thd, chd, phd, out):
    """Euler state (Eq. 43, with sin and cos of theta and chi given) -> fixed-frame state in
    `out`. Eq. (3) gives the frame xi, eta, zeta; Eq. (1) the angular velocity."""
    axis_spin_into(x, y, sth, cth, sch, cch, thd, chd, phd, out)
    # phi is the angle of the body about eta, from xi (right-handed about eta: xi -> -zeta)
    cph, sph = math.cos(ph), math.sin(ph)
    ze0, ze1, ze2 = -sth * sch, sth * cch, cth
    out[BX], out[BY], out[BZ] = cph * cch - sph * ze0, cph * sch - sph * ze1, -sph * ze2


@jit
def axis_spin_into(x, y, sth, cth, sch, cch, thd, chd, phd, out):
    """`euler_to_fixed_into` but the body vector b (which needs phi): G, the axis e and the
    angular velocity w into `out`, b left as it is."""
    xi0, xi1 = cch, sch
    et0, et1, et2 = -cth * sch, cth * cch, -sth
    ze0, ze1, ze2 = -sth * sch, sth * cch, cth
    out[FX], out[FY] = x, y
    out[EX], out[EY], out[EZ] = et0, et1, et2
    weta = phd - chd * sth
    out[WX] = -thd * xi0 + weta * et0 + chd * cth * ze0
    out[WY] = -thd * xi1 + weta * et1 + chd * cth * ze1
    out[WZ] = weta * et2 + chd * cth * ze2


@jit
def _nearest_branch(angle, ref):
    """angle + 2 pi k nearest ref."""
    return angle + 2.0 * math.pi * math.floor((ref - angle) / (2.0 * math.pi) + 0.5)


@jit
def _euler_rates(ex, ey, ez, wx, wy, wz, sth, cth, sch, cch):
    """(thetadot, chidot, phidot) from the axis e and the angular velocity w, given theta's and
    chi's sines and cosines, solving w = -thetadot xi + chidot z_hat + phidot e with
    xi = (cos chi, sin chi, 0) (`euler_to_fixed_into` builds w this way)."""
    thd = -(wx * cch + wy * sch)
    chd = (-wx * sth * sch + wy * sth * cch + wz * cth) / cth
    phd = (wx * ex + wy * ey + wz * ez) + chd * sth
    return thd, chd, phd


@jit
def fixed_to_euler_scalars(v, chi_ref, phi_ref):
    """Fixed-frame state -> (ok, theta, chi, phi, thetadot, chidot, phidot, sin theta, cos theta,
    sin chi, cos chi); chi and phi on the branches nearest chi_ref and phi_ref (phi NaN when
    phi_ref is). ok is False (the rest NaN) where the chart is degenerate: cos theta below
    CHART_MIN_COS, the axis vertical, where the Euler angles are not defined."""
    ex, ey, ez = v[EX], v[EY], v[EZ]
    wx, wy, wz = v[WX], v[WY], v[WZ]
    sth = -ez
    cth = math.sqrt(ex * ex + ey * ey)
    if cth < CHART_MIN_COS:
        nan = math.nan
        return False, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan
    th = math.atan2(sth, cth)
    ch = _nearest_branch(math.atan2(-ex, ey), chi_ref)
    sch, cch = math.sin(ch), math.cos(ch)
    thd, chd, phd = _euler_rates(ex, ey, ez, wx, wy, wz, sth, cth, sch, cch)
    # xi = (cos chi, sin chi, 0), zeta = (-sth sch, sth cch, cth); b = cos phi xi - sin phi zeta
    bx, by, bz = v[BX], v[BY], v[BZ]
    ph = _nearest_branch(
        math.atan2(-(-bx * sth * sch + by * sth * cch + bz * cth), bx * cch + by * sch), phi_ref)
    return True, th, ch, ph, thd, chd, phd, sth, cth, sch, cch


@jit
def euler_view_scalars(v, chi_ref):
    """The Euler view without phi, for an observer: (ok, theta, chi, thetadot, chidot, phidot,
    sin theta, cos theta), as `fixed_to_euler_scalars` gives them to rounding, with chi on the
    branch nearest chi_ref. The axis e is normalised first (an interpolated state is off the
    unit sphere by the interpolant's error), and sin chi, cos chi are e's components over
    cos theta (no sin, cos or phi's atan2)."""
    ex, ey, ez = v[EX], v[EY], v[EZ]
    wx, wy, wz = v[WX], v[WY], v[WZ]
    inv = 1.0 / math.sqrt(ex * ex + ey * ey + ez * ez)
    ex, ey, ez = ex * inv, ey * inv, ez * inv
    sth = -ez
    cth = math.sqrt(ex * ex + ey * ey)
    if not cth >= CHART_MIN_COS:
        nan = math.nan
        return False, nan, nan, nan, nan, nan, nan, nan
    th = math.atan2(sth, cth)
    ch = _nearest_branch(math.atan2(-ex, ey), chi_ref)
    thd, chd, phd = _euler_rates(ex, ey, ez, wx, wy, wz, sth, cth, -ex / cth, ey / cth)
    return True, th, ch, thd, chd, phd, sth, cth


def euler_to_fixed(u: np.ndarray) -> np.ndarray:
    """Euler state (Eq. 43) -> fixed-frame state (`euler_to_fixed_into`)."""
    v = np.empty(N_FIXED)
    th, ch = u[TH], u[CHI]
    euler_to_fixed_into(u[X], u[Y], math.sin(th), math.cos(th), math.sin(ch), math.cos(ch),
                        u[PHI], u[THD], u[CHD], u[PHD], v)
    return v


def fixed_to_euler(v: np.ndarray, chi_ref: float = 0.0, phi_ref: float = 0.0) -> np.ndarray:
    """Fixed-frame state -> Euler state (`fixed_to_euler_scalars`); chi and phi are put on the
    branches nearest the refs. Valid for |theta| < 90 deg (cos theta > 0)."""
    ok, th, ch, ph, thd, chd, phd, *_ = fixed_to_euler_scalars(
        np.asarray(v, dtype=np.float64), float(chi_ref), float(phi_ref))
    u = np.empty(N_EULER)
    u[X], u[Y], u[TH], u[CHI], u[PHI] = v[FX], v[FY], th, ch, ph
    u[THD], u[CHD], u[PHD] = thd, chd, phd
    return u

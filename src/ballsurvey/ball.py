"""The ball: SI parameters, the truncated-sphere geometry, and the non-dimensional constants.

Non-dimensional units (paper Sec. IV): lengths / a, times / sqrt(a/g), moments of inertia / (M a^2).
Everything inside the kernels is non-dimensional; SI lives here and in the API around the kernels.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numpy.polynomial import Polynomial


def nondim_params_of(a, c, M, A, B) -> np.ndarray:
    """(c/a, A/(M a^2), B/(M a^2)) stacked on axis 0; scalars or arrays (one ball per launch)."""
    a, c, M, A, B = (np.asarray(v, dtype=float) for v in (a, c, M, A, B))
    return np.stack(np.broadcast_arrays(c / a, A / (M * a * a), B / (M * a * a)))


def flat_face_theta_of(a, cut_height):
    """Tilt (rad) below which the contact point lies on the flat face; -pi/2 without a cut."""
    a, h = np.asarray(a, dtype=float), np.asarray(cut_height, dtype=float)
    return np.where(h > 0, -np.arcsin(np.clip((a - h) / a, -1.0, 1.0)), -np.pi / 2)


def tilt_error(theta0_deg, flat_face_deg) -> str | None:
    """Why a launch tilt (deg, scalar or array) is outside the model, or None if all are valid:
    |theta0| >= 90 deg (the Euler form is singular) or below the flat-face limit (deg)."""
    th = np.atleast_1d(np.asarray(theta0_deg, dtype=float))
    if np.any(np.abs(th) >= 90.0):
        bad = th[np.abs(th) >= 90.0][0]
        return f"|theta0| must be < 90 deg (the Euler form is singular there); got {float(bad):g}"
    if np.any(th < flat_face_deg):
        return (f"theta0 = {float(th.min()):g} deg rests the ball on its flat face (below "
                f"{float(flat_face_deg):.2f} deg the rolling model does not hold)")
    return None


@dataclass(frozen=True)
class Ball:
    """An axisymmetric biased ball, SI units.

    a: radius (m); c: offset of the centre of mass G from the geometric centre C, towards the
    symmetry axis +eta (m); M: mass (kg); A, B: principal moments of inertia about G, transverse and
    about the symmetry axis (kg m^2); g: gravity (m/s^2); cut_height: height of the cap cut off the
    sphere, on the -eta side (m; 0 for an untruncated ball). The flat face touches the table when
    sin(theta) < -(a - cut_height)/a (theta < -31.8 deg for the paper's ball).
    """

    a: float = 0.0254
    c: float = 0.0029
    M: float = 0.0984
    A: float = 2.39e-5
    B: float = 2.69e-5
    g: float = 9.81
    cut_height: float = 0.012

    def __post_init__(self):
        for name in ("a", "M", "A", "B", "g"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"ball.{name} must be a finite positive number, got {v!r}")
        if not (math.isfinite(self.c) and 0 <= self.c < self.a):
            raise ValueError(f"ball.c must satisfy 0 <= c < a, got c={self.c!r}, a={self.a!r}")
        if not (math.isfinite(self.cut_height) and 0 <= self.cut_height < 2 * self.a):
            raise ValueError(f"ball.cut_height must satisfy 0 <= h < 2a, got {self.cut_height!r}")
        # a physical rigid body satisfies the triangle inequality of principal moments about G
        if self.B > 2 * self.A * (1 + 1e-9):
            raise ValueError(f"ball inertia violates B <= 2A (A={self.A!r}, B={self.B!r})")

    # --- constructors -------------------------------------------------------------------------
    @classmethod
    def paper(cls) -> Ball:
        """The truncated billiard ball of the paper (Sec. V): a = 25.4 mm, c = 2.9 mm,
        M = 98.4 g."""
        return cls()

    @classmethod
    def from_geometry(cls, a: float, cut_height: float, M: float, g: float = 9.81) -> Ball:
        """A uniform sphere of radius a (m) with a cap of height cut_height (m) removed; mass M
        (kg).

        c, A and B are exact integrals over the solid (polynomials in the axial coordinate z,
        integrated exactly), not approximations.
        """
        a, h = float(a), float(cut_height)
        if not (a > 0 and 0 <= h < 2 * a):
            raise ValueError(f"need a > 0 and 0 <= cut_height < 2a, got a={a!r}, cut_height={h!r}")
        z = Polynomial([0.0, 1.0])
        r2 = a * a - z * z  # squared radius of the disc at height z (cap at the top, z > a - h)

        def integral(p: Polynomial) -> float:
            q = p.integ()
            return float(q(a - h) - q(-a))

        volume = integral(np.pi * r2)
        rho = M / volume
        z_g = integral(np.pi * r2 * z) / volume  # < 0: G lies away from the cut
        i_axis = rho * integral(np.pi * r2 * r2 / 2)  # discs: r^4/2 about the axis
        i_perp_centre = rho * integral(np.pi * (r2 * r2 / 4 + r2 * z * z))
        c = -z_g + 0.0  # + 0.0: a whole sphere has c = 0.0, not -0.0
        A = i_perp_centre - M * c * c  # parallel-axis theorem to G
        return cls(a=a, c=c, M=M, A=A, B=i_axis, g=g, cut_height=h)

    # --- non-dimensional view ----------------------------------------------------------------
    @property
    def time_unit(self) -> float:
        """sqrt(a/g) in s: the unit of non-dimensional time."""
        return math.sqrt(self.a / self.g)

    def nondim_params(self) -> np.ndarray:
        """(c/a, A/(M a^2), B/(M a^2)) as float64: the only ball constants the kernels need."""
        return nondim_params_of(self.a, self.c, self.M, self.A, self.B)

    @property
    def flat_face_theta_rad(self) -> float:
        """Tilt (rad) below which the contact point lies on the flat face (-pi/2 if never)."""
        return float(flat_face_theta_of(self.a, self.cut_height))

    def as_dict(self) -> dict:
        return asdict(self)


#: named presets usable in sweep specs
PRESETS = {"paper": Ball.paper}

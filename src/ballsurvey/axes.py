"""The one table of launch and ball axes: CF units, long name, units as text, plot label.

Used by the spec (validation), the store (the stored coordinates' attributes, through `schema`),
the sweep engine, `plot` and `query`. A new sweep axis is one row here.
"""
from __future__ import annotations

from typing import NamedTuple


class Axis(NamedTuple):
    units: str  #: CF / UDUNITS units of the stored coordinate
    long_name: str
    text_units: str  #: units as people write them (query's column headers)
    plot_label: str  #: axis label on plots (matplotlib mathtext)


AXES = {
    "theta0_deg": Axis("degree", "initial tilt of the symmetry axis (theta0)", "deg",
                       r"$\theta_0$ (deg)"),
    "thetadot0": Axis("rad s-1", "initial rate of tilt (thetadot0)", "rad/s",
                      r"$\dot\theta_0$ (rad/s)"),
    "chidot0": Axis("rad s-1", "initial precession rate (chidot0)", "rad/s",
                    r"$\dot\chi_0$ (rad/s)"),
    "phidot0": Axis("rad s-1", "initial spin rate about the symmetry axis (phidot0)", "rad/s",
                    r"$\dot\phi_0$ (rad/s)"),
    "chi0_deg": Axis("degree", "initial heading (chi0)", "deg", r"$\chi_0$ (deg)"),
    "c": Axis("m", "offset of the centre of mass from the centre", "m", "c (m)"),
    "cut_height": Axis("m", "height of the cut cap", "m", "cut height (m)"),
    "M": Axis("kg", "mass", "kg", "M (kg)"),
    "A": Axis("kg m2", "transverse moment of inertia about G", "kg m2", "A (kg m²)"),
    "B": Axis("kg m2", "axial moment of inertia about G", "kg m2", "B (kg m²)"),
}
LAUNCH_AXES = ("theta0_deg", "thetadot0", "chidot0", "phidot0")
BALL_AXES = ("c", "cut_height", "M", "A", "B")

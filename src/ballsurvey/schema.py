"""What a stored map holds: its axes' CF units and long names (the columns of `axes.AXES`) and
its result variables (name, dtype, units, long name, CF attributes, flag values and meanings).

The one table the spec (which variables a map may ask for) and the store (the file's writer)
both read.
"""
from __future__ import annotations

import numpy as np

from .axes import AXES
from .classify.labels import CORNER_KINDS, LABELS
from .integrate.outcome import FORMULATIONS

AXIS_UNITS = {k: ax.units for k, ax in AXES.items()}
AXIS_LONG_NAMES = {k: ax.long_name for k, ax in AXES.items()}

#: name -> (dtype, units or None, long_name, extra attributes)
RESULT_VARIABLES = {
    "label": ("i1", None, "path shape, or the status that replaces it",
              {"flag_values": np.arange(len(LABELS), dtype=np.int8),
               "flag_meanings": " ".join(LABELS)}),
    "n_sides": ("f8", "1", "360 deg over the absolute net turn per theta cycle", {}),
    "turn_per_cycle_deg": ("f8", "degree",
                           "net turn of the path per theta cycle, folded into (-180, 180], "
                           "counter-clockwise positive seen from above",
                           {"comment": "the heading of the path, not chi: chi's change per "
                                       "cycle is this plus a whole number of turns "
                                       "(ballsurvey.quadrature.launch_cycle gives it)"}),
    "chord_turn_per_cycle_deg": ("f8", "degree",
                                 "mean rotation of the chord between successive theta maxima", {}),
    "formulation": ("i1", None, "equations the launch was integrated with (quadrature: none, "
                    "its theta cycle from the conserved quantities)",
                    {"flag_values": np.arange(len(FORMULATIONS), dtype=np.int8),
                     "flag_meanings": " ".join(FORMULATIONS)}),
    "theta_period_s": ("f8", "s", "period of the tilt theta", {}),
    "side_m": ("f8", "m", "polygon side: distance between successive theta minima (corners)", {}),
    "chord_m": ("f8", "m", "chord between successive theta maxima (mid-side to mid-side)", {}),
    "roundness": ("f8", "1", "(largest - smallest distance of the path from its orbit centre) "
                  "over the mean of the two (0 for a circle)", {}),
    "corner_kind": ("i1", None, "kind of corner",
                    {"flag_values": np.arange(len(CORNER_KINDS), dtype=np.int8),
                     "flag_meanings": " ".join(CORNER_KINDS)}),
    "corner_sharpness": ("f8", "1", "peak over mean heading rate of the path per cycle", {}),
    "turn_monotonicity": ("f8", "1", "net heading change over total absolute turning per cycle",
                          {}),
    "closure_m": ("f8", "m", "drift of a corner per circuit of the nearest closed polygon or star",
                  {}),
    "loops_per_cycle": ("f8", "1", "whole extra turns of the heading per cycle (loop corners)", {}),
    "star_points": ("i2", "1", "p of the star polygon {p/q} (0 if not a star)", {}),
    "star_step": ("i2", "1", "q of the star polygon {p/q} (0 if not a star)", {}),
    "n_theta_cycles": ("i4", "1", "complete theta cycles observed", {}),
    "samples_per_cycle": ("f8", "1", "observer samples per theta cycle (below the classifier's "
                          "min_samples_per_cycle: unresolved)", {}),
    "theta_min_deg": ("f8", "degree", "smallest tilt theta reached", {}),
    "theta_max_deg": ("f8", "degree", "largest tilt theta reached", {}),
    "max_friction_ratio": ("f8", "1", "largest friction demand |F_h|/N", {}),
    "min_normal_force_ratio": ("f8", "1", "smallest normal force over M g", {}),
    "energy_drift": ("f8", "1", "largest |E - E0| / |E0| (energy, Eqs. 11-12)", {}),
    "jellett_drift": ("f8", "kg m3 s-1", "largest |J - J0| (Jellett's integral)", {}),
    "routh_drift": ("f8", "kg m2 s-1", "largest |R - R0| (Routh's integral)", {}),
    "t_stop_s": ("f8", "s", "time at which a blown-up or singular launch was stopped", {}),
}

DEFAULT_VARIABLES = tuple(RESULT_VARIABLES)

"""The label vocabulary and the post-hoc labeller: observer slots -> fields -> labels.

One vocabulary for store, plot and query: `LABELS` (shape words, then status words), with the int8
codes stored in files. Shape and validity are separate: a launch that blew up, hit the Euler form's
singularity, slipped, lifted off or rolled onto its flat face gets a status word, never a shape.

How a label is decided: one principle, the word says what the eye sees over one orbit (the n
cycles, n = 360 / |net turn per cycle|, after which the path would close). docs/labels.md states
every rule and threshold in words, with a picture per word; the code below is that list (per-cycle
quantities only, so a label does not change with T). In short: a path within +-5 % of one circle
is a `circle` whatever small ripples, corners or specks of loops it has; else loops the eye sees
(the speed stays up through them) make a `rosette`; a turn over 125 deg per cycle with points is a
`star`; everything else is named by its nearest whole n: under 2.5 a precessing oval (`rosette`),
3 `triangle`, 4 `square`, more `ngon`. Roundness is the spread of the path's distance from the
orbit centre over a cycle (the observer measures it; every cycle is a rotated copy about that
centre, so it holds for the whole orbit) over its mean.
Status first: the run's own failure (non-finite state or step underflow -> `blew_up`; out of steps
-> `unresolved`; the Euler chart's singularity with no fixed-frame run -> `singular`) is passed
in by the caller as a label word (`failure`); the labeller adds the validity checks (energy drift,
flat face, lift-off, slipping).

The classifier needs `min_cycles` (default 2) complete theta cycles, i.e. three theta maxima, within
T: about 2 s for the paper's ball at its square and triangle launches (theta period 0.57-0.63 s).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

import numpy as np

from . import observer as ob

SHAPES = ("circle", "near_straight", "triangle", "square", "ngon", "star", "rosette")
STATUSES = ("unresolved", "blew_up", "singular", "flat_face", "lift_off", "slipping",
            "inaccurate")
LABELS = SHAPES + STATUSES
CODE = {w: i for i, w in enumerate(LABELS)}

CORNER_KINDS = ("none", "rounded", "cusp", "loop")
CORNER_CODE = {w: i for i, w in enumerate(CORNER_KINDS)}


@dataclass(frozen=True)
class Thresholds:
    """Classifier settings (all settable in a sweep spec's [classify] table)."""

    mu: float = 0.3  #: friction coefficient: max |F_h|/N above it -> slipping
    min_cycles: int = 2  #: complete theta cycles needed to label a shape
    steady_theta_tol_deg: float = 0.5  #: theta range below it -> steady circle
    star_min_turn_deg: float = 125.0  #: |net turn per cycle| above it -> star polygon
    near_straight_ratio: float = 10.0  #: corner-circle radius / side above it -> near_straight
    #: min / mean speed in a cycle below it -> the corner is a point (a cusp, or a loop too small
    #: to see)
    cusp_speed_ratio: float = 0.15
    retrace_ratio: float = 0.03  #: chord / distance rolled per cycle below it -> retraced line
    max_star_points: int = 12  #: largest p searched for a star {p/q}
    max_energy_drift: float = 1e-4  #: |E - E0| / |E0| above it -> inaccurate (step too large)
    #: radial spread / mean radius about the orbit centre at most it -> circle
    max_roundness: float = 0.1
    #: peak / mean heading rate at least it (or cusped corners) -> a turn over star_min_turn_deg
    #: per cycle has points: a star
    star_sharpness_min: float = 4.0
    #: |thetadot|, |thetadot'| at launch below it (a/g units) -> launched steady
    steady_rate_tol: float = 1e-8
    #: observer samples per theta cycle below it -> unresolved (too few to see the path's shape)
    min_samples_per_cycle: float = 20.0

    @classmethod
    def from_mapping(cls, mapping: dict) -> Thresholds:
        names = {f.name: f.type for f in fields(cls)}
        kw = {}
        for key, value in mapping.items():
            if key not in names:
                raise ValueError(f"[classify] unknown key {key!r}; known: {', '.join(names)}")
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"[classify] {key} must be a number, got {value!r}")
            if not math.isfinite(value) or value < 0:
                raise ValueError(f"[classify] {key} must be finite and >= 0, got {value!r}")
            kw[key] = int(value) if names[key] in ("int", int) else float(value)
        return cls(**kw)

    def as_dict(self) -> dict:
        return asdict(self)


def fold_deg(angle_deg):
    """Fold angles into (-180, 180]."""
    a = np.mod(np.asarray(angle_deg, dtype=float) + 180.0, 360.0) - 180.0
    return np.where(a == -180.0, 180.0, a)


def star_type(turn_deg: np.ndarray, max_points: int):
    """Best {p/q} with p <= max_points for |turn| = 360 q / p; returns (p, q) arrays (0 if none)."""
    x = np.abs(np.asarray(turn_deg, dtype=float)) / 360.0
    best_p = np.zeros(x.shape, dtype=np.int16)
    best_q = np.zeros(x.shape, dtype=np.int16)
    best_err = np.full(x.shape, np.inf)
    for p in range(2, max_points + 1):
        q = np.rint(x * p)
        err = np.abs(x * p - q) / p
        better = (err < best_err - 1e-12) & (q >= 1) & (np.gcd(q.astype(int), p) == 1)
        best_p = np.where(better, p, best_p)
        best_q = np.where(better, q, best_q)
        best_err = np.where(better, err, best_err)
    return best_p, best_q


#: dimensions (mass, length, time exponents) of the fields `label_fields` returns in units of
#: M, a and sqrt(a/g); fields not named here are dimensionless (or angles, counts, codes). The
#: run's own fields (`t_stop_s`) are here too, so one table converts everything to SI.
FIELD_DIMENSIONS = {
    "theta_period_s": (0, 0, 1),
    "side_m": (0, 1, 0),
    "chord_m": (0, 1, 0),
    "closure_m": (0, 1, 0),
    "jellett_drift": (1, 3, -1),  # angular momentum x length
    "routh_drift": (1, 2, -1),  # angular momentum
    "t_stop_s": (0, 0, 1),
}


def line_turn_deg(th: Thresholds) -> float:
    """The turn per cycle (deg) below which a path is near_straight: the circle through its
    corners has a radius `near_straight_ratio` times a side, side / (2 sin(D / 2))."""
    return math.degrees(2.0 * math.asin(0.5 / th.near_straight_ratio))


def label_fields(obs: np.ndarray, flat_face_theta, th: Thresholds = Thresholds(), *,
                 chart_free=None, failure=None, variables=None) -> dict:
    """Turn observer slots (N_OBS, n) into labels and fields, non-dimensional: the names are the
    stored variable names, whose suffix or `FIELD_DIMENSIONS` gives the SI unit they take in
    `ballsurvey.units.fields_to_si`.

    flat_face_theta: tilt (rad) below which the flat face touches the table, per launch or scalar.
    chart_free (bool, n): launches integrated without the Euler chart (their net turn comes from
    the chord between theta maxima). failure (int, n): the label word's code a run failure
    decides (`blew_up`, `singular` or `unresolved`), -1 where the run did not fail.
    variables: the names wanted (None: all); `label` is always given, names it does not make
    are passed over, and a field not wanted is not computed.
    """
    o = np.asarray(obs, dtype=float)
    n = o.shape[1]
    chart_free = (np.zeros(n, dtype=bool) if chart_free is None
                  else np.broadcast_to(np.asarray(chart_free, dtype=bool), (n,)))
    failure = (np.full(n, -1) if failure is None
               else np.broadcast_to(np.asarray(failure), (n,)))
    with np.errstate(invalid="ignore", divide="ignore"):
        n_cyc = np.maximum(o[ob.O_NMAX] - 1.0, 0.0)
        has = n_cyc >= 1
        dchi = np.where(has, (o[ob.O_CHIL] - o[ob.O_CHI1]) / np.where(has, n_cyc, 1.0), np.nan)
        turn = fold_deg(np.degrees(dchi))
        # chart-free alternative: mean folded rotation of the chord between successive maxima;
        # used where the Euler chart was left (fixed-frame integration through theta = 90 deg)
        chord_turn = np.degrees(o[ob.O_CR_SUM] / o[ob.O_CR_N])
        # better still where the path's heading at every theta maximum was well defined: its
        # folded change between maxima (it does not shrink with the chord)
        heading_turn = np.where(o[ob.O_HD_N] >= n_cyc, np.degrees(o[ob.O_HD_SUM] / o[ob.O_HD_N]),
                                chord_turn)
        turn = np.where(chart_free, heading_turn, turn)
        turn = np.where(has, turn, np.nan)
        abs_turn = np.abs(turn)
        n_sides = 360.0 / abs_turn
        side = np.hypot(o[ob.O_XL] - o[ob.O_XP], o[ob.O_YL] - o[ob.O_YP])
        rho = side / (2.0 * np.sin(np.radians(abs_turn) / 2.0))  # radius of the corners' circle
        # heading change of the path per cycle: exact from chi and the winding in the Euler chart;
        # in the fixed frame (chart left near theta = 90 deg) the integrated heading rate
        raw = np.where(chart_free, np.degrees(o[ob.O_C_RAW]),
                       np.degrees(dchi) + 360.0 * o[ob.O_C_WIND])
        loops = np.rint((raw - turn) / 360.0)
        raw_rad = np.abs(np.radians(raw))
        sharp = o[ob.O_C_PSID] * o[ob.O_C_DUR] / raw_rad  # peak / mean rate of the raw turn
        is_star = abs_turn > th.star_min_turn_deg
        # the star {p/q} is read only where the turn makes a star (0 elsewhere)
        star_p, star_q = np.zeros(n, dtype=np.int16), np.zeros(n)
        star_p[is_star], star_q[is_star] = star_type(turn[is_star], th.max_star_points)
        theta_range = np.degrees(o[ob.O_TH_MAX] - o[ob.O_TH_MIN])
        # radial spread of the path about its orbit centre over a cycle (= over an orbit)
        r_lo, r_hi = o[ob.O_C_RMIN], o[ob.O_C_RMAX]
        roundness = (r_hi - r_lo) / (0.5 * (r_hi + r_lo))
        # samples per theta cycle: those the observer saw in the last cycle, and pi times theta's
        # range over the largest change of theta between samples (the count for a sinusoid);
        # the smaller, since samples far apart can alias a cycle into several
        by_step = math.pi * (o[ob.O_TH_MAX] - o[ob.O_TH_MIN]) / o[ob.O_TH_STEP]
        samples = np.fmin(o[ob.O_C_NSAMP], by_step)

    # steady rolling: launched at rest in theta with no theta acceleration, and theta stayed put
    # (a short run of any launch also keeps theta nearly still: that is `unresolved`, not steady)
    launched_steady = ((o[ob.O_THD0] < th.steady_rate_tol)
                       & (o[ob.O_THDD0] < th.steady_rate_tol))
    steady = (theta_range < th.steady_theta_tol_deg) & launched_steady
    cusp = o[ob.O_C_VMIN] < th.cusp_speed_ratio * o[ob.O_C_VMEAN]
    # a loop the eye sees: the velocity winds a whole extra turn in a cycle while the speed stays
    # up; where it nearly stops the loop is a speck at a pointed corner, i.e. a cusp
    kind = np.where(cusp, CORNER_CODE["cusp"],
                    np.where(loops != 0, CORNER_CODE["loop"], CORNER_CODE["rounded"]))
    with np.errstate(invalid="ignore"):
        # the chord between maxima is a tiny part of the distance rolled: the path comes back
        # near where the cycle began (turning at a cusp, or on a petal: see below)
        retraced = side < th.retrace_ratio * o[ob.O_C_VMEAN] * o[ob.O_C_DUR]
    kind = np.where(retraced, CORNER_CODE["cusp"], kind)
    kind = np.where(has & ~steady, kind, CORNER_CODE["none"]).astype(np.int8)

    # one principle: the word says what the eye sees over one orbit. Rules from the most
    # general look of the path (round, loops) to its details (points, number of sides); the
    # later assignments below override the earlier ones, so they are written in reverse
    nn = np.rint(n_sides)
    label = np.full(n, CODE["ngon"], dtype=np.int8)
    label[nn == 4] = CODE["square"]
    label[nn == 3] = CODE["triangle"]
    # under 2.5 cycles per orbit: each cycle crosses most of the orbit, half of an oval that
    # precesses (a two-sided path), unless it has points (below)
    label[nn <= 2] = CODE["rosette"]
    with np.errstate(invalid="ignore"):
        pointed = (sharp >= th.star_sharpness_min) | (kind == CORNER_CODE["cusp"])
    # a turn over star_min_turn_deg per cycle with points: a star {p/q}, which steps over q >= 2
    # corners (a best fit {p/1} is no star: the nearest whole n names the path, as for a turn
    # without points: a triangle precessing where n rounds to 3)
    label[is_star & pointed & (star_q >= 2)] = CODE["star"]
    # loops the eye sees (rings of loops, clovers, flowers of petals through the middle)
    label[kind == CORNER_CODE["loop"]] = CODE["rosette"]
    with np.errstate(invalid="ignore"):
        round_enough = roundness <= th.max_roundness
    # the whole orbit stays within +-max_roundness/2 of one circle: whatever ripples, scallops,
    # specks of loops or small corners it has, the eye sees a circle
    label[round_enough] = CODE["circle"]
    label[rho / side > th.near_straight_ratio] = CODE["near_straight"]
    # a retraced cycle goes back and forth along a line (no spin: the ball rocks in a vertical
    # plane through the upright position) ... unless its heading turns on the way: then each
    # cycle is a petal that comes back near its start, and the petals, rotated cycle by cycle,
    # draw a rosette
    # (a line turns only at its cusps, where the speed vanishes: under a quarter turn elsewhere)
    # ... and unless the petals turn so little a cycle that the eye sees one line turning
    # slowly: a retraced cycle's heading turns by 180 deg less the line's own turn per cycle, so
    # the line is near_straight below the turn per cycle of a near_straight path, as any path.
    # Whether the heading's turn at a hairpin counts (over a quarter turn) depends on how finely
    # the observer resolves the hairpin; the turn between maxima does not
    with np.errstate(invalid="ignore"):
        petal_cycle = o[ob.O_C_TURN] > 0.5 * math.pi
        slow_line = 180.0 - abs_turn < line_turn_deg(th)
    label[retraced] = np.where(petal_cycle & ~slow_line, CODE["rosette"],
                               CODE["near_straight"])[retraced]
    label[~has] = CODE["unresolved"]
    label[n_cyc < th.min_cycles] = CODE["unresolved"]
    with np.errstate(invalid="ignore"):
        # too few samples a cycle to see corners, loops or the cycle itself (aliased): no shape
        label[samples < th.min_samples_per_cycle] = CODE["unresolved"]
    label[steady] = CODE["circle"]
    # validity overrides shape, least specific first so the most basic failure wins
    label[o[ob.O_FRIC] > th.mu] = CODE["slipping"]
    label[o[ob.O_NMIN] <= 0.0] = CODE["lift_off"]
    # a run that stopped early (the Euler chart's singularity, out of steps) says so
    stopped = (failure >= 0) & (failure != CODE["blew_up"])
    label[stopped] = failure[stopped]
    # touching the flat face invalidates the model from then on, so whatever followed (even the
    # Euler singularity) is its consequence; only a numerical blow-up is reported before it
    label[o[ob.O_TH_MIN] < np.broadcast_to(flat_face_theta, (n,))] = CODE["flat_face"]
    with np.errstate(invalid="ignore"):
        label[o[ob.O_DE] / np.abs(o[ob.O_E0]) > th.max_energy_drift] = CODE["inaccurate"]
    label[failure == CODE["blew_up"]] = CODE["blew_up"]

    # a line retraced has no turn: its heading flips at the cusps and its chord between maxima
    # is a rounding-sized remainder, so turn, n_sides and closure would be noise (-135 or -180 deg
    # for launches a hair apart near the vertical): not given
    line = retraced & ~petal_cycle
    e0 = o[ob.O_E0]
    fin = lambda a: np.where(has & ~steady, a, np.nan)  # noqa: E731 - per-cycle fields
    turning = lambda a: np.where(line, np.nan, fin(a))  # noqa: E731 - fields of a turn
    star = lambda a: np.where(label == CODE["star"], a, 0).astype(np.int16)  # noqa: E731

    def period():
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(has, (o[ob.O_TL] - o[ob.O_T1]) / np.where(has, n_cyc, 1.0), np.nan)

    def monotone():
        with np.errstate(invalid="ignore", divide="ignore"):
            return raw_rad / o[ob.O_C_TURN]

    def closure():
        # how far a corner drifts per circuit of the nearest closed polygon / star
        with np.errstate(invalid="ignore", divide="ignore"):
            p_close = np.where(is_star, star_p, np.rint(n_sides))
            q_close = np.where(is_star, star_q, 1)
            delta = np.radians(p_close * abs_turn - 360.0 * q_close)
            return np.abs(2.0 * rho * np.sin(delta / 2.0))

    # each field made only when asked for (`variables`)
    made = {
        "n_sides": lambda: turning(n_sides),
        "turn_per_cycle_deg": lambda: turning(turn),
        "theta_period_s": lambda: fin(period()),
        "side_m": lambda: fin(o[ob.O_C_SIDE]),
        "chord_m": lambda: fin(side),
        "roundness": lambda: fin(roundness),
        "corner_kind": lambda: kind,
        "corner_sharpness": lambda: fin(sharp),
        "turn_monotonicity": lambda: fin(monotone()),
        "closure_m": lambda: turning(closure()),
        "loops_per_cycle": lambda: fin(loops),
        "star_points": lambda: star(star_p),
        "star_step": lambda: star(star_q),
        "n_theta_cycles": lambda: n_cyc.astype(np.int32),
        # also where no cycle completed (theta's largest step between samples still tells how
        # coarse the sampling is: an aliased run may see no cycle at all); not for steady runs
        "samples_per_cycle": lambda: np.where(steady, np.nan, samples),
        "chord_turn_per_cycle_deg": lambda: turning(chord_turn),
        "theta_min_deg": lambda: np.degrees(o[ob.O_TH_MIN]),
        "theta_max_deg": lambda: np.degrees(o[ob.O_TH_MAX]),
        "max_friction_ratio": lambda: o[ob.O_FRIC],
        "min_normal_force_ratio": lambda: o[ob.O_NMIN],
        "energy_drift": lambda: o[ob.O_DE] / np.abs(e0),
        "jellett_drift": lambda: o[ob.O_DJ],
        "routh_drift": lambda: o[ob.O_DR],
    }
    wanted = made if variables is None else [k for k in made if k in variables]
    return {"label": label, **{k: made[k]() for k in wanted}}

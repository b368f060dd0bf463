"""A measured track (`Track`): its columns, and the checks that make it a rolling ball's in s and m
(`make_track`)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import limits

#: track checks: fewest samples, shortest duration (s), largest sample interval (s), largest
#: speed (m/s), largest extent (m): beyond them the track is not a rolling ball in s and m
MIN_SAMPLES = 20
#: most samples a track may have (600 s at 300 per second is 180 000)
MAX_SAMPLES = 200_000
MIN_DURATION_S = 0.2
MAX_INTERVAL_S = 0.1
#: the longest gap (s) the track may have (lost frames)
MAX_GAP_S = 0.5
MAX_SPEED = 5.0
MAX_EXTENT_M = 20.0
#: the largest |theta_deg| a track may hold (deg): 90 and its measurement noise
MAX_THETA_DEG = 95.0
#: the longest track (s)
MAX_DURATION_S = 600.0


@dataclass
class Track:
    """A measured track; t in s from the first sample (t_start: its time in the file, s).
    Arrays are None where the file has no such column. dropped_t: the file's times (s) of the
    rows dropped for a blank or non-finite cell (lost frames); dropped_untimed: rows dropped
    without a time."""

    t: np.ndarray
    t_start: float = 0.0
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    theta_deg: np.ndarray | None = None
    chidot: np.ndarray | None = None
    x_tip: np.ndarray | None = None
    y_tip: np.ndarray | None = None
    x_base: np.ndarray | None = None
    y_base: np.ndarray | None = None
    probe_m: float | None = None
    source: str = "track"
    dropped_t: np.ndarray = field(default_factory=lambda: np.empty(0))
    dropped_untimed: int = 0

    @property
    def probe(self) -> bool:
        return self.x_tip is not None


PROBE_COLUMNS = ("x_tip", "y_tip", "x_base", "y_base")
COLUMNS = ("t", "x", "y", "theta_deg", "chidot") + PROBE_COLUMNS
POSITION_PAIRS = (("x", "y"), ("x_tip", "y_tip"), ("x_base", "y_base"))
#: length and time units a track may come in (factor to m, to s)
LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
TIME_UNITS = {"s": 1.0, "ms": 1e-3}
#: positions this far from the origin are not resolved to a tracking precision by float64 (its
#: spacing there is 1 mm): refused (the fit works relative to the first sample, nearer is fine)
MAX_POSITION_M = 8.0e12


def make_track(t, x=None, y=None, *, theta_deg=None, chidot=None, x_tip=None, y_tip=None,
               x_base=None, y_base=None, probe_m=None, source="track",
               drop_missing: bool = False) -> Track:
    """A checked Track from arrays (the rules of `read_track`); InputError, one line, if not.
    drop_missing: rows with a non-finite value (a lost frame) are dropped and their times kept
    in `Track.dropped_t` (without it such a value is refused)."""
    def arr(name, v):
        if v is None:
            return None
        return np.asarray(v, dtype=float).ravel()

    t = arr("t", t)
    if t is None:
        raise limits.InputError(f"{source}: needs a column t (s)")
    cols = {k: arr(k, v) for k, v in dict(x=x, y=y, theta_deg=theta_deg, chidot=chidot,
                                          x_tip=x_tip, y_tip=y_tip, x_base=x_base,
                                          y_base=y_base).items()}
    for k, v in cols.items():
        if v is not None and v.size != t.size:
            raise limits.InputError(f"{source}: column {k} has {v.size} values, t has {t.size}")
    dropped_t, untimed = np.empty(0), 0
    named = [("t", t)] + [(k, v) for k, v in cols.items() if v is not None]
    bad_rows = np.zeros(t.size, bool)
    for name, v in named:
        bad = ~np.isfinite(v)
        if bad.any() and not drop_missing:
            raise limits.InputError(f"{source}: column {name} has a missing or non-finite value "
                                    f"at sample {np.flatnonzero(bad)[0] + 1} (row 1 is the "
                                    "first after the header)")
        bad_rows |= bad
    if bad_rows.any():
        untimed = int((~np.isfinite(t)).sum())
        dropped_t = t[bad_rows & np.isfinite(t)]
        keep = ~bad_rows
        t = t[keep]
        cols = {k: (None if v is None else v[keep]) for k, v in cols.items()}
    have_g = cols["x"] is not None and cols["y"] is not None
    have_p = all(cols[k] is not None for k in PROBE_COLUMNS)
    if (cols["x"] is None) != (cols["y"] is None):
        raise limits.InputError(f"{source}: give both x and y (m) of the centre of mass")
    if any(cols[k] is not None for k in PROBE_COLUMNS) and not have_p:
        raise limits.InputError(f"{source}: the probe needs all of {', '.join(PROBE_COLUMNS)}")
    if have_g == have_p:
        raise limits.InputError(f"{source}: give the centre of mass (x, y) or the probe "
                                f"({', '.join(PROBE_COLUMNS)}), one of them")
    if have_p:
        if probe_m is None:
            raise limits.InputError(f"{source}: a probe track needs the probe's length "
                                    "(--probe-m, m)")
        probe_m = limits.number("probe_m", probe_m, positive=True, hi=1.0)
    elif probe_m is not None:
        raise limits.InputError(f"{source}: the probe's length (--probe-m) goes with a track of "
                                f"the probe ({', '.join(PROBE_COLUMNS)}); this one has x, y")
    lost = f" ({dropped_t.size + untimed} rows with a blank or non-finite cell dropped)" \
        if bad_rows.any() else ""
    if t.size < MIN_SAMPLES:
        raise limits.InputError(f"{source}: {t.size} samples is too short a track{lost}; a fit "
                                f"needs at least {MIN_SAMPLES}")
    steps = np.diff(t)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        raise limits.InputError(f"{source}: t must increase; sample {bad[0] + 2} (t = "
                                f"{t[bad[0] + 1]:g}) does not come after the one before")
    span = t[-1] - t[0]
    if span < MIN_DURATION_S:
        raise limits.InputError(f"{source}: the track lasts {span:g} s; a fit needs at least "
                                f"{MIN_DURATION_S:g} s (t is in s; --time-units ms for ms)")
    if span > MAX_DURATION_S:
        raise limits.InputError(f"{source}: the track lasts {span:g} s, more than "
                                f"{MAX_DURATION_S:g} s (is t in ms? give --time-units ms)")
    if np.median(steps) > MAX_INTERVAL_S:
        raise limits.InputError(f"{source}: samples are {np.median(steps):g} s apart (median); "
                                f"a fit needs at most {MAX_INTERVAL_S:g} s (is t in ms? give "
                                "--time-units ms)")
    gap = int(np.argmax(steps))
    if steps[gap] > MAX_GAP_S:
        raise limits.InputError(f"{source}: sample {gap + 2} (t = {t[gap + 1]:g} s) comes "
                                f"{steps[gap]:g} s after the one before{lost}; a fit needs "
                                f"samples at most {MAX_GAP_S:g} s apart (cut the track at the "
                                "gap)")
    if t.size > MAX_SAMPLES:
        raise limits.InputError(f"{source}: {t.size} samples; a fit takes at most {MAX_SAMPLES} "
                                "(keep every k-th row: 300 per second is plenty)")
    for px, py in POSITION_PAIRS:
        if cols[px] is None:
            continue
        far = max(np.max(np.abs(cols[px])), np.max(np.abs(cols[py])))
        if far > MAX_POSITION_M:
            raise limits.InputError(
                f"{source}: {px}, {py} reach {far:.3g} m from the origin, where a float64 "
                f"holds them only to {np.spacing(far):.3g} m; subtract an origin nearer the "
                "track")
        extent = max(np.ptp(cols[px]), np.ptp(cols[py]))
        speed = np.median(np.hypot(np.diff(cols[px]), np.diff(cols[py])) / steps)
        if extent > MAX_EXTENT_M or speed > MAX_SPEED:
            raise limits.InputError(
                f"{source}: {px}, {py} move {speed:g} m/s over {extent:g} m; a rolling ball "
                f"stays below {MAX_SPEED:g} m/s and {MAX_EXTENT_M:g} m (are they in mm or cm? "
                "give --units mm or cm, or a header such as 'x (mm)')")
    # a tilt read near the vertical may pass 90 deg by its noise
    if cols["theta_deg"] is not None and np.any(np.abs(cols["theta_deg"]) > MAX_THETA_DEG):
        raise limits.InputError(f"{source}: theta_deg must stay within +-{MAX_THETA_DEG:g} deg "
                                "(is it in deg?)")
    if cols["chidot"] is not None and np.any(np.abs(cols["chidot"]) > limits.MAX_RATE):
        raise limits.InputError(f"{source}: chidot beyond {limits.MAX_RATE:g} rad/s")
    return Track(t=t - t[0], t_start=float(t[0]), probe_m=probe_m, source=source,
                 dropped_t=dropped_t, dropped_untimed=untimed, **cols)

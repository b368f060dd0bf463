"""Launch conditions fitted to a measured track (the paper's Sec. VI: a filmed ball reproduced by
guessing its launch).

A track is a table of times t (s) with the centre of mass x, y (m), or the probe's tip and base
x_tip, y_tip, x_base, y_base (m, a probe of known length), and optionally the tilt theta_deg (deg)
and the precession rate chidot (rad/s), as the paper read them off its probe. `fit_track` finds
the launch at the first sample (theta0_deg, thetadot0, chidot0, phidot0, chi0_deg, x0, y0) whose
integrated motion best reproduces it:

1. a global start: a survey of the launch box (theta0, thetadot0, chidot0 on a grid; phidot0 from
   the track's initial speed, both signs) on the ensemble kernel over the first seconds, each
   launch integrated once with chi0 = 0 at the origin and then turned and moved onto the track
   in closed form (the motion is the same under a turn about the vertical and a shift);
2. a local refinement by scipy's least_squares (trust-region reflective, Jacobian by forward
   differences, all its launches in one kernel call): the best N_STARTS survey launches a few
   iterations over the first START_T seconds (where a launch a grid step off still keeps the
   track's phase), then the best N_CARRIED of those over a window doubled until it holds the
   whole track;
3. uncertainties from the Jacobian at the optimum: covariance s^2 (J^T J)^-1, s^2 the residual
   variance per degree of freedom.

Residuals are weighted by nominal measurement errors (POSITION_SIGMA_M, THETA_SIGMA_DEG,
CHIDOT_SIGMA) so channels of different units can be mixed; the uncertainties rescale by the
residual itself, so they do not depend on those nominal values when one channel is used.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from . import limits
from .ball import Ball
from .compose import run_resisted_trajectory, run_tracks, run_trajectory
from .integrate.outcome import OK
from .physics.fast import N_FAST, S_CHD, S_CHI, S_TH, S_X, S_Y
from .simulate import body_points, simulate
from .units import StepPlan, launch_state

#: the launch the fit returns, in order, with units
PARAMS = ("theta0_deg", "thetadot0", "chidot0", "phidot0", "chi0_deg", "x0", "y0")
UNITS = {"theta0_deg": "deg", "thetadot0": "rad/s", "chidot0": "rad/s", "phidot0": "rad/s",
         "chi0_deg": "deg", "x0": "m", "y0": "m", "rolling_resistance": "(dimensionless)"}
#: the extra parameter a fit of a slowing ball (`fit_track(slowing=True)`) returns after PARAMS:
#: the rolling-resistance coefficient mu_r (dimensionless, `simulate`'s rolling_resistance)
SLOWING = "rolling_resistance"
#: where the slowing fit's coefficient starts (the order of a ball on a table, docs/physics.md)
SLOWING_START = 1e-3
#: nominal measurement errors that weight the residual channels
POSITION_SIGMA_M = 1e-4
THETA_SIGMA_DEG = 0.1
CHIDOT_SIGMA = 0.05
#: the launch box of the global survey: theta0 (deg), thetadot0, chidot0 (rad/s)
BOX = {"theta0_deg": (-30.0, 89.0), "thetadot0": (-4.0, 4.0), "chidot0": (-30.0, 30.0)}
#: tilts (deg) the survey adds near the vertical, where paths change fast with theta0
NEAR_VERTICAL = (87.0, 88.0, 89.5, 89.9)
#: grid of the survey inside the box
GRID = {"theta0_deg": 31, "thetadot0": 9, "chidot0": 61}
#: the survey's window (s), step (s) and sample spacing (s)
SURVEY_T = 1.5
SURVEY_DT = 2e-3
SURVEY_EVERY = 0.01
#: share of the survey window a launch must stay on the Euler chart to be judged
SURVEY_VALID = 1.0
#: the refinement's RK4 step (s): the model is sampled every step and interpolated to the track
FIT_DT = 5e-4
#: survey launches refined over the first START_T seconds, and how many of them are carried
#: on to the whole track
N_STARTS = 24
START_T = 0.5
N_CARRIED = 3
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
#: duration (s) of the run that labels the fitted launch (or the track's, if longer)
LABEL_T = 20.0
#: the survey's best launches always refined; then one a basin, scanning this many
N_BEST = 8
PICK_SCAN = 20_000
#: refined starts carried on to the whole track: those within CARRY_FACTOR of the best cost over
#: the first START_T seconds, one a basin (SAME_BASIN: theta0 deg, thetadot0, chidot0, phidot0)
CARRY_FACTOR = 25.0
SAME_BASIN = np.array([1.0, 0.2, 0.2, 0.2])
#: an alternative launch fits within the noise when its chi^2 exceeds the best's by less than
#: the ALT_LEVEL quantile of chi^2 with 7 degrees of freedom (21.7 at 0.997), and differs from
#: the best by more than SAME_SIGMAS of its standard deviations (and SAME_FLOOR)
ALT_LEVEL = 0.997
SAME_SIGMAS = 5.0
SAME_FLOOR = np.array([0.05, 0.005, 0.005, 0.005])
#: the model's resolution (m): misfits below it are never called a mismatch or a failure
RESOLUTION_M = 1e-5
#: the noise estimate's relative spread: NOISE_SPREAD / sqrt(values) (third differences' MAD)
NOISE_SPREAD = 1.55
#: mismatch: the rms exceeds the noise by MISFIT_Z of their joint spread, or the residuals'
#: runs or lag-1 autocorrelation are STRUCTURE_Z from white noise
MISFIT_Z = 3.0
STRUCTURE_Z = 4.0
#: failed: the rms is FAIL_RATIO times the noise, or above it (MISFIT_Z) by FAIL_FRACTION of the
#: track's extent, or
#: thetadot0, chidot0 beyond the survey's box by BOX_MARGIN of its half-width
FAIL_RATIO = 20.0
FAIL_FRACTION = 0.05
BOX_MARGIN = 0.5
#: a standard deviation wider than WIDE_SHARE of the survey box's span (theta0, thetadot0,
#: chidot0), WIDE_PHIDOT (rad/s) or WIDE_CHI_DEG (deg): the track does not fix the launch
WIDE_SHARE = 0.1
WIDE_PHIDOT = 3.0
WIDE_CHI_DEG = 30.0
#: the plot's model drawn every PLOT_DT seconds (or finer)
PLOT_DT = 0.01
#: a Jacobian condition number above it: the track does not separate the parameters
MAX_CONDITION = 1e8


@dataclass
class Track:
    """A measured track; t in s from the first sample (t_start: its time in the file, s).
    Arrays are None where the file has no such column. dropped_t: the file's times (s) of the
    rows dropped for a blank or NaN cell (lost frames); dropped_untimed: rows dropped without a
    time."""

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
    lost = f" ({dropped_t.size + untimed} rows with a blank or NaN cell dropped)" \
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


# --- reading a file -------------------------------------------------------------------------

#: column names (lower case, units and spaces stripped) -> the track's columns
ALIASES = {"t": "t", "time": "t", "x": "x", "y": "y", "theta_deg": "theta_deg",
           "chidot": "chidot", **{k: k for k in PROBE_COLUMNS}}
#: a column's name and its unit: 'x (cm)', 'x [cm]', 'x/cm'
_UNIT_RE = re.compile(r"^(.*?)\s*(?:[(\[]\s*([^)\]]*?)\s*[)\]]|/\s*([A-Za-z]+))\s*$")
#: how many lines may come before the header (a name line or two)
HEADER_WITHIN = 5


def _split(line: str, sep: str | None) -> list[str]:
    return [c.strip().strip('"').strip() for c in (line.split(sep) if sep else line.split())]


def _separator(line: str) -> str | None:
    for sep in ("\t", ";", ","):
        if sep in line:
            return sep
    return None


def _name_and_unit(cell: str) -> tuple[str, str | None]:
    m = _UNIT_RE.match(cell)
    if m and (m.group(2) or m.group(3)) is not None:
        return m.group(1).strip().lower(), (m.group(2) or m.group(3)).strip()
    return cell.strip().lower(), None


def _quoted(cells) -> str:
    return ", ".join(repr(str(c)) for c in cells) or "none"


def read_track(path, probe_m: float | None = None, units: str | None = None,
               time_units: str | None = None) -> Track:
    """Read a track file as a spreadsheet or Tracker ("Export Data") writes it.

    Layout: up to HEADER_WITHIN lines before the header (Tracker's line naming the tracked
    mass); a header with a column t (or time) and x, y (the centre of mass), or two tracked
    masses named with 'tip' and 'base' on the name line (each with its x, y), or columns
    x_tip, y_tip, x_base, y_base (the probe, with probe_m); optionally theta_deg (deg) and
    chidot (rad/s); other columns are ignored. Cells separated by tabs, semicolons or commas
    (a decimal comma with tabs or semicolons). Units: from the header ('x (cm)', 't (ms)') or
    `units` (m, cm, mm) and `time_units` (s, ms); default m and s. Rows with a blank or NaN
    cell (lost frames) are dropped and their times kept in `Track.dropped_t`. InputError (one
    line) for a file that is not such a track."""
    import io

    import pandas as pd

    p = limits.regular_file(path, "track (a CSV or Tracker file)")
    for name, u, allowed in (("--units", units, LENGTH_UNITS), ("--time-units", time_units,
                                                                TIME_UNITS)):
        if u is not None and u not in allowed:
            raise limits.InputError(f"{name} {u!r}: one of {', '.join(allowed)}")
    try:
        text = p.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError:
        text = p.read_bytes().decode("latin-1")
    lines = text.splitlines()
    head_at, sep, header = None, None, []
    seen = [ln for ln in lines[:HEADER_WITHIN] if ln.strip()]
    for i, line in enumerate(lines[:HEADER_WITHIN + 1]):
        if not line.strip():
            continue
        sep = _separator(line)
        cells = _split(line, sep)
        if any(ALIASES.get(_name_and_unit(c)[0]) == "t" for c in cells):
            head_at, header = i, cells
            break
    if head_at is None:
        # the line most like a header: the one with the most cells
        first = max((_split(ln, _separator(ln)) for ln in seen), key=len, default=[])
        raise limits.InputError(f"{path}: needs a header with a column t (s); found columns "
                                f"{_quoted(first)}")
    # Tracker's name line: one name over each tracked mass's block of columns
    names = [""] * len(header)
    if head_at > 0 and lines[head_at - 1].strip():
        above = _split(lines[head_at - 1], sep)
        current = ""
        for j in range(len(header)):
            if j < len(above) and above[j]:
                current = above[j]
            names[j] = current
    blocks = [n for n in dict.fromkeys(names) if n]
    found = f"found columns {_quoted(header)}"
    columns, col_units = {}, {}
    for j, cell in enumerate(header):
        base, unit = _name_and_unit(cell)
        key = ALIASES.get(base)
        if key is None:
            continue
        if key in ("x", "y") and len(blocks) > 1:
            low = names[j].lower()
            role = "tip" if "tip" in low else "base" if "base" in low else None
            if role is None:
                raise limits.InputError(
                    f"{path}: {len(blocks)} tracked masses ({_quoted(blocks)}); name the probe's "
                    f"two 'tip' and 'base' (or give columns x_tip, y_tip, x_base, y_base); "
                    f"{found}")
            key = f"{key}_{role}"
        if key in columns:
            if key == "t":
                continue  # each tracked mass's own t: the first is the track's
            raise limits.InputError(f"{path}: column {key} twice; {found}")
        columns[key], col_units[key] = j, unit
    body = "\n".join(lines[head_at + 1:])
    if not body.strip():
        raise limits.InputError(f"{path}: no rows below the header; {found}")
    decimal = "."
    if sep in ("\t", ";") and re.search(r"(?m)(^|[\t;])\s*-?\d+,\d+\s*([\t;]|$)", body):
        decimal = ","
    try:
        df = pd.read_csv(io.StringIO(body), sep=sep if sep else r"\s+", header=None,
                         dtype=str, keep_default_na=False, decimal=decimal,
                         skipinitialspace=True, engine="python")
    except (ValueError, pd.errors.ParserError) as exc:
        raise limits.InputError(f"{path}: not a table ({str(exc).splitlines()[0]}); "
                                f"{found}") from None
    if df.shape[1] < len(header):  # trailing empty columns of the last rows
        for j in range(df.shape[1], len(header)):
            df[j] = ""
    data = {}
    for key, j in columns.items():
        raw = df[j].astype(str).str.strip()
        if decimal == ",":
            raw = raw.str.replace(",", ".", regex=False)
        missing = raw.str.lower().isin(("", "nan", "na", "n/a", "null", "none"))
        v = pd.to_numeric(raw.where(~missing, "nan"), errors="coerce")
        odd = np.flatnonzero(v.isna().to_numpy() & ~missing.to_numpy())
        if odd.size:
            raise limits.InputError(f"{path}: row {head_at + 2 + odd[0]}, column "
                                    f"{header[j]!r}: {raw.iloc[odd[0]]!r} is not a number; "
                                    f"{found}")
        data[key] = v.to_numpy(dtype=float)
    if "t" not in data:
        raise limits.InputError(f"{path}: needs a header with a column t (s); {found}")
    positions = [k for k in data if k not in ("t", "theta_deg", "chidot")]
    if not positions:
        raise limits.InputError(f"{path}: needs columns x, y (the centre of mass) or the "
                                f"probe's tip and base; {found}")
    for key, allowed, given, flag in (("x", LENGTH_UNITS, units, "--units"),
                                      ("t", TIME_UNITS, time_units, "--time-units")):
        keys = positions if key == "x" else ["t"]
        said = {col_units[k] for k in keys if col_units[k] is not None}
        for u in said:
            if u not in allowed:
                raise limits.InputError(f"{path}: unit {u!r} in the header; {', '.join(allowed)} "
                                        f"are read ({flag} for a header without units); {found}")
        if len(said) > 1:
            raise limits.InputError(f"{path}: the header mixes units {_quoted(sorted(said))}; "
                                    f"{found}")
        if said and given is not None and said != {given}:
            raise limits.InputError(f"{path}: the header says {said.pop()} and {flag} says "
                                    f"{given}: one of them")
        unit = said.pop() if said else (given or ("m" if key == "x" else "s"))
        for k in keys:
            data[k] = data[k] * allowed[unit]
    for k in ("theta_deg", "chidot"):
        if k in data and col_units[k] not in (None, "deg", "rad/s"):
            raise limits.InputError(f"{path}: column {header[columns[k]]!r}: {k} is read in "
                                    f"{'deg' if k == 'theta_deg' else 'rad/s'}; {found}")
    return make_track(data.pop("t"), probe_m=probe_m, source=str(path), drop_missing=True,
                      **data)


# --- the model ------------------------------------------------------------------------------

def _channels(track: Track) -> list[str]:
    out = ["x_tip", "y_tip", "x_base", "y_base"] if track.probe else ["x", "y"]
    return out + [k for k in ("theta_deg", "chidot") if getattr(track, k) is not None]


def _sigma(name: str) -> float:
    return {"theta_deg": THETA_SIGMA_DEG, "chidot": CHIDOT_SIGMA}.get(name, POSITION_SIGMA_M)


def _model_local(traj: np.ndarray, ball: Ball, probe_m: float | None) -> dict:
    """Channels of sampled fast states (n_t, N_FAST, n) launched at chi0 = 0 from the origin:
    positions (m) before the turn and shift, theta (deg), chidot (rad/s)."""
    a, tu = ball.a, ball.time_unit
    gx, gy = traj[:, S_X] * a, traj[:, S_Y] * a
    out = {"theta_deg": np.degrees(traj[:, S_TH]), "chidot": traj[:, S_CHD] / tu}
    if probe_m is None:
        out["x"], out["y"] = gx, gy
    else:
        with np.errstate(invalid="ignore"):  # a launch that blew up: NaN, judged as such
            pts = body_points(gx, gy, traj[:, S_TH], traj[:, S_CHI], ball, probe_m)
        for k in ("x_tip", "y_tip", "x_base", "y_base"):
            out[k] = pts[k]
    return out


def _place(local: dict, chi0_deg, x0, y0) -> dict:
    """Turn the positions by chi0 about the origin and shift them by (x0, y0)."""
    c, s = np.cos(np.radians(chi0_deg)), np.sin(np.radians(chi0_deg))
    out = dict(local)
    for px, py in POSITION_PAIRS:
        if px in local:
            out[px] = c * local[px] - s * local[py] + x0
            out[py] = s * local[px] + c * local[py] + y0
    return out


def _integrate(dyn: np.ndarray, ball: Ball, T: float, dt: float, every: int):
    """Fast-state samples of launches dyn (4, n) = theta0_deg, thetadot0, chidot0, phidot0 from
    chi0 = 0 at the origin: (times (s), traj (n_t, N_FAST, n), ok (n,): ran to the end, valid
    (n_t, n): the samples before a launch stopped (the Euler chart's edge, or non-finite))."""
    tu = ball.time_unit
    plan = StepPlan(T, dt, tu, multiple=every)
    n_rec = plan.n_steps // every + 1
    y0 = launch_state(dyn[0], dyn[1], dyn[2], dyn[3], tu)
    p = np.repeat(ball.nondim_params().reshape(3, 1), dyn.shape[1], axis=1)
    res = run_tracks(y0, p, plan, every, n_rec, parallel=dyn.shape[1] > 16)  # one block: serial
    traj = res.traj
    t_nd = np.arange(n_rec) * plan.dt_nd * every
    with np.errstate(invalid="ignore"):
        valid = (np.isnan(res.t_stop) | (t_nd[:, None] < res.t_stop - plan.dt_nd * every))
        valid &= np.isfinite(traj[:, S_X]) & np.isfinite(traj[:, S_Y])
        ok = (res.outcome == OK) & valid.all(axis=0)
    return t_nd * tu, traj, ok, valid


def _integrate_resisted(dyn: np.ndarray, ball: Ball, t: np.ndarray):
    """`_integrate` for launches dyn (5, n) that slow: theta0_deg, thetadot0, chidot0, phidot0
    and the rolling-resistance coefficient, each by `compose.run_resisted_trajectory`, sampled
    at the times t (s) themselves: (t, traj (n_t, N_FAST, n), ok (n,))."""
    tu = ball.time_unit
    traj = np.empty((t.size, N_FAST, dyn.shape[1]))
    ok = np.empty(dyn.shape[1], dtype=bool)
    for j in range(dyn.shape[1]):
        y0 = launch_state(dyn[0, j], dyn[1, j], dyn[2, j], dyn[3, j], tu)[:, 0]
        res = run_resisted_trajectory(y0, ball.nondim_params(), dyn[4, j], t[-1] / tu,
                                      t_out=t / tu)
        traj[:, :, j] = res.traj
        ok[j] = res.outcome[0] == OK and bool(np.isfinite(res.traj[:, :S_Y + 1]).all())
    return t, traj, ok


def _dyn_index(slowing: bool) -> list[int]:
    """Where the integration's parameters stand in a fitted launch (PARAMS, then SLOWING): the
    tilt and three rates, and with slowing the rolling-resistance coefficient."""
    return [0, 1, 2, 3, 7] if slowing else [0, 1, 2, 3]


def _fallback_traj(q, ball: Ball, T: float, dt: float, n_t: int) -> np.ndarray:
    """One launch's samples through `run_trajectory`, which integrates again in the fixed frame
    a launch that meets the Euler chart's singularity (near-vertical)."""
    tu = ball.time_unit
    plan = StepPlan(T, dt, tu, multiple=n_t - 1)
    y0 = launch_state(q[0], q[1], q[2], q[3], tu)[:, 0]
    res = run_trajectory(y0, ball.nondim_params(), plan, "rk4", n_out=n_t)
    return res.traj[:, :, None]


class _Model:
    """Residuals and Jacobian of one track's fit over its first T seconds."""

    def __init__(self, track: Track, ball: Ball, T: float, slowing: bool = False):
        self.track, self.ball, self.slowing = track, ball, slowing
        # the parameters the integration takes (the rest turn and shift its positions)
        self.dyn = _dyn_index(slowing)
        m = track.t <= T + 1e-12
        self.idx = np.flatnonzero(m)
        self.T = float(track.t[self.idx[-1]])
        self.names = _channels(track)
        self.data = {k: getattr(track, k)[self.idx] for k in self.names}
        self.cache: dict = {}

    def _run(self, dyn: np.ndarray) -> list[dict]:
        if self.slowing:
            times, traj, ok = _integrate_resisted(dyn, self.ball, self.track.t[self.idx])
        else:
            times, traj, ok, _ = _integrate(dyn, self.ball, self.T, FIT_DT, 1)
        out = []
        for j in range(dyn.shape[1]):
            tr = traj[:, :, j:j + 1]
            if not ok[j] and not self.slowing:  # the resisted run is in the fixed frame already
                tr = _fallback_traj(dyn[:, j], self.ball, self.T, FIT_DT, times.size)
            loc = _model_local(tr, self.ball, self.track.probe_m)
            tt = self.track.t[self.idx]
            out.append({k: np.interp(tt, times, v[:, 0]) for k, v in loc.items()})
        return out

    def residual_of(self, placed: dict) -> np.ndarray:
        r = np.concatenate([(placed[k] - self.data[k]) / _sigma(k) for k in self.names])
        # a sample exactly at the vertical has no Euler angles: far off, not NaN
        return np.nan_to_num(r, nan=1e8, posinf=1e8, neginf=-1e8)

    def fun(self, q: np.ndarray) -> np.ndarray:
        key = q.tobytes()
        if key not in self.cache:
            self.cache = {key: self._run(q[self.dyn].reshape(-1, 1))[0]}
        return self.residual_of(_place(self.cache[key], *q[4:7]))

    def jac(self, q: np.ndarray) -> np.ndarray:
        nd = len(self.dyn)
        h = 1e-7 * np.maximum(1.0, np.abs(q[self.dyn]))
        dyn = np.repeat(q[self.dyn].reshape(nd, 1), nd + 1, axis=1)
        dyn[np.arange(nd), np.arange(1, nd + 1)] += h
        runs = self._run(dyn)
        self.cache = {q.tobytes(): runs[0]}
        r0 = self.residual_of(_place(runs[0], *q[4:7]))
        cols = [(self.residual_of(_place(runs[k + 1], *q[4:7])) - r0) / h[k] for k in range(nd)]
        slowing_col = cols[4:]  # the coefficient's column goes last, after chi0, x0, y0
        cols = cols[:4]
        # chi0, x0, y0 turn and shift the positions: their columns in closed form
        loc, rad = runs[0], math.radians(q[4])
        c, s = math.cos(rad), math.sin(rad)
        dchi, dx, dy = {}, {}, {}
        for k in self.names:
            z = np.zeros(self.idx.size)
            dchi[k], dx[k], dy[k] = z, z, z
        for px, py in POSITION_PAIRS:
            if px in self.names:
                one, zero = np.ones(self.idx.size), np.zeros(self.idx.size)
                dchi[px] = (-s * loc[px] - c * loc[py]) * math.pi / 180
                dchi[py] = (c * loc[px] - s * loc[py]) * math.pi / 180
                dx[px], dx[py], dy[px], dy[py] = one, zero, zero, one
        for d in (dchi, dx, dy):
            cols.append(np.concatenate([d[k] / _sigma(k) for k in self.names]))
        return np.column_stack(cols + slowing_col)


# --- the global start -----------------------------------------------------------------------

def _centre_of_probe(track: Track, ball: Ball):
    """G's horizontal position from the probe: G = base + (c + a - h) (base - tip) / L (the
    probe lies on the symmetry axis, its base at the flat face's centre)."""
    k = (ball.c + ball.a - ball.cut_height) / track.probe_m
    return (track.x_base + k * (track.x_base - track.x_tip),
            track.y_base + k * (track.y_base - track.y_tip))


def initial_velocity(track: Track, ball: Ball, window_s: float = 0.1):
    """(x0, y0, vx0, vy0) of G at the first sample (m, m/s): a quadratic least-squares fit over
    the first window_s seconds (at least 5 samples)."""
    gx, gy = (track.x, track.y) if not track.probe else _centre_of_probe(track, ball)
    n = max(5, int(np.searchsorted(track.t, window_s)))
    t = track.t[:n]
    cx = np.polynomial.polynomial.polyfit(t, gx[:n], 2)
    cy = np.polynomial.polynomial.polyfit(t, gy[:n], 2)
    return cx[0], cy[0], cx[1], cy[1]


def survey_launches(track: Track, ball: Ball, box=None, grid=None) -> np.ndarray:
    """The survey's launches (4, n): theta0_deg, thetadot0, chidot0 on the grid of the box
    (narrowed to the track's own first theta_deg and chidot when it has them), and phidot0 from
    the initial speed of G, |v| = sqrt(((a phidot - c chidot) cos th)^2 + ((a - c sin th)
    thetadot)^2) (Eqs. 6-7), with both signs."""
    box = {**BOX, **(box or {})}
    grid = {**GRID, **(grid or {})}
    axes = {k: np.linspace(*box[k], grid[k]) for k in box}
    flat = math.degrees(ball.flat_face_theta_rad)
    th = np.union1d(axes["theta0_deg"], [t for t in NEAR_VERTICAL if t >= box["theta0_deg"][0]])
    axes["theta0_deg"] = th[th > flat]
    if track.theta_deg is not None:
        th = float(np.median(track.theta_deg[:3]))
        axes["theta0_deg"] = np.unique(np.clip(th + np.linspace(-3, 3, 7), flat + 0.1, 89.9))
    if track.chidot is not None:
        ch = float(np.median(track.chidot[:3]))
        axes["chidot0"] = ch + np.linspace(-1.5, 1.5, 13)
    th, thd, chd = (g.ravel() for g in np.meshgrid(axes["theta0_deg"], axes["thetadot0"],
                                                  axes["chidot0"], indexing="ij"))
    _, _, vx, vy = initial_velocity(track, ball)
    v2 = vx * vx + vy * vy
    a, c = ball.a, ball.c
    sth, cth = np.sin(np.radians(th)), np.cos(np.radians(th))
    w = (a - c * sth) * thd
    u = np.sqrt(np.maximum(v2 - w * w, 0.0))
    phd = [(c * chd + sign * u / cth) / a for sign in (1.0, -1.0)]
    keep = np.concatenate([np.abs(p) <= limits.MAX_RATE for p in phd])
    return np.stack([np.tile(th, 2), np.tile(thd, 2), np.tile(chd, 2),
                     np.concatenate(phd)])[:, keep]


def _align(loc: dict, data: dict, names, w: dict, valid: np.ndarray):
    """Best turn chi0 (deg) and shift (x0, y0) of each launch's positions onto the data, in
    closed form (2-D Procrustes without reflection, over each launch's valid samples), and the
    weighted misfit left, scaled to all the samples (a launch that left the Euler chart part
    way is judged by its mean misfit before)."""
    pos = [(px, py) for px, py in POSITION_PAIRS
           if px in names]
    wt = np.concatenate([valid] * len(pos)).astype(float)
    n = wt.sum(0)

    def clean(v):
        return np.where(wt > 0, v, 0.0)

    mx = clean(np.concatenate([loc[px] for px, _ in pos]))
    my = clean(np.concatenate([loc[py] for _, py in pos]))
    dx = np.concatenate([data[px] for px, _ in pos])[:, None]
    dy = np.concatenate([data[py] for _, py in pos])[:, None]
    mcx, mcy = mx.sum(0) / n, my.sum(0) / n
    dcx, dcy = (wt * dx).sum(0) / n, (wt * dy).sum(0) / n
    ax, ay, bx, by = wt * (mx - mcx), wt * (my - mcy), wt * (dx - dcx), wt * (dy - dcy)
    ang = np.arctan2((ax * by - ay * bx).sum(0), (ax * bx + ay * by).sum(0))
    c, s = np.cos(ang), np.sin(ang)
    x0, y0 = dcx - (c * mcx - s * mcy), dcy - (s * mcx + c * mcy)
    cost = ((c * ax - s * ay - bx) ** 2 + (s * ax + c * ay - by) ** 2).sum(0) / POSITION_SIGMA_M**2
    for k in ("theta_deg", "chidot"):
        if k in names:
            r = np.where(valid, (loc[k] - data[k][:, None]) / w[k], 0.0)
            cost = cost + (r * r).sum(0)
    return np.degrees(ang), x0, y0, cost * wt.shape[0] / n


def survey(track: Track, ball: Ball, *, box=None, grid=None, T: float = SURVEY_T,
           batch: int = 4096) -> np.ndarray:
    """The global survey: every launch of `survey_launches` over the first T seconds of the
    track on the ensemble kernel, aligned in closed form; returns rows (7, n) of launches
    (PARAMS order) and their misfit (n,), best first."""
    dyn = survey_launches(track, ball, box, grid)
    T = min(T, float(track.t[-1]))
    every = max(1, int(round(SURVEY_EVERY / SURVEY_DT)))
    names = _channels(track)
    w = {k: _sigma(k) for k in names}
    launches, costs = [], []
    for lo in range(0, dyn.shape[1], batch):
        part = dyn[:, lo:lo + batch]
        times, traj, ok, valid = _integrate(part, ball, T, SURVEY_DT, every)
        data = {k: np.interp(times, track.t, getattr(track, k)) for k in names}
        loc = _model_local(traj, ball, track.probe_m)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            chi0, x0, y0, cost = _align(loc, data, names, w, valid)
        # a launch that left the Euler chart (near the vertical) within the first half of the
        # window, or blew up: out; later, judged by its mean misfit (the refinement integrates
        # it again in the fixed frame)
        enough = valid.sum(0) >= SURVEY_VALID * valid.shape[0]
        cost = np.where(enough & np.isfinite(cost), cost, np.inf)
        launches.append(np.vstack([part, chi0, x0, y0]))
        costs.append(cost)
    launches, costs = np.hstack(launches), np.concatenate(costs)
    order = np.argsort(costs, kind="stable")
    return launches[:, order], costs[order]


# --- the fit --------------------------------------------------------------------------------

def _bounds(ball: Ball, slowing: bool = False):
    flat = math.degrees(ball.flat_face_theta_rad)
    r = limits.MAX_RATE
    lo = [flat + 1e-3, -r, -r, -r, -np.inf, -np.inf, -np.inf] + [0.0] * slowing
    hi = [89.9, r, r, r, np.inf, np.inf, np.inf] + [limits.MAX_ROLLING_RESISTANCE] * slowing
    return np.array(lo), np.array(hi)


def _refine(model: _Model, q0: np.ndarray, ball: Ball, max_nfev: int):
    from scipy.optimize import least_squares

    lo, hi = _bounds(ball, model.slowing)
    q0 = np.clip(q0, lo + 1e-9, hi - 1e-9)
    return least_squares(model.fun, q0, jac=model.jac, bounds=(lo, hi), x_scale="jac",
                         method="trf", max_nfev=max_nfev, xtol=1e-12, ftol=1e-12, gtol=1e-12)


def _as_track(track, probe_m) -> Track:
    if isinstance(track, (str, Path)):
        track = read_track(track, probe_m=probe_m)
    elif not isinstance(track, Track):  # a mapping of columns or a pandas DataFrame
        cols = {str(k): np.asarray(track[k], dtype=float) for k in track.keys()
                if str(k) in COLUMNS}
        if "t" not in cols:
            raise limits.InputError("track: needs a column t (s)")
        track = make_track(cols.pop("t"), probe_m=probe_m, drop_missing=True, **cols)
    if track.probe and track.probe_m is None:
        raise limits.InputError("a probe track needs probe_m (m)")
    return track


def _origin(track: Track) -> tuple[float, float]:
    """The track's first position (m): the fit works relative to it, so a track far from the
    origin loses no digits to it."""
    px, py = ("x", "y") if not track.probe else ("x_base", "y_base")
    return float(getattr(track, px)[0]), float(getattr(track, py)[0])


def _shifted(track: Track, ox: float, oy: float) -> Track:
    cols = {}
    for px, py in POSITION_PAIRS:
        if getattr(track, px) is not None:
            cols[px], cols[py] = getattr(track, px) - ox, getattr(track, py) - oy
    return replace(track, **cols)


def _pick_starts(starts: np.ndarray, costs: np.ndarray, n: int, box, grid) -> list:
    """The survey's launches to refine: the N_BEST best, then the best of each further basin
    (a launch more than a grid step from every one picked, in theta0, thetadot0 or chidot0, or
    with the other sign of phidot0), n in all."""
    box, grid = {**BOX, **(box or {})}, {**GRID, **(grid or {})}
    step = np.array([(box[k][1] - box[k][0]) / max(grid[k] - 1, 1) * 1.01
                     for k in ("theta0_deg", "thetadot0", "chidot0")])
    picked: list[int] = []
    for j in np.flatnonzero(np.isfinite(costs))[:PICK_SCAN]:
        if len(picked) >= n:
            break
        if len(picked) >= N_BEST:
            p = starts[:4, picked]
            near = np.all(np.abs(p[:3] - starts[:3, j:j + 1]) <= step[:, None], axis=0) & \
                (np.sign(p[3]) == np.sign(starts[3, j]))
            if near.any():
                continue
        picked.append(int(j))
    return [starts[:, j] for j in picked]


def _same_launch(qa, qb, tol) -> bool:
    d = np.abs(np.asarray(qa[:4]) - np.asarray(qb[:4]))
    return bool(np.all(d <= tol))


def noise_estimate(track: Track) -> tuple[float, int]:
    """The tracking noise of the positions (m, one coordinate), from the track alone: the
    median absolute third difference of consecutive samples, 1.4826 MAD / sqrt(20) (white
    noise of deviation s gives third differences of deviation sqrt(20) s; a smooth path adds
    its third derivative times dt^3, small at video rates). Returns (estimate, values used)."""
    d = np.concatenate([np.diff(getattr(track, k), 3)
                        for pair in POSITION_PAIRS for k in pair if getattr(track, k) is not None])
    return float(1.4826 * np.median(np.abs(d)) / math.sqrt(20.0)), int(d.size)


def residual_tests(res: dict) -> dict:
    """Structure in the position residuals (each channel in time order): the Wald-Wolfowitz
    runs test of their signs (z: below -4, far fewer runs than white noise makes) and the lag-1
    autocorrelation rho (z = rho sqrt(n))."""
    runs = mu = var = 0.0
    num = den = 0.0
    n_all = 0
    for r in res.values():
        pos = r > 0
        n1, n2 = int(pos.sum()), int((~pos).sum())
        n = n1 + n2
        if n1 == 0 or n2 == 0:
            continue
        runs += 1 + int(np.count_nonzero(pos[1:] != pos[:-1]))
        m = 2.0 * n1 * n2 / n + 1.0
        mu += m
        var += (m - 1.0) * (m - 2.0) / (n - 1.0)
        c = r - r.mean()
        num += float(np.dot(c[1:], c[:-1]))
        den += float(np.dot(c, c))
        n_all += n
    z_runs = (runs - mu) / math.sqrt(var) if var > 0 else 0.0
    rho = num / den if den > 0 else 0.0
    return {"runs_z": float(z_runs), "autocorrelation": float(rho),
            "autocorrelation_z": float(rho * math.sqrt(max(n_all, 1)))}


def _covariance(J: np.ndarray, s2: float):
    """Covariance s^2 (J^T J)^-1 by the SVD of J with its columns scaled to unit norm (no
    direction dropped: one the track does not fix comes out wide, not zero), its condition
    number, and the one-parameter floor sqrt(s^2 / |J_k|^2) below which no marginal sigma can
    lie."""
    norm = np.linalg.norm(J, axis=0)
    norm = np.where(norm > 0, norm, 1.0)
    _, sv, vt = np.linalg.svd(J / norm, full_matrices=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
    sv = np.maximum(sv, sv[0] * 1e-15)
    cov = (vt.T / sv**2) @ vt / np.outer(norm, norm) * s2
    floor = np.sqrt(s2) / norm
    return cov, cond, floor


def heading_deg(q, ball: Ball) -> float:
    """Direction (deg, counter-clockwise from x) of G's velocity at the launch q (PARAMS order):
    chi0 + atan2(w, u), u = (a phidot0 - c chidot0) cos theta0 along xi = (cos chi0, sin chi0),
    w = (a - c sin theta0) thetadot0 along the normal to xi (Eqs. 6-7)."""
    th = math.radians(q[0])
    u = (ball.a * q[3] - ball.c * q[2]) * math.cos(th)
    w = (ball.a - ball.c * math.sin(th)) * q[1]
    return _wrap_deg(q[4] + math.degrees(math.atan2(w, u)))


def _wrap_deg(a: float) -> float:
    """An angle in (-180, 180] deg."""
    return float(-((-a + 180.0) % 360.0 - 180.0)) + 0.0


def _angle_err(f, q, cov, h=1e-6) -> float:
    """One standard deviation of an angle f(q) (deg) by linear propagation."""
    g = np.zeros(q.size)
    for k in range(q.size):
        dq = np.zeros(q.size)
        dq[k] = h * max(1.0, abs(q[k]))
        g[k] = ((f(q + dq) - f(q - dq) + 180.0) % 360.0 - 180.0) / (2 * dq[k])
    return float(math.sqrt(max(g @ cov @ g, 0.0)))


def _carry(model_short: _Model, track: Track, ball: Ball, r, T_full: float):
    """One refined start taken on over windows doubled until they hold the whole track."""
    T, x, model = min(START_T, T_full), r.x, model_short
    while T < T_full:
        T = min(2 * T, T_full)
        model = _Model(track, ball, T, model_short.slowing)
        r = _refine(model, x, ball, 60 if T == T_full else 25)
        x = r.x
    return r, model


def _undetermined(err, box) -> dict:
    """The parameters whose standard deviation spans more than WIDE_SHARE of the survey's box
    (theta0, thetadot0, chidot0), more than WIDE_PHIDOT rad/s (phidot0) or WIDE_CHI_DEG (chi0):
    over such a span the motion changes, so a linear uncertainty cannot describe it and other
    launches fit as well. Returns {name: sigma}."""
    box = {**BOX, **(box or {})}
    wide = {k: WIDE_SHARE * (box[k][1] - box[k][0]) for k in box}
    wide.update(phidot0=WIDE_PHIDOT, chi0_deg=WIDE_CHI_DEG)
    return {k: float(err[PARAMS.index(k)]) for k in PARAMS if k in wide
            and err[PARAMS.index(k)] > wide[k]}


def _label_run(q, ball: Ball, T: float, rolling_resistance: float = 0.0):
    return simulate(q[0], q[1], q[2], q[3], T=T, chi0_deg=q[4], x0=q[5], y0=q[6], ball=ball,
                    n_out=2001, rolling_resistance=rolling_resistance)


def _model_problems(ds, T_track: float, ball: Ball) -> list[str]:
    """Where the launch leaves the rolling model over the track's time: the flat face on the
    table, lift-off (N <= 0) or slipping (|F_h|/N above the classifier's mu)."""
    from .classify.labels import Thresholds

    on = ds.time.values <= T_track + 1e-9
    out = []
    flat = math.degrees(ball.flat_face_theta_rad)
    th = ds.theta_deg.values[on]
    if np.nanmin(th) < flat:
        t = float(ds.time.values[on][np.nanargmin(th)])
        out.append(f"the flat face reaches the table (theta {np.nanmin(th):.1f} deg < "
                   f"{flat:.1f} deg at t = {t:.2f} s)")
    n = ds.normal_force.values[on]
    if np.nanmin(n) <= 0:
        out.append(f"the ball lifts off (normal force {np.nanmin(n):.3g} N)")
    mu = Thresholds().mu
    fr = ds.friction_ratio.values[on]
    fr = fr[np.isfinite(fr)]  # infinite where the ball has lifted off: said above
    if fr.size and fr.max() > mu:
        out.append(f"it would slip (friction |F_h|/N up to {fr.max():.2f}, above mu = "
                   f"{mu:g})")
    return out


def fit_track(track, ball: Ball | None = None, *, probe_m: float | None = None, box=None,
              grid=None, n_starts: int = N_STARTS, label_T: float = LABEL_T,
              slowing: bool = False) -> dict:
    """Fit the launch that best reproduces a measured track, and say how far to trust it.

    Parameters
    ----------
    track : Track, str, Path, dict or pandas.DataFrame
        A `Track` (`make_track`), a track file (`read_track`), or columns by name (t, x, y or
        x_tip, y_tip, x_base, y_base, optionally theta_deg, chidot; the rules of `make_track`,
        rows with a non-finite value dropped).
    ball : Ball, optional
        The ball (default: the paper's).
    probe_m : float, optional
        Probe length (m) for a track given by its probe's tip and base.
    box, grid : dict, optional
        The survey's launch box ``{name: (lo, hi)}`` and grid sizes ``{name: n}`` for
        theta0_deg (deg), thetadot0 and chidot0 (rad/s); defaults `BOX`, `GRID`.
    n_starts : int
        Survey launches refined locally over the first START_T seconds (the best of each
        distinct basin, up to N_CARRIED, carried on to the whole track).
    label_T : float
        Duration (s) of the run that labels the fitted launch (the track's if longer).
    slowing : bool
        Fit a ball that slows: the model has the rolling resistance (`simulate`'s
        rolling_resistance), its coefficient fitted with the launch (from SLOWING_START, within
        0 to 1). The survey is of the rolling model without it; the refinement integrates each
        launch in the fixed frame by dopri5 (rtol 1e-10), slower than the plain fit.

    Returns
    -------
    dict
        theta0_deg (deg), thetadot0, chidot0, phidot0 (rad/s), chi0_deg (deg), x0, y0 (m) at the
        first sample, each with ``_err`` (one standard deviation); rms_m, the root-mean-square
        position residual per coordinate (m); label, the label of the fitted launch; status:
        "ok", "ambiguous" (other launches fit within the noise: ``alternatives``, each with its
        launch, rms_m, label and delta_chi2), "mismatch" (the model does not explain the track:
        ``evidence``) or "failed" (``reasons``); heading_deg (and _err): the direction of G's
        velocity at the first sample in the track's axes (deg); noise_m, the tracking noise
        estimated from the track alone (m); notes (list of str); n_dropped, dropped_t (s);
        and t_start (s), n_samples, cost, survey_launches, seconds. With slowing, also
        rolling_resistance and rolling_resistance_err (dimensionless).
    """
    import time

    from scipy.stats import chi2

    t_wall = time.perf_counter()
    ball = ball or Ball.paper()
    track = _as_track(track, probe_m)
    ox, oy = _origin(track)
    rel = _shifted(track, ox, oy)
    starts, costs = survey(rel, ball, box=box, grid=grid)
    n_survey = costs.size
    if not np.isfinite(costs[0]):
        raise limits.InputError(f"{track.source}: no launch of the survey box stays on the "
                                "Euler chart over the track; widen the box")
    T_full = float(track.t[-1])
    picked = _pick_starts(starts, costs, n_starts, box, grid)
    if slowing:
        picked = [np.append(q, SLOWING_START) for q in picked]
    names = PARAMS + (SLOWING,) * slowing
    mu_r = (lambda v: float(v[7])) if slowing else (lambda v: 0.0)
    # the starts refined a little over a short window, where a launch a grid step away still
    # keeps the track's phase; the best of each distinct basin taken on over windows doubled to
    # the whole track
    T = min(START_T, T_full)
    model = _Model(rel, ball, T, slowing)
    fits = sorted((_refine(model, q, ball, 12) for q in picked), key=lambda r: r.cost)
    carried = []
    for r in fits:
        if len(carried) >= N_CARRIED or r.cost > CARRY_FACTOR * fits[0].cost:
            break
        if not any(_same_launch(r.x, c.x, SAME_BASIN) for c in carried):
            carried.append(r)
    ends = [_carry(model, rel, ball, r, T_full) for r in carried]
    ends.sort(key=lambda e: e[0].cost)
    best, model = ends[0]
    q = best.x
    J = best.jac
    m, n = J.shape
    dof = max(m - n, 1)
    s2 = 2.0 * best.cost / dof
    cov, cond, floor = _covariance(J, s2)
    err = np.sqrt(np.maximum(np.diag(cov), 0.0))
    notes: list[str] = []
    if np.any(err < 0.999 * floor):
        notes.append("some standard deviations fell below what the noise allows for one "
                     "parameter alone; raised to that floor")
        err = np.maximum(err, floor)
    if cond > MAX_CONDITION:
        weak = [names[k] for k in range(n) if err[k] > 0.5 * (abs(q[k]) + floor[k] * 1e3)]
        notes.append(f"the track does not separate the parameters (Jacobian condition number "
                     f"{cond:.2g})" + (f": {', '.join(weak)} are barely fixed" if weak else ""))
    if q.tobytes() not in model.cache:
        model.fun(q)
    placed = _place(model.cache[q.tobytes()], *q[4:7])
    pos = [k for k in model.names if k not in ("theta_deg", "chidot")]
    res = {k: placed[k] - model.data[k] for k in pos}
    rms = float(np.sqrt(np.mean(np.concatenate(list(res.values())) ** 2)))

    # --- is it the only launch that fits? ----------------------------------------------------
    alternatives = []
    limit = chi2.ppf(ALT_LEVEL, n)
    for r, mod in ends[1:]:
        d_chi2 = 2.0 * (r.cost - best.cost) / s2
        if d_chi2 > limit or _same_launch(r.x, q, np.maximum(SAME_SIGMAS * err[:4], SAME_FLOOR)):
            continue
        if any(_same_launch(r.x, a["q"], SAME_BASIN) for a in alternatives):
            continue
        if r.x.tobytes() not in mod.cache:
            mod.fun(r.x)
        pl = _place(mod.cache[r.x.tobytes()], *r.x[4:7])
        rms_a = float(np.sqrt(np.mean(np.concatenate([pl[k] - mod.data[k] for k in pos]) ** 2)))
        alternatives.append({"q": r.x, "rms_m": rms_a, "delta_chi2": float(d_chi2)})

    # --- does the track fix the launch at all? ----------------------------------------------
    undetermined = _undetermined(err, box)
    if undetermined:
        notes.append("the track does not fix the launch: " + ", ".join(
            f"{k} +- {v:.3g}" for k, v in undetermined.items()) + " span motions of other "
            "kinds, so the standard deviations are not meaningful and other launches fit as well")

    # --- does the model explain the track? ---------------------------------------------------
    noise, n_diff = noise_estimate(rel)
    noise_eff = math.hypot(noise, RESOLUTION_M)
    ratio = rms / noise_eff
    sd_ratio = math.sqrt(NOISE_SPREAD**2 / max(n_diff, 1) + 1.0 / (2.0 * max(
        sum(v.size for v in res.values()) - n, 1)))
    tests = residual_tests(res)
    evidence = {"rms_over_noise": ratio, "rms_over_noise_z": (ratio - 1.0) / sd_ratio, **tests}
    structured = rms > RESOLUTION_M and (tests["runs_z"] < -STRUCTURE_Z
                                         or tests["autocorrelation_z"] > STRUCTURE_Z)
    ds = _label_run(np.r_[q[:5], 0.0, 0.0], ball, max(label_T, T_full), mu_r(q))
    lab = ds.attrs["label"]
    reasons = []
    extent = max(np.ptp(model.data[k]) for k in pos)
    misfit = evidence["rms_over_noise_z"] > MISFIT_Z
    if rms > RESOLUTION_M and (ratio > FAIL_RATIO or (misfit and rms > FAIL_FRACTION * extent)):
        reasons.append(f"the best launch misses the track: rms {rms * 1e3:.3g} mm, "
                       f"{ratio:.1f} times the noise ({noise * 1e3:.2g} mm), "
                       f"{100 * rms / extent:.2g} % of the track's extent")
    reasons += _model_problems(ds, T_full, ball)
    box_ = {**BOX, **(box or {})}
    for k, i in (("thetadot0", 1), ("chidot0", 2)):
        lo, hi = box_[k]
        half = 0.5 * (hi - lo)
        if q[i] < lo - BOX_MARGIN * half or q[i] > hi + BOX_MARGIN * half:
            reasons.append(f"{k} {q[i]:.3g} rad/s lies far outside the survey's box "
                           f"({lo:g}..{hi:g})")
    lo_b, hi_b = _bounds(ball, slowing)
    at = [PARAMS[k] for k in range(4) if min(q[k] - lo_b[k], hi_b[k] - q[k]) < 1e-6]
    if at:
        reasons.append(f"{', '.join(at)} at the model's limit")
    if reasons:
        status = "failed"
    elif misfit or structured:
        status = "mismatch"
        widen = math.sqrt((1 + min(max(tests["autocorrelation"], 0.0), 0.95))
                          / (1 - min(max(tests["autocorrelation"], 0.0), 0.95)))
        err = err * widen
        cov = cov * widen**2
        notes.append(f"the model does not explain the track (rms {ratio:.2f} times the noise; "
                     f"runs z {tests['runs_z']:.1f}, autocorrelation "
                     f"{tests['autocorrelation']:.2f}): "
                     f"the standard deviations are widened by the residuals' correlation (x "
                     f"{widen:.2f}) and are a lower bound")
    elif alternatives or undetermined:
        status = "ambiguous"
    else:
        status = "ok"

    out = {}
    q_abs = q.copy()
    q_abs[5] += ox
    q_abs[6] += oy
    for k, v, e in zip(names, q_abs, err):
        out[k], out[k + "_err"] = float(v), float(e)
    # the heading is an angle: reported in (-180, 180] deg (the fit may wander a few turns)
    out["chi0_deg"] = _wrap_deg(out["chi0_deg"])
    out.update(rms_m=rms, label=lab, status=status)
    if alternatives or status == "ambiguous":
        alts = []
        for a in alternatives:
            qa = a["q"]
            alt = {k: float(v) for k, v in zip(PARAMS, qa)}
            alt["chi0_deg"] = _wrap_deg(alt["chi0_deg"])
            alt["x0"] += ox
            alt["y0"] += oy
            alt.update(rms_m=a["rms_m"], delta_chi2=a["delta_chi2"],
                       label=_label_run(np.r_[qa[:5], 0.0, 0.0], ball,
                                        max(label_T, T_full), mu_r(qa)).attrs["label"],
                       heading_deg=heading_deg(qa, ball))
            alts.append(alt)
        out["alternatives"] = alts
    if status == "mismatch":
        out["evidence"] = evidence
    if status == "failed":
        out["reasons"] = reasons
    out.update(heading_deg=heading_deg(q, ball),
               heading_deg_err=_angle_err(lambda v: heading_deg(v, ball), q, cov),
               noise_m=noise, rms_over_noise=ratio, notes=notes,
               n_dropped=int(track.dropped_t.size + track.dropped_untimed),
               dropped_t=[float(v) for v in track.dropped_t], condition=cond,
               t_start=track.t_start, n_samples=int(track.t.size), cost=float(2 * best.cost),
               survey_launches=int(n_survey), seconds=time.perf_counter() - t_wall)
    return out


def fitted_track(fit: dict, track: Track, ball: Ball | None = None, times=None) -> dict:
    """The fitted launch's channels (positions in m, theta in deg, chidot in rad/s) at the
    track's times, or at `times` (s from the first sample; e.g. a dense grid for a plot)."""
    ball = ball or Ball.paper()
    slowing = SLOWING in fit
    q = np.array([fit[k] for k in PARAMS + (SLOWING,) * slowing])
    T = float(track.t[-1])
    if slowing:
        grid = np.linspace(0.0, T, max(int(round(T / FIT_DT)), 1) + 1)
        times_, traj, _ = _integrate_resisted(q[_dyn_index(True)].reshape(-1, 1), ball, grid)
    else:
        times_, traj, ok, _ = _integrate(q[:4].reshape(4, 1), ball, T, FIT_DT, 1)
        if not ok[0]:
            traj = _fallback_traj(q[:4], ball, T, FIT_DT, times_.size)
    loc = _model_local(traj, ball, track.probe_m)
    at = track.t if times is None else np.asarray(times, dtype=float)
    return _place({k: np.interp(at, times_, v[:, 0]) for k, v in loc.items()}, *q[4:7])


def plot_fit(track: Track, fit: dict, out=None, ball: Ball | None = None):
    """Track and fitted launch overlaid: the path in the plane (m), and theta (deg) and chidot
    (rad/s) against time where the track has them. The model is drawn dense in time (every
    10 ms or finer) over the whole track, the dropped frames' model positions marked with
    crosses, and the alternative launches that fit as well drawn dashed. Returns the
    matplotlib Figure; writes it to `out` (PNG) if given."""
    from matplotlib.figure import Figure  # the object API: no global matplotlib state

    T = float(track.t[-1])
    dense = np.linspace(0.0, T, max(int(T / PLOT_DT) + 1, 2 * track.t.size))
    model = fitted_track(fit, track, ball, times=dense)
    lost = track.dropped_t - track.t_start
    lost = lost[(lost >= 0) & (lost <= T)]
    at_lost = fitted_track(fit, track, ball, times=lost) if lost.size else None
    alts = [fitted_track(a, track, ball, times=dense) for a in fit.get("alternatives", [])]
    extra = [k for k in ("theta_deg", "chidot") if getattr(track, k) is not None]
    fig = Figure(figsize=(6 + 4 * len(extra), 5.5), layout="constrained")
    axs = fig.subplots(1, 1 + len(extra), squeeze=False)
    ax = axs[0, 0]
    pairs = [("x_tip", "y_tip", "probe tip"), ("x_base", "y_base", "probe base")] \
        if track.probe else [("x", "y", "centre of mass")]
    for (px, py, what), col in zip(pairs, ("C0", "C2")):
        ax.plot(getattr(track, px), getattr(track, py), ".", ms=2, color=col,
                label=f"track: {what}")
        ax.plot(model[px], model[py], "-", lw=1, color="k" if col == "C0" else "C3",
                label=f"fit: {what}")
        for i, alt in enumerate(alts):
            ax.plot(alt[px], alt[py], "--", lw=0.8, color=f"C{4 + i}",
                    label=f"also fits: {what}" if i == 0 else None)
        if at_lost is not None:
            ax.plot(at_lost[px], at_lost[py], "x", ms=5, color="C1",
                    label="dropped frames (model)" if col == "C0" else None)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=8)
    ax.set_title(f"fit: {fit['label']}, {fit.get('status', 'ok')}, rms "
                 f"{fit['rms_m'] * 1e3:.3f} mm", fontsize=10)
    for axe, k in zip(axs[0, 1:], extra):
        axe.plot(track.t, getattr(track, k), ".", ms=2, label="track")
        axe.plot(dense, model[k], "k-", lw=1, label="fit")
        for i, alt in enumerate(alts):
            axe.plot(dense, alt[k], "--", lw=0.8, color=f"C{4 + i}",
                     label="also fits" if i == 0 else None)
        if at_lost is not None:
            axe.plot(lost, at_lost[k], "x", ms=5, color="C1", label="dropped frames (model)")
        axe.set_xlabel("t since the first sample (s)")
        axe.set_ylabel({"theta_deg": "theta (deg)", "chidot": "chidot (rad/s)"}[k])
        axe.legend(fontsize=8)
    # two short lines: one long one ran off a one-panel figure at both edges
    angles = ", ".join(f"{k} {fit[k]:.4g}" for k in PARAMS[:5] if k.endswith("_deg"))
    rates = ", ".join(f"{k} {fit[k]:.4g}" for k in PARAMS[:5] if not k.endswith("_deg"))
    fig.suptitle(f"{angles} (deg)\n{rates} (rad/s)", fontsize=9)
    if out is not None:
        fig.savefig(out, dpi=120)
    return fig

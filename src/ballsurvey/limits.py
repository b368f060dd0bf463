"""Input rules and size limits shared by the sweep spec, the command line and the Python API.

One place for what a number may be (finite, positive, whole, within a range) and for how much work
or memory one request may ask for, so `sweep`, `path`, `simulate`, `find` and `refine` refuse the
same things with the same words. Every check raises `InputError` (a ValueError) whose message is
one line naming the input; callers add where it came from (a spec file, a command-line option).
Limits are checked before anything is allocated or written, with Python integers (no overflow).
"""
from __future__ import annotations

import math

#: most launches in one request (a sweep grid, a refined plane, a traced curve)
MAX_LAUNCHES = 10**10
#: most integration steps of one launch (T / dt)
MAX_STEPS = 10**10
#: most integration steps of one launch that a command integrates again from a map (explore's
#: click and static page, gallery): some seconds of one core (about 1.5e6 steps/s with rk4)
MAX_REPLAY_STEPS = 10**7
#: longest duration of one launch (s): about 12 days of rolling; far beyond it the kernels'
#: scaled time overflows (an adaptive method takes no step count to refuse it by)
MAX_DURATION_S = 1e6
#: most values on one axis of a sweep grid (each axis is an array in memory)
MAX_AXIS_VALUES = 10**7
#: most combinations of ball axes (each is one ball checked up front)
MAX_BALLS = 10**6
#: most chunks in one sweep (the chunk plan is a list in memory; raise `chunk` for bigger grids)
MAX_CHUNKS = 10**6
#: estimated bytes per launch while a chunk is integrated and labelled (state, observer slots,
#: launch table, result variables, with room to spare)
BYTES_PER_LAUNCH = 2048
#: most memory one chunk may take
MAX_CHUNK_BYTES = 4 * 2**30
#: most trajectory samples kept by `simulate` / `path`
MAX_SAMPLES = 10**7
#: most dask worker processes started by --workers
MAX_WORKERS = 1024
#: adaptive tolerances: below RTOL_MIN the step underflows against the rounding of the state
RTOL_MIN, RTOL_MAX = 1e-14, 0.1
ATOL_MAX = 1.0
#: observer cadence (steps between classifier samples) and other integer knobs
MAX_OBSERVE_EVERY = 10**4
MAX_BLOCK = 2**16
MAX_CYCLES = 10**4
#: launch rates a request may give (rad/s): a hundred times the paper's, which reach about
#: 10 rad/s. The integration step is set by the fastest rate, so a launch at 1e9 rad/s would need
#: some 1e10 steps a second of motion; it is an input error, not a run to wait for.
MAX_RATE = 1000.0
#: initial heading (deg): it only turns the path; far beyond a turn its rounding would reach the
#: path (at 1e15 deg a float's step is 0.1 deg)
MAX_HEADING_DEG = 1e6
#: launch inputs with bounds of their own: name -> (largest magnitude, unit)
LAUNCH_BOUNDS = {"thetadot0": (MAX_RATE, "rad/s"), "chidot0": (MAX_RATE, "rad/s"),
                 "phidot0": (MAX_RATE, "rad/s"), "chi0_deg": (MAX_HEADING_DEG, "deg")}
#: largest rolling-resistance coefficient mu_r (the couple's lever arm over the ball's radius):
#: a lever arm as long as the radius is far past any ball that rolls (0.001 to 0.02 on a table)
MAX_ROLLING_RESISTANCE = 1.0
#: integer thresholds of the classifier ([classify] table): name -> (lowest, highest)
CLASSIFY_INT_RANGES = {"min_cycles": (1, 10**4), "max_star_points": (2, 1000)}


#: the largest finite float
MAX_FLOAT = 1.7976931348623157e308


class InputError(ValueError):
    """An input outside the rules: one line naming the input."""


class RunError(RuntimeError):
    """A run that could not finish for a reason outside its input (a full disk, a lost dask
    scheduler or workers): one line, exit status 1; finished work is kept for --resume."""


def number(name: str, v, *, positive: bool = False, nonnegative: bool = False,
           integer: bool = False, lo=None, hi=None, finite: bool = True):
    """Check one number; returns it as float (or int when `integer`). Raises InputError.

    positive: > 0; nonnegative: >= 0; integer: a whole number; lo, hi: inclusive bounds."""
    if isinstance(v, float):
        v = float(v)  # numpy's float64 is a float, whose repr is np.float64(...) in messages
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        try:  # numpy scalars
            import numpy as np

            if isinstance(v, np.ndarray) and v.ndim == 0:
                v = v[()]  # a 0-d array: its scalar
            if isinstance(v, np.generic) and np.issubdtype(type(v), np.number):
                v = v.item()
            else:
                raise TypeError
        except TypeError:
            raise InputError(f"{name}: must be a number, got {type(v).__name__} {v!r}") from None
    if isinstance(v, int) and not abs(v) <= MAX_FLOAT:  # a Python int past any float
        digits = len(str(abs(v))) if abs(v) < 10**4000 else "over 4000"
        raise InputError(f"{name}: must be within +-1.8e308, got a whole number of {digits} "
                         "digits")
    if finite and not math.isfinite(v):
        raise InputError(f"{name}: must be finite, got {v!r}")
    if positive and not v > 0:
        raise InputError(f"{name}: must be > 0, got {v!r}")
    if nonnegative and not v >= 0:
        raise InputError(f"{name}: must be >= 0, got {v!r}")
    if integer:
        if int(v) != v:
            raise InputError(f"{name}: must be a whole number, got {v!r}")
        v = int(v)
    if lo is not None and v < lo:
        raise InputError(f"{name}: must be >= {lo:g}, got {v!r}")
    if hi is not None and v > hi:
        raise InputError(f"{name}: must be <= {hi:g}, got {v!r}")
    return v if integer else float(v)


def rolling_resistance(v, label: str = "rolling_resistance") -> float:
    """The rolling-resistance coefficient mu_r (dimensionless): a finite number in
    [0, MAX_ROLLING_RESISTANCE]."""
    return number(label, v, nonnegative=True, hi=MAX_ROLLING_RESISTANCE)


def launch_value(name: str, v, label: str | None = None) -> float:
    """A launch rate or heading (`LAUNCH_BOUNDS`: thetadot0, chidot0, phidot0 in rad/s, chi0_deg):
    a finite number within its bound. `label` names it in the message (default: name)."""
    label = label or name
    v = number(label, v)
    bound, unit = LAUNCH_BOUNDS[name]
    if not abs(v) <= bound:
        raise InputError(f"{label}: must be within +-{bound:g} {unit}, got {v!r}")
    return v


def step_count(T: float, dt: float, multiple: int = 1) -> int:
    """The one step-count rule: the fewest equal steps, a multiple of `multiple`, with T / n <= dt
    (to 1e-9 relative, so T / dt a whole number up to rounding takes that many)."""
    return max(multiple, multiple * math.ceil(T / dt / multiple - 1e-9))


def steps(T: float, dt: float, name_T: str = "T", name_dt: str = "dt") -> int:
    """Check a duration and step (0 < dt <= T, both finite) and the step count; returns it."""
    T = number(name_T, T, positive=True, hi=MAX_DURATION_S)
    dt = number(name_dt, dt, positive=True)
    if dt > T:
        raise InputError(f"{name_dt}: must be <= T ({T:g} s), got {dt!r}")
    n = T / dt
    if n > MAX_STEPS:
        raise InputError(f"{name_dt}: T/dt = {n:.3g} steps per launch is more than "
                         f"{MAX_STEPS:.0e}; use a larger step or a shorter T")
    return step_count(T, dt)


def replay_steps(T: float, dt: float, fixed_step: bool, name_dt: str = "dt",
                 what: str = "a command integrates launches again") -> int:
    """Steps of a launch a command integrates again from a map (T, dt as checked by `steps`):
    refused above MAX_REPLAY_STEPS for a fixed-step method (an adaptive one chooses its own)."""
    n = step_count(T, dt)
    if fixed_step and n > MAX_REPLAY_STEPS:
        raise InputError(f"{name_dt}: T/dt = {n:.3g} steps a launch; {what}, each with at "
                         f"most {MAX_REPLAY_STEPS:.0e} steps (some seconds of one core)")
    return n


def tolerances(rtol, atol, name_rtol: str = "rtol", name_atol: str = "atol") -> tuple:
    """Adaptive tolerances: RTOL_MIN <= rtol <= RTOL_MAX, 0 < atol <= ATOL_MAX."""
    rtol = number(name_rtol, rtol, positive=True)
    if not RTOL_MIN <= rtol <= RTOL_MAX:
        raise InputError(f"{name_rtol}: must be in [{RTOL_MIN:g}, {RTOL_MAX:g}] (below "
                         f"{RTOL_MIN:g} the step underflows), got {rtol!r}")
    atol = number(name_atol, atol, positive=True, hi=ATOL_MAX)
    return rtol, atol


def launches(shape, name: str = "launches") -> int:
    """The number of launches of a grid of this shape (exact), refused above MAX_LAUNCHES."""
    n = math.prod(int(s) for s in shape)
    if n > MAX_LAUNCHES:
        dims = " x ".join(str(int(s)) for s in shape)
        raise InputError(f"{name}: {dims} = {n:.3g} launches is more than {MAX_LAUNCHES:.0e}")
    if n < 1:
        raise InputError(f"{name}: no launches")
    return n


def chunk_size(chunk, name: str = "chunk") -> int:
    """Launches per chunk: a whole number >= 1 whose estimated memory fits MAX_CHUNK_BYTES."""
    chunk = number(name, chunk, integer=True, lo=1)
    if chunk * BYTES_PER_LAUNCH > MAX_CHUNK_BYTES:
        raise InputError(f"{name}: {chunk} launches per chunk need about "
                         f"{chunk * BYTES_PER_LAUNCH / 2**30:.3g} GiB; at most "
                         f"{MAX_CHUNK_BYTES // BYTES_PER_LAUNCH} per chunk")
    return chunk


def count_chunks(shape, chunk: int) -> int:
    """How many chunks `sweep.engine.plan_chunks` makes, without making them."""
    shape = [int(s) for s in shape]
    if math.prod(shape) == 0:
        return 0
    d = 0
    while math.prod(shape[d:]) > chunk:
        d += 1
    if d == 0:
        return 1
    run = max(1, chunk // math.prod(shape[d:]))
    return math.prod(shape[:d - 1]) * -(-shape[d - 1] // run)


def chunk_plan(shape, chunk, name: str = "chunk") -> int:
    """Check a chunk size against a grid: memory and the number of chunks; returns the count."""
    chunk = chunk_size(chunk, name)
    n = count_chunks(shape, chunk)
    if n > MAX_CHUNKS:
        raise InputError(f"{name}: {chunk} launches per chunk cut {math.prod(shape):.3g} launches "
                         f"into {n:.3g} chunks, more than {MAX_CHUNKS:.0e}; use a larger chunk")
    return n


def workers(n, name: str = "--workers") -> int:
    return number(name, n, integer=True, lo=1, hi=MAX_WORKERS)


#: a ball a map can be made of: radius (m), gravity (m s-2), mass (kg), and the moments of
#: inertia about G over M a^2 (a rigid body inside the sphere has them below 4; far below 1e-4
#: the spin equations are stiff beyond any step). Outside them the launches only overflow.
BALL_RANGES = {"a": (1e-4, 100.0, "m"), "g": (1e-2, 1000.0, "m s-2"), "M": (1e-6, 1e6, "kg")}
INERTIA_RATIO = (1e-4, 4.0)


def ball(values: dict, where: str = "ball") -> None:
    """Check a ball's parameters (a dict of a, c, M, A, B, g, cut_height in SI) against
    `BALL_RANGES` and `INERTIA_RATIO`."""
    for k, (lo, hi, unit) in BALL_RANGES.items():
        v = values[k]
        if not lo <= v <= hi:
            raise InputError(f"{where} {k}: must be within {lo:g}..{hi:g} {unit}, got {v!r}")
    scale = values["M"] * values["a"] ** 2
    lo, hi = INERTIA_RATIO
    for k in ("A", "B"):
        r = values[k] / scale
        if not lo <= r <= hi:
            raise InputError(f"{where} {k}: {k}/(M a^2) must be within {lo:g}..{hi:g}, got "
                             f"{r:.3g} ({k} = {values[k]!r} kg m2)")


#: dask schedulers a run can reach: protocol://host:port (no protocol: tcp)
SCHEDULER_PROTOCOLS = ("tcp", "tls", "ws", "wss", "ucx")


def scheduler(addr, name: str = "--scheduler") -> str:
    """A running dask scheduler's address: [PROTOCOL://]HOST:PORT, PROTOCOL one of
    `SCHEDULER_PROTOCOLS`, PORT 1..65535. Checked before anything starts."""
    import re

    if not isinstance(addr, str):
        raise InputError(f"{name}: an address such as tcp://127.0.0.1:8786, got "
                         f"{type(addr).__name__}")
    m = re.fullmatch(r"(?:([A-Za-z0-9+.-]+)://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+):(\d{1,5})",
                     addr.strip())
    if (not m or (m.group(1) or "tcp") not in SCHEDULER_PROTOCOLS
            or not 1 <= int(m.group(3)) <= 65535):
        raise InputError(f"{name}: {addr!r} is not a scheduler address; give "
                         f"PROTOCOL://HOST:PORT with PROTOCOL one of "
                         f"{', '.join(SCHEDULER_PROTOCOLS)} (e.g. tcp://127.0.0.1:8786)")
    return addr.strip()


def samples(n, name: str = "n_out") -> int:
    return number(name, n, integer=True, lo=2, hi=MAX_SAMPLES)


def regular_file(path, what: str = "file"):
    """`path` as a Path when it is a regular file (or a link to one); InputError saying what it
    is otherwise: missing, a folder, a FIFO (opening one would wait for a writer), a device or
    a socket. Only stat is called: nothing is opened."""
    import stat
    from pathlib import Path

    p = Path(path)
    try:
        mode = p.stat().st_mode
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None
    if stat.S_ISREG(mode):
        return p
    kind = ("a folder" if stat.S_ISDIR(mode) else "a FIFO (named pipe)" if stat.S_ISFIFO(mode)
            else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
            else "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
    raise InputError(f"{path} is {kind}, not a {what}")

"""Sweep specs: TOML in, a validated `Spec` out. Every problem is one line naming the key.

Format (all keys documented in docs/specs.md, "Sweep specs"):

    title = "..."
    [ball]      preset = "paper" | a, c, M, A, B (SI), g, cut_height | a, cut_height, M (geometry)
    [launch]    grid axes: theta0_deg, thetadot0, chidot0, phidot0 (rad/s), each a number, a list
                or {start, stop, num}; chi0_deg (a number); ball axes c, cut_height, M, A, B (SI)
    [[points]]  instead of [launch]: name, theta0_deg, thetadot0, chidot0, phidot0, chi0_deg
    [run]       T (s), dt (s), method, observe_every, block, chunk
    [classify]  thresholds (see classify.labels.Thresholds)
    [output]    file, variables, compression
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from .. import limits
from ..axes import BALL_AXES, LAUNCH_AXES
from ..ball import PRESETS, Ball, tilt_error
from ..classify.labels import Thresholds
from ..compose import CUDA_METHODS, MAP_METHODS
from ..integrate.tableaus import FIXED_STEP
from ..limits import InputError
from ..schema import DEFAULT_VARIABLES, RESULT_VARIABLES

BALL_KEYS = ("preset", "a", "c", "M", "A", "B", "g", "cut_height")
RUN_KEYS = ("T", "dt", "method", "rtol", "atol", "mode", "cycles", "observe_every", "block",
            "chunk", "backend")
BACKENDS = ("cpu", "cuda")
#: launches per chunk when [run] chunk is not given: a chunk is the unit of saving and of dask
#: tasks on the CPU; on the GPU it is also one kernel launch, which needs about 1e5 threads or
#: more to fill a card (an H100 holds 132 x 2048)
DEFAULT_CHUNK = {"cpu": 4096, "cuda": 1 << 19}
OUTPUT_KEYS = ("file", "variables", "compression")
POINT_KEYS = ("name",) + LAUNCH_AXES + ("chi0_deg",)
TOP_KEYS = ("title", "ball", "launch", "points", "run", "classify", "output")


class SpecError(InputError):
    """A spec problem; the message names the file, the key and what is wrong."""


@dataclass(frozen=True)
class Spec:
    text: str
    source: str
    title: str
    ball: Ball
    kind: str  # "grid" or "points"
    axes: dict  # grid: name -> 1-D float array (launch axes first, then ball axes)
    points: dict  # points: name -> array (names: str array)
    chi0_deg: float
    T: float
    dt: float
    method: str
    rtol: float
    atol: float
    mode: str
    cycles: int
    observe_every: int
    block: int
    chunk: int
    thresholds: Thresholds
    output: Path
    variables: tuple
    compression: int
    digest: str = field(default="")
    backend: str = "cpu"

    @property
    def shape(self) -> tuple:
        if self.kind == "grid":
            return tuple(len(v) for v in self.axes.values())
        return (len(self.points["name"]),)

    @property
    def dims(self) -> tuple:
        return tuple(self.axes) if self.kind == "grid" else ("launch",)

    @property
    def n_launches(self) -> int:
        return math.prod(self.shape)


def _err(src, where, msg):
    raise SpecError(f"{src}: {where}: {msg}")


def _number(src, where, v, *, positive=False, integer=False, lo=None, hi=None):
    """One number by the shared rules of `ballsurvey.limits`; a SpecError naming the key."""
    try:
        return limits.number(where, v, positive=positive, integer=integer, lo=lo, hi=hi)
    except InputError as exc:
        raise SpecError(f"{src}: {exc}") from None


def _limit(src, check, *args, **kw):
    """Run a `ballsurvey.limits` check; its InputError becomes a SpecError naming the file."""
    try:
        return check(*args, **kw)
    except InputError as exc:
        raise SpecError(f"{src}: {exc}") from None


def _unknown(src, section, table, allowed):
    for k in table:
        if k not in allowed:
            _err(src, f"{section}{k}", f"unknown key; allowed: {', '.join(allowed)}")


def _axis_size(src, where, v) -> int:
    """How many values an axis has, checked before any array is made."""
    if isinstance(v, dict):
        if "num" not in v:
            _err(src, where, "a range needs start, stop and num (missing num)")
        return _number(src, f"{where}.num", v["num"], integer=True, lo=1,
                       hi=limits.MAX_AXIS_VALUES)
    if isinstance(v, list):
        if not v:
            _err(src, where, "empty list")
        if len(v) > limits.MAX_AXIS_VALUES:
            _err(src, where, f"more than {limits.MAX_AXIS_VALUES:.0e} values")
        return len(v)
    return 1


def _axis(src, where, v):
    """A number, a list of numbers, or {start, stop, num} -> sorted-as-given 1-D array."""
    if isinstance(v, dict):
        _unknown(src, f"{where}.", v, ("start", "stop", "num"))
        for k in ("start", "stop", "num"):
            if k not in v:
                _err(src, where, f"a range needs start, stop and num (missing {k})")
        start = _number(src, f"{where}.start", v["start"])
        stop = _number(src, f"{where}.stop", v["stop"])
        num = _number(src, f"{where}.num", v["num"], integer=True, lo=1, hi=limits.MAX_AXIS_VALUES)
        if num > 1 and not start < stop:
            _err(src, where, f"empty or reversed range: start={start} must be < stop={stop}")
        return np.linspace(start, stop, num)
    if isinstance(v, list):
        if not v:
            _err(src, where, "empty list")
        vals = np.array([_number(src, f"{where}[{i}]", x) for i, x in enumerate(v)])
        if len(np.unique(vals)) != len(vals):
            _err(src, where, "repeated values")
        if np.any(np.diff(vals) < 0):  # the map's axis is its coordinate: plots and queries
            _err(src, where, "values must increase along the list (a map's axis is sorted)")
        return vals
    return np.array([_number(src, where, v)])


def _ball(src, table) -> Ball:
    _unknown(src, "[ball] ", table, BALL_KEYS)
    if "preset" in table:
        if set(table) != {"preset"}:
            _err(src, "[ball]", "give either preset or parameters, not both")
        name = table["preset"]
        if name not in PRESETS:
            _err(src, "[ball] preset", f"unknown preset {name!r}; known: {', '.join(PRESETS)}")
        return PRESETS[name]()
    vals = {k: _number(src, f"[ball] {k}", v, positive=k not in ("c", "cut_height"))
            for k, v in table.items()}
    try:
        if set(vals) <= {"a", "cut_height", "M", "g"} and {"a", "cut_height", "M"} <= set(vals):
            return Ball.from_geometry(**vals)
        missing = [k for k in ("a", "c", "M", "A", "B") if k not in vals]
        if missing:
            _err(src, "[ball]",
                 f"missing {', '.join(missing)} (or give preset, or a, cut_height, M)")
        vals.setdefault("cut_height", 0.0)
        return Ball(**vals)
    except ValueError as exc:
        if isinstance(exc, SpecError):
            raise
        _err(src, "[ball]", str(exc))


def _check_bounds(src, where, columns):
    """Launch rates and heading within `limits.LAUNCH_BOUNDS` (columns: name -> values; a
    points table's `name` column names the point at fault)."""
    for k in limits.LAUNCH_BOUNDS:
        vals = np.asarray(columns.get(k, ()), dtype=float)
        if vals.size:  # the largest in magnitude stands for them all
            i = int(np.argmax(np.abs(vals)))
            at = f"{where} {str(columns['name'][i])!r}" if "name" in columns else where
            _limit(src, limits.launch_value, k, vals[i], f"{at} {k}")


def _check_tilts(src, where, theta0_deg, balls_flat_deg):
    problem = tilt_error(theta0_deg, max(balls_flat_deg))
    if problem:
        _err(src, where, problem)


def _count_balls(src, where, sizes: dict) -> None:
    """Refuse more than `limits.MAX_BALLS` combinations of ball axes (sizes: axis -> count)."""
    n_balls = math.prod(n for k, n in sizes.items() if k in BALL_AXES)
    if n_balls > limits.MAX_BALLS:
        _err(src, f"{where} " + "/".join(k for k in BALL_AXES if k in sizes),
             f"{n_balls:.3g} balls (combinations of ball axes) is more than "
             f"{limits.MAX_BALLS:.0e}")


def _check_grid(src, where, axes, chi0, base_ball):
    """A grid's launch values within `limits.LAUNCH_BOUNDS`, every ball its ball axes make
    within `limits.ball`, and its tilts within the model (axes: name -> values)."""
    _check_bounds(src, where, {**axes, "chi0_deg": np.array([chi0])})
    _count_balls(src, where, {k: len(v) for k, v in axes.items()})
    ball_axes = [k for k in BALL_AXES if k in axes]
    flat = []
    for combo in itertools.product(*[axes[k] for k in ball_axes]):
        try:
            b = replace(base_ball, **dict(zip(ball_axes, map(float, combo))))
        except ValueError as exc:
            _err(src, f"{where} " + "/".join(ball_axes), f"gives an invalid ball: {exc}")
        _limit(src, limits.ball, b.as_dict(),
               f"{where} " + "/".join(ball_axes) + " gives a ball whose")
        flat.append(math.degrees(b.flat_face_theta_rad))
    _check_tilts(src, f"{where} theta0_deg", axes["theta0_deg"], flat)


def _check_points(src, where, points, base_ball):
    """Named points' launch values within `limits.LAUNCH_BOUNDS` and their tilts in the model."""
    _check_bounds(src, where, points)
    _check_tilts(src, f"{where} theta0_deg", points["theta0_deg"],
                 [math.degrees(base_ball.flat_face_theta_rad)])


def _run(src, run: dict, name) -> dict:
    """The run settings (T, dt, method, rtol, atol, mode, cycles, observe_every) of a spec's [run]
    table or of a map's attributes, by one set of rules; name(key) is how a message names a key
    ('[run] T' in a spec, a map's attribute run_T_s). Missing keys take a spec's defaults."""
    T = _number(src, name("T"), run["T"], positive=True)
    dt = _number(src, name("dt"), run.get("dt", 1e-4), positive=True)
    _limit(src, limits.steps, T, dt, name("T"), name("dt"))
    method = run.get("method", "rk4")
    if not isinstance(method, str) or method not in MAP_METHODS:
        _err(src, name("method"), f"unknown method {method!r}; known: {', '.join(MAP_METHODS)}")
    rtol, atol = _limit(src, limits.tolerances, run.get("rtol", 1e-9), run.get("atol", 1e-12),
                        name("rtol"), name("atol"))
    mode = run.get("mode", "full")
    if not isinstance(mode, str) or mode not in ("full", "period"):
        _err(src, name("mode"), f"must be 'full' or 'period', got {mode!r}")
    cycles = _number(src, name("cycles"), run.get("cycles", 2), integer=True, lo=1,
                     hi=limits.MAX_CYCLES)
    observe_every = _number(src, name("observe_every"), run.get("observe_every", 4),
                            integer=True, lo=1, hi=limits.MAX_OBSERVE_EVERY)
    return {"T": T, "dt": dt, "method": method, "rtol": rtol, "atol": atol, "mode": mode,
            "cycles": cycles, "observe_every": observe_every}


def _thresholds(src, classify: dict, name) -> Thresholds:
    """Classifier thresholds of a spec's [classify] table or a map's classify_* attributes;
    name(key) names a key in messages."""
    for key, (lo, hi) in limits.CLASSIFY_INT_RANGES.items():
        if key in classify:
            _number(src, name(key), classify[key], integer=True, lo=lo, hi=hi)
    known = {f.name for f in fields(Thresholds)}
    for key, v in classify.items():
        if key in known and _number(src, name(key), v) < 0:
            _err(src, name(key), f"must be finite and >= 0, got {v!r}")
    try:
        return Thresholds.from_mapping({k: (v.item() if isinstance(v, np.generic) else v)
                                        for k, v in classify.items()})
    except ValueError as exc:
        raise SpecError(f"{src}: {exc}") from None


#: [run] keys a command line may set, with the value a spec that does not name them runs with
RUN_OVERRIDE_DEFAULTS = {"backend": "cpu"}


def _override_run(src, text: str, doc: dict, run: dict) -> tuple[str, dict]:
    """The spec's text with [run] keys replaced by `run` (scalars), and its parsed document.

    The text itself is rewritten (the key's line replaced, or a line added under [run]), so the
    override travels wherever the spec's text goes: to dask workers, into the parts' manifest
    and into the map's provenance. A value already in effect changes nothing, not even the
    digest. The rewritten text is parsed again and must give the same document with the merged
    [run] table; anything else is refused with one line."""
    table = doc.get("run", {})
    if not isinstance(table, dict):
        return text, doc  # validation says what is wrong with it
    unset = object()
    run = {k: v for k, v in run.items() if table.get(k, RUN_OVERRIDE_DEFAULTS.get(k, unset)) != v}
    if not run:
        return text, doc
    lines = text.split("\n")  # only newlines: TOML strings and comments may hold U+2028 etc.
    head = [i for i, ln in enumerate(lines) if re.fullmatch(r"\s*\[run\]\s*(#.*)?", ln)]
    if len(head) == 1:
        end = next((i for i in range(head[0] + 1, len(lines))
                    if re.match(r"\s*\[", lines[i])), len(lines))
        for key, value in run.items():
            new = f"{key} = {json.dumps(value)}  # from the command line"
            at = [i for i in range(head[0] + 1, end)
                  if re.match(rf"\s*{re.escape(key)}\s*=", lines[i])]
            if at:
                lines[at[0]] = new
            else:
                lines.insert(head[0] + 1, new)
                end += 1
        new_text = "\n".join(lines)
        try:
            new_doc = tomllib.loads(new_text)
        except ValueError:  # TOMLDecodeError is one
            new_doc = None

        def canon(d):  # NaN equals NaN here: validation, not this check, refuses it
            return json.dumps(d, sort_keys=True, default=str)

        if new_doc is not None and canon(new_doc) == canon({**doc, "run": {**table, **run}}):
            return new_text, new_doc
    keys = ", ".join(run)
    _err(src, "[run]", f"cannot set {keys} from the command line: write them in a [run] table "
                       "of the spec (one 'key = value' line each)")


def load_spec(path, *, text: str | None = None, run: dict | None = None) -> Spec:
    """Read and validate a spec file (or its `text`). Raises SpecError (one line) on any problem.
    run: [run] keys that replace the file's (a command-line override, e.g. {"backend": "cuda"}):
    checked as if written there, and part of the digest, so a map made with them is not taken
    for the file's own."""
    src = str(path)
    if text is None:
        try:
            text = Path(path).read_text()
        except OSError as exc:
            raise SpecError(f"{src}: cannot read: {exc.strerror}") from None
        except UnicodeDecodeError:
            raise SpecError(f"{src}: not a text file (a sweep spec is TOML text)") from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"{src}: not valid TOML: {exc}") from None
    except ValueError as exc:  # an integer of more digits than Python converts
        raise SpecError(f"{src}: not a usable spec: {str(exc).split(';')[0]}") from None
    if run:
        text, doc = _override_run(src, text, doc, run)
    _unknown(src, "", doc, TOP_KEYS)
    for sec in ("ball", "launch", "run", "classify", "output"):
        if sec in doc and not isinstance(doc[sec], dict):
            _err(src, f"[{sec}]", "must be a table")
    title = doc.get("title", Path(src).stem)
    if not isinstance(title, str):
        _err(src, "title", "must be a string")
    base_ball = _ball(src, doc.get("ball", {"preset": "paper"}))
    _limit(src, limits.ball, base_ball.as_dict(), "[ball]")

    # ---- launches --------------------------------------------------------------------------
    if ("launch" in doc) == ("points" in doc):
        _err(src, "[launch]/[[points]]", "give exactly one of a [launch] grid or [[points]]")
    axes, points, chi0 = {}, {}, 0.0
    if "launch" in doc:
        kind = "grid"
        launch = doc["launch"]
        _unknown(src, "[launch] ", launch, LAUNCH_AXES + ("chi0_deg",) + BALL_AXES)
        for k in LAUNCH_AXES:
            if k not in launch:
                _err(src, f"[launch] {k}", "missing (give a number, a list or {start, stop, num})")
        names = [k for k in LAUNCH_AXES + BALL_AXES if k in launch]
        # sizes first: no array is made for a grid that is refused for its size
        sizes = [_axis_size(src, f"[launch] {k}", launch[k]) for k in names]
        _limit(src, limits.launches, sizes, "[launch]")
        _count_balls(src, "[launch]", dict(zip(names, sizes)))
        for k in names:
            axes[k] = _axis(src, f"[launch] {k}", launch[k])
        chi0 = _number(src, "[launch] chi0_deg", launch.get("chi0_deg", 0.0))
        _check_grid(src, "[launch]", axes, chi0, base_ball)
    else:
        kind = "points"
        pts = doc["points"]
        if not isinstance(pts, list) or not pts:
            _err(src, "[[points]]", "must be a non-empty array of tables")
        cols = {k: [] for k in POINT_KEYS}
        for i, pt in enumerate(pts):
            if not isinstance(pt, dict):
                _err(src, f"[[points]] #{i + 1}", "must be a table")
            _unknown(src, f"[[points]] #{i + 1} ", pt, POINT_KEYS)
            name = pt.get("name", f"point{i + 1}")
            if not isinstance(name, str) or not name:
                _err(src, f"[[points]] #{i + 1} name", "must be a non-empty string")
            if not name.isprintable():  # netCDF ends a string at NUL: "a" and "a\0" are one
                _err(src, f"[[points]] #{i + 1} name", f"must be printable text, got {name!r}")
            cols["name"].append(name)
            for k in LAUNCH_AXES:
                if k not in pt:
                    _err(src, f"[[points]] {name!r} {k}", "missing")
                cols[k].append(_number(src, f"[[points]] {name!r} {k}", pt[k]))
            cols["chi0_deg"].append(_number(src, f"[[points]] {name!r} chi0_deg",
                                            pt.get("chi0_deg", 0.0)))
        if len(set(cols["name"])) != len(cols["name"]):
            _err(src, "[[points]] name", "names must be unique")
        points = {k: np.array(v, dtype=object if k == "name" else float) for k, v in cols.items()}
        points["name"] = np.array(cols["name"], dtype=str)
        _check_points(src, "[[points]]", points, base_ball)

    # ---- run ---------------------------------------------------------------------------------
    run = doc.get("run", {})
    _unknown(src, "[run] ", run, RUN_KEYS)
    if "T" not in run:
        _err(src, "[run] T", "missing (duration in s)")
    r = _run(src, run, lambda k: f"[run] {k}")
    T, dt, method, rtol, atol = r["T"], r["dt"], r["method"], r["rtol"], r["atol"]
    mode, cycles, observe_every = r["mode"], r["cycles"], r["observe_every"]
    backend = run.get("backend", RUN_OVERRIDE_DEFAULTS["backend"])
    if backend not in BACKENDS:
        _err(src, "[run] backend", f"must be one of {', '.join(BACKENDS)}, got {backend!r}")
    if backend == "cuda" and method not in CUDA_METHODS:
        _err(src, "[run] backend", f"cuda runs the fixed-step methods ({', '.join(FIXED_STEP)}) "
             f"and quadrature; {method} runs on the cpu")
    block = _number(src, "[run] block", run.get("block", 64), integer=True, lo=1,
                    hi=limits.MAX_BLOCK)
    chunk = _number(src, "[run] chunk", run.get("chunk", DEFAULT_CHUNK[backend]), integer=True,
                    lo=1)
    shape = (tuple(len(v) for v in axes.values()) if kind == "grid"
             else (len(points["name"]),))
    _limit(src, limits.chunk_plan, shape, chunk, "[run] chunk")

    thresholds = _thresholds(src, doc.get("classify", {}), lambda k: f"[classify] {k}")
    if mode == "period" and cycles < thresholds.min_cycles:
        _err(src, "[run] cycles", f"period mode integrates {cycles} theta cycle(s), fewer than "
             f"the {thresholds.min_cycles} a label needs ([classify] min_cycles): every launch "
             "would be unresolved")

    out = doc.get("output", {})
    _unknown(src, "[output] ", out, OUTPUT_KEYS)
    ofile = out.get("file", f"results/{Path(src).stem}.nc")
    if not isinstance(ofile, str) or not ofile.endswith(".nc"):
        _err(src, "[output] file", f"must be a path ending in .nc, got {ofile!r}")
    variables = out.get("variables", list(DEFAULT_VARIABLES))
    if not isinstance(variables, list) or not all(isinstance(v, str) for v in variables):
        _err(src, "[output] variables", "must be a list of variable names")
    for v in variables:
        if v not in RESULT_VARIABLES:
            _err(src, "[output] variables",
                 f"unknown variable {v!r}; known: {', '.join(RESULT_VARIABLES)}")
    variables = tuple(dict.fromkeys(["label"] + variables))
    compression = _number(src, "[output] compression", out.get("compression", 4), integer=True)
    if not 0 <= compression <= 9:
        _err(src, "[output] compression", f"must be 0..9, got {compression}")

    spec = Spec(text=text, source=src, title=title, ball=base_ball, kind=kind, axes=axes,
                points=points, chi0_deg=chi0, T=T, dt=dt, method=method, rtol=rtol, atol=atol,
                mode=mode, cycles=cycles,
                observe_every=observe_every, block=block, chunk=chunk, thresholds=thresholds,
                output=Path(ofile), variables=variables, compression=compression,
                backend=backend)
    return replace(spec, digest=spec_digest(spec))


def _canon(v):
    """A value for the digest: every number as the repr of its float (20 and 20.0 alike, -0.0 as
    0.0), arrays and tuples as lists."""
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, dict):
        return {str(k): _canon(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_canon(x) for x in v]
    if isinstance(v, bool) or v is None or isinstance(v, str):
        return v
    if isinstance(v, (int, float, np.number)):
        return repr(float(v) + 0.0)
    return str(v)


def spec_digest(spec: Spec) -> str:
    """SHA-256 of what a spec asks for, from its parsed and completed values: comments, layout,
    how a number is written (20 or 20.0), defaults written out or left to apply and the order of
    [output] variables change nothing. The chunk plan and the output file are not part of it (a
    map's results do not depend on them)."""
    what = {"title": spec.title, "ball": spec.ball.as_dict(), "kind": spec.kind,
            "axes": [[k, v] for k, v in spec.axes.items()],
            "points": [[k, v] for k, v in spec.points.items()], "chi0_deg": spec.chi0_deg,
            "T": spec.T, "dt": spec.dt, "method": spec.method, "rtol": spec.rtol,
            "atol": spec.atol, "mode": spec.mode, "cycles": spec.cycles,
            "observe_every": spec.observe_every, "block": spec.block,
            "thresholds": spec.thresholds.as_dict(), "variables": sorted(spec.variables),
            "compression": spec.compression, "backend": spec.backend}
    return hashlib.sha256(json.dumps(_canon(what), sort_keys=True).encode()).hexdigest()


def ball_from_options(ball: str | None = None, cut_height: float | None = None,
                      spec=None) -> Ball:
    """The ball of the command line's --ball, --cut-height and --spec, by the rules of a spec's
    [ball] table (SpecError, one line, naming the option).

    ball: "a=..,c=..,M=..,A=..,B=.." (SI; also g, cut_height; or a, cut_height, M for a
    truncated uniform sphere, or preset=paper); cut_height (m): with --ball, its cap; alone, the
    paper's sphere (a = 25.4 mm, M = 98.4 g) with that cap cut off, c, A and B from the
    geometry; spec: a spec file whose [ball] is used (the paper's ball if it has none). None of
    them: the paper's ball."""
    if spec is not None:
        if ball is not None or cut_height is not None:
            raise SpecError("--spec: give the ball by --spec or by --ball/--cut-height, not both")
        src = str(spec)
        try:
            doc = tomllib.loads(Path(spec).read_text())
        except OSError as exc:
            raise SpecError(f"{src}: cannot read: {exc.strerror}") from None
        except UnicodeDecodeError:
            raise SpecError(f"{src}: not a text file (a sweep spec is TOML text)") from None
        except tomllib.TOMLDecodeError as exc:
            raise SpecError(f"{src}: not valid TOML: {exc}") from None
        table = doc.get("ball", {"preset": "paper"})
        if not isinstance(table, dict):
            _err(src, "[ball]", "must be a table")
        return _ball(src, table)
    if ball is None and cut_height is None:
        return Ball.paper()
    table: dict = {}
    for item in (ball or "").split(","):
        if not item.strip():
            continue
        key, sep, val = item.partition("=")
        key = key.strip()
        if not sep or not key:
            _err("--ball", item.strip(), "takes KEY=VALUE pairs separated by commas, such as "
                 "a=0.0254,c=0.0029,M=0.0984,A=2.39e-5,B=2.69e-5")
        if key in table:
            _err("--ball", key, "given twice")
        if key == "preset":
            table[key] = val.strip()
            continue
        try:
            table[key] = float(val)
        except ValueError:
            _err("--ball", key, f"{val.strip()!r} is not a number")
    if cut_height is not None:
        if "cut_height" in table:
            _err("--cut-height", "cut_height", "given by --ball too")
        if not table:
            paper = Ball.paper()
            table = {"a": paper.a, "M": paper.M}
        table["cut_height"] = cut_height
    return _ball("--ball" if ball is not None else "--cut-height", table)


# ---------------------------------------------------------------------------------------------
# a map read back: its run settings, ball, thresholds and axes by the rules of a spec
#: a map's global attributes that hold its run settings: [run] key -> attribute
RUN_ATTRS = {"T": "run_T_s", "dt": "run_dt_s", "method": "run_method", "rtol": "run_rtol",
             "atol": "run_atol", "mode": "run_mode", "cycles": "run_cycles",
             "observe_every": "run_observe_every"}
#: run settings a map that records none is integrated again with
MAP_RUN_DEFAULTS = {"T": 20.0, "dt": 1e-4}


@dataclass(frozen=True)
class MapSettings:
    """A map's run settings (attributes run_*), classifier thresholds (classify_*) and ball
    (ball_*), checked by the rules of a spec's [run], [classify] and [ball] tables."""

    T: float  #: duration (s)
    dt: float  #: step used (s; an adaptive method's first trial step)
    dt_requested: float  #: the spec's step (s)
    method: str
    rtol: float
    atol: float
    mode: str
    cycles: int
    observe_every: int
    thresholds: Thresholds
    ball: Ball
    recorded: bool  #: the map records its method and step


def _attr(k: str) -> str:
    return f"attribute {k}"


def map_settings(attrs: dict, src: str = "map") -> MapSettings:
    """The run settings, thresholds and ball of a map's global attributes (defaults of a spec
    where it records none); SpecError (one line naming the file and the attribute) for anything
    a spec could not hold."""
    run = {k: attrs[a] for k, a in RUN_ATTRS.items() if a in attrs}
    r = _run(src, {**MAP_RUN_DEFAULTS, **run}, lambda k: _attr(RUN_ATTRS[k]))
    req = r["dt"]
    if "run_dt_s_requested" in attrs:
        req = _number(src, _attr("run_dt_s_requested"), attrs["run_dt_s_requested"],
                      positive=True)
        _limit(src, limits.steps, r["T"], req, _attr("run_T_s"), _attr("run_dt_s_requested"))
    pre = "classify_"
    thresholds = _thresholds(src, {k[len(pre):]: v for k, v in attrs.items()
                                   if k.startswith(pre) and k[len(pre):] in
                                   {f.name for f in fields(Thresholds)}},
                             lambda k: _attr(pre + k))
    kw = {k: _number(src, _attr(f"ball_{k}"), attrs[f"ball_{k}"])
          for k in BALL_KEYS if k != "preset" and f"ball_{k}" in attrs}
    try:
        ball = Ball(**kw)
    except ValueError as exc:
        _err(src, "attributes ball_*", str(exc))
    _limit(src, limits.ball, ball.as_dict(), "attribute ball_*: ball")
    return MapSettings(T=r["T"], dt=r["dt"], dt_requested=req, method=r["method"],
                       rtol=r["rtol"], atol=r["atol"], mode=r["mode"], cycles=r["cycles"],
                       observe_every=r["observe_every"], thresholds=thresholds, ball=ball,
                       recorded="run_method" in attrs and "run_dt_s" in attrs)


def _coordinate(src, ds, k) -> np.ndarray:
    """A map's coordinate k as finite floats (1-D); SpecError naming it otherwise."""
    v = ds[k]
    if v.dtype.kind not in "iuf":
        _err(src, f"coordinate {k}", f"must be numbers, got {v.dtype}")
    vals = np.atleast_1d(np.asarray(v.values, dtype=float))
    if vals.ndim != 1:
        _err(src, f"coordinate {k}", f"must be one value or an axis, got shape {vals.shape}")
    if not np.all(np.isfinite(vals)):
        _err(src, f"coordinate {k}", f"must be finite, got {float(vals[~np.isfinite(vals)][0])!r}")
    return vals


def check_map(ds, src: str = "map") -> MapSettings:
    """Check an opened map by the rules of a spec before any work: its run settings, thresholds
    and ball (`map_settings`), its axes (known names, finite, increasing, launch values and
    tilts within the limits, every ball of its ball axes within `limits.ball`), its label codes
    (ballsurvey's words) and its result variables (numbers over the label's dimensions).
    Reads only the coordinates (a points map's launch values), never the results."""
    from ..classify.labels import LABELS

    settings = map_settings(ds.attrs, src)
    label = ds["label"]
    words = str(label.attrs.get("flag_meanings", "")).split()
    values = label.attrs.get("flag_values", np.arange(len(words)))
    codes = np.atleast_1d(np.asarray(values))
    if (codes.dtype.kind not in "iu" or codes.shape != (len(words),)
            or any(not 0 <= c < len(LABELS) or LABELS[c] != w for c, w in zip(codes, words))):
        _err(src, "variable label", "its flag_values and flag_meanings are not ballsurvey's "
             "label codes")
    for k in RESULT_VARIABLES:
        if k in ds.variables and k != "label":
            v = ds[k]
            if v.dtype.kind not in "iuf" or v.dims != label.dims:
                _err(src, f"variable {k}", f"must be numbers over {', '.join(label.dims)}, got "
                     f"{v.dtype} over {', '.join(v.dims) or 'no dimension'}")
    if label.dims == ("launch",):
        points = {k: _coordinate(src, ds, k) for k in LAUNCH_AXES + ("chi0_deg",)
                  if k in ds.variables}
        n = ds.sizes["launch"]
        for k, vals in points.items():
            if vals.shape != (n,):
                _err(src, f"coordinate {k}", f"must have one value per launch ({n})")
        if "name" in ds.variables:
            points["name"] = np.asarray(ds["name"].values).astype(str)
        _check_points(src, "launch", points, settings.ball)
        return settings
    for d in label.dims:
        if d not in LAUNCH_AXES + BALL_AXES:
            _err(src, f"dimension {d}", f"not an axis of a map; axes: "
                 f"{', '.join(LAUNCH_AXES + BALL_AXES)}")
    _limit(src, limits.launches, label.shape, "map")
    axes = {}
    for k in LAUNCH_AXES + BALL_AXES:
        if k in ds.variables:
            axes[k] = _coordinate(src, ds, k)
            if k in label.dims and np.any(np.diff(axes[k]) <= 0):
                _err(src, f"coordinate {k}", "values must increase along the axis")
    chi0 = _coordinate(src, ds, "chi0_deg") if "chi0_deg" in ds.variables else np.zeros(1)
    if chi0.size != 1:
        _err(src, "coordinate chi0_deg", "must be one value on a grid")
    _check_grid(src, "coordinate", axes, float(chi0[0]), settings.ball)
    return settings

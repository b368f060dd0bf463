"""Handing an observer to a kernel.

The integrators in this package know nothing of what an observer computes. An observer is
jitted functions (an `Observer`): `record(obs, i, first, t, dt, x, y, theta, sin theta, cos theta,
chi, thetadot, chidot, phidot, thetaddot, chiddot, phiddot, c, A, B, psid, fric, normal)` updates
launch i's column of `obs` with one sample (psid, fric, normal: the path's heading rate, |F_h|/N and
N/(M g) computed without the Euler chart, or NaN), and `done(obs, i, target) -> bool` says when a
launch may stop early (period mode); the fixed-step block kernel feeds a whole block's sample at
once to `block_record`, between `block_open` and `block_close` (`Observer`). The layer above
(`ballsurvey.compose`) hands one in.

numba caches a function only if everything it calls is known when it is compiled, and cannot cache
one that takes functions as arguments. So a kernel module is a template whose module globals
(`record`, `done`, ...) are placeholders: `bind(name, source, observer)` writes the template with
the observer's identity and the digest of its source into a module in the cache directory
($BALLSURVEY_CACHE_DIR, default ~/.cache/ballsurvey), named by a hash of that text and of
`_jit.SOURCE_DIGEST`, imports it and sets the globals before anything is compiled. numba's
on-disk cache then works across processes, and a change to the kernel, to the observer or to
any physics either inlines gives a new module instead of stale machine code.
"""
from __future__ import annotations

import hashlib
import importlib
import inspect
import os
import sys
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import NamedTuple

from .._jit import SOURCE_DIGEST


class Observer(NamedTuple):
    """A streaming observer: `record` one sample, say when a launch is `done` (module docstring);
    for the fixed-step ensemble kernel, which samples a block of launches at once, also
    `block_open(obs) -> lanes` (its working state for the launches whose slots are obs's
    columns), `block_record(lanes, obs, alive, first, t, dt, x, y, theta, sin theta, cos theta,
    chi, thetadot, chidot, phidot, c, A, B)` (`record` for every launch i with alive[i], its
    state and parameters in 1-D arrays, one per variable, indexed by i; what `done` reads of obs
    is current after it) and `block_close(lanes, obs)` (every column of obs complete)."""

    record: Callable
    done: Callable
    block_open: Callable | None = None
    block_record: Callable | None = None
    block_close: Callable | None = None


class StepObserver(NamedTuple):
    """An observer fed by an adaptive integrator's steps: `start(obs, i, y, f, c, A, B)` with a
    launch's fixed-frame state y and its rate f, `step(obs, i, t0, h, ya, fa, yb, fb, c, A, B,
    last)` with each accepted step's start time, length, states and rates at both ends and
    whether it is the run's last, and `done` as `Observer.done`; for a fixed-step kernel, which
    observes a launch every so many of its short steps, `span(obs, i, ya, fa, yb, fb)`: the
    longest span (non-dimensional time) the observer's next step may cover after the step just
    observed (as `step`'s arguments)."""

    start: Callable
    step: Callable
    done: Callable
    span: Callable | None = None


def cache_dir() -> Path:
    return Path(os.environ.get("BALLSURVEY_CACHE_DIR", Path.home() / ".cache" / "ballsurvey"))


def _identity(fn) -> str:
    py = getattr(fn, "py_func", fn)
    try:
        src = inspect.getsource(inspect.getmodule(py))
    except (OSError, TypeError):
        src = repr(py.__code__.co_code)
    return f"{py.__module__}.{py.__qualname__} {hashlib.sha256(src.encode()).hexdigest()[:16]}"


_MODULES: dict = {}


@cache
def inlined(fn):
    """`fn` (a numba function) compiled again from its Python source for numba to inline into
    every caller's IR (`inline="always"`), as it does the fixed-frame right-hand side: LLVM's
    inliner finds the observer too big, and as a call it cost the RK4 kernel a tenth of the
    observer's time (benchmarks/observer_cost.py; the same record bit for bit); inlined, the
    block functions also show LLVM where their working arrays come from (allocated in the
    kernel, rows of a constant length), which their vectorised loops need. Only the hot
    kernels take it (`bind(..., inline_record=True)`): the inlined body is compiled again at each
    call site, which doubled the adaptive fallback's first compilation (25 -> 48 s)."""
    import numba

    opts = {k: v for k, v in fn.targetoptions.items() if k in ("nogil", "error_model")}
    return numba.njit(inline="always", **opts)(fn.py_func)


def bind(name: str, source: str, observer: Observer | StepObserver | None, *,
         inline_record: bool = False):
    """The module of `source` (a template with a global for each of the observer's functions:
    `record`, `done` and the block functions, or `start`, `step` and `done`) bound to the
    functions `observer` has (None: a kernel with no observer; its module is cached all the
    same). inline_record: numba inlines the observer's functions other than `done` into the
    kernel (`inlined`)."""
    # the observer's functions by name (those it has)
    fns = {} if observer is None else {k: f for k, f in observer._asdict().items()
                                       if f is not None}
    if observer is None:
        text = source + "\n\n# no observer\n"
    else:
        if inline_record:
            fns = {k: f if k == "done" else inlined(f) for k, f in fns.items()}
        text = source + "\n\n# observer bound by ballsurvey.integrate.binding:\n" + "".join(
            f"#   {k} = {_identity(f)}{' (inlined)' if inline_record and k != 'done' else ''}\n"
            for k, f in fns.items())
    digest = hashlib.sha256(f"{text}\0{SOURCE_DIGEST}".encode()).hexdigest()[:16]
    modname = f"ballsurvey_{name}_{digest}"
    if modname in _MODULES:
        return _MODULES[modname]
    path = cache_dir() / f"{modname}.py"
    try:
        if SOURCE_DIGEST is None:  # sources unreadable: no way to tell a stale module, no disk
            raise OSError("no source digest")
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists():
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(text)
            os.replace(tmp, path)
        # importable by name: numba's cache re-imports the defining module when it loads
        if str(path.parent) not in sys.path:
            sys.path.append(str(path.parent))
        mod = importlib.import_module(modname)
    except OSError:  # read-only home: compile in memory, without the on-disk cache
        mod = type(sys)(modname)
        for k, f in fns.items():
            setattr(mod, k, f)
        exec(compile(text.replace("cache=True", "cache=False"), f"<{modname}>", "exec"),
             mod.__dict__)
    for k, f in fns.items():
        setattr(mod, k, f)
    _MODULES[modname] = mod
    return mod

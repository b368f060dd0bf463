"""What the commands share: the one-line input error, the checks of option values and of output
files, and the option groups of a launch, a ball, rolling resistance and the drawn axes.
"""
from __future__ import annotations

import sys

from ..limits import InputError


class UserError(InputError):
    """A problem with the user's input: reported as one line, exit status 2."""


def _opt(name, value, **rules):
    """A numeric option by the shared rules of `ballsurvey.limits`; UserError naming it."""
    from .. import limits

    if value is None:
        return None
    try:
        return limits.number(name, value, **rules)
    except limits.InputError as exc:
        raise UserError(str(exc)) from None


def _launch_opt(flag, name, value, ball=None):
    """A launch input option: theta0_deg inside the model's tilts (of `ball`, default the
    paper's), a rate or the heading within `limits.LAUNCH_BOUNDS`; UserError naming the flag."""
    import math

    from .. import limits
    from ..ball import Ball, tilt_error

    if value is None:
        return None
    try:
        if name != "theta0_deg":
            return limits.launch_value(name, value, flag)
        value = limits.number(flag, value)
    except limits.InputError as exc:
        raise UserError(str(exc)) from None
    problem = tilt_error(value, math.degrees((ball or Ball.paper()).flat_face_theta_rad))
    if problem:
        raise UserError(f"{flag}: {problem}")
    return value


def _out_file(name, value, suffix):
    """-o/--output: a file name ending in `suffix` (a string, or a tuple of those allowed) that
    is not an existing folder."""
    from pathlib import Path

    if value is None:
        return None
    suffixes = (suffix,) if isinstance(suffix, str) else tuple(suffix)
    p = Path(value)
    ok = any(p.name.lower().endswith(s) and p.name.lower() != s for s in suffixes)
    want = " or ".join(suffixes)
    if not value or not ok:
        raise UserError(f"{name}: must be a file name ending in {want}, got {value!r}")
    if p.is_dir():
        raise UserError(f"{name}: {value} is a folder; give a file name ending in {want}")
    _check_writable(name, p.parent)
    return p


def _figure_file(value):
    """-o/--output of a figure command: .png, .pdf or .svg."""
    from ..plot import FIGURE_SUFFIXES

    return _out_file("-o/--output", value, FIGURE_SUFFIXES)


def _check_writable(name, folder) -> None:
    """Refuse (one line, exit 2, before any work) an output folder that cannot be written: the
    nearest folder of it that exists must take a new file (tried, and removed at once)."""
    import os
    import tempfile
    from pathlib import Path

    d = Path(os.path.abspath(folder))
    while not d.exists() and d != d.parent:
        d = d.parent
    if not d.is_dir():
        raise UserError(f"{name}: {d} is a file, not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".ballsurvey-probe-", dir=d)
    except OSError as exc:
        raise UserError(f"{name}: cannot write in {d}: {exc.strerror}") from None
    os.close(fd)
    os.unlink(probe)


def _check_cuda() -> None:
    """One line (exit 2) before anything is written when the CUDA backend cannot run here."""
    from ..integrate.cuda import BackendError, cuda_module

    try:
        cuda_module()
    except BackendError as exc:
        raise UserError(f"backend cuda: {exc}") from None


def _open_map(path):
    """A map for plot/query/gallery; one line (exit 2) for anything that is not one."""
    from ..api import open_map

    return open_map(path)


def _parse_at(items):
    at = {}
    for item in items or []:
        key, sep, val = item.partition("=")
        if not sep or not key:
            raise UserError(f"--at takes AXIS=VALUE, got {item!r}")
        try:
            at[key] = float(val)
        except ValueError:
            raise UserError(f"--at {key}: {val!r} is not a number") from None
        _opt(f"--at {key}", at[key])
    return at


def _ball_arg(args):
    """The ball of --ball / --cut-height / --spec (`sweep.spec.ball_from_options`)."""
    from ..sweep.spec import ball_from_options

    cut = _opt("--cut-height", args.cut_height, nonnegative=True)
    return ball_from_options(args.ball, cut, args.spec)


def _add_launch_options(parser) -> None:
    """One launch's options (path, animate): tilt and heading in deg, rates in rad/s."""
    parser.add_argument("--theta0-deg", type=float, required=True, metavar="DEG",
                        help="initial tilt (deg)")
    parser.add_argument("--thetadot0", type=float, default=0.0, metavar="RATE",
                        help="initial tilt rate (rad/s)")
    parser.add_argument("--chidot0", type=float, required=True, metavar="RATE",
                        help="initial precession rate (rad/s)")
    parser.add_argument("--phidot0", type=float, required=True, metavar="RATE",
                        help="initial spin rate (rad/s)")
    parser.add_argument("--chi0-deg", type=float, default=0.0, metavar="DEG",
                        help="initial heading (deg)")


def _add_rolling_option(parser) -> None:
    """--rolling-resistance of a command that integrates one launch (path, animate)."""
    parser.add_argument("--rolling-resistance", type=float, default=0.0, metavar="MU",
                        help="rolling-resistance coefficient mu_r (dimensionless: the lever arm "
                             "of the couple mu_r N a that opposes the rolling, over the ball's "
                             "radius a; 0.001-0.02 on a table); 0: none, as the paper. Above 0 "
                             "the launch is integrated in the fixed frame by dopri5")


def _rolling_opt(args) -> float:
    from .. import limits

    return _opt("--rolling-resistance", args.rolling_resistance, nonnegative=True,
                hi=limits.MAX_ROLLING_RESISTANCE)


def _add_drawn_axes_options(parser) -> None:
    """--x and --y of a command that draws a map (plot, explore): both choose alike."""
    parser.add_argument("--x", metavar="AXIS",
                        help="axis drawn across (default: the map's first axis with more than "
                             "one value, in its order theta0_deg, thetadot0, chidot0, phidot0, "
                             "...)")
    parser.add_argument("--y", metavar="AXIS",
                        help="axis drawn up (default: the next axis with more than one value)")


def _add_ball_options(parser, default="the paper's truncated billiard ball") -> None:
    g = parser.add_argument_group(f"the ball (default: {default})")
    g.add_argument("--ball", metavar="K=V,...",
                   help="the ball as a spec's [ball] gives it, SI: a=..,c=..,M=..,A=..,B=.. "
                        "(m, m, kg, kg m^2, kg m^2; also g=, cut_height=) or a=..,cut_height=..,"
                        "M=.. for a truncated uniform sphere")
    g.add_argument("--cut-height", type=float, metavar="METRES",
                   help="height (m) of the cap cut off: alone, from the paper's sphere (a = 25.4 "
                        "mm, M = 98.4 g), c, A, B from the geometry; with --ball, its cap")
    g.add_argument("--spec", metavar="SPEC.toml", help="use the [ball] of this sweep spec")


def _ignore_more_ctrl_c() -> None:
    """After the one line of an interruption, or the work: a burst of Ctrl-C (a key held down)
    does not cut the exit short into a traceback or a death by signal. The command line only
    (`ballsurvey._COMMAND_LINE`): `main` called from Python leaves the caller's Ctrl-C alone."""
    import signal
    import threading

    command_line = getattr(sys.modules.get("ballsurvey"), "_COMMAND_LINE", False)
    if command_line and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)

"""Command line: `ballsurvey <command>` (or `python -m ballsurvey <command>`).

Each command is a module of this package, its parser (`add_parser`) beside its `run`; what
they share is in `options`. Here: the top parser, `main`, the compiling line and Ctrl-C.

Exit status: 0 done; 2 an input error (`ballsurvey.limits.InputError`, raised by validation code:
one line on stderr, nothing written); 1 a run that failed for a reason outside its input
(`RunError`, or the system refused a file operation: one line); 130 interrupted (Ctrl-C). Any
other exception is a bug and shows its traceback.
"""
from __future__ import annotations

import argparse
import re
import sys
from contextlib import contextmanager

from ..limits import InputError
from . import (
    accuracy,
    animate,
    bench,
    explore,
    find,
    fit,
    gallery,
    paper,
    path,
    plot,
    query,
    refine,
    sweep,
)

# the names callers import from ballsurvey.cli, besides main and build_parser
from .options import UserError, _ignore_more_ctrl_c  # noqa: F401
from .sweep import _where_the_time_went, sweep_summary  # noqa: F401

#: each command's handler: `build_parser` looks them up here, where a caller may replace one
_cmd_bench = bench.run
_cmd_sweep = sweep.run
_cmd_plot = plot.run
_cmd_path = path.run
_cmd_explore = explore.run
_cmd_animate = animate.run
_cmd_fit = fit.run
_cmd_query = query.run
_cmd_gallery = gallery.run
_cmd_paper = paper.run
_cmd_find = find.run
_cmd_refine = refine.run
_cmd_accuracy = accuracy.run
#: the commands' modules, in the order their parsers are made (argparse's errors list them so)
COMMANDS = (bench, sweep, plot, path, explore, animate, fit, query, gallery, paper, find, refine,
            accuracy)
#: the order of `ballsurvey --help`: what a user does first comes first
COMMAND_ORDER = ("path", "sweep", "plot", "query", "find", "explore", "animate", "fit", "gallery",
                 "refine", "paper", "accuracy", "bench")


def _version() -> str:
    """The installed distribution's version; the package's own when run from a source tree."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("ballsurvey")
    except PackageNotFoundError:
        from .._version import __version__

        return __version__


class _Help(argparse.HelpFormatter):
    """Shows each option's default after its help, unless it has none (None or a bare flag)."""

    def _get_help_string(self, action):
        h = action.help or ""
        d = action.default
        if (d is None or d is False or d is argparse.SUPPRESS or "default" in h
                or not action.option_strings
                or isinstance(action, (argparse._VersionAction, argparse._CountAction))):
            return h
        d = " ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in d) \
            if isinstance(d, (list, tuple)) else (f"{d:g}" if isinstance(d, float) else d)
        return f"{h} (default: {d})"


class _Parser(argparse.ArgumentParser):
    """argparse with its errors on one line (exit 2), like every other input error, and a
    negative number in exponent form (-5e0, -1e-3) or -inf read as a value, not an option
    (argparse knows only -5 and -5.0; its matcher is internal: where it is gone, nothing
    changes)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        if hasattr(self, "_negative_number_matcher"):
            self._negative_number_matcher = re.compile(
                r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-inf(inity)?$", re.IGNORECASE)

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (--help lists the options)\n")


def build_parser() -> argparse.ArgumentParser:
    ap = _Parser(prog="ballsurvey", formatter_class=_Help,
                                 description="Map how a biased ball rolls (Wheatland, Cross et al. "
                                             "2020). Exit status: 0 done, 1 run failed, 2 input "
                                             "error, 130 interrupted.")
    ap.add_argument("--version", action="version", version=f"ballsurvey {_version()}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    ap.commands = sub.choices  # each command's own parser, by name

    def cmd(name, **kw):
        return sub.add_parser(name, formatter_class=_Help, **kw)

    handlers = globals()
    for module in COMMANDS:
        name = module.__name__.rpartition(".")[2]
        module.add_parser(cmd).set_defaults(func=handlers[f"_cmd_{name}"])
    # `ballsurvey --help` lists the commands in the order people use them, not of COMMANDS
    rank = {name: i for i, name in enumerate(COMMAND_ORDER)}
    sub._choices_actions.sort(key=lambda a: rank.get(a.dest, len(rank)))
    return ap


@contextmanager
def _compiling_line(command: str):
    """While a command runs, its first numba compilation prints one line on stderr, so a cold
    start (seconds to a minute) is not silent; `sweep` says it itself, with its progress."""
    if command == "sweep":
        yield
        return
    from ..sweep.compute import compile_watch

    def say(msg):
        print(f"ballsurvey {command}: {msg}", file=sys.stderr, flush=True)

    with compile_watch(say):
        yield


def _quiet_unraisable(info) -> None:
    """sys.unraisablehook for the command line: a Ctrl-C that lands inside a callback Python
    cannot raise from (a garbage-collection callback of distributed's, a finaliser) is dropped
    without its 'Exception ignored in ...' traceback: the run's own Ctrl-C handling says what
    happened, in one line. Anything else is reported as usual."""
    if issubclass(info.exc_type, KeyboardInterrupt):
        return
    sys.__unraisablehook__(info)


def main(argv=None) -> int:
    """Run the command in `argv` (default: sys.argv[1:]); returns the exit status."""
    code = _main(argv)
    _skip_final_collection()
    return code


def _skip_final_collection() -> None:
    """The command line (`ballsurvey._COMMAND_LINE`) only, its command done: the objects alive
    now are left out of the interpreter's garbage collections at exit (`gc.freeze`). Those
    collections walk every object of numba, xarray and pandas, about 0.25 s of each process's
    exit; Python does not promise to finalize objects still alive at exit anyway, and the
    command's files are closed by then (exit handlers still run). `main` called from Python
    leaves the caller's collector alone."""
    import gc

    if getattr(sys.modules.get("ballsurvey"), "_COMMAND_LINE", False):
        gc.freeze()


def _main(argv=None) -> int:
    sys.unraisablehook = _quiet_unraisable
    try:
        parser = build_parser()
        args, extra = parser.parse_known_args(argv)
        if extra:  # said by the command's own parser, so the line names the command
            parser.commands[args.command].error(f"unrecognized arguments: {' '.join(extra)}")
    except SystemExit as exc:  # --help, --version (0) or an option argparse refused (2)
        return exc.code
    from ..limits import RunError

    try:
        with _compiling_line(args.command):
            args.func(args)
    except InputError as exc:
        print(f"ballsurvey {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except RunError as exc:
        print(f"ballsurvey {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # the reader of stdout left (`query ... | head`): nothing to say
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # the system refused a file operation (disk full, permissions)
        name = exc.filename or getattr(args, "html", None) or getattr(args, "output", None)
        what = f"{exc.strerror or exc}: {name}" if name else str(exc)
        print(f"ballsurvey {args.command}: error: {what or type(exc).__name__}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        _ignore_more_ctrl_c()
        print(f"ballsurvey {args.command}: interrupted", file=sys.stderr)
        return 130
    _ignore_more_ctrl_c()  # done: a Ctrl-C while the interpreter shuts down changes nothing
    return 0

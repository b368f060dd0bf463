"""ballsurvey: maps how a biased ball rolls (Wheatland, Cross et al., Am. J. Phys. 88, 465 (2020)).

Public API: `simulate` (one launch), `sweep` (a map from a spec: path, TOML text or dict),
`open_map`, `query` (a map's launches of one shape as a pandas DataFrame), `select` (one value of
an axis), the `ds.ballsurvey` accessor (label words), `Ball`, `Thresholds`, `LABELS`,
`InputError` (every input problem), `SweepInterrupted` (Ctrl-C during a sweep).

`ballsurvey.sweep` and `ballsurvey.query` are the functions; their modules are
`ballsurvey.sweep` / `ballsurvey.query` only through `from ballsurvey.sweep import ...` and
`from ballsurvey.query import ...`.
"""
from ._version import __version__

#: this process is the command line (`ballsurvey ...`, `python -m ballsurvey ...`)
_COMMAND_LINE = False


def _is_command_line(argv0: str, orig_argv: list) -> bool:
    """Whether this process is the command line: the `ballsurvey` script, or `python -m
    ballsurvey` (sys.argv[0] is "-m" while the package of any module run with -m imports, so the
    module's name is read from the interpreter's own arguments: `python -m mytool`, whose
    package imports ballsurvey, is library use)."""
    import os

    name = os.path.basename(argv0)
    if name != "-m":
        return name == "ballsurvey"
    args = iter(orig_argv[1:])
    for arg in args:  # the interpreter's options, up to -m MODULE
        if arg == "--check-hash-based-pycs":
            next(args, None)
            continue
        if not arg.startswith("-") or arg.startswith("--"):
            return False
        for k, flag in enumerate(arg[1:], 2):  # a cluster of one-letter flags, such as -Im
            if flag in "WX":  # their value: the rest of this argument, or the next one
                if k == len(arg):
                    next(args, None)
                break
            if flag == "c":
                return False
            if flag == "m":
                module = arg[k:] or next(args, "")
                return module in ("ballsurvey", "ballsurvey.__main__")
    return False


def _one_line_interrupt() -> None:
    """The command line (`ballsurvey ...`, `python -m ballsurvey ...`): a Ctrl-C that escapes
    everything, such as one while this package is still importing, ends with one line and exit
    status 130, not a traceback. Library use is left alone."""
    import os
    import sys

    global _COMMAND_LINE
    if not _is_command_line(sys.argv[0] if sys.argv else "", getattr(sys, "orig_argv", [])):
        return
    _COMMAND_LINE = True
    previous = sys.excepthook

    def hook(kind, value, tb):
        if not issubclass(kind, KeyboardInterrupt):
            return previous(kind, value, tb)
        try:
            sys.stdout.flush()
        except Exception:  # noqa: BLE001, S110 - a closed stdout: nothing to flush
            pass
        sys.stderr.write("ballsurvey: interrupted\n")
        sys.stderr.flush()
        os._exit(130)

    sys.excepthook = hook


_one_line_interrupt()

#: the public names and the modules that define them
_PUBLIC = {"open_map": "api", "query": "api", "select": "api", "sweep": "api", "Ball": "ball",
           "LABELS": "classify.labels", "Thresholds": "classify.labels",
           "InputError": "limits", "simulate": "simulate", "SweepInterrupted": "sweep.engine"}


def _load_public() -> None:
    """Every public name bound here. The subpackages `sweep` and `query` are imported first:
    importing them later would rebind the names `sweep` and `query` to the modules."""
    import importlib

    importlib.import_module(".query", __name__)
    importlib.import_module(".sweep", __name__)
    for name, module in _PUBLIC.items():
        globals()[name] = getattr(importlib.import_module(f".{module}", __name__), name)


def __getattr__(name):
    """The command line binds the public names on first use (PEP 562): a sweep or a path needs
    neither xarray nor pandas, a third of a fresh process's start."""
    if name in _PUBLIC:
        _load_public()
        return globals()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


if not _COMMAND_LINE:  # library use: everything at once, the `ds.ballsurvey` accessor included
    _load_public()

__all__ = ["Ball", "simulate", "sweep", "open_map", "query", "select", "Thresholds", "LABELS",
           "InputError", "SweepInterrupted", "__version__"]

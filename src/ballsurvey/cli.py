"""Command line: `python -m ballsurvey <command>`. Errors are one line on stderr with exit status 2."""
from __future__ import annotations

import argparse
import sys


class UserError(Exception):
    """A problem with the user's input: reported as one line, exit status 2."""


def _cmd_bench(args):
    from .bench import run_bench

    run_bench(n_launches=args.launches, n_steps=args.steps, dt=args.dt, repeats=args.repeats,
              block=args.block, observe_every=args.observe_every)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m ballsurvey",
                                 description="Map how a biased ball rolls (Wheatland, Cross et al. 2020).")
    sub = ap.add_subparsers(dest="command", required=True)

    b = sub.add_parser("bench", help="IC-steps/s of the ensemble kernel vs a naive per-launch loop")
    b.add_argument("--launches", type=int, default=4096)
    b.add_argument("--steps", type=int, default=2000)
    b.add_argument("--dt", type=float, default=1e-4, help="step (s)")
    b.add_argument("--repeats", type=int, default=3)
    b.add_argument("--block", type=int, default=64, help="launches per block")
    b.add_argument("--observe-every", type=int, default=4, help="observer cadence (steps)")
    b.set_defaults(func=_cmd_bench)
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except (UserError, ValueError, FileNotFoundError, FileExistsError, PermissionError) as exc:
        print(f"ballsurvey {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"ballsurvey {args.command}: interrupted", file=sys.stderr)
        return 130
    return 0

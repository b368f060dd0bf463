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


def _cmd_sweep(args):
    import shlex
    from dataclasses import replace
    from pathlib import Path

    from .sweep import load_spec, run_sweep
    from .sweep.engine import output_is_current

    spec = load_spec(args.spec)
    if args.output:
        spec = replace(spec, output=Path(args.output))
    if args.chunk is not None:
        if args.chunk < 1:
            raise UserError(f"--chunk must be >= 1, got {args.chunk}")
        spec = replace(spec, chunk=args.chunk)

    if output_is_current(spec) and not args.force:
        print(f"{spec.output} is up to date (made by this spec); --force recomputes it")
        return
    client = cluster = None
    if args.scheduler or args.workers:
        from distributed import Client, LocalCluster

        if args.scheduler:
            client = Client(args.scheduler)
        else:
            cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                                   host="127.0.0.1", dashboard_address=None)
            client = Client(cluster)
    command = "python -m ballsurvey " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    try:
        out = run_sweep(spec, resume=args.resume, force=args.force, client=client,
                        progress=args.progress, command=command)
    except KeyboardInterrupt:
        raise UserError("interrupted; finished chunks are kept: run again with --resume") from None
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    print(f"wrote {out} ({spec.n_launches} launches)")


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

    s = sub.add_parser("sweep", help="integrate and classify every launch of a spec; write a netCDF map")
    s.add_argument("spec", help="sweep spec (TOML); see README 'Sweep spec'")
    s.add_argument("--resume", action="store_true", help="continue an interrupted sweep of this spec")
    s.add_argument("--force", action="store_true", help="overwrite an existing result or discard parts")
    s.add_argument("-o", "--output", help="output file (.nc), overriding [output] file")
    s.add_argument("--chunk", type=int, help="launches per chunk (default: [run] chunk, 4096)")
    g = s.add_mutually_exclusive_group()
    g.add_argument("--scheduler", help="address of a running dask.distributed scheduler")
    g.add_argument("--workers", type=int, help="start a local dask cluster with N worker processes")
    s.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="progress bar on stderr (default: when stderr is a terminal)")
    s.set_defaults(func=_cmd_sweep)
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

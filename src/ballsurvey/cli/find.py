"""`ballsurvey find`: the launch that closes an exact n-gon."""
from __future__ import annotations

import sys

from .options import UserError, _add_ball_options, _ball_arg, _launch_opt, _opt, _out_file


def run(args):
    import numpy as np

    from .. import limits
    from ..find import SHAPE_OF_N, NoSolution, find_launch, trace

    _opt("--n-sides", args.n_sides, integer=True, lo=3, hi=1000)
    ball = _ball_arg(args)
    for name in ("theta0_deg", "thetadot0", "chidot0", "phidot0"):
        _launch_opt("--" + name.replace("_", "-"), name, getattr(args, name), ball)
    if args.bracket:
        # a theta0 bracket may reach past the model's tilts: the scan skips what it cannot take
        lo, hi = (_opt("--bracket", v) if args.solve == "theta0_deg"
                  else _launch_opt("--bracket", args.solve, v) for v in args.bracket)
        if not lo < hi:
            raise UserError(f"--bracket: must have LO < HI, got {lo:g} {hi:g}")
    if args.output is not None and not args.trace_theta0:
        raise UserError("-o/--output goes with --trace-theta0 (one solve prints its roots)")
    out = _out_file("-o/--output", args.output, ".csv")
    if args.trace_theta0:
        start, stop = (_launch_opt("--trace-theta0", "theta0_deg", v, ball)
                       for v in args.trace_theta0[:2])
        _opt("--trace-theta0 NUM", args.trace_theta0[2], integer=True, lo=1,
             hi=min(limits.MAX_LAUNCHES, 10**5))
    polygons = {"triangle": 3, "square": 4, "pentagon": 5, "hexagon": 6, "heptagon": 7,
                "octagon": 8, "nonagon": 9, "decagon": 10}
    if args.shape and args.shape not in ("triangle", "square"):
        n_named = polygons.get(args.shape.lower())
        hint = f"use --n-sides {n_named}" if n_named else "use --n-sides N for other polygons"
        raise UserError(f"--shape {args.shape}: --shape takes triangle or square; {hint}")
    n = args.n_sides or polygons.get(args.shape or "")
    if not n:
        raise UserError("give --shape triangle|square or --n-sides N")
    launch = dict(theta0_deg=args.theta0_deg, thetadot0=args.thetadot0, chidot0=args.chidot0,
                  phidot0=args.phidot0)
    if args.trace_theta0:
        import time

        if args.phidot0 is None:
            raise UserError("give --phidot0 (--trace-theta0 traces theta0 and solves chidot0)")
        start, stop, num = args.trace_theta0
        t0 = time.perf_counter()
        rows = trace(n, np.linspace(start, stop, int(num)), launch, args.bracket, ball=ball)
        took = time.perf_counter() - t0
        lines = ["theta0_deg,chidot0_rad_s,n_sides_integrated,closure_m,label,shape"] + [
            f"{th:.6g},{s.value:.9g},{s.n_sides:.9f},{s.closure_m:.2e},{s.label},{s.shape}"
            for th, s in rows]
        if out is not None:
            out.write_text("\n".join(lines) + "\n")
            print(f"wrote {len(rows)} points of the n = {n} curve to {args.output} "
                  f"({took:.1f} s, each checked by integration)")
        else:
            print("\n".join(lines))
        return
    missing = [k for k, v in launch.items() if v is None and k != args.solve]
    if missing:
        flag = missing[0].replace("_", "-")
        raise UserError(f"give --{flag} (only --solve {args.solve} is free)")
    launch = {k: (0.0 if v is None else v) for k, v in launch.items()}
    rejected: list = []
    try:
        sols = find_launch(n, launch, args.solve, args.bracket, ball=ball, rejected=rejected)
    except NoSolution as exc:
        print(f"ballsurvey find: no solution: {exc}", file=sys.stderr)
        raise SystemExit(1) from None
    unit = "deg" if args.solve == "theta0_deg" else "rad/s"
    for s in sols:
        called = "" if s.label == SHAPE_OF_N.get(n, "ngon") else f" (labelled {s.label})"
        print(f"{s.variable} = {s.value:.10g} {unit}: integrated (adaptive, rtol 1e-10): "
              f"{s.shape}{called}, roundness {s.roundness:.3f}, {s.corner_kind} corners, "
              f"n_sides = {s.n_sides:.9f}, turn per cycle "
              f"{s.turn_per_cycle_deg:.7f} deg, theta period {s.theta_period_s:.6f} s, "
              f"closure {s.closure_m:.2e} m per circuit")
    for s in rejected:
        print(f"not a solution: {s.variable} = {s.value:.10g} {unit} turns 360/{n} deg per cycle "
              f"but integrates as {s.label} (n_sides = {s.n_sides:.6f}, roundness "
              f"{s.roundness:.3f}, {s.corner_kind} corners)")


def add_parser(cmd):
    """`ballsurvey find`'s parser, made by `cmd` (`build_parser`'s)."""
    fd = cmd("find", help="solve for the launch condition that closes an exact n-gon")
    g = fd.add_mutually_exclusive_group(required=True)
    g.add_argument("--shape", metavar="WORD", help="triangle or square (other polygons: --n-sides)")
    g.add_argument("--n-sides", type=int, metavar="N",
                   help="number of sides of the polygon (3 to 1000)")
    fd.add_argument("--theta0-deg", type=float, metavar="DEG", help="initial tilt (deg)")
    fd.add_argument("--thetadot0", type=float, default=0.0, metavar="RATE",
                    help="initial tilt rate (rad/s)")
    fd.add_argument("--chidot0", type=float, metavar="RATE", help="initial precession rate (rad/s)")
    fd.add_argument("--phidot0", type=float, metavar="RATE", help="initial spin rate (rad/s)")
    fd.add_argument("--solve", default="chidot0", choices=("chidot0", "theta0_deg", "phidot0"),
                    help="the launch variable to solve for")
    fd.add_argument("--bracket", type=float, nargs=2, metavar=("LO", "HI"),
                    help="search range of the solved variable (its units: deg or rad/s)")
    fd.add_argument("--trace-theta0", type=float, nargs=3, metavar=("START", "STOP", "NUM"),
                    help="trace the curve of exact n-gons in the (theta0, chidot0) plane: NUM "
                         "values of theta0 from START to STOP (deg)")
    fd.add_argument("-o", "--output", metavar="FILE.csv", help="CSV file for --trace-theta0")
    _add_ball_options(fd)
    return fd

"""`ballsurvey animate`: one launch as a GIF or MP4."""
from __future__ import annotations

from .options import (
    UserError,
    _add_ball_options,
    _add_launch_options,
    _add_rolling_option,
    _ball_arg,
    _check_writable,
    _launch_opt,
    _opt,
    _rolling_opt,
)


def run(args):
    from .. import limits
    from ..animate import check_output, frame_count, write_animation
    from ..simulate import check_simulate_inputs, simulate

    ball = _ball_arg(args)
    for name in ("theta0_deg", "thetadot0", "chidot0", "phidot0", "chi0_deg"):
        _launch_opt("--" + name.replace("_", "-"), name, getattr(args, name), ball)
    fps = _opt("--fps", args.fps, lo=1, hi=120)  # a GIF frame lasts at most 655 s
    speed = _opt("--speed", args.speed, positive=True, hi=100)
    probe = _opt("--probe-m", args.probe_m, nonnegative=True, hi=1.0)
    mu_r = _rolling_opt(args)
    try:
        out = check_output(args.output)
    except limits.InputError as exc:
        raise UserError(f"-o/--output: {exc}") from None
    _check_writable("-o/--output", out.parent)
    try:
        limits.steps(args.T, args.dt, "--T", "--dt")
        check_simulate_inputs(args.theta0_deg, args.thetadot0, args.chidot0, args.phidot0, args.T,
                              args.dt, args.chi0_deg, ball=ball)
        frames = frame_count(args.T, fps, speed)
        n_out = int(min(max(round(args.T / args.dt), 1), 20000)) + 1
        ds = simulate(args.theta0_deg, args.thetadot0, args.chidot0, args.phidot0, args.T,
                      dt=args.dt, chi0_deg=args.chi0_deg, n_out=n_out, ball=ball, probe_m=probe,
                      rolling_resistance=mu_r)
    except limits.InputError as exc:
        raise UserError(str(exc)) from None
    write_animation(ds, out, ball=ball, fps=fps, speed=speed)
    print(f"{ds.attrs['label']}: wrote {out} ({frames} frames, {fps:g} fps, {speed:g}x speed)")


def add_parser(cmd):
    """`ballsurvey animate`'s parser, made by `cmd` (`build_parser`'s)."""
    an = cmd("animate", help="animate one launch: the truncated ball with its flat face and probe "
                             "from above and from the side, the path being traced (GIF or MP4)")
    _add_launch_options(an)
    an.add_argument("--T", type=float, default=3.0, metavar="SECONDS",
                    help="duration of the motion shown (s); a square or triangle of the paper "
                         "closes in 2-3 s")
    an.add_argument("--dt", type=float, default=1e-4, metavar="SECONDS", help="largest step (s)")
    an.add_argument("--fps", type=float, default=20.0,
                    help="frames per second of the file (1 to 120)")
    an.add_argument("--speed", type=float, default=0.5,
                    help="seconds of motion per second of playback (0.5: half speed, so the "
                         "quick turns near theta = 90 deg can be followed)")
    an.add_argument("--probe-m", type=float, default=0.0254, metavar="METRES",
                    help="probe length (m) on the flat face")
    _add_rolling_option(an)
    an.add_argument("-o", "--output", required=True, metavar="FILE.gif|FILE.mp4",
                    help="GIF (Pillow, always there) or MP4 (needs ffmpeg on the PATH)")
    _add_ball_options(an)
    return an

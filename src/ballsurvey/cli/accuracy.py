"""`ballsurvey accuracy`: the work-precision report."""
from __future__ import annotations

from .options import UserError, _check_writable


def run(args):
    if args.ensemble is not None:
        from ..accuracy import ensemble_work_precision

        if args.ensemble < 1:
            raise UserError(f"--ensemble needs at least 1 launch, got {args.ensemble}")
        ensemble_work_precision(n=args.ensemble)
        return
    from ..accuracy import run_accuracy

    _check_writable("-o/--output", args.output)
    run_accuracy(args.output, quick=args.quick, fig_format=args.format)


def add_parser(cmd):
    """`ballsurvey accuracy`'s parser, made by `cmd` (`build_parser`'s)."""
    ac = cmd("accuracy", help="work-precision report: error against run time, RK4 and adaptive, "
                              "paper and extreme cases")
    ac.add_argument("-o", "--output", default="results/accuracy", metavar="FOLDER",
                    help="folder for the .nc file and the figure")
    ac.add_argument("--format", choices=("png", "pdf", "svg"), default="png",
                    help="file format of the figure")
    ac.add_argument("--quick", action="store_true", help="fewer cases and settings (a minute)")
    ac.add_argument("--ensemble", type=int, nargs="?", const=256, default=None, metavar="N",
                    help="only the ensemble table: N launches around the square (256 when not "
                         "given), final position error against launches/s for DOP853 (SIMD "
                         "lanes), dopri5 and RK4")
    return ac

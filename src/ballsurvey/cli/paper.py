"""`ballsurvey paper`: the paper's numerical figures."""
from __future__ import annotations

from .options import _check_writable


def run(args):
    from ..paper import reproduce

    _check_writable("-o/--output", args.output)
    reproduce(args.output, fig_format=args.format)


def add_parser(cmd):
    """`ballsurvey paper`'s parser, made by `cmd` (`build_parser`'s)."""
    pp = cmd("paper", help="reproduce the paper's numerical figures and compare numbers")
    pp.add_argument("-o", "--output", default="results/paper", metavar="FOLDER",
                    help="folder for the figures")
    pp.add_argument("--format", choices=("png", "pdf", "svg"), default="png",
                    help="file format of the figures")
    return pp

"""`ballsurvey query`: the launches of a map that give a shape."""
from __future__ import annotations

import sys

from .options import _open_map, _opt


def run(args):
    from ..query import DEFAULT_LIMIT, format_table, query

    limit = _opt("--limit", args.limit, integer=True, lo=1)
    if limit is None and not args.all:
        limit = DEFAULT_LIMIT
    _opt("--n-sides", args.n_sides, integer=True, lo=3)
    df = query(_open_map(args.result), shape=args.shape, n_sides=args.n_sides, limit=limit,
               max_n_error=args.max_n_error, max_closure=args.max_closure)
    print(format_table(df, args.format), flush=True)
    more = df.attrs["matched"] - len(df)
    if more > 0:
        print(f"... {more} more matched (--limit N or --all to see more)", file=sys.stderr)


def add_parser(cmd):
    """`ballsurvey query`'s parser, made by `cmd` (`build_parser`'s)."""
    r = cmd("query", help="list the launches of a map that give a shape, best first")
    r.add_argument("result", help="a ballsurvey netCDF map (.nc)")
    g = r.add_mutually_exclusive_group(required=True)
    g.add_argument("--shape", metavar="WORD",
                   help="a label word (circle, square, triangle, ngon, star, ..., or a status)")
    g.add_argument("--n-sides", type=int, metavar="N", help="polygons that close with N sides")
    r.add_argument("--format", choices=("table", "csv", "json"), default="table",
                   help="table for people; csv or json (keys without units; the units and the "
                        "values common to every row are given once) for scripts")
    lim = r.add_mutually_exclusive_group()
    lim.add_argument("--limit", type=int, default=None, metavar="N",
                     help="at most N rows (default: 20)")
    lim.add_argument("--all", action="store_true", help="every matching row")
    r.add_argument("--max-n-error", type=float, metavar="E",
                   help="only launches with |n_sides - nearest whole n| <= E")
    r.add_argument("--max-closure", type=float, metavar="METRES",
                   help="only launches whose corner drifts at most METRES (m) per circuit")
    return r

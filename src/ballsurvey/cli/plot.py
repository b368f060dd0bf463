"""`ballsurvey plot`: draw a regime map."""
from __future__ import annotations

from .options import _add_drawn_axes_options, _figure_file, _open_map, _parse_at


def run(args):
    from pathlib import Path

    from ..api import select
    from ..plot import plot_map

    out = _figure_file(args.output) or Path(args.result).with_suffix(".png")
    at = _parse_at(args.at)
    ds = _open_map(args.result)
    plot_map(ds, out, x=args.x, y=args.y, at=at, facet=args.facet,
             contours=not args.no_contours)
    for key, asked in at.items():
        used = float(select(ds[[key]], **{key: asked})[key])
        if used != asked:
            print(f"--at {key}={asked:g}: drew the map's nearest value, {key} = {used:g}")
    print(f"wrote {out}")


def add_parser(cmd):
    """`ballsurvey plot`'s parser, made by `cmd` (`build_parser`'s)."""
    p = cmd("plot", help="draw a regime map (PNG, PDF or SVG) from a sweep's netCDF file")
    p.add_argument("result", help="a ballsurvey netCDF map (.nc, written by sweep)")
    _add_drawn_axes_options(p)
    p.add_argument("--at", action="append", metavar="AXIS=VALUE",
                   help="fix another axis at one of its values (within half a grid step; "
                        "repeatable), in the axis's units (deg or rad/s)")
    p.add_argument("--facet", metavar="AXIS", help="one panel per value of AXIS")
    p.add_argument("--no-contours", action="store_true", help="omit the n_sides = 3, 4 contours")
    p.add_argument("-o", "--output", metavar="FILE",
                   help="figure file, .png, .pdf or .svg (default: RESULT with .png)")
    return p

"""`ballsurvey gallery`: sample paths behind each label of a map."""
from __future__ import annotations

from .options import _add_ball_options, _ball_arg, _figure_file, _open_map, _opt


def run(args):
    from pathlib import Path

    from ..gallery import draw_gallery

    _opt("--per-label", args.per_label, integer=True, lo=1, hi=100)
    _opt("--seed", args.seed, integer=True, lo=0, hi=2**32 - 1)
    _opt("--T", args.T, positive=True, hi=1e6)
    ds = _open_map(args.result)  # a folder or '.' is refused here, before naming the output
    out = _figure_file(args.output or str(Path(args.result).with_name(
        Path(args.result).stem + "-gallery.png")))
    rows = draw_gallery(ds, out, per_label=args.per_label, seed=args.seed, T=args.T,
                        ball=_ball_arg(args) if (args.ball or args.cut_height is not None
                                                 or args.spec) else None)
    changed = [r for r in rows if r["label_again"] != r["label"]]
    print(f"wrote {out}: {len(rows)} paths, "
          f"{len(changed)} labelled differently when integrated again")


def add_parser(cmd):
    """`ballsurvey gallery`'s parser, made by `cmd` (`build_parser`'s)."""
    gl = cmd("gallery", help="draw sample paths behind each label of a map, integrated again, "
                             "to check the labels by eye")
    gl.add_argument("result", help="a ballsurvey netCDF map (.nc)")
    gl.add_argument("-o", "--output", metavar="FILE",
                    help="figure file, .png, .pdf or .svg (default: RESULT-gallery.png)")
    gl.add_argument("--per-label", type=int, default=4, metavar="N", help="paths per label")
    gl.add_argument("--seed", type=int, default=0, help="random seed of the sample")
    gl.add_argument("--T", type=float, metavar="SECONDS",
                    help="duration (s) of each integration (default: the map's)")
    _add_ball_options(gl, default="the map's own ball")
    return gl

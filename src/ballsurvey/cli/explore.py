"""`ballsurvey explore`: the browser app or a static page of a map."""
from __future__ import annotations

import sys

from .options import UserError, _add_drawn_axes_options, _opt, _out_file, _parse_at


def run(args):
    from ..explore import require_bokeh

    require_bokeh()
    port = _opt("--port", args.port, integer=True, lo=1, hi=65535)
    at = _parse_at(args.at)
    if args.html is not None:
        from ..explore import write_html

        if args.allow_host:
            raise UserError("--allow-host is for the app; a static page (--html) is served by "
                            "no one")
        out = _out_file("--html", args.html, ".html")
        r = write_html(args.result, out, x=args.x, y=args.y, at=at)
        paths = "with paths" if r["paths"] else "without paths (slice too large)"
        print(f"wrote {out} ({r['launches']} launches shown, {paths})")
        return
    from ..explore import host_names, serve

    extra = host_names(args.allow_host or [], int(port))
    if extra:
        print(f"warning: --allow-host: the app also answers {', '.join(extra)}: whoever reaches "
              "it by that name can drive it and read the map", file=sys.stderr, flush=True)
    serve(args.result, port=int(port), open_browser=not args.no_browser, x=args.x, y=args.y,
          at=at, ready=lambda line: print(line, flush=True), allow_hosts=extra)


def add_parser(cmd):
    """`ballsurvey explore`'s parser, made by `cmd` (`build_parser`'s)."""
    e = cmd("explore", help="explore a map in the browser: hover, click a launch to see its "
                            "path (needs ballsurvey[explore])")
    e.add_argument("result", help="a ballsurvey netCDF map (.nc)")
    e.add_argument("--port", type=int, default=5006, metavar="P",
                   help="port of the local app (served on 127.0.0.1 only)")
    e.add_argument("--no-browser", action="store_true",
                   help="print the address instead of opening a browser")
    _add_drawn_axes_options(e)
    e.add_argument("--at", action="append", metavar="AXIS=VALUE",
                   help="start another axis at one of its values (repeatable), in its units "
                        "(deg or rad/s); default: its first value")
    e.add_argument("--html", metavar="OUT.html",
                   help="instead: write a self-contained static page (works offline) with hover "
                        "values and, for a slice of at most 1024 launches, each launch's path "
                        "precomputed over one theta cycle and drawn on click")
    e.add_argument("--allow-host", action="append", metavar="NAME[:PORT]",
                   help="also answer requests for this host name (repeatable; default port: "
                        "--port), for deliberate sharing behind a proxy; without it the app "
                        "answers only Host 127.0.0.1:PORT and localhost:PORT")
    return e

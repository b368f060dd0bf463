"""The Bokeh server that serves the app on 127.0.0.1: requests answered only for the Host names
allowed (`host_names` reads `--allow-host`), websockets only from pages of those origins.
"""
from __future__ import annotations

from ..limits import InputError, RunError
from .document import build_document, require_bokeh
from .launch import integrate_launch, launch_at, open_lazily, run_settings
from .view import make_view


def host_names(names, port: int) -> list[str]:
    """--allow-host values as HOST:PORT (lower case; PORT: `port` where a name gives none);
    InputError for anything that is not a host name or address with an optional port."""
    import re

    out = []
    for name in names:
        m = re.fullmatch(r"(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+)(?::(\d{1,5}))?", str(name).strip())
        if not m or (m.group(2) and not 1 <= int(m.group(2)) <= 65535):
            raise InputError(f"--allow-host: {name!r} is not a host name with an optional "
                             "port (NAME or NAME:PORT)")
        out.append(f"{m.group(1).lower()}:{m.group(2) or port}")
    return list(dict.fromkeys(out))


def _answer_only(tornado_app, hosts) -> None:
    """Make the Bokeh server's Tornado application answer only requests whose Host header is
    one of `hosts` (HOST:PORT): any other, or none, gets 403 and nothing of the app (a page
    whose name was rebound to 127.0.0.1 cannot reach it)."""
    from tornado.web import RequestHandler

    allowed = {h.lower() for h in hosts}

    class Refused(RequestHandler):
        def prepare(self):
            self.set_status(403)
            self.set_header("Content-Type", "text/plain; charset=utf-8")
            self.finish("ballsurvey explore answers only " + ", ".join(sorted(allowed)) + "\n")

    find = tornado_app.find_handler

    def find_handler(request, **kw):
        if request.headers.get("Host", "").strip().lower() not in allowed:
            return tornado_app.get_handler_delegate(request, Refused)
        return find(request, **kw)

    tornado_app.find_handler = find_handler


def serve(path, port: int = 5006, open_browser: bool = True, x=None, y=None, at=None,
          ready=print, allow_hosts=()) -> None:
    """Serve the app for the map at `path` on http://127.0.0.1:`port`/ until Ctrl-C (which
    raises KeyboardInterrupt). The map and the axes are checked first (InputError); the
    kernels are compiled (or read from the cache) before the address is printed.

    Only requests for Host 127.0.0.1:`port` or localhost:`port` are answered, and websockets
    only from pages of those origins; `allow_hosts` (HOST:PORT, `host_names`) adds others."""
    require_bokeh()
    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.server.server import Server

    ds = open_lazily(path)
    view = make_view(ds, x, y, at)
    settings = run_settings(ds)
    info = launch_at(ds, view.where(0))
    try:  # compile now, not at the first click
        integrate_launch(ds, info["launch"], info["ball"], T=min(settings.T, 10 * settings.dt),
                         n_out=2, settings=settings)
    except (InputError, ValueError):
        pass
    app = Application(FunctionHandler(lambda doc: build_document(doc, ds, path, x, y, at)))
    hosts = [f"127.0.0.1:{port}", f"localhost:{port}", *allow_hosts]
    try:
        server = Server({"/": app}, port=port, address="127.0.0.1", num_procs=1,
                        allow_websocket_origin=hosts)
    except OSError as exc:
        raise RunError(f"cannot listen on 127.0.0.1:{port} ({exc.strerror or exc}): give "
                       "another --port") from None
    _answer_only(server._tornado, hosts)
    server.start()
    url = f"http://127.0.0.1:{port}/"
    ready(f"ballsurvey explore: serving {path} at {url} (Ctrl-C stops)")
    if open_browser:
        import webbrowser

        server.io_loop.add_callback(webbrowser.open, url)
    try:
        server.io_loop.start()
    finally:
        server.stop()

"""Outside input: a shared map, spec or track is refused in one line (exit 2) before any work
when a spec could not hold it; text from it never runs as script in a page (test_explore's
browser tests hold the pages); the explorer answers only its own host. docs/reliability.md,
"Security", lists each promise with its test."""
import html
import shutil
import subprocess
import sys
import time

import netCDF4
import numpy as np
import pytest

from ballsurvey import api
from ballsurvey.cli import main

GRID = """
title = "crafted"
[launch]
theta0_deg = [2.0, 10.0]
thetadot0 = 0.0
chidot0 = [4.0, 6.0, 8.0]
phidot0 = [-3.0, -2.5]
[run]
T = 3.0
dt = 2e-4
"""


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    d = tmp_path_factory.mktemp("crafted")
    api.sweep(GRID, output=d / "base.nc", progress=False, notice=lambda m: None)
    return d / "base.nc"


def crafted(base, to, attrs=None, coord=None):
    """A copy of the map `base` with global attributes set (attrs) or a coordinate's values
    replaced (coord: (name, index, value))."""
    shutil.copy(base, to)
    with netCDF4.Dataset(to, "a") as nc:
        for k, v in (attrs or {}).items():
            nc.setncattr(k, v)
        if coord:
            name, i, v = coord
            nc[name][i] = v
    return to


#: (what is crafted, words the one line holds)
CRAFTED = [
    (dict(attrs={"ball_a": "-1"}), "attribute ball_a: must be a number"),
    (dict(attrs={"ball_a": -1.0}), "ball.a must be a finite positive number"),
    (dict(attrs={"ball_a": 1e3}), "ball_*: ball a: must be within"),
    (dict(attrs={"classify_max_star_points": "abc"}), "classify_max_star_points: must be a number"),
    (dict(attrs={"classify_max_star_points": 1e9}), "classify_max_star_points: must be <= 1000"),
    (dict(attrs={"classify_mu": np.nan}), "classify_mu: must be finite"),
    (dict(attrs={"run_method": "nope"}), "run_method: unknown method 'nope'"),
    (dict(attrs={"run_T_s": "1e300"}), "run_T_s: must be a number"),
    (dict(attrs={"run_T_s": 1e300}), "run_T_s: must be <= 1e+06"),
    (dict(attrs={"run_dt_s": -1e-4}), "run_dt_s: must be > 0"),
    (dict(attrs={"run_rtol": 0.0}), "run_rtol: must be > 0"),
    (dict(attrs={"run_observe_every": 0}), "run_observe_every: must be >= 1"),
    (dict(attrs={"run_mode": 3}), "run_mode: must be 'full' or 'period'"),
    (dict(coord=("chidot0", 1, np.nan)), "coordinate chidot0: must be finite"),
    (dict(coord=("chidot0", 1, 9.0)), "coordinate chidot0: values must increase"),
    (dict(coord=("phidot0", 0, -1e9)), "phidot0: must be within +-1000 rad/s"),
    (dict(coord=("theta0_deg", 1, 95.0)), "|theta0| must be < 90 deg"),
]


@pytest.mark.parametrize("how, msg", CRAFTED, ids=[m.split(":")[0] for _, m in CRAFTED])
def test_open_map_refuses_what_a_spec_could_not_hold(base, tmp_path, how, msg):
    bad = crafted(base, tmp_path / "bad.nc", **how)
    with pytest.raises(api.InputError, match=msg.replace("+", r"\+").replace("*", r"\*")) as e:
        api.open_map(bad)
    assert "\n" not in str(e.value) and str(bad) in str(e.value)


@pytest.mark.parametrize("argv", [["plot"], ["query", "--shape", "square"], ["gallery"],
                                  ["explore", "--html", "page.html"], ["explore",
                                                                       "--no-browser"]])
@pytest.mark.parametrize("how, msg", [CRAFTED[0], CRAFTED[3], CRAFTED[6], CRAFTED[7],
                                      CRAFTED[13]], ids=["ball_a", "max_star_points",
                                                         "run_method", "run_T_s", "nan"])
def test_every_command_refuses_a_crafted_map_in_one_line(base, tmp_path, capsys, monkeypatch,
                                                          argv, how, msg):
    monkeypatch.chdir(tmp_path)
    bad = crafted(base, tmp_path / "bad.nc", **how)
    assert main([argv[0], str(bad), *argv[1:]]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and msg in err, err
    assert not list(tmp_path.glob("*.png")) + list(tmp_path.glob("*.html"))


def test_a_step_too_fine_to_integrate_again_is_refused_at_once(base, tmp_path):
    """run_dt_s = 1e-9 on T = 3 s: 3e9 steps a launch, within a spec's 1e10 but some half hour
    a launch; explore (both ways) and gallery refuse it before any work, well within 60 s."""
    bad = crafted(base, tmp_path / "fine.nc", attrs={"run_dt_s": 1e-9,
                                                      "run_dt_s_requested": 1e-9})
    for argv in (["explore", str(bad), "--html", str(tmp_path / "p.html")],
                 ["explore", str(bad), "--no-browser", "--port", "1"],
                 ["gallery", str(bad), "-o", str(tmp_path / "g.png")]):
        r = subprocess.run([sys.executable, "-m", "ballsurvey", *argv], capture_output=True,
                           text=True, timeout=60)
        assert r.returncode == 2, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1 and "at most 1e+07 steps" in r.stderr
    bad = crafted(base, tmp_path / "finer.nc", attrs={"run_dt_s": 1e-9, "run_T_s": 20.0})
    with pytest.raises(api.InputError, match="more than 1e"):  # past a spec's own limit
        api.open_map(bad)


def test_label_codes_must_be_ballsurveys(base, tmp_path):
    bad = tmp_path / "codes.nc"
    shutil.copy(base, bad)
    with netCDF4.Dataset(bad, "a") as nc:
        words = nc["label"].flag_meanings.split()
        nc["label"].flag_meanings = " ".join([words[1], words[0]] + words[2:])  # swapped
    with pytest.raises(api.InputError, match="not ballsurvey's label codes"):
        api.open_map(bad)


def test_codes_outside_the_tables_in_the_results_are_unwritten_cells(base, tmp_path, capsys):
    """Result values are not checked when a map is opened (that would read them all): a label
    or corner kind code outside ballsurvey's tables reads as an unwritten cell everywhere."""
    bad = tmp_path / "codes.nc"
    shutil.copy(base, bad)
    with netCDF4.Dataset(bad, "a") as nc:
        nc["corner_kind"][...] = 99
        nc["label"][0, 0, 0, 0] = 99
    for argv in (["gallery", "--per-label", "1", "-o", str(tmp_path / "g.png")],
                 ["query", "--shape", "square"], ["plot", "--at", "phidot0=-3", "-o",
                                                  str(tmp_path / "p.png")]):
        assert main([argv[0], str(bad), *argv[1:]]) == 0, capsys.readouterr().err


# ---------------------------------------------------------------------------------------------
# text from outside in the pages, in a real headless Chromium
#: each sets window.__pwned (and the page's title) if it ever runs
PAYLOADS = [
    '<img src=x onerror="window.__pwned=1;document.title=\'pwned\'">',
    '<svg onload="window.__pwned=2">',
    '"><img src=x onerror=window.__pwned=3>',
    "'><img src=x onerror=window.__pwned=4>",
    "javascript:window.__pwned=5",
    "</script><script>window.__pwned=6</script>",
    "${window.__pwned=7}`<img src=x onerror=window.__pwned=7>",
]
#: a map file's name and title that would run script where inserted as HTML
FILE_NAME = "<img src=x onerror=window.__pwned=8>.nc"
TITLE = "<svg onload=window.__pwned=9>"


def payload_spec() -> str:
    import json

    pts = "".join(f"[[points]]\nname = {json.dumps(n)}\ntheta0_deg = {2.0 + 2 * i}\n"
                  f"thetadot0 = 0.0\nchidot0 = {4.0 + 0.5 * i}\nphidot0 = -3.0\n"
                  for i, n in enumerate(PAYLOADS))
    return f"title = {json.dumps(TITLE)}\n{pts}[run]\nT = 3.0\ndt = 2e-4\n"


@pytest.fixture(scope="module")
def payload_map(tmp_path_factory):
    d = tmp_path_factory.mktemp("payload")
    api.sweep(payload_spec(), output=d / FILE_NAME, progress=False, notice=lambda m: None)
    return d / FILE_NAME


def test_text_from_outside_is_escaped_in_the_launch_panel(payload_map):
    pytest.importorskip("bokeh")
    from ballsurvey import explore

    with explore.open_lazily(payload_map) as ds:
        for i, name in enumerate(PAYLOADS):
            text = explore.launch_html(explore.launch_at(ds, i), note=name, timing=name)
            assert "<img" not in text and "<svg" not in text and "<script" not in text
            assert text.count(explore._h(name)) == 3  # the name, the note, the timing
    assert html.unescape(explore._h(PAYLOADS[2])) == PAYLOADS[2]


#: (value of window.__pwned, document.title, elements with an on* attribute or a javascript: URL,
#: text of the launch panel) of the page, shadow roots included
_PROBE = """const bad = [];
const walk = (root) => { for (const el of root.querySelectorAll('*')) {
  for (const a of el.attributes) {
    if (/^on/i.test(a.name) || /^\\s*javascript:/i.test(a.value)) {
      bad.push(el.outerHTML.slice(0, 80)); } }
  if (el.shadowRoot) { walk(el.shadowRoot); } } };
walk(document);
const v = Bokeh.index.find_one(Bokeh.documents[0].get_model_by_name('launch'));
const root = v.el.shadowRoot || v.el;
return [window.__pwned === undefined ? null : window.__pwned, document.title, bad,
        root.textContent];"""
#: all text shown on the page (not scripts' or styles'), shadow roots included
_TEXT = """const out = [];
const walk = (root) => {
  const w = document.createTreeWalker(root, NodeFilter.SHOW_TEXT);
  while (w.nextNode()) {
    const p = w.currentNode.parentNode;
    if (!p || !['SCRIPT', 'STYLE'].includes(p.nodeName)) { out.push(w.currentNode.data); } }
  for (const el of root.querySelectorAll('*')) { if (el.shadowRoot) { walk(el.shadowRoot); } } };
walk(document.body);
return out.join(' ');"""
_SELECT = """const src = Bokeh.documents[0].get_model_by_name('points');
src.selected.indices = [arguments[0]];"""


def _browser_bits():
    import test_explore as te

    return te


def _visit_every_point(d, te):
    """Hover over and select each point of the page's points map; returns the probe after each."""
    from selenium.webdriver.common.actions.action_builder import ActionBuilder

    seen = []
    for i in range(len(PAYLOADS)):
        x, y = 2.0 + 2 * i, 4.0 + 0.5 * i
        sx, sy = d.execute_script(te._WHERE, "map", x, y)
        a = ActionBuilder(d)
        a.pointer_action.move_to_location(int(round(sx)), int(round(sy)))
        a.perform()  # the hover tooltip, with the point's name as text
        te._wait(lambda i=i: PAYLOADS[i] in d.execute_script(_TEXT), what=f"point {i}'s tooltip")
        d.execute_script(_SELECT, i)
        te._wait(lambda i=i: PAYLOADS[i] in d.execute_script(_PROBE)[3],
                 what=f"point {i} in the launch panel")
        seen.append(d.execute_script(_PROBE))
    return seen


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    te = _browser_bits()
    yield from te.browser.__wrapped__(tmp_path_factory)


def test_no_payload_runs_in_the_static_page(payload_map, browser, tmp_path):
    te = _browser_bits()
    out = tmp_path / "page.html"
    assert main(["explore", str(payload_map), "--html", str(out), "--x", "theta0_deg",
                 "--y", "chidot0"]) == 0
    browser.get(out.as_uri())
    te._wait(lambda: browser.execute_script(te._READY), what="the static page")
    for pwned, title, bad, _ in _visit_every_point(browser, te):
        assert pwned is None and title == f"ballsurvey: {TITLE} ({FILE_NAME})" and not bad
    footer = browser.execute_script(
        "const v = Bokeh.index.find_one(Bokeh.documents[0].get_model_by_name('footer'));"
        "return (v.el.shadowRoot || v.el).textContent;")
    assert FILE_NAME in footer  # shown as text


@pytest.mark.parametrize("csp", [True, False], ids=["with-csp", "without-csp"])
def test_the_static_pages_policy_stops_a_missed_escape(payload_map, browser, tmp_path,
                                                       monkeypatch, csp):
    """The escaping turned off: the payloads are in the page as HTML. With the page's
    Content-Security-Policy none runs; without it (the check that the payloads are live) the
    file name's runs as the page loads."""
    from ballsurvey import explore

    te = _browser_bits()
    for room in (explore.document, explore.static):  # the escaper, where each room calls it
        monkeypatch.setattr(room, "_h", str)
    if not csp:
        monkeypatch.setattr(explore.static, "with_csp", lambda page: page)
    out = tmp_path / "unescaped.html"
    explore.write_html(payload_map, out, x="theta0_deg", y="chidot0")
    browser.get(out.as_uri())
    te._wait(lambda: browser.execute_script(te._READY), what="the static page")
    if not csp:
        assert te._wait(lambda: browser.execute_script("return window.__pwned;"),
                        what="the unescaped payload to run") == 8
        return
    browser.execute_script(_SELECT, 0)
    time.sleep(0.5)
    pwned, _, bad, _ = browser.execute_script(_PROBE)
    assert bad  # injected: the policy alone stands in the way
    assert pwned is None


def test_no_payload_runs_in_the_app(payload_map, browser):
    te = _browser_bits()
    port = te._free_port()
    proc = subprocess.Popen([sys.executable, "-m", "ballsurvey", "explore", str(payload_map),
                             "--port", str(port), "--no-browser", "--x", "theta0_deg",
                             "--y", "chidot0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert f"http://127.0.0.1:{port}/" in line, line + proc.stderr.read()
        browser.get(f"http://127.0.0.1:{port}/")
        te._wait(lambda: browser.execute_script(te._READY), what="the app")
        for pwned, title, bad, panel in _visit_every_point(browser, te):
            assert pwned is None and title == f"ballsurvey explore: {FILE_NAME}" and not bad
            assert "Integrated again" in panel or "cannot integrate" in panel
        toml = browser.execute_script(
            "const v = Bokeh.index.find_one(Bokeh.documents[0].get_model_by_name('toml'));"
            "return (v.el.shadowRoot || v.el).textContent;")
        assert PAYLOADS[-1].replace("\\", "\\\\") in toml.replace('\\"', '"')
    finally:
        proc.kill()
        proc.wait()


# ---------------------------------------------------------------------------------------------
# the explorer answers only its own host: raw requests, as a page whose name was rebound to
# 127.0.0.1 (DNS rebinding) or a sandboxed frame (Origin: null) would send them
def _raw(port: int, request: str) -> str:
    """The response's status line to a raw HTTP request."""
    import socket

    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(request.encode())
        data = b""
        while b"\r\n" not in data:
            more = s.recv(65536)
            if not more:
                break
            data += more
    return data.decode("latin1").split("\r\n")[0]


def _get(port, host, origin=None):
    return _raw(port, f"GET / HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n"
                + (f"Origin: {origin}\r\n" if origin else "") + "\r\n")


def _upgrade(port, host, origin, token):
    return _raw(port, f"GET /ws HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\n"
                "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                f"Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: bokeh, {token}\r\n"
                + (f"Origin: {origin}\r\n" if origin else "") + "\r\n")


def _token(port) -> str:
    """A session token, as the app's own page hands it out (to 127.0.0.1)."""
    import re
    import socket

    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
                  .encode())
        page = b""
        while more := s.recv(65536):
            page += more
    m = re.search(r'token&quot;:&quot;([^&]+)&quot;|"token":\s*"([^"]+)"', page.decode())
    return m.group(1) or m.group(2)


@pytest.fixture
def served(base):
    """serve(extra arguments) -> (port, process) of `explore` on the crafted-test map."""
    pytest.importorskip("bokeh")
    import socket

    procs = []

    def start(*extra):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        p = subprocess.Popen([sys.executable, "-m", "ballsurvey", "explore", str(base), "--port",
                              str(port), "--no-browser", "--at", "phidot0=-3", *extra],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        procs.append(p)
        line = p.stdout.readline()
        assert f"127.0.0.1:{port}" in line, line + p.stderr.read()
        return port, p
    yield start
    for p in procs:
        p.kill()
        p.wait()


def test_the_app_answers_only_its_own_host(served):
    port, _ = served()
    token = _token(port)
    own, evil = f"127.0.0.1:{port}", f"evil.example:{port}"
    assert _get(port, own).endswith("200 OK")
    assert _get(port, f"localhost:{port}").endswith("200 OK")
    assert _get(port, evil).endswith("403 Forbidden")  # a foreign Host
    assert _get(port, evil, f"http://{evil}").endswith("403 Forbidden")  # ... equal to Origin
    assert _get(port, f"127.0.0.1:{port + 1}").endswith("403 Forbidden")  # another port
    assert _raw(port, "GET / HTTP/1.0\r\n\r\n").endswith("403 Forbidden")  # no Host at all
    assert _upgrade(port, evil, f"http://{evil}", token).endswith("403 Forbidden")
    assert _upgrade(port, own, "null", token).endswith("403 Forbidden")  # a null Origin
    assert _upgrade(port, own, f"http://{evil}", token).endswith("403 Forbidden")
    assert _upgrade(port, own, f"http://{own}", token).endswith("101 Switching Protocols")


def test_allow_host_shares_deliberately_with_a_warning(served):
    port, p = served("--allow-host", "Proxy.Example")
    assert _get(port, f"proxy.example:{port}").endswith("200 OK")
    assert _get(port, f"evil.example:{port}").endswith("403 Forbidden")
    p.kill()
    warning = p.stderr.readline()
    assert warning.startswith("warning: --allow-host") and f"proxy.example:{port}" in warning


@pytest.mark.parametrize("argv, msg", [
    (["--allow-host", "a b"], "not a host name"),
    (["--allow-host", "x:99999"], "not a host name"),
    (["--allow-host", "x", "--html", "p.html"], "for the app"),
])
def test_allow_host_values_are_checked_first(base, tmp_path, capsys, monkeypatch, argv, msg):
    pytest.importorskip("bokeh")
    monkeypatch.chdir(tmp_path)
    assert main(["explore", str(base), "--no-browser", *argv]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and msg in err


# ---------------------------------------------------------------------------------------------
# commands' own promises
def test_a_printed_force_resume_runs_as_printed_after_a_physics_edit(tmp_path, monkeypatch,
                                                                      capsys):
    """A map and the parts of an interrupted rerun, both made before the code changed: the
    refusal offers --force --resume only where it would run (parts of other code cannot be
    resumed), and what it offers runs."""
    from ballsurvey.sweep import parts, run_sweep
    from test_reliability import Crash, crash_at, tiny_spec

    spec = tiny_spec(tmp_path, "m.nc")
    run_sweep(spec, command="test")
    with pytest.raises(Crash):
        run_sweep(spec, force=True, on_chunk=crash_at(1), command="test")
    assert (parts.parts_dir(spec.output) / parts.MANIFEST).is_file()
    monkeypatch.setattr(parts, "code_digest", lambda: "0" * 64)  # the physics edited since
    toml = str(tmp_path / "tiny.toml")
    assert main(["sweep", toml, "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "other code" in err
    offered = next(a for a in (["--force", "--resume"], ["--force"]) if " ".join(a) in err)
    assert main(["sweep", toml, "--no-progress", *offered]) == 0, capsys.readouterr().err


@pytest.mark.parametrize("fps", ["0.001", "0.5", "0", "-3", "nan", "1e9"])
def test_animate_fps_is_checked_before_any_work(tmp_path, capsys, monkeypatch, fps):
    import importlib

    def no_work(*a, **k):
        raise AssertionError("integrated before checking --fps")
    monkeypatch.setattr(importlib.import_module("ballsurvey.simulate"), "simulate", no_work)
    assert main(["animate", "--theta0-deg", "2", "--chidot0", "4", "--phidot0", "-3", "--fps",
                 fps, "-o", str(tmp_path / "a.gif")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--fps" in err
    assert not (tmp_path / "a.gif").exists()


@pytest.mark.parametrize("kind", ["folder", "fifo", "device"])
def test_fit_says_what_a_track_that_is_no_file_is(tmp_path, capsys, kind):
    import os

    path = {"folder": tmp_path, "device": "/dev/null"}.get(kind, tmp_path / "pipe.csv")
    if kind == "fifo":
        os.mkfifo(path)  # opened for reading, it would wait for a writer for ever
    assert main(["fit", str(path)]) == 2
    err = capsys.readouterr().err
    words = {"folder": "is a folder", "fifo": "is a FIFO", "device": "is a device"}[kind]
    assert len(err.strip().splitlines()) == 1 and words in err and "no such file" not in err


def test_a_static_page_whose_paths_would_take_too_long_is_written_without(base, tmp_path,
                                                                         monkeypatch):
    """The map's own settings within every limit, its stored theta periods long (T = 1e4 s,
    dt = 1e-3 s: 1e7 steps a launch at most): the page's paths would take 6e7 steps; with the
    page's budget at 1e6 it is written at once, without paths, and says why."""
    pytest.importorskip("bokeh")
    from ballsurvey import explore

    bad = tmp_path / "long.nc"
    shutil.copy(base, bad)
    with netCDF4.Dataset(bad, "a") as nc:
        nc.setncatts({"run_T_s": 1e4, "run_dt_s": 1e-3, "run_dt_s_requested": 1e-3})
        nc["theta_period_s"][...] = 1e9
    monkeypatch.setattr(explore.static, "MAX_HTML_STEPS", 10**6)
    t0 = time.monotonic()
    r = explore.write_html(bad, tmp_path / "p.html", at={"phidot0": -3.0})
    assert r == {"launches": 6, "paths": False} and time.monotonic() - t0 < 30
    assert "this slice's take 6e+07" in (tmp_path / "p.html").read_text()

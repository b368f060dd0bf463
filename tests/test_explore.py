"""`ballsurvey explore`: the map app and the static page, in Python and in a real headless
Chromium driven by Selenium (skipped, with the reason, only where no chromium or chromedriver is
found). Maps are tiny sweeps made here: 4 x 5 x 2 launches and three named points, T = 3 s."""
import csv
import io
import math
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
import xarray as xr

pytest.importorskip("bokeh", reason="explore needs bokeh (pip install -e '.[test]')")

from ballsurvey import api, explore  # noqa: E402
from ballsurvey.cli import main  # noqa: E402
from ballsurvey.simulate import simulate  # noqa: E402
from ballsurvey.sweep import load_spec  # noqa: E402

GRID_SPEC = """
title = "explore grid"
[launch]
theta0_deg = {start = -10.0, stop = 26.0, num = 4}
thetadot0 = 0.0
chidot0 = {start = 2.0, stop = 10.0, num = 5}
phidot0 = [-3.0, -2.5]
[run]
T = 3.0
dt = 2e-4
[classify]
mu = 0.35
"""
POINTS_SPEC = """
title = "explore points"
[[points]]
name = "square"
theta0_deg = 2.0
thetadot0 = 0.0
chidot0 = 4.0
phidot0 = -3.0
[[points]]
name = "triangle"
theta0_deg = -10.0
thetadot0 = 0.0
chidot0 = 2.3
phidot0 = -2.5
[[points]]
name = "tall"
theta0_deg = 20.0
thetadot0 = 0.5
chidot0 = 6.0
phidot0 = -3.0
chi0_deg = 30.0
[run]
T = 3.0
dt = 2e-4
"""
#: the launch clicked: theta0 = 2 deg, chidot0 = 4 rad/s (a square), phidot0 at its first value
CLICK = {"theta0_deg": 2.0, "chidot0": 4.0}


@pytest.fixture(scope="module")
def maps(tmp_path_factory):
    d = tmp_path_factory.mktemp("explore")
    api.sweep(GRID_SPEC, output=d / "grid.nc", progress=False, notice=lambda m: None)
    api.sweep(POINTS_SPEC, output=d / "points.nc", progress=False, notice=lambda m: None)
    return d


@pytest.fixture
def lazy():
    """explore.open_lazily, each map closed when the test ends (HDF5 errors on a later open of a
    file whose lazily opened handle was left to the garbage collector)."""
    held = []

    def open_(path):
        held.append(explore.open_lazily(path))
        return held[-1]
    yield open_
    for ds in held:
        ds.close()


def stored(path, **at) -> dict:
    """The map's own values at a launch, read with xarray (not through explore)."""
    with xr.open_dataset(path) as ds:
        one = (ds.isel(at) if "launch" in at else ds.sel(at)).load()
    from ballsurvey.classify.labels import LABELS

    return {"label": LABELS[int(one.label)], "n_sides": float(one.n_sides)}


# ---------------------------------------------------------------------------------------------
# without a browser
def test_a_click_integrates_with_the_maps_settings_and_agrees_with_it(maps, lazy):
    ds = lazy(maps / "grid.nc")
    s = explore.run_settings(ds)
    assert (s.T, s.dt, s.method, s.thresholds.mu) == (3.0, 2e-4, "rk4", 0.35)
    view = explore.make_view(ds)
    assert (view.x, view.y) == ("theta0_deg", "chidot0")  # the longest axes, up the longest
    for k in range(20):
        info = explore.launch_at(ds, view.where(k))
        traj = explore.integrate_launch(ds, info["launch"], info["ball"], settings=s)
        assert traj.attrs["dt_s"] == pytest.approx(2e-4, rel=1e-12)  # the map's own step
        assert traj.attrs["label"] == info["stored"]["label"]
        # the map samples its observer every 4th step (0.8 ms), the click every step: a theta
        # maximum's time moves by up to 0.8 ms of a 0.55 s period, n_sides by up to 4 * 0.15 %
        if math.isfinite(info["stored"]["n_sides"]):
            assert traj.attrs["n_sides"] == pytest.approx(info["stored"]["n_sides"], abs=6e-3)


def test_path_csv_and_points_entry_give_the_launch_back(maps, lazy):
    ds = lazy(maps / "grid.nc")
    view = explore.make_view(ds)
    k = view.nearest(CLICK["theta0_deg"], CLICK["chidot0"])
    info = explore.launch_at(ds, view.where(k))
    assert info["launch"] == {"theta0_deg": 2.0, "thetadot0": 0.0, "chidot0": 4.0,
                              "phidot0": -3.0, "chi0_deg": 0.0}
    traj = explore.integrate_launch(ds, info["launch"], info["ball"], T=0.5)
    rows = list(csv.DictReader(io.StringIO(explore.path_csv(traj))))
    assert len(rows) == traj.sizes["time"]
    assert float(rows[0]["t_s"]) == 0.0 and float(rows[0]["theta_deg"]) == pytest.approx(2.0)
    assert float(rows[-1]["x_m"]) == pytest.approx(float(traj.x[-1]), rel=1e-9)
    assert float(rows[-1]["chi_deg"]) == pytest.approx(math.degrees(float(traj.chi[-1])))
    entry = explore.points_entry(info, explore.launch_name(info, (view.x, view.y)))
    spec = load_spec("entry", text=entry + "[run]\nT = 3.0\ndt = 2e-4\n")
    assert spec.points["name"][0] == "theta0=2,chidot0=4"
    for key, v in info["launch"].items():
        assert spec.points[key][0] == v


def test_only_the_slice_shown_is_read_and_the_sliders_move_it(maps, lazy):
    from bokeh.document import Document
    from bokeh.events import Tap

    ds = lazy(maps / "grid.nc")
    with xr.open_dataset(maps / "grid.nc") as f:
        full = f.load()
    doc = Document()
    explore.build_document(doc, ds, maps / "grid.nc")
    assert not ds.label.variable._in_memory  # the file is read slice by slice
    image = doc.get_model_by_name("image")

    def shown():
        return np.asarray(image.data["image"][0])

    expect = full.label.isel(thetadot0=0, phidot0=0).transpose("chidot0", "theta0_deg").values
    assert np.array_equal(shown(), expect)
    doc.get_model_by_name("slider_phidot0").trigger("value_throttled", 0, 1)  # as a drag ends
    expect = full.label.isel(thetadot0=0, phidot0=1).transpose("chidot0", "theta0_deg").values
    assert np.array_equal(shown(), expect)
    assert "phidot0 = -2.5 rad/s" in doc.get_model_by_name("fixed").text
    # a tap on the map (as the browser sends it) fills the launch panel and the downloads
    fig = doc.get_model_by_name("map")
    fig._trigger_event(Tap(fig, x=CLICK["theta0_deg"] + 1.0, y=CLICK["chidot0"] - 0.3))
    want = stored(maps / "grid.nc", thetadot0=0.0, phidot0=-2.5, **CLICK)
    assert f"<td class='bs-map' data-field='label'>{want['label']}</td>" in \
        doc.get_model_by_name("launch").text
    assert "phidot0 = -2.5" in doc.get_model_by_name("toml").text
    assert doc.get_model_by_name("downloads").data["csv"][0].startswith("t_s,x_m,y_m")


def test_points_map_app_selects_a_point(maps, lazy):
    from bokeh.document import Document

    ds = lazy(maps / "points.nc")
    doc = Document()
    explore.build_document(doc, ds, maps / "points.nc")
    src = doc.get_model_by_name("points")
    i = src.data["name"].index("tall")
    src.selected.indices = [i]  # as a tap on the point selects it
    text = doc.get_model_by_name("launch").text
    want = stored(maps / "points.nc", launch=i)
    assert f"<td class='bs-map' data-field='label'>{want['label']}</td>" in text
    assert "tall: theta0 = 20 deg, thetadot0 = 0.5 rad/s" in text and "chi0 = 30 deg" in text
    assert 'name = "tall"' in doc.get_model_by_name("toml").text


def test_uneven_axis_pixels_show_their_nearest_value():
    lo, hi, idx = explore.axis_pixels(np.array([0.0, 1.0, 4.0]))
    assert (lo, hi) == (-0.5, 4.5)  # pixels at the smallest spacing, 1: centres 0, 1, 2, 3, 4
    assert list(idx) == [0, 1, 1, 2, 2]
    lo, hi, idx = explore.axis_pixels(np.array([3.0, 2.0, 1.0]))  # even, decreasing
    assert (lo, hi, list(idx)) == (0.5, 3.5, [2, 1, 0])


@pytest.mark.parametrize("sizes", [(6, 3), (3, 6), (9, 12)])
def test_explore_draws_a_grid_the_way_plot_does(sizes):
    """theta0 across and chidot0 up whatever the grid sizes, as in plot's figure."""
    from ballsurvey.plot import map_figure

    codes = np.zeros((sizes[0], 1, sizes[1], 1), dtype=np.int8)
    ds = xr.Dataset({"label": (("theta0_deg", "thetadot0", "chidot0", "phidot0"), codes)},
                    coords={"theta0_deg": np.linspace(-10, 30, sizes[0]), "thetadot0": [0.0],
                            "chidot0": np.linspace(1, 12, sizes[1]), "phidot0": [-3.0]})
    view = explore.make_view(ds)
    assert (view.x, view.y) == ("theta0_deg", "chidot0")
    ax = map_figure(ds, contours=False).axes[0]
    assert "theta" in ax.get_xlabel() and "chi" in ax.get_ylabel()
    # one axis given: the other is the first free one, as in plot
    assert (explore.make_view(ds, y="theta0_deg").x, explore.make_view(ds, x="chidot0").y) == (
        "chidot0", "theta0_deg")


def test_panel_texts_are_plain_text_with_units(maps, lazy):
    """A Bokeh Div shows its text as it is: no mathtext dollars, the CLI's names and units."""
    ds = lazy(maps / "grid.nc")
    assert explore.make_view(ds).fixed_text() == "thetadot0 = 0 rad/s, phidot0 = -3 rad/s"
    head = explore.launch_html(explore.launch_at(ds, {"theta0_deg": 0, "thetadot0": 0, "chidot0": 0,
                                                      "phidot0": 0}))
    assert "$" not in head and "theta0 = -10 deg" in head and "chidot0 = 2 rad/s" in head


def test_views_refuse_axes_the_map_lacks(maps, lazy):
    ds = lazy(maps / "grid.nc")
    for kw, msg in ((dict(x="c"), "not an axis"), (dict(x="chidot0", y="chidot0"), "same axis"),
                    (dict(x="theta0_deg", at={"theta0_deg": 2.0}), "axis drawn"),
                    (dict(at={"phidot0": -2.0}), "not on the map's grid")):
        with pytest.raises(api.InputError, match=msg):
            explore.make_view(ds, **kw)
    pts = lazy(maps / "points.nc")
    with pytest.raises(api.InputError, match="named points"):
        explore.make_view(pts, at={"phidot0": -3.0})
    view = explore.make_view(pts)
    assert {view.x, view.y} <= {"theta0_deg", "thetadot0", "chidot0", "phidot0", "chi0_deg"}
    assert explore.launch_at(pts, 2)["launch"]["chi0_deg"] == 30.0


def test_cli_errors_are_one_line_exit_2(maps, capsys, monkeypatch):
    for args, msg in ((["--port", "70000"], "--port"), (["--x", "nope"], "not an axis"),
                      (["--html", str(maps / "page.txt")], "ending in .html")):
        assert main(["explore", str(maps / "grid.nc"), *args]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and msg in err
    assert main(["explore", str(maps / "nope.nc"), "--no-browser"]) == 2
    assert "no such file" in capsys.readouterr().err
    with socket.socket() as busy:  # a port in use: one line, exit 1, before serving anything
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = str(busy.getsockname()[1])
        assert main(["explore", str(maps / "grid.nc"), "--port", port, "--no-browser"]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and f"127.0.0.1:{port}" in err
    monkeypatch.setitem(sys.modules, "bokeh", None)  # as if bokeh were not installed
    assert main(["explore", str(maps / "grid.nc")]) == 2
    assert "pip install 'ballsurvey[explore]'" in capsys.readouterr().err


def test_static_page_limits(maps, tmp_path, monkeypatch):
    r = explore.write_html(maps / "grid.nc", tmp_path / "a.html", max_paths=5)  # 20 shown
    assert r == {"launches": 20, "paths": False}
    assert "paths are precomputed for slices of at most 5 launches" in \
        (tmp_path / "a.html").read_text()
    monkeypatch.setattr(explore.static, "MAX_HTML_LAUNCHES", 10)
    with pytest.raises(api.InputError, match="at most 10"):
        explore.write_html(maps / "grid.nc", tmp_path / "b.html")
    assert not (tmp_path / "b.html").exists()


def test_help_states_the_static_pages_path_limit():
    from ballsurvey.cli import build_parser

    sub = build_parser()._subparsers._group_actions[0].choices["explore"]
    assert f"at most {explore.MAX_HTML_PATHS} launches" in " ".join(sub.format_help().split())


# ---------------------------------------------------------------------------------------------
# in a real browser
@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    from conftest import headless_chromium

    d = headless_chromium()
    d.downloads = tmp_path_factory.mktemp("downloads")
    d.execute_cdp_cmd("Page.setDownloadBehavior", {"behavior": "allow",
                                                   "downloadPath": str(d.downloads)})
    yield d
    d.quit()


def _wait(fn, timeout=20.0, what="the page"):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        v = fn()
        if v:
            return v
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def _finished_download(folder, pattern):
    """The downloads matching pattern once Chrome has finished: it makes an empty file of the
    final name at the start and renames its .crdownload over it at the end."""
    if list(folder.glob("*.crdownload")):
        return []
    return [p for p in folder.glob(pattern) if p.stat().st_size > 0]


_READY = """const d = window.Bokeh && Bokeh.documents[0];
const m = d && d.get_model_by_name('map');
return !!(m && Bokeh.index.find_one(m));"""
_WHERE = """const v = Bokeh.index.find_one(Bokeh.documents[0].get_model_by_name(arguments[0]));
v.el.scrollIntoView({block: 'center'});
const r = (v.canvas_view ? v.canvas_view.el : v.el).getBoundingClientRect();
if (!v.frame) { return [r.left + r.width / 2, r.top + r.height / 2]; }
return [r.left + v.frame.x_scale.compute(arguments[1]),
        r.top + v.frame.y_scale.compute(arguments[2])];"""
_CELLS = """const v = Bokeh.index.find_one(Bokeh.documents[0].get_model_by_name('launch'));
const root = v.el.shadowRoot || v.el, out = {};
for (const td of root.querySelectorAll('td[data-field]')) {
  out[td.className.slice(3) + ' ' + td.dataset.field] = td.textContent; }
return out;"""


def _click(d, name, x=0.0, y=0.0):
    """A real pointer click at data point (x, y) of the figure (or the middle of a widget)."""
    from selenium.webdriver.common.actions.action_builder import ActionBuilder

    sx, sy = d.execute_script(_WHERE, name, x, y)
    a = ActionBuilder(d)
    a.pointer_action.move_to_location(int(round(sx)), int(round(sy))).click()
    a.perform()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_app_in_a_browser_shows_the_clicked_launch(maps, browser, tmp_path):
    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "ballsurvey", "explore",
                             str(maps / "grid.nc"), "--port", str(port), "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()  # printed once the kernels are ready
        assert f"http://127.0.0.1:{port}/" in line, line + proc.stderr.read()
        browser.get(f"http://127.0.0.1:{port}/")
        _wait(lambda: browser.execute_script(_READY), what="the app")
        t0 = time.monotonic()
        _click(browser, "map", CLICK["theta0_deg"] + 1.5, CLICK["chidot0"] + 0.5)  # in its pixel
        cells = _wait(lambda: browser.execute_script(_CELLS), what="the launch panel")
        took = time.monotonic() - t0
        want = stored(maps / "grid.nc", thetadot0=0.0, phidot0=-3.0, **CLICK)
        assert cells["map label"] == want["label"] == "square"
        assert cells["map n_sides"] == f"{want['n_sides']:.4f}"
        assert cells["again label"] == want["label"]
        assert float(cells["again n_sides"]) == pytest.approx(want["n_sides"], abs=6e-3)
        assert took < 10.0  # about a second on a quiet machine, kernels compiled
        browser.save_screenshot(str(tmp_path / "explore-app.png"))
        _click(browser, "download_csv")
        got = _wait(lambda: _finished_download(browser.downloads, "*.csv"), what="the CSV download")
        first = next(csv.DictReader(io.StringIO(got[0].read_text())))
        assert got[0].name == "theta0_2_chidot0_4.csv"
        assert float(first["theta_deg"]) == pytest.approx(2.0) and float(first["t_s"]) == 0
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=20) == 130
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_static_page_in_a_browser_draws_the_precomputed_path(maps, browser, tmp_path):
    out = tmp_path / "grid.html"
    assert main(["explore", str(maps / "grid.nc"), "--html", str(out)]) == 0
    html = out.read_text()
    assert "cdn.bokeh.org" not in html and "<script src=" not in html  # works offline
    # the page draws whole cycles from a theta maximum, the app from the launch point: each
    # names its black triangle
    assert "first theta maximum (whole cycles drawn from here)" in html
    browser.get(out.as_uri())
    _wait(lambda: browser.execute_script(_READY), what="the static page")
    _click(browser, "map", CLICK["theta0_deg"], CLICK["chidot0"])
    cells = _wait(lambda: browser.execute_script(_CELLS), what="the launch panel")
    want = stored(maps / "grid.nc", thetadot0=0.0, phidot0=-3.0, **CLICK)
    assert cells["map label"] == want["label"]
    assert cells["map n_sides"] == f"{want['n_sides']:.4f}"
    drawn = _wait(lambda: browser.execute_script(
        "const p = Bokeh.documents[0].get_model_by_name('path').data;"
        "return p.x.length ? [Array.from(p.x), Array.from(p.y)] : null;"), what="the path")
    browser.save_screenshot(str(tmp_path / "explore-static.png"))
    # one theta cycle turned about the orbit centre, as drawn in the page, lies on the path
    # integrated whole (T = 3 s, 4001 samples: about 0.1 mm apart)
    full = simulate(2.0, 0.0, 4.0, -3.0, T=3.0, dt=2e-4, n_out=4001, chi0_deg=0.0)
    pts = np.column_stack([full.x.values, full.y.values])
    drawn = np.column_stack(drawn)
    gap = np.min(np.hypot(*(drawn[:, None, :] - pts[None, :, :]).transpose(2, 0, 1)), axis=1)
    assert len(drawn) > 2 * explore.CYCLE_SAMPLES and gap.max() < 1e-3
    size = np.ptp(pts, axis=0).max()
    assert np.ptp(drawn, axis=0).max() == pytest.approx(size, rel=0.02)  # the whole orbit


def test_points_map_page_in_a_browser(maps, browser, tmp_path):
    out = tmp_path / "points.html"
    explore.write_html(maps / "points.nc", out, x="theta0_deg", y="chidot0")
    browser.get(out.as_uri())
    _wait(lambda: browser.execute_script(_READY), what="the static page")
    _click(browser, "map", -10.0, 2.3)
    cells = _wait(lambda: browser.execute_script(_CELLS), what="the launch panel")
    with xr.open_dataset(maps / "points.nc") as ds:
        i = [str(n) for n in ds.name.values].index("triangle")
        from ballsurvey.classify.labels import LABELS

        assert cells["map label"] == LABELS[int(ds.label.values[i])]
        assert cells["map n_sides"] == f"{float(ds.n_sides.values[i]):.4f}"


def test_the_legend_says_where_an_exact_curve_runs_through_another_label():
    from ballsurvey.explore import legend_html

    text = legend_html([0, 3], {4.0: ([0.0], [0.0])}, {4.0: ["circle"]})
    assert "exact square (n = 4) (also through circle: n=4 there, but the path reads as circle)" \
        in text
    assert "also through" not in legend_html([0, 3], {4.0: ([0.0], [0.0])})


def test_a_quadrature_maps_click_is_integrated_by_dopri5_and_says_so(maps, lazy):
    ds = lazy(maps / "grid.nc").copy()
    ds.attrs["run_method"] = "quadrature"
    s = explore.run_settings(ds)
    assert s.method == "dopri5"
    assert "the map's quadrature computes one theta cycle, no path" in s.note

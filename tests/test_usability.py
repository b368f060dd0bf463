"""What makes the commands pleasant to use, each judged from outside the code that does it: map
axes that do not turn with grid size, a path figure that shows a few orbits with every corner
marked and rates on a scale that shows both spikes and ordinary motion, PDF and SVG output,
{p/q} and honest corner words, `query --all`, a line while compiling, `simulate` in degrees with
its friction ratio and normal force checked against Newton's law from the path itself, label
words for pandas, `--at` saying the value used, and `--help` in the order of use."""
import json
import math

import numpy as np
import pytest
import xarray as xr

import ballsurvey
from ballsurvey import cli
from ballsurvey.ball import Ball
from ballsurvey.classify.labels import CODE, LABELS
from ballsurvey.plot import (
    default_axes,
    map_figure,
    orbit_window,
    path_figure,
    shape_text,
    spin_about_axis,
)


@pytest.fixture(scope="module")
def small_map(tmp_path_factory):
    """A 5 x 10 x 2 map, short runs: a real file for the commands."""
    out = tmp_path_factory.mktemp("usability") / "m.nc"
    spec = {"title": "usability map",
            "launch": {"theta0_deg": {"start": -10.0, "stop": 30.0, "num": 5}, "thetadot0": 0.0,
                       "chidot0": {"start": 1.0, "stop": 12.0, "num": 10},
                       "phidot0": [-3.0, -2.5]},
            "run": {"T": 4.0, "dt": 5e-4}}
    ballsurvey.sweep(spec, output=out, progress=False, notice=lambda msg: None)
    return out


@pytest.fixture(scope="module")
def square():
    """The paper's Fig. 12a, 20 s, samples every 2.5 ms."""
    return ballsurvey.simulate(-5.0, 0.0, 4.05, -3.0, T=20.0, n_out=8001)


def _grid(n_theta, n_chidot):
    codes = np.zeros((n_theta, 1, n_chidot, 1), dtype=np.int8)
    return xr.Dataset({"label": (("theta0_deg", "thetadot0", "chidot0", "phidot0"), codes)},
                      coords={"theta0_deg": np.linspace(-10, 30, n_theta), "thetadot0": [0.0],
                              "chidot0": np.linspace(1, 12, n_chidot), "phidot0": [-3.0]})


# ---- maps ------------------------------------------------------------------------------------
@pytest.mark.parametrize("sizes", [(26, 23), (11, 12), (9, 12), (12, 11)])
def test_map_axes_do_not_turn_with_grid_size(sizes):
    ds = _grid(*sizes)
    assert default_axes(ds) == ("theta0_deg", "chidot0")
    fig = map_figure(ds, contours=False)
    ax = fig.axes[0]
    assert "theta" in ax.get_xlabel() and "chi" in ax.get_ylabel()
    # the drawn extent is theta0's range across and chidot0's up
    assert ax.get_xlim()[0] < -10 < 30 < ax.get_xlim()[1]
    assert ax.get_ylim()[0] < 1 < 12 < ax.get_ylim()[1] < 13


def test_one_axis_given_takes_the_first_free_one_for_the_other():
    ds = _grid(5, 7)
    fig = map_figure(ds, y="theta0_deg", contours=False)
    assert "chi" in fig.axes[0].get_xlabel() and "theta" in fig.axes[0].get_ylabel()


def test_exact_triangle_is_dashed_and_square_solid_on_the_map_and_in_its_legend():
    ds = _grid(6, 7)
    n = np.linspace(2.5, 4.5, 7)[None, None, :, None] + np.zeros((6, 1, 7, 1))
    ds["n_sides"] = (ds.label.dims, n)
    ds["label"] = (ds.label.dims, np.where(n < 3.5, CODE["triangle"], CODE["square"]).astype(
        np.int8))
    fig = map_figure(ds)
    cs = [c for c in fig.axes[0].collections if hasattr(c, "levels")][0]
    dashed = {float(lv): ls[1] is not None for lv, ls in zip(cs.levels, cs.get_linestyles())}
    assert dashed == {3.0: True, 4.0: False}
    legend = {h.get_label(): h.get_linestyle() for h in fig.legends[0].legend_handles
              if h.get_label().startswith("exact")}
    assert legend == {"exact triangle (n=3)": "--", "exact square (n=4)": "-"}


def test_spin_about_the_axis_is_the_fixed_frame_spin_and_stays_bounded(square):
    """omega_eta = phidot - chidot sin(theta) against w . e of the fixed-frame state, and, for
    the paper's square, bounded where the Euler rates spike (theta near 90 deg)."""
    from ballsurvey.physics.euler import CHD, CHI, N_EULER, PHD, PHI, TH, THD, X, Y
    from ballsurvey.physics.fixed import EX, EZ, WX, WZ, euler_to_fixed

    spin = spin_about_axis(square.theta.values, square.chidot.values, square.phidot.values)
    for i in range(0, square.sizes["time"], 97):
        u = np.empty(N_EULER)
        for k, name in ((X, "x"), (Y, "y"), (TH, "theta"), (CHI, "chi"), (PHI, "phi"),
                        (THD, "thetadot"), (CHD, "chidot"), (PHD, "phidot")):
            u[k] = float(square[name][i])
        v = euler_to_fixed(u)
        assert float(np.dot(v[WX:WZ + 1], v[EX:EZ + 1])) == pytest.approx(spin[i], abs=1e-9)
    assert np.abs(square.phidot.values).max() > 50 and np.abs(square.chidot.values).max() > 50
    assert -3.0 < spin.min() and spin.max() < -2.5  # launched at -3 - 4.05 sin(-5 deg) = -2.65
    rates = [ax for ax in path_figure(square).axes if ax.get_yscale() == "symlog"][0]
    assert any("spin about the axis" in t.get_text() for t in rates.get_legend().get_texts())


def test_map_title_names_the_ball_and_the_fixed_values(small_map):
    ds = ballsurvey.open_map(small_map)
    title = map_figure(ds, at={"phidot0": -2.5})._suptitle.get_text()
    assert "the paper's ball (a = 25.4 mm, c = 2.9 mm, M = 98.4 g)" in title
    assert r"$\dot\phi_0$ = -2.5 rad/s" in title
    other = dict(ds.attrs, ball_c=0.002)
    assert map_figure(ds.assign_attrs(other), at={"phidot0": -3})._suptitle.get_text().count(
        "ball: a = 25.4 mm, c = 2 mm") == 1


def test_plot_at_says_the_value_it_drew(small_map, tmp_path, capsys):
    out = tmp_path / "m.svg"
    assert cli.main(["plot", str(small_map), "--at", "phidot0=-2.4", "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert "--at phidot0=-2.4: drew the map's nearest value, phidot0 = -2.5" in said
    assert out.read_text().lstrip().startswith("<?xml") and "<svg" in out.read_text()
    assert cli.main(["plot", str(small_map), "--at", "phidot0=-2.5", "-o", str(out)]) == 0
    assert "nearest value" not in capsys.readouterr().out


@pytest.mark.parametrize("suffix,magic", [(".pdf", b"%PDF"), (".svg", b"<?xml"),
                                          (".png", b"\x89PNG")])
def test_figure_commands_write_pdf_svg_and_png(small_map, tmp_path, suffix, magic):
    out = tmp_path / f"map{suffix}"
    assert cli.main(["plot", str(small_map), "--at", "phidot0=-3", "-o", str(out)]) == 0
    assert out.read_bytes().startswith(magic)


def test_a_figure_file_of_another_kind_is_one_line_exit_2(small_map, tmp_path, capsys):
    for argv in (["plot", str(small_map), "-o", str(tmp_path / "m.jpg")],
                 ["path", "--theta0-deg", "-5", "--chidot0", "4", "--phidot0", "-3", "-o",
                  str(tmp_path / "p.jpg")],
                 ["gallery", str(small_map), "-o", str(tmp_path / "g.eps")]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and ".png or .pdf or .svg" in err
    assert not list(tmp_path.iterdir())


# ---- path --------------------------------------------------------------------------------------
def test_path_window_shows_three_orbits_of_the_square(square):
    """Three orbits of Fig. 12a: the heading of the path, read off its own velocity, turns by
    three full turns (clockwise) within the window, and theta has 12 cycles there."""
    a = square.attrs
    window = orbit_window(a, 20.0)
    drawn = square.sel(time=slice(0.0, window))
    vx, vy = np.gradient(drawn.x.values), np.gradient(drawn.y.values)
    turned = np.degrees(np.unwrap(np.arctan2(vy, vx)))
    assert turned[-1] - turned[0] == pytest.approx(-3 * 360.0, abs=30.0)
    th = drawn.theta_deg.values
    minima = np.flatnonzero((th[1:-1] < th[:-2]) & (th[1:-1] <= th[2:]))
    assert len(minima) in (11, 12)  # plus the start, a minimum too: 12 or 13 corners
    assert window < 8.0


def test_path_marks_every_corner_and_says_what_the_marks_are(square):
    drawn = square.sel(time=slice(0.0, orbit_window(square.attrs, 20.0)))
    drawn.attrs = square.attrs
    fig = path_figure(drawn)
    ax = fig.axes[0]
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    corners = lines[r"corner ($\theta$ minimum)"]
    assert "start" in lines
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert r"corner ($\theta$ minimum)" in legend and "start" in legend
    # the square's four corners, each visited three times (the path drifts < 1 mm an orbit)
    pts = np.stack([corners.get_xdata(), corners.get_ydata()], 1)
    distinct = []
    for p in pts:
        if all(np.hypot(*(p - q)) > 5e-3 for q in distinct):
            distinct.append(p)
    assert len(distinct) == 4
    # each mark is where theta is lowest: theta there is theta0 = -5 deg
    ci = [int(np.argmin(np.hypot(drawn.x.values - px, drawn.y.values - py))) for px, py in pts]
    assert np.allclose(drawn.theta_deg.values[ci], -5.0, atol=0.05)


def test_path_rates_show_spikes_and_ordinary_motion(square):
    fig = path_figure(square.sel(time=slice(0.0, 3.0)).assign_attrs(square.attrs))
    rates = fig.axes[3]  # path, its colour bar, theta, rates, friction, normal force
    assert rates.get_yscale() == "symlog"
    lo, hi = rates.get_ylim()
    # the spin spikes near the vertical (~150 rad/s) and the launch rates (~3-4 rad/s) both
    # inside the axis, the small ones in its linear part
    assert hi > 100 and lo < -2.5
    assert rates.get_yaxis().get_transform().linthresh == pytest.approx(10.0)


def test_path_line_says_what_was_drawn_and_no_turn_where_there_is_none(tmp_path, capsys):
    def said(*launch):
        assert cli.main(["path", *launch, "--panels", "path", "-o", str(tmp_path / "p.png")]) == 0
        return capsys.readouterr().out

    # Fig. 7 turns -2.9 deg a cycle: 36 cycles are a quarter of an orbit, not three orbits
    line = said("--theta0-deg", "-5", "--chidot0", "23", "--phidot0", "-3", "--chi0-deg", "190")
    turn = float(line.split("turn per cycle ")[1].split(" deg")[0])
    cycles = float(line.split(" s (")[1].split(" theta cycles")[0])
    orbits = float(line.split("theta cycles, ")[1].split(" of an orbit")[0])
    assert cycles == 36 and orbits == pytest.approx(cycles * abs(turn) / 360.0, abs=0.005)
    assert "three orbits" not in line
    # a steady circle (theta stays at 24 deg) has no theta cycle to turn per
    line = said("--theta0-deg", "24", "--chidot0", "-3.23", "--phidot0", "-10.2126")
    assert "steady" in line and "turn per cycle -" not in line and "theta 24.00..24.00" in line
    # a run too short for one cycle: said in words, not as nan
    line = said("--theta0-deg", "-5", "--chidot0", "4.05", "--phidot0", "-3", "--T", "0.1")
    assert "nan" not in line and "no turn per cycle (too few theta cycles in 0.1 s)" in line


def test_path_command_prints_the_star_with_its_p_q(tmp_path, capsys):
    out = tmp_path / "star.pdf"
    assert cli.main(["path", "--theta0-deg", "-8", "--chidot0", "-2", "--phidot0", "0", "--T",
                     "8", "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert said.startswith("star {")
    p, q = (int(v) for v in said[len("star {"):said.index("}")].split("/"))
    turn = float(said.split("turn per cycle ")[1].split(" deg")[0])
    # a star {p/q} would close after p cycles and q turns (p |turn| = q 360 deg): p/q is the
    # fraction with at most 12 points nearest 360 / |turn| (this pentagram drifts 22 deg a circuit)
    n = 360.0 / abs(turn)
    best = min((abs(a / b - n), a, b) for a in range(2, 13) for b in range(2, a)
               if math.gcd(a, b) == 1)
    assert (p, q) == best[1:] == (5, 2)
    assert out.read_bytes().startswith(b"%PDF")


@pytest.mark.parametrize("fields,text", [
    ({"label": "star", "star_points": 5, "star_step": 2, "n_sides": 2.5, "corner_kind": "cusp"},
     "star {5/2}, n = 2.500, cusped corners"),
    ({"label": "circle", "n_sides": 3.9, "corner_kind": "none"}, "circle"),
    ({"label": "rosette", "n_sides": 4.0, "corner_kind": "cusp"}, "rosette, n = 4.000"),
    ({"label": "near_straight", "n_sides": math.nan, "corner_kind": "rounded"}, "near straight"),
    ({"label": "square", "n_sides": 3.998, "corner_kind": "rounded"},
     "square, n = 3.998, rounded corners"),
    ({"label": "lift_off", "n_sides": 3.0, "corner_kind": "loop"}, "lift off"),
])
def test_shape_words_name_corners_only_where_there_are_corners(fields, text):
    assert shape_text(fields) == text


# ---- query -------------------------------------------------------------------------------------
def test_query_all_lists_every_match(small_map, capsys):
    ds = ballsurvey.open_map(small_map)
    codes = ds.label.values
    word = LABELS[int(np.bincount(codes[codes >= 0].ravel()).argmax())]
    n = int((codes == CODE[word]).sum())
    assert n > 20  # more than the default page
    assert cli.main(["query", str(small_map), "--shape", word, "--all", "--format",
                     "json"]) == 0
    captured = capsys.readouterr()
    assert len(json.loads(captured.out)["launches"]) == n
    assert "more matched" not in captured.err
    assert cli.main(["query", str(small_map), "--shape", word]) == 0
    assert f"... {n - 20} more matched (--limit N or --all" in capsys.readouterr().err
    assert cli.main(["query", str(small_map), "--shape", word, "--all", "--limit", "3"]) == 2


def test_query_gives_each_star_its_p_q(small_map, tmp_path):
    # the pentagram launch and two stars beside it (theta0 -8 deg, phidot0 0: cusped points)
    spec = {"launch": {"theta0_deg": -8.0, "thetadot0": 0.0,
                       "chidot0": {"start": -2.2, "stop": -1.8, "num": 3}, "phidot0": 0.0},
            "run": {"T": 4.0, "dt": 5e-4}}
    ds = ballsurvey.sweep(spec, output=tmp_path / "stars.nc", progress=False,
                          notice=lambda msg: None)
    df = ballsurvey.query(ds, shape="star")
    assert len(df) == int((ds.label.values == CODE["star"]).sum()) > 0
    for pq, n in zip(df.star, df.n_sides):
        p, q = (int(v) for v in pq.strip("{}").split("/"))
        # n_sides = 360/|turn| and a star {p/q} turns q/p of 360 deg a cycle: p/q is the
        # fraction nearest n_sides with p <= 12 points (max_star_points)
        best = min(abs(a / b - n) for a in range(2, 13) for b in range(2, a) if math.gcd(a, b) == 1)
        assert abs(p / q - n) == pytest.approx(best, abs=1e-12) and math.gcd(p, q) == 1
    assert "star" not in ballsurvey.query(ballsurvey.open_map(small_map),
                                          shape="circle").columns


# ---- compiling ---------------------------------------------------------------------------------
@pytest.mark.parametrize("command", ["path", "find", "gallery", "refine"])
def test_every_command_that_compiles_says_so(command, monkeypatch, capsys):
    import numba

    def compiles(args):
        numba.njit(lambda v: v * 2.0 + len(command))(1.0)  # a new function: a compilation

    monkeypatch.setattr(cli, f"_cmd_{command}", compiles)
    argv = {"path": ["path", "--theta0-deg", "0", "--chidot0", "1", "--phidot0", "1"],
            "find": ["find", "--shape", "square"], "gallery": ["gallery", "x.nc"],
            "refine": ["refine"]}[command]
    assert cli.main(argv) == 0
    err = capsys.readouterr().err
    assert err.count(f"ballsurvey {command}: compiling numba kernels") == 1


def test_help_lists_commands_in_the_order_of_use(capsys):
    assert cli.main(["--help"]) == 0
    text = capsys.readouterr().out
    listed = [ln.split()[0] for ln in text.split("COMMAND\n", 2)[-1].splitlines()
              if ln.startswith("    ") and not ln.startswith("     ")]
    assert listed[:5] == ["path", "sweep", "plot", "query", "find"]
    assert listed[-1] == "bench"


# ---- simulate ----------------------------------------------------------------------------------
def test_simulate_angles_in_degrees_and_clean_times(square):
    assert square.theta_deg.attrs["units"] == "degree"
    assert square.theta_deg.values[0] == pytest.approx(-5.0, abs=1e-12)
    assert square.chi_deg.values[0] == 0.0
    assert square.theta_deg.values.max() == pytest.approx(square.attrs["theta_max_deg"],
                                                          abs=0.05)
    t = square.time.values
    assert t[1] == 0.0025 and t[3] == 0.0075 and t[-1] == 20.0
    assert repr(float(t[7])) == "0.0175"


def test_simulate_friction_and_normal_force_obey_newton_on_the_path():
    """N = M (g + z''), F_h = M (x'', y''), with z = a - c sin(theta) (Eq. 9): second
    differences of the integrated path itself, independent of the contact-force formulas."""
    ball = Ball.paper()
    ds = ballsurvey.simulate(20.0, 0.0, 10.0, -2.9, T=1.0, n_out=20001)  # Fig. 9a, dt 5e-5 s
    t = ds.time.values
    h = t[1] - t[0]
    z = ball.a - ball.c * np.sin(ds.theta.values)

    def dd(v):
        return (v[2:] - 2 * v[1:-1] + v[:-2]) / h**2

    normal = ball.M * (ball.g + dd(z))
    friction = ball.M * np.hypot(dd(ds.x.values), dd(ds.y.values))
    assert np.allclose(ds.normal_force.values[1:-1], normal, rtol=1e-4)
    assert np.allclose(ds.friction_ratio.values[1:-1], friction / normal, rtol=1e-3, atol=1e-6)
    assert ds.normal_force.attrs["units"] == "N" and ds.friction_ratio.attrs["units"] == "1"


# ---- pandas ------------------------------------------------------------------------------------
def test_to_dataframe_decodes_every_coded_variable(small_map):
    ds = ballsurvey.open_map(small_map)
    words = ds.ballsurvey.to_dataframe()
    codes = ds.to_dataframe()
    for name in ("label", "corner_kind", "formulation"):
        meanings = ds[name].attrs["flag_meanings"].split()
        values = list(ds[name].attrs["flag_values"])
        assert str(words[name].dtype) == "category"
        assert list(words[name].cat.categories) == meanings
        want = [meanings[values.index(int(c))] for c in codes[name]]
        assert list(words[name].astype(str)) == want


def test_labels_is_a_property_as_the_docs_write_it(small_map):
    from pathlib import Path

    ds = ballsurvey.open_map(small_map)
    words = ds.ballsurvey.labels
    assert words.dims == ds.label.dims
    assert (words.values == np.array(LABELS, dtype=object)[ds.label.values]).all()
    root = Path(__file__).resolve().parents[1]
    for doc in [root / "README.md", *sorted((root / "docs").glob("*.md"))]:
        assert "ballsurvey.labels()" not in doc.read_text(), doc.name


def test_a_reader_that_leaves_early_is_no_error(small_map):
    """`ballsurvey query MAP ... | head -1`: the reader closes the pipe; no error line, exit 0."""
    import subprocess
    import sys

    p = subprocess.Popen([sys.executable, "-m", "ballsurvey", "query", str(small_map),
                          "--shape", "circle", "--all", "--format", "csv"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()  # before it writes anything
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) == 0 and err == "", err


# Machado, Oliveira and Fernandes (2009), full severity: linear-RGB simulation of each
# colour-vision deficiency
_CVD = {
    "protanopia": [[0.152286, 1.052583, -0.204868], [0.114503, 0.786281, 0.099216],
                   [-0.003882, -0.048116, 1.051998]],
    "deuteranopia": [[0.367322, 0.860646, -0.227968], [0.280085, 0.672501, 0.047413],
                     [-0.011820, 0.042940, 0.968881]],
    "tritanopia": [[1.255528, -0.076749, -0.178779], [-0.078411, 0.930809, 0.147602],
                   [0.004733, 0.691367, 0.303900]],
    "normal vision": np.eye(3).tolist(),
}


def _cielab(linear_rgb):
    xyz = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722],
                    [0.0193, 0.1192, 0.9505]]) @ np.clip(linear_rgb, 0, 1)
    t = xyz / np.array([0.95047, 1.0, 1.08883])
    f = np.where(t > (6 / 29) ** 3, np.cbrt(t), t / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


@pytest.mark.parametrize("vision", sorted(_CVD))
def test_map_colours_stay_apart_for_colour_blind_readers(vision):
    """Every two shape colours of a map differ by at least 10 (CIELAB Delta E) as seen with each
    full colour-vision deficiency: told apart without the legend's words."""
    from ballsurvey.classify.labels import SHAPES
    from ballsurvey.plot import LABEL_COLOURS

    def seen(hex_colour):
        c = np.array([int(hex_colour[i:i + 2], 16) / 255 for i in (1, 3, 5)])
        linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
        return _cielab(np.array(_CVD[vision]) @ linear)

    lab = {w: seen(LABEL_COLOURS[w]) for w in SHAPES}
    gaps = {(a, b): float(np.linalg.norm(lab[a] - lab[b]))
            for i, a in enumerate(SHAPES) for b in SHAPES[i + 1:]}
    assert min(gaps.values()) >= 10.0, min(gaps.items(), key=lambda kv: kv[1])

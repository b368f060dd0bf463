"""`fit` at a lab bench: tracks as Tracker and spreadsheets export them, and fits that say how
far to trust them (status ok / ambiguous / mismatch / failed). Every track is made by another
code path than the fit's model: scipy's solve_ivp on the fixed-frame Newton-Euler form
(`ballsurvey.synthetic`), or plain geometry."""
import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

from ballsurvey.cli import main
from ballsurvey.fit import (
    PARAMS,
    _covariance,
    fit_track,
    make_track,
    noise_estimate,
    plot_fit,
    read_track,
    residual_tests,
)
from ballsurvey.synthetic import fixed_frame_states, synthetic_track

ROOT = Path(__file__).resolve().parents[1]


def _module(name):
    spec = importlib.util.spec_from_file_location(name, ROOT / "examples" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _square(fps=30, T=1.0, noise=2e-4, seed=1):
    return synthetic_track(-5.0, 0.0, 4.05, -3.0, T=T, fps=fps, noise_m=noise, seed=seed)


# --- reading ------------------------------------------------------------------------------

def test_a_tracker_export_reads_as_it_comes_in_every_layout(tmp_path, ball):
    tr = _square()
    lost = {5, 6, 20}
    rows = ["\t".join([f"{t:.4f}"] + (["", ""] if i in lost else [f"{x * 100:.5f}",
                                                                  f"{y * 100:.5f}"]))
            for i, (t, x, y) in enumerate(zip(tr["t"], tr["x"], tr["y"]))]
    (tmp_path / "tracker.txt").write_text("mass A\nt\tx\ty\n" + "\n".join(rows) + "\n")
    got = read_track(tmp_path / "tracker.txt", units="cm")
    keep = np.array([i not in lost for i in range(tr["t"].size)])
    assert np.allclose(got.x, tr["x"][keep], atol=1e-7) and np.allclose(got.y, tr["y"][keep],
                                                                         atol=1e-7)
    assert np.allclose(got.dropped_t, tr["t"][sorted(lost)], atol=1e-4)
    # semicolons, decimal commas, units in the header (t in ms, x and y in mm), NaN cells
    rows = [";".join([f"{t * 1000:.2f}"] + (["NaN", "NaN"] if i in lost else
                                           [f"{x * 1000:.4f}", f"{y * 1000:.4f}"]))
            .replace(".", ",") for i, (t, x, y) in enumerate(zip(tr["t"], tr["x"], tr["y"]))]
    (tmp_path / "semi.csv").write_text("t (ms);x (mm);y (mm)\n" + "\n".join(rows) + "\n")
    again = read_track(tmp_path / "semi.csv")
    # to the two files' last digits: t 5e-5 s, x 1e-7 m in each
    assert np.allclose(again.t, got.t, atol=6e-5) and np.allclose(again.x, got.x, atol=2e-7)
    assert again.dropped_t.size == 3
    # two tracked masses named for the probe's tip and base, each with its own t column
    pr = synthetic_track(-5.0, 0.0, 4.05, -3.0, T=1.0, fps=30, probe_m=0.03)
    rows = ["\t".join(f"{v:.6f}" for v in (t, xt, yt, t, xb, yb)) for t, xt, yt, xb, yb in
            zip(pr["t"], pr["x_tip"], pr["y_tip"], pr["x_base"], pr["y_base"])]
    (tmp_path / "probe.txt").write_text("probe tip\t\t\tprobe base\t\t\nt\tx\ty\tt\tx\ty\n"
                                        + "\n".join(rows) + "\n")
    probe = read_track(tmp_path / "probe.txt", probe_m=0.03)
    assert np.allclose(probe.x_tip, pr["x_tip"], atol=1e-6)
    assert np.allclose(probe.y_base, pr["y_base"], atol=1e-6)


@pytest.mark.parametrize("text, args, words", [
    ("t\tx (cm)\ty (cm)\n", ["--units", "mm"], "the header says cm and --units says mm"),
    ("t,x (in),y (in)\n", [], "unit 'in' in the header"),
    ("mass A\t\t\tmass B\t\t\nt\tx\ty\tt\tx\ty\n", [], "name the probe's two 'tip' and 'base'"),
    ("t,x,y\n0,1,abc\n", [], "'abc' is not a number"),
    ("t,x,y\n", ["--units", "km"], "invalid choice"),
])
def test_a_file_the_reader_cannot_take_is_one_line_quoting_its_columns(tmp_path, capsys, text,
                                                                       args, words):
    body = "".join(f"{i / 30:.4f}{text[1] if text[1] in ',;' else chr(9)}{i * 1e-3:.4f}"
                   f"{text[1] if text[1] in ',;' else chr(9)}0\n" for i in range(30))
    sep_ok = "abc" not in text and "mass B" not in text
    path = tmp_path / "bad.txt"
    path.write_text(text + (body if sep_ok else ""))
    assert main(["fit", str(path), *args]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1, err


def test_a_track_far_from_the_origin_is_fitted_relative_to_its_first_sample(tmp_path, capsys):
    """1e12 m away the fit is the fit of the same samples at the origin (float64 holds them
    there to 0.12 mm: the near track is the far one moved back, exactly); 1e20 m away, where it
    holds them to 16 km, one line."""
    tr = synthetic_track(-5.0, 0.0, 4.05, -3.0, T=2.0, fps=30, noise_m=2e-4, seed=4)
    fx, fy = tr["x"] + 1e12, tr["y"] - 1e12
    far = fit_track(make_track(tr["t"], fx, fy))
    near = fit_track(make_track(tr["t"], fx - 1e12, fy + 1e12))
    assert near["status"] == far["status"] == "ok"
    truth = dict(theta0_deg=-5.0, thetadot0=0.0, chidot0=4.05, phidot0=-3.0, chi0_deg=0.0,
                 x0=1e12, y0=-1e12)
    for k in PARAMS:
        shift = {"x0": 1e12, "y0": -1e12}.get(k, 0.0)
        # x0, y0 near 1e12 m are themselves held to float64's spacing there
        assert abs((far[k] - shift) - near[k]) < 0.01 * near[k + "_err"] + np.spacing(
            abs(shift)), k
        assert abs(far[k + "_err"] / near[k + "_err"] - 1) < 0.01, k
        assert abs(far[k] - truth[k]) < 3 * far[k + "_err"], k
    path = tmp_path / "far.csv"
    path.write_text("t,x,y\n" + "".join(f"{t},{x + 1e20},{y}\n"
                                        for t, x, y in zip(tr["t"], tr["x"], tr["y"])))
    assert main(["fit", str(path)]) == 2
    err = capsys.readouterr().err
    assert "subtract an origin" in err and err.count("\n") == 1


# --- the fit's judgement ------------------------------------------------------------------

def test_the_shipped_tracker_example_fits_back_through_the_command_line(tmp_path, capsys, ball):
    """examples/track-tracker.txt is what examples/make_tracker_export.py writes (the paper's
    triangle in Tracker's layout: name line, tabs, cm, three lost frames), and `fit` finds its
    launch within 3 sigma, the lost frames by their t, and the heading G starts in, judged by
    the fixed-frame integration's own first step."""
    mod = _module("make_tracker_export")
    again = mod.main(tmp_path / "t.txt")
    shipped = ROOT / "examples" / "track-tracker.txt"
    assert again.read_text().splitlines()[:2] == shipped.read_text().splitlines()[:2]
    a = np.genfromtxt(again, delimiter="\t", skip_header=2)
    b = np.genfromtxt(shipped, delimiter="\t", skip_header=2)
    assert a.shape == b.shape and np.allclose(a, b, atol=2e-4, equal_nan=True)
    assert main(["fit", str(shipped), "--units", "cm", "--format", "json"]) == 0
    fit = json.loads(capsys.readouterr().out)
    assert fit["status"] == "ok" and fit["label"] == "triangle"
    for k in PARAMS:
        assert abs(fit[k] - mod.LAUNCH[k]) < 3 * fit[k + "_err"], (k, fit[k], fit[k + "_err"])
    assert fit["n_dropped"] == 3
    assert np.allclose(fit["dropped_t"], [i / mod.FPS for i in mod.LOST], atol=1e-4)
    L = mod.LAUNCH
    g = fixed_frame_states(L["theta0_deg"], L["thetadot0"], L["chidot0"], L["phidot0"],
                           L["chi0_deg"], 0.0, 0.0, np.array([0.0, 1e-5]), ball)
    true_heading = math.degrees(math.atan2(g[1, 1] - g[0, 1], g[1, 0] - g[0, 0]))
    assert abs((fit["heading_deg"] - true_heading + 180) % 360 - 180) < \
        3 * fit["heading_deg_err"] + 0.05
    assert 0.5 * mod.NOISE_M < fit["noise_m"] < 1.5 * mod.NOISE_M


def test_the_steady_circle_and_its_twin_are_reported_ambiguous():
    """The paper's steady circle (Fig. 4) at 30 frames/s has a twin steady circle at theta0 about
    -14 deg on the same path: the fit gives both, the launch that made the track among them."""
    tr = synthetic_track(24.0, 0.0, -3.23, -10.2126, T=3.0, fps=30, noise_m=2e-4, seed=3)
    fit = fit_track(make_track(tr["t"], tr["x"], tr["y"]))
    assert fit["status"] == "ambiguous", fit
    launches = [fit] + fit["alternatives"]
    thetas = sorted(f["theta0_deg"] for f in launches)
    assert any(abs(th - 24.0) < 0.5 for th in thetas), thetas
    assert any(abs(th + 14.2) < 1.0 for th in thetas), thetas
    for alt in fit["alternatives"]:
        assert alt["rms_m"] < 1.1 * fit["rms_m"] and alt["label"] == "circle"
        assert set(PARAMS) <= set(alt)


def test_a_ball_that_slows_is_a_mismatch_with_its_evidence():
    """A square whose ball loses 3 % of its speed a second (the fixed-frame integration played
    back slower and slower): no launch of the rolling model explains it."""
    from scipy.interpolate import CubicSpline

    dense = synthetic_track(-5.0, 0.0, 4.05, -3.0, T=3.0, fps=600)
    t = np.arange(901) / 300
    warp = t - 0.015 * t**2
    rng = np.random.default_rng(2)
    x = CubicSpline(dense["t"], dense["x"])(warp) + rng.normal(0, 2e-4, t.size)
    y = CubicSpline(dense["t"], dense["y"])(warp) + rng.normal(0, 2e-4, t.size)
    fit = fit_track(make_track(t, x, y))
    assert fit["status"] == "mismatch", fit
    ev = fit["evidence"]
    assert ev["rms_over_noise_z"] > 3 or ev["runs_z"] < -4
    assert ev["runs_z"] < -4 and ev["autocorrelation"] > 0.5
    assert any("lower bound" in n for n in fit["notes"])


def test_a_track_no_rolling_launch_makes_is_a_failed_fit():
    """A straight line at 0.82 m/s, a plausible track on a table: the best launch misses it or
    leaves the model, and the fit says so (exit 0, status failed, reasons)."""
    t = np.arange(91) / 30
    rng = np.random.default_rng(5)
    fit = fit_track(make_track(t, 0.82 * t + rng.normal(0, 2e-4, t.size),
                               rng.normal(0, 2e-4, t.size)))
    assert fit["status"] == "failed" and fit["reasons"], fit


# --- the pieces ---------------------------------------------------------------------------

def test_noise_estimate_reads_the_tracking_noise_off_a_smooth_path():
    tr = _square(fps=30, T=3.0, noise=0.0)
    rng = np.random.default_rng(0)
    for sd in (2e-4, 1e-3):
        noisy = make_track(tr["t"], tr["x"] + rng.normal(0, sd, tr["t"].size),
                           tr["y"] + rng.normal(0, sd, tr["t"].size))
        est, n = noise_estimate(noisy)
        # its spread is 1.55 / sqrt(n) of the noise
        assert abs(est / sd - 1) < 4 * 1.55 / math.sqrt(n), (sd, est)


def test_residual_tests_tell_white_noise_from_structure():
    rng = np.random.default_rng(1)
    white = residual_tests({"x": rng.normal(size=900), "y": rng.normal(size=900)})
    assert abs(white["runs_z"]) < 4 and abs(white["autocorrelation_z"]) < 4
    t = np.arange(900) / 300
    wave = residual_tests({"x": np.sin(3 * t) + 0.3 * rng.normal(size=900),
                           "y": np.cos(3 * t) + 0.3 * rng.normal(size=900)})
    assert wave["runs_z"] < -10 and wave["autocorrelation"] > 0.8


def test_covariance_keeps_a_direction_the_data_barely_fix_wide():
    """Two nearly equal columns: their difference is barely fixed, so their sigmas are large
    (a pseudo-inverse that drops the direction would give them a tiny sigma instead), and no
    sigma lies below the one-parameter floor sqrt(s2) / |J_k|."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=200)
    J = np.column_stack([a, a * (1 + 1e-9) + 1e-9 * rng.normal(size=200), rng.normal(size=200)])
    cov, cond, floor = _covariance(J, 1.0)
    err = np.sqrt(np.diag(cov))
    assert cond > 1e8
    assert err[0] > 1e3 * floor[0] and err[1] > 1e3 * floor[1]
    assert np.all(err >= 0.999 * floor)
    assert abs(err[2] - floor[2]) < 0.2 * floor[2]


def test_the_plot_draws_the_model_dense_the_dropped_frames_and_the_alternatives(ball):
    tr = _square(fps=30, T=1.0)
    keep = np.ones(tr["t"].size, bool)
    keep[[8, 9]] = False
    x = np.where(keep, tr["x"], np.nan)
    track = make_track(tr["t"], x, tr["y"], drop_missing=True)
    launch = dict(theta0_deg=-5.0, thetadot0=0.0, chidot0=4.05, phidot0=-3.0, chi0_deg=0.0,
                  x0=0.0, y0=0.0)
    fit = {**launch, "label": "square", "status": "ambiguous", "rms_m": 2e-4,
           "alternatives": [{**launch, "theta0_deg": -4.0}]}
    fig = plot_fit(track, fit, ball=ball)
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    assert lines["fit: centre of mass"].get_xdata().size > 3 * track.t.size
    assert lines["dropped frames (model)"].get_xdata().size == 2
    assert "also fits: centre of mass" in lines


def test_a_sigma_wider_than_a_tenth_of_the_box_says_the_track_does_not_fix_the_launch():
    from ballsurvey.fit import BOX, _undetermined

    tight = np.array([0.05, 0.02, 0.01, 0.01, 0.2, 1e-4, 1e-4])
    assert _undetermined(tight, None) == {}
    # the near-straight fit at 30 frames/s that missed the launch by 17 sigma in chidot0
    loose = np.array([20.0, 5.3, 2.9, 9.9, 100.0, 3e-4, 3e-4])
    assert set(_undetermined(loose, None)) == {"theta0_deg", "thetadot0", "phidot0", "chi0_deg"}
    span = BOX["chidot0"][1] - BOX["chidot0"][0]
    edge = tight.copy()
    edge[2] = 0.1 * span * 1.01
    assert set(_undetermined(edge, None)) == {"chidot0"}

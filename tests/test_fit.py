"""`fit` / `fit_track`: launches recovered from synthetic tracks made by another model than the
fit's (scipy's solve_ivp on the fixed-frame Newton-Euler form; the fit integrates the Euler-angle
form on the ensemble kernel), and bad tracks refused in one line."""
import json

import numpy as np
import pandas as pd
import pytest

from ballsurvey.cli import main
from ballsurvey.fit import PARAMS, fit_track
from ballsurvey.synthetic import synthetic_track

FIG9A = dict(theta0_deg=20.0, thetadot0=0.0, chidot0=10.0, phidot0=-2.9, chi0_deg=30.0,
             x0=0.01, y0=-0.02)


def _write(path, cols):
    pd.DataFrame(cols).to_csv(path, index=False)
    return str(path)


def test_fit_cli_json_recovers_a_circle_launch_from_a_noisy_fixed_frame_track(tmp_path, capsys):
    launch = dict(FIG9A)
    tr = synthetic_track(**{k: launch[k] for k in PARAMS[:4]}, chi0_deg=launch["chi0_deg"],
                         x0=launch["x0"], y0=launch["y0"], T=2.0, fps=300, noise_m=2e-4, seed=1)
    path = _write(tmp_path / "track.csv", {k: tr[k] for k in ("t", "x", "y")})
    assert main(["fit", path, "--format", "json"]) == 0
    fit = json.loads(capsys.readouterr().out)
    # the keys a script reads come first, in order; status says how far to trust them
    assert list(fit)[:16] == [k for p in PARAMS for k in (p, p + "_err")] + ["rms_m", "label"]
    assert fit["status"] == "ok", fit
    # the residual is the noise put in (0.2 mm a coordinate), not a wrong basin
    assert 1.8e-4 < fit["rms_m"] < 2.2e-4
    # within 4 of its own standard deviations, and those are small
    tol = {"theta0_deg": 0.2, "thetadot0": 0.2, "chidot0": 0.02, "phidot0": 0.02,
           "chi0_deg": 2.0, "x0": 2e-4, "y0": 2e-4}
    for k in PARAMS:
        assert abs(fit[k] - launch[k]) < 4 * fit[k + "_err"] + 1e-12, k
        assert fit[k + "_err"] < tol[k] / 4, k
    assert fit["label"] == "circle"


def test_fit_of_a_probe_track_with_theta_and_chidot_recovers_the_square(ball):
    # the paper's Fig. 12a square, tracked as the paper did: probe tip and base, theta, chidot
    tr = synthetic_track(-5.0, 0.0, 4.05, -3.0, T=1.5, fps=300, noise_m=3e-4,
                         noise_theta_deg=0.3, noise_chidot=0.3, probe_m=0.03, seed=2)
    fit = fit_track(pd.DataFrame(tr), ball, probe_m=0.03)  # columns by name
    truth = dict(theta0_deg=-5.0, thetadot0=0.0, chidot0=4.05, phidot0=-3.0, chi0_deg=0.0,
                 x0=0.0, y0=0.0)
    for k in PARAMS:
        assert abs(fit[k] - truth[k]) < 4 * fit[k + "_err"], k
    assert abs(fit["chidot0"] - 4.05) < 0.01 and abs(fit["phidot0"] + 3.0) < 0.01
    assert fit["label"] == "square"


def _good(n=300, fps=300.0):
    t = np.arange(n) / fps
    return {"t": t, "x": 0.2 * t, "y": 0.01 * np.sin(t)}


@pytest.mark.parametrize("change, words", [
    (lambda d: {k: v[:10] for k, v in d.items()}, "too short"),
    (lambda d: {k: np.where(np.arange(d["t"].size) < 285, np.nan, v) if k == "x" else v
                for k, v in d.items()}, "285 rows with a blank or non-finite cell dropped"),
    (lambda d: {**d, "t": d["t"][[0, 1, 2, 4, 3] + list(range(5, d["t"].size))]},
     "t must increase"),
    (lambda d: {**d, "x": d["x"] * 1000, "y": d["y"] * 1000}, "are they in mm or cm?"),
    (lambda d: {**d, "t": d["t"] * 1000}, "is t in ms?"),
    (lambda d: {"t": d["t"], "x": d["x"]}, "give both x and y"),
    (lambda d: {**d, "theta_deg": np.full(d["t"].size, 120.0)}, "theta_deg must stay within"),
    (lambda d: {"t": d["t"], "x_tip": d["x"], "y_tip": d["y"], "x_base": d["x"],
                "y_base": d["y"]}, "--probe-m"),
])
def test_bad_tracks_are_one_line_exit_2_before_any_work(tmp_path, capsys, change, words):
    path = _write(tmp_path / "bad.csv", change(_good()))
    assert main(["fit", path]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1, err


def test_a_missing_file_and_a_file_without_t_are_one_line(tmp_path, capsys):
    assert main(["fit", str(tmp_path / "none.csv")]) == 2
    (tmp_path / "no_t.csv").write_text("frame,x,y\n0,0,0\n")
    assert main(["fit", str(tmp_path / "no_t.csv")]) == 2
    # a tab-separated header is quoted cell by cell, so a tab never reads as a found 't'
    (tmp_path / "tabs.txt").write_text("mass A\nframe\tx\ty\n0\t0\t0\n")
    assert main(["fit", str(tmp_path / "tabs.txt")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 3 and "no such file" in err[0]
    assert "column t" in err[1] and "found columns 'frame', 'x', 'y'" in err[1]
    assert "found columns 'frame', 'x', 'y'" in err[2]


def test_the_shipped_example_track_is_reproducible_and_fits_back_to_its_launch(tmp_path):
    """examples/track-square.csv (the README's `fit` example) is what examples/make_track.py
    writes (the paper's square at 30 frames/s, 0.2 mm noise), and the fit finds that launch
    again: every parameter within 3 of its stated standard deviations, a square, and a residual
    about the noise."""
    import importlib.util
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("make_track", root / "examples" / "make_track.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    again = mod.main(tmp_path / "track.csv")
    shipped = root / "examples" / "track-square.csv"
    # to the file's last digit (1 um), allowing a libm's last bit at a rounding edge
    a = np.loadtxt(again, delimiter=",", skiprows=1)
    b = np.loadtxt(shipped, delimiter=",", skiprows=1)
    assert a.shape == b.shape and np.allclose(a, b, rtol=0.0, atol=2e-6)
    fit = fit_track(str(shipped))
    truth = {"theta0_deg": -5.0, "thetadot0": 0.0, "chidot0": 4.05, "phidot0": -3.0,
             "chi0_deg": 0.0, "x0": 0.0, "y0": 0.0}
    for k, v in truth.items():
        assert abs(fit[k] - v) < 3 * fit[f"{k}_err"], (k, fit[k], fit[f"{k}_err"])
    assert fit["label"] == "square"
    assert 0.5 * mod.NOISE_M < fit["rms_m"] < 1.5 * mod.NOISE_M


def test_fit_names_the_rows_it_dropped_timed_or_not(tmp_path, capsys):
    # a lost frame: its x infinite (dropped at its time) or its t blank (no time to name): the
    # summary said "(t =  s)" for the second
    launch = dict(FIG9A)
    tr = synthetic_track(**{k: launch[k] for k in PARAMS[:4]}, chi0_deg=launch["chi0_deg"],
                         x0=launch["x0"], y0=launch["y0"], T=2.0, fps=300, noise_m=2e-4, seed=1)
    cols = {k: np.array(tr[k], dtype=float) for k in ("t", "x", "y")}
    t_bad = cols["t"][100]
    cols["x"][100] = np.inf
    cols["t"][200] = np.nan
    assert main(["fit", _write(tmp_path / "track.csv", cols)]) == 0
    out = capsys.readouterr().out
    assert (f"dropped     2 rows with a blank or non-finite cell (at t = {t_bad:g} s; 1 with "
            "no time)") in out, out

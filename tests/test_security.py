"""Outside input: a shared map, spec or track is refused in one line (exit 2) before any work
when a spec could not hold it; text from it never runs as script in a page (test_explore's
browser tests hold the pages); the explorer answers only its own host. docs/reliability.md,
"Security", lists each promise with its test."""
import shutil
import subprocess
import sys

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

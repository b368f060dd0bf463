"""The Python way in (sweep from a dict, TOML text or path; open_map; label words; query as a
DataFrame), units of work (bit-identical whatever the chunking), Ctrl-C (saves finished units,
exit 130, --resume gives the same file), and the command line's misuse messages."""
import json
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import ballsurvey
from ballsurvey.cli import main
from ballsurvey.sweep import load_spec, run_sweep
from ballsurvey.sweep.compute import compute_chunk, compute_launches
from ballsurvey.sweep.engine import parts_dir

ROOT = Path(__file__).resolve().parents[1]

SPEC = {"title": "api", "launch": {"theta0_deg": [-10.0, 0.0, 20.0], "thetadot0": 0.0,
                                   "chidot0": [2.3, 3.0, 4.05], "phidot0": [-3.0, -2.5]},
        "run": {"T": 3.0, "dt": 5e-4}}


@pytest.fixture(scope="module")
def mem_map():
    return ballsurvey.sweep(SPEC, progress=False, notice=lambda m: None)


def same(a, b):
    assert set(a.data_vars) == set(b.data_vars)
    for v in a.data_vars:
        assert np.array_equal(a[v].values, b[v].values, equal_nan=True), v


def test_sweep_from_a_dict_text_or_path_is_the_same_map(mem_map, tmp_path):
    assert isinstance(mem_map, xr.Dataset) and mem_map.label.shape == (3, 1, 3, 2)
    assert not list(Path.cwd().glob("results/api.nc"))  # nothing written: held in memory
    text = ballsurvey.api.spec_to_toml(SPEC)
    same(mem_map, ballsurvey.sweep(text, progress=False, notice=lambda m: None))
    p = tmp_path / "s.toml"
    p.write_text(text + f'\n[output]\nfile = "{tmp_path / "s.nc"}"\n')
    got = ballsurvey.sweep(p, progress=False, notice=lambda m: None)
    assert (tmp_path / "s.nc").exists()  # written as the spec says
    same(mem_map, got)
    same(mem_map, ballsurvey.open_map(tmp_path / "s.nc"))
    same(mem_map, ballsurvey.sweep(str(p), progress=False))  # up to date: opened


def test_bad_specs_and_files_are_input_errors(tmp_path):
    with pytest.raises(ballsurvey.InputError, match="T: must be > 0"):
        ballsurvey.sweep({**SPEC, "run": {"T": 0.0}})
    with pytest.raises(ballsurvey.InputError, match="sweep spec, not a map"):
        ballsurvey.open_map(ROOT / "sweeps" / "quick.toml")
    (tmp_path / "x.nc").write_text("not netcdf")
    with pytest.raises(ballsurvey.InputError, match="not a netCDF file"):
        ballsurvey.open_map(tmp_path / "x.nc")


@pytest.mark.parametrize("call,words", [
    # from the review: each answered something (0 rows, a truncated n, a TypeError) before
    (lambda ds: ballsurvey.query(ds, n_sides=4.7), "n_sides: must be a whole number"),
    (lambda ds: ds.ballsurvey.mask(n_sides=4.7), "n_sides: must be a whole number"),
    (lambda ds: ballsurvey.query(ds, n_sides=float("nan")), "n_sides: must be finite"),
    (lambda ds: ballsurvey.query(ds, n_sides="4"), "n_sides: must be a number"),
    (lambda ds: ds.ballsurvey.mask(n_sides="x"), "n_sides: must be a number"),
    (lambda ds: ballsurvey.query(ds, shape="square", limit=-2), "limit: must be >= 1"),
    (lambda ds: ballsurvey.query(ds, shape="square", limit=0), "limit: must be >= 1"),
    (lambda ds: ballsurvey.query(ds, shape=["square", "triangle"]), "shape: one label word"),
    (lambda ds: ballsurvey.query(ds.drop_vars("n_sides"), n_sides=4), "does not hold 'n_sides'"),
    (lambda ds: ds.drop_vars("n_sides").ballsurvey.mask(n_sides=4), "does not hold 'n_sides'"),
    (lambda ds: ballsurvey.query(ds.drop_vars("closure_m"), shape="square", max_closure=1e-3),
     "does not hold 'closure_m'"),
    (lambda ds: ballsurvey.open_map(None), "a path to a .nc file"),
    (lambda ds: ds.ballsurvey.where(thetadot0=1e-7), "not the map's one value of thetadot0, 0.0"),
])
def test_questions_a_map_cannot_answer_are_one_line_input_errors(mem_map, call, words):
    with pytest.raises(ballsurvey.InputError) as exc:
        call(mem_map)
    assert words in str(exc.value) and "\n" not in str(exc.value), str(exc.value)


def test_frames_cut_from_a_query_format_as_they_are(mem_map):
    """query() names the columns common to every match; a frame a user cuts from it (fewer
    columns, no rows) formatted with KeyError and IndexError (review)."""
    from ballsurvey.query import format_table

    df = ballsurvey.query(mem_map, "square")
    assert len(df) >= 2
    assert "theta0_deg" in format_table(df[["theta0_deg", "label"]])
    assert json.loads(format_table(df[df.theta0_deg > 100], "json"))["launches"] == []


def test_numpy_scalars_and_0d_arrays_are_numbers(mem_map):
    n = len(ballsurvey.query(mem_map, n_sides=4))
    assert len(ballsurvey.query(mem_map, n_sides=np.array(4))) == n
    assert len(ballsurvey.query(mem_map, n_sides=np.int64(4), limit=np.array(1))) == min(n, 1)


def test_a_binary_file_as_a_spec_is_an_input_error(tmp_path):
    p = tmp_path / "m.toml"
    p.write_bytes(b"\x89HDF\r\n\x1a\n\x00\xff\xfe")
    with pytest.raises(ballsurvey.InputError, match="not a text file"):
        ballsurvey.sweep(p)


def test_label_words_accessor_and_cf_xarray(mem_map):
    cf_xarray = pytest.importorskip("cf_xarray")  # noqa: F841
    m = mem_map.ballsurvey.mask(shape="square")
    assert m.equals(mem_map.label.cf == "square")
    assert int(m.sum()) == int((mem_map.label == 3).sum()) > 0
    w = mem_map.ballsurvey.where(shape="square", phidot0=-3)
    assert set(np.unique(w.label.values)) <= {-1, 3} and "phidot0" not in w.dims
    assert (mem_map.ballsurvey.labels.values[m.values] == "square").all()
    assert mem_map.ballsurvey.counts().sum() == mem_map.label.size


def test_query_is_a_dataframe_without_units_in_its_names(mem_map):
    df = ballsurvey.query(mem_map, shape="square", phidot0=-3)
    assert list(df.columns[:5]) == ["theta0_deg", "thetadot0", "chidot0", "phidot0", "chi0_deg"]
    assert df.attrs["units"]["chidot0"] == "rad/s" and (df.phidot0 == -3).all()
    assert (df.label == "square").all() and list(df.n_sides_error) == sorted(df.n_sides_error)
    assert len(df) == int(mem_map.ballsurvey.mask(shape="square").sel(phidot0=-3).sum())
    with pytest.raises(ballsurvey.InputError, match="nearest values: -3, -2.5"):
        ballsurvey.query(mem_map, shape="square", phidot0=-3.3)
    assert len(ballsurvey.query(mem_map, shape="square", phidot0=-3.1)) == len(df)  # < half step


def test_example_answers_the_question():
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "square_at_phidot0.py"),
                        "--small"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert re.search(r"\d+ square launches at phidot0 = -3", r.stdout)
    assert "most exact" in r.stdout


def test_units_of_work_are_bit_identical_to_one_kernel_call(tmp_path):
    spec = load_spec("u", text=ballsurvey.api.spec_to_toml(SPEC))
    whole = compute_launches(spec, 0, spec.n_launches)
    seen = []
    for unit in (1, 5, 7, None):
        got = compute_chunk(spec.text, spec.source, 0, spec.n_launches, unit=unit,
                            on_unit=seen.append)
        for k in spec.variables:
            assert np.array_equal(whole[k], got[k], equal_nan=True), (unit, k)
    assert seen[:18] == [1] * 18 and sum(seen) == 4 * spec.n_launches
    # resuming a chunk from its first launches gives the same result
    first = {k: v[:4] for k, v in whole.items()}
    got = compute_chunk(spec.text, spec.source, 0, spec.n_launches, done=first)
    for k in spec.variables:
        assert np.array_equal(whole[k], got[k], equal_nan=True), k


def test_unit_size_carries_over_from_chunk_to_chunk_bit_identical(tmp_path):
    spec = load_spec("u", text=ballsurvey.api.spec_to_toml(SPEC))
    whole = compute_launches(spec, 0, spec.n_launches, parallel=False)
    pace, seen = {}, []
    # unit_s so large that each unit asks for 4x the last: 4, then 16 (cut to 6 by the end)
    a = compute_chunk(spec.text, spec.source, 0, 10, False, on_unit=seen.append, unit_s=1e3,
                      spec=spec, pace=pace)
    assert seen == [4, 6] and pace["size"] == 16
    assert pace["target"] > 1000  # launches a unit of 1e3 s holds at the pace measured
    # the next chunk starts at the size reached (one unit of 8), not again at 4
    b = compute_chunk(spec.text, spec.source, 10, 18, False, on_unit=seen.append, unit_s=1e3,
                      spec=spec, pace=pace)
    assert seen[2:] == [8]
    fresh = []
    compute_chunk(spec.text, spec.source, 10, 18, False, on_unit=fresh.append, unit_s=1e3)
    assert fresh == [4, 4]
    for k in spec.variables:
        assert np.array_equal(whole[k], np.concatenate([a[k], b[k]]), equal_nan=True), k


def test_ctrl_c_keeps_finished_units_of_a_one_chunk_map_and_resume_is_identical(tmp_path,
                                                                                  big_spec_text):
    (tmp_path / "big.toml").write_text(big_spec_text)
    spec = load_spec(tmp_path / "big.toml")
    assert spec.n_launches <= spec.chunk  # one chunk
    cmd = [sys.executable, "-m", "ballsurvey", "sweep", "big.toml", "-v", "--no-progress"]
    proc = subprocess.Popen(cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    killer = threading.Timer(300, proc.kill)
    killer.start()
    lines = []
    try:
        for line in proc.stderr:
            lines.append(line)
            m = re.search(r"(\d+) of 2000 launches done", line)
            if m and int(m.group(1)) > 0:
                break
        t0 = time.monotonic()
        proc.send_signal(signal.SIGINT)
        err = proc.stderr.read()
        proc.wait()
        took = time.monotonic() - t0
    finally:
        killer.cancel()
    assert proc.returncode == 130, "".join(lines) + err
    assert took < 5, took
    assert "--resume" in err and "launches are saved in" in err, err
    kept = int(re.search(r"interrupted; (\d+) of 2000", err).group(1))
    assert kept > 0
    parts = parts_dir(tmp_path / "big.nc")
    assert list(parts.glob("partial-*.npz")) or list(parts.glob("chunk-*.npz"))
    r = subprocess.run(cmd[:-2] + ["--resume", "--no-progress"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert f"{kept} of them from the interrupted run" in r.stdout, r.stdout
    from dataclasses import replace

    ref = xr.open_dataset(run_sweep(replace(spec, output=tmp_path / "ref.nc"), command="t"))
    same(ref, xr.open_dataset(tmp_path / "big.nc"))


# ---------------------------------------------------------------------------------------------
# command line
@pytest.fixture(scope="module")
def map_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    p = d / "m.toml"
    p.write_text(ballsurvey.api.spec_to_toml(SPEC) + f'\n[output]\nfile = "{d / "m.nc"}"\n')
    assert main(["sweep", str(p), "-q"]) == 0
    return d / "m.nc"


@pytest.mark.parametrize("argv,words", [
    (["plot", "SPEC"], "is a sweep spec, not a map: run `ballsurvey sweep"),
    (["plot", "MAP", "--at", "chidot0=4", "--at", "phidot0=-3"], "chidot0 is the axis drawn"),
    (["plot", "MAP", "--at", "phidot0=-10"], "nearest values: -3"),
    (["query", "MAP", "--shape", "square", "--limit", "0"], "--limit: must be >= 1"),
    (["query", "MAP", "--shape", "hexagon"], "unknown shape 'hexagon'"),
    (["find", "--shape", "hexagon", "--theta0-deg", "5", "--phidot0", "-3"], "--n-sides 6"),
    # argparse's own errors were usage plus error, five lines
    (["query", "MAP", "--n-sides", "abc"], "argument --n-sides: invalid int value: 'abc'"),
    (["query", "MAP"], "one of the arguments --shape --n-sides is required"),
    (["sweep", "MAP"], "not a text file (a sweep spec is TOML text)"),
    (["gallery", "MAP", "--per-label", "0"], "--per-label: must be >= 1"),
    (["query", "MAP", "--n-sides", "2"], "--n-sides: must be >= 3"),
    (["find", "--shape", "square", "--theta0-deg", "-5", "--phidot0", "-3", "-o", "x.csv"],
     "-o/--output goes with --trace-theta0"),
])
def test_misuse_is_one_line_exit_2(map_file, tmp_path, capsys, argv, words):
    spec = map_file.with_suffix(".toml")
    argv = [str(spec) if a == "SPEC" else str(map_file) if a == "MAP" else a for a in argv]
    assert main(argv + (["-o", str(tmp_path / "p.png")] if argv[0] == "plot" else [])) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not (tmp_path / "p.png").exists()


def test_query_csv_and_json_for_scripts(map_file, capsys):
    import io
    import json

    import pandas as pd

    assert main(["query", str(map_file), "--shape", "square", "--format", "json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["units"]["chidot0"] == "rad/s" and doc["common"]["thetadot0"] == 0.0
    assert doc["launches"] and all(" " not in k for k in doc["launches"][0])
    assert main(["query", str(map_file), "--shape", "square", "--format", "csv"]) == 0
    df = pd.read_csv(io.StringIO(capsys.readouterr().out), comment="#")
    assert "thetadot0" not in df.columns and "chidot0" in df.columns
    # the columns are the matches' whatever --limit keeps (they changed with it)
    for limit in ("1", "2", "3"):
        assert main(["query", str(map_file), "--shape", "square", "--format", "csv",
                     "--limit", limit]) == 0
        cut = pd.read_csv(io.StringIO(capsys.readouterr().out), comment="#")
        assert list(cut.columns) == list(df.columns) and len(cut) == min(int(limit), len(df))


def test_a_refined_map_names_whole_launches_and_refuses_what_it_lacks(tmp_path, capsys):
    out = tmp_path / "ref.nc"
    assert main(["refine", "--coarse", "3", "--levels", "1", "--T", "2", "-o", str(out)]) == 0
    ds = ballsurvey.open_map(out)
    assert float(ds.thetadot0) == 0.0 and ds.thetadot0.attrs["units"] == "rad s-1"
    capsys.readouterr()
    assert main(["query", str(out), "--n-sides", "4"]) == 2  # it said "no launches match"
    assert "does not hold 'n_sides'" in capsys.readouterr().err


def test_help_shows_defaults_and_units():
    from ballsurvey.cli import build_parser

    ap = build_parser()
    sub = ap._subparsers._group_actions[0].choices
    text = sub["bench"].format_help()
    assert "(default: 4096)" in text and "RK4 steps per launch (default: 2000)" in text
    assert "range of the initial tilt (deg) (default: -10 30)" in sub["refine"].format_help()
    assert "number of sides" in sub["find"].format_help()
    assert "(default: 30)" in sub["sweep"].format_help()


def test_a_bug_is_not_an_input_error(monkeypatch):
    def buggy(args):
        raise ValueError("a bug, not the user's input")

    from ballsurvey import cli

    monkeypatch.setattr(cli, "_cmd_paper", buggy)
    with pytest.raises(ValueError, match="a bug"):
        main(["paper"])


def test_importing_plot_leaves_matplotlib_alone():
    code = ("import matplotlib; b = matplotlib.get_backend(); import ballsurvey.plot; "
            "assert matplotlib.get_backend() == b, (b, matplotlib.get_backend()); "
            "import sys; assert 'matplotlib.pyplot' not in sys.modules")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       env={"MPLBACKEND": "svg", **__import__("os").environ})
    assert r.returncode == 0, r.stderr


def test_the_summary_of_a_map_of_named_points_suggests_no_plot(tmp_path, capsys):
    """`plot` refuses a map of named points; the summary suggested it."""
    p = tmp_path / "pts.toml"
    p.write_text('[[points]]\nname = "a"\ntheta0_deg = -5.0\nthetadot0 = 0.0\nchidot0 = 4.05\n'
                 'phidot0 = -3.0\n[[points]]\nname = "b"\ntheta0_deg = 10.0\nthetadot0 = 0.0\n'
                 f'chidot0 = 4.0\nphidot0 = -3.0\n[run]\nT = 3.0\ndt = 5e-4\n[output]\n'
                 f'file = "{tmp_path / "pts.nc"}"\n')
    assert main(["sweep", str(p)]) == 0
    out = capsys.readouterr().out
    assert "wrote" in out and "ballsurvey plot" not in out, out


def test_a_units_blocks_are_shared_evenly_over_the_threads():
    # numba hands each thread an equal, contiguous share of a unit's blocks: the block size
    # takes as few blocks a thread as the largest block allows, and leaves the busiest thread
    # (in SIMD vectors, a block's remainder launch by launch) no more to do than blocks of n /
    # threads or of the largest size did (141 launches on two threads in blocks of 64: 128 and
    # 13; in blocks of 40: 80 and 61)
    import math

    from ballsurvey.sweep.compute import _balanced_block, busiest_thread

    for threads in (1, 2, 3, 16):
        for n in range(1, 700):
            block = _balanced_block(n, threads, 64)
            assert 1 <= block <= 64
            fewest = math.ceil(math.ceil(n / threads) / 64)
            assert math.ceil(math.ceil(n / block) / threads) == fewest, (n, threads, block)
            before = min(64, math.ceil(n / threads))
            assert busiest_thread(n, threads, block) <= busiest_thread(n, threads, before), (
                n, threads, block)
    assert _balanced_block(141, 2, 64) == 40
    # the cost counted: 40 launches are 5 vectors; 13 are one and 5 launches alone
    assert busiest_thread(53, 2, 40) == 5 and busiest_thread(13, 1, 64) == 1 + 5 * 0.45

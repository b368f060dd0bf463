"""The command line as a user meets it: exit codes, one-line errors, the README's commands."""
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def run(*args, cwd=ROOT, timeout=300):
    return subprocess.run([sys.executable, "-m", "ballsurvey", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout)


def test_quick_sweep_then_up_to_date(tmp_path):
    out = tmp_path / "quick.nc"
    r = run("sweep", "sweeps/quick.toml", "-o", str(out))
    assert r.returncode == 0, r.stderr
    assert out.exists() and "wrote" in r.stdout
    r = run("sweep", "sweeps/quick.toml", "-o", str(out))
    assert r.returncode == 0 and "up to date" in r.stdout


def test_a_sweep_from_the_command_line_imports_neither_xarray_nor_pandas(tmp_path):
    """Their import is a quarter of a fresh process's start (the fixed cost of every sweep, and
    of each run `bench --scaling` times); a sweep writes with netCDF4 and needs neither. Library
    use still gets every public name and the `ds.ballsurvey` accessor at `import ballsurvey`."""
    out = tmp_path / "quick.nc"
    r = subprocess.run([sys.executable, "-X", "importtime", "-m", "ballsurvey", "sweep",
                        "sweeps/quick.toml", "-o", str(out)], cwd=ROOT, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "shapes: circle 45, triangle 22, square 14, ngon 27" in r.stdout, r.stdout
    imported = {line.rsplit("|", 1)[-1].strip() for line in r.stderr.splitlines()
                if line.startswith("import time:")}
    assert "numpy" in imported and "netCDF4" in imported, sorted(imported)[:20]
    assert not {"xarray", "pandas"} & imported
    lib = subprocess.run([sys.executable, "-c", (
        "import ballsurvey, xarray as xr; "
        "assert callable(ballsurvey.sweep) and callable(ballsurvey.query); "
        f"print(int(sum(xr.open_dataset({str(out)!r}).ballsurvey.counts().values)))")],
        cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert lib.returncode == 0 and lib.stdout.strip() == "108", lib.stderr


def test_another_program_run_with_m_that_imports_ballsurvey_is_library_use(tmp_path):
    # `python -m mytool`, whose package imports ballsurvey: sys.argv[0] is "-m" then too, yet
    # this is library use: `ballsurvey.sweep` is the function even after a submodule of the
    # subpackage is imported, and the `ds.ballsurvey` accessor is there
    pkg = tmp_path / "mytool"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("import ballsurvey\n")
    (pkg / "__main__.py").write_text(
        "import xarray as xr\n"
        "import ballsurvey\n"
        "import ballsurvey.sweep.spec\n"
        "print(callable(ballsurvey.sweep), hasattr(xr.Dataset(), 'ballsurvey'))\n")
    r = subprocess.run([sys.executable, "-m", "mytool"], cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["True", "True"]


@pytest.mark.parametrize("orig_argv, command_line", [
    (["python", "-m", "ballsurvey", "sweep", "s.toml"], True),
    (["python", "-X", "importtime", "-m", "ballsurvey"], True),
    (["python", "-Xfrozen_modules=off", "-Im", "ballsurvey"], True),
    (["python", "-mballsurvey", "plot"], True),
    (["python", "-W", "ignore", "-m", "mytool", "-m", "ballsurvey"], False),
    (["python", "-m", "ballsurveyx"], False),
    (["python", "-c", "import ballsurvey", "-m", "ballsurvey"], False)])
def test_which_module_python_m_runs(orig_argv, command_line):
    from ballsurvey import _is_command_line

    assert _is_command_line("-m", orig_argv) is command_line
    assert _is_command_line("/venv/bin/ballsurvey", ["python", "/venv/bin/ballsurvey"])
    assert not _is_command_line("script.py", ["python", "script.py"])


def test_missing_spec_is_one_line_exit_2(tmp_path):
    r = run("sweep", str(tmp_path / "nope.toml"))
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "cannot read" in r.stderr


@pytest.mark.parametrize("args", [("sweep", "sweeps/quick.toml", "--T", "-2"),
                                  ("query", "m.nc", "--shape", "square", "--nope"),
                                  ("plot", "m.nc", "extra.nc")])
def test_unknown_options_are_one_line_naming_the_command(args, capsys):
    from ballsurvey.cli import main

    assert main(list(args)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"ballsurvey {args[0]}: error: unrecognized "
                                               "arguments: ")


def test_bench_prints_rates_and_ratio():
    r = run("bench", "--launches", "64", "--steps", "50", "--repeats", "1")
    assert r.returncode == 0, r.stderr
    assert "IC-steps/s" in r.stdout and "vs naive" in r.stdout



TINY_SPEC = """
[launch]
theta0_deg = {{start = -5.0, stop = 5.0, num = 3}}
thetadot0 = 0.0
chidot0 = [4.05]
phidot0 = -3.0
[run]
T = 0.05
dt = 1e-3
mode = "{mode}"
[output]
file = "{out}"
"""


def test_bench_spec_times_the_sweep_against_its_bare_kernel_and_writes_nothing(tmp_path):
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY_SPEC.format(mode="full", out=tmp_path / "tiny.nc"))
    r = run("bench", "--spec", str(spec))
    assert r.returncode == 0, r.stderr
    assert "3 launches" in r.stdout and "50 rk4 steps each" in r.stdout
    assert "sweep, end to end" in r.stdout and "bare kernel" in r.stdout
    assert "ratio sweep / bare kernel" in r.stdout
    assert not (tmp_path / "tiny.nc").exists()  # the map goes to a temporary folder
    spec.write_text(TINY_SPEC.format(mode="period", out=tmp_path / "tiny.nc"))
    r = run("bench", "--spec", str(spec))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "mode 'period'" in r.stderr

def test_bench_scaling_runs_the_spec_on_one_thread_on_threads_and_on_workers(tmp_path):
    pytest.importorskip("distributed")
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY_SPEC.format(mode="full", out=tmp_path / "tiny.nc"))
    r = run("bench", "--scaling", str(spec), "--threads", "2", "--workers", "2")
    assert r.returncode == 0, r.stderr
    for row in ("1 thread, one process", "2 threads, one process", "--workers 2 (dask"):
        line = next(ln for ln in r.stdout.splitlines() if row in ln)
        # two speed-ups, each its own column: a kernel time that rounds to 0.00 s gives '-'
        # (a ratio of rounding once printed as 10000000.0x, run into the wall's column)
        assert re.search(r" \d+\.\dx +(\d+\.\dx|-)$", line), line
    assert "the 3 maps are the same, bit for bit: yes" in r.stdout
    assert not (tmp_path / "tiny.nc").exists()  # the maps go to a temporary folder
    for bad, says in ((["--scaling", str(spec), "--threads", "0"], "--threads: must be >= 1"),
                      (["--scaling", str(spec), "--workers", "2000"], "--workers: must be <="),
                      (["--workers", "2"], "go with --scaling")):
        r = run("bench", *bad)  # refused before anything runs
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert says in r.stderr, r.stderr


def test_version():
    from importlib.metadata import version

    r = run("--version")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == f"ballsurvey {version('ballsurvey')}"


def test_ctrl_c_while_numba_starts_names_the_saved_parts_and_resume(tmp_path, monkeypatch,
                                                                     capsys):
    """A Ctrl-C in the first second of a run (numba starting), after an earlier run saved some
    parts: one line naming them and the command that resumes, status 130."""
    from ballsurvey.cli import main
    from ballsurvey.cli import sweep as cli_sweep
    from test_reliability import crashed_sweep

    spec, parts = crashed_sweep(tmp_path)

    def interrupted():
        raise KeyboardInterrupt
    monkeypatch.setattr(cli_sweep, "_start_numba", interrupted)
    with pytest.raises(SystemExit) as stop:
        main(["sweep", str(tmp_path / "tiny.toml"), "--resume", "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert stop.value.code == 130 and len(err) == 1, err
    assert f"saved parts in {parts}" in err[0] and "--resume" in err[0], err


def test_negative_numbers_in_exponent_form_are_values_not_options():
    # argparse reads -5 and -5.0 as values but took -5e0 for an option ("expected one
    # argument"), and left two-value options like --bracket -1e1 5 no way around it
    from ballsurvey.cli import build_parser

    a = build_parser().parse_args(["find", "--shape", "square", "--theta0-deg", "-5e0",
                                   "--phidot0", "-3E-0", "--bracket", "-1e1", "5"])
    assert (a.theta0_deg, a.phidot0, a.bracket) == (-5.0, -3.0, [-10.0, 5.0])
    assert build_parser().parse_args(["refine", "--chidot0", "-inf", "3"]).chidot0[0] == -math.inf

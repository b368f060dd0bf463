"""Reliability at the edges: resuming across a change of code, the printed resume command,
threads and netCDF, outputs inside a sweep's own folders, digests of parsed values. Tiny maps
(T = 2 s, dt = 1e-3 s) keep it quick."""
import json
import math
import re
import shlex
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import ballsurvey
from ballsurvey.cli import main
from ballsurvey.limits import InputError
from ballsurvey.sweep import load_spec, parts, provenance, run_sweep
from ballsurvey.sweep.engine import UpToDate, parts_dir
from test_reliability import TINY, crashed_sweep, same_map, tiny_spec

REPO_SRC = Path(ballsurvey.__file__).resolve().parent


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    d = tmp_path_factory.mktemp("ref")
    with xr.open_dataset(run_sweep(tiny_spec(d, "ref.nc"), command="test")) as ds:
        return ds.load()


def other_code(monkeypatch):
    """As if the package had changed since the parts or the map were written."""
    monkeypatch.setattr(parts, "code_digest", lambda: "0" * 64)


# ---------------------------------------------------------------------------------------------
# the code digest
def _package_copy(tmp_path):
    dst = tmp_path / "pkg"
    shutil.copytree(REPO_SRC, dst, ignore=lambda d, names: [
        n for n in names if not n.endswith(".py") and not (Path(d) / n).is_dir()
        or n == "__pycache__"])
    return dst


def _digest_of(monkeypatch, package):
    monkeypatch.setattr(provenance, "PACKAGE", package)
    provenance._module_code.cache_clear()
    provenance.code_digest.cache_clear()
    try:
        return provenance.code_digest()
    finally:
        provenance._module_code.cache_clear()
        provenance.code_digest.cache_clear()


def test_code_digest_follows_the_code_that_computes_a_launch(tmp_path, monkeypatch):
    """A classifier default, a kernel line or the version changes the digest; a comment, a
    docstring or a module outside the compute path (the plots) does not."""
    pkg = _package_copy(tmp_path)
    base = _digest_of(monkeypatch, pkg)
    assert base == _digest_of(monkeypatch, REPO_SRC)  # a copy of the same code: the same
    modules = provenance.compute_modules()
    for m in ("classify/labels.py", "compose.py", "integrate/ensemble.py", "sweep/compute.py",
              "physics/euler.py", "integrate/adaptive_kernel.py", "store.py"):
        assert m in modules
    assert "plot.py" not in modules and not any(m.startswith("cli") for m in modules)

    labels = pkg / "classify" / "labels.py"
    text = labels.read_text()
    labels.write_text(text.replace('"""', '"""A docstring changed. ', 1) + "\n# a comment\n")
    (pkg / "plot.py").write_text((pkg / "plot.py").read_text() + "\nX = 1\n")
    assert _digest_of(monkeypatch, pkg) == base
    assert "    min_cycles: int = 2" in text
    labels.write_text(text.replace("    min_cycles: int = 2", "    min_cycles: int = 3", 1))
    assert _digest_of(monkeypatch, pkg) != base
    labels.write_text(text)
    init = pkg / "__init__.py"
    init.write_text(init.read_text().replace('__version__ = "', '__version__ = "9'))
    monkeypatch.setattr(provenance, "__version__", "9" + ballsurvey.__version__)
    assert _digest_of(monkeypatch, pkg) != base


def test_resume_across_a_code_change_is_refused_and_says_what_to_do(tmp_path, monkeypatch,
                                                                     capsys, reference):
    spec, p = crashed_sweep(tmp_path, at=1)
    man = json.loads((p / "manifest.json").read_text())
    assert man["code_digest"] == provenance.code_digest() and man["version"]
    other_code(monkeypatch)
    with pytest.raises(InputError, match="saved by other code.*--force without --resume"):
        run_sweep(spec, resume=True, command="test")
    assert sorted(x.name for x in p.glob("chunk-*")) == ["chunk-000000.npz", "chunk-000001.npz"]
    toml = tmp_path / "tiny.toml"
    for argv in (["sweep", str(toml), "--resume"], ["sweep", str(toml), "--resume", "--force"]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "saved by other code" in err[0], err
    assert len(list(p.glob("chunk-*"))) == 2  # nothing discarded
    assert main(["sweep", str(toml), "--force", "--no-progress"]) == 0  # starts over, says so
    assert "discarded 2 saved parts" in capsys.readouterr().err
    same_map(spec.output, reference)


def test_a_map_made_by_other_code_is_not_up_to_date(tmp_path, monkeypatch, capsys):
    spec = tiny_spec(tmp_path)
    run_sweep(spec, command="test")
    with xr.open_dataset(spec.output) as ds:
        assert ds.attrs["code_digest"] == provenance.code_digest()
    with pytest.raises(UpToDate):
        run_sweep(spec, command="test")
    other_code(monkeypatch)
    with pytest.raises(InputError, match="made by this spec with other code.*--force recomputes"):
        run_sweep(spec, command="test")
    assert main(["sweep", str(tmp_path / "tiny.toml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "other code" in err[0]
    with pytest.raises(InputError, match="other code"):
        ballsurvey.sweep(tmp_path / "tiny.toml", progress=False)


# ---------------------------------------------------------------------------------------------
# digests of parsed values
@pytest.mark.parametrize("old, new", [
    ("T = 2.0", "T = 2"),
    ("dt = 1e-3", "dt = 0.001\nobserve_every = 4\nmethod = 'rk4'"),  # defaults written out
    ("chunk = 2", "chunk = 5"),  # the chunk plan does not change results
    ("phidot0 = -3.0", "phidot0 = [-3]"),
    ('file = "OUT"', 'file = "OUT"\nvariables = ["n_sides", "label", "closure_m"]'),
    ("title = \"tiny\"", "title = \"tiny\"  # a comment"),
])
def test_spec_digest_is_of_parsed_values(tmp_path, old, new):
    a = tiny_spec(tmp_path)
    assert old in TINY
    b = tiny_spec(tmp_path, text=TINY.replace(old, new))
    if "variables" in new:  # the same variables in another order
        a = tiny_spec(tmp_path, text=TINY.replace(old, 'file = "OUT"\nvariables = '
                                                       '["closure_m", "n_sides"]'))
    assert a.digest == b.digest
    c = tiny_spec(tmp_path, text=TINY.replace("T = 2.0", "T = 2.5"))
    assert c.digest != a.digest


def test_same_run_written_differently_is_up_to_date(tmp_path, capsys):
    spec = tiny_spec(tmp_path)
    run_sweep(spec, command="test")
    (tmp_path / "tiny.toml").write_text(
        TINY.replace("OUT", str(spec.output)).replace("T = 2.0", "T = 2"))
    assert main(["sweep", str(tmp_path / "tiny.toml")]) == 0
    assert "up to date" in capsys.readouterr().out


# ---------------------------------------------------------------------------------------------
# the printed resume command resumes; --resume --force keeps the parts
def _interrupting(monkeypatch, at):
    """The CLI's run_sweep with a Ctrl-C once chunk `at` is saved."""
    pkg = pkg_sweep()
    real = pkg.run_sweep

    def run(spec, **kw):
        def on_chunk(k):
            if k == at:
                raise KeyboardInterrupt
        return real(spec, **{**kw, "on_chunk": on_chunk})
    monkeypatch.setattr(pkg, "run_sweep", run)
    return real


def test_printed_resume_command_resumes_over_another_specs_map(tmp_path, monkeypatch, capsys,
                                                               reference):
    """A --force run over another spec's map, interrupted: the command it prints continues it
    from the saved parts (they are not recomputed or deleted) and overwrites the old map."""
    out = tmp_path / "m.nc"
    other = tmp_path / "other.toml"
    other.write_text(TINY.replace("OUT", str(out)).replace("T = 2.0", "T = 1.0"))
    assert main(["sweep", str(other), "-q"]) == 0
    toml = tmp_path / "tiny.toml"
    toml.write_text(TINY.replace("OUT", str(out)))
    real = _interrupting(monkeypatch, at=1)
    monkeypatch.setattr(sys, "argv", ["ballsurvey", "sweep", str(toml), "--force", "-q"])
    with pytest.raises(SystemExit) as stop:
        main(sys.argv[1:])
    assert stop.value.code == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "4 of 6 launches are saved" in err[0], err
    cmd = err[0].split("`")[1]
    seen = []
    monkeypatch.setattr(pkg_sweep(), "run_sweep",
                        lambda spec, **kw: real(spec, **{**kw, "on_chunk": seen.append}))
    assert main(shlex.split(cmd)[1:]) == 0
    assert seen == [2]  # only the chunk not saved
    same_map(out, reference)
    assert not parts_dir(out).exists()


def pkg_sweep():
    """The package ballsurvey.sweep (the name `ballsurvey.sweep` is the function)."""
    return sys.modules["ballsurvey.sweep"]


def test_resume_force_keeps_the_parts_force_alone_says_it_discards(tmp_path, reference):
    spec, p = crashed_sweep(tmp_path, at=1)
    notes, computed = [], []
    run_sweep(spec, resume=True, force=True, command="test", notice=notes.append,
              on_chunk=computed.append)
    assert computed == [2] and not notes
    same_map(spec.output, reference)
    spec, p = crashed_sweep(tmp_path, "d.nc", at=0)
    notes = []
    run_sweep(spec, force=True, command="test", notice=notes.append)
    assert any("discarded 1 saved part in" in n for n in notes), notes


def test_plain_resume_over_another_specs_map_points_to_force_resume(tmp_path):
    spec, p = crashed_sweep(tmp_path, at=1)
    other = run_sweep(tiny_spec(tmp_path, "o.nc", text=TINY.replace("T = 2.0", "T = 1.0")),
                      command="test")
    shutil.copy(other, spec.output)
    with pytest.raises(InputError, match=r"another spec.*--force --resume keeps the saved parts"):
        run_sweep(spec, resume=True, command="test")
    assert len(list(p.glob("chunk-*"))) == 2


# ---------------------------------------------------------------------------------------------
# outputs inside a sweep's working folders; leftovers of a crash after the rename
@pytest.mark.parametrize("inside", ["big.nc.parts/q.nc", ".big.nc.tmp-abc123/q.nc",
                                    "big.nc.parts/sub/q.nc"])
def test_output_inside_a_sweeps_working_folder_is_refused(tmp_path, capsys, monkeypatch, inside):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.toml").write_text(TINY.replace("OUT", "x.nc"))
    assert main(["sweep", "s.toml", "-o", inside]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "removed when that sweep ends" in err[0]
    assert not (tmp_path / inside).parent.exists()


def test_leftovers_of_a_crash_after_the_rename_are_removed(tmp_path, capsys):
    # the state a kill -9 between the rename and the removal leaves: parts and a temp folder
    _, p2 = crashed_sweep(tmp_path, "x.nc", at=1)
    spec = tiny_spec(tmp_path)
    run_sweep(spec, command="test")
    p = parts_dir(spec.output)
    p.mkdir()
    for f in p2.iterdir():
        shutil.copy(f, p / f.name)
    tmp = tmp_path / f".{spec.output.name}.tmp-zz"
    tmp.mkdir()
    (tmp / spec.output.name).write_bytes(b"x")
    assert main(["sweep", str(tmp_path / "tiny.toml")]) == 0
    io = capsys.readouterr()
    assert "up to date" in io.out and "removed" in io.err
    assert not p.exists() and not tmp.exists()


# ---------------------------------------------------------------------------------------------
# threads: one lock around netCDF
THREADS = textwrap.dedent("""
    import sys, threading
    import ballsurvey
    spec, ref, root = sys.argv[1], sys.argv[2], sys.argv[3]
    text = open(spec).read()
    errors, done = [], threading.Event()
    def run(i):
        try:
            for j in range(2):
                ballsurvey.sweep(text.replace("OUT", f"{root}/t{i}-{j}.nc"), progress=False,
                                 notice=lambda m: None)
        except BaseException as exc:
            errors.append(repr(exc))
    ts = [threading.Thread(target=run, args=(i,)) for i in range(3)]
    for t in ts:
        t.start()
    n = 0
    while any(t.is_alive() for t in ts):
        ds = ballsurvey.open_map(ref)
        assert int(ds.label.size) == 6
        n += 1
    for t in ts:
        t.join()
    print("ok", n, errors)
    sys.exit(1 if errors else 0)
""")


def test_sweeps_in_threads_with_open_map_in_the_main_thread(tmp_path):
    """Three threads each running sweeps while the main thread opens a map again and again:
    no crash, every map written (HDF5 is entered by one thread at a time; parallel kernels take
    turns, which numba's workqueue threading layer needs: it is the layer used here, as where
    neither OpenMP nor TBB is found)."""
    import os

    ref = run_sweep(tiny_spec(tmp_path, "ref.nc"), command="test")
    (tmp_path / "s.toml").write_text(TINY)
    env = dict(os.environ, NUMBA_THREADING_LAYER="workqueue")
    r = subprocess.run([sys.executable, "-c", THREADS, str(tmp_path / "s.toml"), str(ref),
                        str(tmp_path)], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, (r.returncode, r.stdout[-500:], r.stderr[-2000:])
    for i in range(3):
        for j in range(2):
            same_map(tmp_path / f"t{i}-{j}.nc", xr.open_dataset(ref).load())


# ---------------------------------------------------------------------------------------------
# find skips what it cannot take
def test_find_skips_bracket_points_on_the_flat_face():
    """A theta0 bracket reaching onto the flat face (below -31.8 deg for the paper's ball): the
    points there have no value; the root inside the model is found and integrates as a square."""
    from ballsurvey.find import _turn, find_launch

    launch = dict(theta0_deg=None, thetadot0=0.0, chidot0=4.0, phidot0=-3.0)
    assert np.isnan(_turn(launch, "theta0_deg", -66.3, ballsurvey.Ball.paper()))
    sols = find_launch(4, launch, "theta0_deg", (-70.0, 50.0), scan=40)
    assert len(sols) == 1 and sols[0].label == "square"
    assert abs(sols[0].value - 1.4899) < 1e-3 and abs(sols[0].n_sides - 4) < 1e-6


# ---------------------------------------------------------------------------------------------
# one line for inputs that are not what they claim
def test_open_map_refuses_a_netcdf_that_is_not_a_map(tmp_path, capsys):
    def fake(name, label, **attrs):
        ds = xr.Dataset({"label": ("x", label)})
        ds.label.attrs.update(attrs)
        ds.to_netcdf(tmp_path / name)
        return str(tmp_path / name)

    for path, words in ((fake("f.nc", np.array([1.5, 2.0])), "not ballsurvey's label codes"),
                        (fake("i.nc", np.array([1, 2], "i1"), flag_meanings="a b"),
                         "not ballsurvey's label codes"),
                        (fake("w.nc", np.array([1, 2], "i1"), flag_meanings="circle square"),
                         "lacks the launch conditions")):
        with pytest.raises(InputError, match=words):
            ballsurvey.open_map(path)
        for argv in (["query", path, "--shape", "square"], ["gallery", path]):
            assert main(argv) == 2
            err = capsys.readouterr().err.strip().splitlines()
            assert len(err) == 1 and words in err[0], err


def test_point_names_must_be_printable(tmp_path):
    text = TINY.split("[launch]")[0] + "".join(
        f'[[points]]\nname = "{n}"\ntheta0_deg = 1.0\nthetadot0 = 0.0\nchidot0 = 3.0\n'
        f'phidot0 = -3.0\n' for n in ("a", "a\\u0000")) + "[run]\nT = 1.0\n"
    with pytest.raises(InputError, match="name: must be printable"):
        load_spec("p.toml", text=text)


def test_workers_in_an_unguarded_script_say_what_to_do(monkeypatch):
    """A worker process re-importing a script that starts a sweep with workers at its top level
    stops with one line naming the main guard (and the parent's run says the same)."""
    pytest.importorskip("distributed")
    import multiprocessing

    from ballsurvey.sweep.executors import dask_client

    monkeypatch.setattr(multiprocessing.current_process(), "_inheriting", True, raising=False)
    with pytest.raises(SystemExit, match="__name__ == .__main__.") as stop:
        with dask_client(None, 2):
            pass
    assert "\n" not in str(stop.value.code)


# ---------------------------------------------------------------------------------------------
# Ctrl-C is one line from the first instant
IMPORT_INTERRUPTED = textwrap.dedent("""
    import runpy, sys
    class CtrlC:  # a Ctrl-C while the command line's modules and their dependencies import
        def find_spec(self, name, path=None, target=None):
            if name == "ballsurvey.cli":
                raise KeyboardInterrupt
    sys.meta_path.insert(0, CtrlC())
    if sys.argv[1] == "script":
        sys.argv = ["/usr/bin/ballsurvey", "--version"]
        from ballsurvey.cli import main
    else:
        sys.argv = ["-m", "--version"]  # as `python -m ballsurvey --version` sets them
        sys.orig_argv = [sys.executable, "-m", "ballsurvey", "--version"]
        runpy._run_module_as_main("ballsurvey")
""")


@pytest.mark.parametrize("how", ["script", "module"])
def test_ctrl_c_while_the_package_imports_is_one_line(how):
    r = subprocess.run([sys.executable, "-c", IMPORT_INTERRUPTED, how], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 130 and r.stderr == "ballsurvey: interrupted\n", r.stderr


EXEC_INTERRUPTED = textwrap.dedent("""
    import runpy, sys
    class CtrlC:  # a Ctrl-C inside an `exec` of a string while the sweep's modules import
        def find_spec(self, name, path=None, target=None):
            if name == "ballsurvey.sweep":
                sys.meta_path.remove(self)
                exec("raise KeyboardInterrupt")
    sys.meta_path.insert(0, CtrlC())
    sys.argv[0] = "ballsurvey"
    runpy.run_module("ballsurvey", run_name="__main__")
""")


def test_ctrl_c_inside_a_librarys_exec_still_exits_130_under_python_m(tmp_path):
    """`python -m ballsurvey sweep`, a Ctrl-C as numba starts (scipy's import runs an `exec` of
    a string then): one line and exit status 130, not a death by SIGINT (CPython's mark of a
    Ctrl-C that left an `exec` outlives the handler that caught it)."""
    (tmp_path / "ctrl_c_probe.py").write_text(EXEC_INTERRUPTED)
    r = subprocess.run([sys.executable, "-m", "ctrl_c_probe", "sweep", "x.toml"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 130 and r.stderr == "ballsurvey sweep: interrupted\n", r.stderr


class Terminal:
    """`python -m ballsurvey ARGS` in its own process group, as at a terminal: `ctrl_c()`
    signals the whole group; killed after 300 s whatever happens."""

    def __init__(self, cwd, *args):
        import os
        import signal
        import threading

        self.proc = subprocess.Popen([sys.executable, "-m", "ballsurvey", *args], cwd=cwd,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     start_new_session=True)
        self.killer = threading.Timer(300, lambda: os.killpg(self.proc.pid, signal.SIGKILL))
        self.killer.start()
        self.seen = []

    def ctrl_c(self, times=1, gap_s=0.03):
        import os
        import signal
        import time

        for _ in range(times):
            try:
                os.killpg(self.proc.pid, signal.SIGINT)
            except ProcessLookupError:
                return
            time.sleep(gap_s)

    def until_launches_done(self, total=2000):
        """Read stderr up to the first line saying some launches are done (or to its end);
        the other lines are kept for `end`."""
        import re

        for line in self.proc.stderr:
            m = re.search(rf"(\d+) of {total} launches done", line)
            if m and int(m.group(1)) > 0:
                return
            self.seen.append(line)

    def end(self):
        """(exit status, stderr lines but those of -v's progress)."""
        try:
            err = self.proc.stderr.read()
            self.proc.wait()
        finally:
            self.killer.cancel()
        lines = "".join(self.seen).splitlines() + err.strip().splitlines()
        return self.proc.returncode, [ln for ln in lines if ln.strip() and not re.search(
            r"launches done|launches \(.*\) ->", ln)]


def test_ctrl_c_while_local_workers_start_is_one_line(tmp_path, big_spec_text):
    """Ctrl-C at a terminal (the whole process group) while the local cluster starts: the
    starting workers ignore it (a traceback each before), and so does the run for those seconds;
    a Ctrl-C once launches run ends it with one line (if the cluster was up in time, the first
    one does)."""
    pytest.importorskip("distributed")
    import time

    (tmp_path / "big.toml").write_text(big_spec_text)
    term = Terminal(tmp_path, "sweep", "big.toml", "--workers", "1", "-v", "--no-progress")
    first = term.proc.stderr.readline()  # "... launches (...) -> ...": the cluster starts next
    assert "launches" in first, first
    time.sleep(0.5)
    term.ctrl_c()
    term.until_launches_done()
    term.ctrl_c()
    code, lines = term.end()
    # where the cluster was up in time, the first Ctrl-C ends the run before a launch is saved:
    # one line too ("interrupted before any launch was saved"); else the second, with the count
    assert code == 130 and len(lines) == 1, lines
    assert lines[0].startswith("ballsurvey sweep: interrupted"), lines


def test_a_burst_of_ctrl_c_is_still_one_line_and_status_130(tmp_path, big_spec_text):
    """A key held down: Ctrl-C after Ctrl-C while the run saves and exits; one line, status 130
    (not a traceback, nor a death by SIGINT)."""
    (tmp_path / "big.toml").write_text(big_spec_text)
    term = Terminal(tmp_path, "sweep", "big.toml", "-v", "--no-progress")
    term.until_launches_done()
    term.ctrl_c(times=10)
    code, lines = term.end()
    assert code == 130 and len(lines) == 1 and "interrupted;" in lines[0], lines


def test_ctrl_c_during_assembly_keeps_every_part_and_says_resume(tmp_path, monkeypatch, capsys,
                                                                 reference):
    from ballsurvey.sweep import engine

    spec = tiny_spec(tmp_path)
    real = engine._write_netcdf

    def interrupted(*a, **kw):
        raise KeyboardInterrupt
    monkeypatch.setattr(engine, "_write_netcdf", interrupted)
    monkeypatch.setattr(sys, "argv", ["ballsurvey", "sweep", str(tmp_path / "tiny.toml")])
    with pytest.raises(SystemExit) as stop:
        main(sys.argv[1:] + ["--no-progress"])
    assert stop.value.code == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "6 of 6 launches are saved" in err[0] and "--resume" in err[0], err
    assert not spec.output.exists() and len(list(parts_dir(spec.output).glob("chunk-*"))) == 3
    assert not list(tmp_path.glob(".*tmp*"))  # the half-written file went with its folder
    monkeypatch.setattr(engine, "_write_netcdf", real)
    report = {}
    run_sweep(spec, resume=True, command="test", report=report)
    assert report["computed"] == 0
    same_map(spec.output, reference)


# ---------------------------------------------------------------------------------------------
# failures outside the input: one line naming the file and what is kept
def test_disk_full_while_saving_a_part_names_it_and_what_is_kept(tmp_path, monkeypatch, capsys,
                                                                  reference):
    import errno

    from ballsurvey.sweep import engine

    spec = tiny_spec(tmp_path)
    real = engine._write_part

    def full(parts, k, *a):
        if k == 1:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(parts, k, *a)
    monkeypatch.setattr(engine, "_write_part", full)
    assert main(["sweep", str(tmp_path / "tiny.toml"), "--no-progress"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert "chunk-000001.npz: No space left on device; 2 of 6 launches are kept" in err[0]
    assert "--resume" in err[0]
    monkeypatch.setattr(engine, "_write_part", real)
    report = {}
    run_sweep(spec, resume=True, command="test", report=report)
    assert report["resumed"] == 2
    same_map(spec.output, reference)


@pytest.mark.parametrize("argv", [
    ["path", "--theta0-deg", "1", "--chidot0", "3", "--phidot0", "-3", "-o", "/proc/x.png"],
    ["plot", "m.nc", "-o", "afile/x.png"],
    ["paper", "-o", "afile/figs"],
    ["accuracy", "-o", "afile"],
    ["sweep", "s.toml", "-o", "nowhere/../b/q.nc"],
])
def test_unwritable_output_is_refused_before_any_work(tmp_path, capsys, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("")
    (tmp_path / "s.toml").write_text(TINY.replace("OUT", "x.nc"))
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ("-o/--output" in err[0] or "cannot write the output" in err[0]), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "s.toml"]


# ---------------------------------------------------------------------------------------------
# small silent ones
def test_a_whole_sphere_has_c_plus_zero():
    spec = load_spec("g.toml", text=TINY.replace("OUT", "x.nc").replace(
        'title = "tiny"', 'title = "tiny"\n[ball]\na = 0.03\ncut_height = 0.0\nM = 0.1'))
    assert spec.ball.c == 0.0 and math.copysign(1.0, spec.ball.c) == 1.0


def test_near_vertical_is_unknown_without_theta_max(tmp_path):
    text = TINY.replace("OUT", str(tmp_path / "v.nc")) + '\nvariables = ["n_sides"]\n'
    ds = ballsurvey.sweep(text, progress=False, notice=lambda m: None)
    assert "theta_max_deg" not in ds
    word = str(ds.ballsurvey.labels.values.ravel()[0])
    df = ballsurvey.query(ds, shape=word)
    assert len(df) and df.near_vertical.isna().all()


def test_summary_of_a_dop853_map_reports_no_fallback(tmp_path, reference):
    """dop853 integrates every launch in the fixed frame by design: no 'done again' line (it
    counted them all); an rk4 map gives the line."""
    from ballsurvey.cli import sweep_summary

    for method, line in (("rk4", True), ("dop853", False)):
        path = tmp_path / f"{method}.nc"
        ds = reference.copy()
        ds.attrs["run_method"] = method
        if method == "dop853":
            ds["formulation"] = ds.formulation * 0 + 1
        ds.to_netcdf(path)
        assert ("done again near the vertical" in sweep_summary(path, 6, {})) == line


@pytest.mark.parametrize("resume", [False, True])
def test_parts_folder_killed_before_its_manifest_is_not_in_the_way(tmp_path, reference, resume):
    """kill -9 between making the parts folder and writing its manifest: nothing was saved, so
    the folder (empty, or holding the manifest's temporary) does not block a run or a resume."""
    spec = tiny_spec(tmp_path)
    p = parts_dir(spec.output)
    p.mkdir()
    (p / ".manifest-x1y2.tmp").write_bytes(b"{")
    run_sweep(spec, resume=resume, command="test")
    same_map(spec.output, reference)


def test_dask_workers_with_other_code_are_refused(tmp_path, monkeypatch):
    """Workers compute with their own installation: one whose code digest differs from this
    process's ends the run with one line before any task is sent."""
    distributed = pytest.importorskip("distributed")
    from ballsurvey.limits import RunError
    from ballsurvey.sweep import executors

    spec = tiny_spec(tmp_path)
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1,
                            dashboard_address=None) as client:
        monkeypatch.setattr(executors, "code_digest", lambda: "0" * 64)
        with pytest.raises(RunError, match="runs other ballsurvey code.*same ballsurvey"):
            run_sweep(spec, client=client, command="test")
        monkeypatch.undo()
        run_sweep(spec, resume=True, client=client, command="test")
    assert spec.output.exists()


def test_a_map_from_before_code_digests_is_named_as_such(tmp_path, reference):
    """A map (or parts) without a recorded code digest: made by an older ballsurvey, whose spec
    digests may be computed otherwise; refused as other code, not as another spec."""
    spec = tiny_spec(tmp_path)
    ds = reference.copy()
    ds.attrs.pop("code_digest")
    ds.attrs["spec_digest"] = "an older digest"
    ds.to_netcdf(spec.output)
    with pytest.raises(InputError, match="by a spec with other code .*no code digest recorded"):
        run_sweep(spec, command="test")



def test_an_output_that_is_no_map_is_named_as_such(tmp_path):
    spec = tiny_spec(tmp_path)
    spec.output.write_text("notes")
    with pytest.raises(InputError, match="is not a map written by a sweep.*--force"):
        run_sweep(spec, command="test")
    assert spec.output.read_text() == "notes"


# ---------------------------------------------------------------------------------------------
# labels made beside the integration (the part writer's thread)

def test_a_second_ctrl_c_while_an_interrupted_chunk_is_labelled_keeps_what_it_counts(
        tmp_path, reference, monkeypatch):
    """Ctrl-C as chunk 1 finishes, then a second one while its launches are labelled for
    saving: the labelling is not cut short, so the 4 launches the run says it kept are the 4 on
    disk, and --resume gives the uninterrupted map."""
    import os
    import signal
    import threading

    from ballsurvey.sweep import compute, engine

    spec = tiny_spec(tmp_path, "burst.nc")
    label = compute.survey_fields

    def burst(run, *asked):  # the second Ctrl-C, delivered at once, inside the main thread's
        if threading.current_thread() is threading.main_thread():  # labelling
            os.kill(os.getpid(), signal.SIGINT)
        return label(run, *asked)

    def on_unit(done, total):
        if done == 4:
            raise KeyboardInterrupt
    monkeypatch.setattr(compute, "survey_fields", burst)
    with pytest.raises(engine.SweepInterrupted) as exc:
        run_sweep(spec, command="test", on_unit=on_unit)
    parts = parts_dir(spec.output)
    on_disk = sorted(p.name for p in parts.glob("chunk-*.npz"))
    assert on_disk == ["chunk-000000.npz", "chunk-000001.npz"] and exc.value.kept == 4
    monkeypatch.setattr(compute, "survey_fields", label)
    same_map(run_sweep(spec, resume=True, command="test"), reference)


def test_a_labelled_chunk_lets_its_observer_records_go(tmp_path):
    """Once `fields_of` has labelled a chunk, the object holds only the fields (not each
    launch's observer record, held while the next chunk runs); labelling again gives the same
    arrays."""
    from ballsurvey.compose import SurveyRun
    from ballsurvey.sweep import compute

    spec = tiny_spec(tmp_path)
    u = compute.compute_chunk(spec.text, spec.source, 0, 4, unit=2, spec=spec, unlabelled=True)
    assert sum(isinstance(p, SurveyRun) for p in u.pieces) == 2
    first = compute.fields_of(u)
    assert not any(isinstance(p, SurveyRun) for p in u.pieces)
    again = compute.fields_of(u)
    assert compute.n_launches(u) == 4 and set(first) == set(spec.variables)
    for k in first:
        assert np.array_equal(first[k], again[k], equal_nan=True) and len(first[k]) == 4


@pytest.mark.parametrize("at", [1, 3])
def test_ctrl_c_while_the_writer_labels_a_chunk_counts_only_what_is_on_disk(tmp_path, reference,
                                                                            monkeypatch, at):
    """Ctrl-C (once, or a burst) as the part writer starts labelling chunk 0 (while chunk 1 is
    integrated) or the last chunk (2): the part in flight is on disk when the run says what it
    kept, that count is the launches on disk, and --resume gives the uninterrupted map."""
    import os
    import signal
    import threading

    from ballsurvey.sweep import compute, engine

    spec = tiny_spec(tmp_path, f"wl{at}.nc")
    label, calls = compute.survey_fields, []

    def ctrl_c(run, *asked):
        calls.append(1)
        if len(calls) == at:
            assert threading.current_thread() is not threading.main_thread()
            for _ in range(at):
                os.kill(os.getpid(), signal.SIGINT)
        return label(run, *asked)
    monkeypatch.setattr(compute, "survey_fields", ctrl_c)
    with pytest.raises(engine.SweepInterrupted) as exc:
        run_sweep(spec, command="test")
    parts = parts_dir(spec.output)
    on_disk = sorted(p.name for p in parts.glob("chunk-*.npz"))
    assert on_disk and exc.value.kept == 2 * len(on_disk), (on_disk, exc.value.kept)
    assert not list(parts.glob("partial-*")) and not list(parts.glob(".*tmp*"))
    monkeypatch.setattr(compute, "survey_fields", label)
    same_map(run_sweep(spec, resume=True, command="test"), reference)

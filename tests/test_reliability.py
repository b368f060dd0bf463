"""Reliability: one writer per output, verified parts and chunk plans, limits before writing,
safe temporary files, bounded waits on dask. Tiny maps (T = 2 s, dt = 1e-3 s) keep it quick."""
import errno
import json
import math
import os
import shutil
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from ballsurvey.cli import main
from ballsurvey.limits import InputError, RunError
from ballsurvey.simulate import simulate
from ballsurvey.sweep import engine, executors, load_spec, run_sweep
from ballsurvey.sweep.engine import OutputBusy, OutputLock, lock_path, parts_dir

TINY = """
title = "tiny"
[launch]
theta0_deg = [-5.0, 10.0, 20.0]
thetadot0 = 0.0
chidot0 = [2.3, 4.05]
phidot0 = -3.0
[run]
T = 2.0
dt = 1e-3
chunk = 2
[output]
file = "OUT"
"""


def tiny_spec(tmp_path, name="tiny.nc", text=TINY, **changes):
    p = tmp_path / "tiny.toml"
    p.write_text(text.replace("OUT", str(tmp_path / name)))
    spec = load_spec(p)
    return replace(spec, **changes) if changes else spec


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    d = tmp_path_factory.mktemp("ref")
    out = run_sweep(tiny_spec(d, "ref.nc"), command="test")
    with xr.open_dataset(out) as ds:
        return ds.load()


def same_map(path, ref):
    with xr.open_dataset(path) as got:
        assert set(got.data_vars) == set(ref.data_vars)
        for v in ref.data_vars:
            assert np.array_equal(ref[v].values, got[v].values, equal_nan=True), v


class Crash(Exception):
    pass


def crash_at(k_crash):
    def on_chunk(k):
        if k == k_crash:
            raise Crash
    return on_chunk


def crashed_sweep(tmp_path, name="c.nc", at=2, text=TINY, **changes):
    """A sweep of TINY (3 chunks of 2) that stopped after chunk `at`: its parts are on disk."""
    spec = tiny_spec(tmp_path, name, text, **changes)
    with pytest.raises(Crash):
        run_sweep(spec, on_chunk=crash_at(at), command="test")
    return spec, parts_dir(spec.output)


# ---------------------------------------------------------------------------------------------
# input errors: one line, exit 2, nothing written (a table of specs and of commands)
BASE = {"launch": {"theta0_deg": "5.0", "thetadot0": "0.0", "chidot0": "4.0", "phidot0": "-3.0"},
        "run": {"T": "2.0", "dt": "1e-3"}, "classify": {}, "output": {"file": "'out/x.nc'"}}


def spec_text(**sections):
    doc = {s: dict(kv) for s, kv in BASE.items()}
    for sec, kv in sections.items():
        doc.setdefault(sec, {}).update(kv)
    return "".join(f"[{s}]\n" + "".join(f"{k} = {v}\n" for k, v in kv.items())
                   for s, kv in doc.items())


R = "{start = -10.0, stop = 20.0, num = %s}"
C = "{start = 1.0, stop = 8.0, num = %s}"
SPEC_CASES = [  # (sections, first words of the message after "<spec file>: ")
    ({"launch": {"theta0_deg": R % "1e9"}}, "[launch] theta0_deg.num: must be <= 1e+07"),
    ({"launch": {"theta0_deg": R % 1000, "chidot0": C % 1000, "thetadot0": C % 1000,
                 "phidot0": "{start = -4.0, stop = -1.0, num = 1000}"}},
     "[launch]: 1000 x 1000 x 1000 x 1000 = 1e+12 launches is more than 1e+10"),
    ({"launch": {"theta0_deg": R % 65536, "chidot0": C % 65536, "thetadot0": C % 65536,
                 "phidot0": "{start = -4.0, stop = -1.0, num = 65536}"}},
     "[launch]: 65536 x 65536 x 65536 x 65536 = 1.84e+19 launches is more than 1e+10"),
    ({"launch": {"c": "{start = 0.001, stop = 0.003, num = 100000}",
                 "M": "{start = 0.09, stop = 0.1, num = 100000}"}},
     "[launch] c/M: 1e+10 balls"),
    ({"run": {"rtol": "1e-300"}}, "[run] rtol: must be in [1e-14, 0.1]"),
    ({"run": {"rtol": "-1.0"}}, "[run] rtol: must be > 0"),
    ({"run": {"atol": "0.0"}}, "[run] atol: must be > 0"),
    ({"run": {"atol": "nan"}}, "[run] atol: must be finite"),
    ({"run": {"observe_every": "1e15"}}, "[run] observe_every: must be <= 10000"),
    ({"run": {"observe_every": "0"}}, "[run] observe_every: must be >= 1"),
    ({"run": {"cycles": "2.5"}}, "[run] cycles: must be a whole number"),
    ({"run": {"block": "-1"}}, "[run] block: must be >= 1"),
    ({"run": {"T": "1e6", "dt": "1e-7"}}, "[run] dt: T/dt = 1e+13 steps per launch"),
    ({"run": {"T": "inf"}}, "[run] T: must be finite"),
    ({"run": {"mode": "'period'", "cycles": "1"}}, "[run] cycles: period mode integrates 1"),
    ({"ball": {"a": "1e300", "c": "0.0", "M": "0.1", "A": "1e-5", "B": "1e-5"}},
     "[ball] a: must be within 0.0001..100 m"),
    ({"ball": {"a": "0.025", "c": "0.0", "M": "0.1", "A": "1e-300", "B": "1e-300"}},
     "[ball] A: A/(M a^2) must be within"),
    ({"ball": {"a": "0.025", "cut_height": "0.005", "M": "0.1", "g": "1e300"}},
     "[ball] g: must be within"),
    ({"run": {"T": "1" * 320}}, "[run] T: must be within +-1.8e308"),
    ({"run": {"T": "1" * 5000}}, "not a usable spec: Exceeds the limit (4300 digits)"),
    ({"run": {"T": "1e308", "dt": "1e300", "method": "'dop853'"}}, "[run] T: must be <= 1e+06"),
    ({"run": {"chunk": "1e9"}}, "[run] chunk: 1000000000 launches per chunk need about"),
    ({"run": {"chunk": "1"}, "launch": {"theta0_deg": R % 2000, "chidot0": C % 1000}},
     "[run] chunk: 1 launches per chunk cut 2e+06 launches into 2e+06 chunks"),
    ({"classify": {"max_star_points": "1e9"}}, "[classify] max_star_points: must be <= 1000"),
    ({"classify": {"min_cycles": "1e30"}}, "[classify] min_cycles: must be <= 10000"),
    ({"classify": {"min_cycles": "2.5"}}, "[classify] min_cycles: must be a whole number"),
    ({"output": {"file": "'out/x'"}}, "[output] file: must be a path ending in .nc"),
    # a list axis out of order made a map whose plots drew shapes in the wrong places
    ({"launch": {"chidot0": "[12.0, 1.0, 4.0]"}},
     "[launch] chidot0: values must increase along the list"),
    ({"launch": {"phidot0": "1e300"}}, "[launch] phidot0: must be within +-1000 rad/s"),
    ({"launch": {"thetadot0": "[0.0, 2000.0]"}}, "[launch] thetadot0: must be within +-1000"),
    ({"launch": {"chidot0": "{start = -1e9, stop = 8.0, num = 3}"}},
     "[launch] chidot0: must be within +-1000 rad/s"),
    ({"launch": {"chi0_deg": "1e15"}}, "[launch] chi0_deg: must be within +-1e+06 deg"),
]


def one_line_exit_2(capsys, argv, cwd, monkeypatch):
    monkeypatch.chdir(cwd)
    before = sorted(p.name for p in Path(cwd).iterdir())
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert sorted(p.name for p in Path(cwd).iterdir()) == before  # nothing written
    return err[0]


@pytest.mark.parametrize("sections,words", SPEC_CASES, ids=[w[:40] for _, w in SPEC_CASES])
def test_bad_spec_one_line_exit_2_nothing_written(tmp_path, capsys, monkeypatch, sections, words):
    (tmp_path / "s.toml").write_text(spec_text(**sections))
    t0 = time.time()
    line = one_line_exit_2(capsys, ["sweep", "s.toml"], tmp_path, monkeypatch)
    assert line.startswith(f"ballsurvey sweep: error: s.toml: {words}"), line
    assert time.time() - t0 < 20  # refused up front, not after allocating


CLI_CASES = [  # (argv, first words of the message after "ballsurvey CMD: error: ")
    (["sweep", "s.toml", "--workers", "-1"], "--workers: must be >= 1"),
    (["sweep", "s.toml", "--workers", "0"], "--workers: must be >= 1"),
    (["sweep", "s.toml", "-o", ""], "-o/--output: must be a file name ending in .nc"),
    (["sweep", "s.toml", "-o", "name_without_ext"], "-o/--output: must be a file name ending in .nc"),
    (["sweep", "s.toml", "--chunk", "0"], "--chunk: must be >= 1"),
    (["sweep", "s.toml", "--chunk", "1000000000"], "--chunk: 1000000000 launches per chunk"),
    (["sweep", "s.toml", "--dask-timeout", "nan"], "--dask-timeout: must be finite"),
    (["sweep", "s.toml", "--chunk", "9" * 400], "--chunk: must be within +-1.8e308"),
    *[(["sweep", "s.toml", "--scheduler", a], f"--scheduler: {a!r} is not a scheduler address")
      for a in ("notanaddress", "tcp://127.0.0.1:abc", "inproc://x", "", "tcp://h:0")],
    *[(["bench", flag, v], f"{flag}: must be") for flag, v in (
        ("--launches", "0"), ("--launches", "-5"), ("--steps", "0"), ("--repeats", "0"),
        ("--block", "0"), ("--dt", "0"), ("--dt", "nan"), ("--observe-every", "-3"),
        ("--map", "0"), ("--period", "0"), ("--headline", "0"), ("--T", "1e308"))],
    (["bench", "--map", "2", "--spec", "x.toml"], "--map and --spec are two benchmarks"),
    (["gallery", "m.nc", "--seed", "-1"], "--seed: must be >= 0"),
    (["sweep", "s.toml", "-o", "adir", "--force"], "-o/--output: must be a file name ending in .nc"),
    (["sweep", "s.toml", "-o", "adir.nc", "--force"], "-o/--output: adir.nc is a folder"),
    (["path", "--theta0-deg", "-5", "--chidot0", "nan", "--phidot0", "-3"],
     "--chidot0: must be finite"),
    (["path", "--theta0-deg", "-5", "--chidot0", "4", "--phidot0", "inf"],
     "--phidot0: must be finite"),
    (["path", "--theta0-deg", "-5", "--chidot0", "4", "--phidot0", "-3", "--T", "1e6", "--dt",
      "1e-7"], "--dt: T/dt = 1e+13 steps per launch is more than 1e+10"),
    (["path", "--theta0-deg", "-5", "--chidot0", "4", "--phidot0", "-3", "--T", "-1"],
     "--T: must be > 0"),
    (["path", "--theta0-deg", "-5", "--chidot0", "4", "--phidot0", "-3", "--n-out", "1"],
     "--n-out: must be >= 2"),
    (["path", "--theta0-deg", "-5", "--chidot0", "4", "--phidot0", "-3", "-o", "p"],
     "-o/--output: must be a file name ending in .png"),
    (["plot", "x.nc", "--at", "phidot0=nan"], "--at phidot0: must be finite"),
    (["plot", "x.nc", "-o", "adir"], "-o/--output: must be a file name ending in .png"),
    (["query", "x.nc", "--shape", "square", "--limit", "-1"], "--limit: must be >= 1"),
    (["refine", "--levels", "-1"], "--levels: must be >= 0"),
    (["refine", "--T", "-1"], "--T: must be > 0"),
    (["refine", "--coarse", "100000", "--levels", "20"], "--coarse/--levels:"),
    (["refine", "--theta0", "10", "nan"], "--theta0: must be finite"),
    (["find", "--shape", "square", "--theta0-deg", "nan", "--phidot0", "-3"],
     "--theta0-deg: must be finite"),
    (["find", "--shape", "square", "--theta0-deg", "-5", "--phidot0", "-3", "--bracket", "5", "1"],
     "--bracket: must have LO < HI"),
    (["find", "--shape", "square", "--phidot0", "-3", "--trace-theta0", "0", "10", "1e12"],
     "--trace-theta0 NUM: must be <= 100000"),
    # a spin of 1e9 rad/s ran for over 10 minutes; theta0 >= 90 deg said "no solution"
    (["find", "--shape", "square", "--theta0-deg", "-5", "--phidot0", "1e9"],
     "--phidot0: must be within +-1000 rad/s"),
    (["find", "--shape", "square", "--theta0-deg", "95", "--phidot0", "-3"],
     "--theta0-deg: |theta0| must be < 90 deg"),
    (["find", "--shape", "square", "--phidot0", "-3", "--trace-theta0", "80", "95", "4"],
     "--trace-theta0: |theta0| must be < 90 deg"),
    (["find", "--shape", "square", "--theta0-deg", "-5", "--phidot0", "-3", "--bracket", "0",
      "1e300"], "--bracket: must be within +-1000 rad/s"),
    (["refine", "--phidot0", "1e300"], "--phidot0: must be within +-1000 rad/s"),
    (["find", "--shape", "square", "--trace-theta0", "0", "20", "1"], "give --phidot0"),
    (["gallery", "."], ". is a folder"),
    (["refine", "--theta0", "-10", "95"], "--theta0: |theta0| must be < 90 deg"),
    (["path", "--theta0-deg", "-5", "--chidot0", "4", "--phidot0", "-3", "--chi0-deg", "1e15"],
     "--chi0-deg: must be within +-1e+06 deg"),
]


@pytest.mark.parametrize("argv,words", CLI_CASES, ids=[" ".join(a)[:50] for a, _ in CLI_CASES])
def test_bad_option_one_line_exit_2_nothing_written(tmp_path, capsys, monkeypatch, argv, words):
    (tmp_path / "s.toml").write_text(spec_text())
    (tmp_path / "adir").mkdir()
    (tmp_path / "adir.nc").mkdir()
    line = one_line_exit_2(capsys, argv, tmp_path, monkeypatch)
    assert line.startswith(f"ballsurvey {argv[0]}: error: {words}"), line
    assert list((tmp_path / "adir").iterdir()) == [] and list((tmp_path / "adir.nc").iterdir()) == []


@pytest.mark.parametrize("kw,words", [
    (dict(chidot0=math.nan), "chidot0: must be finite"),
    (dict(phidot0=math.inf), "phidot0: must be finite"),
    (dict(thetadot0="1"), "thetadot0: must be a number"),
    (dict(rtol=-1.0, method="dopri5"), "rtol: must be > 0"),
    (dict(rtol=1e-300, method="dopri5"), "rtol: must be in"),
    (dict(T=1e6, dt=1e-7), "dt: T/dt = 1e+13 steps"),
    (dict(T=1e308, dt=1e300, method="dop853"), "T: must be <= 1e+06"),
    (dict(T=-1.0), "T: must be > 0"),
    (dict(n_out=10**9), "n_out: must be <= 1e+07"),
    (dict(method="euler"), "method: unknown method"),
    (dict(phidot0=-1e9), "phidot0: must be within +-1000 rad/s"),
    (dict(chi0_deg=1e17), "chi0_deg: must be within +-1e+06 deg"),
])
def test_simulate_refuses_bad_input_at_once(kw, words):
    launch = dict(theta0_deg=-5.0, thetadot0=0.0, chidot0=4.05, phidot0=-3.0, T=1.0, dt=1e-3)
    launch.update(kw)
    t0 = time.time()
    with pytest.raises(InputError) as exc:
        simulate(**launch)
    assert str(exc.value).startswith(words) and "\n" not in str(exc.value)
    assert time.time() - t0 < 5


# ---------------------------------------------------------------------------------------------
# one writer per output
def test_second_run_is_refused_naming_the_running_process(tmp_path, reference):
    spec, parts = crashed_sweep(tmp_path, at=0)
    before = sorted(p.name for p in parts.iterdir())
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys; from ballsurvey.sweep.engine import OutputLock; "
         f"l = OutputLock({str(spec.output)!r}).acquire(); print('held', flush=True); "
         "sys.stdin.read()"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        for kw in (dict(), dict(force=True), dict(resume=True)):
            with pytest.raises(OutputBusy, match=f"being written by another sweep \\(pid "
                                                 f"{holder.pid}\\)"):
                run_sweep(spec, command="test", **kw)
            assert sorted(p.name for p in parts.iterdir()) == before  # --force deleted nothing
        r = subprocess.run([sys.executable, "-m", "ballsurvey", "sweep", str(tmp_path / "tiny.toml"),
                            "--force"], capture_output=True, text=True, timeout=120)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
        assert f"(pid {holder.pid})" in r.stderr and "wrote" not in r.stdout
    finally:
        holder.communicate("", timeout=30)
    same_map(run_sweep(spec, resume=True, command="test"), reference)
    assert not lock_path(spec.output).exists()


def test_lock_is_released_after_a_crash_and_a_refusal(tmp_path):
    spec, parts = crashed_sweep(tmp_path, at=0)
    assert not lock_path(spec.output).exists()
    with pytest.raises(FileExistsError, match="--resume"):
        run_sweep(spec, command="test")
    lock = OutputLock(spec.output).acquire()  # free again
    lock.release()


# ---------------------------------------------------------------------------------------------
# chunk plan and verified parts
def test_manifest_and_parts_describe_themselves(tmp_path):
    spec, parts = crashed_sweep(tmp_path, at=1)
    man = json.loads((parts / "manifest.json").read_text())
    assert man["spec_digest"] == spec.digest and man["chunk"] == 2 and man["n_chunks"] == 3
    assert man["shape"] == [3, 1, 2, 1]
    with np.load(parts / "chunk-000001.npz") as z:
        meta = json.loads(str(z["__meta__"]))
    assert (meta["chunk"], meta["lo"], meta["hi"], meta["spec_digest"]) == (1, 2, 4, spec.digest)
    assert len(meta["sha256"]) == 64


@pytest.mark.parametrize("chunk", [1, 3, 5])
def test_resume_uses_the_recorded_chunk_plan(tmp_path, reference, chunk):
    spec, parts = crashed_sweep(tmp_path, at=1)
    notes, done = [], []
    out = run_sweep(replace(spec, chunk=chunk), resume=True, command="test", notice=notes.append,
                    on_chunk=done.append)
    assert any(n.startswith("resuming with the recorded chunk plan (chunk = 2)") for n in notes)
    assert done == [2]  # only the missing chunk of the recorded plan
    same_map(out, reference)
    # and afterwards the output is current
    assert engine.output_is_current(spec)


def _swap(parts):
    shutil.copy(parts / "chunk-000001.npz", parts / "chunk-000000.npz")


def _truncate(parts):
    p = parts / "chunk-000000.npz"
    p.write_bytes(p.read_bytes()[:100])


def _empty(parts):
    (parts / "chunk-000000.npz").write_bytes(b"")


def _garbage(parts):
    (parts / "chunk-000000.npz").write_bytes(os.urandom(2000))


def _flip(parts):  # a valid zip whose data changed: only the checksum sees it
    p = parts / "chunk-000000.npz"
    with np.load(p) as z:
        d = {k: z[k] for k in z.files}
    d["theta_max_deg"] = d["theta_max_deg"] + 1.0
    np.savez(p, **d)


@pytest.mark.parametrize("damage,why", [(_swap, "holds chunk 1 (launches 2..4), expected chunk 0"),
                                        (_truncate, "unreadable"), (_empty, "unreadable"),
                                        (_garbage, "unreadable"), (_flip, "checksum mismatch")])
def test_damaged_part_is_named_and_computed_again(tmp_path, reference, damage, why):
    spec, parts = crashed_sweep(tmp_path, at=2)  # all three parts on disk
    damage(parts)
    notes, done = [], []
    out = run_sweep(spec, resume=True, command="test", notice=notes.append, on_chunk=done.append)
    assert done == [0]
    assert any("chunk-000000.npz failed verification (" + why in n for n in notes), notes
    same_map(out, reference)
    assert not parts.exists()


def test_part_damaged_after_the_check_is_computed_again_at_assembly(tmp_path, reference,
                                                                     monkeypatch):
    spec, parts = crashed_sweep(tmp_path, at=1)
    real = engine.assemble
    notes = []

    def damage_then_assemble(*a, **k):
        _garbage(parts)
        return real(*a, **k)

    monkeypatch.setattr(engine, "assemble", damage_then_assemble)
    same_map(run_sweep(spec, resume=True, command="test", notice=notes.append), reference)
    assert any("chunk-000000.npz failed verification" in n for n in notes)


def test_stray_part_is_ignored(tmp_path, reference):
    spec, parts = crashed_sweep(tmp_path, at=1)
    shutil.copy(parts / "chunk-000000.npz", parts / "chunk-000099.npz")
    (parts / "chunk-junk.npz").write_bytes(b"x")
    notes = []
    same_map(run_sweep(spec, resume=True, command="test", notice=notes.append), reference)
    assert sum("not a chunk of this sweep's plan" in n for n in notes) == 2


def test_part_of_another_spec_is_refused(tmp_path):
    other_text = TINY.replace("T = 2.0", "T = 1.5")
    o_spec, o_parts = crashed_sweep(tmp_path, "o.nc", at=2, text=other_text)
    spec, parts = crashed_sweep(tmp_path, at=0)
    shutil.copy(o_parts / "chunk-000001.npz", parts / "chunk-000001.npz")
    before = sorted(p.name for p in parts.iterdir())
    with pytest.raises(FileExistsError, match="chunk-000001.npz was made by another spec"):
        run_sweep(spec, resume=True, command="test")
    assert sorted(p.name for p in parts.iterdir()) == before and not spec.output.exists()


def test_manifest_without_a_chunk_plan_is_refused(tmp_path):
    spec, parts = crashed_sweep(tmp_path, at=0)
    man = json.loads((parts / "manifest.json").read_text())
    del man["chunk"]
    (parts / "manifest.json").write_text(json.dumps(man))
    with pytest.raises(FileExistsError, match="no chunk plan"):
        run_sweep(spec, resume=True, command="test")


# ---------------------------------------------------------------------------------------------
# nothing deleted before the final file is in place and verified; failures are one line
def test_failed_verification_keeps_the_parts(tmp_path, reference, monkeypatch):
    spec, parts = crashed_sweep(tmp_path, at=1)

    def bad(path, spec):
        raise RunError(f"the written map {path} does not hold this spec's results")

    monkeypatch.setattr(engine, "verify_output", bad)
    with pytest.raises(RunError):
        run_sweep(spec, resume=True, command="test")
    assert not spec.output.exists() and len(list(parts.glob("chunk-*.npz"))) == 3
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".tiny.nc.")]
    monkeypatch.undo()
    same_map(run_sweep(spec, resume=True, command="test"), reference)


@pytest.mark.parametrize("read", [None, 1])
def test_verification_reads_every_label(tmp_path, monkeypatch, read):
    """The written map is checked before the parts go: its spec digest, its shape and every
    label (a code outside the words, in the first or the last launch, fails it), whether the
    labels are read back at once or a chunk at a time."""
    import netCDF4

    spec = tiny_spec(tmp_path)
    out = run_sweep(spec, command="test")
    if read is not None:
        monkeypatch.setattr(engine, "VERIFY_READ", read)
    engine.verify_output(out, spec)
    with pytest.raises(RunError, match="does not hold"):
        engine.verify_output(out, replace(spec, digest="0" * 64))
    for cell, bad in (((0, 0, 0, 0), 99), ((-1, 0, -1, -1), -1)):
        with netCDF4.Dataset(out, "a") as nc:
            good = int(nc.variables["label"][cell])
            nc.variables["label"][cell] = bad
        with pytest.raises(RunError, match="does not hold"):
            engine.verify_output(out, spec)
        with netCDF4.Dataset(out, "a") as nc:
            nc.variables["label"][cell] = good
        engine.verify_output(out, spec)


def test_full_disk_at_assembly_is_one_line_and_leaves_no_temporary(tmp_path, reference,
                                                                    monkeypatch, capsys):
    def full(path, *a, **k):
        Path(path).write_bytes(b"partial")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(engine, "_write_netcdf", full)
    toml = tmp_path / "tiny.toml"
    tiny_spec(tmp_path)
    monkeypatch.chdir(tmp_path)
    for argv in (["sweep", str(toml)], ["sweep", str(toml), "--resume"]):
        code = main(argv)
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 1 and len(err) == 1 and "No space left on device" in err[0], err
        assert "--resume" in err[0]
        assert not [p for p in tmp_path.iterdir() if p.name.startswith(".tiny.nc.")]
        assert not (tmp_path / "tiny.nc").exists()
    monkeypatch.undo()
    assert main(["sweep", str(toml), "--resume"]) == 0
    same_map(tmp_path / "tiny.nc", reference)


@pytest.mark.parametrize("why", ["NetCDF: HDF error", "Permission denied"])
def test_a_full_disk_in_netcdfs_words_is_named_a_full_disk(tmp_path, monkeypatch, capsys, why):
    """netCDF4 and HDF5 report a full device as "NetCDF: HDF error", even "Permission denied"
    (both seen on a full tmpfs): with under a MiB free where the file was written, the line
    says that there is no room, with their words after; with room, their words alone."""
    def fails(path, *a, **k):
        Path(path).write_bytes(b"partial")
        raise RuntimeError(why)

    for free, full in ((4096, True), (10 << 30, False)):
        monkeypatch.setattr(engine, "_write_netcdf", fails)
        monkeypatch.setattr(engine, "_free_bytes", lambda folder, free=free: free)
        tiny_spec(tmp_path, f"full{free}.nc")
        monkeypatch.chdir(tmp_path)
        assert main(["sweep", str(tmp_path / "tiny.toml")]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and why in err[0] and "--resume" in err[0], err
        assert ("no space left on the device (4 kB free" in err[0]) == full, err
        assert ("--resume once there is room" in err[0]) == full, err
        monkeypatch.undo()


# ---------------------------------------------------------------------------------------------
# safe files
def test_planted_links_are_not_followed_and_leftovers_are_cleaned(tmp_path, reference):
    spec, parts = crashed_sweep(tmp_path, "tiny.nc", at=0)
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    pid = os.getpid()
    planted = [tmp_path / f".tiny.nc.{pid}.tmp", parts / f".chunk-000001.{pid}.tmp.npz",
               parts / f".chunk-000002.{pid}.tmp.npz"]
    for p in planted:
        p.symlink_to(victim)
    crashed_dir = tmp_path / ".tiny.nc.tmp-crashed"
    crashed_dir.mkdir()
    (crashed_dir / "tiny.nc").write_bytes(b"half")
    (parts / ".chunk-000001.abc123.tmp.npz").write_bytes(b"half")
    same_map(run_sweep(spec, resume=True, command="test"), reference)
    assert victim.read_text() == "keep me"
    assert not any(os.path.lexists(p) for p in planted) and not crashed_dir.exists()


def test_parts_dir_that_is_a_link_is_refused(tmp_path):
    spec = tiny_spec(tmp_path)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "precious").write_text("x")
    parts_dir(spec.output).symlink_to(elsewhere)
    for kw in (dict(), dict(force=True), dict(resume=True)):
        with pytest.raises(FileExistsError, match="is not a directory a sweep made"):
            run_sweep(spec, command="test", **kw)
    assert (elsewhere / "precious").read_text() == "x" and len(list(elsewhere.iterdir())) == 1


def test_lock_file_that_is_a_link_is_refused(tmp_path):
    spec = tiny_spec(tmp_path)
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    lock_path(spec.output).symlink_to(victim)
    with pytest.raises(FileExistsError, match="symbolic link"):
        run_sweep(spec, command="test")
    assert victim.read_text() == "keep me"


def test_printed_path_is_the_path_written(tmp_path, capsys, monkeypatch):
    tiny_spec(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert main(["sweep", "tiny.toml", "-o", "sub/m.nc"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("wrote sub/m.nc (6 launches)") and (tmp_path / "sub" / "m.nc").is_file()


def test_busy_output_on_the_command_line_is_exit_2(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "t2.toml").write_text(TINY.replace("OUT", "new/dir/b.nc"))
    holder = OutputLock(tmp_path / "new" / "dir" / "b.nc")
    (tmp_path / "new" / "dir").mkdir(parents=True)
    holder.acquire()
    try:
        assert main(["sweep", "t2.toml"]) == 2
    finally:
        holder.release()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"being written by another sweep (pid {os.getpid()})" in err[0]
    assert not (tmp_path / "new" / "dir" / "b.nc.parts").exists()


# ---------------------------------------------------------------------------------------------
# interruptions: bounded waits on dask
def test_unreachable_scheduler_is_one_line_after_a_bounded_wait(tmp_path, capsys, monkeypatch):
    pytest.importorskip("distributed")
    tiny_spec(tmp_path)
    monkeypatch.chdir(tmp_path)
    t0 = time.time()
    code = main(["sweep", "tiny.toml", "--scheduler", "tcp://127.0.0.1:1", "--dask-timeout", "2"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and "cannot reach the dask scheduler" in err[0], err
    assert time.time() - t0 < 30
    assert not (tmp_path / "tiny.nc").exists() and not parts_dir(tmp_path / "tiny.nc").exists()


def test_no_workers_left_ends_with_one_line_and_keeps_parts(tmp_path, reference):
    distributed = pytest.importorskip("distributed")
    spec, parts = crashed_sweep(tmp_path, at=0)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        cluster.scale(0)
        t0 = time.time()
        while client.nthreads() and time.time() - t0 < 30:
            time.sleep(0.1)
        assert not client.nthreads()
        t0 = time.time()
        with pytest.raises(RunError, match="no dask workers for 2 s; finished chunks are kept"):
            run_sweep(spec, resume=True, client=client, dask_wait_s=2.0, command="test")
        assert time.time() - t0 < 30
    assert (parts / "chunk-000000.npz").exists() and not spec.output.exists()
    assert not lock_path(spec.output).exists()
    same_map(run_sweep(spec, resume=True, command="test"), reference)


def test_ctrl_c_while_a_part_is_written_counts_only_what_is_on_disk(tmp_path, reference,
                                                                     monkeypatch):
    """Ctrl-C arriving as chunk 1's part is being written (in the background, while chunk 2
    runs): the write is finished first, so both parts are on disk, and the launches the run says
    it kept are those on disk (4, or 6 where chunk 2 had finished and was saved too); --resume
    gives the uninterrupted map."""
    import signal

    spec = tiny_spec(tmp_path, "w.nc")
    write = engine._write_part

    def write_part(parts, k, *args):
        if k == 1:
            os.kill(os.getpid(), signal.SIGINT)  # delivered at once, inside the write
        return write(parts, k, *args)

    monkeypatch.setattr(engine, "_write_part", write_part)
    with pytest.raises(engine.SweepInterrupted) as exc:
        run_sweep(spec, command="test")
    parts = parts_dir(spec.output)
    on_disk = sorted(p.name for p in parts.glob("chunk-*.npz"))
    assert on_disk[:2] == ["chunk-000000.npz", "chunk-000001.npz"], on_disk
    assert exc.value.kept == 2 * len(on_disk) and not list(parts.glob("partial-*"))
    monkeypatch.setattr(engine, "_write_part", write)
    same_map(run_sweep(spec, resume=True, command="test"), reference)


def _slow_writes(monkeypatch, log, delay=0.5, fail_at=None):
    """engine._write_part taking `delay` s (a slow disk), logging ('start', k, in the main
    thread?) and ('end', k); chunk `fail_at` fails as on a full disk."""
    import threading

    write = engine._write_part

    def write_part(parts, k, *args):
        log.append(("start", k, threading.current_thread() is threading.main_thread()))
        time.sleep(delay)
        if k == fail_at:
            raise OSError(errno.ENOSPC, "No space left on device")
        write(parts, k, *args)
        log.append(("end", k))
    monkeypatch.setattr(engine, "_write_part", write_part)
    return write


def test_parts_are_saved_in_the_background_in_order(tmp_path, reference, monkeypatch):
    """In this process a part is saved by a background thread while the next chunk runs: one
    at a time, in chunk order, and on_chunk(k) only once part k is on disk."""
    spec = tiny_spec(tmp_path, "bg.nc")
    log, seen, at_unit = [], [], {}
    _slow_writes(monkeypatch, log)

    def on_chunk(k):
        assert (parts_dir(spec.output) / f"chunk-{k:06d}.npz").is_file()
        seen.append(k)
    run_sweep(spec, command="test", on_chunk=on_chunk,
              on_unit=lambda done, total: at_unit.setdefault(done, list(log)))
    assert seen == [0, 1, 2]
    assert log == [("start", 0, False), ("end", 0), ("start", 1, False), ("end", 1),
                   ("start", 2, False), ("end", 2)]
    # chunk 1 was computed while chunk 0's part was being written (or was still waiting for
    # the writer's thread to start, on a busy machine): not after it
    assert at_unit[4] in ([], [("start", 0, False)]), at_unit
    same_map(spec.output, reference)


def test_chunks_are_labelled_in_the_part_writers_thread(tmp_path, reference, monkeypatch):
    """The labelling (numpy, one core) of a chunk runs in the part writer's thread, while the
    next chunk is integrated, and gives the same map bit for bit."""
    import threading

    from ballsurvey.sweep import compute

    spec = tiny_spec(tmp_path, "lab.nc")
    where = []
    label = compute.survey_fields

    def recorded(run, *asked):
        where.append(threading.current_thread().name)
        return label(run, *asked)
    monkeypatch.setattr(compute, "survey_fields", recorded)
    run_sweep(spec, command="test")
    assert where and all(name.startswith("ballsurvey-part") for name in where), where
    same_map(spec.output, reference)


def test_ctrl_c_while_a_part_is_saved_behind_keeps_it_and_the_chunk_after(tmp_path, reference,
                                                                         monkeypatch):
    """Ctrl-C as chunk 2 finishes while chunk 1's part is still being written: the run waits
    for it, saves chunk 2 after it, and counts the 6 launches on disk; --resume only
    assembles."""
    spec = tiny_spec(tmp_path, "bgc.nc")
    log = []
    write = _slow_writes(monkeypatch, log)

    def on_unit(done, total):
        if done == 6:
            raise KeyboardInterrupt
    with pytest.raises(engine.SweepInterrupted) as exc:
        run_sweep(spec, command="test", on_unit=on_unit)
    assert [e[1] for e in log if e[0] == "start"] == [0, 1, 2]
    parts = parts_dir(spec.output)
    assert len(list(parts.glob("chunk-*.npz"))) == 3 and exc.value.kept == 6
    monkeypatch.setattr(engine, "_write_part", write)
    redone = []
    same_map(run_sweep(spec, resume=True, command="test", on_chunk=redone.append), reference)
    assert redone == []


def test_a_part_failing_in_the_background_stops_the_run_and_it_resumes(tmp_path, reference,
                                                                       monkeypatch):
    """Chunk 0's part cannot be written (a full disk) while chunk 1 runs: the run stops with
    one RunError naming the part and what is kept, chunk 1 is not saved after it, chunk 2 is
    not computed, and --resume gives the uninterrupted map."""
    spec = tiny_spec(tmp_path, "bgf.nc")
    log, units = [], []
    write = _slow_writes(monkeypatch, log, delay=0.2, fail_at=0)
    with pytest.raises(RunError, match=r"chunk-000000\.npz: No space left on device; 0 of 6 "
                                       r"launches are kept .*--resume") as exc:
        run_sweep(spec, command="test", on_unit=lambda done, total: units.append(done))
    assert "\n" not in str(exc.value)
    assert log == [("start", 0, False)] and max(units) <= 4
    parts = parts_dir(spec.output)
    assert not list(parts.glob("chunk-*.npz")) and not list(parts.glob(".*tmp*"))
    monkeypatch.setattr(engine, "_write_part", write)
    same_map(run_sweep(spec, resume=True, command="test"), reference)


def _calls(monkeypatch):
    """The launch ranges the embedded run hands compute_chunk, in order."""
    calls = []
    compute_chunk = executors.compute_chunk

    def recorded(text, source, lo, hi, *args, **kw):
        calls.append((lo, hi))
        return compute_chunk(text, source, lo, hi, *args, **kw)
    monkeypatch.setattr(executors, "compute_chunk", recorded)
    return calls


def test_parallel_run_computes_successive_chunks_in_one_call_same_map(tmp_path, reference,
                                                                      monkeypatch):
    """With the parallel kernels, the chunks after the first (whose pace sets the unit) are
    computed in one call: parts and map are those of the chunk-by-chunk run, and on_chunk
    still hears of every chunk, in order, once its part is on disk."""
    spec = tiny_spec(tmp_path, "grp.nc")
    calls, seen = _calls(monkeypatch), []

    def on_chunk(k):
        assert (parts_dir(spec.output) / f"chunk-{k:06d}.npz").exists()
        seen.append(k)
    same_map(run_sweep(spec, command="test", parallel=True, on_chunk=on_chunk), reference)
    assert calls == [(0, 2), (2, 6)] and seen == [0, 1, 2]


def test_ctrl_c_within_a_call_of_several_chunks_keeps_them_all(tmp_path, reference,
                                                               monkeypatch):
    """Ctrl-C as a call of chunks 1 and 2 ends: both are saved (2 as the interrupted chunk, 1
    as a whole chunk before it), all 6 launches are counted, and --resume only assembles."""
    spec = tiny_spec(tmp_path, "grpc.nc")
    calls = _calls(monkeypatch)

    def on_unit(done, total):
        if done == 6:
            raise KeyboardInterrupt
    with pytest.raises(engine.SweepInterrupted) as exc:
        run_sweep(spec, command="test", parallel=True, on_unit=on_unit)
    assert calls == [(0, 2), (2, 6)] and exc.value.kept == 6
    assert len(list(parts_dir(spec.output).glob("chunk-*.npz"))) == 3
    redone = []
    same_map(run_sweep(spec, resume=True, command="test", on_chunk=redone.append), reference)
    assert redone == []


def test_a_part_failing_in_a_batch_stops_the_run_and_it_resumes(tmp_path, reference,
                                                                monkeypatch):
    """Chunks 1 and 2 are saved as one batch behind the run; chunk 1's part fails (a full
    disk): one RunError that counts only chunk 0 as kept, chunk 2 is not saved after it, and
    --resume gives the uninterrupted map."""
    spec = tiny_spec(tmp_path, "grpf.nc")
    log = []
    calls = _calls(monkeypatch)
    write = _slow_writes(monkeypatch, log, delay=0.05, fail_at=1)
    with pytest.raises(RunError, match=r"chunk-000001\.npz: No space left on device; 2 of 6 "
                                       r"launches are kept .*--resume"):
        run_sweep(spec, command="test", parallel=True)
    assert calls == [(0, 2), (2, 6)]
    assert [e[1] for e in log if e[0] == "start"] == [0, 1]
    assert [p.name for p in parts_dir(spec.output).glob("chunk-*.npz")] == ["chunk-000000.npz"]
    monkeypatch.setattr(engine, "_write_part", write)
    same_map(run_sweep(spec, resume=True, command="test"), reference)


def test_the_map_file_grows_as_parts_are_saved_and_a_stopped_run_drops_it(tmp_path,
                                                                          reference):
    """While a run computes, its netCDF file grows in a private temporary folder beside the
    output; a run that stops (an error, Ctrl-C) leaves no such folder, only its parts, and the
    resumed run adds the earlier run's chunks to its own file: the same map."""
    spec = tiny_spec(tmp_path, "grow.nc")
    seen = []

    def on_chunk(k):
        seen.append([p.name for p in tmp_path.glob(".grow.nc.tmp-*/grow.nc")])
        if k == 1:
            raise Crash
    with pytest.raises(Crash):
        run_sweep(spec, command="test", on_chunk=on_chunk)
    assert seen == [["grow.nc"], ["grow.nc"]]
    assert not list(tmp_path.glob(".*tmp*")) and not spec.output.exists()

    def on_unit(done, total):
        raise KeyboardInterrupt
    with pytest.raises(engine.SweepInterrupted):
        run_sweep(spec, resume=True, command="test", on_unit=on_unit)
    assert not list(tmp_path.glob(".*tmp*")) and not spec.output.exists()
    same_map(run_sweep(spec, resume=True, command="test"), reference)
    assert not list(tmp_path.glob(".*tmp*"))


def test_ctrl_c_while_the_growing_file_is_made_leaves_no_temporary_folder(tmp_path, reference,
                                                                          monkeypatch):
    """A Ctrl-C while the map file is being created (its folder made, the file not yet) stops
    the run and removes that folder; the next run makes the same map."""
    spec = tiny_spec(tmp_path, "early.nc")
    made = []

    def writer(path, *args, **kw):
        made.append(path.parent.is_dir())
        raise KeyboardInterrupt
    monkeypatch.setattr(engine, "MapWriter", writer)
    with pytest.raises((KeyboardInterrupt, engine.SweepInterrupted)):
        run_sweep(spec, command="test")
    assert made == [True]
    assert not list(tmp_path.glob(".*tmp*")) and not spec.output.exists()
    monkeypatch.undo()
    same_map(run_sweep(spec, resume=True, command="test"), reference)


def test_a_run_on_a_neighbouring_output_leaves_the_growing_file_alone(tmp_path, reference):
    """A run on a.nc cleans its own crashed runs' folders (.a.nc.tmp-XXXX), not the folder of
    a run on a.nc.tmp-b.nc beside it (.a.nc.tmp-b.nc.tmp-XXXX)."""
    spec = tiny_spec(tmp_path, "a.nc")
    mine = tmp_path / ".a.nc.tmp-crashed1"
    neighbour = tmp_path / ".a.nc.tmp-b.nc.tmp-k3x9q2"
    for d in (mine, neighbour):
        d.mkdir()
        (d / "x.nc").write_bytes(b"half")
    same_map(run_sweep(spec, command="test"), reference)
    assert not mine.exists() and (neighbour / "x.nc").read_bytes() == b"half"


def test_ctrl_c_splits_over_the_chunks_of_its_call():
    """A Ctrl-C after 3 launches of a call over chunks 1 and 2 (2 launches each): chunk 1 is
    whole (a prefix), chunk 2 holds its first launch (the interrupted chunk); one chunk in the
    call: the interruption is that chunk's, as it came."""
    from ballsurvey.sweep.compute import ChunkInterrupted, fields_of, n_launches

    chunks = [(0, 2, None), (2, 4, None), (4, 6, None)]
    got = {"label": np.array([10, 11, 12], dtype=np.int8), "x": np.array([1.0, 2.0, 3.0])}
    out = executors._split_interrupt(ChunkInterrupted(got, 3), [1, 2], chunks)
    assert out.chunk == 2 and out.done == 1 and list(out.prefixes) == [1]
    assert fields_of(out.result)["label"].tolist() == [12]
    assert fields_of(out.prefixes[1])["x"].tolist() == [1.0, 2.0]
    assert n_launches(out.prefixes[1]) == 2
    first = {k: v[:1] for k, v in got.items()}
    alone = executors._split_interrupt(ChunkInterrupted(first, 1), [2], chunks)
    assert alone.chunk == 2 and alone.done == 1 and alone.result is first
    assert not getattr(alone, "prefixes", None)
    none = executors._split_interrupt(ChunkInterrupted({}, 0), [1, 2], chunks)
    assert none.chunk == 1 and none.done == 0


def _launches_on_disk(spec):
    """Launches a run's parts hold: whole parts' chunks, partial parts' `done` (of chunks with
    no whole part)."""
    from ballsurvey.sweep.plan import plan_chunks

    chunks, parts = plan_chunks(spec.shape, spec.chunk), parts_dir(spec.output)
    whole = {int(p.name[6:12]) for p in parts.glob("chunk-*.npz")}
    n = sum(chunks[k][1] - chunks[k][0] for k in whole)
    for p in parts.glob("partial-*.npz"):
        if int(p.name[8:14]) not in whole:
            with np.load(p) as z:
                n += json.loads(str(z["__meta__"]))["done"]
    return n


@pytest.mark.parametrize("where", ["hand-over", "unwinding"])
def test_a_ctrl_c_no_handler_holds_counts_only_the_launches_on_disk(tmp_path, reference,
                                                                    monkeypatch, where):
    """A Ctrl-C where no handler holds it loses the launches of the call in hand: as a call's
    kernels return, before its chunks reach the writer ('hand-over'), or a second Ctrl-C while
    the first is on its way out of the run ('unwinding'). The one line counts the launches on
    disk (chunk 0's), not those computed, and --resume gives the uninterrupted map."""
    spec = tiny_spec(tmp_path, f"{where}.nc")
    calls, on_unit = _calls(monkeypatch), None
    if where == "hand-over":
        shares = executors._shares

        def cut(result, group, *args):
            if len(group) > 1:
                raise KeyboardInterrupt
            return shares(result, group, *args)
        monkeypatch.setattr(executors, "_shares", cut)
    else:
        stop = executors.stop_prefetch

        def second():
            monkeypatch.setattr(executors, "stop_prefetch", stop)
            stop()
            raise KeyboardInterrupt

        def on_unit(done, total):
            if done == 6:
                monkeypatch.setattr(executors, "stop_prefetch", second)
                raise KeyboardInterrupt
    with pytest.raises(engine.SweepInterrupted) as exc:
        run_sweep(spec, command="test", parallel=True, on_unit=on_unit)
    assert calls == [(0, 2), (2, 6)]
    assert exc.value.kept == _launches_on_disk(spec) == 2
    monkeypatch.undo()
    same_map(run_sweep(spec, resume=True, command="test"), reference)


@pytest.mark.parametrize("fail_at", [None, 1])
def test_a_call_may_begin_at_a_partial_part_and_a_failed_write_counts_it_kept(
        tmp_path, reference, monkeypatch, fail_at):
    """Chunk 0's part is missing and chunk 1 has a partial part (its first launch) from an
    earlier run: the parallel resume computes chunk 0, then chunks 1 and 2 in one call from the
    partial part on, and the map is the uninterrupted one without that launch computed again.
    A full disk at chunk 1's part: the one RunError counts the partial part, still on disk, as
    kept (3 of 6 launches), and --resume gives the map."""
    from ballsurvey.sweep.compute import compute_chunk
    from ballsurvey.sweep.parts import write_partial

    spec, parts = crashed_sweep(tmp_path, f"p{fail_at}.nc", at=0)
    (parts / "chunk-000000.npz").unlink()
    first = compute_chunk(spec.text, spec.source, 2, 3, parallel=False, spec=spec)
    write_partial(parts, 1, 2, 4, spec.digest, first, 1)
    calls, report = _calls(monkeypatch), {}
    if fail_at is None:
        same_map(run_sweep(spec, resume=True, command="test", parallel=True, report=report),
                 reference)
        assert report["resumed"] == 1 and report["computed"] == 5
    else:
        _slow_writes(monkeypatch, [], delay=0, fail_at=fail_at)
        with pytest.raises(RunError, match=r"chunk-000001\.npz: No space left on device; 3 of "
                                           r"6 launches are kept"):
            run_sweep(spec, resume=True, command="test", parallel=True)
        assert _launches_on_disk(spec) == 3
        monkeypatch.undo()
        same_map(run_sweep(spec, resume=True, command="test"), reference)
    assert calls[:2] == [(0, 2), (2, 6)]


def test_a_held_ctrl_c_goes_to_the_handler_that_was_there():
    """_DeferSigint holds a Ctrl-C during a part write: an ignored SIGINT (while an interrupted
    run saves its work) stays ignored, not a bare KeyboardInterrupt; a handler of the caller's
    gets it once, after the write; a write that fails still delivers it (review)."""
    import signal

    with engine._NoSigint():
        with engine._DeferSigint():
            os.kill(os.getpid(), signal.SIGINT)
    seen = []
    old = signal.signal(signal.SIGINT, lambda s, f: seen.append(s))
    try:
        with engine._DeferSigint():
            os.kill(os.getpid(), signal.SIGINT)
            assert seen == []
        assert seen == [signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, old)
    with pytest.raises(KeyboardInterrupt):
        with engine._DeferSigint():
            os.kill(os.getpid(), signal.SIGINT)
            raise OSError(28, "No space left on device")
    assert signal.getsignal(signal.SIGINT) is old


def test_a_point_out_of_bounds_is_named(tmp_path, capsys, monkeypatch):
    (tmp_path / "p.toml").write_text(
        '[[points]]\nname = "ok"\ntheta0_deg = 5.0\nthetadot0 = 0.0\nchidot0 = 4.0\n'
        'phidot0 = -3.0\n[[points]]\nname = "fast"\ntheta0_deg = 5.0\nthetadot0 = 0.0\n'
        'chidot0 = 4.0\nphidot0 = -3e4\n[run]\nT = 2.0\ndt = 1e-3\n'
        '[output]\nfile = "p.nc"\n')
    line = one_line_exit_2(capsys, ["sweep", "p.toml"], tmp_path, monkeypatch)
    assert "[[points]] 'fast' phidot0: must be within +-1000 rad/s" in line, line

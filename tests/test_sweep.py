"""Sweeps: spec validation, chunk plans, storage (CF), resume after a crash, dask = embedded."""
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from ballsurvey.classify.labels import CODE
from ballsurvey.sweep import SpecError, load_spec, plan_chunks, run_sweep
from ballsurvey.sweep.engine import parts_dir

ROOT = Path(__file__).resolve().parents[1]

SMALL = """
title = "small"
[launch]
theta0_deg = {start = -10.0, stop = 20.0, num = 4}
thetadot0 = 0.0
chidot0 = [2.3, 4.05, 8.0]
phidot0 = [-3.0, -2.5]
[run]
T = 3.0
dt = 5e-4
chunk = 5
[output]
file = "OUT"
"""


def small_spec(tmp_path, name="small.nc", text=SMALL):
    p = tmp_path / "small.toml"
    p.write_text(text.replace("OUT", str(tmp_path / name)))
    return load_spec(p)


def test_plan_chunks_cover_the_grid_once():
    for shape, chunk in [((4, 3, 2, 1), 5), ((100, 100, 100), 4096), ((1, 1, 7, 1), 3),
                         ((3, 4), 100), ((5,), 2)]:
        flat = np.arange(int(np.prod(shape))).reshape(shape)
        seen = []
        for lo, hi, slab in plan_chunks(shape, chunk):
            assert 0 < hi - lo <= chunk
            assert np.array_equal(flat[slab].ravel(), np.arange(lo, hi))
            seen.append((lo, hi))
        assert seen[0][0] == 0 and seen[-1][1] == flat.size
        assert all(a[1] == b[0] for a, b in zip(seen, seen[1:]))


def test_storage_chunks_lie_inside_one_slab_each():
    """netCDF storage chunks never straddle two write slabs (a straddled chunk is decompressed and
    compressed again at each write: the 1e8-launch map spent minutes there) where the slabs' run
    has a divisor near the even split: every slab then starts and ends on storage-chunk
    boundaries (or the axis end). A run without one (prime) gets the even split, each chunk
    meeting at most two slabs, not slivers. Never more than the target's values a chunk."""
    import math

    from ballsurvey.store import storage_chunks

    def slabs_met(shape, plan, sizes):
        """Most slabs one storage chunk meets (by the flat ranges of the chunks' cells)."""
        owner = np.empty(shape, dtype=np.int64)
        for k, (_lo, _hi, slab) in enumerate(plan):
            owner[slab] = k
        grid = [range(0, s, c) for s, c in zip(shape, sizes)]
        most = 0
        for corner in np.ndindex(*[len(g) for g in grid]):
            box = tuple(slice(g[j], g[j] + c) for g, j, c in zip(grid, corner, sizes))
            most = max(most, len(np.unique(owner[box])))
        return most

    aligned = [((464, 1, 464, 464), 1 << 20, 1 << 20), ((100, 1, 100, 100), 8192, 1 << 20),
               ((3000, 3000), 1 << 22, 1 << 20), ((41, 1, 45, 1), 4096, 1 << 20),
               ((4, 3, 2, 1), 5, 4), ((97, 89), 1000, 64), ((600,), 4096, 100), ((7,), 3, 2),
               ((1031, 1031), 2_000_000, 1 << 16)]
    for shape, chunk, target in aligned:
        plan = plan_chunks(shape, chunk)
        sizes = storage_chunks(plan[0][2], shape, target)
        assert len(sizes) == len(shape) and all(1 <= c <= s for c, s in zip(sizes, shape))
        assert math.prod(sizes) <= target, (shape, sizes)
        for _lo, _hi, slab in plan:
            for ax, (s, c) in enumerate(zip(slab, sizes)):
                a, b = (s, s + 1) if isinstance(s, int) else (s.start, s.stop)
                assert a % c == 0 and (b % c == 0 or b == shape[ax]), (shape, chunk, slab, sizes)
    # one slab along the split axis: not cut to single rows for want of a divisor
    assert storage_chunks(plan_chunks((1031, 1031), 2_000_000)[0][2], (1031, 1031),
                          1 << 16)[0] > 1
    # a prime run (1009 rows of 7 a slab): the even split, at most two slabs a chunk
    shape, chunk, target = (2000, 7), 1009 * 7, 7 * 300
    plan = plan_chunks(shape, chunk)
    sizes = storage_chunks(plan[0][2], shape, target)
    assert math.prod(sizes) <= target and sizes[0] >= 150, sizes
    assert slabs_met(shape, plan, sizes) <= 2
    for shape, chunk, target in aligned[4:8]:
        plan = plan_chunks(shape, chunk)
        assert slabs_met(shape, plan, storage_chunks(plan[0][2], shape, target)) == 1


def test_sweep_writes_a_cf_file_that_xarray_reads(tmp_path):
    spec = small_spec(tmp_path)
    out = run_sweep(spec, command="test")
    ds = xr.open_dataset(out)
    assert ds.label.dims == ("theta0_deg", "thetadot0", "chidot0", "phidot0")
    assert ds.label.shape == (4, 1, 3, 2)
    assert ds.label.dtype == np.int8
    assert ds.label.attrs["flag_meanings"].split()[:6] == ["circle", "near_straight", "triangle",
                                                           "square", "ngon", "star"]
    assert ds.theta0_deg.attrs["units"] == "degree" and ds.chidot0.attrs["units"] == "rad s-1"
    assert ds.attrs["Conventions"] == "CF-1.10"
    assert "chunk = 5" in ds.attrs["spec_toml"]
    assert ds.attrs["ball_c"] == 0.0029
    # Fig. 12a's launch is in the grid: theta0 = -10 -> no; (-10, 2.3, -2.5) is Fig. 12b
    assert int(ds.label.sel(theta0_deg=-10.0, chidot0=2.3, phidot0=-2.5).item()) == CODE["triangle"]
    assert not parts_dir(out).exists()


def test_cf_compliance(tmp_path):
    from compliance_checker.runner import CheckSuite, ComplianceChecker

    CheckSuite.load_all_available_checkers()
    out = run_sweep(small_spec(tmp_path), command="test")
    spec_pts = load_spec(ROOT / "sweeps" / "paper.toml")
    spec_pts = replace(spec_pts, output=tmp_path / "paper.nc", T=2.0, dt=1e-3)
    pts = run_sweep(spec_pts, command="test")
    for path in (out, pts):
        report = tmp_path / f"{path.stem}.json"
        passed, errors = ComplianceChecker.run_checker(str(path), ["cf:1.10"], 0, "strict",
                                                       output_filename=str(report),
                                                       output_format="json")
        assert passed and not errors, report.read_text()[:2000]


def test_results_do_not_depend_on_chunking(tmp_path):
    a = xr.open_dataset(run_sweep(small_spec(tmp_path, "a.nc"), command="test"))
    b_spec = replace(small_spec(tmp_path, "b.nc"), chunk=1000)
    b = xr.open_dataset(run_sweep(b_spec, command="test"))
    for v in a.data_vars:
        assert np.array_equal(a[v].values, b[v].values, equal_nan=True), v


def test_a_map_written_as_it_runs_is_the_one_assembled_from_held_parts_or_files(tmp_path,
                                                                                monkeypatch):
    """A run writes its map file as its parts are saved; where that file cannot be written (it
    is dropped), the run assembles the map from the parts it holds in memory; with no room to
    hold any, from the part files it wrote: the same numbers each way."""
    from ballsurvey.store import MapWriter
    from ballsurvey.sweep import engine

    read, put = [], []
    real = engine.read_part
    monkeypatch.setattr(engine, "read_part", lambda *a, **k: read.append(1) or real(*a, **k))

    class Counted(MapWriter):
        def put(self, k, part):
            put.append(k)
            super().put(k, part)

    monkeypatch.setattr(engine, "MapWriter", Counted)
    spec = small_spec(tmp_path, "a.nc")
    n_chunks = len(plan_chunks(spec.shape, spec.chunk))
    a = xr.open_dataset(run_sweep(spec, command="test"))
    assert not read and sorted(put) == list(range(n_chunks)) and n_chunks > 1

    class Failing(MapWriter):
        def put(self, k, part):
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(engine, "MapWriter", Failing)
    b = xr.open_dataset(run_sweep(small_spec(tmp_path, "b.nc"), command="test"))
    assert not read  # from the parts held
    monkeypatch.setattr(engine, "HELD_PARTS_BYTES", 0)
    c = xr.open_dataset(run_sweep(small_spec(tmp_path, "c.nc"), command="test"))
    assert len(read) == n_chunks  # every part read back
    assert not list(tmp_path.glob(".*tmp*"))  # the dropped files went with their folders
    for v in a.data_vars:
        for other in (b, c):
            assert np.array_equal(a[v].values, other[v].values, equal_nan=True), v


class Boom(Exception):
    pass


def test_resume_after_a_crash_gives_the_same_file(tmp_path):
    ref = xr.open_dataset(run_sweep(small_spec(tmp_path, "ref.nc"), command="test"))
    spec = small_spec(tmp_path, "crash.nc")

    def crash(k):
        if k == 2:
            raise Boom

    with pytest.raises(Boom):
        run_sweep(spec, on_chunk=crash, command="test")
    parts = parts_dir(spec.output)
    assert len(list(parts.glob("chunk-*.npz"))) == 3 and not spec.output.exists()
    with pytest.raises(FileExistsError, match="--resume"):
        run_sweep(spec, command="test")
    other = small_spec(tmp_path, "crash.nc", SMALL.replace("T = 3.0", "T = 4.0"))
    with pytest.raises(FileExistsError, match="different spec"):
        run_sweep(other, resume=True, command="test")
    done = []
    got = xr.open_dataset(run_sweep(spec, resume=True, on_chunk=done.append, command="test"))
    assert 0 not in done and 1 not in done and 2 not in done  # finished chunks were not redone
    for v in ref.data_vars:
        assert np.array_equal(ref[v].values, got[v].values, equal_nan=True), v


def test_existing_result_is_not_overwritten_without_force(tmp_path):
    spec = small_spec(tmp_path, "keep.nc")
    out = run_sweep(spec, command="test")
    before = out.read_bytes()
    other = small_spec(tmp_path, "keep.nc", SMALL.replace("T = 3.0", "T = 4.0"))
    with pytest.raises(FileExistsError, match="another spec"):
        run_sweep(other, command="test")
    assert out.read_bytes() == before
    run_sweep(other, force=True, command="test")
    assert xr.open_dataset(out).attrs["run_T_s"] == 4.0


def test_kill_9_loses_only_chunks_in_flight(tmp_path):
    # chunks of about 0.1 s each (two launches of 1e6 steps), so that the run cannot finish
    # between two looks at its parts on a busy machine
    text = SMALL.replace("T = 3.0", "T = 100.0").replace("dt = 5e-4", "dt = 1e-4") \
        .replace("chunk = 5", "chunk = 2")
    spec = small_spec(tmp_path, "killed.nc", text)
    cmd = [sys.executable, "-m", "ballsurvey", "sweep", str(tmp_path / "small.toml"), "--no-progress"]
    proc = subprocess.Popen(cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    parts = parts_dir(spec.output)
    t0 = time.time()
    while len(list(parts.glob("chunk-*.npz"))) < 2 and time.time() - t0 < 120:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    kept = len(list(parts.glob("chunk-*.npz")))
    assert 2 <= kept < len(plan_chunks(spec.shape, spec.chunk))
    assert json.loads((parts / "manifest.json").read_text())["spec_digest"] == spec.digest
    # the half-grown map file stays, hidden, until the next run on this output removes it
    assert len(list(tmp_path.glob(".killed.nc.tmp-*/killed.nc"))) == 1
    r = subprocess.run(cmd + ["--resume"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert not list(tmp_path.glob(".killed.nc.tmp-*"))
    ref = xr.open_dataset(run_sweep(replace(spec, output=tmp_path / "ref.nc"), command="test"))
    got = xr.open_dataset(spec.output)
    for v in ref.data_vars:
        assert np.array_equal(ref[v].values, got[v].values, equal_nan=True), v


#: one chunk of 130 launches: on two workers, it goes as two tasks (`task_ranges`)
ONE_CHUNK = SMALL.replace("num = 4", "num = 13").replace("[-3.0, -2.5]", "[-3.0, -2.5, -2.0]") \
    .replace("[2.3, 4.05, 8.0]", "[1.0, 2.3, 3.0, 4.05, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0]") \
    .replace("chunk = 5", "chunk = 4096").replace("T = 3.0", "T = 0.3")


def test_dask_local_cluster_matches_embedded(tmp_path):
    distributed = pytest.importorskip("distributed")
    from ballsurvey.sweep.executors import task_ranges

    one_chunk = small_spec(tmp_path, "emb1.nc", ONE_CHUNK)
    assert one_chunk.n_launches == 390 and len(task_ranges([(0, 390)], [0], 2)) == 1
    assert len(task_ranges([(0, 390)], [0], 2)[0]) == 6  # tasks of 65 launches
    seen = []  # progress of the one-chunk map: as each task comes back
    refs = [xr.open_dataset(run_sweep(small_spec(tmp_path, "emb.nc"), command="test")),
            xr.open_dataset(run_sweep(one_chunk, command="test"))]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        gots = [xr.open_dataset(run_sweep(small_spec(tmp_path, "dask.nc"), client=client,
                                          command="test")),
                xr.open_dataset(run_sweep(small_spec(tmp_path, "dask1.nc", ONE_CHUNK),
                                          client=client, command="test",
                                          on_unit=lambda done, total: seen.append(done)))]
    assert len(seen) == 6 and seen == sorted(seen) and seen[-1] == 390
    for ref, got in zip(refs, gots):
        for v in ref.data_vars:
            assert np.array_equal(ref[v].values, got[v].values, equal_nan=True), v


def _interrupt_after(n):
    """on_unit for run_sweep: Ctrl-C once n launches are reported done."""
    def on_unit(done, total):
        if done >= n:
            raise KeyboardInterrupt
    return on_unit


def _partial_lengths(parts):
    out = {}
    for p in parts.glob("partial-*.npz"):
        with np.load(p) as z:
            out[p.name] = json.loads(str(z["__meta__"]))["done"]
    return out


def test_dask_ctrl_c_keeps_a_chunks_tasks_in_a_row_and_resume_uses_partials(tmp_path):
    """Ctrl-C on a dask run keeps, of a chunk not yet whole, its launches back in a row from its
    start (a partial part), says exactly how many it kept, and --resume on dask computes only the
    rest; an embedded run's partial part is used by a dask resume the same way."""
    distributed = pytest.importorskip("distributed")
    from ballsurvey.sweep.engine import SweepInterrupted

    ref = xr.open_dataset(run_sweep(small_spec(tmp_path, "ref.nc", ONE_CHUNK), command="t"))
    emb = small_spec(tmp_path, "emb.nc", ONE_CHUNK)
    with pytest.raises(SweepInterrupted) as caught:  # embedded: stops after its first unit
        run_sweep(emb, command="t", on_unit=_interrupt_after(1))
    kept_emb = caught.value.kept
    assert 0 < kept_emb < 390
    assert list(_partial_lengths(parts_dir(emb.output)).values()) == [kept_emb]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        seen, report = [], {}
        run_sweep(emb, resume=True, client=client, command="t", report=report,
                  on_unit=lambda done, total: seen.append(done))
        assert report["resumed"] == kept_emb and report["computed"] == 390 - kept_emb
        assert seen == sorted(seen) and seen[-1] == 390  # no launch counted twice
        same_maps(ref, xr.open_dataset(emb.output))

        dsk = small_spec(tmp_path, "dask.nc", ONE_CHUNK)
        with pytest.raises(SweepInterrupted) as caught:
            run_sweep(dsk, client=client, command="t", on_unit=_interrupt_after(130))
        kept = caught.value.kept
        on_disk = sum(_partial_lengths(parts_dir(dsk.output)).values())
        assert kept == on_disk and kept % 65 == 0  # whole tasks of 65, in a row from 0
        report = {}
        run_sweep(dsk, resume=True, client=client, command="t", report=report)
        assert report["resumed"] == kept
        same_maps(ref, xr.open_dataset(dsk.output))

        # chunks of one task each: a Ctrl-C at the first progress finds that chunk already saved
        # as a whole part (a whole chunk saved as a partial part would be refused on resume)
        many = small_spec(tmp_path, "many.nc")
        with pytest.raises(SweepInterrupted) as caught:
            run_sweep(many, client=client, command="t", on_unit=_interrupt_after(1))
        parts = parts_dir(many.output)
        plan = plan_chunks(many.shape, many.chunk)
        saved = [int(f.stem.split("-")[1]) for f in parts.glob("chunk-*.npz")]
        assert caught.value.kept == sum(plan[k][1] - plan[k][0] for k in saved) > 0
        assert not list(parts.glob("partial-*.npz"))
        report = {}
        run_sweep(many, resume=True, client=client, command="t", report=report)
        assert report["resumed"] == caught.value.kept
        same_maps(xr.open_dataset(run_sweep(small_spec(tmp_path, "many-ref.nc"), command="t")),
                  xr.open_dataset(many.output))


def same_maps(ref, got):
    for v in ref.data_vars:
        assert np.array_equal(ref[v].values, got[v].values, equal_nan=True), v


def test_task_ranges_cover_each_chunk_once_and_spread_one_chunk_over_the_threads():
    from ballsurvey.sweep.executors import MIN_TASK_LAUNCHES, TASKS_PER_THREAD, task_ranges

    for shape, chunk, threads in [((41, 45), 4096, 16), ((41, 45), 4096, 2), ((100, 100), 512, 8),
                                  ((7,), 4096, 16), ((3, 4), 5, 1), ((1000,), 300, 1000)]:
        chunks = plan_chunks(shape, chunk)
        todo = list(range(len(chunks)))[::-1]  # any order, any subset
        ranges = task_ranges(chunks, todo, threads)
        assert sorted(ranges) == sorted(todo)
        n_tasks = sum(len(r) for r in ranges.values())
        n = int(np.prod(shape))
        for k, r in ranges.items():
            lo, hi = chunks[k][0], chunks[k][1]
            assert r[0][0] == lo and r[-1][1] == hi  # the chunk, once, in order, no gaps
            assert all(a[1] == b[0] and a[0] < a[1] for a, b in zip(r, r[1:] + [(hi, hi + 1)]))
            assert all(b - a >= min(hi - lo, MIN_TASK_LAUNCHES) for a, b in r)
        if n >= 2 * MIN_TASK_LAUNCHES * threads * TASKS_PER_THREAD:
            assert n_tasks >= threads * TASKS_PER_THREAD // 2  # every thread gets work
    # the square map (one chunk of 1845) on 16 workers: every one of them busy
    assert len(task_ranges(plan_chunks((41, 45), 4096), [0], 16)[0]) >= 16


def test_paper_points_spec_labels():
    spec = load_spec(ROOT / "sweeps" / "paper.toml")
    assert spec.kind == "points" and spec.shape == (6,)


BAD = [
    ("nope = 1", "unknown key"),
    ("[launch]\ntheta0_deg = 'x'", "must be a number"),
    ("theta0_deg = {start = 10.0, stop = 0.0, num = 5}", "reversed range"),
    ("theta0_deg = []", "empty list"),
    ("theta0_deg = nan", "must be finite"),
    ("theta0_deg = inf", "must be finite"),
    ("theta0_deg = -40.0", "flat face"),
    ("theta0_deg = 90.0", "< 90 deg"),
    ("T = 0.0", "must be > 0"),
    ("T = -1.0", "must be > 0"),
    ("dt = 0.0", "must be > 0"),
    ("dt = 5.0", "must be <= T"),
    ("method = 'euler'", "unknown method"),
    ("mu = -1.0", "finite and >= 0"),
    ("variables = ['label', 'colour']", "unknown variable"),
    ("chidot0 = {start = 1.0, stop = 2.0}", "missing num"),
]


def _bad_text(fragment):
    base = {"[launch]": ["theta0_deg = 5.0", "thetadot0 = 0.0", "chidot0 = 4.0", "phidot0 = -3.0"],
            "[run]": ["T = 2.0", "dt = 1e-3"], "[classify]": [], "[output]": ["file = 'x.nc'"]}
    key = fragment.split("=")[0].strip()
    if fragment.startswith("[launch]"):
        return fragment + "\nthetadot0 = 0.0\nchidot0 = 4.0\nphidot0 = -3.0\n[run]\nT = 2.0\n"
    if key == "nope":
        return fragment + "\n" + "\n".join(["[launch]"] + base["[launch]"] + ["[run]"] + base["[run]"])
    sec = next(s for s, ks in {"[launch]": ["theta0_deg", "chidot0"], "[run]": ["T", "dt", "method"],
                               "[classify]": ["mu"], "[output]": ["variables"]}.items() if key in ks)
    lines = []
    for s, ks in base.items():
        lines.append(s)
        lines += [k for k in ks if k.split("=")[0].strip() != key]
        if s == sec:
            lines.append(fragment)
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("fragment,message", BAD)
def test_bad_specs_are_refused_with_one_line(tmp_path, fragment, message):
    p = tmp_path / "bad.toml"
    p.write_text(_bad_text(fragment))
    with pytest.raises(SpecError, match=message):
        load_spec(p)


def test_bad_spec_on_the_command_line_exits_2_and_writes_nothing(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text(_bad_text("theta0_deg = nan").replace("'x.nc'", "'out/x.nc'"))
    r = subprocess.run([sys.executable, "-m", "ballsurvey", "sweep", str(p)], cwd=tmp_path,
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "theta0_deg" in r.stderr
    assert not (tmp_path / "out").exists()


def test_unwritable_output_is_refused(tmp_path):
    if os.geteuid() == 0:
        target = "/proc/ballsurvey-cannot-write/x.nc"  # not writable even for root
    else:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        target = str(ro / "x.nc")
    spec = replace(small_spec(tmp_path), output=Path(target))
    with pytest.raises(PermissionError, match="cannot write"):
        run_sweep(spec, command="test")

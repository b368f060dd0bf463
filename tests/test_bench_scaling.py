"""`ballsurvey bench --scaling`: the headline map as fresh sweep processes on 1 thread, on threads
and on dask workers; the fixed cost per process and each run's wall, kernels and rest; identical
maps. Printed structure and arithmetic only: timings on a shared machine are not asserted."""
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HAS_DASK = importlib.util.find_spec("distributed") is not None


def run(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "ballsurvey", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout)


def test_scaling_on_the_headline_map_prints_fixed_cost_kernels_rest_and_same_maps():
    r = run("bench", "--scaling", "--headline", "3", "--T", "2", "--threads", "2",
            "--workers", "2")
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert "the headline map, N = 3: 27 launches, T = 2.0 s, method dop853, mode period" in out
    fixed = re.search(r"fixed cost per process \(a fresh process sweeping 8 launches.*\): "
                      r"([\d.]+) s on 1 thread \(numba start ([\d.]+) s, kernels ([\d.]+) s\), "
                      r"([\d.]+) s on 2 threads \(numba start ([\d.]+) s, kernels ([\d.]+) s\)",
                      out)
    assert fixed, out
    wall1, start1, kernels1, wall2, start2, kernels2 = map(float, fixed.groups())
    assert wall1 > start1 + kernels1 and wall2 > start2 + kernels2, out
    assert start1 > 0 and start2 > 0, out
    names = ["1 thread, one process", "2 threads, one process"]
    names += ["--workers 2 (dask, 1 thread each)"] if HAS_DASK else []
    rows = {}
    for name in names:
        m = re.search(re.escape(name) + r" +([\d.]+) +(\d+)% +([\d.]+) +(-?[\d.]+) +([\d.]+)x +"
                      r"([\d.]+)x", out)
        assert m, (name, out)
        rows[name] = [float(v) for v in m.groups()]
    one_wall, one_kernels = rows[names[0]][0], rows[names[0]][2]
    for name, (wall, _, kernels, rest, up_wall, up_kernels) in rows.items():
        # every launch integrates: the kernels' time is read from each child's `sweep -v`
        assert kernels > 0, (name, out)
        assert abs(kernels + rest - wall) <= 0.011, (name, out)  # printed to 0.01 s each
        assert up_wall == pytest.approx(one_wall / wall, abs=0.051 + 0.01 * one_wall / wall)
        assert up_kernels == pytest.approx(one_kernels / kernels,
                                           abs=0.051 + 0.01 * one_kernels / kernels)
    assert rows[names[0]][4] == 1.0 and rows[names[0]][5] == 1.0
    if HAS_DASK:
        assert re.search(r"dask: cluster start [\d.]+ s, the workers' first call \(imports, "
                         r"kernels loaded\) [\d.]+ s, closing the cluster [\d.]+ s", out), out
    else:
        assert "--workers left out: dask is not installed" in out
    assert re.search(r"with this fixed cost \([\d.]+ s\), 2 threads can at best give [\d.]+x",
                     out), out
    assert f"the {len(names)} maps are the same, bit for bit: yes" in out


def test_phase_times_reads_what_sweep_verbose_prints():
    """The bench's reader of a child's times against the line `sweep -v` writes, both kinds."""
    from ballsurvey.bench import _phase_times
    from ballsurvey.cli import _where_the_time_went
    from ballsurvey.compose import TIMES

    saved = dict(TIMES)
    TIMES.clear()
    TIMES.update({"integrate": 1.25, "near-vertical fallback": 0.5, "label": 0.125})
    try:
        line = _where_the_time_went({"wall_s": 3.0, "compile_s": 0.4, "numba_start_s": 0.25},
                                    on_dask=False)
    finally:
        TIMES.clear()
        TIMES.update(saved)
    assert _phase_times("other\n" + line) == {"numba start": 0.25, "integrate": 1.25,
                                              "near-vertical fallback": 0.5,
                                              "label": 0.12}  # .2f rounds 0.125 to even
    report = {"wall_s": 5.0, "cluster_start_s": 1.5, "workers_start_s": 0.75, "n_workers": 4,
              "cluster_close_s": 0.5, "worker_times": {"integrate": 8.0, "label": 1.0}}
    got = _phase_times(_where_the_time_went(report, on_dask=True))
    # the kernels: each worker's on average, the sums over the 4 workers / 4
    assert got == {"dask cluster start": 1.5, "workers' first call": 0.75,
                   "the run on the cluster": 5.0, "closing": 0.5, "integrate": 2.0,
                   "label": 0.25}


@pytest.mark.parametrize("args, says", [
    (["--scaling"], "--scaling: give a spec file (.toml), or --headline [N]"),
    (["--scaling", "sweeps/quick.toml", "--headline", "3"], "not both"),
    (["--threads", "2", "--headline", "3"], "go with --scaling"),
    (["--scaling", "--headline", "0"], "--headline: must be >= 1"),
])
def test_scaling_input_errors_are_one_line_exit_2(args, says):
    r = run("bench", *args)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert says in r.stderr, r.stderr


def test_code_digest_is_read_back_from_its_cache_only_for_the_same_sources(tmp_path,
                                                                            monkeypatch):
    """A part of each process's fixed cost kept on disk: the stored digest is used while every
    source byte is the same, and computed again after any change (here a comment) or when the
    stored line is not a digest."""
    import shutil

    import ballsurvey
    from ballsurvey.sweep import provenance

    pkg = tmp_path / "pkg"
    shutil.copytree(Path(ballsurvey.__file__).parent, pkg,
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    monkeypatch.setattr(provenance, "PACKAGE", pkg)

    def digest():
        provenance._module_code.cache_clear()
        provenance.code_digest.cache_clear()
        return provenance.code_digest()

    try:
        _digest_cache_checks(pkg, digest)
    finally:
        provenance._module_code.cache_clear()
        provenance.code_digest.cache_clear()


def _digest_cache_checks(pkg, digest):
    from ballsurvey.sweep import provenance

    real = digest()
    cache = pkg / "__pycache__" / provenance.DIGEST_CACHE
    key, stored = cache.read_text().split()
    assert stored == real
    cache.write_text(f"{key} {'f' * 64}\n")
    assert digest() == "f" * 64  # the same sources: read back, not computed
    labels = pkg / "classify" / "labels.py"
    labels.write_text(labels.read_text() + "\n# a comment\n")
    assert digest() == real  # another key: computed (a comment leaves the digest unchanged)
    assert cache.read_text().split()[0] != key
    cache.write_text("not a digest\n")
    assert digest() == real

"""No stale kernels: an edit to a physics file reaches every cached kernel that inlines it.

Each run is a fresh process on a private copy of the package with private caches (the generated
kernel modules in $BALLSURVEY_CACHE_DIR, numba's index and object files in $NUMBA_CACHE_DIR), so
the only thing carried between runs is what the on-disk caches keep. The edit changes one digit of
a coefficient in theta's equation in physics/euler.py, which the ensemble kernel inlines from
another file; the file keeps its size and its modification time (the nastiest case: numba's own
freshness check looks only at the file that defines a cached function).
"""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

import ballsurvey

PKG = Path(ballsurvey.__file__).resolve().parent

#: one short launch through the ensemble kernel; prints theta exactly, which ballsurvey ran and
#: whether the block kernel came from numba's on-disk cache
SCRIPT = r"""
import json, ballsurvey
from ballsurvey.integrate import ensemble
ds = ballsurvey.simulate(theta0_deg=-5, thetadot0=0, chidot0=4.05, phidot0=-3, T=0.05, dt=1e-3,
                         n_out=11)
from ballsurvey.compose import OBSERVER
run_serial = ensemble.make_kernels("rk4", OBSERVER)[1]
st = run_serial.stats
print(json.dumps({"theta": [float(v).hex() for v in ds.theta.values],
                  "file": ballsurvey.__file__,
                  "hits": sum(st.cache_hits.values()), "misses": sum(st.cache_misses.values())}))
"""

ORIGINAL = "thdd = cth / (A + 1.0 - 2.0 * c * sth + c * c) * ("
EDITED = "thdd = cth / (A + 1.0 - 3.0 * c * sth + c * c) * ("


def _copy_package(tmp_path: Path) -> Path:
    src = tmp_path / "src"
    shutil.copytree(PKG, src / "ballsurvey", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    return src


def _run(src: Path, tmp_path: Path) -> dict:
    env = dict(os.environ)
    env.update(PYTHONPATH=str(src), BALLSURVEY_CACHE_DIR=str(tmp_path / "kernels"),
               NUMBA_CACHE_DIR=str(tmp_path / "numba"),
               # no .pyc: Python's own bytecode cache also trusts mtime and size
               PYTHONDONTWRITEBYTECODE="1")
    r = subprocess.run([sys.executable, "-c", SCRIPT], env=env, cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert Path(out["file"]).resolve().is_relative_to(src.resolve()), out["file"]
    return out


def test_edit_in_inlined_file_reaches_cached_kernel(tmp_path):
    src = _copy_package(tmp_path)
    first = _run(src, tmp_path)
    again = _run(src, tmp_path)
    # control: no edit, the kernel comes from the on-disk cache and gives the same numbers
    assert again["hits"] > 0 and again["misses"] == 0
    assert again["theta"] == first["theta"]

    euler = src / "ballsurvey" / "physics" / "euler.py"
    st = euler.stat()
    text = euler.read_text()
    assert text.count(ORIGINAL) == 1
    euler.write_text(text.replace(ORIGINAL, EDITED))
    os.utime(euler, ns=(st.st_atime_ns, st.st_mtime_ns))  # same size, same mtime
    assert euler.stat().st_size == st.st_size and euler.stat().st_mtime_ns == st.st_mtime_ns

    edited = _run(src, tmp_path)
    assert edited["misses"] > 0 and edited["hits"] == 0  # recompiled, not served from the cache
    assert edited["theta"][0] == first["theta"][0]  # same launch
    assert edited["theta"][1:] != first["theta"][1:]  # new physics


def _package_imports(path: Path) -> set[Path]:
    """Files of the package that `path` imports (relative or absolute `ballsurvey` imports)."""
    import ast

    out = set()
    pkg_of = path.parent
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg_of
                for _ in range(node.level - 1):
                    base = base.parent
                parts = (node.module or "").split(".") if node.module else []
            elif node.module and node.module.split(".")[0] == "ballsurvey":
                base, parts = PKG, node.module.split(".")[1:]
            else:
                continue
            target = base.joinpath(*parts)
            names = [a.name for a in node.names]
            cands = [target.with_suffix(".py"), target / "__init__.py"]
            cands += [target / f"{n}.py" for n in names]
            out |= {c.resolve() for c in cands if c.is_file()}
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "ballsurvey":
                    raise AssertionError(f"{path}: use `from ... import` for package modules")
    return out


def test_digest_covers_every_jitted_function_and_what_it_can_inline():
    """Every jitted function lives in a digested file, and digested files import only digested
    files (so no code or frozen constant a cached kernel uses can change without the digest)."""
    from ballsurvey import _jit

    digested = {f.resolve() for f in _jit.digested_files()}
    for f in PKG.rglob("*.py"):
        text = f.read_text()
        if f.resolve() not in digested:
            for marker in ("njit", "nb.jit", "numba.jit", "@jit", "prange", "_jit import"):
                assert marker not in text, f"{f}: jitted code outside {_jit.DIGESTED_DIRS}"
            continue
        # the package's __init__ gives _jit only __version__, which is digested
        outside = _package_imports(f) - digested - {(PKG / "__init__.py").resolve()}
        assert not outside, f"{f} imports {sorted(map(str, outside))}, not in the digest"


def test_digest_changes_with_physics_not_with_cli(tmp_path):
    from ballsurvey import _jit

    src = _copy_package(tmp_path) / "ballsurvey"
    d0 = _jit.source_digest(src)
    assert d0 == _jit.SOURCE_DIGEST and _jit.caching_available()
    cli = src / "cli" / "__init__.py"
    cli.write_text(cli.read_text() + "\n# edited\n")
    assert _jit.source_digest(src) == d0
    euler = src / "physics" / "euler.py"
    euler.write_text(euler.read_text().replace(ORIGINAL, EDITED))
    assert _jit.source_digest(src) != d0


PARALLEL_SCRIPT = """
import numpy as np
from ballsurvey.compose import OBSERVER
from ballsurvey.classify.observer import N_OBS
from ballsurvey.integrate import ensemble
from ballsurvey.physics.fast import fast_state
y = fast_state(np.zeros(64), 0, np.linspace(0.1, 0.5, 64), 0, 0, 0, 1.0, -1.0)
p = np.repeat(np.array([[0.1], [0.4], [0.4]]), 64, 1)
r = ensemble.integrate(y, p, 1e-3, 200, observer=OBSERVER, n_slots=N_OBS, parallel=True, block=8)
np.save(__import__("sys").argv[1], r.obs)
"""


def test_cached_parallel_driver_serves_any_thread_count(tmp_path):
    """The parallel driver is cached on disk: a process with another thread count loads it and
    gets the same bits (numba picks the thread count at run time)."""
    env = dict(os.environ, BALLSURVEY_CACHE_DIR=str(tmp_path / "c"),
               NUMBA_CACHE_DIR=str(tmp_path / "n"))
    outs = []
    for threads in ("2", "1"):
        out = tmp_path / f"obs{threads}.npy"
        r = subprocess.run([sys.executable, "-c", PARALLEL_SCRIPT, str(out)], capture_output=True,
                           text=True, env=dict(env, NUMBA_NUM_THREADS=threads), timeout=300)
        assert r.returncode == 0, r.stderr[-2000:]
        outs.append(np.load(out))
    assert np.array_equal(outs[0], outs[1], equal_nan=True)
    # the second process compiled nothing: its index files were all written by the first
    assert any((tmp_path / "n").rglob("*run_parallel*.nbi"))

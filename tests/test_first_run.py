"""The first run after an install: what a job compiles, and that none of it changes a result.

* a small map runs the serial kernels (no parallel driver to compile), a large one the parallel
  ones; the file is the same either way;
* with empty caches and a core to spare, the near-vertical fallback (the serial quadrature) is
  compiled by a helper process beside the run's own compilation, and the run then finds it in
  numba's disk cache (nothing compiled twice);
* the fallback's kernel is compiled for one signature, whoever calls it (the parallel driver,
  the serial loop, one launch's trajectory).
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import xarray as xr

import ballsurvey
from ballsurvey.sweep import load_spec, run_sweep
from ballsurvey.sweep.executors import parallel_for

ROOT = Path(__file__).resolve().parents[1]

SMALL = """
title = "near the vertical"
[launch]
theta0_deg = [60.0, 80.0]
thetadot0 = [0.0, 5.0]
chidot0 = [0.0, 3.0]
phidot0 = [-3.0, 0.0]
[run]
T = 0.5
dt = 5e-4
[output]
file = "OUT"
"""


def test_small_maps_run_serial_large_ones_parallel():
    assert not parallel_for(load_spec(ROOT / "sweeps" / "quick.toml"))
    assert parallel_for(load_spec(ROOT / "sweeps" / "square-map.toml"))


def test_serial_and_parallel_runs_write_the_same_map(tmp_path):
    (tmp_path / "s.toml").write_text(SMALL.replace("OUT", str(tmp_path / "s.nc")))
    (tmp_path / "p.toml").write_text(SMALL.replace("OUT", str(tmp_path / "p.nc")))
    run_sweep(load_spec(tmp_path / "s.toml"), progress=False, parallel=False)
    run_sweep(load_spec(tmp_path / "p.toml"), progress=False, parallel=True)
    with xr.open_dataset(tmp_path / "s.nc") as a, xr.open_dataset(tmp_path / "p.nc") as b:
        # the map has launches for the fallback's two ways: by quadrature, and through the
        # vertical in the fixed frame
        assert (a.formulation == 2).any() and (a.formulation == 1).any()
        for k in a.data_vars:
            assert np.array_equal(a[k].values, b[k].values, equal_nan=True), k


#: in a fresh process with empty caches: the helper starts for a cold cache and the fallback
#: then comes from the disk cache; prints what was compiled in this process
COLD = r"""
import json, sys
import numpy as np
from numba.core import event
compiled = []
class Listener(event.Listener):
    def on_start(self, ev):
        compiled.append(ev.data["dispatcher"].py_func.__qualname__)
    def on_end(self, ev):
        pass
from ballsurvey import compose
from ballsurvey.classify import cycle
compose.idle_core = lambda: True  # as on a quiet machine, whatever the load of this one
before = compose.cached_on_disk(cycle._block)
compose.prefetch_fallback()
started = len(compose._HELPER)
compose.await_prefetch()
after = compose.cached_on_disk(cycle._block)
compose.prefetch_fallback()
again = len(compose._HELPER)
with event.install_listener("numba:compile", Listener()):
    compose.warm_near_vertical(np.array([0.1, 0.4, 0.4]))
print(json.dumps(dict(before=before, started=started, after=after, again=again,
                      compiled=compiled)))
"""


def test_cold_cache_fallback_is_compiled_by_a_helper_and_loaded_here(tmp_path):
    root = str(Path(ballsurvey.__file__).resolve().parent.parent)
    env = dict(os.environ, BALLSURVEY_CACHE_DIR=str(tmp_path / "kernels"),
               NUMBA_CACHE_DIR=str(tmp_path / "numba"), NUMBA_NUM_THREADS="2",
               PYTHONPATH=root)
    r = subprocess.run([sys.executable, "-c", COLD], env=env, cwd=tmp_path,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert not out["before"] and out["started"] == 1  # cold: the helper was started
    assert out["after"] and out["again"] == 0  # its work is on disk: no second helper
    assert out["compiled"] == []  # the fallback came from the disk cache, compiled nowhere here


def test_fallback_kernel_has_one_signature_for_every_caller():
    from ballsurvey import compose
    from ballsurvey.integrate.adaptive import make_kernels, trajectory_adaptive
    from ballsurvey.physics.fast import fast_state

    p = np.repeat(np.array([[0.1], [0.4], [0.4]]), 3, axis=1)
    y0 = fast_state(0.0, 0.0, np.radians([10.0, 20.0, 30.0]), 0.0, 0.0, 0.0, 1.0, -1.0)
    for parallel in (True, False):
        compose._fixed_frame(y0, p, 1e-3, parallel=parallel)
    trajectory_adaptive(y0[:, 0], p[:, 0], 1e-3, t_out=np.linspace(0, 1e-3, 3), **{
        k: v for k, v in compose.FALLBACK.items() if k != "observer" and k != "n_slots"},
        observer=compose.OBSERVER, n_slots=compose.N_OBS)
    # the map's re-run (step observer) and the trajectory's (sampling observer): one each
    assert len(make_kernels(compose.STEP_OBSERVER).adaptive_one.signatures) == 1
    assert len(make_kernels(compose.OBSERVER).adaptive_one.signatures) == 1


def test_a_core_to_spare_is_measured_from_the_cores_idle_time():
    """idle_core watches the CPUs' idle ticks: with every CPU this process may use kept busy by
    a spinning process there is no core to spare, whatever the load average said before; the
    idle cores are the idle share of the ticks that passed, times the CPUs."""
    import time

    import pytest

    from ballsurvey import compose

    assert compose.idle_cores((100, 1000), (150, 1100), 2) == 1.0
    assert compose.idle_cores((100, 1000), (100, 1000), 4) == 4.0  # no tick passed
    if compose._cpu_ticks(os.sched_getaffinity(0)) is None:
        pytest.skip("no /proc/stat here: idle_core falls back on the load average")
    spin = "import time\nt = time.time()\nwhile time.time() - t < 4: pass"
    procs = [subprocess.Popen([sys.executable, "-c", spin])
             for _ in os.sched_getaffinity(0)]
    try:
        time.sleep(0.5)
        assert not compose.idle_core()
    finally:
        for p in procs:
            p.kill()
            p.wait()

"""The CUDA backend, run through numba's CUDA simulator (no GPU here or in CI): the kernel generated
from the same tableau, with the same right-hand side and observer re-targeted to device functions,
gives the CPU kernel's observer record and end state."""
import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent('''
    import numpy as np
    from ballsurvey import Ball
    from ballsurvey.compose import OBSERVER, stop_target
    from ballsurvey.classify.observer import N_OBS
    from ballsurvey.integrate import cuda as bc, ensemble, outcome
    from ballsurvey.physics.fast import fast_state
    b = Ball.paper()
    tu = b.time_unit
    # the paper's square and triangle, a near-vertical square, a circle, and one that reaches the
    # Euler singularity within the run (cos theta < cos_min)
    th = np.radians([-5.0, -10.0, 26.0, 40.0, 89.97])
    chd = np.array([4.05, 2.3, 3.75, 5.0, 0.0]) * tu
    phd = np.array([-3.0, -2.5, -3.0, -7.5, 0.0]) * tu
    y0 = fast_state(0, 0, th, 0, 0, 0, chd, phd)
    p = np.repeat(b.nondim_params()[:, None], th.size, axis=1)
    dt = 2e-4 / tu
    for method, stop in (("rk4", 0), ("rk38", 0), ("rk4", stop_target(2))):
        kw = dict(observer=OBSERVER, n_slots=N_OBS, observe_every=4, stop_after=stop)
        g = bc.integrate(y0, p, dt, 600, method, batch=3, **kw)
        c = ensemble.integrate(y0, p, dt, 600, method, block=2, **kw)
        for j in range(th.size):  # launch by launch
            assert np.array_equal(np.isnan(g.obs[:, j]), np.isnan(c.obs[:, j])), (method, j)
            # the same arithmetic in the simulator: equal to rounding (a GPU may fuse
            # multiply-adds; another platform's libm may round a sine differently)
            assert np.allclose(g.obs[:, j], c.obs[:, j], rtol=1e-12, atol=1e-14,
                               equal_nan=True), (method, j)
            assert g.outcome[j] == c.outcome[j], (method, j)
            assert np.allclose(g.t_stop[j], c.t_stop[j], equal_nan=True), (method, j)
            if c.outcome[j] == outcome.OK:
                assert np.allclose(g.y_end[:, j], c.y_end[:, j], rtol=1e-12, atol=1e-14), (
                    method, j)
    assert g.outcome[4] == outcome.CHART_SINGULAR  # the near-vertical launch was stopped
    print("ok")
''')


def run_in_simulator(script: str) -> None:
    """Run a script in a fresh Python with numba's CUDA simulator on; it must print "ok" last.
    Skipped where numba has no CUDA target at all."""
    try:
        import numba.cuda  # noqa: F401  (only to know whether the CUDA target exists at all)
    except ImportError:
        pytest.skip("numba has no CUDA target here")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env,
                       timeout=600)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), r.stderr[-3000:]


def test_cuda_kernel_matches_cpu_in_the_simulator():
    run_in_simulator(SCRIPT)


def test_kernel_is_generated_from_the_tableau():
    from ballsurvey.integrate.cuda import kernel_source
    from ballsurvey.integrate.tableaus import FIXED_STEP

    for name, tab in FIXED_STEP.items():
        src = kernel_source(tab)
        assert src.count("fast_rhs(") == tab.stages, name
        for w in tab.b:
            if w:
                assert repr(float(w)) in src, name


SPEC = """
title = "backend check"
[launch]
theta0_deg = [-5.0, 26.0]
thetadot0 = 0.0
chidot0 = [3.75, 4.05]
phidot0 = -3.0
[run]
T = 1.5
dt = 1e-3
backend = "{backend}"
[output]
file = "{out}"
"""


def test_sweep_with_backend_cuda_gives_the_cpu_map(tmp_path):
    """A map through the CUDA backend (simulator) is the CPU map: labels identical, fields to the
    two observers' difference; the near-vertical launches' fallback runs on the CPU
    in both."""
    import numpy as np
    import xarray as xr

    try:
        import numba.cuda  # noqa: F401
    except ImportError:
        pytest.skip("numba has no CUDA target here")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    spec = tmp_path / "map.toml"
    spec.write_text(SPEC.format(backend="cpu", out=tmp_path / "cpu.nc"))
    # the cuda map from the same spec file, through `sweep --backend cuda`
    for extra in ([], ["--backend", "cuda", "-o", str(tmp_path / "cuda.nc")]):
        r = subprocess.run([sys.executable, "-m", "ballsurvey", "sweep", str(spec), "-q", *extra],
                           capture_output=True, text=True, env=env, timeout=600)
        assert r.returncode == 0, r.stderr
    cpu, gpu = (xr.open_dataset(tmp_path / f"{b}.nc") for b in ("cpu", "cuda"))
    # the override reached the run (the chunks re-read the spec from its text) and the record
    assert (cpu.attrs["run_backend"], gpu.attrs["run_backend"]) == ("cpu", "cuda")
    assert 'backend = "cuda"' in gpu.attrs["spec_toml"]
    assert gpu.attrs["spec_digest"] != cpu.attrs["spec_digest"]
    assert np.array_equal(cpu.label.values, gpu.label.values)
    # the same spec without the flag on the cuda map: refused, naming the flag that made it
    r = subprocess.run([sys.executable, "-m", "ballsurvey", "sweep", str(spec), "-q", "-o",
                        str(tmp_path / "cuda.nc")], capture_output=True, text=True, env=env,
                       timeout=600)
    assert r.returncode == 2 and "it is this spec run with --backend cuda" in r.stderr, r.stderr
    # the two launches that pass 88.5 deg are done again by quadrature, on the CPU in both: the
    # same to rounding
    again = cpu.formulation.values == 2
    assert again.sum() == 2 and np.array_equal(gpu.formulation.values, cpu.formulation.values)
    for v in ("n_sides", "turn_per_cycle_deg", "theta_period_s", "roundness", "energy_drift"):
        assert np.allclose(cpu[v].values[again], gpu[v].values[again], rtol=1e-9), v
    # the others: the same RK4 steps, seen by two observers (the card samples every 4th step,
    # the CPU map's step observer reads each launch's own spans), at a coarse 1 ms step with
    # theta up to 88.3 deg, where RK4 itself errs by 8e-6 in the period, 1e-3 deg in the turn and
    # 2e-4 deg in theta max (against the quadrature). Measured between them: turn and n_sides
    # 3.3e-5 relative, period 1e-6, roundness 2e-4, theta max 4e-7; the energy drift is read at
    # other instants (within a factor 1.7)
    e = ~again
    for v, rtol in (("n_sides", 1e-4), ("turn_per_cycle_deg", 1e-4), ("theta_period_s", 3e-6),
                    ("roundness", 1e-3), ("theta_max_deg", 1e-6)):
        assert np.allclose(cpu[v].values[e], gpu[v].values[e], rtol=rtol), v
    ratio = cpu.energy_drift.values[e] / gpu.energy_drift.values[e]
    assert ((ratio > 0.5) & (ratio < 2.0)).all(), ratio


@pytest.mark.parametrize("run,words", [
    ('backend = "gpu"', "[run] backend: must be one of cpu, cuda"),
    ('backend = "cuda"\nmethod = "dopri5"', "[run] backend: cuda runs the fixed-step methods"),
])
def test_backend_spec_errors(tmp_path, run, words):
    from ballsurvey.limits import InputError
    from ballsurvey.sweep import load_spec

    text = SPEC.replace('backend = "{backend}"', run).format(out=tmp_path / "x.nc")
    with pytest.raises(InputError, match=words.replace("[", r"\[").replace("]", r"\]")):
        load_spec(tmp_path / "x.toml", text=text)


def test_run_override_rewrites_the_spec_text(tmp_path):
    """`sweep --backend`: the [run] key is replaced in the spec's text (which chunks, workers and
    the map's provenance read), the rest of the text is kept, and the digest changes."""
    from ballsurvey.limits import InputError
    from ballsurvey.sweep import load_spec

    text = SPEC.format(backend="cpu", out=tmp_path / "x.nc")
    plain = load_spec(tmp_path / "x.toml", text=text)
    over = load_spec(tmp_path / "x.toml", text=text, run={"backend": "cuda"})
    assert (plain.backend, over.backend) == ("cpu", "cuda")
    assert over.text.count("backend =") == 1 and 'title = "backend check"' in over.text
    again = load_spec(tmp_path / "x.toml", text=over.text)
    assert again.backend == "cuda" and again.digest == over.digest != plain.digest
    # no backend line: one is added under [run]; the chunk default follows the backend
    bare = text.replace('backend = "cpu"\n', "")
    added = load_spec(tmp_path / "x.toml", text=bare, run={"backend": "cuda"})
    assert added.backend == "cuda" and added.chunk == 1 << 19
    assert load_spec(tmp_path / "x.toml", text=bare).chunk == 4096
    # checked as if written in the file
    with pytest.raises(InputError, match="cuda runs the fixed-step methods"):
        dopri = bare.replace("dt = 1e-3", 'dt = 1e-3\nmethod = "dopri5"')
        load_spec(tmp_path / "x.toml", text=dopri, run={"backend": "cuda"})
    # a value already in effect changes nothing: same text, same digest (a map made without the
    # flag stays up to date, its parts resumable)
    same = load_spec(tmp_path / "x.toml", text=bare, run={"backend": "cpu"})
    assert same.text == bare and same.digest == load_spec(tmp_path / "x.toml", text=bare).digest
    # only newlines end lines: a U+2028 inside a comment must not turn the rest into a key
    sneaky = bare.replace('title = "backend check"',
                          'title = "backend check"\n# heading\u2028chi0_deg = 90.0')
    assert load_spec(tmp_path / "x.toml", text=sneaky).chi0_deg == 0.0
    assert load_spec(tmp_path / "x.toml", text=sneaky, run={"backend": "cuda"}).chi0_deg == 0.0
    # a "[run]" line inside a multi-line string is not the table: the rewrite is refused
    fake = bare.replace('title = "backend check"', 'title = """x\n[run]\ny"""').replace(
        "[run]\nT", "[ run ]\nT")
    assert load_spec(tmp_path / "x.toml", text=fake).title == "x\n[run]\ny"
    with pytest.raises(InputError, match="cannot set backend from the command line"):
        load_spec(tmp_path / "x.toml", text=fake, run={"backend": "cuda"})
    # the spec's own errors come first
    with pytest.raises(InputError, match=r"\[run\] T"):
        load_spec(tmp_path / "x.toml", text=bare.replace("T = 1.5", "T = nan"),
                  run={"backend": "cuda"})
    # a [run] written inline cannot be rewritten line by line: one line says so
    inline = bare.replace("[run]\nT = 1.5\ndt = 1e-3\n", "").replace(
        'title = "backend check"', 'title = "backend check"\nrun = {T = 1.5, dt = 1e-3}')
    assert load_spec(tmp_path / "x.toml", text=inline).T == 1.5
    with pytest.raises(InputError, match="cannot set backend from the command line"):
        load_spec(tmp_path / "x.toml", text=inline, run={"backend": "cuda"})


def test_streamed_sums_are_the_cpu_kernels_arithmetic():
    """The CUDA step sums each group of equal weights as soon as its last stage exists, and keeps
    the values it carries across right-hand side calls in shared memory: run the CPU kernel's text
    and both CUDA texts in plain Python (IEEE doubles, no fused multiply-add; shared memory as an
    array, the fence a no-op) on a nonlinear right-hand side: the same numbers bit for bit, for
    every fixed-step tableau."""
    import math
    import random
    import types

    import numpy as np

    from ballsurvey.integrate.cuda import carried, streamed_stage_source
    from ballsurvey.integrate.tableaus import FIXED_STEP, stage_source, step_constants

    n = 12

    def fast_rhs(s, c, A, B):
        return tuple(math.sin(1.3 * s[q] + c) * s[(q + 1) % n] + A * s[(q + 5) % n] ** 2 - B
                     for q in range(n))

    cuda = types.SimpleNamespace(threadfence_block=lambda: None)
    rng = random.Random(7)
    for name, tab in FIXED_STEP.items():
        s0 = tuple(rng.uniform(-2.0, 2.0) for _ in range(n))
        texts = [stage_source(tab, n, ""), streamed_stage_source(tab, n, ""),
                 streamed_stage_source(tab, n, "", carry="shared")]
        stepped = []
        for stages, update in texts:
            ns = {"fast_rhs": fast_rhs, "c": 0.3, "A": 0.7, "B": 0.4, "dt": 0.0137, "s0": s0,
                  "cuda": cuda, "tid": 0}
            ns.update({f"st_{v}": np.full((n, 1), np.nan) for v in carried(tab, n)})
            exec(step_constants(tab, "") + "\n" + stages + "\n" + update, ns)
            stepped.append([float(ns[f"r{q}"]) for q in range(n)])
        assert stepped[0] == stepped[1] == stepped[2], name  # exact
        assert "g0 = (" in texts[1][0], name  # a sum was streamed
        assert "s0" in carried(tab, n) and "st_s0[" in texts[2][1], name  # and s0 carried


TILE_SCRIPT = textwrap.dedent('''
    import numba
    import numpy as np
    from ballsurvey.integrate import cuda as bc
    from ballsurvey.integrate.binding import Observer
    from ballsurvey.physics.fast import fast_state

    @numba.njit
    def record(obs, i, first, t, dt, x, y, th, sth, cth, chi, thd, chd, phd, thdd, chdd, phdd,
               c, A, B, psid, fric, normal):
        last = obs.shape[0] - 1
        if first:  # slot k: the launch's x plus 1000 k; the last slot counts the samples
            for k in range(last):
                obs[k, i] = x + 1000.0 * k
            obs[last, i] = 0.0
        obs[last, i] += 1.0

    @numba.njit
    def done(obs, i, target):
        return obs[obs.shape[0] - 1, i] >= target

    m = 37  # two tiles and a bit in the first batch of 33, a part tile in the second
    y0 = fast_state(np.arange(m, dtype=float), 0.0, 0.3, 0.0, 0.0, 0.0, 1.0, -1.0)
    p = np.repeat(np.array([[0.2], [0.4], [0.5]]), m, axis=1)
    for slots, stop, samples in ((3, 0, 3), (64, 0, 3), (64, 2, 2)):
        r = bc.integrate(y0, p, 1e-3, 3, observer=Observer(record, done), n_slots=slots,
                         observe_every=2, stop_after=stop, batch=33)
        want = np.arange(m)[None, :] + 1000.0 * np.arange(slots - 1)[:, None]
        assert r.obs.shape == (slots, m)
        for j in range(m):  # launch by launch: its own column, whatever its tile and lane
            assert np.array_equal(r.obs[:-1, j], want[:, j]), (slots, j, r.obs[:, j])
            assert r.obs[-1, j] == samples, (slots, stop, j, r.obs[-1, j])
    print("ok")
''')


def test_record_tiles_hold_each_launch_in_its_column():
    """The record lives on the card as (slot, lane) tiles of TILE launches: an observer with
    few or many slots (the kernel is compiled for each count) finds launch i's slots in column
    i after the batches and the part tiles are put back together, and its `done` sees them."""
    run_in_simulator(TILE_SCRIPT)


def test_ptxas_figures_of_the_kernel_in_use():
    """benchmarks/ptxas.py (numba-cuda to PTX, ptxas -v for sm_90, no GPU needed): the kernel in
    use spills nothing and takes fewer registers than the record as plain columns. Skipped
    without the NVIDIA compiler wheels (nvidia-cuda-nvcc-cu12, nvidia-cuda-nvrtc-cu12)."""
    import importlib.util
    import shutil

    def found(name):  # find_spec of a submodule raises where its parent package is missing
        try:
            return importlib.util.find_spec(name) is not None
        except ModuleNotFoundError:
            return False

    have = os.environ.get("PTXAS") or shutil.which("ptxas") or found("nvidia.cuda_nvcc")
    if not have or not found("nvidia.cuda_nvrtc"):
        pytest.skip("no ptxas / nvrtc here (pip install nvidia-cuda-nvcc-cu12 "
                    "nvidia-cuda-nvrtc-cu12)")
    try:
        import numba.cuda  # noqa: F401
    except ImportError:
        pytest.skip("numba has no CUDA target here")
    bench = os.path.join(os.path.dirname(__file__), "..", "benchmarks", "ptxas.py")
    script = textwrap.dedent(f'''
        import runpy
        m = runpy.run_path({bench!r})
        ptxas = m["find_ptxas"]()
        for variant in ({{}}, dict(record="columns", sums="final", carry="registers")):
            f = m["measure"](m["kernel_ptx"]("rk4", (9, 0), **variant), ptxas, "sm_90")
            print(f["regs"], f["spill_st"], f["spill_ld"])
    ''')
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    (regs, spill_st, spill_ld), (regs_columns, _, _) = (
        [int(x) for x in line.split()] for line in r.stdout.strip().splitlines())
    assert spill_st == spill_ld == 0, r.stdout
    assert regs < regs_columns, r.stdout


QUAD_SCRIPT = textwrap.dedent('''
import numpy as np
from ballsurvey.ball import Ball
from ballsurvey.classify import cycle, observer
from ballsurvey.integrate import cuda
from ballsurvey.units import launch_state

ball = Ball.paper()
tu = ball.time_unit
# a square, a near-straight path, a circle, a launch through the vertical and one at rest in theta
th = np.array([-5.0, 12.0, 30.0, 60.0, 85.0])
chd = np.array([3.9, -6.0, 9.0, 0.5, 0.2])
phd = np.array([-3.0, 1.0, 6.0, -2.0, 0.0])
thd = np.array([0.0, 0.3, 0.0, 0.0, 0.0])
y0 = launch_state(th, thd, chd, phd, tu)
params = np.repeat(ball.nondim_params()[:, None], th.size, 1)
T = 20.0 / tu
cpu, st_cpu = cycle.cycles_by_quadrature(y0, params, T, stop_after=3, parallel=False)
gpu, st_gpu = cuda.per_launch(cycle.cycle_one, y0, params, T, 3, 1e-8, cycle.tables(),
                              n_scratch=cycle.N_SCRATCH, n_node=cycle.N_NODE,
                              n_points=cycle.ROW, n_slots=observer.N_OBS)
assert np.array_equal(st_cpu, st_gpu), (st_cpu, st_gpu)
assert (st_cpu == cycle.DONE).sum() >= 3, st_cpu
assert np.array_equal(np.isnan(cpu), np.isnan(gpu))
ok = ~np.isnan(cpu)
assert np.allclose(cpu[ok], gpu[ok], rtol=1e-12, atol=1e-14)
print("ok")
''')


def test_quadrature_per_launch_kernel_matches_cpu_in_the_simulator():
    """The quadrature's per-launch function re-targeted to CUDA (one thread a launch, its scratch
    in the thread's local memory) gives the CPU kernel's record and statuses."""
    run_in_simulator(QUAD_SCRIPT)


def test_sweep_by_quadrature_on_backend_cuda_gives_the_cpu_map(tmp_path):
    """`method = "quadrature"` with `--backend cuda` (simulator): the CPU's map, labels identical,
    fields to rounding (the near-vertical launch goes to the CPU's integrator in both)."""
    import numpy as np
    import xarray as xr

    try:
        import numba.cuda  # noqa: F401
    except ImportError:
        pytest.skip("numba has no CUDA target here")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    spec = tmp_path / "map.toml"
    spec.write_text(SPEC.format(backend="cpu", out=tmp_path / "cpu.nc").replace(
        "dt = 1e-3", 'dt = 1e-3\nmethod = "quadrature"\nmode = "period"'))
    for extra in ([], ["--backend", "cuda", "-o", str(tmp_path / "cuda.nc")]):
        r = subprocess.run([sys.executable, "-m", "ballsurvey", "sweep", str(spec), "-q", *extra],
                           capture_output=True, text=True, env=env, timeout=600)
        assert r.returncode == 0, r.stderr
    cpu, gpu = (xr.open_dataset(tmp_path / f"{b}.nc") for b in ("cpu", "cuda"))
    assert gpu.attrs["run_backend"] == "cuda" and gpu.attrs["run_method"] == "quadrature"
    assert np.array_equal(cpu.label.values, gpu.label.values)
    for v in ("n_sides", "turn_per_cycle_deg", "theta_period_s", "roundness"):
        assert np.allclose(cpu[v].values, gpu[v].values, rtol=1e-9, equal_nan=True), v

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
        assert np.array_equal(np.isnan(g.obs), np.isnan(c.obs)), method
        # the same arithmetic in the simulator: equal to rounding (a GPU may fuse multiply-adds)
        assert np.allclose(g.obs, c.obs, rtol=1e-12, atol=1e-14, equal_nan=True), method
        assert np.array_equal(g.outcome, c.outcome), method
        assert np.allclose(g.t_stop, c.t_stop, equal_nan=True), method
        ok = c.outcome == outcome.OK
        assert np.allclose(g.y_end[:, ok], c.y_end[:, ok], rtol=1e-12, atol=1e-14), method
    assert g.outcome[4] == outcome.CHART_SINGULAR  # the near-vertical launch was stopped
    print("ok")
''')


def test_cuda_kernel_matches_cpu_in_the_simulator():
    try:
        import numba.cuda  # noqa: F401  (only to know whether the CUDA target exists at all)
    except ImportError:
        pytest.skip("numba has no CUDA target here")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    r = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env,
                       timeout=600)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), r.stderr[-3000:]


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
    """A map through the CUDA backend (simulator) equals the CPU map: labels identical, fields to
    rounding; the near-vertical launch's fixed-frame fallback runs on the CPU in both."""
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
    for v in ("n_sides", "turn_per_cycle_deg", "theta_period_s", "roundness", "energy_drift"):
        assert np.allclose(cpu[v].values, gpu[v].values, rtol=1e-9, equal_nan=True), v


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

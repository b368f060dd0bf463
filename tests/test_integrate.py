"""The ensemble kernel: convergence orders, invariants' drift, agreement with independent steppers,
determinism under chunking and threading, and the flags for blown-up and singular launches."""
import math
from types import SimpleNamespace

import numba
import numpy as np
import pytest

from ballsurvey.ball import Ball
from ballsurvey.classify import observer as ob
from ballsurvey.compose import FIXED_STEP_OBSERVER, OBSERVER
from ballsurvey.integrate import ensemble, naive
from ballsurvey.integrate import outcome as oc
from ballsurvey.integrate.tableaus import FIXED_STEP
from ballsurvey.physics import fixed
from ballsurvey.physics.fast import S_CHD, S_CHI, S_PHI, fast_state

B = Ball.paper()
P = B.nondim_params()
TU = B.time_unit
U12A = np.array([0, 0, math.radians(-5), 0, 0, 0, 4.05 * TU, -3 * TU])  # Fig. 12a, non-dim


def integrate(y0, params, dt, n, method="rk4", **kw):
    """The ensemble kernel fed the classifier's sampling observer (or kw's observer)."""
    kw.setdefault("observer", OBSERVER)
    return ensemble.integrate(y0, params, dt, n, method, n_slots=ob.N_OBS, **kw)


def run(u0, T_s, dt_s, method="rk4", **kw):
    n = int(round(T_s / dt_s))
    y0 = fast_state(*[u0[k] for k in range(8)])
    kw.setdefault("parallel", False)
    r = integrate(y0, np.repeat(P[:, None], y0.shape[1], 1), T_s / TU / n, n, method, **kw)
    return r.y_end, r.obs, r.traj


@pytest.mark.parametrize("method", ["rk4", "rk38", "ssprk3", "heun"])
def test_global_error_order(method):
    # Fig. 12a over 1 s (through its first corner, theta up to 86 deg); error at T against a run
    # with a 16x smaller step of the same method
    order = FIXED_STEP[method].order
    dts = [1e-3, 5e-4, 2.5e-4] if order >= 3 else [2e-4, 1e-4, 5e-5]
    ref = run(U12A, 1.0, dts[-1] / 16, method)[0][:8, 0]
    errs = [np.abs(run(U12A, 1.0, dt, method)[0][:8, 0] - ref).max() for dt in dts]
    ratio = errs[-2] / errs[-1]
    assert abs(math.log2(ratio) - order) < 0.4, (errs, ratio)



@pytest.mark.parametrize("method", ["rk4", "rk38", "ssprk3", "heun"])
def test_generated_step_is_the_tableaus_stability_polynomial(method):
    # the step text the kernels compile (dt folded into hoisted constants, equal coefficients
    # sharing a product), executed on y' = lam y, must give the tableau's R(z) = 1 + z b^T
    # (I - z A)^-1 1, computed here from the coefficients by linear algebra
    from ballsurvey.integrate.tableaus import stage_source, step_constants

    tab = FIXED_STEP[method]
    stages, update = stage_source(tab, 2, "    ")  # two variables: y and 2 y
    src = ("def step(y, dt, lam):\n" + step_constants(tab, "    ") + "\n"
           + "    c = A = B = 0.0\n    s0 = (y, 2.0 * y)\n" + stages + "\n" + update
           + "\n    return r0, r1\n")
    env = {"fast_rhs": lambda s, c, A, B: (lam_of[0] * s[0], lam_of[0] * s[1])}
    lam_of = [0.0]
    exec(src, env)
    for lam, dt in ((-1.3, 0.37), (2.1, 0.11), (-40.0, 0.01)):
        lam_of[0] = lam
        z = lam * dt
        s = tab.stages
        want = 1.0 + z * tab.b @ np.linalg.solve(np.eye(s) - z * tab.a, np.ones(s))
        assert env["step"](1.0, dt, lam) == pytest.approx((want, 2.0 * want), rel=1e-14, abs=0.0)

def test_rk4_error_falls_by_16_per_halving():
    dts = [5e-4, 2.5e-4]
    ref = naive.rk4_euler(U12A, P, 1.0 / TU / 32000, 32000)  # independent stepper, dt = 3.1e-5 s
    errs = [np.abs(run(U12A, 1.0, dt)[0][:8, 0] - ref).max() for dt in dts]
    assert 13.0 < errs[0] / errs[1] < 19.0, errs


def test_invariant_drift_shrinks_like_dt4():
    # Fig. 12a, T = 20 s: energy, Jellett and Routh drift (max over the run) at dt and dt/2
    drifts = []
    for dt in (1.25e-4, 6.25e-5):
        obs = run(U12A, 20.0, dt, observe_every=1)[1][:, 0]
        drifts.append(np.array([obs[ob.O_DE], obs[ob.O_DJ], obs[ob.O_DR]]))
    orders = np.log2(drifts[0] / drifts[1])
    assert np.all((orders > 3.6) & (orders < 4.6)), orders
    assert np.all(drifts[1] < 1e-9)


def test_fast_state_agrees_with_euler_angle_rk4():
    # the sin/cos-carrying state and the paper's Euler-angle state, same RK4, 20 s square path
    ye = run(U12A, 20.0, 1e-4)[0][:8, 0]
    ue = naive.rk4_euler(U12A, P, 1e-4 / TU, 200000)
    assert np.hypot(ye[0] - ue[0], ye[1] - ue[1]) * B.a < 1e-8


def test_euler_and_fixed_frame_trajectories_agree():
    n, every = 50000, 5000  # 5 s at dt = 1e-4 s
    v = naive.rk4_fixed_frame(fixed.euler_to_fixed(U12A), P, 1e-4 / TU, n, every)
    ye, _, traj = run(U12A, 5.0, 1e-4, n_rec=n // every + 1, stride=every)
    for k in range(v.shape[0]):
        e = fixed.fixed_to_euler(v[k], traj[k, S_CHI, 0], traj[k, S_PHI, 0])
        assert np.abs(e[:2] - traj[k, :2, 0]).max() * B.a < 1e-8  # position, m
        assert np.abs(e[2:5] - traj[k, 2:5, 0]).max() < 1e-6  # angles, rad


def _launches(n=37, seed=4):
    rng = np.random.default_rng(seed)
    return fast_state(0, 0, np.radians(rng.uniform(-10, 40, n)), 0, 0,
                               rng.normal(0, 1, n) * TU, rng.uniform(-12, 12, n) * TU,
                               rng.uniform(-8, 0, n) * TU)


def _same(a, b) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return np.array_equal(a, b, equal_nan=a.dtype.kind == "f")


@pytest.mark.parametrize("observer", ["sampling", "steps"])
def test_results_independent_of_block_size_and_threads(observer):
    # the sampling observer on every third step, and the map's step observer (each launch at its
    # own cadence, the block's launches observed together on a common grid of steps)
    kw = ({} if observer == "sampling" else
          dict(observer=FIXED_STEP_OBSERVER))
    y0 = _launches()
    params = np.repeat(P[:, None], y0.shape[1], 1)
    dt, n = 1e-3 / TU, 3000
    ref = integrate(y0, params, dt, n, block=64, parallel=False, observe_every=3, **kw)
    runs = [integrate(y0, params, dt, n, block=b, parallel=False, observe_every=3, **kw)
            for b in (1, 5)]
    old = numba.get_num_threads()
    try:
        for threads in sorted({1, old}):
            numba.set_num_threads(threads)
            runs.append(integrate(y0, params, dt, n, block=4, observe_every=3, **kw))
    finally:
        numba.set_num_threads(old)
    # a launch's result does not depend on its neighbours: run a slice alone
    alone = integrate(y0[:, 10:13], params[:, 10:13], dt, n, block=64, parallel=False,
                      observe_every=3, **kw)
    for got in runs:
        for a, b in zip(ref, got):
            assert _same(a, b)
    for a, b in zip(alone, ref):
        assert _same(a, b if b is None or not b.ndim else b[..., 10:13])
    if observer == "steps":
        assert ref.by_steps.all() and np.isfinite(ref.obs[ob.O_TL]).sum() > 10


def test_blow_up_is_flagged_and_others_go_on():
    y0 = _launches(8)
    y0[S_CHD, 3] = 400 * TU  # far too fast for dt = 0.02 s
    params = np.repeat(P[:, None], 8, 1)
    dt, n = 0.02 / TU, 500
    r = integrate(y0, params, dt, n, parallel=False)
    assert r.outcome[3] == oc.NONFINITE
    assert 0 < r.t_stop[3] < n * dt
    good = [0, 1, 2, 4, 5, 6, 7]
    alone = integrate(y0[:, good], params[:, good], dt, n, parallel=False)
    assert np.array_equal(alone.obs, r.obs[:, good], equal_nan=True)
    assert np.array_equal(alone.outcome, r.outcome[good])
    assert np.array_equal(alone.t_stop, r.t_stop[good], equal_nan=True)


def test_tilt_reaching_90_deg_is_flagged_singular():
    y0 = fast_state(0, 0, math.radians(85.0), 0, 0, 3.0 * TU, 0.0, 0.0)
    r = integrate(y0, P[:, None], 1e-4 / TU, 20000, parallel=False)
    assert r.outcome[0] == oc.CHART_SINGULAR and r.formulation[0] == oc.EULER_ANGLES
    assert math.degrees(r.obs[ob.O_TH_MAX, 0]) > 85.0


def test_period_mode_refill_matches_the_block_kernel_bit_for_bit():
    """Period mode refills a lane as soon as its launch has its cycles; per launch the arithmetic
    is the block kernel's, so the observer record, outcome and stop time are the same bits, for
    any block size and thread count. The refill kernel records one launch at a time
    (`observe`), the block kernel a block at once (`block_record`, in chunks of CHUNK
    launches: a block of 150 holds three)."""
    from ballsurvey.classify.observer import N_OBS
    from ballsurvey.compose import OBSERVER, stop_target
    from ballsurvey.units import launch_state

    ball = Ball.paper()
    tu = ball.time_unit
    rng = np.random.default_rng(3)
    n = 200
    y0 = launch_state(rng.uniform(-20, 89.9, n), rng.uniform(-2, 2, n), rng.uniform(-12, 12, n),
                      rng.uniform(-8, 8, n), tu)
    p = np.repeat(ball.nondim_params()[:, None], n, 1)
    dt, steps, stop = 5e-4 / tu, 6000, stop_target(2)
    kw = dict(observer=OBSERVER, n_slots=N_OBS, observe_every=4, stop_after=stop)
    refill = ensemble.integrate(y0, p, dt, steps, block=16, **kw)
    serial = ensemble.integrate(y0, p, dt, steps, block=5, parallel=False, **kw)
    par, _, _, _ = ensemble.make_kernels("rk4", OBSERVER)  # the block kernel (no refill)
    obs = np.full((N_OBS, n), np.nan)
    out, t_stop = np.zeros(n, np.int8), np.full(n, np.nan)
    par(y0, p, dt, steps, 16, 1e-3, True, 4, obs, np.full((0, 12, n), np.nan), 1,
        np.empty_like(y0), stop, out, t_stop)
    assert (out != 0).any() and (out == 0).any()  # both kinds of ending are exercised
    wide = SimpleNamespace(obs=np.full((N_OBS, n), np.nan), outcome=np.zeros(n, np.int8),
                           t_stop=np.full(n, np.nan))
    par(y0, p, dt, steps, 150, 1e-3, True, 4, wide.obs, np.full((0, 12, n), np.nan), 1,
        np.empty_like(y0), stop, wide.outcome, wide.t_stop)
    for r in (refill, serial, wide):
        assert np.array_equal(r.obs, obs, equal_nan=True)
        assert np.array_equal(r.outcome, out) and np.array_equal(r.t_stop, t_stop, equal_nan=True)

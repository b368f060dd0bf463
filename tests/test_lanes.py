"""The SIMD-lane adaptive kernel (integrate/lanes.py) and its DOP853 pair.

The pair's coefficients are checked by conditions computed here (quadrature, the linear stability
function, a measured convergence order with a stepper written in this file), and the kernel
against an independent integrator: the scalar Dormand-Prince 5(4) of adaptive.py, another method
in other code.
"""
import math
from math import factorial

import numpy as np
import pytest
from numba import njit

from ballsurvey.accuracy import square_launches
from ballsurvey.ball import Ball
from ballsurvey.classify.observer import N_OBS
from ballsurvey.compose import OBSERVER
from ballsurvey.integrate.adaptive import integrate_adaptive
from ballsurvey.integrate.lanes import integrate_lanes, kernel_module_source
from ballsurvey.integrate.outcome import FIXED_FRAME, NONFINITE, OK, STEP_BUDGET
from ballsurvey.integrate.tableaus import DOP853, DOPRI5, LaneTableau
from ballsurvey.physics import fixed
from ballsurvey.units import launch_state


def test_dop853_quadrature_and_linear_conditions():
    a, b = DOP853.a, DOP853.b
    c = a.sum(axis=1)
    one = np.ones(len(b))
    for k in range(8):  # b . c^k = 1 / (k + 1): exact for polynomials of degree 7
        assert b @ c**k == pytest.approx(1.0 / (k + 1), abs=1e-14)
    for k in range(8):  # b A^k 1 = 1 / (k + 1)!: the stability function matches exp to z^8
        assert b @ np.linalg.matrix_power(a, k) @ one == pytest.approx(1.0 / factorial(k + 1),
                                                                       abs=1e-14)
    assert np.allclose(np.triu(a), 0.0)  # explicit
    # both error estimates vanish on constants: they estimate the error, not the solution
    assert abs(DOP853.e5.sum()) < 1e-14 and abs(DOP853.e3.sum()) < 1e-14
    assert DOP853.error_exponent == -1.0 / 8.0


def _pendulum_error(h, T=2.0):
    """Fixed-step DOP853 on the pendulum q'' = -sin q, written here from the tableau alone;
    error against the same stepper at h / 16."""
    def f(y):
        return np.array([y[1], -math.sin(y[0])])

    def run(h):
        y = np.array([1.2, 0.0])
        for _ in range(int(round(T / h))):
            k = []
            for s in range(DOP853.stages):
                k.append(f(y + h * sum(DOP853.a[s, j] * k[j] for j in range(s))))
            y = y + h * sum(DOP853.b[s] * k[s] for s in range(DOP853.stages))
        return y

    return np.abs(run(h) - run(h / 16)).max()


def test_dop853_converges_at_order_8():
    e1, e2 = _pendulum_error(0.4), _pendulum_error(0.2)
    order = math.log2(e1 / e2)
    assert 7.5 < order < 8.7, order


def test_lane_kernel_refuses_an_exponent_it_cannot_vectorise():
    bad = LaneTableau("dopri5", 5, 4, DOPRI5.a, DOPRI5.b, DOPRI5.b_err, 0 * DOPRI5.b)
    with pytest.raises(ValueError, match="-1/8"):
        kernel_module_source(bad)


@pytest.fixture(scope="module")
def around_square():
    y0, p, _, ball = square_launches(12, seed=4, T=5.0)
    return y0, p, 5.0 / ball.time_unit, ball


def test_lanes_agree_with_an_independent_integrator(around_square):
    y0, p, T, ball = around_square
    res = integrate_lanes(y0, p, T, 1e-10, 1e-13)
    ref = integrate_adaptive(y0, p, T, 1e-12, 1e-15, observer=OBSERVER, n_slots=N_OBS,
                             fixed_frame=True)
    assert (res.outcome == OK).all() and (res.formulation == FIXED_FRAME).all()
    err_m = np.hypot(*(res.traj[:2] - ref.y_end[:2])) * ball.a
    assert err_m.max() < 1e-8, err_m.max()
    # the Euler view carries the same position, and the orientation (theta) agrees
    assert np.array_equal(res.y_end[:2], res.traj[:2])
    assert np.abs(res.y_end[2] - ref.y_end[2]).max() < 1e-7
    # the tolerance steers the error: looser is worse, and still bounded
    loose = integrate_lanes(y0, p, T, 1e-6, 1e-9)
    err_loose = np.hypot(*(loose.traj[:2] - ref.y_end[:2])) * ball.a
    assert err_m.max() < err_loose.max() < 1e-3
    assert loose.n_steps.mean() < res.n_steps.mean()


def test_lanes_conserve_energy(around_square):
    y0, p, T, _ = around_square
    res = integrate_lanes(y0, p, T, 1e-10, 1e-13)
    v0 = np.empty((fixed.N_FIXED, y0.shape[1]))
    from ballsurvey.integrate.lanes import fixed_columns
    fixed_columns(y0, v0)
    for j in range(y0.shape[1]):
        e0 = fixed.energy(v0[:, j], p[:, j])
        assert abs(fixed.energy(res.traj[:, j], p[:, j]) - e0) < 1e-9 * abs(e0)


def test_lanes_bit_identical_across_blocks_and_threads(around_square):
    y0, p, T, _ = around_square
    base = integrate_lanes(y0, p, T, 1e-8, 1e-11, block=64)
    for kw in (dict(block=1), dict(block=5), dict(block=64, parallel=False)):
        other = integrate_lanes(y0, p, T, 1e-8, 1e-11, **kw)
        assert np.array_equal(other.traj, base.traj), kw
        assert np.array_equal(other.n_steps, base.n_steps), kw


def test_lanes_near_the_vertical():
    ball = Ball.paper()
    tu = ball.time_unit
    y0 = launch_state(89.2, 0.0, 2.0, -3.0, tu)
    p = ball.nondim_params()[:, None]
    res = integrate_lanes(y0, p, 5.0 / tu, 1e-10, 1e-13)
    ref = integrate_adaptive(y0, p, 5.0 / tu, 1e-12, 1e-15, observer=OBSERVER, n_slots=N_OBS,
                             fixed_frame=True)
    assert res.outcome[0] == OK
    assert math.hypot(*(res.traj[:2, 0] - ref.y_end[:2, 0])) * ball.a < 1e-8


def test_lanes_failures_stay_in_their_lane(around_square):
    y0, p, T, _ = around_square
    bad = y0.copy()
    bad[5, 3] = np.nan  # thetadot of launch 3
    res = integrate_lanes(bad, p, T, 1e-8, 1e-11)
    good = integrate_lanes(y0, p, T, 1e-8, 1e-11)
    assert res.outcome[3] == NONFINITE and np.isfinite(res.t_stop[3])
    keep = np.arange(y0.shape[1]) != 3
    assert (res.outcome[keep] == OK).all()
    assert np.array_equal(res.traj[:, keep], good.traj[:, keep])
    short = integrate_lanes(y0[:, :2], p[:, :2], T, 1e-8, 1e-11, max_steps=20)
    assert (short.outcome == STEP_BUDGET).all() and (short.t_stop < T).all()


def test_lanes_refuse_bad_tolerances(around_square):
    y0, p, T, _ = around_square
    with pytest.raises(ValueError, match="finite atol"):
        integrate_lanes(y0, p, T, 1e-8, 0.0)
    with pytest.raises(ValueError, match="T must be"):
        integrate_lanes(y0, p, math.inf, 1e-8, 1e-11)


def test_ensemble_work_precision_table():
    from ballsurvey.accuracy import ensemble_work_precision

    lines = []
    rows = ensemble_work_precision(n=4, repeats=1, emit=lines.append, rtols=(1e-6, 1e-9),
                                   dts=(2e-4,), dopri5_rtols=(1e-8,))
    by = {(r["method"], r["setting"]): r for r in rows}
    assert set(by) == {("dop853", 1e-6), ("dop853", 1e-9), ("dopri5", 1e-8), ("rk4", 2e-4)}
    # errors are measured against the reference, so they follow the settings
    assert by["dop853", 1e-9]["max_err_m"] < by["dop853", 1e-6]["median_err_m"]
    assert by["dop853", 1e-9]["max_err_m"] < 1e-7
    assert all(r["launches_per_s"] > 0 for r in rows)
    assert any("independent check" in line for line in lines)


def test_cli_ensemble_refuses_no_launches():
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "ballsurvey", "accuracy", "--ensemble", "0"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1


def test_lanes_refuse_unusable_settings(around_square):
    y0, p, T, _ = around_square
    for kw in (dict(atol=math.inf), dict(rtol=math.nan), dict(rtol=-1.0), dict(h_init=0.0),
               dict(h_init=math.nan)):
        with pytest.raises(ValueError):
            integrate_lanes(y0, p, T, **{"rtol": 1e-8, "atol": 1e-11, **kw})
    # a first step below the floor starts above it instead of underflowing
    tiny = integrate_lanes(y0[:, :2], p[:, :2], T, 1e-8, 1e-11, h_init=1e-300)
    assert (tiny.outcome == OK).all()



@njit
def _one_store_start(obs, i, y, f, c, A, B):
    obs[0, i] = y[0]


@njit
def _one_store_step(obs, i, t0, h, ya, fa, yb, fb, c, A, B, last):
    obs[0, i] = t0


@njit
def _never_done(obs, i, target):
    return False


def _packed_multiplies(source: str, bind_observer: bool, call) -> int:
    """Packed double multiplies in the machine code of a generated lane module's block function,
    compiled here without the disk cache (numba shows no code it loaded from it)."""
    import re
    import types

    mod = types.ModuleType("lanes_vectorised_probe")
    exec(compile(source.replace("cache=True", "cache=False"), "<lanes probe>", "exec"),
         mod.__dict__)
    if bind_observer:  # the trial loop never sees the observer: a one-store one compiles in
        mod.start, mod.step, mod.done = _one_store_start, _one_store_step, _never_done  # less time
    fn = call(mod)
    return len(re.findall(r"\bv?mulpd\b", "\n".join(fn.inspect_asm().values())))


@pytest.mark.skipif(__import__("platform").machine() not in ("x86_64", "AMD64"),
                    reason="checks x86 packed instructions")
@pytest.mark.parametrize("kernel", ["bare", "observed"])
def test_the_lane_trial_loop_is_vectorised(kernel):
    # a guard on a measured fact (docs/performance.md, "How the kernels are built"): with one
    # more array in the trial loop (a live-flag row, the step counters, the kept slopes) LLVM
    # keeps it scalar, 2.7x slower
    from ballsurvey.integrate.lanes import observed_module_source

    n = 8
    p = np.repeat(Ball.paper().nondim_params()[:, None], n, 1)
    if kernel == "bare":
        v0 = np.zeros((fixed.N_FIXED, n))
        v0[fixed.EZ] = 1.0  # upright axis, spinning: a valid state
        v0[fixed.BX] = 1.0
        v0[fixed.WZ] = 2.0

        def call(mod):
            mod.run_block(v0, p, 0.01, 1e-9, 1e-12, 1e-3, 1000, 0, n, np.empty_like(v0),
                          np.zeros(n, np.int64), np.zeros(n, np.int8), np.zeros(n))
            return mod.run_block

        packed = _packed_multiplies(kernel_module_source(DOP853), False, call)
    else:
        y0 = launch_state(np.full(n, -5.0), 0.0, 4.05, -3.0, Ball.paper().time_unit)

        def call(mod):
            mod.run_serial(y0, p, 0.05, 1e-9, 1e-12, 1e-3, 1000, n, 1, 0,
                           np.full((N_OBS, n), np.nan), np.empty((fixed.N_FIXED, n)),
                           np.zeros(n, np.int64), np.zeros(n, np.int8), np.zeros(n))
            return mod.run_group

        packed = _packed_multiplies(observed_module_source(DOP853), True, call)
    assert packed > 500, f"{packed} packed multiplies: the trial loop is not vectorised"

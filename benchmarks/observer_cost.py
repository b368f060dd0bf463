"""What each part of the streaming observer costs inside the RK4 ensemble kernel (the kernel of
`ballsurvey bench`: 4096 launches x 2000 steps, dt = 1e-4 s, a sample every 4 steps).

Each row is the same kernel with the observer, or a part of it, taken out: the observer module's
source is executed again with a physics function replaced by a constant stub (so the part and what
only it feeds are gone), and the kernel compiled against that copy's block functions
(`block_open`, `block_record`, `block_close`), in memory (numba's on-disk cache is never touched:
a stub must not reach a real run). The rows are timed in turns, best of
`--repeats`, so the machine's noise hits them alike. The figures are costs above the bare kernel
(no observer), in per cent of its time. The stubbed rows compute wrong fields: they are for timing
only. Needs only ballsurvey:

    python benchmarks/observer_cost.py [--repeats 5]
"""
from __future__ import annotations

import argparse
import inspect
import time
import types

import numba
import numpy as np

from ballsurvey import bench
from ballsurvey.classify import observer as observer_module
from ballsurvey.classify.observer import N_OBS
from ballsurvey.integrate.binding import inlined
from ballsurvey.integrate.ensemble import kernel_module_source

N_LAUNCHES, N_STEPS, DT, EVERY, BLOCK = 4096, 2000, 1e-4, 4, 64


@numba.njit
def _zero(sth, cth, thd, chd, phd, c, A, B):
    return 0.0


@numba.njit
def _one(sth, cth, thd, thdd, c):
    return 1.0


@numba.njit
def _no_accelerations(sth, cth, thd, chd, phd, c, A, B):
    return 0.0, 0.0, 0.0


@numba.njit
def _no_record(lanes, obs, alive, first, t, dt, x, y, th, sth, cth, chi, thd, chd, phd, c, A, B):
    for i in range(x.shape[0]):
        obs[0, i] = t  # one store a launch and sample, so the sample loop is kept


def _module(source: str, name: str, **stubs) -> types.ModuleType:
    """`source` executed as a fresh module, in memory and uncached, with names replaced."""
    mod = types.ModuleType(name)
    mod.__package__ = "ballsurvey.classify"
    exec(compile(source.replace("cache=True", "cache=False"), f"<{name}>", "exec"), mod.__dict__)
    for key, value in stubs.items():
        setattr(mod, key, value)
    return mod


def _kernel(block_open, block_record, block_close, done):
    """The RK4 kernel as `ensemble.make_kernels` binds it (numba inlines the block functions),
    in memory."""
    kernel = _module(kernel_module_source("rk4"), "observer_cost_kernel")
    kernel.block_open, kernel.block_record = inlined(block_open), inlined(block_record)
    kernel.block_close, kernel.done = inlined(block_close), done
    return kernel.run_parallel


def _observer(**stubs):
    obs = _module(inspect.getsource(observer_module), "observer_cost_observer", **stubs)
    return obs.block_open, obs.block_record, obs.block_close, obs.cycles_done


def variants() -> dict:
    """name -> (kernel, slots); the first is the bare kernel."""
    full = _observer()
    no_invariants = _observer(energy=_zero, jellett=_zero, routh=_zero)
    physics_free = _observer(energy=_zero, jellett=_zero, routh=_zero, normal_force=_one,
                             accelerations=_no_accelerations)
    return {
        "bare kernel (no observer)": (_kernel(*full), 0),
        "observer, all of it": (_kernel(*full), N_OBS),
        "  without the sample's accelerations": (
            _kernel(*_observer(accelerations=_no_accelerations)), N_OBS),
        "  without the invariants (E, J, R)": (_kernel(*no_invariants), N_OBS),
        "  without invariants, normal force, accelerations": (_kernel(*physics_free), N_OBS),
        "  one store a sample (the sample loop alone)": (
            _kernel(full[0], _no_record, full[2], full[3]), N_OBS),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    ball, y0, params, *_ = bench._kernel_launches(N_LAUNCHES, 0)
    dt = DT / ball.time_unit
    n = y0.shape[1]

    def run(kernel, slots):
        obs = np.full((max(slots, 1), n), np.nan)
        traj = np.full((0, y0.shape[0], n), np.nan)
        y_end, outcome, t_stop = np.empty_like(y0), np.zeros(n, np.int8), np.full(n, np.nan)
        kernel(y0, params, dt, N_STEPS, BLOCK, 1e-3, slots > 0, EVERY, obs, traj, 1, y_end, 0,
               outcome, t_stop)
        return obs, y_end

    rows = variants()
    for kernel, slots in rows.values():  # compile
        run(kernel, slots)
    best = dict.fromkeys(rows, np.inf)
    for _ in range(args.repeats):  # in turns: noise hits every row alike
        for name, (kernel, slots) in rows.items():
            t0 = time.perf_counter()
            run(kernel, slots)
            best[name] = min(best[name], time.perf_counter() - t0)
    bare = best["bare kernel (no observer)"]
    samples = n * (N_STEPS // EVERY + 1)
    print(f"observer cost: {N_LAUNCHES} launches x {N_STEPS} RK4 steps (dt = {DT} s), a sample "
          f"every {EVERY} steps, {numba.get_num_threads()} threads, best of {args.repeats}")
    print(f"  {'kernel':52s}{'IC-steps/s':>12s}{'above bare':>12s}{'ns/sample':>11s}")
    for name, t in best.items():
        extra = (t - bare) * numba.get_num_threads() / samples * 1e9
        print(f"  {name:52s}{n * N_STEPS / t:12.3e}{(t / bare - 1) * 100:11.0f}%{extra:11.1f}")
    print("  (ns/sample: core time above the bare kernel per launch and sample)")


if __name__ == "__main__":
    main()

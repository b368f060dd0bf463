"""CUDA backend: the fixed-step ensemble kernel on an NVIDIA GPU (numba-cuda), one thread a launch.

Imported only when asked (`backend = "cuda"`): nothing here runs at package import, and numba's
CUDA target is loaded by `cuda_module()` on first use. The kernel is generated from the same Butcher
tableau data as the CPU kernel (`tableaus.FIXED_STEP`, `tableaus.stage_source`), and it calls the
same right-hand side and the observer it is handed (an `Observer`, as the CPU kernels take): their
numba-compiled CPU functions are re-targeted to CUDA device functions from their Python source
(`device_twin`), so a formula or an observer quantity is written once for both backends.

Layout: state arrays are (variable, launch), so consecutive threads touch consecutive addresses
(coalesced). The observer's record stays in global memory, never in registers: on the card it is
an array of tiles, one a warp (`TILE` launches), each tile a (slot, lane) block, so slot k of
launch i sits at (i // TILE) * n_slots * TILE + k * TILE + i % TILE (coalesced as well). The tile's
shape is part of the array's type (a numpy record with one sub-array field, `record_dtype`), so
the compiler knows every slot's offset from the tile's start: one base address a thread instead
of one 64-bit address a slot, which the compiler hoisted out of the step loop into registers (and
spilt). The kernel is compiled again for another number of slots, so an observer that gains slots
needs no change here. The RK stages are written out from the tableau with each group of equal
weights summed as soon as its last stage exists, and the values a step carries across two or
more right-hand side calls (its start state; RK4's k0) kept in the block's shared memory
(`streamed_stage_source`): the same operations in the same order as the CPU kernel, with fewer
values in registers at once. `benchmarks/ptxas.py` reports registers and spills for sm_90
without a GPU.

Launches are streamed through the card in batches (`batch` launches at a time, by default sized to
a quarter of its free memory), so a map larger than the card works; only the observer slots and
the end states come back.

Results agree with the CPU backend to rounding (the operations are the same, but the GPU compiler
may contract a * b + c into one fused multiply-add), not bit for bit; in the simulator, bit for
bit. A lane that turns non-finite or reaches the Euler chart's singularity stops there (the CPU
kernel keeps stepping its frozen lane inside the SIMD block); its observer record is the same.

Without a GPU the same code runs in numba's CUDA simulator (`NUMBA_ENABLE_CUDASIM=1`, set before
numba.cuda is imported): that is how the tests check it.
"""
from __future__ import annotations

import math
import types
from functools import cache

import numpy as np

from ..physics.euler import accelerations
from ..physics.fast import N_FAST, fast_rhs
from .binding import Observer
from .outcome import CHART_SINGULAR, EULER_ANGLES, NONFINITE, Result
from .tableaus import FIXED_STEP, Tableau, _grouped, stage_source, step_constants

#: threads a block on a GPU (the shared-memory arrays of the step are sized for it)
THREADS_PER_BLOCK = 128
#: launches a tile of the observer record holds (a warp: one tile's slot k is one 256-byte line)
TILE = 32
#: the record dtype's one field: a (slot, lane) float64 block
TILE_FIELD = "slots"
#: the observer record's layouts on the card (`kernel_source`): "tiles" is the one in use,
#: "columns" the plain (slot, launch) array, kept to be measured against (benchmarks/ptxas.py)
RECORD_LAYOUTS = ("tiles", "columns")
#: how the RK update sums its stages: "streamed" (in use) or "final" (the CPU kernel's text)
STAGE_SUMS = ("streamed", "final")
#: where a step keeps the values it carries across right-hand side calls: the block's "shared"
#: memory (in use) or "registers" (the compiler's choice)
CARRY = ("shared", "registers")


class BackendError(RuntimeError):
    """The CUDA backend cannot run here (no numba-cuda, no GPU or driver)."""


def cuda_module():
    """numba.cuda, checked to have a GPU (or the simulator); BackendError with one line if not."""
    if not hasattr(np, "row_stack"):  # numba-cuda still calls it; numpy 2.5 removed it
        np.row_stack = np.vstack
    try:
        from numba import cuda
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise BackendError(f"the CUDA backend needs numba-cuda: pip install 'ballsurvey[cuda]' "
                           f"({exc})") from None
    try:
        ok = cuda.is_available()
    except Exception as exc:  # pragma: no cover - driver errors vary
        raise BackendError(f"no usable CUDA driver: {exc}") from None
    if not ok:
        raise BackendError("no CUDA GPU or driver found (backend = 'cuda'); use backend = 'cpu'")
    return cuda


def device_twin(fn, cuda, _memo=None):
    """A CUDA device function compiled from the Python source of a numba CPU function, with every
    numba function it calls replaced by its own device twin (recursively), or by the device form
    it names (`device_form`: `_jit.sqrt`, whose CPU form is an LLVM intrinsic)."""
    memo = {} if _memo is None else _memo
    py = getattr(fn, "py_func", fn)
    if py in memo:
        return memo[py]
    env = dict(py.__globals__)
    for name in py.__code__.co_names:
        obj = env.get(name)
        if hasattr(obj, "device_form"):
            env[name] = obj.device_form
        elif hasattr(obj, "py_func"):  # a numba dispatcher: use its device twin
            env[name] = device_twin(obj, cuda, memo)
    clone = types.FunctionType(py.__code__, env, py.__name__, py.__defaults__, py.__closure__)
    memo[py] = cuda.jit(device=True)(clone)
    return memo[py]


_TEMPLATE = '''
def kernel(y0, params, dt, n_steps, cos_min, observer_on, observe_every, obs, y_end, stop_after,
           outcome, t_stop_out):
    i = cuda.grid(1)
    if i >= y0.shape[1]:
        return
{record_view}
{carried}
{load}
    c = params[0, i]
    A = params[1, i]
    B = params[2, i]
    t_seen = 0.0
    status = 0
    t_stop = math.nan
{consts}
    for n in range(n_steps + 1):
        t = n * dt
        if observer_on and (n % observe_every == 0 or n == n_steps):
            thdd, chdd, phdd = accelerations(r8, r9, r5, r6, r7, c, A, B)
            record({rec}, n == 0, t, t - t_seen, r0, r1, r2, r8, r9, r3, r5, r6, r7, thdd, chdd,
                   phdd, c, A, B, math.nan, math.nan, math.nan)
            t_seen = t
            if stop_after > 0 and done({rec}, stop_after):
                break  # period mode: enough theta cycles seen
        if n == n_steps:
            break
        s0 = ({tuple_r})
{stages}
{update}
        if (n + 1) % observe_every == 0 or n + 1 == n_steps:
            if not math.isfinite(r0 + r1 + r5 + r6 + r7):
                status = NONFINITE
                t_stop = t + dt
                break
            elif r9 < cos_min:
                status = CHART_SINGULAR
                t_stop = t + dt
                break
{store}
    outcome[i] = status
    t_stop_out[i] = t_stop
'''

#: (how the kernel names launch i's record, what it calls record and done with), by layout
_RECORD_VIEW = {
    "tiles": (f"    tile = obs[i // {TILE}][{TILE_FIELD!r}]\n    lane = i % {TILE}", "tile, lane"),
    "columns": ("", "obs, i"),
}


def streamed_stage_source(tab: Tableau, n_vars: int, indent: str,
                          carry: str = "registers") -> tuple[str, str]:
    """`tableaus.stage_source`'s step with the update's sums formed early: each group of equal
    weights (RK4's k0 + k3 and k1 + k2) is summed as soon as its last stage exists, left to right
    as the CPU kernel's text sums it, so the stages it holds need not stay alive to the end of the
    step. The same floating-point operations in the same order: the same numbers, bit for bit.

    carry "shared": every value read two or more right-hand side calls after it was made (the
    step's start state s0; RK4's k0, kept for k0 + k3) is stored in the block's shared memory
    (array `st_<name>`, column `tid`) and read back from there, with a block memory fence after
    each call, so that the compiler can neither forward a stored value nor reuse a loaded one
    across a call: it cannot keep them in registers instead. The kernel declares the arrays
    (`carried`). "registers": the compiler decides where they live."""
    return _streamed(tab, n_vars, indent, carry)[:2]


def _streamed(tab: Tableau, n_vars: int, indent: str, carry: str):
    """streamed_stage_source's (stages, update) and the set of names carried in shared memory."""
    v = range(n_vars)
    groups = _grouped(enumerate(tab.b))

    def emit(staged):
        out, events, seg, born = [], [], 0, {"s0": 0}

        def ref(name, q):
            events.append((name, born[name], seg))
            if name in staged and born[name] < seg:
                return f"st_{name}[{q}, tid]"
            return f"{name}[{q}]"

        def define(name, text):
            born[name] = seg
            out.append(f"{indent}{name} = {text}")
            if name in staged:
                out.extend(f"{indent}st_{name}[{q}, tid] = {name}[{q}]" for q in v)

        if "s0" in staged:
            out.extend(f"{indent}st_s0[{q}, tid] = s0[{q}]" for q in v)
        for s in range(tab.stages):
            if s > 0:
                terms = [(f"dta{s}_{g}", js)
                         for g, (_, js) in enumerate(_grouped(enumerate(tab.a[s, :s])))]
                comps = []
                for q in v:
                    parts = []
                    for h, js in terms:
                        ks = " + ".join(ref(f"k{j}", q) for j in js)
                        parts.append(f"{h} * ({ks})" if len(js) > 1 else f"{h} * {ks}")
                    comps.append(f"{ref('s0', q)} + ({' + '.join(parts)})")
                define(f"s{s}", "(" + ", ".join(comps) + ")")
            out.append(f"{indent}k{s} = fast_rhs(s{s}, c, A, B)")
            seg += 1
            born[f"k{s}"] = seg
            if carry == "shared":
                out.append(f"{indent}cuda.threadfence_block()")
            if f"k{s}" in staged:
                out.extend(f"{indent}st_k{s}[{q}, tid] = k{s}[{q}]" for q in v)
            for g, (_, js) in enumerate(groups):
                if s in js[1:]:  # this stage extends group g's running sum
                    prev = f"k{js[0]}" if s == js[1] else f"g{g}"
                    define(f"g{g}", "(" + ", ".join(f"{ref(prev, q)} + {ref(f'k{s}', q)}"
                                                    for q in v) + ")")
        names = [f"dtb{g}" for g in range(len(groups))]
        sums = [(h, f"g{g}" if len(js) > 1 else f"k{js[0]}") for g, (h, (_, js)) in
                enumerate(zip(names, groups))]
        update = [f"{indent}r{q} = {ref('s0', q)} + ("
                  + " + ".join(f"{h} * {ref(name, q)}" for h, name in sums) + ")" for q in v]
        return out, update, events

    staged: set = set()
    if carry == "shared":
        _, _, events = emit(staged)
        staged = {name for name, born, seg in events if seg - born >= 2}
    out, update, _ = emit(staged)
    return "\n".join(out), "\n".join(update), staged


def carried(tab: Tableau, n_vars: int) -> list[str]:
    """Names of the values `streamed_stage_source(..., carry="shared")` keeps in shared memory
    (the kernel declares an array `st_<name>` for each)."""
    return sorted(_streamed(tab, n_vars, "", "shared")[2])


def kernel_source(tab: Tableau, *, record: str = "tiles", sums: str = "streamed",
                  carry: str = "shared") -> str:
    """The CUDA kernel's Python source for a tableau (the stages written out, as on the CPU).

    record: the observer record's layout (RECORD_LAYOUTS); sums: how the update sums its stages
    (STAGE_SUMS); carry: where the values a step carries across right-hand side calls live
    (CARRY; "shared" needs sums "streamed"). The defaults are the kernel `integrate` runs; the
    others are there to be measured against it (benchmarks/ptxas.py)."""
    if record not in RECORD_LAYOUTS or sums not in STAGE_SUMS or carry not in CARRY:
        raise ValueError(f"record must be one of {RECORD_LAYOUTS}, sums one of {STAGE_SUMS}, "
                         f"carry one of {CARRY}")
    if carry == "shared" and sums != "streamed":
        raise ValueError("carry 'shared' is written for sums 'streamed'")
    v = range(N_FAST)
    if sums == "streamed":
        stages, update = streamed_stage_source(tab, N_FAST, " " * 8, carry=carry)
    else:
        stages, update = stage_source(tab, N_FAST, " " * 8)
    view, rec = _RECORD_VIEW[record]
    shared = carried(tab, N_FAST) if carry == "shared" else []
    decl = "".join(f"    st_{name} = cuda.shared.array(({N_FAST}, {THREADS_PER_BLOCK}), float64)\n"
                   for name in shared)
    return _TEMPLATE.format(
        record_view=view,
        rec=rec,
        carried=decl + "    tid = cuda.threadIdx.x" if shared else "",
        load="\n".join(f"    r{q} = y0[{q}, i]" for q in v),
        tuple_r=", ".join(f"r{q}" for q in v),
        stages=stages,
        update=update,
        store="\n".join(f"    y_end[{q}, i] = r{q}" for q in v),
        consts=step_constants(tab, " " * 4),
    )


def kernel_function(method: str, observer: Observer, cuda, **variant):
    """The kernel as a Python function whose globals are the device twins of the right-hand side
    and of the observer (for `cuda.jit`, or `cuda.compile_ptx` without a GPU). variant:
    `kernel_source`'s record, sums and carry."""
    if method not in FIXED_STEP:
        raise ValueError(f"unknown method {method!r}; known: {', '.join(FIXED_STEP)}")
    from numba import float64

    memo: dict = {}
    ns = {
        "cuda": cuda, "math": math, "float64": float64,
        "accelerations": device_twin(accelerations, cuda, memo),
        "fast_rhs": device_twin(fast_rhs, cuda, memo),
        "record": device_twin(observer.record, cuda, memo),
        "done": device_twin(observer.done, cuda, memo),
        "NONFINITE": NONFINITE, "CHART_SINGULAR": CHART_SINGULAR,
    }
    src = kernel_source(FIXED_STEP[method], **variant)
    exec(compile(src, f"<ballsurvey cuda kernel {method}>", "exec"), ns)
    return ns["kernel"]


def record_dtype(n_slots: int) -> np.dtype:
    """The observer record's element on the card: one tile, a (n_slots, TILE) float64 block."""
    return np.dtype([(TILE_FIELD, np.float64, (n_slots, TILE))])


def nan_tiles(n_slots: int, m: int) -> np.ndarray:
    """The record of m launches as the card holds it, every slot NaN: ceil(m / TILE) tiles."""
    tiles = np.empty(-(-m // TILE), dtype=record_dtype(n_slots))
    tiles[TILE_FIELD] = np.nan
    return tiles


def from_tiles(tiles: np.ndarray, m: int) -> np.ndarray:
    """The card's tiles -> (n_slots, m) record columns: launch i's slot k is tile i // TILE,
    row k, lane i % TILE."""
    block = tiles[TILE_FIELD]  # (n_tiles, n_slots, TILE)
    return block.transpose(1, 0, 2).reshape(block.shape[1], -1)[:, :m]


@cache
def make_kernel(method: str, observer: Observer, **variant):
    """The compiled CUDA kernel for a fixed-step method named in FIXED_STEP, with `observer`;
    variant: `kernel_source`'s record, sums and carry (default: the kernel in use)."""
    if method not in FIXED_STEP:
        raise ValueError(f"unknown method {method!r}; known: {', '.join(FIXED_STEP)}")
    cuda = cuda_module()
    return cuda.jit(kernel_function(method, observer, cuda, **variant))


def threads_per_block() -> int:
    """THREADS_PER_BLOCK on a GPU; 1 in numba's simulator, which runs a block's threads as Python
    threads and swaps the `cuda` global of device functions without a lock: with several threads
    a call intermittently failed there ("dictionary changed size during iteration", a race fixed
    upstream in NVIDIA/numba-cuda#690). Each launch is its own thread, so results do not change."""
    import numba

    return 1 if numba.config.ENABLE_CUDASIM else THREADS_PER_BLOCK


def default_batch(cuda, n_slots: int) -> int:
    """Launches per batch: a quarter of the card's free memory (the simulator: 4096)."""
    per_launch = 8 * (2 * N_FAST + 3 + n_slots) + 1
    try:
        free, _ = cuda.current_context().get_memory_info()
        free = float(free)
    except Exception:  # pragma: no cover - the driver's answer varies
        free = math.nan
    if not math.isfinite(free) or free <= 0:  # the simulator has no memory to tell of
        return 4096
    return max(THREADS_PER_BLOCK, int(free // 4 // per_launch))


def integrate(y0, params, dt, n_steps, method="rk4", *, observer: Observer, n_slots: int,
              cos_min=1e-3, observe_every=1, stop_after=0, batch: int | None = None,
              variant: dict | None = None) -> Result:
    """The CPU `ensemble.integrate` on the GPU, without a trajectory: a `Result`.

    y0: (N_FAST, n) fast states; params: (3, n) non-dimensional (c, A, B); dt, n_steps:
    non-dimensional step and count; the observer (n_slots slots per launch) sees every
    `observe_every`-th step and the last. Launches go through the card `batch` at a time.
    variant: `kernel_source`'s record, sums and carry, to time the kernel's variants against the
    one in use (benchmarks/ptxas.py --time); the results are the same."""
    y0 = np.ascontiguousarray(y0, dtype=np.float64)
    params = np.ascontiguousarray(params, dtype=np.float64)
    n = y0.shape[1]
    if y0.shape[0] != N_FAST or params.shape != (3, n):
        raise ValueError(f"need y0 ({N_FAST}, n) and params (3, n); got {y0.shape}, {params.shape}")
    variant = dict(variant or {})
    kern = make_kernel(method, observer, **variant)
    tiled = variant.get("record", "tiles") == "tiles"
    cuda = cuda_module()
    slots = max(int(n_slots), 1)
    batch = int(batch or default_batch(cuda, slots))
    obs = np.empty((slots, n))
    y_end = np.empty_like(y0)
    outcome = np.empty(n, dtype=np.int8)
    t_stop = np.empty(n)
    threads = threads_per_block()
    for lo in range(0, n, batch):
        hi = min(n, lo + batch)
        m = hi - lo
        d_obs = cuda.to_device(nan_tiles(slots, m) if tiled else np.full((slots, m), np.nan))
        d_end = cuda.device_array((N_FAST, m))
        d_out = cuda.device_array(m, dtype=np.int8)
        d_stop = cuda.device_array(m)
        blocks = (m + threads - 1) // threads
        kern[blocks, threads](
            cuda.to_device(np.ascontiguousarray(y0[:, lo:hi])),
            cuda.to_device(np.ascontiguousarray(params[:, lo:hi])), float(dt), int(n_steps),
            float(cos_min), n_slots > 0, max(1, int(observe_every)), d_obs, d_end,
            int(stop_after), d_out, d_stop)
        obs[:, lo:hi] = from_tiles(d_obs.copy_to_host(), m) if tiled else d_obs.copy_to_host()
        y_end[:, lo:hi] = d_end.copy_to_host()
        outcome[lo:hi] = d_out.copy_to_host()
        t_stop[lo:hi] = d_stop.copy_to_host()
    return Result(obs=obs[:n_slots], outcome=outcome, t_stop=t_stop,
                  formulation=np.full(n, EULER_ANGLES, dtype=np.int8), y_end=y_end,
                  n_steps=np.full(n, int(n_steps), dtype=np.int64), t=np.empty(0),
                  traj=np.empty((0, N_FAST, n)))


_PER_LAUNCH_TEMPLATE = '''
def kernel(y0, params, T, stop_after, steady_tol, s, sin_s, cos_s, weights, qm, offsets, obs,
           status):
    i = cuda.grid(1)
    if i >= y0.shape[1]:
        return
    scr = cuda.local.array(({n_scratch}, {n_points}), float64)
    node = cuda.local.array(({n_node}, {n_points}), float64)
    status[i] = one(y0[{th}, i], y0[{thd}, i], y0[{chd}, i], y0[{phd}, i], params[0, i],
                    params[1, i], params[2, i], T, stop_after, steady_tol, s, sin_s, cos_s,
                    weights, qm, offsets, scr, node, obs, i)
'''


@cache
def make_per_launch_kernel(one, n_scratch: int, n_node: int, n_points: int):
    """The compiled CUDA kernel that runs a per-launch function of `classify.cycle.cycle_one`'s
    signature (a launch's tilt and rates, its parameters, the run's scalars and tables, two
    scratch arrays, the record and the launch's column) one thread a launch; the scratch arrays
    are the thread's local memory (n_scratch and n_node rows of n_points)."""
    from numba import float64

    from ..physics.fast import S_CHD, S_PHD, S_TH, S_THD

    cuda = cuda_module()
    ns = {"cuda": cuda, "float64": float64, "one": device_twin(one, cuda)}
    src = _PER_LAUNCH_TEMPLATE.format(n_scratch=n_scratch, n_node=n_node, n_points=n_points,
                                      th=S_TH, thd=S_THD, chd=S_CHD, phd=S_PHD)
    exec(compile(src, "<ballsurvey cuda per-launch kernel>", "exec"), ns)
    return cuda.jit(ns["kernel"])


def per_launch(one, y0, params, T, stop_after, steady_tol, tables, *, n_scratch: int,
               n_node: int, n_points: int, n_slots: int, batch: int | None = None):
    """`one` (see `make_per_launch_kernel`) over every launch on the GPU: (record (n_slots, n),
    status (n,) int8). y0: (N_FAST, n) fast states; params: (3, n); tables: the arrays `one`
    reads (copied to the card once). Launches go through the card `batch` at a time."""
    y0 = np.ascontiguousarray(y0, dtype=np.float64)
    params = np.ascontiguousarray(params, dtype=np.float64)
    n = y0.shape[1]
    obs = np.full((n_slots, n), np.nan)
    status = np.zeros(n, dtype=np.int8)
    if not n:
        return obs, status
    kern = make_per_launch_kernel(one, n_scratch, n_node, n_points)
    cuda = cuda_module()
    d_tabs = [cuda.to_device(np.ascontiguousarray(t)) for t in tables]
    batch = int(batch or default_batch(cuda, n_slots))
    threads = threads_per_block()
    for lo in range(0, n, batch):
        hi = min(n, lo + batch)
        m = hi - lo
        d_obs = cuda.to_device(np.full((n_slots, m), np.nan))
        d_status = cuda.device_array(m, dtype=np.int8)
        kern[(m + threads - 1) // threads, threads](
            cuda.to_device(np.ascontiguousarray(y0[:, lo:hi])),
            cuda.to_device(np.ascontiguousarray(params[:, lo:hi])), float(T), int(stop_after),
            float(steady_tol), *d_tabs, d_obs, d_status)
        obs[:, lo:hi] = d_obs.copy_to_host()
        status[lo:hi] = d_status.copy_to_host()
    return obs, status

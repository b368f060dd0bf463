"""Registers, spills and local memory of the CUDA kernel per thread, for an NVIDIA architecture,
measured without a GPU: the kernel is compiled to PTX by numba-cuda (`numba.cuda.compile_ptx`)
and assembled by NVIDIA's `ptxas -v`, which reports what the card would run.

    pip install numba-cuda nvidia-cuda-nvcc-cu12 nvidia-cuda-nvrtc-cu12
    python benchmarks/ptxas.py [--method rk4,rk38] [--arch sm_90] [--cap 160,128]
    python benchmarks/ptxas.py --time 4194304 [--steps 2000]    # on a GPU: the variants timed

One row per kernel variant (`integrate.cuda.kernel_source`): the observer record as tiles (in
use) or as plain (slot, launch) columns, and the RK update summing its stages as they come
(streamed, in use) or at the end (final, the CPU kernel's text); record "none" is the step loop
alone (an observer that records nothing), the floor the observer adds to. Columns: registers a
thread, spill stores and loads (bytes a thread), stack frame (local memory, bytes a thread),
shared memory (bytes a block), and the warps an SM can hold by registers alone (65536 registers
an SM, allocated 8 a thread at a time, in whole blocks of 128 threads; an H100 SM holds at most
64 warps). --cap N adds the variant in use compiled with `ptxas -maxrregcount N` (a list:
--cap 160,128): what capping registers would cost in spills.

ptxas is found as $PTXAS, in the nvidia-cuda-nvcc-cu12 wheel, or on PATH.

--time N (needs a GPU, or numba's simulator at tiny N): each variant run on the card back to back
in one process, `integrate.cuda.integrate` with the map's observer (every 4 steps) on N launches
of `bench --backend cuda` x --steps RK steps, best of 3, transfers included: IC-steps/s, and the
largest difference of its observer record from the kernel in use's (the same science: 0 up to
the compiler's fused multiply-adds).
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
import types
from contextlib import contextmanager
from importlib.metadata import version
from pathlib import Path

import numpy as np

REGISTERS_PER_SM = 65536
MAX_WARPS_PER_SM = 64


def find_ptxas() -> str:
    """Path of ptxas: $PTXAS, the nvidia-cuda-nvcc wheel's, or the one on PATH."""
    if os.environ.get("PTXAS"):
        return os.environ["PTXAS"]
    spec = importlib.util.find_spec("nvidia.cuda_nvcc")
    for root in (spec.submodule_search_locations or []) if spec else []:
        cand = Path(root) / "bin" / "ptxas"
        if cand.is_file():
            return str(cand)
    found = shutil.which("ptxas")
    if found:
        return found
    raise SystemExit("ptxas.py: no ptxas found: pip install nvidia-cuda-nvcc-cu12 (or set PTXAS)")


@contextmanager
def no_device(cc):
    """numba-cuda asks the current device for its compute capability when it compiles a device
    function; without a GPU, answer with `cc` (the PTX is for cc anyway)."""
    import numba.cuda.dispatcher as disp

    real = disp.get_current_device
    disp.get_current_device = lambda: types.SimpleNamespace(compute_capability=cc)
    try:
        yield
    finally:
        disp.get_current_device = real


def _record_nothing(obs, i, first, t, dt, x, y, th, sth, cth, chi, thd, chd, phd, thdd, chdd,
                    phdd, c, A, B, psid, fric, normal):
    pass


def _never_done(obs, i, target):
    return False


def kernel_ptx(method: str, cc: tuple[int, int], bare: bool = False, **variant) -> str:
    """PTX of the map's kernel (the map's observer, its N_OBS slots) for compute capability cc;
    bare: with an observer that records nothing (the step loop alone)."""
    if not hasattr(np, "row_stack"):  # numba-cuda still calls it; numpy 2.5 removed it
        np.row_stack = np.vstack
    import numba
    from numba import cuda
    from numba import types as nt

    from ballsurvey.classify.observer import N_OBS
    from ballsurvey.compose import OBSERVER
    from ballsurvey.integrate import cuda as bc
    from ballsurvey.integrate.binding import Observer

    a2, f1 = nt.float64[:, ::1], nt.float64[::1]
    if variant.get("record", "tiles") == "tiles":
        obs = numba.from_dtype(bc.record_dtype(N_OBS))[::1]
    else:
        obs = a2
    # y0, params, dt, n_steps, cos_min, observer_on, observe_every, obs, y_end, stop_after,
    # outcome, t_stop_out: as integrate() passes them
    sig = (a2, a2, nt.float64, nt.int64, nt.float64, nt.boolean, nt.int64, obs, a2, nt.int64,
           nt.int8[::1], f1)
    observer = OBSERVER
    if bare:
        observer = Observer(record=numba.njit(_record_nothing), done=numba.njit(_never_done))
    with no_device(cc):
        fn = bc.kernel_function(method, observer, cuda, **variant)
        ptx, _ = cuda.compile_ptx(fn, sig, cc=cc)
    return ptx


def checked_ptx(method: str, cc: tuple[int, int], **kw) -> str:
    """`kernel_ptx`, with one line instead of a traceback when numba-cuda or NVRTC is missing."""
    try:
        return kernel_ptx(method, cc, **kw)
    except ImportError as exc:
        raise SystemExit(f"ptxas.py: {exc}: pip install numba-cuda") from None
    except Exception as exc:
        if "nvrtc" in str(exc).lower():
            raise SystemExit("ptxas.py: numba-cuda needs NVRTC to compile: "
                             "pip install nvidia-cuda-nvrtc-cu12") from None
        raise


def ptxas_figures(text: str) -> dict:
    """The kernel's figures from `ptxas -v` output (the entry whose name holds 'kernel')."""
    fig = {}
    blocks = re.split(r"ptxas info\s*: Compiling entry function", text)
    for block in blocks[1:]:
        if "kernel" not in block.split("\n", 1)[0]:
            continue
        m = re.search(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads",
                      block)
        if m:
            fig["stack"], fig["spill_st"], fig["spill_ld"] = map(int, m.groups())
        m = re.search(r"Used (\d+) registers", block)
        if m:
            fig["regs"] = int(m.group(1))
        m = re.search(r"(\d+) bytes smem", block)
        fig["smem"] = int(m.group(1)) if m else 0
    if "regs" not in fig:
        raise SystemExit(f"ptxas.py: no kernel figures in ptxas' output:\n{text[-2000:]}")
    return fig


def warps_by_registers(regs: int, block_warps: int = 4) -> int:
    """Warps an SM holds when each thread takes `regs` registers (allocated 8 at a time), in
    whole blocks of `block_warps` warps (the kernel's THREADS_PER_BLOCK = 128: 4)."""
    per_warp = -(-regs // 8) * 8 * 32
    warps = min(MAX_WARPS_PER_SM, REGISTERS_PER_SM // per_warp)
    return warps - warps % block_warps


def measure(ptx: str, ptxas: str, arch: str, cap: int | None = None) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "kernel.ptx"
        src.write_text(ptx)
        cmd = [ptxas, "-v", f"-arch={arch}", str(src), "-o", str(Path(tmp) / "kernel.cubin")]
        if cap:
            cmd.insert(1, f"-maxrregcount={cap}")
        r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(f"ptxas.py: ptxas failed: {r.stderr.strip()[-2000:]}")
    return ptxas_figures(r.stdout + r.stderr)


def row(method, record, sums, carry, cap, f):
    print(f"{method:7} {record:8} {sums:9} {carry:9} {cap or '-':>4} {f['regs']:9d} "
          f"{f['spill_st']:10d} "
          f"{f['spill_ld']:10d} {f['stack']:7d} {f['smem']:8d} {warps_by_registers(f['regs']):8d}")


VARIANTS = [("columns", "final", "registers"), ("columns", "streamed", "registers"),
            ("tiles", "final", "registers"), ("tiles", "streamed", "registers"),
            ("tiles", "streamed", "shared")]


def time_variants(methods, n_launches: int, n_steps: int) -> None:
    """IC-steps/s of each variant on the card (see the module docstring)."""
    import time

    from ballsurvey.bench import _best, _kernel_launches
    from ballsurvey.classify.observer import N_OBS
    from ballsurvey.compose import OBSERVER
    from ballsurvey.integrate import cuda as bc

    cuda = bc.cuda_module()
    try:
        name = cuda.get_current_device().name
        name = name.decode() if isinstance(name, bytes) else name
    except AttributeError:  # numba's simulator
        name = "numba's CUDA simulator"
    ball, y0, params, _, _, _ = _kernel_launches(n_launches, 0)
    dt = 1e-4 / ball.time_unit
    print(f"{name}: {n_launches} launches x {n_steps} steps, observer every 4, best of 3")
    print(f"{'method':7} {'record':8} {'sums':9} {'carry':9} {'IC-steps/s':>11} "
          f"{'compile s':>9} {'max |obs - in use|':>18}")
    for method in methods:
        runs = {}
        for record, sums, carry in reversed(VARIANTS):  # the kernel in use first
            v = dict(record=record, sums=sums, carry=carry)
            kw = dict(observer=OBSERVER, n_slots=N_OBS, observe_every=4, variant=v)
            t0 = time.perf_counter()
            bc.integrate(y0[:, :4], params[:, :4], dt, 2, method, **kw)  # compile
            compile_s = time.perf_counter() - t0
            res = {}

            def run(kw=kw, res=res, method=method):
                res["r"] = bc.integrate(y0, params, dt, n_steps, method, **kw)

            best = _best(run, 3)
            runs[(record, sums, carry)] = res["r"].obs
            ref = runs[VARIANTS[-1]]
            diff = np.nanmax(np.abs(res["r"].obs - ref)) if np.isfinite(ref).any() else 0.0
            print(f"{method:7} {record:8} {sums:9} {carry:9} {n_launches * n_steps / best:11.3e} "
                  f"{compile_s:9.1f} {diff:18.1e}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="rk4", help="fixed-step methods, comma-separated")
    ap.add_argument("--arch", default="sm_90", help="NVIDIA architecture (sm_90: H100, H200)")
    ap.add_argument("--cap", default="",
                    help="register caps, comma-separated: the kernel in use also under ptxas "
                         "-maxrregcount CAP (what a cap costs in spills)")
    ap.add_argument("--time", type=int, default=0, metavar="N",
                    help="on a GPU: time each variant on N launches instead (0: not)")
    ap.add_argument("--steps", type=int, default=2000, help="RK steps a launch for --time")
    args = ap.parse_args(argv)
    from ballsurvey.integrate.cuda import BackendError
    from ballsurvey.integrate.tableaus import FIXED_STEP

    methods = args.method.split(",")
    unknown = [m for m in methods if m not in FIXED_STEP]
    if unknown:
        print(f"ptxas.py: --method {unknown[0]!r} is not a fixed-step method "
              f"({', '.join(FIXED_STEP)})", file=sys.stderr)
        return 2
    if args.time:
        try:
            time_variants(methods, args.time, args.steps)
        except BackendError as exc:
            print(f"ptxas.py: --time needs a GPU: {exc}", file=sys.stderr)
            return 2
        return 0
    m = re.fullmatch(r"sm_(\d+)(\d)", args.arch)
    if not m:
        print(f"ptxas.py: --arch must read like sm_90, not {args.arch!r}", file=sys.stderr)
        return 2
    cc = (int(m.group(1)), int(m.group(2)))
    ptxas = find_ptxas()
    about = subprocess.run([ptxas, "--version"], capture_output=True, text=True).stdout
    release = re.search(r"release [^\n]*", about)
    print(f"ptxas -v -arch={args.arch} ({release.group(0) if release else ptxas}); "
          f"numba-cuda {version('numba-cuda')}")
    head = (f"{'method':7} {'record':8} {'sums':9} {'carry':9} {'cap':>4} {'registers':>9} "
            f"{'spill st B':>10} {'spill ld B':>10} {'local B':>7} {'shared B':>8} "
            f"{'warps/SM':>8}")
    print(head)
    caps = [int(c) for c in args.cap.split(",") if c.strip()]
    variants = VARIANTS
    for method in methods:
        for record, sums, carry in variants:
            ptx = checked_ptx(method, cc, record=record, sums=sums, carry=carry)
            for cap in [None] + (caps if (record, sums, carry) == variants[-1] else []):
                row(method, record, sums, carry, cap, measure(ptx, ptxas, args.arch, cap))
        # the step loop alone: an observer that records nothing (its code is left out)
        row(method, "none", "streamed", "shared", None,
            measure(checked_ptx(method, cc, bare=True), ptxas, args.arch))
    return 0


if __name__ == "__main__":
    sys.exit(main())

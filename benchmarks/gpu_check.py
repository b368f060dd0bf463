"""The CUDA backend on a real GPU, in one process (the CUDA kernel is compiled once):

1. `bench --backend cuda`: IC-steps/s with the observer on, and the end positions against the CPU
   kernel;
2. the shipped maps (`sweeps/paper.toml`, `square-map.toml`, `broad.toml`) on both backends:
   labels identical?, and the largest relative difference of the per-cycle figures;
3. the headline map (`bench --headline --backend cuda`): 1e6 launches in period mode, wall time,
   and label agreement against full CPU integration.

    python benchmarks/gpu_check.py [--launches N] [--headline N] [--maps paper,square-map,broad]

Without a GPU it stops with one line; in numba's simulator (NUMBA_ENABLE_CUDASIM=1) it runs, very
slowly, at small sizes (--launches 64 --headline 3 --maps paper), as a check of this script.
"""
import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import xarray as xr

from ballsurvey.bench import run_bench_cuda, run_headline
from ballsurvey.integrate.cuda import BackendError, cuda_module
from ballsurvey.sweep import load_spec, run_sweep

ROOT = Path(__file__).resolve().parents[1]
#: per-cycle figures compared between the backends (relative difference where both are finite)
FIGURES = ("turn_per_cycle_deg", "n_sides", "theta_period_s", "side_m", "roundness",
           "theta_max_deg")


def compare(a: xr.Dataset, b: xr.Dataset) -> tuple[int, int, dict]:
    """(launches with the same label, launches, {figure: largest relative difference})."""
    la, lb = a.label.values.ravel(), b.label.values.ravel()
    same = int(np.sum(la == lb))
    rel = {}
    for name in FIGURES:
        if name not in a or name not in b:
            continue
        x, y = a[name].values.ravel().astype(float), b[name].values.ravel().astype(float)
        ok = np.isfinite(x) & np.isfinite(y) & (la == lb)
        if ok.any():
            d = np.abs(x[ok] - y[ok]) / np.maximum(np.abs(x[ok]), 1e-300)
            rel[name] = float(d.max())
    return same, la.size, rel


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--launches", type=int, default=4194304)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--headline", type=int, default=100, help="N of the N^3 map (0: skip)")
    ap.add_argument("--maps", default="paper,square-map,broad",
                    help="shipped specs to run on both backends (empty: none)")
    args = ap.parse_args(argv)
    try:
        cuda = cuda_module()
    except BackendError as exc:
        raise SystemExit(f"gpu_check: {exc}") from None
    import numba

    try:
        name = cuda.get_current_device().name
        name = name.decode() if isinstance(name, bytes) else name
    except AttributeError:  # numba's simulator
        name = "numba's CUDA simulator"
    print(f"GPU: {name}; numba {numba.__version__}, {numba.get_num_threads()} CPU threads")

    run_bench_cuda(n_launches=args.launches, n_steps=args.steps)

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for stem in filter(None, args.maps.split(",")):
            path = ROOT / "sweeps" / f"{stem}.toml"
            maps, walls = {}, {}
            for backend in ("cpu", "cuda"):
                spec = load_spec(path, run={"backend": backend})
                out = Path(tmp) / f"{stem}-{backend}.nc"
                spec = replace(spec, output=out)
                t0 = time.perf_counter()
                run_sweep(spec, command="gpu_check", progress=False, force=True)
                walls[backend] = time.perf_counter() - t0
                maps[backend] = xr.open_dataset(out)
            same, n, rel = compare(maps["cpu"], maps["cuda"])
            rows.append((stem, n, same, walls, rel))
            for m in maps.values():
                m.close()
    if rows:
        print("shipped maps on both backends (the cuda wall includes its first compile for the "
              "first map):")
        for stem, n, same, walls, rel in rows:
            figs = ", ".join(f"{k} {v:.1e}" for k, v in rel.items())
            print(f"  {stem}: {same}/{n} labels identical; cpu {walls['cpu']:.1f} s, "
                  f"cuda {walls['cuda']:.1f} s; largest relative difference: {figs}")
    if args.headline:
        run_headline(n=args.headline, method="rk4", backend="cuda")


if __name__ == "__main__":
    main()

"""Time writing a large map's netCDF file from its parts (the last step of a sweep), with
synthetic parts, for the box of sweeps/gpu-1e8.toml at N points an axis:

    python benchmarks/assemble.py N [--old]

--old: the storage chunks used before (at most 256 along each axis, straddling the write slabs).
N = 464 is the 1e8-launch map: about 0.9 GB of label and n_sides values (and that much memory).
"""
import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from ballsurvey import store
from ballsurvey.sweep import load_spec
from ballsurvey.sweep.plan import plan_chunks

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("n", type=int)
    ap.add_argument("--old", action="store_true")
    args = ap.parse_args(argv)
    path = ROOT / "sweeps" / "gpu-1e8.toml"
    spec = load_spec(path, text=path.read_text().replace("num = 464", f"num = {args.n}"))
    chunks = plan_chunks(spec.shape, spec.chunk)
    rng = np.random.default_rng(0)

    def get_part(k):
        m = chunks[k][1] - chunks[k][0]
        return {"label": rng.integers(0, 10, m).astype(np.int8),
                "n_sides": np.round(rng.uniform(2.0, 8.0, m), 3)}

    sizes = (tuple(min(s, 256) for s in spec.shape) if args.old
             else store.storage_chunks(chunks[0][2], spec.shape))
    store.storage_chunks = lambda *args, **kw: sizes
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        store.write_netcdf(Path(tmp) / "map.nc", spec, chunks, {}, get_part)
        wall = time.perf_counter() - t
    print(f"{spec.n_launches} launches ({args.n}^3) in {len(chunks)} parts, storage chunks "
          f"{sizes}: written in {wall:.1f} s")


if __name__ == "__main__":
    main()

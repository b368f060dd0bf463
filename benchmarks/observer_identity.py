"""The fixed-step kernel's observer record against another git revision's, bit for bit.

Each revision runs in a fresh process of its own (the revision's tree exported with `git archive`
into a temporary folder, first on the path), on the same launches: a spec's map through
`ensemble.integrate` in full-length mode (every observer slot of every launch, its outcome, stop
time and end state; blocks of 64, 37 and 150 launches), the same launches in period mode
(`stop_after`: the refill kernel) and with samples kept (`run_block` with `stop_after`), and the
spec's sweep end to end (the map file: fixed-frame fallback and labels included). Prints, per
case, whether the two revisions agree to the bit (NaN payloads and signed zeros included) and,
where they do not, the slots that differ:

    python benchmarks/observer_identity.py --against eca85b6 [--spec sweeps/square-map.toml]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

_CHILD = r'''
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from ballsurvey.compose import OBSERVER, launch_arrays
from ballsurvey.classify.observer import N_OBS
from ballsurvey.integrate import ensemble
from ballsurvey.sweep import load_spec, run_sweep
from ballsurvey.sweep.plan import launch_table
from ballsurvey.units import StepPlan

spec_path, out = sys.argv[1], Path(sys.argv[2])
spec = load_spec(spec_path)
y0, params, tu, _ = launch_arrays(launch_table(spec, 0, spec.n_launches))
plan = StepPlan(spec.T, spec.dt, tu)
kw = dict(observer=OBSERVER, n_slots=N_OBS, observe_every=spec.observe_every)
arrays = {}
cases = {
    "full": dict(),
    "full, block 37, serial": dict(block=37, parallel=False),
    "full, block 150": dict(block=150),
    "period (refill)": dict(stop_after=3),
    "period with samples kept": dict(stop_after=3, n_rec=5, stride=plan.n_steps // 4),
}
for name, extra in cases.items():
    r = ensemble.integrate(y0, params, plan.dt_nd, plan.n_steps, spec.method, **kw, **extra)
    for field in ("obs", "outcome", "t_stop", "y_end", "traj"):
        arrays[f"{name}/{field}"] = getattr(r, field)
np.savez(out / "arrays.npz", **arrays)
run_sweep(replace(spec, output=out / "map.nc"), command="identity", progress=False,
          notice=lambda line: None)
'''


def _run(src: Path, spec: str, out: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(src))
    subprocess.run([sys.executable, "-c", _CHILD, spec, str(out)], cwd=ROOT, env=env, check=True)


def _bits(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    return a.view(np.uint8) if a.dtype.itemsize == 1 else a.view(f"u{a.dtype.itemsize}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--against", required=True, help="git revision of the baseline")
    ap.add_argument("--spec", default="sweeps/square-map.toml")
    args = ap.parse_args()
    from ballsurvey.bench import _same_maps
    from ballsurvey.classify.observer import SLOTS

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        base = tmp / "tree"
        base.mkdir()
        archive = subprocess.run(["git", "archive", args.against], cwd=ROOT, check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(base)], input=archive, check=True)
        outs = {"baseline": tmp / "baseline", "today": tmp / "today"}
        for name, src in (("baseline", base / "src"), ("today", ROOT / "src")):
            outs[name].mkdir()
            _run(src, str(Path(args.spec).resolve()), outs[name])
        a = np.load(outs["baseline"] / "arrays.npz")
        b = np.load(outs["today"] / "arrays.npz")
        ok = True
        print(f"observer record, {args.spec}: {args.against} against the working tree")
        for key in a.files:
            same = a[key].shape == b[key].shape and np.array_equal(_bits(a[key]), _bits(b[key]))
            ok &= same
            line = f"  {key:40s} {'bit-identical' if same else 'DIFFERS'}"
            if not same and key.endswith("/obs") and a[key].shape == b[key].shape:
                slots = [SLOTS[k] for k in range(a[key].shape[0])
                         if not np.array_equal(_bits(a[key][k]), _bits(b[key][k]))]
                line += f" in slots {', '.join(slots)}"
            print(line)
        same = _same_maps(outs["baseline"] / "map.nc", outs["today"] / "map.nc")
        ok &= same
        print(f"  {'sweep map file (every data variable)':40s} "
              f"{'bit-identical' if same else 'DIFFERS'}")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()

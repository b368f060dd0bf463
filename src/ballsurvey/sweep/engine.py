"""Run a sweep: chunks of launches through the ensemble kernel, results to a CF netCDF file.

* The launch grid (C order) is cut into chunks that are each a rectangular hyperslab of the grid
  and a contiguous range of launches (`plan_chunks`), so every chunk is one write.
* Each finished chunk is saved at once, atomically, as a part file in `<output>.parts/`, so a crash
  or kill -9 loses only the chunks in flight; `resume=True` continues after checking the spec's
  digest, and a different spec is refused.
* When all chunks are done, the netCDF file is assembled from the parts one chunk at a time
  (memory bounded by the chunk size), written to a temporary name and renamed into place.
* `compute_chunk` is a pure function of (spec text, chunk range): the embedded run (numba threads)
  and a dask.distributed run (one serial, GIL-free kernel per worker thread) call the same code on
  the same chunks, and a launch's result never depends on its chunk, so both give identical files.
"""
from __future__ import annotations

import datetime as _dt
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from .. import __version__
from ..ball import flat_face_theta_of, nondim_params_of
from ..classify.labels import label_fields
from ..classify.observer import O_T_STOP
from ..integrate import ensemble
from ..integrate.driver import run_launches
from ..store import CONVENTIONS, FLOAT_FILL, REFERENCES, RESULT_VARIABLES, variable_attrs
from .spec import AXIS_LONG_NAMES, AXIS_UNITS, BALL_AXES, LAUNCH_AXES, Spec, SpecError, load_spec

PARTS_SUFFIX = ".parts"


class UpToDate(Exception):
    """The output exists and was made by the same spec: nothing to do."""

MANIFEST = "manifest.json"


# ---------------------------------------------------------------------------------------------
# chunks
def plan_chunks(shape: tuple, chunk: int) -> list[tuple[int, int, tuple]]:
    """Cut a C-ordered grid into chunks of at most `chunk` launches (fewer only where needed).

    Returns (lo, hi, slab): the flat launch range [lo, hi) and the matching hyperslab (ints and
    slices per axis). Axes after the split axis are whole; the split axis takes a run of indices.
    """
    shape = tuple(int(s) for s in shape)
    n = int(np.prod(shape))
    if n == 0:
        return []
    if chunk < 1:
        raise ValueError("chunk must be >= 1")
    d = 0  # first axis whose trailing block (the axes d, d+1, ...) fits in a chunk
    while int(np.prod(shape[d:])) > chunk:
        d += 1
    if d == 0:
        return [(0, n, tuple(slice(0, s) for s in shape))]
    inner = int(np.prod(shape[d:]))
    run = max(1, chunk // inner)
    out = []
    for outer in np.ndindex(*shape[:d - 1]):
        for j0 in range(0, shape[d - 1], run):
            j1 = min(shape[d - 1], j0 + run)
            lo = (int(np.ravel_multi_index(outer + (j0,), shape[:d])) if d - 1 else j0) * inner
            out.append((lo, lo + (j1 - j0) * inner,
                        tuple(outer) + (slice(j0, j1),) + tuple(slice(0, s) for s in shape[d:])))
    return out


def launch_table(spec: Spec, lo: int, hi: int) -> dict:
    """SI launch conditions and ball parameters for launches lo..hi-1 (1-D arrays)."""
    m = hi - lo
    b = spec.ball
    cols = {k: np.full(m, getattr(b, k), dtype=float) for k in ("a", "c", "M", "A", "B", "g",
                                                               "cut_height")}
    if spec.kind == "grid":
        idx = np.unravel_index(np.arange(lo, hi), spec.shape)
        for k, ix in zip(spec.axes, idx):
            cols[k] = spec.axes[k][ix]
        cols["chi0_deg"] = np.full(m, spec.chi0_deg)
    else:
        for k in LAUNCH_AXES + ("chi0_deg",):
            cols[k] = spec.points[k][lo:hi].astype(float)
    return cols


def _steps(spec: Spec) -> int:
    return max(1, math.ceil(spec.T / spec.dt - 1e-9))


def compute_chunk(spec_text: str, spec_source: str, lo: int, hi: int, parallel: bool = True) -> dict:
    """Integrate and label launches lo..hi-1 of a spec; returns {variable: 1-D array}."""
    spec = load_spec(spec_source, text=spec_text)
    t = launch_table(spec, lo, hi)
    a, M = t["a"], t["M"]
    tu = spec.ball.time_unit  # a and g are never sweep axes, so the time unit is common
    params = nondim_params_of(a, t["c"], M, t["A"], t["B"])
    flat = flat_face_theta_of(a, t["cut_height"])
    y0 = ensemble.fast_state(0.0, 0.0, np.radians(t["theta0_deg"]), np.radians(t["chi0_deg"]), 0.0,
                             t["thetadot0"] * tu, t["chidot0"] * tu, t["phidot0"] * tu)
    n_steps = _steps(spec)
    obs = run_launches(y0, params, spec.T / tu, spec.T / n_steps / tu, spec.method,
                       rtol=spec.rtol, atol=spec.atol, block=spec.block,
                       observe_every=spec.observe_every, parallel=parallel,
                       cycles=spec.cycles if spec.mode == "period" else 0)
    f = label_fields(obs, flat, a, tu, spec.thresholds)
    f["jellett_drift"] = f["jellett_drift"] * M * a**3 / tu
    f["routh_drift"] = f["routh_drift"] * M * a**2 / tu
    f["t_stop_s"] = obs[O_T_STOP] * tu
    return {k: np.asarray(f[k]) for k in spec.variables}


# ---------------------------------------------------------------------------------------------
# parts on disk
def parts_dir(output: Path) -> Path:
    return output.with_name(output.name + PARTS_SUFFIX)


def _part_path(parts: Path, k: int) -> Path:
    return parts / f"chunk-{k:06d}.npz"


def _write_part(parts: Path, k: int, result: dict) -> None:
    tmp = parts / f".chunk-{k:06d}.{os.getpid()}.tmp.npz"
    np.savez(tmp, **result)
    os.replace(tmp, _part_path(parts, k))


def _git_commit() -> str | None:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=Path(__file__).parent,
                             capture_output=True, text=True, timeout=5)
        return out.stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        return None


def _existing_digest(path: Path) -> str | None:
    import netCDF4

    try:
        with netCDF4.Dataset(path) as nc:
            return getattr(nc, "spec_digest", None)
    except OSError:
        return None


def output_is_current(spec: Spec) -> bool:
    """True when the spec's output file exists and was made by this same spec."""
    return spec.output.exists() and _existing_digest(spec.output) == spec.digest


def prepare_output(spec: Spec, *, resume: bool, force: bool) -> tuple[Path, set]:
    """Check what is on disk; returns (parts dir, chunks already done). Refuses to mix specs."""
    out = spec.output
    parts = parts_dir(out)
    if out.exists() and not force:
        if output_is_current(spec):
            raise UpToDate(f"{out} is up to date (made by this spec); --force recomputes it")
        raise FileExistsError(f"{out} exists, made by another spec; use --force to overwrite it")
    if parts.exists():
        if force:
            shutil.rmtree(parts)
        elif not resume:
            raise FileExistsError(f"an interrupted sweep is in {parts}; use --resume to continue "
                                  "it or --force to start over")
        else:
            try:
                man = json.loads((parts / MANIFEST).read_text())
            except (OSError, ValueError):
                raise FileExistsError(f"{parts} has no readable manifest; use --force") from None
            if man.get("spec_digest") != spec.digest:
                raise FileExistsError(f"{parts} belongs to a different spec; refusing to mix "
                                      "results (use --force to discard it)")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        parts.mkdir(exist_ok=True)
        probe = parts / ".write-test"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        raise PermissionError(f"cannot write the output {out}: {exc.strerror}") from None
    man_path = parts / MANIFEST
    if not man_path.exists():
        man_path.write_text(json.dumps({"spec_digest": spec.digest, "version": __version__,
                                        "spec": spec.text}))
    done = {int(p.stem.split("-")[1]) for p in parts.glob("chunk-*.npz")}
    return parts, done


# ---------------------------------------------------------------------------------------------
# assembling the netCDF file
def _global_attrs(spec: Spec, command: str, dt_used: float) -> dict:
    commit = _git_commit()
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    attrs = {
        "Conventions": CONVENTIONS,
        "title": spec.title,
        "institution": "ballsurvey users",
        "source": f"ballsurvey {__version__}" + (f" (git {commit})" if commit else ""),
        "history": f"{now}: {command}",
        "references": REFERENCES,
        "comment": "Paths of a biased ball rolling without slipping; labels from the streaming "
                   "classifier (see flag_meanings of label).",
        "spec_toml": spec.text,
        "spec_digest": spec.digest,
        "run_T_s": spec.T, "run_dt_s_requested": spec.dt, "run_dt_s": dt_used,
        "run_method": spec.method, "run_observe_every": spec.observe_every,
        "run_rtol": spec.rtol, "run_atol": spec.atol, "run_mode": spec.mode,
        "run_cycles": spec.cycles,
    }
    for k, v in spec.ball.as_dict().items():
        unit = {"a": "m", "c": "m", "M": "kg", "A": "kg m2", "B": "kg m2", "g": "m s-2",
                "cut_height": "m"}[k]
        attrs[f"ball_{k}"] = v
        attrs[f"ball_{k}_units"] = unit
    for k, v in spec.thresholds.as_dict().items():
        attrs[f"classify_{k}"] = v
    return attrs


def assemble(spec: Spec, parts: Path, chunks: list, command: str) -> Path:
    """Write the netCDF file from the part files, one chunk in memory at a time."""
    import netCDF4

    out = spec.output
    tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp")
    dims = spec.dims
    n_steps = _steps(spec)
    with netCDF4.Dataset(tmp, "w", format="NETCDF4") as nc:
        nc.setncatts(_global_attrs(spec, command, spec.T / n_steps))
        if spec.kind == "grid":
            for k, vals in spec.axes.items():
                nc.createDimension(k, len(vals))
                v = nc.createVariable(k, "f8", (k,))
                v[:] = vals
                v.units = AXIS_UNITS[k]
                v.long_name = AXIS_LONG_NAMES[k]
            v = nc.createVariable("chi0_deg", "f8", ())
            v[...] = spec.chi0_deg
            v.units, v.long_name = "degree", AXIS_LONG_NAMES["chi0_deg"]
            coords = "chi0_deg"
        else:
            n = spec.n_launches
            nc.createDimension("launch", n)
            v = nc.createVariable("launch", "i4", ("launch",))
            v[:] = np.arange(n)
            v.long_name = "launch index"
            v = nc.createVariable("name", str, ("launch",))
            for i, s in enumerate(spec.points["name"]):
                v[i] = str(s)
            v.long_name = "launch name"
            v.cf_role = "timeseries_id"
            for k in LAUNCH_AXES + ("chi0_deg",):
                v = nc.createVariable(k, "f8", ("launch",))
                v[:] = spec.points[k]
                v.units, v.long_name = AXIS_UNITS[k], AXIS_LONG_NAMES[k]
            coords = "name " + " ".join(LAUNCH_AXES) + " chi0_deg"
        shape = spec.shape
        chunksizes = tuple(min(s, 256) for s in shape)
        vars_ = {}
        for name in spec.variables:
            dtype = RESULT_VARIABLES[name][0]
            v = nc.createVariable(name, dtype, dims, zlib=spec.compression > 0,
                                  complevel=max(spec.compression, 1), chunksizes=chunksizes,
                                  fill_value=FLOAT_FILL if dtype == "f8" else False)
            attrs = variable_attrs(name)
            attrs["coordinates"] = coords
            v.setncatts(attrs)
            vars_[name] = v
        for k, (lo, hi, slab) in enumerate(chunks):
            with np.load(_part_path(parts, k)) as part:
                sub = tuple(s.stop - s.start for s in slab if isinstance(s, slice))
                for name in spec.variables:
                    vars_[name][slab] = part[name].reshape(sub)
    os.replace(tmp, out)
    return out


# ---------------------------------------------------------------------------------------------
# running
def _warm_worker():
    """On a dask worker: one numba thread (workers are single-threaded), kernels compiled once."""
    import numba

    numba.set_num_threads(1)
    y = ensemble.fast_state(0, 0, 0.1, 0, 0, 0, 1.0, -1.0)
    ensemble.integrate(y, np.array([[0.1], [0.4], [0.4]]), 1e-3, 2, parallel=False)
    return True


def run_sweep(spec: Spec, *, resume: bool = False, force: bool = False, client=None,
              progress: bool | None = None, command: str = "", on_chunk=None) -> Path:
    """Run (or continue) a sweep and write its netCDF file. `client`: a dask.distributed Client."""
    from tqdm import tqdm

    parts, done = prepare_output(spec, resume=resume, force=force)
    chunks = plan_chunks(spec.shape, spec.chunk)
    todo = [k for k in range(len(chunks)) if k not in done]
    n_done = sum(chunks[k][1] - chunks[k][0] for k in done)
    if progress is None:
        progress = sys.stderr.isatty()
    bar = tqdm(total=spec.n_launches, initial=n_done, unit="launch", disable=not progress,
               desc=spec.title[:40], smoothing=0.1, file=sys.stderr)

    def finished(k, result):
        _write_part(parts, k, result)
        bar.update(chunks[k][1] - chunks[k][0])
        if on_chunk is not None:
            on_chunk(k)

    try:
        if client is None:
            for k in todo:
                lo, hi, _ = chunks[k]
                finished(k, compute_chunk(spec.text, spec.source, lo, hi, parallel=True))
        else:
            from distributed import as_completed

            client.run(_warm_worker)
            futs = {client.submit(compute_chunk, spec.text, spec.source, chunks[k][0],
                                  chunks[k][1], False, pure=False): k for k in todo}
            for fut in as_completed(futs):
                finished(futs[fut], fut.result())
    finally:
        bar.close()
    out = assemble(spec, parts, chunks, command)
    shutil.rmtree(parts)
    return out

"""The Python way in: run a sweep from a path, TOML text or a dict and get an `xarray.Dataset`;
open a stored map; pick launches by label word; query a map into a `pandas.DataFrame`.

    import ballsurvey
    ds = ballsurvey.sweep({"launch": {"theta0_deg": {"start": -10, "stop": 30, "num": 9},
                                      "thetadot0": 0, "phidot0": -3,
                                      "chidot0": {"start": 1, "stop": 12, "num": 12}},
                           "run": {"T": 6, "dt": 2e-4}})
    ds.ballsurvey.where(shape="square")        # the map with every other launch masked
    ballsurvey.query(ds, shape="square")       # a DataFrame, most exact first

Every input problem raises `ballsurvey.InputError` (a ValueError) with a one-line message.
"""
from __future__ import annotations

import json
import math
import os
import tempfile
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import xarray as xr

from . import limits
from .axes import LAUNCH_AXES
from .classify.labels import CODE, LABELS
from .limits import InputError
from .store import decode_label, netcdf_lock

#: a map written by `sweep` with no output file named is kept in memory up to this many launches
MAX_IN_MEMORY = 10**6


# ---------------------------------------------------------------------------------------------
# specs from Python
def _toml_value(v, where: str) -> str:
    if isinstance(v, np.ndarray):
        v = v.tolist()
    elif isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("nan" if v != v else ("inf" if v > 0 else "-inf"))
    if isinstance(v, (str, Path)):
        return json.dumps(str(v))
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x, where) for x in v) + "]"
    if isinstance(v, dict):
        items = (f"{k} = {_toml_value(x, f'{where}.{k}')}" for k, x in v.items())
        return "{" + ", ".join(items) + "}"
    raise InputError(f"spec {where}: cannot be written as TOML ({type(v).__name__})")


def spec_to_toml(spec: dict) -> str:
    """A spec given as a dict (the layout of docs/specs.md) as TOML text."""
    if not isinstance(spec, dict):
        raise InputError(f"a spec is a path, TOML text or a dict, got {type(spec).__name__}")
    lines = []
    for k, v in spec.items():
        if not isinstance(v, dict) and k != "points":
            lines.append(f"{k} = {_toml_value(v, k)}")
    for k, v in spec.items():
        if isinstance(v, dict):
            lines.append(f"\n[{k}]")
            lines += [f"{kk} = {_toml_value(vv, f'[{k}] {kk}')}" for kk, vv in v.items()]
        elif k == "points":
            if not isinstance(v, (list, tuple)) or not all(isinstance(p, dict) for p in v):
                raise InputError("spec points: must be a list of dicts")
            for p in v:
                lines.append("\n[[points]]")
                lines += [f"{kk} = {_toml_value(vv, f'[[points]] {kk}')}" for kk, vv in p.items()]
    return "\n".join(lines) + "\n"


def _spec_text(spec) -> tuple[str, str, bool]:
    """(TOML text, source name, names an output file) of a path, TOML text or dict."""
    if isinstance(spec, dict):
        text, source = spec_to_toml(spec), "spec (dict)"
    elif isinstance(spec, Path) or (isinstance(spec, str) and "\n" not in spec and "=" not in spec):
        p = Path(spec)
        try:
            text = p.read_text()
        except OSError as exc:
            raise InputError(f"{spec}: cannot read: {exc.strerror}") from None
        except UnicodeDecodeError:
            raise InputError(f"{spec}: not a text file (a sweep spec is TOML text)") from None
        return text, str(p), True  # a spec file: its output defaults to results/<name>.nc
    elif isinstance(spec, str):
        text, source = spec, "spec (TOML text)"
    else:
        raise InputError(f"a spec is a path, TOML text or a dict, got {type(spec).__name__}")
    try:
        names_file = "file" in tomllib.loads(text).get("output", {})
    except (ValueError, AttributeError):  # TOMLDecodeError is a ValueError
        names_file = True  # load_spec says what is wrong
    return text, source, names_file


def sweep(spec, *, output=None, resume: bool = False, force: bool = False,
          progress: bool | None = None, workers: int | None = None, scheduler: str | None = None,
          notice=None) -> xr.Dataset:
    """Integrate and classify every launch of a spec; return the map as an `xarray.Dataset`.

    Parameters
    ----------
    spec : str, path or dict
        A path to a TOML file, TOML text, or a dict laid out like the TOML (the docs' 'Sweep
        specs' page).
    output : str or path, optional
        Where to write the map; default: the spec's `[output] file` (a spec file without one:
        `results/<name>.nc`). A relative path is relative to the current folder. TOML text or a
        dict naming no file is computed in a private temporary folder and returned in memory
        (at most 1e6 launches).
    resume : bool
        Continue an interrupted sweep of this spec from its saved parts (`sweep --resume`).
    force : bool
        Overwrite an existing result or discard saved parts (`sweep --force`); without it,
        rerunning a finished spec just opens its file.
    progress : bool, optional
        A progress bar on stderr (default: when stderr is a terminal).
    workers : int, optional
        Start a local dask cluster of that many worker processes.
    scheduler : str, optional
        The address of a running dask.distributed scheduler.
    notice : callable, optional
        Receives the run's one-line messages (compiling, parts computed again); default: print.

    Returns
    -------
    xarray.Dataset
        The map, loaded into memory when small.

    Raises
    ------
    InputError
        A problem with the spec (one line naming the key), before any work.
    SweepInterrupted
        Ctrl-C; the finished work is kept for `resume=True`.
    """
    from .sweep import load_spec
    from .sweep.engine import UpToDate, check_output_path, dask_client, run_sweep
    from .sweep.parts import existing_output, tidy_finished

    if workers is not None:
        limits.workers(workers, "workers")
    if scheduler is not None:
        limits.scheduler(scheduler, "scheduler")
    text, source, names_file = _spec_text(spec)
    s = load_spec(source, text=text)
    if output is not None:
        s = replace(s, output=Path(output))
    in_memory = output is None and not names_file
    if in_memory and s.n_launches > MAX_IN_MEMORY:
        raise InputError(f"{s.n_launches} launches are too many to keep in memory only (at most "
                         f"{MAX_IN_MEMORY:.0e}): name a file with output=... or [output] file")
    notice = notice or (lambda msg: print(f"ballsurvey: {msg}", flush=True))
    with tempfile.TemporaryDirectory(prefix="ballsurvey-") if in_memory else _nothing() as tmp:
        if in_memory:
            s = replace(s, output=Path(tmp) / "map.nc")
        check_output_path(s.output)
        try:
            existing_output(s, force=force)
            current = False
        except UpToDate:
            tidy_finished(s, notice)
            current = True
        if not current:
            with dask_client(scheduler, workers) as client:
                try:
                    run_sweep(s, resume=resume, force=force, client=client, progress=progress,
                              command=f"ballsurvey.sweep({source!r})", notice=notice)
                except UpToDate:
                    pass
        ds = open_map(s.output, load=True if in_memory else None)
    if in_memory:
        ds.encoding.pop("source", None)
    return ds


class _nothing:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


def open_map(path, load: bool | None = None) -> xr.Dataset:
    """Open a ballsurvey map (a netCDF file written by `sweep`).

    Parameters
    ----------
    path : str or path
        The .nc file.
    load : bool, optional
        Read it into memory and close the file (default: when it is under 256 MB); otherwise
        open it lazily (with dask when installed).

    Returns
    -------
    xarray.Dataset

    Raises
    ------
    InputError
        Anything that is not a map (a spec, a folder, another file), or a map whose attributes
        or coordinates a spec could not hold (`sweep.spec.check_map`), with one line.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"open_map: a path to a .nc file, got {type(path).__name__}")
    p = Path(path)
    if p.suffix == ".toml":
        raise InputError(f"{path} is a sweep spec, not a map: run `ballsurvey sweep {path}` and "
                         "use the .nc file it writes")
    if not p.exists():
        raise InputError(f"no such file: {path}")
    if p.is_dir():
        raise InputError(f"{path} is a folder, not a map (.nc file)")
    try:
        with open(p, "rb") as f:
            magic = f.read(4)
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror}") from None
    if magic not in (b"\x89HDF", b"CDF\x01", b"CDF\x02"):
        raise InputError(f"{path} is not a netCDF file (a ballsurvey map is written by `sweep`)")
    with netcdf_lock():  # one thread in netCDF/HDF5 at a time (a sweep may be writing)
        try:
            ds = xr.open_dataset(p)
        except Exception as exc:  # noqa: BLE001 - xarray's backends raise many kinds; one line
            raise InputError(f"cannot read {path} as netCDF ({type(exc).__name__})") from None
        if "label" not in ds:
            ds.close()
            raise InputError(f"{path} has no 'label' variable: not a ballsurvey map")
        words = str(ds.label.attrs.get("flag_meanings", "")).split()
        if (not np.issubdtype(ds.label.dtype, np.integer) or not words
                or not set(words) <= set(LABELS)):
            ds.close()
            raise InputError(f"{path}: its 'label' variable is not ballsurvey's label codes "
                             "(integers with flag_meanings naming label words): not a map")
        missing = [k for k in LAUNCH_AXES if k not in ds.variables]
        if missing:
            ds.close()
            raise InputError(f"{path} lacks the launch conditions {', '.join(missing)}: not a "
                             "ballsurvey map")
        from .sweep.spec import check_map

        try:  # a spec's rules: a crafted or damaged map is refused before any work
            check_map(ds, str(path))
        except InputError:
            ds.close()
            raise
        if load is None:
            load = p.stat().st_size < 256 * 2**20
        if load:
            with ds:
                ds = ds.load()
    return ds


# ---------------------------------------------------------------------------------------------
# label words on a plain Dataset
def label_mask(ds: xr.Dataset, shape=None, n_sides: int | None = None) -> xr.DataArray:
    """True where a launch's label is `shape` (a word or a list of words), or where its path closes
    as a polygon with `n_sides` sides (triangle, square or ngon with round(n_sides) == N)."""
    if "label" not in ds:
        raise InputError("the dataset has no 'label' variable (not a ballsurvey map?)")
    mask = xr.ones_like(ds.label, dtype=bool)
    if shape is not None:
        words = [shape] if isinstance(shape, str) else list(shape)
        bad = [w for w in words if w not in CODE]
        if bad:
            raise InputError(f"unknown shape {bad[0]!r}; words: {', '.join(LABELS)}")
        mask = mask & ds.label.isin([CODE[w] for w in words])
    if n_sides is not None:
        n = limits.number("n_sides", n_sides, integer=True, lo=3)
        if "n_sides" not in ds:
            raise InputError("n_sides: this map does not hold 'n_sides' (a spec whose [output] "
                             "variables leave it out, or a refine map): ask by shape")
        poly = ds.label.isin([CODE["triangle"], CODE["square"], CODE["ngon"]])
        mask = mask & poly & (np.round(ds.n_sides) == n)
    return mask


@xr.register_dataset_accessor("ballsurvey")
class BallsurveyAccessor:
    """`ds.ballsurvey`: a map's labels as words, on any map (importing `ballsurvey` registers it).

    Examples
    --------
    >>> ds = ballsurvey.open_map("results/quick.nc")
    >>> ds.ballsurvey.labels                     # a property: words on the map's dimensions
    >>> ds.ballsurvey.counts()                   # launches per label word
    >>> ds.ballsurvey.where(shape="square", phidot0=-3)
    >>> ds.ballsurvey.to_dataframe()             # labels as a pandas categorical
    """

    def __init__(self, ds: xr.Dataset):
        self._ds = ds

    @property
    def labels(self) -> xr.DataArray:
        """The label words (an object array) on the map's dimensions, named `label_word`; '' where
        a cell was never written. A property: `ds.ballsurvey.labels`, no parentheses."""
        lab = self._ds.label
        return xr.DataArray(decode_label(lab.values), dims=lab.dims, coords=lab.coords,
                            name="label_word")

    def mask(self, shape=None, n_sides=None) -> xr.DataArray:
        """True where the label is `shape` (a word or a list of words), or where the path closes
        as a polygon with `n_sides` sides (a boolean DataArray on the map's dimensions)."""
        return label_mask(self._ds, shape, n_sides)

    def where(self, shape=None, n_sides=None, **at) -> xr.Dataset:
        """The map with every other launch masked (NaN, label -1); axis keywords (`phidot0=-3`)
        first select one value of an axis, as `ballsurvey.select` does."""
        ds = select(self._ds, **at) if at else self._ds
        m = label_mask(ds, shape, n_sides)
        out = ds.where(m)
        out["label"] = ds.label.where(m, -1).astype(ds.label.dtype)
        out["label"].attrs = ds.label.attrs
        return out

    def counts(self):
        """Launches per label word present in the map (a pandas Series named `launches`)."""
        import pandas as pd

        codes = self._ds.label.values.ravel()
        codes = codes[(codes >= 0) & (codes < len(LABELS))].astype(int)
        c = np.bincount(codes, minlength=len(LABELS))
        return pd.Series({w: int(c[i]) for i, w in enumerate(LABELS) if c[i]}, name="launches")

    def query(self, **kw):
        """The same DataFrame as `ballsurvey.query(ds, **kw)`."""
        return query(self._ds, **kw)

    def to_dataframe(self):
        """The map as a pandas DataFrame, one row per launch, with every coded variable (`label`,
        `corner_kind`, `formulation`: CF `flag_values` and `flag_meanings`) decoded to a pandas
        categorical of its words (all the vocabulary's words as categories, in code order; a
        cell never written is missing). `ds.to_dataframe()` gives the int8 codes instead."""
        return decoded_frame(self._ds)


def decoded_frame(ds: xr.Dataset):
    """`ds.to_dataframe()` with each variable that has CF `flag_values`/`flag_meanings` as a
    pandas Categorical of its words (see `BallsurveyAccessor.to_dataframe`)."""
    import pandas as pd

    df = ds.to_dataframe()
    for name, var in ds.data_vars.items():
        values, meanings = var.attrs.get("flag_values"), var.attrs.get("flag_meanings")
        if name not in df or values is None or not meanings:
            continue
        words = str(meanings).split()
        codes = np.asarray(values).astype(int).tolist()
        word_of = dict(zip(codes, words))
        df[name] = pd.Categorical(df[name].map(word_of), categories=words)
    return df


def select(ds: xr.Dataset, **at) -> xr.Dataset:
    """One value of each named axis, e.g. ``select(ds, phidot0=-3)``.

    A value within half a grid step of one of the axis's values takes that value; another raises
    InputError naming the nearest values.
    """
    for k, v in at.items():
        if k not in ds.dims:
            raise InputError(f"{k}: not an axis of this map; axes: {', '.join(ds.dims)}")
        vals = np.asarray(ds[k].values, dtype=float)
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise InputError(f"{k}: {v!r} is not a number") from None
        i = int(np.argmin(np.abs(vals - v)))
        step = np.min(np.diff(np.sort(vals))) if vals.size > 1 else 0.0
        tol = 0.5 * step if vals.size > 1 else 1e-9 * max(1.0, abs(vals[0]))
        if not abs(vals[i] - v) <= tol * (1 + 1e-9):
            if vals.size == 1:
                raise InputError(f"{k} = {v!r} is not the map's one value of {k}, "
                                 f"{float(vals[0])!r}")
            near = sorted(vals[np.argsort(np.abs(vals - v))[:2]])
            raise InputError(f"{k} = {v:g} is not on the map's grid ({vals.min():g} .. "
                             f"{vals.max():g}); nearest values: "
                             f"{', '.join(f'{x:g}' for x in near)}")
        ds = ds.isel({k: i})
    return ds


def query(ds: xr.Dataset, shape=None, n_sides: int | None = None, *, limit: int | None = None,
          max_n_error: float | None = None, max_closure: float | None = None, **at):
    """The launches of a map with a shape, most exact first, as a `pandas.DataFrame`.

    Parameters
    ----------
    ds : xarray.Dataset
        A map.
    shape : str or list of str, optional
        A label word (or words): square, triangle, star, ..., or a status.
    n_sides : int, optional
        Polygons that close with this many sides (triangle, square or ngon with round(n_sides)
        == N), instead of `shape`.
    limit : int, optional
        At most this many rows (default: all).
    max_n_error : float, optional
        Only launches with |n_sides - nearest whole n| <= this.
    max_closure : float, optional
        Only launches whose corner drifts at most this far per circuit (m).
    **at
        Axis keywords (e.g. ``phidot0=-3``) keep one value of an axis (within half a grid step).

    Returns
    -------
    pandas.DataFrame
        One row per launch: the launch conditions (axis names, in the map's units: deg where the
        name says `_deg`, rad/s, SI for ball axes), label, n_sides, n_sides_error, closure_m,
        theta_max_deg, near_vertical (theta max above 89 deg). `df.attrs['units']` gives each
        column's units, `df.attrs['matched']` how many matched before `limit`.
    """
    from .query import query as query_rows

    if at:
        ds = select(ds, **at)
    return query_rows(ds, shape, n_sides, limit, max_n_error, max_closure)

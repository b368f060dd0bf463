"""A stored map: its writer (`write_netcdf`, called by the sweep engine), the variables' CF
attributes, the netCDF lock, and the readers' helpers (`launches`, `decode_label`); plot and
query read through it. What each variable means (names, dtypes, units, flag values and meanings)
is the table in `schema`.
Files follow CF-1.10 (checked in the tests with the IOOS compliance-checker).
"""
from __future__ import annotations

import math
import sys
import threading
from contextlib import contextmanager, nullcontext

import numpy as np

from .axes import LAUNCH_AXES
from .classify.labels import LABELS
from .schema import AXIS_LONG_NAMES, AXIS_UNITS, RESULT_VARIABLES

CONVENTIONS = "CF-1.10"
REFERENCES = ("M. S. Wheatland, R. C. Cross et al., Rolling along a square path: the dynamics of "
              "biased balls, Am. J. Phys. 88, 465 (2020), doi:10.1119/10.0000905")

#: fill of float variables (cells never written); integer variables need none: the file is only
#: assembled once every chunk is done
FLOAT_FILL = np.nan


#: the one lock around every netCDF4/HDF5 call the package makes (HDF5 as built for netCDF4 is not
#: thread-safe: two threads in it at once crash the process). Reentrant in its thread.
NETCDF_LOCK = threading.RLock()
_held = threading.local()


@contextmanager
def netcdf_lock(direct: bool = False):
    """Hold the package's netCDF lock (`NETCDF_LOCK`) for a block of netCDF4/HDF5 calls.

    direct: the block calls netCDF4 itself (not through xarray); xarray's own HDF5 and netCDF-C
    locks are then held too, so the block is also serialised with reads of a map that xarray
    opened lazily, which take only those. Through xarray (direct=False) they are not taken here:
    xarray takes them itself, and they do not nest. Where xarray is not imported (the command
    line's sweep: the package imports it for library use), nothing can read through it, and
    importing it only for its locks would cost a quarter of a fresh process's start."""
    with NETCDF_LOCK:
        depth = getattr(_held, "depth", 0)
        if not direct or depth:
            _held.depth = depth + bool(depth)
            try:
                yield
            finally:
                _held.depth = depth
            return
        locks = sys.modules.get("xarray.backends.locks")
        with (locks.NETCDFC_LOCK if locks else nullcontext()), \
                (locks.HDF5_LOCK if locks else nullcontext()):
            _held.depth = 1
            try:
                yield
            finally:
                _held.depth = 0


def variable_attrs(name: str) -> dict:
    dtype, units, long_name, extra = RESULT_VARIABLES[name]
    attrs = {"long_name": long_name}
    if units is not None:
        attrs["units"] = units
    attrs.update(extra)
    return attrs


def launches(ds):
    """A map as one launch axis `_launch`: a grid stacked, points renamed, a lone launch expanded
    (the order is the map's own, C order for grids)."""
    if ds.label.ndim == 0:
        return ds.expand_dims("_launch")
    if ds.label.ndim > 1 or "launch" not in ds.dims:
        return ds.stack(_launch=list(ds.label.dims))
    return ds.rename({"launch": "_launch"})


def decode_label(codes, words=LABELS) -> np.ndarray:
    """int8 label codes -> label words ('' for unwritten cells and codes outside `words`; the
    corner kinds: words=CORNER_KINDS)."""
    codes = np.asarray(codes)
    table = np.array(tuple(words) + ("",), dtype=object)
    return table[np.where((codes >= 0) & (codes < len(words)), codes, len(words))]


#: most values in one netCDF storage chunk (8 MB of float64)
STORAGE_CHUNK_VALUES = 1 << 20


def storage_chunks(slab, shape, target: int = STORAGE_CHUNK_VALUES) -> tuple:
    """The netCDF storage-chunk shape for a map of `shape` written slab by slab
    (`sweep.plan_chunks`; `slab` its first): at most `target` values, and each storage chunk
    inside one slab, so it is compressed and written once.

    A slab is single indices on the outer axes, a run of indices on its split axis (every slab's
    run starts at a multiple of the first's) and whole inner axes. Storage chunks that straddled
    slabs were read back, decompressed and compressed again at every write that touched them:
    a 1e8-launch map, whose 134 MB chunks each spanned 4 slabs, spent minutes there. Along the
    split axis the size is a divisor of the run; where the run has no divisor near the even
    split (a prime run, say), the even split is taken, and a storage chunk then meets at most
    two slabs rather than shrinking to a sliver."""
    sizes = [1 if isinstance(s, (int, np.integer)) else s.stop - s.start for s in slab]
    split = next((i for i, s in enumerate(slab) if not isinstance(s, (int, np.integer))), 0)
    run = sizes[split]
    whole = list(range(split + 1, len(sizes)))  # axes whole in every slab: any size tiles them
    if run >= int(shape[split]):  # one slab along the split axis too
        whole.insert(0, split)
    else:
        pieces = -(-math.prod(sizes) // target)
        if pieces > 1:
            even = -(-run // pieces)
            div = next(d for d in range(even, 0, -1) if run % d == 0)
            sizes[split] = div if 2 * div >= even else even
    for i in whole:
        while math.prod(sizes) > target and sizes[i] > 1:
            sizes[i] = -(-sizes[i] // 2)
    return tuple(sizes)


class MapWriter:
    """A sweep's map file (netCDF4, CF) open for writing: the dimensions, coordinates and
    variables at once, then each chunk's slab by `put` (in any order: the storage chunks lie
    within slabs, so no write reads another back), then `close`. Every call holds the netCDF
    lock; the file may be filled from another thread than the one that opened it (the sweep's
    part writer fills it as parts are saved), one thread at a time.

    spec: a `sweep.Spec`; chunks: its plan [(lo, hi, slab)]; attrs: the global attributes."""

    def __init__(self, path, spec, chunks: list, attrs: dict):
        import netCDF4

        self.chunks, self.variables, self.written = chunks, tuple(spec.variables), set()
        with netcdf_lock(direct=True):
            self.nc = nc = netCDF4.Dataset(path, "w", format="NETCDF4")
            try:
                self.vars = self._define(nc, spec, chunks, attrs)
            except BaseException:
                nc.close()
                raise

    @staticmethod
    def _define(nc, spec, chunks, attrs) -> dict:
        dims = spec.dims
        nc.setncatts(attrs)
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
        chunksizes = storage_chunks(chunks[0][2], spec.shape) if chunks else None
        vars_ = {}
        for name in spec.variables:
            dtype = RESULT_VARIABLES[name][0]
            # byte shuffle before zlib: a float's bytes grouped by significance compress
            # faster and smaller (n_sides of the headline map: 0.31 s and 6.4 MB against
            # 0.39 s and 7.1 MB at level 4)
            v = nc.createVariable(name, dtype, dims, zlib=spec.compression > 0,
                                  complevel=max(spec.compression, 1), chunksizes=chunksizes,
                                  shuffle=spec.compression > 0 and dtype == "f8",
                                  fill_value=FLOAT_FILL if dtype == "f8" else False)
            if chunksizes:
                # a chunk cache of two storage chunks, whole ones evicted first: each slab is
                # compressed and written as it is put, not all at the close (the default cache
                # of 64 MB held the headline map's whole file until then); a storage chunk that
                # meets two slabs stays until its second part comes
                v.set_var_chunk_cache(size=2 * math.prod(chunksizes) * np.dtype(dtype).itemsize,
                                      nelems=11, preemption=1.0)
            attrs_v = variable_attrs(name)
            attrs_v["coordinates"] = coords
            v.setncatts(attrs_v)
            vars_[name] = v
        return vars_

    def put(self, k: int, part: dict) -> None:
        """Chunk k's slab from part ({variable: 1-D array of its launches})."""
        slab = self.chunks[k][2]
        sub = tuple(s.stop - s.start for s in slab if isinstance(s, slice))
        with netcdf_lock(direct=True):
            for name in self.variables:
                self.vars[name][slab] = np.asarray(part[name]).reshape(sub)
        self.written.add(k)

    def close(self) -> None:
        """Close the file (written to disk); again: nothing."""
        if self.nc is not None:
            nc, self.nc = self.nc, None
            with netcdf_lock(direct=True):
                nc.close()


def write_netcdf(path, spec, chunks: list, attrs: dict, get_part, writer=None) -> None:
    """Write a sweep's map to `path` (netCDF4, CF) one chunk in memory at a time.

    spec: a `sweep.Spec`; chunks: its plan [(lo, hi, slab)]; attrs: the global attributes;
    get_part(k): {variable: 1-D array} of chunk k. writer: a `MapWriter` of that file already
    holding some chunks (they are not asked for again); it is closed here."""
    writer = writer or MapWriter(path, spec, chunks, attrs)
    try:
        for k in range(len(chunks)):
            if k not in writer.written:
                writer.put(k, get_part(k))
    finally:
        writer.close()

"""Query a stored map: which launches give a shape, best (most exact) first, as a pandas
DataFrame (`query_frame`); `format_table` makes the command line's table, csv and json from it."""
from __future__ import annotations

import io
import json
import math

import numpy as np
import xarray as xr

from . import limits
from .axes import AXES
from .classify.labels import CODE, LABELS
from .limits import InputError
from .store import decode_label, launches

CONDITION_UNITS = {k: ax.text_units for k, ax in AXES.items()}


#: theta max above it: the path passes within a degree of the vertical, where the Euler form is
#: singular and the result is numerically delicate (computed in the fixed frame where needed)
NEAR_VERTICAL_DEG = 89.0
DEFAULT_LIMIT = 20
#: `query` reads a map in slabs of about this many launches along its first axis, so a map
#: opened lazily (larger than `open_map` loads) is never read whole
SLAB_LAUNCHES = 1 << 22


def _best_first(n_error, closure) -> np.ndarray:
    """The order best first: by |n_sides - N|, then by closure (unknown last); a stable sort, so
    ties keep their order."""
    return np.lexsort((np.nan_to_num(closure, nan=np.inf), np.nan_to_num(n_error, nan=np.inf)))


def _needs(ds, name: str, asked: bool, what: str) -> None:
    """A question that needs a variable the map does not hold is refused (it matched nothing)."""
    if asked and name not in ds:
        raise InputError(f"{what}: this map does not hold {name!r} (a spec whose [output] "
                         "variables leave it out, or a refine map): ask by --shape")


def query_frame(ds: xr.Dataset, shape: str | None = None, n_sides: int | None = None,
                max_n_error: float | None = None, max_closure: float | None = None):
    """Launches whose label is `shape` (any label word), or whose path closes as an n-gon with
    `n_sides` sides (label triangle/square/ngon and round(n_sides) == N), best first, as a
    `pandas.DataFrame`.

    Best first: for polygons and stars, by |n_sides - N| (N the nearest whole n, or the asked one)
    then closure_m; for other words, by launch order. max_n_error keeps rows with
    |n_sides - N| <= E, max_closure those whose corner drifts at most that far (m) per circuit.
    Columns: the launch conditions (plain names; units in `df.attrs['units']`), label (and for
    stars `star`, their {p/q}), n_sides,
    n_sides_error (|n_sides - N|), closure_m, theta_max_deg and near_vertical (theta max above
    89 deg: numerically delicate). `df.attrs['matched']` is the number of rows.
    """
    import pandas as pd

    for name, v in (("max_n_error", max_n_error), ("max_closure", max_closure)):
        if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
            raise InputError(f"{name} must be a finite number >= 0, got {v!r}")
    if "label" not in ds:
        raise InputError("the file has no 'label' variable (not a ballsurvey map?)")
    if shape is not None and not isinstance(shape, str):
        raise InputError(f"shape: one label word, got {shape!r} (ds.ballsurvey.mask takes a "
                         "list)")
    if (shape is None) == (n_sides is None):
        raise InputError("give exactly one of shape (--shape WORD) or n_sides (--n-sides N)")
    if shape is not None and shape not in LABELS:
        raise InputError(f"unknown shape {shape!r}; words: {', '.join(LABELS)}")
    if n_sides is not None:
        n_sides = limits.number("n_sides", n_sides, integer=True, lo=3)
    _needs(ds, "n_sides", n_sides is not None or max_n_error is not None,
           "--n-sides N or --max-n-error")
    _needs(ds, "closure_m", max_closure is not None, "--max-closure")
    flat = launches(ds)
    label = flat.label.values.astype(int)
    ns = flat.n_sides.values if "n_sides" in flat else np.full(label.shape, np.nan)
    closure = flat.closure_m.values if "closure_m" in flat else np.full(label.shape, np.nan)
    if shape is not None:
        mask = label == CODE[shape]
        if shape in ("triangle", "square"):
            target = {"triangle": 3.0, "square": 4.0}[shape]
        elif shape == "ngon":
            target = np.round(ns)
        elif shape == "star" and "star_points" in flat:
            target = flat.star_points.values / np.maximum(flat.star_step.values, 1)
        else:  # circle, near_straight, status words: no "exactness", launch order
            target = None
    else:
        mask = np.isin(label, [CODE["triangle"], CODE["square"], CODE["ngon"]]) & \
            (np.round(ns) == n_sides)
        target = float(n_sides)
    err = np.abs(ns - target) if target is not None else np.full(label.shape, np.nan)
    with np.errstate(invalid="ignore"):
        if max_n_error is not None:
            mask &= np.abs(ns - (target if target is not None else np.round(ns))) <= max_n_error
        if max_closure is not None:
            mask &= closure <= max_closure
    idx = np.flatnonzero(mask)
    idx = idx[_best_first(err[idx], closure[idx])] if target is not None else idx
    th_max = flat.theta_max_deg.values if "theta_max_deg" in flat else np.full(label.shape, np.nan)
    conds = [c for c in ("name", "theta0_deg", "thetadot0", "chidot0", "phidot0", "chi0_deg",
                         "c", "cut_height", "M", "A", "B") if c in flat.coords]
    cols = {}
    for c in conds:
        v = np.broadcast_to(flat[c].values, label.shape)[idx]  # scalar coords (chi0_deg) too
        cols[c] = v.astype(str) if c == "name" else v.astype(float)
    cols["label"] = decode_label(label[idx]).astype(str)
    if shape == "star" and "star_points" in flat and "star_step" in flat:  # its {p/q}
        pq = zip(flat.star_points.values[idx], flat.star_step.values[idx])
        cols["star"] = [f"{{{int(a)}/{int(b)}}}" if np.isfinite(a) and np.isfinite(b) and a > 0
                        else "" for a, b in pq]
    cols["n_sides"] = ns[idx].astype(float)
    cols["n_sides_error"] = err[idx].astype(float)
    cols["closure_m"] = closure[idx].astype(float)
    cols["theta_max_deg"] = th_max[idx].astype(float)
    with np.errstate(invalid="ignore"):  # unknown (NA) where theta max is not known
        near = pd.array(th_max[idx] > NEAR_VERTICAL_DEG, dtype="boolean")
    near[np.isnan(th_max[idx].astype(float))] = pd.NA
    cols["near_vertical"] = near
    df = pd.DataFrame(cols)
    df.attrs["units"] = {c: COLUMN_UNITS[c] for c in df.columns if c in COLUMN_UNITS}
    df.attrs["matched"] = len(df)
    df.attrs["ranked"] = target is not None  # best first; else in launch order
    return df


COLUMN_UNITS = dict(CONDITION_UNITS, n_sides="1", n_sides_error="1", closure_m="m",
                    theta_max_deg="deg")


def _constant_columns(df) -> list:
    """Launch-condition columns with one value on every row (said once, not on every row)."""
    if len(df) < 2:
        return []
    return [c for c in df.columns if c in CONDITION_UNITS and df[c].nunique(dropna=False) == 1]


def _fmt(v) -> str:
    if isinstance(v, (float, np.floating)):
        return f"{v:.6g}"
    return str(v)


def format_table(df, fmt: str = "table") -> str:
    """A query's DataFrame for the command line: `table` (launch conditions common to every row
    in a heading line, with units), `csv` (comment lines starting with '#' give the units and
    the common values; pandas: read_csv(f, comment='#')) or `json` ({"units", "common",
    "launches"})."""
    if fmt not in ("table", "csv", "json"):
        raise InputError(f"unknown format {fmt!r}; use table, csv or json")
    # query() names the columns common to every match; a frame cut from it keeps that list
    # only where it still holds (the column is there and constant)
    const = [c for c in df.attrs.get("common", _constant_columns(df))
             if c in df.columns and len(df) and df[c].nunique(dropna=False) == 1]
    common = {c: (df[c].iloc[0].item() if hasattr(df[c].iloc[0], "item") else df[c].iloc[0])
              for c in const}
    body = df.drop(columns=const)
    units = {c: u for c, u in df.attrs.get("units", COLUMN_UNITS).items() if c in df.columns}
    if fmt == "json":
        rows = [{k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                 for k, v in r.items()} for r in json.loads(body.to_json(orient="records"))]
        return json.dumps({"units": units, "common": common, "launches": rows}, indent=1)
    if fmt == "csv":
        head = ["# units: " + ", ".join(f"{c} {u}" for c, u in units.items() if c in body)]
        if common:
            head.append("# common to every row: " + ", ".join(
                f"{c} = {_fmt(v)} {units.get(c, '')}".rstrip() for c, v in common.items()))
        buf = io.StringIO()
        body.to_csv(buf, index=False, float_format="%.10g", lineterminator="\n")
        return "\n".join(head) + "\n" + buf.getvalue().rstrip("\n")
    if df.empty:
        return "no launches match"
    lines = []
    if common:
        lines.append("all rows: " + ", ".join(f"{c} = {_fmt(v)} {units.get(c, '')}".rstrip()
                                              for c, v in common.items()))
    cols = list(body.columns)
    heads = [f"{c} ({units[c]})" if units.get(c) not in (None, "1")
             and not c.endswith(("_deg", "_m")) else c for c in cols]
    cells = [[_fmt(v) for v in body[c].tolist()] for c in cols]
    width = [max(len(h), *(len(x) for x in cs)) for h, cs in zip(heads, cells)]
    lines.append("  ".join(h.rjust(w) for h, w in zip(heads, width)))
    for i in range(len(body)):
        lines.append("  ".join(cells[j][i].rjust(width[j]) for j in range(len(cols))))
    return "\n".join(lines)


def slabs(ds: xr.Dataset, launches: int = 0):
    """The map in slabs along its first axis of about `launches` launches each (default
    SLAB_LAUNCHES; at least one row of that axis), in the map's order; a lone launch: itself."""
    if "label" not in ds or ds.label.ndim == 0:
        yield ds
        return
    dim = ds.label.dims[0]
    per_row = max(1, ds.label.size // max(ds.sizes[dim], 1))
    rows = max(1, (launches or SLAB_LAUNCHES) // per_row)
    for lo in range(0, max(ds.sizes[dim], 1), rows):
        yield ds.isel({dim: slice(lo, lo + rows)})


def query(ds: xr.Dataset, shape: str | None = None, n_sides: int | None = None,
          limit: int | None = None, max_n_error: float | None = None,
          max_closure: float | None = None):
    """`query_frame` cut to `limit` rows; `df.attrs['matched']` is how many matched before it.

    The map is read a slab at a time (`slabs`): each slab's best `limit` rows are kept and the
    kept rows ranked again together (a stable sort: ties stay in launch order), which gives the
    rows `query_frame` on the whole map would."""
    import pandas as pd

    if limit is not None:
        limit = limits.number("limit", limit, integer=True, lo=1)
    parts, matched, ranked, units = [], 0, False, None
    seen: dict = {}  # per condition column: its distinct values over the matches (two at most)
    for part in slabs(ds):
        d = query_frame(part, shape, n_sides, max_n_error, max_closure)
        matched += len(d)
        ranked, units = d.attrs["ranked"], d.attrs["units"]
        for c in d.columns if len(d) else ():
            if c in CONDITION_UNITS:
                new = pd.unique(d[c])
                seen[c] = pd.unique(np.concatenate([seen[c], new]) if c in seen else new)[:2]
        parts.append(d.head(limit) if limit is not None else d)
    df = pd.concat(parts, ignore_index=True) if len(parts) > 1 else parts[0]
    if ranked and len(parts) > 1:
        key = _best_first(df.n_sides_error.to_numpy(float), df.closure_m.to_numpy(float))
        df = df.iloc[key].reset_index(drop=True)
    if limit is not None:
        df = df.head(limit)
    # columns said once are those common to every match, not to the rows kept: a script's
    # columns do not change with --limit
    df.attrs = {"units": units, "ranked": ranked, "matched": matched,
                "common": [c for c, v in seen.items() if len(v) == 1] if matched >= 2 else []}
    return df

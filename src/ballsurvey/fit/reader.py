"""Reading a track file as a spreadsheet or Tracker ("Export Data") writes it (`read_track`)."""
from __future__ import annotations

import re

import numpy as np

from .. import limits
from .track import LENGTH_UNITS, PROBE_COLUMNS, TIME_UNITS, Track, make_track

#: column names (lower case, units and spaces stripped) -> the track's columns
ALIASES = {"t": "t", "time": "t", "x": "x", "y": "y", "theta_deg": "theta_deg",
           "chidot": "chidot", **{k: k for k in PROBE_COLUMNS}}
#: a column's name and its unit: 'x (cm)', 'x [cm]', 'x/cm'
_UNIT_RE = re.compile(r"^(.*?)\s*(?:[(\[]\s*([^)\]]*?)\s*[)\]]|/\s*([A-Za-z]+))\s*$")
#: how many lines may come before the header (a name line or two)
HEADER_WITHIN = 5


def _split(line: str, sep: str | None) -> list[str]:
    return [c.strip().strip('"').strip() for c in (line.split(sep) if sep else line.split())]


def _separator(line: str) -> str | None:
    for sep in ("\t", ";", ","):
        if sep in line:
            return sep
    return None


def _name_and_unit(cell: str) -> tuple[str, str | None]:
    m = _UNIT_RE.match(cell)
    if m and (m.group(2) or m.group(3)) is not None:
        return m.group(1).strip().lower(), (m.group(2) or m.group(3)).strip()
    return cell.strip().lower(), None


def _quoted(cells) -> str:
    return ", ".join(repr(str(c)) for c in cells) or "none"


def read_track(path, probe_m: float | None = None, units: str | None = None,
               time_units: str | None = None) -> Track:
    """Read a track file as a spreadsheet or Tracker ("Export Data") writes it.

    Layout: up to HEADER_WITHIN lines before the header (Tracker's line naming the tracked
    mass); a header with a column t (or time) and x, y (the centre of mass), or two tracked
    masses named with 'tip' and 'base' on the name line (each with its x, y), or columns
    x_tip, y_tip, x_base, y_base (the probe, with probe_m); optionally theta_deg (deg) and
    chidot (rad/s); other columns are ignored. Cells separated by tabs, semicolons or commas
    (a decimal comma with tabs or semicolons). Units: from the header ('x (cm)', 't (ms)') or
    `units` (m, cm, mm) and `time_units` (s, ms); default m and s. Rows with a blank or non-finite
    cell (lost frames) are dropped and their times kept in `Track.dropped_t`. InputError (one
    line) for a file that is not such a track."""
    import io

    import pandas as pd

    p = limits.regular_file(path, "track (a CSV or Tracker file)")
    for name, u, allowed in (("--units", units, LENGTH_UNITS), ("--time-units", time_units,
                                                                TIME_UNITS)):
        if u is not None and u not in allowed:
            raise limits.InputError(f"{name} {u!r}: one of {', '.join(allowed)}")
    try:
        text = p.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError:
        text = p.read_bytes().decode("latin-1")
    lines = text.splitlines()
    head_at, sep, header = None, None, []
    seen = [ln for ln in lines[:HEADER_WITHIN] if ln.strip()]
    for i, line in enumerate(lines[:HEADER_WITHIN + 1]):
        if not line.strip():
            continue
        sep = _separator(line)
        cells = _split(line, sep)
        if any(ALIASES.get(_name_and_unit(c)[0]) == "t" for c in cells):
            head_at, header = i, cells
            break
    if head_at is None:
        # the line most like a header: the one with the most cells
        first = max((_split(ln, _separator(ln)) for ln in seen), key=len, default=[])
        raise limits.InputError(f"{path}: needs a header with a column t (s); found columns "
                                f"{_quoted(first)}")
    # Tracker's name line: one name over each tracked mass's block of columns
    names = [""] * len(header)
    if head_at > 0 and lines[head_at - 1].strip():
        above = _split(lines[head_at - 1], sep)
        current = ""
        for j in range(len(header)):
            if j < len(above) and above[j]:
                current = above[j]
            names[j] = current
    blocks = [n for n in dict.fromkeys(names) if n]
    found = f"found columns {_quoted(header)}"
    columns, col_units = {}, {}
    for j, cell in enumerate(header):
        base, unit = _name_and_unit(cell)
        key = ALIASES.get(base)
        if key is None:
            continue
        if key in ("x", "y") and len(blocks) > 1:
            low = names[j].lower()
            role = "tip" if "tip" in low else "base" if "base" in low else None
            if role is None:
                raise limits.InputError(
                    f"{path}: {len(blocks)} tracked masses ({_quoted(blocks)}); name the probe's "
                    f"two 'tip' and 'base' (or give columns x_tip, y_tip, x_base, y_base); "
                    f"{found}")
            key = f"{key}_{role}"
        if key in columns:
            if key == "t":
                continue  # each tracked mass's own t: the first is the track's
            raise limits.InputError(f"{path}: column {key} twice; {found}")
        columns[key], col_units[key] = j, unit
    body = "\n".join(lines[head_at + 1:])
    if not body.strip():
        raise limits.InputError(f"{path}: no rows below the header; {found}")
    decimal = "."
    if sep in ("\t", ";") and re.search(r"(?m)(^|[\t;])\s*-?\d+,\d+\s*([\t;]|$)", body):
        decimal = ","
    try:
        df = pd.read_csv(io.StringIO(body), sep=sep if sep else r"\s+", header=None,
                         dtype=str, keep_default_na=False, decimal=decimal,
                         skipinitialspace=True, engine="python")
    except (ValueError, pd.errors.ParserError) as exc:
        raise limits.InputError(f"{path}: not a table ({str(exc).splitlines()[0]}); "
                                f"{found}") from None
    if df.shape[1] < len(header):  # trailing empty columns of the last rows
        for j in range(df.shape[1], len(header)):
            df[j] = ""
    data = {}
    for key, j in columns.items():
        raw = df[j].astype(str).str.strip()
        if decimal == ",":
            raw = raw.str.replace(",", ".", regex=False)
        missing = raw.str.lower().isin(("", "nan", "na", "n/a", "null", "none"))
        v = pd.to_numeric(raw.where(~missing, "nan"), errors="coerce")
        odd = np.flatnonzero(v.isna().to_numpy() & ~missing.to_numpy())
        if odd.size:
            raise limits.InputError(f"{path}: row {head_at + 2 + odd[0]}, column "
                                    f"{header[j]!r}: {raw.iloc[odd[0]]!r} is not a number; "
                                    f"{found}")
        data[key] = v.to_numpy(dtype=float)
    if "t" not in data:
        raise limits.InputError(f"{path}: needs a header with a column t (s); {found}")
    positions = [k for k in data if k not in ("t", "theta_deg", "chidot")]
    if not positions:
        raise limits.InputError(f"{path}: needs columns x, y (the centre of mass) or the "
                                f"probe's tip and base; {found}")
    for key, allowed, given, flag in (("x", LENGTH_UNITS, units, "--units"),
                                      ("t", TIME_UNITS, time_units, "--time-units")):
        keys = positions if key == "x" else ["t"]
        said = {col_units[k] for k in keys if col_units[k] is not None}
        for u in said:
            if u not in allowed:
                raise limits.InputError(f"{path}: unit {u!r} in the header; {', '.join(allowed)} "
                                        f"are read ({flag} for a header without units); {found}")
        if len(said) > 1:
            raise limits.InputError(f"{path}: the header mixes units {_quoted(sorted(said))}; "
                                    f"{found}")
        if said and given is not None and said != {given}:
            raise limits.InputError(f"{path}: the header says {said.pop()} and {flag} says "
                                    f"{given}: one of them")
        unit = said.pop() if said else (given or ("m" if key == "x" else "s"))
        for k in keys:
            data[k] = data[k] * allowed[unit]
    for k in ("theta_deg", "chidot"):
        if k in data and col_units[k] not in (None, "deg", "rad/s"):
            raise limits.InputError(f"{path}: column {header[columns[k]]!r}: {k} is read in "
                                    f"{'deg' if k == 'theta_deg' else 'rad/s'}; {found}")
    return make_track(data.pop("t"), probe_m=probe_m, source=str(path), drop_missing=True,
                      **data)

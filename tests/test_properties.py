"""Property tests (Hypothesis) of the three readers of outside input: the spec reader, a map's
attributes and coordinates as `open_map` reads them, and the track reader of `fit`. Whatever
the input, each gives a result or InputError with a one-line message: no other exception, no
traceback, no hang (each example within the deadline). Seeded (derandomize) and bounded
(max_examples), the whole file takes some tens of seconds."""
import json
import math
import shutil
import tempfile
from pathlib import Path

import netCDF4
import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from ballsurvey import api
from ballsurvey.fit import read_track
from ballsurvey.limits import InputError
from ballsurvey.sweep import load_spec

BOUNDED = settings(max_examples=150, deadline=2000, derandomize=True, database=None,
                   suppress_health_check=[HealthCheck.too_slow])


def one_line(exc: Exception) -> None:
    assert isinstance(exc, InputError), f"{type(exc).__name__}: {exc}"
    assert str(exc) and "\n" not in str(exc), repr(str(exc))


# ---------------------------------------------------------------------------------------------
# the spec reader
FLOATS = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                   st.sampled_from([0.0, -0.0, 1e-300, 1e-9, 2e-4, 1.0, 3.0, 20.0, 1e6, 1e300]))
INTS = st.one_of(st.integers(-10, 60), st.sampled_from([0, 1, 10**7, 10**19, -(10**19)]))
SCALARS = st.one_of(FLOATS, INTS, st.booleans(), st.text(max_size=12))
VALUES = st.one_of(SCALARS, st.lists(SCALARS, max_size=5),
                   st.fixed_dictionaries({}, optional={"start": FLOATS, "stop": FLOATS,
                                                       "num": INTS, "x": SCALARS}))
SECTIONS = {
    "ball": ["preset", "a", "c", "M", "A", "B", "g", "cut_height", "q"],
    "launch": ["theta0_deg", "thetadot0", "chidot0", "phidot0", "chi0_deg", "c", "cut_height",
               "M", "z"],
    "run": ["T", "dt", "method", "rtol", "atol", "mode", "cycles", "observe_every", "block",
            "chunk", "backend"],
    "classify": ["mu", "min_cycles", "max_star_points", "max_roundness", "nope"],
    "output": ["file", "variables", "compression"],
}
#: a runnable spec each example starts from and changes
GOOD = {"title": "prop", "launch": {"theta0_deg": [2.0, 10.0], "thetadot0": 0.0,
                                    "chidot0": {"start": 2.0, "stop": 8.0, "num": 3},
                                    "phidot0": -3.0},
        "run": {"T": 3.0, "dt": 2e-4}, "output": {"file": "out.nc"}}


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) \
            else repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"


def toml_text(doc: dict) -> str:
    top = "".join(f"{k} = {toml_value(v)}\n" for k, v in doc.items() if not isinstance(v, dict))
    return top + "".join(f"[{s}]\n" + "".join(f"{k} = {toml_value(v)}\n" for k, v in t.items())
                         for s, t in doc.items() if isinstance(t, dict))


@st.composite
def spec_docs(draw):
    doc = json.loads(json.dumps(GOOD))
    for _ in range(draw(st.integers(1, 4))):
        sec = draw(st.sampled_from(sorted(SECTIONS)))
        key = draw(st.sampled_from(SECTIONS[sec]))
        if draw(st.booleans()) and key in doc.get(sec, {}):
            del doc[sec][key]
        else:
            doc.setdefault(sec, {})[key] = draw(VALUES)
    if draw(st.integers(0, 9)) == 0:  # now and then points instead of a grid
        del doc["launch"]
        doc["points"] = draw(st.lists(st.fixed_dictionaries(
            {"theta0_deg": FLOATS, "thetadot0": FLOATS, "chidot0": FLOATS, "phidot0": FLOATS},
            optional={"name": st.text(max_size=10), "chi0_deg": FLOATS}), min_size=0,
            max_size=3))
    return doc


def _load(text: str) -> None:
    try:
        spec = load_spec("prop.toml", text=text)
    except Exception as exc:  # noqa: BLE001 - the property: InputError only
        one_line(exc)
    else:
        assert spec.n_launches >= 1 and spec.T > 0 and spec.dt > 0


@BOUNDED
@given(spec_docs())
def test_spec_reader_gives_a_spec_or_one_line(doc):
    text = toml_text({k: v for k, v in doc.items() if k != "points"})
    if "points" in doc:
        text += "".join("[[points]]\n" + "".join(f"{k} = {toml_value(v)}\n" for k, v in p.items())
                        for p in doc["points"])
    _load(text)


@settings(BOUNDED, max_examples=100)
@given(st.text(max_size=200))
def test_spec_reader_on_any_text(text):
    _load(text)


# ---------------------------------------------------------------------------------------------
# a map's attributes and coordinates
ATTRS = ["run_T_s", "run_dt_s", "run_dt_s_requested", "run_method", "run_rtol", "run_atol",
         "run_mode", "run_cycles", "run_observe_every", "classify_mu", "classify_min_cycles",
         "classify_max_star_points", "classify_max_energy_drift", "ball_a", "ball_c", "ball_M",
         "ball_A", "ball_B", "ball_g", "ball_cut_height", "title"]
ATTR_VALUES = st.one_of(FLOATS, st.integers(-(2**63), 2**63 - 1), st.text(max_size=12),
                        st.sampled_from(["rk4", "dopri5", "dop853", "full", "period"]),
                        st.lists(st.floats(-1e3, 1e3), min_size=2, max_size=3))
COORDS = ["theta0_deg", "chidot0", "phidot0", "thetadot0", "chi0_deg"]


@pytest.fixture(scope="module")
def base_map(tmp_path_factory):
    from test_security import GRID

    d = tmp_path_factory.mktemp("prop")
    api.sweep(GRID, output=d / "base.nc", progress=False, notice=lambda m: None)
    return d / "base.nc"


@settings(BOUNDED, max_examples=80, suppress_health_check=[HealthCheck.too_slow,
                                                           HealthCheck.function_scoped_fixture])
@given(attrs=st.dictionaries(st.sampled_from(ATTRS), ATTR_VALUES, max_size=4),
       coords=st.lists(st.tuples(st.sampled_from(COORDS), st.integers(0, 2), FLOATS),
                       max_size=2))
def test_open_map_gives_a_checked_map_or_one_line(base_map, attrs, coords):
    from ballsurvey import explore, gallery
    from ballsurvey.query import query

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "m.nc"
        shutil.copy(base_map, path)
        with netCDF4.Dataset(path, "a") as nc:
            for k, v in attrs.items():
                nc.setncattr(k, np.asarray(v) if isinstance(v, list) else v)
            for name, i, v in coords:
                var = nc[name]
                var[min(i, var.size - 1) if var.ndim else ...] = v
        try:
            ds = api.open_map(path)
        except Exception as exc:  # noqa: BLE001 - the property: InputError only
            one_line(exc)
            return
        with ds:  # what every command reads of it works
            gallery.map_settings(ds)
            gallery.map_ball(ds)
            try:
                explore.run_settings(ds)  # may refuse a step too fine to integrate again
            except InputError as exc:
                one_line(exc)
            query(ds, shape="square")


# ---------------------------------------------------------------------------------------------
# the track reader
HEADS = ["t", "x", "y", "theta_deg", "chidot", "x_tip", "y_tip", "x_base", "y_base", "other",
         "", " t ", "T"]
CELLS = st.one_of(FLOATS.map(repr), st.integers(-(10**30), 10**30).map(str),
                  st.text(alphabet=st.characters(blacklist_categories=["Cs"]), max_size=6),
                  st.sampled_from(["", "nan", "inf", "1e999", "-0", '"', "1,2"]))


@st.composite
def tracks(draw):
    cols = draw(st.lists(st.sampled_from(HEADS), min_size=0, max_size=6))
    sep = draw(st.sampled_from([",", ";", "\t", ", "]))
    rows = draw(st.lists(st.lists(CELLS, min_size=0, max_size=len(cols) + 1), max_size=12))
    text = sep.join(cols) + "\n" + "".join(sep.join(r) + "\n" for r in rows)
    data = text.encode("utf-8")
    how = draw(st.integers(0, 5))
    if how == 0:
        data = b"\xef\xbb\xbf" + data  # a byte-order mark
    elif how == 1:
        data = draw(st.binary(max_size=200))  # anything at all
    return data


@BOUNDED
@given(data=tracks(), probe=st.one_of(st.none(), st.sampled_from([0.0254, 1e-9, 0.5])))
@example(data=b"\xef\xbb\xbft, t \n", probe=None)  # found: one column twice once stripped
def test_track_reader_gives_a_track_or_one_line(data, probe):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "track.csv"
        path.write_bytes(data)
        try:
            track = read_track(path, probe_m=probe)
        except Exception as exc:  # noqa: BLE001 - the property: InputError only
            one_line(exc)
            return
        assert len(track.t) >= 1

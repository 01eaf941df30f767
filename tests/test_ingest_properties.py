"""Property-based tests: random and malformed tables / mapping files give a valid Flight or a
FlightReconError (with its documented exit code), never anything else."""

from __future__ import annotations

import string
import warnings

import numpy as np
import pandas as pd
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flightrecon.errors import FlightReconError, FlightReconWarning
from flightrecon.ingest import load_flight, load_mapping
from flightrecon.schema import BY_NAME, REQUIRED
from flightrecon.types import Flight

# 400 examples per test: thousands of fuzzed inputs per CI run in ~20 s; deadline off (first
# calls compile/import)
FAST = settings(max_examples=400, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])

CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64).map(repr),
    st.integers(-10**6, 10**6).map(str),
    st.just(""), st.just("NaN"), st.just("inf"),
    st.text(alphabet=string.printable.replace("\r", ""), max_size=6),
)
NAMES = st.one_of(st.sampled_from(list(BY_NAME)), st.text(string.ascii_letters + "_", min_size=1,
                                                          max_size=8))


def _check(path, **kw) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FlightReconWarning)
        try:
            fl = load_flight(path, **kw)
        except FlightReconError as exc:
            assert 3 <= exc.exit_code <= 7, exc
            return
    assert isinstance(fl, Flight)
    t = fl.data["t_s"].to_numpy()
    assert np.all(np.isfinite(t))
    for c in REQUIRED:
        assert c in fl.data.columns
    for name in fl.data.columns:
        ch = BY_NAME.get(name)
        if ch is not None and ch.kind != "time":
            v = fl.data[name].to_numpy()
            v = v[~np.isnan(v)]
            assert np.all((v >= ch.lo) & (v <= ch.hi))


@FAST
@given(names=st.lists(NAMES, min_size=1, max_size=12),
       n_rows=st.integers(0, 6), data=st.data())
def test_random_csv_tables(tmp_path_factory, names, n_rows, data):
    rows = [",".join(data.draw(CELLS).replace(",", ";").replace("\n", " ") for _ in names)
            for _ in range(n_rows)]
    p = tmp_path_factory.mktemp("h") / "r.csv"
    p.write_text("\n".join([",".join(names), *rows]) + "\n")
    _check(p)


@FAST
@given(data=st.data(), seed=st.integers(0, 2**31 - 1))
def test_mutated_valid_tables(tmp_path_factory, data, seed):
    """A valid log with random cells replaced, rows shuffled or bytes cut, as CSV or Parquet."""
    from test_ingest_support import handmade_frame

    rng = np.random.default_rng(seed)
    d = handmade_frame().iloc[:300].copy()
    kind = data.draw(st.sampled_from(["cells", "shuffle", "cut", "parquet-cut", "parquet"]))
    tmp = tmp_path_factory.mktemp("m")
    if kind == "cells":
        for _ in range(data.draw(st.integers(1, 5))):
            c = d.columns[rng.integers(len(d.columns))]
            d[c] = d[c].astype(object)
            d.iloc[rng.integers(len(d)), d.columns.get_loc(c)] = data.draw(CELLS)
    if kind == "shuffle":
        i = rng.integers(0, len(d) - 1, 2)
        d.iloc[i] = d.iloc[i[::-1]].to_numpy()
    if kind.startswith("parquet"):
        p = tmp / "m.parquet"
        d.to_parquet(p)
    else:
        p = tmp / "m.csv"
        d.to_csv(p, index=False)
    if kind.endswith("cut"):
        b = p.read_bytes()
        p.write_bytes(b[: int(rng.integers(0, len(b)))])
    _check(p)


TOML_VALUES = st.one_of(st.text(max_size=8).map(lambda s: '"' + s.replace('\\', '').replace(
    '"', '') + '"'), st.integers(-3, 3).map(str), st.just("true"), st.just("[1, 2]"))
KEYS = st.sampled_from(["column", "unit", "sign", "reference", "from", "format", "colum"])
UNITS = st.sampled_from(["ft", "m", "kt", "g", "deg", "rad", "K", "degC", "bogus", "s",
                         "timestamp", "m/s^2", "ft/min", "km/h"])


@FAST
@given(tables=st.lists(st.tuples(st.one_of(st.sampled_from(
    ["time", "channels.n_norm_g", "channels.tas_mps", "channels.heading_deg", "gnss.time",
     "channels.bogus_x", "chanels.x"])), st.lists(st.tuples(KEYS, st.one_of(TOML_VALUES, UNITS.map(
        lambda u: f'"{u}"'))), max_size=4)), max_size=4), junk=st.booleans())
def test_random_mapping_files(tmp_path_factory, tables, junk):
    lines = []
    seen = set()
    for name, kv in tables:
        if name in seen:
            continue
        seen.add(name)
        lines.append(f"[{name}]")
        keys = set()
        for k, v in kv:
            if k not in keys:
                keys.add(k)
                lines.append(f"{k} = {v}")
    if junk:
        lines.append("= broken")
    p = tmp_path_factory.mktemp("t") / "m.toml"
    p.write_text("\n".join(lines) + "\n")
    try:
        m = load_mapping(p)
    except FlightReconError as exc:
        assert exc.exit_code in (3, 6)
        return
    assert m.file == str(p)
    # a mapping that loads must also apply cleanly or fail with a project error
    from test_ingest_support import handmade_frame

    log = p.with_name("l.csv")
    handmade_frame().iloc[:200].to_csv(log, index=False)
    _check(log, mapping=p)


def test_empty_dataframe_parquet(tmp_path):
    pd.DataFrame({"t_s": pd.Series([], dtype=float)}).to_parquet(tmp_path / "e.parquet")
    _check(tmp_path / "e.parquet")

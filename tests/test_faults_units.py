"""Issue #24, input: units and time bases checked against physics, time-base repair with a
report.  Each test is named after a finding of the mutation fuzzer that opened the issue."""

from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from _cli import run_cli_stderr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flightrecon.errors import ValidationError
from flightrecon.ingest import load_flight
from flightrecon.ingest.physics import MIN_DURATION_S, MIN_INPUT_SAMPLES

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"
HANDMADE = pd.read_csv(SAMPLES / "handmade.csv")


def write(d: Path, name: str, df: pd.DataFrame, sidecar: str = "handmade") -> Path:
    p = d / f"{name}.csv"
    df.to_csv(p, index=False)
    shutil.copy(SAMPLES / f"{sidecar}.meta.toml", d / f"{name}.meta.toml")
    return p


run = run_cli_stderr


def load_quiet(path, **kw):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        fl = load_flight(path, **kw)
    return fl, [str(x.message) for x in w]


@pytest.mark.parametrize("name,kw", [
    ("circuit.parquet", {}), ("regional.parquet", {}), ("landing.parquet", {}),
    ("seed-ads-arms.parquet", {}), ("handmade.csv", {}),
    ("foreign.csv", {"mapping": SAMPLES / "foreign.mapping.toml"})])
def test_shipped_logs_pass_the_physics_checks_without_a_word(name, kw):
    """Nothing wrongly refused: every shipped log loads with no unit or time-base message."""
    _, warns = load_quiet(SAMPLES / name, **kw)
    assert not [w for w in warns if "unit" in w or "radian" in w or "swap" in w
                or "duplicate" in w], warns


# ------------------------------------------------------------------ units


def test_attitude_in_radians_in_deg_columns_is_refused(tmp_path, capsys):
    """Roll, pitch and heading recorded in radians in _deg columns gave an all-NaN track
    with exit 0."""
    d = HANDMADE.copy()
    for c in ("roll_deg", "pitch_deg", "heading_deg"):
        d[c] = np.radians(d[c])
    p = write(tmp_path, "rad", d)
    code, err = run(["reconstruct", p, "-o", tmp_path / "r.parquet"], capsys)
    assert code == 5, err
    assert "rad.csv" in err and "pitch_deg" in err and "likely unit rad" in err
    assert not (tmp_path / "r.parquet").exists()


def test_attitude_in_radian_range_without_evidence_is_a_warning(tmp_path):
    """All three attitude channels inside the radian range but nothing to test them with
    (no longitudinal load factor, no GNSS velocity, no turn in the normal load factor): a
    warning naming the likely unit.  (With the normal load's turns the log is refused:
    ``tests/test_faults_contradicted.py``.)"""
    d = HANDMADE.copy()
    for c in ("roll_deg", "pitch_deg", "heading_deg"):
        d[c] = np.radians(d[c])
    d["n_long_g"] = np.where(d["n_long_g"].notna(), 0.0, np.nan)
    d["n_norm_g"] = np.where(d["n_norm_g"].notna(), 1.0, np.nan)
    d = d.drop(columns=["gnss_vn_mps", "gnss_ve_mps"])
    p = write(tmp_path, "radw", d)
    _, warns = load_quiet(p)
    assert any("likely unit rad" in w and "radw.csv" in w for w in warns), warns


def test_time_column_in_milliseconds_is_refused(tmp_path, capsys):
    """A time column in milliseconds gave speeds of 3.3e5 m/s with exit 0."""
    d = HANDMADE.copy()
    d["t_s"] = d["t_s"] * 1000.0
    p = write(tmp_path, "ms", d)
    code, err = run(["reconstruct", p, "-o", tmp_path / "r.parquet"], capsys)
    assert code == 5, err
    assert "ms.csv" in err and "likely unit: ms" in err


def test_time_in_milliseconds_caught_by_gnss_alone(tmp_path):
    """Without the load factors' witness, the GNSS positions' implied ground speed (1000
    times too slow) names the unit."""
    d = HANDMADE.copy()
    d["t_s"] = d["t_s"] * 1000.0
    d["n_long_g"] = np.where(d["n_long_g"].notna(), 0.0, np.nan)
    p = write(tmp_path, "msg", d)
    with pytest.raises(ValidationError, match="likely unit: ms") as ex:
        load_quiet(p)
    assert "msg.csv" in str(ex.value)


@pytest.mark.parametrize("col,factor", [("gnss_alt_m", 1 / 0.3048), ("baro_alt_m", 1 / 0.3048),
                                        ("gnss_alt_m", 0.3048)])
def test_gnss_height_in_feet_in_a_metre_column_is_refused(tmp_path, col, factor):
    """GNSS height in feet in a metre column passed without a word (the handmade log climbs
    1375 m: GNSS against pressure altitude gives the factor 3.28)."""
    d = HANDMADE.copy()
    d[col] = d[col] * factor
    p = write(tmp_path, "ft", d)
    with pytest.raises(ValidationError, match="likely unit ft|in feet") as ex:
        load_quiet(p)
    assert "ft.csv" in str(ex.value)


def _foreign_with_altitude_unit(tmp_path: Path, unit_line: str) -> Path:
    for f in ("foreign.csv", "foreign.meta.toml"):
        shutil.copy(SAMPLES / f, tmp_path / f)
    text = (SAMPLES / "foreign.mapping.toml").read_text()
    bad = text.replace('column = "ALT_FT"\nunit = "ft"', 'column = "ALT_FT"' + unit_line)
    assert bad != text
    (tmp_path / "m.toml").write_text(bad)
    return tmp_path / "m.toml"


def test_pressure_altitude_in_feet_read_as_metres_by_a_mapping_is_refused(tmp_path):
    """A mapping maps the feet column without a unit (read in the channel's metres): the
    pressure altitude's rate against the vertical acceleration says feet with certainty
    (factor 3.06 +- 0.19, r 0.99): refused, naming the mapping's table and how to confirm."""
    m = _foreign_with_altitude_unit(tmp_path, "")
    with pytest.raises(ValidationError, match="likely unit ft") as ex:
        load_quiet(tmp_path / "foreign.csv", mapping=m)
    msg = str(ex.value)
    assert "foreign.csv" in msg and "ALT_FT" in msg
    assert "m.toml [channels.baro_alt_m]" in msg and "used as declared" in msg


def test_a_unit_declared_in_the_mapping_and_contradicted_is_refused_unless_confirmed(
        tmp_path, capsys):
    """Feet declared as metres explicitly: the physics contradicts it with certainty, so it
    is refused naming the mapping's line (issue #50: it was used as declared, and the
    reconstruction ended in exit 8 'no method produced a physically possible track').  With
    ``unit_confirmed = true`` the user's word wins, recorded as ``overridden`` with its
    figure, on the console of a reconstruction and in its summary."""
    m = _foreign_with_altitude_unit(tmp_path, '\nunit = "m"')
    code, err = run(["reconstruct", tmp_path / "foreign.csv", "--mapping", m, "-o",
                     tmp_path / "r.parquet"], capsys)
    assert code == 5, err
    assert "ALT_FT" in err and "likely unit ft" in err and "m.toml line" in err
    assert "[channels.baro_alt_m] unit = \"m\"" in err and "unit_confirmed = true" in err
    m = _foreign_with_altitude_unit(tmp_path, '\nunit = "m"\nunit_confirmed = true')
    fl, warns = load_quiet(tmp_path / "foreign.csv", mapping=m)
    hit = [w for w in warns if "ALT_FT" in w and "unit_confirmed = true" in w]
    assert hit and "likely unit ft" in hit[0] and 'unit = "m"' in hit[0], warns
    door = {c["check"]: c for c in fl.meta.ingest.door}
    assert door["baro_alt_m unit"]["verdict"] == "overridden"
    assert 2.6 < door["baro_alt_m unit"]["figure"] < 3.9
    # the values are the file's, as declared (not converted from feet)
    raw = pd.read_csv(tmp_path / "foreign.csv")["ALT_FT"].dropna().to_numpy()
    got = fl.data["baro_alt_m"].dropna().to_numpy()
    assert np.allclose(np.sort(got)[[0, -1]], np.sort(raw)[[0, -1]])


def test_unit_confirmed_without_a_unit_is_a_mapping_error(tmp_path, capsys):
    """``unit_confirmed`` confirms a written unit: alone, or not a boolean, it is a mapping
    error (exit 6) naming its line."""
    m = _foreign_with_altitude_unit(tmp_path, '\nunit_confirmed = true')
    code, err = run(["info", tmp_path / "foreign.csv", "--mapping", m], capsys)
    assert code == 6 and "unit_confirmed" in err and "line" in err, err


def test_ten_row_airborne_log_is_refused_with_the_minimum(tmp_path, capsys):
    """A 10-row airborne log gave a track 9.9 km off with exit 0."""
    p = write(tmp_path, "ten", HANDMADE.iloc[1000:1010])
    code, err = run(["reconstruct", p, "-o", tmp_path / "r.parquet"], capsys)
    assert code == 5, err
    assert "ten.csv" in err and "too short" in err
    assert f"{MIN_DURATION_S:g} s" in err and f"{MIN_INPUT_SAMPLES} samples" in err


# ------------------------------------------------------------------ time base


def _rows_in(msg: str) -> set[int]:
    import re

    m = re.search(r"rows? ([\d, ]+)", msg)
    return {int(x) for x in m.group(1).replace(" ", "").split(",") if x} if m else set()


def test_three_swapped_row_pairs_are_resorted_and_reported(tmp_path, capsys):
    """Three pairs of adjacent rows swapped ("time goes backward") were refused."""
    d = HANDMADE.copy()
    for i in (200, 700, 1500):
        d.iloc[[i, i + 1]] = d.iloc[[i + 1, i]].to_numpy()
    p = write(tmp_path, "swap", d)
    fl, warns = load_quiet(p)
    assert np.all(np.diff(fl.data.t_s) > 0)
    pd.testing.assert_frame_equal(
        fl.data[["t_s", "n_norm_g"]].reset_index(drop=True),
        load_quiet(SAMPLES / "handmade.csv")[0].data[["t_s", "n_norm_g"]])
    w = [x for x in warns if "local swap" in x]
    assert len(w) == 1 and "swap.csv" in w[0]
    assert _rows_in(w[0]) == {201, 202, 701, 702, 1501, 1502}   # 1-based data rows
    code, err = run(["reconstruct", p, "-o", tmp_path / "r.parquet"], capsys)
    assert code == 0, err
    summary = json.loads((tmp_path / "r.summary.json").read_text())
    assert any("local swap" in x for x in summary["warnings"])


def test_five_exactly_repeated_rows_are_dropped_and_reported(tmp_path):
    """Five exactly repeated rows ("duplicate timestamps") were refused."""
    d = HANDMADE.copy()
    idx = [100, 400, 800, 1200, 1600]
    d = pd.concat([d, d.iloc[idx]]).sort_index(kind="stable").reset_index(drop=True)
    p = write(tmp_path, "dup", d)
    fl, warns = load_quiet(p)
    assert len(fl.data) == len(HANDMADE)
    w = [x for x in warns if "exact duplicate" in x]
    assert len(w) == 1 and "dup.csv" in w[0] and "5 exact" in w[0]
    # the repeats are the rows right after each original (1-based: original i+1, repeat i+2
    # plus the rows inserted before it)
    assert _rows_in(w[0]) == {i + 2 + k for k, i in enumerate(idx)}


def test_conflicting_duplicates_on_a_few_rows_are_merged_and_reported(tmp_path):
    """One time stamp written twice with different values (issue #39 item 4) was refused:
    the pair is merged into one row, channel by channel the mean, and reported."""
    d = HANDMADE.copy()
    extra = d.iloc[[500]].copy()
    extra["n_norm_g"] += 0.2
    d = pd.concat([d.iloc[:501], extra, d.iloc[501:]]).reset_index(drop=True)
    p = write(tmp_path, "conf", d)
    fl, warns = load_quiet(p)
    assert len(fl.data) == len(HANDMADE)
    w = [x for x in warns if "written twice with different values" in x]
    assert len(w) == 1 and "conf.csv" in w[0] and _rows_in(w[0]) == {502}
    got = fl.data.loc[fl.data["row"] == 501, "n_norm_g"].to_numpy()
    # the mean of the two values written: the original + 0.1 g (to rounding of the CSV text)
    assert got == pytest.approx(HANDMADE["n_norm_g"].iloc[500] + 0.1, abs=1e-9)


def test_conflicting_duplicates_on_many_rows_are_refused_naming_the_rows(tmp_path):
    """More than 1 % of the rows repeating a stamp with other values: a time base coarser
    than the sampling, which no rule recovers (exit 5, rows named)."""
    d = HANDMADE.copy()
    idx = list(range(100, 1900, 60))                     # 30 rows of 1921: 1.6 %
    extra = d.iloc[idx].copy()
    extra["n_norm_g"] += 0.2
    d = pd.concat([d, extra]).sort_index(kind="stable").reset_index(drop=True)
    p = write(tmp_path, "conf", d)
    with pytest.raises(ValidationError, match="duplicate timestamps with different") as ex:
        load_quiet(p)
    assert ex.value.rows[0] == 102 and len(ex.value.rows) == 30
    assert ex.value.file.endswith("conf.csv")


def test_clock_reset_is_refused_naming_the_rows(tmp_path):
    d = HANDMADE.copy()
    d.loc[1000:, "t_s"] = d.loc[1000:, "t_s"] - 100.0      # a recorder restart
    p = write(tmp_path, "reset", d)
    with pytest.raises(ValidationError, match="backward.*clock reset") as ex:
        load_quiet(p)
    assert ex.value.rows == [1001]


def test_clock_jump_is_refused_naming_the_rows(tmp_path):
    """Time leaping forward by an hour while the aircraft's own GNSS positions moved 75 m."""
    d = HANDMADE.copy()
    d.loc[1200:, "t_s"] = d.loc[1200:, "t_s"] + 3600.0
    p = write(tmp_path, "jump", d)
    with pytest.raises(ValidationError, match="clock jump") as ex:
        load_quiet(p)
    assert ex.value.rows == [1201]


def test_a_recording_gap_is_not_a_clock_jump(tmp_path):
    """Nothing wrongly refused: an hour missing from the record (positions far apart) is a
    gap, left to the cleaning layer."""
    d = HANDMADE.copy()
    d.loc[1200:, "t_s"] = d.loc[1200:, "t_s"] + 3600.0
    d.loc[1200:, "gnss_lon_deg"] = d.loc[1200:, "gnss_lon_deg"] + 3.0   # 250 km on
    p = write(tmp_path, "gap", d)
    fl, _ = load_quiet(p)
    assert len(fl.data) == len(d)


def test_complementary_rows_sharing_a_time_stamp_are_kept(tmp_path):
    """Nothing wrongly refused: a GNSS fix written on its own row with the time of a recorder
    row (no channel in common) is merged by the cleaning layer."""
    d = HANDMADE.copy()
    gcols = [c for c in d.columns if c.startswith("gnss_")]
    fix = d.iloc[[800]].copy()
    d.loc[800, gcols] = np.nan
    fix.loc[:, [c for c in d.columns if c not in gcols and c != "t_s"]] = np.nan
    d = pd.concat([d.iloc[:801], fix, d.iloc[801:]]).reset_index(drop=True)
    p = write(tmp_path, "comp", d)
    fl, _ = load_quiet(p)
    assert len(fl.data) == len(d)


def test_airspeed_in_knots_in_a_metre_per_second_column_is_refused(tmp_path):
    """TAS in knots in tas_mps: 1.94 times the GNSS ground speed (the shipped logs: 1.00 to
    1.16 with their winds)."""
    d = HANDMADE.copy()
    d["tas_mps"] = d["tas_mps"] * 3600 / 1852
    p = write(tmp_path, "kt", d)
    with pytest.raises(ValidationError, match="likely unit kt") as ex:
        load_quiet(p)
    assert "kt.csv" in str(ex.value) and "tas_mps" in str(ex.value)


def test_gnss_height_in_feet_is_named_when_the_pressure_altitude_is_confirmed(tmp_path):
    """On the circuit the pressure altitude agrees with the vertical acceleration (factor
    0.89), so the message says which of the two heights is in feet."""
    d = pd.read_parquet(SAMPLES / "circuit.parquet")
    d["gnss_alt_m"] = d["gnss_alt_m"] / 0.3048
    d.to_parquet(tmp_path / "cg.parquet")
    shutil.copy(SAMPLES / "circuit.meta.toml", tmp_path / "cg.meta.toml")
    with pytest.raises(ValidationError, match="gnss_alt_m is in ft") as ex:
        load_quiet(tmp_path / "cg.parquet")
    assert ex.value.column == "gnss_alt_m" and "cg.parquet" in str(ex.value)

_ORIGINAL = None


def _original():
    global _ORIGINAL
    if _ORIGINAL is None:
        _ORIGINAL = load_quiet(SAMPLES / "handmade.csv")[0].data.drop(columns=["row"])
    return _ORIGINAL


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(swaps=st.sets(st.integers(min_value=1, max_value=950), max_size=12),
       repeats=st.sets(st.integers(min_value=0, max_value=1920), max_size=8))
def test_swaps_and_repeats_are_repaired_to_the_original(tmp_path_factory, swaps, repeats):
    """Property: any set of disjoint adjacent swaps and exact repeats of rows loads as the
    original log (same times, same values), with each repair reported."""
    d = HANDMADE.copy()
    for k in swaps:                       # rows 2k and 2k+1: disjoint pairs
        i = 2 * k
        d.iloc[[i, i + 1]] = d.iloc[[i + 1, i]].to_numpy()
    if repeats:
        d = pd.concat([d, d.iloc[sorted(repeats)]]).sort_index(kind="stable")
    p = write(tmp_path_factory.mktemp("prop"), "p", d.reset_index(drop=True))
    fl, warns = load_quiet(p)
    pd.testing.assert_frame_equal(fl.data.drop(columns=["row"]).reset_index(drop=True),
                                  _original().reset_index(drop=True))
    assert bool(swaps) == any("local swap" in w for w in warns)
    assert bool(repeats) == any("exact duplicate" in w for w in warns)

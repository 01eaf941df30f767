"""The formats analysts have (issue #36): Garmin glass-cockpit exports read as recorded, a
separate date / time / UTC-offset time base, logs without a longitudinal accelerometer, and the
time-base repairs of 1 Hz loggers (issue #39 item 4).

The real sample is ``sample_logs/g1000_sr22_LFQA_20220417.csv`` (a Cirrus SR22T's Perspective+
export, MIT, ``sample_logs/LICENSE-flightlogstats``); its conventions are checked against its
own GPS, which is independent of the air data.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from flightrecon.errors import SchemaError, ValidationError
from flightrecon.ingest.garmin import INHG_PA, pressure_altitude_from_indicated
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.ingest.readers import read_table
from flightrecon.ingest.time_cells import combine_date_time
from flightrecon.ingest.timestamps import repair_time_order
from tests.test_ingest_support import handmade_frame, load_quiet

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
GARMIN = SAMPLES / "g1000_sr22_LFQA_20220417.csv"


@pytest.fixture(scope="module")
def garmin():
    return load_quiet(GARMIN)


# ------------------------------------------------------------------------ the Garmin export


def test_garmin_export_is_recognised_with_its_units_and_airframe_line():
    raw = read_table(GARMIN)
    assert raw.dialect == "garmin" and raw.header_line == 3
    assert raw.preamble["airframe_name"] == "Cirrus SR22 Turbo"
    assert raw.units["AltGPS"] == "ft wgs" and raw.units["NormAc"] == "G"
    assert raw.units["BaroA"] == "inch" and raw.units["OAT"] == "deg C"
    assert len(raw.columns) == 80
    # the last line (24 fields written of 80, no line end) is dropped with a warning
    assert raw.n_rows == 2841
    assert len(raw.warnings) == 1 and "data row 2842" in raw.warnings[0]


def test_garmin_export_loads_as_recorded(garmin):
    """No mapping, no sidecar: every wall of issue #36 is passed with a warning, not an exit."""
    fl, warns = garmin
    text = "\n".join(warns)
    assert "cut short" in text                                      # wall 6
    assert "2 row(s) at the start have no time" in text             # wall 3
    assert "clock steps back by 3 s at row 21" in text              # the export's own quirk
    assert "n_long_g not recorded: derived" in text                 # wall 4
    assert "column(s) not in the schema and not mapped, ignored" in text
    assert fl.meta.epoch_utc == "2022-04-17T12:48:47Z"              # UTCOfst +00:00
    assert fl.meta.ingest.derived_channels["n_long_g"].startswith("(dV/dt)/g0")
    d = fl.data
    # 2841 rows read, 2 before the clock was set: 2839 rows at 1 Hz, strictly increasing
    assert len(d) == 2839 and np.all(np.diff(d.t_s) == 1.0)
    for c in ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg", "heading_deg",
              "tas_mps", "ias_mps", "baro_alt_m", "sat_degc", "gnss_lat_deg", "gnss_lon_deg",
              "gnss_alt_m", "gnss_vn_mps", "gnss_ve_mps", "gnss_quality"):
        assert c in d.columns, c


def test_garmin_normal_load_is_one_g_at_rest(garmin):
    """NormAc is n - 1: +1 g standing still (the recorder's 0.01 g resolution)."""
    d = garmin[0].data
    rest = d.ias_mps < 1.0
    assert rest.sum() > 300
    assert np.nanmedian(d.n_norm_g[rest]) == pytest.approx(1.0, abs=0.01)


def test_garmin_heading_is_true_against_the_gps_track(garmin):
    """HDG + MagVar against the track of consecutive GPS positions, straight and fast: they
    differ by the drift angle only (wind 10-20 kt at 150 kt: a few degrees, both signs), so
    the median is within 2 deg; HDG alone (magnetic) would be 1.7 deg off on top of it, and a
    MagVar of the wrong sign 3.5 deg."""
    d = garmin[0].data
    lat, lon = np.radians(d.gnss_lat_deg), np.radians(d.gnss_lon_deg)
    trk = np.degrees(np.arctan2(np.gradient(lon) * np.cos(lat), np.gradient(lat))) % 360
    ok = (d.tas_mps > 60) & (d.roll_deg.abs() < 3) & np.isfinite(trk)
    assert ok.sum() > 1000
    diff = (d.heading_deg - trk + 180) % 360 - 180
    assert abs(np.median(diff[ok])) < 2.0
    # the GNSS velocity (GndSpd along TRK + MagVar) agrees with the positions' track to 1 deg
    vtrk = np.degrees(np.arctan2(d.gnss_ve_mps, d.gnss_vn_mps)) % 360
    assert abs(np.median(((vtrk - trk + 180) % 360 - 180)[ok])) < 1.0


def test_garmin_lateral_load_is_positive_to_the_right(garmin):
    """In the taxi turns the lateral load follows the centripetal acceleration V dpsi/dt,
    positive turning right (+ toward the right wing)."""
    d = garmin[0].data
    psi = np.unwrap(np.radians(d.heading_deg.interpolate().bfill()))
    gs = np.hypot(d.gnss_vn_mps, d.gnss_ve_mps)
    a = gs * np.gradient(psi) / 9.80665
    turn = (gs > 2) & (gs < 13) & (np.abs(np.degrees(np.gradient(psi))) > 3)
    assert turn.sum() > 30
    assert np.corrcoef(d.n_lat_g[turn], a[turn])[0, 1] > 0.4


def test_garmin_pressure_altitude_from_the_altimeter_setting(garmin):
    """AltInd at BaroA is turned into pressure altitude: at LFQA's apron (AltInd 313 ft at
    30.21 inHg = 1023.0 hPa) it is about 270 ft lower (27 ft/hPa near sea level)."""
    d = garmin[0].data
    h = pressure_altitude_from_indicated(np.array([0.0, 313 * 0.3048]),
                                         np.array([1013.25e2, 30.21 * INHG_PA]))
    assert h[0] == pytest.approx(0.0, abs=1e-6)
    assert (313 * 0.3048 - h[1]) / 0.3048 == pytest.approx(27.0 * (30.21 * INHG_PA / 100
                                                                   - 1013.25), rel=0.03)
    first = d.baro_alt_m.dropna().iloc[0]
    assert first == pytest.approx(h[1], abs=2.0)


def test_garmin_derived_long_load_at_rest_is_sin_pitch(garmin):
    d = garmin[0].data
    # standing still over the whole +-3 s of the airspeed difference
    still = d.tas_mps.fillna(0.0).abs().rolling(9, center=True, min_periods=1).max() < 0.1
    rest = still & d.pitch_deg.notna()
    assert rest.sum() > 300
    np.testing.assert_allclose(d.n_long_g[rest], np.sin(np.radians(d.pitch_deg[rest])),
                               atol=1e-9)


def test_garmin_gnss_withheld(garmin):
    fl, _ = load_quiet(GARMIN, gnss_use=GnssUse(withhold=True))
    assert not [c for c in fl.data.columns if c.startswith("gnss_")]
    assert any("GNSS withheld" in n for n in fl.meta.ingest.notes)
    # everything else as with the GNSS
    np.testing.assert_array_equal(fl.data.heading_deg, garmin[0].data.heading_deg)


def test_user_mapping_overrides_the_garmin_preset(tmp_path):
    """A mapping file laid over the preset wins channel by channel: here the heading is taken
    magnetic and converted with the World Magnetic Model instead of the recorded MagVar, and
    the pitch is read with the other sign."""
    m = tmp_path / "g.mapping.toml"
    m.write_text('[channels.heading_deg]\ncolumn = "HDG"\nreference = "magnetic"\n'
                 '[channels.pitch_deg]\ncolumn = "Pitch"\nsign = -1\n')
    fl, _ = load_quiet(GARMIN, mapping=m)
    base, _ = load_quiet(GARMIN)
    notes = "\n".join(fl.meta.ingest.notes)
    assert "WMM" in notes and "HDG + MagVar" not in notes
    np.testing.assert_allclose(fl.data.pitch_deg, -base.data.pitch_deg)
    # WMM and the avionics' variation agree within 0.5 deg there
    diff = (fl.data.heading_deg - base.data.heading_deg + 180) % 360 - 180
    assert np.nanmax(np.abs(diff)) < 0.5


# --------------------------------------------------------------- date, time and UTC offset


@pytest.mark.parametrize("offset,utc", [("-05:00", "2024-03-01T15:00:00"),
                                        ("+02:00", "2024-03-01T08:00:00"),
                                        ("+0530", "2024-03-01T04:30:00"),
                                        ("Z", "2024-03-01T10:00:00"),
                                        ("-3", "2024-03-01T13:00:00")])
def test_local_date_time_and_offset_to_utc(tmp_path, offset, utc):
    p = tmp_path / "x.csv"
    p.write_text(f"d,t,o,v\n2024-03-01,10:00:00,{offset},1\n")
    raw = read_table(p)
    ns = combine_date_time(raw, "t", "d", "o", None, np.array([1]))
    assert ns[0] == np.datetime64(utc, "ns").astype(np.int64)


def test_unparsable_offset_names_the_column_and_row(tmp_path):
    p = tmp_path / "x.csv"
    p.write_text("d,t,o,v\n2024-03-01,10:00:00,+02:00,1\n2024-03-01,10:00:01,+25:00,1\n")
    with pytest.raises(ValidationError, match="UTC offset") as ex:
        combine_date_time(read_table(p), "t", "d", "o", None, np.array([1, 2]))
    assert ex.value.column == "o" and list(ex.value.rows) == [2]


def test_mapping_with_separate_date_time_and_offset_columns(tmp_path):
    """Generic, not only Garmin: a mapping's [time] takes date_column and utc_offset_column."""
    d = handmade_frame()
    t0 = pd.Timestamp("2026-03-15T11:00:00")            # local, UTC+02:00 (sidecar epoch 09:00Z)
    stamps = t0 + pd.to_timedelta(d.pop("t_s"), unit="s")
    d.insert(0, "DATE", stamps.dt.strftime("%d/%m/%Y"))
    d.insert(1, "TIME", stamps.dt.strftime("%H:%M:%S.%f"))
    d.insert(2, "TZ", "+02:00")
    log = tmp_path / "dt.csv"
    d.to_csv(log, index=False)
    (tmp_path / "dt.meta.toml").write_text((SAMPLES / "handmade.meta.toml").read_text())
    m = tmp_path / "m.toml"
    m.write_text('[time]\ncolumn = "TIME"\ndate_column = "DATE"\nutc_offset_column = "TZ"\n'
                 'format = "%d/%m/%Y %H:%M:%S.%f"\n')
    fl, warns = load_quiet(log, mapping=m)
    ref, _ = load_quiet(SAMPLES / "handmade.csv")
    np.testing.assert_allclose(fl.data.t_s, ref.data.t_s, atol=1e-6)
    assert not [w for w in warns if "not mapped" in w]


# ------------------------------------------------------------------ no longitudinal channel


def test_log_without_n_long_is_accepted_and_derived(tmp_path):
    d = handmade_frame().drop(columns=["n_long_g"])
    log = tmp_path / "nl.csv"
    d.to_csv(log, index=False)
    (tmp_path / "nl.meta.toml").write_text((SAMPLES / "handmade.meta.toml").read_text())
    fl, warns = load_quiet(log)
    ref, _ = load_quiet(SAMPLES / "handmade.csv")
    assert any("n_long_g not recorded" in w for w in warns)
    # against the recorded channel of the hand-made flight (rest, take-off run, climb, turn):
    # within 0.03 g at the median, the 6-s difference lagging the take-off acceleration
    both = fl.data.n_long_g.notna() & ref.data.n_long_g.notna()
    err = (fl.data.n_long_g - ref.data.n_long_g)[both]
    assert np.median(np.abs(err)) < 0.03


def test_missing_n_long_without_pitch_is_refused_with_a_usable_hint(tmp_path):
    d = handmade_frame().drop(columns=["n_long_g", "pitch_deg"])
    log = tmp_path / "np.csv"
    d.to_csv(log, index=False)
    with pytest.raises(SchemaError) as ex:
        load_quiet(log)
    msg = str(ex.value)
    assert "n_long_g" in msg and "pitch_deg" in msg and "derived" in msg


def test_unmapped_column_of_any_type_is_ignored(tmp_path):
    """A time-of-day column (Arrow time32) not mapped to a channel was exit 4."""
    d = handmade_frame()
    tbl = pa.Table.from_pandas(d, preserve_index=False).append_column(
        "Lcl Time", pa.array(np.arange(len(d), dtype=np.int32) % 86400, pa.time32("s")))
    log = tmp_path / "tt.parquet"
    pq.write_table(tbl, log)
    (tmp_path / "tt.meta.toml").write_text((SAMPLES / "handmade.meta.toml").read_text())
    fl, warns = load_quiet(log)
    assert any("Lcl Time" in w and "ignored" in w for w in warns)
    assert len(fl.data) == len(d)


# ------------------------------------------------------------------------ 1 Hz time repairs


def _regular(n=40):
    t = np.arange(n, dtype=float)
    return t, np.arange(1, n + 1), {"tas_mps": 50.0 + t, "heading_deg": np.full(n, 90.0)}


def test_repeated_whole_second_followed_by_a_skip_is_spread():
    """t, t, t+2 (and t, t+2, t+2): the repeat is moved onto the missing second."""
    t, rows, v = _regular()
    t[10] = 9.0            # 8, 9, 9, 11
    t[20] = 21.0           # 19, 21, 21, 22
    rep = repair_time_order(t, rows, v, "f.csv", "time")
    np.testing.assert_array_equal(rep.t[rep.selection], np.arange(40.0))
    assert len(rep.warnings) == 1 and "2 row(s)" in rep.warnings[0]
    assert "rows 11, 21" in rep.warnings[0]


def test_short_backward_clock_step_retimes_the_rows_before():
    """The shipped export's pattern: 0..4, then 1, 2, 3, 4, 5...: the 5 rows before the step
    are re-timed 4 s earlier, nothing is dropped."""
    t = np.r_[np.arange(5.0), np.arange(1.0, 30.0)]
    rows = np.arange(1, t.size + 1)
    rep = repair_time_order(t, rows, {"tas_mps": np.ones(t.size)}, "f.csv", "time")
    np.testing.assert_array_equal(rep.t, np.arange(-4.0, 30.0))
    assert "steps back by 3 s at row 6" in rep.warnings[0]


def test_conflicting_duplicate_angles_merge_on_the_circle():
    t, rows, v = _regular()
    t = np.r_[t[:11], 10.0, t[11:]]
    rows = np.arange(1, t.size + 1)
    v = {k: np.r_[a[:11], a[10], a[11:]] for k, a in v.items()}
    v["heading_deg"] = v["heading_deg"].copy()
    v["heading_deg"][10], v["heading_deg"][11] = 358.0, 4.0
    v["tas_mps"] = v["tas_mps"].copy()
    v["tas_mps"][11] += 1.0
    rep = repair_time_order(t, rows, v, "f.csv", "time")
    assert rep.selection.size == 40
    assert rep.values["heading_deg"][10] == pytest.approx(1.0)
    assert rep.values["tas_mps"][10] == pytest.approx(60.5)
    assert v["heading_deg"][10] == 358.0                    # inputs not modified


def test_backward_step_beyond_a_few_seconds_is_still_refused():
    t = np.r_[np.arange(30.0), np.arange(10.0, 40.0)]       # back by 20 s: a restart
    rows = np.arange(1, t.size + 1)
    with pytest.raises(ValidationError, match="clock reset") as ex:
        repair_time_order(t, rows, {"tas_mps": np.ones(t.size)}, "f.csv", "time")
    assert list(ex.value.rows) == [31]


def test_cleaning_report_names_ignored_columns_and_derived_channels(garmin):
    from flightrecon.cleaning import clean_flight

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rep = clean_flight(garmin[0]).report
    ign = [e for e in rep if e["action"] == "ignored_columns"]
    # 80 columns: 20 read (AltMSL among them: the altitude's and the GPS height's datums are
    # checked against it, issue #49), 60 - 1 ignored
    assert len(ign) == 1 and ign[0]["count"] == 59 and "E1 RPM" in ign[0]["columns"]
    assert "AltMSL" not in ign[0]["columns"]
    der = [e for e in rep if e["action"] == "derived_channel"]
    assert [e["channel"] for e in der] == ["n_long_g"]


def test_garmin_export_with_repeated_and_skipped_seconds_is_retimed(tmp_path, garmin):
    """A 1 Hz logger stamping whole seconds writes t, t, t+2 now and then (728 times in a
    held-back export of this family: "duplicate timestamps with different values", exit 5).
    The shipped export with 700 such stamps written in loads to the same time base and values
    as the export itself, with one warning."""
    lines = GARMIN.read_bytes().decode().split("\n")
    data0 = 3 + 2                    # preamble, header, the 2 rows before the clock was set
    ks = list(range(data0 + 40, data0 + 40 + 4 * 700, 4))
    for k in ks:
        f, prev = lines[k].split(","), lines[k - 1].split(",")
        f[1] = prev[1]               # Lcl Time of the row before: t, t, t+2
        lines[k] = ",".join(f)
    log = tmp_path / "skips.csv"
    log.write_bytes("\n".join(lines).encode())
    fl, warns = load_quiet(log)
    w = [x for x in warns if "re-timed onto the missing stamp" in x]
    assert len(w) == 1 and "700 row(s)" in w[0]
    pd.testing.assert_frame_equal(fl.data, garmin[0].data)


def test_garmin_export_with_windows_line_ends_reads_the_same(tmp_path, garmin):
    log = tmp_path / "crlf.csv"
    log.write_bytes(GARMIN.read_bytes().replace(b"\n", b"\r\n"))
    fl, _ = load_quiet(log)
    pd.testing.assert_frame_equal(fl.data, garmin[0].data)


def test_garmin_unit_it_does_not_know_is_a_schema_error_naming_the_column(tmp_path):
    lines = GARMIN.read_bytes().decode().split("\n")
    units = lines[1].split(",")
    units[6] = "   metres"                    # AltInd
    lines[1] = ",".join(units)
    log = tmp_path / "u.csv"
    log.write_bytes("\n".join(lines).encode())
    with pytest.raises(SchemaError, match="unit 'metres'") as ex:
        load_quiet(log)
    assert ex.value.column == "AltInd"


def test_garmin_altimeter_setting_is_the_qnh_unless_given(garmin):
    """BaroA in use at the take-off (30.18 inHg, set on the apron after the previous flight's
    30.33) and at the landing (30.21 inHg) becomes the departure's and the arrival's QNH, as
    the sidecar's would: the field's elevation under it (the stand's 89.3 m from the GPS) is
    the recorded pressure altitude at rest before the take-off within 3 m (measured 0.5 m; the
    stale 30.33 inHg would be 41 m off).  A QNH given by the user wins, with a note."""
    from flightrecon.geo.atmosphere import field_pressure_altitude_m

    fl = garmin[0]
    assert fl.meta.qnh_departure_hpa == pytest.approx(30.18 * INHG_PA / 100.0, abs=0.01)
    assert fl.meta.qnh_arrival_hpa == pytest.approx(30.21 * INHG_PA / 100.0, abs=0.01)
    d = fl.data
    t = d.t_s.to_numpy()
    rest = float(np.nanmedian(d.baro_alt_m.to_numpy()[t < t[0] + 20.0]))
    assert field_pressure_altitude_m(89.3, fl.meta.qnh_departure_hpa) == pytest.approx(
        rest, abs=3.0)
    assert any(n.startswith("qnh_departure_hpa = 1022.0 hPa: the altimeter setting BaroA")
               for n in fl.meta.ingest.notes)
    mine, _ = load_quiet(GARMIN, meta_overrides={"qnh_departure_hpa": 1013.0})
    assert mine.meta.qnh_departure_hpa == 1013.0
    assert mine.meta.qnh_arrival_hpa == fl.meta.qnh_arrival_hpa
    assert any("1013.0 hPa as given" in n and "1022.0 hPa" in n
               for n in mine.meta.ingest.notes)

"""Every layout and convention of the Garmin family read as recorded, with no mapping (issue #49
items 1, 3, 7; issue #50 item 5).

The real Perspective+ export ``sample_logs/g1000_sr22_LFQA_20220417.csv`` (MIT,
``sample_logs/LICENSE-flightlogstats``) stands for its own variant.  The others have no real
file the project may ship: their rows are generated from the documented layouts
(docs/ingest.md, "Garmin glass-cockpit exports") on one simulated circuit written as the
G1000 writes it (:mod:`flightrecon.sim.glass_cockpit`), then rewritten as each variant would
record it: the older G1000's ``AltB`` ("ft Baro"), no altimeter setting, a normal load recorded
as n, a true track, a variation of the other sign, a GPS height above MSL, the G3X Touch's long
and short names.  Each variant must read back to the channels the G1000 layout gives, and
``info`` must name the variant and each convention with its evidence.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.errors import InputFileError
from flightrecon.ingest import load_flight
from flightrecon.ingest.readers import read_table
from flightrecon.sim.glass_cockpit import glass_cockpit_export, glass_cockpit_text

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_logs" / "g1000_sr22_LFQA_20220417.csv"

#: G3X Touch long names of the columns written (bracket: the unit), after the layout of the
#: GDU 4xx data log (docs/ingest.md); an empty short name stands where the unit writes none
G3X_LONG = {"Lcl Date": "Date (yyyy-mm-dd)", "Lcl Time": "Time (hh:mm:ss)",
            "UTCOfst": "UTC Offset (hh:mm)", "Latitude": "Latitude (deg)",
            "Longitude": "Longitude (deg)", "AltGPS": "GPS Altitude (WGS84 ft)",
            "GPSfix": "GPS Fix Status", "GndSpd": "GPS Ground Speed (kt)",
            "TRK": "GPS Ground Track (deg true)", "HDG": "Magnetic Heading (deg)",
            "AltP": "Pressure Altitude (ft)", "AltInd": "Baro Altitude (ft)",
            "VSpd": "Vertical Speed (ft/min)", "IAS": "Indicated Airspeed (kt)",
            "TAS": "True Airspeed (kt)", "Pitch": "Pitch (deg)", "Roll": "Roll (deg)",
            "LatAc": "Lateral Acceleration (G)", "NormAc": "Normal Acceleration (G)",
            "BaroA": "Baro Setting (inch Hg)", "MagVar": "Magnetic Variation (deg)",
            "OAT": "Outside Air Temp (deg C)"}


@pytest.fixture(scope="module")
def export():
    """One simulated circuit (Baku, WMM variation +6.5 deg, geoid -22 m, QNH 1006 hPa) as the
    G1000 writes it: a table of text cells, and the flight's metadata."""
    from flightrecon.sim import simulate

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = simulate("circuit", 1)
    return glass_cockpit_export(r.log, r.truth, r.meta), r.meta


def _num(ex: pd.DataFrame, c: str) -> np.ndarray:
    return pd.to_numeric(ex[c], errors="coerce").to_numpy(float)


def _cells(v: np.ndarray, fmt: str) -> list[str]:
    return ["" if not np.isfinite(x) else format(x, fmt) for x in v]


def _load(path: Path):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        fl = load_flight(path)
    return fl, [str(x.message) for x in w]


def _write(tmp: Path, name: str, text: str, encoding: str = "utf-8") -> Path:
    p = tmp / name
    p.write_bytes(text.encode(encoding))
    return p


def _recorded(fl) -> dict[str, str]:
    return fl.meta.ingest.recorder["conventions"]


@pytest.fixture(scope="module")
def reference(export, tmp_path_factory):
    """The G1000 layout as the simulator writes it, read: the channels every variant must give."""
    ex, _ = export
    p = _write(tmp_path_factory.mktemp("ref"), "ref.csv", glass_cockpit_text(ex))
    return _load(p)[0]


def _same_channels(fl, ref, tol_alt_m: float = 0.5) -> None:
    a, b = fl.data, ref.data
    assert len(a) == len(b)
    for c, tol in (("heading_deg", 0.051), ("n_norm_g", 1e-9), ("roll_deg", 1e-9),
                   ("baro_alt_m", tol_alt_m), ("gnss_lat_deg", 1e-9)):
        d = a[c].to_numpy(float) - b[c].to_numpy(float)
        if c == "heading_deg":
            d = (d + 180.0) % 360.0 - 180.0
        assert np.nanmax(np.abs(d)) <= tol, c


# ------------------------------------------------------------------------- G1000 family


def test_perspective_export_names_its_variant_and_conventions():
    """The shipped Perspective+ export: each convention decided by its own figures."""
    fl, _ = _load(SAMPLE)
    rec = fl.meta.ingest.recorder
    assert rec["variant"].startswith("G1000 / G1000 NXi / Perspective (GIFD, Cirrus SR22 Turbo)")
    assert "AltInd + BaroA" in rec["variant"]
    conv = rec["conventions"]
    assert conv["NormAc"].startswith("n - 1 (data: median +0.000 g over")
    assert conv["MagVar"].startswith("east positive (data: WMM +1.8 deg")
    assert conv["TRK"].startswith("magnetic (data:")
    assert conv["AltInd"].startswith("indicated (data: at rest")
    assert conv["AltGPS"].startswith("ellipsoid (data: AltGPS - AltMSL median +45.2 m")
    assert rec["recorded_undulation_m"] == pytest.approx(45.2, abs=0.1)
    # identity: the avionics' system id, the airframe's name as its type
    assert fl.meta.aircraft_id == "25B289D04"
    assert rec["aircraft_type"] == "Cirrus SR22 Turbo"


def test_old_g1000_altb_ft_baro_is_read(export, reference, tmp_path):
    """Older G1000 software writes the altitude as ``AltB`` in "ft Baro" (log_version 1.00):
    before issue #49, "missing required channel(s): baro_alt_m"."""
    ex, _ = export
    text = glass_cockpit_text(ex.rename(columns={"AltInd": "AltB"}),
                              airframe_name="Cessna 172S", system_id="24B0000AA")
    lines = text.split("\n")
    units = lines[1].split(",")
    i = [c.strip() for c in lines[2].split(",")].index("AltB")
    units[i] = " ft Baro"
    lines[0] = lines[0].replace('log_version="1.03"', 'log_version="1.00"')
    lines[1] = ",".join(units)
    fl, _ = _load(_write(tmp_path, "altb.csv", "\n".join(lines)))
    _same_channels(fl, reference)
    assert "AltB + BaroA" in fl.meta.ingest.recorder["variant"]
    assert _recorded(fl)["AltB"].startswith("indicated (data:")
    assert fl.meta.aircraft_id == "24B0000AA"


def test_without_altimeter_setting_the_altitude_is_pressure_with_a_warning(export, tmp_path):
    ex, _ = export
    ex = ex.drop(columns=["BaroA"]).copy()
    # the unit recorded the pressure altitude itself (no setting to read it at)
    p = _num(export[0], "AltInd") * 0.3048
    from flightrecon.ingest.garmin import INHG_PA, pressure_altitude_from_indicated

    hp = pressure_altitude_from_indicated(p, _num(export[0], "BaroA") * INHG_PA)
    ex["AltInd"] = _cells(hp / 0.3048, ".1f")
    fl, warns = _load(_write(tmp_path, "nobaro.csv", glass_cockpit_text(ex)))
    assert any("no altimeter setting recorded" in w for w in warns)
    assert _recorded(fl)["AltInd"].startswith("pressure (built-in")
    assert np.nanmax(np.abs(fl.data.baro_alt_m - hp[:len(fl.data)])) < 0.06


def test_normal_load_recorded_as_n_is_found_from_the_data(export, reference, tmp_path):
    ex, _ = export
    ex = ex.copy()
    ex["NormAc"] = _cells(_num(ex, "NormAc") + 1.0, ".2f")
    fl, warns = _load(_write(tmp_path, "n.csv", glass_cockpit_text(ex)))
    _same_channels(fl, reference)
    assert _recorded(fl)["NormAc"].startswith("n (data: median +1.0")
    assert any("recorded as n, not n - 1 as the built-in convention" in w for w in warns)


def test_variation_of_the_other_sign_is_found_against_the_model(export, reference, tmp_path):
    """A variation written west positive: the WMM (+6.5 deg there) and the GPS track say so."""
    ex, _ = export
    ex = ex.copy()
    ex["MagVar"] = _cells(-_num(ex, "MagVar"), ".1f")
    fl, warns = _load(_write(tmp_path, "west.csv", glass_cockpit_text(ex)))
    _same_channels(fl, reference)
    assert _recorded(fl)["MagVar"].startswith("west positive (sign changed) (data: WMM +6.")
    assert any("west positive" in w for w in warns)


def test_true_track_is_found_from_the_gps_positions(export, reference, tmp_path):
    """TRK written true (the NAV angle set to TRUE): the positions' track says so, and HDG is
    taken on the same reference."""
    ex, _ = export
    ex = ex.copy()
    ex["TRK"] = _cells(np.mod(_num(ex, "TRK") + _num(ex, "MagVar"), 360.0), ".1f")
    ex["HDG"] = _cells(np.mod(_num(ex, "HDG") + _num(ex, "MagVar"), 360.0), ".1f")
    fl, warns = _load(_write(tmp_path, "true.csv", glass_cockpit_text(ex)))
    _same_channels(fl, reference, tol_alt_m=0.5)
    assert _recorded(fl)["TRK"].startswith("true (data:")
    assert any("the track is true, not magnetic" in w for w in warns)
    gv = np.degrees(np.arctan2(fl.data.gnss_ve_mps, fl.data.gnss_vn_mps))
    rv = np.degrees(np.arctan2(reference.data.gnss_ve_mps, reference.data.gnss_vn_mps))
    fast = np.hypot(fl.data.gnss_vn_mps, fl.data.gnss_ve_mps) > 20
    assert np.nanmax(np.abs(((gv - rv + 180) % 360 - 180)[fast])) < 0.11


def test_gps_height_above_msl_is_found_from_altmsl(export, tmp_path):
    ex, meta = export
    ex = ex.copy()
    ex["AltGPS"] = ex["AltMSL"]
    fl, warns = _load(_write(tmp_path, "msl.csv", glass_cockpit_text(ex)))
    assert _recorded(fl)["AltGPS"].startswith("msl (data: AltGPS - AltMSL median +0.0 m")
    assert fl.meta.gnss_alt_datum == "msl"
    assert any("above the msl, not the ellipsoid its unit 'ft wgs' says" in w for w in warns)


# --------------------------------------------------------------------------- G3X Touch


def _g3x_text(ex: pd.DataFrame, meta) -> str:
    """The circuit as a G3X Touch writes it: information line with the registration, long
    names with units, short names (some empty), a true track, a pressure altitude, n."""
    from flightrecon.ingest.garmin import INHG_PA, pressure_altitude_from_indicated

    g = ex.copy()
    g["TRK"] = _cells(np.mod(_num(ex, "TRK") + _num(ex, "MagVar"), 360.0), ".1f")
    g["NormAc"] = _cells(_num(ex, "NormAc") + 1.0, ".2f")
    hp = pressure_altitude_from_indicated(_num(ex, "AltInd") * 0.3048,
                                          _num(ex, "BaroA") * INHG_PA) / 0.3048
    g["AltP"] = _cells(hp, ".0f")
    g["Latitude"] = [("+" + x) if x and not x.startswith("-") else x for x in g["Latitude"]]
    cols = [c for c in G3X_LONG if c in g.columns]
    short = ["" if c in ("BaroA", "GPSfix") else c for c in cols]
    info = ('#airframe_info,log_version="1.00",log_content_version="1.02",product="GDU 460",'
            'aircraft_ident="N123AB",unit_software_part_number="006-B1727-40",'
            'software_version="9.51",system_id="6000ABCD01234",unit="PFD1"')
    rows = [",".join(r) for r in g[cols].to_numpy(dtype=str)]
    return "\r\n".join([info, ",".join(G3X_LONG[c] for c in cols), ",".join(short), *rows]) \
        + "\r\n"


def test_g3x_touch_layout_reads_as_the_g1000_layout(export, reference, tmp_path):
    """Before issue #49: "line 2 should be the units line".  Long names with units, short
    names with blanks, CRLF, a signed latitude; the track true, the normal load n and the
    pressure altitude recorded: decided from the data and the names, the same channels come
    out (the pressure altitude in whole feet: 0.16 m)."""
    ex, meta = export
    p = _write(tmp_path, "log_20260101_100000_UBBB.csv", _g3x_text(ex, meta))
    raw = read_table(p)
    assert raw.layout == "long and short names" and raw.header_line == 3
    assert raw.units["TRK"] == "deg true" and raw.long_names["AltP"] == "Pressure Altitude (ft)"
    assert "Baro Setting" in raw.columns and "GPS Fix Status" in raw.columns
    fl, warns = _load(p)
    _same_channels(fl, reference, tol_alt_m=0.16)
    rec = fl.meta.ingest.recorder
    assert rec["variant"].startswith("G3X / G3X Touch (GDU 460)")
    assert "altitude from AltP" in rec["variant"]
    conv = rec["conventions"]
    assert conv["NormAc"].startswith("n (data:") and conv["TRK"].startswith("true (data:")
    assert conv["HDG"].startswith("magnetic (label")
    assert not [w for w in warns if "built-in convention" in w]
    assert fl.meta.aircraft_id == "N123AB" and rec["registration"] == "N123AB"


def test_long_names_only_layout_is_read(export, tmp_path):
    """A unit writing its long names and no short names (the data from line 3)."""
    ex, meta = export
    lines = _g3x_text(ex, meta).split("\r\n")
    p = _write(tmp_path, "long.csv", "\r\n".join([lines[0], lines[1], *lines[3:]]))
    raw = read_table(p)
    assert raw.layout == "long names" and raw.header_line == 2
    assert "Normal Acceleration" in raw.columns
    fl, _ = _load(p)
    assert fl.meta.ingest.recorder["conventions"]["Normal Acceleration"].startswith("n (")


# ------------------------------------------------------------------- the information line


def test_quoted_information_line_of_a_resaved_export(tmp_path):
    """A spreadsheet's re-save quotes each field of the information line (the realdata TEST1
    export's first line, as it is): the keys are read through the quotes."""
    line = ('#airframe_info," log_version=""1.03"""," Product=""GIFD"""," airframe_name='
            '""Cirrus SR22 Turbo"""," system_id=""25B289D04""", mode=NORMAL, ,,,')
    text = SAMPLE.read_text(encoding="utf-8").split("\n")
    p = _write(tmp_path, "quoted.csv", "\n".join([line, *text[1:400]]) + "\n")
    raw = read_table(p)
    assert raw.preamble["airframe_name"] == "Cirrus SR22 Turbo"
    assert raw.preamble["system_id"] == "25B289D04" and raw.preamble["log_version"] == "1.03"
    assert raw.layout == "units line" and len(raw.columns) == 80


def test_sidecar_aircraft_id_wins_over_the_export(tmp_path):
    text = SAMPLE.read_text(encoding="utf-8").split("\n")
    p = _write(tmp_path, "x.csv", "\n".join(text[:800]) + "\n")
    (tmp_path / "x.meta.toml").write_text('[flight]\naircraft_id = "F-HXYZ"\n')
    fl, _ = _load(p)
    assert fl.meta.aircraft_id == "F-HXYZ"
    assert fl.meta.ingest.recorder["system_id"] == "25B289D04"


# ----------------------------------------------------------------- legacy 8-bit encodings


def test_windows_1252_header_is_read_with_a_warning(tmp_path):
    """A Windows tool's CSV with a degree sign in a header: before issue #50 refused as "not
    valid UTF-8"; now read, the warning naming the encoding and the byte."""
    text = ("t_s,n_long_g,n_lat_g,n_norm_g,roll_deg,pitch_deg,heading_deg,tas_mps,baro_alt_m,"
            "OAT (\u00b0C)\n")
    text += "".join(f"{i * 0.5},0,0,1,0,0,90,60,1000,15\n" for i in range(400))
    p = _write(tmp_path, "w.csv", text, "cp1252")
    raw = read_table(p)
    assert "OAT (\u00b0C)" in raw.columns
    assert "read as Windows-1252 / Latin-1 (ISO-8859-1)" in raw.warnings[0]
    assert "0xB0" in raw.warnings[0] and "line 1" in raw.warnings[0]


def test_windows_1252_only_characters_name_windows_1252(tmp_path):
    text = "a,b\n1,2\n3,4 \u20ac\n"        # the euro sign: 0x80 in Windows-1252, not Latin-1
    raw = read_table(_write(tmp_path, "e.csv", text, "cp1252"))
    assert "read as Windows-1252 (" in raw.warnings[0]


def test_mixed_encodings_and_c1_bytes_are_refused_with_the_offset(tmp_path):
    p = _write(tmp_path, "m.csv", "a,b\n1,\u00e9\n", "utf-8")
    p.write_bytes(p.read_bytes() + b"2,\xe9\n")
    with pytest.raises(InputFileError, match=r"byte offset 11 \(line 3\).*mixed encodings"):
        read_table(p)
    q = tmp_path / "c.csv"
    q.write_bytes(b"a,b\n1,2\n3,\x9d\n")
    with pytest.raises(InputFileError, match=r"byte 0x9D at byte offset 10 \(line 3\)"):
        read_table(q)


# ------------------------------------------------------------- whole-second time stamps


def test_jittering_whole_second_stamps_are_re_timed_at_the_rows_period():
    """Rows exactly 1 s apart (a GPS-timed 1 Hz series, one row lost after row 2000) stamped
    by a clock 1.8 % fast that jitters across the second: a repeated second now and then, a
    skipped one.  Re-timed at the period the GPS motion gives, the rows are 1 s apart again
    (2 s across the lost row), placed on their stamps on average; without a period, at the
    stamps' mean.  A coarse clock (4 rows a second, no skipped second) is left alone."""
    from flightrecon.ingest.garmin_time import motion_period_s, motion_rows, regular_rows

    rng = np.random.default_rng(7)
    k = np.arange(3000.0)
    k[2000:] += 1.0                                        # one row lost
    clock = 1.3e9 + 0.3 + 1.018 * k + 0.4 * np.sin(k / 7.0) + rng.normal(0.0, 0.1, k.size)
    stamps = np.floor(clock).astype(np.int64) * 1_000_000_000
    d = np.diff(stamps) / 1e9
    assert (d == 0).sum() > 30 and (d == 2).sum() > 30
    # a straight flight at 60 m/s north: the motion gives the 1 s period
    lat = 40.0 + np.degrees(60.0 * k / 6_371_000.0)
    period = motion_period_s(lat, np.full(k.size, 50.0), np.full(k.size, 60.0))
    assert period == pytest.approx(1.0, abs=1e-3)
    between = motion_rows(lat, np.full(k.size, 50.0), np.full(k.size, 60.0), period)
    t, note = regular_rows(stamps, period, between)
    assert note is not None and "GPS motion's (1.0000 s" in note and "repeated" in note
    steps = np.diff(t) / 1e9
    assert np.allclose(steps, np.diff(k) * period, atol=1e-6)      # the lost row found
    assert abs(np.mean(t / 1e9 - (stamps / 1e9 + 0.5))) < 0.01
    t2, note2 = regular_rows(stamps)
    assert note2 is not None and "the stamps' mean" in note2
    assert np.median(np.diff(t2)) / 1e9 == pytest.approx(1.018, abs=0.01)
    coarse = (1.3e9 + np.floor(np.arange(3000) / 4.0)).astype(np.int64) * 1_000_000_000
    same, none = regular_rows(coarse, 1.0)
    assert none is None and np.array_equal(same, coarse)


def test_one_column_files_with_a_windows_1252_header_are_read(tmp_path):
    """Every CSV reader path: a folder of one-column files whose header has a degree sign in
    Windows-1252 (before: the file left out as not numeric)."""
    d = tmp_path / "rec"
    d.mkdir()
    for name in ("Pitch", "Roll"):
        (d / f"{name}.csv").write_bytes(f"{name} (\u00b0)\n".encode("cp1252")
                                        + b"".join(f"{i * 0.1:.1f}\n".encode() for i in range(50)))
    raw = read_table(d)
    assert set(raw.columns) == {"Pitch", "Roll"} and raw.n_rows == 50
    assert raw.columns["Roll"][10] == pytest.approx(1.0)


def test_standalone_instrument_info_line_and_utc_columns(export, reference, tmp_path):
    """A standalone instrument's log (``#info`` line, the names twice, UTC date and time
    columns and no local time, after a public converter writing that format): read in UTC."""
    ex, meta = export
    lines = _g3x_text(ex, meta).split("\r\n")
    swap = {"Date (yyyy-mm-dd)": "UTC Date", "Time (hh:mm:ss)": "UTC Time",
            "Lcl Date": "UTC Date", "Lcl Time": "UTC Time"}
    names = [swap.get(c, c) for c in lines[2].split(",")]
    longs = [swap.get(c, c) for c in lines[1].split(",")]
    keep = [i for i, c in enumerate(names) if c != "UTCOfst"]
    rows = [",".join(r.split(",")[i] for i in keep) for r in lines[3:] if r]
    info = '#info,log_version="1.00",software_part_number="006-B2304-23",software_version="6.40"'
    p = _write(tmp_path, "g5.csv", "\n".join([info, ",".join(longs[i] for i in keep),
                                                ",".join(names[i] for i in keep), *rows]) + "\n")
    raw = read_table(p)
    assert raw.layout == "long and short names" and "UTC Time" in raw.columns
    fl, _ = _load(p)
    assert fl.meta.epoch_utc == reference.meta.epoch_utc       # the export's offset is +00:00
    _same_channels(fl, reference, tol_alt_m=0.16)
    assert fl.meta.aircraft_id is None                         # nothing names the aircraft

"""The Sabziev method adapter on a synthetic, truth-consistent CleanFlight."""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import brentq
from test_sabziev_flights import synthetic_flight

from flightrecon.errors import FlightReconWarning, MetadataError, SchemaError
from flightrecon.geo.atmosphere import field_pressure_altitude_m
from flightrecon.geo.frames import output_plane
from flightrecon.geo.kinematics import load_factors_from_acceleration
from flightrecon.methods.sabziev.method import run_sabziev
from flightrecon.methods.sabziev.result import LIFTOFF_SD_M
from flightrecon.types import CleanFlight, FlightMeta, FlightPhases, Position

PAD_S = 20.0
DEP = Position(40.46, 50.05, 10.0)
QNH_DEP, QNH_ARR = 1020.0, 1005.0


def clean_flight(T=900.0, rate=8.0, wind=True, seed=3, **sensors):
    """A CleanFlight whose recorded channels are consistent with a synthetic truth.

    ``PAD_S`` seconds of ground samples before lift-off (t = 0) and after touchdown (t = T);
    loads from the truth acceleration through the exact inverse of the kinematic formula;
    baro = pressure altitude (departure QNH 1020 hPa); the arrival airfield at the truth end
    point, its elevation chosen so that its pressure altitude under QNH 1005 hPa equals the
    truth end height (the pressure-consistent vertical end point of the adapter).
    """
    f = synthetic_flight(T=T, rate_hz=rate, seed=seed, **sensors)
    n_pad = int(PAD_S * rate)
    n = len(f["t"])
    dt = 1.0 / rate
    t = np.arange(-n_pad, n + n_pad) * dt
    sl = slice(n_pad, n_pad + n)

    def padded(x, before, after):
        return np.concatenate([np.full(n_pad, before), x, np.full(n_pad, after)])

    hp_dep = field_pressure_altitude_m(DEP.elev_m, QNH_DEP)
    a_ned = np.vstack([np.zeros((n_pad, 3)), f["a_ned"], np.zeros((n_pad, 3))])
    hdg_deg = padded(np.degrees(f["hdg"]), np.degrees(f["hdg"][0]), np.degrees(f["hdg"][-1]))
    baro = padded(f["h"] + hp_dep, hp_dep, f["h"][-1] + hp_dep)
    roll = 10.0 * np.sin(t / 50.0)
    pitch = 2.0 + np.cos(t / 70.0)
    loads = load_factors_from_acceleration(a_ned, roll, pitch, hdg_deg, lat_deg=DEP.lat_deg,
                                           h_m=baro)
    grid = pd.DataFrame({"t_s": t, "n_long_g": loads[:, 0], "n_lat_g": loads[:, 1],
                         "n_norm_g": loads[:, 2], "roll_deg": roll, "pitch_deg": pitch,
                         "heading_deg": hdg_deg, "tas_mps": padded(f["tas"], 0.0, 0.0),
                         "baro_alt_m": baro})
    if wind:
        w = f["wind"][0]
        grid["wind_speed_mps"] = np.hypot(*w)
        grid["wind_from_deg"] = (np.degrees(np.arctan2(w[1], w[0])) + 180.0) % 360.0
    meta0 = FlightMeta(departure=DEP, qnh_departure_hpa=QNH_DEP, qnh_arrival_hpa=QNH_ARR,
                       geoid_undulation_m=0.0)
    plane = output_plane(meta0)
    y_T = -f["end"][2]
    elev = brentq(lambda e: field_pressure_altitude_m(e, QNH_ARR) - hp_dep - y_T, -500, 3000,
                  xtol=1e-9)
    lat, lon, _ = plane.inverse(f["end"][1], f["end"][0], elev + (plane.h0_m - DEP.elev_m))
    meta = replace(meta0, arrival=Position(float(lat), float(lon), float(elev)))
    phases = FlightPhases(liftoff_t_s=0.0, touchdown_t_s=float(f["t"][-1]),
                          starts_airborne=False, ends_airborne=False,
                          liftoff_velocity_ned_mps=tuple(float(x) for x in f["v0"]))
    clean = CleanFlight(grid=grid, rate_hz=rate, gnss=pd.DataFrame(), radar=pd.DataFrame(),
                        meta=meta, phases=phases)
    return clean, f, sl, a_ned


def test_adapter_matches_the_end_point_and_reports():
    """Converged on all axes, the track ends on the arrival point (< 1 m per axis; tolerance of
    the root finder 1 mm plus the ENU round trip of the arrival position, ~cm), NaN outside
    lift-off..touchdown, and the summary carries k, per-axis reports and the history.  The
    paper's policy: the vertical in pressure terms (the arrival elevation here is chosen to be
    pressure-consistent, see :func:`clean_flight`); the default policy is tested in
    tests/test_sabziev_stable.py."""
    clean, f, sl, _ = clean_flight()
    res = run_sabziev(clean, policy="paper")
    tr, s = res.track, res.summary
    assert res.name == "sabziev" and s["converged"] and s["mode"] == "boundary-value"
    # the one builder's columns (flightrecon/tracks.py): the plane position, the fusion's
    # height above the departure airfield, the plane's up, WGS-84, the velocities
    assert list(tr.columns[:11]) == ["t_s", "sabziev_north_m", "sabziev_east_m",
                                     "sabziev_height_m", "sabziev_up_m", "sabziev_lat_deg",
                                     "sabziev_lon_deg", "sabziev_alt_m", "sabziev_vn_mps",
                                     "sabziev_ve_mps", "sabziev_vu_mps"]
    inside = np.zeros(len(tr), bool)
    inside[sl] = True
    assert tr.loc[inside].notna().all().all()
    assert tr.loc[~inside, "sabziev_north_m"].isna().all()
    end = s["end_point"]
    last = tr.loc[inside].iloc[-1]
    assert abs(last["sabziev_north_m"] - end["north_m"]) < 1.0
    assert abs(last["sabziev_east_m"] - end["east_m"]) < 1.0
    assert abs(last["sabziev_height_m"] - end["up_pressure_m"]) < 1.0
    for axis in ("x", "y", "z"):
        a = s["axes"][axis]
        assert a["converged"] and a["branch"] == "negative" and abs(a["residual_m"]) < 1e-3
        assert a["iterations"] >= 1 and a["reason"]
        assert len(s["history"][axis]) >= 1
    assert s["wind_modelled"] is True
    assert all(np.isfinite([s["k1"], s["k2"], s["k3"]]))
    # against truth: vertical at the baro level (bias 5 m + noise 2 m; 3x margin on the
    # measured RMS), horizontal within the dead-reckoning error budget of the synthetic sensors
    # (1 % airspeed scale + 0.5 deg heading bias over 900 s: ~1 km uncorrected, measured RMS
    # after the end-point fit ~0.1 km; bound 0.5 km)
    up = tr["sabziev_height_m"].to_numpy()[sl]
    assert np.sqrt(np.mean((up - f["truth"][:, 1]) ** 2)) < 30.0
    north = tr["sabziev_north_m"].to_numpy()[sl]
    east = tr["sabziev_east_m"].to_numpy()[sl]
    assert np.sqrt(np.mean((north - f["truth"][:, 0]) ** 2)) < 500.0
    assert np.sqrt(np.mean((east - f["truth"][:, 2]) ** 2)) < 500.0


def test_default_acceleration_path_equals_the_override():
    """Loads -> kinematic acceleration inside the adapter gives the same track as the exact
    acceleration passed in (the loads were built with the exact inverse: agreement 1e-6 m)."""
    clean, _, _, a_ned = clean_flight(T=300.0)
    a = run_sabziev(clean).track
    b = run_sabziev(clean, acceleration_ned=a_ned).track
    np.testing.assert_allclose(a.to_numpy(), b.to_numpy(), rtol=0, atol=1e-6, equal_nan=True)


def test_no_wind_channel_is_reported():
    """Without a wind channel the result says 'wind unmodelled' (summary and a warning)."""
    clean, _, _, _ = clean_flight(T=300.0, wind=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = run_sabziev(clean)
    assert res.summary["wind_modelled"] is False
    assert any("wind unmodelled" in w for w in res.summary["warnings"])
    assert any(issubclass(w.category, FlightReconWarning) and "wind unmodelled" in str(w.message)
               for w in caught)


def test_initial_value_mode_with_fleet_spread():
    """k given, no arrival: the same track as the boundary-value fit (1e-9 m), plus standard
    deviation columns from the exact sensitivities: zero at lift-off, growing, finite.  (The
    paper's policy: with the default ``stable`` one the boundary-value reference is made
    consistent with the end point, which an initial-value run without one cannot do.)"""
    clean, _, sl, _ = clean_flight(T=600.0)
    bv = run_sabziev(clean, policy="paper")
    s = bv.summary
    k = (s["k1"], s["k2"], s["k3"])
    clean_iv = replace(clean, meta=replace(clean.meta, arrival=None))
    iv = run_sabziev(clean_iv, k=k, k_sd=(0.1 * abs(k[0]), 0.1 * abs(k[1]), 0.1 * abs(k[2])),
                     policy="paper")
    assert iv.summary["mode"] == "initial-value" and iv.summary["converged"]
    for c in ("sabziev_north_m", "sabziev_east_m", "sabziev_up_m"):
        np.testing.assert_allclose(iv.track[c], bv.track[c], rtol=0, atol=1e-9, equal_nan=True)
    for c in ("sabziev_north_sd_m", "sabziev_east_sd_m", "sabziev_up_sd_m", "sabziev_vn_sd_mps"):
        sd = iv.track[c].to_numpy()[sl]
        assert np.all(np.isfinite(sd)) and np.all(sd >= 0)
        # horizontally the lift-off point's own sd (not given: the airfield's reference point)
        # is the floor; the spread from k adds to it in quadrature
        start = LIFTOFF_SD_M if c in ("sabziev_north_sd_m", "sabziev_east_sd_m") else 0.0
        assert sd[0] == start and sd[-1] > start


def test_record_cut_in_the_air():
    """A record that starts and ends airborne uses all its samples; the lift-off velocity then
    comes from the air data (reported).  The vertical fit converges; a horizontal axis may find
    no root (the air-derived start velocity is ~1.6 m/s off with the 1 % airspeed error, and a
    wrong start velocity often moves both ends of F(k) to the same side: measured on six sensor
    error combinations, the north axis never had a root).  Either way each axis says so: with
    the default policy a finite track that meets the end point (a root, or the linear
    correction with the reason), with the paper's a finite track or NaN with a reason."""
    clean, _, sl, _ = clean_flight(T=600.0)
    g = clean.grid.iloc[sl].reset_index(drop=True)
    ph = FlightPhases(float("nan"), float("nan"), True, True, (float("nan"),) * 3)
    stable = run_sabziev(replace(clean, grid=g, phases=ph))
    assert stable.summary["converged"]
    for axis, col in (("x", "sabziev_north_m"), ("z", "sabziev_east_m")):
        a = stable.summary["axes"][axis]
        assert stable.track[col].notna().all()
        assert a["converged"] or (a["fallback"] and "no root" in a["reason"])
    res = run_sabziev(replace(clean, grid=g, phases=ph), policy="paper")
    s = res.summary
    assert s["interval_s"] == [float(g["t_s"].iloc[0]), float(g["t_s"].iloc[-1])]
    assert any("lift-off velocity not known" in w for w in s["warnings"])
    assert s["axes"]["y"]["converged"] and res.track["sabziev_up_m"].notna().all()
    for axis, col in (("x", "sabziev_north_m"), ("z", "sabziev_east_m")):
        a = s["axes"][axis]
        if a["converged"]:
            assert res.track[col].notna().all()
        else:
            assert res.track[col].isna().all() and "no root" in a["reason"]
            assert s["converged"] is False


def test_bad_input_raises_project_errors():
    """No departure / neither arrival nor k -> MetadataError; missing channel -> SchemaError."""
    clean, _, _, _ = clean_flight(T=120.0)
    with pytest.raises(MetadataError):
        run_sabziev(replace(clean, meta=replace(clean.meta, departure=None)))
    with pytest.raises(MetadataError):
        run_sabziev(replace(clean, meta=replace(clean.meta, arrival=None)))
    with pytest.raises(SchemaError):
        run_sabziev(replace(clean, grid=clean.grid.drop(columns=["tas_mps"])))


def test_field_pressure_altitude():
    """Standard QNH gives the elevation (ISA round trip, 1e-6 m); near sea level the pressure
    altitude falls by 8.2..8.5 m per hPa of QNH (ISA: R T0 / (g0 p0) * 100 = 8.32 m/hPa)."""
    assert field_pressure_altitude_m(123.0, None) == pytest.approx(123.0, abs=1e-6)
    assert field_pressure_altitude_m(123.0, 1013.25) == pytest.approx(123.0, abs=1e-6)
    slope = field_pressure_altitude_m(0.0, 1014.25) - field_pressure_altitude_m(0.0, 1013.25)
    assert -8.5 < slope < -8.2
    with pytest.raises(MetadataError):
        field_pressure_altitude_m(0.0, 13.0)


def test_pipeline_calls_the_adapter():
    """The pipeline's method table reaches run_sabziev with its (k, k_sd) keywords."""
    from flightrecon.pipeline import ReconstructSettings, run_method

    clean, _, _, _ = clean_flight(T=300.0)
    res = run_method("sabziev", clean, ReconstructSettings())
    assert res.summary["converged"] and "sabziev_north_m" in res.track.columns


def test_liftoff_point_and_velocity_overrides():
    """A lift-off point 1 km north of the departure airfield shifts the whole (initial-value)
    track by 1 km north, output still relative to the departure airfield (ENU round trip of
    the point ~1e-6 m; tolerance 1e-3 m; the paper's policy, whose boundary-value track is an
    initial-value track).  A given lift-off velocity is used as is; a
    malformed one is a ValidationError."""
    from flightrecon.errors import ValidationError

    clean, f, sl, _ = clean_flight(T=600.0)
    bv = run_sabziev(clean, liftoff_velocity_ned=tuple(f["v0"]), policy="paper")
    assert bv.summary["liftoff_velocity_ned_mps"] == pytest.approx(list(f["v0"]))
    k = (bv.summary["k1"], bv.summary["k2"], bv.summary["k3"])
    plane = output_plane(clean.meta)
    lat, lon, _ = plane.inverse(0.0, 1000.0, 0.0)
    lift = Position(float(lat), float(lon), DEP.elev_m)
    iv = run_sabziev(clean, k=k, liftoff=lift, liftoff_velocity_ned=tuple(f["v0"]),
                     policy="paper")
    d_north = (iv.track["sabziev_north_m"] - bv.track["sabziev_north_m"]).to_numpy()[sl]
    d_east = (iv.track["sabziev_east_m"] - bv.track["sabziev_east_m"]).to_numpy()[sl]
    np.testing.assert_allclose(d_north, 1000.0, atol=1e-3)
    np.testing.assert_allclose(d_east, 0.0, atol=1e-3)
    with pytest.raises(ValidationError):
        run_sabziev(clean, liftoff_velocity_ned=(1.0, np.nan, 0.0))


def test_accuracy_study_on_one_simulated_flight():
    """Reduced-count run of scripts/sabziev_accuracy.py (one circuit flight with a wind channel,
    seed 1): the fit converges, ends on its end point, and beats uncorrected air dead reckoning
    on both horizontal axes (full-size study, 5 flights: 354/644 m vs 587/893 m mean RMS; seed 1:
    341/684 vs 1085/1257 m, so the ordering is not marginal).  The vertical stays within 30 m of
    the truth (measured RMS 7.7 m: baro noise plus the pressure-vs-geometric difference of the
    simulated +6 K atmosphere over ~450 m of height)."""
    from _scripts import load_script

    mod = load_script("sabziev_accuracy")
    f = mod.one_flight("circuit", {"wind_hz": 1.0}, 1)
    s = f["summary_a"]
    assert s["converged"]
    assert all(abs(v) < 1.0 for v in s["end_residual_m"].values())
    sab, dr = f["errors"][mod.METHODS[0]], f["errors"]["air DR"]
    for ax in ("north", "east"):
        assert sab[ax][0] < dr[ax][0]
    assert sab["up"][0] < 30.0

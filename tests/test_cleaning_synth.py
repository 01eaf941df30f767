"""A synthetic traffic circuit with consistent loads, used by the signals-layer tests.

The trajectory is built from analytic accelerations (a (1 - cos) bump for every change of
vertical speed, constant along-track accelerations on the runway, coordinated 3 deg/s turns),
integrated on a 64 Hz base; the recorded load factors are the exact inverse of the project's
kinematics (:func:`flightrecon.geo.kinematics.load_factors_from_acceleration`, itself tested
against closed forms in ``test_kinematics.py``), then sampled at recorder rates, with seeded
noise and quantisation.  Truth: lift-off at 65 s, touchdown at ``TD_S``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.geo.frames import TangentPlane
from flightrecon.geo.kinematics import load_factors_from_acceleration
from flightrecon.types import Flight, FlightMeta, Position

LIFTOFF_S = 65.0
FIELD_PALT_M = 100.0
DEPARTURE = Position(45.0, 10.0, 100.0)
STATION = Position(45.05, 10.05, 120.0)
_FLARE_START_S = 376.0 + (600.0 - 10.5 - 12.25) / 3.5
TD_S = _FLARE_START_S + 6.0
END_S = TD_S + 65.0
BASE_HZ = 64


def _bump(t, t0, width, total):
    """Acceleration of a (1 - cos) bump over [t0, t0 + width] changing a speed by ``total``."""
    u = (t - t0) / width
    inside = (u >= 0) & (u < 1)
    return np.where(inside, total / width * (1 - np.cos(2 * np.pi * u)), 0.0)


def _smoothstep(t, t0, t1):
    u = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return u * u * (3 - 2 * u)


def truth_circuit(wind_ne=(0.0, 0.0)) -> pd.DataFrame:
    """Truth on the 64 Hz base: t_s, north/east/up, vn/ve/vu, a_n/a_e/a_d, attitude, tas."""
    t = np.arange(int(END_S * BASE_HZ) + 1) / BASE_HZ
    dt = 1.0 / BASE_HZ
    # along-track acceleration
    a_t = np.where((t >= 30) & (t < LIFTOFF_S), 2.0, 0.0)
    a_t += np.where((t >= 270) & (t < 290), -0.5, 0.0)
    a_t += np.where((t >= TD_S) & (t < TD_S + 25), -2.0, 0.0)
    a_t += np.where((t >= TD_S + 25) & (t < TD_S + 35), -1.0, 0.0)
    V = np.concatenate([[0.0], np.cumsum(0.5 * (a_t[1:] + a_t[:-1])) * dt])
    V = np.maximum(V, 0.0)
    # turn rate: two 180 deg turns at 3 deg/s
    rate = np.where(((t >= 200) & (t < 260)) | ((t >= 300) & (t < 360)), np.radians(3.0), 0.0)
    psi = np.radians(20.0) + np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1])) * dt])
    # vertical
    a_up = (_bump(t, LIFTOFF_S, 6.0, 5.0) + _bump(t, 185.0, 6.0, -5.0) + _bump(t, 370.0, 6.0, -3.5)
            + _bump(t, _FLARE_START_S, 5.0, 2.5) + _bump(t, TD_S, 0.25, 1.0))
    vu = np.concatenate([[0.0], np.cumsum(0.5 * (a_up[1:] + a_up[:-1])) * dt])
    vu[t >= TD_S + 0.25] = 0.0
    up = np.concatenate([[0.0], np.cumsum(0.5 * (vu[1:] + vu[:-1])) * dt])
    up[t >= TD_S] = 0.0
    up = np.maximum(up, 0.0)
    vn, ve = V * np.cos(psi), V * np.sin(psi)
    a_n = a_t * np.cos(psi) - V * rate * np.sin(psi)
    a_e = a_t * np.sin(psi) + V * rate * np.cos(psi)
    north = np.concatenate([[0.0], np.cumsum(0.5 * (vn[1:] + vn[:-1])) * dt])
    east = np.concatenate([[0.0], np.cumsum(0.5 * (ve[1:] + ve[:-1])) * dt])
    # attitude
    gamma = np.degrees(np.arctan2(vu, np.maximum(V, 1.0)))
    rot = 8.0 * _smoothstep(t, 62.0, LIFTOFF_S)
    alpha_air = 8.0 - 3.0 * _smoothstep(t, LIFTOFF_S, LIFTOFF_S + 6.0)
    airborne = (t >= LIFTOFF_S) & (t < TD_S)
    pitch = np.where(t < LIFTOFF_S, rot, gamma + alpha_air)
    pitch = np.where(t >= TD_S, 5.0 * (1 - _smoothstep(t, TD_S + 1.0, TD_S + 4.0)), pitch)
    roll = np.degrees(np.arctan(V * rate / 9.81))
    wn, we = wind_ne
    tas = np.hypot(vn - wn, ve - we)
    return pd.DataFrame({"t_s": t, "north_m": north, "east_m": east, "up_m": up, "vn_mps": vn,
                         "ve_mps": ve, "vu_mps": vu, "a_n": a_n, "a_e": a_e, "a_d": -a_up,
                         "roll_deg": roll, "pitch_deg": pitch,
                         "heading_deg": np.degrees(psi) % 360.0, "tas_mps": tas,
                         "airborne": airborne})


def _q(x, step):
    return np.round(x / step) * step


def synthetic_flight(seed: int = 0, *, wind_ne=(0.0, 0.0), noise: bool = True,
                     wind_channel: bool = False, gnss_offset_s: float = 0.0
                     ) -> tuple[Flight, pd.DataFrame]:
    """A multi-rate canonical log of the circuit (16 Hz loads/attitude, 8 Hz TAS, 4 Hz baro,
    1 Hz GNSS at ``k + gnss_offset_s``, radar every 4 s) and the 64 Hz truth."""
    rng = np.random.default_rng(seed)
    tr = truth_circuit(wind_ne)
    a = tr[["a_n", "a_e", "a_d"]].to_numpy()
    h = FIELD_PALT_M + tr["up_m"].to_numpy()
    n = load_factors_from_acceleration(a, tr["roll_deg"], tr["pitch_deg"], tr["heading_deg"],
                                       lat_deg=DEPARTURE.lat_deg, h_m=h)
    t16 = np.arange(int(END_S * 16) + 1) / 16.0
    idx = np.round(t16 * BASE_HZ).astype(int)

    def noisy(x, sd, step):
        return _q(x + (rng.normal(0, sd, x.shape) if noise else 0.0), step)

    df = pd.DataFrame({"t_s": t16})
    df["n_long_g"] = noisy(n[idx, 0], 0.003, 0.001)
    df["n_lat_g"] = noisy(n[idx, 1], 0.003, 0.001)
    df["n_norm_g"] = noisy(n[idx, 2], 0.003, 0.001)
    df["roll_deg"] = noisy(tr["roll_deg"].to_numpy()[idx], 0.05, 0.01)
    df["pitch_deg"] = noisy(tr["pitch_deg"].to_numpy()[idx], 0.05, 0.01)
    df["heading_deg"] = noisy(tr["heading_deg"].to_numpy()[idx], 0.05, 0.1) % 360.0
    def every(k):
        return (np.arange(len(t16)) % k) == 0

    tas = noisy(tr["tas_mps"].to_numpy()[idx], 0.3, 0.1)
    df["tas_mps"] = np.where(every(2), np.maximum(tas, 0.0), np.nan)
    df["baro_alt_m"] = np.where(every(4), noisy(h[idx], 1.0, 0.3048), np.nan)
    if wind_channel:
        wn, we = wind_ne
        spd = np.hypot(wn, we)
        frm = (np.degrees(np.arctan2(-we, -wn)) % 360.0)
        df["wind_speed_mps"] = np.where(every(16), spd, np.nan)
        df["wind_from_deg"] = np.where(every(16), frm, np.nan)
    # GNSS at 1 Hz (own times), radar every 4 s
    tg = np.arange(0.0, END_S - 1.0, 1.0) + gnss_offset_s
    tp = TangentPlane(DEPARTURE.lat_deg, DEPARTURE.lon_deg, DEPARTURE.elev_m)
    tt = tr["t_s"].to_numpy()
    ng = np.interp(tg, tt, tr["north_m"]) + (rng.normal(0, 3, len(tg)) if noise else 0)
    eg = np.interp(tg, tt, tr["east_m"]) + (rng.normal(0, 3, len(tg)) if noise else 0)
    ug = np.interp(tg, tt, tr["up_m"]) + DEPARTURE.elev_m
    lat, lon, alt = tp.inverse(eg, ng, ug - DEPARTURE.elev_m)
    gnss = pd.DataFrame({"t_s": tg, "gnss_lat_deg": lat, "gnss_lon_deg": lon,
                         "gnss_alt_m": alt + DEPARTURE.elev_m,
                         "gnss_vn_mps": np.interp(tg, tt, tr["vn_mps"]),
                         "gnss_ve_mps": np.interp(tg, tt, tr["ve_mps"])})
    tr_ = np.arange(0.0, END_S - 1.0, 4.0)
    st = TangentPlane(STATION.lat_deg, STATION.lon_deg, STATION.elev_m)
    plat, plon, ph = tp.inverse(np.interp(tr_, tt, tr["east_m"]), np.interp(tr_, tt, tr["north_m"]),
                                np.interp(tr_, tt, tr["up_m"]))
    e, nn, u = st.forward(plat, plon, ph)
    radar = pd.DataFrame({"t_s": tr_, "arms_range_m": np.sqrt(e**2 + nn**2 + u**2),
                          "arms_azimuth_deg": np.degrees(np.arctan2(e, nn)) % 360.0,
                          "arms_elevation_deg": np.degrees(np.arctan2(u, np.hypot(e, nn)))})
    data = df.merge(gnss, on="t_s", how="outer").merge(radar, on="t_s", how="outer")
    data = data.sort_values("t_s", kind="stable").reset_index(drop=True)
    meta = FlightMeta(flight_id="synthetic-circuit", epoch_utc="2026-01-01T00:00:00Z",
                      departure=DEPARTURE, arrival=DEPARTURE, station=STATION)
    return Flight(data=data, meta=meta, sources=("synthetic",)), tr


def test_synthetic_loads_reproduce_truth_accelerations():
    """The generator's loads invert back to its accelerations (guards the test fixture)."""
    from flightrecon.geo.kinematics import kinematic_acceleration_ned

    flight, tr = synthetic_flight(noise=False)
    d = flight.data.dropna(subset=["n_long_g"])
    a = kinematic_acceleration_ned(d["n_long_g"], d["n_lat_g"], d["n_norm_g"], d["roll_deg"],
                                   d["pitch_deg"], d["heading_deg"], lat_deg=45.0,
                                   h_m=FIELD_PALT_M + np.interp(d["t_s"], tr["t_s"], tr["up_m"]))
    idx = np.round(d["t_s"].to_numpy() * BASE_HZ).astype(int)
    # quantisation 0.001 g of loads, 0.01 deg of attitude and 0.1 deg of heading: at most
    # ~0.0009 g * 9.81 + 9.81 * 0.05 deg -> < 0.03 m/s^2 even in the 4.5 m/s^2 turns
    np.testing.assert_allclose(a, tr[["a_n", "a_e", "a_d"]].to_numpy()[idx], atol=0.03)
    assert abs(tr["up_m"].max() - 600.0) < 0.5  # the designed circuit height
    # touchdown happens where the designed descent reaches the runway (|h| small just before)
    i = int(np.searchsorted(tr["t_s"], TD_S)) - 1
    assert tr["up_m"].iloc[i] < 0.05

"""Synthetic recorder tables for the ingest tests and the hand-made sample log.

``handmade_frame()`` builds the content of ``sample_logs/handmade.csv``: a 4-minute departure
(30 s at rest with 2 deg nose-up attitude, a 30 s take-off roll at 2.5 m/s^2, rotation, climb at
6 deg flight-path angle, a 20 deg right turn), multi-rate (loads 8 Hz, attitude 4 Hz, air data
2 Hz, SAT 1 Hz, GNSS 1 Hz).  Loads follow METHODS.md "Common ground":
``f_b = C_nb^T (a_NED - [0, 0, g0])``, ``n_long = f_x/g0``, ``n_lat = f_y/g0``,
``n_norm = -f_z/g0``.  ``test_handmade_is_reproducible`` checks the shipped file against it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.constants import G0
from flightrecon.geo.atmosphere import isa_temperature_k
from flightrecon.geo.frames import TangentPlane

DEPARTURE = (40.46, 50.05, 3.0)
EPOCH = "2026-03-15T09:00:00Z"
FINE_HZ = 64


def _ramp(t, t0, t1, a, b):
    return a + (b - a) * np.clip((t - t0) / (t1 - t0), 0.0, 1.0)


def truth(duration_s: float = 240.0) -> pd.DataFrame:
    """Kinematic truth at 64 Hz: attitude, speed, loads, position (no wind)."""
    t = np.arange(0.0, duration_s + 1e-9, 1.0 / FINE_HZ)
    speed = np.where(t < 30, 0.0, np.minimum(2.5 * (t - 30), 75.0))
    gamma = np.radians(_ramp(t, 60, 70, 0.0, 6.0))
    pitch = np.radians(_ramp(t, 60, 70, 2.0, 10.0))
    roll = np.radians(_ramp(t, 150, 160, 0.0, 20.0) - _ramp(t, 220, 230, 0.0, 20.0))
    vh = speed * np.cos(gamma)
    psi_rate = np.where(vh > 1.0, G0 * np.tan(roll) / np.maximum(vh, 1.0), 0.0)
    psi = np.radians(90.0) + np.concatenate([[0.0], np.cumsum(0.5 * (psi_rate[1:] + psi_rate[:-1])
                                                              / FINE_HZ)])
    vn, ve, vd = vh * np.cos(psi), vh * np.sin(psi), -speed * np.sin(gamma)
    a = np.stack([np.gradient(v, t) for v in (vn, ve, vd)], axis=1)
    f_ned = a - np.array([0.0, 0.0, G0])
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(psi), np.sin(psi)
    # C_nb (body -> NED), ZYX; f_b = C_nb^T f_ned
    c = np.empty((t.size, 3, 3))
    c[:, 0, 0], c[:, 0, 1], c[:, 0, 2] = cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy
    c[:, 1, 0], c[:, 1, 1], c[:, 1, 2] = cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy
    c[:, 2, 0], c[:, 2, 1], c[:, 2, 2] = -sp, sr * cp, cr * cp
    f_b = np.einsum("nji,nj->ni", c, f_ned)

    def integ(v):
        return np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) / FINE_HZ)])

    north, east, up = integ(vn), integ(ve), integ(-vd)
    lat, lon, h = TangentPlane(*DEPARTURE).inverse(east, north, up)
    baro = DEPARTURE[2] + up
    return pd.DataFrame({
        "t_s": t, "n_long_g": f_b[:, 0] / G0, "n_lat_g": f_b[:, 1] / G0,
        "n_norm_g": -f_b[:, 2] / G0, "roll_deg": np.degrees(roll), "pitch_deg": np.degrees(pitch),
        "heading_deg": np.mod(np.degrees(psi), 360.0), "tas_mps": speed, "baro_alt_m": baro,
        "sat_degc": isa_temperature_k(baro) - 273.15 + 5.0,
        "gnss_lat_deg": lat, "gnss_lon_deg": lon, "gnss_alt_m": h,
        "gnss_vn_mps": vn, "gnss_ve_mps": ve,
    })


RATES_HZ = {"n_long_g": 8, "n_lat_g": 8, "n_norm_g": 8, "roll_deg": 4, "pitch_deg": 4,
            "heading_deg": 4, "tas_mps": 2, "baro_alt_m": 2, "sat_degc": 1, "gnss_lat_deg": 1,
            "gnss_lon_deg": 1, "gnss_alt_m": 1, "gnss_vn_mps": 1, "gnss_ve_mps": 1}


def multirate(tr: pd.DataFrame, base_hz: int = 8) -> pd.DataFrame:
    """Sample ``tr`` on a ``base_hz`` grid, each channel only on the rows of its own rate."""
    step = FINE_HZ // base_hz
    d = tr.iloc[::step].reset_index(drop=True).copy()
    k = np.arange(len(d))
    for name, hz in RATES_HZ.items():
        every = base_hz // hz
        d.loc[k % every != 0, name] = np.nan
    return d


def handmade_frame() -> pd.DataFrame:
    """The content of ``sample_logs/handmade.csv`` (values rounded as written)."""
    d = multirate(truth())
    rnd = {"t_s": 3, "n_long_g": 4, "n_lat_g": 4, "n_norm_g": 4, "roll_deg": 2, "pitch_deg": 2,
           "heading_deg": 2, "tas_mps": 2, "baro_alt_m": 1, "sat_degc": 1, "gnss_lat_deg": 7,
           "gnss_lon_deg": 7, "gnss_alt_m": 1, "gnss_vn_mps": 2, "gnss_ve_mps": 2}
    return d.round(rnd)


if __name__ == "__main__":  # regenerate the sample log: python tests/test_ingest_support.py
    from pathlib import Path

    out = Path(__file__).resolve().parents[1] / "sample_logs" / "handmade.csv"
    handmade_frame().to_csv(out, index=False, na_rep="")
    print(f"wrote {out}")


def load_quiet(path, **kw):
    """``load_flight`` with its warnings caught: the flight and the warnings' texts."""
    import warnings

    from flightrecon.ingest import load_flight

    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        fl = load_flight(path, **kw)
    return fl, [str(x.message) for x in w]

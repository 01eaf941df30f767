"""Where body rates and attitude both exist, the rates shape the attitude between its samples
(flightrecon.cleaning.rate_aided.rate_aided_attitude)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.cleaning import clean_flight
from flightrecon.types import Flight, FlightMeta


def _truth(t):
    """Roll oscillating +-25 deg with a 20 s period (S-turns), pitch +-3 deg, heading from the
    coordinated-turn rate g tan(roll) / V at V = 80 m/s."""
    phi = 25.0 * np.sin(2 * np.pi * t / 20.0)
    th = 3.0 * np.sin(2 * np.pi * t / 13.0)
    dt = np.diff(t, prepend=t[0])
    psi = 90.0 + np.degrees(np.cumsum(9.80665 * np.tan(np.radians(phi)) / 80.0 * dt))
    return phi, th, psi


def _flight(with_rates: bool, rng):
    t = np.arange(0.0, 300.0, 1 / 16)
    phi, th, psi = _truth(t)
    P, T, S = (np.radians(x) for x in (phi, th, psi))
    dphi, dth, dpsi = (np.gradient(x, t) for x in (P, T, S))
    p = dphi - dpsi * np.sin(T)
    q = dth * np.cos(P) + dpsi * np.sin(P) * np.cos(T)
    r = -dth * np.sin(P) + dpsi * np.cos(P) * np.cos(T)
    att = (np.arange(len(t)) % 16) == 0          # attitude at 1 Hz, rates at 16 Hz
    # the normal load of the coordinated turn (a channel constant over the record is dead and
    # dropped by the cleaning, cleaning/dead.py: this one sets the 16 Hz grid)
    d = pd.DataFrame({"t_s": t, "n_long_g": 0.0, "n_lat_g": 0.0,
                      "n_norm_g": 1.0 / np.cos(P), "tas_mps": 80.0, "baro_alt_m": 1000.0})
    for name, v in (("roll_deg", phi), ("pitch_deg", th), ("heading_deg", psi % 360.0)):
        d[name] = np.where(att, v, np.nan)
    if with_rates:
        bias = (0.05, -0.03, 0.04)                 # deg/s, removed interval by interval
        for name, v, b in (("p_dps", p, bias[0]), ("q_dps", q, bias[1]), ("r_dps", r, bias[2])):
            d[name] = np.degrees(v) + b + 0.02 * rng.standard_normal(len(t))
    return Flight(data=d, meta=FlightMeta()), (t, phi, th, psi)


def test_rates_shape_attitude_between_samples():
    rng = np.random.default_rng(7)
    fa, (t, phi, th, psi) = _flight(True, rng)
    fl, _ = _flight(False, rng)
    a = clean_flight(fa).grid
    b = clean_flight(fl).grid
    assert np.allclose(a["t_s"], t) and np.allclose(b["t_s"], t)
    for c, truth in (("roll_deg", phi), ("pitch_deg", th), ("heading_deg", psi)):
        ea = a[c].to_numpy() - truth
        eb = b[c].to_numpy() - truth
        if c == "heading_deg":
            ea = (ea + 180) % 360 - 180
            eb = (eb + 180) % 360 - 180
        sel = (t > 2) & (t < 298)
        rms_a, rms_b = np.sqrt(np.mean(ea[sel] ** 2)), np.sqrt(np.mean(eb[sel] ** 2))
        # linear interpolation of 1 Hz samples of a 20 s oscillation: 0.2-0.5 deg RMS;
        # rate-aided: the rate noise's random walk over one second, far smaller
        assert rms_a < 0.2 * rms_b, (c, rms_a, rms_b)
    rep = [e for e in clean_flight(fa).report if e["action"] == "rate_aided_interpolation"]
    assert {e["channel"] for e in rep} == {"roll_deg", "pitch_deg", "heading_deg"}
    # the samples themselves are not moved
    on = (np.arange(len(t)) % 16) == 0
    assert np.allclose(a["roll_deg"].to_numpy()[on], phi[on], atol=1e-9)


def test_no_aid_when_rates_not_faster():
    rng = np.random.default_rng(8)
    fa, _ = _flight(True, rng)
    d = fa.data.copy()
    for c in ("roll_deg", "pitch_deg", "heading_deg"):
        d[c] = d[c].interpolate(limit_area="inside")   # attitude at the rates' 16 Hz
    rep = clean_flight(Flight(data=d, meta=FlightMeta())).report
    assert not [e for e in rep if e["action"] == "rate_aided_interpolation"]

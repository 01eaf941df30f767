"""The attitude reference's tilt after sustained loads as extra acceleration noise of the joint
smoother (flightrecon/methods/joint/tilt.py; issue #35: the PH-LAB flights' zero-g parabolas
left the loads integrated through the recorded attitude 15-39 m/s per minute off the GPS)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from flightrecon.cleaning import clean_flight
from flightrecon.ingest import load_flight
from flightrecon.methods.joint.linearisation import smoother_flight
from flightrecon.methods.joint.problem import joint_inputs
from flightrecon.methods.joint.settings import JointNoise, JointSettings
from flightrecon.methods.joint.tilt import load_departure_g, remembered, tilt_psd

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"


def test_load_departure_is_the_distance_of_the_load_from_one_g():
    f = np.array([[0.0, 0.0, -1.0],            # level flight: 1 g, no departure
                  [0.0, 0.0, 0.0],             # zero g (a parabola's top)
                  [0.6, 0.0, -0.8],            # 1 g along a tilted axis: none
                  [0.0, 0.0, -2.0],            # a 2 g pull-up
                  [np.nan, 0.0, -1.0]])        # a missing component: left to qv_extra
    np.testing.assert_allclose(load_departure_g(f), [0.0, 1.0, 0.0, 1.0, 0.0], atol=1e-15)


def test_the_memory_is_the_exponential_mean_of_eq_1():
    """A departure of 1 g from t = 0 to 60 s: D rises as 1 - exp(-t / tau) and decays as
    exp(-(t - 60) / tau) after; the recursion is exact for held samples, up to the first
    sample's weight (1 - a) instead of a ramp: dt / tau = 1/600 relative."""
    tau = 60.0
    t = np.arange(0.0, 300.0, 0.1)
    u = ((t > 0.0) & (t <= 60.0)).astype(float)
    D = remembered(t, u, tau)
    i60, i120 = np.searchsorted(t, [60.0, 120.0])
    assert D[i60] == pytest.approx(1.0 - np.exp(-1.0), rel=2e-3)
    assert D[i120] == pytest.approx((1.0 - np.exp(-1.0)) * np.exp(-1.0), rel=4e-3)
    assert D[0] == 0.0 and np.all(np.diff(D[i60:]) < 0)


def test_the_memory_is_scipys_first_order_filter_to_the_bit():
    """The compiled recursion replaces ``scipy.signal.lfilter([1 - a], [1, -a], u)`` (not
    imported on a run's path): the same numbers to the bit on a long random driver."""
    from scipy.signal import lfilter

    rng = np.random.default_rng(7)
    t = np.arange(20000) * 0.0625
    u = np.abs(rng.normal(size=len(t)))
    a = float(np.exp(-0.0625 / 60.0))
    assert np.array_equal(remembered(t, u, 60.0), lfilter([1.0 - a], [1.0, -a], u))


def test_psd_is_eq_2_and_off_at_zero():
    t = np.arange(0.0, 200.0, 0.1)
    f = np.tile([0.0, 0.0, -1.0], (len(t), 1))
    f[(t >= 50.0) & (t < 110.0)] = [0.0, 0.0, 0.0]     # a minute at zero g
    idx = np.arange(0, len(t), 10)
    assert JointNoise().ahrs_tilt_mps2_per_g == 0.0      # off by default (inertial attitude)
    nz = JointNoise(ahrs_tilt_mps2_per_g=1.0)
    q = tilt_psd(t, f, idx, nz)
    D = remembered(t, load_departure_g(f), nz.ahrs_tilt_tau_s)[idx]
    np.testing.assert_allclose(q, (nz.ahrs_tilt_mps2_per_g * D) ** 2 * nz.ahrs_tilt_tau_s,
                               rtol=1e-12)
    assert q[idx < 500].max() == 0.0
    # a minute at zero g: D = 1 - 1/e, a_e = 0.63 m/s^2, q = 24 (m/s^2)^2/Hz (sd of the
    # velocity error over a minute: sqrt(q 60) = 38 m/s, the parabolas' 15-39 m/s)
    k = int(np.searchsorted(t[idx], 110.0))
    assert q[k] == pytest.approx((1.0 - np.exp(-1.0)) ** 2 * 60.0, rel=5e-3)
    off = dataclasses.replace(nz, ahrs_tilt_mps2_per_g=0.0)
    assert not tilt_psd(t, f, idx, off).any()
    assert not tilt_psd(t, None, idx, nz).any()
    with pytest.raises(ValueError, match="ahrs_tilt_mps2_per_g"):
        JointNoise(ahrs_tilt_mps2_per_g=-1.0)


def test_the_smoother_takes_the_tilt_noise_where_the_loads_left_one_g():
    """Wiring: the joint smoother's per-step extra acceleration PSD holds eq. (2) of the
    recorded loads: a 20 s zero-g stretch put into a shipped flight's loads raises it there
    and for a few erection time constants after, by exactly the tilt term."""
    inp = joint_inputs(clean_flight(load_flight(SAMPLES / "circuit.parquet")))
    f = np.array(inp.f_body_g, float)
    t = inp.t_in
    mid = float(t[len(t) // 2])
    f[(t >= mid) & (t < mid + 20.0)] = 0.0
    settings = JointSettings(noise=JointNoise(ahrs_tilt_mps2_per_g=1.0))
    base = smoother_flight(dataclasses.replace(inp, f_body_g=np.array(inp.f_body_g)), settings)
    fl = smoother_flight(dataclasses.replace(inp, f_body_g=f), settings)
    extra = fl.qv_extra - base.qv_extra
    want = (tilt_psd(t, f, fl.idx, settings.noise)
            - tilt_psd(t, np.array(inp.f_body_g), fl.idx, settings.noise))
    np.testing.assert_allclose(extra, want, rtol=1e-9, atol=1e-12)
    # the default (0) adds nothing
    with_f = smoother_flight(dataclasses.replace(inp, f_body_g=f), JointSettings())
    assert np.array_equal(with_f.qv_extra, smoother_flight(inp, JointSettings()).qv_extra)
    k = int(np.searchsorted(fl.T, mid + 20.0))
    assert extra[k] > 1.0          # (1 - exp(-1/3))^2 * 60 = 4.8 (m/s^2)^2/Hz at its end
    assert np.all(extra[fl.T < mid - 1.0] == 0.0)


def test_the_erection_driver_of_a_coordinated_turn_eq_1b():
    """A level coordinated turn at 30 deg of bank: the load is 1/cos(30) = 1.1547 g along the
    body's z axis, the aircraft accelerates horizontally by g tan(30) = 0.5774 g.  Eq. (1b)
    with the horizontal share 0 is the load's departure alone, 0.1547 g; with share 1 the whole
    acceleration, sqrt(0.1547^2 + 0.5774^2) = 0.5977 g; without ``acc_ned`` the share is
    ignored."""
    from flightrecon.constants import G0
    from flightrecon.methods.joint.tilt import erection_driver_g

    phi = np.radians(30.0)
    f = np.array([[0.0, 0.0, -1.0 / np.cos(phi)]])
    acc = np.array([[0.0, G0 * np.tan(phi), 0.0]])
    dep = 1.0 / np.cos(phi) - 1.0
    assert erection_driver_g(f, acc, 0.0)[0] == pytest.approx(dep, rel=1e-12)
    assert erection_driver_g(f, acc, 1.0)[0] == pytest.approx(np.hypot(dep, np.tan(phi)),
                                                              rel=1e-12)
    assert erection_driver_g(f, acc, 0.5)[0] == pytest.approx(
        np.sqrt(dep ** 2 + 0.5 * np.tan(phi) ** 2), rel=1e-12)
    assert erection_driver_g(f, None, 1.0)[0] == pytest.approx(dep, rel=1e-12)
    with pytest.raises(ValueError, match="ahrs_tilt_horizontal"):
        JointNoise(ahrs_tilt_horizontal=-0.5)


def test_the_declared_attitude_source_switches_the_tilt_noise(tmp_path):
    """``[flight] attitude_source``: "ahrs" turns the tilt noise on at the PH-LAB figure
    (1 m/s^2 per g, horizontal share 1) unless the settings give it; "inertial" leaves it
    off; undeclared it stays off and, with a minute at zero g in the loads (remembered
    departure 0.63 g, above the 0.1 g threshold), the note says the source was taken as
    inertial; a wrong value is refused."""
    from flightrecon.errors import MetadataError
    from flightrecon.ingest.sidecar import load_sidecar
    from flightrecon.methods.joint.problem import (
        AHRS_TILT_HORIZONTAL,
        AHRS_TILT_MPS2_PER_G,
        UNDECLARED_TILT_WARN_G,
        attitude_source_noise,
    )

    clean = clean_flight(load_flight(SAMPLES / "circuit.parquet"))
    inp = joint_inputs(clean)
    f = np.array(inp.f_body_g, float)
    t = inp.t_in
    mid = float(t[len(t) // 2])
    f[(t >= mid) & (t < mid + 60.0)] = 0.0
    zero_g = dataclasses.replace(inp, f_body_g=f)
    meta = clean.meta
    ahrs = dataclasses.replace(clean, meta=dataclasses.replace(meta, attitude_source="ahrs"))
    ins = dataclasses.replace(clean, meta=dataclasses.replace(meta, attitude_source="inertial"))
    s, note = attitude_source_noise(ahrs, zero_g, JointSettings(), None)
    assert s.noise.ahrs_tilt_mps2_per_g == AHRS_TILT_MPS2_PER_G == 1.0 and note is None
    assert s.noise.ahrs_tilt_horizontal == AHRS_TILT_HORIZONTAL == 1.0
    given = JointSettings(noise=JointNoise(ahrs_tilt_mps2_per_g=0.5))
    assert attitude_source_noise(ahrs, zero_g, given, None)[0] == given
    assert attitude_source_noise(ins, zero_g, JointSettings(), None) == (JointSettings(), None)
    s, note = attitude_source_noise(clean, zero_g, JointSettings(), None)
    assert s == JointSettings() and note is not None and "not declared" in note
    assert float(note.split("by ")[1].split(" g")[0]) == pytest.approx(1.0 - np.exp(-1.0),
                                                                       abs=0.02)
    assert UNDECLARED_TILT_WARN_G == 0.1
    side = tmp_path / "x.meta.toml"
    side.write_text('[flight]\nattitude_source = "ahrs"\n')
    assert load_sidecar(side).meta.attitude_source == "ahrs"
    side.write_text('[flight]\nattitude_source = "gyro"\n')
    with pytest.raises(MetadataError, match="attitude_source"):
        load_sidecar(side)


def _evidence(gain):
    return {"gain_mps2_per_g": gain, "floor_mps": 1.0, "windows": 40, "busy_windows": 12,
            "heading_bias_deg": 0.0, "window_s": 60.0}


def test_the_gnss_measured_tilt_gain_sets_the_noise():
    """What the fixes measure (:func:`gnss_tilt_evidence`) sets the gain: undeclared from
    0.25 m/s^2 per g on (below it the attitude holds: no noise, no note), at most the PH-LAB
    figure; a declared AHRS takes the measured gain whatever its size; a declared inertial
    source and a gain given in the settings win over the measurement."""
    from flightrecon.methods.joint.problem import (
        TILT_GAIN_MIN_MPS2_PER_G,
        attitude_source_noise,
    )

    clean = clean_flight(load_flight(SAMPLES / "circuit.parquet"))
    inp = joint_inputs(clean)
    meta = clean.meta
    ahrs = dataclasses.replace(clean, meta=dataclasses.replace(meta, attitude_source="ahrs"))
    ins = dataclasses.replace(clean, meta=dataclasses.replace(meta, attitude_source="inertial"))
    assert TILT_GAIN_MIN_MPS2_PER_G == 0.25
    s, note = attitude_source_noise(clean, inp, JointSettings(), _evidence(0.41))
    assert s.noise.ahrs_tilt_mps2_per_g == 0.41 and s.noise.ahrs_tilt_horizontal == 1.0
    assert note is not None and "GNSS measures" in note and "0.41" in note
    assert attitude_source_noise(clean, inp, JointSettings(), _evidence(0.17)) == (
        JointSettings(), None)
    assert attitude_source_noise(clean, inp, JointSettings(),
                                 _evidence(3.0))[0].noise.ahrs_tilt_mps2_per_g == 1.0
    assert attitude_source_noise(ahrs, inp, JointSettings(),
                                 _evidence(0.07))[0].noise.ahrs_tilt_mps2_per_g == 0.07
    assert attitude_source_noise(ins, inp, JointSettings(), _evidence(0.9)) == (
        JointSettings(), None)
    given = JointSettings(noise=JointNoise(ahrs_tilt_mps2_per_g=0.5))
    assert attitude_source_noise(clean, inp, given, _evidence(0.9)) == (given, None)


def _turning_flight(gain, seed=1):
    """Ten 300 s legs alternating straight flight and a 30 deg banked turn at 60 m/s, 10 Hz
    loads, 1 Hz fixes (3 m sd); the loads integrated through the attitude carry a constant
    heading error (2 deg), a 1 % scale error of the horizontal acceleration, and a tilt error of
    ``gain`` times the remembered driver (eq. 1b), towards the north, its sign alternating
    from turn to turn."""
    from flightrecon.constants import G0
    from flightrecon.methods.joint.tilt import erection_driver_g, remembered

    rng = np.random.default_rng(seed)
    dt, v = 0.1, 60.0
    t = np.arange(0.0, 3000.0, dt)
    leg = (t // 300).astype(int)
    phi = np.where(leg % 2 == 1, np.radians(30.0), 0.0)
    rate = G0 * np.tan(phi) / v
    psi = np.cumsum(rate) * dt
    a_true = np.column_stack([-v * rate * np.sin(psi), v * rate * np.cos(psi), np.zeros(len(t))])
    vel = v * np.column_stack([np.cos(psi), np.sin(psi)])
    pos = np.cumsum(vel, axis=0) * dt
    f_body = np.column_stack([np.zeros(len(t)), np.zeros(len(t)), -1.0 / np.cos(phi)])
    D = remembered(t, erection_driver_g(f_body, a_true, 1.0), 60.0)
    d = np.radians(2.0)
    rot = np.array([[np.cos(d), -np.sin(d)], [np.sin(d), np.cos(d)]])
    a_rec = a_true.copy()
    a_rec[:, :2] = 1.01 * a_true[:, :2] @ rot.T
    sign = np.where(leg % 4 < 2, 1.0, -1.0)
    a_rec[:, 0] += gain * D * sign
    k = np.arange(0, len(t), 10)
    fixes = pos[k] + rng.normal(0.0, 3.0, (len(k), 2))
    return t, a_rec, f_body, psi, t[k], fixes


@pytest.mark.parametrize("gain", [0.0, 0.5, 1.0])
def test_tilt_evidence_recovers_the_gain_of_a_simulated_tilt(gain):
    """On :func:`_turning_flight` the constant errors (heading, scale) are fitted away and the
    load-driven error's gain comes back: below 0.1 m/s^2 per g without a tilt (the
    simulator's flights gave 0.06-0.17, the threshold is 0.25), within 30 % of 0.5 and 1 with
    one (measured 0.39 and 0.93: the floor, the lower quartile of the windows' residuals, takes
    part of an error that is present in most windows).  In a coordinated turn the normal axis
    carries the whole horizontal acceleration: its scale error's regressor."""
    from flightrecon.geo.navframe import radii_of_curvature
    from flightrecon.methods.joint.tilt import tilt_evidence

    t, a, f, psi, tg, fx = _turning_flight(gain)
    f_ned_h = np.zeros((len(t), 2, 3))
    f_ned_h[:, :, 2] = a[:, :2]
    rm, rn = radii_of_curvature(0.0)   # the flight near (0, 0): no Coriolis term
    lat = np.degrees(fx[:, 0] / rm)
    lon = np.degrees(fx[:, 1] / (rn * np.cos(np.radians(lat))))
    ev = tilt_evidence(t, a, f, psi, f_ned_h, tg, lat, lon, 60.0, 2940.0)
    assert ev is not None and ev["busy_windows"] >= 10
    if gain == 0.0:
        assert ev["gain_mps2_per_g"] < 0.1
    else:
        assert ev["gain_mps2_per_g"] == pytest.approx(gain, rel=0.3)

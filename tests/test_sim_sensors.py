"""Sensor statistics against their configuration (docs/simulator.md, "Sensors").

Every band is 5 standard errors of the estimator for the sample size used (a false failure
has probability ~6e-7 per check; the seeds are fixed, so the outcome is deterministic):
mean of N iid samples: 5 sd/sqrt(N); sample sd: 5 sd/sqrt(2N); lag-1 autocorrelation phi of a
Gauss-Markov series: 5 sqrt((1 - phi^2)/N).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from flightrecon.sim import simulate
from flightrecon.sim.recorder import record_log, sample_rows
from flightrecon.sim.sensors import (
    AirspeedSensor,
    AttitudeSensor,
    BaroSensor,
    DopplerSensor,
    Faults,
    GnssReceiver,
    LoadFactorSensor,
    SensorSuite,
    WindSensor,
    first_order_lag,
    gauss_markov,
)

N = 200_000


def _synthetic_truth(n: int, rate: float = 16.0) -> pd.DataFrame:
    """A smooth synthetic truth with the columns the sensors read (no trajectory needed)."""
    t = np.arange(n) / rate
    w = 2 * np.pi * t / 600.0
    return pd.DataFrame({
        "t_s": t, "n_long_g": 0.05 * np.sin(w), "n_lat_g": 0.01 * np.cos(w),
        "n_norm_g": 1.0 + 0.2 * np.sin(3 * w), "roll_deg": 20 * np.sin(w),
        "pitch_deg": 3 + np.cos(w), "heading_deg": np.mod(100 * t / 600.0, 360.0),
        "tas_mps": 100 + 5 * np.sin(w), "pressure_alt_m": 3000 + 100 * np.sin(w),
        "sat_degc": np.full(n, -5.0), "gs_mps": 110 + 5 * np.cos(w),
        "track_deg": np.mod(100 * t / 600.0 + 4.0, 360.0),
        "wind_n_mps": np.full(n, -6.0), "wind_e_mps": np.full(n, -8.0),
        "lat_deg": np.full(n, 40.0), "lon_deg": np.full(n, 50.0), "alt_m": np.full(n, 3000.0),
        "vn_mps": np.full(n, 100.0), "ve_mps": np.zeros(n),
    })


@pytest.fixture(scope="module")
def truth():
    return _synthetic_truth(N)


def _mean_band(sd, n):
    return 5 * sd / np.sqrt(n)


def _sd_band(sd, n):
    return 5 * sd / np.sqrt(2 * n)


def test_load_factor_bias_scale_noise(truth):
    s = LoadFactorSensor(16.0, (0.01, -0.02, 0.005), (0.01, 0.0, -0.02), (0.003, 0.004, 0.006))
    rows = np.arange(N)
    m = s.record(truth, rows, np.random.default_rng(1), 1 / 16)
    for i, c in enumerate(("n_long_g", "n_lat_g", "n_norm_g")):
        err = m[c] - (1 + s.scale[i]) * truth[c].to_numpy()
        assert abs(err.mean() - s.bias_g[i]) < _mean_band(s.noise_sd_g[i], N)
        assert abs(err.std() - s.noise_sd_g[i]) < _sd_band(s.noise_sd_g[i], N)
    # scale error: regression slope of the reading on the truth (n_norm varies +-0.2 g)
    slope = np.polyfit(truth["n_norm_g"], m["n_norm_g"], 1)[0]
    # slope sd = noise / (sqrt(N) sd(n_norm)) with sd(n_norm) = 0.2/sqrt(2)
    assert abs(slope - 0.98) < 5 * 0.006 / (np.sqrt(N) * 0.2 / np.sqrt(2))


def test_quantisation_grid(truth):
    s = LoadFactorSensor(16.0, quantum_g=1 / 256)
    m = s.record(truth, np.arange(1000), np.random.default_rng(2), 1 / 16)["n_norm_g"]
    assert np.allclose(m * 256, np.round(m * 256), atol=1e-9)
    b = BaroSensor(4.0, quantum_m=0.3048)
    h = b.record(truth, np.arange(1000), np.random.default_rng(2), 1 / 16)["baro_alt_m"]
    assert np.allclose(h / 0.3048, np.round(h / 0.3048), atol=1e-9)


def test_attitude_heading_bias_and_noise(truth):
    s = AttitudeSensor(16.0, 0.05, 0.07, 0.2, heading_bias_deg=1.3)
    m = s.record(truth, np.arange(N), np.random.default_rng(3), 1 / 16)
    err = np.angle(np.exp(1j * np.radians(m["heading_deg"] - truth["heading_deg"])), deg=True)
    assert abs(err.mean() - 1.3) < _mean_band(0.2, N)
    assert abs(err.std() - 0.2) < _sd_band(0.2, N)
    assert m["heading_deg"].min() >= 0 and m["heading_deg"].max() < 360
    assert abs((m["pitch_deg"] - truth["pitch_deg"]).std() - 0.07) < _sd_band(0.07, N)


def test_airspeed_scale_noise_and_exact_lag():
    """Lag: a ramp through the exact first-order-hold discretisation equals the analytic
    response x(t) - tau slope (1 - e^{-t/tau}) to rounding; scale and noise statistics."""
    dt, tau = 0.0625, 0.8
    t = np.arange(2000) * dt
    x = 50 + 3.0 * t
    y = first_order_lag(x, dt, tau)
    assert np.allclose(y, x - 3.0 * tau * (1 - np.exp(-t / tau)), atol=1e-9)
    tr = _synthetic_truth(N)
    s = AirspeedSensor(16.0, scale=0.03, noise_sd_mps=0.4, lag_s=0.0)
    m = s.record(tr, np.arange(N), np.random.default_rng(4), dt)["tas_mps"]
    err = m - 1.03 * tr["tas_mps"].to_numpy()
    assert abs(err.mean()) < _mean_band(0.4, N)
    assert abs(err.std() - 0.4) < _sd_band(0.4, N)


def test_gauss_markov_sigma_and_correlation_time():
    """Exact discretisation: stationary sd sigma and lag-1 autocorrelation e^{-dt/tau}.
    Bands: the variance of a GM series has N_eff = N (1 - phi)/(1 + phi) independent samples."""
    dt, sigma, tau, n = 60.0, 20.0, 360.0, N
    x = gauss_markov(n, dt, sigma, tau, np.random.default_rng(5))
    phi = np.exp(-dt / tau)
    phi_hat = np.corrcoef(x[:-1], x[1:])[0, 1]
    assert abs(phi_hat - phi) < 5 * np.sqrt((1 - phi**2) / n)
    tau_hat = -dt / np.log(phi_hat)
    assert abs(tau_hat - tau) / tau < 0.05  # 5 sd of phi_hat mapped through -dt/ln(phi)
    n_eff = n * (1 - phi) / (1 + phi)
    assert abs(x.std() - sigma) < _sd_band(sigma, n_eff)


def test_gnss_dropout_fraction_and_noise(truth):
    g = GnssReceiver(1.0, pos_sd_h_m=3.0, pos_sd_v_m=5.0, vel_sd_mps=0.2,
                     dropouts=((1000.0, 500.0), (5000.0, 250.0)))
    suite = SensorSuite(LoadFactorSensor(16.0), AttitudeSensor(16.0), AirspeedSensor(16.0),
                        BaroSensor(16.0), g)
    rec = record_log(truth, suite, 7, 16.0)
    fixes = rec.log["gnss_lat_deg"].notna()
    n_slots = sample_rows(N, 16.0, 1.0).size
    assert n_slots - fixes.sum() == 750  # 500 + 250 one-second fixes missing, exactly
    t = rec.log.loc[fixes, "t_s"]
    assert not ((t >= 1000) & (t < 1500)).any()
    dn = (rec.log.loc[fixes, "gnss_lat_deg"] - 40.0) * np.pi / 180 * 6363e3  # M at 40 deg
    k = int(fixes.sum())
    assert abs(dn.std() - 3.0) < _sd_band(3.0, k) + 0.01  # + radius approximation 0.3 %
    dv = rec.log.loc[fixes, "gnss_vn_mps"] - 100.0
    assert abs(dv.std() - 0.2) < _sd_band(0.2, k)


def test_doppler_and_wind_sensor(truth):
    d = DopplerSensor(16.0, scale=0.015, drift_bias_deg=0.7, gs_noise_sd_mps=0.3,
                      drift_noise_sd_deg=0.2)
    m = d.record(truth, np.arange(N), np.random.default_rng(8), 1 / 16)
    err = m["doppler_gs_mps"] - 1.015 * truth["gs_mps"].to_numpy()
    assert abs(err.mean()) < _mean_band(0.3, N)
    drift_err = m["drift_deg"] - 4.0  # track = heading + 4 deg in the synthetic truth
    assert abs(drift_err.mean() - 0.7) < _mean_band(0.2, N)
    w = WindSensor(16.0, speed_bias_mps=1.5, from_bias_deg=-3.0, speed_noise_sd_mps=0.5,
                   from_noise_sd_deg=2.0)
    m = w.record(truth, np.arange(N), np.random.default_rng(9), 1 / 16)
    # truth wind blows TO (-6, -8): from the north-east-ish, from = atan2(8, 6) = 53.13 deg
    assert abs(m["wind_speed_mps"].mean() - 11.5) < _mean_band(0.5, N)
    assert abs(m["wind_from_deg"].mean() - (np.degrees(np.arctan2(8, 6)) - 3.0)) < \
        _mean_band(2.0, N)


def test_radar_noise_statistics_seed_scenario():
    """seed-ads-arms: 1200 plots at 1 s; range and azimuth residuals have the configured sd
    (sigma_rho 50 m, sigma_theta 0.25 deg; bands 5 sd/sqrt(2N) ~ 10 %) and zero mean."""
    r = simulate("seed-ads-arms", seed=11)
    radar = r.log.dropna(subset=["arms_range_m"])
    assert len(radar) == 1201
    from flightrecon.sim.sensors import ArmsRadar
    st = ArmsRadar(r.meta.station, r.meta.geoid_undulation_m)
    rows = np.searchsorted(r.truth.t_s.to_numpy(), radar.t_s.to_numpy())
    rng_m, az, _ = st.geometry(r.truth, rows)
    dr = radar.arms_range_m.to_numpy() - rng_m
    da = np.angle(np.exp(1j * np.radians(radar.arms_azimuth_deg.to_numpy() - az)), deg=True)
    n = len(radar)
    assert abs(dr.std() - 50.0) < _sd_band(50.0, n) and abs(dr.mean()) < _mean_band(50.0, n)
    assert abs(da.std() - 0.25) < _sd_band(0.25, n) and abs(da.mean()) < _mean_band(0.25, n)


def test_seed_scenario_air_data_is_ground_velocity_plus_gm():
    """METHODS.md section 2: TAS (sin hdg, cos hdg) = ground velocity + dV exactly, with the dV
    series in the truth."""
    r = simulate("seed-ads-arms", seed=3)
    log = r.log.dropna(subset=["tas_mps"])
    tr = r.truth.set_index("t_s").loc[log.t_s]
    h = np.radians(log.heading_deg.to_numpy())
    ve = log.tas_mps.to_numpy() * np.sin(h)
    vn = log.tas_mps.to_numpy() * np.cos(h)
    assert np.allclose(ve, tr.ve_mps + tr.airdata_err_e_mps, atol=1e-9)
    assert np.allclose(vn, tr.vn_mps + tr.airdata_err_n_mps, atol=1e-9)
    assert r.sensor_truth["airdata_error_gm"]["sigma_mps"] == 20.0
    assert np.allclose(r.truth.tas_mps, 100.0) and np.allclose(r.truth.alt_msl_m, 1000.0)


def test_faults_spikes_gaps_clock_offset():
    f = Faults(spikes=4, spike_channels=(("n_norm_g", 2.0),), gaps=(("tas_mps", 100.0, 30.0),),
               clock_offsets=(("baro", 0.5),))
    clean = simulate("circuit", seed=2, ideal_sensors=True)
    r = simulate("circuit", seed=2, ideal_sensors=True, faults=f)
    spikes = [e for e in r.sensor_truth["faults"] if e["kind"] == "spike"]
    assert len(spikes) == 4
    diff = (r.log.n_norm_g - clean.log.n_norm_g).abs()
    assert (diff > 1.9).sum() == 4
    gap = r.log[(r.log.t_s >= 100) & (r.log.t_s < 130)]
    assert gap.tas_mps.isna().all()
    # baro stamped 0.5 s late: reading at t is the truth at t - 0.5
    tr = r.truth.set_index("t_s")
    b = r.log.dropna(subset=["baro_alt_m"])
    b = b[b.t_s > 1.0]
    assert np.allclose(b.baro_alt_m.to_numpy(), tr.loc[b.t_s - 0.5, "pressure_alt_m"].to_numpy())


def test_gnss_lever_arm_offset_in_ecef():
    """Noise-free GNSS fixes sit at the centre of mass + C_nb r (r = lever arm, body FRD): the
    ECEF difference equals R_ne C_nb r to 1e-4 m (the fix uses the radii of curvature for the
    2 m offset: error ~ r^2 / R ~ 1e-6 m; 1e-4 covers float rounding of lat/lon in degrees)."""
    from flightrecon.geo.frames import geodetic_to_ecef
    from flightrecon.sim.kinematics import dcm_body_to_ned
    r = simulate("circuit", seed=0, ideal_sensors=True)
    arm = np.array(r.meta.gnss_lever_arm_m)
    assert np.any(arm != 0)
    fixes = r.log.dropna(subset=["gnss_lat_deg"])
    tr = r.truth.set_index("t_s").loc[fixes.t_s]
    xa = np.column_stack(geodetic_to_ecef(fixes.gnss_lat_deg, fixes.gnss_lon_deg,
                                          fixes.gnss_alt_m))
    xc = np.column_stack(geodetic_to_ecef(tr.lat_deg, tr.lon_deg, tr.alt_m))
    c = dcm_body_to_ned(np.radians(tr.heading_deg.to_numpy()), np.radians(tr.pitch_deg.to_numpy()),
                        np.radians(tr.roll_deg.to_numpy()))
    d_ned = c @ arm
    lat, lon = np.radians(tr.lat_deg.to_numpy()), np.radians(tr.lon_deg.to_numpy())
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    n, e, d = d_ned[:, 0], d_ned[:, 1], d_ned[:, 2]
    expect = np.column_stack([-sl * co * n - so * e - cl * co * d,
                              -sl * so * n + co * e - cl * so * d,
                              cl * n - sl * d])
    assert np.max(np.abs(xa - xc - expect)) < 1e-4

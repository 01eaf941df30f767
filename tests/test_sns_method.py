"""The SNS adapter run_sns / solve_sns on simulated flights (flightrecon.methods.sns.method)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from _scripts import load_script

from flightrecon.errors import MetadataError, SchemaError, ValidationError
from flightrecon.geo.frames import output_plane
from flightrecon.methods import sns as core
from flightrecon.methods.sns.method import run_sns, solve_sns

mc = load_script("mc_sns")


def _noiseless(model):
    n = core.default_noise(model)
    return replace(n, sensor_sd=(0.0, 0.0, 0.0, 0.0), rw_q=(0.0, 0.0, 0.0), pos_sd_m=0.0,
                   vel_sd_mps=0.0)


@pytest.fixture(scope="module")
def noiseless_run():
    sim = mc.simulate(11, duration_s=1200.0, rate_hz=8.0, noise=_noiseless(0))
    res = run_sns(sim.clean, filter_rate_hz=1.0)
    return sim, res


def test_noiseless_flight_recovered_on_decimated_grid(noiseless_run):
    """Error-free sensors and fixes, recorder at 8 Hz, filter at 1 Hz (8 recorder samples per
    step integrated exactly): the smoothed track on the 8 Hz grid matches the truth, in the
    output plane, to 0.05 m (measured 4 mm: the filter assumes 3 m GNSS noise, so it averages rather than
    interpolates; a missing sub-step or a mis-held sample would give tens of metres at 200 m/s),
    and the corrections to 1e-3 of their prior sd (sd reported about 1e-4 of the prior)."""
    sim, res = noiseless_run
    plane = output_plane(sim.clean.meta)
    e, n, _ = plane.forward(np.rad2deg(sim.lat), np.rad2deg(sim.lon), np.full(len(sim.t), 9000.0))
    tr = res.track
    assert len(tr) == len(sim.t)
    err = np.hypot(tr["sns_north_m"] - n, tr["sns_east_m"] - e)
    assert err.max() < 0.05
    verr = np.hypot(tr["sns_vn_mps"] - sim.v_ne[:, 0], tr["sns_ve_mps"] - sim.v_ne[:, 1])
    assert verr.max() < 0.05
    c = res.summary["corrections"]
    assert abs(np.deg2rad(c["heading_corr_deg"]) - sim.corr[-1, 2]) < 1e-3 * np.deg2rad(2.0)
    assert abs(c["wind_corr_n_mps"] - sim.corr[-1, 0]) < 1e-3 * 10.0
    assert abs(c["wind_corr_e_mps"] - sim.corr[-1, 1]) < 1e-3 * 10.0


def test_summary_and_columns(noiseless_run):
    sim, res = noiseless_run
    s = res.summary
    assert res.name == "sns"
    assert s["model"] == "airspeed" and s["form"] == "consistent"
    assert s["n_fixes_used"] == len(sim.clean.gnss)
    assert s["filter_rate_hz"] == pytest.approx(1.0)
    assert s["converged"] is True
    for col in ("t_s", "sns_north_m", "sns_east_m", "sns_north_sd_m", "sns_east_sd_m",
                "sns_vn_mps", "sns_ve_mps", "sns_vn_sd_mps", "sns_ve_sd_mps"):
        assert col in res.track.columns
    assert (res.track["sns_north_sd_m"] > 0).all()


def test_doppler_chosen_automatically_and_track_correction_recovered():
    """Doppler channels present -> heading-Doppler; the scale and the track-angle correction
    (drift + heading, the combination the data determine) are recovered within 3 reported sd
    (a 99.7 % interval for one seeded run)."""
    sim = mc.simulate(5, model=core.MODEL_DOPPLER, duration_s=1200.0)
    res = run_sns(sim.clean)
    c = res.summary["corrections"]
    assert res.summary["model"] == "doppler"
    assert abs(c["doppler_scale_corr"] - sim.corr[-1, 0]) < 3 * c["doppler_scale_corr_sd"]
    true_track = np.rad2deg(sim.corr[-1, 1] + sim.corr[-1, 2])
    assert abs(c["track_corr_deg"] - true_track) < 3 * c["track_corr_sd_deg"]
    with pytest.raises(SchemaError):
        run_sns(mc.simulate(5, duration_s=300.0).clean, model="doppler")


def test_gnss_gap_reported_and_lever_arm_applied():
    """A 60 s dropout appears in the summary; ignoring the 6 m lever arm biases the track by
    about the lever arm (measured against the truth: error grows by more than 2 m)."""
    sim = mc.simulate(3, duration_s=900.0, gaps=((400.0, 60.0),))
    res = run_sns(sim.clean)
    gaps = [g for g in res.summary["gaps"] if g["duration_s"] > 30]
    assert len(gaps) == 1 and gaps[0]["start_s"] == pytest.approx(399.3, abs=1.0)
    plane = output_plane(sim.clean.meta)
    e, n, _ = plane.forward(np.rad2deg(sim.lat), np.rad2deg(sim.lon), np.full(len(sim.t), 9000.))

    def rms(r):
        return float(np.sqrt(np.mean((r.track["sns_north_m"] - n) ** 2
                                     + (r.track["sns_east_m"] - e) ** 2)))

    clean_noarm = replace(sim.clean, meta=replace(sim.clean.meta, gnss_lever_arm_m=(0., 0., 0.)))
    assert rms(run_sns(clean_noarm)) > rms(res) + 2.0


def test_smoothed_covariance_not_above_filtered():
    """P_smoothed <= P_filtered in the positive semi-definite sense at every filter step
    (smallest eigenvalue of the difference above -1e-9 of the largest variance: rounding)."""
    sim = mc.simulate(8, duration_s=600.0, gaps=((200.0, 120.0),))
    sol = solve_sns(sim.clean)
    diff = sol.run.P - sol.smoothed.P
    scale = np.abs(sol.run.P).max()
    lam = np.linalg.eigvalsh(0.5 * (diff + np.transpose(diff, (0, 2, 1))))
    assert lam.min() > -1e-9 * scale


def test_seed_form_runs_and_differs():
    sim = mc.simulate(4, duration_s=300.0)
    a = solve_sns(sim.clean, form="consistent")
    b = solve_sns(sim.clean, form="seed")
    assert np.isfinite(b.run.P).all()
    assert not np.allclose(a.run.P_pred, b.run.P_pred)


def test_bad_input_raises_project_errors():
    sim = mc.simulate(2, duration_s=120.0)
    clean = sim.clean
    with pytest.raises(ValidationError):
        run_sns(clean, form="kalman")
    with pytest.raises(SchemaError):
        run_sns(clean, model="inertial")
    with pytest.raises(ValidationError):
        run_sns(clean, filter_rate_hz=0.0)
    with pytest.raises(MetadataError):
        run_sns(replace(clean, meta=replace(clean.meta, departure=None)))
    with pytest.raises(ValidationError):
        run_sns(replace(clean, gnss=clean.gnss.iloc[:1]))
    with pytest.raises(SchemaError):
        run_sns(replace(clean, gnss=clean.gnss.drop(columns="gnss_lat_deg")))
    with pytest.raises(SchemaError):
        run_sns(replace(clean, grid=clean.grid.drop(columns="tas_mps")))


@pytest.mark.slow
def test_ten_hour_16hz_flight_runs_in_seconds():
    """The yardstick: 576,000 recorder samples, 36,000 fixes, filter at 2 Hz.  Under 60 s on a
    loaded 2-core machine (measured about 4 s after compilation)."""
    import time

    sim = mc.simulate(1, duration_s=36000.0, rate_hz=16.0)
    run_sns(sim.clean)  # compile
    t0 = time.perf_counter()
    res = run_sns(sim.clean)
    assert time.perf_counter() - t0 < 60.0
    assert res.summary["converged"]


def test_position_only_fixes():
    """GNSS without velocity columns: the velocity rows are dropped and the filter runs on
    positions alone.  RMS error against the truth under 5 m (3 m fixes at 1 Hz; measured
    about 1.5 m) and the reported 2-sigma covers at least 85 % of the samples (95 % expected;
    one 15-minute run has strongly correlated errors, hence the margin)."""
    sim = mc.simulate(6, duration_s=900.0)
    clean = replace(sim.clean, gnss=sim.clean.gnss.drop(columns=["gnss_vn_mps", "gnss_ve_mps"]))
    res = run_sns(clean)
    assert res.summary["converged"]
    plane = output_plane(sim.clean.meta)
    e, n, _ = plane.forward(np.rad2deg(sim.lat), np.rad2deg(sim.lon), np.full(len(sim.t), 9000.))
    en = res.track["sns_north_m"] - n
    ee = res.track["sns_east_m"] - e
    assert np.sqrt(np.mean(en ** 2 + ee ** 2)) < 5.0
    assert np.mean(np.abs(en) <= 2 * res.track["sns_north_sd_m"]) > 0.85
    assert np.mean(np.abs(ee) <= 2 * res.track["sns_east_sd_m"]) > 0.85


def test_singular_prediction_reported_as_convergence_error():
    """Zero noise on the corrections (prior and random walk) and zero sensor noise leave the
    predicted covariance singular (rank 2 of 5); the smoother's solve then fails and the user
    gets the project's ConvergenceError, not a bare numpy exception."""
    from flightrecon.errors import ConvergenceError

    sim = mc.simulate(9, duration_s=120.0, noise=_noiseless(0))
    noise = replace(_noiseless(0), prior_sd=(0.0, 0.0, 0.0))
    with pytest.raises(ConvergenceError, match="singular"):
        run_sns(sim.clean, noise=noise)


def test_filter_rate_does_not_change_the_answer():
    """Recorder at 16 Hz with white errors per sample; filter at 1 Hz and at 16 Hz.  The
    decimated filter splits each step's noise exactly (the sample held at the fix, and the
    summed samples before and after it), so both runs agree and both are consistent: mean NIS
    per degree of freedom within 0.15 of 1 (about 4800 degrees of freedom: sd 0.02; a filter
    that holds the reading error over the whole step gives 2.1 here), heading corrections
    within 0.1 of their sd of each other, and positions within 0.1 m RMS, 0.5 m at worst
    (measured 0.04 / 0.2 m: the corrections' random walk and the linearisation points differ
    between the grids; reported position sd about 1 m)."""
    sim = mc.simulate(12, duration_s=1200.0, rate_hz=16.0)
    r1 = run_sns(sim.clean, filter_rate_hz=1.0)
    r16 = run_sns(sim.clean, filter_rate_hz=16.0)
    for r in (r1, r16):
        assert abs(r.summary["nis_per_dof"] - 1.0) < 0.15
    c1, c16 = r1.summary["corrections"], r16.summary["corrections"]
    assert abs(c1["heading_corr_deg"] - c16["heading_corr_deg"]) < 0.1 * c16["heading_corr_sd_deg"]
    d = np.hypot(r1.track["sns_north_m"] - r16.track["sns_north_m"],
                 r1.track["sns_east_m"] - r16.track["sns_east_m"])
    assert np.sqrt(np.mean(d ** 2)) < 0.1 and d.max() < 0.5

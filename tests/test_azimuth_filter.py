"""Azimuth filters and smoother (flightrecon.methods.azimuth.azimuth_filter; METHODS.md s. 3)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flightrecon.errors import ValidationError
from flightrecon.methods.azimuth import RangeTrack, azimuth_filter, track_range, wrap_pi


def straight_pass(sigma_az_deg=0.05, seed=0, scan_s=4.0):
    """Straight, unaccelerated flight 8 km north of the station, east to west at 100 m/s.

    Azimuth passes through north (32 deg -> 0 -> 328 deg): the wrap of the radar azimuth.
    Events every second, plots every ``scan_s``; the on-board acceleration is exactly zero.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 101.0)
    n = np.full(t.size, 8000.0)
    e = 5000.0 - 100.0 * t
    eps = np.unwrap(np.arctan2(e, n))
    r = np.hypot(n, e)
    plot = (t % scan_s) == 0
    eps_meas = np.where(plot, np.mod(eps + np.radians(sigma_az_deg) * rng.standard_normal(t.size),
                                     2 * np.pi), np.nan)
    r_meas = np.where(plot, r + 20.0 * rng.standard_normal(t.size), np.nan)
    rt = track_range(t, r_meas, np.full(t.size, 400.0), q_range_m2ps3=0.1)
    return t, eps, eps_meas, rt


@pytest.mark.parametrize("model", ["singer", "aided"])
def test_tracks_through_north(model):
    """No 2-pi jump where the radar azimuth wraps from 0 to 360 deg.

    The error must stay within 5 sigma of the filter's own sd (0.05 deg radar noise: a jump
    would be 6.28 rad).
    """
    t, eps, eps_meas, rt = straight_pass()
    a_ne = np.zeros((t.size, 2))
    cov = np.tile(np.eye(2) * 0.01, (t.size, 1, 1))
    run = azimuth_filter(t, eps_meas, np.full(t.size, np.radians(0.05) ** 2), rt, model=model,
                         a_ne=a_ne, a_ne_cov=cov)
    for x, P in ((run.filt.x, run.filt.P), (run.smooth.x, run.smooth.P)):
        err = wrap_pi(x[:, 0] - eps)
        assert np.all(np.abs(err[10:]) < 5 * np.sqrt(P[10:, 0, 0]))
        assert np.all(np.abs(x[:, 0] - eps) < 0.05)  # continuous state: no 2 pi offset
    # wrapped (the first two plots set omega)
    assert np.nanmax(np.abs(run.filt.diagnostics["nu_eps"][8:])) < 0.01


def test_aided_keeps_tracking_without_radar():
    """Radar silent after t = 40 s: the aided filter follows on the on-board observation alone.

    On this straight pass the on-board observation z = 0 = 2 r_dot omega + r a pins the
    acceleration; after 60 s without radar the aided azimuth error must be below the Singer
    filter's by a factor 2 (the Singer extrapolation grows like its acceleration uncertainty
    T^2/2, the aided one only with the rate error) and inside 4 of its own sd.
    """
    t, eps, eps_meas, rt_full = straight_pass(sigma_az_deg=0.1, seed=3)
    eps_meas = np.where(t <= 40.0, eps_meas, np.nan)
    a_ne = np.zeros((t.size, 2))
    cov = np.tile(np.eye(2) * 0.02**2, (t.size, 1, 1))
    # the range is known here (the range tracker's own outage is not under test)
    n = np.full(t.size, 8000.0)
    e = 5000.0 - 100.0 * t
    r = np.hypot(n, e)
    rt = RangeTrack(r, (e * -100.0) / r, np.tile(np.diag([100.0, 1.0]), (t.size, 1, 1)),
                    rt_full.nis)
    err = {}
    for model in ("singer", "aided"):
        run = azimuth_filter(t, eps_meas, np.full(t.size, np.radians(0.1) ** 2), rt,
                             model=model, a_ne=a_ne, a_ne_cov=cov)
        err[model] = abs(wrap_pi(run.filt.x[-1, 0] - eps[-1]))
        if model == "aided":
            assert err[model] < 4 * np.sqrt(run.filt.P[-1, 0, 0])
            assert np.all(np.isfinite(run.filt.diagnostics["nu_z"][t > 40]))
    assert err["aided"] < 0.5 * err["singer"]


def test_smoother_covariance_below_filter():
    """Smoothed covariance never above the filtered one (P_f - P_s PSD, to 1e-12 of P_f)."""
    t, _, eps_meas, rt = straight_pass()
    run = azimuth_filter(t, eps_meas, np.full(t.size, np.radians(0.05) ** 2), rt, model="aided",
                         a_ne=np.zeros((t.size, 2)),
                         a_ne_cov=np.tile(np.eye(2) * 0.01, (t.size, 1, 1)))
    D = run.filt.P - run.smooth.P
    scale = np.trace(run.filt.P, axis1=1, axis2=2)
    assert np.all(np.linalg.eigvalsh(D).min(axis=1) > -1e-12 * scale)
    assert np.all(np.linalg.eigvalsh(run.smooth.P).min(axis=1) > 0)


def test_input_errors():
    t, _, eps_meas, rt = straight_pass()
    var = np.full(t.size, 1e-6)
    with pytest.raises(ValidationError):
        azimuth_filter(t, eps_meas, var, rt, model="kalman")
    with pytest.raises(ValidationError):
        azimuth_filter(t, eps_meas, var, rt, model="aided")  # no on-board data
    with pytest.raises(ValidationError):
        azimuth_filter(t[::-1], eps_meas, var, rt, model="singer")
    bad = eps_meas.copy()
    bad[0] = np.nan
    with pytest.raises(ValidationError):
        azimuth_filter(t, bad, var, rt, model="singer")
    with pytest.raises(ValidationError):
        track_range(t, np.r_[np.nan, eps_meas[1:]], var, q_range_m2ps3=1.0)


def test_singer_kernel_matches_generic_kalman_filter():
    """With the plots unwrapped, the azimuth kernel (Singer) equals the generic linear KF + RTS.

    Same model and updates, different order of operations (scalar vs matrix Joseph form):
    1e-9 of the state sd.
    """
    from flightrecon.estimation.kalman import kalman_filter, rts_smooth_run
    from flightrecon.methods.azimuth import singer_process_noise

    t, _, eps_meas, rt = straight_pass()
    plot = np.isfinite(eps_meas)
    eps_meas[plot] = np.unwrap(eps_meas[plot])
    var = np.full(t.size, np.radians(0.05) ** 2)
    run = azimuth_filter(t, eps_meas, var, rt, model="singer", alpha_m=0.1, sigma_m_mps2=1.5)
    Q = singer_process_noise(0.1, 1.5 / rt.r, np.diff(t, prepend=t[0]))
    z = eps_meas.copy()
    z[0] = np.nan  # the first plot is the prior (x_pred[0], P_pred[0]), used once
    ref = kalman_filter(run.filt.x_pred[0], run.filt.P_pred[0], run.filt.diagnostics["F"], Q,
                        z[:, None], np.array([[1.0, 0.0, 0.0]]), var[:, None, None])
    sd = np.sqrt(np.diagonal(run.filt.P, axis1=1, axis2=2))
    np.testing.assert_allclose((ref.x - run.filt.x) / sd, 0.0, atol=1e-9)
    np.testing.assert_allclose(ref.P, run.filt.P, rtol=1e-9, atol=0)
    sm = rts_smooth_run(ref)
    np.testing.assert_allclose((sm.x - run.smooth.x) / sd, 0.0, atol=1e-9)


@settings(max_examples=15, deadline=None)
@given(offset=st.floats(2000.0, 30000.0), speed=st.floats(40.0, 250.0),
       heading=st.floats(0.0, 2 * np.pi), turn=st.floats(-0.05, 0.05),
       model=st.sampled_from(["singer", "aided"]), seed=st.integers(0, 1000))
def test_covariances_stay_positive_definite(offset, speed, heading, turn, model, seed):
    """Property: on any (turning) pass, P and the smoothed P stay PD and P_s <= P_f.

    Random circular arcs (turn rate up to 0.05 rad/s) at 2-30 km, noisy plots every 4 s and
    on-board acceleration every second.  Bounds relative to the trace (1e-12) as in the test
    above.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 121.0)
    chi = heading + turn * t
    vn, ve = speed * np.cos(chi), speed * np.sin(chi)
    n = offset + np.cumsum(vn) - vn[0]
    e = 0.3 * offset + np.cumsum(ve) - ve[0]
    a_ne = np.stack([-speed * turn * np.sin(chi), speed * turn * np.cos(chi)], -1)
    plot = (t % 4) == 0
    eps = np.arctan2(e, n)
    eps_meas = np.where(plot, np.mod(eps + 0.003 * rng.standard_normal(t.size), 2 * np.pi),
                        np.nan)
    r = np.hypot(n, e)
    r_meas = np.where(plot, r + 50.0 * rng.standard_normal(t.size), np.nan)
    rt = track_range(t, r_meas, np.full(t.size, 2500.0), q_range_m2ps3=10.0)
    run = azimuth_filter(t, eps_meas, np.full(t.size, 0.003**2), rt, model=model, a_ne=a_ne,
                         a_ne_cov=np.tile(np.eye(2) * 0.01, (t.size, 1, 1)))
    scale = np.trace(run.filt.P, axis1=1, axis2=2)
    assert np.all(np.linalg.eigvalsh(run.filt.P).min(axis=1) > 0)
    assert np.all(np.linalg.eigvalsh(run.smooth.P).min(axis=1) > 0)
    assert np.all(np.linalg.eigvalsh(run.filt.P - run.smooth.P).min(axis=1) > -1e-12 * scale)


def test_range_tracker_uses_its_first_plot_once():
    """Regression: the range tracker took its first plot as the prior *and* as a measurement,
    so one plot of variance 100 m^2 came out with variance 50 m^2.  With a single plot the
    smoothed range variance must be that plot's variance, and the plot has no innovation."""
    t = np.array([0.0, 1.0])
    rt = track_range(t, np.array([5000.0, np.nan]), np.array([100.0, np.nan]),
                     q_range_m2ps3=1e-6)
    assert rt.P[0, 0, 0] == pytest.approx(100.0, rel=1e-12)
    assert rt.r[0] == 5000.0
    assert np.isnan(rt.nis).all()


@pytest.mark.parametrize("model", ["singer", "aided"])
def test_azimuth_filter_uses_its_first_plot_once(model):
    """Regression: the azimuth filter also used its first plot twice (prior and update),
    halving the first azimuth variance.  The filtered variance at the first event must be the
    plot's variance, with no innovation recorded there; the second plot is used as usual."""
    t = np.array([0.0, 1.0, 2.0])
    eps = np.radians([30.0, np.nan, 30.1])
    var = np.full(3, np.radians(0.2) ** 2)
    rt = track_range(t, np.array([8000.0, np.nan, 8010.0]), np.array([400.0, np.nan, 400.0]),
                     q_range_m2ps3=0.1)
    extra = {}
    if model == "aided":
        extra = {"a_ne": np.full((3, 2), np.nan), "a_ne_cov": np.zeros((3, 2, 2))}
    run = azimuth_filter(t, eps, var, rt, model=model, **extra)
    assert run.filt.P[0, 0, 0] == pytest.approx(var[0], rel=1e-12)
    nu_eps = run.filt.diagnostics["nu_eps"]
    assert np.isnan(nu_eps[0]) and np.isfinite(nu_eps[2])

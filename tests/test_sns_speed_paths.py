"""The fast code paths of the SNS method (issue #13) against their plain references.

Each fast path (allocation-free kernels, Cholesky inverse, pre-computed boxplus, linear blend in
densify, lever arm on the needed rows, decimated meridian convergence) is compared with the
straightforward computation it replaces; tolerances are round-off unless stated.
"""

from __future__ import annotations

import numpy as np
import pytest
from _scripts import load_script

from flightrecon.estimation import linalg as sns_linalg
from flightrecon.geo.frames import output_plane
from flightrecon.methods import sns as core
from flightrecon.methods.sns import method as sns_method
from flightrecon.methods.sns import output as sns_output
from flightrecon.methods.sns.method import run_sns, solve_sns

mc = load_script("mc_sns")
RNG = np.random.default_rng(13)


@pytest.fixture(scope="module")
def flight16():
    """Ten minutes at 16 Hz (8 samples per 2 Hz filter step), airspeed model, with a gap."""
    sim = mc.simulate(21, duration_s=600.0, rate_hz=16.0, gaps=((250.0, 40.0),))
    return sim, solve_sns(sim.clean)


def test_small_matrix_products_equal_numpy():
    """Loop products on strided views equal numpy's (1e-13 relative: summation order)."""
    A = RNG.normal(size=(5, 11))
    Bm = RNG.normal(size=(4, 11))
    C = RNG.normal(size=(11, 3))
    dg = RNG.normal(size=11)
    big = np.zeros((6, 6))
    out = big[:5, :4]  # a strided view, as the kernel uses
    sns_linalg.mmt_into(A, Bm, out)
    np.testing.assert_allclose(out, A @ Bm.T, rtol=1e-13, atol=1e-13)
    out2 = np.zeros((5, 3))
    sns_linalg.mm_into(A, C, out2)
    np.testing.assert_allclose(out2, A @ C, rtol=1e-13, atol=1e-13)
    acc = np.ones((5, 4))
    sns_linalg.mdmt_acc_into(A, dg, Bm, acc)
    np.testing.assert_allclose(acc, 1.0 + A @ np.diag(dg) @ Bm.T, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("m", [2, 4, 8])
def test_pinv_fast_inverse_matches_numpy(m):
    """Well-conditioned innovation covariances take the Cholesky inverse: equal to numpy's
    pinv to 1e-12 relative (condition number below 1e3 here) and full rank."""
    X = RNG.normal(size=(m, m + 3))
    S = X @ X.T + np.eye(m)
    Sp, rank = core.pinv_sym(S, 1e-10)
    assert rank == m
    np.testing.assert_allclose(Sp, np.linalg.pinv(S), rtol=1e-12, atol=1e-12 * np.abs(Sp).max())


@pytest.mark.parametrize("small, expected_rank", [(1e-12, 3), (1e-8, 4)])
def test_pinv_threshold_near_rcond(small, expected_rank):
    """Eigenvalues around the threshold (rcond 1e-10 of the largest): 1e-12 is dropped (Cholesky
    succeeds but cannot prove full rank, the Jacobi path decides), 1e-8 is kept.  Compared with
    numpy's eigen-decomposition pseudo-inverse at the same cut-off (1e-7 relative: with the
    eigenvalue 1e-8 kept the condition number is 1e8, so either method is accurate only to
    cond x eps = 1e-8 relative; measured 9e-9)."""
    V = np.linalg.qr(RNG.normal(size=(4, 4)))[0]
    lam = np.array([1.0, 0.5, 0.2, small])
    S = V @ np.diag(lam) @ V.T
    Sp, rank = core.pinv_sym(S, 1e-10)
    assert rank == expected_rank
    ref = np.linalg.pinv(S, rcond=1e-10, hermitian=True)
    np.testing.assert_allclose(Sp, ref, rtol=1e-7, atol=1e-7 * np.abs(ref).max())


def test_jacobi_eigenvalues_match_lapack():
    """Cyclic Jacobi eigenvalues equal LAPACK's to 1e-13 of the largest; V orthogonal and
    A = V diag V^T to 1e-13."""
    X = RNG.normal(size=(6, 6))
    S = X + X.T
    A = S.copy()
    V = np.empty((6, 6))
    sns_linalg._jacobi_eigh(A, V)
    lam = np.sort(np.diag(A))
    scale = np.abs(lam).max()
    np.testing.assert_allclose(lam, np.linalg.eigvalsh(S), atol=1e-13 * scale)
    np.testing.assert_allclose(V.T @ V, np.eye(6), atol=1e-13)
    np.testing.assert_allclose(V @ np.diag(np.diag(A)) @ V.T, S, atol=1e-13 * scale)


def test_boxplus_with_precomputed_trig_equals_boxplus():
    """_boxplus_pre (series for the mid-latitude shift) equals boxplus to 1e-15 rad (6 nm:
    round-off of the angle addition), for moves up to 2 km and for a 50 km move (direct
    fallback, identical)."""
    for _ in range(200):
        lat = RNG.uniform(-1.4, 1.4)
        lon = RNG.uniform(-3.0, 3.0)
        h = RNG.uniform(-100.0, 12000.0)
        dn, de = RNG.uniform(-2000.0, 2000.0, 2)
        mr, nr = core.radii(lat, 0.0)
        a = sns_output._boxplus_pre(lat, lon, np.sin(lat), np.cos(lat), mr, nr, dn, de, h)
        b = core.boxplus(lat, lon, dn, de, h)
        assert abs(a[0] - b[0]) < 1e-15 and abs(a[1] - b[1]) < 1e-15
    a = sns_output._boxplus_pre(0.7, 0.1, np.sin(0.7), np.cos(0.7), *core.radii(0.7, 0.0), 5e4, 1e3,
                          0.0)
    assert a == core.boxplus(0.7, 0.1, 5e4, 1e3, 0.0)


def test_integrate_readings_equals_numpy_cumsum():
    """One compiled pass gives bit-identical cumulative sums (same additions, same order)."""
    M = 1001
    t = np.cumsum(RNG.uniform(0.05, 0.07, M))
    a, u, w = (RNG.normal(size=(M, 2)) for _ in range(3))
    IA, IU, IW, CQ = core.integrate_readings(t, a, u, w)
    for v, I in ((a, IA), (u, IU), (w, IW)):
        ref = np.zeros_like(v)
        ref[1:] = np.cumsum(v[:-1] * np.diff(t)[:, None], axis=0)
        assert np.array_equal(I, ref)
    dts = np.append(np.diff(t), 0.0)[:, None] ** 2
    ja = np.column_stack([-a[:, 1], a[:, 0]])
    qs = dts * np.column_stack([u[:, 0] ** 2, u[:, 0] * u[:, 1], u[:, 1] ** 2, ja[:, 0] ** 2,
                                ja[:, 0] * ja[:, 1], ja[:, 1] ** 2, np.ones(M)])
    assert np.array_equal(CQ, np.vstack([np.zeros((1, 7)), np.cumsum(qs, axis=0)]))


def test_lever_arm_on_needed_rows_equals_full_grid(flight16):
    """The lever arm and its derivative at the fixes from the needed rows only equal
    np.interp of lever_arm_ne / np.gradient on the whole grid (1e-12 m, 1e-12 m/s), including
    fixes on the first and last samples."""
    sim, _ = flight16
    grid = sim.clean.grid
    t = grid["t_s"].to_numpy(float)
    tf = np.concatenate([[t[0], t[1] + 0.01], sim.clean.gnss["t_s"].to_numpy(float), [t[-1]]])
    tf = np.sort(tf[(tf >= t[0]) & (tf <= t[-1])])
    jf = np.clip(np.searchsorted(t, tf, side="right") - 1, 0, len(t) - 1)
    lever = (6.0, 0.5, -2.0)
    arm_f, darm_f = sns_method.lever_arm_at_fixes(grid, t, tf, jf, lever)
    arm = sns_method.lever_arm_ne(grid, lever)
    darm = np.gradient(arm, t, axis=0)
    for i in range(2):
        np.testing.assert_allclose(arm_f[:, i], np.interp(tf, t, arm[:, i]), atol=1e-12)
        np.testing.assert_allclose(darm_f[:, i], np.interp(tf, t, darm[:, i]), atol=1e-12)


def _densify_reference(sol, t, IA, IU, IW, a, u, w, rows):
    """Per-sample densify as first written: tangent-plane blend through boxminus/boxplus."""
    xs, Ps, tk = sol.smoothed.x, sol.smoothed.P, sol.inputs.t
    idx = sol.idx
    sig = np.asarray(sol.noise.sensor_sd, float)
    N = len(idx)
    out_lat, out_lon, out_v, out_Pv = [], [], [], []
    for j in rows:
        k = min(int(np.searchsorted(idx, j, side="right") - 1), N - 1)
        k1 = min(k + 1, N - 1)
        c = xs[k, 2:5].copy()
        d1, _, _ = core.increment(sol.model, c, IA[j] - IA[idx[k]], IU[j] - IU[idx[k]],
                                  IW[j] - IW[idx[k]], t[j] - tk[k], sig)
        la, lo = core.boxplus(xs[k, 0], xs[k, 1], d1[0], d1[1], sol.h[j])
        if k < N - 1:
            wgt = (t[j] - tk[k]) / (tk[k1] - tk[k])
            d2, _, _ = core.increment(sol.model, c, IA[idx[k1]] - IA[j], IU[idx[k1]] - IU[j],
                                      IW[idx[k1]] - IW[j], tk[k1] - t[j], sig)
            la2, lo2 = core.boxplus(xs[k1, 0], xs[k1, 1], -d2[0], -d2[1], sol.h[j])
            dn, de = core.boxminus(la2, lo2, la, lo, sol.h[j])
            la, lo = core.boxplus(la, lo, wgt * dn, wgt * de, sol.h[j])
        vv, Jv, Gv = core.increment(sol.model, c, a[j], u[j], w[j], 1.0, sig)
        out_lat.append(la)
        out_lon.append(lo)
        out_v.append(vv)
        out_Pv.append(Jv @ Ps[k, 2:5, 2:5] @ Jv.T + Gv @ Gv.T)
    return np.array(out_lat), np.array(out_lon), np.array(out_v), np.array(out_Pv)


def test_densify_matches_tangent_plane_blend(flight16):
    """The compiled densify (linear latitude/longitude blend, pre-computed trigonometry) equals
    the per-sample reference with the tangent-plane blend on 2000 samples of a 16 Hz flight
    (and the last 20): positions to 2e-15 rad (1e-8 m; the two dead-reckoned positions differ by
    millimetres, over which the blends differ by 1e-9 relative), velocities to 1e-12 m/s, their
    covariance to 1e-12 relative."""
    sim, sol = flight16
    grid = sim.clean.grid
    t = grid["t_s"].to_numpy(float)
    a, u, w = sns_method.held_readings(grid, sol.model, [])
    IA, IU, IW, _ = core.integrate_readings(t, a, u, w)
    rows = np.r_[3000:5000, len(t) - 20:len(t)]
    lat, lon, v, Pv = _densify_reference(sol, t, IA, IU, IW, a, u, w, rows)
    np.testing.assert_allclose(sol.lat[rows], lat, rtol=0, atol=2e-15)
    np.testing.assert_allclose(sol.lon[rows], lon, rtol=0, atol=2e-15)
    np.testing.assert_allclose(sol.v_ne[rows], v, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sol.P_v[rows], Pv, rtol=1e-12, atol=1e-15)


def test_decimated_meridian_convergence_matches_every_sample(flight16, monkeypatch):
    """Position sds with the convergence angle from pyproj every 16 samples (interpolated)
    equal those with it at every sample to 1e-8 relative (interpolation error of a smooth
    angle over 250 m, 2e-10 rad, times the anisotropy of P; measured on the 10-hour flight:
    2.4e-8 relative at worst); positions identical."""
    sim, _ = flight16
    res = run_sns(sim.clean)
    monkeypatch.setattr(sns_method, "GAMMA_STRIDE", 1)
    ref = run_sns(sim.clean)
    for c in ("sns_north_m", "sns_east_m", "sns_vn_mps", "sns_ve_mps"):
        assert np.array_equal(res.track[c].to_numpy(), ref.track[c].to_numpy())
    for c in ("sns_north_sd_m", "sns_east_sd_m"):
        np.testing.assert_allclose(res.track[c], ref.track[c], rtol=1e-8)


def test_track_block_is_a_plain_float_frame(flight16):
    """The track built from one block has the documented columns, float64, no NaN, and the
    plane positions equal a direct pyproj conversion of the smoothed lat/lon."""
    sim, sol = flight16
    res = run_sns(sim.clean)
    assert tuple(res.track.columns) == sns_method.TRACK_COLUMNS
    assert all(res.track.dtypes == np.float64)
    assert np.isfinite(res.track.to_numpy()).all()
    e, n, _ = output_plane(sim.clean.meta).forward(np.rad2deg(sol.lat), np.rad2deg(sol.lon),
                                                   sol.h)
    assert np.array_equal(res.track["sns_north_m"].to_numpy(), n)
    assert np.array_equal(res.track["sns_east_m"].to_numpy(), e)


def test_pinv_rejects_non_finite_matrix():
    """A NaN in S raises LinAlgError (as LAPACK's eigh did), which run_sns reports as a
    ConvergenceError instead of spreading NaN silently."""
    S = np.eye(4)
    S[1, 2] = S[2, 1] = np.nan
    with pytest.raises(np.linalg.LinAlgError):
        core.pinv_sym(S, 1e-10)

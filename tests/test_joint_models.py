"""Joint smoother: measurement Jacobians against finite differences, transition consistency."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flightrecon.estimation import predict as est_predict
from flightrecon.estimation import rts as est_rts
from flightrecon.estimation.manifold import EUCLIDEAN
from flightrecon.geo.frames import geodetic_to_ecef
from flightrecon.geo.navframe import ned_to_ecef_matrix
from flightrecon.methods.joint import enu_to_ecef_matrix
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint import model as jd
from flightrecon.methods.joint import model as jo
from flightrecon.methods.joint import solve as jp


def _measure(j, k, x, *args):
    """h(x) and its gradient of measurement j at step k (the kernel's ``measure_into``)."""
    H = np.empty(jl.N_STATE)
    return jo.measure_into(H, j, k, x, *args), H


def _transition(*args):
    """The transition matrix F_k (the kernel's ``transition_into``)."""
    F = np.empty((jl.N_STATE, jl.N_STATE))
    jd.transition_into(F, *args)
    return F


def _setup(rng):
    lat, lon, h = 40.4, 49.9, 3000.0
    ex, ey, ez = geodetic_to_ecef(lat, lon, h)
    p = np.array([float(ex), float(ey), float(ez)])
    Cen = ned_to_ecef_matrix(np.array([lat]), np.array([lon]))
    x = np.zeros(jl.N_STATE)
    x[jl.IP:jl.IP + 3] = p + rng.normal(0, 50, 3)
    x[jl.IV:jl.IV + 3] = [150.0, -80.0, -5.0]
    x[jl.IW:jl.IW + 2] = [10.0, -7.0]
    x[jl.IPSI] = np.radians(1.2)
    x[jl.IS] = 0.02
    x[jl.IBH] = 12.0
    x[jl.IC] = 0.03
    x[jl.IDW] = 0.01
    x[jl.IDC] = np.radians(0.4)
    x[jl.S_GUST] = [1.8, -2.4]   # a gust: the air data see v - w - u
    st = (40.3, 49.7, 20.0)
    sx, sy, sz = geodetic_to_ecef(*st)
    pst = np.array([float(sx), float(sy), float(sz)])
    Cst = enu_to_ecef_matrix(st[0], st[1])
    return x, p, Cen, pst, Cst, h


@pytest.mark.parametrize("mtype", [jl.LINEAR, jl.RANGE, jl.AZIMUTH, jl.ELEVATION, jl.TAS,
                                   jl.HEADING, jl.BARO, jl.DOPPLER, jl.TRACK, jl.NED_POS,
                                   jl.STATE])
def test_measurement_jacobian_vs_central_differences(mtype):
    rng = np.random.default_rng(mtype)
    x, p, Cen, pst, Cst, h = _setup(rng)
    mH = rng.normal(size=(1, jl.N_STATE))
    # the row index: LINEAR's row of mH, NED_POS's axis (down), STATE's index (east velocity)
    row = {jl.NED_POS: 2, jl.STATE: jl.IV + 1}.get(mtype, 0)
    args = (np.array([mtype]), np.zeros(1), np.array([0.37]), mH, np.array([row]),
            np.array([1.5]), Cen,
            p[None, :], np.array([h - 10.0]), pst, Cst)
    hx, H = _measure(0, 0, x, *args)
    num = np.empty(jl.N_STATE)
    for i in range(jl.N_STATE):
        step = 1e-3 * max(1.0, abs(x[i])) if i >= 3 else 1e-2
        xp, xm = x.copy(), x.copy()
        xp[i] += step
        xm[i] -= step
        num[i] = (_measure(0, 0, xp, *args)[0] - _measure(0, 0, xm, *args)[0]) / (2 * step)
    scale = np.max(np.abs(H)) + 1e-30
    # central differences: truncation O(step^2) on smooth functions; 1e-6 of the largest
    # gradient component is far above rounding (ECEF coordinates ~6e6 m, eps 1e-16)
    np.testing.assert_allclose(num, H, atol=1e-6 * scale, rtol=1e-5)


def test_transition_propagates_held_acceleration():
    """With no biases, one step moves p by C(v dt + dP) and v by dV (the input increments)."""
    rng = np.random.default_rng(3)
    x, p, Cen, *_ = _setup(rng)
    x[jl.IBA:] = 0.0
    x[jl.IG:jl.IG + 2] = [0.004, -0.002]   # wind gradient with height [(m/s)/m]
    N = 2
    dt = np.array([0.0, 0.25])
    Cen2 = np.repeat(Cen, N, axis=0)
    Cnb = np.repeat(np.eye(3)[None], N, axis=0)
    acc = np.array([[0, 0, 0], [0.4, -0.2, 0.1]])
    Csf = np.zeros((N, 3, 3))
    dz = np.array([0.0, 30.0])        # the nominal climbs 30 m over the step
    x[jl.S_GUST] = [1.5, -0.5]
    ga = np.array([1.0, 0.9])          # the gust decays by 0.9 over the step
    F = _transition(1, dt, Cen2, Cnb, Csf, np.zeros((N, 3, 2)), acc, 3600.0, dz, ga)
    xn = F @ x
    np.testing.assert_allclose(xn[jl.S_GUST], 0.9 * x[jl.S_GUST], atol=1e-15)
    np.testing.assert_allclose(xn[jl.IP:jl.IP + 3], x[jl.IP:jl.IP + 3] + Cen[0] @ x[3:6] * 0.25,
                               atol=1e-9)
    np.testing.assert_allclose(xn[3:6], x[3:6], atol=1e-12)
    # the wind moves along its gradient with height: w+ = w + g dz
    np.testing.assert_allclose(xn[jl.IW:jl.IW + 2],
                               x[jl.IW:jl.IW + 2] + 30.0 * x[jl.IG:jl.IG + 2], atol=1e-12)
    np.testing.assert_array_equal(xn[jl.IG:jl.IG + 2], x[jl.IG:jl.IG + 2])
    # heading bias of +1 mrad rotates the measured acceleration: true a_N = a_N + a_E dpsi
    y = np.zeros(jl.N_STATE)
    y[jl.IPSI] = 1e-3
    dv = (F @ y)[3:6]
    np.testing.assert_allclose(dv, [acc[1, 1] * 1e-3 * 0.25, -acc[1, 0] * 1e-3 * 0.25, 0.0])


def _random_spd(rng, n):
    A = rng.normal(size=(n, n))
    return A @ A.T + n * np.eye(n)


def test_sparse_prediction_equals_dense_products():
    """P <- F P F^T with the row-compressed F equals the dense product (round-off only)."""
    rng = np.random.default_rng(11)
    x, p, Cen, *_ = _setup(rng)
    N = 2
    dt = np.array([0.0, 1.0])
    Cen2 = np.repeat(Cen, N, axis=0)
    Cnb = np.repeat(ned_to_ecef_matrix(np.array([10.0]), np.array([20.0])), N, axis=0)
    Csf = rng.normal(size=(N, 3, 3))
    acc = rng.normal(size=(N, 3))
    F = _transition(1, dt, Cen2, Cnb, Csf, np.zeros((N, 3, 2)), acc, 3600.0,
                      rng.normal(size=N) * 20.0, np.array([1.0, 0.8]))
    n = jl.N_STATE
    cols = np.empty((n, n), np.int64)
    vals = np.empty((n, n))
    cnt = np.empty(n, np.int64)
    est_predict.sparse_rows(F, cols, vals, cnt)
    assert cnt.sum() == np.count_nonzero(F)
    P = _random_spd(rng, n)
    want = F @ P @ F.T
    got = P.copy()
    est_predict.predict_cov_sparse(got, cols, vals, cnt, np.empty((n, n)))
    # entries up to ~1e2 * 1e2; 1e-12 relative is a few ulps of the largest term summed
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
    assert np.array_equal(got, got.T)
    y = rng.normal(size=n)
    out = np.empty(n)
    est_predict.sparse_matvec(cols, vals, cnt, y, out)
    np.testing.assert_allclose(out, F @ y, rtol=1e-13, atol=1e-13 * np.abs(F @ y).max())
    est_predict.sparse_rmatvec(cols, vals, cnt, y, out)
    np.testing.assert_allclose(out, F.T @ y, rtol=1e-13, atol=1e-13 * np.abs(F.T @ y).max())


def test_cholesky_solve_and_its_refusal():
    """The core's mean-step solve y = A^-1 (b - 0): by Cholesky for a positive-definite A; for
    an indefinite (regular) A it says so (returns False, the caller counts it) and still
    solves, by LU."""
    rng = np.random.default_rng(5)
    n = jl.N_STATE
    A = _random_spd(rng, n)
    b = rng.normal(size=n)
    y = np.empty(n)
    zero = np.zeros(n)
    L, d = np.empty((n, n)), np.empty(n)
    assert est_rts.rts_mean_solve(EUCLIDEAN, zero, A, b, 0.0, 0.0, L, d, y)
    # condition number of A is O(10): 1e-12 is far above round-off, far below any real error
    np.testing.assert_allclose(A @ y, b, atol=1e-12)
    A[3, 3] = -1.0
    assert not est_rts.rts_mean_solve(EUCLIDEAN, zero, A, b, 0.0, 0.0, L, d, y)
    np.testing.assert_allclose(A @ y, b, atol=1e-10)


def test_mean_only_backward_pass_gives_the_covariance_pass_states():
    """The Gauss-Newton iterations use the mean-only RTS pass; the final covariance pass must
    reproduce its states (same gains, same linearisation) to round-off."""
    from pathlib import Path

    from flightrecon.cleaning import clean_flight
    from flightrecon.ingest import load_flight
    from flightrecon.methods.joint import JointSettings, problem_of, smooth_joint
    from flightrecon.methods.joint.problem import joint_inputs

    log = Path(__file__).resolve().parents[1] / "sample_logs" / "circuit.parquet"
    run = smooth_joint(problem_of(joint_inputs(clean_flight(load_flight(log))),
                                  JointSettings(iterations=1)))
    # run.lat/lon/h: geodetic of the mean-only pass; run.x: states of the covariance pass
    ex, ey, ez = geodetic_to_ecef(run.lat_deg, run.lon_deg, run.h_m)
    # pyproj's geodetic round trip is good to ~1e-9 m; Cholesky vs LU solves differ by
    # round-off times the condition number of P_p (ECEF variances 1e6 .. angles 1e-10): 1 mm
    np.testing.assert_allclose(np.c_[ex, ey, ez], run.x[:, :3], rtol=0, atol=1e-3)


def test_attitude_jacobian_against_central_differences():
    """d(C_nb f)/d(roll, pitch) of joint.attitude_jacobian vs differences of body_to_ned_matrix."""
    from flightrecon.geo.kinematics import body_to_ned_matrix
    from flightrecon.methods.joint import attitude_jacobian

    rng = np.random.default_rng(4)
    roll, pitch, hdg = rng.uniform(-50, 50, 20), rng.uniform(-25, 25, 20), rng.uniform(0, 360, 20)
    f = rng.normal(0, 1, (20, 3))
    J = attitude_jacobian(body_to_ned_matrix(roll, pitch, hdg), f)
    h = 1e-4  # deg; central differences: truncation ~ (h in rad)^2 ~ 3e-12 relative
    for col, (dr, dp) in enumerate(((h, 0.0), (0.0, h))):
        cp = np.einsum("kij,kj->ki", body_to_ned_matrix(roll + dr, pitch + dp, hdg), f)
        cm = np.einsum("kij,kj->ki", body_to_ned_matrix(roll - dr, pitch - dp, hdg), f)
        num = (cp - cm) / (2 * np.radians(h))
        np.testing.assert_allclose(J[:, :, col], num, atol=1e-7)


def test_transition_applies_attitude_biases_with_the_right_sign():
    """A pitch bias of +1 mrad (measured nose-up too much) over one 1 s step: the true velocity
    change is the measured one minus g0 dC/dtheta f * 1e-3 * dt."""
    rng = np.random.default_rng(6)
    x, p, Cen, *_ = _setup(rng)
    N = 2
    dt = np.array([0.0, 1.0])
    Cen2 = np.repeat(Cen, N, axis=0)
    Cnb = np.repeat(np.eye(3)[None], N, axis=0)
    Jatt = np.zeros((N, 3, 2))
    Jatt[1, :, 1] = [-1.0, 0.0, 0.0]  # level, f = (0, 0, -1) g: dC/dtheta f = (-1, 0, 0)
    F = _transition(1, dt, Cen2, Cnb, np.zeros((N, 3, 3)), Jatt, np.zeros((N, 3)), 3600.0,
                      np.zeros(N), np.ones(N))
    y = np.zeros(jl.N_STATE)
    y[jl.IATT + 1] = 1e-3
    # measured pitch too high by 1 mrad tilts the measured specific force backward: the true
    # acceleration is g0 * 1e-3 further north than measured
    np.testing.assert_allclose((F @ y)[3:6], [jl.G0 * 1e-3, 0.0, 0.0], atol=1e-15)


def _step_mean(x, idx, t_in):
    """Reference: the mean over each state step weighted by the samples' centred holds (the
    samples idx[k-1] .. idx[k], each end for half its interval; nominal._half_holds),
    non-finite values as zero, the sample itself for a step that holds none (the first)."""
    Ni, N = len(t_in), len(idx)
    d = np.diff(t_in, append=t_in[-1])
    k_r = np.searchsorted(idx, np.arange(Ni), side="right")
    k_l = np.r_[N, k_r[:-1]]
    w_r, w_l = 0.5 * d, 0.5 * np.r_[0.0, d[:-1]]
    cnt = np.zeros(N)
    for k_h, w_h in ((k_r, w_r), (k_l, w_l)):
        ok = k_h < N
        cnt += np.bincount(k_h[ok], weights=w_h[ok], minlength=N)[:N]
    flat = x.reshape(Ni, -1)
    out = np.zeros((N, flat.shape[1]))
    for j in range(flat.shape[1]):
        v = np.where(np.isfinite(flat[:, j]), flat[:, j], 0.0)
        for k_h, w_h in ((k_r, w_r), (k_l, w_l)):
            ok = k_h < N
            out[:, j] += np.bincount(k_h[ok], weights=(v * w_h)[ok], minlength=N)[:N]
    out /= np.where(cnt > 0, cnt, 1.0)[:, None]
    out[cnt == 0] = flat[np.minimum(idx[cnt == 0], Ni - 1)]
    return out.reshape((N,) + x.shape[1:])


def test_fused_attitude_step_means_equal_the_per_sample_route():
    from flightrecon.geo.kinematics import body_to_ned_matrix
    from flightrecon.methods.joint.linearisation import (
        attitude_jacobian,
        attitude_step_means,
        state_grid,
    )

    rng = np.random.default_rng(9)
    n = 1000
    t = np.arange(n) / 16.0
    C = body_to_ned_matrix(rng.uniform(-40, 40, n), rng.uniform(-15, 15, n),
                           rng.uniform(0, 360, n))
    f = rng.normal(0, 1, (n, 3))
    idx = state_grid(t, 1.0)
    Cm, Sm, Jm = attitude_step_means(C, f, idx, t)
    # same sums in a different order: a few ulps of O(1) values
    np.testing.assert_allclose(Cm, _step_mean(C, idx, t), atol=1e-13)
    np.testing.assert_allclose(Sm, _step_mean(C * f[:, None, :], idx, t), atol=1e-13)
    np.testing.assert_allclose(Jm, _step_mean(attitude_jacobian(C, f), idx, t), atol=1e-13)


def test_hermite_interpolation_is_exact_for_cubics_and_matches_the_formula():
    """Positions of a cubic path with exact velocities are reproduced to round-off."""
    from flightrecon.methods.joint.solve import hermite_positions

    T = np.array([0.0, 1.0, 2.5, 4.0])
    t = np.linspace(-0.5, 4.5, 41)   # includes points outside (clamped to the ends)

    def path(tt):
        return np.c_[tt ** 3 - 2 * tt, 0.5 * tt ** 2, 3.0 + 0 * tt]

    def vel(tt):
        return np.c_[3 * tt ** 2 - 2, tt, 0 * tt]

    got = hermite_positions(t, T, path(T), vel(T))
    inside = (t >= 0) & (t <= 4)
    np.testing.assert_allclose(got[inside], path(t[inside]), atol=1e-12)
    np.testing.assert_allclose(got[t < 0], np.repeat(path(T[:1]), (t < 0).sum(), 0), atol=1e-12)


@pytest.fixture(scope="module")
def captured_passes():
    """The forward and (mean-only) backward kernels' arguments of one joint pass on the circuit
    sample: ``fw`` (bufs, x0, P0, dyn, meas, geo, gate, xlin, clock), ``bw`` (bufs, dyn, meas,
    geo)."""
    from pathlib import Path

    import flightrecon.methods.joint as J
    from flightrecon.cleaning import clean_flight
    from flightrecon.ingest import load_flight
    from flightrecon.methods.joint.problem import joint_inputs

    log = Path(__file__).resolve().parents[1] / "sample_logs" / "circuit.parquet"
    inp = joint_inputs(clean_flight(load_flight(log)))
    cap = {}
    orig_fw, orig_bw = jp.forward, jp.backward

    def fw(*a):
        cap["fw"] = a
        return orig_fw(*a)

    def bw(*a):
        if not a[4]:                 # the mean-only pass (the covariance pass runs beside it)
            cap["bw"] = a[:4]
        return orig_bw(*a)

    mp = pytest.MonkeyPatch()
    mp.setattr(jp, "forward", fw)
    mp.setattr(jp, "backward", bw)
    try:
        J.smooth_joint(J.problem_of(inp, J.JointSettings(iterations=1)))
    finally:
        mp.undo()
    return cap


def _refiltered(cap, store_predicted=True):
    """The captured forward pass run again into fresh buffers (``Pp`` kept or not); returns
    the buffers and the backward pass's layouts."""
    a = list(cap["fw"])
    a[0] = jp.filter_buffers(len(a[0][0]), store_predicted)
    jp.forward(*a)
    return a[0], cap["bw"][1:]


def test_backward_passes_count_cholesky_failures(captured_passes):
    """Regression: where a predicted covariance was not positive definite the backward passes
    fell back to a general solve without a word.  They now count those steps (reported in the
    summary as ``cholesky_fallbacks``): zero on the circuit, one after making one P_p[k+1]
    indefinite (one diagonal entry negated), in both the mean and the covariance pass."""
    bufs, b = _refiltered(captured_passes)
    assert jp.backward(bufs, *b, False).cholesky_fallbacks == 0
    assert jp.backward(bufs, *b, True).cholesky_fallbacks == 0
    bad = bufs[3].copy()
    k = len(bad) // 2
    i = jl.IBH * (jl.IBH + 1) // 2 + jl.IBH    # (IBH, IBH) in the packed lower triangle
    bad[k, i] = -bad[k, i]
    bad_bufs = (*bufs[:3], bad)
    assert jp.backward(bad_bufs, *b, False).cholesky_fallbacks == 1
    assert jp.backward(bad_bufs, *b, True, False).cholesky_fallbacks == 1


def test_recomputed_predicted_covariances_give_bit_identical_smoothing(captured_passes):
    """The backward passes recompute P_p[k+1] from P_f[k] (not stored): with the stored ones
    the smoothed states, covariances and residuals must be bit for bit the same."""
    bufs, b = _refiltered(captured_passes)
    no_pp = (*bufs[:3], jp.filter_buffers(len(bufs[0]), store_predicted=False)[3])
    with_pp, without = jp.backward(bufs, *b, True), jp.backward(no_pp, *b, True)
    np.testing.assert_array_equal(with_pp.x, without.x)
    for name in ("Pblk", "var", "res_n", "res", "rate", "hph"):
        np.testing.assert_array_equal(getattr(with_pp.model, name),
                                      getattr(without.model, name))
    np.testing.assert_array_equal(jp.backward(no_pp, *b, False).x,
                                  jp.backward(bufs, *b, False).x)
    # the covariance pass with and without residuals: the same covariances
    no_res = jp.backward(bufs, *b, True, False)
    np.testing.assert_array_equal(no_res.model.Pblk, with_pp.model.Pblk)
    np.testing.assert_array_equal(no_res.model.var, with_pp.model.var)


def test_joint_passes_equal_a_dense_numpy_rts_on_the_real_model(captured_passes):
    """The joint smoother's backward passes (on the core's sparse C^T and RTS step) against the
    textbook RTS in dense numpy on the same forward run of the circuit sample: the 24-state
    transitions built densely by ``dynamics.transition``, ``C = P_f F^T inv(P_p)``.  Smoothed
    states and position-velocity covariances of the covariance pass, states of the mean-only
    pass, to 1e-9 of the smoothed standard deviation (900 steps, condition numbers of P_p up to
    1e12: the two agree to 4e-12 sd in the states and 5e-11 in the variances; 1e-9 is above that
    rounding and far below any error in the step, e.g. a transposed F or a missed P_p)."""
    from flightrecon.estimation.linalg import unpack_sym

    n = jl.N_STATE
    bufs, b = _refiltered(captured_passes)
    xf, Pf_packed, xp, Pp_packed = bufs
    N = len(xf)
    dyn = b[0]
    cov = jp.backward(bufs, *b, True)
    xs, Pblk, var = cov.x, cov.model.Pblk, cov.model.var
    xm = jp.backward(bufs, *b, False).x
    Pf, Pp = np.empty((N, n, n)), np.empty((N, n, n))
    for k in range(N):
        unpack_sym(Pf_packed[k], Pf[k])
        unpack_sym(Pp_packed[k], Pp[k])
    dt, Cen, Cnb, Csf, Jatt, acc, dP, dV, dz, qv_extra, q, ga = dyn
    ref_x, ref_P = xf.copy(), Pf.copy()
    for k in range(N - 2, -1, -1):
        F = _transition(k + 1, dt, Cen, Cnb, Csf, Jatt, acc, q[4], dz, ga)
        C = Pf[k] @ F.T @ np.linalg.inv(Pp[k + 1])
        ref_x[k] = xf[k] + C @ (ref_x[k + 1] - xp[k + 1])
        ref_P[k] = Pf[k] + C @ (ref_P[k + 1] - Pp[k + 1]) @ C.T
    sd = np.sqrt(np.diagonal(ref_P, axis1=1, axis2=2))
    np.testing.assert_allclose((xs - ref_x) / sd, 0.0, atol=1e-9)
    np.testing.assert_allclose((xm - ref_x) / sd, 0.0, atol=1e-9)
    np.testing.assert_allclose(var / sd**2, 1.0, atol=1e-9)
    blk = sd[:, :6, None] * sd[:, None, :6]
    np.testing.assert_allclose(Pblk / blk, ref_P[:, :6, :6] / blk, atol=1e-9)


def test_gust_process_noise_keeps_the_stationary_variance():
    """Guards the exact discretisation of the first-order Gauss-Markov gust (docs/joint.md,
    "Wind and turbulence"): from its stationary variance sigma^2, one step of any length keeps
    sigma^2 (F P F^T + Q = a^2 s^2 + s^2 (1 - a^2)); the other states' noise is unchanged."""
    from flightrecon.methods.joint.linearisation import gust_decay, q_vector
    from flightrecon.methods.joint.settings import JointNoise
    nz = JointNoise(gust_mps=2.5, gust_length_m=400.0)
    q = q_vector(nz)
    rng = np.random.default_rng(5)
    _, _, Cen, *_ = _setup(rng)
    for h, v in ((0.25, 60.0), (1.0, 230.0), (5.0, 10.0)):
        dt = np.array([0.0, h])
        ga = gust_decay(dt, np.array([np.nan, v]), nz, 30.0)
        a = np.exp(-h * max(v, 30.0) / 400.0)
        assert ga[0] == 1.0 and abs(ga[1] - a) < 1e-15
        N = 2
        F = _transition(1, dt, np.repeat(Cen, N, axis=0), np.repeat(np.eye(3)[None], N, 0),
                          np.zeros((N, 3, 3)), np.zeros((N, 3, 2)), np.zeros((N, 3)), 3600.0,
                          np.zeros(N), ga)
        P = np.zeros((jl.N_STATE, jl.N_STATE))
        P[jl.S_GUST, jl.S_GUST] = np.eye(2) * 2.5 ** 2
        P = F @ P @ F.T
        jd.add_process_noise(P, 1, dt, np.repeat(Cen, N, axis=0), np.zeros(N), np.zeros(N), q, ga)
        np.testing.assert_allclose(np.diag(P)[jl.S_GUST], 2.5 ** 2, rtol=1e-12)
        assert P[jl.IGU, jl.IGU + 1] == 0.0


def test_compact_linear_rows_equal_the_stored_rows():
    """Guards the compact GNSS rows (docs/performance.md, memory): a NED_POS measurement (axis
    i, no stored row) gives the same h and gradient as the LINEAR row it replaced,
    H[p] = column i of C_en at the step, H[v_i] = tau, and a STATE measurement as the unit
    row of its state, to rounding (the products are of ECEF coordinates, 6e6 m: summed in
    another order they differ by a few 1e-9 m; 1e-8 m)."""
    rng = np.random.default_rng(3)
    x, p, Cen, pst, Cst, h = _setup(rng)
    for axis in range(3):
        row = np.zeros((1, jl.N_STATE))
        row[0, jl.S_POS] = Cen[0][:, axis]
        row[0, jl.IV + axis] = 0.37
        common = (np.zeros(1), np.array([0.37]))
        geo = (np.array([4.5]), Cen, p[None, :], np.array([h]), pst, Cst)
        lin = _measure(0, 0, x, np.array([jl.LINEAR]), *common, row, np.zeros(1, np.int64),
                         *geo)
        ned = _measure(0, 0, x, np.array([jl.NED_POS]), *common, np.zeros((0, jl.N_STATE)),
                         np.array([axis]), *geo)
        assert ned[0] == pytest.approx(lin[0], abs=1e-8)
        np.testing.assert_allclose(ned[1], lin[1], rtol=0, atol=1e-15)
    unit = np.zeros((1, jl.N_STATE))
    unit[0, jl.IV + 1] = 1.0
    geo = (np.array([0.2]), Cen, p[None, :], np.array([h]), pst, Cst)
    lin = _measure(0, 0, x, np.array([jl.LINEAR]), np.zeros(1), np.zeros(1), unit,
                     np.zeros(1, np.int64), *geo)
    st = _measure(0, 0, x, np.array([jl.STATE]), np.zeros(1), np.zeros(1),
                    np.zeros((0, jl.N_STATE)), np.array([jl.IV + 1]), *geo)
    assert st[0] == lin[0]
    np.testing.assert_array_equal(st[1], lin[1])


def test_gust_is_seen_by_the_air_data_only():
    """Guards the air-data model with turbulence (docs/joint.md, "Wind and turbulence"): the
    along-track gust adds to the airspeed in m/s whatever the airspeed scale, the cross-track
    gust turns the heading by u_c / V with V the recorded airspeed (the measurement's d), so
    neither gets cheaper as the scale error grows; the ground-referenced Doppler and track do
    not see the gust."""
    rng = np.random.default_rng(8)
    x, p, Cen, pst, Cst, h = _setup(rng)
    V = 57.0
    for mtype in (jl.TAS, jl.HEADING, jl.DOPPLER, jl.TRACK):
        args = (np.array([mtype]), np.zeros(1), np.array([0.0]), np.zeros((1, jl.N_STATE)),
                np.zeros(1, np.int64), np.array([V]), Cen, p[None, :], np.array([h]), pst, Cst)
        hx, H = _measure(0, 0, x, *args)
        y = x.copy()
        y[jl.S_GUST] += [0.7, -0.3]
        y[jl.IS] += 0.5          # a larger scale error does not change the gust's effect
        z = x.copy()
        z[jl.IS] += 0.5
        d_gust = _measure(0, 0, y, *args)[0] - _measure(0, 0, z, *args)[0]
        if mtype == jl.TAS:
            np.testing.assert_array_equal(H[jl.S_GUST], [1.0, 0.0])
            assert d_gust == pytest.approx(0.7, rel=1e-12)
        elif mtype == jl.HEADING:
            np.testing.assert_allclose(H[jl.S_GUST], [0.0, 1.0 / V], rtol=1e-15)
            assert d_gust == pytest.approx(-0.3 / V, rel=1e-12)
        else:
            assert not H[jl.S_GUST].any() and d_gust == 0.0


def test_heading_kept_only_where_the_nose_is_along_the_air():
    """Guards the air-data heading's attitude gate (docs/joint.md, "Measurements"): in a
    spiral dive or a spin the nose is not along the air velocity, and the heading must not be
    used as its direction; level and moderately banked samples keep it."""
    from flightrecon.methods.joint.measurements import nose_along_air
    from flightrecon.methods.joint.settings import JointSettings

    # a roll of 190 deg is -170 deg, a pitch of 151 deg (past the vertical) is 29 deg inverted
    roll = np.array([0.0, 30.0, -44.0, 60.0, -75.0, 10.0, 5.0, 170.0, 330.0, 190.0, 0.0])
    pitch = np.array([0.0, 5.0, -10.0, 0.0, -20.0, -45.0, 29.0, 0.0, 0.0, 0.0, 151.0])
    att = np.c_[roll, pitch, np.full(len(roll), 123.0)]
    keep = nose_along_air(att, JointSettings())
    np.testing.assert_array_equal(keep, [True, True, True, False, False, False, True, False,
                                         True, False, False])


@settings(max_examples=60, deadline=None)
@given(roll=st.floats(-45.0, 45.0), pitch=st.floats(-20.0, 25.0), alpha=st.floats(-4.0, 15.0),
       heading=st.floats(0.0, 360.0), tas=st.floats(35.0, 250.0))
def test_nose_offset_is_the_angle_between_nose_and_air_velocity(roll, pitch, alpha, heading,
                                                                  tas):
    """Guards the heading's angle-of-attack offset (docs/joint.md, "Measurements"): the
    offset that :func:`nose_offset` derives from attitude, pressure-altitude rate and airspeed
    is the angle between the heading and the horizontal direction of the air velocity
    C (cos a, 0, sin a) V, for any attitude inside the heading's gate (rotation computed
    independently with :func:`body_to_ned_matrix`)."""
    import pandas as pd

    from flightrecon.geo.kinematics import body_to_ned_matrix
    from flightrecon.methods.joint.inputs import JointInputs
    from flightrecon.methods.joint.measurements import nose_offset

    C = body_to_ned_matrix(roll, pitch, heading)[0]
    a = np.radians(alpha)
    v = C @ np.array([np.cos(a), 0.0, np.sin(a)]) * tas
    want = np.angle(np.exp(1j * (np.radians(heading) - np.arctan2(v[1], v[0]))))
    t = np.arange(0.0, 10.0, 0.0625)
    n = len(t)
    inp = JointInputs(t_in=t, acc_ned=np.zeros((n, 3)),
                      attitude_deg=np.tile([roll, pitch, heading], (n, 1)),
                      tas=np.full(n, tas), heading_rad=np.full(n, np.radians(heading)),
                      baro_rel_m=100.0 - v[2] * t, gnss=pd.DataFrame(), radar=pd.DataFrame(),
                      station=None, departure=None, arrival=None, liftoff_t=np.nan,
                      touchdown_t=np.nan, field_h=0.0)
    got = nose_offset(inp)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    # at chosen samples (the air-data measurements'): the whole grid's numbers there
    pick = np.zeros(n, bool)
    pick[::7] = True
    np.testing.assert_array_equal(nose_offset(inp, at=pick), got[pick])
    # about a sin(roll): the nose points to the inside of the turn's air track by that much
    assert abs(want - a * np.sin(np.radians(roll))) <= 0.1 * abs(a) + 1e-12


def test_nose_offset_left_out_where_the_angle_of_attack_is_not_believable():
    """Guards the offset's range (docs/joint.md, "Measurements"): a sink that the attitude
    can only explain with an angle of attack of 30 deg (a stall) gives no offset."""
    import pandas as pd

    from flightrecon.methods.joint.inputs import JointInputs
    from flightrecon.methods.joint.measurements import nose_offset

    t = np.arange(0.0, 10.0, 0.0625)
    n = len(t)
    inp = JointInputs(t_in=t, acc_ned=np.zeros((n, 3)),
                      attitude_deg=np.tile([20.0, 5.0, 90.0], (n, 1)), tas=np.full(n, 40.0),
                      heading_rad=np.full(n, np.pi / 2), baro_rel_m=100.0 - 40.0 * 0.45 * t,
                      gnss=pd.DataFrame(), radar=pd.DataFrame(), station=None, departure=None,
                      arrival=None, liftoff_t=np.nan, touchdown_t=np.nan, field_h=0.0)
    assert np.all(nose_offset(inp) == 0.0)


def test_ground_roll_tells_the_heading_no_more_than_one_track_angle():
    """Guards the runway rows' common error (docs/joint.md, "Measurements", on the ground):
    a roll's track is off the runway by one angle for the whole roll (JSBSim: up to 1.7 deg,
    the nose up to 3.3 deg), so with ``ground_slip_deg`` its m cross-track velocity rows each
    carry m (s V)^2 on top of the white noise (V: the airspeed at lift-off), whatever the
    iterate's velocity (the cost function must not move with the linearisation point); at the
    default 0 the rows are the white noise alone."""
    from dataclasses import replace

    import pandas as pd

    from flightrecon.methods.joint.inputs import JointInputs
    from flightrecon.methods.joint.measurements import (
        _MeasBuilder,
        ground_rolls,
        runway_measurements,
    )
    from flightrecon.methods.joint.settings import JointSettings

    assert JointSettings().noise.ground_slip_deg == 0.0
    t = np.arange(0.0, 80.0, 0.25)
    n = len(t)
    tas = np.clip(1.5 * t, 0.0, 60.0)
    inp = JointInputs(t_in=t, acc_ned=np.zeros((n, 3)), attitude_deg=np.tile([0, 0, 90.0], (n, 1)),
                      tas=tas, heading_rad=np.full(n, np.pi / 2), baro_rel_m=np.zeros(n),
                      gnss=pd.DataFrame(), radar=pd.DataFrame(), station=None,
                      departure=(40.0, 20.0, 100.0), arrival=None, liftoff_t=30.0,
                      touchdown_t=np.nan, field_h=100.0, runway_rad=(np.pi / 2, None))
    base = JointSettings()
    s = replace(base, noise=replace(base.noise, ground_slip_deg=1.5))
    T = t[::4]
    rows = []
    for speed in (10.0, 40.0):
        b = _MeasBuilder(T)
        vnom = np.c_[np.zeros(len(T)), np.full(len(T), speed), np.zeros(len(T))]
        pnom = np.zeros((len(T), 3))
        runway_measurements(b, ground_rolls(inp, s, T), pnom, vnom)
        rows.append(b.parts[0])
    ground = rows[0]
    m = len(ground.t)
    assert m == 28   # 1 Hz, more than 2 s before lift-off
    v_liftoff = 45.0
    want = s.noise.ground_mps ** 2 + m * (np.radians(s.noise.ground_slip_deg) * v_liftoff) ** 2
    np.testing.assert_allclose(ground.r, want, rtol=1e-12)
    np.testing.assert_array_equal(rows[1].r, ground.r)
    # the roll's information on a track angle: one angle's worth, not m of them
    info = float(np.sum(v_liftoff ** 2 / ground.r))
    assert info < 1.0 / np.radians(s.noise.ground_slip_deg) ** 2
    b = _MeasBuilder(T)
    runway_measurements(b, ground_rolls(inp, base, T), np.zeros((len(T), 3)), vnom)
    np.testing.assert_array_equal(b.parts[0].r, base.noise.ground_mps ** 2)


def test_lined_up_at_rest_the_heading_gives_its_bias():
    """Guards the line-up row (docs/joint.md, "The heading reference"): lined up at rest before
    the roll the recorded heading minus the runway's direction is the heading bias, one row
    for the rest (the circular mean of its samples, at their mean time); the runway given in the
    opposite direction is the same line; without the runway's direction there is no row."""
    import pandas as pd

    from flightrecon.methods.joint.inputs import JointInputs
    from flightrecon.methods.joint.measurements import lineup_heading

    t = np.arange(0.0, 60.0, 0.25)
    n = len(t)
    rng = np.random.default_rng(4)
    psi = np.radians(160.0 + 1.5 + rng.normal(0.0, 0.2, n))   # 1.5 deg bias, 0.2 deg noise

    def row(rw):
        inp = JointInputs(t_in=t, acc_ned=np.zeros((n, 3)),
                          attitude_deg=np.c_[np.zeros(n), np.zeros(n), np.degrees(psi)],
                          tas=np.zeros(n), heading_rad=psi, baro_rel_m=np.zeros(n),
                          gnss=pd.DataFrame(), radar=pd.DataFrame(), station=None,
                          departure=(40.0, 20.0, 100.0), arrival=None, liftoff_t=50.0,
                          touchdown_t=np.nan, field_h=100.0, runway_rad=(rw, None))
        return lineup_heading(inp, t[(t >= 5.0) & (t <= 35.0)])
    for rw in (np.radians(160.0), np.radians(340.0)):
        t_row, z = row(rw)
        assert 5.0 <= t_row <= 35.0
        # the mean of 121 samples of 0.2 deg noise: 0.02 deg sd, bound 4 sd
        assert np.degrees(z) == pytest.approx(1.5, abs=0.08)
    assert len(row(None)) == 0


def _runway_rows(t, hdg, tas, settings=None, **where):
    """The runway rows (``ground.runway_measurements``) of a roll recorded at ``t`` with the
    heading ``hdg`` [deg] and airspeed ``tas`` on a 1 s state grid (every fourth sample),
    the nominal ground velocity 20 m/s east; ``where``: the inputs' airfields, lift-off,
    touchdown, runway and roll.  Returns the rows, their H, the settings and the state grid."""
    import pandas as pd

    from flightrecon.methods.joint.inputs import JointInputs
    from flightrecon.methods.joint.measurements import (
        _MeasBuilder,
        ground_rolls,
        runway_measurements,
    )
    from flightrecon.methods.joint.settings import JointSettings

    n = len(t)
    inp = JointInputs(t_in=t, acc_ned=np.zeros((n, 3)),
                      attitude_deg=np.c_[np.zeros(n), np.zeros(n), hdg], tas=tas,
                      heading_rad=np.radians(hdg), baro_rel_m=np.zeros(n), gnss=pd.DataFrame(),
                      radar=pd.DataFrame(), station=None, field_h=100.0, **where)
    s = settings or JointSettings()
    T = t[::4]
    b = _MeasBuilder(T)
    vnom = np.c_[np.zeros(len(T)), np.full(len(T), 20.0), np.zeros(len(T))]
    runway_measurements(b, ground_rolls(inp, s, T), np.zeros((len(T), 3)), vnom)
    return b.parts[0], b.H[0], s, T


def test_a_swerve_on_the_roll_loosens_its_cross_track_rows():
    """Guards the steering term of the runway rows (docs/joint.md, "The heading reference"):
    where the recorded heading swings 8 deg off the heading lined up at rest, the track
    follows the nose, so those cross-track velocity rows carry (V sin 8 deg)^2 on top of the
    white noise (V: the lift-off airspeed), and the rows where the nose stays lined up (and
    the rest itself) keep the white noise alone; without a rest the reference is the roll's
    mean heading."""
    from flightrecon.cleaning.ground_roll import TakeoffRoll
    from flightrecon.methods.joint.measurements import steering_variance
    from flightrecon.methods.joint.settings import JointSettings

    t = np.arange(0.0, 80.0, 0.25)
    n = len(t)
    hdg = np.full(n, 90.0)
    swing = (t >= 22.0) & (t < 26.0)
    hdg[swing] += 8.0
    where = dict(departure=(40.0, 20.0, 100.0), arrival=None, liftoff_t=42.0,
                 touchdown_t=np.nan, runway_rad=(np.pi / 2, None),
                 roll=TakeoffRoll(12.0, (0.0, 10.0)))
    tas = np.clip(1.5 * (t - 12.0), 0.0, 60.0)
    g, _, s, T = _runway_rows(t, hdg, tas, **where)
    v_lo = 1.5 * (42.0 - 12.0)          # the airspeed at lift-off: 45 m/s
    in_swing = (g.t >= 22.0) & (g.t < 26.0)
    assert in_swing.sum() == 4 and len(g.t) == 40
    np.testing.assert_allclose(g.r[in_swing], s.noise.ground_mps ** 2
                               + (v_lo * np.sin(np.radians(8.0))) ** 2, rtol=1e-9)
    np.testing.assert_allclose(g.r[~in_swing], s.noise.ground_mps ** 2, rtol=1e-12)
    # no rest: the reference is the roll's circular mean (4 of 40 samples 8 deg off: 0.8 deg)
    d = np.radians(np.array([8.0, 0.0]))
    r = steering_variance(d, 45.0)
    mean = np.arctan2(np.sin(d).mean(), np.cos(d).mean())
    np.testing.assert_allclose(r, (45.0 * np.sin(d - mean)) ** 2, rtol=1e-12)
    assert steering_variance(np.zeros(0), 45.0).size == 0
    # roll_velocity="nose": the rows across the recorded heading (less the bias), white noise
    g, H, _, _ = _runway_rows(t, hdg, tas, JointSettings(roll_velocity="nose"), **where)
    psi = np.radians(np.interp(g.t, t, hdg))
    np.testing.assert_allclose(H[:, jl.IV:jl.IV + 2], np.c_[-np.sin(psi), np.cos(psi)],
                               atol=1e-12)
    np.testing.assert_allclose(H[:, jl.IPSI], 20.0 * np.sin(psi), atol=1e-12)
    np.testing.assert_allclose(g.r, s.noise.ground_mps ** 2, rtol=1e-12)


def test_implausible_sensor_error_is_named():
    """Guards the joint's health rule against implausible sensor errors: an airspeed scale 25
    prior sd from its prior is reported (and makes the track unhealthy in run_joint); one at
    3 sd is not."""
    from flightrecon.methods.joint.health import implausible_corrections

    c = {"tas_scale": {"value": 0.75, "sd": 0.01, "prior_mean": 0.0, "prior_sd": 0.03},
         "heading_bias_deg": {"value": -6.0, "sd": 0.5, "prior_mean": 0.0, "prior_sd": 2.0}}
    far = implausible_corrections(c)
    assert list(far) == ["tas_scale"] and far["tas_scale"] == pytest.approx(25.0)


def test_gust_at_its_upper_bound_is_named():
    """Guards the warning of a gust sd estimated up to its bound (the air data all but
    dropped); an estimate below it, or no estimate at all, says nothing."""
    from types import SimpleNamespace

    from flightrecon.methods.joint.health import gust_warnings

    rounds = [{"pass": 1, "gust_mps": 2.0, "estimate_mps": 9.0, "changed": True}]
    assert gust_warnings(SimpleNamespace(gust={"sd_mps": 8.0, "rounds": rounds}), 8.0)
    assert not gust_warnings(SimpleNamespace(gust={"sd_mps": 3.1, "rounds": rounds}), 8.0)
    assert not gust_warnings(SimpleNamespace(gust={"sd_mps": 8.0, "rounds": []}), 8.0)
    assert not gust_warnings(SimpleNamespace(gust=None), 8.0)


def test_a_wind_that_turns_faster_than_its_random_walk_is_named():
    """Guards the wind's process-model check (diagnostics.wind_walk_check): a wind drawn from
    the model itself (random walk 0.05 m/s/sqrt(s) for 40 minutes, and a climb of 1500 m
    through a gradient of 10 (m/s)/km that the gradient state carries) passes; 22 m/s turning
    100 deg in 30 minutes at a constant height (JSBSim's holding) is named, its worst
    10-minute window's change (about 13 m/s) against the 1.2 m/s sd the walk allows."""
    from types import SimpleNamespace

    from flightrecon.methods.joint.health import wind_walk_check, wind_walk_warning

    t = np.arange(0.0, 2400.0, 1.0)
    n = len(t)
    q = 0.05
    rng = np.random.default_rng(11)
    h = np.clip(t, 0.0, 1500.0)                        # 1 m/s climb to 1500 m, then level
    g = np.full((n, 2), [0.010, -0.004])               # (m/s)/m
    w = g * h[:, None] + np.cumsum(rng.normal(0.0, q, (n, 2)), axis=0)

    def run(wind):
        x = np.zeros((n, jl.N_STATE))
        x[:, jl.S_WIND] = wind
        x[:, jl.S_WIND_GRAD] = g
        return SimpleNamespace(t=t, x=x, h_m=h + 100.0)
    assert wind_walk_check(run(w), q, 0.05) is None
    ang = np.radians(np.clip((t - 300.0) / 1800.0, 0.0, 1.0) * 100.0)
    turning = 22.0 * np.c_[np.cos(ang), np.sin(ang)]
    flat = SimpleNamespace(t=t, x=run(turning).x, h_m=np.full(n, 1600.0))
    c = wind_walk_check(flat, q, 0.05)
    assert c is not None and c["z2"] > c["limit"]
    # the chord of 33.3 deg of a 22 m/s circle in 600 s: 12.6 m/s; sd sqrt(0.05^2 600) m/s
    assert c["change_mps"] == pytest.approx(2 * 22.0 * np.sin(np.radians(100.0 / 6)), rel=1e-6)
    assert c["model_sd_mps"] == pytest.approx(np.sqrt(q ** 2 * 600.0), rel=1e-9)
    assert "(unhealthy)" in wind_walk_warning(c)


def test_the_wind_walk_is_re_estimated_where_the_wind_outran_it(monkeypatch):
    """Guards the wind walk's rounds (calibration.wind_walk_rounds): the turning wind of the
    test above, chi-square 106 on its worst 10-minute window against the default walk, gets
    the walk 0.05 sqrt(106 / 2) = 0.364 m/s/sqrt(s) in one round, after which the same wind
    is a typical one (chi-square 2.0); a steady wind keeps the default and no round; with
    ``wind_rounds`` = 0 nothing is re-estimated.  The smoother is a stand-in returning the
    given wind (the rounds' arithmetic, not the smoother's answer, is under test); the dead
    reckoning's sd in the health evidence takes twice the re-estimated walk."""
    from dataclasses import replace
    from types import SimpleNamespace

    import pandas as pd

    import flightrecon.methods.joint.calibration as jm
    from flightrecon.methods.joint.problem import JointProblem
    from flightrecon.methods.joint.settings import JointSettings
    from flightrecon.track_evidence import Evidence, dr_walk

    t = np.arange(0.0, 2400.0, 1.0)
    n = len(t)
    ang = np.radians(np.clip((t - 300.0) / 1800.0, 0.0, 1.0) * 100.0)

    def fake_run(wind):
        x = np.zeros((n, jl.N_STATE))
        x[:, jl.S_WIND] = wind
        return SimpleNamespace(t=t, x=x, h_m=np.full(n, 1600.0))
    turning = fake_run(22.0 * np.c_[np.cos(ang), np.sin(ang)])
    calls = []
    monkeypatch.setattr(jm, "smooth_joint", lambda p: calls.append(p.settings) or turning)
    monkeypatch.setattr(jm, "adjusted", lambda p, settings, choice: replace(
        p, settings=settings, choices=(*p.choices, choice)))   # (the stand-in has no flight)
    stand_in = SimpleNamespace(gnss=pd.DataFrame(), radar=pd.DataFrame(), fixes=None,
                               wind_ne=None, doppler_gs=None, wind_aloft=None,
                               liftoff_t=np.nan, touchdown_t=np.nan)

    def problem(settings):
        return JointProblem(stand_in, settings)  # type: ignore[arg-type]
    adjusted, run, rounds = jm.wind_walk_rounds(problem(JointSettings()), turning)
    s = adjusted.settings
    chord = 2 * 22.0 * np.sin(np.radians(100.0 / 6))
    z2 = chord ** 2 / (0.05 ** 2 * 600.0)
    assert len(rounds) == 1 and len(calls) == 1 and rounds[0]["z2"] == pytest.approx(z2)
    assert s.noise.wind_rw_mps_sqrt_s == pytest.approx(0.05 * np.sqrt(z2 / 2.0))
    steady = fake_run(np.tile([5.0, -3.0], (n, 1)))
    assert jm.wind_walk_rounds(problem(JointSettings()), steady)[2] == []
    assert jm.wind_walk_rounds(problem(replace(JointSettings(), wind_rounds=0)), turning)[2] == []
    assert [c.setting for c in adjusted.choices] == ["noise.wind_rw_mps_sqrt_s"]
    res = SimpleNamespace(summary={"wind_walk": {"wind_rw_mps_sqrt_s": 0.364,
                                                 "rounds": rounds}})
    assert dr_walk(res, Evidence()) == pytest.approx(0.728)
    res.summary["wind_walk"] = {"wind_rw_mps_sqrt_s": 0.05, "rounds": []}
    assert dr_walk(res, Evidence()) == Evidence().dr_walk_mps_per_sqrt_s


def test_increments_do_not_lag_a_turning_acceleration():
    """Guards the increments' hold: a recorder sample is its channel at its own time, so it is
    held on the interval centred there. Held forward on [t_i, t_i+1) it was applied half an
    interval late: in a rate-one turn at 16 Hz the acceleration lagged by 0.09 deg, which the
    joint smoother took up as a heading bias (+0.09 deg on noise-free JSBSim circuits, odd in
    the turn direction; docs/joint.md "Increments"). The centred hold's error is second order:
    9e-7 of the velocity increment and 1.7e-5 of the position increment here, where the
    forward hold's is 1.6e-3 for both (bounds 1e-5 and 5e-5)."""
    from flightrecon.methods.joint.linearisation import held_increments, state_grid

    w = np.radians(3.0)                                 # rate-one turn
    t = np.arange(0.0, 60.0, 1.0 / 16.0)
    acc = np.c_[np.cos(w * t), np.sin(w * t), np.zeros(len(t))] * 2.6   # centripetal, m/s^2
    idx = state_grid(t, 1.0)
    dV, dP, _ = held_increments(t, acc, idx)
    T = t[idx]
    exact = np.c_[np.sin(w * T[1:]) - np.sin(w * T[:-1]),
                  -np.cos(w * T[1:]) + np.cos(w * T[:-1])] * 2.6 / w
    err = np.abs(dV[1:, :2] - exact).max() / np.abs(exact).max()
    assert err < 1e-5
    # the position increment: exact T_k-weighted integral, to second order as well
    tt = np.linspace(T[4], T[5], 20001)
    a = np.c_[np.cos(w * tt), np.sin(w * tt)] * 2.6
    ref = np.trapezoid(a * (T[5] - tt)[:, None], tt, axis=0)
    assert np.abs(dP[5, :2] - ref).max() < 5e-5 * np.abs(ref).max()


def test_runway_centreline_runs_through_the_threshold():
    """Regression (issue #35, the PH-LAB flights): with the runway's threshold given, the
    centreline rows pass through the threshold, not through the airfield's reference point.
    The analyst's departure point of the real flights is the apron, 650 m beside runway 24:
    the centreline through it was parallel to the runway and 650 m off, and it overruled the
    threshold's own cross-track row (26 sd, rejected by the robust loss).  Here the reference
    point lies 650 m to the left of a runway heading 237 deg: the threshold meets every
    centreline row to rounding (ECEF coordinates of 6.4e6 m: 1 mm), the reference point misses
    each by its 650 m offset."""
    import pandas as pd

    from flightrecon.geo.frames import offset_latlon
    from flightrecon.methods.joint.inputs import JointInputs
    from flightrecon.methods.joint.measurements import (
        _MeasBuilder,
        ground_rolls,
        runway_measurements,
    )
    from flightrecon.methods.joint.settings import JointSettings

    rw = np.radians(237.0)
    thr = (51.9627, 4.4548, 38.5)
    # 650 m to the left of the runway (across it, towards heading - 90 deg)
    arp_lat, arp_lon = offset_latlon(thr[0], thr[1], 650.0 * np.cos(rw - np.pi / 2),
                                     650.0 * np.sin(rw - np.pi / 2))
    t = np.arange(0.0, 80.0, 0.25)
    n = len(t)
    inp = JointInputs(t_in=t, acc_ned=np.zeros((n, 3)),
                      attitude_deg=np.tile([0.0, 0.0, 237.0], (n, 1)),
                      tas=np.clip(1.5 * t, 0.0, 60.0), heading_rad=np.full(n, rw),
                      baro_rel_m=np.zeros(n), gnss=pd.DataFrame(), radar=pd.DataFrame(),
                      station=None, departure=(arp_lat, arp_lon, thr[2]), arrival=None,
                      liftoff_t=30.0, touchdown_t=np.nan, field_h=thr[2],
                      runway_rad=(rw, None), thresholds=(thr, None))
    T = t[::4]
    b = _MeasBuilder(T)
    runway_measurements(b, ground_rolls(inp, JointSettings(), T), np.zeros((len(T), 3)),
                        np.zeros((len(T), 3)))
    src = [int(p.source[0]) for p in b.parts]
    from flightrecon.methods.joint.settings import SOURCES

    k = src.index(SOURCES.index("runway"))
    H, d = b.H[k], b.parts[k].d
    assert len(d) == 28   # the centreline rows: 1 Hz, more than 2 s before lift-off
    p_thr = np.array(geodetic_to_ecef(*thr), float).reshape(3)
    p_arp = np.array(geodetic_to_ecef(arp_lat, arp_lon, thr[2]), float).reshape(3)
    np.testing.assert_allclose(H[:, jl.S_POS] @ p_thr + d, 0.0, atol=1e-3)
    np.testing.assert_allclose(np.abs(H[:, jl.S_POS] @ p_arp + d), 650.0, atol=0.5)


def test_centreline_through_a_reference_point_is_one_unknown_offset():
    """Without a threshold the centreline rows run through the airfield's reference point, which
    need not lie on the runway (issue #36: the Garmin study's stands, 364 m beside the arrival
    runway's line at touchdown, where the 25 m rows made the north sd 17 m: error 20 sd, mean
    NEES north 5.9).  Its distance from the centreline is one error for the whole roll, known
    no better than the reference itself (``endpoint_h_m``): each of the m rows carries
    ``halfwidth^2 + m endpoint_h_m^2``, so that the roll tells the cross-track position no
    more than one reference's worth (sum of 1/r below 1/endpoint_h_m^2).  With the threshold
    the rows keep the half-width alone."""
    import pandas as pd

    from flightrecon.methods.joint.inputs import JointInputs
    from flightrecon.methods.joint.measurements import (
        _MeasBuilder,
        ground_rolls,
        runway_measurements,
    )
    from flightrecon.methods.joint.settings import SOURCES, JointSettings

    rw = np.radians(237.0)
    thr = (51.9627, 4.4548, 38.5)
    t = np.arange(0.0, 80.0, 0.25)
    n = len(t)
    nz = JointSettings().noise
    T = t[::4]
    for thresholds in ((thr, None), (None, None)):
        inp = JointInputs(t_in=t, acc_ned=np.zeros((n, 3)),
                          attitude_deg=np.tile([0.0, 0.0, 237.0], (n, 1)),
                          tas=np.clip(1.5 * t, 0.0, 60.0), heading_rad=np.full(n, rw),
                          baro_rel_m=np.zeros(n), gnss=pd.DataFrame(), radar=pd.DataFrame(),
                          station=None, departure=(thr[0] + 0.005, thr[1], thr[2]),
                          arrival=None, liftoff_t=30.0, touchdown_t=np.nan, field_h=thr[2],
                          runway_rad=(rw, None), thresholds=thresholds)
        b = _MeasBuilder(T)
        runway_measurements(b, ground_rolls(inp, JointSettings(), T), np.zeros((len(T), 3)),
                        np.zeros((len(T), 3)))
        k = [int(p.source[0]) for p in b.parts].index(SOURCES.index("runway"))
        r = b.parts[k].r
        m = len(r)
        assert m == 28   # 1 Hz, more than 2 s before lift-off
        if thresholds[0] is not None:
            np.testing.assert_allclose(r, nz.runway_halfwidth_m ** 2, rtol=1e-12)
        else:
            np.testing.assert_allclose(r, nz.runway_halfwidth_m ** 2 + m * nz.endpoint_h_m ** 2,
                                       rtol=1e-12)
            assert float(np.sum(1.0 / r)) < 1.0 / nz.endpoint_h_m ** 2


def test_a_wind_change_the_loads_alone_witness_is_weighed_at_their_share(monkeypatch):
    """Guards the wind-walk check where the loads are the wind's only witness
    (diagnostics.wind_walk_check with ``loads_psd_m2ps3``, calibration.inertial_wind_share,
    calibration.wind_walk_rounds): 4 m/s turning 100 deg in 30 minutes, a 10-minute chord
    of 2.29 m/s, passes the bound (chi-square 3.5 against the walk's 1.5 m^2/s^2) but a 1 Hz
    record's loads (sampling 0.28 m/s^2/sqrt(Hz) per axis: r = 0.0809 m^2/s^3, r L = 48.5)
    let a smoother see only the share Q / (Q + r L) = 0.030 of a change, so the same smoothed
    chord is chi-square |dw|^2 (Q + r L) / Q^2 = 117 against the 1e-4 limit 21.1 of the
    3.8 windows clear of the rolls; the walk is raised to the smallest the check accepts,
    q' L = z^2 (Q + r L) / limit - r L: 0.618 m/s/sqrt(s) (229 m^2/s^2 over 600 s).  With a
    GNSS (or no sampling term) r = 0 and the check is the bound.  The smoother is a stand-in
    returning the given wind."""
    from dataclasses import replace
    from types import SimpleNamespace

    import pandas as pd

    import flightrecon.methods.joint.calibration as jm
    from flightrecon.methods.joint.health import wind_walk_check
    from flightrecon.methods.joint.problem import JointProblem
    from flightrecon.methods.joint.settings import JointSettings

    t = np.arange(0.0, 2400.0, 1.0)
    n = len(t)
    ang = np.radians(np.clip((t - 300.0) / 1800.0, 0.0, 1.0) * 100.0)
    x = np.zeros((n, jl.N_STATE))
    x[:, jl.S_WIND] = 4.0 * np.c_[np.cos(ang), np.sin(ang)]
    turning = SimpleNamespace(t=t, x=x, h_m=np.full(n, 1600.0))
    chord = 2 * 4.0 * np.sin(np.radians(100.0 / 6))
    Q = 0.05 ** 2 * 600.0
    assert wind_walk_check(turning, 0.05, 0.05) is None           # the bound: 3.5 < 12.0
    assert chord ** 2 / Q == pytest.approx(3.50, abs=0.01)

    base = JointSettings()
    one_hz = replace(base, noise=replace(base.noise,
                                           accel_sampling_mps2_sqrt_hz=(0.28, 0.28, 0.5)))
    inp = SimpleNamespace(gnss=pd.DataFrame(), radar=pd.DataFrame(), fixes=None, wind_ne=None,
                          doppler_gs=None, wind_aloft=None, liftoff_t=0.0, touchdown_t=2399.0)
    r = jm.inertial_wind_share(inp, one_hz)
    assert r == pytest.approx(0.05 ** 2 + 0.28 ** 2, rel=1e-12)
    assert jm.inertial_wind_share(inp, base) == 0.0               # no sampling term
    with_gnss = SimpleNamespace(**{**vars(inp), "gnss": pd.DataFrame({"t_s": [1.0]})})
    assert jm.inertial_wind_share(with_gnss, one_hz) == 0.0

    within = (60.0, 2339.0)
    c = wind_walk_check(turning, 0.05, 0.05, loads_psd_m2ps3=r, within_s=within, p_false=1e-4)
    z2 = chord ** 2 * (Q + r * 600.0) / Q ** 2
    limit = -2.0 * np.log(1e-4 / (2279.0 / 600.0))
    assert c is not None and c["z2"] == pytest.approx(z2, rel=1e-9)
    assert (z2, limit) == pytest.approx((117.1, 21.09), abs=0.1)
    assert c["limit"] == pytest.approx(limit, rel=1e-12)
    assert c["model_sd_mps"] == pytest.approx(np.sqrt(Q * Q / (Q + r * 600.0)), rel=1e-9)
    # a span shorter than the window (a circuit clear of its rolls): no window, no finding
    assert wind_walk_check(turning, 0.05, 0.05, loads_psd_m2ps3=r, within_s=(60.0, 600.0),
                           p_false=1e-4) is None

    calls = []
    monkeypatch.setattr(jm, "smooth_joint", lambda p: calls.append(p.settings) or turning)
    monkeypatch.setattr(jm, "adjusted", lambda p, settings, choice: replace(
        p, settings=settings, choices=(*p.choices, choice)))   # (the stand-in has no flight)
    _, run, rounds = jm.wind_walk_rounds(JointProblem(inp, one_hz), turning)  # type: ignore[arg-type]
    q1 = (z2 * (Q + r * 600.0) / limit - r * 600.0) / 600.0
    assert rounds[0]["z2"] == pytest.approx(z2, rel=1e-9)
    assert calls[0].noise.wind_rw_mps_sqrt_s == pytest.approx(np.sqrt(q1), rel=1e-9)
    assert np.sqrt(q1) == pytest.approx(0.618, abs=0.001)
    assert 1 <= len(rounds) <= one_hz.wind_rounds


def test_a_landing_roll_angled_off_the_runway_loosens_its_cross_track_rows():
    """Guards the landing roll's steering term (issue #38): there is no rest before it, and a
    roll held 6 deg off the runway (JSBSim's Cessna 310 on cross-country seed 6030 rolls out
    at 256-257 deg on runway 250) has a constant offset from its own mean heading of zero, so
    the rows held the track on the runway and the heading bias took up the 6 deg (3.3 +- 0.5
    deg for a true 0.5, mean NEES north 11.5). The reference is now the runway's direction:
    each row carries (V sin 6 deg)^2, V the touchdown airspeed."""
    t = np.arange(0.0, 40.0, 0.25)
    n = len(t)
    hdg = np.full(n, 96.0)
    g, _, s, _ = _runway_rows(t, hdg, np.clip(40.0 - 1.5 * (t - 10.0), 0.0, 40.0),
                              departure=None, arrival=(40.0, 20.0, 100.0), liftoff_t=np.nan,
                              touchdown_t=10.0, runway_rad=(None, np.pi / 2))
    assert len(g.t) > 20
    np.testing.assert_allclose(g.r, s.noise.ground_mps ** 2
                               + (40.0 * np.sin(np.radians(6.0))) ** 2, rtol=1e-9)


def test_background_covariance_pass_raises_its_error_where_it_is_joined(monkeypatch):
    """The covariance pass on its second thread (``passes.BackgroundCovariances``): its
    outputs come back from :meth:`result`, and an error of the pass is raised there, on the
    thread that waits for it, not lost with its thread."""

    from flightrecon.methods.joint import solve as jp

    def fake(bufs, dyn, meas, geo, with_cov, residuals):
        assert with_cov and residuals is False
        return jp.Smoothed(bufs[0], "model", 3)

    monkeypatch.setattr(jp, "backward", fake)
    bufs = tuple(np.zeros((2, 2)) for _ in range(4))
    got = jp.BackgroundCovariances(bufs, None, None, None).result()
    assert (got.model, got.cholesky_fallbacks) == ("model", 3)

    def broken(*args):
        raise np.linalg.LinAlgError("not positive definite")

    monkeypatch.setattr(jp, "backward", broken)
    job = jp.BackgroundCovariances(bufs, None, None, None)
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
        job.result()

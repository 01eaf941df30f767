"""The shared estimation core (flightrecon.estimation): each piece against a reference."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from flightrecon.estimation.updates import scalar_update_short


def _joseph(x, P, h, nu, r):
    S = h @ P @ h + r
    K = P @ h / S
    A = np.eye(len(x)) - np.outer(K, h)
    return x + K * nu, A @ P @ A.T + r * np.outer(K, K)


def test_scalar_update_is_the_short_form_and_equals_joseph_at_the_optimal_gain():
    """Regression: the joint smoother's comment called its scalar update the Joseph form; it is
    the short form P - PH PH^T / S (now :func:`scalar_update_short`, which the joint calls).
    Guards what the docstring claims: the short form equals the Joseph form at the optimal
    gain to rounding (1e-12 relative) and keeps P bitwise symmetric."""
    rng = np.random.default_rng(11)
    n = 24
    A = rng.standard_normal((n, n))
    P = A @ A.T + np.eye(n)
    P = 0.5 * (P + P.T)
    x = rng.standard_normal(n)
    h = np.zeros(n)
    h[[0, 3, 11]] = rng.standard_normal(3)
    r, nu = 0.3, 0.7
    xj, Pj = _joseph(x, P, h, nu, r)
    xs, Ps = x.copy(), P.copy()
    PH = P @ h
    scalar_update_short(xs, Ps, PH, nu, float(h @ PH + r))
    np.testing.assert_allclose(xs, xj, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(Ps, Pj, rtol=0, atol=1e-12 * np.abs(P).max())
    np.testing.assert_array_equal(Ps, Ps.T)


def test_chi_square_verdict_band_and_gross_factor():
    """The one health verdict: the mean NIS per dof against the chi-square band (consistency)
    and the gross factor (health); NaN entries ignored, per-entry dof honoured."""
    from scipy import stats

    from flightrecon.estimation.consistency import chi_square_verdict

    rng = np.random.default_rng(3)
    nis = rng.chisquare(2, 5000)
    v = chi_square_verdict(np.r_[nis, np.nan], 2.0)
    assert v.count == 5000 and v.dof == 10000.0
    lo, hi = stats.chi2.ppf([0.025, 0.975], 10000) / 10000
    assert v.band == (lo, hi) and v.consistent and not v.gross
    assert chi_square_verdict(6.0 * nis, 2.0).gross
    assert not chi_square_verdict(0.2 * nis, 2.0).consistent      # conservative: not gross
    assert not chi_square_verdict(0.2 * nis, 2.0).gross
    empty = chi_square_verdict([np.nan])
    assert empty.count == 0 and not empty.gross and not empty.consistent


def test_track_columns_rotate_vectors_and_covariances_in_either_order():
    """The one track builder: a horizontal vector and its covariance given east-first and
    rotated by M into the output axes equal the north-first form; NaN outside the rows."""
    from flightrecon.tracks import TrackColumns

    rng = np.random.default_rng(2)
    K = 5
    v_ne = rng.standard_normal((K, 2))
    A = rng.standard_normal((K, 2, 2))
    C_ne = A @ A.transpose(0, 2, 1)
    g = 0.02
    M_ne = np.array([[np.cos(g), -np.sin(g)], [np.sin(g), np.cos(g)]])
    rows = np.arange(1, K + 1)
    a = TrackColumns("x", np.arange(K + 2.0), rows)
    a.add_horizontal("vn", "ve", "mps", v_ne, C_ne, M_ne)
    b = TrackColumns("x", np.arange(K + 2.0), rows)
    swap = np.array([[0.0, 1.0], [1.0, 0.0]])
    b.add_horizontal("vn", "ve", "mps", v_ne[:, ::-1], C_ne[:, ::-1, ::-1], swap @ M_ne @ swap,
                     order="en")
    fa, fb = a.frame(), b.frame()
    np.testing.assert_allclose(fa.to_numpy(), fb.to_numpy(), rtol=1e-14, atol=1e-14)
    want = v_ne @ M_ne.T
    np.testing.assert_allclose(fa["x_vn_mps"].to_numpy()[rows], want[:, 0], rtol=1e-14)
    sd_e = np.sqrt((M_ne @ C_ne @ M_ne.T)[:, 1, 1])
    np.testing.assert_allclose(fa["x_ve_sd_mps"].to_numpy()[rows], sd_e, rtol=1e-14)
    assert np.isnan(fa["x_vn_mps"].to_numpy()[[0, K + 1]]).all()
    assert list(fa.columns) == ["t_s", "x_vn_mps", "x_vn_sd_mps", "x_ve_mps", "x_ve_sd_mps"]


@settings(max_examples=50, deadline=None)
@given(n=st.integers(1, 30), seed=st.integers(0, 2**32 - 1))
def test_packed_covariances_round_trip_exactly(n, seed):
    """Guards the joint smoother's stored covariances (packed lower triangles, half the
    memory): pack then unpack gives the symmetric matrix back bit for bit, and the packed
    length is n (n + 1) / 2."""
    from flightrecon.estimation.linalg import pack_sym, packed_size, unpack_sym

    A = np.random.default_rng(seed).normal(size=(n, n))
    P = A @ A.T
    P = np.tril(P) + np.tril(P, -1).T          # exactly symmetric
    p = np.empty(packed_size(n))
    pack_sym(P, p)
    out = np.full((n, n), np.nan)
    unpack_sym(p, out)
    np.testing.assert_array_equal(out, P)


@given(st.integers(1, 30), st.integers(0, 2**31 - 1))
@settings(max_examples=40, deadline=None)
def test_cholesky_vector_solve_is_the_column_solve_to_the_bit(n, seed):
    """The mean-only RTS pass's one-vector solve (:func:`cholesky_solve_vector`) gives the
    numbers of the column solve with one column, to the bit (its results must not move), and
    solves the system (1e-9 relative to the solution at these conditionings)."""
    from flightrecon.estimation.linalg import (
        cholesky_factor,
        cholesky_solve_columns,
        cholesky_solve_vector,
    )

    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    P = A @ A.T + n * np.eye(n)
    b = rng.standard_normal(n)
    L = np.zeros((n, n))
    assert cholesky_factor(P, L, 1e-12)
    x_vec, x_col = np.empty(n), np.empty((n, 1))
    cholesky_solve_vector(L, b, x_vec)
    cholesky_solve_columns(L, b.reshape(-1, 1), x_col)
    np.testing.assert_array_equal(x_vec, x_col[:, 0])
    np.testing.assert_allclose(P @ x_vec, b, rtol=0, atol=1e-9 * max(1.0, np.abs(b).max()))

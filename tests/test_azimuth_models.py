"""Process models of the azimuth channel (flightrecon.methods.azimuth; METHODS.md s. 3).

Singer's exact discrete matrices against the continuous-time model (Van Loan's matrix
exponential), their small-alpha limits, the Euler form of seed 002, and the aided model's exact
random-walk discretisation.
"""

import numpy as np
import pytest
import scipy.linalg as sl

from flightrecon.errors import ValidationError
from flightrecon.methods.azimuth import (
    random_walk_matrices,
    singer_process_noise,
    singer_transition,
    wrap_pi,
)


def van_loan(A: np.ndarray, Qc: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation of x' = A x + w, E[w w^T] = Qc delta (Van Loan 1978)."""
    n = A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -A
    M[:n, n:] = Qc
    M[n:, n:] = A.T
    E = sl.expm(M * T)
    Phi = E[n:, n:].T
    return Phi, Phi @ E[:n, n:]


def singer_continuous(alpha: float, sigma: float):
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -alpha]])
    Qc = np.zeros((3, 3))
    Qc[2, 2] = 2.0 * alpha * sigma**2
    return A, Qc


@pytest.mark.parametrize("alpha", [1e-4, 0.003, 0.02, 0.1, 0.5, 1.0])
@pytest.mark.parametrize("T", [0.0625, 1.0, 4.0])
def test_singer_matches_van_loan(alpha, T):
    """Closed forms (series below alpha T = 0.1) equal expm of the continuous model.

    Tolerance: Phi to 1e-12 absolute (entries are O(T^2) <= 16); Q relative to the scale
    sqrt(Q_ii Q_jj) to 1e-9 (the closed forms cancel to ~1e-11 just above the series switch,
    expm itself is accurate to ~1e-13 here).
    """
    sigma = 0.003
    A, Qc = singer_continuous(alpha, sigma)
    Phi_ref, Q_ref = van_loan(A, Qc, T)
    Phi = singer_transition(alpha, T)[0]
    Q = singer_process_noise(alpha, sigma, T)[0]
    np.testing.assert_allclose(Phi, Phi_ref, rtol=0, atol=1e-12)
    scale = np.sqrt(np.outer(np.diag(Q_ref), np.diag(Q_ref)))
    assert np.max(np.abs(Q - Q_ref) / scale) < 1e-9
    assert np.allclose(Q, Q.T)
    assert np.all(np.linalg.eigvalsh(Q) > -1e-15 * np.trace(Q))


def test_singer_continuous_across_series_switch():
    """The series/closed-form switch at alpha T = 0.1 leaves no step.

    alpha differs by 2e-12 across the switch, so the true change is ~2e-11 relative; the
    closed form's cancellation error at x = 0.1 is ~1e-11 (q_11 cancels to order x^5):
    1e-9 relative would catch a wrong series coefficient (those change values at 1e-3 or more).
    """
    T = 1.0
    a = np.array([0.1 - 1e-12, 0.1 + 1e-12])
    Q_lo = singer_process_noise(a[0], 1.0, T)[0]
    Q_hi = singer_process_noise(a[1], 1.0, T)[0]
    np.testing.assert_allclose(Q_lo, Q_hi, rtol=1e-9)
    np.testing.assert_allclose(singer_transition(a[0], T), singer_transition(a[1], T), rtol=1e-9)


def test_singer_small_alpha_limit_is_random_walk():
    """alpha -> 0 with q = 2 alpha sigma^2 fixed: Singer -> random-walk (white jerk) model.

    The difference is first order in alpha T (1e-7 here), so 1e-6 relative is ample.
    """
    alpha, T, q = 1e-7, 2.0, 4e-6
    sigma = np.sqrt(q / (2 * alpha))
    F_rw, Q_rw = random_walk_matrices(q, T)
    np.testing.assert_allclose(singer_transition(alpha, T), F_rw, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(singer_process_noise(alpha, sigma, T), Q_rw, rtol=1e-6)


def test_singer_euler_form_of_seed_for_small_alpha_T():
    """Seed 002 eqs. (1)-(3) are the first-order form: Phi = [[1,T,T^2/2],[0,1,T],[0,0,1-aT]].

    The exact Phi differs by O((alpha T)^2) in Phi_33 and O(alpha T^3) in Phi_13: tolerance
    (alpha T)^2 = 1e-6 and alpha T^3 / 6 = 1.7e-5 respectively (with margin x2).
    """
    alpha, T = 1e-3, 1.0
    euler = np.array([[1, T, T**2 / 2], [0, 1, T], [0, 0, 1 - alpha * T]])
    F = singer_transition(alpha, T)[0]
    assert abs(F[2, 2] - euler[2, 2]) < 2 * (alpha * T) ** 2
    assert abs(F[0, 2] - euler[0, 2]) < 2 * alpha * T**3 / 6
    assert abs(F[1, 2] - euler[1, 2]) < 2 * alpha * T**2 / 2


def test_singer_long_step_steady_state():
    """For alpha T >> 1 the acceleration forgets: Phi_33 -> 0 and Q_33 -> sigma^2 (1e-12)."""
    alpha, sigma = 2.0, 0.7
    Q = singer_process_noise(alpha, sigma, 30.0)[0]
    assert singer_transition(alpha, 30.0)[0, 2, 2] < 1e-25
    assert Q[2, 2] == pytest.approx(sigma**2, rel=1e-12)


def test_random_walk_matches_van_loan():
    """The aided model's Q = q [[T^5/20, ...]] is the exact integral of white noise on a'."""
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    Qc = np.zeros((3, 3))
    Qc[2, 2] = 0.3
    for T in (0.25, 1.0, 4.0):
        Phi_ref, Q_ref = van_loan(A, Qc, T)
        F, Q = random_walk_matrices(0.3, T)
        # expm of a nilpotent-plus-small matrix: 1e-12 absolute/relative is its accuracy
        np.testing.assert_allclose(F[0], Phi_ref, atol=1e-12)
        np.testing.assert_allclose(Q[0], Q_ref, rtol=1e-10, atol=1e-15)


def test_vectorised_steps_match_scalar():
    """Stacked steps give, row by row, the scalar result (exactly: same arithmetic)."""
    T = np.array([0.0, 0.5, 1.0, 3.7])
    sig = np.array([1.0, 2.0, 3.0, 4.0])
    Q = singer_process_noise(0.05, sig, T)
    for k in range(T.size):
        np.testing.assert_array_equal(Q[k], singer_process_noise(0.05, sig[k], T[k])[0])
    assert np.all(Q[0] == 0) and np.array_equal(singer_transition(0.05, 0.0)[0], np.eye(3))


def test_bad_parameters_raise():
    with pytest.raises(ValidationError):
        singer_transition(0.0, 1.0)
    with pytest.raises(ValidationError):
        singer_process_noise(0.1, 1.0, -1.0)
    with pytest.raises(ValidationError):
        random_walk_matrices(1.0, np.nan)


def test_wrap_pi():
    x = np.array([0.0, np.pi, -np.pi, 3 * np.pi / 2, 2 * np.pi + 0.1, -0.1])
    np.testing.assert_allclose(wrap_pi(x), [0.0, np.pi, np.pi, -np.pi / 2, 0.1, -0.1],
                               atol=1e-15)

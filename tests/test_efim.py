"""Fisher-information tools of DiPNet §III-A (phyloc.analysis.efim).

Expected values are written by hand (comments show the arithmetic), or come from independent
references: the ranging CRB of phyloc.phy.bounds, the closed form of anchors on a circle, and
a finite-difference Jacobian of the link distances.
"""

import math

import numpy as np
import pytest

from phyloc.analysis.efim import (
    direction_vectors,
    efim,
    equivalent_noise_variance,
    equivalent_ranging_information,
    position_crb,
    projected_variance,
    ranging_information,
    spectral_moment2,
)
from phyloc.errors import ValidationError
from phyloc.phy.bounds import crb_range, ranging_crb
from phyloc.phy.waveform import qpsk_symbols

C0 = 299_792_458.0  # the tests keep their own copy


# -- DiPNet eq. (24) -------------------------------------------------------------------------------
def test_ranging_information_hand_values():
    # ω = c0 ⇒ ω²/c0² = 1: ν = 2·SNR·M = 2·10·5 = 100
    assert ranging_information(10.0, 5.0, C0) == pytest.approx(100.0, rel=1e-14)
    # ω = c0/1000 ⇒ ω²/c0² = 1e-6: ν = 2·250·4e4·1e-6 = 20
    assert ranging_information(250.0, 4.0e4, C0 / 1000) == pytest.approx(20.0, rel=1e-14)
    # ω = 1e8 rad/s: ν = 2·10·1e16·5/c0² = 1e18/8.987551787368176e16 = 11.126500560536184
    assert ranging_information(10.0, 5.0, 1e8) == pytest.approx(11.126500560536184, rel=1e-13)
    # zero SNR: no information
    assert ranging_information(0.0, 5.0, 1e8) == 0.0


def test_spectral_moment2_hand_and_qpsk():
    # n = -2..2, |S|² = (1, 4, 9, 1, 1): 4·1 + 1·4 + 0 + 1·1 + 4·1 = 13
    S = np.array([1.0, 2.0, 3.0j, 1.0, -1.0])
    assert spectral_moment2(S) == pytest.approx(13.0)
    # unit-modulus pilots: Σ n² = N(N²−1)/12
    # N = 2569: (2569³ − 2569)/12 = 16_954_783_440/12 = 1_412_898_620
    assert spectral_moment2(np.exp(1j * np.arange(2569))) == pytest.approx(
        1_412_898_620.0, rel=1e-15
    )
    with pytest.raises(ValidationError, match="N odd"):
        spectral_moment2(np.ones(4))


def test_ranging_information_is_inverse_of_phy_crb(small_system, rng):
    S = qpsk_symbols(small_system, 1, rng)[0]
    snr = np.array([0.1, 1.0, 1e3])
    nu = ranging_information(snr, spectral_moment2(S), small_system.omega)
    np.testing.assert_allclose(1.0 / nu, crb_range(snr, S, small_system), rtol=1e-12)


def test_ranging_information_calls_the_one_eq24():
    snr = np.array([0.0, 0.5, 3.0, 1e6])
    np.testing.assert_array_equal(
        ranging_information(snr, 7.0, 1e8), 1.0 / ranging_crb(snr, 7.0, 1e8)
    )


def test_efim_is_exactly_symmetric(rng):
    for _ in range(20):
        pu, P, nu = rng.normal(0, 30, 3), rng.normal(0, 30, (7, 3)), rng.uniform(0.1, 10, 7)
        J = efim(pu, P, nu)
        np.testing.assert_array_equal(J, J.T)  # exactly: rounding could break the symmetry
        e = (pu - P) / np.linalg.norm(pu - P, axis=1)[:, None]
        by_hand = sum(n * np.outer(u, u) for n, u in zip(nu, e, strict=True))
        np.testing.assert_allclose(J, by_hand, rtol=1e-12)


def test_ranging_information_validation():
    with pytest.raises(ValidationError, match="snr"):
        ranging_information(-1.0, 5.0, 1e8)
    with pytest.raises(ValidationError, match="omega"):
        ranging_information(1.0, 5.0, 0.0)
    with pytest.raises(ValidationError, match="symbols_power_moment2"):
        ranging_information(1.0, np.nan, 1e8)


# -- DiPNet eq. (15) -------------------------------------------------------------------------------
def test_projected_variance_hand_values():
    C = np.array([[4.0, 1.0], [1.0, 2.0]])
    # e = (0.6, 0.8): 0.36·4 + 2·0.6·0.8·1 + 0.64·2 = 1.44 + 0.96 + 1.28 = 3.68
    assert projected_variance(C, [0.6, 0.8]) == pytest.approx(3.68, rel=1e-14)
    # the same direction given unnormalized
    assert projected_variance(C, [3.0, 4.0]) == pytest.approx(3.68, rel=1e-14)
    # along the axes: the diagonal entries
    assert projected_variance(C, [1.0, 0.0]) == pytest.approx(4.0)
    assert projected_variance(C, [0.0, -1.0]) == pytest.approx(2.0)
    # 3-D: e = (1, 2, 2)/3, C = diag(9, 1, 4): (9 + 4 + 16)/9 = 29/9
    assert projected_variance(np.diag([9.0, 1.0, 4.0]), [1.0, 2.0, 2.0]) == pytest.approx(29 / 9)


def test_projected_variance_batch_and_coincident():
    C = np.stack([np.diag([4.0, 2.0]), np.array([[4.0, 1.0], [1.0, 2.0]]), np.diag([1.0, 5.0])])
    e = np.array([[1.0, 0.0], [0.6, 0.8], [0.0, 0.0]])
    out = projected_variance(C, e)
    # last row: direction undefined -> isotropic tr(C)/dim = (1 + 5)/2 = 3
    np.testing.assert_allclose(out, [4.0, 3.68, 3.0], rtol=1e-14)
    assert np.all(np.isfinite(out))


def test_projected_variance_averages_to_isotropic_value(rng):
    # the isotropic choice is the average of eᵀCe over directions: check by quadrature
    A = rng.standard_normal((2, 2))
    C = A @ A.T
    phi = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    e = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    assert projected_variance(C, e).mean() == pytest.approx(
        projected_variance(C, [0.0, 0.0]), rel=1e-12
    )


# -- DiPNet eqs. (14), (18) ------------------------------------------------------------------------
def test_equivalent_ranging_information_hand_values():
    # ν = 4 m⁻² (CRB 0.25 m²), σ² = 0.75 m²: 1/ν̃ = 0.25 + 0.75 = 1 (18); 4/(1 + 3) = 1 (14)
    assert equivalent_ranging_information(4.0, 0.75) == pytest.approx(1.0, rel=1e-15)
    # ν = 100, σ² = 0.01: 100/(1 + 1) = 50
    assert equivalent_ranging_information(100.0, 0.01) == pytest.approx(50.0, rel=1e-14)
    # an anchor (σ² = 0) keeps its ν
    assert equivalent_ranging_information(7.0, 0.0) == 7.0


def test_eq14_equals_eq18(rng):
    nu = 10.0 ** rng.uniform(-4, 6, size=1000)
    s2 = 10.0 ** rng.uniform(-6, 4, size=1000)
    eq14 = nu / (1.0 + nu * s2)
    eq18 = 1.0 / (1.0 / nu + s2)
    out = equivalent_ranging_information(nu, s2)
    np.testing.assert_allclose(out, eq14, rtol=1e-12)
    np.testing.assert_allclose(out, eq18, rtol=1e-12)
    # ν̃ never exceeds ν nor 1/σ²
    assert np.all(out <= nu) and np.all(out <= 1.0 / s2)


def test_equivalent_ranging_information_limits_never_nan():
    nu = np.array([0.0, np.inf, np.inf, 5.0, 0.0])
    s2 = np.array([1.0, 0.5, 0.0, np.inf, 0.0])
    out = equivalent_ranging_information(nu, s2)
    np.testing.assert_array_equal(out, [0.0, 2.0, np.inf, 0.0, 0.0])
    with pytest.raises(ValidationError, match="nu"):
        equivalent_ranging_information(np.nan, 1.0)
    with pytest.raises(ValidationError, match="sigma2_proj"):
        equivalent_ranging_information(1.0, -0.1)


# -- DiPNet eq. (26) -------------------------------------------------------------------------------
def test_equivalent_noise_variance_hand_values():
    # ω = c0: σ̃² = 2 + 2·1·0.5·3·4 = 2 + 12 = 14
    assert equivalent_noise_variance(2.0, 0.5, 3.0, 4.0, C0) == pytest.approx(14.0, rel=1e-14)
    # ω = c0/10: 2 + 2·0.01·0.5·3·4 = 2.12
    assert equivalent_noise_variance(2.0, 0.5, 3.0, 4.0, C0 / 10) == pytest.approx(2.12)
    # a known neighbour (σ² = 0) leaves the noise variance unchanged
    assert equivalent_noise_variance(2.0, 0.0, 3.0, 4.0, C0) == 2.0


def test_env_reproduces_equivalent_ranging_uncertainty(rng, paper_system):
    # the derivation of DiPNet eq. (26): DiPNet eq. (24) with σ̃² in place of σ² gives
    # 1/ν + σ²_{v→uv} (DiPNet eq. (18))
    S = qpsk_symbols(paper_system, 1, rng)[0]
    M = spectral_moment2(S)
    w = paper_system.omega
    alpha2 = 10.0 ** rng.uniform(-12, -6, size=200)
    noise = 10.0 ** rng.uniform(-14, -11, size=200)
    s2 = 10.0 ** rng.uniform(-4, 3, size=200)
    env = equivalent_noise_variance(noise, s2, alpha2, M, w)
    lhs = 1.0 / ranging_information(alpha2 / env, M, w)
    rhs = 1.0 / ranging_information(alpha2 / noise, M, w) + s2
    np.testing.assert_allclose(lhs, rhs, rtol=1e-12)
    # and the ν̃ of DiPNet eq. (14) is the same number
    nu_eq = equivalent_ranging_information(ranging_information(alpha2 / noise, M, w), s2)
    np.testing.assert_allclose(1.0 / lhs, nu_eq, rtol=1e-12)


# -- EFIM (DiPNet eqs. (13), (17)) and the position bound ------------------------------------------
@pytest.mark.parametrize("K", [3, 4, 5, 8, 13])
def test_efim_anchors_on_circle_closed_form(K, rng):
    nu = 2.5
    phi = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.arange(K) / K
    center = np.array([12.0, -3.0])
    anchors = center + 40.0 * np.stack([np.cos(phi), np.sin(phi)], axis=1)
    J = efim(center, anchors, np.full(K, nu))
    np.testing.assert_allclose(J, (K / 2) * nu * np.eye(2), atol=1e-12)
    # tr J⁻¹ = 2 · 2/(Kν)
    assert position_crb(J) == pytest.approx(4.0 / (K * nu), rel=1e-12)


def test_efim_octahedron_3d():
    axes = np.vstack([np.eye(3), -np.eye(3)]) * 7.0
    J = efim(np.zeros(3), axes, np.full(6, 3.0))
    np.testing.assert_allclose(J, 2 * 3.0 * np.eye(3), atol=1e-12)  # Σ e eᵀ = 2 I
    assert position_crb(J) == pytest.approx(3 / 6.0)


def test_efim_matches_finite_difference_fisher_information(rng):
    # Gaussian ranging z_v = ‖p_u − p_v‖ + N(0, 1/ν_v): FIM = Hᵀ diag(ν) H, H = ∂d/∂p_u
    pu = rng.uniform(0, 50, size=2)
    P = rng.uniform(0, 50, size=(6, 2))
    nu = rng.uniform(0.5, 5.0, size=6)
    prior = np.array([[0.3, 0.1], [0.1, 0.2]])
    h = 1e-6
    H = np.empty((6, 2))
    for i in range(2):
        dp = np.zeros(2)
        dp[i] = h
        plus = np.linalg.norm(pu + dp - P, axis=1)
        minus = np.linalg.norm(pu - dp - P, axis=1)
        H[:, i] = (plus - minus) / (2 * h)
    np.testing.assert_allclose(efim(pu, P, nu, prior), prior + H.T @ (nu[:, None] * H), atol=1e-7)


def test_efim_with_neighbor_covariances_hand_values():
    # u at 0; v1 at (10, 0), C1 = diag(1, 5) -> σ² = 1, ν̃ = 1/(1 + 1) = 1/2
    #         v2 at (0, 10), C2 = diag(5, 2) -> σ² = 2, ν̃ = 1/(1 + 2) = 1/3
    J = efim(
        [0.0, 0.0],
        [[10.0, 0.0], [0.0, 10.0]],
        [1.0, 1.0],
        neighbor_cov=[np.diag([1.0, 5.0]), np.diag([5.0, 2.0])],
    )
    np.testing.assert_allclose(J, np.diag([0.5, 1.0 / 3.0]), atol=1e-15)
    assert position_crb(J) == pytest.approx(2.0 + 3.0)


def test_efim_coincident_neighbor_is_isotropic_and_finite():
    # a neighbour at u's own position: direction undefined -> ν I/dim
    J = efim([1.0, 1.0], [[1.0, 1.0], [4.0, 5.0]], [2.0, 5.0])
    # second link: e = (−0.6, −0.8): 5·[[0.36, 0.48], [0.48, 0.64]]; first: 2·I/2
    np.testing.assert_allclose(J, [[1.0 + 1.8, 2.4], [2.4, 1.0 + 3.2]], atol=1e-14)
    J3 = efim(np.zeros(3), np.zeros((1, 3)), [3.0], neighbor_cov=np.eye(3)[None] * 2.0)
    # σ² = tr(2I)/3 = 2, ν̃ = 3/(1 + 6) = 3/7, contribution (3/7)·I/3
    np.testing.assert_allclose(J3, np.eye(3) / 7.0, atol=1e-15)
    e, same = direction_vectors([1.0, 1.0], [[1.0, 1.0], [4.0, 5.0]])
    np.testing.assert_array_equal(same, [True, False])
    np.testing.assert_allclose(e, [[0.0, 0.0], [-0.6, -0.8]])


def test_efim_no_neighbors_and_prior_only():
    assert np.array_equal(efim([0.0, 0.0], np.zeros((0, 2)), []), np.zeros((2, 2)))
    assert position_crb(efim([0.0, 0.0], np.zeros((0, 2)), [])) == np.inf
    J = efim([0.0, 0.0], np.zeros((0, 2)), [], prior_info=np.diag([0.01, 0.04]))
    assert position_crb(J) == pytest.approx(100.0 + 25.0)


def test_efim_validation():
    with pytest.raises(ValidationError, match="nu"):
        efim([0.0, 0.0], [[1.0, 0.0]], [1.0, 2.0])
    with pytest.raises(ValidationError, match="nu"):
        efim([0.0, 0.0], [[1.0, 0.0]], [np.inf])
    with pytest.raises(ValidationError, match="neighbor_positions"):
        efim([0.0, 0.0], [[1.0, 0.0, 0.0]], [1.0])
    with pytest.raises(ValidationError, match="prior_info"):
        efim([0.0, 0.0], [[1.0, 0.0]], [1.0], prior_info=np.eye(3))


def test_position_crb_singular_and_regular():
    # collinear anchors (both on the x-axis): no information across -> inf, not NaN
    J = efim([0.0, 0.0], [[5.0, 0.0], [-7.0, 0.0]], [1.0, 1.0])
    assert position_crb(J) == np.inf
    assert position_crb(np.zeros((2, 2))) == np.inf
    # hand value: J = [[2, 1], [1, 2]] -> J⁻¹ = [[2, −1], [−1, 2]]/3, trace 4/3
    assert position_crb([[2.0, 1.0], [1.0, 2.0]]) == pytest.approx(4.0 / 3.0, rel=1e-14)
    out = position_crb(np.stack([np.diag([1.0, 4.0]), np.diag([1.0, 0.0]), np.eye(2) * 1e-30]))
    np.testing.assert_array_equal(out[:2], [1.25, np.inf])
    assert out[2] == pytest.approx(2e30)  # tiny but regular: scale does not matter
    with pytest.raises(ValidationError, match="PSD"):
        position_crb(np.diag([1.0, -1.0]))
    with pytest.raises(ValidationError, match="finite"):
        position_crb(np.diag([1.0, np.nan]))


def test_position_crb_matches_inverse_for_random_spd(rng):
    A = rng.standard_normal((50, 3, 3))
    J = A @ np.swapaxes(A, 1, 2) + 0.1 * np.eye(3)
    np.testing.assert_allclose(
        position_crb(J), np.trace(np.linalg.inv(J), axis1=1, axis2=2), rtol=1e-10
    )
    assert math.isfinite(float(position_crb(J[0])))


def test_projected_variance_of_a_collapsed_belief_is_never_negative():
    """A rank-1 covariance seen orthogonally is 0 in exact arithmetic; the raw quadratic form
    rounds below zero in about a quarter of the cases (this crashed a Fig. 5 run through
    DiPNet eq. (26)). Clamped: >= 0, and the ENV built on it stays valid."""
    rng = np.random.default_rng(0)
    a = rng.normal(size=(4000, 2))
    C = a[:, :, None] * a[:, None, :]
    e = np.stack([-a[:, 1], a[:, 0]], axis=1)
    u = e / np.linalg.norm(e, axis=1, keepdims=True)
    raw = np.einsum("ni,nij,nj->n", u, C, u)
    assert np.sum(raw < 0) > 100  # the case is exercised
    got = projected_variance(C, e)
    assert np.all(got >= 0) and np.all(got <= 1e-12 * np.trace(C, axis1=1, axis2=2))
    env = equivalent_noise_variance(1e-3, got, 1.0, 1e6, 2 * np.pi * 14.65e3)
    assert np.all(np.isfinite(env)) and np.all(env > 0)

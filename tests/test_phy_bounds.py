"""Ranging CRB (DiPNet eq. (24)) and the one-path Ziv–Zakai bound."""

import math

import numpy as np
import pytest

from naive import C0, trapezoid_zzb
from phyloc.errors import ValidationError
from phyloc.phy.bounds import crb_range, post_correlation_snr, ranging_crb, zzb_range
from phyloc.phy.system import OFDMSystem
from phyloc.phy.waveform import qpsk_symbols
from phyloc.ranging.variance import ranging_variance


@pytest.fixture
def S(paper_system):
    return qpsk_symbols(paper_system, 1, np.random.default_rng(0))[0]


def test_ranging_crb_is_the_one_eq24(paper_system, S):
    # ω = c0 ⇒ CRB = 1/(2·SNR·M) = 1/(2·10·5) = 0.01
    assert ranging_crb(10.0, 5.0, C0) == pytest.approx(0.01, rel=1e-14)
    assert ranging_crb(0.0, 5.0, C0) == np.inf
    # crb_range is DiPNet eq. (24) for given pilots: the same numbers, bit for bit
    n = paper_system.subcarrier_indices()
    M = float((np.abs(S) ** 2 * n**2).sum())
    snr = np.array([0.01, 0.37, 5.0])
    np.testing.assert_array_equal(
        crb_range(snr, S, paper_system), ranging_crb(snr, M, paper_system.omega)
    )


def test_crb_closed_form_for_unit_modulus_pilots(paper_system, S):
    N = 2569
    sum_n2 = (N - 1) * N * (N + 1) / 12  # Σ n² over the symmetric index set
    omega = 2 * math.pi * 14650
    snr = 0.37
    expected = C0**2 / (2 * snr * omega**2 * sum_n2)
    assert crb_range(snr, S, paper_system) == pytest.approx(expected, rel=1e-12)
    assert post_correlation_snr(snr, S, paper_system) == pytest.approx(snr * N)


def test_crb_scales_with_pilot_power(paper_system, S):
    # doubling every |S_n|² is the same as doubling the SNR
    assert crb_range(1.0, np.sqrt(2) * S, paper_system) == pytest.approx(
        crb_range(2.0, S, paper_system)
    )


def test_zzb_tends_to_crb_at_high_snr(paper_system, S):
    pc_db = np.array([30.0, 40.0, 50.0, 60.0])
    snr = 10 ** (pc_db / 10) / 2569
    ratio = zzb_range(snr, S, paper_system) / crb_range(snr, S, paper_system)
    np.testing.assert_allclose(ratio, 1.0, atol=0.01)


def test_zzb_exceeds_crb_below_threshold_and_is_capped_by_prior(paper_system, S):
    D = 100.0
    pc_db = np.arange(-30.0, 41.0, 2.5)
    snr = 10 ** (pc_db / 10) / 2569
    z = zzb_range(snr, S, paper_system, prior_range_m=D)
    c = crb_range(snr, S, paper_system)
    assert np.all(np.diff(z) <= 1e-12)  # non-increasing in SNR
    assert np.all(z <= D**2 / 12 * (1 + 1e-9))
    below = (pc_db >= -10) & (pc_db <= 5)
    assert np.all(z[below] > 2.0 * c[below])
    assert z[0] == pytest.approx(D**2 / 12, rel=0.05)  # no information: the prior variance


def test_zzb_matches_brute_force_integral_without_valley_filling(paper_system, S):
    n = paper_system.subcarrier_indices()
    P = np.abs(S) ** 2
    w = paper_system.omega / C0

    def one_minus_rho(h):
        return 1.0 - (np.cos(w * np.outer(h, n)) @ P) / P.sum()

    for pc_db in (5.0, 12.0):
        snr = 10 ** (pc_db / 10) / 2569
        ref = trapezoid_zzb(snr * P.sum(), one_minus_rho, 60.0, n=8001)
        got = zzb_range(snr, S, paper_system, prior_range_m=60.0, valley_filling=False)
        assert got == pytest.approx(ref, rel=1e-3)
        # valley filling only tightens (raises) the bound
        assert zzb_range(snr, S, paper_system, prior_range_m=60.0) >= got


def test_bounds_at_extreme_snr_stay_defined(paper_system, S):
    assert crb_range(0.0, S, paper_system) == np.inf
    z = zzb_range(np.array([0.0, 1e-30, 1e30]), S, paper_system)
    assert np.all(np.isfinite(z)) and np.all(z >= 0)
    with pytest.raises(ValidationError, match="snr"):
        crb_range(-1.0, S, paper_system)
    with pytest.raises(ValidationError, match="prior_range_m"):
        zzb_range(1.0, S, paper_system, prior_range_m=0.0)


def test_zzb_prior_beyond_its_lag_grid_is_refused_by_name(paper_system, S):
    """The ZZB is integrated on a uniform lag grid of step c0/(32 B) held in memory, so the prior
    range has a limit (65 536 steps); 1e300 m once made the grid overflow NumPy ("Maximum allowed
    size exceeded", found by the recipe fuzzer). A prior beyond the unambiguous range c0/Δf is
    still a prior (ρ repeats, the hypotheses a period apart are confused), so 300 m at Δf = 1 MHz
    (c0/Δf = 299.8 m) is allowed."""
    step = C0 / (32.0 * paper_system.bandwidth_hz)
    zzb_range(np.array([1.0]), S, paper_system, prior_range_m=0.99 * 65_536 * step)  # allowed
    for D in (1.01 * 65_536 * step, 1e300):
        with pytest.raises(ValidationError, match=r"prior_range_m.*lag grid of step c0/\(32 B\)"):
            zzb_range(np.array([1.0]), S, paper_system, prior_range_m=D)
    with pytest.raises(ValidationError, match="prior_range_m"):
        ranging_variance(np.array([1.0]), S, paper_system, prior_range_m=1e300)
    wide = OFDMSystem(n_subcarriers=65, subcarrier_spacing_hz=1e6)
    Sw = np.ones(wide.n_subcarriers, complex)
    assert np.isfinite(zzb_range(np.array([1.0, 1e6]), Sw, wide, prior_range_m=300.0)).all()

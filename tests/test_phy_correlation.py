"""Correlation tables (β-interpolated IFFT, eq. (23)), interpolation bounds, α̂, SNR, peaks."""

import math

import numpy as np
import pytest
from naive_phy import interp_numpy, refine_peaks_numpy, spectrum_numpy, symbol_moments_numpy

from naive import C0, cross_correlation, lagrange
from phyloc.errors import ValidationError
from phyloc.phy import OFDMSystem, PathSet
from phyloc.phy import _kernels as K
from phyloc.phy import fft as phyfft
from phyloc.phy.bounds import crb_range
from phyloc.phy.correlation import correlation_tables, fft_length
from phyloc.phy.synthesis import synthesize
from phyloc.phy.waveform import qpsk_symbols, to_time_domain


def multipath_table(rng, sysm, n_links=3, beta=8.0, noise=True):
    S = qpsk_symbols(sysm, 1, rng)
    counts = rng.integers(1, 6, n_links)
    tot = int(counts.sum())
    paths = PathSet(
        rng.uniform(0, 40 / sysm.bandwidth_hz, tot),
        1e-5 * (rng.standard_normal(tot) + 1j * rng.standard_normal(tot)),
        np.concatenate([[0], np.cumsum(counts)]),
    )
    R = synthesize(paths, S, sysm, rng if noise else None)
    return S, R, correlation_tables(R, S, sysm, beta=beta)


@pytest.mark.parametrize("os", [1, 2])
def test_table_equals_direct_cross_correlation(rng, os):
    sysm = OFDMSystem(n_subcarriers=33, subcarrier_spacing_hz=1e6, oversampling=os)
    S, R, tab = multipath_table(rng, sysm, n_links=2)
    r = to_time_domain(R, sysm)
    grid = tab.distances()
    for i in range(2):
        for k in [0, 1, 7, 100, tab.n_fft - 1]:
            ref = cross_correlation(r[i], S[0], 33, 1e6, os, grid[k]) / os
            assert abs(tab.values[i, k] - ref) <= 1e-10 * abs(tab.values[i]).max()
        for d in rng.uniform(-50, 500, 4):  # off-grid, negative and beyond: exact form
            ref = cross_correlation(r[i], S[0], 33, 1e6, os, d) / os
            assert abs(tab.exact([d], links=[i])[0] - ref) <= 1e-10 * abs(tab.values[i]).max()


@pytest.mark.parametrize(
    ("method", "rel_bound"), [("linear", 1.95e-2), ("cubic", 5.7e-4), ("quintic", 1.9e-5)]
)
def test_interpolation_error_within_stated_bound_at_beta_8(paper_system, rng, method, rel_bound):
    _S, _R, tab = multipath_table(rng, paper_system, n_links=4)
    assert tab.beta == pytest.approx(7.972, abs=1e-3)
    bound = tab.interpolation_error_bound(method)
    # the documented relative bound (W_p/p!)(π/β)^p Σ|c_n| is no looser than stated
    assert np.all(bound <= rel_bound * np.abs(tab.spectrum).sum(axis=1))
    d = rng.uniform(0, 300, (4, 400))
    err = np.abs(tab.evaluate(d, interpolation=method) - tab.exact(d))
    assert np.all(err <= bound[:, None])
    # and the bound is not vacuous: the observed error reaches a sizeable part of it
    assert err.max() >= 0.02 * bound.max()


def test_interpolation_converges_with_beta(paper_system, rng):
    errs = []
    S = qpsk_symbols(paper_system, 1, rng)
    R = synthesize(PathSet.single_path([37.7 / C0], [1e-5]), S, paper_system, None)
    d = rng.uniform(20, 60, (1, 2000))
    for beta in (4, 8, 16):
        tab = correlation_tables(R, S, paper_system, beta=beta)
        errs.append(np.abs(tab.evaluate(d) - tab.exact(d)).max())
    # cubic Lagrange: error ∝ β^-4 (factor 16 per doubling, allow slack for the smooth lengths)
    assert errs[0] / errs[1] > 10 and errs[1] / errs[2] > 10


@pytest.mark.parametrize("order", [2, 4, 6])
def test_interp_kernel_matches_twin_and_naive(rng, order):
    values = rng.standard_normal((3, 50)) + 1j * rng.standard_normal((3, 50))
    rows = rng.integers(0, 3, 64)
    x = rng.uniform(-60, 120, 64)  # wraps around the period both ways
    out = np.empty(64, complex)
    K.interp_kernel(values, rows, x, order, out)
    np.testing.assert_allclose(out, interp_numpy(values, rows, x, order), rtol=1e-13)
    ref = [lagrange(values[r], xx, order) for r, xx in zip(rows, x, strict=True)]
    np.testing.assert_allclose(out, ref, rtol=1e-12)
    out1 = np.empty(64, complex)
    K.interp_row_kernel(values, 1, x, order, out1)
    np.testing.assert_allclose(out1, interp_numpy(values, np.ones(64, np.int64), x, order))


def test_interpolation_is_exact_on_grid_points(paper_system, rng):
    _, _, tab = multipath_table(rng, paper_system, n_links=2)
    k = rng.integers(0, tab.n_fft, (2, 10))
    for method in ("linear", "cubic", "quintic"):
        np.testing.assert_allclose(
            tab.evaluate(k * tab.spacing_m, interpolation=method),
            np.take_along_axis(tab.values, k, axis=1),
            rtol=1e-9,
            atol=1e-18,
        )


def test_noise_free_one_path_recovers_delay_amplitude_and_likelihood(paper_system, rng):
    S = qpsk_symbols(paper_system, 1, rng)
    d_true = rng.uniform(1, 150, 8)
    alpha = 1e-6 * np.exp(2j * np.pi * rng.uniform(size=8))
    R = synthesize(PathSet.single_path(d_true / C0, alpha), S, paper_system, None)
    tab = correlation_tables(R, S, paper_system)
    est = tab.peak(window_m=(0, 200))
    np.testing.assert_allclose(est, d_true, atol=1e-6)
    np.testing.assert_allclose(tab.peak(refine=False), d_true, atol=tab.spacing_m / 2 + 1e-9)
    a_hat = tab.amplitude(d_true[:, None], interpolation="quintic")[:, 0]
    np.testing.assert_allclose(a_hat, alpha, rtol=1e-4)
    # eq. (22) at the true distance: |α|² ‖S‖² / σ²
    ll = tab.log_likelihood(d_true[:, None], interpolation="quintic")[:, 0]
    np.testing.assert_allclose(
        ll, np.abs(alpha) ** 2 * 2569 / paper_system.noise_power_w, rtol=1e-4
    )


@pytest.mark.parametrize("pc_snr_db", [20.0, 30.0, 40.0])
def test_peak_estimate_attains_the_crb_in_awgn(paper_system, pc_snr_db):
    rng = np.random.default_rng(int(pc_snr_db))
    n = 500
    S = qpsk_symbols(paper_system, 1, rng)
    snr = 10 ** (pc_snr_db / 10) / paper_system.n_subcarriers
    amp = math.sqrt(snr * paper_system.noise_power_w)
    d_true = rng.uniform(5.0, 140.0, n)
    paths = PathSet.single_path(d_true / C0, amp * np.exp(2j * np.pi * rng.uniform(size=n)))
    tab = correlation_tables(synthesize(paths, S, paper_system, rng), S, paper_system)
    err = tab.peak(window_m=(0.0, 200.0)) - d_true
    rmse = math.sqrt(np.mean(err**2))
    sqrt_crb = math.sqrt(crb_range(snr, S[0], paper_system))
    assert rmse == pytest.approx(sqrt_crb, rel=0.15)


def test_snr_estimate_is_unbiased(paper_system, rng):
    S = qpsk_symbols(paper_system, 1, rng)
    snr = 10 ** (25 / 10) / 2569
    n = 400
    d = rng.uniform(5, 100, n)
    amp = math.sqrt(snr * paper_system.noise_power_w)
    tab = correlation_tables(
        synthesize(PathSet.single_path(d / C0, amp), S, paper_system, rng), S, paper_system
    )
    est = tab.snr(d[:, None], interpolation="quintic")[:, 0]
    assert est.mean() / snr == pytest.approx(1.0, rel=0.03)
    # noise only: the bias-corrected estimate is ~0, never negative, never NaN
    empty = PathSet(np.zeros(0), np.zeros(0, complex), np.zeros(n + 1, np.int64))
    t0 = correlation_tables(synthesize(empty, S, paper_system, rng), S, paper_system)
    e0 = t0.snr(d[:, None])
    assert np.all(e0 >= 0) and np.all(np.isfinite(e0)) and e0.mean() < 3.0 / 2569


def test_refine_kernel_matches_twin(paper_system, rng):
    _, _, tab = multipath_table(rng, paper_system, n_links=6)
    d0 = tab.peak(refine=False)
    out = np.empty_like(d0)
    n = paper_system.subcarrier_indices()
    w = paper_system.omega / C0
    K.refine_peaks_kernel(tab.spectrum, n, w, d0, tab.spacing_m, 8, out)
    np.testing.assert_allclose(
        out, refine_peaks_numpy(tab.spectrum, n, w, d0, tab.spacing_m, 8), atol=1e-9
    )
    # refinement never lowers the correlation magnitude it maximizes
    assert np.all(np.abs(tab.exact(out[:, None])) >= np.abs(tab.exact(d0[:, None])) * (1 - 1e-12))


def test_pyfftw_and_scipy_backends_agree(paper_system, rng):
    S, R, tab = multipath_table(rng, paper_system, n_links=5, noise=True)
    previous = phyfft.backend()
    try:
        phyfft.set_backend("scipy")
        other = correlation_tables(R, S, paper_system)
    finally:
        phyfft.set_backend(previous)
    np.testing.assert_allclose(other.values, tab.values, atol=1e-12 * np.abs(tab.values).max())


def test_fft_length_is_smooth_and_near_beta_n(paper_system):
    assert fft_length(paper_system, 8) == 20480  # 2^12·5, not 8·2569 = 20552 = 2^3·7·367
    for beta in (1, 3.3, 8, 16):
        L = fft_length(paper_system, beta)
        assert L >= paper_system.n_subcarriers
        m = L
        for p in (2, 3, 5):
            while m % p == 0:
                m //= p
        assert m == 1
        assert abs(L / paper_system.n_subcarriers - beta) / beta < 0.05


@pytest.mark.parametrize(
    ("beta", "match"),
    [(0.0, "beta = 0.0 .*> 0"), (0.5, "beta = 0.5 .*>= 1"), (float("nan"), "beta")],
)
def test_bad_beta(paper_system, rng, beta, match):
    S = qpsk_symbols(paper_system, 1, rng)
    with pytest.raises(ValidationError, match=match):
        correlation_tables(np.zeros((1, 2569), complex), S, paper_system, beta=beta)


def test_bad_table_inputs(paper_system, rng):
    S = qpsk_symbols(paper_system, 1, rng)
    with pytest.raises(ValidationError, match="R = array of shape"):
        correlation_tables(np.zeros((2, 100), complex), S, paper_system)
    R = np.zeros((1, 2569), complex)
    R[0, 5] = np.nan
    with pytest.raises(ValidationError, match=r"R = \(nan.*finite"):
        correlation_tables(R, S, paper_system)
    tab = correlation_tables(np.ones((2, 2569), complex), S, paper_system)
    with pytest.raises(ValidationError, match="interpolation"):
        tab.evaluate(np.zeros((2, 1)), interpolation="spline")
    with pytest.raises(ValidationError, match="links"):
        tab.evaluate([1.0], links=[2])
    with pytest.raises(ValidationError, match="window_m"):
        tab.peak(window_m=(5.0, 1.0))


@pytest.mark.slow
def test_peak_estimate_attains_the_crb_across_snr_dense(paper_system):
    """Slow: 4000 links per SNR from 20 to 50 dB; RMSE within 5 % of √CRB everywhere."""
    S = qpsk_symbols(paper_system, 1, np.random.default_rng(0))
    for pc_snr_db in np.arange(20.0, 51.0, 5.0):
        rng = np.random.default_rng(int(pc_snr_db * 10))
        snr = 10 ** (pc_snr_db / 10) / paper_system.n_subcarriers
        amp = math.sqrt(snr * paper_system.noise_power_w)
        d_true = rng.uniform(5.0, 140.0, 4000)
        phase = np.exp(2j * np.pi * rng.uniform(size=4000))
        paths = PathSet.single_path(d_true / C0, amp * phase)
        tab = correlation_tables(synthesize(paths, S, paper_system, rng), S, paper_system)
        rmse = math.sqrt(np.mean((tab.peak(window_m=(0.0, 200.0)) - d_true) ** 2))
        assert rmse == pytest.approx(math.sqrt(crb_range(snr, S[0], paper_system)), rel=0.05)


@pytest.mark.parametrize("dtype", [np.complex128, np.complex64])
@pytest.mark.parametrize("n_links", [3, 40])
def test_spectrum_kernel_equals_numpy_twin_and_flags_non_finite(rng, dtype, n_links):
    """c = R* S[tx] of eq. (23) in one pass: NumPy's product to the last bit or two (NumPy may
    fuse multiply-adds), serial bit-equal to parallel, and any NaN or ±inf in a real or
    imaginary part is reported."""
    N = 257
    S = rng.standard_normal((3, N)) + 1j * rng.standard_normal((3, N))
    R = (rng.standard_normal((n_links, N)) + 1j * rng.standard_normal((n_links, N))).astype(dtype)
    tx = rng.integers(0, 3, n_links)
    ref, ok = spectrum_numpy(R, S, tx)
    assert ok
    outs = []
    for kernel in (K.spectrum_kernel, K.spectrum_serial_kernel):
        outs.append(np.empty((n_links, N), np.complex128))
        assert kernel(R, S, tx, outs[-1])
        np.testing.assert_allclose(outs[-1], ref, rtol=1e-15)
    np.testing.assert_array_equal(outs[0], outs[1])
    for bad in (np.nan, np.inf, -np.inf):
        for part in (1.0, 1j):
            Rb = R.copy()
            Rb[n_links - 1, N // 2] = bad * part if part == 1.0 else complex(0.0, bad)
            out = np.empty((n_links, N), np.complex128)
            assert not K.spectrum_kernel(Rb, S, tx, out)
            assert not K.spectrum_serial_kernel(Rb, S, tx, out)


def test_symbol_moments_kernel_equals_numpy_twin(rng):
    S = rng.standard_normal((4, 2569)) + 1j * rng.standard_normal((4, 2569))
    energy, moment2 = np.empty(4), np.empty(4)
    K.symbol_moments_kernel(S, -1284.0, energy, moment2)
    e_ref, m_ref = symbol_moments_numpy(S, -1284.0)
    np.testing.assert_allclose(energy, e_ref, rtol=1e-13)
    np.testing.assert_allclose(moment2, m_ref, rtol=1e-13)


def test_tables_reject_non_finite_received_symbols_naming_the_entry(paper_system, rng):
    S = qpsk_symbols(paper_system, 1, rng)
    R = synthesize(PathSet.single_path([1e-7, 2e-7], [1e-6, 1e-6]), S, paper_system, rng)
    R[1, 5] = complex(0.0, np.inf)
    with pytest.raises(ValidationError, match=r"R = .*inf.* at flat index 2574"):
        correlation_tables(R, S, paper_system)
    R[1, 5] = 0.0
    tab32 = correlation_tables(R.astype(np.complex64), S, paper_system)
    ref = correlation_tables(R.astype(np.complex64).astype(np.complex128), S, paper_system)
    np.testing.assert_array_equal(tab32.values, ref.values)  # complex64 read as it is


def test_tables_written_into_a_callers_array_equal_fresh_ones(rng):
    """``out=`` reuses the caller's memory: same values as a fresh table (also when the last
    FFT chunk is partial), the table holds that array, and a wrong array is refused by name."""
    sysm = OFDMSystem(n_subcarriers=65)
    S, R, fresh = multipath_table(rng, sysm, n_links=5, beta=4.0)
    buf = phyfft.aligned_empty((5, fresh.n_fft))
    buf[...] = np.nan  # stale contents of an earlier batch must not survive
    tab = correlation_tables(R, S, sysm, beta=4.0, chunk=2, out=buf)
    assert tab.values is buf
    np.testing.assert_array_equal(tab.values, fresh.values)
    strided = np.zeros((5, 2 * fresh.n_fft), np.complex128)[:, ::2]
    for bad in (buf[:4], buf.astype(np.complex64), strided, np.zeros(5)):
        with pytest.raises(ValidationError, match=r"^out = "):
            correlation_tables(R, S, sysm, beta=4.0, out=bad)


def test_a_held_table_is_never_overwritten_and_a_dropped_ones_memory_is_reused(paper_system, rng):
    """Tables of at least :data:`~phyloc.phy.fft.RECYCLE_MIN_BYTES` recycle the memory of dropped
    ones (no fresh pages to zero) and are then the same as tables in fresh memory; a table, or
    any view of its values, still held keeps its values through later tables."""
    S = qpsk_symbols(paper_system, 1, rng)
    n = 16  # 16 · 20480 · 16 B = 5.2 MB

    def table():
        d = rng.uniform(5.0, 100.0, n) / C0
        paths = PathSet(d, np.full(n, 1e-6 + 0j), np.arange(n + 1))
        R = synthesize(paths, S, paper_system, rng)
        return correlation_tables(R, S, paper_system), R

    phyfft.release_recycled()
    first, _ = table()
    assert first.values.nbytes >= phyfft.RECYCLE_MIN_BYTES
    addresses = {first.values.ctypes.data}
    kept_row = first.values[3]  # a view only
    copy = kept_row.copy()
    del first
    second, _ = table()
    assert second.values.ctypes.data not in addresses
    np.testing.assert_array_equal(kept_row, copy)
    addresses.add(second.values.ctypes.data)
    del kept_row, second  # now nothing refers to either
    third, R = table()
    assert third.values.ctypes.data in addresses
    fresh = phyfft.aligned_empty(third.values.shape)
    np.testing.assert_array_equal(
        third.values, correlation_tables(R, S, paper_system, out=fresh).values
    )

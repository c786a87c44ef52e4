"""The fused pipeline kernels (:mod:`phyloc.phy._pipeline_kernels`) against their plain twins
(``tests/naive_phy.py``) and, bit for bit, against the two-pass kernels they replace."""

import numpy as np
import pytest
from naive_phy import (
    finite_nonzero_numpy,
    noisy_synthesize_numpy,
    spectrum_padded_numpy,
)

from phyloc.phy import OFDMSystem, PathSet, _gauss, _kernels
from phyloc.phy import _pipeline_kernels as pk
from phyloc.phy import fft as phyfft
from phyloc.phy.correlation import correlation_tables
from phyloc.phy.synthesis import synthesize
from phyloc.phy.waveform import qpsk_symbols

Z = (_gauss.ZIG_X, _gauss.ZIG_F, _gauss.ZIG_K)


def random_paths(rng, n_links, max_paths):
    counts = rng.integers(0, max_paths + 1, n_links)  # links without paths included
    total = int(counts.sum())
    delays = rng.uniform(0.0, 2e-6, total)
    gains = 1e-6 * (rng.standard_normal(total) + 1j * rng.standard_normal(total))
    return PathSet(delays, gains, np.concatenate([[0], np.cumsum(counts)]))


def _inputs(rng, n_links, N, n_tx=3):
    S = qpsk_symbols(OFDMSystem(n_subcarriers=N), n_tx, rng)
    paths = random_paths(rng, n_links, 30)
    tx = rng.integers(0, n_tx, n_links).astype(np.int64)
    seeds = rng.integers(0, 2**64, n_links, dtype=np.uint64)
    scale = rng.uniform(0.5, 2.0, n_links) * 1e-7
    return S, paths, tx, seeds, scale


@pytest.mark.parametrize("kernel", ["parallel", "serial"])
def test_noisy_synthesis_equals_plain_twin(rng, kernel):
    N, n = 65, 9
    S, paths, tx, seeds, scale = _inputs(rng, n, N)
    omega, n_first = 2 * np.pi * 1e6, -float((N - 1) // 2)
    out = np.empty((n, N), dtype=np.complex128)
    k = pk.noisy_synthesize_kernel if kernel == "parallel" else pk.noisy_synthesize_serial_kernel
    k(seeds, scale, *Z, S, tx, paths.delays, paths.gains, paths.offsets, omega, n_first, out,
      out.view(np.float64))  # fmt: skip
    ref = noisy_synthesize_numpy(
        seeds, scale, *Z, S, tx, paths.delays, paths.gains, paths.offsets, omega, n_first, N
    )
    assert np.abs(out - ref).max() <= 1e-12 * np.abs(ref).max()


@pytest.mark.parametrize("N", [3, 65, 2569])
def test_noisy_synthesis_is_bitwise_the_two_pass_path(rng, N):
    """Noise drawn for all rows first, then the synthesis kernel reading it (the path the fused
    kernel replaces): the same bits, for every row and thread count."""
    n = 70  # more rows than the kernel's 64 chunks
    S, paths, tx, seeds, scale = _inputs(rng, n, N)
    omega, n_first = 2 * np.pi * 14.65e3, -float((N - 1) // 2)
    two = np.empty((n, N), dtype=np.complex128)
    _gauss.normal_rows_kernel(seeds, scale, *Z, two.view(np.float64))
    _kernels.synthesize_kernel(
        S, tx, paths.delays, paths.gains, paths.offsets, omega, n_first, two, two
    )
    for k in (pk.noisy_synthesize_kernel, pk.noisy_synthesize_serial_kernel):
        one = np.empty((n, N), dtype=np.complex128)
        k(seeds, scale, *Z, S, tx, paths.delays, paths.gains, paths.offsets, omega, n_first,
          one, one.view(np.float64))  # fmt: skip
        assert np.array_equal(one.view(np.float64), two.view(np.float64))


@pytest.mark.parametrize("dtype", [np.complex128, np.complex64])
def test_spectrum_padded_equals_plain_twin(rng, dtype):
    N, L, n = 65, 96, 11
    R = (rng.standard_normal((n, N)) + 1j * rng.standard_normal((n, N))).astype(dtype)
    S = qpsk_symbols(OFDMSystem(n_subcarriers=N), 2, rng)
    tx = rng.integers(0, 2, n).astype(np.int64)
    for a, rows in ((0, 4), (8, 4)):  # a full chunk, and the last one with 3 rows left
        spec = np.full((n, N), np.nan + 0j)
        buf = np.zeros((rows, L), dtype=np.complex128)
        ok = pk.spectrum_padded_kernel(R, S, tx, a, spec, buf)
        b = min(rows, n - a)
        c, padded, finite = spectrum_padded_numpy(R, S, tx, a, b, L)
        tol = 1e-15 * np.abs(c).max()  # NumPy's complex product may round through an FMA
        assert np.abs(spec[a : a + b] - c).max() <= tol
        assert np.abs(buf[:b] - padded).max() <= tol
        assert np.count_nonzero(buf[:b]) == np.count_nonzero(padded)  # the middle stays zero
        assert ok == finite is True
        # bit for bit the two-pass path: the spectrum kernel, then the copy into the padding
        two = np.empty((n, N), dtype=np.complex128)
        _kernels.spectrum_kernel(R, S, tx, two)
        assert np.array_equal(spec[a : a + b], two[a : a + b])
        assert np.all(np.isnan(np.delete(spec, np.s_[a : a + b], axis=0)))  # others untouched


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_spectrum_padded_flags_a_non_finite_entry(rng, bad):
    N, L = 65, 96
    R = rng.standard_normal((4, N)) + 0j
    R[2, 40] = complex(0.0, bad)
    S = qpsk_symbols(OFDMSystem(n_subcarriers=N), 1, rng)
    tx = np.zeros(4, np.int64)
    buf = np.zeros((4, L), dtype=np.complex128)
    assert not pk.spectrum_padded_kernel(R, S, tx, 0, np.empty((4, N), complex), buf)
    assert pk.spectrum_padded_kernel(R, S, tx, 3, np.empty((4, N), complex), buf[:1])


def test_spectrum_padded_fft_is_bitwise_the_centered_fft(rng, paper_system):
    """Filling the FFT input in the kernel and copying a spectrum in (``centered``) give the
    same transform input, so the same table bits."""
    n, L = 5, 20480
    R = rng.standard_normal((n, 2569)) + 1j * rng.standard_normal((n, 2569))
    S = qpsk_symbols(paper_system, 1, rng)
    tx = np.zeros(n, np.int64)
    spec = np.empty_like(R)
    plan = phyfft.batch_fft(n, L)
    got = plan.filled(lambda buf: pk.spectrum_padded_kernel(R, S, tx, 0, spec, buf), n, 1284)
    got = got.copy()
    two = np.empty_like(R)
    _kernels.spectrum_kernel(R, S, tx, two)
    ref = plan.centered(two)
    assert np.array_equal(spec, two)
    assert np.array_equal(got, ref)


@pytest.mark.parametrize(
    "x",
    [
        np.array([0.0, -0.0, 1e-300]),
        np.array([0.0, -0.0]),
        np.array([1.0, np.nan]),
        np.array([np.inf, 0.0]),
        np.array([-np.inf]),
        np.array([5e-324, 0.0]),  # a subnormal is non-zero
        np.array([1.7976931348623157e308]),  # the largest float is finite
        np.zeros(0),
    ],
)
def test_finite_nonzero_equals_plain_twin(x):
    assert pk.finite_nonzero_kernel(x.view(np.uint64)) == finite_nonzero_numpy(x)


@pytest.mark.parametrize("n_links", [1, 3, 8, 70])
def test_public_pipeline_does_not_depend_on_the_link_count_path(paper_system, n_links):
    """Serial (few links) and parallel synthesis, and any chunking of the table, give the
    values of one link at a time (rows are independent)."""
    rng = np.random.default_rng(4)
    S = qpsk_symbols(paper_system, 2, rng)
    paths = random_paths(rng, n_links, 6)
    tx = rng.integers(0, 2, n_links)
    R = synthesize(paths, S, paper_system, np.random.default_rng(9), tx_index=tx)
    tab = correlation_tables(R, S, paper_system, tx_index=tx, chunk=3)
    for i in range(n_links):
        one = correlation_tables(R[i], S, paper_system, tx_index=tx[i : i + 1])
        assert np.array_equal(one.values[0], tab.values[i])
        assert np.array_equal(one.spectrum[0], tab.spectrum[i])

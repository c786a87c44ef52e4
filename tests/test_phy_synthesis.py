"""Multipath synthesis (DiPNet eq. (6)) against the direct time-domain sum and its NumPy twin."""

import numpy as np
import pytest
from naive_phy import synthesize_numpy

from naive import received_samples
from phyloc.errors import ValidationError
from phyloc.phy import OFDMSystem, PathSet
from phyloc.phy.synthesis import complex_noise, synthesize
from phyloc.phy.waveform import qpsk_symbols, to_time_domain


def random_paths(rng, n_links, max_paths, max_delay=2e-6, scale=1e-5, allow_empty=True):
    counts = rng.integers(0 if allow_empty else 1, max_paths + 1, n_links)
    total = int(counts.sum())
    delays = rng.uniform(0.0, max_delay, total)
    gains = scale * (rng.standard_normal(total) + 1j * rng.standard_normal(total))
    return PathSet(delays, gains, np.concatenate([[0], np.cumsum(counts)]))


@pytest.mark.parametrize("os", [1, 2])
def test_synthesis_equals_direct_sum_of_delayed_symbols(rng, os):
    sysm = OFDMSystem(n_subcarriers=41, subcarrier_spacing_hz=1.3e6, oversampling=os)
    S = qpsk_symbols(sysm, 2, rng)
    paths = random_paths(rng, 4, 5, allow_empty=False)
    tx = np.array([0, 1, 1, 0])
    r = to_time_domain(synthesize(paths, S, sysm, None, tx_index=tx), sysm)
    for i in range(paths.n_links):
        d, g = paths.link(i)
        ref = received_samples(S[tx[i]], d, g, 41, 1.3e6, os)
        err = np.abs(r[i] - ref).max() / np.abs(ref).max()
        assert err <= 1e-9


@pytest.mark.parametrize("N", [3, 65, 2569])
def test_kernel_equals_numpy_twin(rng, N):
    sysm = OFDMSystem(n_subcarriers=N)
    S = qpsk_symbols(sysm, 3, rng)
    paths = random_paths(rng, 17, 30)  # includes links without paths
    tx = rng.integers(0, 3, paths.n_links)
    a = synthesize(paths, S, sysm, np.random.default_rng(1), tx_index=tx)
    noise = complex_noise((paths.n_links, N), sysm.noise_power_w, np.random.default_rng(1))
    n_first = -float((N - 1) // 2)
    b = synthesize_numpy(
        S, tx, paths.delays, paths.gains, paths.offsets, sysm.omega, n_first, noise
    )
    assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()


def test_long_delays_keep_exact_phase(rng):
    # delays near the symbol period stress the phasor recurrence: compare with exact exp
    sysm = OFDMSystem()
    S = qpsk_symbols(sysm, 1, rng)
    tau = sysm.symbol_duration_s * np.array([0.999999, 0.5 + 1e-9, 1e-12])
    paths = PathSet.single_path(tau, 1.0)
    R = synthesize(paths, S, sysm, None)
    n = sysm.subcarrier_indices()
    ref = S[0] * np.exp(-1j * sysm.omega * np.outer(tau, n))
    assert np.abs(R - ref).max() < 1e-11


def test_link_without_paths_receives_only_noise(paper_system, rng):
    S = qpsk_symbols(paper_system, 1, rng)
    empty = PathSet(np.zeros(0), np.zeros(0, complex), np.zeros(2, np.int64))
    np.testing.assert_array_equal(synthesize(empty, S, paper_system, None), 0)


def test_extreme_gains_stay_finite(paper_system, rng):
    S = qpsk_symbols(paper_system, 1, rng)
    paths = PathSet.single_path([1e-7, 2e-7], [1e150, 1e-300])
    R = synthesize(paths, S, paper_system, rng)
    assert np.all(np.isfinite(R))


def test_same_seed_same_signal(paper_system):
    S = qpsk_symbols(paper_system, 1, np.random.default_rng(3))
    paths = PathSet.single_path([1e-7], [1e-6])
    a = synthesize(paths, S, paper_system, np.random.default_rng(9))
    b = synthesize(paths, S, paper_system, np.random.default_rng(9))
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"delays": [-1e-9], "gains": [1.0], "offsets": [0, 1]}, r"paths.delays = -1e-09 .*>= 0"),
        ({"delays": [1e-9, 2e-9], "gains": [1.0, 1.0], "offsets": [0, 1]}, "paths.offsets"),
        ({"delays": [1e-9, 2e-9], "gains": [1.0, 1.0], "offsets": [0, 2, 1]}, "never decrease"),
        ({"delays": [1e-9], "gains": [np.nan], "offsets": [0, 1]}, "paths.gains .*finite"),
        ({"delays": [1e-9], "gains": [1.0, 2.0], "offsets": [0, 1]}, "one gain per delay"),
        ({"delays": [np.inf], "gains": [1.0], "offsets": [0, 1]}, "paths.delays .*finite"),
    ],
)
def test_bad_paths_name_the_field(kwargs, match):
    with pytest.raises(ValidationError, match=match):
        PathSet(**kwargs)


def test_bad_synthesis_arguments(small_system, rng):
    S = qpsk_symbols(small_system, 2, rng)
    paths = PathSet.single_path([1e-7, 2e-7], 1.0)
    with pytest.raises(ValidationError, match="tx_index"):
        synthesize(paths, S, small_system, rng, tx_index=[0, 2])
    with pytest.raises(ValidationError, match="noise_var"):
        synthesize(paths, S, small_system, rng, noise_var=-1.0)
    with pytest.raises(ValidationError, match="symbols"):
        synthesize(paths, S[:, :10], small_system, rng)


def test_pathset_helpers():
    ps = PathSet.from_lists([[3e-7, 1e-7], [], [2e-7]], [[1.0, 2.0], [], [3.0j]])
    np.testing.assert_allclose(ps.total_power(), [5.0, 0.0, 9.0])
    np.testing.assert_allclose(ps.first_delay(), [1e-7, np.inf, 2e-7])
    both = PathSet.concatenate([ps, ps.select([2, 0])])
    assert both.n_paths.tolist() == [2, 0, 1, 1, 2]
    np.testing.assert_allclose(both.link(4)[0], [3e-7, 1e-7])


def test_single_path_takes_one_gain_per_link_or_one_scalar():
    ps = PathSet.single_path([1e-7, 2e-7], 0.5j)  # one scalar gain for every link
    np.testing.assert_array_equal(ps.gains, [0.5j, 0.5j])
    assert ps.n_paths.tolist() == [1, 1]
    with pytest.raises(ValidationError, match="gains"):
        PathSet.single_path([1e-7, 2e-7], [1.0])  # 2 delays, 1 gain: not broadcast
    with pytest.raises(ValidationError, match="gains"):
        PathSet.single_path([1e-7, 2e-7], [1.0, 2.0, 3.0])
    with pytest.raises(ValidationError, match="delays"):
        PathSet.single_path([[1e-7, 2e-7]], [1.0, 2.0])


def test_numpy_twin_handles_all_empty():
    out = synthesize_numpy(
        np.ones((1, 5), complex),
        np.zeros(2, np.int64),
        np.zeros(0),
        np.zeros(0, complex),
        np.zeros(3, np.int64),
        1.0,
        -2.0,
        np.zeros((2, 5), complex),
    )
    np.testing.assert_array_equal(out, 0)


def test_small_batches_take_the_serial_kernels_with_the_same_values(paper_system):
    """Below SERIAL_BELOW links the synthesis and the noise run the serial twins of the
    parallel kernels (the same code): a link's signal and noise do not depend on which path
    computed them, and the one-thread FFT plan of a one-link table agrees with the batched
    table."""
    from phyloc.phy import synthesis
    from phyloc.phy.correlation import correlation_tables

    rng = np.random.default_rng(4)
    S = qpsk_symbols(paper_system, 1, rng)
    n = 2 * synthesis.SERIAL_BELOW
    d = rng.uniform(5e-8, 4e-7, (n, 6))
    g = 1e-6 * (rng.standard_normal((n, 6)) + 1j * rng.standard_normal((n, 6)))
    paths = PathSet(d.ravel(), g.ravel(), np.arange(0, 6 * n + 1, 6))
    big = synthesize(paths, S, paper_system, None)  # parallel kernel
    for i in (0, 5, n - 1):
        one = PathSet(d[i], g[i], np.array([0, 6]))
        np.testing.assert_array_equal(synthesize(one, S, paper_system, None)[0], big[i])
    few = synthesis.SERIAL_BELOW - 1
    a = complex_noise((few, 257), 2.0, np.random.default_rng(9))  # serial
    b = complex_noise((n, 257), 2.0, np.random.default_rng(9))  # parallel
    np.testing.assert_array_equal(a, b[:few])
    R = synthesize(paths, S, paper_system, np.random.default_rng(2))
    full = correlation_tables(R, S, paper_system).values
    single = correlation_tables(R[3:4], S, paper_system).values[0]
    np.testing.assert_allclose(single, full[3], rtol=0, atol=1e-12 * np.abs(full[3]).max())

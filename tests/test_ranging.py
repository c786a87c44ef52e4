"""Range estimators (correlation peak, first peak, SAGE, NLOS-rejected SAGE) and the ranging
variance, against closed forms, brute force and their kernels' NumPy twins."""

import dataclasses
import math

import numpy as np
import pytest
from naive_phy import refine_peaks_numpy
from naive_ranging import (
    C0,
    correlate,
    correlate_derivs_numpy,
    correlate_numpy,
    crb_unit_pilots,
    first_peak_dense,
    residual,
    residual_numpy,
    sage_numpy,
)

from phyloc.errors import ValidationError
from phyloc.phy import OFDMSystem, PathSet
from phyloc.phy import _kernels as PK
from phyloc.phy.bounds import crb_range, zzb_range
from phyloc.phy.correlation import correlation_tables
from phyloc.phy.synthesis import synthesize
from phyloc.phy.waveform import qpsk_symbols
from phyloc.ranging import (
    METHODS,
    RangeEstimates,
    correlation_peak,
    estimate,
    first_peak,
    nlos_rejected,
    ranging_variance,
    sage,
)
from phyloc.ranging import _kernels as K
from phyloc.ranging.sage import sage_sweeps, sic_init
from phyloc.ranging.variance import clear_cache


def sample_m(system):
    """One sample period in distance, c0/B [m]."""
    return C0 / system.bandwidth_hz


def amplitude_for(system, pc_snr_db):
    """|α| giving a post-correlation SNR |α|²N/σ² (unit-modulus pilots)."""
    return math.sqrt(10 ** (pc_snr_db / 10) / system.n_subcarriers * system.noise_power_w)


def table_of(system, rng, dists, gains, *, noise=True, S=None):
    """Correlation tables of links with the given path distances [m] and gains (lists per link)."""
    S = qpsk_symbols(system, 1, rng) if S is None else S
    paths = PathSet.from_lists([np.asarray(d) / C0 for d in dists], gains)
    R = synthesize(paths, S, system, rng if noise else None)
    return correlation_tables(R, S, system, beta=8.0)


def random_phases(rng, shape):
    return np.exp(2j * np.pi * rng.uniform(size=shape))


# -- kernels and their twins --------------------------------------------------------------------
@pytest.mark.parametrize("N", [5, 65, 2569])
def test_correlate_kernels_match_direct_sums(rng, N):
    system = OFDMSystem(n_subcarriers=N, subcarrier_spacing_hz=1e6 if N < 100 else 14.65e3)
    n = system.subcarrier_indices()
    w = system.omega / C0
    x = rng.standard_normal(N) + 1j * rng.standard_normal(N)
    scale = np.abs(x).sum()
    for d in (0.0, 3.7, -41.3, 123.456, 2999.9):
        ref = correlate(x, n, w, d)
        T = K._correlate_derivs(x, n[0], w, d)
        for got, r, m in zip(T, ref, (0, 1, 2), strict=True):
            assert abs(got - r) <= 1e-12 * scale * (N / 2) ** m
        assert abs(K._correlate(x, n[0], w, d) - ref[0]) <= 1e-12 * scale
        twin = correlate_derivs_numpy(x, n, w, d)
        assert abs(twin[0] - ref[0]) <= 1e-12 * scale


@pytest.mark.parametrize("N", [5, 65, 2569])
def test_residual_kernel_matches_twin_and_direct_sum(rng, N):
    system = OFDMSystem(n_subcarriers=N, subcarrier_spacing_hz=1e6 if N < 100 else 14.65e3)
    n = system.subcarrier_indices()
    w = system.omega / C0
    S = qpsk_symbols(system, 2, rng) * rng.uniform(0.5, 2.0, (2, N))  # uneven pilots
    power = np.abs(S) ** 2
    c = rng.standard_normal((3, N)) + 1j * rng.standard_normal((3, N))
    tx = np.array([0, 1, 1])
    dist = rng.uniform(-20, 300, (3, 4))
    gain = rng.standard_normal((3, 4)) + 1j * rng.standard_normal((3, 4))
    out = np.empty_like(c)
    K.residual_kernel(c, power, tx, n[0], w, dist, gain, out)
    twin = residual_numpy(c, power, tx, n[0], w, dist, gain)
    np.testing.assert_allclose(out, twin, atol=1e-12 * np.abs(c).max())
    for i in range(3):
        ref = residual(c[i], power[tx[i]], n, w, dist[i], gain[i])
        np.testing.assert_allclose(out[i], ref, atol=1e-12 * np.abs(c).max())


def test_refine_and_correlate_kernels_match_twins_and_phy(paper_system, rng):
    amp = amplitude_for(paper_system, 25.0)
    dists = [[x, x + 9.0] for x in rng.uniform(5, 200, 6)]
    tab = table_of(paper_system, rng, dists, [[amp, 0.7 * amp]] * 6)
    n = paper_system.subcarrier_indices()
    w = paper_system.omega / C0
    d0 = tab.peak(refine=False) + rng.uniform(-0.4, 0.4, 6) * tab.spacing_m
    out = np.empty(6)
    K.refine_kernel(tab.spectrum, n[0], w, d0, tab.spacing_m, 8, out)
    np.testing.assert_allclose(
        out, refine_peaks_numpy(tab.spectrum, n, w, d0, tab.spacing_m, 8), atol=1e-9
    )
    ref = np.empty(6)
    PK.refine_peaks_kernel(tab.spectrum, n, w, d0, tab.spacing_m, 8, ref)
    np.testing.assert_allclose(out, ref, atol=1e-9)
    assert not np.allclose(out, d0)
    F = np.empty(6, complex)
    K.correlate_kernel(tab.spectrum, n[0], w, out, F)
    np.testing.assert_allclose(F, correlate_numpy(tab.spectrum, n[0], w, out), rtol=1e-12)
    np.testing.assert_allclose(F, tab.exact(out[:, None])[:, 0], rtol=1e-12)


def _sweeps_numpy(tab, dist, gain, *, n_iter, search_steps, n_newton, n_active=None):
    """:func:`sage_sweeps` with the kernel replaced by its NumPy twin (same arguments)."""
    if n_active is None:
        n_active = np.full(dist.shape[0], dist.shape[1], dtype=np.int64)
    return sage_numpy(
        tab.spectrum,
        np.abs(tab.symbols) ** 2,
        tab.tx_index,
        tab.symbol_energy,
        float(tab.system.subcarrier_indices()[0]),
        tab.system.omega / C0,
        dist,
        gain,
        np.asarray(n_active, dtype=np.int64),
        n_iter,
        tab.spacing_m,
        search_steps,
        n_newton,
    )


def test_sage_kernel_matches_twin(rng, monkeypatch):
    system = OFDMSystem(n_subcarriers=129, subcarrier_spacing_hz=0.25e6)
    h = sample_m(system)
    dists = [[30.0, 30 + 2.5 * h, 30 + 6 * h], [80.0, 80 + 0.7 * h], [15.0]]
    amp = amplitude_for(system, 35.0)
    gains = [amp * np.array(g) * random_phases(rng, len(g)) for g in ([1, 0.8, 0.5], [1, 1], [1])]
    tab = table_of(system, rng, dists, gains)
    d0, a0, n_act = sic_init(tab, 3, (0.0, 400.0), init_sweeps=0)
    assert n_act.tolist() == [3, 3, 3]  # no noise threshold: every link gets every path
    args = dict(n_iter=3, search_steps=2, n_newton=4)
    d1, a1 = sage_sweeps(tab, d0, a0, **args)
    d2, a2 = _sweeps_numpy(tab, d0, a0, **args)
    np.testing.assert_allclose(d1, d2, atol=1e-9)
    np.testing.assert_allclose(a1, a2, atol=1e-9 * np.abs(a2).max())
    assert not np.allclose(d1, d0)  # the sweeps did move the paths
    # with fewer active paths per link, the rest are neither used nor touched
    act = np.array([3, 2, 1])
    d3, a3 = sage_sweeps(tab, d0, a0, n_active=act, **args)
    d4, a4 = _sweeps_numpy(tab, d0, a0, n_active=act, **args)
    np.testing.assert_allclose(d3, d4, atol=1e-9)
    np.testing.assert_allclose(a3, a4, atol=1e-9 * np.abs(a4).max())
    idle = np.arange(3)[None, :] >= act[:, None]
    np.testing.assert_array_equal(d3[idle], d0[idle])
    np.testing.assert_array_equal(a3[idle], a0[idle])
    # and the public function agrees with itself run on the twins (SIC with re-estimation
    # included): the SAGE and residual kernels are swapped for their NumPy twins
    e1 = sage(tab, n_paths=3, n_iter=2, window_m=(0.0, 400.0))
    calls = {"sage": 0, "residual": 0}

    def sage_twin(*args):
        calls["sage"] += 1
        d, a = args[6], args[7]
        d[:], a[:] = sage_numpy(*args)

    def residual_twin(*args):
        calls["residual"] += 1
        args[-1][:] = residual_numpy(*args[:-1])

    monkeypatch.setattr(K, "sage_kernel", sage_twin)  # sage.py calls K.<kernel>
    monkeypatch.setattr(K, "residual_kernel", residual_twin)
    e2 = sage(tab, n_paths=3, n_iter=2, window_m=(0.0, 400.0))
    assert calls["sage"] >= 2 and calls["residual"] >= 1  # the twins did run
    np.testing.assert_allclose(e1.path_distance_m, e2.path_distance_m, atol=1e-9)
    np.testing.assert_allclose(e1.range_m, e2.range_m, atol=1e-9)


def test_sage_sweeps_never_decrease_the_likelihood(rng):
    """Each SAGE update maximizes the likelihood over its own path: ‖residual‖ never grows."""
    system = OFDMSystem()
    h = sample_m(system)
    amp = amplitude_for(system, 30.0)
    dists = [[50.0, 50 + 0.6 * h, 50 + 3 * h]] * 4
    gains = [amp * np.array([1, 0.9, 0.4]) * random_phases(rng, 3) for _ in range(4)]
    tab = table_of(system, rng, dists, gains)
    power = np.abs(tab.symbols) ** 2
    n0, w = system.subcarrier_indices()[0], system.omega / C0
    d, a, _ = sic_init(tab, 4, init_sweeps=0)

    def cost(d, a):
        out = np.empty_like(tab.spectrum)
        K.residual_kernel(tab.spectrum, power, tab.tx_index, n0, w, d, a, out)
        return (np.abs(out) ** 2 / power[tab.tx_index]).sum(axis=1)

    prev = cost(d, a)
    for _ in range(4):
        d, a = sage_sweeps(tab, d, a, n_iter=1)
        now = cost(d, a)
        assert np.all(now <= prev * (1 + 1e-12))
        prev = now


# -- SAGE ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("n_paths", [3, 5])
def test_sage_recovers_three_separated_paths(paper_system, n_paths):
    rng = np.random.default_rng(33 + n_paths)
    sysm = paper_system
    smp = sample_m(sysm)
    n_links = 6
    base = rng.uniform(5.0, 150.0, n_links)
    sep = np.array([0.0, 3.3, 7.9]) * smp  # well separated: > 3 samples apart
    dists = [b + sep for b in base]
    amp = amplitude_for(sysm, 45.0)
    gains = [amp * np.array([1.0, 0.7, 0.5]) * random_phases(rng, 3) for _ in range(n_links)]
    tab = table_of(sysm, rng, dists, gains)
    est = sage(tab, n_paths=n_paths)
    assert np.all(est.valid)
    for i in range(n_links):
        pd, pa = est.paths(i)
        assert 3 <= pd.size <= n_paths and np.all(np.diff(pd) >= 0)
        for d_true, g_true in zip(dists[i], gains[i], strict=True):
            j = np.argmin(np.abs(pd - d_true) + 1e9 * (np.abs(pa) < 0.2 * amp))
            assert abs(pd[j] - d_true) < 0.1 * smp
            assert abs(pa[j] - g_true) < 0.05 * abs(g_true)
        assert est.range_m[i] == pytest.approx(dists[i][0], abs=0.1 * smp)
    # the SNR estimate is the LOS path's
    np.testing.assert_allclose(est.snr, amp**2 / sysm.noise_power_w, rtol=0.1)


def test_sage_no_worse_than_correlation_peak_for_close_paths(paper_system):
    """Two paths 0.6 samples apart (unresolved by the correlation): the peak is biased, SAGE not."""
    rng = np.random.default_rng(2)
    sysm = paper_system
    n_links = 48
    d_los = rng.uniform(10.0, 140.0, n_links)
    amp = amplitude_for(sysm, 35.0)
    dists = [[d, d + 0.6 * sample_m(sysm)] for d in d_los]
    gains = [amp * np.array([1.0, 0.8]) * random_phases(rng, 2) for _ in range(n_links)]
    tab = table_of(sysm, rng, dists, gains)
    rmse_corr = math.sqrt(np.mean((correlation_peak(tab).range_m - d_los) ** 2))
    est = sage(tab)
    rmse_sage = math.sqrt(np.mean((est.range_m - d_los) ** 2))
    assert rmse_sage <= rmse_corr
    assert rmse_corr > 0.5  # the correlation peak is really biased here (the test has teeth)


def test_sic_stops_at_the_noise_floor(paper_system, rng):
    """The SIC adds paths only while the residual's peak exceeds κσ²‖S‖²."""
    amp = amplitude_for(paper_system, 40.0)
    clean = table_of(paper_system, rng, [[33.0], [90.0, 130.0]], [[amp], [amp, amp]], noise=False)
    clean = dataclasses.replace(clean, noise_var=np.full(2, paper_system.noise_power_w))
    _, _, n_act = sic_init(clean, 5, noise_factor=16.0)
    assert n_act.tolist() == [1, 2]
    est = sage(clean)
    assert np.diff(est.path_offsets).tolist() == [1, 2]
    np.testing.assert_allclose(est.path_distance_m, [33.0, 90.0, 130.0], atol=1e-6)
    np.testing.assert_allclose(np.abs(est.path_amplitude), amp, rtol=1e-6)
    # without a threshold every link gets all five paths (surplus ones fit nothing: α ≈ 0)
    _, a, n_act = sic_init(clean, 5, noise_factor=None)
    assert n_act.tolist() == [5, 5] and np.abs(a[0, 1:]).max() < 1e-6 * amp


def test_sage_los_threshold_picks_the_earliest_strong_path(paper_system):
    rng = np.random.default_rng(8)
    sysm = paper_system
    amp = amplitude_for(sysm, 40.0)
    # LOS 6 dB below a later path: within −10 dB → LOS; with −3 dB → the later path
    dists = [[40.0, 70.0]]
    gains = [amp * np.array([0.5, 1.0]) * random_phases(rng, 2)]
    tab = table_of(sysm, rng, dists, gains)
    assert sage(tab).range_m[0] == pytest.approx(40.0, abs=0.1)
    assert sage(tab, los_threshold_db=-3.0).range_m[0] == pytest.approx(70.0, abs=0.1)
    # a path outside the window is never the LOS (nor modelled: its sidelobes bias the other)
    assert sage(tab, window_m=(50.0, 300.0)).range_m[0] == pytest.approx(70.0, abs=0.5)


# -- first peak vs correlation peak ----------------------------------------------------------------
def test_first_peak_returns_los_when_a_later_path_is_stronger(paper_system):
    rng = np.random.default_rng(4)
    sysm = paper_system
    n_links = 16
    d_los = rng.uniform(5.0, 120.0, n_links)
    amp = amplitude_for(sysm, 40.0)
    dists = [[d, d + 25.0] for d in d_los]  # ~3 samples apart: resolved
    gains = [amp * np.array([0.5, 1.0]) * random_phases(rng, 2) for _ in range(n_links)]
    tab = table_of(sysm, rng, dists, gains)
    fp = first_peak(tab)
    corr = correlation_peak(tab)
    assert np.all(fp.valid) and np.all(corr.valid)
    # the LOS, up to the multipath bias from the strong path's sidelobes (~0.2 samples) ...
    np.testing.assert_allclose(fp.range_m, d_los, atol=2.5)
    np.testing.assert_allclose(corr.range_m, d_los + 25.0, atol=1.0)  # ... the stronger path
    np.testing.assert_allclose(sage(tab).range_m, d_los, atol=0.3)  # SAGE removes the bias
    # a LOS more than 12 dB below the strongest path is not detected by first_peak either
    # (its threshold is relative to the strongest peak; lowering it finds the LOS again)
    weak = table_of(sysm, rng, [[40.0, 120.0]], [amp * np.array([0.2, 1.0])])
    assert first_peak(weak).range_m[0] == pytest.approx(120.0, abs=0.5)
    # (the strong path's far sidelobes are −30 dB of it but −16 dB of the LOS: ~1 m of bias)
    assert first_peak(weak, rel_threshold_db=-16.0).range_m[0] == pytest.approx(40.0, abs=1.5)


def test_first_peak_ignores_sidelobes_of_a_strong_single_path(paper_system, rng):
    amp = amplitude_for(paper_system, 50.0)
    d = rng.uniform(20.0, 150.0, 8)
    tab = table_of(paper_system, rng, [[x] for x in d], [[amp]] * 8)
    np.testing.assert_allclose(first_peak(tab).range_m, correlation_peak(tab).range_m)
    np.testing.assert_allclose(first_peak(tab).range_m, d, atol=0.05)


def test_first_peak_matches_dense_brute_force(small_system, rng):
    sysm = small_system
    amp = amplitude_for(sysm, 30.0)
    dists = [[60.0, 80.0, 101.0], [33.0, 50.0]]
    gains = [amp * np.array([0.45, 1.0, 0.6]), amp * np.array([0.3, 1.0])]
    tab = table_of(sysm, rng, dists, gains)
    fp = first_peak(tab, window_m=(0.0, 200.0), rel_threshold_db=-12.0)
    n, w = sysm.subcarrier_indices(), sysm.omega / C0
    floor = 16.0 * tab.noise_var[0] * tab.symbol_energy[0]
    for i in range(2):
        ref = first_peak_dense(tab.spectrum[i], n, w, 0.0, 200.0, -12.0, floor, step=0.05)
        assert fp.range_m[i] == pytest.approx(ref, abs=0.05)


# -- correlation peak in AWGN ---------------------------------------------------------------------
@pytest.mark.parametrize("pc_snr_db", [20.0, 30.0, 40.0])
def test_correlation_peak_attains_the_crb_in_awgn(paper_system, pc_snr_db):
    rng = np.random.default_rng(100 + int(pc_snr_db))
    n = 600
    S = qpsk_symbols(paper_system, 1, rng)
    amp = amplitude_for(paper_system, pc_snr_db)
    d_true = rng.uniform(5.0, 250.0, n)
    R = synthesize(
        PathSet.single_path(d_true / C0, amp * random_phases(rng, n)), S, paper_system, rng
    )
    est = correlation_peak(correlation_tables(R, S, paper_system))
    assert np.all(est.valid)
    rmse = math.sqrt(np.mean((est.range_m - d_true) ** 2))
    snr = amp**2 / paper_system.noise_power_w
    crb = crb_unit_pilots(snr, 2569, 14.65e3)
    assert rmse == pytest.approx(math.sqrt(crb), rel=0.15)
    # the SNR estimate is unbiased and the variance is the ZZB at the estimate (≈ CRB here)
    assert est.snr.mean() == pytest.approx(snr, rel=0.05)
    np.testing.assert_allclose(est.variance_m2, ranging_variance(est.snr, S[0], paper_system))


# -- noise-only links ---------------------------------------------------------------------------
def test_noise_only_links_are_finite_and_flagged(paper_system, rng):
    n = 300
    S = qpsk_symbols(paper_system, 1, rng)
    empty = PathSet(np.zeros(0), np.zeros(0, complex), np.zeros(n + 1, np.int64))
    tab = correlation_tables(synthesize(empty, S, paper_system, rng), S, paper_system)
    for name in ("corr", "first_peak", "sage"):
        est = estimate(name, tab)
        for a in (est.range_m, est.snr, est.variance_m2):
            assert np.all(np.isfinite(a))
        assert not est.valid.any()
        assert np.all((est.range_m >= -1.0) & (est.range_m <= 301.0))  # placeholder in window
        assert np.all(est.variance_m2 > 0) and np.all(est.variance_m2 <= 300.0**2 / 12 * 1.001)
    # without the noise threshold the correlation peak reports every link
    assert correlation_peak(tab, noise_factor=None).valid.all()
    # and a completely silent table (R = 0) stays finite too
    silent = correlation_tables(np.zeros((2, 2569), complex), S, paper_system)
    for name in ("corr", "first_peak", "sage"):
        est = estimate(name, silent)
        assert np.all(np.isfinite(est.range_m)) and not est.valid.any()
        assert np.all(est.snr == 0) and np.all(est.variance_m2 == pytest.approx(300.0**2 / 12))


def test_links_above_the_detection_threshold_are_valid(paper_system, rng):
    amp = amplitude_for(paper_system, 18.0)  # 6 dB above κ = 16 (12 dB)
    tab = table_of(paper_system, rng, [[x] for x in rng.uniform(5, 250, 50)], [[amp]] * 50)
    for name in ("corr", "first_peak", "sage"):
        assert estimate(name, tab).valid.mean() >= 0.96


# -- ranging variance ---------------------------------------------------------------------------
def test_zzb_interpolation_matches_direct_bound(paper_system):
    S = qpsk_symbols(paper_system, 1, np.random.default_rng(0))[0]
    clear_cache()
    rng = np.random.default_rng(9)
    pc_db = np.concatenate([rng.uniform(-40.0, 60.0, 8), [9.0, 11.0, 12.5, 14.0]])
    snr = 10 ** (pc_db / 10) / 2569
    got = ranging_variance(snr, S, paper_system, prior_range_m=300.0)
    ref = np.array([zzb_range(s, S, paper_system, prior_range_m=300.0) for s in snr])
    np.testing.assert_allclose(got, ref, rtol=0.01)
    # other prior widths and the plain (no valley filling) bound are tabulated separately
    got = ranging_variance(snr[:3], S, paper_system, prior_range_m=50.0, valley_filling=False)
    ref = zzb_range(snr[:3], S, paper_system, prior_range_m=50.0, valley_filling=False)
    np.testing.assert_allclose(got, ref, rtol=0.01)


def test_crb_option_and_extreme_snrs(paper_system):
    S = qpsk_symbols(paper_system, 1, np.random.default_rng(0))[0]
    snr = np.array([1e-3, 0.1, 1.0, 37.0, 1e6])
    np.testing.assert_array_equal(
        ranging_variance(snr, S, paper_system, kind="crb"), crb_range(snr, S, paper_system)
    )
    for kind in ("zzb", "crb"):
        v = ranging_variance(np.array([0.0, 1e-300, 1e12]), S, paper_system, kind=kind)
        assert np.all(np.isfinite(v)) and np.all(v > 0)
        assert v[0] == pytest.approx(300.0**2 / 12, rel=1e-9)
        assert v[1] == pytest.approx(300.0**2 / 12, rel=1e-3)
        assert v[2] == pytest.approx(float(crb_range(1e12, S, paper_system)), rel=1e-3)
    # the ZZB variance never increases with SNR
    grid = np.geomspace(1e-9, 1e9, 400)
    assert np.all(np.diff(ranging_variance(grid, S, paper_system)) <= 0)


def test_ranging_variance_per_link_pilots(small_system, rng):
    S = qpsk_symbols(small_system, 2, rng)
    S[1] *= 2.0  # transmitter 1 sends 6 dB more pilot energy: same as 4× the SNR
    R = np.zeros((3, 65), complex)
    tab = correlation_tables(R, S, small_system, tx_index=[0, 1, 1])
    snr = np.array([0.5, 0.5, 0.125])
    v = ranging_variance(snr, tab, kind="crb")
    assert v[1] == pytest.approx(v[0] / 4) and v[2] == pytest.approx(v[0])
    z = ranging_variance(snr, tab)
    assert z[2] == pytest.approx(z[0], rel=1e-3) and z[1] < z[0]


def test_ranging_variance_errors(paper_system):
    S = qpsk_symbols(paper_system, 1, np.random.default_rng(0))[0]
    with pytest.raises(ValidationError, match=r"variance = bayes .*zzb, crb"):
        ranging_variance(1.0, S, paper_system, kind="bayes")
    with pytest.raises(ValidationError, match="snr"):
        ranging_variance(-1.0, S, paper_system)
    with pytest.raises(ValidationError, match="snr"):
        ranging_variance(np.nan, S, paper_system)
    with pytest.raises(ValidationError, match="system"):
        ranging_variance(1.0, S, None)
    tab = correlation_tables(np.zeros((2, 2569), complex), S, paper_system)
    with pytest.raises(ValidationError, match="one SNR per link"):
        ranging_variance(np.ones(3), tab)


# -- oracle, dispatch, validation ------------------------------------------------------------------
def test_nlos_rejected_is_an_oracle(paper_system, rng):
    amp = amplitude_for(paper_system, 30.0)
    tab = table_of(paper_system, rng, [[20.0], [50.0], [80.0]], [[amp]] * 3)
    los = np.array([True, False, True])
    base = sage(tab, n_paths=2)
    est = nlos_rejected(base, los)
    assert est.oracle and not base.oracle
    assert est.method == "sage_los" and est.label == "sage_los (oracle)"
    np.testing.assert_array_equal(est.valid, base.valid & los)
    np.testing.assert_array_equal(est.range_m, base.range_m)
    via = estimate("sage_los", tab, los=los, n_paths=2)
    assert via.oracle and via.method == "sage_los"
    np.testing.assert_array_equal(via.valid, est.valid)
    with pytest.raises(ValidationError, match="los"):
        nlos_rejected(base, np.array([1, 0, 1]))  # ints are not flags
    with pytest.raises(ValidationError, match="los"):
        nlos_rejected(base, np.array([True, False]))


def test_estimate_dispatch(paper_system, rng):
    assert set(METHODS) == {"corr", "first_peak", "sage", "sage_los"}
    tab = table_of(paper_system, rng, [[30.0]], [[amplitude_for(paper_system, 30.0)]])
    with pytest.raises(ValidationError, match="corr, first_peak, sage, sage_los"):
        estimate("matched_filter", tab)
    with pytest.raises(ValidationError, match="oracle"):
        estimate("sage_los", tab)
    with pytest.raises(TypeError):
        estimate("corr", tab, n_paths=3)  # an option of another estimator
    for name in ("corr", "first_peak", "sage"):
        est = estimate(name, tab, variance="crb")
        assert est.method == name and not est.oracle
        np.testing.assert_allclose(est.variance_m2, ranging_variance(est.snr, tab, kind="crb"))
        # 30 dB post-correlation SNR: √CRB ≈ 0.1 m; the estimate is within 4 of them
        assert est.range_m[0] == pytest.approx(30.0, abs=4 * math.sqrt(est.variance_m2[0]))


def test_estimator_input_errors(paper_system, rng):
    tab = table_of(paper_system, rng, [[30.0]], [[1e-6]])
    with pytest.raises(ValidationError, match="CorrelationTable"):
        correlation_peak(np.zeros((1, 10)))
    with pytest.raises(ValidationError, match="window_m"):
        first_peak(tab, window_m=(10.0, 5.0))
    with pytest.raises(ValidationError, match="unambiguous"):
        correlation_peak(tab, window_m=(0.0, 30000.0))
    with pytest.raises(ValidationError, match="rel_threshold_db"):
        first_peak(tab, rel_threshold_db=3.0)
    with pytest.raises(ValidationError, match="noise_factor"):
        first_peak(tab, noise_factor=-1.0)
    with pytest.raises(ValidationError, match="variance"):
        sage(tab, variance="zz")
    with pytest.raises(ValidationError, match="n_paths"):
        sage(tab, n_paths=0)
    with pytest.raises(ValidationError, match="los_threshold_db"):
        sage(tab, los_threshold_db=1.0)


def test_range_estimates_reject_nan_and_bad_shapes():
    ok = dict(
        method="x", range_m=[1.0, 2.0], snr=[0.0, 1.0], variance_m2=[1.0, 1.0], valid=[True, False]
    )
    est = RangeEstimates(**ok)
    assert est.n_links == 2 and est.valid.dtype == bool
    with pytest.raises(ValidationError, match="range_m"):
        RangeEstimates(**{**ok, "range_m": [np.nan, 1.0]})
    with pytest.raises(ValidationError, match="snr"):
        RangeEstimates(**{**ok, "snr": [1.0]})
    with pytest.raises(ValidationError, match="paths"):
        est.paths(0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        est.method = "y"


# -- slow statistics ----------------------------------------------------------------------------
@pytest.mark.slow
def test_sage_attains_the_crb_for_separated_paths(paper_system):
    """Slow: 3 paths > 3 samples apart at pc SNR 30 dB; SAGE's LOS RMSE within 25 % of √CRB
    (the others' sidelobes cost a little information)."""
    rng = np.random.default_rng(77)
    sysm = paper_system
    n_links = 400
    d_los = rng.uniform(5.0, 150.0, n_links)
    sep = np.array([0.0, 3.3, 7.9]) * sample_m(sysm)
    amp = amplitude_for(sysm, 30.0)
    gains = [amp * np.array([1.0, 0.7, 0.5]) * random_phases(rng, 3) for _ in range(n_links)]
    tab = table_of(sysm, rng, [d + sep for d in d_los], gains)
    est = sage(tab)
    rmse = math.sqrt(np.mean((est.range_m - d_los) ** 2))
    crb = crb_unit_pilots(amp**2 / sysm.noise_power_w, 2569, 14.65e3)
    assert rmse == pytest.approx(math.sqrt(crb), rel=0.25)


@pytest.mark.slow
def test_correlation_peak_crb_dense(paper_system):
    """Slow: 3000 links per SNR, 20–50 dB: RMSE within 5 % of √CRB."""
    for pc_snr_db in np.arange(20.0, 51.0, 10.0):
        rng = np.random.default_rng(int(pc_snr_db) + 7)
        S = qpsk_symbols(paper_system, 1, rng)
        amp = amplitude_for(paper_system, pc_snr_db)
        d_true = rng.uniform(5.0, 250.0, 3000)
        R = synthesize(
            PathSet.single_path(d_true / C0, amp * random_phases(rng, 3000)), S, paper_system, rng
        )
        est = correlation_peak(correlation_tables(R, S, paper_system))
        rmse = math.sqrt(np.mean((est.range_m - d_true) ** 2))
        crb = crb_unit_pilots(amp**2 / paper_system.noise_power_w, 2569, 14.65e3)
        assert rmse == pytest.approx(math.sqrt(crb), rel=0.05)


def test_pilots_equal_to_rounding_share_one_zzb_table(paper_system, monkeypatch):
    """QPSK pilots e^{j(π/4 + kπ/2)} have |S_n|² of 1 or 1 + 4e-16 depending on the symbol, so
    every transmitter's power spectrum differs in the last bit: all of them still share one
    tabulated bound, which agrees with each row's own table within 1e-9 relative; a pilot of
    another power gets its own."""
    import phyloc.ranging.variance as var

    S = qpsk_symbols(paper_system, 6, np.random.default_rng(3))
    P = np.abs(S) ** 2
    assert len({row.tobytes() for row in P}) == 6  # the rows differ by rounding
    built = []
    real = var._ZZBTable

    def counting(power, *a):
        built.append(power)
        return real(power, *a)

    monkeypatch.setattr(var, "_ZZBTable", counting)
    clear_cache()
    snr = np.geomspace(1e-4, 10.0, 6)
    tab = correlation_tables(S, S, paper_system, tx_index=np.arange(6))
    shared = ranging_variance(snr, tab)
    assert len(built) == 1
    for r in range(6):
        own = real(P[r], paper_system, var.DEFAULT_PRIOR_RANGE_M, True)(snr[r : r + 1])
        np.testing.assert_allclose(shared[r], own, rtol=1e-9)
    ranging_variance(snr[:1], 2.0 * S[0], paper_system)
    assert len(built) == 2

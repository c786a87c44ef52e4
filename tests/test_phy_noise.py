"""Gaussian noise of the PHY (phyloc.phy._gauss, complex_noise): exactness and statistics."""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest
from naive_phy import normal_rows_py, splitmix64_py, xoshiro_py
from scipy import stats

from phyloc.phy import _gauss
from phyloc.phy.synthesis import complex_noise


def test_xoshiro_and_splitmix_reference_vectors():
    """xoshiro256** from state (1, 2, 3, 4) and SplitMix64 from seed 1234567, as the
    reference implementations print them."""
    s = [1, 2, 3, 4]
    assert [xoshiro_py(s) for _ in range(4)] == [11520, 0, 1509978240, 1215971899390074240]
    z, outs = 1234567, []
    for _ in range(5):
        z, o = splitmix64_py(z)
        outs.append(o)
    assert outs == [
        6457827717110365317,
        3203168211198807973,
        9817491932198370423,
        4593380528125082431,
        16408922859458223821,
    ]
    z = np.uint64(1234567)
    for _ in range(5):
        zk, ok = _gauss.splitmix64(z)
        zp, op = splitmix64_py(int(z))
        assert (int(zk), int(ok)) == (zp, op)
        z = np.uint64(zk)


def test_ziggurat_tables_have_equal_layers_and_the_right_tail():
    x, f = _gauss.ZIG_X, _gauss.ZIG_F
    v = _gauss.ZIG_V
    # layers 1..255: rectangles [0, x_i] × [f(x_i), f(x_{i+1})] of area v
    areas = x[1:256] * (f[2:257] - f[1:256])
    assert np.allclose(areas[:-1], v, rtol=1e-9)
    assert areas[-1] == pytest.approx(v, rel=1e-4)  # the top layer closes at x = 0
    # base strip: r f(r) + ∫_r^∞ f = v (Marsaglia and Tsang 2000)
    tail = math.sqrt(2 * math.pi) * stats.norm.sf(_gauss.ZIG_R)
    assert _gauss.ZIG_R * math.exp(-0.5 * _gauss.ZIG_R**2) + tail == pytest.approx(v, rel=1e-9)
    assert x[0] * math.exp(-0.5 * _gauss.ZIG_R**2) == pytest.approx(v, rel=1e-12)


def test_kernel_equals_the_python_twin_bit_for_bit():
    seeds = np.array([0, 1, 2**63 + 12345, 2**64 - 1], dtype=np.uint64)
    scale = np.array([1.0, 0.5, 2.0, 3.0])
    m = 6000  # ≈ 90 wedge and ≈ 6 tail draws in all
    got = np.empty((seeds.size, m))
    _gauss.normal_rows_kernel(seeds, scale, _gauss.ZIG_X, _gauss.ZIG_F, _gauss.ZIG_K, got)
    ref = normal_rows_py(seeds, scale, _gauss.ZIG_X, _gauss.ZIG_F, _gauss.ZIG_K, m)
    assert np.array_equal(got, ref)
    assert np.any(np.abs(got / scale[:, None]) > _gauss.ZIG_R)  # the tail branch ran


def test_rows_do_not_depend_on_threads():
    seeds = np.arange(64, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15)
    out = {}
    before = numba.get_num_threads()
    try:
        for t in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            numba.set_num_threads(t)
            o = np.empty((64, 3000))
            _gauss.normal_rows_kernel(
                seeds, np.ones(64), _gauss.ZIG_X, _gauss.ZIG_F, _gauss.ZIG_K, o
            )
            out[t] = o
    finally:
        numba.set_num_threads(before)
    vals = list(out.values())
    assert all(np.array_equal(vals[0], o) for o in vals[1:])


@pytest.fixture(scope="module")
def noise():
    return complex_noise((800, 2569), 2.0, np.random.default_rng(2024))


def test_noise_is_standard_complex_normal(noise):
    z = np.concatenate([noise.real.ravel(), noise.imag.ravel()]) / math.sqrt(1.0)
    n = z.size  # 4.1e6 values of variance 1 (σ² = 2 split over re/im)
    assert abs(z.mean()) < 5 / math.sqrt(n)
    assert abs(z.var() - 1.0) < 5 * math.sqrt(2 / n)
    assert abs(stats.skew(z)) < 5 * math.sqrt(6 / n)
    assert abs(stats.kurtosis(z)) < 5 * math.sqrt(24 / n)
    assert stats.kstest(z[:1_000_000], "norm").pvalue > 1e-3
    # the tail beyond r (drawn by its own branch) has the right mass
    p = 2 * stats.norm.sf(_gauss.ZIG_R)
    k = np.sum(np.abs(z) > _gauss.ZIG_R)
    assert abs(k - n * p) < 5 * math.sqrt(n * p)
    # circular symmetry: E[w²] = 0, re and im uncorrelated
    w = noise.ravel()
    assert abs(np.mean(w * w)) < 5 * 2.0 / math.sqrt(w.size)


def test_noise_is_white_within_and_across_rows(noise):
    x = noise.real
    n = x.size
    for lag in (1, 2, 7):
        rho = np.mean(x[:, lag:] * x[:, :-lag]) / np.mean(x * x)
        assert abs(rho) < 5 / math.sqrt(n)
    across = np.mean(x[1:] * x[:-1]) / np.mean(x * x)  # consecutive seeds of one Generator
    assert abs(across) < 5 / math.sqrt(n)
    # real and imaginary parts interleave in one stream: no correlation between them either
    assert abs(np.mean(noise.real * noise.imag)) < 5 * 1.0 / math.sqrt(n)


def test_per_row_variance_and_reproducibility():
    nv = np.array([1e-12, 4e-12, 9e-12])
    a = complex_noise((3, 20000), nv, np.random.default_rng(5))
    b = complex_noise((3, 20000), nv, np.random.default_rng(5))
    assert np.array_equal(a, b)
    got = np.mean(np.abs(a) ** 2, axis=1)
    assert np.allclose(got, nv, rtol=5 * math.sqrt(1 / 20000))
    # a 3-D batch scales per leading index
    c = complex_noise((2, 4, 5000), np.array([1.0, 100.0]), np.random.default_rng(1))
    assert np.mean(np.abs(c[1]) ** 2) / np.mean(np.abs(c[0]) ** 2) == pytest.approx(100, rel=0.1)

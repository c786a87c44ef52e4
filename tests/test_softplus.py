"""The vectorized ``log(1 + e^{−x})`` of the bounded-evidence likelihood against NumPy's
``log1p(exp(−x))`` (the C library), in units in the last place."""

import numpy as np
import pytest

from phyloc.localization._softplus import exp_neg_into, log1p_exp_neg_into


def _ulps(got, ref):
    return np.abs(got - ref) / np.spacing(np.abs(ref))


def test_log1p_exp_neg_is_within_4_ulp_of_the_c_library():
    x = np.concatenate(
        [[0.0, 5e-324, 1e-300, 1e-16, 0.5 * np.log(2.0)], np.linspace(0.0, 760.0, 400_001)]
    )
    out, work = np.empty_like(x), np.empty_like(x)
    log1p_exp_neg_into(x, out, work)
    with np.errstate(under="ignore"):
        ref = np.log1p(np.exp(-x))
    normal = ref > 1e-300
    assert _ulps(out[normal], ref[normal]).max() <= 4.0
    assert out[0] == pytest.approx(np.log(2.0), rel=2e-16)
    # beyond the cap (x > 708) the result is e^{−708} ≈ 3.3e-308 instead of less
    assert np.all(np.abs(out - ref) <= np.exp(-708.0) + 4 * np.spacing(np.maximum(ref, 1e-300)))


def test_exp_neg_matches_numpy_and_the_result_never_overflows_or_vanishes_wrongly():
    x = np.concatenate([np.linspace(0.0, 700.0, 100_001), [708.0, 709.0, 1e300, np.inf]])
    out, work = np.empty_like(x), np.empty_like(x)
    exp_neg_into(x, out, work)
    ref = np.exp(-x[:-4])
    assert _ulps(out[:-4], ref).max() <= 4.0
    assert np.all(np.isfinite(out)) and np.all(out > 0)
    assert out[-4] == out[-3] == out[-2] == out[-1] == pytest.approx(np.exp(-708.0), rel=1e-15)


def test_in_place_and_any_length():
    rng = np.random.default_rng(20261129)
    for n in (0, 1, 3, 4, 5, 17, 1000):  # remainders of every SIMD width
        x = rng.exponential(5.0, n)
        out, work = np.empty(n), np.empty(n)
        log1p_exp_neg_into(x, out, work)
        y = x.copy()
        log1p_exp_neg_into(y, y, work)
        np.testing.assert_array_equal(y, out)
        np.testing.assert_allclose(out, np.log1p(np.exp(-x)), rtol=1e-15)


def test_bounded_gaussian_kernel_stays_finite_at_extreme_precision_and_distance():
    """The bounded-evidence link term at inverse variances up to 1e308 and particles kilometres
    off: ``u = ½·inv_var·e²`` overflows to inf, and the term is then exactly the floor
    ``−γ·f`` (the mixture's outlier part); a particle on the range gets ``log(1 + e^{−f})``."""
    from phyloc.localization.direct._kernels import gauss_loglik_kernel

    centers = np.array([[0.0, 0.0], [10.0, 0.0]])
    X = np.array([[[0.0, 0.0], [3.0, 4.0], [5e3, 0.0], [1e150, 0.0]]])  # agent 0
    offsets, nb = np.array([0, 1]), np.array([1])
    out = np.empty((1, 4))
    for inv_var in (1e-300, 1.0, 1e308):
        gamma, f = 0.5, 10.0
        gauss_loglik_kernel(
            X,
            np.array([0]),
            offsets,
            nb,
            np.array([10.0]),
            np.array([inv_var * gamma]),
            centers,
            out,
            f,
            gamma,
            False,
        )
        assert np.all(np.isfinite(out)) and np.all(out <= gamma * np.log1p(np.exp(-f)) + 1e-15)
        assert np.all(out >= -gamma * f - 1e-12)
        assert out[0, 0] == pytest.approx(gamma * np.log1p(np.exp(-f)), rel=1e-14)  # d = r
    assert out[0, 2] == out[0, 3] == pytest.approx(-gamma * f, rel=1e-15)

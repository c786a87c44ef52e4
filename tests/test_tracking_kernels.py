"""The trackers' bookkeeping kernel against its plain-NumPy twin (``tests/naive_tracking.py``),
and the draw-for-draw identity of SIR-BP's one-pass resampling with jitter."""

import numpy as np
from naive_tracking import mean_cov_numpy

from phyloc.localization.particles import regularize, resample_permute
from phyloc.localization.tracking import RangeModel
from phyloc.localization.tracking import _kernels as TK


def test_mean_cov_kernel_is_its_twin():
    rng = np.random.default_rng(2)
    X = rng.normal(5.0, 3.0, size=(4, 2000, 9)) @ rng.normal(size=(9, 9))
    mean = np.empty((4, 9))
    cov = np.empty((4, 9, 9))
    TK.mean_cov_kernel(X, mean, cov)
    m_ref, c_ref = mean_cov_numpy(X)
    np.testing.assert_allclose(mean, m_ref, rtol=1e-12)
    np.testing.assert_allclose(cov, c_ref, rtol=1e-10, atol=1e-10 * np.abs(c_ref).max())
    np.testing.assert_array_equal(cov, np.swapaxes(cov, 1, 2))  # exactly symmetric


def test_mean_cov_kernel_of_identical_particles_is_rounding_only():
    """A collapsed belief far from the origin: the two-pass covariance stays at rounding
    level (no cancellation of E[x²] − E[x]²) and its diagonal is never negative."""
    X = np.tile(np.arange(9.0) * 1e6 + 0.1, (2, 1000, 1))
    mean = np.empty((2, 9))
    cov = np.empty((2, 9, 9))
    TK.mean_cov_kernel(X, mean, cov)
    np.testing.assert_allclose(mean, X[:, 0], rtol=1e-12)  # M·eps: a plain running sum
    assert np.all(np.diagonal(cov, axis1=1, axis2=2) >= 0.0)
    assert np.abs(cov).max() <= (1e-12 * 8e6) ** 2


def test_fused_resample_jitter_equals_resample_then_regularize():
    """SIR-BP's resampling with the jitter of eq. (32) in one call is, draw for draw, a
    resampling followed by :func:`regularize`; positions are the resampled ones."""
    rng = np.random.default_rng(3)
    X = rng.normal(size=(5000, 9))
    lw = rng.normal(size=5000) * 3.0
    lw[::7] = -np.inf  # dead particles are never picked
    plain = resample_permute(X, lw, np.random.default_rng(11))
    for model in (
        RangeModel("constant_acceleration", 3),
        RangeModel("constant_velocity", 3, planar=True),
    ):
        nd = model.state_dim
        S = model.regularization_cov(0.15, 0.25)
        fused = resample_permute(X[:, :nd], lw, np.random.default_rng(11), S)
        r = np.random.default_rng(11)
        two = regularize(resample_permute(X[:, :nd], lw, r), S, r)
        np.testing.assert_array_equal(fused, two)
        np.testing.assert_array_equal(fused[:, :3], plain[:, :3])
        assert np.isin(plain[:, 0], X[lw > -np.inf, 0]).all()

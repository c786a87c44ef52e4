"""Kernels of the resample-move step (``phyloc.localization._particle_kernels``) against their
plain-NumPy twins, and the filter's fused steps against the forms they replace, bit for bit."""

import numpy as np
import pytest
from naive_direct import mh_propose_numpy, systematic_resample_numpy

from phyloc.localization import _kernels as K
from phyloc.localization import _particle_kernels as PK
from phyloc.localization import particles as P


def systematic_gather_numpy(w, total, u0, X):
    """Twin of ``systematic_gather_kernel``: per agent the textbook searchsorted resampler on
    ``w / total`` and a ``take_along_axis`` gather."""
    idx = np.stack(
        [systematic_resample_numpy(w[a] / total[a], u0[a], X.shape[1]) for a in range(len(X))]
    )
    return idx, np.take_along_axis(X, idx[:, :, None], axis=1)


def test_systematic_gather_kernel_matches_its_twin(rng):
    """Indices and gathered particles against the searchsorted twin, weights with zeros."""
    n, Q, m = 6, 257, 257
    w = rng.random((n, m)) ** 4
    w[1, :200] = 0.0  # most of the mass on a few particles
    w[2] = 0.0
    w[2, 17] = 3.0  # one particle takes every draw
    total = w.sum(axis=1)
    u0 = rng.random(n)
    X = rng.normal(size=(n, Q, 3))
    idx, out = np.empty((n, Q), np.int64), np.empty((n, Q, 3))
    PK.systematic_gather_kernel(w.copy(), total, u0, X, idx, out)
    ref_idx, ref_out = systematic_gather_numpy(w, total, u0, X)
    np.testing.assert_array_equal(idx, ref_idx)
    np.testing.assert_array_equal(out, ref_out)
    assert np.all(idx[2] == 17)
    # systematic resampling: every particle is drawn floor or ceil of Q·w times
    counts = np.stack([np.bincount(i, minlength=m) for i in idx])
    expect = Q * w / total[:, None]
    assert np.all(counts >= np.floor(expect - 1e-9)) and np.all(counts <= np.ceil(expect + 1e-9))


def test_gather_rows_kernel_is_take_along_axis(rng):
    """``gather_rows_kernel`` against ``numpy.take_along_axis``, float and integer values."""
    idx = rng.integers(0, 50, (4, 70))
    for values in (rng.normal(size=(4, 50)), rng.integers(-9, 9, (4, 50))):
        out = np.empty(idx.shape, values.dtype)
        PK.gather_rows_kernel(values, idx, out)
        np.testing.assert_array_equal(out, np.take_along_axis(values, idx, axis=1))


def test_resample_agents_is_the_per_agent_resampler(rng):
    """``resample_agents`` (one uniform per agent, the fused kernel) against the per-agent
    ``systematic_resample`` loop it replaces: the same indices from the same stream, bit for
    bit, with ``−inf`` weights and carried arrays."""
    n, Q = 7, 500
    X = rng.normal(size=(n, Q, 2))
    lw = rng.normal(0.0, 30.0, (n, Q))
    lw[3, ::3] = -np.inf
    lp, ll = rng.normal(size=(2, n, Q))
    seed = int(rng.integers(1 << 30))
    got = P.resample_agents(X, lw, np.random.default_rng(seed), lp, ll)
    g = np.random.default_rng(seed)
    idx = np.stack([P.systematic_resample(lw[a], Q, g) for a in range(n)])
    ref = [np.take_along_axis(X, idx[:, :, None], axis=1)]
    ref += [np.take_along_axis(a, idx, axis=1) for a in (lp, ll)]
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("bit_generator", [np.random.PCG64, np.random.Philox])
def test_mh_propose_draw_kernel_draws_the_normals_of_numpy(rng, bit_generator):
    """``mh_propose_draw_kernel`` equals ``mh_propose_kernel`` on
    ``rng.standard_normal(X.shape)`` bit for bit and leaves the generator in the same state;
    against the twin (a NumPy std) to rounding. A collapsed cloud takes the minimum step."""
    n, Q = 5, 400
    X = rng.normal(0.0, 3.0, (n, Q, 2)) * np.array([1.0, 0.2])
    X[4] = 7.0
    a = np.random.Generator(bit_generator(3))
    b = np.random.Generator(bit_generator(3))
    got = np.empty_like(X)
    PK.mh_propose_draw_kernel(a, X, 0.5, 1e-4, got)
    z = b.standard_normal(X.shape)
    ref = np.empty_like(X)
    K.mh_propose_kernel(X, z, 0.5, 1e-4, ref)
    np.testing.assert_array_equal(got, ref)
    assert a.random() == b.random()  # the same number of draws
    np.testing.assert_allclose(got, mh_propose_numpy(X, z, 0.5, 1e-4), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got[4] - 7.0, 1e-4 * z[4], rtol=0, atol=1e-14)


def test_mh_moves_with_the_prior_passed_on_equal_the_moves_without(rng):
    """An ``old_fn`` that takes the prior at its points (``takes_prior``) gives the sweep the
    same moves, bit for bit, as one that evaluates it itself: the values are the same."""
    n, Q = 3, 300
    lam = np.array([0.2, 1.0, 0.6])

    def logp(x):
        return -0.5 * np.sum(x**2, axis=-1) / 9.0

    def new_fn(x, agents=None):
        return -0.5 * np.sum((x - 1.0) ** 2, axis=-1)

    def plain_old(x, agents=None):
        return -0.5 * np.sum((x + 1.0) ** 2, axis=-1) + 0.1 * logp(x)

    def old_taking(x, agents=None, lp_x=None):
        calls.append(lp_x is not None)
        return -0.5 * np.sum((x + 1.0) ** 2, axis=-1) + 0.1 * lp_x

    old_taking.takes_prior = True
    calls = []
    X = rng.normal(size=(n, Q, 2))
    args = (X, logp(X), plain_old(X), new_fn(X), lam)
    a = P.mh_moves(*args, plain_old, new_fn, logp, np.random.default_rng(4), n_moves=3,
                   move_scale=0.5)  # fmt: skip
    b = P.mh_moves(*args, old_taking, new_fn, logp, np.random.default_rng(4), n_moves=3,
                   move_scale=0.5)  # fmt: skip
    assert calls == [True] * 3
    for u, v in zip(a, b, strict=True):
        np.testing.assert_array_equal(u, v)
    assert np.mean(a[0] != X) > 0.2  # the sweeps do move


def test_shifted_old_target_with_the_prior_passed_on(rng):
    """The translation's shifted old target gives the same values whether it evaluates the
    prior at its points or is given it, on every row and on a subset of rows."""
    from phyloc.localization.direct.dpf import _translate

    Q = 500
    mu = np.array([[3.0, 0.0], [0.0, 0.5], [-2.0, 1.0]])

    def logp(x):
        return -0.5 * np.sum(x**2, axis=-1) / 25.0

    def old_fn(x, agents=None):
        return -0.5 * np.sum(x**2, axis=-1) / 0.04

    def new_fn(x, agents=None):
        m = mu if agents is None else mu[np.asarray(agents)]
        return -0.5 * np.sum((x - m[:, None]) ** 2, axis=-1) / 0.04

    X = 0.2 * rng.standard_normal((3, Q, 2))
    lw = np.full((3, Q), -np.log(Q))
    out = _translate(X, lw, logp(X), old_fn(X), new_fn(X), old_fn, new_fn, logp, 3, Q)
    shifted = out[4]
    assert shifted.takes_prior
    Y = out[0] + 0.05 * rng.standard_normal(X.shape)
    np.testing.assert_array_equal(shifted(Y, lp_x=logp(Y)), shifted(Y))
    rows = np.array([0, 2])
    np.testing.assert_array_equal(
        shifted(Y[rows], rows, lp_x=logp(Y)[rows]), shifted(Y[rows], rows)
    )
    np.testing.assert_array_equal(shifted(Y[rows], rows), shifted(Y)[rows])

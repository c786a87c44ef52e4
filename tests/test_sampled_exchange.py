"""Sample-based belief exchange (sample-based DPE / SAGE, DiPNet §V-B, Table I "Sampled SPAWN").

The message of a neighbour v at particle x is ``log Σ_i w_v^i p(r | ‖x − x_v^i‖)``. Checked here:
the Numba kernels against their NumPy twins, a Dirac neighbour against the anchor likelihood
(exactly), convergence to the marginal ``∫ p(x_v) p(r | ‖x − x_v‖) dx_v`` computed by brute-force
quadrature, degenerate inputs, and the methods end to end.
"""

import math

import numpy as np
import pytest
from naive_direct import sampled_direct_numpy, sampled_gauss_numpy, sampled_mixture_numpy
from test_dpf import ANCHORS, agent_map, awgn_network, gaussian_prior

from phyloc.errors import ValidationError
from phyloc.localization import METHODS
from phyloc.localization.direct import DirectOptions, DPFOptions, LinkMeasurements, LinkRanges
from phyloc.localization.direct import _sampled_kernels as K
from phyloc.localization.direct import run as run_direct
from phyloc.localization.direct.likelihoods import (
    DirectLikelihood,
    GaussianRangeLikelihood,
    MarginalDirectLikelihood,
)
from phyloc.localization.direct.sampled_exchange import NodeBeliefs, SampledLikelihood


def _beliefs(rng, n_nodes, q_max, dim, counts):
    pts = rng.uniform(0, 100, (n_nodes, q_max, dim))
    lw = np.full((n_nodes, q_max), -np.inf)
    for v, c in enumerate(counts):
        w = rng.random(c)
        lw[v, :c] = np.log(w / w.sum())
    return pts, lw, np.asarray(counts, np.int64)


def test_sampled_kernels_match_numpy_twins(rng):
    n_agents, Q, dim, n_nodes = 3, 40, 2, 6
    X = rng.uniform(0, 100, (n_agents, Q, dim))
    offsets = np.array([0, 2, 2, 6])  # agent 1 has no links
    nb = np.array([3, 4, 0, 5, 1, 2])
    pts, lw, cnt = _beliefs(rng, n_nodes, 25, dim, [1, 25, 7, 25, 1, 12])
    lw[2] = -np.inf  # a neighbour whose weights are all zero: no information
    values = rng.standard_normal((6, 400)) + 1j * rng.standard_normal((6, 400))
    scale = rng.uniform(0.1, 2, 6)
    out = np.empty((n_agents, Q))
    args = (X, offsets, nb, np.arange(6), scale, pts, lw, cnt, values, 1.3, 4, 0.7)
    K.sampled_direct_kernel(*args, out)
    np.testing.assert_allclose(out, sampled_direct_numpy(*args), rtol=1e-12)
    assert np.all(out[1] == 0) and np.all(np.isfinite(out))
    r, iv = rng.uniform(10, 90, 6), rng.uniform(0.01, 3, 6)
    K.sampled_gauss_kernel(X, offsets, nb, r, iv, pts, lw, cnt, 0.7, out)
    ref = sampled_gauss_numpy(X, offsets, nb, r, iv, pts, lw, cnt, 0.7)
    np.testing.assert_allclose(out, ref, rtol=1e-12)
    assert np.all(np.isfinite(out))
    K.sampled_gauss_kernel(X, offsets, nb, r, iv, pts, lw, cnt, 0.7, out, 3.0)  # outlier bound
    ref = sampled_gauss_numpy(X, offsets, nb, r, iv, pts, lw, cnt, 0.7, 3.0)
    np.testing.assert_allclose(out, ref, rtol=1e-12)
    assert np.all(out >= -0.7 * 3.0 * np.diff(offsets)[:, None] - 1e-12)  # ≥ −γf per link
    K.sampled_gauss_kernel(X, offsets, nb, r, iv, pts, lw, cnt, 0.7, out, 3.0, True)  # one-sided
    ref = sampled_gauss_numpy(X, offsets, nb, r, iv, pts, lw, cnt, 0.7, 3.0, True)
    np.testing.assert_allclose(out, ref, rtol=1e-12)
    assert np.all(np.isfinite(out))
    n_pk = np.array([1, 3, 0, 2, 4, 1])  # link 2 has no peak: the floor only
    pk_off = np.concatenate([[0], np.cumsum(n_pk)])
    pk_d, pk_h = rng.uniform(10, 120, pk_off[-1]), rng.uniform(0, 40, pk_off[-1])
    pk_c, s2, floor = rng.uniform(0.5, 20, pk_off[-1]), rng.uniform(0, 4, 6), rng.uniform(0, 5, 6)
    args = (X, offsets, nb, pk_off, pk_d, pk_h, pk_c, s2, floor, 2.0, pts, lw, cnt, 0.7)
    K.sampled_mixture_kernel(*args, out)
    np.testing.assert_allclose(out, sampled_mixture_numpy(*args), rtol=1e-11)
    assert np.all(np.isfinite(out))


def _two_agents(rng):
    """Two agents (nodes 0, 1) and four anchors; agent 0 hears node 1 and every anchor."""
    pos = np.vstack([[[37.0, 61.0], [55.0, 42.0]], ANCHORS])
    is_anchor = np.array([False, False, True, True, True, True])
    links = np.array([[0, 1], [0, 2], [0, 3], [0, 4], [0, 5], [1, 0], [1, 2]])
    return pos, is_anchor, links


def test_dirac_neighbour_equals_the_anchor_likelihood_exactly(rng):
    pos, is_anchor, links = _two_agents(rng)
    table = awgn_network(pos, is_anchor, links, rng)
    X = pos[0] + rng.normal(0, 3.0, (1, 300, 2))
    d = np.linalg.norm(pos[links[:, 0]] - pos[links[:, 1]], axis=1) + rng.normal(0, 0.2, 7)
    var = np.full(7, 0.04)
    anchored = is_anchor.copy()
    anchored[1] = True  # node 1 known exactly at its (single) particle
    dirac = pos[1] + np.array([0.3, -0.2])
    centers = pos.copy()
    centers[1] = dirac
    covs = np.zeros((6, 2, 2))
    for base_sampled, base_anchor in (
        (
            DirectLikelihood(table, links, agent_map(is_anchor), 2, use_env=False),
            DirectLikelihood(table, links, agent_map(anchored), 1, use_env=False),
        ),
        (
            MarginalDirectLikelihood(table, links, agent_map(is_anchor), 2),
            MarginalDirectLikelihood(table, links, agent_map(anchored), 1, use_env=False),
        ),
        (
            GaussianRangeLikelihood(d, var, np.ones(7, bool), links, agent_map(is_anchor), 2),
            GaussianRangeLikelihood(
                d, var, np.ones(7, bool), links, agent_map(anchored), 1, use_erv=False
            ),
        ),
    ):
        both = np.concatenate([X, pos[1] + rng.normal(0, 1, (1, 300, 2))])
        beliefs = NodeBeliefs(
            centers, np.array([0, 1]), dirac[None, None].repeat(2, 0), np.zeros((2, 1))
        )
        got = SampledLikelihood(base_sampled).loglik(both, centers, covs, beliefs=beliefs)[0]
        want = base_anchor.loglik(X, centers, covs)[0]
        # two kernels, one sum: equal to the last bits (a few ulps of reordered addition)
        np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-13)


def _marginal_by_quadrature(x, mu, s, r, sigma):
    """``∫ N(y; mu, s²I) N(r; ‖x − y‖, σ²)·√(2πσ²) dy`` on a fine grid (brute force)."""
    g = np.linspace(-7 * s, 7 * s, 1401)
    h = g[1] - g[0]
    yy = mu[None, None, :] + np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1)
    dens = np.exp(-0.5 * (g[:, None] ** 2 + g[None, :] ** 2) / s**2) / (2 * math.pi * s**2)
    out = []
    for xi in x:
        d = np.linalg.norm(yy - xi, axis=-1)
        out.append(np.sum(dens * np.exp(-0.5 * (d - r) ** 2 / sigma**2)) * h * h)
    return np.array(out)


def test_gaussian_neighbour_particles_converge_to_the_marginal(rng):
    """With neighbour particles ~ N(mu, s²I), the sampled message → the marginal as Q grows."""
    mu, s, r, sigma = np.array([50.0, 50.0]), 2.0, 10.0, 0.5
    x = mu + np.array([[10.0, 0.0], [7.0, 7.5], [0.0, 12.0], [-9.0, 1.0], [3.0, 3.0]])
    ref = _marginal_by_quadrature(x, mu, s, r, sigma)
    offsets, nb = np.array([0, 1]), np.array([1])
    errs = {}
    for Q in (100, 10000):
        e = []
        for _ in range(20):
            pts = np.zeros((2, Q, 2))
            pts[1] = mu + s * rng.standard_normal((Q, 2))
            lw = np.full((2, Q), -np.log(Q))
            out = np.empty((1, len(x)))
            K.sampled_gauss_kernel(
                x[None],
                offsets,
                nb,
                np.array([r]),
                np.array([sigma**-2]),
                pts,
                lw,
                np.array([Q, Q]),
                1.0,
                out,
            )
            e.append(np.exp(out[0]) / ref - 1.0)
        errs[Q] = np.sqrt(np.mean(np.square(e)))
    assert errs[10000] < 0.05
    assert errs[100] / errs[10000] > 5.0  # Monte Carlo rate 1/√Q: a ratio of ≈ 10


def test_all_zero_and_empty_likelihoods_stay_finite(rng):
    """Neighbours with all-(−inf) weights, agents without links, absurd ranges: no NaN."""
    pos, is_anchor, links = _two_agents(rng)
    far = np.full(7, 1e9)
    lik = SampledLikelihood(
        GaussianRangeLikelihood(
            far, np.full(7, 1e-12), np.ones(7, bool), links, agent_map(is_anchor), 2
        )
    )
    X = rng.uniform(0, 100, (2, 50, 2))
    lw = np.full((2, 50), -np.inf)
    b = NodeBeliefs(pos, np.array([0, 1]), X, lw)
    out = lik.loglik(X, pos, np.zeros((6, 2, 2)), beliefs=b)
    assert not np.any(np.isnan(out))
    meas = LinkMeasurements(
        6,
        2,
        [2, 3, 4, 5],
        ANCHORS[None],
        [links],
        ranges={"sage": LinkRanges.single(far, np.full(7, 1e-12))},
    )
    prior = gaussian_prior(pos[:2], 5.0, 60, rng)
    res = run_direct(meas, prior, rng, METHODS["sage_sampled"].make_options({"n_particles": 60}))
    assert np.all(np.isfinite(res.estimates))


@pytest.mark.parametrize("name", ["dpe_sampled", "sage_sampled"])
def test_sampled_methods_localize_two_cooperating_agents(rng, name):
    pos, is_anchor, links = _two_agents(rng)
    table = awgn_network(pos, is_anchor, links, rng)
    d = np.linalg.norm(pos[links[:, 0]] - pos[links[:, 1]], axis=1) + rng.normal(0, 0.05, 7)
    meas = LinkMeasurements(
        6,
        2,
        [2, 3, 4, 5],
        ANCHORS[None],
        [links],
        tables=[table],
        ranges={"sage": LinkRanges.single(d, np.full(7, 0.0025))},
    )
    prior = gaussian_prior(pos[:2] + rng.normal(0, 3, (2, 2)), 5.0, 200, rng)
    res = run_direct(meas, prior, rng, METHODS[name].make_options({"n_particles": 200}))
    err = np.linalg.norm(res.estimates[0] - pos[:2], axis=1)
    assert np.all(err < 0.5), err


def test_exchange_and_kernel_options_are_checked():
    with pytest.raises(ValidationError, match="exchange"):
        DirectOptions(exchange="beliefs")
    with pytest.raises(ValidationError, match="sample_kernel"):
        DirectOptions(exchange="particles", sample_kernel="epanechnikov")
    assert DirectOptions(dpf=DPFOptions(), likelihood="env", exchange="particles")


def test_silverman_bandwidth_of_gaussian_particles(rng):
    """``h² = (4/(n(d + 2)))^{2/(d + 4)}·σ²`` for equally weighted particles of std σ."""
    X = rng.normal(0.0, 3.0, (1, 4000, 2))
    b = NodeBeliefs(np.zeros((3, 2)), np.array([1]), X, np.full((1, 4000), -np.log(4000)))
    expect = (4.0 / (4000 * 4)) ** (2.0 / 6) * 9.0
    assert b.bandwidth2[1] == pytest.approx(expect, rel=0.05)
    assert b.bandwidth2[0] == b.bandwidth2[2] == 0.0

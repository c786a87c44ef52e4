"""The equivalent-likelihood DPF: DiPNet (DiPNet eqs. (25)–(28)) and its safeguards."""

import math
import types

import numba
import numpy as np
import pytest
from naive_direct import (
    direct_loglik_numpy,
    gauss_loglik_numpy,
    mh_accept_numpy,
    mh_propose_numpy,
    mixture_grid_numpy,
    mixture_loglik_numpy,
    mixture_table_numpy,
    mixture_tabulated_numpy,
    next_lambda_numpy,
    systematic_resample_numpy,
)

from phyloc.localization import _kernels as K
from phyloc.localization import particles as P
from phyloc.localization.direct import (
    DirectOptions,
    DPFOptions,
    LinkMeasurements,
    Prior,
    run,
    run_dpf,
)
from phyloc.localization.direct import _kernels as DK
from phyloc.localization.direct.dpf import _floor
from phyloc.localization.direct.likelihoods import (
    TABLE_MARGIN,
    TABLE_MAX_POINTS,
    TABLE_RESOLUTION,
    DirectLikelihood,
    GaussianRangeLikelihood,
    MarginalDirectLikelihood,
    projected_variances,
)
from phyloc.localization.direct.sampled_exchange import SampledLikelihood
from phyloc.localization.likelihoods import IncomingLinks, Likelihood
from phyloc.phy import C0, OFDMSystem, PathSet
from phyloc.phy.correlation import correlation_tables
from phyloc.phy.synthesis import synthesize
from phyloc.phy.waveform import qpsk_symbols

SYSTEM = OFDMSystem()


def awgn_network(positions, is_anchor, links, rng, pc_snr_db=40.0, scale_gain=1.0):
    d = np.linalg.norm(positions[links[:, 0]] - positions[links[:, 1]], axis=1)
    S = qpsk_symbols(SYSTEM, len(positions), rng)
    snr = 10 ** (pc_snr_db / 10) / SYSTEM.n_subcarriers
    gains = (
        scale_gain * math.sqrt(snr * SYSTEM.noise_power_w) * np.exp(2j * np.pi * rng.random(d.size))
    )
    R = synthesize(PathSet.single_path(d / C0, gains), S, SYSTEM, rng, tx_index=links[:, 1])
    return correlation_tables(R, S, SYSTEM, tx_index=links[:, 1])


def agent_map(is_anchor):
    out = -np.ones(is_anchor.size, np.int64)
    out[~is_anchor] = np.arange((~is_anchor).sum())
    return out


def gaussian_prior(centers, std, Q, rng, label="test"):
    X = centers[:, None, :] + std * rng.standard_normal((len(centers), Q, centers.shape[1]))

    def logp(x):
        return -0.5 * np.sum((x - centers[:, None, :]) ** 2, axis=2) / std**2

    return Prior(X, logp, label)


ANCHORS = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 100.0], [100.0, 100.0]])


def single_agent_setup(agent=(37.0, 61.0)):
    pos = np.vstack([np.array([agent]), ANCHORS])
    is_anchor = np.array([False, True, True, True, True])
    links = np.array([[0, j] for j in range(1, 5)])
    return pos, is_anchor, links


# -- equations by hand ------------------------------------------------------------------------
def test_projected_variance_eq15_by_hand():
    centers = np.array([[0.0, 0.0], [3.0, 4.0]])  # e_uv = (-3, -4)/5
    covs = np.array([np.zeros((2, 2)), [[2.0, 0.5], [0.5, 1.0]]])
    # e^T C e = (9·2 + 2·12·0.5 + 16·1)/25 = (18 + 12 + 16)/25 = 1.84
    got = projected_variances(centers, covs, np.array([0]), np.array([1]))
    assert got[0] == pytest.approx(1.84)
    # coincident nodes: isotropic trace/dim = 1.5, not NaN
    got = projected_variances(np.zeros((2, 2)), covs, np.array([0]), np.array([1]))
    assert got[0] == pytest.approx(1.5)


def test_env_eq26_and_erv_eq18_by_hand(rng):
    pos, is_anchor, links = single_agent_setup()
    tab = awgn_network(pos, is_anchor, links, rng)
    lik = DirectLikelihood(tab, links, agent_map(is_anchor), 1)
    centers = pos.copy()
    covs = np.zeros((5, 2, 2))
    covs[1] = np.diag([4.0, 1.0])  # anchor 1 at (100, 0): e_01 = (-63, 61)/|.|
    e = (pos[0] - pos[1]) / np.linalg.norm(pos[0] - pos[1])
    s2 = 4.0 * e[0] ** 2 + 1.0 * e[1] ** 2
    omega = 2 * math.pi * 14650.0
    n = np.arange(-1284, 1285)
    expected = lik.noise_var[0] + 2 * omega**2 * s2 * lik.alpha_abs2[0] * np.sum(n**2) / C0**2
    env = lik.env(centers, covs)
    assert env[0] == pytest.approx(expected, rel=1e-12)
    np.testing.assert_allclose(env[1:], lik.noise_var[1:])
    # ENV consistency: CRB with σ̃² (DiPNet eq. (24)) = CRB with σ² + σ²_{v→uv} (DiPNet eq. (18))
    crb = C0**2 * lik.noise_var[0] / (2 * lik.alpha_abs2[0] * omega**2 * np.sum(n**2))
    crb_env = C0**2 * env[0] / (2 * lik.alpha_abs2[0] * omega**2 * np.sum(n**2))
    assert crb_env == pytest.approx(crb + s2, rel=1e-10)
    # ERV of the Gaussian model: var + e^T C e
    g = GaussianRangeLikelihood(
        np.full(4, 50.0), np.full(4, 0.25), np.ones(4, bool), links, agent_map(is_anchor), 1
    )
    X = np.array([[[37.0, 61.0]]])
    d = np.linalg.norm(X[0, 0] - pos[1])
    by_hand = -0.5 * (d - 50.0) ** 2 / (0.25 + s2)
    others = sum(-0.5 * (np.linalg.norm(X[0, 0] - pos[j]) - 50.0) ** 2 / 0.25 for j in (2, 3, 4))
    assert g.loglik(X, centers, covs)[0, 0] == pytest.approx(by_hand + others, rel=1e-12)


def test_every_link_likelihood_has_the_members_of_the_protocol(rng):
    pos, is_anchor, links = single_agent_setup()
    tab = awgn_network(pos, is_anchor, links, rng)
    amap = agent_map(is_anchor)
    ranges = (np.full(4, 50.0), np.full(4, 0.25), np.ones(4, bool))
    liks = [
        DirectLikelihood(tab, links, amap, 1),
        MarginalDirectLikelihood(tab, links, amap, 1),
        GaussianRangeLikelihood(*ranges, links, amap, 1),
    ]
    liks += [SampledLikelihood(lik) for lik in liks]
    X = pos[None, :1] + rng.normal(0.0, 1.0, (1, 20, 2))
    for lik in liks:
        assert isinstance(lik, Likelihood)
        assert isinstance(lik.csr, IncomingLinks) and lik.csr.offsets.tolist() == [0, 4]
        assert lik.nu.shape == lik.csr.rx.shape == (4,)
        assert lik.loglik(X, pos, np.zeros((5, 2, 2)), 0.5).shape == (1, 20)
    assert not isinstance(types.SimpleNamespace(kind="x", csr=None), Likelihood)


def test_the_numerics_seam_is_the_numerics_of_the_tables_and_estimators(rng):
    """``lagrange_eval`` is the interpolation of ``CorrelationTable.evaluate``, and
    ``correlate_derivs`` / ``newton_peak`` the peak refinement of the range estimators."""
    from phyloc.phy import _kernels as phy_kernels
    from phyloc.phy.correlation import lagrange_eval
    from phyloc.ranging import _kernels as ranging_kernels
    from phyloc.ranging.numerics import correlate_derivs, newton_peak

    values = rng.normal(size=(3, 64)) + 1j * rng.normal(size=(3, 64))
    rows, x = np.array([0, 1, 2, 1]), np.array([0.3, 17.9, 63.5, -2.2])
    for order in (2, 4, 6):
        ref = np.empty(4, np.complex128)
        phy_kernels.interp_kernel(values, rows, x, order, ref)
        got = [lagrange_eval(values, r, 64, xq, order) for r, xq in zip(rows, x, strict=True)]
        np.testing.assert_array_equal(got, ref)
    n0, w, spacing = -40.0, 2 * math.pi * 1e6 / C0, 0.4
    n = n0 + np.arange(81)
    spec = np.exp(1j * w * n[None, :] * np.array([[31.3], [77.05]]))  # peaks at 31.3, 77.05 m
    d0 = np.array([31.2, 77.2])
    ref = np.empty(2)
    ranging_kernels.refine_kernel(spec, n0, w, d0, spacing, 8, ref)
    got = [newton_peak(spec[i], n0, w, d0[i], spacing, 8) for i in range(2)]
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_allclose(got, [31.3, 77.05], atol=1e-9)
    for i in range(2):
        assert correlate_derivs(spec[i], n0, w, got[i]) == ranging_kernels._correlate_derivs(
            spec[i], n0, w, got[i]
        )


# -- kernels against their twins -----------------------------------------------------------------
@pytest.mark.parametrize("dim", [1, 2, 3])  # the planar and spatial distance loops are unrolled
def test_loglik_kernels_match_numpy_twins(rng, dim):
    n_agents, Q, n_nodes = 3, 50, 6
    X = rng.uniform(0, 100, (n_agents, Q, dim))
    centers = rng.uniform(0, 100, (n_nodes, dim))
    offsets = np.array([0, 2, 2, 5])  # agent 1 has no links
    nb = np.array([3, 4, 0, 5, 1])
    values = rng.standard_normal((5, 400)) + 1j * rng.standard_normal((5, 400))
    scale = rng.uniform(0.1, 2, 5)
    out = np.empty((n_agents, Q))
    DK.direct_loglik_kernel(X, offsets, nb, np.arange(5), scale, centers, values, 1.3, 4, out)
    ref = direct_loglik_numpy(X, offsets, nb, np.arange(5), scale, centers, values, 1.3, 4)
    np.testing.assert_allclose(out, ref, rtol=1e-12)
    assert np.all(out[1] == 0)
    r, iv = rng.uniform(10, 90, 5), rng.uniform(0.1, 3, 5)
    DK.gauss_loglik_kernel(X, np.arange(n_agents), offsets, nb, r, iv, centers, out)
    np.testing.assert_allclose(out, gauss_loglik_numpy(X, offsets, nb, r, iv, centers), rtol=1e-12)
    sub = np.empty((2, Q))  # a subset of the agents, in any order
    DK.gauss_loglik_kernel(X[[2, 0]], np.array([2, 0]), offsets, nb, r, iv, centers, sub)
    np.testing.assert_array_equal(sub, out[[2, 0]])
    for gamma in (0.7, 0.0):  # the outlier mixture, tempered (inv_var carries γ)
        DK.gauss_loglik_kernel(
            X, np.arange(n_agents), offsets, nb, r, gamma * iv, centers, out, 4.0, gamma
        )
        ref = gauss_loglik_numpy(X, offsets, nb, r, gamma * iv, centers, 4.0, gamma)
        np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-300)
        assert np.all(out >= -gamma * 4.0 * np.diff(offsets)[:, None] - 1e-12)
        # one-sided: the same mixture where d < r, the Gaussian's pull where d > r
        DK.gauss_loglik_kernel(
            X, np.arange(n_agents), offsets, nb, r, gamma * iv, centers, out, 4.0, gamma, True
        )
        ref = gauss_loglik_numpy(X, offsets, nb, r, gamma * iv, centers, 4.0, gamma, True)
        np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-300)


def test_log_normalize_kernel_matches_scipy_and_falls_back_to_uniform(rng):
    """``normalize_log_weights`` (``log_normalize_kernel``) against ``scipy.special.logsumexp``
    on ordinary and extreme rows; rows with no finite weight, a NaN or a +inf become uniform
    and are counted; nothing non-finite but −inf leaks."""
    from scipy.special import logsumexp

    lw = rng.normal(0, 50, (6, 300))
    lw[1, ::3] = -np.inf  # some zero weights
    lw[1] -= 2000.0  # every exp() would underflow without the max shift
    lw[2] += 2000.0  # … or overflow
    lw[3] = -np.inf  # no finite weight
    lw[4, 7] = np.nan
    lw[5, 0] = np.inf
    out, bad = P.normalize_log_weights(lw)
    assert bad == 3
    for a in (0, 1, 2):
        ref = lw[a] - logsumexp(lw[a])
        np.testing.assert_allclose(out[a][np.isfinite(ref)], ref[np.isfinite(ref)], atol=1e-12)
        np.testing.assert_array_equal(np.isfinite(out[a]), np.isfinite(ref))
        assert np.exp(out[a]).sum() == pytest.approx(1.0, rel=1e-12)
    np.testing.assert_array_equal(out[3:], -np.log(300))
    # log-likelihoods of ~1e24 nats (+200 dBm): a constant row and a row whose spread is below
    # the rounding step of its magnitude still normalize to weights summing to 1 (with
    # lw − (max + log Σ) every particle at the maximum got weight 1: a sum of Q)
    huge = np.full((2, 1000), 1.4e24)
    huge[1, ::2] += 2.0**28  # one ulp at 1.4e24
    out, bad = P.normalize_log_weights(huge)
    assert bad == 0
    np.testing.assert_allclose(np.exp(out).sum(axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(np.exp(out[0]), 1e-3, rtol=1e-12)


def test_systematic_resampling_matches_twin_and_textbook(rng):
    w = rng.random(37)
    w /= w.sum()
    for u0 in (0.0, 0.3, 0.999):
        out = np.empty(100, np.int64)
        K.systematic_resample_kernel(w, u0, out)
        np.testing.assert_array_equal(out, systematic_resample_numpy(w, u0, 100))
        # textbook: particle i is copied floor(N w_i) or ceil(N w_i) times
        counts = np.bincount(out, minlength=37)
        assert np.all(counts >= np.floor(100 * w) - 1e-9) and np.all(counts <= np.ceil(100 * w))
    one = np.zeros(10)
    one[7] = 1.0
    out = np.empty(10, np.int64)
    K.systematic_resample_kernel(one, 0.5, out)
    assert np.all(out == 7)  # all weight on one particle ⇒ every copy is that particle


# -- behaviour --------------------------------------------------------------------------------
def test_dipnet_single_agent_reaches_the_efim_bound():
    rng = np.random.default_rng(5)
    pos, is_anchor, links = single_agent_setup()
    tab = awgn_network(pos, is_anchor, links, rng)
    lik = DirectLikelihood(tab, links, agent_map(is_anchor), 1)
    e = (pos[0] - pos[1:]) / np.linalg.norm(pos[0] - pos[1:], axis=1)[:, None]
    J = np.einsum("l,li,lj->ij", lik.nu, e, e)
    bound = math.sqrt(np.trace(np.linalg.inv(J)))
    errs = []
    for _ in range(25):
        lt = awgn_network(pos, is_anchor, links, rng)
        lk = DirectLikelihood(lt, links, agent_map(is_anchor), 1)
        res = run_dpf(lk, gaussian_prior(pos[:1], 10.0, 1000, rng), pos[is_anchor], is_anchor, rng)
        errs.append(res.means[0] - pos[0])
    rmse = math.sqrt(np.mean(np.sum(np.square(errs), axis=1)))
    assert bound / 2 <= rmse <= 2 * bound


def test_published_variant_collapses_and_default_does_not():
    rng = np.random.default_rng(8)
    pos, is_anchor, links = single_agent_setup()
    tab = awgn_network(pos, is_anchor, links, rng)
    lik = DirectLikelihood(tab, links, agent_map(is_anchor), 1)
    wide = gaussian_prior(pos[:1] + 20.0, 40.0, 1000, rng)  # uninformative-ish
    pub = run_dpf(lik, wide, pos[is_anchor], is_anchor, rng, DPFOptions.published())
    safe = run_dpf(lik, wide, pos[is_anchor], is_anchor, rng, DPFOptions())
    assert pub.ess_history[0, 0] < 3.0
    assert safe.ess_history.min() >= 0.45 * 1000
    assert safe.annealing_steps > 1


def _finite_belief(res):
    w = np.exp(res.log_weights)
    assert np.all(np.isfinite(res.means)) and np.all(np.isfinite(res.covs))
    np.testing.assert_allclose(w.sum(axis=1), 1.0, rtol=1e-9)


@pytest.mark.parametrize("opts", [DPFOptions(n_iterations=3), DPFOptions.published(n_iterations=3)])
def test_degenerate_inputs_stay_finite(opts):
    rng = np.random.default_rng(2)
    pos, is_anchor, links = single_agent_setup()
    # all-zero likelihood: a table of zeros
    tab = awgn_network(pos, is_anchor, links, rng, scale_gain=0.0)
    object.__setattr__(tab, "values", np.zeros_like(tab.values))
    lik = DirectLikelihood(tab, links, agent_map(is_anchor), 1)
    _finite_belief(
        run_dpf(lik, gaussian_prior(pos[:1], 5.0, 200, rng), pos[is_anchor], is_anchor, rng, opts)
    )
    # SNR of 100 dB
    tab = awgn_network(pos, is_anchor, links, rng, pc_snr_db=100.0)
    lik = DirectLikelihood(tab, links, agent_map(is_anchor), 1)
    res = run_dpf(lik, gaussian_prior(pos[:1], 5.0, 200, rng), pos[is_anchor], is_anchor, rng, opts)
    _finite_belief(res)
    # an agent with no neighbours and two coincident agents
    pos2 = np.vstack([pos, [[37.0, 61.0]], [[80.0, 20.0]]])
    is_anchor2 = np.append(is_anchor, [False, False])
    links2 = np.array([[0, 1], [0, 2], [0, 5], [5, 0], [5, 3]])  # node 6 has no links
    tab2 = awgn_network(pos2, is_anchor2, links2, rng)
    lik2 = DirectLikelihood(tab2, links2, agent_map(is_anchor2), 3)
    prior2 = gaussian_prior(pos2[~is_anchor2], 5.0, 200, rng)
    res2 = run_dpf(lik2, prior2, pos2[is_anchor2], is_anchor2, rng, opts)
    _finite_belief(res2)


def test_many_particles_and_neighbours_stay_finite():
    rng = np.random.default_rng(3)
    n_nb = 100
    ang = np.linspace(0, 2 * np.pi, n_nb, endpoint=False)
    anchors = 50 + 40 * np.c_[np.cos(ang), np.sin(ang)]
    pos = np.vstack([[[50.0, 50.0]], anchors])
    is_anchor = np.r_[False, np.ones(n_nb, bool)]
    links = np.c_[np.zeros(n_nb, np.int64), np.arange(1, n_nb + 1)]
    g = GaussianRangeLikelihood(
        np.full(n_nb, 40.0),
        np.full(n_nb, 1e-4),
        np.ones(n_nb, bool),
        links,
        agent_map(is_anchor),
        1,
    )
    res = run_dpf(
        g,
        gaussian_prior(pos[:1], 3.0, 10_000, rng),
        pos[is_anchor],
        is_anchor,
        rng,
        DPFOptions(n_iterations=2),
    )
    _finite_belief(res)
    assert np.linalg.norm(res.means[0] - pos[0]) < 0.05


def test_same_seed_same_result_with_any_thread_count():
    pos, is_anchor, links = single_agent_setup()
    tab = awgn_network(pos, is_anchor, links, np.random.default_rng(4))
    lik = DirectLikelihood(tab, links, agent_map(is_anchor), 1)
    out = []
    before = numba.get_num_threads()
    try:
        for threads in (1, before):
            numba.set_num_threads(threads)
            rng = np.random.default_rng(12)
            out.append(
                run_dpf(
                    lik, gaussian_prior(pos[:1], 10.0, 300, rng), pos[is_anchor], is_anchor, rng
                )
            )
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(out[0].means, out[1].means)
    np.testing.assert_array_equal(out[0].particles, out[1].particles)


# -- the marginal equivalent likelihood ---------------------------------------------------------
@pytest.mark.parametrize("dim", [1, 2, 3])
def test_mixture_kernel_matches_numpy_twin(rng, dim):
    from phyloc.localization.direct._kernels import mixture_loglik_kernel

    n_agents, Q = 3, 40
    X = rng.uniform(0, 100, (n_agents, Q, dim))
    centers = rng.uniform(0, 100, (6, dim))
    offsets = np.array([0, 2, 2, 4])
    nb = np.array([3, 4, 5, 0])
    pk_off = np.array([0, 3, 3, 4, 9])  # link 1 has no peak: only the floor
    n_pk = 9
    pk_d = rng.uniform(0, 150, n_pk)
    pk_h = rng.uniform(0, 500, n_pk)
    pk_c = rng.uniform(0.1, 1e3, n_pk)
    s2 = np.array([0.0, 4.0, 100.0, 0.5])
    out = np.empty((n_agents, Q))
    floor = np.array([0.0, 3.0, 0.0, 50.0])
    mixture_loglik_kernel(
        X, offsets, nb, pk_off, pk_d, pk_h, pk_c, s2, floor, 2.0, 0.7, centers, out
    )
    ref = mixture_loglik_numpy(
        X, offsets, nb, pk_off, pk_d, pk_h, pk_c, s2, floor, 2.0, 0.7, centers
    )
    np.testing.assert_allclose(out, ref, rtol=1e-10)
    assert np.all(out >= 0)  # the floor: exp(ℓ) >= 1


def random_mixture(rng, n_agents=3, n_centers=7, dim=2):
    """Links with 0–6 peaks: sharp (c up to 30 m⁻²) and strong (h up to 400 nats), broad,
    and one link with only the floor; floors 0 (``outlier_nats = inf``) and higher."""
    centers = rng.uniform(0, 100, (n_centers, dim))
    n_links_per = rng.integers(2, 5, n_agents)
    offsets = np.concatenate([[0], np.cumsum(n_links_per)])
    n_links = offsets[-1]
    nb = rng.integers(n_agents, n_centers, n_links)
    n_pk = rng.integers(1, 7, n_links)
    n_pk[1] = 0
    pk_off = np.concatenate([[0], np.cumsum(n_pk)])
    d_true = np.linalg.norm(
        centers[nb] - centers[np.repeat(np.arange(n_agents), n_links_per)], axis=1
    )
    pk_d = np.repeat(2.0 * d_true, n_pk) + rng.uniform(0, 20, n_pk.sum())
    pk_h = rng.uniform(5, 400, n_pk.sum())
    pk_c = 10 ** rng.uniform(-1, 1.5, n_pk.sum())
    s2 = rng.choice([0.0, 0.3, 4.0], n_links)
    floor = np.where(rng.random(n_links) < 0.5, 0.0, rng.uniform(1, 300, n_links))
    return centers, offsets, nb, pk_off, pk_d, pk_h, pk_c, s2, floor


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_tabulated_mixture_kernels_match_their_twins(rng, dim):
    """Grid, table and interpolation kernels against the NumPy twins, on an agent subset: the
    kernel's power-basis cubic pieces (Horner) against the twin's Lagrange weights."""
    for _trial in range(5):
        centers, offsets, nb, pk_off, pk_d, pk_h, pk_c, s2, floor = random_mixture(rng, dim=dim)
        X = centers[:3, None, :] + rng.normal(0, 4.0, (3, 60, dim))
        grid_args = (X, offsets, nb, pk_off, pk_h, pk_c, s2, floor, 2.0, centers)
        consts = (TABLE_RESOLUTION, TABLE_MAX_POINTS, TABLE_MARGIN)
        n_links = nb.size
        lo, inv_h, count = np.zeros(n_links), np.zeros(n_links), np.zeros(n_links, np.int64)
        DK.mixture_grid_kernel(*grid_args, *consts, lo, inv_h, count)
        ref = mixture_grid_numpy(*grid_args, *consts)
        np.testing.assert_array_equal(count, ref[2])
        np.testing.assert_allclose(lo, ref[0], rtol=1e-12)
        np.testing.assert_allclose(inv_h, ref[1], rtol=1e-12)
        assert count.sum() > 0
        count[0] = 0  # a link with peaks but no grid: evaluated exactly everywhere
        t_off = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
        table = np.empty((count.sum(), 4))
        DK.mixture_table_kernel(
            offsets, pk_off, pk_d, pk_h, pk_c, s2, floor, lo, inv_h, count, t_off, table
        )
        ref_table = mixture_table_numpy(pk_off, pk_d, pk_h, pk_c, s2, floor, lo, inv_h, count)
        np.testing.assert_allclose(table[:, 0], ref_table, rtol=1e-10, atol=1e-12)
        agents = np.array([2, 0])
        Y = X[agents] + rng.normal(0, 1.0, (2, 60, dim))
        Y[0, :5] += 300.0  # beyond every grid: evaluated exactly
        out = np.empty((2, 60))
        tail = (2.0, 0.7, centers, lo, inv_h, count)
        DK.mixture_tabulated_kernel(
            Y, agents, offsets, nb, pk_off, pk_d, pk_h, pk_c, s2, floor, *tail, t_off, table, out
        )
        twin = mixture_tabulated_numpy(
            Y, agents, offsets, nb, pk_off, pk_d, pk_h, pk_c, s2, floor, *tail, table[:, 0]
        )
        np.testing.assert_allclose(out, twin, rtol=1e-10, atol=1e-9)


def test_tabulated_mixture_is_within_a_millinat_of_the_exact_one(rng):
    """The interpolated log-likelihood (the DPF's frozen likelihood) against the exact
    mixture: at most 1e-3 nats per link anywhere, exact outside the grids."""
    worst = 0.0
    for _trial in range(20):
        centers, offsets, nb, pk_off, pk_d, pk_h, pk_c, s2, floor = random_mixture(rng)
        spread = rng.choice([0.5, 5.0, 30.0])
        X = centers[:3, None, :] + rng.normal(0, spread, (3, 400, 2))
        n_links = nb.size
        lo, inv_h, count = np.zeros(n_links), np.zeros(n_links), np.zeros(n_links, np.int64)
        DK.mixture_grid_kernel(
            X,
            offsets,
            nb,
            pk_off,
            pk_h,
            pk_c,
            s2,
            floor,
            2.0,
            centers,
            TABLE_RESOLUTION,
            TABLE_MAX_POINTS,
            TABLE_MARGIN,
            lo,
            inv_h,
            count,
        )
        t_off = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
        table = np.empty((count.sum(), 4))
        DK.mixture_table_kernel(
            offsets, pk_off, pk_d, pk_h, pk_c, s2, floor, lo, inv_h, count, t_off, table
        )
        agents = np.arange(3)
        out = np.empty((3, 400))
        DK.mixture_tabulated_kernel(
            X,
            agents,
            offsets,
            nb,
            pk_off,
            pk_d,
            pk_h,
            pk_c,
            s2,
            floor,
            2.0,
            1.0,
            centers,
            lo,
            inv_h,
            count,
            t_off,
            table,
            out,
        )
        exact = mixture_loglik_numpy(
            X, offsets, nb, pk_off, pk_d, pk_h, pk_c, s2, floor, 2.0, 1.0, centers
        )
        err = np.abs(out - exact) / np.diff(offsets)[:, None]
        worst = max(worst, err.max())
    assert worst <= 1e-3


def test_frozen_likelihood_equals_the_marginal_one():
    """MarginalDirectLikelihood.frozen: the tabulated function the DPF steps with agrees with
    loglik, a subset of agents gives the same rows, and coincident nodes stay finite."""
    rng = np.random.default_rng(17)
    pos = np.vstack([rng.uniform(20, 80, (3, 2)), ANCHORS])
    is_anchor = np.array([False] * 3 + [True] * 4)
    links = np.array([[a, b] for a in range(3) for b in range(7) if a != b])
    tab = awgn_network(pos, is_anchor, links, rng, pc_snr_db=30.0)
    amap = agent_map(is_anchor)
    covs = np.zeros((7, 2, 2))
    covs[:3] = 4.0 * np.eye(2)
    lik = MarginalDirectLikelihood(tab, links, amap, 1)
    X = pos[:3, None, :] + rng.normal(0, 3.0, (3, 500, 2))
    X[1, 0] = pos[4]  # a particle on an anchor: distance 0
    X[2, 1] = pos[0]  # and on a neighbour's centre
    fn = lik.frozen(X, pos, covs, gamma=0.6)
    assert fn.table_points > 0
    got = fn(X)
    exact = lik.loglik(X, pos, covs, gamma=0.6)
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, exact, rtol=0, atol=0.6 * 6 * 1e-3)
    sub = fn(X[[2, 0]], agents=[2, 0])
    np.testing.assert_array_equal(sub, got[[2, 0]])
    same = np.repeat(X[:, :1], 50, axis=1)  # every particle at one point: a one-point range
    np.testing.assert_allclose(
        lik.frozen(same, pos, covs)(same), lik.loglik(same, pos, covs), atol=6e-3
    )
    off = MarginalDirectLikelihood(tab, links, amap, 1, tabulate=False)
    assert off.frozen(X, pos, covs) is None


def test_marginal_likelihood_is_the_convolution_of_the_exact_one(rng):
    """log p̃(d) ≈ log ∫ exp(ℓ(d − y)) N(y; 0, s²) dy, ℓ = |f|²/(σ²‖S‖²) (brute force)."""
    pos, is_anchor, links = single_agent_setup()
    tab = awgn_network(pos, is_anchor, links, rng, pc_snr_db=25.0).select([0])
    lik = MarginalDirectLikelihood(tab, links[:1], agent_map(is_anchor), 1, outlier_nats=np.inf)
    d_true = np.linalg.norm(pos[0] - pos[1])
    inv_scale = 1.0 / (tab.noise_var[0] * tab.symbol_energy[0])
    direction = (pos[0] - pos[1]) / d_true
    for s2 in (0.0, 0.25, 4.0, 100.0):
        covs = np.zeros((5, 2, 2))
        covs[1] = s2 * np.eye(2)  # projected variance s² on any link
        s = math.sqrt(s2)
        y = np.linspace(-8 * s - 6, 8 * s + 6, 4001)
        for off in (-5.0, -0.7, 0.0, 0.3, 3.0):
            X = np.array([[pos[1] + (d_true + off) * direction]])
            # loglik is relative to the link's highest peak height (``pk_ref``): add it back
            got = lik.loglik(X, pos, covs)[0, 0] + lik.pk_ref[0]
            ell = np.abs(tab.exact((d_true + off - y)[None, :], links=[0])[0]) ** 2 * inv_scale
            if s2 == 0.0:
                brute = np.log1p(np.exp(ell[y.size // 2]))  # no smoothing: the exact ℓ(d)
            else:
                wts = np.exp(-0.5 * y**2 / s2) / math.sqrt(2 * math.pi * s2)
                m = ell.max()
                brute = m + np.log(np.trapezoid(np.exp(ell - m) * wts, y))
            if s2 == 0.0 and abs(off) > 1.0:
                continue  # far from the peak the unsmoothed Laplace tail is not the sinc²
            assert got == pytest.approx(brute, rel=0.03, abs=1.0)


@pytest.mark.parametrize("pc_snr_db", [25.0, 120.0, 200.0])
def test_marginal_evidence_bound_survives_extreme_snr(rng, pc_snr_db):
    """At +200 dB the peak height ``h`` is ~1e20 nats, where float64 resolves only ~1e4 nats:
    an absolute floor ``h − f`` would round the bound ``f`` away. Relative to each link's
    highest peak it holds at any SNR: on the peak the link's log-likelihood is
    ``f + log(1 + e^{−f})`` nats above a particle far from every peak (the floor), to 1e-6."""
    pos, is_anchor, links = single_agent_setup()
    tab = awgn_network(pos, is_anchor, links, rng, pc_snr_db=pc_snr_db).select([0])
    lik = MarginalDirectLikelihood(tab, links[:1], agent_map(is_anchor), 1, outlier_nats=10.0)
    d_true = np.linalg.norm(pos[0] - pos[1])
    direction = (pos[0] - pos[1]) / d_true
    peak = lik.pk_d[np.argmax(lik.pk_h)]
    X = np.array([[pos[1] + peak * direction, pos[1] + (peak + 40.0) * direction]])
    ll = lik.loglik(X, pos, np.zeros((5, 2, 2)))[0]
    assert np.all(np.isfinite(ll))
    # log(e^0 + e^{−f}) − (−f) on the peak (no smoothing) against the floor
    assert ll[0] - ll[1] == pytest.approx(10.0 + math.log1p(math.exp(-10.0)), abs=1e-6)


def test_gauge_priors_show_the_published_collapse():
    from phyloc.localization import gauge_log_prior, gauge_priors

    rng = np.random.default_rng(21)
    pos = rng.uniform(0, 60, (6, 2))
    pos[0] = 0.0  # the gauge: agent 0 at the origin, agent 1 on +x, agent 2 above the x-axis
    pos[1] = [40.0, 0.0]
    pos[2, 1] = abs(pos[2, 1]) + 5
    is_anchor = np.zeros(6, bool)
    links = np.array([(u, v) for u in range(6) for v in range(6) if u != v])
    tab = awgn_network(pos, is_anchor, links, rng, pc_snr_db=35.0)
    X = gauge_priors(6, 2, 500, 100.0, rng)
    prior = Prior(X, lambda x: gauge_log_prior(x, 100.0), "gauge")
    pub = run_dpf(
        DirectLikelihood(tab, links, agent_map(is_anchor), 6),
        prior,
        pos[is_anchor],
        is_anchor,
        rng,
        DPFOptions.published(n_iterations=4),
    )
    safe = run_dpf(
        MarginalDirectLikelihood(tab, links, agent_map(is_anchor), 6),
        prior,
        pos[is_anchor],
        is_anchor,
        rng,
        DPFOptions(n_iterations=4),
    )
    # published: the Dirac prior of agent 0 makes its links exact; its neighbours collapse
    assert np.median(pub.ess_history[0, 1:]) < 3.0
    assert safe.ess_history[:, 1:].min() >= 0.45 * 500


def test_tracking_follows_a_moving_agent():
    rng = np.random.default_rng(31)
    T = 8
    path = np.array([37.0, 61.0]) + np.cumsum(rng.normal(0, 1.0, (T, 2)), axis=0)
    tables, links_t = [], []
    for t in range(T):
        pos, is_anchor, links = single_agent_setup(tuple(path[t]))
        tables.append(awgn_network(pos, is_anchor, links, rng, pc_snr_db=35.0))
        links_t.append(links)
    meas = LinkMeasurements(
        n_nodes=5,
        dim=2,
        anchor_nodes=[1, 2, 3, 4],
        anchor_positions=np.repeat(ANCHORS[None], T, axis=0),
        links=links_t,
        tables=tables,
    )
    prior = gaussian_prior(np.array([path[0]]), 5.0, 1000, rng)
    opts = DirectOptions(likelihood="env", dpf=DPFOptions(n_iterations=2), process_std_m=1.5)
    res = run(meas, prior, rng, opts)
    assert res.estimates.shape == (T, 1, 2) and res.covariances.shape == (T, 1, 2, 2)
    err = np.linalg.norm(res.estimates[:, 0] - path, axis=1)
    assert np.all(err < 0.3)  # every snapshot, although the agent moves ~1.4 m per step
    assert res.diagnostics["ess_history"].shape == (T, 2, 1)
    assert res.timing.agent_iterations == T * 2
    assert np.all(np.isfinite(res.log_weights[np.isfinite(res.log_weights)]))


def test_covariance_floor_is_the_efim_crb(rng):
    """The floor is max(floor², tr(J⁻¹)/dim)·I with J = Σ ν e eᵀ (DiPNet eq. (17)), by hand."""
    pos, is_anchor, links = single_agent_setup()
    nu = np.array([0.5, 2.0, 1.0, 4.0])
    g = GaussianRangeLikelihood(
        np.full(4, 50.0), 1.0 / nu, np.ones(4, bool), links, agent_map(is_anchor), 1
    )
    e = (pos[0] - pos[1:]) / np.linalg.norm(pos[0] - pos[1:], axis=1)[:, None]
    J = sum(n * np.outer(u, u) for n, u in zip(nu, e, strict=True))
    crb = np.trace(np.linalg.inv(J)) / 2
    tiny = np.zeros((1, 2, 2))
    out = _floor(tiny, g, pos, np.array([0]), 1e-3)
    np.testing.assert_allclose(out[0], crb * np.eye(2), rtol=1e-12)
    out = _floor(tiny, g, pos, np.array([0]), 10.0)  # a floor above the CRB wins
    np.testing.assert_allclose(out[0], 100.0 * np.eye(2))
    big = np.array([np.diag([50.0, 60.0])])
    np.testing.assert_array_equal(_floor(big, g, pos, np.array([0]), 1e-3), big)


def test_covariance_floor_of_many_agents_matches_the_per_agent_efim(rng):
    """The floor of every agent at once against :func:`efim` / :func:`position_crb` agent by
    agent: random networks with an agent without links, one with a single link (singular J),
    a neighbour coincident with its agent, and covariances above and below the floor."""
    from phyloc.analysis.efim import efim, position_crb

    for dim in (2, 3):
        n_agents, n_nodes = 5, 9
        agent_nodes = np.arange(n_agents)
        centers = rng.uniform(0, 50, (n_nodes, dim))
        n_links = np.array([4, 0, 1, 6, 3])
        offsets = np.concatenate([[0], np.cumsum(n_links)])
        tx = np.concatenate([rng.choice(np.delete(np.arange(n_nodes), a), k, replace=False)
                             for a, k in enumerate(n_links)])  # fmt: skip
        centers[tx[offsets[3]]] = centers[3]  # coincident neighbour of agent 3
        nu = rng.uniform(0.1, 50.0, tx.size)
        lik = types.SimpleNamespace(csr=types.SimpleNamespace(offsets=offsets, tx=tx), nu=nu)
        A = rng.normal(0, 0.1, (n_agents, dim, dim))
        cov = A @ np.swapaxes(A, 1, 2)
        cov[4] = 9.0 * np.eye(dim)  # above every floor: unchanged
        out = _floor(cov, lik, centers, agent_nodes, 0.05)
        for a in range(n_agents):
            j0, j1 = offsets[a], offsets[a + 1]
            crb = 0.0
            if j1 > j0:
                crb = float(position_crb(efim(centers[a], centers[tx[j0:j1]], nu[j0:j1]))) / dim
            var = max(0.05**2, crb if np.isfinite(crb) else 0.0)
            low = np.linalg.eigvalsh(cov[a]).min()
            ref = cov[a] + (var - low) * np.eye(dim) if low < var else cov[a]
            np.testing.assert_allclose(out[a], ref, rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(out[4], cov[4])
        assert np.isfinite(out).all()


def test_outlier_floor_bounds_the_evidence_of_one_link(rng):
    """With outlier_nats = Δ a single link moves log-weights by at most γΔ (NLOS robustness)."""
    pos, is_anchor, links = single_agent_setup()
    tab = awgn_network(pos, is_anchor, links, rng, pc_snr_db=40.0).select([0])
    covs = np.zeros((5, 2, 2))
    covs[1] = 100.0 * np.eye(2)  # a neighbour known to 10 m: the smoothed peak is wide
    X = pos[1] + rng.uniform(-150, 150, (1, 4000, 2))
    for delta in (5.0, 10.0):
        lik = MarginalDirectLikelihood(tab, links[:1], agent_map(is_anchor), 1, outlier_nats=delta)
        ll = lik.loglik(X, pos, covs, gamma=0.5)
        # range = Δ + log(1 + e^{−Δ} + other peaks at the maximum), tiny for a one-path link
        assert ll.max() - ll.min() <= 0.5 * (delta + 0.05)
        assert ll.max() - ll.min() >= 0.5 * delta * 0.9  # and it is reached far from the peak
    plain = MarginalDirectLikelihood(tab, links[:1], agent_map(is_anchor), 1, outlier_nats=np.inf)
    ll = plain.loglik(X, pos, covs)
    assert ll.max() - ll.min() > 50.0  # unclipped: ~(140 m)²/(2·100 m²) ≈ 98 nats of pull


def test_next_lambda_kernel_matches_its_twin_and_keeps_the_ess():
    """Adaptive tempering (the safeguarded DPF's bridge): the kernel's step equals the NumPy
    twin's, keeps the ESS at the target, and covers −inf weights, NaN increments and agents
    already at λ = 1."""
    rng = np.random.default_rng(4)
    n, Q = 12, 500
    lw = np.log(rng.dirichlet(np.ones(Q), n))
    delta = rng.normal(0.0, 1.0, (n, Q)) * np.geomspace(0.1, 300.0, n)[:, None]
    lam = rng.uniform(0.0, 0.9, n)
    lam[0] = 1.0
    lw[1, :200] = -np.inf
    delta[2, :10] = np.nan
    lw[3] = -np.inf  # no finite weight: uniform
    target = 0.5 * Q
    out = np.empty(n)
    DK.next_lambda_kernel(lw, delta, lam, target, 30, out)
    ref = next_lambda_numpy(lw, delta, lam, target)
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-7)
    assert out[0] == 1.0 and np.all(out >= lam) and np.all(out <= 1.0)

    def ess(a, step):
        x = lw[a] + step * np.nan_to_num(delta[a], nan=-np.inf)
        w = np.exp(x - np.max(x))
        return w.sum() ** 2 / np.sum(w * w)

    bisected = 0
    for a in range(4, n):
        if out[a] < 1.0 and ess(a, 0.0) >= target:  # a bisected step: ESS at the target
            assert ess(a, out[a] - lam[a]) == pytest.approx(target, rel=1e-3)
            bisected += 1
    assert bisected >= 3


def test_mh_kernels_match_their_twins(rng):
    """Proposal and acceptance kernels of the resample-move sweep against their NumPy twins,
    with −inf targets at the proposal (rejected) and at the current particle (accepted)."""
    n, Q = 5, 300
    X = rng.normal(0, 3.0, (n, Q, 2)) * np.array([1.0, 0.2])
    X[4] = 7.0  # a collapsed cloud: the minimum step
    z = rng.standard_normal(X.shape)
    Xp = np.empty_like(X)
    K.mh_propose_kernel(X, z, 0.5, 1e-4, Xp)
    np.testing.assert_allclose(Xp, mh_propose_numpy(X, z, 0.5, 1e-4), rtol=1e-12, atol=1e-12)
    assert np.allclose(Xp[4] - 7.0, 1e-4 * z[4])
    lp, ll_old, ll_new, lpp, lop, lnp = rng.normal(0, 2.0, (6, n, Q))
    lpp[0, :50] = -np.inf
    lp[1, :50] = -np.inf
    lam = np.array([0.0, 0.3, 1.0, 0.7, 0.5])
    log_u = np.log(rng.random((n, Q)))
    ref, n_ref = mh_accept_numpy(X, lp, ll_old, ll_new, Xp, lpp, lop, lnp, lam, log_u)
    got = [a.copy() for a in (X, lp, ll_old, ll_new)]
    n_acc = K.mh_accept_kernel(*got, Xp, lpp, lop, lnp, lam, log_u)
    assert n_acc == n_ref and 0 < n_acc < n * Q
    for g, r in zip(got, ref, strict=True):
        np.testing.assert_array_equal(g, r)
    assert np.all(got[0][0, :50] == X[0, :50]) and np.all(got[0][1, :50] == Xp[1, :50])


def test_mh_moves_leave_the_bridge_target_invariant():
    """Exact samples of ``prior·exp(λ ll_new + (1 − λ) ll_old)`` stay samples of it after
    Metropolis–Hastings sweeps: 1-D Gaussians, prior N(0, 4), ll_new = N(x; 2, 1),
    ll_old = N(x; −2, 1). The agent at λ = 1 never evaluates the old likelihood; the agent
    at λ = 0.4 evaluates it on its own row only."""
    rng = np.random.default_rng(11)
    Q = 20000
    lam = np.array([1.0, 0.4])

    def logp(x):
        return -(x[..., 0] ** 2) / 8.0

    def new_fn(x):
        return -0.5 * (x[..., 0] - 2.0) ** 2

    calls = []

    def old_fn(x, agents=None):
        calls.append(None if agents is None else list(agents))
        return -0.5 * (x[..., 0] + 2.0) ** 2

    # the bridge is Gaussian: precision 1/4 + 1, mean (2λ − 2(1 − λ)) / (5/4)
    prec = 1.25
    mean = (2.0 * lam - 2.0 * (1.0 - lam)) / prec
    X = (mean[:, None] + rng.standard_normal((2, Q)) / np.sqrt(prec))[..., None]
    X2, lp, ll_old, ll_new = P.mh_moves(
        X, logp(X), old_fn(X), new_fn(X), lam, old_fn, new_fn, logp, rng,
        n_moves=6, move_scale=0.5,
    )  # fmt: skip
    assert calls[1:] == [[1]] * 6
    moved = np.mean(X2 != X, axis=1)[:, 0]
    assert np.all(moved > 0.5)  # the sweeps do move
    se_mean = 3.0 / np.sqrt(prec * Q) * 3  # ~3 σ, allowing for the chain's correlation
    np.testing.assert_allclose(X2[..., 0].mean(axis=1), mean, atol=se_mean)
    np.testing.assert_allclose(X2[..., 0].var(axis=1), 1.0 / prec, rtol=0.06)
    np.testing.assert_allclose(ll_new, new_fn(X2), rtol=1e-12)
    np.testing.assert_allclose(lp, logp(X2), rtol=1e-12)
    np.testing.assert_allclose(ll_old[1], old_fn(X2)[1], rtol=1e-12)


def test_translation_transport_reaches_a_far_target_and_stays_exact():
    """Translation transport (``DPFOptions.translate``): a cloud of the old target N(0, σ²)
    whose new target N(μ, σ²) lies 20 σ away is shifted onto it (ESS from ≈ 1 to > 0.9 Q),
    the importance weights are exact (ll_new − ll_old at the shifted particles equals the log
    ratio of the two densities there), and the returned old function is the shifted old
    target: ``lp + ll_old`` = log π_old(x − s) at the particles and elsewhere."""
    from phyloc.localization.direct.dpf import _translate

    rng = np.random.default_rng(5)
    Q, sig = 2000, 0.02
    mu = np.array([[0.4, 0.0], [0.0, 0.001]])  # agent 0: far; agent 1: already there

    def logp(x):  # a broad Gaussian prior
        return -0.5 * np.sum(x**2, axis=-1) / 25.0

    def old_fn(x, agents=None):
        return -0.5 * np.sum(x**2, axis=-1) / sig**2 + 0.5 * np.sum(x**2, axis=-1) / 25.0

    def new_fn(x, agents=None):
        m = mu if agents is None else mu[np.asarray(agents)]
        return -0.5 * np.sum((x - m[:, None]) ** 2, axis=-1) / sig**2

    X = sig * rng.standard_normal((2, Q, 2))
    lw = np.full((2, Q), -np.log(Q))
    lp, ll_old, ll_new = logp(X), old_fn(X), new_fn(X)
    ess0 = P.effective_sample_size(P.normalize_log_weights(lw + ll_new - ll_old)[0])
    assert ess0[0] < 5
    X2, lp2, lo2, ln2, shifted = _translate(X, lw, lp, ll_old, ll_new, old_fn, new_fn, logp, 3, Q)
    ess = P.effective_sample_size(P.normalize_log_weights(lw + ln2 - lo2)[0])
    assert ess[0] > 0.9 * Q and ess[1] >= ess0[1]
    s = (X2 - X)[:, 0]
    assert np.allclose(X2 - X, s[:, None]) and abs(s[0, 0] - 0.4) < 0.01
    np.testing.assert_allclose(lp2 + lo2, lp + ll_old, rtol=1e-10, atol=1e-8)
    np.testing.assert_allclose(ln2, new_fn(X2), rtol=1e-12)
    Y = X2 + 0.01 * rng.standard_normal(X2.shape)  # other points: the shifted old target
    back = Y - s[:, None]
    np.testing.assert_allclose(
        logp(Y) + shifted(Y), logp(back) + old_fn(back), rtol=1e-10, atol=1e-8
    )
    np.testing.assert_allclose(shifted(Y[[0]], [0]), shifted(Y)[[0]], rtol=1e-12)


def test_model_error_is_smoothing_like_a_known_neighbour_uncertainty(rng):
    """model_error_m = σ adds σ² to the smoothing: the same likelihood as a neighbour whose
    isotropic covariance σ²·I projects σ² on every link (DiPNet eq. (15)), tabulated or not."""
    from phyloc.errors import ValidationError

    pos, is_anchor, links = single_agent_setup()
    tab = awgn_network(pos, is_anchor, links, rng, pc_snr_db=30.0)
    amap = agent_map(is_anchor)
    X = pos[:1, None, :] + rng.normal(0, 2.0, (1, 300, 2))
    zero = np.zeros((5, 2, 2))
    iso = np.repeat(0.09 * np.eye(2)[None], 5, axis=0)
    a = MarginalDirectLikelihood(tab, links, amap, 1, model_error_m=0.3)
    b = MarginalDirectLikelihood(tab, links, amap, 1)
    np.testing.assert_allclose(a.loglik(X, pos, zero), b.loglik(X, pos, iso), rtol=1e-12)
    np.testing.assert_allclose(a.frozen(X, pos, zero)(X), b.frozen(X, pos, iso)(X), rtol=1e-12)
    with pytest.raises(ValidationError, match="model_error_m"):
        MarginalDirectLikelihood(tab, links, amap, 1, model_error_m=-0.1)
    with pytest.raises(ValidationError, match="model_error_m"):
        DirectOptions(model_error_m=-1.0)


def test_gaussian_outlier_bound_keeps_one_biased_certain_range_from_moving_the_maximum():
    """At high SNR a range's model variance vanishes (here 1 mm²) while an NLOS bias does not
    (here +20 m on one of four anchor links). The plain Gaussian of DiPNet §V-A puts its
    maximum where the biased link is met, metres off; with the outlier bound the biased link
    costs at most ``outlier_nats`` and the maximum is at the truth (brute-force grid)."""
    truth = np.array([37.0, 61.0])
    pos = np.vstack([[truth], ANCHORS])
    is_anchor = np.array([False, True, True, True, True])
    links = np.array([[0, j] for j in range(1, 5)])
    r = np.linalg.norm(ANCHORS - truth, axis=1)
    r[2] += 20.0
    var = np.full(4, 1e-6)
    centers, covs = pos, np.zeros((5, 2, 2))
    g = np.linspace(-40, 40, 1601)  # 5 cm grid around the truth
    X = (truth + np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2))[None]
    best = {}
    for f in (np.inf, 10.0):
        lik = GaussianRangeLikelihood(
            r, var, np.ones(4, bool), links, agent_map(is_anchor), 1, outlier_nats=f
        )
        ll = lik.loglik(X, centers, covs)[0]
        assert np.all(np.isfinite(ll))
        best[f] = np.linalg.norm(X[0, np.argmax(ll)] - truth)
        if np.isfinite(f):  # each link costs at most f nats below its peak
            assert ll.min() >= -4 * f - 1e-9
    assert best[np.inf] > 1.0
    assert best[10.0] < 0.05
    # model error widens every link: σ² = var + model_error_m² (the curvature at the peak)
    lik = GaussianRangeLikelihood(
        r, var, np.ones(4, bool), links, agent_map(is_anchor), 1, model_error_m=0.5
    )
    np.testing.assert_allclose(lik.var, 1e-6 + 0.25)

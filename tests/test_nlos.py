"""NLOS-aware pieces of the two-step and direct pipelines.

- the energy concentration of a link's correlation (NLOS identification from the waveform):
  closed forms for one path, ``n`` equal separated paths and noise only, and its behaviour at
  low SNR (only what the detection test sees counts);
- the one-sided outlier component of the Gaussian range likelihood (NLOS biases are positive);
- the one-sided robust start (a range shorter than the fitted distance keeps its pull);
- ``LinkMeasurements.usable``: leaving links out is the same as never having measured them.
"""

import math

import numpy as np
import pytest

from phyloc.errors import ValidationError
from phyloc.evaluation.metrics import framework_distance_errors
from phyloc.localization.direct import DirectOptions, LinkMeasurements, LinkRanges
from phyloc.localization.direct.likelihoods import GaussianRangeLikelihood
from phyloc.localization.direct.method import link_likelihood
from phyloc.localization.initialization import coarse_positions
from phyloc.phy import C0, OFDMSystem, PathSet
from phyloc.phy.correlation import correlation_tables
from phyloc.phy.synthesis import synthesize
from phyloc.phy.waveform import qpsk_symbols
from phyloc.ranging.nlos import check_min_concentration, energy_concentration, single_path_share

SYSTEM = OFDMSystem(n_subcarriers=257, subcarrier_spacing_hz=0.5e6)  # 128.5 MHz, 2.3 m cells


def _table(distances, snr_db, rng, beta=8.0):
    """One link with equal-power paths at ``distances`` [m], each at ``snr_db`` per subcarrier."""
    S = qpsk_symbols(SYSTEM, 1, rng)
    amp = math.sqrt(10 ** (snr_db / 10) * SYSTEM.noise_power_w)
    phases = np.exp(2j * np.pi * rng.random(len(distances)))
    paths = PathSet.from_lists([list(np.asarray(distances) / C0)], [list(amp * phases)])
    return correlation_tables(synthesize(paths, S, SYSTEM, rng), S, SYSTEM, beta=beta)


def test_single_path_share_is_one_over_beta_for_constant_modulus_pilots(rng):
    """QPSK pilots: ``‖S‖⁴/(L Σ|S|⁴) = N²/(L N) = N/L`` (Parseval on the pilots'
    autocorrelation)."""
    for beta in (4.0, 8.0):
        tab = _table([40.0], 30.0, rng, beta=beta)
        np.testing.assert_allclose(single_path_share(tab), SYSTEM.n_subcarriers / tab.n_fft)


@pytest.mark.parametrize("n_paths", [1, 2, 4])
def test_concentration_of_n_equal_separated_paths_is_one_over_n(rng, n_paths):
    """High SNR: κ = 1/n for n equal paths whose main lobes do not overlap (30 m apart, 13
    resolution cells); one path gives 1 up to the grid's scalloping."""
    d = 20.0 + 30.0 * np.arange(n_paths)
    kappa = energy_concentration(_table(d, 30.0, rng), window_m=(0.0, 200.0))
    assert kappa[0] == pytest.approx(1.0 / n_paths, rel=0.08)


def test_concentration_ignores_what_the_detection_test_cannot_see(rng):
    """A path 30 dB below the strongest, at a post-correlation SNR under the threshold, does
    not lower κ: at low SNR the feature never rejects what it cannot judge, and it falls only
    once the weaker path is visible."""
    S = qpsk_symbols(SYSTEM, 1, rng)
    out = {}
    for snr_db in (-12.0, 30.0):  # per subcarrier; +24 dB and +54 dB after 257 subcarriers
        a = math.sqrt(10 ** (snr_db / 10) * SYSTEM.noise_power_w)
        # the weaker path: 20 dB below the strongest, below the 12 dB threshold at low SNR
        paths = PathSet.from_lists([[30.0 / C0, 80.0 / C0]], [[a, 0.1j * a]])
        tab = correlation_tables(synthesize(paths, S, SYSTEM, rng), S, SYSTEM)
        out[snr_db] = float(energy_concentration(tab, window_m=(0.0, 200.0))[0])
    assert out[-12.0] > 0.9  # the weaker path is below the threshold: one path seen
    assert out[30.0] == pytest.approx(1 / 1.01, rel=0.05)  # both seen: 1/(1 + 0.01)


def test_concentration_of_noise_only_is_one_and_never_nan(rng):
    """Nothing above the threshold: κ = 1 (the detection test, not κ, rejects such links);
    with the threshold off every sample counts and κ is the (small) share of noise."""
    tab = _table([50.0], -200.0, rng)
    assert energy_concentration(tab)[0] == 1.0
    k0 = energy_concentration(tab, noise_factor=0)[0]
    assert np.isfinite(k0) and 0 < k0 < 0.5


def test_min_concentration_is_checked_by_key():
    assert check_min_concentration(0.6) == 0.6
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValidationError, match=r"localization\.los_min_concentration"):
            check_min_concentration(bad, "localization.los_min_concentration")


# -- one-sided Gaussian range likelihood ---------------------------------------------------------
ANCHORS = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 100.0], [100.0, 100.0]])


def _grid_loglik(r, var, f, one_sided, truth, half=20.0, n=401):
    pos = np.vstack([[truth], ANCHORS])
    links = np.array([[0, j] for j in range(1, 5)])
    agent_of = np.array([0, -1, -1, -1, -1])
    lik = GaussianRangeLikelihood(
        r, var, np.ones(4, bool), links, agent_of, 1, outlier_nats=f, one_sided=one_sided
    )
    g = np.linspace(-half, half, n)
    X = (truth + np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2))[None]
    return X[0], lik.loglik(X, pos, np.zeros((5, 2, 2)))[0]


def test_one_sided_bound_keeps_the_pull_where_the_distance_exceeds_a_range():
    """σ = 0.1 m, f = 10 nats: the symmetric bound is flat beyond √(2f)σ ≈ 0.45 m of every
    range (no pull from afar), the one-sided one still falls on every ray from the truth (on
    each ray some distance grows past its range); both peak at the truth, and a range biased
    *long* by 30 m (an NLOS range) costs the one-sided likelihood only the bound."""
    truth = np.array([37.0, 61.0])
    r = np.linalg.norm(ANCHORS - truth, axis=1)
    var = np.full(4, 0.01)
    for bias in (0.0, 30.0):
        rb = r + np.array([0.0, bias, 0.0, 0.0])
        X, sym = _grid_loglik(rb, var, 10.0, False, truth)
        _, one = _grid_loglik(rb, var, 10.0, True, truth)
        assert np.all(np.isfinite(sym)) and np.all(np.isfinite(one))
        for ll in (sym, one):
            assert np.linalg.norm(X[np.argmax(ll)] - truth) < 0.11  # the grid step is 0.1 m
        assert sym.min() >= -4 * 10.0 - 1e-9  # each link at most f below its peak
        for u in ([1.0, 0.0], [0.0, -1.0], [0.6, 0.8]):  # along rays: 5 m and 15 m out
            i5 = np.argmin(np.linalg.norm(X - truth - 5.0 * np.array(u), axis=1))
            i15 = np.argmin(np.linalg.norm(X - truth - 15.0 * np.array(u), axis=1))
            assert abs(sym[i5] - sym[i15]) < 2 * 10.0  # links at their bounds: little pull
            assert one[i5] - one[i15] > 100.0


def test_one_sided_flag_is_validated():
    with pytest.raises(ValidationError, match="one_sided"):
        GaussianRangeLikelihood(
            [1.0], [1.0], [True], [[0, 1]], np.array([0, -1]), 1, one_sided="yes"
        )


# -- one-sided robust start ----------------------------------------------------------------------
@pytest.mark.slow  # 16 draws x 2 fits with 10 restarts: ~1 min
def test_one_sided_start_recovers_networks_with_many_long_biased_ranges():
    """8 nodes, 30 % of the pairs biased long by Exp(90 m) (the NLOS bias of the C2 recipes),
    the rest within 0.3 m: the one-sided robust fit recovers clearly more networks (framework
    RMSE < 1 m) than the symmetric one, and its RMSE over the draws is lower."""
    rng = np.random.default_rng(0)
    n, draws = 8, 16
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    links = np.array(pairs + [(j, i) for i, j in pairs])
    ok, se = {False: 0, True: 0}, {False: [], True: []}
    for _ in range(draws):
        P = rng.uniform(0, 100, (n, 2))
        d = np.linalg.norm(P[links[:, 0]] - P[links[:, 1]], axis=1)
        bias = np.zeros(len(pairs))
        nlos = rng.choice(len(pairs), round(0.3 * len(pairs)), replace=False)
        bias[nlos] = rng.exponential(90.0, nlos.size)
        r = d + np.r_[bias, bias] + rng.normal(0, 0.3, len(links))
        for one in (False, True):
            sol = coarse_positions(
                links,
                r,
                n,
                2,
                combine="min",
                robust_scale_m=(5.0, 2.0, 1.0),
                n_restarts=10,
                rng=np.random.default_rng(1),
                one_sided=one,
            )
            e = framework_distance_errors(sol.positions, P, np.zeros(n, bool))
            ok[one] += bool(np.sqrt(np.mean(e**2)) < 1.0)
            se[one].append(np.mean(e**2))
    assert ok[True] >= ok[False] + 3
    assert np.mean(se[True]) < np.mean(se[False])


def test_one_sided_start_equals_the_symmetric_one_on_exact_ranges(rng):
    """No residual far from 0: the two costs agree to second order and both fits are exact."""
    P = rng.uniform(0, 50, (6, 2))
    links = np.array([(i, j) for i in range(6) for j in range(6) if i != j])
    r = np.linalg.norm(P[links[:, 0]] - P[links[:, 1]], axis=1)
    for one in (False, True):
        sol = coarse_positions(links, r, 6, 2, robust_scale_m=(5.0, 1.0), one_sided=one)
        e = framework_distance_errors(sol.positions, P, np.zeros(6, bool))
        assert np.max(np.abs(e)) < 1e-4


# -- usable links --------------------------------------------------------------------------------
def _measurements(rng, usable=None, keep=None):
    nodes = np.vstack([ANCHORS[:3] * 0.4, [[12.0, 17.0], [25.0, 9.0]]])
    links = np.array([(u, v) for u in (3, 4) for v in range(5) if v != u])
    d = np.linalg.norm(nodes[links[:, 0]] - nodes[links[:, 1]], axis=1)
    S = qpsk_symbols(SYSTEM, 5, rng)
    amp = math.sqrt(10 ** (3.0) * SYSTEM.noise_power_w)
    R = synthesize(PathSet.single_path(d / C0, amp), S, SYSTEM, rng, tx_index=links[:, 1])
    tab = correlation_tables(R, S, SYSTEM, tx_index=links[:, 1])
    r = d + rng.normal(0, 0.3, d.size)
    idx = np.arange(len(links)) if keep is None else np.flatnonzero(keep)
    return LinkMeasurements(
        n_nodes=5,
        dim=2,
        anchor_nodes=[0, 1, 2],
        anchor_positions=nodes[None, :3],
        links=[links[idx]],
        tables=[tab.select(idx)],
        ranges={"corr": LinkRanges.single(r[idx], np.full(idx.size, 0.09))},
        window_m=(0.0, 100.0),
        usable=None if usable is None else [usable],
    )


@pytest.mark.parametrize("likelihood", ["marginal", "gaussian"])
def test_unusable_links_are_as_if_never_measured(likelihood):
    """A likelihood with links marked unusable equals the one built without those links."""
    keep = np.array([1, 0, 1, 1, 0, 1, 1, 1], bool)
    masked = _measurements(np.random.default_rng(4), usable=keep)
    subset = _measurements(np.random.default_rng(4), keep=keep)
    opts = DirectOptions(likelihood=likelihood)
    X = np.random.default_rng(5).uniform(0, 40, (2, 300, 2))
    centers = np.vstack([ANCHORS[:3] * 0.4, [[10.0, 15.0], [27.0, 10.0]]])
    covs = np.repeat(np.eye(2)[None] * 4.0, 5, axis=0)
    a = link_likelihood(masked, 0, opts).loglik(X, centers, covs)
    b = link_likelihood(subset, 0, opts).loglik(X, centers, covs)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    full = link_likelihood(_measurements(np.random.default_rng(4)), 0, opts)
    assert not np.allclose(full.loglik(X, centers, covs), a)  # the mask does remove links


def test_usable_shape_is_checked(rng):
    with pytest.raises(ValidationError, match=r"usable\[0\]"):
        _measurements(rng, usable=np.ones(3, bool))

"""The regularization of PF-BP §VI, eqs. (32)–(33), and the "reg" variant of every tracker.

The paper regularizes every method it compares (Figs. 4, 6, 7: SIR-BP reg, SP-BP reg, EDH
reg, PF-BP reg): resampled particles are drawn from ``N(x, Σ_r)`` with the kernel of eq. (32),
``Σ_r = diag(0, σ²_r,vel, σ²_r,acc)`` per block, and the published covariance gets ``+ Σ_r``
(eq. (33)).
"""

import numpy as np
import pytest

from phyloc.localization import METHODS
from phyloc.localization.particles import regularize
from phyloc.localization.tracking import GaussianPrior, RangeMeasurements, RangeModel

CA3 = RangeModel("constant_acceleration", 3, dt_s=0.1, accel_std=0.15, sigma_r=0.1)


def test_regularization_kernel_is_eq_32():
    S = CA3.regularization_cov(0.15, 0.25)
    expected = np.diag([0.0] * 3 + [0.15**2] * 3 + [0.25**2] * 3)  # PF-BP eq. (32), 3-D CA
    np.testing.assert_array_equal(S, expected)
    cv2 = RangeModel("constant_velocity", 2).regularization_cov(0.15, 0.25)
    np.testing.assert_array_equal(cv2, np.diag([0.0, 0.0, 0.15**2, 0.15**2]))


def test_regularization_jitter_has_covariance_sigma_r():
    """``regularize`` adds ``N(0, Σ_r)``: zero on position, and a sample covariance that agrees
    with Σ_r within 5 standard errors entry by entry (M = 200 000 particles)."""
    S = CA3.regularization_cov(0.15, 0.25)
    M = 200_000
    X = np.tile(np.arange(9.0), (M, 1))
    J = regularize(X, S, np.random.default_rng(3)) - X
    assert np.all(J[:, :3] == 0.0)  # positions are not jittered
    C = np.cov(J, rowvar=False)
    sd = np.sqrt(np.diag(S))
    se = np.outer(sd, sd) / np.sqrt(M)  # of a sample covariance of independent coordinates
    se[np.diag_indices(9)] = sd**2 * np.sqrt(2.0 / (M - 1))  # of a sample variance
    z = np.abs(C - S)[3:, 3:] / se[3:, 3:]
    assert z.max() < 5.0, z
    # the kernel's mean is zero
    assert np.all(np.abs(J[:, 3:].mean(axis=0)) < 5 * sd[3:] / np.sqrt(M))


def _silent(model, n_agents=2, n_steps=1):
    """Agents with no measurement at all: the update is the prediction, plus regularization."""
    z = np.full((n_steps, n_agents, n_agents + 1), np.nan)
    anchors = np.zeros((1, model.dim))
    prior = GaussianPrior(
        np.zeros((n_agents, model.state_dim)), np.tile(np.eye(model.state_dim), (n_agents, 1, 1))
    )
    return RangeMeasurements(model, anchors, z), prior


@pytest.mark.parametrize("name", ["pfbp", "spbp", "edh"])
def test_reg_variant_adds_sigma_r_to_the_covariance(name):
    """Eq. (33): for an agent without measurements the reg variant's published covariance is
    the plain one plus Σ_r exactly (the same prediction, deterministic in the covariance)."""
    meas, prior = _silent(CA3)
    out = {}
    for variant in (name, name + "_reg"):
        m = METHODS[variant]
        opts = m.make_options({"n_particles": 50} if name != "spbp" else {})
        out[variant] = m.run(meas, prior, np.random.default_rng(0), opts).covariances
    assert METHODS[name + "_reg"].make_options().regularize
    assert not METHODS[name].make_options().regularize
    diff = out[name + "_reg"] - out[name]
    S = CA3.regularization_cov()
    np.testing.assert_allclose(diff, np.broadcast_to(S, diff.shape), atol=1e-12)


def test_sirbp_reg_jitters_resampled_particles_by_sigma_r():
    """SIR-BP reg: the published (sample) covariance of a silent agent grows by Σ_r, within the
    sampling error of M = 100 000 particles; positions are untouched."""
    meas, prior = _silent(CA3, n_agents=1)
    res = {}
    for variant in ("sirbp", "sirbp_reg"):
        m = METHODS[variant]
        opts = m.make_options({"n_particles": 100_000, "n_iterations": 1})
        res[variant] = m.run(meas, prior, np.random.default_rng(5), opts)
    P = res["sirbp"].covariances[0, 0]
    diff = res["sirbp_reg"].covariances[0, 0] - P
    S = CA3.regularization_cov()
    np.testing.assert_allclose(diff[:3, :3], 0.0, atol=1e-12)
    # the same predicted particles X plus the jitter J: cov(X + J) − cov(X) = cov(J) + the two
    # cross covariances, each with standard error ≈ std_i·std_j/√M
    sx, sj, M = np.sqrt(np.diag(P)), np.sqrt(np.diag(S)), 100_000
    se = (np.outer(sx, sj) + np.outer(sj, sx) + np.outer(sj, sj) * np.sqrt(2)) / np.sqrt(M)
    z = np.abs(diff - S)[3:, 3:] / se[3:, 3:]
    assert z.max() < 5.0, z


def test_every_reg_variant_is_registered_in_the_tracking_family():
    for name in ("pfbp", "sirbp", "spbp", "edh"):
        reg = METHODS[name + "_reg"]
        assert reg.family == "tracking"
        assert reg.run is METHODS[name].run
        assert reg.label.endswith(" reg")

"""Centralized exact Daum–Huang (EDH) particle-flow filter on the joint state (PF-BP App. B).

The joint state stacks all agents, ``x = [x_1; …; x_|C|]`` (``|C|·N_D`` components). Per time
step: predict the particles by eq. (1) and the covariance by eqs. (45)–(48); flow all particles
with the exact drift of eqs. (13), (40), (41), linearized at the flowing mean, over exponentially
spaced λ-steps (eqs. (42), (43)), using every range of the time step (centralized factors: both
``z_ij`` and ``z_ji``); weight by the invertible flow (eq. (44)); resample systematically; update
the covariance by a UKF at the posterior mean (eq. (49)). The prior-density ratio of eq. (44)
uses the Gaussian ``N(x̄^{(k|k−1)}, P^{(k|k−1)})`` (the transition density is singular for CV/CA),
as in :mod:`phyloc.localization.tracking.pfbp`.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.linalg import block_diag

from phyloc.localization.tracking import _flow
from phyloc.localization.tracking.pfbp import (
    PFBPOptions,
    regularize,
    resample_permute,
    run_flow,
    stacked_loglik,
)
from phyloc.localization.tracking.range_models import (
    RangeScenario,
    TrackResult,
    all_measurements,
    check_prior,
    check_run_args,
    flow_links,
    sample_gaussian,
)


def run_edh(
    scenario: RangeScenario,
    prior_mean: np.ndarray,
    prior_cov: np.ndarray,
    rng: np.random.Generator,
    options: PFBPOptions | None = None,
) -> TrackResult:
    """Track all agents jointly with the particle-based EDH filter (PF-BP Appendix B).

    Parameters
    ----------
    scenario : RangeScenario
    prior_mean : [n_agents, N_D] float64
    prior_cov : [n_agents, N_D, N_D] float64
        Independent Gaussian priors per agent (block-diagonal joint prior).
    rng : numpy.random.Generator
    options : PFBPOptions, optional
        ``n_particles`` (joint particles), ``n_lambda``, ``lambda_ratio``, ``regularize``,
        ``reg_std_*``, ``backend``; ``n_iterations`` and ``factors`` are not used.

    Returns
    -------
    TrackResult
        Per-agent blocks of the joint mean and covariance; ``agent_s`` is NaN (the EDH filter
        has no distributed form).
    """
    opt = check_run_args(options, PFBPOptions, rng)
    mean0, cov0 = check_prior(scenario, prior_mean, prior_cov)
    model = scenario.model
    dim, nd, n_ag, M, K = (
        model.dim,
        model.state_dim,
        scenario.n_agents,
        opt.n_particles,
        scenario.n_steps,
    )
    N = n_ag * nd
    lambdas, steps = _flow.lambda_schedule(opt.n_lambda, opt.lambda_ratio)
    var = model.sigma_r**2
    F, Q = model.matrices()
    Ft = np.kron(np.eye(n_ag), F)  # eq. (46)
    W = np.kron(np.eye(n_ag), Q)  # eq. (47)
    Sr = None
    if opt.regularize:
        Sr = np.kron(np.eye(n_ag), model.regularization_cov(opt.reg_std_vel, opt.reg_std_acc))
    local = np.arange(n_ag, dtype=np.int64)

    X = sample_gaussian(mean0, cov0, M, rng).transpose(1, 0, 2).reshape(M, N)
    P = block_diag(*cov0)
    out_mean = np.empty((K, n_ag, nd))
    out_cov = np.empty((K, n_ag, nd, nd))
    step_s = np.empty(K)
    for k in range(K):
        t0 = time.perf_counter()
        X0 = model.predict_particles(X.reshape(M, n_ag, nd), rng).reshape(M, N)
        P_pred = Ft @ P @ Ft.T + W  # eq. (45)
        rx, tx, zz = all_measurements(scenario.z[k])
        if zz.size == 0:
            X, P = X0, P_pred
        else:
            off_a, off_b, apos, zz = flow_links(rx, tx, zz, local, n_ag, scenario.anchors, dim, nd)
            r_var = np.full(zz.size, var)
            x_bar = X0.mean(axis=0)
            X1, _ = run_flow(
                X0,
                x_bar,
                P_pred,
                off_a,
                off_b,
                apos,
                zz,
                r_var,
                dim,
                N,
                lambdas,
                steps,
                opt.backend,
            )  # eqs. (42), (43)
            ll = stacked_loglik(X1, off_a, off_b, apos, zz, 1.0 / var, dim)
            lw = _flow.invertible_flow_log_weights(X0, X1, x_bar, P_pred, ll)  # eq. (44)
            X = resample_permute(X1, lw, rng)
            P = _flow.ukf_covariance_update(
                X.mean(axis=0), P_pred, off_a, off_b, apos, r_var, dim, N
            )  # eq. (49)
        if Sr is not None:
            X = regularize(X, Sr, rng)
            P = P + Sr
        out_mean[k] = X.mean(axis=0).reshape(n_ag, nd)
        for i in range(n_ag):
            out_cov[k, i] = P[i * nd : (i + 1) * nd, i * nd : (i + 1) * nd]
        step_s[k] = time.perf_counter() - t0
    return TrackResult(out_mean, out_cov, step_s, np.full(K, np.nan), label="edh")

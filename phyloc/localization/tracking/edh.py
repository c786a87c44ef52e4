"""Centralized exact Daum–Huang (EDH) particle-flow filter on the joint state (PF-BP App. B).

The joint state stacks all agents, ``x = [x_1; …; x_|C|]`` (``|C|·N_D`` components). Per time
step: predict the particles by PF-BP eq. (1) and the covariance by PF-BP eqs. (45)–(48); flow
all particles with the exact drift of PF-BP eqs. (13), (40), (41), linearized at the flowing
mean, over exponentially spaced λ-steps (PF-BP eqs. (42), (43)), using every range of the time
step (centralized factors: both ``z_ij`` and ``z_ji``); weight by the invertible flow (PF-BP
eq. (44)); resample systematically; update the covariance by a UKF at the posterior mean
(PF-BP eq. (49)). The prior-density ratio of PF-BP eq. (44) uses the Gaussian
``N(x̄^{(k|k−1)}, P^{(k|k−1)})`` (the transition density is singular for CV/CA), as in
:mod:`phyloc.localization.tracking.pfbp`.

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow" (Appendix B).
"""

from __future__ import annotations

import time

import numpy as np
from scipy.linalg import block_diag

from phyloc.localization.particles import regularize, resample_permute
from phyloc.localization.results import Result, Timing
from phyloc.localization.tracking import _flow
from phyloc.localization.tracking.pfbp import PFBPOptions
from phyloc.localization.tracking.range_models import (
    GaussianPrior,
    RangeMeasurements,
    all_measurements,
    check_inputs,
    check_run_args,
    flow_links,
    message_floats,
    sample_gaussian,
)


def run_edh(
    measurements: RangeMeasurements,
    prior: GaussianPrior,
    rng: np.random.Generator,
    options: PFBPOptions | None = None,
) -> Result:
    """Track all agents jointly with the particle-based EDH filter (PF-BP Appendix B).

    Registered as ``edh``.

    Parameters
    ----------
    measurements : RangeMeasurements
    prior : GaussianPrior
        Independent Gaussian priors per agent (block-diagonal joint prior).
    rng : numpy.random.Generator
    options : PFBPOptions, optional
        ``n_particles`` (joint particles), ``n_lambda``, ``lambda_ratio``, ``regularize``,
        ``reg_std_*``; ``n_iterations`` and ``factors`` are not used.

    Returns
    -------
    Result
        Per-agent blocks of the joint mean and covariance; ``particles [n_agents, M, N_D]``
        (the joint particles split by agent) with uniform ``log_weights``; ``timing.agent_s`` is
        NaN (the EDH filter has no distributed form), ``agent_iterations = K · n_agents``.

    Examples
    --------
    >>> from phyloc.localization.tracking import GaussianPrior, RangeMeasurements, RangeModel
    >>> z = np.full((2, 1, 4), np.nan)
    >>> z[:, 0, 1:] = [5.0, 5.0, 5.0]
    >>> anchors = np.array([[0.0, 0.0], [8.0, 0.0], [0.0, 8.0]])
    >>> meas = RangeMeasurements(RangeModel("static", 2), anchors, z)
    >>> prior = GaussianPrior(np.array([[3.0, 3.0]]), np.eye(2)[None] * 4.0)
    >>> res = run_edh(meas, prior, np.random.default_rng(0), PFBPOptions(n_particles=100))
    >>> res.estimates.shape, bool(np.isnan(res.timing.agent_s).all())
    ((2, 1, 2), True)
    """
    t_start = time.perf_counter()
    opt = check_run_args(options, PFBPOptions, rng)
    mean0, cov0 = check_inputs(measurements, prior)
    model = measurements.model
    dim, nd, n_ag, M, K = (
        model.dim,
        model.state_dim,
        measurements.n_agents,
        opt.n_particles,
        measurements.n_steps,
    )
    N = n_ag * nd
    lambdas, steps = _flow.lambda_schedule(opt.n_lambda, opt.lambda_ratio)
    var = model.sigma_r**2
    F, Q = model.matrices()
    Ft = np.kron(np.eye(n_ag), F)  # PF-BP eq. (46)
    W = np.kron(np.eye(n_ag), Q)  # PF-BP eq. (47)
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
        anchors = measurements.anchors_at(k)
        t0 = time.perf_counter()
        X0 = model.predict_particles(X.reshape(M, n_ag, nd), rng).reshape(M, N)
        P_pred = Ft @ P @ Ft.T + W  # PF-BP eq. (45)
        rx, tx, zz = all_measurements(measurements.z[k])
        if zz.size == 0:
            X, P = X0, P_pred
        else:
            off_a, off_b, apos, zz = flow_links(rx, tx, zz, local, n_ag, anchors, dim, nd)
            r_var = np.full(zz.size, var)
            x_bar = X0.mean(axis=0)
            # PF-BP eqs. (42), (43)
            X1, _ = _flow.run_flow(
                X0, x_bar, P_pred, off_a, off_b, apos, zz, r_var, dim, N, lambdas, steps
            )
            ll = _flow.stacked_loglik(X1, off_a, off_b, apos, zz, 1.0 / var, dim)
            lw = _flow.invertible_flow_log_weights(X0, X1, x_bar, P_pred, ll)  # PF-BP eq. (44)
            X = resample_permute(X1, lw, rng)
            P = _flow.ukf_covariance_update(
                X.mean(axis=0), P_pred, off_a, off_b, apos, r_var, dim, N
            )  # PF-BP eq. (49)
        if Sr is not None:
            X = regularize(X, Sr, rng)
            P = P + Sr
        out_mean[k] = X.mean(axis=0).reshape(n_ag, nd)
        for i in range(n_ag):
            out_cov[k, i] = P[i * nd : (i + 1) * nd, i * nd : (i + 1) * nd]
        step_s[k] = time.perf_counter() - t0
    timing = Timing(time.perf_counter() - t_start, step_s, np.full(K, np.nan), K * n_ag)
    return Result(
        out_mean,
        out_cov,
        timing,
        particles=np.ascontiguousarray(X.reshape(M, n_ag, nd).transpose(1, 0, 2)),
        log_weights=np.full((n_ag, M), -np.log(M)),
        diagnostics={"floats_per_link_iteration": message_floats("none", nd)},  # centralized
        label="edh",
    )

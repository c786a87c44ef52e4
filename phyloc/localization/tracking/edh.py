"""Centralized exact Daum–Huang (EDH) particle-flow filter on the joint state (PF-BP App. B).

The joint state stacks all agents, ``x = [x_1; …; x_|C|]`` (``|C|·N_D`` components). Per time
step: predict the particles by PF-BP eq. (1) and the covariance by PF-BP eqs. (45)–(48); flow
all particles with the exact drift of PF-BP eqs. (13), (40), (41), linearized at the flowing
mean, over exponentially spaced λ-steps (PF-BP eqs. (42), (43)), using every range of the time
step (centralized factors: both ``z_ij`` and ``z_ji``); weight by the invertible flow (PF-BP
eq. (44)); resample systematically; update the covariance by a UKF at the posterior mean
(PF-BP eq. (49)). The prior-density ratio of PF-BP eq. (44) uses the Gaussian
``N(x̄^{(k|k−1)}, P^{(k|k−1)})`` (the transition density is singular for CV/CA), as in
:mod:`phyloc.localization.tracking.pfbp`. The prediction and the bookkeeping are the family's
loop (:func:`~phyloc.localization.tracking.loop.track`, with a joint belief); this module
supplies :class:`EDHUpdate`.

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
(Appendix B.)
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import block_diag

from phyloc.localization.particles import regularize, resample_permute
from phyloc.localization.results import Result
from phyloc.localization.tracking import _flow
from phyloc.localization.tracking.loop import (
    Belief,
    Update,
    check_inputs,
    check_run_args,
    message_floats,
    track,
)
from phyloc.localization.tracking.measurements import RangeMeasurements, all_measurements
from phyloc.localization.tracking.pfbp import PFBPOptions
from phyloc.localization.tracking.priors import GaussianPrior, sample_gaussian


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
    opt = check_run_args(options, PFBPOptions, rng)
    check_inputs(measurements, prior)
    return track(measurements, prior, rng, EDHUpdate(measurements.model, opt))


class EDHUpdate(Update):
    """One time step of the EDH filter for :func:`~phyloc.localization.tracking.loop.track`:
    ``M`` particles of the joint state (``[M, n_agents, N_D]``) and its joint covariance, one
    centralized update by every range of the step (no message passing).

    Parameters
    ----------
    model : RangeModel
    options : PFBPOptions
    """

    label = "edh"
    distributed = False
    #: One joint update per step: ``agent_iterations = K · n_agents``.
    iterations = 1

    def __init__(self, model, options: PFBPOptions):
        super().__init__(model, options)
        self._lambdas, self._steps = _flow.lambda_schedule(options.n_lambda, options.lambda_ratio)
        self._var = model.sigma_r**2
        self._Sr = None
        if options.regularize:  # PF-BP eq. (32), per agent
            self._Sr = model.regularization_cov(options.reg_std_vel, options.reg_std_acc)

    def initial(self, mean0, cov0, rng) -> Belief:
        """Joint particles from the independent priors; the block-diagonal joint covariance."""
        X = sample_gaussian(mean0, cov0, self.options.n_particles, rng)
        return Belief(
            particles=np.ascontiguousarray(X.transpose(1, 0, 2)), cov=block_diag(*cov0), joint=True
        )

    def update(self, pred, z_k, anchors_k, rng) -> Belief:
        """Flow the predicted joint particles (PF-BP eq. (1)) from the predicted covariance
        (PF-BP eq. (45)) by every range of the step; weight, resample, UKF covariance."""
        model, clock = self.model, self.clock
        dim, nd = model.dim, model.state_dim
        M, n_ag, _ = pred.particles.shape
        N = n_ag * nd
        X0, P_pred = pred.particles.reshape(M, N), pred.cov
        rx, tx, zz = all_measurements(z_k)
        if zz.size == 0:
            X, P = X0, P_pred
        else:
            local = np.arange(n_ag, dtype=np.int64)
            off_a, off_b, apos, zz = _flow.flow_links(rx, tx, zz, local, n_ag, anchors_k, dim, nd)
            r_var = np.full(zz.size, self._var)
            x_bar = X0.mean(axis=0)
            with clock("flow"):
                X1, _ = _flow.run_flow(  # PF-BP eqs. (42), (43)
                    X0, x_bar, P_pred, off_a, off_b, apos, zz, r_var, dim, N,
                    self._lambdas, self._steps,
                )  # fmt: skip
            with clock("weights"):  # PF-BP eq. (44)
                ll = _flow.stacked_loglik(X1, off_a, off_b, apos, zz, 1.0 / self._var, dim)
                lw = _flow.invertible_flow_log_weights(X0, X1, x_bar, P_pred, ll)
            with clock("resample"):
                X = resample_permute(X1, lw, rng)
            with clock("covariance"):  # PF-BP eq. (49)
                P = _flow.ukf_covariance_update(
                    X.mean(axis=0), P_pred, off_a, off_b, apos, r_var, dim, N
                )
        if self._Sr is not None:
            with clock("regularize"):
                Sr = np.kron(np.eye(n_ag), self._Sr)
                X = regularize(X, Sr, rng)
                P = P + Sr
        return Belief(particles=X.reshape(M, n_ag, nd), cov=P, joint=True)

    def estimate(self, belief):
        """The per-agent blocks of the joint sample mean and covariance."""
        M, n_ag, nd = belief.particles.shape
        mean = belief.particles.reshape(M, n_ag * nd).mean(axis=0).reshape(n_ag, nd)
        cov = np.empty((n_ag, nd, nd))
        for i in range(n_ag):
            cov[i] = belief.cov[i * nd : (i + 1) * nd, i * nd : (i + 1) * nd]
        return mean, cov

    def floats_per_link_iteration(self) -> float:
        """None: a centralized filter exchanges no beliefs (NaN)."""
        return message_floats("none", self.model.state_dim)

"""Particle-flow belief propagation (PF-BP), PF-BP Algorithm 1.

Every agent ``i`` holds ``M`` equally weighted particles and a covariance ``P_i``. Per time step:

1. predict the particles by the motion model (PF-BP eq. (1)) and the covariance by PF-BP
   eq. (29) (PF-BP Algorithm 1, line 7); the sample mean is ``x̄_{λ=0,i}`` (line 8);
2. for ``u = 1 … U`` message-passing iterations, all beliefs in parallel (lines 10–18): stack the
   agent's predicted particles with the neighbours' belief particles of iteration ``u − 1`` into
   β (PF-BP eq. (21), extrinsic information approximated by beliefs), with block-diagonal
   covariance ``P̃_i`` (PF-BP eq. (28)); flow the agent's components over the exponentially
   spaced λ-steps with the exact Daum–Huang drift of the stacked state (PF-BP eqs. (23)–(27));
   weight by the invertible flow (PF-BP eq. (22)); resample systematically; the covariance by
   the UKF update (PF-BP eq. (30)) at the resampled mean; optionally regularize (PF-BP
   eqs. (32), (33));
3. the estimate is the sample mean (PF-BP eq. (20), line 20).

Steps 1 and 3 and the bookkeeping are the family's loop
(:func:`~phyloc.localization.tracking.loop.track`); this module supplies
:class:`PFBPUpdate`, step 2.

Implementation notes (deviations are marked):

- The prior-density ratio of PF-BP eq. (22) uses the Gaussian ``N(x̄_{λ=0,i}, P_i^{(k|k−1)})``
  the flow was derived for: the transition density of PF-BP eq. (22) is singular for CV/CA
  (rank-``dim`` Q).
- Neighbour ``j``'s particle ``m`` is paired with agent ``i``'s particle ``m`` (PF-BP eq. (22));
  resampled particles are randomly permuted so that pairs are independent draws (systematic
  resampling returns them sorted by ancestor).
- Measurements: ``factors="distributed"`` uses agent ``i``'s own ranges (PF-BP eq. (17));
  ``"centralized"`` also the neighbours' ranges to ``i`` (PF-BP eq. (18)).
- An agent without measurements keeps its predicted particles and covariance.

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag

from phyloc import _validate as v
from phyloc._validate import from_table
from phyloc.errors import ValidationError
from phyloc.localization.particles import regularize, resample_permute
from phyloc.localization.results import Result
from phyloc.localization.tracking import _flow
from phyloc.localization.tracking.loop import (
    Belief,
    Tracker,
    Update,
    check_inputs,
    check_run_args,
    message_floats,
    message_passing,
    track,
)
from phyloc.localization.tracking.measurements import (
    FACTORS,
    RangeMeasurements,
    agent_measurements,
)
from phyloc.localization.tracking.priors import GaussianPrior, sample_gaussian

EXCHANGES = ("particles", "gaussian")


@dataclass(frozen=True)
class PFBPOptions:
    """Options of PF-BP and of the EDH filter (defaults: PF-BP §VI).

    Parameters
    ----------
    n_particles : int
        M per agent (200).
    n_lambda : int
        Pseudo-time steps N_λ (20).
    lambda_ratio : float
        Ratio of consecutive λ-steps, >= 1 (1.2; 1 is uniform spacing).
    n_iterations : int
        Message-passing iterations U (2).
    factors : {"distributed", "centralized"}
        PF-BP §V-A.
    regularize : bool
        Regularization kernel of PF-BP eqs. (32), (33) (off; on for ``pfbp_reg``).
    reg_std_vel, reg_std_acc : float
        σ_r,vel [m/s], σ_r,acc [m/s²] of PF-BP eq. (32) (0.15).
    exchange : {"particles", "gaussian"}
        What a PF-BP agent takes from a neighbour's belief at each message-passing iteration:
        its particles and covariance (``"particles"``, default), or — as PF-BP §VI describes
        the communication — only its mean and covariance, from which the agent draws the
        neighbour's particles locally (``"gaussian"``). EDH (centralized) ignores it.
    """

    n_particles: int = 200
    n_lambda: int = 20
    lambda_ratio: float = 1.2
    n_iterations: int = 2
    factors: str = "distributed"
    regularize: bool = False
    reg_std_vel: float = 0.15
    reg_std_acc: float = 0.15
    exchange: str = "particles"

    def __post_init__(self):
        for name, lo in (("n_particles", 2), ("n_lambda", 1), ("n_iterations", 1)):
            object.__setattr__(self, name, v.integer(name, getattr(self, name), minimum=lo))
        ratio = v.positive("lambda_ratio", self.lambda_ratio)
        if ratio < 1.0:
            raise ValidationError("lambda_ratio", ratio, "must be >= 1 (growing λ-steps)")
        object.__setattr__(self, "lambda_ratio", ratio)
        if self.factors not in FACTORS:
            raise ValidationError("factors", self.factors, f"must be one of {FACTORS}")
        if self.exchange not in EXCHANGES:
            raise ValidationError("exchange", self.exchange, f"must be one of {EXCHANGES}")
        for name in ("reg_std_vel", "reg_std_acc"):
            object.__setattr__(self, name, v.positive(name, getattr(self, name), allow_zero=True))

    @classmethod
    def from_dict(cls, d: dict, section: str = "localization") -> PFBPOptions:
        """Build from a recipe table; unknown keys are errors naming the closest valid key."""
        return from_table(cls, d, section)


def run_pfbp(
    measurements: RangeMeasurements,
    prior: GaussianPrior,
    rng: np.random.Generator,
    options: PFBPOptions | None = None,
) -> Result:
    """Track all agents with PF-BP (PF-BP Algorithm 1); registered as ``pfbp``, ``pfbp_reg``.

    Parameters
    ----------
    measurements : RangeMeasurements
        Ranges ``z [K, n_agents, n_agents + n_anchors]``, anchors, model (no truth).
    prior : GaussianPrior
        ``x̄_i^{(0)}``, ``P_i^{(0)}`` (e.g. :func:`~phyloc.localization.tracking.paper_prior`,
        PF-BP eq. (31)).
    rng : numpy.random.Generator
    options : PFBPOptions, optional

    Returns
    -------
    Result
        ``estimates [K, n_agents, N_D]`` (sample means, PF-BP eq. (20)), ``covariances``
        (UKF, PF-BP eq. (30)), the final ``particles [n_agents, M, N_D]`` with uniform
        ``log_weights``; ``timing.step_s`` per time step, ``agent_s = step_s / n_agents``,
        ``agent_iterations = K · U · n_agents``; ``diagnostics["floats_per_link_iteration"]``,
        what one agent sends a neighbour per message-passing iteration
        (:func:`~phyloc.localization.tracking.loop.message_floats`: particles and
        covariance, or mean and covariance with ``exchange = "gaussian"``).

    Examples
    --------
    >>> from phyloc.localization.tracking import GaussianPrior, RangeMeasurements, RangeModel
    >>> z = np.full((2, 1, 4), np.nan)
    >>> z[:, 0, 1:] = [5.0, 5.0, 5.0]
    >>> anchors = np.array([[0.0, 0.0], [8.0, 0.0], [0.0, 8.0]])
    >>> meas = RangeMeasurements(RangeModel("static", 2), anchors, z)
    >>> prior = GaussianPrior(np.array([[3.0, 3.0]]), np.eye(2)[None] * 4.0)
    >>> res = run_pfbp(meas, prior, np.random.default_rng(0), PFBPOptions(n_particles=100))
    >>> res.estimates.shape, res.particles.shape
    ((2, 1, 2), (1, 100, 2))
    """
    opt = check_run_args(options, PFBPOptions, rng)
    check_inputs(measurements, prior)
    return track(measurements, prior, rng, PFBPUpdate(measurements.model, opt))


class PFBPUpdate(Update):
    """One time step of PF-BP for :func:`~phyloc.localization.tracking.loop.track`: particles
    and a UKF covariance per agent, ``U`` iterations of PF-BP Algorithm 1, lines 10–18.

    Parameters
    ----------
    model : RangeModel
    options : PFBPOptions
    """

    label = "pfbp"

    def __init__(self, model, options: PFBPOptions):
        super().__init__(model, options)
        self._lambdas, self._steps = _flow.lambda_schedule(options.n_lambda, options.lambda_ratio)
        self._var = model.sigma_r**2
        self._Sr = None
        if options.regularize:  # PF-BP eq. (32)
            self._Sr = model.regularization_cov(options.reg_std_vel, options.reg_std_acc)

    def initial(self, mean0, cov0, rng) -> Belief:
        """Particles drawn from the prior (PF-BP Algorithm 1, lines 1–4) and its covariance."""
        return Belief(
            particles=sample_gaussian(mean0, cov0, self.options.n_particles, rng), cov=cov0
        )

    def update(self, pred, z_k, anchors_k, rng) -> Belief:
        """Lines 10–18: all agents in parallel from the predicted particles ``pred.particles``
        (line 7, PF-BP eq. (1)) and covariances ``pred.cov`` (PF-BP eq. (29))."""
        X0, P_pred = pred.particles, pred.cov

        def share(_u, chi, P_bel):
            # what each agent broadcasts: its belief's particles, or only its mean (+ P_bel);
            # each broadcast belief's Cholesky factor once, not once per receiving agent
            if self.options.exchange != "gaussian":
                return None
            with self.clock("sample"):
                return chi.mean(axis=1), np.stack([_flow.robust_cholesky(c) for c in P_bel])

        def agent(i, chi, P_bel, means):
            return self._agent_update(i, z_k, anchors_k, X0, P_pred, chi, P_bel, rng, means)

        chi, P_bel = message_passing(self.options.n_iterations, (X0, P_pred), agent, share)
        return Belief(particles=chi, cov=P_bel)

    def estimate(self, belief):
        """Sample means (PF-BP eq. (20), line 20) and the UKF covariances."""
        return belief.particles.mean(axis=1), belief.cov.copy()

    def floats_per_link_iteration(self) -> float:
        """What a PF-BP agent sends a neighbour per iteration (PF-BP §VI; ``exchange``)."""
        if self.options.exchange == "gaussian":
            return message_floats("gaussian", self.model.state_dim)
        return message_floats("particles+cov", self.model.state_dim, self.options.n_particles)

    def _agent_update(self, i, z_k, anchors_k, X0, P_pred, chi, P_bel, rng, means):
        """One belief update of agent ``i`` (PF-BP Algorithm 1, lines 12–16). With ``means`` =
        (mean, Cholesky factor of ``P_bel``) per agent (``exchange = "gaussian"``) the
        neighbours' particles are drawn here from ``N(mean_j, P_bel[j])``: ``chi[j]`` itself is
        not read."""
        model, opt, var, Sr, clock = self.model, self.options, self._var, self._Sr, self.clock
        dim, nd, n_ag = model.dim, model.state_dim, X0.shape[0]
        rx, tx, zz, partners = agent_measurements(z_k, i, opt.factors)
        if zz.size == 0:
            xi, Pi = X0[i], P_pred[i]
        else:
            local = np.full(n_ag, -1, dtype=np.int64)
            local[i] = 0
            local[partners] = np.arange(1, partners.size + 1)
            off_a, off_b, apos, zz = _flow.flow_links(rx, tx, zz, local, n_ag, anchors_k, dim, nd)
            if means is None or partners.size == 0:
                nb = [chi[j] for j in partners]
            else:  # PF-BP §VI: sample the neighbours' Gaussian beliefs locally
                with clock("sample"):
                    mu, L = means[0][partners], means[1][partners]
                    w = rng.standard_normal((partners.size, X0.shape[1], nd))
                    nb = list(mu[:, None, :] + np.einsum("aij,anj->ani", L, w))
            beta = np.concatenate([X0[i], *nb], axis=1)  # PF-BP eq. (21)
            P_t = block_diag(P_pred[i], *[P_bel[j] for j in partners])  # PF-BP eq. (28)
            beta_bar = beta.mean(axis=0)
            r_var = np.full(zz.size, var)
            with clock("flow"):
                B1, _ = _flow.run_flow(  # PF-BP eqs. (21), (23)–(27)
                    beta, beta_bar, P_t, off_a, off_b, apos, zz, r_var, dim, nd,
                    self._lambdas, self._steps,
                )  # fmt: skip
            with clock("weights"):
                ll = _flow.stacked_loglik(B1, off_a, off_b, apos, zz, 1.0 / var, dim)
                lw = _flow.invertible_flow_log_weights(
                    X0[i], B1[:, :nd], beta_bar[:nd], P_pred[i], ll
                )
            with clock("resample"):
                xi = resample_permute(B1[:, :nd], lw, rng)  # PF-BP eq. (22), line 13
            with clock("covariance"):  # PF-BP eq. (30)
                at = np.concatenate([xi.mean(axis=0), beta_bar[nd:]])
                Pi = _flow.ukf_covariance_update(at, P_t, off_a, off_b, apos, r_var, dim, nd)
        if Sr is not None:  # PF-BP eq. (33), line 16
            with clock("regularize"):
                xi = regularize(xi, Sr, rng)
                Pi = Pi + Sr
        return xi, Pi


class PFBPTracker(Tracker):
    """PF-BP one time step at a time (:class:`~phyloc.localization.tracking.loop.Tracker` with
    :class:`PFBPUpdate`), for a closed loop whose next measurements depend on the current
    beliefs (e.g. anchors steered by :mod:`phyloc.control`). The particles carry over between
    steps.

    Parameters
    ----------
    model : RangeModel
    prior : GaussianPrior
        Beliefs at time 0 (the particles are drawn from it, PF-BP Algorithm 1, lines 1–4).
    rng : numpy.random.Generator
    options : PFBPOptions, optional

    The tracker's ``particles`` (``[n_agents, M, N_D]``) and ``cov`` (``[n_agents, N_D, N_D]``,
    the UKF covariances of PF-BP eq. (30)) carry over between steps.

    Examples
    --------
    >>> from phyloc.localization.tracking import GaussianPrior, RangeModel
    >>> prior = GaussianPrior(np.ones((1, 2)), np.eye(2)[None])
    >>> t = PFBPTracker(RangeModel("static", 2), prior, np.random.default_rng(0),
    ...                 PFBPOptions(n_particles=200))
    >>> mean, cov = t.step(np.array([[np.nan, 1.0, 1.0]]), np.array([[0.0, 1.0], [1.0, 0.0]]))
    >>> mean.shape, t.particles.shape
    ((1, 2), (1, 200, 2))
    """

    def __init__(self, model, prior: GaussianPrior, rng, options: PFBPOptions | None = None):
        opt = check_run_args(options, PFBPOptions, rng)
        super().__init__(PFBPUpdate(model, opt), prior, rng)

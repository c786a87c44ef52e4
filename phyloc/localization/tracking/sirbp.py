"""Bootstrap-particle belief propagation (SIR-BP), PF-BP §V-B.

Every agent holds ``M`` equally weighted particles. Per time step the particles are predicted by
the motion model (the message η of PF-BP eq. (15)); then, for ``u = 1 … U`` message-passing
iterations with all beliefs updated in parallel (extrinsic information approximated by beliefs,
PF-BP eq. (19)), the predicted particles of agent ``i`` are weighted by the anchor messages
(PF-BP eq. (16)) and the cooperative messages (PF-BP eq. (17), or PF-BP eq. (18) with
centralized factors), resampled systematically and optionally regularized by the kernel of
PF-BP eq. (32).

The cooperative message at particle ``m`` is estimated with one particle of the neighbour's
belief, ``ν_j(x_i^m) ≈ f(z_ij | x_i^m, x_j^m)`` (neighbour particles randomly permuted after
resampling), which keeps the cost O(M) per link as in PF-BP eq. (22), instead of the O(M²) sum
over all neighbour particles. The estimate is the sample mean (PF-BP eq. (20)); the covariance
is the sample covariance. The loop over time steps (prediction, estimates, timing) is
:func:`~phyloc.localization.tracking.loop.track`; this module supplies :class:`SIRBPUpdate`.

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc._validate import from_table
from phyloc.errors import ValidationError
from phyloc.localization.particles import regularize, resample_permute
from phyloc.localization.results import Result
from phyloc.localization.tracking import _flow
from phyloc.localization.tracking import _kernels as _tk
from phyloc.localization.tracking.loop import (
    Belief,
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


@dataclass(frozen=True)
class SIRBPOptions:
    """Options of SIR-BP (defaults: PF-BP §VI, 100 000 particles, 2 iterations).

    Parameters
    ----------
    n_particles : int
        M per agent.
    n_iterations : int
        U.
    factors : {"distributed", "centralized"}
    regularize : bool
        Kernel of PF-BP eq. (32) after resampling.
    reg_std_vel, reg_std_acc : float
        σ_r,vel [m/s], σ_r,acc [m/s²].
    uniform_positions : bool
        Draw the initial positions uniformly in the bounding box of the anchors (PF-BP §VI for
        SIR-BP) instead of from the Gaussian prior; velocity/acceleration stay Gaussian.
    """

    n_particles: int = 100_000
    n_iterations: int = 2
    factors: str = "distributed"
    regularize: bool = False
    reg_std_vel: float = 0.15
    reg_std_acc: float = 0.15
    uniform_positions: bool = True

    def __post_init__(self):
        for name, lo in (("n_particles", 2), ("n_iterations", 1)):
            object.__setattr__(self, name, v.integer(name, getattr(self, name), minimum=lo))
        if self.factors not in FACTORS:
            raise ValidationError("factors", self.factors, f"must be one of {FACTORS}")
        for name in ("reg_std_vel", "reg_std_acc"):
            object.__setattr__(self, name, v.positive(name, getattr(self, name), allow_zero=True))

    @classmethod
    def from_dict(cls, d: dict, section: str = "localization") -> SIRBPOptions:
        """Build from a recipe table; unknown keys are errors naming the closest valid key."""
        return from_table(cls, d, section)


def run_sirbp(
    measurements: RangeMeasurements,
    prior: GaussianPrior,
    rng: np.random.Generator,
    options: SIRBPOptions | None = None,
) -> Result:
    """Track all agents with SIR-BP (PF-BP §V-B); registered as ``sirbp``.

    Parameters
    ----------
    measurements : RangeMeasurements
    prior : GaussianPrior
    rng : numpy.random.Generator
    options : SIRBPOptions, optional

    Returns
    -------
    Result
        ``estimates [K, n_agents, N_D]`` (sample means), ``covariances`` (sample covariances),
        the final ``particles [n_agents, M, N_D]`` with uniform ``log_weights``;
        ``timing.agent_s = step_s / n_agents``, ``agent_iterations = K · U · n_agents``.

    Examples
    --------
    >>> from phyloc.localization.tracking import GaussianPrior, RangeMeasurements, RangeModel
    >>> z = np.full((1, 1, 4), np.nan)
    >>> z[:, 0, 1:] = [5.0, 5.0, 5.0]
    >>> anchors = np.array([[0.0, 0.0], [8.0, 0.0], [0.0, 8.0]])
    >>> meas = RangeMeasurements(RangeModel("static", 2), anchors, z)
    >>> prior = GaussianPrior(np.array([[3.0, 3.0]]), np.eye(2)[None] * 4.0)
    >>> res = run_sirbp(meas, prior, np.random.default_rng(0), SIRBPOptions(n_particles=1000))
    >>> res.estimates.shape
    (1, 1, 2)
    """
    opt = check_run_args(options, SIRBPOptions, rng)
    check_inputs(measurements, prior)
    bounds = None
    if opt.uniform_positions and measurements.n_anchors > 0:
        bounds = measurements.anchor_bounds()
    return track(measurements, prior, rng, SIRBPUpdate(measurements.model, opt, bounds))


class SIRBPUpdate(Update):
    """One time step of SIR-BP for :func:`~phyloc.localization.tracking.loop.track`: ``M``
    equally weighted particles per agent, weighted by the messages of PF-BP eqs. (16)–(19) and
    resampled, ``U`` iterations.

    Parameters
    ----------
    model : RangeModel
    options : SIRBPOptions
    anchor_bounds : (lo, hi) of [dim] float, optional
        Box of the uniformly drawn initial positions (``uniform_positions``, PF-BP §VI); None:
        the positions are drawn from the Gaussian prior.
    """

    label = "sirbp"

    def __init__(self, model, options: SIRBPOptions, anchor_bounds=None):
        super().__init__(model, options)
        self.anchor_bounds = anchor_bounds
        self._inv_var = 1.0 / model.sigma_r**2
        self._Sr = None
        if options.regularize:  # PF-BP eq. (32)
            self._Sr = model.regularization_cov(options.reg_std_vel, options.reg_std_acc)

    def initial(self, mean0, cov0, rng) -> Belief:
        """Particles from the prior; positions uniform in ``anchor_bounds`` when given."""
        X = sample_gaussian(mean0, cov0, self.options.n_particles, rng)
        if self.anchor_bounds is not None:
            lo, hi = self.anchor_bounds
            X[..., : self.model.dim] = rng.uniform(lo, hi, size=(*X.shape[:2], self.model.dim))
        return Belief(particles=X)

    def update(self, pred, z_k, anchors_k, rng) -> Belief:
        """Weight the predicted particles ``pred.particles`` (η, PF-BP eq. (15)) by the messages
        and resample, all agents in parallel."""
        dim, Sr = self.model.dim, self._Sr
        X0 = pred.particles
        n_ag, M = X0.shape[:2]
        pos0 = np.ascontiguousarray(X0[..., :dim])

        def share(u, chi):  # the neighbours' particle positions of iteration u − 1
            return pos0 if u == 0 else np.ascontiguousarray(chi[..., :dim])

        def agent(i, _chi, chi_pos):
            rx, tx, zz, _ = agent_measurements(z_k, i, self.options.factors)
            lw = np.zeros(M)
            with self.clock("weights"):
                for a, b, zq in zip(rx, tx, zz, strict=True):
                    other = b if a == i else a  # the node that is not i
                    if other >= n_ag:
                        y = anchors_k[other - n_ag][None]  # PF-BP eq. (16)
                    else:
                        y = chi_pos[other]  # belief of j at u − 1, PF-BP eqs. (17)–(19)
                    _flow.paired_range_loglik_kernel(pos0[i], y, float(zq), self._inv_var, lw)
            if zz.size:  # resampling, then the jitter of PF-BP eq. (32), jittered block only
                with self.clock("resample"):
                    return (resample_permute(X0[i], lw, rng, Sr),)
            with self.clock("regularize"):
                return (X0[i] if Sr is None else regularize(X0[i], Sr, rng),)

        (chi,) = message_passing(self.options.n_iterations, (X0,), agent, share)
        return Belief(particles=chi)

    def estimate(self, belief):
        """Sample means (PF-BP eq. (20)) and covariances, without a ``[M, N_D]`` temporary."""
        n_ag, _, nd = belief.particles.shape
        mean, cov = np.empty((n_ag, nd)), np.empty((n_ag, nd, nd))
        _tk.mean_cov_kernel(belief.particles, mean, cov)
        return mean, cov

    def floats_per_link_iteration(self) -> float:
        """The ``M`` particle positions a neighbour's range factor reads."""
        nd, dim = self.model.state_dim, self.model.dim
        return message_floats("positions", nd, self.options.n_particles, dim)

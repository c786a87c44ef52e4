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
is the sample covariance.

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc._validate import check_keys
from phyloc.errors import ValidationError
from phyloc.localization.particles import regularize, resample_permute
from phyloc.localization.results import Result, Timing
from phyloc.localization.tracking import _flow
from phyloc.localization.tracking import _kernels as _tk
from phyloc.localization.tracking.range_models import (
    FACTORS,
    GaussianPrior,
    RangeMeasurements,
    agent_measurements,
    check_inputs,
    check_run_args,
    message_floats,
    sample_gaussian,
)


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
        check_keys(d, [f.name for f in dataclasses.fields(cls)], section)
        return cls(**d)


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
    t_start = time.perf_counter()
    opt = check_run_args(options, SIRBPOptions, rng)
    mean0, cov0 = check_inputs(measurements, prior)
    model = measurements.model
    dim, nd, n_ag, M, K = (
        model.dim,
        model.state_dim,
        measurements.n_agents,
        opt.n_particles,
        measurements.n_steps,
    )
    inv_var = 1.0 / model.sigma_r**2
    Sr = model.regularization_cov(opt.reg_std_vel, opt.reg_std_acc) if opt.regularize else None

    X = sample_gaussian(mean0, cov0, M, rng)
    if opt.uniform_positions and measurements.n_anchors > 0:
        lo, hi = measurements.anchor_bounds()
        X[..., :dim] = rng.uniform(lo, hi, size=(n_ag, M, dim))
    out_mean = np.empty((K, n_ag, nd))
    out_cov = np.empty((K, n_ag, nd, nd))
    step_s = np.empty(K)
    for k in range(K):
        t0 = time.perf_counter()
        X0 = model.predict_particles(X, rng)  # η, PF-BP eq. (15)
        pos0 = np.ascontiguousarray(X0[..., :dim])
        chi_pos = pos0
        chi = X0
        for _u in range(opt.n_iterations):
            new_chi = np.empty_like(chi)
            for i in range(n_ag):
                rx, tx, zz, _ = agent_measurements(measurements.z[k], i, opt.factors)
                lw = np.zeros(M)
                for a, b, zq in zip(rx, tx, zz, strict=True):
                    other = b if a == i else a  # the node that is not i
                    if other >= n_ag:
                        y = measurements.anchors_at(k)[other - n_ag][None]  # PF-BP eq. (16)
                    else:
                        y = chi_pos[other]  # belief of j at u − 1, PF-BP eqs. (17)–(19)
                    _flow.paired_range_loglik_kernel(pos0[i], y, float(zq), inv_var, lw)
                if zz.size:  # resampling, then the jitter of PF-BP eq. (32), jittered block only
                    new_chi[i] = resample_permute(X0[i], lw, rng, Sr)
                else:
                    new_chi[i] = X0[i] if Sr is None else regularize(X0[i], Sr, rng)
            chi = new_chi
            chi_pos = np.ascontiguousarray(chi[..., :dim])
        X = chi
        _tk.mean_cov_kernel(X, out_mean[k], out_cov[k])  # PF-BP eq. (20), no [M, N_D] temporary
        step_s[k] = time.perf_counter() - t0
    timing = Timing(
        time.perf_counter() - t_start, step_s, step_s / n_ag, K * opt.n_iterations * n_ag
    )
    return Result(
        out_mean,
        out_cov,
        timing,
        particles=X,
        log_weights=np.full((n_ag, M), -np.log(M)),
        diagnostics={"floats_per_link_iteration": message_floats("positions", nd, M, dim)},
        label="sirbp",
    )

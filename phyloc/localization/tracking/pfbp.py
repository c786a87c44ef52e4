"""Particle-flow belief propagation (PF-BP), Algorithm 1 of the PF-BP paper.

Every agent ``i`` holds ``M`` equally weighted particles and a covariance ``P_i``. Per time step:

1. predict the particles by the motion model (eq. (1)) and the covariance by eq. (29)
   (Algorithm 1, line 7); the sample mean is ``x̄_{λ=0,i}`` (line 8);
2. for ``u = 1 … U`` message-passing iterations, all beliefs in parallel (lines 10–18): stack the
   agent's predicted particles with the neighbours' belief particles of iteration ``u − 1`` into
   β (eq. (21), extrinsic information approximated by beliefs), with block-diagonal
   covariance ``P̃_i`` (eq. (28)); flow the agent's components over the exponentially spaced
   λ-steps with the exact Daum–Huang drift of the stacked state (eqs. (23)–(27)); weight by the
   invertible flow (eq. (22)); resample systematically; the covariance by the UKF update
   (eq. (30)) at the resampled mean; optionally regularize (eqs. (32), (33));
3. the estimate is the sample mean (eq. (20), line 20).

Implementation notes (deviations are marked):

- The prior-density ratio of eq. (22) uses the Gaussian ``N(x̄_{λ=0,i}, P_i^{(k|k−1)})`` the flow
  was derived for: the transition density of eq. (22) is singular for CV/CA (rank-``dim`` Q).
- Neighbour ``j``'s particle ``m`` is paired with agent ``i``'s particle ``m`` (eq. (22));
  resampled particles are randomly permuted so that pairs are independent draws (systematic
  resampling returns them sorted by ancestor).
- Measurements: ``factors="distributed"`` uses agent ``i``'s own ranges (eq. (17));
  ``"centralized"`` also the neighbours' ranges to ``i`` (eq. (18)).
- An agent without measurements keeps its predicted particles and covariance.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag

from phyloc import _validate as v
from phyloc._validate import check_keys
from phyloc.errors import ValidationError
from phyloc.localization.particles import regularize, resample_permute
from phyloc.localization.tracking import _flow
from phyloc.localization.tracking.range_models import (
    FACTORS,
    RangeScenario,
    TrackResult,
    agent_measurements,
    check_prior,
    check_run_args,
    flow_links,
    sample_gaussian,
)


@dataclass(frozen=True)
class PFBPOptions:
    """Options of PF-BP (defaults: PF-BP §VI).

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
        Regularization kernel of eqs. (32), (33) (off).
    reg_std_vel, reg_std_acc : float
        σ_r,vel [m/s], σ_r,acc [m/s²] of eq. (32) (0.15).
    backend : {"numba", "numpy"}
        Flow kernel.
    """

    n_particles: int = 200
    n_lambda: int = 20
    lambda_ratio: float = 1.2
    n_iterations: int = 2
    factors: str = "distributed"
    regularize: bool = False
    reg_std_vel: float = 0.15
    reg_std_acc: float = 0.15
    backend: str = "numba"

    def __post_init__(self):
        for name, lo in (("n_particles", 2), ("n_lambda", 1), ("n_iterations", 1)):
            object.__setattr__(self, name, v.integer(name, getattr(self, name), minimum=lo))
        ratio = v.positive("lambda_ratio", self.lambda_ratio)
        if ratio < 1.0:
            raise ValidationError("lambda_ratio", ratio, "must be >= 1 (growing λ-steps)")
        object.__setattr__(self, "lambda_ratio", ratio)
        if self.factors not in FACTORS:
            raise ValidationError("factors", self.factors, f"must be one of {FACTORS}")
        if self.backend not in ("numba", "numpy"):
            raise ValidationError("backend", self.backend, "must be 'numba' or 'numpy'")
        for name in ("reg_std_vel", "reg_std_acc"):
            object.__setattr__(self, name, v.positive(name, getattr(self, name), allow_zero=True))

    @classmethod
    def from_dict(cls, d: dict, section: str = "localization") -> PFBPOptions:
        """Build from a recipe table; unknown keys are errors naming the closest valid key."""
        check_keys(d, [f.name for f in dataclasses.fields(cls)], section)
        return cls(**d)


def run_flow(X, mean, P, off_a, off_b, anchor_pos, z, r_var, dim, n_flow, lambdas, steps, backend):
    """Flow particles ``X [M, n]`` (copies) with the numba kernel or its NumPy twin."""
    if backend == "numpy":
        return _flow.range_flow_numpy(
            X, mean, P, off_a, off_b, anchor_pos, z, r_var, dim, n_flow, lambdas, steps
        )
    X1 = np.array(X, dtype=np.float64, order="C")
    m1 = np.array(mean, dtype=np.float64)
    _flow.range_flow_kernel(
        X1,
        m1,
        np.ascontiguousarray(P),
        off_a,
        off_b,
        anchor_pos,
        z,
        r_var,
        dim,
        n_flow,
        lambdas,
        steps,
    )
    return X1, m1


def stacked_loglik(B, off_a, off_b, anchor_pos, z, inv_var, dim):
    """``Σ_q log f(z_q | β^m)`` for stacked particles ``B [M, n]`` (paired, eq. (22))."""
    out = np.zeros(B.shape[0])
    for q in range(z.size):
        a = off_a[q]
        x = np.ascontiguousarray(B[:, a : a + dim])
        b = off_b[q]
        y = anchor_pos[q : q + 1] if b < 0 else np.ascontiguousarray(B[:, b : b + dim])
        _flow.paired_range_loglik_kernel(x, y, float(z[q]), inv_var, out)
    return out






def run_pfbp(
    scenario: RangeScenario,
    prior_mean: np.ndarray,
    prior_cov: np.ndarray,
    rng: np.random.Generator,
    options: PFBPOptions | None = None,
) -> TrackResult:
    """Track all agents of a scenario with PF-BP (Algorithm 1).

    Parameters
    ----------
    scenario : RangeScenario
        From :func:`~phyloc.localization.tracking.range_models.simulate_scenario`.
    prior_mean : [n_agents, N_D] float64
        ``x̄_i^{(0)}`` (e.g. :func:`~phyloc.localization.tracking.range_models.paper_prior`, eq. (31)).
    prior_cov : [n_agents, N_D, N_D] float64
        ``P_i^{(0)}``.
    rng : numpy.random.Generator
    options : PFBPOptions, optional

    Returns
    -------
    TrackResult
        ``mean [K, n_agents, N_D]`` (sample means, eq. (20)), ``cov`` (UKF, eq. (30)), timings.

    Examples
    --------
    >>> from phyloc.network import make_network
    >>> from phyloc.localization.tracking.range_models import (RangeModel, paper_prior,
    ...     scenario_network_spec, simulate_scenario)
    >>> rng = np.random.default_rng(1)
    >>> net = make_network(scenario_network_spec(n_agents=3, n_steps=2), rng)
    >>> sc = simulate_scenario(net, RangeModel(), rng)
    >>> m, P = paper_prior(sc, rng)
    >>> run_pfbp(sc, m, P, rng, PFBPOptions(n_particles=50)).mean.shape
    (2, 3, 9)
    """
    opt = check_run_args(options, PFBPOptions, rng)
    mean0, cov0 = check_prior(scenario, prior_mean, prior_cov)
    model = scenario.model
    _dim, nd, n_ag, M, K = (
        model.dim,
        model.state_dim,
        scenario.n_agents,
        opt.n_particles,
        scenario.n_steps,
    )
    lambdas, steps = _flow.lambda_schedule(opt.n_lambda, opt.lambda_ratio)
    var = model.sigma_r**2
    Sr = model.regularization_cov(opt.reg_std_vel, opt.reg_std_acc) if opt.regularize else None

    X = sample_gaussian(mean0, cov0, M, rng)  # Algorithm 1, lines 1–4
    P = cov0
    out_mean = np.empty((K, n_ag, nd))
    out_cov = np.empty((K, n_ag, nd, nd))
    step_s = np.empty(K)
    for k in range(K):
        t0 = time.perf_counter()
        X0 = model.predict_particles(X, rng)  # line 7, eq. (1)
        P_pred = model.predict_cov(P)  # eq. (29)
        chi, P_bel = X0, P_pred
        for _u in range(opt.n_iterations):  # lines 10–18, all agents in parallel
            new_chi = np.empty_like(chi)
            new_P = np.empty_like(P_bel)
            for i in range(n_ag):
                new_chi[i], new_P[i] = _agent_update(
                    i, scenario, k, X0, P_pred, chi, P_bel, opt, lambdas, steps, var, Sr, rng
                )
            chi, P_bel = new_chi, new_P
        X, P = chi, P_bel
        out_mean[k] = X.mean(axis=1)  # eq. (20), line 20
        out_cov[k] = P
        step_s[k] = time.perf_counter() - t0
    return TrackResult(out_mean, out_cov, step_s, step_s / n_ag, label="pfbp")


def _agent_update(i, scenario, k, X0, P_pred, chi, P_bel, opt, lambdas, steps, var, Sr, rng):
    """One belief update of agent ``i`` (Algorithm 1, lines 12–16)."""
    model = scenario.model
    dim, nd, n_ag = model.dim, model.state_dim, scenario.n_agents
    rx, tx, zz, partners = agent_measurements(scenario.z[k], i, opt.factors)
    if zz.size == 0:
        xi, Pi = X0[i], P_pred[i]
    else:
        local = np.full(n_ag, -1, dtype=np.int64)
        local[i] = 0
        local[partners] = np.arange(1, partners.size + 1)
        off_a, off_b, apos, zz = flow_links(rx, tx, zz, local, n_ag, scenario.anchors, dim, nd)
        beta = np.concatenate([X0[i]] + [chi[j] for j in partners], axis=1)  # β, eq. (21)
        P_t = block_diag(P_pred[i], *[P_bel[j] for j in partners])  # eq. (28)
        beta_bar = beta.mean(axis=0)
        r_var = np.full(zz.size, var)
        B1, _ = run_flow(
            beta,
            beta_bar,
            P_t,
            off_a,
            off_b,
            apos,
            zz,
            r_var,
            dim,
            nd,
            lambdas,
            steps,
            opt.backend,
        )  # eqs. (21), (23)–(27)
        ll = stacked_loglik(B1, off_a, off_b, apos, zz, 1.0 / var, dim)
        lw = _flow.invertible_flow_log_weights(X0[i], B1[:, :nd], beta_bar[:nd], P_pred[i], ll)
        xi = resample_permute(B1[:, :nd], lw, rng)  # eq. (22), line 13
        at = np.concatenate([xi.mean(axis=0), beta_bar[nd:]])
        Pi = _flow.ukf_covariance_update(at, P_t, off_a, off_b, apos, r_var, dim, nd)  # eq. (30)
    if Sr is not None:  # eq. (33), line 16
        xi = regularize(xi, Sr, rng)
        Pi = Pi + Sr
    return xi, Pi

"""The equivalent-likelihood distributed particle filter: DiPNet and its two-step twin.

One filter, two kinds of likelihood (:mod:`phyloc.localization.direct.likelihoods`, seen
through the :class:`~phyloc.localization.likelihoods.Likelihood` protocol): with a direct
likelihood from correlation tables it is DiPNet (DiPNet Algorithm 1), with
:class:`~phyloc.localization.direct.likelihoods.GaussianRangeLikelihood` it is the two-step
EL-DPF fed by a range estimator. :func:`run_dpf` is one snapshot of the filter; the family's
entry point ``run(measurements, prior, rng, options)`` (:mod:`phyloc.localization.direct.method`)
chains snapshots. Every agent runs in parallel:

1. draw Q particles from its prior (DiPNet Algorithm 1, line 3);
2. for k = 1 … K: receive the neighbours' published means and covariances (line 5), compute
   the ENV/ERV per link (line 6), weight the particles (DiPNet eq. (28), line 8; log domain,
   normalized with log-sum-exp, line 9) and publish the new mean and covariance (line 10).

The paper stops there (``DPFOptions.published()``). Run as published from uninformative
priors, the weights collapse after the first informative link (effective sample size ≈ 1), the
published covariance is ≈ 0 and DiPNet eq. (26) then treats neighbours as exact anchors.
phyloc's default adds three safeguards, each an option::

    ``tempering``      the log-likelihood is multiplied by γ_k ≤ 1 over the first iterations;
    ``resample_move``  after weighting, systematic resampling and Metropolis–Hastings moves that
                       leave the current target ``prior(x)·exp(γ_k Σ_v log p̃)`` invariant
                       (regularization by Gaussian random-walk proposals scaled to the cloud);
                       the next iteration then reweights by the change of the target only;
    ``translate``      before tempering, each agent's cloud is shifted rigidly towards the new
                       target (mean-shift iterations on the importance weights; the shifted
                       cloud is weighted exactly, the bridge then starts from it): when the
                       neighbours' means move by more than the belief's width, the geometric
                       bridge alone needs many small steps;
    ``cov_floor_m``    the published covariance is at least ``max(floor², CRB_u/dim)·I`` where
                       CRB_u is the agent's position CRB from its links' ranging information
                       (the EFIM of DiPNet eq. (17), :func:`phyloc.analysis.efim.efim`) at the
                       current means.

A likelihood whose ``exchange`` is ``"particles"``
(:class:`~phyloc.localization.direct.sampled_exchange.SampledLikelihood`) receives the
neighbours' particle sets of the previous iteration instead of their moments (sample-based
DPE / SAGE, DiPNet §V-B).

Weights stay in the log domain; an agent whose weights are all ``−inf`` or NaN (an empty
likelihood) falls back to uniform weights and is counted in ``n_degenerate``.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
(Regularized resampling, PF-BP eq. (32).)
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc._validate import from_table
from phyloc.analysis.efim import direction_vectors, position_crb
from phyloc.errors import ValidationError
from phyloc.localization import particles as P
from phyloc.localization.direct import _kernels as K
from phyloc.localization.direct.sampled_exchange import NodeBeliefs
from phyloc.localization.likelihoods import Likelihood


@dataclass(frozen=True)
class DPFOptions:
    """Options of the EL-DPF (defaults: phyloc's safeguarded DiPNet).

    Parameters
    ----------
    n_particles : int
        Q per agent (DiPNet §V-A: 1000).
    n_iterations : int
        K message-passing iterations.
    tempering : tuple of float
        Fixed γ_k for k = 1, 2, … (last value repeats) of the filter *without* resample-move.
        ``(1.0,)`` is the published algorithm.
    resample_move : bool
        Safeguarded filter: every iteration moves the particles from the previous target to
        the new one by adaptive likelihood tempering (steps keeping ESS >= ``ess_fraction``·Q),
        systematic resampling and Metropolis–Hastings moves (needs an evaluable prior).
    ess_fraction : float
        Target ESS fraction of each tempering step.
    max_annealing_steps : int
        Upper bound of tempering steps per iteration (the last one jumps to λ = 1).
    n_moves : int
        Metropolis–Hastings sweeps per iteration.
    move_scale : float
        Proposal std as a fraction of the cloud's per-axis std.
    translate : int
        Mean-shift iterations of the translation transport before each iteration's tempering
        (0: none). Each costs one evaluation of the new likelihood and the prior; the shift
        with the largest ESS is kept per agent, and only when it raises the ESS.
    cov_floor_m : float
        Minimum published std per axis [m]; 0 disables the floor (and the CRB term).
    interpolation : str
        Correlation-table interpolation (direct likelihood).
    """

    n_particles: int = 1000
    n_iterations: int = 8
    tempering: tuple = (1.0,)
    resample_move: bool = True
    ess_fraction: float = 0.5
    max_annealing_steps: int = 60
    n_moves: int = 2
    move_scale: float = 0.5
    translate: int = 3
    cov_floor_m: float = 0.05
    interpolation: str = "cubic"

    def __post_init__(self):
        v.integer_field(self, "n_particles", "n_particles", minimum=1)
        v.integer_field(self, "n_iterations", "n_iterations", minimum=1)
        temp = tuple(float(g) for g in np.atleast_1d(self.tempering))
        if not temp or any(not (0 < g <= 1) for g in temp):
            raise ValidationError("tempering", self.tempering, "values in (0, 1]")
        object.__setattr__(self, "tempering", temp)
        v.integer_field(self, "n_moves", "n_moves", minimum=0)
        if not 0 < float(self.ess_fraction) < 1:
            raise ValidationError("ess_fraction", self.ess_fraction, "in (0, 1)")
        v.integer_field(self, "max_annealing_steps", "max_annealing_steps", minimum=1)
        v.positive("move_scale", self.move_scale)
        v.integer_field(self, "translate", "translate", minimum=0)
        v.positive("cov_floor_m", self.cov_floor_m, allow_zero=True)
        if self.interpolation not in ("linear", "cubic", "quintic"):
            raise ValidationError("interpolation", self.interpolation, "linear, cubic or quintic")

    @classmethod
    def published(cls, **kw) -> DPFOptions:
        """DiPNet Algorithm 1 as published: no tempering, no resample-move, no covariance floor."""
        base = {"tempering": (1.0,), "resample_move": False, "cov_floor_m": 0.0}
        return cls(**{**base, **kw})

    @classmethod
    def from_dict(cls, d: dict, section: str = "localization") -> DPFOptions:
        """From a recipe table (unknown keys are errors)."""
        return from_table(cls, d, section)

    def gamma(self, k: int) -> float:
        """Tempering exponent of iteration k (1-based)."""
        return self.tempering[min(k, len(self.tempering)) - 1]


@dataclass(frozen=True)
class Prior:
    """The prior of the direct family: particles per agent drawn from it, and its log density.

    Attributes
    ----------
    particles : [n_agents, Q, dim] float64
        Q particles per agent [m], agents in ``measurements.agent_nodes`` order (DiPNet
        Algorithm 1, line 3).
    log_density : callable or None
        ``log_density(x [n_agents, Q, dim]) -> [n_agents, Q]``, may be −inf outside a support,
        row ``a`` a function of ``x[a]`` only (each agent's own prior; the filter reuses rows
        evaluated in other calls); None means the prior cannot be evaluated (the resample-move
        safeguard is then skipped).
    label : str
        Names the initialization in every output (e.g. ``"informed start"``).
    log_weights : [n_agents, Q] float64, optional
        Log weights of the particles (default: equal weights).
    """

    particles: np.ndarray
    log_density: object = None
    label: str = "truth-free"
    log_weights: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class DPFResult:
    """Output of :func:`run_dpf` for one snapshot (the family's ``run`` maps it to a Result).

    Attributes
    ----------
    means : [n_nodes, dim]  final estimates (anchors: their known positions)
    covs : [n_nodes, dim, dim]  published covariances (anchors: 0)
    mean_history : [K + 1, n_nodes, dim]  published means after each iteration (0 = prior)
    cov_trace_history : [K + 1, n_agents]  trace of the published covariances
    ess_history : [K, n_agents]  effective sample size after weighting
    particles, log_weights : [n_agents, Q, dim], [n_agents, Q]  final belief
    n_degenerate : int  weight vectors that fell back to uniform
    annealing_steps : int  tempering steps taken by the safeguarded filter (0 when published)
    seconds : float  wall time; ``agent_iterations`` = n_agents·K
    label : str  the initialization label
    """

    means: np.ndarray
    covs: np.ndarray
    mean_history: np.ndarray
    cov_trace_history: np.ndarray
    ess_history: np.ndarray
    particles: np.ndarray
    log_weights: np.ndarray
    n_degenerate: int
    seconds: float
    agent_iterations: int
    label: str
    annealing_steps: int = 0


def _floor(cov, likelihood: Likelihood, centers, agent_nodes, floor_m):
    """Add the covariance floor: max(floor², CRB_u/dim) per axis.

    ``CRB_u = tr J_u⁻¹`` from the EFIM of DiPNet eq. (17) (``J_u = Σ_v ν_uv e_uv e_uvᵀ``, the
    form of :func:`phyloc.analysis.efim.efim`, for every agent at once; neighbours at their
    published means, the links' ranging information ``likelihood.nu``); a singular ``J_u``
    (no links, or links that leave a direction undetermined) adds no CRB term.
    """
    if floor_m <= 0:
        return cov
    n_agents, dim = cov.shape[0], cov.shape[1]
    csr = likelihood.csr
    owner = np.repeat(np.arange(n_agents), np.diff(csr.offsets))
    e, coincident = direction_vectors(centers[agent_nodes[owner]], centers[csr.tx])
    nu = np.asarray(likelihood.nu, dtype=np.float64)
    J = np.zeros((n_agents, dim, dim))
    for i in range(dim):
        for k in range(i + 1):  # a coincident neighbour contributes ν I/dim (as efim)
            w = nu * (e[:, i] * e[:, k] + (coincident / dim if i == k else 0.0))
            J[:, i, k] = J[:, k, i] = np.bincount(owner, weights=w, minlength=n_agents)
    with np.errstate(invalid="ignore"):
        crb = position_crb(J) / dim  # inf where singular (no links included)
    # the CRB term only raises the floor where the links determine the position
    var = np.maximum(floor_m**2, np.where(np.isfinite(crb), crb, 0.0))
    low = np.linalg.eigvalsh(cov)[:, 0]
    lift = np.where(low < var, var - np.minimum(low, var), 0.0)
    return cov + lift[:, None, None] * np.eye(dim)


def run_dpf(
    likelihood: Likelihood,
    prior: Prior,
    anchor_positions,
    is_anchor,
    rng: np.random.Generator,
    options: DPFOptions = DPFOptions(),
) -> DPFResult:
    """Run the EL-DPF on one snapshot (DiPNet Algorithm 1 with optional safeguards).

    The single-snapshot step of the direct family's ``run``; it sees no agent position.

    Parameters
    ----------
    likelihood : Likelihood
        The link likelihood of this snapshot (a ``DirectLikelihood``,
        ``MarginalDirectLikelihood``, ``GaussianRangeLikelihood`` or ``SampledLikelihood``).
    prior : Prior
        ``particles [n_agents, Q, dim]`` drawn from each agent's prior.
    anchor_positions : [n_anchors, dim] float64
        Known anchor positions [m], in the node order of ``is_anchor``.
    is_anchor : [n_nodes] bool
        Which nodes are anchors; the others are the agents, in increasing node order.
    rng : numpy.random.Generator
        Stream of the resample-move safeguard (unused by the published filter).
    options : DPFOptions

    Returns
    -------
    DPFResult
    """
    t0 = time.perf_counter()
    is_anchor = np.asarray(is_anchor, bool)
    agent_nodes = np.flatnonzero(~is_anchor)
    X = np.array(prior.particles, dtype=np.float64, copy=True)
    if X.ndim != 3:
        raise ValidationError("prior.particles", f"shape {X.shape}", "[n_agents, Q, dim]")
    n_agents, Q, dim = X.shape
    if n_agents != agent_nodes.size:
        raise ValidationError("prior.particles", f"{n_agents} agents", f"{agent_nodes.size}")
    anchors = np.asarray(anchor_positions, dtype=np.float64)
    n_anchors = is_anchor.size - agent_nodes.size
    if anchors.size == 0 and n_anchors == 0:
        anchors = anchors.reshape(0, dim)
    if anchors.shape != (n_anchors, dim):
        raise ValidationError(
            "anchor_positions", f"shape {anchors.shape}", f"[n_anchors = {n_anchors}, {dim}]"
        )
    positions = np.zeros((is_anchor.size, dim))  # agents' rows are set from the prior below
    positions[is_anchor] = anchors
    logp = prior.log_density
    moving = options.resample_move and logp is not None
    lp = logp(X) if logp is not None else np.zeros((n_agents, Q))
    w_init = 0.0 if prior.log_weights is None else np.asarray(prior.log_weights, float)
    # DiPNet eq. (27): the initial weights w^(p,0)
    lw0, n_bad = P.normalize_log_weights(np.where(np.isfinite(lp), w_init, -np.inf))

    centers = positions.copy()
    covs = np.zeros((is_anchor.size, dim, dim))
    m, c = P.weighted_moments(X, lw0)
    centers[agent_nodes], covs[agent_nodes] = m, c
    K_it = options.n_iterations
    mean_hist = np.empty((K_it + 1, is_anchor.size, dim))
    tr_hist = np.empty((K_it + 1, n_agents))
    ess_hist = np.empty((K_it, n_agents))
    mean_hist[0], tr_hist[0] = centers, np.trace(c, axis1=1, axis2=2)
    n_steps = 0

    lw = lw0
    ll_old = np.zeros((n_agents, Q))  # log-likelihood of the target the particles represent
    old_fn = None  # evaluates ll_old at other particles (None: the prior, ll ≡ 0)
    for k in range(1, K_it + 1):
        gamma = 1.0 if moving else options.gamma(k)
        new_fn = _frozen_loglik(likelihood, centers, covs, gamma, agent_nodes, X, lw)
        ll_new = new_fn(X)
        if not moving:  # DiPNet eq. (28): reweight the prior particles by the product of ELs
            lw, bad = P.normalize_log_weights(lw0 + ll_new)
            n_bad += bad
            ess_hist[k - 1] = P.effective_sample_size(lw)
        else:
            X, lp, ll_new, lw, ess, steps = _anneal(
                X, lw, lp, ll_old, ll_new, old_fn, new_fn, logp, rng, options
            )
            ess_hist[k - 1] = ess
            n_steps += steps
            ll_old, old_fn = ll_new, new_fn
        m, c = P.weighted_moments(X, lw)
        new_centers = centers.copy()
        new_centers[agent_nodes] = m
        if options.cov_floor_m > 0:
            c = _floor(c, likelihood, new_centers, agent_nodes, options.cov_floor_m)
        covs = covs.copy()
        covs[agent_nodes] = c
        centers = new_centers
        mean_hist[k], tr_hist[k] = centers, np.trace(c, axis1=1, axis2=2)
    return DPFResult(
        means=centers,
        covs=covs,
        mean_history=mean_hist,
        cov_trace_history=tr_hist,
        ess_history=ess_hist,
        particles=X,
        log_weights=lw,
        n_degenerate=n_bad,
        seconds=time.perf_counter() - t0,
        agent_iterations=n_agents * K_it,
        label=prior.label,
        annealing_steps=n_steps,
    )


def _frozen_loglik(likelihood: Likelihood, centers, covs, gamma, agent_nodes, X, lw):
    """The log-likelihood with the neighbours' beliefs of one iteration frozen: their moments,
    or (a likelihood with ``exchange == "particles"``) their particle sets ``X``, ``lw``.

    A likelihood with a ``frozen`` method builds the function itself (the marginal EL
    tabulates each link once per iteration over the range the particles ``X`` cover).
    The function is ``fn(x, agents=None)``: ``x`` holds the rows of ``agents`` (all when
    None), the form :func:`~phyloc.localization.particles.mh_moves` evaluates the old
    likelihood in."""
    c, v = centers.copy(), covs.copy()
    if getattr(likelihood, "exchange", "moments") == "particles":
        beliefs = NodeBeliefs(c, agent_nodes, X, lw)

        def every_row(x):
            return likelihood.loglik(x, c, v, gamma=gamma, beliefs=beliefs)

    else:
        if hasattr(likelihood, "frozen"):
            fn = likelihood.frozen(X, c, v, gamma)
            if fn is not None:
                return fn

        def every_row(x):
            return likelihood.loglik(x, c, v, gamma=gamma)

    def fn(x, agents=None):
        if agents is None:
            return every_row(x)
        full = np.array(X, dtype=np.float64, copy=True)  # other rows: any valid particles
        full[agents] = x
        return every_row(full)[agents]

    return fn


def _anneal(X, lw, lp, ll_old, ll_new, old_fn, new_fn, logp, rng, options):
    """Move the particles ``X`` (log weights ``lw``) of ``prior·exp(ll_old)`` to
    ``prior·exp(ll_new)``.

    First the translation transport (:func:`_translate`, ``options.translate`` iterations),
    then the geometric bridge ``prior·exp(λ ll_new + (1 − λ) ll_old)``, λ: 0 → 1, each step
    as large as keeps the effective sample size >= ``ess_fraction``·Q (bisection), followed
    by systematic resampling and Metropolis–Hastings moves that leave the bridge target
    invariant. Returns the moved particles with uniform weights, the smallest ESS seen and
    the number of steps.
    """
    n_agents, Q, _ = X.shape
    if options.translate > 0:
        X, lp, ll_old, ll_new, old_fn = _translate(
            X, lw, lp, ll_old, ll_new, old_fn, new_fn, logp, options.translate,
            options.ess_fraction * Q,
        )  # fmt: skip
    lam = np.zeros(n_agents)
    ess_min = np.full(n_agents, float(Q))
    steps = 0
    while np.any(lam < 1.0) and steps < options.max_annealing_steps:
        steps += 1
        delta = ll_new - ll_old
        nxt = _next_lambda(lw, delta, lam, options.ess_fraction * Q)
        if steps == options.max_annealing_steps:
            nxt = np.ones(n_agents)
        lw, _ = P.normalize_log_weights(lw + (nxt - lam)[:, None] * delta)
        ess_min = np.minimum(ess_min, P.effective_sample_size(lw))
        lam = nxt
        X, lp, ll_old, ll_new = P.resample_agents(X, lw, rng, lp, ll_old, ll_new)
        lw = np.full((n_agents, Q), -np.log(Q))
        X, lp, ll_old, ll_new = P.mh_moves(
            X,
            lp,
            ll_old,
            ll_new,
            lam,
            old_fn,
            new_fn,
            logp,
            rng,
            n_moves=options.n_moves,
            move_scale=options.move_scale,
        )
    return X, lp, ll_new, lw, ess_min, steps


def _translate(X, lw, lp, ll_old, ll_new, old_fn, new_fn, logp, n_iter, ess_target):
    """Translation transport: shift each agent's cloud rigidly towards the new target.

    The particles ``X`` with log weights ``lw`` represent ``π_old = prior·exp(ll_old)``.
    Shifted by ``s_a`` they represent ``π_old(x − s_a)``, and the importance weights
    ``lw + log π_new(x + s_a) − log π_old(x)`` make them a weighted sample of ``π_new``
    exactly (a translation has unit Jacobian). ``s_a`` starts at 0 and moves to the weighted
    mean of the shifted cloud under these weights (mean shift), ``n_iter`` times for every
    agent and up to ``4·n_iter`` times for agents whose best ESS is still below
    ``ess_target`` and whose last shift exceeded half the cloud's width (a cloud far from a
    narrow target advances by about its own width per iteration; one whose target is
    narrower but not far has converged).
    Each iteration evaluates the prior and ``new_fn`` once (``new_fn`` on the rows still
    shifting). Per agent the shift with the largest ESS is kept when it beats no shift and
    leaves the prior finite at every particle.

    The bridge that follows runs from the shifted old target: the returned ``ll_old`` is
    ``log π_old(x − s) − log prior(x)`` at the returned particles, and ``old_fn`` evaluates it
    at other particles (``fn(x, agents=None)``). Agents left unshifted keep their values.
    """
    n_agents, _, dim = X.shape
    base = lp + ll_old  # log π_old at the particles
    w_old = np.exp(lw)
    cur_lw = lw + ll_new - ll_old  # no shift: the prior cancels
    best_ess = P.effective_sample_size(P.normalize_log_weights(cur_lw)[0])
    best_s = np.zeros((n_agents, dim))
    best_X, best_lp, best_ln = X, lp, ll_new
    s = np.zeros((n_agents, dim))
    cur_X = X
    rows = np.arange(n_agents)
    width = np.linalg.norm(X.std(axis=1), axis=1)
    for k in range(4 * n_iter):
        w = np.exp(P.normalize_log_weights(cur_lw[rows])[0])
        step = np.einsum("aq,aqd->ad", w - w_old[rows], cur_X[rows])  # mean shift
        s[rows] += step
        cur_X = X + s[:, None, :]
        lpp = logp(cur_X)[rows]
        lnp = new_fn(cur_X[rows], rows)
        cur_lw = cur_lw.copy()
        cur_lw[rows] = lw[rows] + lpp + lnp - base[rows]
        ess = P.effective_sample_size(P.normalize_log_weights(cur_lw[rows])[0])
        better = (ess > best_ess[rows]) & np.all(np.isfinite(lpp), axis=1)
        up = rows[better]
        best_ess[up] = ess[better]
        best_s[up] = s[up]
        best_X = best_X.copy() if best_X is X else best_X
        best_X[up] = cur_X[up]
        best_lp = best_lp.copy() if best_lp is lp else best_lp
        best_lp[up] = lpp[better]
        best_ln = best_ln.copy() if best_ln is ll_new else best_ln
        best_ln[up] = lnp[better]
        if k + 1 >= n_iter:  # beyond n_iter: agents below the target whose cloud still travels
            travels = np.linalg.norm(step, axis=1) > 0.5 * width[rows]
            rows = rows[(best_ess[rows] < ess_target) & travels]
            if rows.size == 0:
                break
    moved = np.any(best_s != 0.0, axis=1)
    if not moved.any():
        return X, lp, ll_old, ll_new, old_fn
    ll_old = np.where(moved[:, None], base - best_lp, ll_old)  # log π_old(x − s) − log prior(x)
    shift = best_s[:, None, :]
    template = best_X
    back_template = template - shift
    every = np.arange(n_agents)

    def shifted_old(x, agents=None, lp_x=None):
        """``log π_old(x − s) − log prior(x)`` at ``x`` (rows of ``agents``, all when None);
        ``lp_x``: the prior at ``x`` when the caller has it (the prior is per agent, so its
        rows are those of the full array evaluated here otherwise)."""
        x = np.asarray(x, dtype=np.float64)
        if agents is None:
            idx = every
            full = x  # every row given: the template drops out
            back = x - shift
        else:  # the other rows: any valid particles (the template), shifted back as well
            idx = np.asarray(agents)
            full = None
            back = back_template.copy()
            back[idx] = x - shift[idx]
        old = np.zeros((idx.size, x.shape[1])) if old_fn is None else old_fn(back[idx], idx)
        # the prior at x − s against the prior at x (the bridge holds prior(x) separately);
        # outside the prior's support at x the target is −inf whatever the old term says
        with np.errstate(invalid="ignore"):
            if lp_x is None:
                if full is None:
                    full = np.array(template, dtype=np.float64, copy=True)
                    full[idx] = x
                ratio = (logp(back) - logp(full))[idx]
            else:
                ratio = logp(back)[idx] - lp_x
        return old + np.where(np.isnan(ratio), -np.inf, ratio)

    shifted_old.takes_prior = True
    return best_X, best_lp, ll_old, best_ln, shifted_old


def _next_lambda(lw, delta, lam, ess_target):
    """Per agent, the largest λ' in (λ, 1] whose incremental weights keep ESS >= target
    (30 bisections on the step, in
    :func:`~phyloc.localization.direct._kernels.next_lambda_kernel`)."""
    out = np.empty(lam.shape)
    K.next_lambda_kernel(
        np.ascontiguousarray(lw, dtype=np.float64),
        np.ascontiguousarray(delta, dtype=np.float64),
        np.ascontiguousarray(lam, dtype=np.float64),
        float(ess_target),
        30,
        out,
    )
    return out


def predict(
    result: DPFResult,
    rng: np.random.Generator,
    *,
    process_std_m: float = 1.0,
    resample_ess: float = 0.5,
    regularize: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Prior particles of the next snapshot from the belief of ``result``.

    Systematic resampling when the ESS falls below ``resample_ess``·Q, Gaussian jitter of
    Silverman's bandwidth when ``regularize`` (regularized particle filter, PF-BP eq. (32)),
    then the random-walk motion model ``x_t = x_{t−1} + N(0, process_std_m²·I)`` (DiPNet §II-C:
    a state transition with the first-order Markov assumption).

    Returns
    -------
    particles : [n_agents, Q, dim] float64
    log_weights : [n_agents, Q] float64
    """
    q = v.positive("process_std_m", process_std_m, allow_zero=True)
    X, lw = result.particles, result.log_weights
    Q = X.shape[1]
    if np.any(P.effective_sample_size(lw) < resample_ess * Q):
        X, lw = P.resample_regularize(X, lw, rng, regularize)
    X = X + q * rng.standard_normal(X.shape)
    return X, lw

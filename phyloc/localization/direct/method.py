"""The direct family's one entry point: ``run(measurements, prior, rng, options) -> Result``.

Every method of the family (DiPNet, its published form, the two-step EL-DPF on the ranges of
any estimator) is :func:`run` with different :class:`DirectOptions`: the option
``likelihood`` picks the link likelihood —

``"marginal"``  DiPNet's direct likelihood marginalized over the neighbour's projected
                uncertainty, bounded by ``outlier_nats``
                (:class:`~phyloc.localization.direct.likelihoods.MarginalDirectLikelihood`; phyloc's
                departure from DiPNet eq. (25));
``"env"``       DiPNet eqs. (25)–(26): the correlation-table likelihood with the equivalent
                noise variance (:class:`~phyloc.localization.direct.likelihoods.DirectLikelihood`);
``"gaussian"``  the two-step equivalent likelihood on the ranges of the estimator
                ``ranges`` with the ERV of DiPNet eq. (18)
                (:class:`~phyloc.localization.direct.likelihoods.GaussianRangeLikelihood`)

— ``exchange`` chooses what neighbours share: ``"moments"`` (mean and covariance, DiPNet
Algorithm 1 line 5) or ``"particles"`` (their particle sets: sample-based DPE with
``"marginal"`` or ``"env"``, sample-based SAGE with ``"gaussian"``, DiPNet §V-B;
:class:`~phyloc.localization.direct.sampled_exchange.SampledLikelihood`) — and ``safeguards``
chooses between phyloc's safeguarded filter and DiPNet Algorithm 1 as published. Snapshot 0 runs the
filter from the prior (:func:`~.dpf.run_dpf`); each later snapshot predicts the particles
(:func:`~.dpf.predict`) and runs the filter's iterations again.

Examples
--------
One agent between three anchors, ranges of an estimator called ``"corr"``:

>>> import numpy as np
>>> from phyloc.localization.direct import LinkMeasurements, LinkRanges, Prior, run
>>> anchors = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
>>> agent = np.array([3.0, 4.0])
>>> links = np.array([[3, 0], [3, 1], [3, 2]])
>>> r = np.linalg.norm(agent - anchors, axis=1)
>>> meas = LinkMeasurements(4, 2, [0, 1, 2], anchors[None], [links],
...                         ranges={"corr": LinkRanges.single(r, np.full(3, 0.01))})
>>> rng = np.random.default_rng(0)
>>> prior = Prior(rng.uniform(-5.0, 15.0, (1, 500, 2)))
>>> # the plain Gaussian: from a prior far wider than σ = 0.1 m every link must pull; the
>>> # default evidence bound (outlier_nats = 10) gives no pull beyond ~0.45 m of a range here
>>> opts = DirectOptions(likelihood="gaussian", ranges="corr", outlier_nats=np.inf)
>>> res = run(meas, prior, rng, opts)
>>> res.estimates.shape
(1, 1, 2)
>>> bool(np.linalg.norm(res.estimates[0, 0] - agent) < 0.5)
True

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

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from phyloc import _validate as v
from phyloc._jit import jit_seconds
from phyloc._validate import check_keys
from phyloc.errors import ValidationError
from phyloc.localization.direct.dpf import DPFOptions, Prior, predict, run_dpf
from phyloc.localization.direct.likelihoods import (
    DirectLikelihood,
    GaussianRangeLikelihood,
    MarginalDirectLikelihood,
)
from phyloc.localization.direct.measurements import LinkMeasurements
from phyloc.localization.direct.sampled_exchange import SAMPLE_KERNELS, SampledLikelihood
from phyloc.localization.likelihoods import Likelihood
from phyloc.localization.results import Result, Timing

LIKELIHOODS = ("marginal", "env", "gaussian")
"""Values of :attr:`DirectOptions.likelihood`."""
EXCHANGES = ("moments", "particles")
"""Values of :attr:`DirectOptions.exchange`."""


@dataclass(frozen=True)
class DirectOptions:
    """Options of every direct-family method (a recipe's ``[localization]`` keys).

    Parameters
    ----------
    dpf : DPFOptions
        Filter options; in a recipe table their keys (``n_particles``, ``n_iterations``,
        ``tempering``, ``resample_move``, …) sit beside the keys below.
    likelihood : {"marginal", "env", "gaussian"}
        The link likelihood (see the module docstring).
    exchange : {"moments", "particles"}
        What a neighbour shares: its mean and covariance (DiPNet Algorithm 1) or its particle
        set (sample-based exchange, DiPNet §V-B; the likelihood is then used without the
        neighbour's projected variance).
    sample_kernel : {"silverman", "none"}
        With ``exchange = "particles"``: Gaussian kernels of Silverman's width on the
        neighbour particles, or none (Dirac particles); see
        :class:`~phyloc.localization.direct.sampled_exchange.SampledLikelihood`.
    ranges : str
        Range estimator whose ranges the ``"gaussian"`` likelihood reads
        (``measurements.ranges[ranges]``).
    outlier_nats : float
        Bound on one link's evidence [nats] of the ``"marginal"`` and ``"gaussian"``
        likelihoods (``inf``: the plain marginal, the plain Gaussian of DiPNet §V-A). For the
        two-step methods it keeps a range whose thermal variance vanishes at high SNR while
        its NLOS bias does not from outweighing every other link.
    model_error_m : float
        Range model error [m] of the ``"marginal"`` and ``"gaussian"`` likelihoods (unresolved
        multipath; default 0), see
        :class:`~phyloc.localization.direct.likelihoods.MarginalDirectLikelihood` and
        :class:`~phyloc.localization.direct.likelihoods.GaussianRangeLikelihood`.
    one_sided : bool
        The ``"gaussian"`` likelihood's outlier component covers only ranges longer than the
        distance (NLOS biases are positive), see
        :class:`~phyloc.localization.direct.likelihoods.GaussianRangeLikelihood`. Default False: in
        the C2 networks of the high-SNR study it changed nothing the NLOS identification
        (``los_min_concentration``) had not already fixed, and with particle exchange and
        uncertain neighbours its floor pulls agents towards their neighbours.
    safeguards : bool
        False runs DiPNet Algorithm 1 as published (:meth:`DPFOptions.published`, keeping only
        ``n_particles``, ``n_iterations`` and ``interpolation`` of ``dpf``).
    process_std_m : float
        Random-walk std between snapshots [m] (tracking; DiPNet §II-C).
    resample_ess : float
        Resample between snapshots when the ESS falls below this fraction of Q.
    regularize : bool
        Jitter resampled particles (regularized particle filter, PF-BP eq. (32)).
    keep_particles : tuple of int
        Snapshots whose final particles and log weights ``run`` keeps in its diagnostics
        (``particles_at``); default none.
    """

    dpf: DPFOptions = field(default_factory=DPFOptions)
    likelihood: str = "marginal"
    exchange: str = "moments"
    sample_kernel: str = "silverman"
    ranges: str = "corr"
    outlier_nats: float = 10.0
    model_error_m: float = 0.0
    one_sided: bool = False
    safeguards: bool = True
    process_std_m: float = 1.0
    resample_ess: float = 0.5
    regularize: bool = True
    keep_particles: tuple = ()

    def __post_init__(self):
        if not isinstance(self.dpf, DPFOptions):
            raise ValidationError("dpf", type(self.dpf).__name__, "a DPFOptions")
        v.choice("likelihood", self.likelihood, LIKELIHOODS)
        v.choice("exchange", self.exchange, EXCHANGES)
        v.choice("sample_kernel", self.sample_kernel, SAMPLE_KERNELS)
        if not isinstance(self.ranges, str) or not self.ranges:
            raise ValidationError("ranges", self.ranges, "the name of a range estimator")
        if not float(self.outlier_nats) > 0:
            raise ValidationError("outlier_nats", self.outlier_nats, "> 0 (inf: off)")
        v.positive("model_error_m", self.model_error_m, allow_zero=True)
        v.positive("process_std_m", self.process_std_m, allow_zero=True)
        if not 0 <= float(self.resample_ess) <= 1:
            raise ValidationError("resample_ess", self.resample_ess, "in [0, 1]")
        keep = tuple(
            v.integer("keep_particles", t, minimum=0) for t in np.atleast_1d(self.keep_particles)
        )
        object.__setattr__(self, "keep_particles", keep)

    @classmethod
    def recipe_keys(cls) -> list[str]:
        """The keys of a flat recipe table: :class:`DPFOptions`'s and this class's own."""
        own = [f.name for f in dataclasses.fields(cls) if f.name != "dpf"]
        return [*(f.name for f in dataclasses.fields(DPFOptions)), *own]

    @classmethod
    def from_dict(cls, d: dict, section: str = "localization") -> DirectOptions:
        """From a flat recipe table: this class's keys and those of :class:`DPFOptions`."""
        own = [f.name for f in dataclasses.fields(cls) if f.name != "dpf"]
        dpf_keys = [f.name for f in dataclasses.fields(DPFOptions)]
        check_keys(d, [*dpf_keys, *own], section)
        v.check_types(cls, {k: d[k] for k in own if k in d}, section)
        v.check_types(DPFOptions, d, section)
        dpf = DPFOptions(**{k: d[k] for k in dpf_keys if k in d})
        return cls(dpf=dpf, **{k: d[k] for k in own if k in d})

    def filter_options(self) -> DPFOptions:
        """The filter options of snapshot 0 (the published filter drops every safeguard)."""
        if self.safeguards:
            return self.dpf
        return DPFOptions.published(
            n_particles=self.dpf.n_particles,
            n_iterations=self.dpf.n_iterations,
            interpolation=self.dpf.interpolation,
        )


def link_likelihood(measurements: LinkMeasurements, t: int, options: DirectOptions) -> Likelihood:
    """The link likelihood of snapshot ``t`` that ``options.likelihood`` names."""
    m = measurements
    links, agent_of, n = m.links[t], m.agent_of_node(), m.n_agents
    usable = m.usable_links(t)
    if options.exchange == "particles":
        moments = dataclasses.replace(options, exchange="moments")
        return SampledLikelihood(link_likelihood(m, t, moments), kernel=options.sample_kernel)
    if options.likelihood != "gaussian":
        table = m.table(t)
        if not usable.all():  # only the links an NLOS identification kept
            keep = np.flatnonzero(usable)
            table, links = table.select(keep), links[keep]
    if options.likelihood == "marginal":
        return MarginalDirectLikelihood(
            table,
            links,
            agent_of,
            n,
            window_m=m.window_m,
            ways=m.ways,
            outlier_nats=options.outlier_nats,
            model_error_m=options.model_error_m,
        )
    if options.likelihood == "env":
        return DirectLikelihood(
            table,
            links,
            agent_of,
            n,
            interpolation=options.dpf.interpolation,
            window_m=m.window_m,
            ways=m.ways,
        )
    rs = m.range_set(options.ranges)
    return GaussianRangeLikelihood(
        rs.range_m[t],
        rs.variance_m2[t],
        rs.valid[t] & usable,
        links,
        agent_of,
        n,
        outlier_nats=options.outlier_nats,
        model_error_m=options.model_error_m,
        one_sided=options.one_sided,
    )


def run(
    measurements: LinkMeasurements,
    prior: Prior,
    rng: np.random.Generator,
    options: DirectOptions | None = None,
) -> Result:
    """Localize the agents of every snapshot with the EL-DPF (DiPNet Algorithm 1).

    Parameters
    ----------
    measurements : LinkMeasurements
        Links, anchors and tables or ranges per snapshot (no agent positions).
    prior : Prior
        Prior particles ``[n_agents, Q, dim]`` of snapshot 0 (agents in
        ``measurements.agent_nodes`` order), with a log density for the resample-move
        safeguard.
    rng : numpy.random.Generator
        The stream of the filter's random moves and of the prediction between snapshots.
    options : DirectOptions, optional
        Default: ``DirectOptions()`` (safeguarded DiPNet with the marginal likelihood).

    Returns
    -------
    Result
        ``estimates [T, n_agents, dim]`` (posterior means), ``covariances [T, n_agents, dim,
        dim]`` (the published covariances), the final ``particles`` / ``log_weights`` and
        ``diagnostics``:

        ``mean_history [T, K+1, n_agents, dim]`` published means after each iteration
        (0 = prior); ``cov_trace_history [T, K+1, n_agents]`` trace of the published
        covariances [m²]; ``ess_history [T, K, n_agents]`` effective sample size after
        weighting; ``n_degenerate [T]`` weight vectors that fell back to uniform;
        ``annealing_steps [T]`` tempering steps of the safeguarded filter; ``setup_s`` [s]
        building the likelihoods; ``jit_s`` [s] compiling Numba kernels (or loading them
        from the cache) during the run, left out of ``setup_s`` and of the timing;
        ``particles_at`` ``{t: (particles, log_weights)}`` at the
        snapshots of ``options.keep_particles``.

        ``timing.wall_s`` is the filter's time (prediction and iterations, likelihood setup
        and JIT compilation excluded) and ``timing.agent_iterations = T·n_agents·K``, so
        ``timing.per_agent_iteration_s`` is the cost of one agent-iteration.
    """
    if not isinstance(measurements, LinkMeasurements):
        raise ValidationError("measurements", type(measurements).__name__, "LinkMeasurements")
    options = DirectOptions() if options is None else options
    m = measurements
    is_anchor = m.is_anchor
    agents = m.agent_nodes
    opts0 = options.filter_options()
    fixed = dataclasses.replace(opts0, resample_move=False)
    steps, setup_s, step_s = [], 0.0, np.zeros(m.n_snapshots)
    kept, prev = {}, None
    jit0 = jit_seconds()
    for t in range(m.n_snapshots):
        t0, j0 = time.perf_counter(), jit_seconds()
        lik = link_likelihood(m, t, options)
        setup_s += time.perf_counter() - t0 - (jit_seconds() - j0)
        if t == 0:
            j1 = jit_seconds()
            res = run_dpf(lik, prior, m.anchor_positions[0], is_anchor, rng, opts0)
            step_s[t] = res.seconds - (jit_seconds() - j1)  # run_dpf times its whole call
        else:
            t1, j1 = time.perf_counter(), jit_seconds()
            X, lw = predict(
                prev,
                rng,
                process_std_m=options.process_std_m,
                resample_ess=options.resample_ess,
                regularize=options.regularize,
            )
            pred_s = time.perf_counter() - t1
            res = run_dpf(
                lik, Prior(X, None, prior.label, lw), m.anchor_positions[t], is_anchor, rng, fixed
            )
            step_s[t] = pred_s + res.seconds - (jit_seconds() - j1)
        if t in options.keep_particles:
            kept[t] = (res.particles, res.log_weights)
        prev = res  # the only particle set kept: a long track holds T small summaries
        steps.append(dataclasses.replace(res, particles=None, log_weights=None))
    last = prev
    n_agents = agents.size
    timing = Timing(
        wall_s=float(step_s.sum()),
        step_s=step_s,
        agent_s=step_s / max(n_agents, 1),
        agent_iterations=int(sum(r.agent_iterations for r in steps)),
    )
    diagnostics = {
        "mean_history": np.stack([r.mean_history[:, agents] for r in steps]),
        "cov_trace_history": np.stack([r.cov_trace_history for r in steps]),
        "ess_history": np.stack([r.ess_history for r in steps]),
        "n_degenerate": np.array([r.n_degenerate for r in steps]),
        "annealing_steps": np.array([r.annealing_steps for r in steps]),
        "setup_s": setup_s,
        "jit_s": jit_seconds() - jit0,
        "particles_at": kept,
    }
    return Result(
        estimates=np.stack([r.means[agents] for r in steps]),
        covariances=np.stack([r.covs[agents] for r in steps]),
        timing=timing,
        particles=last.particles,
        log_weights=last.log_weights,
        diagnostics=diagnostics,
        label=last.label,
    )

"""Nonparametric belief propagation (NBP) for static 2-D cooperative localization (POA-NBP §II-B).

Every agent ``j`` holds a particle belief of ``N_S`` samples. One iteration ``l`` (parallel,
Jacobi schedule: every agent uses its neighbours' beliefs of iteration ``l − 1``):

1. **Message filtering** (POA-NBP eqs. (4), (5)). For every link ``i → j`` with range
   ``ẑ_{i→j}``, the message is the particle set ``y_k = x_i^{(k)} + (ẑ_{i→j} − ε_k)·u_k`` with
   ``x_i^{(k)}`` the ``N_S`` belief samples of ``i`` (the anchor position for an anchor),
   ``ε_k`` drawn from the error model and ``u_k`` a uniformly random unit vector. With
   ``jacobian_weights`` the samples are weighted by ``|ẑ − ε_k|``, which turns the polar
   sampling density ``p_ε(ẑ − ρ)/(2πρ)`` into the message density ``∝ p(ẑ | ρ)`` in the plane
   (POA-NBP eq. (5) draws them with equal weights; ``jacobian_weights=False`` reproduces
   that). As in the paper (POA-NBP eq. (6): the outgoing message is the belief), neighbours
   send their full belief, not the extrinsic one.
2. **Kernel density estimates** (POA-NBP eq. (7)): an isotropic Gaussian kernel per message
   with bandwidth ``h`` chosen by least-squares cross-validation (``bandwidth="lscv"``, the
   paper's choice, its ref. [32]), Silverman's rule of thumb (``"silverman"``:
   ``h = σ̄·n_eff^{−1/6}``, ``σ̄² = ½ tr Σ̂``, the 2-D normal-reference rule) or a fixed value
   [m]. Silverman's rule is built for unimodal densities and over-smooths the ring-shaped range
   messages (``σ̄`` is of the order of the range); LSCV picks ``h`` on the grid
   ``√2·h_S·2^{−t/2}``, ``t = 0 … 12``, by minimising the exact Gaussian-kernel LSCV score
   (computed on a random subset of at most ``lscv_max_samples`` samples, rescaled by
   ``(n_sub/n)^{1/6}``). Every bandwidth is at least ``min_bandwidth_m``.
3. **Message multiplication** by importance sampling (POA-NBP eqs. (8), (9)): draw ``N_S``
   samples ``x^{(k)}`` from a proposal ``q`` and weight them by
   ``log w = Σ_{agent i} log μ̂_{i→j}(x) + Σ_{anchor i} log p(ẑ_{i→j} | x, x_i) + log p(x)
   − log q(x)`` (anchor messages are evaluated exactly with the error model's likelihood, the
   prior ``p(x)`` is uniform over the region); weights are normalised with logsumexp. Samples
   outside the region or outside a polygon proposal get weight exactly zero. Proposals:

   - ``"min_entropy"`` (POA-NBP ref. [19], 'NBP min.'): the KDE of the incoming message of
     least entropy, measured by its Gaussian upper bound ``½ log det(Σ̂ + h² I)``;
   - ``"mixture"`` (POA-NBP ref. [27]): ``(1 − ε)·(1/M) Σ_m μ̂_m + ε·U(region)``,
     ``ε = uniform_fraction``;
   - ``"parsimonious"`` (POA-NBP ref. [25], 'NBP par.'): ``(1 − ε)·KDE(previous belief) +
     ε·U(region)``, the KDE of the agent's weighted samples of its last update with
     Silverman's bandwidth; while the belief is still the uniform prior the agent uses
     ``"mixture"`` instead;
   - ``"auxiliary"`` (POA-NBP ref. [27], 'NBP aux.': "the proposal distribution is augmented
     with an auxiliary variable [that] takes the messages from anchors into account"): for an
     agent with at least one anchor neighbour, ``q(x) ∝ Π_{anchor a} p(ẑ_{a→j} | x, x_a)``
     restricted to the region, sampled by auxiliary-variable importance resampling: draw
     ``L·N_S`` candidates (``L = aux_oversampling``) from the equal mixture of the anchor
     messages' KDEs — the auxiliary variable is the mixture component, then the candidate
     index —, weight them by ``Π_a p(ẑ_a | x) / mixture(x)`` (zero outside the region) and
     keep ``N_S`` by systematic resampling. In the weights the anchor terms cancel against
     ``q``: the final weight is the product of the agent messages' KDEs times the prior.
     Without an anchor neighbour the agent uses ``"mixture"`` (also when no candidate lands
     in the anchors' support). This is *our interpretation*: the sampling details of
     ref. [27] (V. Savic and S. Zazo, Ad Hoc Networks 11(1), 2013, where the auxiliary
     variable enters the importance density as in an auxiliary particle filter) were not
     available to us beyond the POA-NBP paper's one-sentence description;
   - ``"polygon"`` (POA-NBP eq. (21)): uniform in the agent's convex support region
     ``q = 1/A_p`` inside, 0 outside. The regions come from the prior
     (``StaticPrior.polygons``) or are computed by the method from the measurements
     (``NBPOptions.support``: POA, POA-NBP Algorithm 1, or the ellipse baseline).

4. **Estimate and resampling**: the MMSE estimate is the weighted mean (POA-NBP §II-B); the
   belief for the next iteration is a systematic resample of ``N_S`` equally weighted samples.

Agents start from a uniform belief over the region (uniform over their polygon when the
polygon proposal is used: the polygon contains the support of the marginal, POA-NBP §III). An
agent whose belief is still the uniform prior sends no messages (they carry almost no
information, as in POA-NBP ref. [3]); an agent without any usable message keeps its belief, so
an isolated agent stays uniform over the region and its estimate is the region's centre (never
NaN). If every proposal sample of an agent has zero weight the agent keeps its previous belief
too.

**Convergence**: with ``c_l`` the mean over agents of ``‖x̂^{(l)} − x̂^{(l−1)}‖``, the run has
converged at the first ``l`` with ``c_l < convergence_tol_m`` or ``c_l > (1 −
convergence_rel)·c_{l−1}``: NBP estimates keep moving by their Monte Carlo error (≈ 0.1–0.8 m
per iteration at ``N_S = 200`` in the POA-NBP §V network), so an absolute threshold alone is
never met; the plateau of ``c_l`` is the truth-free counterpart of POA-NBP §V footnote 5 (the
average error no longer changes notably). ``stop_on_convergence`` ends the run there.

The messages, their KDEs and the proposals' importance sampling are
:mod:`phyloc.localization.static.messages` and :mod:`phyloc.localization.static.kde`; this
module runs the iterations (:func:`run_nbp`).

**Cost**: the ``O(|S_{→j}|·N_S²)`` KDE evaluation (POA-NBP eq. (8)) is ``kde_logpdf_kernel``
(numba, serial) and the LSCV score, O(N_S²) per message up to ``lscv_max_samples``, is
``lscv_grid_kernel``, both in the private module
:mod:`phyloc.localization.static._nbp_kernels` (their plain-NumPy references are test code,
``tests/naive_static.py``). Measured in the POA-NBP §V network (≈ 12.5 links per agent, one
loaded 2-core machine): ≈ 3 / 5 / 10 / 24 ms per agent and iteration at N_S = 100 / 200 / 400
/ 800 with the polygon proposal — at these sizes the O(N_S) per-message work and the capped
LSCV weigh as much as the quadratic KDE, which itself grows as N_S² (≈ 0.2 / 0.9 / 4.6 ms for
10 messages at N_S = 100 / 200 / 400, 20–40× faster than the NumPy reference, depending on the
load).

**Communication and operation counts** (``Result.diagnostics``): every agent broadcasts its
belief, ``N_S`` equally weighted (resampled) samples of 2 coordinates, once per iteration;
the receiver forms the range message and chooses its bandwidth itself, so nothing else is sent:
``floats_per_link_iteration = 2·N_S``. The support phase (POA, POA-NBP Algorithm 1, or the
ellipses) exchanges its regions before NBP starts: ``support_floats_per_link_iteration``
(POA: 2 per polygon vertex, :attr:`~phyloc.localization.static.poa_network.POAResult.
floats_per_link_iteration`; ellipses: 5, centre and symmetric shape matrix). The operations
counted are the ones POA-NBP §II-B calls dominant, the Gaussian kernel evaluations of the
message KDEs (POA-NBP eq. (7)) in the importance weights (POA-NBP eq. (8), ``O(|S_{→j}|·N_S²)``)
and in the proposal densities (the mixture, parsimonious and auxiliary proposals evaluate
KDEs at their samples or candidates): ``P·K`` for a KDE of ``K`` centres at ``P`` points
(``kernel_evaluations``); not counted are the exact anchor likelihoods (``N_S`` per anchor
link), the ``O(N_S)`` message filtering, the LSCV bandwidth search and the resampling.
``operations_per_node`` adds the support's own count (POA:
:attr:`~phyloc.localization.static.poa_network.POAResult.operations_per_node`; ellipses: not
counted, 0).

Support regions: any object with ``.area`` [m²], ``.contains(points [n, 2]) -> bool [n]`` and
``.sample_uniform(n, rng) -> [n, 2]`` (e.g.
:class:`phyloc.localization.static.polygons.ConvexPolygon` or
:class:`~phyloc.localization.static.ellipses.EllipseRegion`).

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc._validate import from_table
from phyloc.errors import ValidationError
from phyloc.localization.particles import systematic_indices
from phyloc.localization.results import Result, Timing
from phyloc.localization.static.ellipses import ellipse_outer_approximation
from phyloc.localization.static.kde import _lscv, _silverman, _weighted_cov
from phyloc.localization.static.messages import (
    PROPOSALS,
    Message,
    _check_polygon,
    _product,
    _uniform_region,
    range_message_samples,
)
from phyloc.localization.static.poa_network import poa
from phyloc.localization.static.static_ranges import (
    LINK_MODES,
    StaticMeasurements,
    StaticNetwork,
    StaticPrior,
    check_inputs,
    convergence_iteration,
)

#: Bandwidth rules (or a float in metres).
BANDWIDTH_RULES = ("lscv", "silverman")
#: Support regions of the polygon proposal that NBP computes itself (:class:`NBPOptions`).
SUPPORTS = ("none", "poa", "ellipse")


@dataclass(frozen=True)
class NBPOptions:
    """Options of :func:`run_nbp` (shared ``[localization]`` keys of a static recipe, or one
    label's ``[localization.<label>]`` table).

    Parameters
    ----------
    n_samples : int
        ``N_S`` samples per belief and message (200).
    n_iterations : int
        ``N_iter`` message-passing iterations (10).
    proposal : {"min_entropy", "mixture", "parsimonious", "polygon", "auxiliary"}
        Importance-sampling proposal (module docstring). Default ``"mixture"``.
    support : {"none", "poa", "ellipse"}
        Support regions of the ``"polygon"`` proposal that the method computes from the
        measurements when the prior brings none (``StaticPrior.polygons``): ``"poa"`` the
        polygon outer-approximation (POA-NBP Algorithm 1, ``N_E = poa_n_edges``,
        ``N_FS = poa_n_fs``, offsets drawn from the run's generator first), ``"ellipse"`` the
        ellipse outer-approximation of ``poa_n_fs`` iterations, ``"none"`` (default) no
        support (the polygon proposal then needs ``StaticPrior.polygons``).
    poa_n_edges, poa_n_fs : int
        ``N_E >= 3`` and ``N_FS >= 1`` of the support (16, 2; POA-NBP §V-B).
    uniform_fraction : float
        ``ε`` of the mixture/parsimonious proposals, in [0, 1] (0.1).
    aux_oversampling : int
        ``L >= 1``: candidates per sample of the auxiliary proposal (4).
    bandwidth : {"lscv", "silverman"} or float
        Message KDE bandwidth rule or a fixed value [m] ("lscv").
    min_bandwidth_m : float
        Lower bound of every bandwidth [m] (0.01).
    lscv_max_samples : int
        Subset size of the LSCV score (256).
    jacobian_weights : bool
        Weight message samples by ``|z − ε|`` (True; False: equal weights, POA-NBP eq. (5)).
    link_mode : {"own", "both"}
        ``"own"``: agent ``j`` uses the ranges it measured, ``ẑ_{i→j}`` (distributed);
        ``"both"``: also ``ẑ_{j→i}`` (both factors of POA-NBP eq. (3)).
    region_prior : bool
        Uniform prior over the region (zero weight outside) (True).
    convergence_tol_m : float
        Mean estimate change [m] below which the run has converged (0.01).
    convergence_rel : float
        ... or the relative decrease of that change below which it has reached its Monte
        Carlo noise floor, in [0, 1) (0.25; 0 disables)
        (:func:`~phyloc.localization.static.static_ranges.convergence_iteration`).
    stop_on_convergence : bool
        End the run at the convergence iteration (False: run ``n_iterations``).
    """

    n_samples: int = 200
    n_iterations: int = 10
    proposal: str = "mixture"
    support: str = "none"
    poa_n_edges: int = 16
    poa_n_fs: int = 2
    uniform_fraction: float = 0.1
    aux_oversampling: int = 4
    bandwidth: str | float = "lscv"
    min_bandwidth_m: float = 0.01
    lscv_max_samples: int = 256
    jacobian_weights: bool = True
    link_mode: str = "own"
    region_prior: bool = True
    convergence_tol_m: float = 0.01
    convergence_rel: float = 0.25
    stop_on_convergence: bool = False

    def __post_init__(self):
        for name, lo in (
            ("n_samples", 2),
            ("n_iterations", 1),
            ("lscv_max_samples", 8),
            ("poa_n_edges", 3),
            ("poa_n_fs", 1),
            ("aux_oversampling", 1),
        ):
            object.__setattr__(self, name, v.integer(name, getattr(self, name), minimum=lo))
        v.choice("proposal", self.proposal, PROPOSALS)
        v.choice("support", self.support, SUPPORTS)
        v.choice("link_mode", self.link_mode, LINK_MODES)
        eps = v.finite("uniform_fraction", self.uniform_fraction)
        if not 0.0 <= eps <= 1.0:
            raise ValidationError("uniform_fraction", eps, "must be in [0, 1]")
        object.__setattr__(self, "uniform_fraction", eps)
        if isinstance(self.bandwidth, str):
            v.choice("bandwidth", self.bandwidth, BANDWIDTH_RULES)
        else:
            object.__setattr__(self, "bandwidth", v.positive("bandwidth", self.bandwidth))
        for name in ("min_bandwidth_m", "convergence_tol_m"):
            object.__setattr__(self, name, v.positive(name, getattr(self, name)))
        rel = v.finite("convergence_rel", self.convergence_rel)
        if not 0.0 <= rel < 1.0:
            raise ValidationError("convergence_rel", rel, "must be in [0, 1)")
        object.__setattr__(self, "convergence_rel", rel)

    @classmethod
    def from_dict(cls, d: dict, section: str = "localization") -> NBPOptions:
        """Build from a recipe table; unknown keys are errors naming the closest valid key."""
        return from_table(cls, d, section)


def _check_polygons(polygons, net: StaticNetwork):
    """Map ``polygons`` (sequence over agents or over all nodes, or dict node → polygon) to a
    list over agents."""
    n_ag, n = net.n_agents, net.ranges.shape[0]
    if polygons is None:
        return [None] * n_ag
    if isinstance(polygons, dict):
        per = [polygons.get(int(j)) for j in net.agents]
    else:
        seq = list(polygons)
        if len(seq) == n_ag:
            per = seq
        elif len(seq) == n:
            per = [seq[j] for j in net.agents]
        else:
            raise ValidationError(
                "polygons", f"sequence of length {len(seq)}", f"must have {n_ag} (agents) or {n}"
            )
    out = []
    for a, p in enumerate(per):
        if p is not None:
            for attr in ("area", "contains", "sample_uniform"):
                if not hasattr(p, attr):
                    _check_polygon(p, f"polygons[{a}]")  # raises, naming the agent
            area = float(p.area)
            if not math.isfinite(area) or area < 0:
                raise ValidationError(f"polygons[{a}].area", area, "must be finite and >= 0")
            if area == 0.0:  # empty / point / segment: no density to sample from
                p = None
        out.append(p)
    return out


def _bandwidth(samples, weights, opt, rng):
    if isinstance(opt.bandwidth, float):
        h = opt.bandwidth
    elif opt.bandwidth == "silverman":
        h = _silverman(samples, weights)
    else:
        h = _lscv(samples, weights, rng, opt.lscv_max_samples)
    return max(h, opt.min_bandwidth_m)


def _support(meas: StaticMeasurements, prior: StaticPrior, opt: NBPOptions, rng):
    """Support regions of the polygon proposal, their setup time per agent [s] and their
    diagnostics (see :func:`run_nbp`)."""
    if prior.polygons is not None:
        diag = {
            "support": "prior",
            "support_operations_per_node": prior.polygon_operations_per_node,
            "support_floats_per_link_iteration": prior.polygon_floats_per_link_iteration,
        }
        return prior.polygons, prior.polygon_time_per_node_s, diag
    if opt.support == "poa":
        res = poa(
            meas.positions,
            meas.ranges,
            meas.is_anchor,
            rng=rng,
            n_edges=opt.poa_n_edges,
            n_iterations=opt.poa_n_fs,
            region=prior.region,
        )
        t = float(res.time_s.sum(axis=0).mean()) if meas.n_agents else 0.0
        diag = {
            "support": "poa",
            "poa_area_m2": res.area_history,
            "poa_time_per_node_s": t,
            "poa_dropped": res.dropped,
            "support_operations_per_node": res.operations_per_node,
            "support_floats_per_link_iteration": res.floats_per_link_iteration,
        }
        return list(res.polygons), t, diag
    if opt.support == "ellipse":
        t0 = time.perf_counter()
        ell = ellipse_outer_approximation(
            meas.positions,
            meas.ranges,
            meas.is_anchor,
            n_iterations=opt.poa_n_fs,
            region=prior.region,
        )
        t = (time.perf_counter() - t0) / max(meas.n_agents, 1)
        diag = {
            "support": "ellipse",
            "ellipse_area_m2": ell.area_history,
            "support_operations_per_node": 0.0,  # not counted
            # centre (2) and symmetric shape matrix (3) per broadcast, N_FS - 1 broadcasts
            "support_floats_per_link_iteration": 5.0 if opt.poa_n_fs > 1 else math.nan,
        }
        return ell.regions(), t, diag
    raise ValidationError(
        "polygons", None, "proposal='polygon' needs StaticPrior.polygons or a support option"
    )


def run_nbp(
    measurements: StaticMeasurements,
    prior: StaticPrior,
    rng: np.random.Generator,
    options: NBPOptions | None = None,
) -> Result:
    """Localize the agents of a static network with NBP (POA-NBP §II-B, §IV-B).

    Parameters
    ----------
    measurements : StaticMeasurements
        Ranges ``ranges[j, i] = ẑ_{i→j}``, anchors and their positions, error model.
    prior : StaticPrior
        ``region`` (support of the uniform prior) and, for ``proposal="polygon"``, optional
        precomputed support ``polygons`` (else ``options.support`` computes them). ``None``
        entries and degenerate polygons (area 0) fall back to the uniform proposal over the
        region.
    rng : numpy.random.Generator
        Draws, in order: the support (``support="poa"`` without prior polygons: the anchor
        polygon offsets), the initial beliefs, then per iteration and agent the messages,
        bandwidth subsets, proposal samples and resampling.
    options : NBPOptions, optional

    Returns
    -------
    Result
        ``estimates [n_iterations, n_agents, 2]``: the MMSE estimate (weighted mean) after
        each iteration (iteration 1 first; the initial uniform belief is not included);
        ``covariances [n_iterations, n_agents, 2, 2]``: the weighted sample covariance of
        each agent's last update (of its initial belief while never updated); ``particles
        [n_agents, N_S, 2]`` and ``log_weights [n_agents, N_S]``: the weighted samples of each
        agent's last update (``-inf`` = zero weight); ``timing``: ``step_s`` the wall time of
        each iteration, ``agent_s`` the mean time per agent update in it. ``diagnostics``:

        ``ess`` [n_iterations, n_agents]
            effective sample size of each update (0 where the agent was not updated);
        ``agent_time_s`` [n_iterations, n_agents]
            wall time of each agent's update [s];
        ``converged_iteration`` int or None
            :func:`~phyloc.localization.static.static_ranges.convergence_iteration`;
        ``setup_time_per_node_s`` float
            time per agent spent on the proposal support before the first iteration [s]
            (POA, ellipses, or ``prior.polygon_time_per_node_s``; 0 without support) — part of
            the time to convergence of POA-NBP Table I;
        ``floats_per_link_iteration`` float
            ``2·N_S``: floats an agent sends a neighbour per iteration (module docstring);
        ``kernel_evaluations`` [n_iterations, n_agents] int
            KDE kernel evaluations of each agent update
            (:attr:`~phyloc.localization.static.messages.Product.kernel_evaluations`);
        ``kde_operations_per_node`` float
            their sum over the iterations, mean over agents;
        ``support_operations_per_node``, ``support_floats_per_link_iteration`` float
            the support phase's operations per agent and floats per link and broadcast (0 and
            NaN without a support; from the prior's ``polygon_operations_per_node`` and
            ``polygon_floats_per_link_iteration`` with ``"prior"``);
        ``operations_per_node`` float
            ``kde_operations_per_node + support_operations_per_node``;
        ``support`` str
            ``"prior"``, ``"poa"``, ``"ellipse"`` or ``"none"``; with ``"poa"`` also
            ``poa_area_m2`` [N_FS, n_agents], ``poa_time_per_node_s``, ``poa_dropped``
            [k, 2] (dropped measurements ``(i, j)``); with ``"ellipse"`` ``ellipse_area_m2``.

    Examples
    --------
    >>> anchors = np.array([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0], [20.0, 20.0]])
    >>> z = np.full((5, 5), np.nan)  # node 4, an agent, measured its ranges to the anchors
    >>> z[4, :4] = [13.2, 17.2, 11.6, 16.0]
    >>> meas, prior = StaticMeasurements(z, [0, 1, 2, 3], anchors), StaticPrior((0, 0, 20, 20))
    >>> res = run_nbp(meas, prior, np.random.default_rng(3),
    ...               NBPOptions(n_samples=100, n_iterations=3))
    >>> res.estimates.shape, res.particles.shape
    ((3, 1, 2), (1, 100, 2))
    """
    t_wall = time.perf_counter()
    opt = options if options is not None else NBPOptions()
    if not isinstance(opt, NBPOptions):
        raise ValidationError("options", type(opt).__name__, "must be NBPOptions")
    meas, prior = check_inputs(measurements, prior, rng)
    net = meas.network
    reg = prior.region
    model = meas.error_model
    diag: dict = {
        "support": "none",
        "support_operations_per_node": 0.0,
        "support_floats_per_link_iteration": math.nan,
    }
    setup_s = 0.0
    polygons = None
    if opt.proposal == "polygon":
        polygons, setup_s, diag = _support(meas, prior, opt, rng)
    polys = _check_polygons(polygons, net)

    n_ag, ns = net.n_agents, opt.n_samples
    node_to_agent = {int(j): a for a, j in enumerate(net.agents)}
    links = [net.links(int(j), opt.link_mode) for j in net.agents]

    # initial beliefs: uniform over the region (or the agent's polygon)
    B = np.empty((n_ag, ns, 2))
    informed = np.zeros(n_ag, bool)
    for a in range(n_ag):
        if opt.proposal == "polygon" and polys[a] is not None:
            B[a] = np.asarray(polys[a].sample_uniform(ns, rng), dtype=np.float64).reshape(ns, 2)
            informed[a] = True
        else:
            B[a] = _uniform_region(ns, reg, rng)
    est = B.mean(axis=1)
    samples, weights = B.copy(), np.full((n_ag, ns), 1.0 / ns)
    cov = np.array([_weighted_cov(B[a], weights[a])[1] for a in range(n_ag)]).reshape(n_ag, 2, 2)

    L = opt.n_iterations
    out_est = np.empty((L, n_ag, 2))
    out_cov = np.empty((L, n_ag, 2, 2))
    out_t = np.zeros((L, n_ag))
    step_t = np.zeros(L)
    out_ess = np.zeros((L, n_ag))
    out_kernel = np.zeros((L, n_ag), dtype=np.int64)
    n_done = L
    for it in range(L):
        t_it = time.perf_counter()
        B_new, informed_new, est_new = B.copy(), informed.copy(), est.copy()
        for a in range(n_ag):
            t0 = time.perf_counter()
            prop = opt.proposal
            if prop == "parsimonious" and not informed[a]:
                prop = "mixture"  # the previous belief is still the uniform prior
            msgs = []
            for i, z in links[a]:
                if net.is_anchor[i]:
                    src = np.broadcast_to(net.positions[i], (ns, 2))
                    anchor = (net.positions[i], z)
                else:
                    b = node_to_agent[i]
                    if not informed[b]:
                        continue
                    src, anchor = B[b], None
                if anchor is not None and prop in ("polygon", "parsimonious"):
                    msgs.append(Message(np.zeros((0, 2)), np.zeros(0), 1.0, anchor))
                    continue  # the exact likelihood is all the product needs
                y, w = range_message_samples(src, z, model, rng, jacobian=opt.jacobian_weights)
                msgs.append(Message(y, w, _bandwidth(y, w, opt, rng), anchor))
            if msgs:
                prev = None
                if prop == "parsimonious":  # KDE of the weighted samples of the last update
                    h = max(_silverman(samples[a], weights[a]), opt.min_bandwidth_m)
                    prev = Message(samples[a], weights[a], h)
                prod = _product(
                    msgs,
                    ns,
                    prop,
                    rng,
                    reg,
                    opt.uniform_fraction,
                    model,
                    polygon=polys[a],
                    previous=prev,
                    region_prior=opt.region_prior,
                    oversampling=opt.aux_oversampling,
                )
                out_kernel[it, a] = prod.kernel_evaluations
                if prod.ok:
                    w = prod.weights
                    est_new[a] = w @ prod.samples
                    idx = systematic_indices(w / w.sum(), ns, rng)
                    B_new[a] = prod.samples[idx]
                    informed_new[a] = True
                    samples[a], weights[a] = prod.samples, w
                    cov[a] = _weighted_cov(prod.samples, w / w.sum())[1]
                    out_ess[it, a] = prod.ess
            out_t[it, a] = time.perf_counter() - t0
        B, informed, est = B_new, informed_new, est_new
        out_est[it] = est
        out_cov[it] = cov
        step_t[it] = time.perf_counter() - t_it
        if opt.stop_on_convergence and convergence_iteration(
            out_est[: it + 1], opt.convergence_tol_m, opt.convergence_rel
        ):
            n_done = it + 1
            break
    out_est, out_cov, out_t, out_ess, out_kernel = (
        out_est[:n_done],
        out_cov[:n_done],
        out_t[:n_done],
        out_ess[:n_done],
        out_kernel[:n_done],
    )
    kde_ops = float(out_kernel.sum(axis=0).mean()) if n_ag else 0.0
    diag.update(
        floats_per_link_iteration=float(2 * ns),
        kernel_evaluations=out_kernel,
        kde_operations_per_node=kde_ops,
        operations_per_node=kde_ops + float(diag["support_operations_per_node"]),
        ess=out_ess,
        agent_time_s=out_t,
        converged_iteration=convergence_iteration(
            out_est, opt.convergence_tol_m, opt.convergence_rel
        ),
        setup_time_per_node_s=setup_s,
    )
    with np.errstate(divide="ignore"):
        log_w = np.log(weights)
    return Result(
        estimates=out_est,
        covariances=out_cov,
        timing=Timing(
            wall_s=time.perf_counter() - t_wall,
            step_s=step_t[:n_done],
            agent_s=out_t.mean(axis=1) if n_ag else np.zeros(n_done),
            agent_iterations=n_done * n_ag,
        ),
        particles=samples,
        log_weights=log_w,
        diagnostics=diag,
        label=f"nbp.{opt.proposal}",
    )

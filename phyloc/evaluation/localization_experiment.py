"""Direct versus two-step network localization (DiPNet Fig. 5).

A recipe of ``kind = "localization"`` runs, for every scenario token, network size and
realization: a network (``[network]``, anchor-free and fully meshed in the paper), channel draws,
received signals and correlation tables, the range estimators, and then every method of
``experiment.methods`` under every initialization of ``experiment.inits`` — all on the *same*
waveforms and, per initialization, from the *same* prior particles (per particle count).

A network with motion (``[network.motion]``, or a stored dataset with several snapshots) is
localized over **all** its snapshots: snapshot 0 from the prior, every later snapshot from the
prediction of the previous belief with the methods' mobility model (the DPF of
:func:`phyloc.localization.direct.run`, ``process_std_m``; DiPNet §II-C), the same model for
every agent. Errors are then pooled over snapshots; the RMSE per snapshot is a series. Methods::

    ``dipnet``            DiPNet with phyloc's safeguards: the marginal equivalent likelihood
                          (:class:`~phyloc.localization.likelihoods.MarginalDirectLikelihood`,
                          DiPNet eq. (22) marginalized over the neighbour's projected uncertainty
                          instead of the ENV of DiPNet eq. (26)), adaptive tempering,
                          resample-move, covariance floor (:class:`~phyloc.localization.DPFOptions`)
    ``dipnet_published``  DiPNet Algorithm 1 as published: DiPNet eqs. (25)–(28) with the ENV, no
                          safeguards
    ``corr`` / ``first_peak`` / ``sage``   the two-step EL-DPF on that estimator's ranges with the
                          ZZB ranging variance (DiPNet §V-A), same safeguards as ``dipnet``,
                          its per-link outlier bound ``outlier_nats`` included (``inf`` gives
                          DiPNet §V-A's plain Gaussian, whose error grows with the SNR in NLOS
                          channels: see :class:`~phyloc.localization.GaussianRangeLikelihood`)
    ``sage_los``          SAGE on LOS links only — an oracle benchmark (ground-truth NLOS rejection)

The methods are the direct family of :data:`phyloc.localization.METHODS` (any registered
direct method runs here too): per realization the experiment builds one
:class:`~phyloc.localization.LinkMeasurements` — the correlation tables and the ranges of every
estimator a method's ``inputs`` names — and calls ``method.run(measurements, prior, rng,
method.make_options([localization]))``; the truth enters only the metrics.

Initializations (labelled in every figure name)::

    ``truth_free`` (token ``<s>``)  Gaussian priors around a coarse two-step solution (MDS → SMACOF
                          on the correlation-peak ranges, the shorter of a pair's two
                          directions, then Cauchy-reweighted SMACOF so NLOS-biased ranges stop
                          pulling — one-sided: only ranges longer than the fit; links the NLOS
                          identification rejects left out; anchors fix the frame when present)
    ``informed`` (``<s>_informed``)  Gaussian priors around the truth plus N(0, σ0²) — an informed
                          start, not a truth-free result
    ``gauge`` (``<s>_gauge``)  the paper's uninformative anchor-free gauge priors (shows the
                          pitfall)

Figures: ``<method>.<token>.agents_<n>.framework_rmse_m`` (DiPNet eq. (4), pooled over
realizations and snapshots), ``<method>.<token>.agents_<n>.agent_snapshot_s`` (filter time per
agent and snapshot),
``<method>.<token>.agents_<n>.shape_difference_m`` (DiPNet eq. (1)),
``<method>.<token>.agents_<n>.ess_min`` (smallest effective sample size of any agent in any
iteration, mean over runs),
``start.<token>.agents_<n>.framework_rmse_m`` (the prior centres themselves: what a method
starts from — the coarse truth-free solution, or the perturbed truth),
``<method>.<token>.agents_<n>.framework_rmse_observable_m`` (DiPNet eq. (4) over the *observable*
pairs only: those whose distance the detected links determine, :func:`observable_pairs`),
``<token>.agents_<n>.unobservable_pair_fraction`` (the share of pairs left out there: no method,
the oracle included, can estimate them),
``<method>.<token>.agents_<n>.nees`` (normalized estimation error squared ``eᵀP⁻¹e`` of the
published covariance, per agent after rigid alignment, mean over agents and realizations:
``dim`` when calibrated) and ``.error_to_belief_ratio`` ``= sqrt(nees/dim)`` (> 1: overconfident;
``.error_to_belief_ratio_median`` the same from the median NEES over the median of χ²_dim, robust
to a few lost agents),
``<method>.runtime_per_agent_iteration_s``, ``<s>.link_bias.<los|nlos>_mean_m`` (correlation-peak
range bias, pooled over snapshots). Series: error CDFs at ``experiment.cdf_agents``, per
iteration at the largest network (snapshot 0): mean ESS, published std ``sqrt(tr C/dim)`` and
actual error of the published means; with several snapshots
``<method>.<token>.agents_<n>.rmse_by_snapshot``.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from phyloc import _validate as v
from phyloc.channels import ChannelSpec
from phyloc.config import Recipe
from phyloc.datasets.simulate import simulate_realization
from phyloc.errors import ValidationError
from phyloc.evaluation._common import experiment_from_dict, scenario_specs
from phyloc.evaluation.metrics import framework_distance_errors, rigid_align, shape_difference
from phyloc.evaluation.ranging_experiment import RangingSpec
from phyloc.localization import METHODS as REGISTRY
from phyloc.localization import (
    DirectOptions,
    LinkMeasurements,
    LinkRanges,
    Prior,
    coarse_positions,
    gauge_log_prior,
    gauge_priors,
    gaussian_log_prior,
    gaussian_priors,
    informed_centers,
)
from phyloc.localization.initialization import PAIR_COMBINE
from phyloc.network import NetworkSpec
from phyloc.network.rigidity import determined_pairs
from phyloc.parallel import run_tasks
from phyloc.phy.correlation import correlation_tables
from phyloc.ranging import estimate
from phyloc.ranging.nlos import check_min_concentration, energy_concentration

METHODS = REGISTRY.family("direct")
"""The methods this experiment can run: every registered method of the direct family."""
INITS = {"truth_free": "", "informed": "_informed", "gauge": "_gauge"}
CDF_GRID_M = np.linspace(0.0, 30.0, 301)


PRIOR_KEYS = (
    "prior_std_m",
    "informed_std_m",
    "gauge_extent_m",
    "init_pair_range",
    "init_robust_scale_m",
    "init_restarts",
    "init_one_sided",
    "los_min_concentration",
)
"""``[localization]`` keys of the experiment's priors; every other key is a method option."""


@dataclass(frozen=True)
class LocalizationSpec:
    """``[localization]``: the methods' options and the experiment's priors.

    ``prior_std_m`` std of the truth-free Gaussian priors around the coarse solution [m];
    ``informed_std_m`` σ0 of the informed start [m]; ``gauge_extent_m`` half-width of the
    uniform gauge priors [m]; ``init_pair_range`` (``"min"``, or ``"mean"``) how the
    truth-free start combines the two directions' correlation ranges of a pair and
    ``init_robust_scale_m`` (default ``[5.0, 2.0, 1.0]``; a number for one scale; 0: plain
    SMACOF) the Cauchy scales of its robust reweighting, the configuration with the lowest
    cost at the smallest scale winning, ``init_restarts`` (default 10) the random SMACOF
    starts it adds to the MDS start, the lowest robust cost winning, and ``init_one_sided``
    (default true) whether the reweighting spares ranges shorter than the fitted distance
    (NLOS biases are positive: a short range is noise, a long one may be biased)
    (:func:`~phyloc.localization.initialization.coarse_positions`).
    ``los_min_concentration`` (default 0.6; 0: off) is the NLOS identification: a link whose
    correlation has an energy concentration below it
    (:func:`~phyloc.ranging.nlos.energy_concentration`, 1 for one path) is left out of the
    start and of every method's likelihood (``LinkMeasurements.usable``). Every other
    key is an option of the direct family (:class:`~phyloc.localization.DirectOptions`: the
    :class:`~phyloc.localization.DPFOptions` fields, ``outlier_nats`` …), kept as written in
    ``options``; a subtable
    ``[localization.<method>]`` (``method_options``) holds the options of one method. A method
    whose options are :class:`~phyloc.localization.DirectOptions` gets ``options`` updated by
    its subtable, any other (a user's method) its subtable only (:meth:`options_for`).
    """

    options: dict = field(default_factory=dict)
    prior_std_m: float = 10.0
    informed_std_m: float = 10.0
    gauge_extent_m: float = 150.0
    method_options: dict = field(default_factory=dict)
    init_pair_range: str = "min"
    init_robust_scale_m: tuple = (5.0, 2.0, 1.0)
    init_restarts: int = 10
    init_one_sided: bool = True
    los_min_concentration: float = 0.6

    def __post_init__(self):
        v.positive("localization.prior_std_m", self.prior_std_m)
        v.choice("localization.init_pair_range", self.init_pair_range, PAIR_COMBINE)
        raw = self.init_robust_scale_m
        scales = tuple(
            v.positive("localization.init_robust_scale_m", c, allow_zero=True)
            for c in ((raw,) if np.ndim(raw) == 0 else raw)
        )
        if not scales or (0.0 in scales and len(scales) > 1):
            raise ValidationError(
                "localization.init_robust_scale_m", raw, "scales > 0 [m], or 0 (plain SMACOF)"
            )
        object.__setattr__(self, "init_robust_scale_m", scales)
        v.integer("localization.init_restarts", self.init_restarts, minimum=0)
        check_min_concentration(self.los_min_concentration, "localization.los_min_concentration")
        v.positive("localization.informed_std_m", self.informed_std_m)
        v.positive("localization.gauge_extent_m", self.gauge_extent_m)
        object.__setattr__(self, "options", dict(self.options))
        object.__setattr__(self, "method_options", dict(self.method_options))
        DirectOptions.from_dict(self.options, "localization")  # names a bad key or value
        for name in self.method_options:
            if name in REGISTRY:
                self.options_for(name)

    @classmethod
    def from_dict(cls, d: dict) -> LocalizationSpec:
        """From ``[localization]``: the prior keys, the direct family's option keys and the
        per-method subtables."""
        d = dict(d)
        own = {k: d.pop(k) for k in PRIOR_KEYS if k in d}
        scale = own.get("init_robust_scale_m")
        if isinstance(scale, int | float) and not isinstance(scale, bool):
            own["init_robust_scale_m"] = [scale]  # one scale, written as a number
        v.check_types(cls, own, "localization")
        sub = {k: d.pop(k) for k in list(d) if isinstance(d[k], dict)}
        return cls(options=d, method_options=sub, **own)

    def options_for(self, name: str):
        """The options of method ``name`` (``METHODS[name].make_options(...)``)."""
        method = REGISTRY[name]
        own = self.method_options.get(name, {})
        if method.options is DirectOptions:
            return method.make_options({**self.options, **own}, "localization")
        return method.make_options(own, f"localization.{name}")

    @property
    def dpf(self):
        """The filter options written in the recipe (``n_particles`` of the priors, meta)."""
        return DirectOptions.from_dict(self.options, "localization").dpf


@dataclass(frozen=True)
class LocalizationExperimentSpec:
    """``[experiment]`` of a localization recipe (``[experiment.fast]`` for ``--fast``).

    ``scenario_localization`` (``{token: {key: value}}``, default none) replaces top-level
    ``[localization]`` keys for one scenario, e.g. a channel's own range model error:
    ``scenario_localization = { d1 = { model_error_m = 0.55 } }``. A method's own subtable
    ``[localization.<method>]`` still wins over it.
    """

    scenarios: dict = field(default_factory=lambda: {"c2": "winner2_c2", "d1": "winner2_d1"})
    agents: tuple = (3, 6, 9, 12, 15, 18, 21, 24, 27, 30)
    realizations: int = 10
    methods: tuple = METHODS
    inits: tuple = ("truth_free", "informed")
    cdf_agents: tuple = (3, 30)
    scenario_localization: dict = field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.scenarios, dict) or not self.scenarios:
            raise ValidationError("experiment.scenarios", self.scenarios, "token = scenario name")
        if not isinstance(self.scenario_localization, dict):
            raise ValidationError(
                "experiment.scenario_localization",
                self.scenario_localization,
                "a table {token = {[localization] key = value}}",
            )
        for tok, over in self.scenario_localization.items():
            if tok not in self.scenarios:
                raise ValidationError(
                    "experiment.scenario_localization",
                    tok,
                    f"a scenario token of experiment.scenarios: {', '.join(self.scenarios)}",
                )
            if not isinstance(over, dict):
                raise ValidationError(
                    f"experiment.scenario_localization.{tok}",
                    over,
                    "a table of [localization] keys",
                )
        agents = tuple(v.integer("experiment.agents", a, minimum=2) for a in self.agents)
        if not agents:
            raise ValidationError("experiment.agents", [], "at least one size >= 2")
        object.__setattr__(self, "agents", agents)
        v.integer("experiment.realizations", self.realizations, minimum=1)
        direct = REGISTRY.family("direct")
        if not tuple(self.methods):
            raise ValidationError("experiment.methods", [], f"at least one of {', '.join(direct)}")
        for m in self.methods:
            if m not in direct:
                raise ValidationError(
                    "experiment.methods", m, f"each a direct-family method: {', '.join(direct)}"
                )
        for i in self.inits:
            if i not in INITS:
                raise ValidationError("experiment.inits", i, f"each one of {', '.join(INITS)}")
        object.__setattr__(self, "methods", tuple(self.methods))
        object.__setattr__(self, "inits", tuple(self.inits))
        object.__setattr__(self, "cdf_agents", tuple(int(a) for a in self.cdf_agents))

    @classmethod
    def from_dict(cls, d: dict, *, fast: bool = False) -> LocalizationExperimentSpec:
        """From ``[experiment]``; with ``fast`` the ``[experiment.fast]`` values win."""
        return experiment_from_dict(cls, d, fast=fast)


UNDETECTED_WEIGHT = 1e-3
"""SMACOF weight of a pair known only from links below the detection threshold, when the
detected links leave the truth-free start disconnected."""


def _priors(init, net, links, corr, lspec, Q, rng):
    """Prior particles (``Q`` per agent) and log density of one initialization (agents only),
    and the prior centres ``[n_agents, dim]`` (None for the gauge priors)."""
    agents = net.agent_index
    pos = net.positions[0]
    if init == "gauge":
        X = gauge_priors(agents.size, net.dim, Q, lspec.gauge_extent_m, rng)
        ext = lspec.gauge_extent_m
        return Prior(X, lambda x: gauge_log_prior(x, ext), "uninformative gauge priors"), None
    if init == "informed":
        centers = informed_centers(pos[agents], lspec.informed_std_m, rng=rng)
        std, label = lspec.informed_std_m, "informed start"
    else:
        anchors = pos[net.is_anchor] if net.n_anchors else None
        robust = {
            "combine": lspec.init_pair_range,
            "robust_scale_m": tuple(c for c in lspec.init_robust_scale_m if c > 0) or None,
            "n_restarts": lspec.init_restarts,
            "one_sided": lspec.init_one_sided,
            "rng": rng,
        }
        try:
            sol = coarse_positions(
                links,
                corr.range_m,
                net.n_nodes,
                net.dim,
                valid=corr.valid,
                is_anchor=net.is_anchor,
                anchor_positions=anchors,
                **robust,
            )
        except ValidationError:
            # some node has no detected range: undetected links join in with their strongest
            # peak at a weight of UNDETECTED_WEIGHT, placing the disconnected nodes (a guess:
            # their pairs are unobservable) without bending the detected part of the network
            sol = coarse_positions(
                links,
                corr.range_m,
                net.n_nodes,
                net.dim,
                valid=corr.valid,
                invalid_weight=UNDETECTED_WEIGHT,
                is_anchor=net.is_anchor,
                anchor_positions=anchors,
                **robust,
            )
        centers, std, label = sol.positions[agents], lspec.prior_std_m, "truth-free"
    X = gaussian_priors(centers, std, Q, rng)
    return Prior(X, lambda x: gaussian_log_prior(x, centers, std), label), centers


def _task(payload, seed_seq):
    """Simulate one realization (stream: the task's seed sequence itself) and localize."""
    system, net_spec, chan_spec, rspec, lspec, methods, inits = payload
    real = simulate_realization(system, net_spec, chan_spec, np.random.default_rng(seed_seq))
    return _localize(real, system, rspec, lspec, methods, inits, seed_seq)


def _dataset_task(payload, seed_seq):
    """Read one stored realization and localize (same streams as the in-memory path)."""
    from phyloc.datasets import open as open_dataset

    path, r, rspec, lspec, methods, inits = payload
    with open_dataset(path) as ds:
        real = ds.realization(r)
        system = ds.system
    return _localize(real, system, rspec, lspec, methods, inits, seed_seq)


def _usable(tables, rspec, lspec):
    """Per snapshot, the links the NLOS identification keeps (``los_min_concentration``,
    :func:`~phyloc.ranging.nlos.energy_concentration` over the ranging window at the
    correlation peak's detection threshold); None when it is off."""
    if lspec.los_min_concentration <= 0:
        return None
    corr = rspec.method_options("corr")
    kw = {"window_m": rspec.window_m}
    if "noise_factor" in corr:
        kw["noise_factor"] = corr["noise_factor"]
    return tuple(energy_concentration(t, **kw) >= lspec.los_min_concentration for t in tables)


def _measurements(real, tables, rspec, methods, usable=None):
    """The measurements of every snapshot of a realization, for every method's ``inputs``.

    Correlation tables, and the ranges of ``"corr"`` (the truth-free initialization and the
    link-bias figures read them) and of every estimator a method's ``inputs`` names
    (``"ranges:<estimator>"``; the oracle ``"sage_los"`` gets the true LOS flags here, in
    the evaluation); ``usable`` the links the NLOS identification kept (:func:`_usable`).
    Returns the measurements and, per estimator, its estimates per snapshot."""
    net = real.network
    ways = real.ways
    names = {"corr"}
    for m in methods:
        inputs = REGISTRY[m].inputs
        if inputs.startswith("ranges:"):
            names.add(inputs.split(":", 1)[1])
    ranges = {}
    for name in sorted(names):
        per_t = []
        for table, draw in zip(tables, real.channels, strict=True):
            e = estimate(name, table, los=draw.los, **rspec.method_options(name))
            if ways != 1:  # two-way tables measure the round trip
                e = dataclasses.replace(
                    e, range_m=e.range_m / ways, variance_m2=e.variance_m2 / ways**2
                )
            per_t.append(e)
        ranges[name] = per_t
    anchors = net.anchor_index
    meas = LinkMeasurements(
        n_nodes=net.n_nodes,
        dim=net.dim,
        anchor_nodes=anchors,
        anchor_positions=net.positions[:, anchors],
        links=tuple(real.links),
        tables=tuple(tables),
        ranges={
            k: LinkRanges(
                tuple(e.range_m for e in es),
                tuple(e.variance_m2 for e in es),
                tuple(e.valid for e in es),
            )
            for k, es in ranges.items()
        },
        ways=ways,
        window_m=rspec.window_m,
        usable=usable,
    )
    return meas, ranges


def _method_plan(methods, lspec):
    """``[(label, registry name, options)]``: ``methods`` is a sequence of registered names
    (options from ``[localization]``) or a mapping ``label -> (name, options)``."""
    if isinstance(methods, dict):
        return [(label, name, opts) for label, (name, opts) in methods.items()]
    return [(m, m, lspec.options_for(m)) for m in methods]


def _localize(real, system, rspec, lspec, methods, inits, seed_seq, keep_particles=()):
    """Ranging and every localization method on every snapshot of a realization.

    ``methods``: registered names, or ``{label: (name, options)}`` (:func:`_method_plan`).
    The randomness of the priors and of each method comes from children of ``seed_seq``
    (spawned after the signals were drawn from the sequence itself). The prior of an
    initialization is drawn from that initialization's stream for each particle count a method
    asks for, so methods with equal ``n_particles`` start from the same particles. Snapshot 0
    starts from the prior; later snapshots predict with the methods' mobility model
    (``process_std_m``, DiPNet §II-C)."""
    plan = _method_plan(methods, lspec)
    streams = seed_seq.spawn(2 + len(inits) * (1 + len(plan)))
    net = real.network
    tables = [
        correlation_tables(rec, real.symbols, system, beta=rspec.beta, tx_index=lk[:, 1])
        for rec, lk in zip(real.received, real.links, strict=True)
    ]
    usable = _usable(tables, rspec, lspec)
    meas, ests = _measurements(real, tables, rspec, [name for _, name, _ in plan], usable)
    corr0 = ests["corr"][0]
    if usable is not None:  # the start ranges only the links the identification kept
        corr0 = dataclasses.replace(corr0, valid=corr0.valid & usable[0])
    out = {
        # distances of the realization's own links (recorded data need not have every link
        # the network's range allows; for simulated data they are the same links)
        "link_err_corr": np.concatenate(
            [
                e.range_m
                - np.linalg.norm(net.positions[t][lk[:, 0]] - net.positions[t][lk[:, 1]], axis=-1)
                for t, (e, lk) in enumerate(zip(ests["corr"], real.links, strict=True))
            ]
        ),
        "link_valid_corr": np.concatenate([e.valid for e in ests["corr"]]),
        "los": np.concatenate([np.asarray(d.los, bool) for d in real.channels]),
        "observable": np.concatenate(
            [
                observable_pairs(
                    net, t, lk, e.valid & meas.usable_links(t), np.random.default_rng(streams[0])
                )
                for t, (e, lk) in enumerate(zip(ests["corr"], real.links, strict=True))
            ]
        ),
        "dim": net.dim,
    }
    s = 2
    for init in inits:
        prior_seed = streams[s]
        s += 1
        priors = {}
        for label, name, opts in plan:
            rng_m = np.random.default_rng(streams[s])
            s += 1
            Q = opts.dpf.n_particles if isinstance(opts, DirectOptions) else lspec.dpf.n_particles
            if Q not in priors:
                rng_p = np.random.default_rng(prior_seed)
                priors[Q], centers = _priors(init, net, real.links[0], corr0, lspec, Q, rng_p)
                if f"start|{init}|err" not in out:  # the start itself, as a method would be
                    out[f"start|{init}|err"] = (
                        np.full(0, np.nan)
                        if centers is None
                        else framework_distance_errors(
                            _nodes(centers, meas, net.agent_index), net.positions[0], net.is_anchor
                        )
                    )
            if keep_particles and isinstance(opts, DirectOptions):
                opts = dataclasses.replace(opts, keep_particles=tuple(keep_particles))
            res = REGISTRY[name].run(meas, priors[Q], rng_m, opts)
            out.update(_run_outputs(f"{label}|{init}", res, meas, net.positions))
    return out


def observable_pairs(net, t, links, detected, rng) -> np.ndarray:
    """Which framework distances of snapshot ``t`` its detected ``links`` determine.

    A pair of nodes is *linked* when a link between them (either direction) passes the
    correlation-peak detection test (``detected``, the ``valid`` flags of the ``"corr"``
    ranges: measurements only, no truth). A framework distance is *observable* when the linked
    pairs fix it (generic infinitesimal rigidity, anchors fixed:
    :func:`~phyloc.network.rigidity.determined_pairs`). Returns a flag per pair of
    :func:`~phyloc.evaluation.metrics.framework_distance_errors` (same order)."""
    pos = net.positions[t]
    _, pairs = framework_distance_errors(pos, pos, net.is_anchor, return_pairs=True)
    edges = np.asarray(links)[np.asarray(detected, bool)]
    return determined_pairs(net.n_nodes, edges, pairs, net.dim, rng, fixed=net.is_anchor)


_CHI2_MEDIAN = {1: 0.454936423119573, 2: 2.0 * math.log(2.0), 3: 2.365973884375338}
"""Median of the χ² distribution with 1, 2, 3 degrees of freedom (NEES of a calibrated belief)."""


def _nees(estimates, covariances, truth, is_anchor):
    """NEES ``eᵀP⁻¹e`` per agent of one snapshot, after the rigid alignment of DiPNet eq. (3)
    (the error of an anchor-free framework is defined up to a rigid motion; the covariance
    rotates with it). NaN for a singular or missing covariance."""
    R, _, aligned = rigid_align(estimates, truth, is_anchor=is_anchor, missing="exclude")
    agents = np.flatnonzero(~np.asarray(is_anchor, bool))
    out = np.full(agents.size, np.nan)
    if covariances is None:
        return out
    for i, u in enumerate(agents):
        P = R @ covariances[i] @ R.T
        e = aligned[u] - truth[u]
        if not (np.all(np.isfinite(P)) and np.all(np.isfinite(e))):
            continue
        try:
            with np.errstate(all="ignore"):
                val = float(e @ np.linalg.solve(P, e))
        except np.linalg.LinAlgError:
            continue
        out[i] = val if np.isfinite(val) and val >= 0 else np.nan
    return out


def _run_outputs(key, res, meas, truth):
    """Metrics of one run (``res``, a Result) against the truth, keyed ``key|<what>``.

    ``truth [T, n_nodes, dim]`` enters only here. Errors are pooled over snapshots (``err``),
    with the RMSE per snapshot (``rmse_t``) and the estimates (``estimates``, for trajectory
    figures). The per-iteration series read snapshot 0 of the direct family's diagnostics
    (``mean_history``, ``cov_trace_history``, ``ess_history``); a method without them (a
    user's method) gives its final estimate as the only "iteration" and NaN for the ESS."""
    dim, is_anchor = meas.dim, meas.is_anchor
    agents = meas.agent_nodes
    diag = res.diagnostics
    T = res.estimates.shape[0]
    errs = [
        framework_distance_errors(_nodes(res.estimates[t], meas, agents, t), truth[t], is_anchor)
        for t in range(T)
    ]
    history = diag["mean_history"][0] if "mean_history" in diag else res.estimates[:1]
    est0 = _nodes(res.estimates[0], meas, agents)
    out = {
        key + "|err": np.concatenate(errs),
        key + "|rmse_t": np.array([math.sqrt(np.mean(e**2)) for e in errs]),
        key + "|estimates": np.asarray(res.estimates),
        key + "|shape": shape_difference(est0, truth[0], is_anchor),
        key + "|actual_err": np.array(
            [shape_difference(_nodes(mk, meas, agents), truth[0], is_anchor) for mk in history]
        )
        / math.sqrt(dim),
        key + "|nees": _nees(
            est0,
            None if res.covariances is None else np.asarray(res.covariances[0]),
            truth[0],
            is_anchor,
        ),
        key + "|sec_per_agent_it": res.timing.per_agent_iteration_s,
        key + "|agent_snapshot_s": float(np.mean(res.timing.agent_s)),
        key + "|particles_at": {
            t: (np.asarray(X), np.asarray(lw))
            for t, (X, lw) in diag.get("particles_at", {}).items()
        },
    }
    if "ess_history" in diag:
        ess = diag["ess_history"][0]
        out[key + "|ess"], out[key + "|ess_min"] = ess.mean(axis=1), float(ess.min())
    else:
        out[key + "|ess"], out[key + "|ess_min"] = np.full(1, np.nan), float("nan")
    if "cov_trace_history" in diag:
        trace = diag["cov_trace_history"][0].mean(axis=1)
    elif res.covariances is not None:
        trace = np.trace(res.covariances[0], axis1=1, axis2=2).mean(keepdims=True)
    else:
        trace = np.full(1, np.nan)
    out[key + "|published_std"] = np.sqrt(trace / dim)
    return out


def _reads_tables(name: str) -> bool:
    """True for a direct method on correlation tables (DiPNet and its variants): the rows the
    summary and the per-iteration panels single out, chosen by the method's inputs, not its
    name."""
    method = REGISTRY.get(name)
    return method is not None and method.inputs == "tables"


def _nodes(agent_estimates, meas, agents, t=0):
    """``[n_nodes, dim]`` positions at snapshot ``t``: the estimates in agents' rows, anchors
    where known."""
    full = np.zeros((meas.n_nodes, meas.dim))
    full[meas.anchor_nodes] = meas.anchor_positions[t]
    full[agents] = agent_estimates
    return full


def prepare(recipe: Recipe, *, fast: bool = False):
    """Validate everything :func:`run` reads from ``recipe`` (the ``fast`` setting or the
    full one) and return what it runs; no work is done (``phyloc evaluate`` and
    :func:`phyloc.evaluation.recipes.validate_recipe` call it for both settings first)."""
    exp = LocalizationExperimentSpec.from_dict(recipe.section("experiment"), fast=fast)
    rspec = recipe.section("ranging", RangingSpec)
    lspec = recipe.section("localization", LocalizationSpec)
    net_raw = dict(recipe.section("network"))
    chan = recipe.section("channel", ChannelSpec)
    nets = {n: NetworkSpec.from_dict({**net_raw, "n_agents": n}) for n in exp.agents}
    return exp, rspec, lspec, nets, scenario_specs(chan, exp.scenarios)


def scenario_localization_specs(recipe: Recipe, exp, lspec) -> dict:
    """``{token: LocalizationSpec}``: ``lspec`` with ``experiment.scenario_localization``
    applied per scenario (errors name the key under ``experiment.scenario_localization``)."""
    raw = recipe.section("localization")
    out = {}
    for tok in exp.scenarios:
        over = exp.scenario_localization.get(tok)
        if not over:
            out[tok] = lspec
            continue
        try:
            out[tok] = LocalizationSpec.from_dict({**raw, **over})
        except ValidationError as exc:
            key = exc.field.removeprefix("localization").lstrip(".")
            where = f"experiment.scenario_localization.{tok}" + (f".{key}" if key else "")
            raise ValidationError(where, exc.value, exc.allowed) from None
    return out


def run(recipe: Recipe, *, fast: bool = False, workers=None, scheduler=None, progress=True):
    """Run a ``kind = "localization"`` recipe; returns ``{"figures", "series", "meta"}``."""
    system = recipe.system
    exp, rspec, lspec, nets, specs = prepare(recipe, fast=fast)
    lspecs = scenario_localization_specs(recipe, exp, lspec)
    payloads, keys = [], []
    for tok, spec in specs.items():
        for n in exp.agents:
            for r in range(exp.realizations):
                payloads.append((system, nets[n], spec, rspec, lspecs[tok], exp.methods, exp.inits))
                keys.append((tok, n, r))
    results = run_tasks(
        _task,
        payloads,
        recipe.seed,
        workers=workers,
        scheduler=scheduler,
        desc="localization",
        progress=progress,
    )
    figures, series = _aggregate(keys, results, exp, list(specs))
    meta = _meta(recipe, exp, lspec, fast)
    return {"figures": figures, "series": series, "meta": meta}


def _meta(recipe, exp, lspec, fast) -> dict:
    """The ``meta`` object of a localization result (labels of every oracle/informed output)."""
    return {
        "recipe": recipe.name,
        "kind": recipe.kind,
        "seed": recipe.seed,
        "fast": fast,
        "agents": list(exp.agents),
        "realizations": exp.realizations,
        "scenarios": dict(exp.scenarios),
        "scenario_localization": {k: dict(o) for k, o in exp.scenario_localization.items()},
        "methods": list(exp.methods),
        "inits": {i: i.replace("_", "-") for i in exp.inits},
        "labels": {
            "informed": "informed start (truth + N(0, σ0²))",
            "gauge": "uninformative gauge priors",
            "truth_free": "truth-free",
            "sage_los": "oracle: NLOS links rejected by ground truth",
        },
        "n_particles": lspec.dpf.n_particles,
        "n_iterations": lspec.dpf.n_iterations,
    }


def _aggregate(keys, results, exp, tokens):
    """Pool the per-realization outputs (keyed ``(token, n_agents, realization)``)."""
    figures: dict[str, float] = {}
    series: dict[str, object] = {"cdf_grid_m": CDF_GRID_M}
    n_max = max(exp.agents)
    for tok in tokens:
        parts = [res for (t, _, _), res in zip(keys, results, strict=True) if t == tok]
        le = np.concatenate([p["link_err_corr"] for p in parts])
        lv = np.concatenate([p["link_valid_corr"] for p in parts])
        los = np.concatenate([p["los"] for p in parts])
        figures[f"{tok}.los_fraction"] = float(los.mean())
        for cond, mask in (("los", los), ("nlos", ~los)):
            sel = lv & mask
            figures[f"{tok}.link_bias.{cond}_mean_m"] = (
                float(le[sel].mean()) if sel.any() else float("nan")
            )
        for n in exp.agents:
            obs = np.concatenate(
                [
                    r["observable"]
                    for (t, nn, _), r in zip(keys, results, strict=True)
                    if t == tok and nn == n
                ]
            )
            figures[f"{tok}.agents_{n}.unobservable_pair_fraction"] = float(1.0 - obs.mean())
        for init in exp.inits:
            tag = tok + INITS[init]
            for n in exp.agents:
                err = np.concatenate(
                    [
                        r.get(f"start|{init}|err", np.full(0, np.nan))
                        for (t, nn, _), r in zip(keys, results, strict=True)
                        if t == tok and nn == n
                    ]
                )
                figures[f"start.{tag}.agents_{n}.framework_rmse_m"] = (
                    float(math.sqrt(np.mean(err**2))) if err.size else float("nan")
                )
            for m in exp.methods:
                key = f"{m}|{init}"
                for n in exp.agents:
                    runs = [
                        res
                        for (t, nn, _), res in zip(keys, results, strict=True)
                        if t == tok and nn == n
                    ]
                    err = np.concatenate([r[key + "|err"] for r in runs])
                    obs = np.concatenate([r["observable"] for r in runs])
                    base = f"{m}.{tag}.agents_{n}"
                    figures[base + ".framework_rmse_m"] = float(math.sqrt(np.mean(err**2)))
                    figures[base + ".framework_rmse_observable_m"] = (
                        float(math.sqrt(np.mean(err[obs] ** 2))) if obs.any() else float("nan")
                    )
                    dim = runs[0]["dim"]
                    nees = np.concatenate([r[key + "|nees"] for r in runs])
                    nees = nees[np.isfinite(nees)]
                    figures[base + ".nees"] = float(nees.mean()) if nees.size else float("nan")
                    figures[base + ".error_to_belief_ratio"] = (
                        float(math.sqrt(nees.mean() / dim)) if nees.size else float("nan")
                    )
                    figures[base + ".error_to_belief_ratio_median"] = (
                        float(math.sqrt(np.median(nees) / _CHI2_MEDIAN[dim]))
                        if nees.size
                        else float("nan")
                    )
                    figures[base + ".shape_difference_m"] = float(
                        math.sqrt(np.mean([r[key + "|shape"] ** 2 for r in runs]))
                    )
                    figures[base + ".ess_min"] = float(np.mean([r[key + "|ess_min"] for r in runs]))
                    figures[base + ".agent_snapshot_s"] = float(
                        np.mean([r[key + "|agent_snapshot_s"] for r in runs])
                    )
                    rmse_t = np.array([r[key + "|rmse_t"] for r in runs])
                    if rmse_t.shape[1] > 1:  # tracking: RMSE per snapshot over realizations
                        series[base + ".rmse_by_snapshot"] = np.sqrt(np.mean(rmse_t**2, axis=0))
                    if n in exp.cdf_agents:
                        series[base + ".error_cdf"] = (
                            np.searchsorted(np.sort(err), CDF_GRID_M, side="right") / err.size
                        )
                    if n == n_max:
                        for what in ("ess", "published_std", "actual_err"):
                            series[f"{base}.{what}_by_iteration"] = np.mean(
                                [r[f"{key}|{what}"] for r in runs], axis=0
                            )
        for m in exp.methods:
            figures[f"{m}.runtime_per_agent_iteration_s"] = float(
                np.mean([r[f"{m}|{i}|sec_per_agent_it"] for r in results for i in exp.inits])
            )
    return figures, series


DATASET_EXPERIMENT_KEYS = ("methods", "inits", "fast")
"""Keys of a dataset recipe's ``[experiment]`` (what ``phyloc evaluate DATASET`` runs)."""


def dataset_specs(recipe, n_agents: int, n_realizations: int):
    """What ``phyloc evaluate DATASET`` runs on a dataset of ``recipe``: the experiment
    (``[experiment]`` methods and inits), ranging and localization specs, and the scenario
    token. Validates those sections with the messages ``evaluate`` gives (``phyloc generate``
    calls it through :func:`check_dataset_recipe` before any work).
    """
    raw = dict(recipe.section("experiment"))
    v.check_keys(raw, DATASET_EXPERIMENT_KEYS, "experiment")
    raw.pop("fast", None)
    scenario = recipe.section("channel", ChannelSpec).scenario
    token = scenario.split("_", 1)[1] if scenario.startswith("winner2_") else scenario
    exp = LocalizationExperimentSpec(
        scenarios={token: scenario},
        agents=(n_agents,),
        realizations=n_realizations,
        methods=tuple(raw.get("methods", METHODS)),
        inits=tuple(raw.get("inits", ("truth_free",))),
        cdf_agents=(n_agents,),
    )
    rspec = recipe.section("ranging", RangingSpec)
    lspec = recipe.section("localization", LocalizationSpec)
    return exp, rspec, lspec, token


def check_dataset_recipe(recipe) -> None:
    """Validate the sections of a dataset recipe that only ``phyloc evaluate`` reads
    (``[experiment]``, ``[ranging]``, ``[localization]``), so ``phyloc generate`` fails before
    hours of work instead of ``evaluate`` after them."""
    from phyloc.datasets.writer import plan_dataset

    plan = plan_dataset(recipe)
    dataset_specs(plan.recipe, plan.network.n_agents, plan.dataset.realizations)


def run_dataset(path, *, fast: bool = False, workers=None, scheduler=None, progress=True):
    """Run the localization methods on the waveforms of a dataset (``phyloc generate``).

    Methods, initializations and filter options come from the dataset's stored recipe
    (``[experiment]`` methods/inits, ``[ranging]``, ``[localization]``; defaults otherwise);
    every realization is one task, seeded like the realization itself, so the results equal
    those of the same recipe evaluated in memory (up to the complex64 storage of the samples).
    With ``fast`` only the first realization is used.
    """
    from phyloc.datasets import open as open_dataset

    with open_dataset(path) as ds:
        recipe = ds.load_recipe()
        n_real = ds.n_realizations
        net = ds.realization(0).network
    exp, rspec, lspec, token = dataset_specs(recipe, net.n_agents, 1 if fast else n_real)
    payloads = [
        (str(path), r, rspec, lspec, exp.methods, exp.inits) for r in range(exp.realizations)
    ]
    keys = [(token, net.n_agents, r) for r in range(exp.realizations)]
    results = run_tasks(
        _dataset_task,
        payloads,
        recipe.seed,
        workers=workers,
        scheduler=scheduler,
        desc="localization",
        progress=progress,
    )
    figures, series = _aggregate(keys, results, exp, [token])
    meta = {**_meta(recipe, exp, lspec, fast), "kind": "localization", "dataset": str(path)}
    return {"figures": figures, "series": series, "meta": meta}


SUMMARY_HEADERS = ["scenario", "method"]


def summary_rows(results: dict):
    """Framework RMSE [m] per method and scenario token (columns: network sizes)."""
    f, meta = results["figures"], results["meta"]
    rows = []
    for tok in meta["scenarios"]:
        for init in meta["inits"]:
            tag = tok + INITS[init]
            for m in meta["methods"]:
                name = f"{m} (oracle)" if m == "sage_los" else m
                rows.append(
                    (
                        tag,
                        name,
                        *[f[f"{m}.{tag}.agents_{n}.framework_rmse_m"] for n in meta["agents"]],
                    )
                )
    return rows


def summary_headers(results: dict):
    """Headers of :func:`summary_rows`."""
    return [*SUMMARY_HEADERS, *[f"{n} agents" for n in results["meta"]["agents"]]]


def summary_lines(results: dict):
    """ESS and runtime lines."""
    f, meta = results["figures"], results["meta"]
    n = max(meta["agents"])
    out = ["framework distance RMSE [m] (DiPNet eq. (4)); informed-start rows are not truth-free"]
    for tok in meta["scenarios"]:
        for init in meta["inits"]:
            tag = tok + INITS[init]
            ess = ", ".join(
                f"{m} {f[f'{m}.{tag}.agents_{n}.ess_min']:.0f}"
                for m in meta["methods"]
                if _reads_tables(m)
            )
            out.append(f"{tag}, {n} agents, smallest ESS: {ess} (of {meta['n_particles']})")
            ratio = ", ".join(
                f"{m} {f.get(f'{m}.{tag}.agents_{n}.error_to_belief_ratio', math.nan):.3g}"
                f" ({f.get(f'{m}.{tag}.agents_{n}.error_to_belief_ratio_median', math.nan):.3g})"
                for m in meta["methods"]
            )
            out.append(
                f"{tag}, {n} agents, error/belief ratio sqrt(NEES/dim) (from the median): {ratio}"
            )
        for k in meta["agents"]:
            frac = f.get(f"{tok}.agents_{k}.unobservable_pair_fraction", 0.0)
            for init in meta["inits"] if frac > 0 else ():
                tag = tok + INITS[init]
                obs = ", ".join(
                    f"{m} {f[f'{m}.{tag}.agents_{k}.framework_rmse_observable_m']:.3g}"
                    for m in meta["methods"]
                )
                out.append(
                    f"{tag}, {k} agents: {100 * frac:.1f} % of the pairs unobservable "
                    f"(no detected links fix them); RMSE over the rest [m]: {obs}"
                )
    rt = ", ".join(
        f"{m} {1e6 * f[f'{m}.runtime_per_agent_iteration_s']:.0f} µs" for m in meta["methods"]
    )
    out.append(f"runtime per agent-iteration: {rt}")
    return out


def plot(results: dict, path) -> None:
    """DiPNet Fig. 5 layout from results only: RMSE vs agents per scenario, CDFs, ESS."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    f, ser, meta = results["figures"], results["series"], results["meta"]
    toks = list(meta["scenarios"])
    tracking = any(k.endswith(".rmse_by_snapshot") for k in ser)
    n_rows = 3 if tracking else 2
    fig = Figure(figsize=(4.6 * len(toks) + 4.6, 4.0 * n_rows), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(n_rows, len(toks) + 1, squeeze=False)
    agents = meta["agents"]
    for j, tok in enumerate(toks):
        ax = axes[0, j]
        for init in meta["inits"]:
            tag = tok + INITS[init]
            ls = "-" if init == "truth_free" else ("--" if init == "informed" else ":")
            for i, m in enumerate(meta["methods"]):
                y = [f[f"{m}.{tag}.agents_{n}.framework_rmse_m"] for n in agents]
                ax.semilogy(
                    agents, y, ls, marker="os^vdx"[i % 6], color=f"C{i}", label=f"{m} ({init})"
                )
        ax.set_title(f"{tok}: framework distance RMSE")
        ax.set_xlabel("number of agents")
        ax.set_ylabel("RMSE [m]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, ncol=2)
        ax = axes[1, j]
        init = "truth_free" if "truth_free" in meta["inits"] else next(iter(meta["inits"]))
        tag = tok + INITS[init]
        for n, ls in zip(
            sorted({*meta["agents"]} & set(_cdf_sizes(ser, meta, tag))), ("-", "--"), strict=False
        ):
            for i, m in enumerate(meta["methods"]):
                k = f"{m}.{tag}.agents_{n}.error_cdf"
                if k in ser:
                    ax.plot(ser["cdf_grid_m"], ser[k], ls, color=f"C{i}", label=f"{m}, {n} agents")
        ax.set_title(f"{tok} ({init.replace('_', '-')} start): error CDF")
        ax.set_xlabel("absolute framework distance error [m]")
        ax.set_ylabel("CDF")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=6)
    n = max(agents)
    ax = axes[0, -1]
    ax2 = axes[1, -1]
    tok = toks[0]
    for i, m in enumerate(meta["methods"]):
        if not _reads_tables(m):
            continue
        for init in meta["inits"]:
            base = f"{m}.{tok}{INITS[init]}.agents_{n}"
            if f"{base}.ess_by_iteration" in ser:
                ax.semilogy(ser[f"{base}.ess_by_iteration"], color=f"C{i}", label=f"{m} ({init})")
                ax2.semilogy(
                    ser[f"{base}.published_std_by_iteration"],
                    "--",
                    color=f"C{i}",
                    label=f"{m} ({init}) published std",
                )
                ax2.semilogy(
                    ser[f"{base}.actual_err_by_iteration"],
                    "-",
                    color=f"C{i}",
                    label=f"{m} ({init}) actual error",
                )
    ax.set_title(f"{tok}, {n} agents: mean ESS per iteration")
    ax.set_xlabel("iteration")
    ax2.set_title("published std vs actual error per axis [m]")
    ax2.set_xlabel("iteration")
    for a in (ax, ax2):
        if a.get_legend_handles_labels()[0]:  # a run without per-iteration series draws none
            a.legend(fontsize=6)
        a.grid(True, which="both", alpha=0.3)
    if tracking:
        _plot_tracks(axes[2], ser, meta, toks)
    fig.suptitle(
        f"Direct vs two-step localization — {meta['recipe']}{' (fast)' if meta.get('fast') else ''}"
    )
    fig.savefig(path, dpi=100)


def _plot_tracks(axes, ser, meta, toks):
    """Per-snapshot framework RMSE of every method (truth-free start), one panel per token."""
    n = max(meta["agents"])
    for j, tok in enumerate(toks):
        ax = axes[j]
        for i, m in enumerate(meta["methods"]):
            k = f"{m}.{tok}.agents_{n}.rmse_by_snapshot"
            if k in ser:
                ax.semilogy(np.asarray(ser[k]), color=f"C{i}", label=m)
        ax.set_title(f"{tok}, {n} agents: framework RMSE per snapshot")
        ax.set_xlabel("snapshot")
        ax.set_ylabel("RMSE [m]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6)
    axes[-1].set_axis_off()


def _cdf_sizes(ser, meta, tok):
    return [
        n
        for n in meta["agents"]
        if any(f"{m}.{tok}.agents_{n}.error_cdf" in ser for m in meta["methods"])
    ]

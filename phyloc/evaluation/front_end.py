"""The direct measurement front end: a realization's waveforms → correlation tables → ranges →
the :class:`~phyloc.localization.LinkMeasurements` every direct-family method reads, the
priors a method starts from, and :func:`localize_realization`: every method of a plan on one
realization, returning that realization's own values (errors per pair, NEES per agent, …).

Every direct experiment (``localization``, ``direct_tracking``, ``phyloc evaluate`` on a
dataset) builds its measurements here, once per realization, so all methods of a realization
see the same tables and ranges; the truth enters only the metrics (and the oracle
``sage_los``'s LOS flags, which :func:`link_measurements` passes to the estimator).

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from phyloc.errors import ValidationError
from phyloc.evaluation.metrics import framework_distance_errors, rigid_align, shape_difference
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
from phyloc.localization.initialization import start_scale
from phyloc.network.rigidity import determined_pairs
from phyloc.phy.correlation import correlation_tables
from phyloc.ranging import estimate
from phyloc.ranging.estimators import ORACLES, nlos_rejected
from phyloc.ranging.nlos import energy_concentration

#: Smallest per-agent prior std of ``prior_std_m = "start"`` [m] (the filter's default
#: covariance floor, :class:`~phyloc.localization.DPFOptions`).
START_PRIOR_FLOOR_M = 0.05
#: Prior std of an agent the start cannot place (no measured pair, or measured directions that
#: leave one undetermined) with ``"start"``, and the largest any agent gets [m].
START_PRIOR_FALLBACK_M = 10.0


def link_tables(real, system, beta: float) -> list:
    """The correlation table of every link of every snapshot of realization ``real``
    (DiPNet eq. (23), interpolation factor ``beta``)."""
    return [
        correlation_tables(rec, real.symbols, system, beta=beta, tx_index=lk[:, 1])
        for rec, lk in zip(real.received, real.links, strict=True)
    ]


def usable_links(tables, rspec, lspec):
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


def link_measurements(real, tables, rspec, methods, usable=None, timings=None):
    """The measurements of every snapshot of a realization, for every method's ``inputs``.

    Correlation tables, and the ranges of ``"corr"`` (the truth-free initialization and the
    link-bias figures read them) and of every estimator a method's ``inputs`` names
    (``"ranges:<estimator>"``; the oracle ``"sage_los"`` gets the true LOS flags here, in
    the evaluation); ``usable`` the links the NLOS identification kept (:func:`usable_links`).
    Returns the measurements and, per estimator, its estimates per snapshot; ``timings``, a
    dict, receives each estimator's wall time [s] as ``ranging_<name>``."""
    net = real.network
    ways = real.ways
    names = {"corr"}
    for m in methods:
        inputs = REGISTRY[m].inputs
        if inputs.startswith("ranges:"):
            names.add(inputs.split(":", 1)[1])
    ranges = {}
    for name in sorted(names):
        clock = time.perf_counter()
        per_t = []
        base = ORACLES.get(name)
        if base in ranges:  # the oracle masks the estimates of its estimator, run once
            ranges[name] = [
                nlos_rejected(e, np.asarray(d.los, bool))
                for e, d in zip(ranges[base], real.channels, strict=True)
            ]
            if timings is not None:
                timings[f"ranging_{name}"] = time.perf_counter() - clock
            continue
        for table, draw in zip(tables, real.channels, strict=True):
            e = estimate(name, table, los=draw.los, **rspec.method_options(name))
            if ways != 1:  # two-way tables measure the round trip
                e = dataclasses.replace(
                    e, range_m=e.range_m / ways, variance_m2=e.variance_m2 / ways**2
                )
            per_t.append(e)
        ranges[name] = per_t
        if timings is not None:
            timings[f"ranging_{name}"] = time.perf_counter() - clock
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


UNDETECTED_WEIGHT = 1e-3
"""SMACOF weight of a pair known only from links below the detection threshold, when the
detected links leave the truth-free start disconnected."""


def start_prior_std(positions, links, ranges, valid, combine) -> np.ndarray:
    """Per node, the prior std of ``prior_std_m = "start"`` [m]: the start's own accuracy
    estimate (:func:`~phyloc.localization.initialization.start_scale` as a position std, the
    network's robust range residual scale through each node's measured directions), between
    :data:`START_PRIOR_FLOOR_M` and :data:`START_PRIOR_FALLBACK_M` — the upper limit also for
    a node the start cannot place, or whose measured neighbours lie nearly in line with it
    (``J_u`` nearly singular: without the limit a 6-agent network gave a prior kilometres
    wide)."""
    scale = start_scale(
        positions,
        links,
        ranges,
        valid=valid,
        combine=combine,
        floor_m=START_PRIOR_FLOOR_M,
        position=True,
    )
    return np.minimum(np.where(np.isfinite(scale), scale, np.inf), START_PRIOR_FALLBACK_M)


def start_prior(init, net, links, corr, lspec, Q, rng):
    """The prior of one initialization and its centres.

    ``init`` is ``"truth_free"`` (Gaussian priors of std ``prior_std_m`` around the coarse
    two-step solution of :func:`~phyloc.localization.coarse_positions` on the correlation-peak
    ranges ``corr``), ``"informed"`` (around the truth plus N(0, ``informed_std_m``²)) or
    ``"gauge"`` (uninformative gauge priors). Returns the :class:`~phyloc.localization.Prior`
    (``Q`` particles per agent), the centres ``[n_agents, dim]`` (None for the gauge
    priors) and, for the truth-free start, which agents the measured pairs leave undetermined
    (``[n_agents]`` bool, the rule of
    :func:`~phyloc.localization.sparse_start.undetermined_nodes`; None otherwise). The coarse
    solution runs on the pairs' own graph (``init_solver``, sparse above
    :data:`~phyloc.localization.initialization.SPARSE_ABOVE_NODES` nodes by default)."""
    agents = net.agent_index
    pos = net.positions[0]
    undetermined = None
    if init == "gauge":
        X = gauge_priors(agents.size, net.dim, Q, lspec.gauge_extent_m, rng)
        ext = lspec.gauge_extent_m
        return Prior(X, lambda x: gauge_log_prior(x, ext), "uninformative gauge priors"), None, None
    if init == "informed":
        centers = informed_centers(pos[agents], lspec.informed_std_m, rng=rng)
        std, label = lspec.informed_std_m, "informed start"
    else:
        anchors = pos[net.is_anchor] if net.n_anchors else None
        args = (links, corr.range_m, net.n_nodes, net.dim)
        kw = {
            "valid": corr.valid,
            "is_anchor": net.is_anchor,
            "anchor_positions": anchors,
            "combine": lspec.init_pair_range,
            "robust_scale_m": tuple(c for c in lspec.init_robust_scale_m if c > 0) or None,
            "n_restarts": lspec.init_restarts,
            "one_sided": lspec.init_one_sided,
            "rng": rng,
            "solver": lspec.init_solver,
        }
        try:
            sol = coarse_positions(*args, **kw)
        except ValidationError:
            # some node has no detected range: undetected links join in with their strongest
            # peak at a weight of UNDETECTED_WEIGHT, placing the disconnected nodes (a guess:
            # their pairs are unobservable) without bending the detected part of the network
            sol = coarse_positions(*args, invalid_weight=UNDETECTED_WEIGHT, **kw)
        centers, std, label = sol.positions[agents], lspec.prior_std_m, "truth-free"
        undetermined = sol.undetermined[agents]
        if std == "start":  # each agent's width: the start's own accuracy estimate
            std = start_prior_std(
                sol.positions, links, corr.range_m, corr.valid, lspec.init_pair_range
            )[agents]
    X = gaussian_priors(centers, std, Q, rng)
    return Prior(X, lambda x: gaussian_log_prior(x, centers, std), label), centers, undetermined


def observable_pairs(net, t, links, detected, rng) -> np.ndarray:
    """Which framework distances of snapshot ``t`` its detected ``links`` determine.

    A pair of nodes is *linked* when a link between them (either direction) passes the
    correlation-peak detection test (``detected``, the ``valid`` flags of the ``"corr"``
    ranges: measurements only, no truth). A framework distance is *observable* when the linked
    pairs fix it (generic infinitesimal rigidity, anchors fixed:
    :func:`~phyloc.network.rigidity.determined_pairs`). Returns a flag per pair of
    :func:`~phyloc.evaluation.metrics.framework_distance_errors` (same order)."""
    pos = net.positions[t]
    scored = scored_pairs(net, links)
    if scored is not None and net.n_nodes > RIGIDITY_MAX_NODES:
        return None
    _, pairs = framework_distance_errors(pos, pos, net.is_anchor, return_pairs=True, pairs=scored)
    edges = np.asarray(links)[np.asarray(detected, bool)]
    return determined_pairs(net.n_nodes, edges, pairs, net.dim, rng, fixed=net.is_anchor)


RIGIDITY_MAX_NODES = 300
"""Largest range-limited network whose observable pairs are computed: the rigidity test
(:func:`~phyloc.network.rigidity.determined_pairs`) takes the null space of the
``n_links × dim·n`` rigidity matrix by a dense SVD — cubic in the network size. Above this
size the ``framework_rmse_observable_m`` and ``unobservable_pair_fraction`` figures are left
out (the start's undetermined agents, :func:`start_prior`, are reported at every size)."""


def scored_pairs(net, links):
    """The ordered pairs DiPNet eq. (4) sums over: ``None`` (every pair) for a fully meshed
    network, the directed ``links`` for a range-limited one (DiPNet eq. (4) over the framework's
    edges; :func:`~phyloc.evaluation.metrics.framework_distance_errors`)."""
    return None if getattr(net, "comm_range_m", None) is None else np.asarray(links)


def _method_plan(methods, lspec):
    """``[(label, registry name, options)]``: ``methods`` is a sequence of labels (options from
    ``[localization]``, :meth:`~phyloc.evaluation.sections.LocalizationSpec.plan`) or a
    mapping ``label -> (name, options)``."""
    plan = methods if isinstance(methods, dict) else lspec.plan(methods)
    return [(label, name, opts) for label, (name, opts) in plan.items()]


def localize_realization(real, system, rspec, lspec, methods, inits, seed_seq, keep_particles=()):
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
    clock = time.perf_counter()
    tables = link_tables(real, system, rspec.beta)
    usable = usable_links(tables, rspec, lspec)
    stage = {"tables": time.perf_counter() - clock}
    meas, ests = link_measurements(
        real, tables, rspec, [name for _, name, _ in plan], usable, timings=stage
    )
    corr0 = ests["corr"][0]
    if usable is not None:  # the start ranges only the links the identification kept
        corr0 = dataclasses.replace(corr0, valid=corr0.valid & usable[0])
    observable = [
        observable_pairs(
            net, t, lk, e.valid & meas.usable_links(t), np.random.default_rng(streams[0])
        )
        for t, (e, lk) in enumerate(zip(ests["corr"], real.links, strict=True))
    ]
    pairs = [scored_pairs(net, lk) for lk in real.links]
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
        "observable": None if any(o is None for o in observable) else np.concatenate(observable),
        "neighbours": real.links[0].shape[0] / max(net.n_agents, 1),
        # with anchors, the first snapshot's true positions (for a map of the estimates)
        "map_truth": np.asarray(net.positions[0]) if bool(np.any(net.is_anchor)) else None,
        "map_is_anchor": np.asarray(net.is_anchor, bool),
        "methods": {label: name for label, name, _ in plan},
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
                clock = time.perf_counter()
                priors[Q], centers, undetermined = start_prior(
                    init, net, real.links[0], corr0, lspec, Q, rng_p
                )
                stage.setdefault(f"start_{init}", time.perf_counter() - clock)
                if centers is not None and len(meas.anchor_nodes):
                    out.setdefault(
                        f"start|{init}|pos_err",
                        np.linalg.norm(
                            np.asarray(centers) - net.positions[0][net.agent_index], axis=-1
                        ),
                    )
                if f"start|{init}|err" not in out:  # the start itself, as a method would be
                    out[f"start|{init}|err"] = (
                        np.full(0, np.nan)
                        if centers is None
                        else framework_distance_errors(
                            _nodes(centers, meas, net.agent_index),
                            net.positions[0],
                            net.is_anchor,
                            pairs=pairs[0],
                        )
                    )
                    out[f"start|{init}|undetermined"] = undetermined
            if keep_particles and isinstance(opts, DirectOptions):
                opts = dataclasses.replace(opts, keep_particles=tuple(keep_particles))
            clock = time.perf_counter()
            res = REGISTRY[name].run(meas, priors[Q], rng_m, opts)
            out[f"{label}|{init}|wall_s"] = time.perf_counter() - clock
            out.update(_run_outputs(f"{label}|{init}", res, meas, net.positions, pairs))
    out["stage_s"] = stage
    return out


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


def _run_outputs(key, res, meas, truth, pairs=None):
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
    pairs = [None] * T if pairs is None else pairs
    errs = [
        framework_distance_errors(
            _nodes(res.estimates[t], meas, agents, t), truth[t], is_anchor, pairs=pairs[t]
        )
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
        key + "|jit_s": float(res.diagnostics.get("jit_s", 0.0)),
        key + "|iteration_s": res.timing.wall_s
        / max(res.timing.agent_iterations / max(len(agents), 1), 1.0),
        key + "|agent_snapshot_s": float(np.mean(res.timing.agent_s)),
        key + "|particles_at": {
            t: (np.asarray(X), np.asarray(lw))
            for t, (X, lw) in diag.get("particles_at", {}).items()
        },
    }
    if len(meas.anchor_nodes):  # anchors fix the frame: the absolute position errors too
        diff = [np.asarray(res.estimates[t]) - truth[t][agents] for t in range(T)]
        out[key + "|pos_err"] = np.concatenate([np.linalg.norm(e, axis=-1) for e in diff])
        if diff[0].shape[-1] == 3:  # 3-D: the horizontal error too (3GPP positioning)
            out[key + "|hpos_err"] = np.concatenate(
                [np.linalg.norm(e[..., :2], axis=-1) for e in diff]
            )
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


def _nodes(agent_estimates, meas, agents, t=0):
    """``[n_nodes, dim]`` positions at snapshot ``t``: the estimates in agents' rows, anchors
    where known."""
    full = np.zeros((meas.n_nodes, meas.dim))
    full[meas.anchor_nodes] = meas.anchor_positions[t]
    full[agents] = agent_estimates
    return full

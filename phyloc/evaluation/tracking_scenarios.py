"""The measurements of one tracking run: the network of a scenario and its ranges, drawn from
the Gaussian range model or estimated by SAGE on simulated waveforms.

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from phyloc.errors import ValidationError
from phyloc.evaluation.range_scenarios import (
    RangeScenario,
    network_states,
    scenario_network_spec,
    simulate_scenario,
)


def run_network_spec(exp, scen: dict):
    """The network of one run of scenario ``scen`` (``n_agents``, ``comm_range_m``) with the
    experiment's motion, dimension, region and time step."""
    spec = scenario_network_spec(
        scen["n_agents"],
        exp.n_steps,
        motion=exp.motion,
        dim=exp.dim,
        side_m=exp.side_m,
        dt_s=exp.dt_s,
        accel_std=exp.accel_std,
    )
    if math.isfinite(scen["comm_range_m"]):
        spec = dataclasses.replace(spec, comm_range_m=scen["comm_range_m"])
    return spec


def gaussian_run(exp, scen, rng):
    """One run with ranges drawn from the Gaussian range model (``measurements = "gaussian"``);
    returns the :class:`~phyloc.evaluation.range_scenarios.RangeScenario` and None."""
    from phyloc.network import make_network

    net = make_network(run_network_spec(exp, scen), rng)
    r = scen["comm_range_m"]
    return simulate_scenario(
        net, exp.model(), rng, comm_range_m=r if math.isfinite(r) else None
    ), None


def sage_run(exp, scen, system, chan, rspec, rng):
    """Range measurements of SAGE on simulated waveforms (``measurements = "sage"``)."""
    from phyloc.datasets.simulate import simulate_realization
    from phyloc.phy.correlation import correlation_tables
    from phyloc.ranging import estimate

    model = exp.model()
    real = simulate_realization(system, run_network_spec(exp, scen), chan, rng)
    net = real.network
    agents, anchors = net.agent_index, net.anchor_index
    col = np.empty(net.n_nodes, np.int64)
    col[agents] = np.arange(agents.size)
    col[anchors] = agents.size + np.arange(anchors.size)
    K = exp.n_steps
    z = np.full((K, agents.size, net.n_nodes), np.nan)
    err, var, n_links = [], [], 0
    first = None  # (links, ranges) of the first snapshot with valid estimates
    for k in range(1, K + 1):
        lk = real.links[k]
        rx_agent = ~net.is_anchor[lk[:, 0]]
        lk = lk[rx_agent]
        n_links += lk.shape[0]
        if lk.shape[0] == 0:
            continue
        table = correlation_tables(
            real.received[k][rx_agent], real.symbols, system, beta=rspec.beta, tx_index=lk[:, 1]
        )
        est = estimate("sage", table, **rspec.method_options("sage"))
        rng_m = est.range_m / real.ways
        ok = np.asarray(est.valid, bool)
        z[k - 1, col[lk[ok, 0]], col[lk[ok, 1]]] = rng_m[ok]
        err.append((rng_m - net.distances(k)[rx_agent])[ok])
        if first is None:
            first = (lk[ok], rng_m[ok])
        var.append(est.variance_m2[ok] / real.ways**2)
    states = network_states(net, model)[: K + 1]  # the truth, for the errors and the PCRLB
    sc = RangeScenario(
        model=model,
        anchors=np.ascontiguousarray(net.positions[0, anchors]),
        initial_states=states[0],
        states=states[1:],
        z=z,
        comm_range_m=scen["comm_range_m"],
    )
    err, var = np.concatenate(err), np.concatenate(var)
    sigma = exp.sage_sigma_m
    zzb = math.sqrt(float(np.median(var))) if var.size else exp.sigma_r
    if sigma == "residual":
        sigma = residual_sigma(net, first, dim=exp.dim)
        sigma = zzb if sigma is None else max(sigma, zzb)
    elif sigma == "zzb":
        sigma = zzb
    info = {
        "sq_err_sum": float(np.sum(err**2)),
        "n_valid": int(err.size),
        "n_links": int(n_links),
        "sigma_m": float(sigma),
    }
    return sc, info


def residual_sigma(net, first, *, dim):
    """RMS range residual [m] of the coarse MDS/SMACOF fit of one snapshot's ranges (anchors
    fixing the frame); truth-free. ``None`` without ranges or for a disconnected graph."""
    from phyloc.localization.initialization import coarse_positions

    if first is None or first[0].shape[0] == 0:
        return None
    links, ranges = first
    try:
        sol = coarse_positions(
            links,
            ranges,
            net.n_nodes,
            dim,
            is_anchor=net.is_anchor,
            anchor_positions=net.positions[0, net.anchor_index],
        )
    except ValidationError:
        return None
    return float(sol.residual_rms_m)

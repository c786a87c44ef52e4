"""DiPNet / EL-DPF benchmarks: likelihood kernels, agent-iterations, scaling in Q and |V_u|.

Work unit: one particle–link likelihood evaluation (distance, table interpolation or peak
mixture, accumulate). Figures (names are the interface):

``dipnet.env.evals_per_s_per_core``       DiPNet eq. (25) kernel (cubic interpolation), 1 thread
``dipnet.marginal.evals_per_s_per_core``  phyloc's marginal EL kernel, 1 thread
``dipnet.marginal_tabulated.evals_per_s_per_core``  the same read from its per-link tables
                                          (what the safeguarded filter evaluates between
                                          message exchanges; table built once), 1 thread
``dipnet.marginal_tabulated.speedup``     over the exact marginal EL kernel
``dipnet.gauss.evals_per_s_per_core``     two-step Gaussian ERV kernel, 1 thread
``dipnet.gauss_bounded.evals_per_s_per_core``  the same with the bounded evidence of the
                                          "_bounded" methods (``outlier_nats = 10``: an
                                          ``exp`` and a ``log1p`` per evaluation), 1 thread
``dipnet.gauss_bounded.cost_vs_gauss``    its cost over the plain Gaussian kernel's, same run
``dipnet.env.numpy_evals_per_s``          the NumPy twin of the DiPNet eq. (25) kernel
``dipnet.env.speedup_vs_numpy``           (the twin is ``tests/naive_direct.py``; without a
                                          source checkout both are omitted: ``MISSING``)
``dipnet.agent_iteration_s``              safeguarded DiPNet, Q = 1000, |V_u| = 29 (30 agents)
``dipnet_published.agent_iteration_s``    DiPNet Algorithm 1 as published, same network
``dipnet.c2.agent_iteration_s``           safeguarded DiPNet on a WINNER II C2 network (multipath:
                                          several peaks per link), Q = 1000, |V_u| = 29
``dipnet.scaling_exponent_q``             d log(time) / d log(Q) of one likelihood sweep
``dipnet.scaling_exponent_links``         d log(time) / d log(|V_u|)   (DiPNet Table I: both 1)

Filter cost (:func:`filter_report`; one Numba thread, as a task of a parallel evaluation; 30
agents, Q = 1000, a WINNER II C2 network from the Fig. 5 truth-free start: priors of std 10 m
around centres 5 m off; the two-step filters read true distances with a positive NLOS-like bias
on about a third of the links and variances log-uniform in [1e-4, 0.3] m² (the spread of the
Fig. 5 ZZB variances), so that their links disagree as measured ranges do; ``<filter>`` one of
``dipnet``, ``two_step_paper`` — the ``corr`` method with the plain Gaussian of DiPNet §V-A,
``outlier_nats = inf`` — and ``two_step_bounded`` — ``outlier_nats = 10``, ``model_error_m =
0.3``, the Fig. 5 recipe's "_bounded" methods):

``filter.<filter>.agent_iteration_s``          s per agent-iteration (the method's own timing)
``filter.<filter>.tempering_steps_per_iteration``  adaptive tempering steps per iteration
``filter.<filter>.sweep_s_per_agent``          reference, measured in the same rounds: one
                                               evaluation of the filter's frozen likelihood at
                                               every particle, per agent
``filter.<filter>.sweeps_per_agent_iteration`` agent_iteration_s / sweep_s_per_agent: the
                                               filter's cost in likelihood sweeps (machine-free)
``filter.<filter>.sweeps_per_tempering_step``  the same per tempering step (each step resamples
                                               and runs two Metropolis–Hastings sweeps, which
                                               evaluate the new and the old likelihood: about
                                               4 sweeps is the floor of the likelihood work)

DiPNet Table I, measured (:mod:`benchmarks._table1`; one Numba thread; ``<scheme>`` one of
``exact``, ``sampled``, ``el``, ``dipnet_published``, ``dipnet``):

``table1.<scheme>.agent_iteration_s.q_<Q>``       s per agent-iteration at |V_u| = 4
``table1.<scheme>.agent_iteration_s.links_<k>``   s per agent-iteration at |V_u| = k, fixed Q
``table1.<scheme>.links_sweep_q``                 that fixed Q (``table1.q_sweep_links``: the 4)
``table1.<scheme>.exponent_q``                    d log(time) / d log(Q)
``table1.<scheme>.exponent_q_largest``            the same over the three largest Q
``table1.<scheme>.exponent_links``                d log(time) / d log(|V_u|)
``table1.<scheme>.fixed_s``, ``.per_link_s``      linear fit ``time = fixed + per_link·|V_u|``
``table1.<scheme>.floats_per_link_iteration.q_<Q>``  floats one link carries per iteration
``table1.<scheme>.bytes_per_link_iteration.q_<Q>``   the same in bytes (float64)
``table1.dipnet.tempering_steps_per_iteration.*``  tempering steps of the safeguarded filter
``table1.exact.exponent_joint_size``              d log(time) / d log(Q^|M|), |M| = 2 → 3
``table1.dipnet.table_s_per_link``                β-interpolated IFFT table per link [s]

Exact is the brute-force joint-grid posterior of a 2-agent toy (Q² joint points); sampled and
el are one weighting sweep of the sample-based exchange (``dpe_sampled``'s likelihood) and of
DiPNet eq. (25) with the ENV; the dipnet rows are the registered methods' agent-iterations.
The expected values (DiPNet Table I) are printed beside the measured ones.

The two agent-iteration figures run the registered methods ``METHODS["dipnet"]`` and
``METHODS["dipnet_published"]`` (``run(measurements, prior, rng, options)``) on the network's
correlation tables; ``timing.per_agent_iteration_s`` is the figure.
"""

from __future__ import annotations

import dataclasses

import numba
import numpy as np

from phyloc.channels import ChannelSpec
from phyloc.datasets.simulate import simulate_realization
from phyloc.localization import (
    METHODS,
    DirectLikelihood,
    GaussianRangeLikelihood,
    LinkMeasurements,
    LinkRanges,
    MarginalDirectLikelihood,
    Prior,
    gaussian_log_prior,
    gaussian_priors,
    informed_centers,
)
from phyloc.network import NetworkSpec
from phyloc.phy import OFDMSystem
from phyloc.phy.correlation import correlation_tables

try:
    from phyloc.benchmarks import _table1 as table1
    from phyloc.benchmarks._reference import MISSING, naive
    from phyloc.benchmarks._timing import best_seconds
except ImportError:  # run from the source tree by asv
    from benchmarks import _table1 as table1
    from benchmarks._reference import MISSING, naive
    from benchmarks._timing import best_seconds


def make_network(n_agents=30, seed=0, scenario="awgn"):
    """A fully meshed anchor-free network, its tables and the three likelihoods."""
    system = OFDMSystem()
    rng = np.random.default_rng(seed)
    real = simulate_realization(system, NetworkSpec(n_agents=n_agents), ChannelSpec(scenario), rng)
    links = real.links[0]
    table = correlation_tables(real.received[0], real.symbols, system, tx_index=links[:, 1])
    agent_of = np.arange(n_agents)
    d = real.network.distances(0)
    liks = {
        "env": DirectLikelihood(table, links, agent_of, n_agents),
        "marginal": MarginalDirectLikelihood(table, links, agent_of, n_agents),
        "gauss": GaussianRangeLikelihood(
            d, np.full(d.size, 0.01), np.ones(d.size, bool), links, agent_of, n_agents
        ),
        "gauss_bounded": GaussianRangeLikelihood(
            d,
            np.full(d.size, 0.01),
            np.ones(d.size, bool),
            links,
            agent_of,
            n_agents,
            outlier_nats=10.0,
            model_error_m=0.3,
        ),
    }
    return real, liks, rng


def _state(real, Q, rng):
    pos = real.network.positions[0]
    centers = informed_centers(pos, 5.0, rng=rng)
    X = gaussian_priors(centers, 5.0, Q, rng)
    covs = np.repeat(np.eye(pos.shape[1])[None] * 25.0, pos.shape[0], axis=0)
    return pos, centers, X, covs


class Likelihood:
    """asv: one likelihood sweep over all agents (30 agents × 29 links × Q = 1000)."""

    params = [["env", "marginal", "gauss", "gauss_bounded"]]
    param_names = ["kind"]

    def setup(self, kind):
        self.real, self.liks, rng = make_network()
        self.pos, self.centers, self.X, self.covs = _state(self.real, 1000, rng)
        self.liks[kind].loglik(self.X, self.pos, self.covs)

    def time_loglik(self, kind):
        self.liks[kind].loglik(self.X, self.pos, self.covs)


def _sweep_rate(lik, X, pos, covs, repeat):
    t = best_seconds(lambda: lik.loglik(X, pos, covs), repeat=repeat)
    return lik.csr.rx.size * X.shape[1] / t, t


def _agent_iteration(name, meas, prior, quick):
    """Seconds per agent-iteration of the registered method ``name`` (its own timing), after
    a one-iteration warm-up run (without it, kernels compiled or loaded from the Numba cache
    on first use were counted: 26 ms instead of 2–3 ms per agent-iteration)."""
    method = METHODS[name]
    method.run(meas, prior, np.random.default_rng(1), method.make_options({"n_iterations": 1}))
    opts = method.make_options({"n_iterations": 4 if quick else 8})
    return method.run(meas, prior, np.random.default_rng(1), opts).timing.per_agent_iteration_s


FILTERS = {
    "dipnet": ("dipnet", {}),
    "two_step_paper": ("corr", {"outlier_nats": float("inf"), "model_error_m": 0.0}),
    "two_step_bounded": ("corr", {"outlier_nats": 10.0, "model_error_m": 0.3}),
}
"""The filters of :func:`filter_report`: figure name → (registered method, options)."""


def filter_report(quick: bool = False) -> dict[str, float]:
    """Cost per agent-iteration of the safeguarded DiPNet and of the two-step EL-DPF in its
    paper form and bounded, against one likelihood sweep measured in the same rounds (the
    ``filter.*`` figures of the module docstring)."""
    from phyloc.localization.direct import link_likelihood

    real, liks, rng = make_network(scenario="winner2_c2", seed=5)
    net = real.network
    pos = net.positions[0]
    n = pos.shape[0]
    centers = informed_centers(pos, 5.0, rng=rng)
    X = gaussian_priors(centers, 10.0, 1000, rng)
    prior = Prior(X, lambda x: gaussian_log_prior(x, centers, 10.0), "truth-free")
    links = real.links[0]
    d = net.distances(0)
    var = 10.0 ** rng.uniform(-4.0, -0.5, d.size)  # the spread of Fig. 5's ZZB variances
    nlos = rng.random(d.size) < 0.35
    bias = np.where(nlos, rng.exponential(3.0, d.size), 0.0)
    biased = d + bias + np.sqrt(var) * rng.normal(size=d.size)
    meas = LinkMeasurements(
        n_nodes=net.n_nodes,
        dim=net.dim,
        anchor_nodes=net.anchor_index,
        anchor_positions=pos[net.anchor_index][None],
        links=(links,),
        tables=(liks["env"].table,),
        ranges={"corr": LinkRanges.single(biased, var)},
    )
    covs = np.repeat(np.eye(pos.shape[1])[None] * 100.0, n, axis=0)
    n_it = 3 if quick else 6
    repeat = 2 if quick else 3
    fig: dict[str, float] = {}
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        for name, (method_name, table) in FILTERS.items():
            method = METHODS[method_name]
            warm = method.make_options({**table, "n_iterations": 1})
            method.run(meas, prior, np.random.default_rng(1), warm)  # compile / load kernels
            opts = method.make_options({**table, "n_iterations": n_it})
            frozen = link_likelihood(meas, 0, opts).frozen(X, centers, covs, 1.0)
            t_it = t_sweep = float("inf")
            steps = 0.0
            for _ in range(repeat):  # the filter and its reference, in turn
                res = method.run(meas, prior, np.random.default_rng(1), opts)
                t_it = min(t_it, res.timing.per_agent_iteration_s)
                steps = float(res.diagnostics["annealing_steps"].sum()) / n_it
                t_sweep = min(t_sweep, best_seconds(lambda f=frozen: f(X), repeat=3) / n)
            fig[f"filter.{name}.agent_iteration_s"] = t_it
            fig[f"filter.{name}.tempering_steps_per_iteration"] = steps
            fig[f"filter.{name}.sweep_s_per_agent"] = t_sweep
            fig[f"filter.{name}.sweeps_per_agent_iteration"] = t_it / t_sweep
            fig[f"filter.{name}.sweeps_per_tempering_step"] = t_it / t_sweep / max(steps, 1.0)
    finally:
        numba.set_num_threads(before)
    return fig


def _slope(x, t):
    return float(np.polyfit(np.log(x), np.log(t), 1)[0])


def report(quick: bool = False) -> dict[str, float]:
    """Measure the figures of the module docstring (``quick``: fewer repeats and sizes)."""
    repeat = 2 if quick else 5
    fig: dict[str, float] = {}
    real, liks, rng = make_network()
    pos, centers, X, covs = _state(real, 1000, rng)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        for kind, lik in liks.items():
            fig[f"dipnet.{kind}.evals_per_s_per_core"] = _sweep_rate(lik, X, pos, covs, repeat)[0]
        marg = liks["marginal"]
        tabulated = marg.frozen(X, pos, covs)
        t_tab = best_seconds(lambda: tabulated(X), repeat=repeat)
        fig["dipnet.marginal_tabulated.evals_per_s_per_core"] = (
            marg.csr.rx.size * X.shape[1] / t_tab
        )
        fig["dipnet.gauss_bounded.cost_vs_gauss"] = (
            fig["dipnet.gauss.evals_per_s_per_core"]
            / fig["dipnet.gauss_bounded.evals_per_s_per_core"]
        )
        fig["dipnet.marginal_tabulated.speedup"] = (
            fig["dipnet.marginal_tabulated.evals_per_s_per_core"]
            / fig["dipnet.marginal.evals_per_s_per_core"]
        )
    finally:
        numba.set_num_threads(before)
    twin = naive("naive_direct")
    if twin is not None:
        env = liks["env"]
        scale = 1.0 / (env.env(pos, covs) * env.energy)
        Xs = X[:4]
        off = env.csr.offsets[:5]
        t_np = best_seconds(
            lambda: twin.direct_loglik_numpy(
                Xs,
                off,
                env.csr.tx,
                env.rows,
                scale,
                pos,
                env.table.values,
                1.0 / env.table.spacing_m,
                4,
            ),
            repeat=max(1, repeat - 2),
        )
        fig["dipnet.env.numpy_evals_per_s"] = off[-1] * Xs.shape[1] / t_np
        fig["dipnet.env.speedup_vs_numpy"] = (
            fig["dipnet.env.evals_per_s_per_core"] / fig["dipnet.env.numpy_evals_per_s"]
        )
    prior = Prior(X, lambda x: gaussian_log_prior(x, centers[:30], 5.0), "informed start")
    net = real.network
    meas = LinkMeasurements(
        n_nodes=net.n_nodes,
        dim=net.dim,
        anchor_nodes=net.anchor_index,
        anchor_positions=pos[net.anchor_index][None],
        links=(real.links[0],),
        tables=(liks["env"].table,),
    )
    for name in ("dipnet", "dipnet_published"):
        fig[f"{name}.agent_iteration_s"] = _agent_iteration(name, meas, prior, quick)
    real_c2, liks_c2, rng_c2 = make_network(scenario="winner2_c2")
    pos_c2, centers_c2, X_c2, _ = _state(real_c2, 1000, rng_c2)
    meas_c2 = dataclasses.replace(
        meas,
        anchor_positions=pos_c2[net.anchor_index][None],
        links=(real_c2.links[0],),
        tables=(liks_c2["env"].table,),
    )
    prior_c2 = Prior(X_c2, lambda x: gaussian_log_prior(x, centers_c2, 5.0), "informed start")
    fig["dipnet.c2.agent_iteration_s"] = _agent_iteration("dipnet", meas_c2, prior_c2, quick)
    qs = [250, 500, 1000, 2000] if quick else [250, 500, 1000, 2000, 4000]
    tq = [
        _sweep_rate(liks["env"], gaussian_priors(centers, 5.0, q, rng), pos, covs, repeat)[1]
        for q in qs
    ]
    fig["dipnet.scaling_exponent_q"] = _slope(qs, tq)
    sizes = [6, 11, 21, 30]
    tl = []
    for n in sizes:
        r2, l2, g2 = make_network(n_agents=n)
        p2, _c2, X2, v2 = _state(r2, 1000, g2)
        tl.append(_sweep_rate(l2["env"], X2, p2, v2, repeat)[1] / n)  # per agent
    fig["dipnet.scaling_exponent_links"] = _slope([n - 1 for n in sizes], tl)
    fig.update(filter_report(quick=quick))
    fig.update(table1.report(quick=quick))
    return fig


def summarize(fig: dict) -> str:
    """The printed form of :func:`report`."""
    from phyloc.reporting import format_table

    has_twin = "dipnet.env.numpy_evals_per_s" in fig
    ratio = f"{fig['dipnet.env.speedup_vs_numpy']:.0f}x NumPy twin" if has_twin else "MISSING"
    rows = [
        ("DiPNet eq. (25) kernel (ENV, cubic)", fig["dipnet.env.evals_per_s_per_core"], ratio),
        ("marginal EL kernel", fig["dipnet.marginal.evals_per_s_per_core"], ""),
        (
            "marginal EL, tabulated links",
            fig["dipnet.marginal_tabulated.evals_per_s_per_core"],
            f"{fig['dipnet.marginal_tabulated.speedup']:.1f}x exact",
        ),
        ("Gaussian ERV kernel", fig["dipnet.gauss.evals_per_s_per_core"], "reference"),
        (
            "Gaussian ERV, bounded evidence",
            fig["dipnet.gauss_bounded.evals_per_s_per_core"],
            f"{fig['dipnet.gauss_bounded.cost_vs_gauss']:.1f}x the cost of the Gaussian",
        ),
        (
            "DiPNet eq. (25) NumPy twin",
            fig["dipnet.env.numpy_evals_per_s"] if has_twin else "MISSING",
            "reference",
        ),
    ]
    t1 = format_table(rows, ["particle-link evaluations", "per s per core", "ratio"])
    rows2 = [
        ("dipnet (safeguarded)", 1e3 * fig["dipnet.agent_iteration_s"]),
        ("dipnet_published", 1e3 * fig["dipnet_published.agent_iteration_s"]),
        ("dipnet (safeguarded), WINNER II C2", 1e3 * fig["dipnet.c2.agent_iteration_s"]),
    ]
    t2 = format_table(rows2, ["Q = 1000, |V_u| = 29", "ms per agent-iteration"])
    t3 = (
        f"scaling of one likelihood sweep: time ∝ Q^{fig['dipnet.scaling_exponent_q']:.2f}, "
        f"∝ |V_u|^{fig['dipnet.scaling_exponent_links']:.2f} per agent "
        "(DiPNet Table I: 1 and 1)"
    )
    missing = "" if has_twin else f"\nMISSING: {MISSING}"
    t4 = f"\n\n{table1.summarize(fig)}" if "table1.q_sweep_links" in fig else ""
    t5 = f"\n\n{summarize_filters(fig)}" if "filter.dipnet.agent_iteration_s" in fig else ""
    return f"{t1}{missing}\n\n{t2}\n\n{t3}{t5}{t4}"


def summarize_filters(fig: dict) -> str:
    """The printed form of :func:`filter_report`."""
    from phyloc.reporting import format_table

    rows = [
        (
            name,
            1e3 * fig[f"filter.{name}.agent_iteration_s"],
            fig[f"filter.{name}.tempering_steps_per_iteration"],
            1e3 * fig[f"filter.{name}.sweep_s_per_agent"],
            fig[f"filter.{name}.sweeps_per_agent_iteration"],
            fig[f"filter.{name}.sweeps_per_tempering_step"],
        )
        for name in FILTERS
    ]
    head = [
        "filter (C2, 30 agents, Q = 1000, 1 thread)",
        "ms per agent-iteration",
        "tempering steps per iteration",
        "ms per sweep per agent (reference)",
        "sweeps per agent-iteration",
        "sweeps per tempering step",
    ]
    return format_table(rows, head)

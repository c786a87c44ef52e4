"""PF-BP / EDH / SIR-BP benchmarks on a small PF-BP Scenario I (5 agents, 9 anchors, 20 m cube).

CA model in 3-D (9-D states), σ = 0.1 m, fully connected (r_max = ∞), 2 message-passing
iterations, 200 particles and 20 λ-steps for the flow methods. Times are medians over the time
steps of one run after a warm-up run (JIT compilation). Figures (names are the interface):

``pfbp.s1_rinf.step_s``                   PF-BP wall time per time step, joint processing [s]
``pfbp.s1_rinf.agent_s``                  ... per agent (distributed processing) [s]
``pfbp.particle_flow_steps_per_s``        particles × λ-steps × agents × iterations per second
``pfbp_numpy.s1_rinf.step_s``             PF-BP with the NumPy flow twin [s] (``range_flow_numpy``
                                          of ``tests/naive_flow.py``, swapped in by
                                          :func:`phyloc.localization.tracking.use_flow`; omitted,
                                          with the ratio, outside a source checkout)
``pfbp.flow_kernel.speedup_vs_numpy``     ratio of the two
``edh.s1_rinf.step_s``                    centralized EDH filter per time step [s]
``sirbp.s1_rinf.step_s``                  SIR-BP per time step [s] (``sirbp.n_particles`` per agent)
``sirbp.s1_rinf.agent_s``                 ... per agent [s]
``sirbp_over_pfbp.step_ratio``            SIR-BP time / PF-BP time per step
``spbp.s1_rinf.step_s``                   sigma-point BP per time step [s]
``spbp.s1_rinf.agent_s``                  ... per agent [s]
``<m>.s2_r18.step_s``, ``<m>.s2_r18.agent_s``   the same for Scenario II (20 agents,
                                          r_max = 18 m; ``m`` in pfbp, edh, sirbp, spbp; SIR-BP
                                          with ``sirbp.n_particles``; PF-BP exchanging Gaussian
                                          beliefs, as the Scenario II recipe), Table II
``sirbp_over_pfbp.s2_r18.step_ratio``     SIR-BP time / PF-BP time per step in Scenario II
``pfbp_over_edh.s2_r18.step_ratio``       PF-BP time / EDH time per step in Scenario II (Table II:
                                          0.9 / 0.25 s = 3.6)
``pfbp_numpy.s2_r18.step_s``              PF-BP with the NumPy flow twin in Scenario II [s]
``edh_numpy.s2_r18.step_s``               EDH with the NumPy flow twin in Scenario II [s]
``pfbp_numpy_over_edh.s2_r18.step_ratio`` PF-BP with the NumPy flow over EDH (numba flow)
``pfbp_numpy_over_edh_numpy.s2_r18.step_ratio``   ... over EDH with the NumPy flow too: Table
                                          II's order with the flow of both written as plain
                                          array code, as the paper's implementation may have had
                                          it (the three omitted with the twin)
``<m>.s2_r18.stage.<stage>_s``            the median step of ``<m>`` (also ``pfbp_numpy``,
                                          ``edh_numpy``) split by stage
                                          (:data:`phyloc.localization.tracking.loop.STAGES`)

Everything runs with one BLAS thread (as the experiment runner does): the matrices are small, and
OpenBLAS threads on a busy machine made a Scenario II step up to 10x slower. The trackers run
through :data:`phyloc.localization.METHODS` on the truth-free measurements of a simulated
scenario (:mod:`phyloc.evaluation.range_scenarios`).

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
(Tables I, II.)
"""

from __future__ import annotations

import dataclasses

import numpy as np
from threadpoolctl import threadpool_limits

from phyloc.evaluation.range_scenarios import scenario_network_spec, simulate_scenario
from phyloc.localization.tracking import (
    PFBPOptions,
    RangeModel,
    SIRBPOptions,
    SPBPOptions,
    paper_prior,
    run_edh,
    run_pfbp,
    run_sirbp,
    run_spbp,
    use_flow,
)
from phyloc.localization.tracking.loop import STAGES
from phyloc.network import make_network
from phyloc.reporting import format_table

try:
    from phyloc.benchmarks._reference import MISSING, naive
except ImportError:  # run from the source tree by asv
    from benchmarks._reference import MISSING, naive

N_AGENTS = 5
N_PARTICLES = 200
N_LAMBDA = 20
N_ITER = 2


def _numpy_flow():
    """The NumPy twin of the flow kernel (``tests/naive_flow.py``), or None."""
    module = naive("naive_flow")
    return None if module is None else module.range_flow_numpy


def make_scenario(n_steps=5, seed=0, n_agents=N_AGENTS, comm_range_m=None):
    """Measurements of a Scenario I (or, with 20 agents and r_max = 18 m, II) realization and
    their PF-BP eq. (31) prior."""
    rng = np.random.default_rng(seed)
    spec = scenario_network_spec(n_agents, n_steps)
    if comm_range_m is not None:
        spec = dataclasses.replace(spec, comm_range_m=comm_range_m)
    net = make_network(spec, rng)
    sc = simulate_scenario(net, RangeModel(), rng, comm_range_m=comm_range_m)
    meas = sc.measurements()
    return meas, paper_prior(meas, rng)


def _median_step(fn, meas, prior, opt, flow=None, stages=None):
    """Median time per step and per agent of one run after a warm-up run; with a dict
    ``stages``, the median of each stage of the step (``diagnostics["stage_s"]``) goes in it."""
    with use_flow(flow):
        fn(meas, prior, np.random.default_rng(1), opt)  # warm-up (JIT)
        r = fn(meas, prior, np.random.default_rng(2), opt)
    if stages is not None:
        stages.update({k: float(np.median(v)) for k, v in r.diagnostics["stage_s"].items()})
    return float(np.median(r.timing.step_s)), float(np.median(r.timing.agent_s))


class TimeStep:
    """asv: one PF-BP time step on Scenario I, numba flow kernel or its NumPy twin."""

    params = [["numba", "numpy"]]
    param_names = ["backend"]

    def setup(self, backend):
        self.flow = None
        if backend == "numpy":
            self.flow = _numpy_flow()
            if self.flow is None:
                raise NotImplementedError(MISSING)  # asv skips the parameter
        self.meas, self.prior = make_scenario(n_steps=1)
        self.opt = PFBPOptions()
        self.time_pfbp_step(backend)

    def time_pfbp_step(self, backend):
        with use_flow(self.flow):
            run_pfbp(self.meas, self.prior, np.random.default_rng(0), self.opt)


class TimeSPBPStep:
    """asv: one SP-BP time step on Scenario I."""

    def setup(self):
        self.meas, self.prior = make_scenario(n_steps=1)
        self.opt = SPBPOptions(n_iterations=N_ITER)

    def time_spbp_step(self):
        run_spbp(self.meas, self.prior, None, self.opt)


def report(quick: bool = False) -> dict[str, float]:
    """Measure every figure of the module docstring; ``quick`` shortens the runs."""
    with threadpool_limits(limits=1, user_api="blas"):
        fig = _report_s1(quick)
        fig.update(_report_s2(quick))
    return fig


def _report_s2(quick: bool) -> dict[str, float]:
    """Scenario II (20 agents, r_max = 18 m): time per step and per agent (Table II)."""
    n_sir = 10_000 if quick else 100_000
    meas, prior = make_scenario(1 if quick else 2, seed=1, n_agents=20, comm_range_m=18.0)
    opt = PFBPOptions(n_particles=N_PARTICLES, n_lambda=N_LAMBDA, n_iterations=N_ITER)
    # PF-BP as Scenario II runs it (datasets/pfbp_scenario2.toml): Gaussian beliefs exchanged
    pf_opt = dataclasses.replace(opt, exchange="gaussian")
    fig: dict[str, float] = {}
    runs = {
        "pfbp": (run_pfbp, pf_opt, None),
        "edh": (run_edh, opt, None),
        "sirbp": (run_sirbp, SIRBPOptions(n_particles=n_sir, n_iterations=N_ITER), None),
        "spbp": (run_spbp, SPBPOptions(n_iterations=N_ITER), None),
    }
    flow = _numpy_flow()
    if flow is not None:  # Table II's order with the flow as plain array code, in both methods
        runs["pfbp_numpy"] = (run_pfbp, pf_opt, flow)
        runs["edh_numpy"] = (run_edh, opt, flow)
    for name, (fn, o, fl) in runs.items():
        stages: dict[str, float] = {}
        step, agent = _median_step(fn, meas, prior, o, fl, stages)
        fig[f"{name}.s2_r18.step_s"] = step
        if not name.startswith("edh"):
            fig[f"{name}.s2_r18.agent_s"] = agent
        for stage, seconds in stages.items():
            fig[f"{name}.s2_r18.stage.{stage}_s"] = seconds
    fig["sirbp_over_pfbp.s2_r18.step_ratio"] = (
        fig["sirbp.s2_r18.step_s"] / fig["pfbp.s2_r18.step_s"]
    )
    fig["pfbp_over_edh.s2_r18.step_ratio"] = fig["pfbp.s2_r18.step_s"] / fig["edh.s2_r18.step_s"]
    if flow is not None:
        fig["pfbp_numpy_over_edh.s2_r18.step_ratio"] = (
            fig["pfbp_numpy.s2_r18.step_s"] / fig["edh.s2_r18.step_s"]
        )
        fig["pfbp_numpy_over_edh_numpy.s2_r18.step_ratio"] = (
            fig["pfbp_numpy.s2_r18.step_s"] / fig["edh_numpy.s2_r18.step_s"]
        )
    return fig


def _report_s1(quick: bool) -> dict[str, float]:
    n_steps = 3 if quick else 10
    n_sir = 10_000 if quick else 100_000
    meas, prior = make_scenario(n_steps)
    opt = PFBPOptions(n_particles=N_PARTICLES, n_lambda=N_LAMBDA, n_iterations=N_ITER)
    fig: dict[str, float] = {
        "n_agents": N_AGENTS,
        "n_particles": N_PARTICLES,
        "n_lambda": N_LAMBDA,
        "sirbp.n_particles": n_sir,
    }
    step, agent = _median_step(run_pfbp, meas, prior, opt)
    fig["pfbp.s1_rinf.step_s"] = step
    fig["pfbp.s1_rinf.agent_s"] = agent
    fig["pfbp.particle_flow_steps_per_s"] = N_PARTICLES * N_LAMBDA * N_AGENTS * N_ITER / step
    flow = _numpy_flow()
    if flow is None:
        print(MISSING)
    else:
        np_opt = PFBPOptions(n_particles=N_PARTICLES, n_lambda=N_LAMBDA)
        fig["pfbp_numpy.s1_rinf.step_s"] = _median_step(run_pfbp, meas, prior, np_opt, flow)[0]
        fig["pfbp.flow_kernel.speedup_vs_numpy"] = fig["pfbp_numpy.s1_rinf.step_s"] / step
    fig["edh.s1_rinf.step_s"] = _median_step(run_edh, meas, prior, opt)[0]
    sir_step, sir_agent = _median_step(run_sirbp, meas, prior, SIRBPOptions(n_particles=n_sir))
    fig["sirbp.s1_rinf.step_s"] = sir_step
    fig["sirbp.s1_rinf.agent_s"] = sir_agent
    fig["sirbp_over_pfbp.step_ratio"] = sir_step / step
    sp_step, sp_agent = _median_step(run_spbp, meas, prior, SPBPOptions(n_iterations=N_ITER))
    fig["spbp.s1_rinf.step_s"] = sp_step
    fig["spbp.s1_rinf.agent_s"] = sp_agent
    return fig


def summarize(fig: dict) -> str:
    """A table of the figures of :func:`report`."""
    rows = [
        ("PF-BP (numba flow)", fig["pfbp.s1_rinf.step_s"], fig["pfbp.s1_rinf.agent_s"]),
        ("PF-BP (NumPy flow)", fig.get("pfbp_numpy.s1_rinf.step_s", float("nan")), None),
        ("EDH (joint)", fig["edh.s1_rinf.step_s"], None),
        (
            f"SIR-BP ({int(fig['sirbp.n_particles'])} particles)",
            fig["sirbp.s1_rinf.step_s"],
            fig["sirbp.s1_rinf.agent_s"],
        ),
        ("SP-BP", fig["spbp.s1_rinf.step_s"], fig["spbp.s1_rinf.agent_s"]),
    ]
    table = format_table(rows, ["Scenario I, r_max = inf", "step [s]", "per agent [s]"])
    rows2 = [
        (label, fig[f"{m}.s2_r18.step_s"], fig.get(f"{m}.s2_r18.agent_s"))
        for m, label in _scenario2_rows(fig)
    ]
    table2 = format_table(rows2, ["Scenario II, r_max = 18 m", "step [s]", "per agent [s]"])
    labels = dict(_scenario2_rows(fig))
    rows3 = [(labels[m], *(fig.get(f"{m}.s2_r18.stage.{st}_s") for st in STAGES)) for m in labels]
    table3 = format_table(rows3, ["Scenario II step by stage [s]", *STAGES])
    speedup = fig.get("pfbp.flow_kernel.speedup_vs_numpy", float("nan"))
    both = fig.get("pfbp_numpy_over_edh_numpy.s2_r18.step_ratio", float("nan"))
    return (
        f"{table}\n{table2}\n{table3}\n"
        f"PF-BP particles x lambda-steps per s: {fig['pfbp.particle_flow_steps_per_s']:.4g}; "
        f"flow kernel speed-up vs NumPy: {speedup:.3g}; "
        f"SIR-BP / PF-BP per step: {fig['sirbp_over_pfbp.step_ratio']:.3g}; Scenario II "
        f"PF-BP / EDH per step: {fig['pfbp_over_edh.s2_r18.step_ratio']:.3g} (NumPy flow: "
        f"{fig.get('pfbp_numpy_over_edh.s2_r18.step_ratio', float('nan')):.3g}, both methods "
        f"with it: {both:.3g}; Table II 3.6)"
    )


def _scenario2_rows(fig: dict):
    """``(method key, label)`` of the Scenario II rows of :func:`summarize`."""
    yield "pfbp", "PF-BP"
    if "pfbp_numpy.s2_r18.step_s" in fig:
        yield "pfbp_numpy", "PF-BP (NumPy flow)"
    yield "edh", "EDH (joint)"
    if "edh_numpy.s2_r18.step_s" in fig:
        yield "edh_numpy", "EDH (NumPy flow)"
    yield "sirbp", f"SIR-BP ({int(fig['sirbp.n_particles'])} particles)"
    yield "spbp", "SP-BP"

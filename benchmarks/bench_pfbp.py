"""PF-BP / EDH / SIR-BP benchmarks on a small PF-BP Scenario I (5 agents, 9 anchors, 20 m cube).

CA model in 3-D (9-D states), σ = 0.1 m, fully connected (r_max = ∞), 2 message-passing
iterations, 200 particles and 20 λ-steps for the flow methods. Times are medians over the time
steps of one run after a warm-up run (JIT compilation). Figures (names are the interface):

``pfbp.s1_rinf.step_s``                   PF-BP wall time per time step, joint processing [s]
``pfbp.s1_rinf.agent_s``                  ... per agent (distributed processing) [s]
``pfbp.particle_flow_steps_per_s``        particles × λ-steps × agents × iterations per second
``pfbp_numpy.s1_rinf.step_s``             PF-BP with the NumPy flow twin [s]
``pfbp.flow_kernel.speedup_vs_numpy``     ratio of the two
``edh.s1_rinf.step_s``                    centralized EDH filter per time step [s]
``sirbp.s1_rinf.step_s``                  SIR-BP per time step [s] (``sirbp.n_particles`` per agent)
``sirbp.s1_rinf.agent_s``                 ... per agent [s]
``sirbp_over_pfbp.step_ratio``            SIR-BP time / PF-BP time per step
``spbp.s1_rinf.step_s``                   sigma-point BP per time step [s]
``spbp.s1_rinf.agent_s``                  ... per agent [s]
"""

from __future__ import annotations

import numpy as np

from phyloc.localization.edh import run_edh
from phyloc.localization.pfbp import PFBPOptions, run_pfbp
from phyloc.localization.range_models import (
    RangeModel,
    paper_prior,
    scenario_network_spec,
    simulate_scenario,
)
from phyloc.localization.sirbp import SIRBPOptions, run_sirbp
from phyloc.localization.spbp import SPBPOptions, run_spbp
from phyloc.network import make_network
from phyloc.reporting import format_table

N_AGENTS = 5
N_PARTICLES = 200
N_LAMBDA = 20
N_ITER = 2


def make_scenario(n_steps=5, seed=0):
    """Scenario I realization and its eq. (31) prior."""
    rng = np.random.default_rng(seed)
    net = make_network(scenario_network_spec(N_AGENTS, n_steps), rng)
    sc = simulate_scenario(net, RangeModel(), rng)
    mean, cov = paper_prior(sc, rng)
    return sc, mean, cov


def _median_step(fn, sc, mean, cov, opt):
    fn(sc, mean, cov, np.random.default_rng(1), opt)  # warm-up (JIT)
    r = fn(sc, mean, cov, np.random.default_rng(2), opt)
    return float(np.median(r.step_s)), float(np.median(r.agent_s))


class TimeStep:
    """asv: one PF-BP time step on Scenario I."""

    params = [["numba", "numpy"]]
    param_names = ["backend"]

    def setup(self, backend):
        self.sc, self.mean, self.cov = make_scenario(n_steps=1)
        self.opt = PFBPOptions(backend=backend)
        run_pfbp(self.sc, self.mean, self.cov, np.random.default_rng(0), self.opt)

    def time_pfbp_step(self, backend):
        run_pfbp(self.sc, self.mean, self.cov, np.random.default_rng(0), self.opt)


class TimeSPBPStep:
    """asv: one SP-BP time step on Scenario I."""

    def setup(self):
        self.sc, self.mean, self.cov = make_scenario(n_steps=1)
        self.opt = SPBPOptions(n_iterations=N_ITER)

    def time_spbp_step(self):
        run_spbp(self.sc, self.mean, self.cov, None, self.opt)


def report(quick: bool = False) -> dict[str, float]:
    """Measure every figure of the module docstring; ``quick`` shortens the runs."""
    n_steps = 3 if quick else 10
    n_sir = 10_000 if quick else 100_000
    sc, mean, cov = make_scenario(n_steps)
    opt = PFBPOptions(n_particles=N_PARTICLES, n_lambda=N_LAMBDA, n_iterations=N_ITER)
    fig: dict[str, float] = {
        "n_agents": N_AGENTS,
        "n_particles": N_PARTICLES,
        "n_lambda": N_LAMBDA,
        "sirbp.n_particles": n_sir,
    }
    step, agent = _median_step(run_pfbp, sc, mean, cov, opt)
    fig["pfbp.s1_rinf.step_s"] = step
    fig["pfbp.s1_rinf.agent_s"] = agent
    fig["pfbp.particle_flow_steps_per_s"] = N_PARTICLES * N_LAMBDA * N_AGENTS * N_ITER / step
    np_opt = PFBPOptions(n_particles=N_PARTICLES, n_lambda=N_LAMBDA, backend="numpy")
    fig["pfbp_numpy.s1_rinf.step_s"] = _median_step(run_pfbp, sc, mean, cov, np_opt)[0]
    fig["pfbp.flow_kernel.speedup_vs_numpy"] = fig["pfbp_numpy.s1_rinf.step_s"] / step
    fig["edh.s1_rinf.step_s"] = _median_step(run_edh, sc, mean, cov, opt)[0]
    sir_step, sir_agent = _median_step(run_sirbp, sc, mean, cov, SIRBPOptions(n_particles=n_sir))
    fig["sirbp.s1_rinf.step_s"] = sir_step
    fig["sirbp.s1_rinf.agent_s"] = sir_agent
    fig["sirbp_over_pfbp.step_ratio"] = sir_step / step
    sp_step, sp_agent = _median_step(run_spbp, sc, mean, cov, SPBPOptions(n_iterations=N_ITER))
    fig["spbp.s1_rinf.step_s"] = sp_step
    fig["spbp.s1_rinf.agent_s"] = sp_agent
    return fig


def summarize(fig: dict) -> str:
    """A table of the figures of :func:`report`."""
    rows = [
        ("PF-BP (numba flow)", fig["pfbp.s1_rinf.step_s"], fig["pfbp.s1_rinf.agent_s"]),
        ("PF-BP (NumPy flow)", fig["pfbp_numpy.s1_rinf.step_s"], None),
        ("EDH (joint)", fig["edh.s1_rinf.step_s"], None),
        (
            f"SIR-BP ({int(fig['sirbp.n_particles'])} particles)",
            fig["sirbp.s1_rinf.step_s"],
            fig["sirbp.s1_rinf.agent_s"],
        ),
        ("SP-BP", fig["spbp.s1_rinf.step_s"], fig["spbp.s1_rinf.agent_s"]),
    ]
    table = format_table(rows, ["Scenario I, r_max = inf", "step [s]", "per agent [s]"])
    return (
        f"{table}\n"
        f"PF-BP particles x lambda-steps per s: {fig['pfbp.particle_flow_steps_per_s']:.4g}; "
        f"flow kernel speed-up vs NumPy: {fig['pfbp.flow_kernel.speedup_vs_numpy']:.3g}; "
        f"SIR-BP / PF-BP per step: {fig['sirbp_over_pfbp.step_ratio']:.3g}"
    )

"""Localization: DiPNet (direct), the two-step equivalent-likelihood DPF, initialization.

See :mod:`phyloc.localization.dpf` (the filter and its safeguards),
:mod:`phyloc.localization.likelihoods` (DiPNet's eq. (25) and the Gaussian ranging model with the
ERV of eq. (18)) and :mod:`phyloc.localization.initialization` (truth-free coarse positions,
informed and gauge priors).
"""

from phyloc.localization.dpf import DPFOptions, DPFResult, Prior, run_dpf, run_tracking
from phyloc.localization.edh import run_edh
from phyloc.localization.initialization import (
    INFORMED_START_STD_M,
    CoarseSolution,
    classical_mds,
    coarse_positions,
    gauge_log_prior,
    gauge_priors,
    gaussian_log_prior,
    gaussian_priors,
    informed_centers,
    range_matrix,
    raw_stress,
    shortest_path_completion,
    smacof,
)
from phyloc.localization.likelihoods import DirectLikelihood, GaussianRangeLikelihood
from phyloc.localization.pfbp import PFBPOptions, run_pfbp
from phyloc.localization.range_models import (
    RangeModel,
    RangeScenario,
    paper_prior,
    scenario_network_spec,
    simulate_scenario,
    state_errors,
)
from phyloc.localization.sirbp import SIRBPOptions, run_sirbp
from phyloc.localization.spbp import SPBPOptions, run_spbp

__all__ = [
    "INFORMED_START_STD_M",
    "CoarseSolution",
    "DPFOptions",
    "DPFResult",
    "DirectLikelihood",
    "GaussianRangeLikelihood",
    "PFBPOptions",
    "Prior",
    "RangeModel",
    "RangeScenario",
    "SIRBPOptions",
    "SPBPOptions",
    "classical_mds",
    "coarse_positions",
    "gauge_log_prior",
    "gauge_priors",
    "gaussian_log_prior",
    "gaussian_priors",
    "informed_centers",
    "paper_prior",
    "range_matrix",
    "raw_stress",
    "run_dpf",
    "run_edh",
    "run_pfbp",
    "run_sirbp",
    "run_spbp",
    "run_tracking",
    "scenario_network_spec",
    "shortest_path_completion",
    "simulate_scenario",
    "smacof",
    "state_errors",
]

"""Localization: DiPNet (direct), the two-step equivalent-likelihood DPF, initialization.

See :mod:`phyloc.localization.dpf` (the filter and its safeguards),
:mod:`phyloc.localization.likelihoods` (DiPNet's eq. (25) and the Gaussian ranging model with the
ERV of eq. (18)) and :mod:`phyloc.localization.initialization` (truth-free coarse positions,
informed and gauge priors).
"""

from phyloc.localization.dpf import DPFOptions, DPFResult, Prior, run_dpf, run_tracking
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

__all__ = [
    "INFORMED_START_STD_M",
    "CoarseSolution",
    "DPFOptions",
    "DPFResult",
    "DirectLikelihood",
    "GaussianRangeLikelihood",
    "Prior",
    "classical_mds",
    "coarse_positions",
    "gauge_log_prior",
    "gauge_priors",
    "gaussian_log_prior",
    "gaussian_priors",
    "informed_centers",
    "range_matrix",
    "raw_stress",
    "run_dpf",
    "run_tracking",
    "shortest_path_completion",
    "smacof",
]

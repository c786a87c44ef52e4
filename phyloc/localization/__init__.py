"""Localization: DiPNet (direct), the two-step equivalent-likelihood DPF, initialization.

See :mod:`phyloc.localization.direct.dpf` (the filter and its safeguards),
:mod:`phyloc.localization.likelihoods` (DiPNet's eq. (25) and the Gaussian ranging model with the
ERV of eq. (18)) and :mod:`phyloc.localization.initialization` (truth-free coarse positions,
informed and gauge priors).

Range-level cooperative methods: PF-BP, SIR-BP, SP-BP and EDH for tracking
(:mod:`~phyloc.localization.tracking.range_models`), and for static networks with one-sided ranging
errors the polygon outer-approximation (:mod:`~phyloc.localization.static.polygons`), NBP with
interchangeable proposals (:mod:`~phyloc.localization.static.nbp`), Gaussian BP and WLS
(:mod:`~phyloc.localization.static.gaussian_bp`) on :mod:`~phyloc.localization.static.static_ranges`.
"""

from phyloc.localization.direct.dpf import DPFOptions, DPFResult, Prior, run_dpf, run_tracking
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
from phyloc.localization.static.gaussian_bp import (
    GaussianBPOptions,
    WLSOptions,
    run_gaussian_bp,
    run_wls,
)
from phyloc.localization.static.nbp import NBPOptions, run_nbp
from phyloc.localization.static.polygons import (
    ConvexPolygon,
    anchor_polygon,
    ellipse_outer_approximation,
    intersect,
    poa,
    scale_polygon,
)
from phyloc.localization.static.static_ranges import (
    ExponentialRangeError,
    GaussianRangeError,
    paper_static_scenario,
    simulate_ranges,
)
from phyloc.localization.tracking.edh import run_edh
from phyloc.localization.tracking.pfbp import PFBPOptions, run_pfbp
from phyloc.localization.tracking.range_models import (
    RangeModel,
    RangeScenario,
    paper_prior,
    scenario_network_spec,
    simulate_scenario,
    state_errors,
)
from phyloc.localization.tracking.sirbp import SIRBPOptions, run_sirbp
from phyloc.localization.tracking.spbp import SPBPOptions, run_spbp

__all__ = [
    "INFORMED_START_STD_M",
    "CoarseSolution",
    "ConvexPolygon",
    "DPFOptions",
    "DPFResult",
    "DirectLikelihood",
    "ExponentialRangeError",
    "GaussianBPOptions",
    "GaussianRangeError",
    "GaussianRangeLikelihood",
    "NBPOptions",
    "PFBPOptions",
    "Prior",
    "RangeModel",
    "RangeScenario",
    "SIRBPOptions",
    "SPBPOptions",
    "WLSOptions",
    "anchor_polygon",
    "classical_mds",
    "coarse_positions",
    "ellipse_outer_approximation",
    "gauge_log_prior",
    "gauge_priors",
    "gaussian_log_prior",
    "gaussian_priors",
    "informed_centers",
    "intersect",
    "paper_prior",
    "paper_static_scenario",
    "poa",
    "range_matrix",
    "raw_stress",
    "run_dpf",
    "run_edh",
    "run_gaussian_bp",
    "run_nbp",
    "run_pfbp",
    "run_sirbp",
    "run_spbp",
    "run_tracking",
    "run_wls",
    "scale_polygon",
    "scenario_network_spec",
    "shortest_path_completion",
    "simulate_ranges",
    "simulate_scenario",
    "smacof",
    "state_errors",
]

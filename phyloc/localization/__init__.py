"""Localization: every method is ``run(measurements, prior, rng, options) -> Result`` of its family.

Families (one folder each; they do not import each other):

- :mod:`phyloc.localization.direct` — DiPNet and the two-step EL-DPF (DiPNet Algorithm 1),
- :mod:`phyloc.localization.tracking` — PF-BP, SIR-BP, SP-BP and EDH on ranges (PF-BP paper),
- :mod:`phyloc.localization.static` — polygon outer-approximation, NBP with its proposals,
  Gaussian BP and WLS for static networks (POA-NBP paper).

Shared parts live here: :mod:`~phyloc.localization.particles` (weights, ESS, resampling,
regularization, Metropolis–Hastings moves), :mod:`~phyloc.localization.likelihoods` (the
``Likelihood`` protocol and its direct, marginal and Gaussian implementations),
:mod:`~phyloc.localization.initialization` (truth-free coarse positions and priors),
:mod:`~phyloc.localization.results` (:class:`Result`) and
:mod:`~phyloc.localization.registry` (:data:`METHODS`, :func:`register_method`).

Examples
--------
>>> from phyloc.localization import METHODS
>>> sorted(METHODS.family("direct"))[:2]
['corr', 'dipnet']
"""

# ruff: noqa: I001 (imports grouped by family)
from phyloc.localization.registry import FAMILIES, METHODS, Method, Registry, register_method
from phyloc.localization.results import Result, Timing

# The families register their methods in METHODS when imported.
# --- direct family -------------------------------------------------------------------------
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

# --- tracking family -----------------------------------------------------------------------
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

# --- static family -------------------------------------------------------------------------
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

__all__ = [  # noqa: RUF022 (grouped by family)
    # shared
    "FAMILIES",
    "METHODS",
    "Method",
    "Registry",
    "Result",
    "Timing",
    "register_method",
    # direct
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
    # tracking
    "PFBPOptions",
    "RangeModel",
    "RangeScenario",
    "SIRBPOptions",
    "SPBPOptions",
    "paper_prior",
    "run_edh",
    "run_pfbp",
    "run_sirbp",
    "run_spbp",
    "scenario_network_spec",
    "simulate_scenario",
    "state_errors",
    # static
    "ConvexPolygon",
    "ExponentialRangeError",
    "GaussianBPOptions",
    "GaussianRangeError",
    "NBPOptions",
    "WLSOptions",
    "anchor_polygon",
    "ellipse_outer_approximation",
    "intersect",
    "paper_static_scenario",
    "poa",
    "run_gaussian_bp",
    "run_nbp",
    "run_wls",
    "scale_polygon",
    "simulate_ranges",
]

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

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost et al., "Distributed Direct Localization Suitable for
Dense Networks," IEEE Trans. Aerosp. Electron. Syst. 56(2), 2020.
PF-BP: L. Wielandner, E. Leitinger, F. Meyer, K. Witrisal, "Message Passing-Based 9-D
Cooperative Localization and Navigation with Embedded Particle Flow."
POA-NBP: R. Mendrzik, G. Bauch, "Position-Constrained Stochastic Inference for Cooperative
Indoor Localization."
"""

# ruff: noqa: I001 (imports grouped by family)
from phyloc.localization import registry
from phyloc.localization.registry import FAMILIES, METHODS, Method, Registry, register_method
from phyloc.localization.results import Result, Timing

# The families register their methods in METHODS when imported.
# --- direct family -------------------------------------------------------------------------
from phyloc.localization.direct import (
    DirectOptions,
    DPFOptions,
    LinkMeasurements,
    LinkRanges,
    Prior,
    dipnet,
    dipnet_published,
)
from phyloc.localization.direct import run as run_direct
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
from phyloc.localization.likelihoods import (
    DirectLikelihood,
    GaussianRangeLikelihood,
    MarginalDirectLikelihood,
    NodeBeliefs,
    SampledLikelihood,
)

# --- tracking family -----------------------------------------------------------------------
from phyloc.localization.tracking import (
    GaussianPrior,
    PFBPOptions,
    RangeMeasurements,
    RangeModel,
    SIRBPOptions,
    SPBPOptions,
    paper_prior,
    run_edh,
    run_pfbp,
    run_sirbp,
    run_spbp,
)

# --- static family -------------------------------------------------------------------------
from phyloc.localization.static import (
    ConvexPolygon,
    EllipseRegion,
    ExponentialRangeError,
    GaussianBPOptions,
    GaussianRangeError,
    NBPOptions,
    StaticMeasurements,
    StaticPrior,
    WLSOptions,
    anchor_polygon,
    ellipse_outer_approximation,
    intersect,
    poa,
    run_gaussian_bp,
    run_nbp,
    run_wls,
    scale_polygon,
)

registry.load_plugins()  # user methods: $PHYLOC_PLUGINS and the "phyloc.methods" entry points

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
    "DirectLikelihood",
    "DirectOptions",
    "GaussianRangeLikelihood",
    "LinkMeasurements",
    "LinkRanges",
    "MarginalDirectLikelihood",
    "NodeBeliefs",
    "SampledLikelihood",
    "Prior",
    "classical_mds",
    "coarse_positions",
    "dipnet",
    "dipnet_published",
    "gauge_log_prior",
    "gauge_priors",
    "gaussian_log_prior",
    "gaussian_priors",
    "informed_centers",
    "range_matrix",
    "raw_stress",
    "run_direct",
    "shortest_path_completion",
    "smacof",
    # tracking
    "GaussianPrior",
    "PFBPOptions",
    "RangeMeasurements",
    "RangeModel",
    "SIRBPOptions",
    "SPBPOptions",
    "paper_prior",
    "run_edh",
    "run_pfbp",
    "run_sirbp",
    "run_spbp",
    # static
    "ConvexPolygon",
    "EllipseRegion",
    "ExponentialRangeError",
    "GaussianBPOptions",
    "GaussianRangeError",
    "NBPOptions",
    "StaticMeasurements",
    "StaticPrior",
    "WLSOptions",
    "anchor_polygon",
    "ellipse_outer_approximation",
    "intersect",
    "poa",
    "run_gaussian_bp",
    "run_nbp",
    "run_wls",
    "scale_polygon",
]

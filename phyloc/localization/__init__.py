"""Localization: every method is ``run(measurements, prior, rng, options) -> Result`` of its family.

Families (one folder each; they do not import each other):

- :mod:`phyloc.localization.direct` — DiPNet and the two-step EL-DPF (DiPNet Algorithm 1),
- :mod:`phyloc.localization.tracking` — PF-BP, SIR-BP, SP-BP and EDH on ranges (PF-BP paper),
- :mod:`phyloc.localization.static` — polygon outer-approximation, NBP with its proposals,
  Gaussian BP and WLS for static networks (POA-NBP paper).

Shared parts live here: :mod:`~phyloc.localization.particles` (weights, ESS, resampling,
regularization, Metropolis–Hastings moves), :mod:`~phyloc.localization.likelihoods` (the
:class:`Likelihood` protocol; its direct, marginal, Gaussian and sample-based implementations
are the direct family's), :mod:`~phyloc.localization.initialization` (the truth-free coarse
solution of the network), :mod:`~phyloc.localization.mds` (classical MDS and weighted SMACOF),
:mod:`~phyloc.localization.priors` (Gaussian priors, the informed start),
:mod:`~phyloc.localization.gauge` (uninformative gauge priors),
:mod:`~phyloc.localization.results` (:class:`Result`) and
:mod:`~phyloc.localization.registry` (:data:`METHODS`, :func:`register_method`).

Examples
--------
>>> from phyloc.localization import METHODS
>>> sorted(METHODS.family("direct"))[:2]
['corr', 'dipnet']

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

# ruff: noqa: I001 (imports grouped by family)
from phyloc.localization import registry
from phyloc.localization.registry import FAMILIES, METHODS, Method, Registry, register_method
from phyloc.localization.results import Result, Timing
from phyloc.localization.likelihoods import Likelihood
from phyloc.localization.initialization import CoarseSolution, coarse_positions, range_matrix
from phyloc.localization.mds import classical_mds, raw_stress, shortest_path_completion, smacof
from phyloc.localization.priors import (
    INFORMED_START_STD_M,
    gaussian_log_prior,
    gaussian_priors,
    informed_centers,
)
from phyloc.localization.gauge import gauge_log_prior, gauge_priors

# The families register their methods in METHODS when imported.
# --- direct family -------------------------------------------------------------------------
from phyloc.localization.direct import (
    DirectLikelihood,
    DirectOptions,
    DPFOptions,
    GaussianRangeLikelihood,
    LinkMeasurements,
    LinkRanges,
    MarginalDirectLikelihood,
    NodeBeliefs,
    Prior,
    SampledLikelihood,
    dipnet,
    dipnet_published,
)
from phyloc.localization.direct import run as run_direct

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
    "INFORMED_START_STD_M",
    "METHODS",
    "CoarseSolution",
    "Likelihood",
    "Method",
    "Registry",
    "Result",
    "Timing",
    "classical_mds",
    "coarse_positions",
    "gauge_log_prior",
    "gauge_priors",
    "gaussian_log_prior",
    "gaussian_priors",
    "informed_centers",
    "range_matrix",
    "raw_stress",
    "register_method",
    "shortest_path_completion",
    "smacof",
    # direct
    "DPFOptions",
    "DirectLikelihood",
    "DirectOptions",
    "GaussianRangeLikelihood",
    "LinkMeasurements",
    "LinkRanges",
    "MarginalDirectLikelihood",
    "NodeBeliefs",
    "Prior",
    "SampledLikelihood",
    "dipnet",
    "dipnet_published",
    "run_direct",
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

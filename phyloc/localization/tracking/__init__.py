"""The tracking family: cooperative tracking of moving agents from range measurements (PF-BP).

Every method is ``run(measurements, prior, rng, options) -> Result`` with
:class:`RangeMeasurements` (model, known anchor positions, ranges ``z [K, n_agents,
n_agents + n_anchors]`` with NaN where absent; no truth) and a :class:`GaussianPrior` of the
states at time 0 (e.g. :func:`paper_prior`, PF-BP eq. (31)). A *step* of the
:class:`~phyloc.localization.results.Result` is a time step: ``estimates [K, n_agents, N_D]``
holds the MMSE estimates of the full states (position, velocity, acceleration blocks of
:class:`RangeModel`), ``covariances`` the published covariances.

Registered in :data:`phyloc.localization.METHODS` (family ``"tracking"``):

===============  ===========  ==================================================================
name             label        method (options)
===============  ===========  ==================================================================
``pfbp``         PF-BP        particle-flow BP, PF-BP Algorithm 1 (:class:`PFBPOptions`)
``pfbp_reg``     PF-BP reg    PF-BP with the regularization of PF-BP eqs. (32), (33)
                              (:class:`PFBPOptions`, ``regularize = True``)
``sirbp``        SIR-BP       bootstrap-particle BP, PF-BP §V-B (:class:`SIRBPOptions`)
``sirbp_reg``    SIR-BP reg   SIR-BP, particles jittered by ``N(0, Σ_r)``, PF-BP eq. (32)
``spbp``         SP-BP        sigma-point BP (:class:`SPBPOptions`)
``spbp_reg``     SP-BP reg    SP-BP, ``Σ_r`` added to each covariance, PF-BP eq. (33)
``edh``          EDH          centralized EDH particle-flow filter, PF-BP Appendix B
                              (:class:`PFBPOptions`; ``agent_s`` is NaN: no distributed form)
``edh_reg``      EDH reg      EDH with the regularization of PF-BP eqs. (32), (33)
===============  ===========  ==================================================================

Modules: the family's input types — :mod:`~phyloc.localization.tracking.model` (state and
range noise model), :mod:`~phyloc.localization.tracking.measurements` (ranges and factors),
:mod:`~phyloc.localization.tracking.priors`; :mod:`~phyloc.localization.tracking.loop`, the one
loop over time steps every method runs (prediction, estimates, results, timing); the methods'
updates :mod:`~phyloc.localization.tracking.pfbp`, :mod:`~phyloc.localization.tracking.sirbp`,
:mod:`~phyloc.localization.tracking.spbp`, :mod:`~phyloc.localization.tracking.edh`; and the flow
kernels in ``_flow`` (:func:`use_flow` swaps the flow of PF-BP and EDH, e.g. for the NumPy twin
in a benchmark). Simulated scenarios (truth and
measurements) are in :mod:`phyloc.evaluation.range_scenarios`.

Examples
--------
>>> import numpy as np
>>> from phyloc.localization import METHODS
>>> z = np.full((3, 1, 4), np.nan)
>>> z[:, 0, 1:] = [5.0, 5.0, 5.0]  # one agent, three anchors, three time steps
>>> meas = RangeMeasurements(RangeModel("static", 2), [[0, 0], [8, 0], [0, 8]], z)
>>> prior = GaussianPrior(np.array([[3.0, 3.0]]), np.eye(2)[None] * 4.0)
>>> m = METHODS["pfbp_reg"]
>>> res = m.run(meas, prior, np.random.default_rng(1), m.make_options({"n_particles": 100}))
>>> m.label, res.estimates.shape, m.make_options().regularize
('PF-BP reg', (3, 1, 2), True)

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
SP-BP: F. Meyer, O. Hlinka and F. Hlawatsch, "Sigma point belief propagation," IEEE Signal
Processing Letters 21(2), pp. 145–149, 2014.
"""

from phyloc.localization.registry import register_method
from phyloc.localization.tracking._flow import use_flow
from phyloc.localization.tracking.edh import run_edh
from phyloc.localization.tracking.measurements import FACTORS, RangeMeasurements
from phyloc.localization.tracking.model import STATE_MODELS, RangeModel
from phyloc.localization.tracking.pfbp import PFBPOptions, run_pfbp
from phyloc.localization.tracking.priors import GaussianPrior, paper_prior
from phyloc.localization.tracking.sirbp import SIRBPOptions, run_sirbp
from phyloc.localization.tracking.spbp import SPBPOptions, run_spbp

__all__ = [
    "FACTORS",
    "STATE_MODELS",
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
    "use_flow",
]

_INPUTS = "ranges"
for _name, _run, _options, _defaults, _label, _description in (
    ("pfbp", run_pfbp, PFBPOptions, {}, "PF-BP", "particle-flow BP (PF-BP Algorithm 1)"),
    (
        "pfbp_reg",
        run_pfbp,
        PFBPOptions,
        {"regularize": True},
        "PF-BP reg",
        "PF-BP with the regularization kernel of PF-BP eqs. (32), (33)",
    ),
    ("sirbp", run_sirbp, SIRBPOptions, {}, "SIR-BP", "bootstrap-particle BP (PF-BP §V-B)"),
    (
        "sirbp_reg",
        run_sirbp,
        SIRBPOptions,
        {"regularize": True},
        "SIR-BP reg",
        "SIR-BP with the regularization kernel of PF-BP eq. (32)",
    ),
    ("spbp", run_spbp, SPBPOptions, {}, "SP-BP", "sigma-point BP (Meyer et al. 2014)"),
    (
        "spbp_reg",
        run_spbp,
        SPBPOptions,
        {"regularize": True},
        "SP-BP reg",
        "SP-BP with Σ_r of PF-BP eq. (32) added to every updated covariance (eq. (33))",
    ),
    (
        "edh",
        run_edh,
        PFBPOptions,
        {},
        "EDH",
        "centralized exact Daum–Huang particle-flow filter (PF-BP Appendix B)",
    ),
    (
        "edh_reg",
        run_edh,
        PFBPOptions,
        {"regularize": True},
        "EDH reg",
        "EDH with the regularization kernel of PF-BP eqs. (32), (33)",
    ),
):
    register_method(
        _name,
        family="tracking",
        run=_run,
        options=_options,
        defaults=_defaults,
        label=_label,
        inputs=_INPUTS,
        description=_description,
    )

"""The direct family: DiPNet and the two-step EL-DPF (DiPNet Algorithm 1).

Every method is :func:`run` (``run(measurements, prior, rng, options) -> Result``) on
:class:`LinkMeasurements` from a :class:`Prior`, with :class:`DirectOptions`; importing this
package registers the named variants in :data:`phyloc.localization.METHODS`:

``dipnet``            DiPNet with phyloc's safeguards: the marginal equivalent likelihood
                      bounded by ``outlier_nats``, adaptive tempering, resample-move,
                      covariance floor (label "DiPNet"); inputs ``"tables"``
``dipnet_published``  DiPNet Algorithm 1 as published: DiPNet eqs. (25)–(28) with the ENV of
                      DiPNet eq. (26), no safeguards; inputs ``"tables"``
``corr``, ``first_peak``, ``sage``
                      the two-step EL-DPF on that estimator's ranges (Gaussian likelihood with
                      the ERV of DiPNet eq. (18)), same safeguards as ``dipnet``; inputs
                      ``"ranges:<estimator>"``
``sage_los``          the two-step EL-DPF on SAGE ranges of LOS links only — an oracle
                      benchmark (NLOS links rejected by ground truth); inputs
                      ``"ranges:sage_los"``
``sage_parametric``   the name DiPNet §V-B gives ``sage`` (Gaussian beliefs exchanged):
                      the same method under its paper name
``dpe_sampled``       sample-based DPE: neighbours exchange particle sets, each message
                      DiPNet's direct likelihood (DiPNet eq. (22), its peak-mixture form as in
                      ``dipnet``) through every neighbour particle, each a Gaussian kernel of
                      Silverman's width (DiPNet §V-B, Table I "Sampled SPAWN"); inputs
                      ``"tables"``
``sage_sampled``      sample-based SAGE: the same exchange with SAGE ranges and their Gaussian
                      variance; inputs ``"ranges:sage"``

A method's ``inputs`` tells an experiment which measurements to build: ``"tables"`` the
correlation tables, ``"ranges:<name>"`` the ranges of estimator ``<name>``, which its options'
``ranges`` key then reads.

Modules: :mod:`~phyloc.localization.direct.measurements` (the family's inputs),
:mod:`~phyloc.localization.direct.likelihoods` (the link likelihoods of the moment exchange),
:mod:`~phyloc.localization.direct.sampled_exchange` (the sample-based exchange),
:mod:`~phyloc.localization.direct.dpf` (the filter, one snapshot) and
:mod:`~phyloc.localization.direct.method` (``run`` and its options); the Numba kernels are in
the private modules ``_kernels`` and ``_sampled_kernels``.

Examples
--------
>>> from phyloc.localization import METHODS
>>> METHODS["dipnet"].label, METHODS["sage"].inputs
('DiPNet', 'ranges:sage')
>>> METHODS["dipnet_published"].make_options({"n_particles": 200}).filter_options().resample_move
False

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from phyloc.localization.direct.dpf import DPFOptions, DPFResult, Prior, predict, run_dpf
from phyloc.localization.direct.likelihoods import (
    DirectLikelihood,
    GaussianRangeLikelihood,
    MarginalDirectLikelihood,
)
from phyloc.localization.direct.measurements import LinkMeasurements, LinkRanges
from phyloc.localization.direct.method import (
    EXCHANGES,
    LIKELIHOODS,
    DirectOptions,
    link_likelihood,
    run,
)
from phyloc.localization.direct.sampled_exchange import NodeBeliefs, SampledLikelihood
from phyloc.localization.registry import register_method


def _register(name, inputs, label, description, **defaults):
    if inputs.startswith("ranges:"):
        defaults = {"likelihood": "gaussian", "ranges": inputs.split(":", 1)[1], **defaults}
    return register_method(
        name,
        family="direct",
        run=run,
        options=DirectOptions,
        defaults=defaults,
        label=label,
        inputs=inputs,
        description=description,
        replace=True,
    )


#: DiPNet (safeguarded, marginal equivalent likelihood): the library's direct localizer.
dipnet = _register(
    "dipnet",
    "tables",
    "DiPNet",
    "DiPNet with safeguards: marginal direct likelihood, tempering, resample-move, floor",
    likelihood="marginal",
)
dipnet_published = _register(
    "dipnet_published",
    "tables",
    "DiPNet (published)",
    "DiPNet Algorithm 1 as published: DiPNet eqs. (25)-(28) with the ENV, no safeguards",
    likelihood="env",
    safeguards=False,
)
_register("corr", "ranges:corr", "EL-DPF (corr)", "two-step EL-DPF on correlation-peak ranges")
_register(
    "first_peak", "ranges:first_peak", "EL-DPF (first peak)", "two-step EL-DPF on first-peak ranges"
)
_register("sage", "ranges:sage", "EL-DPF (SAGE)", "two-step EL-DPF on SAGE ranges")
_register(
    "sage_los",
    "ranges:sage_los",
    "EL-DPF (SAGE, LOS oracle)",
    "two-step EL-DPF on SAGE ranges of LOS links only (oracle: NLOS rejected by ground truth)",
)

_register(
    "sage_parametric",
    "ranges:sage",
    "parametric SAGE",
    "two-step EL-DPF on SAGE ranges, Gaussian beliefs exchanged (DiPNet §V-B name of sage)",
)
_register(
    "dpe_sampled",
    "tables",
    "sample-based DPE",
    "DPF with neighbours' particle sets through the direct likelihood (DiPNet eq. (22)), O(Q^2)",
    likelihood="marginal",
    exchange="particles",
)
_register(
    "sage_sampled",
    "ranges:sage",
    "sample-based SAGE",
    "DPF with neighbours' particle sets through Gaussian SAGE ranges, O(Q^2) per link",
    exchange="particles",
)

#: The names of the direct family's methods, in registration order.
NAMES = (
    "dipnet",
    "dipnet_published",
    "corr",
    "first_peak",
    "sage",
    "sage_los",
    "sage_parametric",
    "dpe_sampled",
    "sage_sampled",
)

__all__ = [
    "EXCHANGES",
    "LIKELIHOODS",
    "NAMES",
    "DPFOptions",
    "DPFResult",
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
    "link_likelihood",
    "predict",
    "run",
    "run_dpf",
]

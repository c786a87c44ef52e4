"""The static family: localization of a network that does not move, from measured ranges.

Every method is ``run(measurements, prior, rng, options) -> Result`` with
:class:`~phyloc.localization.static.static_ranges.StaticMeasurements` (range matrix, anchors,
error model; no truth) and :class:`~phyloc.localization.static.static_ranges.StaticPrior`
(region, optional start and support polygons). A *step* of the :class:`~phyloc.localization.
results.Result` is a message-passing iteration: ``estimates [n_iterations, n_agents, 2]`` holds
the estimates after iterations ``1 … n_iterations`` (the start is not included).

Registered in :data:`phyloc.localization.METHODS` (family ``"static"``):

====================  ===========  =========================================================
name                  label        method
====================  ===========  =========================================================
``poa_nbp``           POA-NBP      NBP, uniform proposal in each agent's POA polygon
                                   (POA-NBP eq. (21); the method runs POA, POA-NBP
                                   Algorithm 1, with ``N_E = poa_n_edges``,
                                   ``N_FS = poa_n_fs``, unless the prior brings polygons)
``nbp_ellipse``       NBP ell.     NBP, uniform proposal in the ellipse outer-approximation
``nbp_min_entropy``   NBP min.     NBP sampling the incoming message of least entropy
``nbp_mixture``       NBP mix.     NBP sampling the mixture of incoming messages
``nbp_parsimonious``  NBP par.     NBP sampling the previous belief
``pbp``               PBP          parametric (Gaussian) BP from the MDS start
``wls``               WLS          weighted least squares by Gauss–Newton from the MDS start
``nbp_aux``           NBP aux.     NBP sampling the product of the anchor messages by
                                   auxiliary-variable importance resampling (POA-NBP
                                   ref. [27]; the mixture proposal without anchor
                                   neighbours)
``nbp_bounding``      NBP bound.   NBP, uniform proposal in each agent's S-procedure bounding
                                   disc ('distributed bounding of feasible sets', the
                                   ellipses POA-NBP cites for 'NBP ell.'; ``N_FS =
                                   poa_n_fs`` iterations)
====================  ===========  =========================================================

Modules: :mod:`~phyloc.localization.static.static_ranges` (measurement models and the family's
input types), :mod:`~phyloc.localization.static.polygons` (convex polygons and the POA
operations), :mod:`~phyloc.localization.static.poa_network` (POA over a network),
:mod:`~phyloc.localization.static.ellipses` (the ellipse baseline),
:mod:`~phyloc.localization.static.bounding` (the ellipse baseline as cited: S-procedure discs),
:mod:`~phyloc.localization.static.kde` (message KDEs and their bandwidths),
:mod:`~phyloc.localization.static.messages` (range messages and their importance-sampled
product with the proposals), :mod:`~phyloc.localization.static.nbp` (NBP),
:mod:`~phyloc.localization.static.gaussian_bp` (Gaussian BP and WLS).

Examples
--------
>>> import numpy as np
>>> from phyloc.localization import METHODS
>>> anchors = np.array([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0], [20.0, 20.0]])
>>> z = np.full((5, 5), np.nan)  # node 4, an agent, measured its ranges to the anchors
>>> z[4, :4] = [13.2, 17.2, 11.6, 16.0]
>>> meas, prior = StaticMeasurements(z, [0, 1, 2, 3], anchors), StaticPrior((0, 0, 20, 20))
>>> m = METHODS["poa_nbp"]
>>> res = m.run(meas, prior, np.random.default_rng(1),
...             m.make_options({"n_samples": 50, "n_iterations": 2}))
>>> m.label, res.estimates.shape, res.diagnostics["support"]
('POA-NBP', (2, 1, 2), 'poa')

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from phyloc.localization.registry import register_method
from phyloc.localization.static.bounding import feasible_set_bounding, run_nbp_bounding
from phyloc.localization.static.ellipses import EllipseRegion, ellipse_outer_approximation
from phyloc.localization.static.gaussian_bp import (
    GaussianBPOptions,
    WLSOptions,
    heuristic_start,
    mds_start,
    run_gaussian_bp,
    run_wls,
)
from phyloc.localization.static.nbp import NBPOptions, run_nbp
from phyloc.localization.static.poa_network import poa
from phyloc.localization.static.polygons import (
    ConvexPolygon,
    anchor_polygon,
    intersect,
    scale_polygon,
)
from phyloc.localization.static.static_ranges import (
    ExponentialRangeError,
    GaussianRangeError,
    StaticMeasurements,
    StaticPrior,
    range_error_model,
)

__all__ = [
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
    "feasible_set_bounding",
    "heuristic_start",
    "intersect",
    "mds_start",
    "poa",
    "range_error_model",
    "run_gaussian_bp",
    "run_nbp",
    "run_nbp_bounding",
    "run_wls",
    "scale_polygon",
]

_INPUTS = "ranges"
for _name, _defaults, _label, _description in (
    (
        "poa_nbp",
        {"proposal": "polygon", "support": "poa"},
        "POA-NBP",
        "NBP with the uniform proposal in each agent's POA polygon (POA-NBP eq. (21))",
    ),
    (
        "nbp_ellipse",
        {"proposal": "polygon", "support": "ellipse"},
        "NBP ell.",
        "NBP with the uniform proposal in the ellipse outer-approximation",
    ),
    (
        "nbp_min_entropy",
        {"proposal": "min_entropy"},
        "NBP min.",
        "NBP sampling the incoming message of least entropy",
    ),
    (
        "nbp_mixture",
        {"proposal": "mixture"},
        "NBP mix.",
        "NBP sampling the mixture of incoming messages plus a uniform fraction",
    ),
    (
        "nbp_parsimonious",
        {"proposal": "parsimonious"},
        "NBP par.",
        "NBP sampling the previous belief (parsimonious sampling)",
    ),
):
    register_method(
        _name,
        family="static",
        run=run_nbp,
        options=NBPOptions,
        defaults=_defaults,
        label=_label,
        inputs=_INPUTS,
        description=_description,
    )
register_method(
    "pbp",
    family="static",
    run=run_gaussian_bp,
    options=GaussianBPOptions,
    defaults={"start": "mds"},
    label="PBP",
    inputs=_INPUTS,
    description="parametric (Gaussian) BP with linearized messages, from the MDS start",
)
register_method(
    "wls",
    family="static",
    run=run_wls,
    options=WLSOptions,
    defaults={"start": "mds"},
    label="WLS",
    inputs=_INPUTS,
    description="weighted least squares by damped Gauss–Newton, from the MDS start",
)
register_method(
    "nbp_aux",
    family="static",
    run=run_nbp,
    options=NBPOptions,
    defaults={"proposal": "auxiliary"},
    label="NBP aux.",
    inputs=_INPUTS,
    description="NBP sampling the product of the anchor messages (auxiliary variable)",
)
register_method(
    "nbp_bounding",
    family="static",
    run=run_nbp_bounding,
    options=NBPOptions,
    defaults={"proposal": "polygon"},
    label="NBP bound.",
    inputs=_INPUTS,
    description="NBP with the uniform proposal in the S-procedure bounding discs of the "
    "feasible sets (distributed bounding of feasible sets: the ellipses POA-NBP cites)",
)

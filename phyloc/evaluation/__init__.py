"""phyloc.evaluation: metrics, the experiment kinds ``phyloc evaluate`` runs, figures.

:mod:`~phyloc.evaluation.experiment` holds the one runner every kind uses,
:mod:`~phyloc.evaluation.kinds` the registry of kinds, :mod:`~phyloc.evaluation.sections` the
shared recipe sections and :mod:`~phyloc.evaluation.front_end` the direct measurement front end.

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

from phyloc.evaluation.metrics import (
    error_cdf,
    framework_distance_errors,
    framework_distance_rmse,
    outage_probability,
    rigid_align,
    rmse_per_snapshot,
    shape_difference,
)

__all__ = [
    "error_cdf",
    "framework_distance_errors",
    "framework_distance_rmse",
    "outage_probability",
    "rigid_align",
    "rmse_per_snapshot",
    "shape_difference",
]

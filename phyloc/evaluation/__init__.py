"""phyloc.evaluation (see DESIGN.md): metrics, experiments, figures."""

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

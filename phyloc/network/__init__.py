"""Networks: deployments, anchors, connectivity, directed links and trajectories.

A :class:`NetworkSpec` (recipe section ``[network]``, with ``[network.motion]`` a
:class:`MotionSpec`) describes a network; :func:`make_network` draws a :class:`Network` from it
with a ``numpy.random.Generator``. :func:`transition_matrices` exposes the CV/CA state models of
PF-BP eqs. (1)–(3) for the tracking filters. :func:`pentagon` and :func:`waypoint_trajectory`
(``model = "waypoints"``) describe the DiPNet experiments: stationary agents in a pentagon and
a rover following a waypoint path.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."

Y. Bar-Shalom, X. R. Li and T. Kirubarajan, *Estimation with Applications to Tracking and
Navigation*, Wiley, 2001 (direct discrete-time kinematic models, §6.3).
"""

from phyloc.network.deployment import (
    ANCHOR_LAYOUTS,
    ON_ISOLATED,
    IsolatedNodesWarning,
    Network,
    NetworkSpec,
    anchor_positions,
    corner_order,
    make_network,
    pentagon,
)
from phyloc.network.motion import (
    INITIAL_VELOCITIES,
    KINEMATIC_MODELS,
    MOTION_MODELS,
    MotionSpec,
    noise_gain_matrix,
    simulate_motion,
    transition_matrices,
    waypoint_trajectory,
)

__all__ = [
    "ANCHOR_LAYOUTS",
    "INITIAL_VELOCITIES",
    "KINEMATIC_MODELS",
    "MOTION_MODELS",
    "ON_ISOLATED",
    "IsolatedNodesWarning",
    "MotionSpec",
    "Network",
    "NetworkSpec",
    "anchor_positions",
    "corner_order",
    "make_network",
    "noise_gain_matrix",
    "pentagon",
    "simulate_motion",
    "transition_matrices",
    "waypoint_trajectory",
]

"""Networks: deployments, anchors, connectivity, directed links and trajectories.

A :class:`NetworkSpec` (recipe section ``[network]``, with ``[network.motion]`` a
:class:`MotionSpec`) describes a network; :func:`make_network` draws a :class:`Network` from it
with a ``numpy.random.Generator``. :func:`transition_matrices` exposes the CV/CA state models of
the PF-BP paper eqs. (1)–(3) for the tracking filters.
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
)
from phyloc.network.motion import (
    INITIAL_VELOCITIES,
    KINEMATIC_MODELS,
    MOTION_MODELS,
    MotionSpec,
    noise_gain_matrix,
    simulate_motion,
    transition_matrices,
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
    "simulate_motion",
    "transition_matrices",
]

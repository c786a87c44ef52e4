"""The one result type of every localization method.

Every method of :data:`phyloc.localization.METHODS` returns a :class:`Result`: estimates per
agent and step, covariances, optionally the final particles, method-specific diagnostics and
timing. A *step* is whatever the family iterates over in time: a snapshot (direct family), a
time step (tracking family) or a message-passing iteration (static family, whose network does
not move). Results never contain the truth; metrics compare them with the truth in
:mod:`phyloc.evaluation`.

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

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, eq=False)
class Timing:
    """Wall times of one run of a method.

    Attributes
    ----------
    wall_s : float
        Total wall time [s].
    step_s : [n_steps] float64
        Wall time of each step, all agents (joint processing) [s].
    agent_s : [n_steps] float64
        Mean wall time per agent in each step (distributed processing) [s].
    agent_iterations : int
        Agent updates performed (agents × message-passing iterations × steps): the unit of
        work of ``per_agent_iteration_s``.
    """

    wall_s: float
    step_s: np.ndarray
    agent_s: np.ndarray
    agent_iterations: int = 0

    @property
    def per_agent_iteration_s(self) -> float:
        """``wall_s / agent_iterations`` [s] (``wall_s`` when no iteration is counted)."""
        return self.wall_s / max(self.agent_iterations, 1)


@dataclass(frozen=True, eq=False)
class Result:
    """Output of every localization method (``run(measurements, prior, rng, options)``).

    Attributes
    ----------
    estimates : [n_steps, n_agents, state_dim] float64
        Point estimates (MMSE: the posterior means) of every agent after every step; the
        first ``dim`` state components are the position [m]. Agents are ordered as in the
        measurements (``measurements.agent_nodes``).
    covariances : [n_steps, n_agents, state_dim, state_dim] float64 or None
        The covariances the method publishes with its estimates.
    timing : Timing
    particles : [n_agents, Q, state_dim] float64 or None
        The final particle belief of particle methods.
    log_weights : [n_agents, Q] float64 or None
        Normalized log weights of ``particles``.
    diagnostics : dict
        Method-specific named arrays and numbers (documented by each family's ``run``), e.g.
        the effective sample size per iteration.
    label : str
        A human-readable label of the run (e.g. the initialization).
    """

    estimates: np.ndarray
    covariances: np.ndarray | None
    timing: Timing
    particles: np.ndarray | None = None
    log_weights: np.ndarray | None = None
    diagnostics: dict = field(default_factory=dict)
    label: str = ""

    @property
    def n_steps(self) -> int:
        """Number of steps (snapshots, time steps or iterations)."""
        return self.estimates.shape[0]

    @property
    def n_agents(self) -> int:
        """Number of agents estimated."""
        return self.estimates.shape[1]

    def positions(self, dim: int) -> np.ndarray:
        """Position estimates ``[n_steps, n_agents, dim]`` (the first ``dim`` state entries)."""
        return self.estimates[..., :dim]

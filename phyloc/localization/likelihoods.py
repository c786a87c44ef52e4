"""The ``Likelihood`` protocol: what the particle filters need from a link likelihood.

A link likelihood weighs every agent's particles by the agent's incoming links, the directed
pairs ``(u, v)`` with u an agent (u uses its own received signal from v), laid out per agent
in CSR form (:class:`IncomingLinks`). It sees a neighbour through the first two moments of
its belief, its published mean and covariance (DiPNet Algorithm 1 line 5), or — with
``exchange = "particles"`` — through its particle set. Tempering multiplies every
log-likelihood by γ ∈ (0, 1].

The implementations are the direct family's: DiPNet's equivalent likelihood (DiPNet
eq. (25)), its marginal over the neighbour's projected uncertainty and the Gaussian ranging
model with the ERV of DiPNet eq. (18) in :mod:`phyloc.localization.direct.likelihoods`, the
sample-based exchange in :mod:`phyloc.localization.direct.sampled_exchange`. The filter
(:func:`phyloc.localization.direct.dpf.run_dpf`) sees only this protocol.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from phyloc.errors import ValidationError


class IncomingLinks:
    """CSR layout of the incoming links of each agent.

    The links of agent ``a`` are ``j = offsets[a] … offsets[a+1]−1``; links received by anchors
    are left out.

    Parameters
    ----------
    links : [n_links, 2] int
        Directed pairs (u, v): u receives from v.
    agent_of_node : [n_nodes] int
        Agent index of each node, −1 for anchors.
    n_agents : int

    Attributes
    ----------
    link_index : [n_used] int64
        Row of each kept link in ``links`` (rows into the caller's per-link arrays).
    rx, tx : [n_used] int64
        Receiving agent's node and neighbour node of each kept link.
    offsets : [n_agents + 1] int64
        Start of each agent's links.
    """

    def __init__(self, links, agent_of_node, n_agents):
        links = np.asarray(links, dtype=np.int64)
        if links.ndim != 2 or links.shape[1] != 2:
            raise ValidationError("links", f"shape {links.shape}", "[n_links, 2] (u, v) pairs")
        rx_agent = agent_of_node[links[:, 0]]
        keep = np.flatnonzero(rx_agent >= 0)  # only links received by agents
        order = keep[np.argsort(rx_agent[keep], kind="stable")]
        self.link_index = order  # rows into the caller's link arrays
        self.rx = links[order, 0]
        self.tx = links[order, 1]
        counts = np.bincount(rx_agent[order], minlength=n_agents)
        self.offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


@runtime_checkable
class Likelihood(Protocol):
    """A link likelihood of the particle filters (the members every implementation has).

    Attributes
    ----------
    kind : str
        Its name: ``"direct"``, ``"marginal"``, ``"gaussian"`` or ``"sampled"``.
    csr : IncomingLinks
        The links it uses, per receiving agent.
    nu : [n_used] float64
        Ranging information ``ν = 1/CRB`` of each link of ``csr`` [1/m²] (DiPNet eq. (24)), from
        which the filter's covariance floor builds the EFIM of DiPNet eq. (17).

    Optional members, which the filter uses when present:

    ``frozen(particles, centers, covs, gamma=1.0)``
        :meth:`loglik` with the neighbours' moments frozen, as ``fn(x, agents=None)`` of the
        particles (``x`` holds the rows of ``agents``, all when None), or None (the filter then
        evaluates :meth:`loglik`): what many evaluations in one iteration share is prepared
        once.
    ``exchange``
        ``"particles"``: :meth:`loglik` takes the neighbours' particle sets as the keyword
        ``beliefs`` (:class:`~phyloc.localization.direct.sampled_exchange.NodeBeliefs`);
        ``"moments"`` when absent.
    """

    kind: str
    csr: IncomingLinks
    nu: np.ndarray

    def loglik(self, particles, centers, covs, gamma=1.0) -> np.ndarray:
        """``γ Σ_v log p̃(r_uv | x, p̂_v)`` for every particle, ``[n_agents, Q]``.

        Parameters
        ----------
        particles : [n_agents, Q, dim] float64
            The agents' particles [m].
        centers : [n_nodes, dim] float64
            Published means [m] (anchors: their positions).
        covs : [n_nodes, dim, dim] float64
            Published covariances [m²] (anchors: 0).
        gamma : float
            Tempering exponent γ ∈ (0, 1].
        """
        ...

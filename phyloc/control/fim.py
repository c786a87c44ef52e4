"""Approximate Bayesian Fisher information of the agents' next positions, and its cost.

After W. Zhang, B. Teague and F. Meyer, "Cooperative localization: a Fisher information
approach" (FIM control; equation numbers in brackets are that paper's). Every agent ``i`` has
a Gaussian belief ``N(x̂_i, P_i)`` of its state (position first, as
:class:`~phyloc.localization.tracking.RangeModel`); the next step is predicted by the linear
motion model, ``x̂⁻ = F x̂``, ``P⁻ = F P Fᵀ + Q`` [1]. A range of standard deviation σ from a
node at ``a`` adds ``σ⁻² q qᵀ`` to the information of the agent's position, ``q`` the unit vector
from ``a`` to the agent's predicted mean [3], [7]–[9] (the Fisher information of a range is
blind to the distance). The approximate Bayesian FIM of the position is

.. math:: \\tilde I_i = (P^-_{i,pp})^{-1} + σ^{-2} \\sum_{j \\in \\mathcal A_i} q_{ij} q_{ij}^T

(the position block of the full-state information ``P⁻⁻¹ + Hᵀ A H`` after eliminating the rates
is exactly ``(P⁻_pp)⁻¹ + A``) and the cost [10] is ``C = Σ_i tr(Ĩ_i⁻¹)``. Over a horizon the
covariance is updated as an information filter with the same ``A`` (the means only predicted),

.. math:: P_{t|t} = P^-_t − P^-_t H^T (I + A_t S_t)^{-1} A_t H P^-_t, \\quad S_t = H P^-_t H^T,

which is Woodbury's form of ``(P⁻⁻¹ + HᵀAH)⁻¹``, valid for singular ``A`` (an agent out of every
anchor's range) and singular ``P⁻``.

Anchor–agent terms are those of the paper; ``agent_terms`` adds agent–agent ranges with the
neighbour at its predicted mean (its uncertainty neglected), an option beyond the paper.

References
----------
FIM: W. Zhang, B. Teague and F. Meyer, "Cooperative localization: a Fisher information
approach," arXiv:2212.14554, 2022.
"""

from __future__ import annotations

import numpy as np

from phyloc import _validate as v
from phyloc.control._kernels import COINCIDENT_M
from phyloc.errors import ValidationError


def control_set(speed_m_s: float = 2.0, n_azimuth: int = 8, elevations_deg=(-45.0, 0.0, 45.0)):
    """The finite set U of anchor velocities: a uniform grid of directions in spherical
    coordinates, all of norm ``speed_m_s`` [2].

    ``n_azimuth`` azimuths (``360°/n_azimuth`` apart, 1 to 3600) at every elevation of
    ``elevations_deg`` (strictly between −90° and 90°), plus straight up and straight down. The
    default is the 26 directions of the 3×3×3 neighbourhood's angular grid (8 azimuths × 3
    elevations + 2). A 2-D set (``elevations_deg = ()``, no poles) is the ``n_azimuth``
    directions in the plane.

    Returns
    -------
    U : ``[|U|, 3]`` float64 (``[|U|, 2]`` for a 2-D set) [m/s]

    Examples
    --------
    >>> U = control_set()
    >>> U.shape, bool(np.allclose(np.linalg.norm(U, axis=1), 2.0))
    ((26, 3), True)
    >>> control_set(1.0, 4, ()).round(12).tolist()
    [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [-0.0, -1.0]]
    """
    s = v.positive("speed_m_s", speed_m_s)
    n = v.integer("n_azimuth", n_azimuth, minimum=1, maximum=3600)  # 0.1° apart
    az = 2.0 * np.pi * np.arange(n) / n
    elev = [v.finite("elevations_deg", e) for e in elevations_deg]
    if not elev:
        return s * np.stack([np.cos(az), np.sin(az)], axis=1)
    if any(abs(e) >= 90.0 for e in elev):
        raise ValidationError("elevations_deg", elevations_deg, "strictly between -90 and 90")
    rows = []
    for e in np.radians(elev):
        rows.append(
            np.stack([np.cos(e) * np.cos(az), np.cos(e) * np.sin(az), np.full(n, np.sin(e))], 1)
        )
    rows.append(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]))
    return s * np.concatenate(rows)


def range_information(agent_pos, nodes, sigma_r: float, comm_range_m: float | None = None):
    """``A = σ⁻² Σ_j q_j q_jᵀ`` of ranges from ``nodes`` to each agent position (FIM [7]–[9]).

    Parameters
    ----------
    agent_pos : [..., n_agents, dim]
        Agents' predicted mean positions.
    nodes : [..., n_nodes, dim]
        Positions of the ranging partners (broadcast against ``agent_pos``'s leading axes).
    sigma_r : float
        Range standard deviation σ [m].
    comm_range_m : float, optional
        Only nodes within this distance contribute (None: all).

    Returns
    -------
    A : [..., n_agents, dim, dim]
        Symmetric PSD; zero for coincident nodes (no direction) and nodes out of range.
    """
    diff = agent_pos[..., :, None, :] - nodes[..., None, :, :]
    dist = np.sqrt(np.sum(diff * diff, axis=-1))
    use = dist > COINCIDENT_M
    if comm_range_m is not None:
        use &= dist <= comm_range_m
    q = np.where(use[..., None], diff / np.where(use, dist, 1.0)[..., None], 0.0)
    return np.einsum("...jk,...jl->...kl", q, q) / (sigma_r * sigma_r)


def update_covariance(P_pred, A, dim: int):
    """``(P⁻⁻¹ + Hᵀ A H)⁻¹`` in Woodbury's form and its position-block trace.

    Parameters
    ----------
    P_pred : [..., N_D, N_D]
        Predicted state covariances (position block first).
    A : [..., dim, dim]
        Range information of the position.
    dim : int

    Returns
    -------
    P_post : [..., N_D, N_D]
    trace : [...]
        ``tr(P_post[:dim, :dim])`` = ``tr(Ĩ⁻¹)`` of FIM [9]–[10].
    """
    B = P_pred[..., :, :dim]  # P⁻ Hᵀ
    S = P_pred[..., :dim, :dim]
    eye = np.eye(dim)
    X = np.linalg.solve(eye + A @ S, A)  # (I + A S)⁻¹ A
    P_post = P_pred - B @ X @ np.swapaxes(B, -1, -2)
    trace = np.trace(P_post[..., :dim, :dim], axis1=-2, axis2=-1)
    return P_post, trace


def position_cost(P_pred, agent_pos, anchors, sigma_r, comm_range_m=None, agent_terms=False):
    """FIM cost [10] ``C = Σ_i tr(Ĩ_i⁻¹)`` for one set of anchor positions.

    Parameters
    ----------
    P_pred : [n_agents, N_D, N_D]
        Predicted covariances ``P⁻``.
    agent_pos : [n_agents, dim]
        Predicted mean positions.
    anchors : [n_anchors, dim]
        Anchor positions at the step (mobile ones after their move).
    sigma_r : float
    comm_range_m : float, optional
    agent_terms : bool
        Add agent–agent ranges (neighbours at their predicted means).

    Returns
    -------
    float

    Examples
    --------
    One agent at the origin with a unit position prior, σ = 1, anchors on two orthogonal axes:
    ``Ĩ = I + diag(1, 1)``, so the cost is ``1/2 + 1/2``.

    >>> P = np.eye(2)[None]
    >>> position_cost(P, np.zeros((1, 2)), np.array([[5.0, 0.0], [0.0, 3.0]]), 1.0)
    1.0
    """
    A = information_at(agent_pos, anchors, sigma_r, comm_range_m, agent_terms)
    dim = agent_pos.shape[-1]
    return float(update_covariance(P_pred, A, dim)[1].sum())


def information_at(agent_pos, anchors, sigma_r, comm_range_m=None, agent_terms=False):
    """Range information ``A [..., n_agents, dim, dim]`` from ``anchors [..., M, dim]`` and,
    with ``agent_terms``, from the other agents at their predicted means."""
    A = range_information(agent_pos, anchors, sigma_r, comm_range_m)
    if agent_terms and agent_pos.shape[-2] > 1:
        A = A + range_information(agent_pos, agent_pos, sigma_r, comm_range_m)
    return A

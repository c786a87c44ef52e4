"""Range measurements over time, and which of them enter each agent's belief (the factors).

:class:`RangeMeasurements` stores them densely: ``z[k−1, i, j]`` is the measurement agent ``i``
made of node ``j`` at time ``k`` (PF-BP eq. (8); NaN when ``i`` and ``j`` are not connected).
Nodes are ordered agents first, anchors last (as in :class:`~phyloc.network.Network`), so
columns ``n_agents …`` are anchors, whose positions are known. Both agents of a connected pair
measure, each with its own noise: ``z_ij ≠ z_ji``. The measurements carry no truth; simulated
ones come from :func:`phyloc.evaluation.range_scenarios.simulate_scenario`.

Factors (PF-BP §V-A): *distributed* — agent ``i`` uses only its own row ``z[i, :]`` (``f_ij ≠
f_ji``, PF-BP eq. (17)); *centralized* — agent ``i`` also uses ``z[j, i]`` of every agent ``j``
(``f_ij = f_ji``, PF-BP eq. (18)). :func:`agent_measurements` lists the measurements of one
agent under either rule; :func:`all_measurements` lists every measurement (the joint likelihood
used by the EDH filter).

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization.tracking.model import RangeModel

#: Factor rules of PF-BP §V-A.
FACTORS = ("distributed", "centralized")


@dataclass(frozen=True, eq=False)
class RangeMeasurements:
    """Range measurements of a network over time: what the trackers see (no truth).

    Time ``k = 1 … K`` is stored at index ``k − 1``. Problem sizes come from ``z``: ``K``,
    ``n_agents`` and ``n_agents + n_anchors``.

    Parameters
    ----------
    model : RangeModel
        State model and range noise σ the trackers assume.
    anchors : [n_anchors, dim] or [K, n_anchors, dim] float64
        Known anchor positions [m]: fixed, or per time step (anchors that move, e.g. under
        :mod:`phyloc.control`); :meth:`anchors_at` gives the positions at one step.
    z : [K, n_agents, n_agents + n_anchors] float64
        ``z[k−1, i, j]``: range agent ``i`` measured to node ``j`` at time ``k`` [m]
        (PF-BP eq. (8)); NaN where absent (and on the diagonal). Nodes: agents first, anchors last.

    Examples
    --------
    >>> z = np.full((2, 1, 2), np.nan)
    >>> z[:, 0, 1] = 5.0
    >>> meas = RangeMeasurements(RangeModel("static", 2), np.zeros((1, 2)), z)
    >>> meas.n_steps, meas.n_agents, meas.n_anchors
    (2, 1, 1)
    >>> moving = RangeMeasurements(RangeModel("static", 2), [[[0, 0]], [[1, 0]]], z)
    >>> moving.anchors_at(1)
    array([[1., 0.]])
    """

    model: RangeModel
    anchors: np.ndarray
    z: np.ndarray

    def __post_init__(self):
        if not isinstance(self.model, RangeModel):
            raise ValidationError("model", type(self.model).__name__, "must be a RangeModel")
        dim = self.model.dim
        shape = np.shape(self.anchors)
        if len(shape) == 3:
            anchors = v.finite_array("anchors", self.anchors, ndim=3)
            if shape[2] != dim:
                raise ValidationError(
                    "anchors", f"array of shape {shape}", f"must be (K, n_anchors, {dim})"
                )
        else:
            anchors = v.finite_array("anchors", np.reshape(self.anchors, (-1, dim)), ndim=2)
            if shape not in (anchors.shape, (0,)):
                raise ValidationError(
                    "anchors", f"array of shape {shape}", f"must be (n_anchors, {dim})"
                )
        n_anchors = anchors.shape[-2]
        try:
            z = np.asarray(self.z, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValidationError("z", "<array>", "must convert to float64") from None
        if z.ndim != 3 or z.shape[2] != z.shape[1] + n_anchors or z.shape[1] < 1:
            raise ValidationError(
                "z",
                f"array of shape {z.shape}",
                f"must be (K, n_agents, n_agents + n_anchors) with n_anchors = {n_anchors}",
            )
        if anchors.ndim == 3 and anchors.shape[0] != z.shape[0]:
            raise ValidationError(
                "anchors",
                f"array of shape {anchors.shape}",
                f"per-step anchors need one row per time step (K = {z.shape[0]})",
            )
        if np.any(np.isinf(z)):
            raise ValidationError("z", "inf", "ranges must be finite or NaN (not measured)")
        object.__setattr__(self, "anchors", anchors)
        object.__setattr__(self, "z", z)

    def anchors_at(self, k: int) -> np.ndarray:
        """Anchor positions ``[n_anchors, dim]`` at time index ``k`` (0-based, ``z[k]``)."""
        return self.anchors[k] if self.anchors.ndim == 3 else self.anchors

    def anchor_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounding box ``(lo, hi)`` of every anchor position (all steps)."""
        flat = self.anchors.reshape(-1, self.model.dim)
        return flat.min(axis=0), flat.max(axis=0)

    @property
    def n_agents(self) -> int:
        """Number of agents (rows of ``z``)."""
        return self.z.shape[1]

    @property
    def n_anchors(self) -> int:
        """Number of anchors."""
        return self.anchors.shape[-2]

    @property
    def n_steps(self) -> int:
        """Number of time steps K."""
        return self.z.shape[0]


def agent_measurements(z_k: np.ndarray, agent: int, factors: str = "distributed"):
    """Measurements entering the belief of one agent at one time step.

    Parameters
    ----------
    z_k : [n_agents, n_nodes] float64
        One time step of :attr:`RangeMeasurements.z`.
    agent : int
    factors : {"distributed", "centralized"}
        Distributed: ``z[agent, j]`` only (PF-BP eq. (17)); centralized: also ``z[j, agent]``
        of every agent ``j`` (PF-BP eq. (18)).

    Returns
    -------
    rx, tx : [L] int64
        The measurement is ``‖p_rx − p_tx‖ + n``; ``rx == agent`` or ``tx == agent``.
    z : [L] float64
    partners : [P] int64
        Sorted agents (≠ ``agent``) that appear in a measurement.
    """
    v.choice("factors", factors, FACTORS)
    row = z_k[agent]
    tx = np.flatnonzero(np.isfinite(row))
    rx = np.full(tx.size, agent)
    zz = row[tx]
    if factors == "centralized":
        col = z_k[:, agent]
        other = np.flatnonzero(np.isfinite(col))
        rx = np.r_[rx, other]
        tx = np.r_[tx, np.full(other.size, agent)]
        zz = np.r_[zz, col[other]]
    n_ag = z_k.shape[0]
    nodes = np.r_[rx, tx]
    partners = np.unique(nodes[(nodes < n_ag) & (nodes != agent)])
    return rx.astype(np.int64), tx.astype(np.int64), zz, partners.astype(np.int64)


def all_measurements(z_k: np.ndarray):
    """Every measurement of a time step: ``rx, tx [L] int64, z [L]`` (the joint likelihood)."""
    rx, tx = np.nonzero(np.isfinite(z_k))
    return rx.astype(np.int64), tx.astype(np.int64), z_k[rx, tx]

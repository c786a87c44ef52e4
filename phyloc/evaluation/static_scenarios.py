"""Simulated static networks: the truth and the ranges measured in it (POA-NBP §V-A).

The scenario simulators of the static family draw the true positions and then the range
matrix from a measurement model of :mod:`phyloc.localization.static.static_ranges`
(POA-NBP eq. (1): ``ẑ_{i→j} = ‖x_i − x_j‖ + ε_{i→j}``). They belong to the evaluation: a
localizer only ever sees :meth:`StaticScenario.measurements` and :meth:`StaticScenario.prior`,
never :attr:`StaticScenario.positions` of the agents.

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization.static.static_ranges import (
    RangeError,
    StaticMeasurements,
    StaticPrior,
    anchor_mask,
    check_error_model,
)

__all__ = [
    "PAPER_ANCHOR_UNITS",
    "StaticScenario",
    "paper_static_scenario",
    "simulate_ranges",
    "true_distances",
]


def _rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", rng, "a numpy.random.Generator is required")
    return rng


# ---------------------------------------------------------------------------------------------
def true_distances(positions) -> np.ndarray:
    """``[N, N]`` Euclidean distances of ``positions [N, 2]`` [m]."""
    p = v.finite_array("positions", positions, ndim=2)
    return np.sqrt(((p[:, None, :] - p[None, :, :]) ** 2).sum(axis=-1))


def simulate_ranges(
    positions,
    comm_range_m: float,
    error_model: RangeError | None,
    rng: np.random.Generator,
    *,
    symmetric: bool = False,
    anchors=None,
) -> np.ndarray:
    """Simulate the dense range matrix of a static network (POA-NBP eq. (1)).

    Parameters
    ----------
    positions : [N, 2] float64
        True node positions [m].
    comm_range_m : float
        ``r_com`` [m], > 0 (``inf``: fully connected). Pairs with ``‖x_i − x_j‖ <= r_com`` are
        linked (POA-NBP §II-A1).
    error_model : ExponentialRangeError or GaussianRangeError or None
        ``None``: exponential, mean 0.38 m.
    rng : numpy.random.Generator
    symmetric : bool
        ``False`` (paper): ``ẑ_{i→j}`` and ``ẑ_{j→i}`` have independent errors. ``True``: one
        error per pair, ``ranges[i, j] == ranges[j, i]``.
    anchors : [N] bool or index list, optional
        Anchor–anchor pairs carry no measurement (NaN) when given.

    Returns
    -------
    ranges : [N, N] float64
        ``ranges[j, i] = ẑ_{i→j}`` [m], measured by node ``j``; NaN off-link and on the
        diagonal.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> z = simulate_ranges([[0, 0], [3, 4], [50, 0]], 20.0, None, rng)
    >>> bool(z[0, 1] >= 5.0), bool(np.isnan(z[0, 2]))
    (True, True)
    """
    d = true_distances(positions)
    n = d.shape[0]
    r = float(comm_range_m)
    if not (r > 0):  # NaN-safe, inf allowed
        raise ValidationError("comm_range_m", comm_range_m, "must be > 0 (inf: fully connected)")
    model = check_error_model(error_model)
    rng = _rng(rng)
    linked = d <= r
    np.fill_diagonal(linked, False)
    if anchors is not None:
        is_anchor = anchor_mask(anchors, n)
        linked &= ~(is_anchor[:, None] & is_anchor[None, :])
    e = model.sample((n, n), rng)
    if symmetric:
        e = np.triu(e, 1)
        e = e + e.T
    return np.where(linked, d + e, np.nan)


#: The 13 anchors of the POA-NBP §V setup as fractions of the side: a 3×3 grid at the cell
#: centres plus a 2×2 grid between them (the paper takes the topology of its ref. [3] without
#: listing coordinates; this regular layout is our assumption).
PAPER_ANCHOR_UNITS = np.array(
    [[(i + 0.5) / 3, (k + 0.5) / 3] for k in range(3) for i in range(3)]
    + [[(i + 1) / 3, (k + 1) / 3] for k in range(2) for i in range(2)]
)


@dataclass(frozen=True, eq=False)
class StaticScenario:
    """One static network with simulated ranges.

    Attributes
    ----------
    positions : [N, 2] float64
        True positions [m]; agents first, anchors last.
    is_anchor : [N] bool
    ranges : [N, N] float64
        ``ranges[j, i] = ẑ_{i→j}`` (see :func:`simulate_ranges`).
    region : (xmin, ymin, xmax, ymax)
    error_model : ExponentialRangeError or GaussianRangeError
    comm_range_m : float
    """

    positions: np.ndarray
    is_anchor: np.ndarray
    ranges: np.ndarray
    region: tuple[float, float, float, float]
    error_model: RangeError
    comm_range_m: float

    @property
    def agents(self) -> np.ndarray:
        """Agent node indices (ascending)."""
        return np.flatnonzero(~self.is_anchor)

    @property
    def anchor_positions(self) -> np.ndarray:
        """``[n_anchors, 2]`` anchor positions in ascending node order."""
        return self.positions[self.is_anchor]

    @property
    def agent_positions(self) -> np.ndarray:
        """``[n_agents, 2]`` true agent positions in ascending node order."""
        return self.positions[~self.is_anchor]

    def measurements(self) -> StaticMeasurements:
        """What a localizer sees: ranges, anchors, anchor positions, error model (no truth)."""
        return StaticMeasurements(
            self.ranges, self.is_anchor, self.anchor_positions, self.error_model
        )

    def prior(self, **kw) -> StaticPrior:
        """The uniform prior over :attr:`region` (keywords: the other :class:`StaticPrior`
        fields)."""
        return StaticPrior(self.region, **kw)


def paper_static_scenario(
    rng: np.random.Generator,
    *,
    n_agents: int = 100,
    side_m: float = 100.0,
    comm_range_m: float = 20.0,
    error_model: RangeError | None = None,
    anchor_units=None,
    symmetric: bool = False,
) -> StaticScenario:
    """The POA-NBP §V-A setup: ``n_agents`` uniform agents and 13 fixed anchors in a
    ``side × side`` square, ``r_com = 20`` m, exponential errors of mean 0.38 m.

    ``anchor_units`` ([n_anchors, 2] in [0, 1]) overrides :data:`PAPER_ANCHOR_UNITS`.
    Draws the agent positions, then the range errors (:func:`simulate_ranges`) from ``rng``.

    Examples
    --------
    >>> sc = paper_static_scenario(np.random.default_rng(3), n_agents=10)
    >>> sc.positions.shape, int(sc.is_anchor.sum()), sc.measurements().n_agents
    ((23, 2), 13, 10)
    """
    rng = _rng(rng)
    n_ag = v.integer("n_agents", n_agents, minimum=0)
    side = v.positive("side_m", side_m)
    units = PAPER_ANCHOR_UNITS if anchor_units is None else anchor_units
    units = v.finite_array("anchor_units", units, ndim=2)
    agents = rng.uniform(0.0, side, size=(n_ag, 2))
    pos = np.vstack([agents, units * side])
    is_anchor = np.r_[np.zeros(n_ag, bool), np.ones(units.shape[0], bool)]
    model = check_error_model(error_model)
    z = simulate_ranges(pos, comm_range_m, model, rng, symmetric=symmetric, anchors=is_anchor)
    return StaticScenario(pos, is_anchor, z, (0.0, 0.0, side, side), model, float(comm_range_m))

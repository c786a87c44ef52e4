"""Range measurements of static 2-D networks, their error models, and the family's inputs.

Measurement model (POA-NBP eq. (1)): node ``j`` estimates its distance to a neighbour ``i`` as

.. math::  \\hat z_{i\\to j} = \\lVert x_i - x_j \\rVert + \\epsilon_{i\\to j},

with one of two error models (measurement models: they sample errors and evaluate the
likelihood; the scenario simulators that draw the truth live in
:mod:`phyloc.evaluation.static_scenarios`):

- :class:`ExponentialRangeError` — one-sided exponential errors ``ε ~ Exp(λ)`` of mean ``1/λ``
  (POA-NBP eq. (2); default mean 0.38 m, POA-NBP §V-A). Its likelihood is zero for ``z < d``.
- :class:`GaussianRangeError` — ``ε ~ N(0, σ²)``.

**Range matrix convention** (as in :mod:`phyloc.localization.tracking.range_models`): a dense
``ranges[N, N]`` float64 array, ``ranges[j, i] = ẑ_{i→j}`` is the range node ``j`` *measured*
to node ``i`` (row = measuring node), NaN where there is no link and on the diagonal. Both nodes
of a linked pair measure, each with its own independent error (``ranges[j, i] ≠ ranges[i, j]``,
POA-NBP's ``ẑ_{i→j}`` and ``ẑ_{j→i}``).

**Log-likelihoods never return -inf.** The exponential model's zero likelihood for ``z < d``
(infeasible distance) is replaced by the finite value
``log λ − INFEASIBLE_LOG_PENALTY − INFEASIBLE_SLOPE·λ·(d − z)``: ``e^{−100}`` below the density
at the boundary and decreasing in the violation, so a feasible point always outweighs an
infeasible one by a factor ``> e^{100}`` (unless its own excess error is beyond ``100/λ``,
38 m at the default), while a set of points that are *all* infeasible (e.g. after kernel
smoothing) still ranks them by how much they violate. Every log-likelihood is finally clipped
at :data:`LOGLIK_FLOOR` so that extreme inputs (σ → 0) stay finite.

**The family's inputs.** Every static method is ``run(measurements, prior, rng, options) ->
Result`` with :class:`StaticMeasurements` (the range matrix, which nodes are anchors, the anchor
positions and the error model — never the agents' true positions) and :class:`StaticPrior`
(the deployment region, optional starting estimates and optional precomputed support polygons).
Also here: the checked network view the localizers work on (:class:`StaticNetwork`) and the
truth-free convergence rule (:func:`convergence_iteration`).

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError

#: Default mean ranging error 1/λ of the exponential model [m] (POA-NBP §V-A).
PAPER_MEAN_ERROR_M = 0.38
#: log-likelihood gap between a feasible and an infeasible (z < d) point, exponential model.
INFEASIBLE_LOG_PENALTY = 100.0
#: Slope of the infeasible branch in units of λ (log-likelihood per metre of violation / λ).
INFEASIBLE_SLOPE = 100.0
#: Lower clip of every log-likelihood (keeps sums of many terms finite).
LOGLIK_FLOOR = -1.0e200
#: Error models understood by :func:`range_error_model`.
ERROR_MODELS = ("exponential", "gaussian")


# ---------------------------------------------------------------------------------------------
# Error models
# ---------------------------------------------------------------------------------------------
def _rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", rng, "a numpy.random.Generator is required")
    return rng


def exponential_loglik(z, d, mean_m: float = PAPER_MEAN_ERROR_M) -> np.ndarray:
    """``log p(z | d)`` of the one-sided exponential error (POA-NBP eq. (2)), finite everywhere.

    .. math::  \\log p = \\log\\lambda - \\lambda (z - d), \\quad z \\ge d,

    and for the infeasible side ``z < d`` (zero likelihood in the paper) the finite floor
    ``log λ − INFEASIBLE_LOG_PENALTY − INFEASIBLE_SLOPE·λ·(d − z)`` (see the module docstring).

    Parameters
    ----------
    z : array_like float64
        Measured ranges [m] (broadcast with ``d``).
    d : array_like float64
        Distances [m].
    mean_m : float
        Mean error ``1/λ`` [m], > 0.

    Returns
    -------
    loglik : ndarray float64, the broadcast shape of ``z`` and ``d``

    Examples
    --------
    >>> import numpy as np
    >>> round(float(exponential_loglik(10.38, 10.0, 0.38)), 6)  # log(1/0.38) − 1
    -0.032416
    """
    lam = 1.0 / v.positive("mean_m", mean_m)
    z = np.asarray(z, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    excess = z - d
    out = np.where(
        excess >= 0.0,
        math.log(lam) - lam * excess,
        math.log(lam) - INFEASIBLE_LOG_PENALTY + INFEASIBLE_SLOPE * lam * excess,
    )
    return np.maximum(out, LOGLIK_FLOOR)


def gaussian_loglik(z, d, std_m: float) -> np.ndarray:
    """``log N(z; d, σ²) = −½ log(2πσ²) − (z − d)²/(2σ²)``, clipped at :data:`LOGLIK_FLOOR`.

    Parameters
    ----------
    z, d : array_like float64
        Measured ranges and distances [m] (broadcast).
    std_m : float
        σ [m], > 0.
    """
    s = v.positive("std_m", std_m)
    e = np.asarray(z, dtype=np.float64) - np.asarray(d, dtype=np.float64)
    with np.errstate(over="ignore"):
        out = -0.5 * math.log(2.0 * math.pi) - math.log(s) - 0.5 * (e / s) ** 2
    return np.maximum(out, LOGLIK_FLOOR)


def sample_exponential_errors(size, mean_m: float, rng: np.random.Generator) -> np.ndarray:
    """Draw ``ε ~ Exp(λ)``, mean ``1/λ = mean_m`` [m] (POA-NBP eq. (2)); all ``ε >= 0``."""
    return _rng(rng).exponential(v.positive("mean_m", mean_m), size=size)


def sample_gaussian_errors(size, std_m: float, rng: np.random.Generator) -> np.ndarray:
    """Draw ``ε ~ N(0, σ²)`` [m]."""
    return _rng(rng).normal(0.0, v.positive("std_m", std_m), size=size)


@dataclass(frozen=True)
class ExponentialRangeError:
    """One-sided exponential ranging error of mean ``1/λ`` (POA-NBP eq. (2)).

    Parameters
    ----------
    mean_m : float
        ``1/λ`` [m], > 0. Default 0.38 m (POA-NBP §V-A).

    Examples
    --------
    >>> m = ExponentialRangeError()
    >>> m.mean_m, round(m.std_m, 2)
    (0.38, 0.38)
    >>> e = m.sample(1000, np.random.default_rng(0))
    >>> bool(e.min() >= 0)
    True
    """

    mean_m: float = PAPER_MEAN_ERROR_M
    kind = "exponential"

    def __post_init__(self):
        object.__setattr__(self, "mean_m", v.positive("mean_m", self.mean_m))

    @property
    def bias_m(self) -> float:
        """Mean error ``E[ε] = 1/λ`` [m]."""
        return self.mean_m

    @property
    def std_m(self) -> float:
        """Standard deviation of ``ε``, ``1/λ`` [m]."""
        return self.mean_m

    def sample(self, size, rng: np.random.Generator) -> np.ndarray:
        """Errors ``ε`` of the given ``size``."""
        return sample_exponential_errors(size, self.mean_m, rng)

    def loglik(self, z, d) -> np.ndarray:
        """:func:`exponential_loglik` with this model's mean."""
        return exponential_loglik(z, d, self.mean_m)


@dataclass(frozen=True)
class GaussianRangeError:
    """Zero-mean Gaussian ranging error ``N(0, σ²)``.

    Parameters
    ----------
    std_m : float
        σ [m], > 0.
    """

    std_m: float = 0.1
    kind = "gaussian"

    def __post_init__(self):
        object.__setattr__(self, "std_m", v.positive("std_m", self.std_m))

    @property
    def bias_m(self) -> float:
        """Mean error, 0."""
        return 0.0

    def sample(self, size, rng: np.random.Generator) -> np.ndarray:
        """Errors ``ε`` of the given ``size``."""
        return sample_gaussian_errors(size, self.std_m, rng)

    def loglik(self, z, d) -> np.ndarray:
        """:func:`gaussian_loglik` with this model's σ."""
        return gaussian_loglik(z, d, self.std_m)


RangeError = ExponentialRangeError | GaussianRangeError


def range_error_model(kind: str = "exponential", **params) -> RangeError:
    """Build an error model by name (recipes): ``"exponential"`` (``mean_m``) or
    ``"gaussian"`` (``std_m``)."""
    if kind == "exponential":
        return ExponentialRangeError(**params)
    if kind == "gaussian":
        return GaussianRangeError(**params)
    raise ValidationError("error_model", kind, f"must be one of {ERROR_MODELS}")


def check_error_model(model) -> RangeError:
    """Default (``None``) → the paper's exponential model; reject anything else."""
    if model is None:
        return ExponentialRangeError()
    if not isinstance(model, (ExponentialRangeError, GaussianRangeError)):
        raise ValidationError(
            "error_model", model, "must be an ExponentialRangeError or GaussianRangeError"
        )
    return model


# ---------------------------------------------------------------------------------------------
# Inputs and results shared by the static localizers (NBP, Gaussian BP, WLS)
# ---------------------------------------------------------------------------------------------
def anchor_mask(anchors, n: int) -> np.ndarray:
    """``[n]`` bool anchor mask from a bool mask or a list of distinct node indices.

    Examples
    --------
    >>> anchor_mask([0, 2], 4).tolist()
    [True, False, True, False]
    """
    a = np.asarray(anchors)
    if a.dtype == bool:
        if a.shape != (n,):
            raise ValidationError("anchors", f"bool array of shape {a.shape}", f"must be ({n},)")
        return a.copy()
    if a.size == 0:
        return np.zeros(n, bool)
    if a.ndim != 1 or not np.issubdtype(a.dtype, np.integer):
        raise ValidationError("anchors", anchors, "must be a bool mask or a list of node indices")
    if a.min() < 0 or a.max() >= n or np.unique(a).size != a.size:
        raise ValidationError("anchors", anchors, f"indices must be distinct and in [0, {n})")
    mask = np.zeros(n, bool)
    mask[a] = True
    return mask


def check_region(region) -> tuple[float, float, float, float]:
    """``(xmin, ymin, xmax, ymax)`` with finite entries and positive extent."""
    try:
        r = tuple(float(x) for x in region)
    except (TypeError, ValueError):
        raise ValidationError("region", region, "must be (xmin, ymin, xmax, ymax)") from None
    if len(r) != 4 or not all(math.isfinite(x) for x in r) or r[2] <= r[0] or r[3] <= r[1]:
        raise ValidationError(
            "region",
            region,
            "must be finite (xmin, ymin, xmax, ymax) with xmax > xmin, ymax > ymin",
        )
    return r


@dataclass(frozen=True, eq=False)
class StaticNetwork:
    """Checked inputs of a static localizer.

    Attributes
    ----------
    ranges : [N, N] float64 (NaN: no link; negative values are allowed — Gaussian errors on
        short links produce them)
    is_anchor : [N] bool
    positions : [N, 2] float64
        Anchor rows hold the known positions, agent rows NaN.
    agents : [n_agents] int64
        Agent node indices (ascending); agent ``a`` of every result is node ``agents[a]``.
    """

    ranges: np.ndarray
    is_anchor: np.ndarray
    positions: np.ndarray
    agents: np.ndarray

    @property
    def n_agents(self) -> int:
        return self.agents.size

    def links(self, node: int, mode: str = "own") -> list[tuple[int, float]]:
        """``(neighbour, z)`` pairs entering ``node``'s belief.

        ``"own"``: the ranges ``node`` measured, ``ẑ_{i→node} = ranges[node, i]`` (distributed
        processing, one factor per neighbour). ``"both"``: also the ranges the neighbours
        measured to ``node``, ``ranges[i, node]`` (both factors of POA-NBP eq. (3) for every pair).
        """
        out = [
            (int(i), float(self.ranges[node, i]))
            for i in np.flatnonzero(np.isfinite(self.ranges[node]))
        ]
        if mode == "both":
            out += [
                (int(i), float(self.ranges[i, node]))
                for i in np.flatnonzero(np.isfinite(self.ranges[:, node]))
            ]
        return out


LINK_MODES = ("own", "both")


def check_static_network(ranges, anchors, anchor_positions) -> StaticNetwork:
    """Validate ``ranges [N, N]``, ``anchors`` (bool mask or index list) and
    ``anchor_positions`` (``[n_anchors, 2]`` in ascending node order, or ``[N, 2]`` of which
    only anchor rows are read)."""
    try:
        z = np.array(ranges, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValidationError("ranges", "<array>", "must convert to float64") from None
    if z.ndim != 2 or z.shape[0] != z.shape[1] or z.shape[0] < 1:
        raise ValidationError("ranges", f"array of shape {z.shape}", "must be square (N, N)")
    n = z.shape[0]
    np.fill_diagonal(z, np.nan)
    if np.any(np.isinf(z)):
        raise ValidationError("ranges", "inf", "entries must be finite or NaN (no link)")
    is_anchor = anchor_mask(anchors, n)
    ap = np.asarray(anchor_positions, dtype=np.float64)
    n_anc = int(is_anchor.sum())
    if ap.ndim == 2 and ap.shape == (n, 2) and n != n_anc:
        ap = ap[is_anchor]
    if ap.size == 0 and n_anc == 0:
        ap = np.zeros((0, 2))
    if ap.shape != (n_anc, 2):
        raise ValidationError(
            "anchor_positions",
            f"array of shape {ap.shape}",
            f"must be ({n_anc}, 2) (anchors in ascending node order) or ({n}, 2)",
        )
    ap = v.finite_array("anchor_positions", ap, ndim=2)
    pos = np.full((n, 2), np.nan)
    pos[is_anchor] = ap
    z[is_anchor[:, None] & is_anchor[None, :]] = np.nan  # anchor–anchor ranges are unused
    return StaticNetwork(z, is_anchor, pos, np.flatnonzero(~is_anchor))


def convergence_iteration(estimates: np.ndarray, tol_m: float, rel: float = 0.0) -> int | None:
    """1-based iteration at which a run has converged, ``None`` if it never does.

    With ``c_l`` the mean over agents of ``‖x̂^{(l)} − x̂^{(l−1)}‖`` (``l >= 2``), the run has
    converged at the first ``l`` with ``c_l < tol_m`` or, when ``rel > 0``, with
    ``c_l > (1 − rel)·c_{l−1}`` (the change no longer shrinks by the fraction ``rel``: the
    Monte Carlo noise floor of a particle method). A truth-free version of the paper's
    criterion (POA-NBP §V, footnote 5: the average localization error no longer changes notably).
    """
    if estimates.shape[0] < 2 or estimates.shape[1] == 0:
        return None
    c = np.linalg.norm(np.diff(estimates, axis=0), axis=-1).mean(axis=1)
    hit = c < tol_m
    if rel > 0:
        hit[1:] |= c[1:] > (1.0 - rel) * c[:-1]
    idx = np.flatnonzero(hit)
    return int(idx[0]) + 2 if idx.size else None


# ---------------------------------------------------------------------------------------------
# The family's measurements and prior
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class StaticMeasurements:
    """What a static localizer is given: ranges, anchors and the error model — no truth.

    Parameters
    ----------
    ranges : [N, N] float64
        ``ranges[j, i] = ẑ_{i→j}`` [m], the range node ``j`` measured to node ``i``; NaN where
        there is no link. The diagonal and anchor–anchor entries are set to NaN (unused).
    is_anchor : [N] bool or sequence of int
        Anchor mask or anchor node indices (stored as the mask); every other node is an agent.
    anchor_positions : [n_anchors, 2] or [N, 2] float64
        Known anchor positions [m] in ascending node order (of an ``[N, 2]`` array only the
        anchor rows are read and kept, so agent rows may hold anything, e.g. NaN).
    error_model : ExponentialRangeError or GaussianRangeError, optional
        The ranging error model (POA-NBP eq. (2)); default exponential, mean 0.38 m.

    Examples
    --------
    >>> z = np.array([[np.nan, 5.1, 5.2], [5.0, np.nan, np.nan], [5.3, np.nan, np.nan]])
    >>> m = StaticMeasurements(z, [1, 2], [[3.0, 4.0], [-3.0, 4.0]])
    >>> m.n_agents, m.agent_nodes.tolist(), m.is_anchor.tolist()
    (1, [0], [False, True, True])
    """

    ranges: np.ndarray
    is_anchor: np.ndarray
    anchor_positions: np.ndarray
    error_model: RangeError | None = None

    def __post_init__(self):
        net = check_static_network(self.ranges, self.is_anchor, self.anchor_positions)
        for a in (net.ranges, net.is_anchor):
            a.flags.writeable = False
        anchors = net.positions[net.is_anchor]
        anchors.flags.writeable = False
        object.__setattr__(self, "ranges", net.ranges)
        object.__setattr__(self, "is_anchor", net.is_anchor)
        object.__setattr__(self, "anchor_positions", anchors)
        object.__setattr__(self, "error_model", check_error_model(self.error_model))
        object.__setattr__(self, "_net", net)

    @property
    def n_nodes(self) -> int:
        """Number of nodes ``N`` (agents and anchors)."""
        return int(self.ranges.shape[0])

    @property
    def agent_nodes(self) -> np.ndarray:
        """``[n_agents]`` int64 node index of each agent (ascending); result row ``a`` is node
        ``agent_nodes[a]``."""
        return self._net.agents

    @property
    def n_agents(self) -> int:
        """Number of agents (nodes with unknown position)."""
        return int(self._net.agents.size)

    @property
    def positions(self) -> np.ndarray:
        """``[N, 2]`` known positions: anchor rows hold them, agent rows are NaN."""
        return self._net.positions

    @property
    def network(self) -> StaticNetwork:
        """The checked network view of the localizers."""
        return self._net


@dataclass(frozen=True, eq=False)
class StaticPrior:
    """Prior knowledge of a static localizer (no truth).

    Parameters
    ----------
    region : (xmin, ymin, xmax, ymax)
        Deployment area [m]: the support of the uniform prior of every agent (POA-NBP §III-B,
        §V-A), the start of the polygon outer-approximation and the box iterates are clipped to.
    initial : [n_agents, 2] float64, optional
        Starting estimates of local methods (Gaussian BP, WLS); ``None``: the method's ``start``
        option decides.
    polygons : sequence or dict, optional
        Precomputed support regions of the polygon proposal (POA-NBP eq. (21)): one object per
        agent (or per node, or ``{node: polygon}``) with ``.area``, ``.contains(points)`` and
        ``.sample_uniform(n, rng)``, e.g. the polygons of
        :func:`~phyloc.localization.static.poa_network.poa`. When given, NBP uses them instead of
        computing its own support (``NBPOptions.support``).
    polygon_time_per_node_s : float
        Wall time per agent it took to compute ``polygons`` [s] (reported as the setup time).
    polygon_operations_per_node : float
        Operations per agent it took to compute ``polygons`` (e.g.
        :attr:`~phyloc.localization.static.poa_network.POAResult.operations_per_node`; 0: not
        counted), reported with the method's operation count.
    polygon_floats_per_link_iteration : float
        Floats per link and iteration exchanged to compute ``polygons`` (e.g.
        :attr:`~phyloc.localization.static.poa_network.POAResult.floats_per_link_iteration`;
        NaN: none or not known).

    Examples
    --------
    >>> StaticPrior((0, 0, 100, 100)).region
    (0.0, 0.0, 100.0, 100.0)
    """

    region: tuple
    initial: np.ndarray | None = None
    polygons: object = None
    polygon_time_per_node_s: float = 0.0
    polygon_operations_per_node: float = 0.0
    polygon_floats_per_link_iteration: float = math.nan

    def __post_init__(self):
        object.__setattr__(self, "region", check_region(self.region))
        if self.initial is not None:
            object.__setattr__(self, "initial", v.finite_array("initial", self.initial, ndim=2))
        t = v.positive("polygon_time_per_node_s", self.polygon_time_per_node_s, allow_zero=True)
        object.__setattr__(self, "polygon_time_per_node_s", t)
        ops = v.positive(
            "polygon_operations_per_node", self.polygon_operations_per_node, allow_zero=True
        )
        object.__setattr__(self, "polygon_operations_per_node", ops)
        fl = self.polygon_floats_per_link_iteration
        try:
            fl = float(fl)
        except (TypeError, ValueError):
            raise ValidationError(
                "polygon_floats_per_link_iteration", fl, "a number >= 0 or NaN"
            ) from None
        if fl < 0 or math.isinf(fl):
            raise ValidationError("polygon_floats_per_link_iteration", fl, "a number >= 0 or NaN")
        object.__setattr__(self, "polygon_floats_per_link_iteration", fl)


def check_inputs(measurements, prior, rng=None, *, need_rng: bool = True):
    """Check the arguments of a static method's ``run``; returns ``(measurements, prior)``."""
    if not isinstance(measurements, StaticMeasurements):
        raise ValidationError(
            "measurements", type(measurements).__name__, "must be StaticMeasurements"
        )
    if not isinstance(prior, StaticPrior):
        raise ValidationError(
            "prior", type(prior).__name__, "must be a StaticPrior (it gives the region)"
        )
    if need_rng and not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", rng, "a numpy.random.Generator is required")
    return measurements, prior

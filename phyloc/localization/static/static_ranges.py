"""Range measurements of static 2-D networks and their error models (POA-NBP paper §II-A).

Measurement model (POA-NBP eq. (1)): node ``j`` estimates its distance to a neighbour ``i`` as

.. math::  \\hat z_{i\\to j} = \\lVert x_i - x_j \\rVert + \\epsilon_{i\\to j},

with one of two error models:

- :class:`ExponentialRangeError` — one-sided exponential errors ``ε ~ Exp(λ)`` of mean ``1/λ``
  (POA-NBP eq. (2); default mean 0.38 m, §V-A). Its likelihood is zero for ``z < d``.
- :class:`GaussianRangeError` — ``ε ~ N(0, σ²)``.

**Range matrix convention** (as in :mod:`phyloc.localization.tracking.range_models`): a dense
``ranges[N, N]`` float64 array, ``ranges[j, i] = ẑ_{i→j}`` is the range node ``j`` *measured*
to node ``i`` (row = measuring node), NaN where there is no link and on the diagonal. Both nodes
of a pair within the communication range ``r_com`` measure, each with its own independent error
(``ranges[j, i] ≠ ranges[i, j]``, the paper's ``ẑ_{i→j}`` and ``ẑ_{j→i}``); ``symmetric=True``
draws one error per pair instead.

**Log-likelihoods never return -inf.** The exponential model's zero likelihood for ``z < d``
(infeasible distance) is replaced by the finite value
``log λ − INFEASIBLE_LOG_PENALTY − INFEASIBLE_SLOPE·λ·(d − z)``: ``e^{−100}`` below the density
at the boundary and decreasing in the violation, so a feasible point always outweighs an
infeasible one by a factor ``> e^{100}`` (unless its own excess error is beyond ``100/λ``,
38 m at the default), while a set of points that are *all* infeasible (e.g. after kernel
smoothing) still ranks them by how much they violate. Every log-likelihood is finally clipped
at :data:`LOGLIK_FLOOR` so that extreme inputs (σ → 0) stay finite.

Also here: the result type shared by the static localizers (:class:`StaticResult`), their input
checks (:func:`check_static_network`) and the §V deployment (:func:`paper_static_scenario`).
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
        ``1/λ`` [m], > 0. Default 0.38 m (§V-A).

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
# Simulation
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
        is_anchor = _anchor_mask(anchors, n)
        linked &= ~(is_anchor[:, None] & is_anchor[None, :])
    e = model.sample((n, n), rng)
    if symmetric:
        e = np.triu(e, 1)
        e = e + e.T
    return np.where(linked, d + e, np.nan)


#: The 13 anchors of the §V setup as fractions of the side: a 3×3 grid at the cell centres plus
#: a 2×2 grid between them (the paper takes the topology of [3] without listing coordinates;
#: this regular layout is our assumption).
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


# ---------------------------------------------------------------------------------------------
# Inputs and results shared by the static localizers (NBP, Gaussian BP, WLS)
# ---------------------------------------------------------------------------------------------
def _anchor_mask(anchors, n: int) -> np.ndarray:
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
        measured to ``node``, ``ranges[i, node]`` (both factors of eq. (3) for every pair).
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
    is_anchor = _anchor_mask(anchors, n)
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
    criterion (§V, footnote 5: the average localization error no longer changes notably).
    """
    if estimates.shape[0] < 2 or estimates.shape[1] == 0:
        return None
    c = np.linalg.norm(np.diff(estimates, axis=0), axis=-1).mean(axis=1)
    hit = c < tol_m
    if rel > 0:
        hit[1:] |= c[1:] > (1.0 - rel) * c[:-1]
    idx = np.flatnonzero(hit)
    return int(idx[0]) + 2 if idx.size else None


@dataclass(frozen=True, eq=False)
class StaticResult:
    """Per-iteration estimates of a static localizer.

    Attributes
    ----------
    estimates : [n_iter, n_agents, 2] float64
        Position estimates after every iteration [m] (NBP: MMSE, the weighted mean; Gaussian
        BP: belief mean; WLS: Gauss–Newton iterate).
    agents : [n_agents] int64
        Node index of each agent.
    converged_iteration : int or None
        1-based iteration of convergence (:func:`convergence_iteration`), None if not reached.
    time_per_node_s : [n_iter, n_agents] float64
        Wall time of each agent's update per iteration [s] (centralized WLS: the joint time
        divided by the number of agents).
    covariances : [n_iter, n_agents, 2, 2] float64 or None
        Belief covariances where the method has them.
    label : str
    """

    estimates: np.ndarray
    agents: np.ndarray
    converged_iteration: int | None
    time_per_node_s: np.ndarray
    covariances: np.ndarray | None = None
    label: str = ""

    @property
    def n_iterations(self) -> int:
        return self.estimates.shape[0]

    @property
    def final(self) -> np.ndarray:
        """``[n_agents, 2]`` estimates after the last iteration."""
        return self.estimates[-1]

    def errors(self, true_positions) -> np.ndarray:
        """``[n_iter, n_agents]`` localization errors ``‖x̂ − x‖`` [m].

        ``true_positions``: ``[n_agents, 2]`` or ``[N, 2]`` (all nodes; agent rows are used).
        """
        t = np.asarray(true_positions, dtype=np.float64)
        if t.shape[0] != self.agents.size:
            t = t[self.agents]
        return np.linalg.norm(self.estimates - t[None], axis=-1)

    def time_to_convergence_per_node_s(self) -> float:
        """Mean over agents of the summed update time up to convergence (all iterations if
        not converged): the paper's ``t_conv`` (Table I)."""
        n = self.converged_iteration or self.n_iterations
        return float(self.time_per_node_s[:n].sum(axis=0).mean()) if self.agents.size else 0.0

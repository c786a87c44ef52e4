"""Baselines of POA-NBP §V for static 2-D range networks: parametric (Gaussian) BP and WLS.

Both use the range matrix convention of :mod:`phyloc.localization.static.static_ranges`
(``ranges[j, i] = ẑ_{i→j}``, measured by node ``j``) and a Gaussian view of the error model:
with ``debias`` the error mean ``b`` is removed (``b = 1/λ`` for the exponential model of
POA-NBP eq. (2), 0 for the Gaussian one) and the variance ``s²`` is matched (``s = 1/λ``
resp. ``σ``).

**Gaussian BP** (:func:`run_gaussian_bp`, 'PBP' of POA-NBP ref. [19]): every agent's belief is
``N(μ_j, P_j)``. In iteration ``l`` (parallel schedule, neighbours' beliefs of ``l − 1``),
agent ``j`` multiplies its prior ``N(μ_0, Λ_0⁻¹)`` (moment match of the uniform prior over the
region: centre and ``diag(w_x², w_y²)/12``) with one linearized message per link ``i → j``:
with ``d = ‖x̄ − μ_i‖``, ``u = (x̄ − μ_i)/d`` at the linearization point ``x̄``,

.. math::  \\hat z - b \\approx d + u^T (x_j - \\bar x) - u^T (x_i - \\mu_i) + (\\epsilon - b),

which, marginalised over ``x_i ~ N(μ_i, P_i)`` (anchors: ``P_i = 0``), is the Gaussian
message ``Λ += u uᵀ/R``, ``η += u (ẑ − b − d + uᵀx̄)/R`` with ``R = s² + uᵀ P_i u``. The belief is
``P_j = Λ⁻¹``, ``μ_j = Λ⁻¹ η``; it is relinearized ``n_inner`` times per iteration at the new
mean (an iterated EKF update, i.e. Gauss–Newton on the MAP cost with fixed neighbour beliefs)
and clipped to the region. As in the NBP of the paper, neighbours send their full beliefs.

**Weighted least squares** (:func:`run_wls`, 'WLS' of POA-NBP ref. [5]): Gauss–Newton with
Levenberg–Marquardt damping on

.. math::  F(X) = \\sum_{(j, i)} w_{ji} (\\hat z_{i\\to j} - b - \\lVert x_j - x_i \\rVert)^2,

``w = 1/s²`` unless ``link_weights`` are given. ``mode="joint"``: centralized, all agents at
once, one damped GN step per iteration (every finite range entry involving an agent is a term;
``link_mode="own"`` keeps only the ranges the agents measured). ``mode="distributed"``: per
iteration each agent takes ``n_inner`` damped GN steps on its own position with the anchors
and its neighbours' previous estimates held fixed (Jacobi).

**Start**: ``StaticPrior.initial`` ([n_agents, 2]), else by the option ``start``: :func:`mds_start`
(the MDS/SMACOF solution of the measured ranges in the anchors' frame; the heuristic start where the
range graph is disconnected) or :func:`heuristic_start`: the centroid of an agent's anchor
neighbours; with a single anchor the point at the measured range from it towards the region centre;
otherwise the mean of the neighbours' starts (propagated over the graph); the region centre for the
rest. A deterministic offset of 1 mm (golden-angle directions) separates agents that would otherwise
start at the same point (a zero distance has no gradient).

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
(Its refs. [19] for PBP and [5] for WLS.)
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc._validate import from_table
from phyloc.errors import ValidationError
from phyloc.localization.initialization import coarse_positions
from phyloc.localization.results import Result, Timing
from phyloc.localization.static.static_ranges import (
    LINK_MODES,
    RangeError,
    StaticMeasurements,
    StaticNetwork,
    StaticPrior,
    check_inputs,
    check_region,
    convergence_iteration,
)

WLS_MODES = ("joint", "distributed")
#: Starting estimates of :func:`run_gaussian_bp` and :func:`run_wls` without ``prior.initial``.
STARTS = ("heuristic", "mds")
_GOLDEN = math.pi * (3.0 - math.sqrt(5.0))
_EPS_D = 1e-9  # distances below this [m] have no direction: the term is skipped


def _moments(model: RangeError, debias: bool) -> tuple[float, float]:
    """``(b, s²)`` of the Gaussian view of the error model."""
    b = model.bias_m if debias else 0.0
    return b, model.std_m**2


def _clip(x, region):
    return np.clip(x, (region[0], region[1]), (region[2], region[3]))


def heuristic_start(net, region, link_mode: str = "own") -> np.ndarray:
    """Truth-free starting positions ``[n_agents, 2]`` (see the module docstring).

    ``net``: :class:`~phyloc.localization.static.static_ranges.StaticMeasurements` or its
    :class:`~phyloc.localization.static.static_ranges.StaticNetwork`.
    """
    if isinstance(net, StaticMeasurements):
        net = net.network
    reg = check_region(region)
    centre = np.array([(reg[0] + reg[2]) / 2, (reg[1] + reg[3]) / 2])
    n_ag = net.n_agents
    start = np.full((n_ag, 2), np.nan)
    node_to_agent = {int(j): a for a, j in enumerate(net.agents)}
    links = [net.links(int(j), link_mode) for j in net.agents]
    for a in range(n_ag):
        anc = {}
        for i, z in links[a]:
            if net.is_anchor[i]:
                anc.setdefault(i, []).append(z)
        if len(anc) >= 2:
            start[a] = np.mean([net.positions[i] for i in anc], axis=0)
        elif len(anc) == 1:
            ((i, zs),) = anc.items()
            p = net.positions[i]
            d = centre - p
            nd = np.linalg.norm(d)
            u = d / nd if nd > 0 else np.array([1.0, 0.0])
            start[a] = p + float(np.mean(zs)) * u
    for _ in range(n_ag):  # propagate over agent neighbours
        unset = np.flatnonzero(np.isnan(start[:, 0]))
        if unset.size == 0:
            break
        new = start.copy()
        for a in unset:
            nb = [node_to_agent[i] for i, _ in links[a] if not net.is_anchor[i]]
            known = [start[b] for b in nb if not np.isnan(start[b, 0])]
            if known:
                new[a] = np.mean(known, axis=0)
        if np.array_equal(np.isnan(new), np.isnan(start)):
            break
        start = new
    start[np.isnan(start[:, 0])] = centre
    ang = _GOLDEN * np.arange(n_ag)
    start = start + 1e-3 * np.column_stack([np.cos(ang), np.sin(ang)])
    return _clip(start, reg)


def mds_start(measurements: StaticMeasurements, region) -> np.ndarray | None:
    """Truth-free MDS/SMACOF start ``[n_agents, 2]`` of the measured ranges in the anchors'
    frame (:func:`~phyloc.localization.initialization.coarse_positions`), clipped to the
    region; ``None`` where the range graph is disconnected (no joint solution)."""
    meas = measurements
    reg = check_region(region)
    j, i = np.nonzero(np.isfinite(meas.ranges))
    links = np.stack([j, i], axis=1)
    try:
        sol = coarse_positions(
            links,
            meas.ranges[j, i],
            meas.n_nodes,
            2,
            is_anchor=meas.is_anchor,
            anchor_positions=meas.anchor_positions,
        )
    except ValidationError:
        return None
    return _clip(sol.positions[~meas.is_anchor], reg)


def _start(meas: StaticMeasurements, prior: StaticPrior, start: str, link_mode: str):
    """``(x0 [n_agents, 2], setup time per agent [s], start used)``: ``prior.initial``,
    else the ``start`` rule (``"mds"`` falls back to the heuristic start when the range graph
    is disconnected)."""
    net = meas.network
    if prior.initial is not None:
        x = prior.initial
        if x.shape != (net.n_agents, 2):
            raise ValidationError(
                "initial", f"array of shape {x.shape}", f"must be ({net.n_agents}, 2)"
            )
        return x.copy(), 0.0, "prior"
    if start == "mds":
        t0 = time.perf_counter()
        x = mds_start(meas, prior.region)
        if x is not None:
            return x, (time.perf_counter() - t0) / max(net.n_agents, 1), "mds"
    return heuristic_start(net, prior.region, link_mode), 0.0, "heuristic"


def _timing(t_wall, step_s, agent_t):
    n_steps, n_ag = agent_t.shape
    return Timing(
        wall_s=time.perf_counter() - t_wall,
        step_s=step_s,
        agent_s=agent_t.mean(axis=1) if n_ag else np.zeros(n_steps),
        agent_iterations=n_steps * n_ag,
    )


# ---------------------------------------------------------------------------------------------
# Gaussian BP
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class GaussianBPOptions:
    """Options of :func:`run_gaussian_bp`.

    Parameters
    ----------
    n_iterations : int
        BP iterations (10).
    n_inner : int
        Relinearizations per iteration (3).
    link_mode : {"own", "both"}
        Ranges entering agent ``j``: its own ``ẑ_{i→j}`` ("own") or also ``ẑ_{j→i}``.
    debias : bool
        Remove the error model's mean from the ranges (True).
    start : {"heuristic", "mds"}
        First linearization points when the prior brings none: :func:`heuristic_start` or
        :func:`mds_start` (falling back to the heuristic start) ("heuristic").
    convergence_tol_m : float
        Mean estimate change [m] below which the run has converged (1e-3).
    stop_on_convergence : bool
    """

    #: The recipe table of these options: ``[localization.pbp]``.

    n_iterations: int = 10
    n_inner: int = 3
    link_mode: str = "own"
    debias: bool = True
    start: str = "heuristic"
    convergence_tol_m: float = 1e-3
    stop_on_convergence: bool = False

    def __post_init__(self):
        for name in ("n_iterations", "n_inner"):
            object.__setattr__(self, name, v.integer(name, getattr(self, name), minimum=1))
        v.choice("link_mode", self.link_mode, LINK_MODES)
        v.choice("start", self.start, STARTS)
        object.__setattr__(
            self, "convergence_tol_m", v.positive("convergence_tol_m", self.convergence_tol_m)
        )

    @classmethod
    def from_dict(cls, d: dict, section: str = "localization") -> GaussianBPOptions:
        """Build from a recipe table; unknown keys are errors naming the closest valid key."""
        return from_table(cls, d, section)


def gaussian_bp_update(x0, prior_mean, prior_info, nb_mean, nb_cov, z, b, s2, n_inner, region):
    """One agent's belief update of Gaussian BP (module docstring).

    Parameters
    ----------
    x0 : [2] float64
        First linearization point.
    prior_mean : [2], prior_info : [2, 2]
        ``μ_0``, ``Λ_0``.
    nb_mean : [L, 2], nb_cov : [L, 2, 2]
        Neighbour beliefs (anchors: their position and zeros).
    z : [L] float64
        Ranges.
    b, s2 : float
        Error mean removed and error variance.

    Returns
    -------
    mean : [2], cov : [2, 2]
    """
    x = np.asarray(x0, dtype=np.float64).copy()
    info = prior_info
    for _ in range(n_inner):
        info = prior_info.copy()
        eta = prior_info @ prior_mean
        diff = x[None, :] - nb_mean
        d = np.linalg.norm(diff, axis=1)
        ok = d > _EPS_D
        if ok.any():
            u = diff[ok] / d[ok, None]
            R = s2 + np.einsum("li,lij,lj->l", u, nb_cov[ok], u)
            info = info + np.einsum("li,lj,l->ij", u, u, 1.0 / R)
            eta = eta + u.T @ ((z[ok] - b - d[ok] + u @ x) / R)
        x = _clip(np.linalg.solve(info, eta), region)
    return x, np.linalg.inv(info)


def run_gaussian_bp(
    measurements: StaticMeasurements,
    prior: StaticPrior,
    rng: np.random.Generator | None = None,
    options: GaussianBPOptions | None = None,
) -> Result:
    """Parametric (Gaussian) BP with linearized messages, parallel schedule ('PBP' of POA-NBP
    ref. [19]).

    Parameters
    ----------
    measurements : StaticMeasurements
    prior : StaticPrior
        ``region`` (prior moments and clipping) and optional ``initial`` first linearization
        points ``[n_agents, 2]`` (else ``options.start``).
    rng : numpy.random.Generator or None
        Unused (the method is deterministic); part of the common call shape.
    options : GaussianBPOptions, optional

    Returns
    -------
    Result
        ``estimates [n_iterations, n_agents, 2]`` (belief means after each iteration, the start
        not included) and ``covariances [n_iterations, n_agents, 2, 2]``; ``timing`` per
        iteration and mean per agent update; ``diagnostics``: ``agent_time_s``
        [n_iterations, n_agents], ``converged_iteration`` (int or None), ``start``
        (``"prior"``, ``"mds"`` or ``"heuristic"``), ``setup_time_per_node_s`` (time per
        agent of the start [s]; 0 for the prior and heuristic starts),
        ``floats_per_link_iteration`` (5: the belief an agent sends a neighbour per
        iteration, mean and symmetric covariance). Label ``"gbp"``.

    Examples
    --------
    >>> anchors = np.array([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0], [20.0, 20.0]])
    >>> z = np.full((5, 5), np.nan)  # node 4, an agent, measured its ranges to the anchors
    >>> z[4, :4] = [13.2, 17.2, 11.6, 16.0]
    >>> meas, prior = StaticMeasurements(z, [0, 1, 2, 3], anchors), StaticPrior((0, 0, 20, 20))
    >>> res = run_gaussian_bp(meas, prior)
    >>> res.estimates.shape, res.covariances.shape
    ((10, 1, 2), (10, 1, 2, 2))
    """
    t_wall = time.perf_counter()
    opt = options if options is not None else GaussianBPOptions()
    if not isinstance(opt, GaussianBPOptions):
        raise ValidationError("options", type(opt).__name__, "must be GaussianBPOptions")
    meas, prior = check_inputs(measurements, prior, need_rng=False)
    net, reg = meas.network, prior.region
    b, s2 = _moments(meas.error_model, opt.debias)
    mean, setup_s, start = _start(meas, prior, opt.start, opt.link_mode)
    n_ag = net.n_agents
    mu0 = np.array([(reg[0] + reg[2]) / 2, (reg[1] + reg[3]) / 2])
    P0 = np.diag([(reg[2] - reg[0]) ** 2 / 12.0, (reg[3] - reg[1]) ** 2 / 12.0])
    L0 = np.linalg.inv(P0)
    cov = np.repeat(P0[None], n_ag, axis=0)
    node_to_agent = {int(j): a for a, j in enumerate(net.agents)}
    links = [net.links(int(j), opt.link_mode) for j in net.agents]

    L = opt.n_iterations
    out_m, out_P, out_t = np.empty((L, n_ag, 2)), np.empty((L, n_ag, 2, 2)), np.zeros((L, n_ag))
    step_t = np.zeros(L)
    n_done = L
    for it in range(L):
        t_it = time.perf_counter()
        new_m, new_P = mean.copy(), cov.copy()
        for a in range(n_ag):
            t0 = time.perf_counter()
            if links[a]:
                nb_m = np.empty((len(links[a]), 2))
                nb_P = np.zeros((len(links[a]), 2, 2))
                z = np.empty(len(links[a]))
                for q, (i, zq) in enumerate(links[a]):
                    z[q] = zq
                    if net.is_anchor[i]:
                        nb_m[q] = net.positions[i]
                    else:
                        nb_m[q], nb_P[q] = mean[node_to_agent[i]], cov[node_to_agent[i]]
                new_m[a], new_P[a] = gaussian_bp_update(
                    mean[a], mu0, L0, nb_m, nb_P, z, b, s2, opt.n_inner, reg
                )
            out_t[it, a] = time.perf_counter() - t0
        mean, cov = new_m, new_P
        out_m[it], out_P[it] = mean, cov
        step_t[it] = time.perf_counter() - t_it
        if opt.stop_on_convergence and convergence_iteration(
            out_m[: it + 1], opt.convergence_tol_m
        ):
            n_done = it + 1
            break
    return Result(
        estimates=out_m[:n_done],
        covariances=out_P[:n_done],
        timing=_timing(t_wall, step_t[:n_done], out_t[:n_done]),
        diagnostics={
            "agent_time_s": out_t[:n_done],
            "converged_iteration": convergence_iteration(out_m[:n_done], opt.convergence_tol_m),
            "start": start,
            "setup_time_per_node_s": setup_s,
            # the belief sent per link and iteration: mean (2) and symmetric covariance (3)
            "floats_per_link_iteration": 5.0,
        },
        label="gbp",
    )


# ---------------------------------------------------------------------------------------------
# Weighted least squares
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class WLSOptions:
    """Options of :func:`run_wls`.

    Parameters
    ----------
    n_iterations : int
        Outer iterations (20).
    mode : {"joint", "distributed"}
        Centralized joint Gauss–Newton or per-agent Jacobi iterations ("joint").
    n_inner : int
        GN steps per agent and iteration in ``"distributed"`` mode (1).
    link_mode : {"own", "both"}
        ``"both"`` (default): every range entry involving an agent; ``"own"``: only the ranges
        the agents measured.
    debias : bool
        Remove the error model's mean (True).
    damping : float
        Initial Levenberg–Marquardt factor λ (relative to ``diag(JᵀJ)``), > 0 (1e-3).
    start : {"heuristic", "mds"}
        Start when the prior brings none (as :class:`GaussianBPOptions`) ("heuristic").
    convergence_tol_m : float
        Mean estimate change [m] below which the run has converged (1e-4).
    stop_on_convergence : bool
    """

    #: The recipe table of these options: ``[localization.wls]``.

    n_iterations: int = 20
    mode: str = "joint"
    n_inner: int = 1
    link_mode: str = "both"
    debias: bool = True
    damping: float = 1e-3
    start: str = "heuristic"
    convergence_tol_m: float = 1e-4
    stop_on_convergence: bool = False

    def __post_init__(self):
        for name in ("n_iterations", "n_inner"):
            object.__setattr__(self, name, v.integer(name, getattr(self, name), minimum=1))
        v.choice("mode", self.mode, WLS_MODES)
        v.choice("link_mode", self.link_mode, LINK_MODES)
        v.choice("start", self.start, STARTS)
        for name in ("damping", "convergence_tol_m"):
            object.__setattr__(self, name, v.positive(name, getattr(self, name)))

    @classmethod
    def from_dict(cls, d: dict, section: str = "localization") -> WLSOptions:
        """Build from a recipe table; unknown keys are errors naming the closest valid key."""
        return from_table(cls, d, section)


def _wls_terms(net: StaticNetwork, link_mode: str, w_matrix, s2):
    """Unique measurement terms ``(row j, col i, z_ji, w_ji)`` with at least one agent."""
    seen, rows, cols = set(), [], []
    for j in net.agents:
        for i, _ in net.links(int(j), "own"):
            seen.add((int(j), i))
        if link_mode == "both":
            for i in np.flatnonzero(np.isfinite(net.ranges[:, j])):
                seen.add((int(i), int(j)))
    for r, c in sorted(seen):
        rows.append(r)
        cols.append(c)
    rows, cols = np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64)
    z = net.ranges[rows, cols] if rows.size else np.zeros(0)
    w = np.full(rows.size, 1.0 / s2) if w_matrix is None else w_matrix[rows, cols]
    return rows, cols, z, w


def wls_cost(positions, rows, cols, z, w, b) -> float:
    """``F = Σ_t w_t (z_t − b − ‖x_{rows_t} − x_{cols_t}‖)²`` for node positions ``[N, 2]``."""
    d = np.linalg.norm(positions[rows] - positions[cols], axis=1)
    return float(np.sum(w * (z - b - d) ** 2))


def _residual_jacobian(pos, rows, cols, z, w, b, col_of, n_par):
    diff = pos[rows] - pos[cols]
    d = np.linalg.norm(diff, axis=1)
    sw = np.sqrt(w)
    r = sw * (z - b - d)
    u = np.where(d[:, None] > _EPS_D, diff / np.maximum(d, _EPS_D)[:, None], 0.0)
    J = np.zeros((rows.size, n_par))
    for ends, sign in ((rows, -1.0), (cols, 1.0)):
        c = col_of[ends]
        m = c >= 0
        t = np.flatnonzero(m)
        J[t, 2 * c[m]] = sign * sw[m] * u[m, 0]
        J[t, 2 * c[m] + 1] = sign * sw[m] * u[m, 1]
    return r, J


def _lm_step(pos, agent_nodes, rows, cols, z, w, b, col_of, lam, region, max_tries=20):
    """One accepted Levenberg–Marquardt step over the agents ``agent_nodes`` (in ``col_of``
    order); returns the new positions and damping."""
    n_par = 2 * agent_nodes.size
    r, J = _residual_jacobian(pos, rows, cols, z, w, b, col_of, n_par)
    f0 = float(r @ r)
    A = J.T @ J
    g = J.T @ r
    dA = np.diag(A).copy()
    for _ in range(max_tries):
        H = A + np.diag(lam * dA + 1e-12)
        step = np.linalg.solve(H, g)  # r ≈ r0 + J δ, minimise ‖r‖²: δ = −(JᵀJ)⁻¹Jᵀr
        trial = pos.copy()
        trial[agent_nodes] = _clip(pos[agent_nodes] - step.reshape(-1, 2), region)
        if wls_cost(trial, rows, cols, z, w, b) <= f0:
            return trial, max(lam / 3.0, 1e-12)
        lam *= 4.0
    return pos, lam


def run_wls(
    measurements: StaticMeasurements,
    prior: StaticPrior,
    rng: np.random.Generator | None = None,
    options: WLSOptions | None = None,
    *,
    link_weights=None,
) -> Result:
    """Weighted least-squares localization by damped Gauss–Newton ('WLS' of POA-NBP ref. [5]).

    Parameters
    ----------
    measurements : StaticMeasurements
        Its error model gives ``b`` and the default weights ``1/s²``.
    prior : StaticPrior
        ``region`` (iterates are clipped to it) and optional ``initial`` ``[n_agents, 2]``
        (else ``options.start``).
    rng : numpy.random.Generator or None
        Unused (the method is deterministic); part of the common call shape.
    options : WLSOptions, optional
    link_weights : [N, N] float64, optional
        ``w_ji`` per range entry (>= 0), overriding ``1/s²``.

    Returns
    -------
    Result
        ``estimates [n_iterations, n_agents, 2]`` (the iterate after each iteration, the start
        not included), no covariances; ``timing`` (joint mode: the joint time of an iteration
        divided by the number of agents is each agent's time); ``diagnostics`` as
        :func:`run_gaussian_bp`, except ``floats_per_link_iteration``: NaN in ``"joint"`` mode
        (centralized: the nodes exchange no messages; reported as NaN, not 0, so that it is
        never averaged with the distributed methods), 2 in ``"distributed"`` mode (the
        estimate an agent sends a neighbour per iteration). Label ``"wls.joint"`` /
        ``"wls.distributed"``.

    Examples
    --------
    >>> anchors = np.array([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0], [20.0, 20.0]])
    >>> z = np.full((5, 5), np.nan)  # node 4, an agent, measured its ranges to the anchors
    >>> z[4, :4] = [13.2, 17.2, 11.6, 16.0]
    >>> meas, prior = StaticMeasurements(z, [0, 1, 2, 3], anchors), StaticPrior((0, 0, 20, 20))
    >>> run_wls(meas, prior).estimates[-1].round(1).tolist()  # the agent is at (7, 11)
    [[7.0, 11.0]]
    """
    t_wall = time.perf_counter()
    opt = options if options is not None else WLSOptions()
    if not isinstance(opt, WLSOptions):
        raise ValidationError("options", type(opt).__name__, "must be WLSOptions")
    meas, prior = check_inputs(measurements, prior, need_rng=False)
    net, reg = meas.network, prior.region
    b, s2 = _moments(meas.error_model, opt.debias)
    n = net.ranges.shape[0]
    W = None
    if link_weights is not None:
        W = np.nan_to_num(np.asarray(link_weights, dtype=np.float64), nan=0.0)
        if W.shape != (n, n) or np.any(~np.isfinite(W)) or np.any(W < 0):
            raise ValidationError(
                "link_weights", f"array of shape {W.shape}", f"must be ({n}, {n}), finite, >= 0"
            )
    x0, setup_s, start = _start(meas, prior, opt.start, opt.link_mode)
    n_ag = net.n_agents
    pos = net.positions.copy()
    pos[net.agents] = x0
    rows, cols, z, w = _wls_terms(net, opt.link_mode, W, s2)

    L = opt.n_iterations
    out, out_t = np.empty((L, n_ag, 2)), np.zeros((L, n_ag))
    step_t = np.zeros(L)
    n_done = L
    if opt.mode == "joint":
        col_of = np.full(n, -1)
        col_of[net.agents] = np.arange(n_ag)
        lam = opt.damping
    else:
        term_sets = []
        for j in net.agents:
            sel = (rows == j) | (cols == j)
            col_of = np.full(n, -1)
            col_of[j] = 0
            term_sets.append((sel, col_of))
        lams = np.full(n_ag, opt.damping)
    for it in range(L):
        t_it = time.perf_counter()
        if opt.mode == "joint":
            t0 = time.perf_counter()
            if rows.size and n_ag:
                pos, lam = _lm_step(pos, net.agents, rows, cols, z, w, b, col_of, lam, reg)
            out_t[it] = (time.perf_counter() - t0) / max(n_ag, 1)
        else:
            new = pos.copy()
            for a, j in enumerate(net.agents):
                t0 = time.perf_counter()
                sel, col_of = term_sets[a]
                if sel.any():
                    p = pos.copy()
                    for _ in range(opt.n_inner):
                        p, lams[a] = _lm_step(
                            p,
                            net.agents[a : a + 1],
                            rows[sel],
                            cols[sel],
                            z[sel],
                            w[sel],
                            b,
                            col_of,
                            lams[a],
                            reg,
                        )
                    new[j] = p[j]
                out_t[it, a] = time.perf_counter() - t0
            pos = new
        out[it] = pos[net.agents]
        step_t[it] = time.perf_counter() - t_it
        if opt.stop_on_convergence and convergence_iteration(out[: it + 1], opt.convergence_tol_m):
            n_done = it + 1
            break
    return Result(
        estimates=out[:n_done],
        covariances=None,
        timing=_timing(t_wall, step_t[:n_done], out_t[:n_done]),
        diagnostics={
            "agent_time_s": out_t[:n_done],
            "converged_iteration": convergence_iteration(out[:n_done], opt.convergence_tol_m),
            "start": start,
            "setup_time_per_node_s": setup_s,
            # joint: centralized, no messages between nodes (NaN); distributed: the estimate
            "floats_per_link_iteration": math.nan if opt.mode == "joint" else 2.0,
        },
        label=f"wls.{opt.mode}",
    )

"""Searches for the mobile anchors' next controls: exact tree, V-best sequences, per anchor.

A *problem* (:class:`ControlProblem`) holds what the controller knows at time ``k``: the
agents' Gaussian beliefs, the motion model, the anchors' positions and the control set U. A
joint control moves every mobile anchor ``j`` by ``T_Δ u_j`` [2]. Over a horizon of ``T`` steps
the cost of a control sequence is ``Σ_t γ^{t−1} C_t`` [12]–[16], ``C_t`` the FIM cost of
:mod:`phyloc.control.fim` with the covariances carried along the sequence (information-filter
updates, predicted means). Only the first control is applied (receding horizon); ``T = 1`` is
the myopic policy [11].

Searches (``|J| = |U|^{M₁}`` joint controls per step):

``exact``            the whole tree, ``|J|^T`` leaves, level by level (each level's covariances
                     are computed once for all the leaves below it): the optimum.
``vbest``            keep the ``V`` best partial sequences by their cost so far at each level
                     (``V·|J|`` nodes per level); ``V >= |J|^{T−1}`` is the exact search.
``approx``           one anchor at a time: anchor ``j``'s sequence is built greedily in time
                     (at step ``t`` the best of ``|U|`` given steps ``< t``), the anchors before
                     it following their chosen sequences, the ones after it holding still;
                     ``O(M₁·|U|·T)`` cost evaluations.
``approx_parallel``  the same with every anchor optimized while all others hold still.

Ties are broken by the lowest index (controls in the order of U, anchor 0 slowest), so a
search is deterministic.

References
----------
FIM: W. Zhang, B. Teague and F. Meyer, "Cooperative localization: a Fisher information
approach," arXiv:2212.14554, 2022.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.control._kernels import (
    SERIAL_BELOW,
    level_kernel,
    level_serial_kernel,
    predict_kernel,
    predict_serial_kernel,
)
from phyloc.control.fim import information_at
from phyloc.errors import ValidationError

SEARCHES = ("exact", "vbest", "approx", "approx_parallel")
#: The exact search refuses trees with more leaves than this (use ``vbest`` or ``approx``).
MAX_LEAVES = 2_000_000


@dataclass(frozen=True, eq=False)
class ControlProblem:
    """What the controller knows at one time step.

    Parameters
    ----------
    mean : [n_agents, N_D]
        The agents' current belief means (position first).
    cov : [n_agents, N_D, N_D]
        Their covariances.
    F, Q : [N_D, N_D]
        Motion model (:meth:`~phyloc.localization.tracking.RangeModel.matrices`).
    mobile : [M₁, dim]
        Current positions of the mobile anchors.
    static : [M₀, dim]
        Positions of the static anchors.
    controls : ``[|U|, dim]``
        The control set U [m/s] (:func:`~phyloc.control.fim.control_set`).
    dt_s : float
        T_Δ [s].
    sigma_r : float
        Range standard deviation σ [m].
    comm_range_m : float, optional
        Ranges only within this distance (None: all).
    agent_terms : bool
        Include agent–agent ranges in the FIM (beyond the paper).
    """

    mean: np.ndarray
    cov: np.ndarray
    F: np.ndarray
    Q: np.ndarray
    mobile: np.ndarray
    static: np.ndarray
    controls: np.ndarray
    dt_s: float
    sigma_r: float
    comm_range_m: float | None = None
    agent_terms: bool = False

    @property
    def dim(self) -> int:
        """Spatial dimension."""
        return self.mobile.shape[1] if self.mobile.size else self.static.shape[1]

    def predicted_means(self, horizon: int) -> np.ndarray:
        """Predicted mean positions ``[T, n_agents, dim]`` (independent of the controls)."""
        x = self.mean
        out = []
        for _ in range(horizon):
            x = x @ self.F.T
            out.append(x[:, : self.dim])
        return np.stack(out)

    def static_information(self, means: np.ndarray) -> np.ndarray:
        """Information from the static anchors (and agents) ``[T, n_agents, dim, dim]``."""
        out = []
        for mu in means:
            A = information_at(mu, self.static, self.sigma_r, self.comm_range_m, self.agent_terms)
            out.append(A)
        return np.stack(out)

    def level(self, covs, positions, t, means, static_info, *, reps=1, want_covs=True):
        """Advance nodes one step: predict ``covs [N', n_agents, N_D, N_D]``, add the range
        information at the mobile anchors' ``positions [N, M₁, dim]`` (node ``c`` a child of
        ``covs[c // reps]``, ``N = N'·reps``); returns the updated covariances (None without
        ``want_covs``: the last level of a search needs the cost alone) and the step's cost
        ``C_t [N]``."""
        covs = np.ascontiguousarray(covs, dtype=np.float64)
        positions = np.ascontiguousarray(positions, dtype=np.float64)
        reps = int(reps)
        if positions.shape[0] != covs.shape[0] * reps:
            raise ValidationError(
                "positions", f"{positions.shape[0]} nodes", f"{covs.shape[0]} parents x {reps}"
            )
        predicted = np.empty_like(covs)
        predict = predict_serial_kernel if covs.shape[0] < SERIAL_BELOW else predict_kernel
        predict(
            covs,
            np.ascontiguousarray(self.F, dtype=np.float64),
            np.ascontiguousarray(self.Q, dtype=np.float64),
            predicted,
        )
        n = positions.shape[0]
        out = np.empty((n, *covs.shape[1:])) if want_covs else np.empty((1,) * covs.ndim)
        cost = np.empty(n)
        kernel = level_serial_kernel if n < SERIAL_BELOW else level_kernel
        kernel(
            predicted,
            reps,
            np.ascontiguousarray(means[t], dtype=np.float64),
            positions,
            np.ascontiguousarray(static_info[t], dtype=np.float64),
            1.0 / (self.sigma_r * self.sigma_r),
            self.comm_range_m or 0.0,
            bool(want_covs),
            out,
            cost,
        )
        return (out if want_covs else None), cost


def joint_controls(controls: np.ndarray, n_mobile: int) -> np.ndarray:
    """All joint controls ``[|U|^{M₁}, M₁, dim]`` (anchor 0 slowest)."""
    idx = np.indices((controls.shape[0],) * n_mobile).reshape(n_mobile, -1).T
    return controls[idx]


def _check(problem, horizon, discount):
    if not isinstance(problem, ControlProblem):
        raise ValidationError("problem", type(problem).__name__, "must be a ControlProblem")
    T = v.integer("horizon", horizon, minimum=1)
    g = v.positive("discount", discount)
    return T, g


def search(
    problem: ControlProblem,
    horizon: int = 1,
    *,
    method: str = "exact",
    discount: float = 0.9,
    beam: int = 10,
):
    """Best first joint control over ``horizon`` steps by the search ``method``.

    Parameters
    ----------
    problem : ControlProblem
    horizon : int
        T (1: myopic, FIM [11]).
    method : {"exact", "vbest", "approx", "approx_parallel"}
    discount : float
        γ of FIM [12] (0.9).
    beam : int
        V of the ``vbest`` search.

    Returns
    -------
    u : [M₁, dim] float64
        The first control of the best sequence found [m/s].
    cost : float
        That sequence's discounted cost ``Σ_t γ^{t−1} C_t``.

    Examples
    --------
    One agent at the origin with an isotropic prior, one static anchor on the x axis, one
    mobile anchor on the y axis that may move along ±x or ±y: every move keeps a range
    direction orthogonal to the static one, up to the small turn of ``±x``, so ``±y`` win.

    >>> U = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    >>> p = ControlProblem(np.zeros((1, 2)), np.eye(2)[None], np.eye(2), np.zeros((2, 2)),
    ...                    np.array([[0.0, 5.0]]), np.array([[5.0, 0.0]]), U, 1.0, 1.0)
    >>> u, cost = search(p)
    >>> u.tolist(), round(cost, 6)
    ([[0.0, 1.0]], 1.0)
    """
    T, g = _check(problem, horizon, discount)
    v.choice("method", method, SEARCHES)
    if problem.mobile.shape[0] == 0:
        return np.zeros((0, problem.dim)), _sequence_cost(problem, np.zeros((T, 0, problem.dim)), g)
    if method in ("exact", "vbest"):
        keep = None if method == "exact" else v.integer("beam", beam, minimum=1)
        return _tree(problem, T, g, keep)
    return _per_anchor(problem, T, g, parallel=method == "approx_parallel")


def _tree(problem, T, g, keep):
    J = joint_controls(problem.controls, problem.mobile.shape[0])  # [|J|, M1, dim]
    nJ = J.shape[0]
    if keep is None and nJ**T > MAX_LEAVES:
        raise ValidationError(
            "search",
            f"exact over {nJ}^{T} = {nJ**T:.3g} sequences",
            f"at most {MAX_LEAVES} leaves: use search = 'vbest' or 'approx', or a shorter horizon",
        )
    means = problem.predicted_means(T)
    sinfo = problem.static_information(means)
    covs = problem.cov[None]
    pos = problem.mobile[None]
    total = np.zeros(1)
    first = np.zeros(1, dtype=np.int64)
    for t in range(T):
        n = covs.shape[0]
        pos = (pos[:, None] + problem.dt_s * J[None]).reshape(n * nJ, *problem.mobile.shape)
        covs, cost = problem.level(covs, pos, t, means, sinfo, reps=nJ, want_covs=t < T - 1)
        total = np.repeat(total, nJ) + g**t * cost
        first = np.repeat(first, nJ) if t else np.arange(nJ)
        if keep is not None and total.size > keep and t < T - 1:
            best = np.argsort(total, kind="stable")[:keep]
            covs, pos, total, first = covs[best], pos[best], total[best], first[best]
    b = int(np.argmin(total))
    return J[first[b]].copy(), float(total[b])


def _sequence_cost(problem, seq, g):
    """Discounted cost of one joint sequence ``seq [T, M₁, dim]`` of controls."""
    T = seq.shape[0]
    means = problem.predicted_means(T)
    sinfo = problem.static_information(means)
    covs = problem.cov[None]
    pos = problem.mobile[None]
    total = 0.0
    for t in range(T):
        pos = pos + problem.dt_s * seq[t][None]
        covs, cost = problem.level(covs, pos, t, means, sinfo, want_covs=t < T - 1)
        total += g**t * float(cost[0])
    return total


def _per_anchor(problem, T, g, *, parallel):
    U = problem.controls
    M1, dim = problem.mobile.shape
    means = problem.predicted_means(T)
    sinfo = problem.static_information(means)
    chosen = np.zeros((T, M1, dim))  # holding still until an anchor is optimized
    base = chosen.copy()
    for j in range(M1):
        seq = (base if parallel else chosen).copy()
        covs = problem.cov[None]
        pos = problem.mobile[None]
        for t in range(T):
            cand = np.repeat(seq[t][None], U.shape[0], axis=0)
            cand[:, j] = U
            trial_pos = pos + problem.dt_s * cand  # [|U|, M1, dim]
            new_covs, cost = problem.level(
                covs, trial_pos, t, means, sinfo, reps=U.shape[0], want_covs=t < T - 1
            )
            b = int(np.argmin(cost))
            seq[t, j] = U[b]
            pos = trial_pos[b : b + 1]
            if new_covs is not None:
                covs = new_covs[b : b + 1]
        chosen[:, j] = seq[:, j]
    return chosen[0].copy(), _sequence_cost(problem, chosen, g)

"""Posterior Cramér–Rao lower bound (PCRLB) of the joint agent state, Tichavský recursion.

For the linear-Gaussian motion ``x^{(k)} = F̃ x^{(k−1)} + w``, ``w ~ N(0, W)`` (PF-BP
eqs. (45)–(48), ``F̃ = I ⊗ F``, ``W = I ⊗ Q``) and range measurements (PF-BP eq. (8)), the
posterior Fisher information of the joint state obeys (Tichavský, Muravchik, Nehorai 1998)

.. math::

    J^{(k)} = D_{22} − D_{21} (J^{(k−1)} + D_{11})^{-1} D_{12}
            = (F̃ J^{(k−1)\\,-1} F̃ᵀ + W)^{-1} + \\mathbb{E}[J_z^{(k)}],

the second form (matrix inversion lemma) being valid for the singular ``W`` of the CV/CA
models. ``J^{(0)}`` is the prior information ``diag(P_i^{(0)})^{-1}`` and the range information at
the true positions is ``J_z = Σ_{(i,j)} u_ij u_ijᵀ / σ²`` on the position blocks (``u_ij`` the
unit vector from ``p_j`` to ``p_i``; for an agent–agent range also ``−u uᵀ/σ²`` on the cross
blocks and ``+u uᵀ/σ²`` on ``j``'s block). The expectation over true trajectories (and the
connectivity they imply) is a Monte Carlo average over scenarios. The bound on the RMSE of
position (velocity, acceleration) at time ``k`` is ``sqrt(tr(C_pos)/|C|)`` with
``C = (J^{(k)})^{-1}`` — comparable to the RMSE of
:func:`~phyloc.evaluation.range_scenarios.state_errors`.

Two ways to average over trajectories are offered (``average=``):

* ``"information"`` (default) — the Bayesian PCRLB proper: the measurement information is
  averaged, ``J^{(k)}`` uses ``E[J_z^{(k)}]``, and the bound is ``(J^{(k)})^{-1}``. It bounds the
  MSE averaged over trajectories.
* ``"bound"`` — the *conditional* (per-trajectory) bound: the recursion runs on each
  trajectory's own ``J_z^{(k)}`` and the resulting covariances are averaged. By Jensen's
  inequality (the inverse is matrix-convex) it is never below the Bayesian bound; the gap is
  large when connectivity varies between trajectories (e.g. ``r_max = 18`` m), because an
  average of informations hides the poorly connected trajectories that dominate the MSE. It is
  the benchmark most tracking studies plot, and it is the one a filter can actually approach
  on a given set of trajectories; it is not a strict Bayesian bound.

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."

P. Tichavský, C. H. Muravchik and A. Nehorai, "Posterior Cramér–Rao bounds for discrete-time
nonlinear filtering," IEEE Trans. Signal Processing 46(5), pp. 1386–1396, 1998.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag

from phyloc import _validate as v
from phyloc.errors import ValidationError


@dataclass(frozen=True, eq=False)
class PCRLBResult:
    """Bounds per time step.

    Attributes
    ----------
    cov : [K, N, N] float64
        ``(J^{(k)})^{-1}`` of the joint state (``N = |C|·N_D``).
    bounds : dict of str -> [K] float64
        ``"p"`` [m], ``"v"`` [m/s], ``"a"`` [m/s²] (those the model has): RMSE bounds.
    per_scenario : dict of str -> [n_scenarios, K] float64, or None
        With ``average="bound"``: each scenario's own mean-square bound (its agents' bound
        variances summed over the axes, averaged over the agents), keyed as ``bounds``;
        ``bounds[b]`` is the square root of their mean over scenarios. None with
        ``average="information"``, whose bound is not an average of per-scenario bounds.
    """

    cov: np.ndarray
    bounds: dict
    per_scenario: dict | None = None


def _inv_sym(A):
    out = np.linalg.inv(A)
    return 0.5 * (out + out.T)


def pcrlb_recursion(J0: np.ndarray, F: np.ndarray, Q: np.ndarray, Jz) -> np.ndarray:
    """Run the information recursion ``J_k = (F J_{k−1}^{-1} Fᵀ + Q)^{-1} + Jz_k``.

    Parameters
    ----------
    J0 : [N, N] float64
        Prior information (positive definite).
    F, Q : [N, N] float64
        Joint transition and process noise covariance (Q may be singular).
    Jz : [K, N, N] float64
        Expected measurement information per time step.

    Returns
    -------
    cov : [K, N, N] float64
        ``J_k^{-1}``: for a linear-Gaussian model, the Kalman filter covariance.
    """
    J = v.finite_array("J0", J0, ndim=2)
    F = v.finite_array("F", F, ndim=2)
    Q = v.finite_array("Q", Q, ndim=2)
    Jz = v.finite_array("Jz", Jz, ndim=3)
    N = J.shape[0]
    if J.shape != (N, N) or F.shape != (N, N) or Q.shape != (N, N) or Jz.shape[1:] != (N, N):
        raise ValidationError("J0/F/Q/Jz", "shapes", f"must all be ({N}, {N}) per step")
    out = np.empty_like(Jz)
    C = _inv_sym(J)
    for k in range(Jz.shape[0]):
        J = _inv_sym(F @ C @ F.T + Q) + Jz[k]
        C = _inv_sym(J)
        out[k] = C
    return out


def range_information(positions, anchors, measured, sigma_r: float, state_dim: int) -> np.ndarray:
    """Fisher information of one time step's ranges about the joint state.

    Parameters
    ----------
    positions : [n_agents, dim] float64
        True agent positions [m].
    anchors : [n_anchors, dim] float64
    measured : [n_agents, n_agents + n_anchors] bool
        ``measured[i, j]``: agent ``i`` has a range to node ``j`` (each one counts once; a
        pair measured both ways counts twice).
    sigma_r : float
        σ [m].
    state_dim : int
        N_D; the position is the first ``dim`` components of each agent's block.

    Returns
    -------
    J : [n_agents·N_D, n_agents·N_D] float64
    """
    p = np.asarray(positions, dtype=np.float64)
    n_ag, dim = p.shape
    nodes = np.concatenate([p, np.asarray(anchors, dtype=np.float64).reshape(-1, dim)])
    J = np.zeros((n_ag * state_dim, n_ag * state_dim))
    inv_var = 1.0 / sigma_r**2
    for i, j in zip(*np.nonzero(measured), strict=True):
        diff = p[i] - nodes[j]
        d = np.linalg.norm(diff)
        if d <= 0.0:
            continue
        u = diff / d
        info = np.outer(u, u) * inv_var
        si = slice(i * state_dim, i * state_dim + dim)
        J[si, si] += info
        if j < n_ag:
            sj = slice(j * state_dim, j * state_dim + dim)
            J[sj, sj] += info
            J[si, sj] -= info
            J[sj, si] -= info
    return J


def one_range_per_pair(measured: np.ndarray) -> np.ndarray:
    """``measured [n_agents, n_agents + n_anchors]`` with each agent pair kept once: the range
    of ``(i, j)``, ``i < j``, if either agent measured it, and never that of ``(j, i)``."""
    m = np.array(measured, dtype=bool)
    n = m.shape[0]
    ag = m[:, :n]
    m[:, :n] = np.triu(ag | ag.T, k=1)
    return m


def pcrlb(
    scenarios, prior_cov: np.ndarray, *, average: str = "information", pairs: str = "both"
) -> PCRLBResult:
    """PCRLB of range-level cooperative tracking, Monte Carlo over scenarios.

    Parameters
    ----------
    scenarios : sequence of objects with ``model``, ``anchors``, ``states``, ``z``
        Independent realizations of one setting (same model, number of agents and steps), e.g.
        :class:`~phyloc.evaluation.range_scenarios.RangeScenario`: ``model`` (with ``dim``,
        ``order``, ``state_dim``, ``sigma_r``, ``matrices()``), true ``states [K, n_agents,
        N_D]``, ``anchors [n_anchors, dim]`` and ranges ``z [K, n_agents, n_nodes]`` whose
        finite entries mark the measured pairs (their values do not enter the bound).
    prior_cov : [n_agents, N_D, N_D] float64
        ``P_i^{(0)}`` (PF-BP eq. (31)).
    average : {"information", "bound"}
        Average the measurement information over scenarios (the Bayesian PCRLB, default) or
        the per-scenario bounds (the conditional bound); see the module docstring.
    pairs : {"both", "one"}
        ``"both"`` counts every measured range (a pair measured both ways twice: the
        information of a centralized estimator, PF-BP eq. (18)); ``"one"`` keeps one range per
        agent pair (:func:`one_range_per_pair`): the information of a pair as PF-BP's
        distributed factor of eq. (17) sees it at one agent. Neither bounds the distributed
        filter itself, which uses each range at one agent only; ``"one"`` shows how much of a
        gap to the ``"both"`` bound is information that filter does not combine.

    Returns
    -------
    PCRLBResult
    """
    scenarios = list(scenarios)
    if not scenarios:
        raise ValidationError("scenarios", "[]", "needs at least one scenario")
    s0 = scenarios[0]
    model, n_ag, K = s0.model, s0.n_agents, s0.n_steps
    nd, dim = model.state_dim, model.dim
    for s in scenarios:
        if s.model != model or s.n_agents != n_ag or s.n_steps != K:
            raise ValidationError("scenarios", "mixed", "must share model, agents and steps")
    P0 = v.finite_array("prior_cov", prior_cov, ndim=3)
    if P0.shape != (n_ag, nd, nd):
        raise ValidationError("prior_cov", f"shape {P0.shape}", f"must be ({n_ag}, {nd}, {nd})")
    if average not in ("information", "bound"):
        raise ValidationError("average", average, "must be 'information' or 'bound'")
    if pairs not in ("both", "one"):
        raise ValidationError("pairs", pairs, "must be 'both' or 'one'")
    mask = one_range_per_pair if pairs == "one" else (lambda m: m)

    def information(sc):
        return np.stack(
            [
                range_information(
                    sc.states[k, :, :dim],
                    sc.anchors,
                    mask(np.isfinite(sc.z[k])),
                    model.sigma_r,
                    nd,
                )
                for k in range(K)
            ]
        )

    F, Q = model.matrices()
    eye = np.eye(n_ag)
    J0, Fj, Qj = _inv_sym(block_diag(*P0)), np.kron(eye, F), np.kron(eye, Q)
    names = "pva"[: model.order]

    def mean_square(c):  # [K, N, N] -> per block [K]: variances summed, averaged over agents
        diag = np.diagonal(c, axis1=-2, axis2=-1).reshape(K, n_ag, model.order, dim)
        return {name: diag[:, :, b].sum(axis=(1, 2)) / n_ag for b, name in enumerate(names)}

    per = None
    if average == "information":
        Jz = sum(information(sc) for sc in scenarios) / len(scenarios)
        cov = pcrlb_recursion(J0, Fj, Qj, Jz)
    else:
        cov, ms = 0.0, []
        for sc in scenarios:
            c = pcrlb_recursion(J0, Fj, Qj, information(sc))
            cov = cov + c
            ms.append(mean_square(c))
        cov /= len(scenarios)
        per = {name: np.stack([m[name] for m in ms]) for name in names}
    bounds = {name: np.sqrt(x) for name, x in mean_square(cov).items()}
    return PCRLBResult(cov=cov, bounds=bounds, per_scenario=per)

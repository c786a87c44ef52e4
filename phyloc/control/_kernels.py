"""Numba kernels of the control searches: one horizon level for many tree nodes.

:func:`predict_kernel` and :func:`level_kernel` are the loop body of
:meth:`phyloc.control.search.ControlProblem.level`. For node ``c`` and agent ``i`` the first
predicts the covariance ``P⁻ = F P Fᵀ + Q`` (FIM [1]), once per parent node: the children of a
tree node share it. The second adds the range information of the mobile anchors at the node's
positions to the static part, ``A = A_static + σ⁻² Σ_j q_j q_jᵀ`` (FIM [7]–[9]), and updates
``P = P⁻ − B (I + A S)⁻¹ A Bᵀ`` (``B = P⁻ Hᵀ``, ``S = H P⁻ Hᵀ``; Woodbury's form of
``(P⁻⁻¹ + HᵀAH)⁻¹``), summing the position traces (FIM [10]) per node; at a search's last
level it computes the traces alone. Their NumPy twin is ``level_numpy`` in
``tests/naive_control.py`` (the vectorized form of :func:`phyloc.control.fim.update_covariance`).

References
----------
FIM: W. Zhang, B. Teague and F. Meyer, "Cooperative localization: a Fisher information
approach," arXiv:2212.14554, 2022.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from phyloc._jit import by_threads

#: Below this distance a node has no direction and adds no information [m].
COINCIDENT_M = 1e-9


@njit(cache=True)
def _solve_small(M, A, X):
    """``X = M⁻¹ A`` for a small square ``M`` (Gauss–Jordan with partial pivoting)."""
    d = M.shape[0]
    W = np.empty((d, 2 * d))
    for r in range(d):
        for c in range(d):
            W[r, c] = M[r, c]
            W[r, d + c] = A[r, c]
    for c in range(d):
        p = c
        for r in range(c + 1, d):
            if abs(W[r, c]) > abs(W[p, c]):
                p = r
        if p != c:
            for k in range(2 * d):
                t = W[c, k]
                W[c, k] = W[p, k]
                W[p, k] = t
        piv = W[c, c]
        for k in range(2 * d):
            W[c, k] /= piv
        for r in range(d):
            if r != c:
                f = W[r, c]
                if f != 0.0:
                    for k in range(2 * d):
                        W[r, k] -= f * W[c, k]
    for r in range(d):
        for c in range(d):
            X[r, c] = W[r, d + c]


@by_threads
@njit(cache=True, parallel=True)
def predict_kernel(covs, F, Q, out):
    """``out[c, i] = F covs[c, i] Fᵀ + Q`` for every node ``c`` and agent ``i`` (FIM [1];
    parallel over nodes). A tree level's children share their parent's prediction, so it is
    computed once per parent (:func:`level_kernel` takes it by parent)."""
    N, n_ag, nd, _ = covs.shape
    for c in prange(N):
        FP = np.empty((nd, nd))
        for i in range(n_ag):
            P = covs[c, i]
            for r in range(nd):
                for k in range(nd):
                    s = 0.0
                    for m in range(nd):
                        s += F[r, m] * P[m, k]
                    FP[r, k] = s
            for r in range(nd):
                for k in range(nd):
                    s = Q[r, k]
                    for m in range(nd):
                        s += FP[r, m] * F[k, m]
                    out[c, i, r, k] = s


@by_threads
@njit(cache=True, parallel=True)
def level_kernel(
    predicted, reps, means, positions, static_info, inv_var, comm_range, want_covs, out_covs,
    out_cost,
):  # fmt: skip
    """One horizon level for every node (parallel over nodes).

    Parameters
    ----------
    predicted : [N / reps, n_agents, N_D, N_D]
        Predicted covariances ``P⁻`` of the parents (:func:`predict_kernel`); node ``c`` is a
        child of parent ``c // reps``.
    reps : int
        Children per parent.
    means : [n_agents, dim]
        Predicted mean positions at this level.
    positions : [N, M₁, dim]
        Mobile anchors' positions at this level.
    static_info : [n_agents, dim, dim]
        Information of the static anchors (and agents) at this level.
    inv_var : float
        σ⁻².
    comm_range : float
        Ranges only within this distance; <= 0: every pair.
    want_covs : bool
        Write ``out_covs``; without, only the position block's diagonal is computed (the last
        level of a search needs the cost alone), with the same arithmetic, so the same cost.
    out_covs : [N, n_agents, N_D, N_D]
        Updated covariances (written when ``want_covs``).
    out_cost : [N]
        ``Σ_i tr(P_i[:dim, :dim])`` (written).
    """
    N = positions.shape[0]
    n_ag, nd = predicted.shape[1], predicted.shape[2]
    dim = means.shape[1]
    M1 = positions.shape[1]
    rows = nd if want_covs else dim
    for c in prange(N):
        A = np.empty((dim, dim))
        Mm = np.empty((dim, dim))
        X = np.empty((dim, dim))
        BX = np.empty((nd, dim))
        q = np.empty(dim)
        total = 0.0
        for i in range(n_ag):
            Pp = predicted[c // reps, i]
            for r in range(dim):
                for k in range(dim):
                    A[r, k] = static_info[i, r, k]
            for j in range(M1):
                dd = 0.0
                for r in range(dim):
                    q[r] = means[i, r] - positions[c, j, r]
                    dd += q[r] * q[r]
                dist = np.sqrt(dd)
                if dist <= COINCIDENT_M or (comm_range > 0.0 and dist > comm_range):
                    continue
                for r in range(dim):
                    for k in range(dim):
                        A[r, k] += inv_var * q[r] * q[k] / dd
            for r in range(dim):  # M = I + A S
                for k in range(dim):
                    s = 1.0 if r == k else 0.0
                    for m in range(dim):
                        s += A[r, m] * Pp[m, k]
                    Mm[r, k] = s
            _solve_small(Mm, A, X)
            for r in range(rows):  # B X, B = P⁻[:, :dim]
                for k in range(dim):
                    s = 0.0
                    for m in range(dim):
                        s += Pp[r, m] * X[m, k]
                    BX[r, k] = s
            if want_covs:
                for r in range(nd):
                    for k in range(nd):
                        s = 0.0
                        for m in range(dim):
                            s += BX[r, m] * Pp[k, m]
                        out_covs[c, i, r, k] = Pp[r, k] - s
                for r in range(dim):
                    total += out_covs[c, i, r, r]
            else:
                for r in range(dim):
                    s = 0.0
                    for m in range(dim):
                        s += BX[r, m] * Pp[r, m]
                    total += Pp[r, r] - s
        out_cost[c] = total


#: :func:`level_kernel` without threads, for levels of fewer nodes than :data:`SERIAL_BELOW`
#: (the first levels of a tree, a per-anchor search): waking the thread pool costs more than
#: such a level, and on a busy machine a parallel region waits for every thread. The same code,
#: so the same values.
level_serial_kernel = level_kernel.serial_only()
#: :func:`predict_kernel` without threads (fewer parents than :data:`SERIAL_BELOW`).
predict_serial_kernel = predict_kernel.serial_only()
#: Levels of fewer nodes than this run :data:`level_serial_kernel`.
SERIAL_BELOW = 256

"""Plain-NumPy twins and brute-force references of the control layer (test code, not installed).

``level_numpy`` is the twin of :func:`phyloc.control._kernels.level_kernel`; ``brute_force``
enumerates every joint control sequence with an independent, loop-by-loop cost (explicit
inverses of the information matrices, no Woodbury form).
"""

from __future__ import annotations

import itertools

import numpy as np

from phyloc.control.fim import range_information, update_covariance


def level_numpy(covs, F, Q, means, positions, static_info, sigma_r, comm_range_m=None):
    """Twin of ``level_kernel``: returns ``(covs [N, n, N_D, N_D], cost [N])``."""
    P_pred = F @ covs @ F.T + Q
    A = static_info + range_information(means, positions, sigma_r, comm_range_m)
    P_post, trace = update_covariance(P_pred, A, means.shape[-1])
    return P_post, trace.sum(axis=-1)


def sequence_cost(problem, seq, discount):
    """Discounted FIM cost of one joint sequence ``seq [T, M1, dim]`` by explicit inverses:
    ``P_t = (P⁻⁻¹ + Hᵀ A H)⁻¹`` with ``A`` summed node by node."""
    dim = problem.dim
    n_ag, nd = problem.mean.shape
    H = np.zeros((dim, nd))
    H[:, :dim] = np.eye(dim)
    mean = problem.mean.copy()
    covs = problem.cov.copy()
    pos = problem.mobile.copy()
    total = 0.0
    for t in range(seq.shape[0]):
        mean = mean @ problem.F.T
        pos = pos + problem.dt_s * seq[t]
        nodes = np.concatenate([pos, problem.static])
        cost = 0.0
        for i in range(n_ag):
            P_pred = problem.F @ covs[i] @ problem.F.T + problem.Q
            A = np.zeros((dim, dim))
            others = list(nodes)
            if problem.agent_terms:
                others += [mean[k, :dim] for k in range(n_ag) if k != i]
            for a in others:
                d = mean[i, :dim] - a
                r = np.linalg.norm(d)
                if r < 1e-9 or (problem.comm_range_m and r > problem.comm_range_m):
                    continue
                A += np.outer(d, d) / r**2 / problem.sigma_r**2
            covs[i] = np.linalg.inv(np.linalg.inv(P_pred) + H.T @ A @ H)
            cost += np.trace(covs[i][:dim, :dim])
        total += discount**t * cost
    return total


def brute_force(problem, horizon, discount):
    """Best first joint control by enumerating every sequence: ``(u [M1, dim], cost)``."""
    U = problem.controls
    M1 = problem.mobile.shape[0]
    best, best_u = np.inf, None
    for combo in itertools.product(range(U.shape[0]), repeat=M1 * horizon):
        seq = U[np.array(combo)].reshape(horizon, M1, -1)
        c = sequence_cost(problem, seq, discount)
        if c < best - 1e-12:
            best, best_u = c, seq[0]
    return best_u, best

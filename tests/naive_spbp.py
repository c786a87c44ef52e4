"""Slow, obviously correct twin of SP-BP with one agent: a textbook unscented Kalman filter.

Independent of phyloc: the constant-acceleration model is transcribed from PF-BP eqs. (1)–(3)
(``F = [[1, ΔT, ΔT²/2], [0, 1, ΔT], [0, 0, 1]] ⊗ I``, ``G = [ΔT²/2, ΔT, 1]ᵀ ⊗ I``), the
unscented transform is the scaled one of Julier / Wan–van der Merwe with parameters
``(α, β, κ)`` and a centre point, written with explicit loops over sigma points and anchors.
``α = 1, β = 0, κ = 0`` gives the centre weight 0 and weights ``1/(2n)`` on ``x ± √n L_j``.
"""

import math

import numpy as np


def ca_matrices(dim, dt, accel_std):
    """``F``, ``Q = G σ_a² Gᵀ`` of the discrete constant-acceleration model."""
    F1 = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    G1 = np.array([[0.5 * dt * dt], [dt], [1.0]])
    F = np.kron(F1, np.eye(dim))
    G = np.kron(G1, np.eye(dim))
    return F, accel_std**2 * G @ G.T


def sigma_points(x, P, alpha=1.0, beta=0.0, kappa=0.0):
    """Scaled sigma points ``[2n+1, n]`` and mean/covariance weights (centre first)."""
    n = x.size
    lam = alpha * alpha * (n + kappa) - n
    S = np.linalg.cholesky((n + lam) * P)
    pts = [x.copy()]
    for j in range(n):
        pts.append(x + S[:, j])
    for j in range(n):
        pts.append(x - S[:, j])
    wm = [lam / (n + lam)] + [1.0 / (2.0 * (n + lam))] * (2 * n)
    wc = [lam / (n + lam) + 1.0 - alpha * alpha + beta] + [1.0 / (2.0 * (n + lam))] * (2 * n)
    return np.array(pts), np.array(wm), np.array(wc)


def ranges_to_anchors(x, anchors, dim):
    """``h(x)``: distances from the position block of ``x`` to every anchor (loops)."""
    out = np.empty(len(anchors))
    for q, a in enumerate(anchors):
        s = 0.0
        for c in range(dim):
            s += (x[c] - a[c]) ** 2
        out[q] = math.sqrt(s)
    return out


def ukf_update(x, P, z, anchors, sigma_r, dim):
    """One UKF measurement update with range measurements ``z`` to ``anchors``."""
    pts, wm, wc = sigma_points(x, P)
    Z = np.array([ranges_to_anchors(p, anchors, dim) for p in pts])
    z_hat = np.zeros(len(anchors))
    for s in range(len(pts)):
        z_hat += wm[s] * Z[s]
    Pzz = sigma_r**2 * np.eye(len(anchors))
    Pxz = np.zeros((x.size, len(anchors)))
    for s in range(len(pts)):
        dz = Z[s] - z_hat
        dx = pts[s] - x
        Pzz += wc[s] * np.outer(dz, dz)
        Pxz += wc[s] * np.outer(dx, dz)
    K = Pxz @ np.linalg.inv(Pzz)
    return x + K @ (z - z_hat), P - K @ Pzz @ K.T


def ukf_track(x0, P0, z, anchors, dim, dt, accel_std, sigma_r):
    """UKF over ``z [K, n_anchors]`` (NaN: not measured). Returns means and covariances."""
    F, Q = ca_matrices(dim, dt, accel_std)
    x, P = x0.copy(), P0.copy()
    means, covs = [], []
    for zk in z:
        x = F @ x
        P = F @ P @ F.T + Q
        ok = np.isfinite(zk)
        if ok.any():
            x, P = ukf_update(x, P, zk[ok], anchors[ok], sigma_r, dim)
        means.append(x)
        covs.append(P)
    return np.array(means), np.array(covs)

"""Exact Daum–Huang (EDH) particle-flow kernels shared by the EDH filter and PF-BP.

For a Gaussian prior ``N(m₀, P)`` and a measurement linearized at the current flow mean ``x̄``,
``h(x) ≈ H x + e`` with ``e = h(x̄) − H x̄`` and noise covariance ``R``, the exact flow drift is
``ζ(x, λ) = A(λ) x + b(λ)`` (PF-BP eqs. (13), (24), (25), (40), (41)):

.. math::

    A(λ) = −\\tfrac12 P Hᵀ (λ H P Hᵀ + R)^{-1} H, \\qquad
    b(λ) = (I + 2λA)\\,[(I + λA) P Hᵀ R^{-1} (z − e) + A m₀].

Particles and the mean move by Euler steps ``x ← x + Δ_l ζ(x, λ_l)`` (eqs. (21), (42), (43))
over exponentially spaced pseudo-times (``Δ_{l+1} = q Δ_l``, ``Σ Δ_l = 1``, q = 1.2). In PF-BP
only the first ``n_flow`` components (agent ``i``) move; the neighbours' components of the
stacked state β stay at their particles (eq. (21)).

Range kernels: measurement ``q`` is ``‖p_a − p_b‖`` with ``p_a`` the ``dim`` components of the
state at offset ``off_a[q]`` and ``p_b`` those at ``off_b[q]`` or, when ``off_b[q] < 0``, the
anchor ``anchor_pos[q]``. A zero distance gives a zero Jacobian row (no NaN).

Every numba kernel has a NumPy twin (``*_numpy``) it is tested against.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_EPS_D = 1e-9


def lambda_schedule(n_steps: int, ratio: float = 1.2) -> tuple[np.ndarray, np.ndarray]:
    """Exponentially spaced pseudo-time steps (PF-BP §V-C, after Daum et al.).

    Returns ``lambdas [N]`` (the end of each step, ``λ_N = 1``) and ``steps [N]`` (``Δ_l``, with
    ``Δ_l = Δ_1 q^{l−1}`` and ``Σ Δ_l = 1``; ``ratio = 1`` gives uniform steps).
    """
    n = int(n_steps)
    if ratio == 1.0:
        steps = np.full(n, 1.0 / n)
    else:
        steps = ratio ** np.arange(n) * (ratio - 1.0) / (ratio**n - 1.0)
    lambdas = np.cumsum(steps)
    lambdas[-1] = 1.0
    return lambdas, steps


def flow_parameters(P, H, R, z, e, m0, lam):
    """``A(λ)``, ``b(λ)`` of the exact flow (PF-BP eqs. (24), (25) / (40), (41)).

    Parameters
    ----------
    P : [n, n]  prior covariance.
    H : [L, n]  measurement Jacobian at the current mean.
    R : [L, L]  measurement noise covariance.
    z : [L]     measurement.
    e : [L]     linearization offset ``h(x̄) − H x̄``.
    m0 : [n]    prior mean (λ = 0).
    lam : float pseudo-time λ.
    """
    PHt = P @ H.T
    S = lam * (H @ PHt) + R
    A = -0.5 * PHt @ np.linalg.solve(S, H)
    g = PHt @ np.linalg.solve(R, z - e)
    vv = g + lam * (A @ g) + A @ m0
    b = vv + 2.0 * lam * (A @ vv)
    return A, b


def edh_flow(X, mean, P, linearize, z, R, lambdas, steps, n_flow=None):
    """Generic EDH flow (NumPy), linearized at the flowing mean (PF-BP eqs. (42), (43)).

    Parameters
    ----------
    X : [M, n] float64
        Particles at λ = 0; the first ``n_flow`` components are moved (a copy is returned).
    mean : [n] float64
        Mean at λ = 0 (``m₀``), flowed alongside.
    P : [n, n] float64
    linearize : callable
        ``linearize(x̄) -> (H [L, n], h(x̄) [L])``.
    z : [L], R : [L, L]
    lambdas, steps : [N]
        From :func:`lambda_schedule`.
    n_flow : int, optional
        Default ``n``.

    Returns
    -------
    X1 : [M, n], mean1 : [n]
    """
    X = np.array(X, dtype=np.float64)
    xb = np.array(mean, dtype=np.float64)
    m0 = xb.copy()
    nf = X.shape[1] if n_flow is None else n_flow
    for lam, dl in zip(lambdas, steps, strict=True):
        H, h = linearize(xb)
        A, b = flow_parameters(P, H, R, z, h - H @ xb, m0, lam)
        X[:, :nf] += dl * (X @ A[:nf].T + b[:nf])
        xb[:nf] += dl * (A[:nf] @ xb + b[:nf])
    return X, xb


def range_linearization(x, off_a, off_b, anchor_pos, dim):
    """``H [L, n]`` and ``h(x) [L]`` of range measurements at the state ``x [n]`` (NumPy)."""
    L = off_a.size
    H = np.zeros((L, x.size))
    h = np.empty(L)
    for q in range(L):
        pa = x[off_a[q] : off_a[q] + dim]
        pb = x[off_b[q] : off_b[q] + dim] if off_b[q] >= 0 else anchor_pos[q]
        diff = pa - pb
        d = np.sqrt(diff @ diff)
        h[q] = d
        if d > _EPS_D:
            u = diff / d
            H[q, off_a[q] : off_a[q] + dim] += u
            if off_b[q] >= 0:
                H[q, off_b[q] : off_b[q] + dim] -= u
    return H, h


def range_flow_numpy(X, mean, P, off_a, off_b, anchor_pos, z, r_var, dim, n_flow, lambdas, steps):
    """NumPy twin of :func:`range_flow_kernel` (returns new arrays)."""
    return edh_flow(
        X,
        mean,
        P,
        lambda x: range_linearization(x, off_a, off_b, anchor_pos, dim),
        z,
        np.diag(r_var),
        lambdas,
        steps,
        n_flow,
    )


@njit(cache=True)
def range_flow_kernel(X, mean, P, off_a, off_b, anchor_pos, z, r_var, dim, n_flow, lambdas, steps):
    """EDH flow of range measurements, in place on ``X [M, n]`` and ``mean [n]``.

    Linearizes at the flowing mean before every step; moves components ``0 … n_flow−1``.
    """
    M, n = X.shape
    L = z.size
    m0 = mean.copy()
    H = np.zeros((L, n))
    e = np.empty(L)
    S = np.empty((L, L))
    for s in range(lambdas.size):
        lam = lambdas[s]
        dl = steps[s]
        H[:, :] = 0.0
        for q in range(L):
            a = off_a[q]
            b = off_b[q]
            d2 = 0.0
            for c in range(dim):
                pb = mean[b + c] if b >= 0 else anchor_pos[q, c]
                diff = mean[a + c] - pb
                d2 += diff * diff
            d = np.sqrt(d2)
            if d > 1e-9:
                for c in range(dim):
                    pb = mean[b + c] if b >= 0 else anchor_pos[q, c]
                    u = (mean[a + c] - pb) / d
                    H[q, a + c] += u
                    if b >= 0:
                        H[q, b + c] -= u
            hx = 0.0
            for j in range(n):
                hx += H[q, j] * mean[j]
            e[q] = d - hx
        PHt = P @ H.T
        HPHt = H @ PHt
        for i in range(L):
            for j in range(L):
                S[i, j] = lam * HPHt[i, j]
            S[i, i] += r_var[i]
        A = -0.5 * (PHt @ np.linalg.solve(S, H))
        r = np.empty(L)
        for q in range(L):
            r[q] = (z[q] - e[q]) / r_var[q]
        g = PHt @ r
        vv = g + lam * (A @ g) + A @ m0
        bb = vv + 2.0 * lam * (A @ vv)
        Af = np.ascontiguousarray(A[:n_flow])
        tmp = np.empty(n_flow)
        for m in range(M):
            for i in range(n_flow):
                acc = bb[i]
                for j in range(n):
                    acc += Af[i, j] * X[m, j]
                tmp[i] = acc
            for i in range(n_flow):
                X[m, i] += dl * tmp[i]
        for i in range(n_flow):
            acc = bb[i]
            for j in range(n):
                acc += Af[i, j] * mean[j]
            tmp[i] = acc
        for i in range(n_flow):
            mean[i] += dl * tmp[i]


@njit(cache=True)
def paired_range_loglik_kernel(x, y, z, inv_var, out):
    """Accumulate ``out[m] += −½ (z − ‖x_m − y_m‖)² / σ²`` (paired particles, eq. (22)).

    ``x [M, dim]``; ``y [My, dim]`` with ``My == M`` (particle ``m`` of the partner) or
    ``My == 1`` (an anchor).
    """
    M, dim = x.shape
    single = y.shape[0] == 1
    for m in range(M):
        k = 0 if single else m
        d2 = 0.0
        for c in range(dim):
            diff = x[m, c] - y[k, c]
            d2 += diff * diff
        r = z - np.sqrt(d2)
        out[m] += -0.5 * r * r * inv_var


def paired_range_loglik_numpy(x, y, z, inv_var):
    """NumPy twin of :func:`paired_range_loglik_kernel` (returns the increment)."""
    d = np.linalg.norm(x - y, axis=1)
    return -0.5 * (z - d) ** 2 * inv_var


def gaussian_logpdf(X, mean, cov):
    """``log N(x; mean, cov)`` for rows of ``X [M, n]`` (Cholesky; PSD jitter if needed)."""
    n = mean.size
    L = robust_cholesky(cov)
    dev = np.linalg.solve(L, (X - mean).T)
    return -0.5 * np.sum(dev * dev, axis=0) - np.log(np.diag(L)).sum() - 0.5 * n * np.log(2 * np.pi)


def robust_cholesky(P):
    """Lower Cholesky factor of a symmetric PSD matrix, adding jitter when it is singular."""
    P = 0.5 * (P + P.T)
    scale = max(float(np.max(np.abs(np.diag(P)))), 1e-300)
    jitter = 0.0
    for _ in range(12):
        try:
            return np.linalg.cholesky(P + jitter * np.eye(P.shape[0]))
        except np.linalg.LinAlgError:
            jitter = scale * 1e-12 if jitter == 0.0 else jitter * 100.0
    w, V = np.linalg.eigh(P)
    return np.linalg.cholesky((V * np.maximum(w, scale * 1e-10)) @ V.T)


def invertible_flow_log_weights(X0, X1, mean0, cov0, loglik1):
    """Log importance weights of the invertible flow (PF-BP eqs. (22), (44)), unnormalized.

    ``log w = log p(x₁) − log p(x₀) + log f(z | x₁)``. The flow Jacobian is common to all
    particles for the EDH (linearized at the mean), so it cancels on normalization. The prior
    density ``p`` is the Gaussian ``N(mean0, cov0)`` the flow was derived for: the transition
    density ``f(x | x^{(k−1)})`` of eq. (22) is singular for the CV/CA models (``Q`` has rank
    ``dim``), so it cannot be evaluated at the flowed particles.
    """
    return gaussian_logpdf(X1, mean0, cov0) - gaussian_logpdf(X0, mean0, cov0) + loglik1


def ukf_covariance_update(mean, P, off_a, off_b, anchor_pos, r_var, dim, n_out):
    """UKF posterior covariance of the first ``n_out`` components (PF-BP eqs. (30), (49)).

    Sigma points ``x̄ ± √n L_j`` (weights ``1/(2n)``, no centre point, so the update is a
    Schur complement of a PSD matrix and stays PSD) around ``mean`` with covariance ``P``;
    ``P⁺ = P − P_xz P_zz^{-1} P_xzᵀ`` on the leading block, ``P_zz`` including ``R``.
    """
    n = mean.size
    L = robust_cholesky(P) * np.sqrt(n)
    pts = np.concatenate([mean + L.T, mean - L.T])  # [2n, n]
    Z = np.empty((2 * n, off_a.size))
    for q in range(off_a.size):
        pa = pts[:, off_a[q] : off_a[q] + dim]
        pb = pts[:, off_b[q] : off_b[q] + dim] if off_b[q] >= 0 else anchor_pos[q]
        Z[:, q] = np.linalg.norm(pa - pb, axis=1)
    dz = Z - Z.mean(axis=0)
    dx = pts[:, :n_out] - mean[:n_out]
    w = 1.0 / (2 * n)
    Pzz = w * dz.T @ dz + np.diag(r_var)
    Pxz = w * dx.T @ dz
    out = P[:n_out, :n_out] - Pxz @ np.linalg.solve(Pzz, Pxz.T)
    return 0.5 * (out + out.T)

"""Exact Daum–Huang (EDH) particle-flow kernels shared by the EDH filter and PF-BP.

For a Gaussian prior ``N(m₀, P)`` and a measurement linearized at the current flow mean ``x̄``,
``h(x) ≈ H x + e`` with ``e = h(x̄) − H x̄`` and noise covariance ``R``, the exact flow drift is
``ζ(x, λ) = A(λ) x + b(λ)`` (PF-BP eqs. (13), (24), (25), (40), (41)):

.. math::

    A(λ) = −\\tfrac12 P Hᵀ (λ H P Hᵀ + R)^{-1} H, \\qquad
    b(λ) = (I + 2λA)\\,[(I + λA) P Hᵀ R^{-1} (z − e) + A m₀].

Particles and the mean move by Euler steps ``x ← x + Δ_l ζ(x, λ_l)`` (PF-BP eqs. (21), (42),
(43)) over exponentially spaced pseudo-times (``Δ_{l+1} = q Δ_l``, ``Σ Δ_l = 1``, q = 1.2). In
PF-BP only the first ``n_flow`` components (agent ``i``) move; the neighbours' components of the
stacked state β stay at their particles (PF-BP eq. (21)).

Range kernels: measurement ``q`` is ``‖p_a − p_b‖`` with ``p_a`` the ``dim`` components of the
state at offset ``off_a[q]`` and ``p_b`` those at ``off_b[q]`` or, when ``off_b[q] < 0``, the
anchor ``anchor_pos[q]``. A zero distance gives a zero Jacobian row (no NaN).

The numba kernels are tested against plain-NumPy twins in ``tests/naive_flow.py``.
:func:`run_flow` is the flow PF-BP and the EDH filter call; :func:`use_flow` swaps in another
implementation for a block of code (the benchmarks time the NumPy twin that way);
:func:`flow_links` converts measurements to the offset form.

Examples
--------
>>> lambdas, steps = lambda_schedule(3, 2.0)
>>> steps.round(4).tolist(), float(lambdas[-1])
([0.1429, 0.2857, 0.5714], 1.0)

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

from contextlib import contextmanager

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


@njit(cache=True)
def _apply_h(U, off_a, off_b, v, out):
    """``out = H v`` for the sparse range Jacobian (row ``q``: ``+u_q`` at ``off_a[q]``,
    ``−u_q`` at ``off_b[q]`` unless an anchor)."""
    L, dim = U.shape
    for q in range(L):
        a = off_a[q]
        b = off_b[q]
        acc = 0.0
        for c in range(dim):
            d = v[a + c] - (v[b + c] if b >= 0 else 0.0)
            acc += U[q, c] * d
        out[q] = acc


@njit(cache=True)
def _move_sparse(U, off_a, off_b, T, bb, x, dl, hv, tmp):
    """One Euler step of the moving components of ``x``: ``x_f += Δ (T (H x) + b_f)``
    (``hv [L]``, ``tmp [n_flow]`` are work arrays)."""
    _apply_h(U, off_a, off_b, x, hv)
    n_flow = tmp.size
    for i in range(n_flow):
        acc = bb[i]
        for q in range(hv.size):
            acc += T[q, i] * hv[q]
        tmp[i] = acc
    for i in range(n_flow):
        x[i] += dl * tmp[i]


@njit(cache=True)
def _chol_solve(C, B):
    """``S^{-1} B`` for ``S = C Cᵀ`` (``C`` lower triangular), ``B [L, k]``: forward and back
    substitution, column by column."""
    L, k = B.shape
    Y = np.empty((L, k))
    for j in range(k):
        for i in range(L):
            acc = B[i, j]
            for t in range(i):
                acc -= C[i, t] * Y[t, j]
            Y[i, j] = acc / C[i, i]
        for i in range(L - 1, -1, -1):
            acc = Y[i, j]
            for t in range(i + 1, L):
                acc -= C[t, i] * Y[t, j]
            Y[i, j] = acc / C[i, i]
    return Y


@njit(cache=True)
def range_flow_kernel(X, mean, P, off_a, off_b, anchor_pos, z, r_var, dim, n_flow, lambdas, steps):
    """EDH flow of range measurements, in place on ``X [M, n]`` and ``mean [n]``.

    Linearizes at the flowing mean before every step; moves components ``0 … n_flow−1``.
    The Jacobian ``H`` of ranges has at most ``2·dim`` non-zeros per row, so nothing of size
    ``n × n`` is formed: with ``T = −½ (P Hᵀ)_{[:n_flow]} S^{-1}`` (``S = λ H P Hᵀ + R``) the
    drift of the moving components is ``A_f x = T (H x)``, and ``A v = −½ P Hᵀ S^{-1} H v`` for
    the vectors of ``b(λ)``. Per λ-step this costs ``O(n·L·dim + L³ + M·L·(dim + n_flow))``
    instead of the dense ``O(n²·L + M·n_flow·n)`` of :func:`edh_flow` with
    :func:`range_linearization` (the NumPy twin ``range_flow_numpy`` of ``tests/naive_flow.py``),
    which it equals to rounding.
    """
    M, n = X.shape
    L = z.size
    m0 = mean.copy()
    U = np.zeros((L, dim))
    e = np.empty(L)
    PHt = np.empty((n, L))
    S = np.empty((L, L))
    hv = np.empty(L)
    tmp = np.empty(n_flow)
    for s in range(lambdas.size):
        lam = lambdas[s]
        dl = steps[s]
        for q in range(L):  # linearize at the flowing mean
            a = off_a[q]
            b = off_b[q]
            d2 = 0.0
            for c in range(dim):
                pb = mean[b + c] if b >= 0 else anchor_pos[q, c]
                diff = mean[a + c] - pb
                d2 += diff * diff
            d = np.sqrt(d2)
            hx = 0.0
            for c in range(dim):
                if d > 1e-9:
                    pb = mean[b + c] if b >= 0 else anchor_pos[q, c]
                    U[q, c] = (mean[a + c] - pb) / d
                else:
                    U[q, c] = 0.0
                hx += U[q, c] * (mean[a + c] - (mean[b + c] if b >= 0 else 0.0))
            e[q] = d - hx
        for q in range(L):  # P Hᵀ, column by column from the sparse rows of H
            a = off_a[q]
            b = off_b[q]
            for i in range(n):
                acc = 0.0
                for c in range(dim):
                    acc += U[q, c] * (P[i, a + c] - (P[i, b + c] if b >= 0 else 0.0))
                PHt[i, q] = acc
        for q1 in range(L):  # S = λ H P Hᵀ + R
            a = off_a[q1]
            b = off_b[q1]
            for q2 in range(L):
                acc = 0.0
                for c in range(dim):
                    acc += U[q1, c] * (PHt[a + c, q2] - (PHt[b + c, q2] if b >= 0 else 0.0))
                S[q1, q2] = lam * acc
            S[q1, q1] += r_var[q1]
        # T = −½ S^{-1} (P Hᵀ)_{[:n_flow]}ᵀ  ([L, n_flow]; S is symmetric)
        # many measurements (the joint EDH): move particles by A_f = T H formed once (LAPACK
        # solve); few (PF-BP): one Cholesky factorization and A_f x = T (H x)
        joint = L * (2 * dim + n_flow) >= n_flow * n
        r = np.empty(L)
        for q in range(L):
            r[q] = (z[q] - e[q]) / r_var[q]
        g = PHt @ r
        if joint:
            T = -0.5 * np.linalg.solve(S, np.ascontiguousarray(PHt[:n_flow].T))
            Af = np.zeros((n_flow, n))
            for q in range(L):
                a = off_a[q]
                b = off_b[q]
                for i in range(n_flow):
                    t = T[q, i]
                    for c in range(dim):
                        Af[i, a + c] += t * U[q, c]
                        if b >= 0:
                            Af[i, b + c] -= t * U[q, c]
        else:
            C = np.linalg.cholesky(S)
            T = -0.5 * _chol_solve(C, np.ascontiguousarray(PHt[:n_flow].T))
            Af = np.zeros((0, 0))
        bb = np.empty(n_flow)
        if joint and n_flow == n:  # A = A_f: b(λ) by plain products
            vv = g + lam * (Af @ g) + Af @ m0
            Avv = Af @ vv
            for i in range(n):
                bb[i] = vv[i] + 2.0 * lam * Avv[i]
        else:  # A v = −½ P Hᵀ S^{-1} H v
            if joint:
                C = np.linalg.cholesky(S)
            _apply_h(U, off_a, off_b, g, hv)
            Ag = -0.5 * (PHt @ np.ascontiguousarray(_chol_solve(C, hv.reshape(L, 1))[:, 0]))
            _apply_h(U, off_a, off_b, m0, hv)
            Am0 = -0.5 * (PHt @ np.ascontiguousarray(_chol_solve(C, hv.reshape(L, 1))[:, 0]))
            vv = g + lam * Ag + Am0
            _apply_h(U, off_a, off_b, vv, hv)
            w = np.ascontiguousarray(_chol_solve(C, hv.reshape(L, 1))[:, 0])
            for i in range(n_flow):  # b = vv + 2λ A vv, moving components only
                acc = 0.0
                for q in range(L):
                    acc += PHt[i, q] * w[q]
                bb[i] = vv[i] - lam * acc
        if not joint:
            for m in range(M):
                _move_sparse(U, off_a, off_b, T, bb, X[m], dl, hv, tmp)
        else:
            for m in range(M):
                for i in range(n_flow):
                    acc = bb[i]
                    for j in range(n):
                        acc += Af[i, j] * X[m, j]
                    tmp[i] = acc
                for i in range(n_flow):
                    X[m, i] += dl * tmp[i]
        _move_sparse(U, off_a, off_b, T, bb, mean, dl, hv, tmp)


@njit(cache=True)
def paired_range_loglik_kernel(x, y, z, inv_var, out):
    """Accumulate ``out[m] += −½ (z − ‖x_m − y_m‖)² / σ²`` (paired particles, PF-BP eq. (22)).

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
    density ``f(x | x^{(k−1)})`` of PF-BP eq. (22) is singular for the CV/CA models (``Q`` has rank
    ``dim``), so it cannot be evaluated at the flowed particles.
    """
    return gaussian_logpdf(X1, mean0, cov0) - gaussian_logpdf(X0, mean0, cov0) + loglik1


def sigma_point_ranges(pts, off_a, off_b, anchor_pos, dim):
    """The ranges ``[points, L]`` of measurements ``q`` (as in :func:`run_flow`) at the sigma
    points ``pts [points, n]``."""
    Z = np.empty((pts.shape[0], off_a.size))
    for q in range(off_a.size):
        pa = pts[:, off_a[q] : off_a[q] + dim]
        pb = pts[:, off_b[q] : off_b[q] + dim] if off_b[q] >= 0 else anchor_pos[q]
        Z[:, q] = np.linalg.norm(pa - pb, axis=1)
    return Z


def ukf_covariance_update(mean, P, off_a, off_b, anchor_pos, r_var, dim, n_out):
    """UKF posterior covariance of the first ``n_out`` components (PF-BP eqs. (30), (49)).

    Sigma points ``x̄ ± √n L_j`` (weights ``1/(2n)``, no centre point, so the update is a
    Schur complement of a PSD matrix and stays PSD) around ``mean`` with covariance ``P``;
    ``P⁺ = P − P_xz P_zz^{-1} P_xzᵀ`` on the leading block, ``P_zz`` including ``R``.
    """
    n = mean.size
    L = robust_cholesky(P) * np.sqrt(n)
    pts = np.concatenate([mean + L.T, mean - L.T])  # [2n, n]
    Z = sigma_point_ranges(pts, off_a, off_b, anchor_pos, dim)
    dz = Z - Z.mean(axis=0)
    dx = pts[:, :n_out] - mean[:n_out]
    w = 1.0 / (2 * n)
    Pzz = w * dz.T @ dz + np.diag(r_var)
    Pxz = w * dx.T @ dz
    out = P[:n_out, :n_out] - Pxz @ np.linalg.solve(Pzz, Pxz.T)
    return 0.5 * (out + out.T)


#: The flow :func:`run_flow` uses instead of :func:`range_flow_kernel` (see :func:`use_flow`).
_flow_override = None


@contextmanager
def use_flow(flow):
    """Run PF-BP and the EDH filter with another range flow inside a ``with`` block.

    Parameters
    ----------
    flow : callable or None
        ``flow(X, mean, P, off_a, off_b, anchor_pos, z, r_var, dim, n_flow, lambdas, steps)
        -> (X1, mean1)`` returning new arrays (the signature of :func:`range_flow_kernel`);
        ``None``: the numba kernel. The benchmarks pass the NumPy twin ``range_flow_numpy`` of
        ``tests/naive_flow.py`` to time it; tests use it to compare whole tracks.

    Examples
    --------
    >>> calls = []
    >>> def traced(X, mean, *args):
    ...     calls.append(X.shape)
    ...     return X.copy(), mean.copy()
    >>> with use_flow(traced):
    ...     _ = run_flow(np.zeros((4, 3)), np.zeros(3), np.eye(3), np.zeros(1, np.int64),
    ...                  np.full(1, -1), np.ones((1, 3)), np.ones(1), np.ones(1), 3, 3,
    ...                  *lambda_schedule(2))
    >>> calls
    [(4, 3)]
    """
    global _flow_override
    if flow is not None and not callable(flow):
        from phyloc.errors import ValidationError

        raise ValidationError("flow", type(flow).__name__, "a callable or None")
    previous, _flow_override = _flow_override, flow
    try:
        yield
    finally:
        _flow_override = previous


def run_flow(X, mean, P, off_a, off_b, anchor_pos, z, r_var, dim, n_flow, lambdas, steps):
    """Flow copies of particles ``X [M, n]`` and ``mean [n]`` (PF-BP eqs. (21), (23)–(27)).

    Calls :func:`range_flow_kernel` on copies, or the flow installed by :func:`use_flow`.
    Returns ``X1 [M, n]``, ``mean1 [n]``.
    """
    if _flow_override is not None:
        return _flow_override(
            X, mean, P, off_a, off_b, anchor_pos, z, r_var, dim, n_flow, lambdas, steps
        )
    X1 = np.array(X, dtype=np.float64, order="C")
    m1 = np.array(mean, dtype=np.float64)
    range_flow_kernel(
        X1,
        m1,
        np.ascontiguousarray(P),
        off_a,
        off_b,
        anchor_pos,
        z,
        r_var,
        dim,
        n_flow,
        lambdas,
        steps,
    )
    return X1, m1


def stacked_loglik(B, off_a, off_b, anchor_pos, z, inv_var, dim):
    """``Σ_q log f(z_q | β^m)`` for stacked particles ``B [M, n]`` (paired, PF-BP eq. (22))."""
    out = np.zeros(B.shape[0])
    for q in range(z.size):
        a = off_a[q]
        x = np.ascontiguousarray(B[:, a : a + dim])
        b = off_b[q]
        y = anchor_pos[q : q + 1] if b < 0 else np.ascontiguousarray(B[:, b : b + dim])
        paired_range_loglik_kernel(x, y, float(z[q]), inv_var, out)
    return out


def flow_links(rx, tx, z, local_index, n_agents, anchors, dim, state_dim):
    """Convert measurements to the offset form of the flow kernels.

    ``local_index[node]`` is the slot of an agent in the stacked state (its position occupies
    ``slot·N_D … slot·N_D + dim``). Anchors get offset −1 and their coordinates in ``anchor_pos``.
    Returns ``off_a, off_b [L] int64, anchor_pos [L, dim], z [L]`` (``rx`` is always an agent).
    """
    off_a = local_index[rx] * state_dim
    is_anchor = tx >= n_agents
    off_b = np.where(is_anchor, -1, local_index[np.minimum(tx, n_agents - 1)] * state_dim)
    anchor_pos = np.zeros((rx.size, dim))
    if is_anchor.any():
        anchor_pos[is_anchor] = anchors[tx[is_anchor] - n_agents]
    return (
        np.ascontiguousarray(off_a, dtype=np.int64),
        np.ascontiguousarray(off_b, dtype=np.int64),
        anchor_pos,
        np.ascontiguousarray(z, dtype=np.float64),
    )

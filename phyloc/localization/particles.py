"""Particle parts shared by every particle method: weights, ESS, resampling, regularization, moves.

Each function has one role (Stone Soup's split of updater, resampler and regulariser is the
model): the direct family (DiPNet / EL-DPF), the tracking family (PF-BP, SIR-BP) and the static
family (NBP) compose them. Weights live in the log domain; a row without any finite weight
falls back to uniform weights instead of producing NaN.

Shapes: per-agent particle sets are ``X [n_agents, Q, dim]`` with log weights
``[n_agents, Q]``; a single (stacked) particle set is ``X [M, n]`` with log weights ``[M]``.

References
----------
A. Doucet, N. de Freitas, N. Gordon (eds.), *Sequential Monte Carlo Methods in Practice*,
Springer, 2001 (systematic resampling, resample-move).
M. S. Arulampalam, S. Maskell, N. Gordon, T. Clapp, "A tutorial on particle filters for online
nonlinear/non-Gaussian Bayesian tracking," IEEE Trans. SP 50(2), 2002 (effective sample size).
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
(PF-BP eq. (32), regularization by Gaussian jitter.)
"""

from __future__ import annotations

import numpy as np

from phyloc.localization import _kernels as K
from phyloc.localization import _particle_kernels as PK


def normalize_log_weights(lw) -> tuple[np.ndarray, int]:
    """Normalize log weights per agent; rows without a finite weight become uniform.

    Parameters
    ----------
    lw : [n_agents, Q] float64
        Unnormalized log weights (−inf allowed).

    Returns
    -------
    log_weights : [n_agents, Q] float64
        ``lw − logsumexp(lw)`` per row; ``−log Q`` on rows that had no finite weight.
    n_degenerate : int
        How many rows fell back to uniform.

    Examples
    --------
    >>> import numpy as np
    >>> lw, bad = normalize_log_weights(np.array([[0.0, 0.0], [-np.inf, -np.inf]]))
    >>> np.exp(lw).round(3).tolist(), bad
    ([[0.5, 0.5], [0.5, 0.5]], 1)
    """
    lw = np.ascontiguousarray(lw, dtype=np.float64)
    out = np.empty_like(lw)
    bad = K.log_normalize_kernel(lw, out)
    return out, int(bad)


def weighted_moments(particles, lw) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean ``[n_agents, dim]`` and covariance ``[n_agents, dim, dim]``.

    ``lw [n_agents, Q]`` must be normalized log weights.
    """
    w = np.exp(lw)
    mean = np.einsum("aq,aqd->ad", w, particles)
    dev = particles - mean[:, None, :]
    cov = np.einsum("aq,aqi,aqj->aij", w, dev, dev)
    return mean, cov


def effective_sample_size(lw) -> np.ndarray:
    """``1 / Σ_q w_q²`` per agent for normalized log weights ``lw [n_agents, Q]``.

    Examples
    --------
    >>> import numpy as np
    >>> lw = np.log(np.array([[0.25] * 4, [1.0, 1e-300, 1e-300, 1e-300]]))
    >>> effective_sample_size(lw).tolist()
    [4.0, 1.0]
    """
    w = np.exp(lw)
    return 1.0 / np.sum(w * w, axis=1)


def systematic_indices(weights, n: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of a systematic resample of ``n`` from normalized linear ``weights [m]``.

    One uniform draw ``u0`` of ``rng``; index ``i`` is the particle whose cumulative weight
    covers ``(i + u0)/n``.

    Examples
    --------
    >>> import numpy as np
    >>> systematic_indices(np.array([0.0, 1.0, 0.0]), 4, np.random.default_rng(0)).tolist()
    [1, 1, 1, 1]
    """
    out = np.empty(n, dtype=np.int64)
    K.systematic_resample_kernel(weights, float(rng.random()), out)
    return out


def systematic_resample(log_weights_row, n: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of a systematic resample of one agent's log weights ``[Q]`` (max-shifted)."""
    w = np.exp(log_weights_row - np.max(log_weights_row))
    w /= w.sum()
    return systematic_indices(w, n, rng)


def resample_agents(X, lw, rng: np.random.Generator, *arrays):
    """Systematically resample every agent's particles ``X [n_agents, Q, dim]``.

    ``arrays`` (each ``[n_agents, Q]``) are resampled with the same indices. Returns the list
    ``[X, *arrays]`` resampled; the new weights are uniform.
    """
    X = np.ascontiguousarray(X, dtype=np.float64)
    n_agents, Q, dim = X.shape
    lw = np.asarray(lw, dtype=np.float64)
    # the weights and their sums of systematic_resample, every agent at once (NumPy's exp and
    # pairwise sum, the same values row by row); one uniform draw per agent, in agent order
    w = np.exp(lw - np.max(lw, axis=1, keepdims=True))
    total = w.sum(axis=1)
    u0 = rng.random(n_agents)
    idx = np.empty((n_agents, Q), dtype=np.int64)
    Xr = np.empty((n_agents, Q, dim))
    PK.systematic_gather_kernel(w, total, u0, X, idx, Xr)
    out = [Xr]
    for arr in arrays:
        arr = np.ascontiguousarray(arr)
        r = np.empty(idx.shape, dtype=arr.dtype)
        PK.gather_rows_kernel(arr, idx, r)
        out.append(r)
    return out


def resample_regularize(X, lw, rng: np.random.Generator, regularize: bool):
    """Systematic resampling of every agent, then optional Gaussian jitter (Silverman's rule).

    Returns ``(X, log_weights)`` with uniform log weights.
    """
    n_agents, Q, dim = X.shape
    X = resample_agents(X, lw, rng)[0]
    if regularize:
        h = (4.0 / (Q * (dim + 2))) ** (1.0 / (dim + 4))  # Silverman's factor
        std = X.std(axis=1, keepdims=True)
        X = X + h * std * rng.standard_normal(X.shape)
    return X, np.full((n_agents, Q), -np.log(Q))


def resample_permute(X, log_w, rng: np.random.Generator, jitter_cov=None):
    """Systematic resampling of a stacked set ``X [M, n]`` followed by a random permutation.

    Non-finite weights fall back to uniform. With ``jitter_cov`` (``[n, n]``, Σ_r of PF-BP eq.
    (32)) the resampled particles are regularized in the same call: the result equals
    ``regularize(resample_permute(X, log_w, rng), jitter_cov, rng)``, draw for draw.
    """
    M = X.shape[0]
    if not np.any(np.isfinite(log_w)):
        log_w = np.zeros(M)
    log_w = np.where(np.isfinite(log_w), log_w, -np.inf)
    idx = rng.permutation(systematic_resample(log_w, M, rng))
    if jitter_cov is None:
        return np.take(X, idx, axis=0)  # = X[idx], 3x faster for 10^6 rows
    return _gather_jitter(X, idx, jitter_cov, rng)


def regularize(X, cov, rng: np.random.Generator):
    """Add ``N(0, diag Σ_r)`` to every particle of ``X [M, n]`` (PF-BP eq. (32)).

    ``cov [n, n]``: only its diagonal is used, so it may be singular; normals are drawn only for
    the components with a non-zero variance (``[M, n_jittered]``, row by row), the others are
    copied.
    """
    return _gather_jitter(X, np.arange(X.shape[0]), cov, rng)


def _gather_jitter(X, idx, cov, rng):
    std = np.sqrt(np.diag(cov))
    cols = np.flatnonzero(std > 0.0)
    out = np.take(X, idx, axis=0)
    if cols.size == 0:
        return out
    W = rng.standard_normal((idx.size, cols.size))
    W *= std[cols]
    if cols[-1] - cols[0] == cols.size - 1:  # Σ_r of PF-BP eq. (32) jitters one block: a view
        out[:, cols[0] : cols[-1] + 1] += W
    else:
        out[:, cols] += W
    return out


def mh_moves(X, lp, ll_old, ll_new, lam, old_fn, new_fn, logp, rng, *, n_moves, move_scale):
    """Random-walk Metropolis–Hastings sweeps per agent (resample-move).

    Target: ``prior · exp(λ ll_new + (1 − λ) ll_old)`` with ``λ [n_agents]``. Proposals are
    ``X + N(0, (move_scale·std_q X)²)``
    (:func:`~phyloc.localization._particle_kernels.mh_propose_draw_kernel`, which draws the
    normals of :func:`~phyloc.localization._kernels.mh_propose_kernel`), acceptance by
    :func:`~phyloc.localization._kernels.mh_accept_kernel`. ``logp`` and ``new_fn`` evaluate
    the prior and the new log-likelihood at ``[n_agents, Q, dim]``, ``old_fn`` (or None:
    ``ll_old ≡ 0``) the old one as ``old_fn(x, agents)`` on the rows of the agents still
    bridging (``λ < 1``): where ``λ = 1`` the old likelihood has weight 0 and is not evaluated
    (its ``ll_old`` entries of accepted moves become 0). An ``old_fn`` with a true attribute
    ``takes_prior`` is also given the prior at ``x``, ``old_fn(x, agents, lp_x=...)`` (rows of
    ``agents``), which the sweep has already evaluated. Each sweep draws
    ``rng.standard_normal(X.shape)`` then ``rng.random((n_agents, Q))``. Returns the moved
    ``(X, lp, ll_old, ll_new)`` (new arrays; the inputs are not modified).
    """
    n_agents, Q, _ = X.shape
    lam = np.ascontiguousarray(lam, dtype=np.float64)
    X, lp, ll_old, ll_new = (np.array(a, dtype=np.float64) for a in (X, lp, ll_old, ll_new))
    bridging = np.flatnonzero(lam < 1.0)
    if bridging.size == 0:
        old_fn = None  # weight 1 − λ = 0 everywhere: the old likelihood drops out
    takes_prior = getattr(old_fn, "takes_prior", False)
    Xp = np.empty_like(X)
    log_u = np.empty((n_agents, Q))
    for _ in range(n_moves):
        # mh_propose_kernel(X, rng.standard_normal(X.shape), ...), the normals drawn in Numba
        PK.mh_propose_draw_kernel(rng, X, float(move_scale), 1e-4, Xp)
        lpp = np.ascontiguousarray(logp(Xp), dtype=np.float64)
        lnp = np.ascontiguousarray(new_fn(Xp), dtype=np.float64)
        lop = np.zeros_like(lnp)
        if old_fn is None:
            pass
        elif bridging.size == n_agents:
            lop[:] = old_fn(Xp, lp_x=lpp) if takes_prior else old_fn(Xp)
        else:
            xb = Xp[bridging]
            if takes_prior:
                lop[bridging] = old_fn(xb, agents=bridging, lp_x=lpp[bridging])
            else:
                lop[bridging] = old_fn(xb, agents=bridging)
        rng.random(out=log_u)
        np.log(log_u, out=log_u)
        K.mh_accept_kernel(X, lp, ll_old, ll_new, Xp, lpp, lop, lnp, lam, log_u)
    return X, lp, ll_old, ll_new

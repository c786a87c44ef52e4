"""Gaussian kernel density estimates of NBP's particle messages and their bandwidths.

The message KDE of POA-NBP eq. (7), ``log μ̂(x) = log Σ_k w_k N(x; y_k, h² I)``
(:func:`kde_logpdf`), and its bandwidth rules: Silverman's 2-D normal-reference rule
(:func:`silverman_bandwidth`) and least-squares cross-validation, the paper's choice (its
ref. [32], :func:`lscv_bandwidth`). The O(P·K) sums are the Numba kernels of
:mod:`phyloc.localization.static._nbp_kernels`.

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import math

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization.static._nbp_kernels import LSCV_GRID, kde_logpdf_kernel, lscv_grid_kernel


def logsumexp(a, axis=None, keepdims=False):
    """``log Σ exp(a)`` along ``axis``, stable (max-shifted); ``-inf`` where every term is
    ``-inf``. Same result as ``scipy.special.logsumexp`` for real input, ~7x less overhead on
    the small arrays of a message product (it was the largest fixed cost per agent update)."""
    a = np.asarray(a, dtype=np.float64)
    m = np.max(a, axis=axis, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    with np.errstate(divide="ignore"):
        out = np.log(np.sum(np.exp(a - m), axis=axis, keepdims=True)) + m
    return out if keepdims else np.squeeze(out, axis=axis)


def _normalized_log(weights: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        lw = np.log(weights)
    return lw - logsumexp(lw, axis=-1, keepdims=True)


def kde_logpdf(points, centers, weights, bandwidths) -> np.ndarray:
    """Log-density of Gaussian KDEs (POA-NBP eq. (7)) at ``points``.

    .. math::  \\log \\hat\\mu_m(x) = \\log \\sum_k w_{mk}\\, \\mathcal N(x; y_{mk}, h_m^2 I)

    Parameters
    ----------
    points : [P, 2] float64
        Evaluation points [m].
    centers : [M, K, 2] or [K, 2] float64
        Kernel centres (message samples) [m].
    weights : [M, K] or [K] float64
        Non-negative sample weights, each row with a positive sum (normalised here).
    bandwidths : float or [M] float64
        Kernel standard deviations ``h_m`` [m], > 0.

    Returns
    -------
    logpdf : [M, P] (or [P] for a single KDE) float64

    Examples
    --------
    >>> x = np.zeros((1, 2))
    >>> round(float(kde_logpdf(x, np.zeros((1, 2)), [1.0], 1.0)[0]), 6)  # log N(0; 0, I)
    -1.837877
    """
    pts = v.finite_array("points", points, ndim=2)
    c = v.finite_array("centers", centers)
    single = c.ndim == 2
    c = c[None] if single else c
    if c.ndim != 3 or c.shape[2] != 2 or pts.shape[1] != 2:
        raise ValidationError("centers", f"array of shape {c.shape}", "must be [M, K, 2] or [K, 2]")
    w = v.finite_array("weights", weights)
    w = w[None] if w.ndim == 1 else w
    if w.shape != c.shape[:2] or np.any(w < 0) or np.any(w.sum(axis=1) <= 0):
        raise ValidationError(
            "weights", f"array of shape {w.shape}", f"must be {c.shape[:2]}, >= 0, rows summing > 0"
        )
    h = np.broadcast_to(v.finite_array("bandwidths", bandwidths), (c.shape[0],)).copy()
    if np.any(h <= 0):
        raise ValidationError("bandwidths", float(h.min()), "must be > 0")
    out = _kde(pts, c, _normalized_log(w), h)
    return out[0] if single else out


def _kde(points, centers, log_weights, bandwidths):
    out = np.empty((centers.shape[0], points.shape[0]))
    kde_logpdf_kernel(
        np.ascontiguousarray(points),
        np.ascontiguousarray(centers),
        np.ascontiguousarray(log_weights),
        np.ascontiguousarray(bandwidths, dtype=np.float64),
        out,
    )
    return out


def _weighted_cov(samples, w):
    mu = w @ samples
    dev = samples - mu
    return mu, (dev * w[:, None]).T @ dev


def silverman_bandwidth(samples, weights=None) -> float:
    """Silverman's 2-D normal-reference rule ``h = σ̄·n_eff^{−1/6}``, ``σ̄² = ½ tr Σ̂``.

    ``n_eff = 1/Σ w²`` (normalised weights). Returns 0 for coincident samples.
    """
    x = v.finite_array("samples", samples, ndim=2)
    w = np.full(x.shape[0], 1.0 / x.shape[0]) if weights is None else np.asarray(weights, float)
    w = w / w.sum()
    return _silverman(x, w)


def _silverman(x, w):
    _, cov = _weighted_cov(x, w)
    n_eff = 1.0 / np.sum(w * w)
    return math.sqrt(max(0.5 * np.trace(cov), 0.0)) * n_eff ** (-1.0 / 6.0)


def lscv_bandwidth(samples, weights=None, *, rng=None, max_samples: int = 256) -> float:
    """Least-squares cross-validation bandwidth of a 2-D Gaussian KDE (POA-NBP eq. (7), [32]).

    Minimises the exact LSCV score over ``h_t = √2·h_S·2^{−t/2}``, ``t = 0 … 12``
    (``h_S``: :func:`silverman_bandwidth`). Above ``max_samples`` samples the score is computed
    on a random subset (``rng`` required) and the result scaled by ``(n_sub/n_eff)^{1/6}``.
    Returns 0 for coincident samples.
    """
    x = v.finite_array("samples", samples, ndim=2)
    w = np.full(x.shape[0], 1.0 / x.shape[0]) if weights is None else np.asarray(weights, float)
    w = w / w.sum()
    if x.shape[0] > max_samples and not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", rng, f"a Generator is needed above {max_samples} samples")
    return _lscv(x, w, rng, max_samples)


def _lscv(x, w, rng, max_samples):
    h_s = _silverman(x, w)
    if h_s <= 0.0 or x.shape[0] < 3:
        return h_s
    n_eff = 1.0 / np.sum(w * w)
    scale = 1.0
    if x.shape[0] > max_samples:
        idx = rng.choice(x.shape[0], size=max_samples, replace=False)
        ws = w[idx] / w[idx].sum()
        scale = ((1.0 / np.sum(ws * ws)) / n_eff) ** (1.0 / 6.0)
        x, w = x[idx], ws
    h0 = math.sqrt(2.0) * _silverman(x, w)
    if h0 <= 0.0:
        return h_s
    score = np.empty(LSCV_GRID)
    lscv_grid_kernel(np.ascontiguousarray(x), np.ascontiguousarray(w), h0, score)
    return h0 * 0.5 ** (int(np.argmin(score)) / 2.0) * scale

"""Nonparametric belief propagation (NBP) for static 2-D cooperative localization (POA-NBP §II-B).

Every agent ``j`` holds a particle belief of ``N_S`` samples. One iteration ``l`` (parallel,
Jacobi schedule: every agent uses its neighbours' beliefs of iteration ``l − 1``):

1. **Message filtering** (POA-NBP eqs. (4), (5)). For every link ``i → j`` with range
   ``ẑ_{i→j}``, the message is the particle set ``y_k = x_i^{(k)} + (ẑ_{i→j} − ε_k)·u_k`` with
   ``x_i^{(k)}`` the ``N_S`` belief samples of ``i`` (the anchor position for an anchor),
   ``ε_k`` drawn from the error model and ``u_k`` a uniformly random unit vector. With
   ``jacobian_weights`` the samples are weighted by ``|ẑ − ε_k|``, which turns the polar
   sampling density ``p_ε(ẑ − ρ)/(2πρ)`` into the message density ``∝ p(ẑ | ρ)`` in the plane
   (POA-NBP eq. (5) draws them with equal weights; ``jacobian_weights=False`` reproduces
   that). As in the paper (POA-NBP eq. (6): the outgoing message is the belief), neighbours
   send their full belief, not the extrinsic one.
2. **Kernel density estimates** (POA-NBP eq. (7)): an isotropic Gaussian kernel per message
   with bandwidth ``h`` chosen by least-squares cross-validation (``bandwidth="lscv"``, the
   paper's choice, its ref. [32]), Silverman's rule of thumb (``"silverman"``:
   ``h = σ̄·n_eff^{−1/6}``, ``σ̄² = ½ tr Σ̂``, the 2-D normal-reference rule) or a fixed value
   [m]. Silverman's rule is built for unimodal densities and over-smooths the ring-shaped range
   messages (``σ̄`` is of the order of the range); LSCV picks ``h`` on the grid
   ``√2·h_S·2^{−t/2}``, ``t = 0 … 12``, by minimising the exact Gaussian-kernel LSCV score
   (computed on a random subset of at most ``lscv_max_samples`` samples, rescaled by
   ``(n_sub/n)^{1/6}``). Every bandwidth is at least ``min_bandwidth_m``.
3. **Message multiplication** by importance sampling (POA-NBP eqs. (8), (9)): draw ``N_S``
   samples ``x^{(k)}`` from a proposal ``q`` and weight them by
   ``log w = Σ_{agent i} log μ̂_{i→j}(x) + Σ_{anchor i} log p(ẑ_{i→j} | x, x_i) + log p(x)
   − log q(x)`` (anchor messages are evaluated exactly with the error model's likelihood, the
   prior ``p(x)`` is uniform over the region); weights are normalised with logsumexp. Samples
   outside the region or outside a polygon proposal get weight exactly zero. Proposals:

   - ``"min_entropy"`` (POA-NBP ref. [19], 'NBP min.'): the KDE of the incoming message of
     least entropy, measured by its Gaussian upper bound ``½ log det(Σ̂ + h² I)``;
   - ``"mixture"`` (POA-NBP ref. [27]): ``(1 − ε)·(1/M) Σ_m μ̂_m + ε·U(region)``,
     ``ε = uniform_fraction``;
   - ``"parsimonious"`` (POA-NBP ref. [25], 'NBP par.'): ``(1 − ε)·KDE(previous belief) +
     ε·U(region)``, the KDE of the agent's weighted samples of its last update with
     Silverman's bandwidth; while the belief is still the uniform prior the agent uses
     ``"mixture"`` instead;
   - ``"auxiliary"`` (POA-NBP ref. [27], 'NBP aux.': "the proposal distribution is augmented
     with an auxiliary variable [that] takes the messages from anchors into account"): for an
     agent with at least one anchor neighbour, ``q(x) ∝ Π_{anchor a} p(ẑ_{a→j} | x, x_a)``
     restricted to the region, sampled by auxiliary-variable importance resampling: draw
     ``L·N_S`` candidates (``L = aux_oversampling``) from the equal mixture of the anchor
     messages' KDEs — the auxiliary variable is the mixture component, then the candidate
     index —, weight them by ``Π_a p(ẑ_a | x) / mixture(x)`` (zero outside the region) and
     keep ``N_S`` by systematic resampling. In the weights the anchor terms cancel against
     ``q``: the final weight is the product of the agent messages' KDEs times the prior.
     Without an anchor neighbour the agent uses ``"mixture"`` (also when no candidate lands
     in the anchors' support). This is *our interpretation*: the sampling details of
     ref. [27] (V. Savic and S. Zazo, Ad Hoc Networks 11(1), 2013, where the auxiliary
     variable enters the importance density as in an auxiliary particle filter) were not
     available to us beyond the POA-NBP paper's one-sentence description;
   - ``"polygon"`` (POA-NBP eq. (21)): uniform in the agent's convex support region
     ``q = 1/A_p`` inside, 0 outside. The regions come from the prior
     (``StaticPrior.polygons``) or are computed by the method from the measurements
     (``NBPOptions.support``: POA, POA-NBP Algorithm 1, or the ellipse baseline).

4. **Estimate and resampling**: the MMSE estimate is the weighted mean (POA-NBP §II-B); the
   belief for the next iteration is a systematic resample of ``N_S`` equally weighted samples.

Agents start from a uniform belief over the region (uniform over their polygon when the
polygon proposal is used: the polygon contains the support of the marginal, POA-NBP §III). An
agent whose belief is still the uniform prior sends no messages (they carry almost no
information, as in POA-NBP ref. [3]); an agent without any usable message keeps its belief, so
an isolated agent stays uniform over the region and its estimate is the region's centre (never
NaN). If every proposal sample of an agent has zero weight the agent keeps its previous belief
too.

**Convergence**: with ``c_l`` the mean over agents of ``‖x̂^{(l)} − x̂^{(l−1)}‖``, the run has
converged at the first ``l`` with ``c_l < convergence_tol_m`` or ``c_l > (1 −
convergence_rel)·c_{l−1}``: NBP estimates keep moving by their Monte Carlo error (≈ 0.1–0.8 m
per iteration at ``N_S = 200`` in the POA-NBP §V network), so an absolute threshold alone is
never met; the plateau of ``c_l`` is the truth-free counterpart of POA-NBP §V footnote 5 (the
average error no longer changes notably). ``stop_on_convergence`` ends the run there.

**Cost**: the ``O(|S_{→j}|·N_S²)`` KDE evaluation (POA-NBP eq. (8)) is :func:`kde_logpdf_kernel`
(numba, serial) and the LSCV score, O(N_S²) per message up to ``lscv_max_samples``, is
:func:`lscv_grid_kernel`, both in the private module
:mod:`phyloc.localization.static._nbp_kernels` (their plain-NumPy references are test code,
``tests/naive_static.py``). Measured in the POA-NBP §V network (≈ 12.5 links per agent, one
loaded 2-core machine): ≈ 3 / 5 / 10 / 24 ms per agent and iteration at N_S = 100 / 200 / 400
/ 800 with the polygon proposal — at these sizes the O(N_S) per-message work and the capped
LSCV weigh as much as the quadratic KDE, which itself grows as N_S² (≈ 0.2 / 0.9 / 4.6 ms for
10 messages at N_S = 100 / 200 / 400, 20–40× faster than the NumPy reference, depending on the
load).

**Communication and operation counts** (``Result.diagnostics``): every agent broadcasts its
belief, ``N_S`` equally weighted (resampled) samples of 2 coordinates, once per iteration;
the receiver forms the range message and chooses its bandwidth itself, so nothing else is sent:
``floats_per_link_iteration = 2·N_S``. The support phase (POA, POA-NBP Algorithm 1, or the
ellipses) exchanges its regions before NBP starts: ``support_floats_per_link_iteration``
(POA: 2 per polygon vertex, :attr:`~phyloc.localization.static.polygons.POAResult.
floats_per_link_iteration`; ellipses: 5, centre and symmetric shape matrix). The operations
counted are the ones POA-NBP §II-B calls dominant, the Gaussian kernel evaluations of the
message KDEs (POA-NBP eq. (7)) in the importance weights (POA-NBP eq. (8), ``O(|S_{→j}|·N_S²)``)
and in the proposal densities (the mixture, parsimonious and auxiliary proposals evaluate
KDEs at their samples or candidates): ``P·K`` for a KDE of ``K`` centres at ``P`` points
(``kernel_evaluations``); not counted are the exact anchor likelihoods (``N_S`` per anchor
link), the ``O(N_S)`` message filtering, the LSCV bandwidth search and the resampling.
``operations_per_node`` adds the support's own count (POA:
:attr:`~phyloc.localization.static.polygons.POAResult.operations_per_node`; ellipses: not
counted, 0).

Support regions: any object with ``.area`` [m²], ``.contains(points [n, 2]) -> bool [n]`` and
``.sample_uniform(n, rng) -> [n, 2]`` (e.g.
:class:`phyloc.localization.static.polygons.ConvexPolygon` or
:class:`~phyloc.localization.static.polygons.EllipseRegion`).

References
----------
R. Mendrzik and G. Bauch, "Position-Constrained Stochastic Inference for Cooperative
Indoor Localization." ("POA-NBP").
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from phyloc import _validate as v
from phyloc._validate import check_keys
from phyloc.errors import ValidationError
from phyloc.localization.particles import systematic_indices
from phyloc.localization.results import Result, Timing
from phyloc.localization.static._nbp_kernels import LSCV_GRID, kde_logpdf_kernel, lscv_grid_kernel
from phyloc.localization.static.polygons import ellipse_outer_approximation, poa
from phyloc.localization.static.static_ranges import (
    LINK_MODES,
    RangeError,
    StaticMeasurements,
    StaticNetwork,
    StaticPrior,
    check_error_model,
    check_inputs,
    check_region,
    convergence_iteration,
)

#: Proposal distributions of :class:`NBPOptions`.
PROPOSALS = ("min_entropy", "mixture", "parsimonious", "polygon", "auxiliary")
#: Bandwidth rules (or a float in metres).
BANDWIDTH_RULES = ("lscv", "silverman")
#: Support regions of the polygon proposal that NBP computes itself (:class:`NBPOptions`).
SUPPORTS = ("none", "poa", "ellipse")


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


@dataclass(frozen=True, eq=False)
class Message:
    """A particle message ``R_{N_S}(μ_{φ_ij → X_j})`` (POA-NBP eq. (5)) with its KDE bandwidth.

    Attributes
    ----------
    samples : [K, 2] float64
        Sample positions [m].
    weights : [K] float64
        Normalised weights.
    bandwidth : float
        Kernel standard deviation ``h`` [m] of POA-NBP eq. (7).
    anchor : (position [2], z) or None
        For a message from an anchor: its position and the range; the message product then
        evaluates the exact likelihood ``p(z | ‖x − position‖)`` instead of the KDE (the KDE is
        only used inside proposals).
    """

    samples: np.ndarray
    weights: np.ndarray
    bandwidth: float
    anchor: tuple[np.ndarray, float] | None = None

    def entropy_bound(self) -> float:
        """``½ log det(Σ̂ + h² I)`` (Gaussian upper bound of the KDE entropy up to a constant)."""
        _, cov = _weighted_cov(self.samples, self.weights)
        sign, logdet = np.linalg.slogdet(cov + self.bandwidth**2 * np.eye(2))
        return 0.5 * logdet if sign > 0 else -np.inf


def range_message_samples(
    sources, z: float, error_model: RangeError, rng: np.random.Generator, *, jacobian=True
) -> tuple[np.ndarray, np.ndarray]:
    """Samples of the message of a range link (message filtering, POA-NBP eqs. (4), (5)).

    ``y_k = sources[k] + (z − ε_k)·(cos θ_k, sin θ_k)``, ``ε_k`` from ``error_model``,
    ``θ_k ~ U[0, 2π)``; weights ``∝ |z − ε_k|`` with ``jacobian`` (the density of ``y`` in the
    plane is then ``∝ p(z | ‖y − x_i‖)``), equal otherwise.

    Parameters
    ----------
    sources : [K, 2] float64
        Equally weighted belief samples of the sending node (``K`` copies of an anchor's
        position).

    Returns
    -------
    samples : [K, 2], weights : [K] (normalised)
    """
    n = sources.shape[0]
    r = z - error_model.sample(n, rng)
    th = rng.uniform(0.0, 2.0 * math.pi, n)
    y = sources + r[:, None] * np.column_stack([np.cos(th), np.sin(th)])
    w = np.abs(r) if jacobian else np.ones(n)
    s = w.sum()
    w = w / s if s > 0 else np.full(n, 1.0 / n)
    return y, w


def _in_region(x, region):
    return (
        (x[:, 0] >= region[0])
        & (x[:, 0] <= region[2])
        & (x[:, 1] >= region[1])
        & (x[:, 1] <= region[3])
    )


def _uniform_region(n, region, rng):
    return rng.uniform((region[0], region[1]), (region[2], region[3]), size=(n, 2))


def _region_area(region):
    return (region[2] - region[0]) * (region[3] - region[1])


def _sample_kde(msg: Message, n: int, rng) -> np.ndarray:
    idx = rng.choice(msg.samples.shape[0], size=n, p=msg.weights)
    return msg.samples[idx] + msg.bandwidth * rng.standard_normal((n, 2))


def _check_polygon(poly, name="polygon"):
    for attr in ("area", "contains", "sample_uniform"):
        if not hasattr(poly, attr):
            raise ValidationError(
                name,
                type(poly).__name__,
                "needs .area, .contains(points) and .sample_uniform(n, rng)",
            )
    area = float(poly.area)
    if not (math.isfinite(area) and area > 0):
        raise ValidationError(f"{name}.area", area, "must be finite and > 0")
    return poly


@dataclass(frozen=True, eq=False)
class Product:
    """Importance-sampled product of messages (POA-NBP eqs. (8), (9)).

    Attributes
    ----------
    samples : [N_S, 2] float64
        Proposal samples.
    log_weights : [N_S] float64
        Normalised log weights; ``-inf`` for zero-weight (invalid) samples, all ``-inf`` only
        when ``ok`` is False.
    ok : bool
        At least one sample has a positive weight.
    kernel_evaluations : int
        Gaussian kernel evaluations of the message KDEs (POA-NBP eq. (7)) this product made:
        ``P·K`` per KDE with ``K`` centres evaluated at ``P`` points — in the weights (POA-NBP
        eq. (8)), in the proposal density and, for ``"auxiliary"``, at the candidates.
    """

    samples: np.ndarray
    log_weights: np.ndarray
    ok: bool
    kernel_evaluations: int = 0

    @property
    def weights(self) -> np.ndarray:
        return np.exp(self.log_weights) if self.ok else np.zeros(self.samples.shape[0])

    @property
    def mean(self) -> np.ndarray:
        """MMSE estimate ``Σ_k v_k x^{(k)}`` (POA-NBP §II-B)."""
        return self.weights @ self.samples

    @property
    def ess(self) -> float:
        """Effective sample size ``1/Σ v_k²``."""
        return 1.0 / float(np.sum(self.weights**2)) if self.ok else 0.0


def _product(
    messages,
    n,
    proposal,
    rng,
    region,
    uniform_fraction,
    error_model,
    polygon=None,
    previous=None,
    region_prior=True,
    oversampling=4,
):
    """Core of :func:`message_product` (no validation)."""
    M = len(messages)
    anchors = [i for i, m in enumerate(messages) if m.anchor is not None]
    if proposal == "auxiliary" and not anchors:
        proposal = "mixture"  # no anchor neighbour: nothing to build the auxiliary proposal on
    valid = None
    n_kernel = 0
    need = list(range(M)) if proposal == "mixture" else []  # KDEs needed by the proposal
    if proposal == "auxiliary":
        X, n_kernel = _auxiliary_samples(
            [messages[i] for i in anchors], n, oversampling, rng, region, error_model
        )
        if X is None:  # no candidate inside the anchors' support: the mixture proposal instead
            prod = _product(
                messages,
                n,
                "mixture",
                rng,
                region,
                uniform_fraction,
                error_model,
                region_prior=region_prior,
            )
            return dataclasses.replace(prod, kernel_evaluations=prod.kernel_evaluations + n_kernel)
    elif proposal == "min_entropy":
        best = int(np.argmin([m.entropy_bound() for m in messages]))
        X = _sample_kde(messages[best], n, rng)
        need = [best]
    elif proposal == "mixture":
        eps = uniform_fraction
        n_u = rng.binomial(n, eps) if eps > 0 else 0
        counts = rng.multinomial(n - n_u, np.full(M, 1.0 / M))
        parts = [_sample_kde(m, c, rng) for m, c in zip(messages, counts, strict=True) if c]
        parts.append(_uniform_region(n_u, region, rng))
        X = np.vstack(parts)
    elif proposal == "parsimonious":
        eps = uniform_fraction if previous is not None else 1.0
        n_u = rng.binomial(n, eps) if eps < 1 else n
        parts = [_uniform_region(n_u, region, rng)]
        if n - n_u:
            parts.append(_sample_kde(previous, n - n_u, rng))
        X = np.vstack(parts)
    elif proposal == "polygon" and polygon is not None:
        X = np.asarray(polygon.sample_uniform(n, rng), dtype=np.float64).reshape(n, 2)
        valid = np.asarray(polygon.contains(X), dtype=bool).reshape(n)
        log_q = np.full(n, -math.log(float(polygon.area)))
    else:  # polygon proposal without a polygon: uniform over the region
        X = _uniform_region(n, region, rng)
        log_q = np.full(n, -math.log(_region_area(region)))

    # KDEs: every agent message (target) plus whatever the proposal density needs
    kde_idx = [i for i, m in enumerate(messages) if m.anchor is None]
    kde_idx += [i for i in need if i not in kde_idx]
    logk = {}
    if kde_idx:
        k_max = max(messages[i].samples.shape[0] for i in kde_idx)
        centers = np.zeros((len(kde_idx), k_max, 2))
        lw = np.full((len(kde_idx), k_max), -np.inf)  # padding: zero weight
        for r, i in enumerate(kde_idx):
            k = messages[i].samples.shape[0]
            centers[r, :k] = messages[i].samples
            lw[r, :k] = _normalized_log(messages[i].weights)
        h = np.array([messages[i].bandwidth for i in kde_idx])
        vals = _kde(X, centers, lw, h)
        logk = {i: vals[r] for r, i in enumerate(kde_idx)}
        n_kernel += n * sum(messages[i].samples.shape[0] for i in kde_idx)

    log_t = np.zeros(n)
    log_anchor = np.zeros(n)
    for i, m in enumerate(messages):
        if m.anchor is None:
            log_t += logk[i]
        else:
            pos, z = m.anchor
            ll = error_model.loglik(z, np.linalg.norm(X - pos, axis=1))
            log_t += ll
            log_anchor += ll

    in_reg = _in_region(X, region)
    with np.errstate(divide="ignore"):
        if proposal == "auxiliary":  # q ∝ Π_anchors p(ẑ | x) on the region: anchor terms cancel
            log_q = log_anchor
        elif proposal == "min_entropy":
            log_q = logk[need[0]]
        elif proposal == "mixture":
            mix = logsumexp(np.stack([logk[i] for i in range(M)]), axis=0) - math.log(M)
            unif = np.where(in_reg, -math.log(_region_area(region)), -np.inf)
            log_q = np.logaddexp(
                math.log1p(-eps) + mix if eps < 1 else -np.inf,
                math.log(eps) + unif if eps > 0 else -np.inf,
            )
        elif proposal == "parsimonious":
            unif = np.where(in_reg, -math.log(_region_area(region)), -np.inf)
            if previous is None:
                log_q = unif
            else:
                prev = _kde(
                    X,
                    previous.samples[None],
                    _normalized_log(previous.weights[None]),
                    np.array([previous.bandwidth]),
                )[0]
                n_kernel += n * previous.samples.shape[0]
                log_q = np.logaddexp(
                    math.log1p(-eps) + prev if eps < 1 else -np.inf,
                    math.log(eps) + unif if eps > 0 else -np.inf,
                )
    ok_mask = np.isfinite(log_q) & np.isfinite(log_t)
    if valid is not None:
        ok_mask &= valid
    if region_prior:
        ok_mask &= in_reg
    lw = np.full(n, -np.inf)
    if not ok_mask.any():
        return Product(X, lw, False, n_kernel)
    raw = log_t[ok_mask] - log_q[ok_mask]
    lw[ok_mask] = raw - logsumexp(raw)
    return Product(X, lw, True, n_kernel)


def _auxiliary_samples(anchor_messages, n, oversampling, rng, region, error_model):
    """Auxiliary-variable importance resampling of ``q(x) ∝ Π_a p(ẑ_a | x, x_a)`` on the region.

    ``L·n`` candidates from the equal mixture of the anchor messages' KDEs (the auxiliary
    variable is the component, then the candidate index), first-stage log weights
    ``Σ_a log p(ẑ_a | x) − log mixture(x)`` (zero outside the region), ``n`` of them kept by
    systematic resampling. Returns ``(samples [n, 2] or None, kernel evaluations)``; ``None``
    when no candidate has a positive weight.
    """
    A = len(anchor_messages)
    n_c = oversampling * n
    counts = rng.multinomial(n_c, np.full(A, 1.0 / A))
    C = np.vstack(
        [_sample_kde(m, c, rng) for m, c in zip(anchor_messages, counts, strict=True) if c]
    )
    k_max = max(m.samples.shape[0] for m in anchor_messages)
    centers = np.zeros((A, k_max, 2))
    lw = np.full((A, k_max), -np.inf)
    for r, m in enumerate(anchor_messages):
        k = m.samples.shape[0]
        centers[r, :k] = m.samples
        lw[r, :k] = _normalized_log(m.weights)
    h = np.array([m.bandwidth for m in anchor_messages])
    log_mix = logsumexp(_kde(C, centers, lw, h), axis=0) - math.log(A)
    n_kernel = n_c * sum(m.samples.shape[0] for m in anchor_messages)
    log_prod = np.zeros(n_c)
    for m in anchor_messages:
        pos, z = m.anchor
        log_prod += error_model.loglik(z, np.linalg.norm(C - pos, axis=1))
    ok = _in_region(C, region) & np.isfinite(log_prod) & np.isfinite(log_mix)
    if not ok.any():
        return None, n_kernel
    w1 = np.zeros(n_c)
    raw = log_prod[ok] - log_mix[ok]
    w1[ok] = np.exp(raw - logsumexp(raw))
    idx = systematic_indices(w1 / w1.sum(), n, rng)
    return C[idx], n_kernel


def message_product(
    messages,
    rng: np.random.Generator,
    *,
    n_samples: int,
    region,
    proposal: str = "mixture",
    uniform_fraction: float = 0.1,
    error_model: RangeError | None = None,
    polygon=None,
    previous: Message | None = None,
    region_prior: bool = True,
    oversampling: int = 4,
) -> Product:
    """Importance-sampled product of incoming messages (message multiplication, POA-NBP
    eqs. (6)–(9)).

    Parameters
    ----------
    messages : sequence of Message
        Incoming messages (at least one); anchor messages are evaluated exactly.
    rng : numpy.random.Generator
    n_samples : int
        ``N_S``.
    region : (xmin, ymin, xmax, ymax)
        Support of the uniform prior and of the proposals' uniform parts.
    proposal : {"min_entropy", "mixture", "parsimonious", "polygon", "auxiliary"}
    uniform_fraction : float
        ``ε`` in [0, 1] of the mixture and parsimonious proposals.
    error_model : ExponentialRangeError or GaussianRangeError, optional
        For the anchor messages (default: exponential, mean 0.38 m).
    polygon : polygon object, optional
        Required by ``"polygon"`` (else uniform over the region).
    previous : Message, optional
        Previous belief, for ``"parsimonious"`` (None: uniform over the region).
    region_prior : bool
        Zero weight outside ``region`` (uniform prior, POA-NBP §III-B).
    oversampling : int
        ``L >= 1``: candidates per sample of the ``"auxiliary"`` proposal (4).

    Returns
    -------
    Product
    """
    v.choice("proposal", proposal, PROPOSALS)
    msgs = list(messages)
    if not msgs or not all(isinstance(m, Message) for m in msgs):
        raise ValidationError("messages", messages, "must be a non-empty sequence of Message")
    for q, m in enumerate(msgs):
        k = np.shape(m.samples)[0] if np.ndim(m.samples) == 2 else -1
        w = np.asarray(m.weights, dtype=np.float64)
        if k == 0 and m.anchor is not None and proposal in ("polygon", "parsimonious"):
            continue  # only the exact anchor likelihood is used
        if (
            k < 1
            or np.shape(m.samples) != (k, 2)
            or w.shape != (k,)
            or not np.all(np.isfinite(m.samples))
            or np.any(w < 0)
            or not w.sum() > 0
            or not (math.isfinite(m.bandwidth) and m.bandwidth > 0)
        ):
            raise ValidationError(
                f"messages[{q}]",
                f"Message with samples of shape {np.shape(m.samples)}",
                "needs samples [K >= 1, 2], weights [K] >= 0 with a positive sum, bandwidth > 0",
            )
    n = v.integer("n_samples", n_samples, minimum=1)
    eps = v.finite("uniform_fraction", uniform_fraction)
    if not 0.0 <= eps <= 1.0:
        raise ValidationError("uniform_fraction", eps, "must be in [0, 1]")
    if polygon is not None:
        _check_polygon(polygon)
    if not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", rng, "a numpy.random.Generator is required")
    oversampling = v.integer("oversampling", oversampling, minimum=1)
    return _product(
        msgs,
        n,
        proposal,
        rng,
        check_region(region),
        eps,
        check_error_model(error_model),
        polygon=polygon,
        previous=previous,
        region_prior=bool(region_prior),
        oversampling=oversampling,
    )


# ---------------------------------------------------------------------------------------------
# NBP
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class NBPOptions:
    """Options of :func:`run_nbp` (recipe table ``[localization.nbp]``).

    Parameters
    ----------
    n_samples : int
        ``N_S`` samples per belief and message (200).
    n_iterations : int
        ``N_iter`` message-passing iterations (10).
    proposal : {"min_entropy", "mixture", "parsimonious", "polygon", "auxiliary"}
        Importance-sampling proposal (module docstring). Default ``"mixture"``.
    support : {"none", "poa", "ellipse"}
        Support regions of the ``"polygon"`` proposal that the method computes from the
        measurements when the prior brings none (``StaticPrior.polygons``): ``"poa"`` the
        polygon outer-approximation (POA-NBP Algorithm 1, ``N_E = poa_n_edges``,
        ``N_FS = poa_n_fs``, offsets drawn from the run's generator first), ``"ellipse"`` the
        ellipse outer-approximation of ``poa_n_fs`` iterations, ``"none"`` (default) no
        support (the polygon proposal then needs ``StaticPrior.polygons``).
    poa_n_edges, poa_n_fs : int
        ``N_E >= 3`` and ``N_FS >= 1`` of the support (16, 2; POA-NBP §V-B).
    uniform_fraction : float
        ``ε`` of the mixture/parsimonious proposals, in [0, 1] (0.1).
    aux_oversampling : int
        ``L >= 1``: candidates per sample of the auxiliary proposal (4).
    bandwidth : {"lscv", "silverman"} or float
        Message KDE bandwidth rule or a fixed value [m] ("lscv").
    min_bandwidth_m : float
        Lower bound of every bandwidth [m] (0.01).
    lscv_max_samples : int
        Subset size of the LSCV score (256).
    jacobian_weights : bool
        Weight message samples by ``|z − ε|`` (True; False: equal weights, POA-NBP eq. (5)).
    link_mode : {"own", "both"}
        ``"own"``: agent ``j`` uses the ranges it measured, ``ẑ_{i→j}`` (distributed);
        ``"both"``: also ``ẑ_{j→i}`` (both factors of POA-NBP eq. (3)).
    region_prior : bool
        Uniform prior over the region (zero weight outside) (True).
    convergence_tol_m : float
        Mean estimate change [m] below which the run has converged (0.01).
    convergence_rel : float
        ... or the relative decrease of that change below which it has reached its Monte
        Carlo noise floor, in [0, 1) (0.25; 0 disables)
        (:func:`~phyloc.localization.static.static_ranges.convergence_iteration`).
    stop_on_convergence : bool
        End the run at the convergence iteration (False: run ``n_iterations``).
    """

    #: The recipe table of these options: ``[localization.nbp]``.
    recipe_section: ClassVar[str] = "nbp"

    n_samples: int = 200
    n_iterations: int = 10
    proposal: str = "mixture"
    support: str = "none"
    poa_n_edges: int = 16
    poa_n_fs: int = 2
    uniform_fraction: float = 0.1
    aux_oversampling: int = 4
    bandwidth: str | float = "lscv"
    min_bandwidth_m: float = 0.01
    lscv_max_samples: int = 256
    jacobian_weights: bool = True
    link_mode: str = "own"
    region_prior: bool = True
    convergence_tol_m: float = 0.01
    convergence_rel: float = 0.25
    stop_on_convergence: bool = False

    def __post_init__(self):
        for name, lo in (
            ("n_samples", 2),
            ("n_iterations", 1),
            ("lscv_max_samples", 8),
            ("poa_n_edges", 3),
            ("poa_n_fs", 1),
            ("aux_oversampling", 1),
        ):
            object.__setattr__(self, name, v.integer(name, getattr(self, name), minimum=lo))
        v.choice("proposal", self.proposal, PROPOSALS)
        v.choice("support", self.support, SUPPORTS)
        v.choice("link_mode", self.link_mode, LINK_MODES)
        eps = v.finite("uniform_fraction", self.uniform_fraction)
        if not 0.0 <= eps <= 1.0:
            raise ValidationError("uniform_fraction", eps, "must be in [0, 1]")
        object.__setattr__(self, "uniform_fraction", eps)
        if isinstance(self.bandwidth, str):
            v.choice("bandwidth", self.bandwidth, BANDWIDTH_RULES)
        else:
            object.__setattr__(self, "bandwidth", v.positive("bandwidth", self.bandwidth))
        for name in ("min_bandwidth_m", "convergence_tol_m"):
            object.__setattr__(self, name, v.positive(name, getattr(self, name)))
        rel = v.finite("convergence_rel", self.convergence_rel)
        if not 0.0 <= rel < 1.0:
            raise ValidationError("convergence_rel", rel, "must be in [0, 1)")
        object.__setattr__(self, "convergence_rel", rel)

    @classmethod
    def from_dict(cls, d: dict, section: str = "localization") -> NBPOptions:
        """Build from a recipe table; unknown keys are errors naming the closest valid key."""
        check_keys(d, [f.name for f in dataclasses.fields(cls)], section)
        return cls(**d)


def _check_polygons(polygons, net: StaticNetwork):
    """Map ``polygons`` (sequence over agents or over all nodes, or dict node → polygon) to a
    list over agents."""
    n_ag, n = net.n_agents, net.ranges.shape[0]
    if polygons is None:
        return [None] * n_ag
    if isinstance(polygons, dict):
        per = [polygons.get(int(j)) for j in net.agents]
    else:
        seq = list(polygons)
        if len(seq) == n_ag:
            per = seq
        elif len(seq) == n:
            per = [seq[j] for j in net.agents]
        else:
            raise ValidationError(
                "polygons", f"sequence of length {len(seq)}", f"must have {n_ag} (agents) or {n}"
            )
    out = []
    for a, p in enumerate(per):
        if p is not None:
            for attr in ("area", "contains", "sample_uniform"):
                if not hasattr(p, attr):
                    _check_polygon(p, f"polygons[{a}]")  # raises, naming the agent
            area = float(p.area)
            if not math.isfinite(area) or area < 0:
                raise ValidationError(f"polygons[{a}].area", area, "must be finite and >= 0")
            if area == 0.0:  # empty / point / segment: no density to sample from
                p = None
        out.append(p)
    return out


def _bandwidth(samples, weights, opt, rng):
    if isinstance(opt.bandwidth, float):
        h = opt.bandwidth
    elif opt.bandwidth == "silverman":
        h = _silverman(samples, weights)
    else:
        h = _lscv(samples, weights, rng, opt.lscv_max_samples)
    return max(h, opt.min_bandwidth_m)


def _support(meas: StaticMeasurements, prior: StaticPrior, opt: NBPOptions, rng):
    """Support regions of the polygon proposal, their setup time per agent [s] and their
    diagnostics (see :func:`run_nbp`)."""
    if prior.polygons is not None:
        diag = {
            "support": "prior",
            "support_operations_per_node": prior.polygon_operations_per_node,
            "support_floats_per_link_iteration": prior.polygon_floats_per_link_iteration,
        }
        return prior.polygons, prior.polygon_time_per_node_s, diag
    if opt.support == "poa":
        res = poa(
            meas.positions,
            meas.ranges,
            meas.is_anchor,
            rng=rng,
            n_edges=opt.poa_n_edges,
            n_iterations=opt.poa_n_fs,
            region=prior.region,
        )
        t = float(res.time_s.sum(axis=0).mean()) if meas.n_agents else 0.0
        diag = {
            "support": "poa",
            "poa_area_m2": res.area_history,
            "poa_time_per_node_s": t,
            "poa_dropped": res.dropped,
            "support_operations_per_node": res.operations_per_node,
            "support_floats_per_link_iteration": res.floats_per_link_iteration,
        }
        return list(res.polygons), t, diag
    if opt.support == "ellipse":
        t0 = time.perf_counter()
        ell = ellipse_outer_approximation(
            meas.positions,
            meas.ranges,
            meas.is_anchor,
            n_iterations=opt.poa_n_fs,
            region=prior.region,
        )
        t = (time.perf_counter() - t0) / max(meas.n_agents, 1)
        diag = {
            "support": "ellipse",
            "ellipse_area_m2": ell.area_history,
            "support_operations_per_node": 0.0,  # not counted
            # centre (2) and symmetric shape matrix (3) per broadcast, N_FS - 1 broadcasts
            "support_floats_per_link_iteration": 5.0 if opt.poa_n_fs > 1 else math.nan,
        }
        return ell.regions(), t, diag
    raise ValidationError(
        "polygons", None, "proposal='polygon' needs StaticPrior.polygons or a support option"
    )


def run_nbp(
    measurements: StaticMeasurements,
    prior: StaticPrior,
    rng: np.random.Generator,
    options: NBPOptions | None = None,
) -> Result:
    """Localize the agents of a static network with NBP (POA-NBP §II-B, §IV-B).

    Parameters
    ----------
    measurements : StaticMeasurements
        Ranges ``ranges[j, i] = ẑ_{i→j}``, anchors and their positions, error model.
    prior : StaticPrior
        ``region`` (support of the uniform prior) and, for ``proposal="polygon"``, optional
        precomputed support ``polygons`` (else ``options.support`` computes them). ``None``
        entries and degenerate polygons (area 0) fall back to the uniform proposal over the
        region.
    rng : numpy.random.Generator
        Draws, in order: the support (``support="poa"`` without prior polygons: the anchor
        polygon offsets), the initial beliefs, then per iteration and agent the messages,
        bandwidth subsets, proposal samples and resampling.
    options : NBPOptions, optional

    Returns
    -------
    Result
        ``estimates [n_iterations, n_agents, 2]``: the MMSE estimate (weighted mean) after
        each iteration (iteration 1 first; the initial uniform belief is not included);
        ``covariances [n_iterations, n_agents, 2, 2]``: the weighted sample covariance of
        each agent's last update (of its initial belief while never updated); ``particles
        [n_agents, N_S, 2]`` and ``log_weights [n_agents, N_S]``: the weighted samples of each
        agent's last update (``-inf`` = zero weight); ``timing``: ``step_s`` the wall time of
        each iteration, ``agent_s`` the mean time per agent update in it. ``diagnostics``:

        ``ess`` [n_iterations, n_agents]
            effective sample size of each update (0 where the agent was not updated);
        ``agent_time_s`` [n_iterations, n_agents]
            wall time of each agent's update [s];
        ``converged_iteration`` int or None
            :func:`~phyloc.localization.static.static_ranges.convergence_iteration`;
        ``setup_time_per_node_s`` float
            time per agent spent on the proposal support before the first iteration [s]
            (POA, ellipses, or ``prior.polygon_time_per_node_s``; 0 without support) — part of
            the time to convergence of POA-NBP Table I;
        ``floats_per_link_iteration`` float
            ``2·N_S``: floats an agent sends a neighbour per iteration (module docstring);
        ``kernel_evaluations`` [n_iterations, n_agents] int
            KDE kernel evaluations of each agent update (:attr:`Product.kernel_evaluations`);
        ``kde_operations_per_node`` float
            their sum over the iterations, mean over agents;
        ``support_operations_per_node``, ``support_floats_per_link_iteration`` float
            the support phase's operations per agent and floats per link and broadcast (0 and
            NaN without a support; from the prior's ``polygon_operations_per_node`` and
            ``polygon_floats_per_link_iteration`` with ``"prior"``);
        ``operations_per_node`` float
            ``kde_operations_per_node + support_operations_per_node``;
        ``support`` str
            ``"prior"``, ``"poa"``, ``"ellipse"`` or ``"none"``; with ``"poa"`` also
            ``poa_area_m2`` [N_FS, n_agents], ``poa_time_per_node_s``, ``poa_dropped``
            [k, 2] (dropped measurements ``(i, j)``); with ``"ellipse"`` ``ellipse_area_m2``.

    Examples
    --------
    >>> anchors = np.array([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0], [20.0, 20.0]])
    >>> z = np.full((5, 5), np.nan)  # node 4, an agent, measured its ranges to the anchors
    >>> z[4, :4] = [13.2, 17.2, 11.6, 16.0]
    >>> meas, prior = StaticMeasurements(z, [0, 1, 2, 3], anchors), StaticPrior((0, 0, 20, 20))
    >>> res = run_nbp(meas, prior, np.random.default_rng(3),
    ...               NBPOptions(n_samples=100, n_iterations=3))
    >>> res.estimates.shape, res.particles.shape
    ((3, 1, 2), (1, 100, 2))
    """
    t_wall = time.perf_counter()
    opt = options if options is not None else NBPOptions()
    if not isinstance(opt, NBPOptions):
        raise ValidationError("options", type(opt).__name__, "must be NBPOptions")
    meas, prior = check_inputs(measurements, prior, rng)
    net = meas.network
    reg = prior.region
    model = meas.error_model
    diag: dict = {
        "support": "none",
        "support_operations_per_node": 0.0,
        "support_floats_per_link_iteration": math.nan,
    }
    setup_s = 0.0
    polygons = None
    if opt.proposal == "polygon":
        polygons, setup_s, diag = _support(meas, prior, opt, rng)
    polys = _check_polygons(polygons, net)

    n_ag, ns = net.n_agents, opt.n_samples
    node_to_agent = {int(j): a for a, j in enumerate(net.agents)}
    links = [net.links(int(j), opt.link_mode) for j in net.agents]

    # initial beliefs: uniform over the region (or the agent's polygon)
    B = np.empty((n_ag, ns, 2))
    informed = np.zeros(n_ag, bool)
    for a in range(n_ag):
        if opt.proposal == "polygon" and polys[a] is not None:
            B[a] = np.asarray(polys[a].sample_uniform(ns, rng), dtype=np.float64).reshape(ns, 2)
            informed[a] = True
        else:
            B[a] = _uniform_region(ns, reg, rng)
    est = B.mean(axis=1)
    samples, weights = B.copy(), np.full((n_ag, ns), 1.0 / ns)
    cov = np.array([_weighted_cov(B[a], weights[a])[1] for a in range(n_ag)]).reshape(n_ag, 2, 2)

    L = opt.n_iterations
    out_est = np.empty((L, n_ag, 2))
    out_cov = np.empty((L, n_ag, 2, 2))
    out_t = np.zeros((L, n_ag))
    step_t = np.zeros(L)
    out_ess = np.zeros((L, n_ag))
    out_kernel = np.zeros((L, n_ag), dtype=np.int64)
    n_done = L
    for it in range(L):
        t_it = time.perf_counter()
        B_new, informed_new, est_new = B.copy(), informed.copy(), est.copy()
        for a in range(n_ag):
            t0 = time.perf_counter()
            prop = opt.proposal
            if prop == "parsimonious" and not informed[a]:
                prop = "mixture"  # the previous belief is still the uniform prior
            msgs = []
            for i, z in links[a]:
                if net.is_anchor[i]:
                    src = np.broadcast_to(net.positions[i], (ns, 2))
                    anchor = (net.positions[i], z)
                else:
                    b = node_to_agent[i]
                    if not informed[b]:
                        continue
                    src, anchor = B[b], None
                if anchor is not None and prop in ("polygon", "parsimonious"):
                    msgs.append(Message(np.zeros((0, 2)), np.zeros(0), 1.0, anchor))
                    continue  # the exact likelihood is all the product needs
                y, w = range_message_samples(src, z, model, rng, jacobian=opt.jacobian_weights)
                msgs.append(Message(y, w, _bandwidth(y, w, opt, rng), anchor))
            if msgs:
                prev = None
                if prop == "parsimonious":  # KDE of the weighted samples of the last update
                    h = max(_silverman(samples[a], weights[a]), opt.min_bandwidth_m)
                    prev = Message(samples[a], weights[a], h)
                prod = _product(
                    msgs,
                    ns,
                    prop,
                    rng,
                    reg,
                    opt.uniform_fraction,
                    model,
                    polygon=polys[a],
                    previous=prev,
                    region_prior=opt.region_prior,
                    oversampling=opt.aux_oversampling,
                )
                out_kernel[it, a] = prod.kernel_evaluations
                if prod.ok:
                    w = prod.weights
                    est_new[a] = w @ prod.samples
                    idx = systematic_indices(w / w.sum(), ns, rng)
                    B_new[a] = prod.samples[idx]
                    informed_new[a] = True
                    samples[a], weights[a] = prod.samples, w
                    cov[a] = _weighted_cov(prod.samples, w / w.sum())[1]
                    out_ess[it, a] = prod.ess
            out_t[it, a] = time.perf_counter() - t0
        B, informed, est = B_new, informed_new, est_new
        out_est[it] = est
        out_cov[it] = cov
        step_t[it] = time.perf_counter() - t_it
        if opt.stop_on_convergence and convergence_iteration(
            out_est[: it + 1], opt.convergence_tol_m, opt.convergence_rel
        ):
            n_done = it + 1
            break
    out_est, out_cov, out_t, out_ess, out_kernel = (
        out_est[:n_done],
        out_cov[:n_done],
        out_t[:n_done],
        out_ess[:n_done],
        out_kernel[:n_done],
    )
    kde_ops = float(out_kernel.sum(axis=0).mean()) if n_ag else 0.0
    diag.update(
        floats_per_link_iteration=float(2 * ns),
        kernel_evaluations=out_kernel,
        kde_operations_per_node=kde_ops,
        operations_per_node=kde_ops + float(diag["support_operations_per_node"]),
        ess=out_ess,
        agent_time_s=out_t,
        converged_iteration=convergence_iteration(
            out_est, opt.convergence_tol_m, opt.convergence_rel
        ),
        setup_time_per_node_s=setup_s,
    )
    with np.errstate(divide="ignore"):
        log_w = np.log(weights)
    return Result(
        estimates=out_est,
        covariances=out_cov,
        timing=Timing(
            wall_s=time.perf_counter() - t_wall,
            step_s=step_t[:n_done],
            agent_s=out_t.mean(axis=1) if n_ag else np.zeros(n_done),
            agent_iterations=n_done * n_ag,
        ),
        particles=samples,
        log_weights=log_w,
        diagnostics=diag,
        label=f"nbp.{opt.proposal}",
    )

"""NBP's messages and their importance-sampled product (POA-NBP eqs. (4)–(9), (21)).

A range link's message is a particle set (message filtering, POA-NBP eqs. (4), (5):
:func:`range_message_samples`, :class:`Message` with its KDE bandwidth), and an agent's
belief update is the product of its incoming messages, sampled by importance sampling from
one of the proposals of :data:`PROPOSALS` (message multiplication, POA-NBP eqs. (8), (9):
:func:`message_product`, :class:`Product`) — the polygon proposal of POA-NBP eq. (21) among
them. :mod:`phyloc.localization.static.nbp` describes the proposals and runs the iterations.

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization.particles import systematic_indices
from phyloc.localization.static.kde import _kde, _normalized_log, _weighted_cov, logsumexp
from phyloc.localization.static.static_ranges import RangeError, check_error_model, check_region

#: Proposal distributions of :func:`message_product` and
#: :class:`~phyloc.localization.static.nbp.NBPOptions`.
PROPOSALS = ("min_entropy", "mixture", "parsimonious", "polygon", "auxiliary")


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

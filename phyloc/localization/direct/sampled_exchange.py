"""Sample-based belief exchange: a neighbour is its particle set (DiPNet §V-B).

:class:`SampledLikelihood` (sample-based DPE / SAGE) is the nonparametric alternative to the
moment exchange of :mod:`phyloc.localization.direct.likelihoods`: a neighbour is its
*particle set* (:class:`NodeBeliefs`), and its message ``log Σ_i w_v^i p(r_uv | ‖x − x_v^i‖)``
carries the direct likelihood of DiPNet eq. (22) or the Gaussian ranging model through every
particle (DiPNet §V-B; DiPNet Table I, "Sampled SPAWN", cost O(Q_u·Q_v) per link). Its
kernels are :mod:`phyloc.localization.direct._sampled_kernels`.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import numpy as np

from phyloc.analysis.efim import equivalent_noise_variance
from phyloc.errors import ValidationError
from phyloc.localization import particles as P
from phyloc.localization.direct import _sampled_kernels as K
from phyloc.localization.direct.likelihoods import (
    DirectLikelihood,
    GaussianRangeLikelihood,
    MarginalDirectLikelihood,
)

SAMPLE_KERNELS = ("silverman", "none")
"""Kernels of :class:`SampledLikelihood`."""


class NodeBeliefs:
    """Every node's belief as weighted points, padded to one array (the sample-based exchange).

    Anchors are one point (their position) with log weight 0; agents are their particles with
    their normalized log weights. Rows beyond a node's count are padded with ``−inf`` weights.

    Attributes
    ----------
    points : [n_nodes, Q_max, dim] float64
    log_weights : [n_nodes, Q_max] float64
    count : [n_nodes] int64
    bandwidth2 : [n_nodes] float64
        Squared Gaussian kernel width per node [m²] by Silverman's rule,
        ``h² = (4/(n_eff(dim + 2)))^{2/(dim + 4)}·tr(C)/dim`` with the belief's weighted
        covariance ``C`` and effective sample size ``n_eff`` (0 for anchors and single points).
    """

    def __init__(self, centers, agent_nodes, particles, log_weights):
        centers = np.asarray(centers, dtype=np.float64)
        X = np.asarray(particles, dtype=np.float64)
        lw = np.asarray(log_weights, dtype=np.float64)
        n_nodes, dim = centers.shape
        n_agents, Q = lw.shape
        if X.shape != (n_agents, Q, dim) or len(agent_nodes) != n_agents:
            raise ValidationError(
                "particles",
                f"shape {X.shape}",
                f"[{len(agent_nodes)}, {Q}, {dim}] (one set per agent)",
            )
        self.points = np.zeros((n_nodes, max(Q, 1), dim))
        self.log_weights = np.full((n_nodes, max(Q, 1)), -np.inf)
        self.count = np.ones(n_nodes, np.int64)
        self.points[:, 0] = centers
        self.log_weights[:, 0] = 0.0
        self.points[agent_nodes, :Q] = X
        self.log_weights[agent_nodes, :Q] = lw
        self.count[agent_nodes] = Q
        self.bandwidth2 = np.zeros(n_nodes)
        if n_agents and Q > 1:
            lw_n, _ = P.normalize_log_weights(lw)
            _, cov = P.weighted_moments(X, lw_n)
            n_eff = P.effective_sample_size(lw_n)
            factor = (4.0 / (n_eff * (dim + 2))) ** (2.0 / (dim + 4))
            self.bandwidth2[agent_nodes] = factor * np.trace(cov, axis1=1, axis2=2) / dim

    @classmethod
    def single(cls, centers) -> NodeBeliefs:
        """Every node a Dirac at ``centers`` (the anchor case)."""
        c = np.asarray(centers, dtype=np.float64)
        return cls(c, np.zeros(0, np.int64), np.zeros((0, 1, c.shape[1])), np.zeros((0, 1)))


class SampledLikelihood:
    """Sample-based belief exchange (nonparametric message passing, DiPNet §V-B).

    The message of neighbour v at the particle ``x`` of agent u is the neighbour's belief
    particles carried through the link likelihood,

    .. math:: \\log m_{v\\to u}(x) = \\log \\sum_i w_v^i\\, p(r_{uv} \\mid \\|x - x_v^i\\|),

    with the one-path direct likelihood of DiPNet eq. (22) (``base`` a
    :class:`~phyloc.localization.direct.likelihoods.MarginalDirectLikelihood`, its peak-mixture
    form with the outlier floor, or a
    :class:`~phyloc.localization.direct.likelihoods.DirectLikelihood`, the interpolated table:
    sample-based DPE) or the Gaussian ranging model (``base`` a
    :class:`~phyloc.localization.direct.likelihoods.GaussianRangeLikelihood`: sample-based
    SAGE). Anchors are single
    particles, so a Dirac neighbour gives exactly the anchor likelihood. No ENV or ERV: the
    particles carry the neighbour's uncertainty. The cost is ``O(Q_u·Q_v)`` per link
    (DiPNet Table I, "Sampled SPAWN"), and ``Q_v·(dim + 1)`` floats cross the link per iteration
    (plus the kernel width, if the receiver does not recompute it from them).

    With ``kernel = "silverman"`` each neighbour particle is a Gaussian kernel
    ``N(y_v^i, h_v² I)`` (:attr:`NodeBeliefs.bandwidth2`, the kernel density estimate of
    nonparametric BP), folded into the link model along the link: the Gaussian ranging
    variance becomes ``var + h_v²``, the peak mixture is convolved with ``N(0, h_v²)`` (exact per
    component), the interpolated table's noise variance becomes the ENV of DiPNet eq. (26)
    with ``σ²_{v→uv} = h_v²``. Few particles with sharp likelihoods otherwise leave the
    message a comb of thin rings that the agent's own particles rarely meet. ``"none"`` is the
    Dirac exchange.

    Parameters
    ----------
    base : DirectLikelihood, MarginalDirectLikelihood or GaussianRangeLikelihood
        The link model; its ENV/ERV setting is ignored.
    kernel : {"silverman", "none"}
        Kernel of the neighbour particles.
    """

    kind = "sampled"
    exchange = "particles"

    def __init__(
        self,
        base: DirectLikelihood | MarginalDirectLikelihood | GaussianRangeLikelihood,
        kernel="silverman",
    ):
        if not isinstance(
            base, DirectLikelihood | MarginalDirectLikelihood | GaussianRangeLikelihood
        ):
            raise ValidationError(
                "base",
                type(base).__name__,
                "a DirectLikelihood, MarginalDirectLikelihood or GaussianRangeLikelihood",
            )
        if kernel not in SAMPLE_KERNELS:
            raise ValidationError("kernel", kernel, "one of " + ", ".join(SAMPLE_KERNELS))
        self.kernel = kernel
        self.base = base
        self.csr = base.csr
        self.nu = base.nu

    def loglik(self, particles, centers, covs, gamma=1.0, *, beliefs=None) -> np.ndarray:
        """``γ Σ_v log m_{v→u}(x)`` for every particle, ``[n_agents, Q]``.

        ``beliefs`` (:class:`NodeBeliefs`) are the neighbours' particle sets; None treats
        every neighbour as a Dirac at ``centers`` (the moment exchange's view).
        """
        b = NodeBeliefs.single(centers) if beliefs is None else beliefs
        out = np.empty(particles.shape[:2])
        base = self.base
        x = np.ascontiguousarray(particles, dtype=np.float64)
        s2 = b.bandwidth2[base.csr.tx] if self.kernel == "silverman" else np.zeros(base.csr.tx.size)
        if isinstance(base, MarginalDirectLikelihood):
            s2 = s2 * base.ways**2  # the table's distance axis is the round trip
            K.sampled_mixture_kernel(
                x,
                base.csr.offsets,
                base.csr.tx,
                base.pk_off,
                base.pk_d,
                base.pk_h,
                base.pk_c,
                s2,
                base._floors(s2),
                float(base.ways),
                b.points,
                b.log_weights,
                b.count,
                float(gamma),
                out,
            )
        elif isinstance(base, DirectLikelihood):
            env = equivalent_noise_variance(
                base.noise_var, s2 * base.ways**2, base.alpha_abs2, base.moment2, base.omega
            )
            K.sampled_direct_kernel(
                x,
                base.csr.offsets,
                base.csr.tx,
                base.rows,
                1.0 / (env * base.energy),
                b.points,
                b.log_weights,
                b.count,
                base.table.values,
                base.ways / base.table.spacing_m,
                base.order,
                float(gamma),
                out,
            )
        else:
            K.sampled_gauss_kernel(
                x,
                base.csr.offsets,
                base.csr.tx,
                base.ranges,
                1.0 / (base.var + s2),
                b.points,
                b.log_weights,
                b.count,
                float(gamma),
                out,
                base.outlier_nats,
                base.one_sided,
            )
        return out

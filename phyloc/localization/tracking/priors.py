"""Gaussian priors of the agent states at time 0, where every tracker of the family starts.

:class:`GaussianPrior` holds independent ``N(x̄_i^{(0)}, P_i^{(0)})`` per agent;
:func:`paper_prior` builds the truth-free prior of PF-BP eq. (31); :func:`sample_gaussian`
draws the initial particles of the particle trackers (PF-BP Algorithm 1, lines 1–4);
:func:`check_prior` validates a prior against the
:class:`~phyloc.localization.tracking.model.RangeModel` of a tracker.

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization.tracking._flow import robust_cholesky
from phyloc.localization.tracking.measurements import RangeMeasurements
from phyloc.localization.tracking.model import RangeModel


@dataclass(frozen=True, eq=False)
class GaussianPrior:
    """Independent Gaussian priors of the agent states at time 0, ``N(mean_i, cov_i)``.

    Parameters
    ----------
    mean : [n_agents, N_D] float64
        ``x̄_i^{(0)}``.
    cov : [n_agents, N_D, N_D] float64
        ``P_i^{(0)}`` (symmetric PSD; a singular block is jittered where it is factorized).
    label : str
        Describes the prior in results (e.g. ``"PF-BP eq. (31)"``).
    """

    mean: np.ndarray
    cov: np.ndarray
    label: str = ""

    def __post_init__(self):
        mean = v.finite_array("prior.mean", self.mean, ndim=2)
        cov = v.finite_array("prior.cov", self.cov, ndim=3)
        if cov.shape != (*mean.shape, mean.shape[1]):
            shape = (*mean.shape, mean.shape[1])
            raise ValidationError("prior.cov", f"array of shape {cov.shape}", f"must be {shape}")
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "cov", cov)


def paper_prior(
    measurements: RangeMeasurements,
    rng: np.random.Generator,
    *,
    sigma_p: float = 20.0,
    region_m=None,
    accel_init_factor: float = 10.0,
) -> GaussianPrior:
    """Gaussian prior of ``x^{(0)}`` of PF-BP eq. (31); it uses no truth.

    ``P_i^{(0)} = diag(σ_p² I, ΔT² σ_ainit² I, σ_ainit² I)`` with ``σ_ainit = 10 σ_a``; the
    velocity and acceleration means are drawn from ``N(0, P^{(0)})`` blocks, the position mean
    uniformly in the region (default: the bounding box of the anchors). Static model: only the
    position block.

    Parameters
    ----------
    measurements : RangeMeasurements
        Gives the model, the number of agents and the anchors.
    rng : numpy.random.Generator
        Draws the positions ``[n_agents, dim]`` then the other blocks.
    sigma_p : float
        σ_p [m] (PF-BP §VI: 20 m).
    region_m : float or [dim] float, optional
        Region ``[0, region_m]`` of the position means (default: the anchors' bounding box).
    accel_init_factor : float
        σ_ainit / σ_a (10).

    Returns
    -------
    GaussianPrior
        ``mean [n_agents, N_D]``, ``cov [n_agents, N_D, N_D]``.

    Examples
    --------
    >>> z = np.full((1, 2, 3), np.nan)
    >>> meas = RangeMeasurements(RangeModel(dim=2), np.zeros((1, 2)), z)
    >>> paper_prior(meas, np.random.default_rng(0)).cov.shape
    (2, 6, 6)
    """
    if not isinstance(measurements, RangeMeasurements):
        raise ValidationError(
            "measurements", type(measurements).__name__, "must be a RangeMeasurements"
        )
    m = measurements.model
    sp = v.positive("sigma_p", sigma_p)
    sai = v.positive("accel_init_factor", accel_init_factor, allow_zero=True) * m.accel_std
    var = [sp**2, (m.dt_s * sai) ** 2, sai**2][: m.order]
    diag = np.repeat(var, m.block_sizes)
    n = measurements.n_agents
    if region_m is None:
        if measurements.n_anchors == 0:
            raise ValidationError("region_m", None, "required when there are no anchors")
        lo, hi = measurements.anchor_bounds()
    else:
        lo, hi = np.zeros(m.dim), np.asarray(region_m, dtype=float) * np.ones(m.dim)
    mean = np.zeros((n, m.state_dim))
    mean[:, : m.dim] = rng.uniform(lo, hi, size=(n, m.dim))
    if m.order > 1:
        mean[:, m.dim :] = rng.normal(size=(n, m.state_dim - m.dim)) * np.sqrt(diag[m.dim :])
    cov = np.repeat(np.diag(diag)[None], n, axis=0)
    return GaussianPrior(mean, cov, label="PF-BP eq. (31)")


def sample_gaussian(mean: np.ndarray, cov: np.ndarray, n: int, rng: np.random.Generator):
    """``n`` draws per agent from ``N(mean_i, cov_i)``: ``[n_agents, n, N_D]``.

    ``mean [n_agents, N_D]``, ``cov [n_agents, N_D, N_D]`` (PSD; a singular block is jittered).
    """
    mean = v.finite_array("prior_mean", mean, ndim=2)
    cov = v.finite_array("prior_cov", cov, ndim=3)
    if cov.shape != (*mean.shape, mean.shape[1]):
        raise ValidationError(
            "prior_cov", f"array of shape {cov.shape}", f"must be {(*mean.shape, mean.shape[1])}"
        )
    L = np.stack([robust_cholesky(c) for c in cov])
    w = rng.standard_normal((mean.shape[0], n, mean.shape[1]))
    return mean[:, None, :] + np.einsum("aij,anj->ani", L, w)


def check_prior(prior, model, n_agents=None):
    """Validate a prior for ``model`` (and ``n_agents`` when given); returns float64 copies."""
    if not isinstance(prior, GaussianPrior):
        raise ValidationError("prior", type(prior).__name__, "must be a GaussianPrior")
    if not isinstance(model, RangeModel):
        raise ValidationError("model", type(model).__name__, "must be a RangeModel")
    n = prior.mean.shape[0] if n_agents is None else n_agents
    nd = model.state_dim
    if prior.mean.shape != (n, nd):
        raise ValidationError(
            "prior.mean", f"array of shape {prior.mean.shape}", f"must be ({n}, {nd})"
        )
    return prior.mean.copy(), prior.cov.copy()

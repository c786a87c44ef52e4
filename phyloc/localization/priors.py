"""Gaussian priors of the particle filters, around a coarse solution or an informed start.

:func:`gaussian_priors` draws each agent's particles from ``N(c_u, σ_u² I)`` and
:func:`gaussian_log_prior` evaluates that density. The centres ``c_u`` are the truth-free
coarse positions (:func:`phyloc.localization.initialization.coarse_positions`, the default)
or those of the **informed start** (:func:`informed_centers`), which perturbs the true
positions: every output computed from it must say "informed start" (scenario tokens
``*_informed``).

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization import _kernels

INFORMED_START_STD_M = 10.0
"""Default σ0 [m] of the informed start (:func:`informed_centers`)."""


def _rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", type(rng).__name__, "must be a numpy.random.Generator")
    return rng


def _std_per_agent(std_m, n_agents: int) -> np.ndarray:
    s = np.asarray(std_m, dtype=np.float64)
    if s.ndim == 0:
        s = np.full(n_agents, float(s))
    if s.shape != (n_agents,):
        raise ValidationError("std_m", f"array of shape {s.shape}", f"scalar or ({n_agents},)")
    if not np.all(np.isfinite(s) & (s > 0)):
        raise ValidationError("std_m", std_m, "standard deviations must be finite and > 0 [m]")
    return s


def _centers(centers) -> np.ndarray:
    c = v.finite_array("centers", centers, ndim=2)
    if c.shape[1] not in (2, 3):
        raise ValidationError("centers", f"array of shape {c.shape}", "must be [n_agents, 2|3]")
    return c


def gaussian_priors(centers, std_m, Q, rng) -> np.ndarray:
    """Particles from isotropic Gaussian priors ``p_u ~ N(c_u, σ_u² I)``.

    Parameters
    ----------
    centers : [n_agents, dim] float64
        Prior means [m]: coarse positions
        (:func:`~phyloc.localization.initialization.coarse_positions`, truth-free) or
        :func:`informed_centers` (informed start).
    std_m : float or [n_agents] float64
        Prior standard deviation σ_u per axis [m], > 0.
    Q : int
        Particles per agent (>= 1).
    rng : numpy.random.Generator

    Returns
    -------
    particles : [n_agents, Q, dim] float64
        [m]. Their log prior density is :func:`gaussian_log_prior`.

    Examples
    --------
    >>> x = gaussian_priors(np.zeros((2, 2)), 5.0, 1000, np.random.default_rng(0))
    >>> x.shape
    (2, 1000, 2)
    """
    c = _centers(centers)
    s = _std_per_agent(std_m, c.shape[0])
    q = v.integer("Q", Q, minimum=1)
    noise = _rng(rng).standard_normal((c.shape[0], q, c.shape[1]))
    return c[:, None, :] + s[:, None, None] * noise


def gaussian_log_prior(particles, centers, std_m) -> np.ndarray:
    """Log density of the priors of :func:`gaussian_priors` at the particles.

    .. math:: \\ln N(x; c_u, σ_u^2 I) = −\\frac{\\|x − c_u\\|^2}{2σ_u^2}
              − \\frac{\\dim}{2}\\ln(2πσ_u^2)

    Parameters
    ----------
    particles : [n_agents, Q, dim] float64
        [m].
    centers : [n_agents, dim] float64
        [m].
    std_m : float or [n_agents] float64
        [m], > 0.

    Returns
    -------
    log_prior : [n_agents, Q] float64
        Normalized log density [log 1/m^dim] (finite everywhere).
    """
    c = _centers(centers)
    x = v.finite_array("particles", particles, ndim=3)
    if x.shape[0] != c.shape[0] or x.shape[2] != c.shape[1]:
        raise ValidationError(
            "particles", f"array of shape {x.shape}", f"must be [{c.shape[0]}, Q, {c.shape[1]}]"
        )
    s = _std_per_agent(std_m, c.shape[0])
    out = np.empty(x.shape[:2])
    _kernels.gaussian_log_prior_kernel(
        np.ascontiguousarray(x, dtype=np.float64),
        np.ascontiguousarray(c, dtype=np.float64),
        np.ascontiguousarray(s, dtype=np.float64),
        out,
    )
    return out


def informed_centers(true_positions, std_m=INFORMED_START_STD_M, *, rng) -> np.ndarray:
    """Prior centres of the **informed start**: ``p + N(0, σ0² I)``.

    This initialization uses the true positions: it is a diagnostic (how good is the filter
    once near the truth?), not a localization method. Every result computed from it must be
    labelled "informed start" (scenario tokens ``*_informed``); the truth-free default is
    :func:`~phyloc.localization.initialization.coarse_positions`.

    Parameters
    ----------
    true_positions : [..., dim] float64
        Positions to perturb [m] (usually the agents' true positions).
    std_m : float
        σ0 [m], >= 0. Default 10 m (:data:`INFORMED_START_STD_M`).
    rng : numpy.random.Generator
        Keyword-only.

    Returns
    -------
    centers : like ``true_positions``, float64 [m]
    """
    p = v.finite_array("true_positions", true_positions)
    if p.ndim < 1:
        raise ValidationError("true_positions", "a scalar", "must be an array [..., dim]")
    s = v.positive("std_m", std_m, allow_zero=True)
    return p + s * _rng(rng).standard_normal(p.shape)

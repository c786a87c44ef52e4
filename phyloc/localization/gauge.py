"""Uninformative anchor-free gauge priors (kept to show DiPNet's collapse from them).

An anchor-free network is determined only up to a rigid transform; :func:`gauge_priors` remove
the gauge freedom by convention (agent 0 at the origin, agent 1 on the positive x-axis, agent 2
in the upper half-plane, the rest uniform) and :func:`gauge_log_prior` evaluates their
uniform density. Run from these priors DiPNet Algorithm 1 collapses; they are kept to show
that, not to be used for results (the default start is
:func:`phyloc.localization.initialization.coarse_positions`).

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


def _rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", type(rng).__name__, "must be a numpy.random.Generator")
    return rng


def _dim(dim) -> int:
    d = v.integer("dim", dim, minimum=1)
    if d not in (2, 3):
        raise ValidationError("dim", dim, "must be 2 or 3")
    return d


def gauge_priors(n_agents, dim, Q, extent_m, rng) -> np.ndarray:
    """Uninformative anchor-free gauge priors (kept to show DiPNet's collapse from them).

    An anchor-free network is determined only up to a rigid transform; these priors remove the
    gauge freedom by convention, with support (``e = extent_m``):

    - agent 0: the origin (a Dirac: all particles exactly at 0) — fixes translation;
    - agent 1: the positive x-axis, ``x ~ U(0, e)``, other coordinates 0 — fixes rotation in
      2-D (and two rotation angles in 3-D);
    - agent 2: the upper half-plane ``y ~ U(0, e)``, ``x ~ U(−e, e)`` (in 3-D: ``z = 0``, i.e.
      the half-plane ``{y >= 0, z = 0}``) — fixes the reflection in 2-D (and the last rotation
      angle in 3-D);
    - 3-D only, agent 3: ``z ~ U(0, e)`` (upper half-space), ``x, y ~ U(−e, e)`` — fixes the
      reflection in 3-D;
    - every other agent: uniform on ``[−e, e]^dim``.

    Choose ``e`` at least the network diameter (e.g. ``√dim ×`` the region side), otherwise the
    true relative configuration lies outside the support. The density is uniform on the
    support; :func:`gauge_log_prior` evaluates it.

    Parameters
    ----------
    n_agents : int
        >= 1 (agents 3, … in 2-D and 4, … in 3-D are uniform on the cube).
    dim : int
        2 or 3.
    Q : int
        Particles per agent (>= 1).
    extent_m : float
        e [m], > 0.
    rng : numpy.random.Generator

    Returns
    -------
    particles : [n_agents, Q, dim] float64
        [m].
    """
    n = v.integer("n_agents", n_agents, minimum=1)
    d = _dim(dim)
    q = v.integer("Q", Q, minimum=1)
    e = v.positive("extent_m", extent_m)
    g = _rng(rng)
    x = g.uniform(-e, e, size=(n, q, d))
    x[0] = 0.0
    if n > 1:
        x[1] = 0.0
        x[1, :, 0] = g.uniform(0.0, e, size=q)
    if n > 2:
        x[2, :, 1] = g.uniform(0.0, e, size=q)
        if d == 3:
            x[2, :, 2] = 0.0
    if n > 3 and d == 3:
        x[3, :, 2] = g.uniform(0.0, e, size=q)
    return x


def gauge_log_prior(particles, extent_m, *, atol_m=None) -> np.ndarray:
    """Unnormalized log density of :func:`gauge_priors`: 0 on the support, ``-inf`` outside.

    Equality constraints (agent 0 at the origin, agent 1's off-axis coordinates, agent 2's z in
    3-D) hold within ``atol_m`` (default ``1e-9·extent_m``). Callers must treat ``-inf`` with
    care: a particle outside the support has zero prior weight, and an agent whose particles all
    lie outside has no valid belief (do not normalize ``-inf − (-inf)``).

    Parameters
    ----------
    particles : [n_agents, Q, dim] float64
        [m], dim 2 or 3.
    extent_m : float
        e [m], > 0, as given to :func:`gauge_priors`.
    atol_m : float, optional
        Tolerance of the equality constraints [m], >= 0.

    Returns
    -------
    log_prior : [n_agents, Q] float64
        0.0 or ``-inf``.
    """
    x = v.finite_array("particles", particles, ndim=3)
    d = _dim(x.shape[2])
    e = v.positive("extent_m", extent_m)
    tol = 1e-9 * e if atol_m is None else v.positive("atol_m", atol_m, allow_zero=True)
    n = x.shape[0]
    inside = np.all(np.abs(x) <= e + tol, axis=2)
    if n > 0:
        inside[0] &= np.all(np.abs(x[0]) <= tol, axis=1)
    if n > 1:
        inside[1] &= (x[1, :, 0] >= -tol) & np.all(np.abs(x[1, :, 1:]) <= tol, axis=1)
    if n > 2:
        inside[2] &= x[2, :, 1] >= -tol
        if d == 3:
            inside[2] &= np.abs(x[2, :, 2]) <= tol
    if n > 3 and d == 3:
        inside[3] &= x[3, :, 2] >= -tol
    return np.where(inside, 0.0, -np.inf)

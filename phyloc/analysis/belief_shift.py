"""Belief shift under a wrong distance: DiPNet's SCF likelihood against a Gaussian two-step model.

DiPNet §IV-B: an agent with a Gaussian position belief ``N(0, σ0²)`` (in 1-D along the link, by
Lemma 1) receives a link whose measurement function peaks at a distance offset δ. The new
log-belief is ``h(x) = g(x) + z(x)`` (DiPNet eq. (45)), ``g(x) = −x²/(2σ0²)``, and

* DiPNet: ``z(x) = SNR · D((x − δ)/c0)² / N`` (DiPNet (V.1)), ``D`` the periodic sinc (Dirichlet
  kernel) of ``N`` subcarriers: in units of the sample distance ``c0/B`` (``u = x B / c0``),
  ``D = sin(π(u − δ)) / sin(π(u − δ)/N)``;
* two-step: ``z(x) = −(x − δ)²/(2 CRB)``, a Gaussian range biased by δ with the ranging CRB as
  variance (DiPNet (46a)).

``ν = CRB/σ0²`` is the ratio of the measurement and a-priori uncertainties (DiPNet (VI.4)):
``CRB = 1/(−z''(δ))`` at the main peak. Scaling ``h`` by ``σ0²`` shows that the maximizer,
in units of ``c0/B``, depends only on δ, ν and N. The *shift* is that of the maximum of ``h``
reached by ascent from the true position ``x = 0`` (what a filter sitting at the truth moves
to), found exactly in 1-D (grid, then Brent's method on ``h'``); the global maximum is reported
too. Bounds: Theorem 1 (``ϱ_κ``, DiPNet App. V) and Theorem 2 (DiPNet eq. (46), App. VI).

All distances here are in units of ``c0/B``.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.reporting import new_figure, save_figure

#: DiPNet §V-A: N = 2569 subcarriers.
DEFAULT_N = 2569
_STEP = 1e-3  # ascent grid [c0/B]


def _check(nu, n_subcarriers):
    nu = v.positive("nu", nu)
    n = v.integer("n_subcarriers", n_subcarriers, minimum=2)
    return nu, n


def _dirichlet2(w, n):
    """``D(w)²/N`` at ``w`` [c0/B] (periodic sinc, exact; L'Hôpital where ``sin(πw/N) = 0``)."""
    a = np.pi * np.asarray(w, dtype=float)
    s, sn = np.sin(a), np.sin(a / n)
    small = np.abs(sn) < 1e-12  # at the peaks only: the limit is exact to O(1e-24) there
    safe = np.where(small, 1.0, sn)
    D = np.where(small, n * np.cos(a) / np.where(small, np.cos(a / n), 1.0), s / safe)
    return D * D / n


def _curvature_at_peak(n):
    """``−(D²/N)''`` at ``w = 0``: ``(2π²/3)(N² − 1)/N`` (from ``D ≈ N(1 − π²w²(1 − 1/N²)/6)``)."""
    return (2.0 * np.pi**2 / 3.0) * (n * n - 1.0) / n


def log_belief(u, delta, nu=1.0, n_subcarriers=DEFAULT_N, model="dipnet"):
    """``σ0² h(u)`` of DiPNet eq. (45) at positions ``u`` [c0/B] (up to a constant).

    Parameters
    ----------
    u : array_like
        Positions along the link [c0/B].
    delta : float
        Distance offset δ [c0/B].
    nu : float
        ν = CRB/σ0² (> 0).
    n_subcarriers : int
        N (DiPNet §V-A: 2569).
    model : {"dipnet", "two_step"}

    Examples
    --------
    >>> float(log_belief(0.0, 0.0, model="two_step"))
    -0.0
    """
    nu, n = _check(nu, n_subcarriers)
    v.choice("model", model, ("dipnet", "two_step"))
    u = np.asarray(u, dtype=float)
    if model == "two_step":
        return -0.5 * u * u - 0.5 * (u - delta) ** 2 / nu
    k = 1.0 / (nu * _curvature_at_peak(n))
    return -0.5 * u * u + k * _dirichlet2(u - delta, n)


def _ascent_maximum(delta, nu, n):
    """The local maximum of ``h`` reached by ascent from 0 (exact: grid, then Brent).

    Where the truth sits exactly at a zero of the likelihood (integer δ) and that point is not
    a maximum of ``h``, both directions ascend; the smaller shift is returned, the convention of
    Theorem 1's ``κ = ⌊|δ|⌋ + 1``.
    """

    def h(x):
        return float(log_belief(x, delta, nu, n))

    def dh(x, e=1e-6):
        return (h(x + e) - h(x - e)) / (2 * e)

    def climb(direction):
        x, d_prev = 0.0, direction
        step = direction * _STEP
        limit = abs(delta) + 4.0
        while abs(x) < limit:
            x_next = x + step
            d_next = dh(x_next)
            if (d_next > 0) != (d_prev > 0) or d_next == 0.0:
                return brentq(dh, min(x, x_next), max(x, x_next), xtol=1e-12)
            x, d_prev = x_next, d_next
        return x  # not reached: the Gaussian prior turns h down

    d0 = dh(0.0)
    if abs(d0) < 1e-8:  # the truth sits at a stationary point of h (round-off level)
        if h(1e-4) + h(-1e-4) - 2 * h(0.0) < 0:
            return 0.0  # a maximum: no shift
        return min(climb(1.0), climb(-1.0), key=abs)
    return climb(1.0 if d0 > 0 else -1.0)


def _global_maximum(delta, nu, n):
    lo, hi = min(0.0, delta) - 2.0, max(0.0, delta) + 2.0
    grid = np.arange(lo, hi, _STEP)
    vals = log_belief(grid, delta, nu, n)
    i = int(np.argmax(vals))
    res = minimize_scalar(
        lambda x: -float(log_belief(x, delta, nu, n)),
        bounds=(grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]),
        method="bounded",
        options={"xatol": 1e-12},
    )
    return float(res.x)


def belief_shift(delta, nu=1.0, n_subcarriers=DEFAULT_N, model="dipnet"):
    """Shift of the belief maximum for distance offsets δ (DiPNet §IV-B, Fig. 3) [c0/B].

    Parameters
    ----------
    delta : float or array_like
        Distance offsets δ [c0/B] (finite).
    nu : float
        ν = CRB/σ0².
    n_subcarriers : int
    model : {"dipnet", "two_step"}
        ``two_step`` is exactly ``δ/(1 + ν)`` (DiPNet (46a) holds with equality).

    Returns
    -------
    ascent : ndarray
        ``|x_ox|``, the maximum reached by ascent from the true position.
    global_max : ndarray
        ``|x|`` of the global maximum of ``h``.

    Examples
    --------
    >>> a, g = belief_shift([0.5, 10.0], nu=1.0)
    >>> bool(a[0] < 0.5 / 2 + 1e-9), bool(a[1] < 0.1)
    (True, True)
    """
    nu, n = _check(nu, n_subcarriers)
    v.choice("model", model, ("dipnet", "two_step"))
    d = np.atleast_1d(np.asarray(delta, dtype=float))
    if not np.all(np.isfinite(d)):
        raise ValidationError("delta", "non-finite", "finite distance offsets [c0/B]")
    if model == "two_step":
        s = np.abs(d) / (1.0 + nu)
        return s, s.copy()
    asc = np.array([abs(_ascent_maximum(x, nu, n)) for x in d])
    glob = np.array([abs(_global_maximum(x, nu, n)) for x in d])
    return asc, glob


def _sidelobe_max(delta, j, n):
    """``γ_j``: the j-th maximum of ``D²`` to the left of the main peak at δ (γ_0 = δ)."""
    if j == 0:
        return float(delta)
    res = minimize_scalar(
        lambda x: -float(_dirichlet2(x - delta, n)),
        bounds=(delta - j - 1.0, delta - j),
        method="bounded",
        options={"xatol": 1e-12},
    )
    return float(res.x)


def theorem1_bound(delta, n_subcarriers=DEFAULT_N):
    """``ϱ_κ = |γ_{κ−1} − x_κ|`` of Theorem 1 (DiPNet App. V), ``κ = ⌊|δ|⌋ + 1`` [c0/B].

    Decreases from ``ϱ_1 = 1`` (``c0/B``) towards ``1/2`` (``c0/2B``).

    Examples
    --------
    >>> [round(float(r), 3) for r in theorem1_bound([0.5, 1.5, 30.5])]
    [1.0, 0.57, 0.503]
    """
    n = v.integer("n_subcarriers", n_subcarriers, minimum=2)
    d = np.abs(np.atleast_1d(np.asarray(delta, dtype=float)))
    if not np.all(np.isfinite(d)):
        raise ValidationError("delta", "non-finite", "finite distance offsets [c0/B]")
    out = np.empty(d.size)
    for i, x in enumerate(d):
        kappa = math.floor(x) + 1
        out[i] = _sidelobe_max(x, kappa - 1, n) - (x - kappa)
    return out


def theorem2_bound(delta, nu=1.0, n_subcarriers=DEFAULT_N):
    """The bound of Theorem 2, DiPNet eq. (46) [c0/B]:
    ``|δ|/(1 + ν)`` for ``|δ| < 1``, ``ϱ_κ / (1 + ν/(3ρ²(1 + ρ²)))`` with
    ``ρ = 1/(π(|δ| − ϱ_κ))`` otherwise.

    Examples
    --------
    >>> float(theorem2_bound(0.5, nu=1.0)[0])
    0.25
    """
    nu, n = _check(nu, n_subcarriers)
    d = np.abs(np.atleast_1d(np.asarray(delta, dtype=float)))
    rho_k = theorem1_bound(d, n)
    out = d / (1.0 + nu)
    big = d >= 1.0
    rho = 1.0 / (np.pi * (d[big] - rho_k[big]))
    out[big] = rho_k[big] / (1.0 + nu / (3.0 * rho**2 * (1.0 + rho**2)))
    return out


def figure3(nu=1.0, n_subcarriers=DEFAULT_N, delta_max=20.0, n_points=401):
    """The data of DiPNet Fig. 3 and its summary numbers.

    Returns
    -------
    dict
        ``series``: ``delta``, ``dipnet`` (ascent shift), ``dipnet_global``, ``bound``
        (Theorem 2), ``theorem1``, ``two_step``, all [c0/B] on a grid of δ in
        ``[0, delta_max]``; ``figures``: ``max_over_c0_b``, ``argmax_delta_over_c0_b``,
        ``at_10_over_c0_b`` (at δ = 10 exactly the truth sits at a zero of the likelihood),
        ``max_10_to_11_over_c0_b`` (largest shift for δ in [10, 11]),
        ``two_step_at_10_over_c0_b``, ``bound_violations``.
    """
    nu, n = _check(nu, n_subcarriers)
    dmax = v.positive("delta_max", delta_max)
    m = v.integer("n_points", n_points, minimum=2)
    delta = np.linspace(0.0, dmax, m)
    asc, glob = belief_shift(delta, nu, n)
    bound = theorem2_bound(delta, nu, n)
    two, _ = belief_shift(delta, nu, n, model="two_step")
    i = int(np.argmax(asc))
    at10 = belief_shift([10.0], nu, n)[0][0]
    beyond = belief_shift(np.linspace(10.0, 11.0, 101), nu, n)[0]
    figures = {
        "max_over_c0_b": float(asc[i]),
        "argmax_delta_over_c0_b": float(delta[i]),
        "at_10_over_c0_b": float(at10),
        "max_10_to_11_over_c0_b": float(beyond.max()),
        "two_step_at_10_over_c0_b": 10.0 / (1.0 + nu),
        "bound_violations": int(np.sum(asc > bound + 1e-9)),
    }
    series = {
        "delta": delta,
        "dipnet": asc,
        "dipnet_global": glob,
        "bound": bound,
        "theorem1": theorem1_bound(delta, n),
        "two_step": two,
    }
    return {"figures": figures, "series": series}


def plot_figure3(result: dict, path, nu: float) -> None:
    """DiPNet Fig. 3: belief shift against δ for DiPNet, its bound, the two-step model, one
    sample."""
    s = result["series"]
    fig, ax = new_figure(size=(7.5, 4.5))
    ax.plot(s["delta"], s["dipnet"], color="C0", label="DiPNet (ascent from the truth)")
    ax.plot(s["delta"], s["bound"], color="C3", label="Theorem 2 bound, DiPNet eq. (46)")
    ax.plot(s["delta"], s["two_step"], color="C2", label="two-step Gaussian, δ/(1 + ν)")
    ax.axhline(1.0, color="k", lw=0.8, label="one sample, c0/B")
    ax.set_ylim(0.0, 1.5)
    ax.set_xlabel("distance offset δ [c0/B]")
    ax.set_ylabel("belief shift |x_ox| [c0/B]")
    ax.set_title(f"Belief shift (DiPNet Fig. 3), ν = {nu:g}")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    save_figure(fig, path)

"""Concavity indicator of DiPNet's expected log-belief in multipath, for any channel scenario.

DiPNet §IV-A asks whether, for an agent with many neighbours, the expected log-belief (the
expected SCF, DiPNet eq. (35)) still has a local maximum at the true position when links carry
multipath and NLOS bias. With the path cross-correlation a Dirichlet kernel ``D`` (DiPNet
eq. (36)), the curvature of the θ-averaged ``D²`` of a path with excess delay ``x = δ_l + b`` at
the true position is (DiPNet eq. (40))::

    D̈²(x) = −π Σ_{m,n} (S²ω² + jSω/τ0) e^{jSωx},   S = m + n,   τ0 = d0/c0,

which is ``−πω²N²(N²−1)/6`` for the LOS path (DiPNet eq. (41)). The true position is a maximum
iff the concavity indicator of DiPNet eq. (42) is negative. Everything here is *normalized to the
expected direct-path power of a LOS link*, so that::

    CCI(d0) = [Σ_paths E[A_l D̈²(x_l)] / |D̈²(0)|] / E[A_0 | LOS]
            = ς̃(d0)/E[A_0 | LOS] − P_LOS(d0),

where the direct path contributes exactly ``−P_LOS(d0)``: the AWGN benchmark of DiPNet Fig. 2.
Three evaluations, for any scenario file:

* :func:`cci_bound` — the upper bound for arbitrary δ_l and b, DiPNet eqs. (43)–(44):
  ``(1 + c0/(πBd0))·M(d0) − P_LOS(d0)``, with ``M`` the expected power of all other paths;
* :func:`cci_exponential` — the closed form for exponential δ_l and b, DiPNet App. III,
  eqs. (III.1)–(III.3), with rates from the scenario's delay spread and NLOS bias;
* :func:`cci_monte_carlo` — the mean of the exact per-path curvature over links drawn by
  :func:`phyloc.channels.draw_links` (the check that ties the formulas to the simulator).

The expected powers (:func:`expected_powers`) come from the scenario's P_LOS, path loss,
shadow fading and K-factor (lognormal, with the tabulated SF–K correlation, by Gauss–Hermite
quadrature), exactly as the sampler draws them.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

WINNER II: IST-4-027756 WINNER II Deliverable D1.1.2 V1.2, Part I (channel models), 2007,
updated 2008; the table each value of the shipped channel files comes from is given in
``channels/PROVENANCE.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from phyloc import _validate as v
from phyloc.channels import draw_links, load_scenario
from phyloc.channels.scenario import AwgnCondition, ExponentialCondition, Winner2Condition
from phyloc.errors import ValidationError
from phyloc.phy.system import C0, OFDMSystem

#: Default d0 range of DiPNet Fig. 2 [m].
D0_RANGE_M = (0.1, 1000.0)
_SERIES_LIMIT = 0.1  # |N ω x| below which the Taylor series of D² is used
_SERIES_TERMS = 7
_GH_NODES = 48


# -- the curvature of one path (DiPNet eqs. (36), (40), (41)) ----------------------------------
def los_curvature(n_subcarriers: int, subcarrier_spacing_hz: float) -> float:
    """``D̈₀² = −πω²N²(N²−1)/6``: curvature of the θ-averaged ``D²`` of the LOS path.

    DiPNet eq. (41); ``ω = 2π f_sc``.

    Examples
    --------
    >>> c = los_curvature(3, 1.0)   # -π (2π)² 9·8/6
    >>> bool(np.isclose(c, -np.pi * (2 * np.pi) ** 2 * 12))
    True
    """
    n = float(n_subcarriers)
    w = 2.0 * math.pi * subcarrier_spacing_hz
    return -math.pi * w * w * n * n * (n * n - 1.0) / 6.0


def _moments(n: int) -> np.ndarray:
    """``M_{2k} = Σ_{m,n}(m+n)^{2k} = Σ_S (N−|S|) S^{2k}`` for k = 1 … terms (exact integers)."""
    s = np.arange(1, n, dtype=object)
    w = n - s
    return np.array(
        [float(2 * int(np.sum(w * s ** (2 * k)))) for k in range(1, _SERIES_TERMS + 2)],
        dtype=np.float64,
    )


def normalized_curvature(excess_delay_s, los_delay_s, n_subcarriers, subcarrier_spacing_hz):
    """``D̈²(x)/|D̈₀²|``: the curvature of one path relative to that of the LOS path.

    For a path with excess delay ``x = δ_l + b`` of a link with LOS delay ``τ0 = d0/c0``,
    DiPNet eq. (40) divided by ``|D̈₀²|`` of eq. (41). With ``D(x) = sin(Nωx/2)/sin(ωx/2)``
    (DiPNet eq. (36)) it equals ``[(D²)''(x) − (D²)'(x)/τ0] / (ω²N²(N²−1)/6)``; it is −1 at
    ``x = 0`` and at most ``1 + 2/(Nωτ0) = 1 + c0/(πBd0)`` (DiPNet eq. (43)). Evaluated in
    closed form, and by the Taylor series of ``D²`` where ``|Nωx| < 0.1`` (exact to rounding).

    Parameters
    ----------
    excess_delay_s : array_like
        ``x`` [s], any real values.
    los_delay_s : array_like
        ``τ0`` [s], > 0, broadcast against ``excess_delay_s``.
    n_subcarriers : int
        N.
    subcarrier_spacing_hz : float
        ``f_sc`` [Hz]; ``ω = 2π f_sc``.

    Returns
    -------
    numpy.ndarray
        The normalized curvature, broadcast shape.

    Examples
    --------
    >>> round(float(normalized_curvature(0.0, 1e-7, 2569, 14.65e3)), 12)
    -1.0
    """
    n = v.integer("n_subcarriers", n_subcarriers, minimum=2)
    f_sc = v.positive("subcarrier_spacing_hz", subcarrier_spacing_hz)
    x, tau0 = np.broadcast_arrays(
        np.asarray(excess_delay_s, dtype=np.float64), np.asarray(los_delay_s, dtype=np.float64)
    )
    shape = x.shape
    x, tau0 = x.ravel(), tau0.ravel()
    w = 2.0 * math.pi * f_sc
    scale = w * w * n * n * (n * n - 1.0) / 6.0
    # closed form: u = ωx/2, D = sin(Nu)/sin(u); derivatives in u, then d/dx = (ω/2) d/du
    u = 0.5 * w * x
    s, c = np.sin(u), np.cos(u)
    sn, cn = np.sin(n * u), np.cos(n * u)
    small = np.abs(n * w * x) < _SERIES_LIMIT
    near_pole = np.abs(s) < 1e-6  # x near a multiple of 1/f_sc: D has a removable singularity
    use_sum = near_pole & ~small
    ss = np.where(small | near_pole, 1.0, s)
    d = sn / ss
    n1 = n * cn * ss - sn * c
    du = n1 / (ss * ss)
    duu = sn * (1.0 - n * n) / ss - 2.0 * c * n1 / (ss**3)
    d2_x = w * d * du  # (D²)'
    d2_xx = 0.5 * w * w * (du * du + d * duu)  # (D²)''
    out = (d2_xx - d2_x / tau0) / scale
    if small.any():
        out[small] = _curvature_series(x[small], tau0[small], n, w) / scale
    if use_sum.any():
        out[use_sum] = _curvature_sum(x[use_sum], tau0[use_sum], n, w) / scale
    return out.reshape(shape)


def _curvature_series(x, tau0, n, w):
    """``(D²)'' − (D²)'/τ0`` by the Taylor series of ``D² = Σ_S (N−|S|) e^{jSωx}``."""
    m = _moments(n)  # M_2, M_4, ...
    wx = w * x
    xx = np.zeros_like(x)
    xd = np.zeros_like(x)
    for k in range(_SERIES_TERMS):
        sign = -1.0 if k % 2 else 1.0
        xx += sign * wx ** (2 * k) / math.factorial(2 * k) * m[k]
        xd += sign * wx ** (2 * k + 1) / math.factorial(2 * k + 1) * m[k]
    return -w * w * xx + w * xd / tau0


def _curvature_sum(x, tau0, n, w):
    """``(D²)'' − (D²)'/τ0`` by the finite sum of DiPNet eq. (40) (used near poles only)."""
    s = np.arange(-(n - 1), n, dtype=np.float64)
    wt = n - np.abs(s)
    ph = np.outer(x, s) * w
    sw = s * w
    return -(np.cos(ph) * (wt * sw * sw)).sum(axis=1) + (np.sin(ph) * (wt * sw)).sum(axis=1) / tau0


def expected_exponential_curvature(
    los_delay_s, delay_rate, bias_rate, n_subcarriers, subcarrier_spacing_hz
):
    """``E[D̈²(δ + b)]/|D̈₀²|`` for ``δ ~ Exp(a_δ)``, ``b ~ Exp(a_B)``: DiPNet App. III.

    DiPNet eq. (III.1) (NLOS, ``a_δ = a_N``) and eq. (III.3) (LOS, ``a_δ = a_L``,
    ``a_B → ∞``), evaluated through the characteristic function
    ``E[e^{jSω(δ+b)}] = a_δ/(a_δ − jSω) · a_B/(a_B − jSω)`` in the sum of DiPNet eq. (40).

    Parameters
    ----------
    los_delay_s : array_like
        ``τ0 = d0/c0`` [s], > 0.
    delay_rate : float
        ``a_δ`` [1/s] (the inverse mean excess delay), > 0; ``inf``: no excess delay.
    bias_rate : float
        ``a_B`` [1/s] (the inverse mean NLOS bias), > 0; ``inf``: no bias (LOS).
    n_subcarriers : int
    subcarrier_spacing_hz : float

    Returns
    -------
    numpy.ndarray
        Shape of ``los_delay_s``.

    Examples
    --------
    A LOS link shorter than ``c0/a_L`` gains convexity from its multipath; a long one does not:

    >>> tau0 = np.array([1e-10, 1e-6])   # 3 cm and 300 m
    >>> expected_exponential_curvature(tau0, 1 / 40e-9, np.inf, 2569, 14.65e3).round(3)
    array([19.814, -0.048])
    """
    n = v.integer("n_subcarriers", n_subcarriers, minimum=2)
    f_sc = v.positive("subcarrier_spacing_hz", subcarrier_spacing_hz)
    a_d = _rate("delay_rate", delay_rate)
    a_b = _rate("bias_rate", bias_rate)
    tau0 = np.asarray(los_delay_s, dtype=np.float64)
    w = 2.0 * math.pi * f_sc
    s = np.arange(1, n, dtype=np.float64)  # S and −S give conjugate terms
    sw = s * w
    phi = np.ones(s.shape, dtype=np.complex128)
    for a in (a_d, a_b):
        if math.isfinite(a):
            phi *= a / (a - 1j * sw)
    wt = 2.0 * (n - s)
    quad = np.sum(wt * sw * sw * phi.real)  # Σ S²ω² Re φ
    lin = np.sum(wt * sw * phi.imag)  # Σ Sω Im φ  (Re[jSω φ] = −Sω Im φ)
    scale = w * w * n * n * (n * n - 1.0) / 6.0
    return -(quad - lin / tau0) / scale


def _rate(name, a):
    a = float(a)
    if math.isnan(a) or a <= 0:
        raise ValidationError(name, a, "a rate in 1/s, > 0 (inf for none)")
    return a


def curvature_bound(d0_m, bandwidth_hz):
    """``1 + c0/(πBd0)``: bound of ``D̈²(x)/|D̈₀²|`` for any ``x`` (DiPNet eqs. (43)–(44)).

    Examples
    --------
    >>> round(float(curvature_bound(10.0, 37e6)), 4)
    1.2579
    """
    return 1.0 + C0 / (math.pi * bandwidth_hz * np.asarray(d0_m, dtype=np.float64))


# -- expected powers of a scenario --------------------------------------------------------------
@dataclass(frozen=True)
class ExpectedPowers:
    """Expected path powers of a scenario at LOS distances ``d0`` (DiPNet eq. (35)).

    All powers are relative to ``los_direct``, the expected direct-path power of a LOS link.

    Attributes
    ----------
    d0_m : [n] float64
    p_los : [n] float64
        ``P_LOS(d0)`` (DiPNet: ``Pr(X = LOS | d0)``).
    los_scatter : [n] float64
        Expected power of all paths but the direct one of a LOS link, ``E[P_rx/(K+1)]``.
    nlos_total : [n] float64
        Expected power of an NLOS link, ``E[P_rx]``.
    los_direct_w : [n] float64
        ``E[A_0 | LOS] = E[P_rx K/(K+1)]`` [W], the normalization.
    """

    d0_m: np.ndarray
    p_los: np.ndarray
    los_scatter: np.ndarray
    nlos_total: np.ndarray
    los_direct_w: np.ndarray

    @property
    def other_power(self) -> np.ndarray:
        """``M(d0)``: expected power of all non-direct paths, LOS and NLOS links together."""
        return self.p_los * self.los_scatter + (1.0 - self.p_los) * self.nlos_total


def _gauss_hermite():
    z, wt = np.polynomial.hermite_e.hermegauss(_GH_NODES)
    return z, wt / wt.sum()


def _lognormal_mean(sf_std_db):
    """``E[10^(−SF/10)]`` for ``SF ~ N(0, σ²)`` [dB]."""
    s = np.asarray(sf_std_db) * math.log(10.0) / 10.0
    return np.exp(0.5 * s * s)


def _los_split(par, sf_std_db):
    """``E[10^(−SF/10) K/(K+1)]`` and ``E[10^(−SF/10)/(K+1)]`` per distance (LOS)."""
    g = _lognormal_mean(sf_std_db)
    if isinstance(par, AwgnCondition):
        return g, np.zeros_like(g)
    if isinstance(par, ExponentialCondition):
        k = 10.0 ** (par.k_db / 10.0)
        return g * k / (k + 1.0), g / (k + 1.0)
    # WINNER II: SF and K jointly normal (in dB) with the tabulated correlation (Table 4-5)
    rho = float(par.correlation[1, 2])
    z, wt = _gauss_hermite()
    z1, z2 = np.meshgrid(z, z, indexing="ij")
    w2 = np.outer(wt, wt).ravel()
    gain_unit = z1.ravel()  # the table correlates K with SF as a gain (P_rx = P_tx − PL + SF)
    k_db = par.k_db_mu + par.k_db_sigma * (rho * z1 + math.sqrt(1.0 - rho * rho) * z2).ravel()
    kr = 10.0 ** (k_db / 10.0)
    att = np.exp(np.outer(sf_std_db, gain_unit) * (math.log(10.0) / 10.0))  # [n_d, nodes]
    direct = att @ (w2 * kr / (kr + 1.0))
    scatter = att @ (w2 / (kr + 1.0))
    return direct, scatter


#: Models whose expected powers have closed forms here (path loss, shadow fading, K-factor).
CLOSED_FORM_MODELS = ("winner2", "exponential", "awgn")
#: Models whose expected powers are estimated from drawn links (:func:`drawn_powers`): their
#: cluster powers (TR 38.901 Sec. 7.5 steps 5-6, the removal of weak clusters, sub-clusters)
#: or tap profiles (Sec. 7.7.2) have no closed form here, and their delays are not the
#: exponential excess delays of DiPNet App. III (no ``exponential`` curve for them).
DRAWN_MODELS = ("tr38901", "tdl")
#: Links drawn per distance and condition for :func:`drawn_powers`, and their seed (the same
#: at every distance: common random numbers give smooth curves in d0).
DRAWN_LINKS = 4000
DRAWN_SEED = 20201


def require_los(scenario):
    """The loaded scenario; an error if it has no LOS part (the CCI's normalization) or its
    model is none of :data:`CLOSED_FORM_MODELS` and :data:`DRAWN_MODELS`."""
    scn = load_scenario(scenario)
    if scn.model not in (*CLOSED_FORM_MODELS, *DRAWN_MODELS):
        raise ValidationError(
            "scenario",
            scn.name,
            "the concavity indicator is computed for the "
            + ", ".join((*CLOSED_FORM_MODELS, *DRAWN_MODELS))
            + f" models; the {scn.model} model is not supported: its path powers are not "
            "given by a path-loss law and a K-factor",
        )
    if scn.los is None or scn.forced == "nlos":
        raise ValidationError(
            "scenario",
            scn.name,
            "the concavity indicator is normalized to the LOS path power (DiPNet Fig. 2); "
            "give a scenario with a [los] part (not an NLOS-only one)",
        )
    return scn


def expected_powers(scenario, d0_m, system: OFDMSystem | None = None, *, h_m=1.5):
    """Expected direct, scatter and NLOS powers of ``scenario`` at distances ``d0_m``.

    Parameters
    ----------
    scenario : str, os.PathLike or Scenario
        Any channel scenario (name or file); it must have a LOS part (the normalization).
    d0_m : array_like
        LOS distances [m], > 0.
    system : OFDMSystem, optional
        Carrier frequency and transmit power (default ``OFDMSystem()``, DiPNet §V-A).
    h_m : float
        Antenna height of both ends [m] (default 1.5, as :func:`~phyloc.channels.draw_links`).

    Returns
    -------
    ExpectedPowers

    Examples
    --------
    >>> p = expected_powers("winner2_c2", [5.0, 500.0])
    >>> p.p_los.round(3).tolist()
    [1.0, 0.036]
    >>> bool(np.allclose(p.los_scatter, p.los_scatter[0]))   # 1/(K+1) of the LOS power
    False
    """
    scn = load_scenario(scenario)
    system = OFDMSystem() if system is None else system
    if not isinstance(system, OFDMSystem):
        raise ValidationError("system", type(system).__name__, "an OFDMSystem")
    fc = system.carrier_frequency_hz
    scn.check_frequency(fc)
    d = np.atleast_1d(v.finite_array("d0_m", d0_m))
    if d.ndim != 1 or d.size == 0 or d.min() <= 0:
        raise ValidationError("d0_m", d.tolist()[:4], "a 1-D array of distances > 0 m")
    h = np.full(d.shape, v.positive("h_m", h_m))
    require_los(scn)
    if scn.model in DRAWN_MODELS:
        return drawn_powers(scn, d, system, h_m=float(h[0]))
    p_los = scn.p_los(d)
    pl_l, sf_l = scn.los.pathloss.evaluate(d, fc, h, h)
    direct, scatter = _los_split(scn.los, sf_l)
    p_tx = system.received_power_w(0.0)
    los_direct_w = p_tx * 10.0 ** (-pl_l / 10.0) * direct
    nlos_rel = np.zeros_like(d)
    if scn.nlos is not None and scn.forced != "los":
        pl_n, sf_n = scn.nlos.pathloss.evaluate(d, fc, h, h)
        nlos_rel = 10.0 ** (-(pl_n - pl_l) / 10.0) * _lognormal_mean(sf_n) / direct
    return ExpectedPowers(
        d0_m=d,
        p_los=np.asarray(p_los, dtype=np.float64),
        los_scatter=scatter / direct,
        nlos_total=nlos_rel,
        los_direct_w=np.asarray(los_direct_w, dtype=np.float64),
    )


def drawn_powers(
    scenario, d0_m, system: OFDMSystem | None = None, *, h_m=1.5, links=DRAWN_LINKS, seed=DRAWN_SEED
) -> ExpectedPowers:
    """:class:`ExpectedPowers` estimated from links drawn by
    :func:`~phyloc.channels.draw_links` (the models of :data:`DRAWN_MODELS`).

    At each distance ``links`` LOS links give ``E[A_0 | LOS]`` (the power of the first path,
    the LOS ray, whose share of a link is ``K/(K+1)`` in TR 38.901 step 6) and the scatter
    power; ``links`` NLOS links (when the scenario has an NLOS part) give the NLOS power.
    Every distance uses the generator ``default_rng(seed)`` afresh (common random numbers),
    so the estimates change smoothly with ``d0``; their relative Monte Carlo error is about
    ``σ/√links`` of the drawn powers (a few per cent at the default).

    >>> p = drawn_powers("tr38901_umi", [5.0, 50.0], links=500)
    >>> p.p_los.round(3).tolist(), bool(np.all(p.los_scatter < 0.5))
    ([1.0, 0.52], True)
    """
    scn = load_scenario(scenario)
    system = OFDMSystem() if system is None else system
    d = np.atleast_1d(np.asarray(d0_m, dtype=np.float64))
    n = v.integer("links", links, minimum=2)
    direct = np.zeros(d.size)
    scatter = np.zeros(d.size)
    nlos = np.zeros(d.size)
    has_nlos = scn.nlos is not None and scn.forced != "los"
    for i, d0 in enumerate(d):
        rng = np.random.default_rng(seed)
        kw = {"system": system, "h_tx_m": h_m, "h_rx_m": h_m}
        los = draw_links(scn, np.full(n, d0), rng, condition="los", **kw)
        p0 = np.abs(los.paths.gains[los.paths.offsets[:-1]]) ** 2  # the LOS ray leads
        direct[i] = p0.mean()
        scatter[i] = (los.received_power_w - p0).mean() / direct[i]
        if has_nlos:
            nl = draw_links(scn, np.full(n, d0), rng, condition="nlos", **kw)
            nlos[i] = nl.received_power_w.mean() / direct[i]
    return ExpectedPowers(
        d0_m=d,
        p_los=np.asarray(scn.p_los(d), dtype=np.float64),
        los_scatter=scatter,
        nlos_total=nlos,
        los_direct_w=direct,
    )


def exponential_rates(scenario) -> dict:
    """Rates ``a_L, a_N, a_B`` [1/s] of DiPNet App. III from a scenario file.

    ``a = 1/mean``: the exponential model's ``excess_delay_mean_s``; for WINNER II the median
    delay spread ``10^μ_DS`` of WINNER II D1.1.2 Table 4-5 (the rms spread of an exponential
    profile equals its mean; DiPNet §V-A takes "delay spreads from the WINNER-II channel
    model"); ``a_B = 1/nlos_bias_mean_s`` (inf when the bias is 0); AWGN: no multipath.

    Examples
    --------
    >>> r = exponential_rates("exponential")
    >>> round(1e9 / r["a_L"], 1), round(1e9 / r["a_N"], 1), round(1e9 / r["a_B"], 1)
    (40.7, 234.0, 300.0)
    """
    scn = load_scenario(scenario)
    out = {"a_L": math.inf, "a_N": math.inf, "a_B": math.inf}
    for cond, key in (("los", "a_L"), ("nlos", "a_N")):
        par = scn.los if cond == "los" else scn.nlos
        if par is None:
            continue
        if isinstance(par, Winner2Condition):
            out[key] = 1.0 / 10.0**par.ds_log10_mu
        elif isinstance(par, ExponentialCondition):
            out[key] = 1.0 / par.excess_delay_mean_s
        if cond == "nlos" and par.nlos_bias_mean_s > 0:
            out["a_B"] = 1.0 / par.nlos_bias_mean_s
    return out


# -- the three evaluations ---------------------------------------------------------------------
def cci_bound(powers: ExpectedPowers, system: OFDMSystem) -> np.ndarray:
    """Upper bound of the normalized CCI for arbitrary δ_l and b: DiPNet eq. (44).

    ``(1 + c0/(πBd0))·M(d0) − P_LOS(d0)``, ``M`` = :attr:`ExpectedPowers.other_power`.
    """
    return curvature_bound(powers.d0_m, system.bandwidth_hz) * powers.other_power - powers.p_los


def cci_exponential(powers: ExpectedPowers, rates: dict, system: OFDMSystem) -> np.ndarray:
    """Normalized CCI for exponential δ_l and b: DiPNet eq. (42) with App. III.

    ``P_LOS·(scatter)·E_LOS[r] + (1 − P_LOS)·(NLOS power)·E_NLOS[r] − P_LOS``, ``r`` the
    normalized curvature, ``E_LOS`` of eq. (III.3) and ``E_NLOS`` of eq. (III.1).
    """
    tau0 = powers.d0_m / C0
    n, f_sc = system.n_subcarriers, system.subcarrier_spacing_hz
    out = -powers.p_los.copy()
    if np.any(powers.los_scatter > 0):
        r_l = expected_exponential_curvature(tau0, rates["a_L"], math.inf, n, f_sc)
        out += powers.p_los * powers.los_scatter * r_l
    if np.any(powers.nlos_total > 0):
        r_n = expected_exponential_curvature(tau0, rates["a_N"], rates["a_B"], n, f_sc)
        out += (1.0 - powers.p_los) * powers.nlos_total * r_n
    return out


def cci_monte_carlo(
    scenario, d0_m: float, n_links: int, rng: np.random.Generator, system=None, *, h_m=1.5
) -> tuple[float, float]:
    """Monte Carlo normalized CCI at one distance from links drawn by ``draw_links``.

    Each drawn link contributes ``Σ_l |α_l|² D̈²(τ_l − d0/c0)/|D̈₀²|`` (DiPNet eqs. (35),
    (40), exact per path; the direct path gives ``−|α_0|²``). The mean over links, divided by
    ``E[A_0 | LOS]`` of :func:`expected_powers`, estimates the CCI; the second value is its
    standard error.

    Parameters
    ----------
    scenario : str, os.PathLike or Scenario
    d0_m : float
        LOS distance [m], > 0.
    n_links : int
        Links to draw, >= 2.
    rng : numpy.random.Generator
    system : OFDMSystem, optional
    h_m : float

    Returns
    -------
    (mean, standard_error) : (float, float)
    """
    scn = load_scenario(scenario)
    system = OFDMSystem() if system is None else system
    d0 = v.positive("d0_m", d0_m)
    n = v.integer("n_links", n_links, minimum=2)
    norm = float(expected_powers(scn, [d0], system, h_m=h_m).los_direct_w[0])
    draw = draw_links(scn, np.full(n, d0), rng, system=system, h_tx_m=h_m, h_rx_m=h_m)
    x = draw.excess_delays()
    r = normalized_curvature(x, d0 / C0, system.n_subcarriers, system.subcarrier_spacing_hz)
    q = np.bincount(draw.paths.link_index(), np.abs(draw.paths.gains) ** 2 * r, n) / norm
    return float(q.mean()), float(q.std(ddof=1) / math.sqrt(n))


def expected_scf(scenario, d0_m, offsets_m, system=None, *, n_theta=64, h_m=1.5):
    """The expected SCF of DiPNet eq. (35) around the true position, for exponential delays.

    For a neighbour at LOS distance ``d0`` and an agent displaced by ``Δd`` from its true
    position, averaged over the neighbour's direction θ (DiPNet eqs. (30)–(32)), the paths'
    powers (:func:`expected_powers`) and exponential δ_l and b (:func:`exponential_rates`,
    DiPNet App. III), with each path's cross-correlation the Dirichlet kernel of DiPNet
    eq. (36)::

        F(Δd) = (1/π) ∫₀^π Σ_S (N − |S|) c(S) e^{jSω(τ0 − τ(Δd, θ))} dθ / N²,
        c(S) = P_LOS + P_LOS·scatter·φ_L(Sω) + (1 − P_LOS)·P_NLOS·φ_N(Sω)·φ_B(Sω),

    ``φ_a(t) = a/(a − jt)``, normalized to the LOS direct-path power and to ``N²`` and without
    the constant noise term ``σ²‖s‖²``: the AWGN profile peaks at ``P_LOS``. Its curvature at
    ``Δd = 0`` is ``CCI·ω²(N² − 1)/12 · c0⁻²`` per m² (DiPNet eqs. (41)–(42)), so the true
    position is a maximum exactly when :func:`cci_exponential` is negative.

    Parameters
    ----------
    scenario : str, os.PathLike or Scenario
    d0_m : float
        LOS distance of the neighbour [m], > 0.
    offsets_m : array_like
        Displacements ``Δd`` of the agent [m] (the profile is even in ``Δd``).
    system : OFDMSystem, optional
    n_theta : int
        Midpoint nodes on ``[0, π]`` (the integrand is smooth and periodic in θ).
    h_m : float

    Returns
    -------
    numpy.ndarray
        ``F`` at ``offsets_m``.

    Examples
    --------
    >>> f = expected_scf("awgn", 20.0, [0.0, 2.0])
    >>> round(float(f[0]), 12), bool(f[1] < f[0])
    (1.0, True)
    """
    scn = load_scenario(scenario)
    system = OFDMSystem() if system is None else system
    d0 = v.positive("d0_m", d0_m)
    off = np.atleast_1d(v.finite_array("offsets_m", offsets_m))
    m = v.integer("n_theta", n_theta, minimum=4)
    pw = expected_powers(scn, [d0], system, h_m=h_m)
    rates = exponential_rates(scn)
    n, w = system.n_subcarriers, system.omega
    s = np.arange(-(n - 1), n, dtype=np.float64)
    sw = s * w
    coeff = np.full(s.shape, pw.p_los[0], dtype=np.complex128)
    if pw.los_scatter[0] > 0:
        coeff += pw.p_los[0] * pw.los_scatter[0] * _char(rates["a_L"], sw)
    if pw.nlos_total[0] > 0:
        phi = _char(rates["a_N"], sw) * _char(rates["a_B"], sw)
        coeff += (1.0 - pw.p_los[0]) * pw.nlos_total[0] * phi
    coeff *= (n - np.abs(s)) / float(n * n)
    tau0 = d0 / C0
    theta = (np.arange(m) + 0.5) * (math.pi / m)
    dt = off.ravel() / C0
    tau = np.sqrt(tau0**2 + dt[:, None] ** 2 - 2.0 * tau0 * dt[:, None] * np.cos(theta))
    u = (tau0 - tau).ravel()
    out = np.empty(u.size)
    step = max(1, 4_000_000 // s.size)
    for i in range(0, u.size, step):
        out[i : i + step] = (np.exp(1j * np.outer(u[i : i + step], sw)) @ coeff).real
    return out.reshape(dt.size, m).mean(axis=1).reshape(off.shape)


def _char(a: float, t: np.ndarray) -> np.ndarray:
    """Characteristic function ``a/(a − jt)`` of Exp(a); 1 for ``a = inf`` (no delay)."""
    if not math.isfinite(a):
        return np.ones(t.shape, dtype=np.complex128)
    return a / (a - 1j * t)


# -- summaries ---------------------------------------------------------------------------------
def negative_above(d0_m, values, fn=None) -> float:
    """The distance above which a CCI curve stays negative [m].

    ``values`` sampled on the increasing grid ``d0_m``: the first grid point after the last
    non-negative value, refined by Brent's method on ``fn`` (a callable ``d → value``) when
    given. ``d0_m[0]`` when the curve is negative on the whole grid, ``inf`` when it is not
    negative at the last point.

    Examples
    --------
    >>> d = np.array([1.0, 2.0, 3.0, 4.0])
    >>> negative_above(d, np.array([0.5, 0.1, -0.2, -0.3]))
    3.0
    >>> negative_above(d, 2.5 - d, fn=lambda x: 2.5 - x)
    2.5
    """
    d = np.asarray(d0_m, dtype=np.float64)
    y = np.asarray(values, dtype=np.float64)
    bad = np.flatnonzero(~(y < 0))
    if bad.size == 0:
        return float(d[0])
    i = int(bad[-1])
    if i == d.size - 1:
        return math.inf
    if fn is None:
        return float(d[i + 1])
    return float(brentq(lambda t: float(fn(t)), d[i], d[i + 1], xtol=1e-9 * d[i + 1]))


def min_bandwidth_hz(powers: ExpectedPowers) -> np.ndarray:
    """Smallest bandwidth for which the bound (44) is negative at each ``d0`` [Hz].

    ``B > c0·M / (π d0 (P_LOS − M))`` when ``P_LOS > M``; ``inf`` where the LOS power does not
    exceed that of all other paths (then no bandwidth guarantees concavity, DiPNet §IV-A).

    Examples
    --------
    >>> p = expected_powers("awgn", [10.0])
    >>> float(min_bandwidth_hz(p)[0])   # no multipath: any bandwidth
    0.0
    """
    m, p = powers.other_power, powers.p_los
    with np.errstate(divide="ignore", invalid="ignore"):
        b = C0 * m / (math.pi * powers.d0_m * (p - m))
    return np.where(p > m, b, math.inf)


def cci_curves(scenario, system: OFDMSystem | None = None, *, points=400, d0_range_m=D0_RANGE_M):
    """The closed-form curves of DiPNet Fig. 2 for one scenario and their summary numbers
    (for :data:`DRAWN_MODELS` the bound uses :func:`drawn_powers` and the exponential curve
    is NaN).

    Returns
    -------
    dict
        ``d0_m``, ``bound`` (DiPNet eq. (44)), ``exponential`` (App. III), ``awgn`` (−P_LOS),
        ``negative_above_m`` and ``exponential_negative_above_m`` (refined), ``rates``, the
        :class:`ExpectedPowers` ``powers``.
    """
    system = OFDMSystem() if system is None else system
    points = v.integer("points", points, minimum=2)
    lo, hi = (v.positive("d0_range_m", x) for x in d0_range_m)
    if not lo < hi:
        raise ValidationError("d0_range_m", [lo, hi], "an increasing pair of distances [m]")
    scn = load_scenario(scenario)
    d = np.geomspace(lo, hi, points)
    pw = expected_powers(scn, d, system)
    rates = exponential_rates(scn)

    def bound_at(x):
        return float(cci_bound(expected_powers(scn, [x], system), system)[0])

    def expo_at(x):
        return float(cci_exponential(expected_powers(scn, [x], system), rates, system)[0])

    bound = cci_bound(pw, system)
    if scn.model in DRAWN_MODELS:  # no exponential delays: no App. III curve
        expo, expo_above = np.full(d.shape, math.nan), math.nan
    else:
        expo = cci_exponential(pw, rates, system)
        expo_above = negative_above(d, expo, expo_at)
    return {
        "d0_m": d,
        "bound": bound,
        "exponential": expo,
        "awgn": -pw.p_los,
        "negative_above_m": negative_above(d, bound, bound_at),
        "exponential_negative_above_m": expo_above,
        "rates": rates,
        "powers": pw,
    }

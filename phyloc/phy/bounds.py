"""Ranging bounds of one-path OFDM links: Cramér–Rao (DiPNet eq. (24)) and Ziv–Zakai.

SNRs here are *per-sample* SNRs ``|α|²/σ²`` (linear); the post-correlation SNR is
``‖S‖²·|α|²/σ²`` (``N`` times for unit-modulus pilots), see :func:`post_correlation_snr`.
Both bounds are variances of a distance estimate [m²].

:func:`ranging_crb` is the one implementation of DiPNet eq. (24) in phyloc: :func:`crb_range`
evaluates it for given pilots, :func:`phyloc.analysis.efim.ranging_information` (the ranging
information ``ν = 1/CRB``) and the covariance floor of the direct localizers call it.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
K. L. Bell, Y. Steinberg, Y. Ephraim and H. L. Van Trees, "Extended Ziv–Zakai lower bound for
vector parameter estimation," IEEE Trans. Information Theory 43(2), pp. 624–637, 1997.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.phy.system import C0, OFDMSystem
from phyloc.phy.waveform import check_symbols

# The ZZB's uniform lag grid: at most this many points (65 536 × 1000 SNRs × 8 B = 0.5 GB per
# array of a chunk of ranging_variance); the prior range is refused beyond it.
_MAX_UNIFORM_LAGS = 65_536


def _snr(snr) -> np.ndarray:
    s = np.asarray(snr, dtype=np.float64)
    if np.any(np.isnan(s)) or np.any(s < 0):
        raise ValidationError("snr", snr, "per-sample SNR must be >= 0 (linear, not dB)")
    return s


def _power_spectrum(symbols, system: OFDMSystem) -> np.ndarray:
    S = check_symbols(symbols, system)
    if S.shape[0] != 1:
        raise ValidationError("symbols", f"{S.shape[0]} rows", "one transmitter's symbols [N]")
    return np.abs(S[0]) ** 2


def post_correlation_snr(snr, symbols, system: OFDMSystem) -> np.ndarray:
    """``‖S‖²·SNR``: the SNR at the correlation peak for a per-sample SNR ``|α|²/σ²``."""
    return _snr(snr) * _power_spectrum(symbols, system).sum()


def ranging_crb(snr, moment2, omega) -> np.ndarray:
    """Cramér–Rao bound of a one-path link's distance from its parts [m²] (DiPNet eq. (24)).

    .. math:: \\mathrm{CRB} = \\frac{c_0^2}{2\\,\\mathrm{SNR}\\,ω^2 M},
              \\qquad \\mathrm{SNR} = \\frac{|α|^2}{σ^2},\\quad M = \\sum_n |S_n|^2 n^2

    The one implementation of DiPNet eq. (24); no validation (callers validate).

    Parameters
    ----------
    snr : array_like float64
        Per-sample SNR ``|α|²/σ²`` (linear, >= 0); 0 gives ``inf``.
    moment2 : array_like float64
        ``M = Σ_n |S_n|² n²`` (dimensionless, > 0).
    omega : float
        ``ω = 2π f_sc`` [rad/s].

    Returns
    -------
    crb : broadcast shape, float64 [m²]

    Examples
    --------
    >>> float(ranging_crb(1.0, 2.0, C0))  # c0²/(2·1·c0²·2)
    0.25
    """
    with np.errstate(divide="ignore"):
        return C0**2 / (2.0 * np.asarray(snr, dtype=np.float64) * omega**2 * moment2)


def crb_range(snr, symbols, system: OFDMSystem) -> np.ndarray:
    """Cramér–Rao bound of the distance of a one-path link [m²] (DiPNet eq. (24)).

    .. math:: \\mathrm{CRB} = \\frac{c_0^2 σ^2}{2 |α|^2 ω^2 \\sum_n |S_n|^2 n^2}

    Parameters
    ----------
    snr : array_like, float
        Per-sample SNR ``|α|²/σ²`` (linear, >= 0). Zero SNR gives ``inf``.
    symbols : [N], complex
        The pilot symbols ``S_n``.
    system : OFDMSystem

    Returns
    -------
    crb : like ``snr``, float64 [m²]

    Notes
    -----
    DiPNet eq. (24) treats the amplitude as decoupled from the delay, which is exact when
    ``Σ|S_n|² n = 0`` (constant-modulus pilots on symmetric subcarriers).
    """
    s = _snr(snr)
    P = _power_spectrum(symbols, system)
    n = system.subcarrier_indices()
    m2 = float((P * n**2).sum())
    return ranging_crb(s, m2, system.omega)


def _one_minus_rho(h_m, P, system: OFDMSystem) -> np.ndarray:
    """``1 − Re ρ(h)`` of the normalized autocorrelation at distance lag h, without
    cancellation: ``Σ|S_n|²·2 sin²(ωnh/(2c0)) / Σ|S_n|²``."""
    n = system.subcarrier_indices()
    w = system.omega / C0
    out = np.empty(h_m.size)
    step = max(1, 4_000_000 // n.size)
    for a in range(0, h_m.size, step):
        x = np.sin(0.5 * w * np.outer(h_m[a : a + step], n))
        out[a : a + step] = 2.0 * (x * x) @ P
    return out / P.sum()


def zzb_range(
    snr,
    symbols,
    system: OFDMSystem,
    *,
    prior_range_m: float = 100.0,
    valley_filling: bool = True,
) -> np.ndarray:
    """Ziv–Zakai bound of the distance of a one-path link [m²], uniform a-priori distance.

    With the distance uniform on ``[0, D]`` and coherent detection between two hypotheses a lag
    h apart (the pairwise error probability of known signals in white noise),

    .. math:: \\mathrm{ZZB} = \\int_0^D h\\, \\mathcal{V}\\Big\\{\\big(1 - \\tfrac hD\\big)
              Q\\big(\\sqrt{\\mathrm{SNR}_{pc}\\,(1 - \\mathrm{Re}\\,ρ(h))}\\big)\\Big\\}\\, dh,

    where ``ρ(h) = Σ|S_n|² e^{−jωnh/c0}/Σ|S_n|²`` is the normalized autocorrelation of s,
    ``SNR_pc`` the post-correlation SNR and ``V{g}(h) = max_{ξ>=0} g(h+ξ)`` the valley-filling
    operator (Bell, Steinberg, Ephraim and Van Trees, 1997). The integral is evaluated
    numerically on a grid that is geometric near 0 (resolving √CRB at any SNR) and uniform at
    ``c0/(32 B)`` (resolving the sidelobes of ρ). At high SNR the bound tends to the CRB; below
    the threshold it exceeds it and tends to the prior variance ``D²/12`` as SNR → 0.

    Parameters
    ----------
    snr : array_like, float
        Per-sample SNR ``|α|²/σ²`` (linear, >= 0).
    symbols : [N], complex
    system : OFDMSystem
    prior_range_m : float
        D [m], the width of the uniform a-priori distance interval (> 0). Default 100 m.
    valley_filling : bool
        Apply the valley-filling operator (tighter bound). Default True.

    Returns
    -------
    zzb : like ``snr``, float64 [m²]
    """
    s = _snr(snr)
    P = _power_spectrum(symbols, system)
    D = v.positive("prior_range_m", prior_range_m)
    step = C0 / (32.0 * system.bandwidth_hz)  # resolves the sidelobes of ρ
    if D / step > _MAX_UNIFORM_LAGS:
        raise ValidationError(
            "prior_range_m",
            D,
            f"at most {_MAX_UNIFORM_LAGS * step:.6g} m for this system: the bound is integrated "
            f"on a lag grid of step c0/(32 B) = {step:.3g} m, limited to {_MAX_UNIFORM_LAGS} "
            "points to stay in memory",
        )
    flat = s.ravel()
    with np.errstate(divide="ignore"):
        crb = crb_range(flat, symbols, system)
    finite_crb = crb[np.isfinite(crb) & (crb > 0)]
    h_lo = 1e-4 * min(np.sqrt(finite_crb.min()) if finite_crb.size else D, D)
    h_lo = max(h_lo, D * 1e-12)
    geo = np.geomspace(h_lo, D, 3000)
    uni = np.arange(0.0, D, step)
    h = np.unique(np.concatenate([[0.0], geo, uni, [D]]))
    h = h[h <= D]
    omr = _one_minus_rho(h, P, system)
    pc = flat * P.sum()
    # pairwise error probability Q(√(SNR_pc (1 − ρ))) = Φ(−√·)
    g = (1.0 - h / D)[None, :] * ndtr(-np.sqrt(np.maximum(pc[:, None] * omr[None, :], 0.0)))
    if valley_filling:
        g = np.maximum.accumulate(g[:, ::-1], axis=1)[:, ::-1]
    out = np.trapezoid(h[None, :] * g, h, axis=1)
    return out.reshape(s.shape)

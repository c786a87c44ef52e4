"""SAGE multipath estimation and LOS ranging (Fessler & Hero 1994; Fleury et al. 1999).

Model
    For link u←v the correlation spectrum ``c_n = R_n^* S_n`` of the received
    ``R_n = S_n Σ_l α_l e^{−jωnτ_l} + W_n`` is

    .. math:: c_n = |S_n|^2 \\sum_{l=0}^{L} α_l^* e^{+jωnτ_l} + W_n^* S_n,

    with ``L + 1 = n_paths`` paths at distances ``d_l = c0 τ_l``. Maximizing the likelihood of R
    (white W) is least squares in c weighted by ``1/|S_n|²``; for constant-modulus pilots this is
    exactly the channel-estimate form ``y_n = R_n/S_n = Σ α_l e^{−jωnτ_l} + noise``.
    Working on c keeps zero or uneven pilots harmless and reuses the correlation machinery:
    ``F_x(d) = Σ_n x_n e^{−jωnd/c0}`` is the correlation function of a spectrum x.

Initialization (successive interference cancellation)
    Path 0 is the strongest peak of the table in the window; path p is the strongest peak in the
    window of the residual ``c − Σ_{k<p} (path k)``, found on a zero-padded FFT grid (β =
    ``init_beta``) and refined by Newton steps on the exact residual correlation. Amplitudes
    ``α_p = F_res(d_p)^*/‖S‖²``. After each new path, ``init_sweeps`` SAGE sweeps re-estimate
    the paths found so far, so the next residual is searched with the stronger paths already
    de-biased (a first estimate is pulled by the other paths' sidelobes; without this the
    surplus paths of an over-ordered model lock onto those errors next to strong paths, and
    SAGE moves them away only very slowly).

SAGE sweeps (``n_iter`` times, over every path l in turn)
    E-step: ``x_l = c − Σ_{k≠l} |S|² α_k^* e^{jωnτ_k}`` (the residual plus path l's own
    contribution — the hidden data of Fessler & Hero with β_l = 1).
    M-step: ``d_l = argmax |F_{x_l}(d)|²`` over ``d_l + m·h``, ``|m| <= search_steps`` (h the
    table spacing), refined by ``n_newton`` Newton steps on the exact ``|F_{x_l}|²``; then
    ``α_l = F_{x_l}(d_l)^*/‖S‖²`` (for unit pilots ``e(τ_l)^H x_l / N`` in the y form).
    Each sweep costs about ``(L+1)(2·search_steps + 4 + 2·n_newton)`` passes over the N
    subcarriers — the ``K_s (L+1) K_τ N`` of DiPNet Table I; ``phyloc bench ranging`` reports
    the µs per sweep and link.

Model order
    Surplus paths of an over-ordered model fit noise; one that lands within a sample of a true
    path biases it (the pair is ill-conditioned). After the sweeps, paths whose post-correlation
    SNR ``|α_l|²‖S‖²/σ²`` is below ``noise_factor`` κ are dropped and the remaining ones
    re-estimated by ``prune_sweeps`` further sweeps (with κ = 0 nothing is dropped).

LOS choice
    The LOS path is the earliest path in the window, among those kept (above κ, the
    estimators' detection threshold, see :mod:`phyloc.ranging.estimators`), whose power
    ``|α_l|²`` is within ``los_threshold_db`` of the strongest kept path in the window. A link
    without any kept path in the window is invalid; its range is then the strongest path in the
    window before pruning, clipped to the window (a finite placeholder).

References
----------
B. H. Fleury, M. Tschudin, R. Heddergott, D. Dahlhaus and K. I. Pedersen, "Channel parameter
estimation in mobile radio environments using the SAGE algorithm," IEEE J. Selected Areas in
Communications 17(3), pp. 434–450, 1999.

J. A. Fessler and A. O. Hero, "Space-alternating generalized expectation-maximization
algorithm," IEEE Trans. Signal Processing 42(10), pp. 2664–2677, 1994 (DiPNet ref. [33]).

DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import math

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.phy import fft as _fft
from phyloc.phy.system import C0
from phyloc.ranging import _kernels
from phyloc.ranging.results import (
    DEFAULT_NOISE_FACTOR,
    DEFAULT_WINDOW_M,
    RangeEstimates,
    check_noise_factor,
    check_table,
    check_variance,
    exact_at,
    noise_floor,
    refine,
    snr_from_amplitude,
    variance_for,
    window_indices,
)

_FFT_CHUNK = 64


def _padded_power(res: np.ndarray, L2: int, k2: np.ndarray) -> np.ndarray:
    """``|F_res(k·c0/(L2 f_sc))|²`` at grid indices ``k2`` by zero-padded FFTs (one planned
    ``[_FFT_CHUNK, L2]`` transform reused for every chunk of links)."""
    n_links = res.shape[0]
    cols = k2 % L2
    out = np.empty((n_links, k2.size))
    plan = _fft.batch_fft(_FFT_CHUNK, L2)
    for a in range(0, n_links, _FFT_CHUNK):
        b = min(a + _FFT_CHUNK, n_links)
        F = plan.centered(res[a:b])[:, cols]
        out[a:b] = F.real**2 + F.imag**2
    return out


def _residual(table, dist, gain, spectrum=None):
    """``c − Σ_p (path p)`` per link (``spectrum`` defaults to the table's c)."""
    system = table.system
    c = np.ascontiguousarray(table.spectrum if spectrum is None else spectrum)
    args = (
        c,
        np.ascontiguousarray(np.abs(table.symbols) ** 2),
        table.tx_index,
        float(system.subcarrier_indices()[0]),
        system.omega / C0,
        np.ascontiguousarray(dist, dtype=np.float64),
        np.ascontiguousarray(gain, dtype=np.complex128),
    )
    out = np.empty_like(c)
    _kernels.residual_kernel(*args, out)
    return out


def sic_init(
    table,
    n_paths: int,
    window_m=DEFAULT_WINDOW_M,
    *,
    noise_factor=0.0,
    init_beta: float = 4.0,
    init_sweeps: int = 1,
    search_steps: int = 2,
    n_newton: int = 4,
):
    """Initial paths by successive interference cancellation (module docstring).

    A link stops growing when its residual's strongest peak in the window is below
    ``noise_factor·σ²‖S‖²`` (its first path is always kept).

    Returns
    -------
    dist : [n_links, n_paths], float64
        Path distances [m] in the order found (strongest first).
    gain : [n_links, n_paths], complex128
        Their amplitudes α [√W] (0 past ``n_active``).
    n_active : [n_links], int64
        Paths found per link (1 … n_paths).
    """
    table = check_table(table)
    P = v.integer("n_paths", n_paths, minimum=1)
    lo, hi, k = window_indices(table, window_m)
    kappa = check_noise_factor(noise_factor)
    b = v.positive("init_beta", init_beta)
    if b < 2.0:
        raise ValidationError("init_beta", init_beta, "must be >= 2 (grid <= c0/(2B))")
    init_sweeps = v.integer("init_sweeps", init_sweeps, minimum=0)
    system = table.system
    N = system.n_subcarriers
    L2 = _fft.next_fast_len(math.ceil(b * N))
    h2 = C0 / (L2 * system.subcarrier_spacing_hz)
    k2 = np.arange(math.ceil(lo / h2), math.floor(hi / h2) + 1)
    n_links = table.n_links
    floor = kappa * noise_floor(table)
    dist = np.zeros((n_links, P))
    gain = np.zeros((n_links, P), dtype=np.complex128)
    n_active = np.zeros(n_links, dtype=np.int64)
    res = np.ascontiguousarray(table.spectrum)
    for p in range(P):
        if p == 0:
            vals = table.values[:, k % table.n_fft]
            d0 = k[np.argmax(vals.real**2 + vals.imag**2, axis=1)] * table.spacing_m
            d = refine(table, d0, table.spacing_m, spectrum=res)
        else:
            d0 = k2[np.argmax(_padded_power(res, L2, k2), axis=1)] * h2
            d = refine(table, d0, h2, spectrum=res)
        F = exact_at(table, d, spectrum=res)
        grow = n_active == p
        if p > 0:
            grow &= (F.real**2 + F.imag**2) >= floor
        if not grow.any():
            break
        dist[grow, p] = d[grow]
        gain[grow, p] = np.conj(F[grow]) / table.symbol_energy[grow]
        n_active[grow] += 1
        if init_sweeps and p > 0:  # re-estimate the paths found so far before the next search
            dp, ap = sage_sweeps(
                table,
                dist[:, : p + 1],
                gain[:, : p + 1],
                n_iter=init_sweeps,
                search_steps=search_steps,
                n_newton=n_newton,
                n_active=n_active,
            )
            dist[:, : p + 1] = dp
            gain[:, : p + 1] = ap
        if p + 1 < P:  # the residual of every path so far (inactive ones have α = 0)
            res = _residual(table, dist[:, : p + 1], gain[:, : p + 1])
    return dist, gain, n_active


def sage_sweeps(
    table,
    dist,
    gain,
    *,
    n_iter: int = 10,
    search_steps: int = 2,
    n_newton: int = 4,
    n_active=None,
):
    """``n_iter`` SAGE sweeps from initial paths ``dist, gain [n_links, P]`` (returns new
    arrays; module docstring). With ``n_active [n_links]`` only the first ``n_active[i]`` paths
    of link i take part (the rest are left as they are and not subtracted)."""
    system = table.system
    args = (
        np.ascontiguousarray(table.spectrum),
        np.ascontiguousarray(np.abs(table.symbols) ** 2),
        table.tx_index,
        table.symbol_energy,
        float(system.subcarrier_indices()[0]),
        system.omega / C0,
    )
    d = np.array(dist, dtype=np.float64, order="C")
    a = np.array(gain, dtype=np.complex128, order="C")
    if n_active is None:
        n_active = np.full(d.shape[0], d.shape[1], dtype=np.int64)
    n_active = np.ascontiguousarray(n_active, dtype=np.int64)
    rest = (int(n_iter), table.spacing_m, int(search_steps), int(n_newton))
    _kernels.sage_kernel(*args, d, a, n_active, *rest)
    return d, a


def sage(
    table,
    *,
    n_paths: int = 5,
    n_iter: int = 10,
    window_m=DEFAULT_WINDOW_M,
    los_threshold_db: float = -10.0,
    noise_factor=DEFAULT_NOISE_FACTOR,
    variance: str = "zzb",
    prior_range_m: float | None = None,
    search_steps: int = 2,
    n_newton: int = 4,
    init_beta: float = 4.0,
    init_sweeps: int = 1,
    prune_sweeps: int = 2,
) -> RangeEstimates:
    """LOS range from SAGE estimates of ``n_paths`` = L+1 paths per link (module docstring).

    Parameters
    ----------
    table : CorrelationTable
        ``n_links`` links (the spectra ``c_n`` are used; the grid seeds the first path).
    n_paths : int
        Model order L+1 (>= 1). Default 5.
    n_iter : int
        SAGE sweeps K_s (>= 0; 0 returns the SIC initialization). Default 10.
    window_m : (float, float)
        Paths are initialized in, and the LOS chosen from, ``lo <= d <= hi`` [m].
    los_threshold_db : float
        The LOS is the earliest path whose power is within this of the strongest (<= 0 dB).
    noise_factor : float or None
        κ: a path qualifies only if ``|α|²‖S‖²/σ² >= κ`` (default 16, as the other estimators).
    variance : {"zzb", "crb"}
    prior_range_m : float, optional
        ZZB prior width D [m]; default the window width.
    search_steps : int
        M-step local search: ``d_l + m·h``, ``|m| <= search_steps`` (h the table spacing).
    n_newton : int
        Newton steps K_τ after the local search.
    init_beta : float
        Oversampling of the zero-padded FFT grid of the SIC initialization (>= 2).
    init_sweeps : int
        SAGE sweeps over the paths found so far after each SIC step (default 1; 0 is plain SIC).
    prune_sweeps : int
        After the sweeps, paths below the noise threshold are dropped and the others
        re-estimated with this many sweeps (default 2; 0 keeps every path in the fit).

    Returns
    -------
    RangeEstimates
        ``method = "sage"``; ``path_distance_m``, ``path_amplitude``, ``path_offsets`` hold
        every path above the noise threshold (per link sorted by distance; a link may have
        fewer than ``n_paths``, or none).

    Examples
    --------
    >>> from phyloc.phy import OFDMSystem, PathSet, C0
    >>> from phyloc.phy.waveform import qpsk_symbols
    >>> from phyloc.phy.synthesis import synthesize
    >>> from phyloc.phy.correlation import correlation_tables
    >>> sysm = OFDMSystem()
    >>> rng = np.random.default_rng(5)
    >>> S = qpsk_symbols(sysm, 1, rng)
    >>> paths = PathSet.from_lists([[40.0 / C0, 71.0 / C0]], [[0.6e-5, 1e-5]])
    >>> est = sage(correlation_tables(synthesize(paths, S, sysm, rng), S, sysm), n_paths=3)
    >>> round(float(est.range_m[0]), 1)
    40.0
    """
    table = check_table(table)
    kappa = check_noise_factor(noise_factor)
    check_variance(variance)
    n_iter = v.integer("n_iter", n_iter, minimum=0)
    search_steps = v.integer("search_steps", search_steps, minimum=0)
    n_newton = v.integer("n_newton", n_newton, minimum=0)
    prune_sweeps = v.integer("prune_sweeps", prune_sweeps, minimum=0)
    los_db = v.finite("los_threshold_db", los_threshold_db)
    if los_db > 0:
        raise ValidationError("los_threshold_db", los_threshold_db, "must be <= 0 dB")
    lo, hi, _ = window_indices(table, window_m)

    dist, gain, n_active = sic_init(
        table,
        n_paths,
        (lo, hi),
        noise_factor=kappa,
        init_beta=init_beta,
        init_sweeps=init_sweeps,
        search_steps=search_steps,
        n_newton=n_newton,
    )
    dist, gain = sage_sweeps(
        table,
        dist,
        gain,
        n_iter=n_iter,
        search_steps=search_steps,
        n_newton=n_newton,
        n_active=n_active,
    )

    # model order: paths below the noise threshold are dropped, the rest re-estimated
    floor = kappa * table.noise_var / table.symbol_energy  # |α|² of post-corr. SNR κ
    found_by_sic = np.arange(dist.shape[1]) < n_active[:, None]
    pw = gain.real**2 + gain.imag**2
    in_win = (dist >= lo) & (dist <= hi) & found_by_sic
    strongest_any = np.argmax(np.where(in_win, pw, -1.0), axis=1)  # placeholder for no path
    rows = np.arange(table.n_links)
    d_fallback = np.clip(dist[rows, strongest_any], lo, hi)
    a_fallback = gain[rows, strongest_any]
    active = (pw >= floor[:, None]) & found_by_sic
    if prune_sweeps and np.any(active.sum(axis=1) < n_active):
        order = np.argsort(~active, axis=1, kind="stable")  # active paths first
        dist = np.take_along_axis(dist, order, axis=1)
        gain = np.take_along_axis(gain, order, axis=1)
        active = np.take_along_axis(active, order, axis=1)
        dist, gain = sage_sweeps(
            table,
            dist,
            gain,
            n_iter=prune_sweeps,
            search_steps=search_steps,
            n_newton=n_newton,
            n_active=active.sum(axis=1),
        )
        pw = gain.real**2 + gain.imag**2
    in_win = (dist >= lo) & (dist <= hi)

    # LOS: the earliest in-window path within los_db of the strongest in-window one
    keep = active & in_win
    strongest = np.where(keep, pw, 0.0).max(axis=1)
    cand = keep & (pw >= strongest[:, None] * 10.0 ** (los_db / 10.0))
    found = cand.any(axis=1)
    idx = np.argmin(np.where(cand, dist, np.inf), axis=1)
    d_los = np.where(found, dist[rows, idx], d_fallback)
    a_los = np.where(found, gain[rows, idx], a_fallback)
    snr = snr_from_amplitude(table, a_los)
    var = variance_for(table, snr, variance, prior_range_m, lo, hi)

    # every path above the noise threshold, per link sorted by distance
    order = np.argsort(np.where(active, dist, np.inf), axis=1, kind="stable")
    dist_s = np.take_along_axis(dist, order, axis=1)
    gain_s = np.take_along_axis(gain, order, axis=1)
    act_s = np.take_along_axis(active, order, axis=1)
    counts = act_s.sum(axis=1)
    return RangeEstimates(
        method="sage",
        range_m=d_los,
        snr=snr,
        variance_m2=var,
        valid=found,
        path_distance_m=dist_s[act_s],
        path_amplitude=gain_s[act_s],
        path_offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
    )

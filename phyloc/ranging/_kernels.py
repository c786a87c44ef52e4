"""Numba kernels of the range estimators.

Kernels take arrays and scalars only: no validation, no objects, no random numbers. The public
functions in :mod:`phyloc.ranging.sage` validate, allocate and call them; ``tests/test_ranging.py``
compares every kernel with its plain-NumPy twin and with the slow references, both in
``tests/naive_ranging.py`` (test code, not installed).

Everything works on a link's *correlation spectrum* ``c_n = R_n^* S_n`` (the
:attr:`~phyloc.phy.correlation.CorrelationTable.spectrum` row), subcarriers ``n = n0 + k``,
``k = 0 … N−1``, and distances d [m] with ``w = ω/c0`` [rad/m]:

.. math:: F(d) = \\sum_n x_n e^{-j w n d}, \\qquad
          \\text{path } (d_l, α_l) \\text{ contributes } |S_n|^2 α_l^* e^{+j w n d_l}
          \\text{ to } c_n.

Phasors ``e^{−jwnd}`` are formed in blocks of ``_BLOCK`` subcarriers as a base phasor times
fixed in-block offsets (independent products, so the loops vectorize); the base advances by one
complex multiplication per block and is re-seeded from an exact exponential every
``_RESEED_BLOCKS`` blocks, which keeps the rounding error ~1e-14 relative for any N.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from phyloc._jit import by_threads

_BLOCK = 32
_RESEED_BLOCKS = 16


# ---------------------------------------------------------------------------------------------
# Correlation of a spectrum at one distance: Σ x e^{−jwnd}, Σ n x e^{−jwnd}, Σ n² x e^{−jwnd}
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _block_phasors(th):
    """In-block offsets ``e^{jθm}``, ``m < _BLOCK`` (real, imag), and the step ``e^{jθ·_BLOCK}``."""
    orr = np.empty(_BLOCK)
    oi = np.empty(_BLOCK)
    zr = math.cos(th)
    zi = math.sin(th)
    pr = 1.0
    pi = 0.0
    for m in range(_BLOCK):
        orr[m] = pr
        oi[m] = pi
        t = pr * zr - pi * zi
        pi = pr * zi + pi * zr
        pr = t
    return orr, oi, math.cos(th * _BLOCK), math.sin(th * _BLOCK)


@njit(cache=True)
def _correlate(x, n0, w, d):
    """``F(d) = Σ_k x_k e^{−j w n_k d}``, ``n_k = n0 + k`` (one pass, vectorized blocks).

    No ``fastmath``: this helper is called from other kernels, and a reassociating helper rounds
    differently when compiled into a fresh caller than in the caller's cached copy, so the same
    run gave different bits in a fresh process and in a Dask worker that loaded the cache
    (``tests/test_kernel_determinism.py``). The block lanes vectorize without reassociation.
    """
    N = x.size
    th = -w * d
    orr, oi, sr, si = _block_phasors(th)
    accr = np.zeros(_BLOCK)
    acci = np.zeros(_BLOCK)
    nb = N // _BLOCK
    br = 1.0
    bi = 0.0
    for b in range(nb):
        k0 = b * _BLOCK
        if b % _RESEED_BLOCKS == 0:  # exact base phasor every few blocks
            ph = th * (n0 + k0)
            br = math.cos(ph)
            bi = math.sin(ph)
        for m in range(_BLOCK):
            qr = br * orr[m] - bi * oi[m]
            qi = br * oi[m] + bi * orr[m]
            xr = x[k0 + m].real
            xi = x[k0 + m].imag
            accr[m] += xr * qr - xi * qi
            acci[m] += xr * qi + xi * qr
        t = br * sr - bi * si
        bi = br * si + bi * sr
        br = t
    ar = accr.sum()
    ai = acci.sum()
    for k in range(nb * _BLOCK, N):
        ph = th * (n0 + k)
        c = math.cos(ph)
        s = math.sin(ph)
        ar += x[k].real * c - x[k].imag * s
        ai += x[k].real * s + x[k].imag * c
    return complex(ar, ai)


@njit(cache=True)
def _correlate_derivs(x, n0, w, d):
    """``(T0, T1, T2)``, ``T_m = Σ_k n_k^m x_k e^{−j w n_k d}``: ``F = T0``, ``F' = −jw T1``,
    ``F'' = −w² T2``."""
    N = x.size
    th = -w * d
    orr, oi, sr, si = _block_phasors(th)
    a0r = np.zeros(_BLOCK)
    a0i = np.zeros(_BLOCK)
    a1r = np.zeros(_BLOCK)
    a1i = np.zeros(_BLOCK)
    a2r = np.zeros(_BLOCK)
    a2i = np.zeros(_BLOCK)
    nb = N // _BLOCK
    br = 1.0
    bi = 0.0
    for b in range(nb):
        k0 = b * _BLOCK
        if b % _RESEED_BLOCKS == 0:
            ph = th * (n0 + k0)
            br = math.cos(ph)
            bi = math.sin(ph)
        for m in range(_BLOCK):
            qr = br * orr[m] - bi * oi[m]
            qi = br * oi[m] + bi * orr[m]
            xr = x[k0 + m].real
            xi = x[k0 + m].imag
            vr = xr * qr - xi * qi
            vi = xr * qi + xi * qr
            nn = n0 + (k0 + m)
            a0r[m] += vr
            a0i[m] += vi
            a1r[m] += nn * vr
            a1i[m] += nn * vi
            a2r[m] += nn * nn * vr
            a2i[m] += nn * nn * vi
        t = br * sr - bi * si
        bi = br * si + bi * sr
        br = t
    t0r = a0r.sum()
    t0i = a0i.sum()
    t1r = a1r.sum()
    t1i = a1i.sum()
    t2r = a2r.sum()
    t2i = a2i.sum()
    for k in range(nb * _BLOCK, N):
        nn = n0 + k
        ph = th * nn
        c = math.cos(ph)
        s = math.sin(ph)
        vr = x[k].real * c - x[k].imag * s
        vi = x[k].real * s + x[k].imag * c
        t0r += vr
        t0i += vi
        t1r += nn * vr
        t1i += nn * vi
        t2r += nn * nn * vr
        t2i += nn * nn * vi
    return complex(t0r, t0i), complex(t1r, t1i), complex(t2r, t2i)


@njit(cache=True)
def _add_path(x, power, n0, w, d, coef):
    """``x_k += coef · power_k · e^{+j w n_k d}`` in place (one path's contribution to c)."""
    N = x.size
    th = w * d
    orr, oi, sr, si = _block_phasors(th)
    cr = coef.real
    ci = coef.imag
    nb = N // _BLOCK
    br = 1.0
    bi = 0.0
    for b in range(nb):
        k0 = b * _BLOCK
        if b % _RESEED_BLOCKS == 0:
            ph = th * (n0 + k0)
            br = cr * math.cos(ph) - ci * math.sin(ph)  # coef · base phasor
            bi = cr * math.sin(ph) + ci * math.cos(ph)
        for m in range(_BLOCK):
            p = power[k0 + m]
            qr = br * orr[m] - bi * oi[m]
            qi = br * oi[m] + bi * orr[m]
            x[k0 + m] += complex(p * qr, p * qi)
        t = br * sr - bi * si
        bi = br * si + bi * sr
        br = t
    for k in range(nb * _BLOCK, N):
        x[k] += power[k] * coef * complex(math.cos(th * (n0 + k)), math.sin(th * (n0 + k)))


@njit(cache=True)
def _newton_peak(x, n0, w, d0, spacing, n_iter):
    """Newton iterations on ``g(d) = |F(d)|²`` from ``d0`` (as the PHY refine kernel).

    A step is taken only where ``g'' < 0``, clipped to half a ``spacing``; a result farther than
    one ``spacing`` from ``d0`` is discarded (``d0`` is kept).
    """
    d = d0
    for _ in range(n_iter):
        T0, T1, T2 = _correlate_derivs(x, n0, w, d)
        F1 = -1j * w * T1
        F2 = -(w * w) * T2
        g1 = 2.0 * (T0.real * F1.real + T0.imag * F1.imag)
        g2 = 2.0 * (F1.real**2 + F1.imag**2 + T0.real * F2.real + T0.imag * F2.imag)
        if not (g2 < 0.0):
            break
        step = -g1 / g2
        if step > 0.5 * spacing:
            step = 0.5 * spacing
        elif step < -0.5 * spacing:
            step = -0.5 * spacing
        d += step
        if abs(step) < 1e-9 * spacing:
            break
    if abs(d - d0) > spacing:
        d = d0
    return d


@by_threads
@njit(cache=True, parallel=True)
def refine_kernel(spectrum, n0, w, d0, spacing, n_iter, out):
    """``out[i]`` = Newton-refined maximum of ``|F_i|²`` from ``d0[i]`` (per link, parallel).

    The algorithm of :func:`phyloc.phy._kernels.refine_peaks_kernel` (whose NumPy twin
    ``refine_peaks_numpy`` of ``tests/naive_phy.py`` is this kernel's reference too), with the
    vectorized block phasors
    instead of one complex exponential per subcarrier (~10× faster).
    """
    for i in prange(d0.size):
        out[i] = _newton_peak(spectrum[i], n0, w, d0[i], spacing, n_iter)


@by_threads
@njit(cache=True, parallel=True)
def correlate_kernel(spectrum, n0, w, d, out):
    """``out[i] = F_i(d[i]) = Σ_k c_{ik} e^{−j w n_k d_i}`` (exact, per link, parallel)."""
    for i in prange(d.size):
        out[i] = _correlate(spectrum[i], n0, w, d[i])


# ---------------------------------------------------------------------------------------------
# Residual spectra: c minus the contributions of estimated paths (SAGE E-step, SIC)
# ---------------------------------------------------------------------------------------------
@by_threads
@njit(cache=True, parallel=True)
def residual_kernel(spectrum, power, tx_index, n0, w, dist, gain, out):
    """``out[i] = c_i − Σ_p |S_n|² α_{ip}^* e^{+jwn d_{ip}}`` (``dist, gain [n_links, P]``)."""
    n_links, P = dist.shape
    for i in prange(n_links):
        for k in range(spectrum.shape[1]):
            out[i, k] = spectrum[i, k]
        for p in range(P):
            _add_path(out[i], power[tx_index[i]], n0, w, dist[i, p], -np.conj(gain[i, p]))


# ---------------------------------------------------------------------------------------------
# SAGE sweeps (Fessler & Hero 1994; Fleury et al. 1999), per link
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _sage_link(c, power, energy, n0, w, d, a, n_active, n_iter, spacing, n_search, n_newton):
    """``n_iter`` SAGE sweeps over the first ``n_active`` paths of one link (the others are
    ignored: not subtracted, not updated); updates ``d`` and ``a`` in place.

    E-step ``x_l = c − Σ_{k≠l} |S|² α_k^* e^{jwnd_k}`` (the residual plus path l), M-step
    ``d_l = argmax |F_x(d)|²`` over ``d_l + m·spacing``, ``|m| <= n_search``, refined by
    ``n_newton`` Newton steps, then ``α_l = F_x(d_l)^*/‖S‖²``.
    """
    e = c.copy()
    for p in range(n_active):
        _add_path(e, power, n0, w, d[p], -np.conj(a[p]))
    for _ in range(n_iter):
        for p in range(n_active):
            _add_path(e, power, n0, w, d[p], np.conj(a[p]))  # e is now x_l
            best = d[p]
            best_g = -1.0
            for m in range(-n_search, n_search + 1):
                dm = d[p] + m * spacing
                F = _correlate(e, n0, w, dm)
                g = F.real**2 + F.imag**2
                if g > best_g:
                    best_g = g
                    best = dm
            dn = _newton_peak(e, n0, w, best, spacing, n_newton)
            F = _correlate(e, n0, w, dn)
            d[p] = dn
            a[p] = np.conj(F) / energy
            _add_path(e, power, n0, w, d[p], -np.conj(a[p]))  # back to the residual


@by_threads
@njit(cache=True, parallel=True)
def sage_kernel(
    spectrum,
    power,
    tx_index,
    energy,
    n0,
    w,
    dist,
    gain,
    n_active,
    n_iter,
    spacing,
    n_search,
    n_newton,
):
    """SAGE sweeps for every link (parallel over links; each writes its own rows of
    ``dist``/``gain`` ``[n_links, P]``, updated in place from their initial values). Only the
    first ``n_active[i]`` paths of link i take part."""
    for i in prange(dist.shape[0]):
        _sage_link(
            spectrum[i],
            power[tx_index[i]],
            energy[i],
            n0,
            w,
            dist[i],
            gain[i],
            n_active[i],
            n_iter,
            spacing,
            n_search,
            n_newton,
        )

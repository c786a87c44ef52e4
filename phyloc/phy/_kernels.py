"""Numba kernels of the PHY core.

Kernels take arrays and scalars only: no validation, no objects, no random numbers. The public
functions in :mod:`phyloc.phy.synthesis` and :mod:`phyloc.phy.correlation` validate, allocate
and call them. Tests compare every kernel with its plain-NumPy twin (``tests/naive_phy.py``,
test code, not installed) and with the slow references in ``tests/naive.py``.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from phyloc._jit import by_threads

# Per path, a chunk of _LANES subcarriers is the path's seed phasor times a table of lane
# offsets e^{jθm}; the seed advances by one complex multiplication per chunk and is re-seeded
# with an exact exp() every _RESEED subcarriers, which keeps the accumulated rounding error below
# ~1e-14 relative for any N.
_LANES = 64
_RESEED = 8 * _LANES  # must be a multiple of _LANES
# links are split into at most this many chunks, each with its own scratch rows
_CHUNKS = 64
#: Batches of fewer links (rows) than this run the serial kernels: one link's synthesis takes
#: ~0.1 ms, less than waking a thread pool, and on a busy machine a parallel region waits for
#: every thread. Rows are independent, so the values do not depend on the path taken.
SERIAL_BELOW = 8


# ---------------------------------------------------------------------------------------------
# Multipath synthesis:  R[i, k] = S[tx[i], k] · Σ_l α_l exp(−j ω n_k τ_l) + W[i, k]
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _synthesize_row(
    s_row, delays, gains, p0, P, omega, n_first, noise_row, out_row, ar, ai, lr, li
):
    """One link: ``out_row[k] = s_row[k] Σ_p α_p e^{jθ_p(n_first+k)} + noise_row[k]`` with
    ``θ_p = −ω τ_p``; ``ar, ai [N]`` and ``lr, li [_LANES]`` are scratch."""
    N = out_row.size
    for k in range(N):
        ar[k] = 0.0
        ai[k] = 0.0
    for p in range(P):
        theta = -omega * delays[p0 + p]
        z1 = np.exp(1j * theta)
        zr = 1.0
        zi = 0.0
        for m in range(_LANES):  # lane offsets e^{jθm}
            lr[m] = zr
            li[m] = zi
            t = zr * z1.real - zi * z1.imag
            zi = zr * z1.imag + zi * z1.real
            zr = t
        sr = zr  # e^{jθ·_LANES}: one chunk further
        si = zi
        g = gains[p0 + p]
        cr = 0.0
        ci = 0.0
        k0 = 0
        while k0 < N:
            if k0 % _RESEED == 0:
                seed = g * np.exp(1j * theta * (n_first + k0))
                cr = seed.real
                ci = seed.imag
            # the chunk's accumulation runs over contiguous arrays, which LLVM vectorizes:
            # 0.45 ns per path and subcarrier on one core, against 0.93 for 8 lanes in scalars
            nb = min(_LANES, N - k0)
            for m in range(nb):
                ar[k0 + m] += cr * lr[m] - ci * li[m]
                ai[k0 + m] += cr * li[m] + ci * lr[m]
            t = cr * sr - ci * si
            ci = cr * si + ci * sr
            cr = t
            k0 += _LANES
    for k in range(N):
        s = s_row[k]
        out_row[k] = (
            complex(s.real * ar[k] - s.imag * ai[k], s.real * ai[k] + s.imag * ar[k]) + noise_row[k]
        )


@by_threads
@njit(cache=True, parallel=True)
def synthesize_kernel(symbols, tx_index, delays, gains, offsets, omega, n_first, noise, out):
    """Fill ``out[i, k]`` with ``S[tx[i], k] Σ_l α_l e^{−jω(n_first+k)τ_l} + noise[i, k]``.

    ``noise`` may be ``out`` itself (as :func:`~phyloc.phy.synthesis.synthesize` passes it):
    each entry is read before it is written. Parallel over links (each link writes its own
    row). Per path, the subcarriers are visited in
    chunks of ``_LANES``: a chunk's phasors are the path's seed ``α_l e^{−jωnτ_l}`` times a table
    of lane offsets ``e^{−jωmτ_l}``, accumulated into the row; the seed advances by one complex
    multiplication per chunk and is re-seeded from an exact exponential every ``_RESEED``
    subcarriers, so rounding stays ~1e-14 relative for any N.
    """
    n_links, N = out.shape
    n_chunks = min(n_links, _CHUNKS)
    for c in prange(n_chunks):  # scratch once per chunk of links, not per link
        ar = np.empty(N)
        ai = np.empty(N)
        lr = np.empty(_LANES)
        li = np.empty(_LANES)
        for i in range(c * n_links // n_chunks, (c + 1) * n_links // n_chunks):
            p0 = offsets[i]
            _synthesize_row(
                symbols[tx_index[i]],
                delays,
                gains,
                p0,
                offsets[i + 1] - p0,
                omega,
                n_first,
                noise[i],
                out[i],
                ar,
                ai,
                lr,
                li,
            )


#: :func:`synthesize_kernel` compiled without threads, for fewer than :data:`SERIAL_BELOW`
#: links; the same code, so the same values.
synthesize_serial_kernel = synthesize_kernel.serial_only()


# ---------------------------------------------------------------------------------------------
# Correlation spectra:  c[i, n] = R[i, n]^* S[tx[i], n]   (DiPNet eq. (23))
# ---------------------------------------------------------------------------------------------
@by_threads
@njit(cache=True, parallel=True)
def spectrum_kernel(R, symbols, tx_index, out):
    """``out[i, n] = conj(R[i, n]) · symbols[tx_index[i], n]``; returns whether R is finite.

    One pass over R, parallel over links: the product, and the finiteness check through
    ``Σ (x − x)``, which is 0 for finite x and NaN for NaN or ±inf (no fast-math, so the
    compiler keeps it).
    """
    n_links, N = R.shape
    acc = 0.0
    for i in prange(n_links):
        s = symbols[tx_index[i]]
        row = 0.0
        for n in range(N):
            rr = np.float64(R[i, n].real)
            ri = np.float64(R[i, n].imag)
            row += (rr - rr) + (ri - ri)
            sr = s[n].real
            si = s[n].imag
            out[i, n] = complex(rr * sr + ri * si, rr * si - ri * sr)
        acc += row
    return acc == 0.0


#: :func:`spectrum_kernel` without threads, for fewer than :data:`SERIAL_BELOW` links.
spectrum_serial_kernel = spectrum_kernel.serial_only()


@njit(cache=True)
def symbol_moments_kernel(symbols, n_first, energy, moment2):
    """``energy[t] = Σ_n |S_tn|²`` and ``moment2[t] = Σ_n |S_tn|² n²`` with
    ``n = n_first + k`` (DiPNet eqs. (24), (26))."""
    n_tx, N = symbols.shape
    for t in range(n_tx):
        e = 0.0
        m = 0.0
        for k in range(N):
            z = symbols[t, k]
            p = z.real * z.real + z.imag * z.imag
            n = n_first + k
            e += p
            m += p * (n * n)
        energy[t] = e
        moment2[t] = m


# ---------------------------------------------------------------------------------------------
# Lagrange interpolation on a periodic uniform grid
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _wrap(j, L):
    if j < 0:
        return j + L
    if j >= L:
        return j - L
    return j


@njit(cache=True, inline="always")
def _lagrange_eval(values, row, L, x, order):
    """Lagrange interpolation of ``values[row]`` (period L) at grid coordinate x.

    Closed-form weights for the nodes −order/2+1 … order/2 around ``floor(x)`` (no divisions
    in the hot path).
    """
    fl = np.floor(x)
    t = x - fl
    j0 = np.int64(fl)
    if j0 < 0 or j0 >= L:  # rare: distances beyond one period (avoids a modulo per call)
        j0 %= L
    if order == 2:
        return values[row, j0] * (1.0 - t) + values[row, _wrap(j0 + 1, L)] * t
    if order == 4:
        tp1 = t + 1.0
        tm1 = t - 1.0
        tm2 = t - 2.0
        w0 = -t * tm1 * tm2 * (1.0 / 6.0)
        w1 = tp1 * tm1 * tm2 * 0.5
        w2 = -tp1 * t * tm2 * 0.5
        w3 = tp1 * t * tm1 * (1.0 / 6.0)
        return (
            values[row, _wrap(j0 - 1, L)] * w0
            + values[row, j0] * w1
            + values[row, _wrap(j0 + 1, L)] * w2
            + values[row, _wrap(j0 + 2, L)] * w3
        )
    half = order // 2
    acc = 0j
    for a in range(order):
        xa = a - half + 1  # nodes −half+1 … half
        w = 1.0
        for b in range(order):
            if b != a:
                xb = b - half + 1
                w *= (t - xb) / (xa - xb)
        acc += values[row, (j0 + xa) % L] * w
    return acc


@by_threads
@njit(cache=True, parallel=True)
def interp_kernel(values, rows, x, order, out):
    """``out[q] = Lagrange_order(values[rows[q]])(x[q])`` with x in grid units (periodic)."""
    L = values.shape[1]
    for q in prange(x.size):
        out[q] = _lagrange_eval(values, rows[q], L, x[q], order)


@njit(cache=True)
def interp_row_kernel(values, row, x, order, out):
    """Serial single-link variant of :func:`interp_kernel` for use inside particle filters."""
    L = values.shape[1]
    for q in range(x.size):
        out[q] = _lagrange_eval(values, row, L, x[q], order)


def lagrange_weight_max(order: int) -> float:
    """``max_{t∈[0,1]} |Π_m (t − x_m)|`` over the interpolation nodes (error-bound constant)."""
    half = order // 2
    nodes = np.arange(order) - half + 1
    t = np.linspace(0.0, 1.0, 20001)
    return float(np.max(np.abs(np.prod(t[:, None] - nodes[None, :], axis=1))))


# ---------------------------------------------------------------------------------------------
# Exact spectral evaluation and Newton refinement of correlation peaks
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _spectral_derivs(c, n, w, d):
    """F, F', F'' of F(d) = Σ_k c_k e^{−j w n_k d} at d (w = ω/c0 [rad/m])."""
    F = 0j
    F1 = 0j
    F2 = 0j
    for k in range(c.size):
        wn = w * n[k]
        e = c[k] * np.exp(-1j * wn * d)
        F += e
        F1 += -1j * wn * e
        F2 += -(wn * wn) * e
    return F, F1, F2


@by_threads
@njit(cache=True, parallel=True)
def refine_peaks_kernel(spectrum, n, w, d0, spacing, n_iter, out):
    """Newton iterations on g(d) = |F(d)|² from the grid maximum ``d0`` (per link).

    ``g' = 2 Re(F* F')``, ``g'' = 2(|F'|² + Re(F* F''))``. A step is taken only where g'' < 0
    and is clipped to half a grid spacing; the result stays within one spacing of ``d0``.
    """
    for i in prange(d0.size):
        d = d0[i]
        for _ in range(n_iter):
            F, F1, F2 = _spectral_derivs(spectrum[i], n, w, d)
            g1 = 2.0 * (F.real * F1.real + F.imag * F1.imag)
            g2 = 2.0 * (F1.real**2 + F1.imag**2 + F.real * F2.real + F.imag * F2.imag)
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
        if abs(d - d0[i]) > spacing:
            d = d0[i]
        out[i] = d


@by_threads
@njit(cache=True, parallel=True)
def spectral_eval_kernel(spectrum, rows, n, w, d, out):
    """Exact ``F(d) = Σ_k c_k e^{−j w n_k d}`` for ``spectrum[rows[q]]`` at ``d[q]``."""
    for q in prange(d.size):
        c = spectrum[rows[q]]
        acc = 0j
        for k in range(c.size):
            acc += c[k] * np.exp(-1j * w * n[k] * d[q])
        out[q] = acc

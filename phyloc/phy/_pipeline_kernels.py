"""Fused Numba kernels of the synthesis → correlation-table pipeline.

Each kernel does in one pass over a link's row what the kernels of :mod:`phyloc.phy._kernels`
and :mod:`phyloc.phy._gauss` do in two, with the same arithmetic in the same order, so the
values are bit for bit those of the two-pass path (``tests/test_phy_pipeline_kernels.py``
checks that, and the plain-NumPy twins in ``tests/naive_phy.py``):

* :func:`noisy_synthesize_kernel`: a link's noise row (the ziggurat of
  :func:`~phyloc.phy._gauss.normal_rows_kernel`) drawn into its output row and, while that row
  is still in cache, the multipath sum added to it
  (:func:`~phyloc.phy._kernels.synthesize_kernel`); the two-pass path wrote the whole noise
  array, then read it back.
* :func:`spectrum_padded_kernel`: the correlation spectrum ``c = R^* S`` of a chunk of links
  (:func:`~phyloc.phy._kernels.spectrum_kernel`) written at once into the table's spectrum and
  into the zero-padded input rows of the FFT; the two-pass path copied the spectrum into the
  FFT input afterwards.
* :func:`finite_nonzero_kernel`: the pilot check of
  :func:`~phyloc.phy.waveform.check_symbols` (every entry finite, one non-zero) in one pass
  without temporaries (two NumPy passes and a temporary array cost a one-link call ~7 µs
  per pilot check).

Kernels take arrays and scalars only: no validation, no objects, no random numbers.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from phyloc._jit import serial_twin
from phyloc.phy._gauss import _wedge_or_tail, _xoshiro, splitmix64
from phyloc.phy._kernels import _CHUNKS, _LANES, _synthesize_row


@njit(cache=True)
def normal_row(seed, a, zx, zf, zk, row):
    """``row[:] = a · N(0, 1)`` draws of the xoshiro256** stream seeded by ``seed``: one row of
    :func:`~phyloc.phy._gauss.normal_rows_kernel` (the same draws in the same order)."""
    z, s0 = splitmix64(seed)
    z, s1 = splitmix64(z)
    z, s2 = splitmix64(z)
    z, s3 = splitmix64(z)
    for j in range(row.size):
        while True:
            r, s0, s1, s2, s3 = _xoshiro(s0, s1, s2, s3)
            idx = np.int64(r & np.uint64(0xFF))
            neg = (r & np.uint64(0x100)) != np.uint64(0)
            rabs = np.int64(r >> np.uint64(12))
            x = rabs * (zx[idx] * (1.0 / 4503599627370496.0))
            if rabs < zk[idx]:
                break
            ok, x, s0, s1, s2, s3 = _wedge_or_tail(idx, x, s0, s1, s2, s3, zx, zf)
            if ok:
                break
        row[j] = -a * x if neg else a * x


@njit(cache=True, parallel=True)
def noisy_synthesize_kernel(
    seeds, scale, zx, zf, zk, symbols, tx_index, delays, gains, offsets, omega, n_first, out, flat
):
    """``out[i, k] = S[tx[i], k] Σ_l α_l e^{−jω(n_first+k)τ_l} + W[i, k]`` with ``W[i]`` the
    complex noise row of seed ``seeds[i]`` and scale ``scale[i]``, real and imaginary parts
    interleaved (``flat`` is ``out``'s float view ``[n_links, 2N]``, filled as
    :func:`~phyloc.phy._gauss.normal_rows_kernel` fills it). Row by row: the noise is drawn
    into the row, then the synthesis reads it back while it is in cache. Parallel over chunks
    of links, as :func:`~phyloc.phy._kernels.synthesize_kernel`."""
    n_links, N = out.shape
    n_chunks = min(n_links, _CHUNKS)
    for c in prange(n_chunks):
        ar = np.empty(N)
        ai = np.empty(N)
        lr = np.empty(_LANES)
        li = np.empty(_LANES)
        for i in range(c * n_links // n_chunks, (c + 1) * n_links // n_chunks):
            normal_row(seeds[i], scale[i], zx, zf, zk, flat[i])
            p0 = offsets[i]
            _synthesize_row(
                symbols[tx_index[i]],
                delays,
                gains,
                p0,
                offsets[i + 1] - p0,
                omega,
                n_first,
                out[i],
                out[i],
                ar,
                ai,
                lr,
                li,
            )


#: :func:`noisy_synthesize_kernel` without threads (fewer links than
#: :data:`~phyloc.phy._kernels.SERIAL_BELOW`); the same code, so the same values.
noisy_synthesize_serial_kernel = serial_twin(noisy_synthesize_kernel)


@njit(cache=True, inline="always")
def _conj_times(R, s, out1, out2):
    """``out1[n] = out2[n] = conj(R[n]) · s[n]``; returns whether an entry of R is not finite."""
    bad = False
    for n in range(R.size):
        rr = np.float64(R[n].real)
        ri = np.float64(R[n].imag)
        bad |= ((rr - rr) != 0.0) | ((ri - ri) != 0.0)
        sr = s[n].real
        si = s[n].imag
        c = complex(rr * sr + ri * si, rr * si - ri * sr)
        out1[n] = c
        out2[n] = c
    return bad


@njit(cache=True)
def spectrum_padded_kernel(R, symbols, tx_index, a, spectrum, buf):
    """For the links ``i = a … a + b − 1`` (b = rows to fill): ``spectrum[i, n] = conj(R[i, n]) ·
    symbols[tx[i], n]`` and the same values into row ``i − a`` of the padded FFT input ``buf
    [≥ b, L]`` (bin ``n`` at index ``n mod L``: ``n = 0 … h`` at ``0 … h``, ``n = −h … −1`` at
    ``L − h … L − 1``; the middle is left alone). ``b = min(buf.shape[0], n_links − a)``.
    Returns whether those rows of R are finite (``x − x`` is 0 for finite x, NaN else; an
    or-reduction of flags, which vectorizes where a floating-point sum is one serial chain).

    Serial: it runs once per FFT chunk, between two multi-threaded transforms, and a parallel
    region per chunk cost more than it saved on a loaded 2-core machine (the pipeline of
    ``phyloc bench phy`` took 1.37 FFT floors with it, 1.20 without)."""
    n_links, N = R.shape
    L = buf.shape[1]
    h = (N - 1) // 2
    b = min(buf.shape[0], n_links - a)
    bad = 0
    for r in range(b):
        i = a + r
        s = symbols[tx_index[i]]
        # columns 0 … h − 1 (n = −h … −1) go to L − h …, columns h … N − 1 (n = 0 … h) to 0 …
        row = _conj_times(R[i, :h], s[:h], spectrum[i, :h], buf[r, L - h :])
        row |= _conj_times(R[i, h:], s[h:], spectrum[i, h:], buf[r, : N - h])
        if row:
            bad += 1
    return bad == 0


@njit(cache=True)
def finite_nonzero_kernel(u):
    """For the bits ``u`` (uint64) of a float array (a complex array's float view): 0 if every
    entry is finite and one is non-zero, 1 if an entry is NaN or ±inf (all exponent bits set),
    2 if all are ±0. One pass of integer max/or reductions, which vectorize."""
    m = np.uint64(0x7FF0000000000000)
    e = np.uint64(0)
    nz = np.uint64(0)
    for k in range(u.size):
        b = u[k]
        t = b & m
        if t > e:
            e = t
        nz |= b << np.uint64(1)  # all bits but the sign
    if e == m:
        return 1
    return 0 if nz != np.uint64(0) else 2

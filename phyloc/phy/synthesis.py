"""Received OFDM signals of a batch of multipath links (DiPNet eq. (6)).

In the frequency domain (the signal model of :doc:`/guide/design`)

.. math:: R_n = S_n \\sum_l α_l e^{-jωnτ_l} + W_n, \\qquad W_n \\sim \\mathcal{CN}(0, σ^2),

which is the exact DFT of ``r(iT) = Σ_l α_l s(iT − τ_l) + ε(iT)`` for any real (fractional)
delays: s(t) is periodic, so a delay is a phase ramp. :func:`~phyloc.phy.waveform.to_time_domain`
gives the time samples (for ``os = 1`` the noise is then white with variance σ² per sample).

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import math

import numpy as np

from phyloc.errors import ValidationError
from phyloc.phy import _gauss, _kernels, _pipeline_kernels
from phyloc.phy import fft as _fft
from phyloc.phy._gauss import ZIG_F, ZIG_K, ZIG_X
from phyloc.phy._kernels import SERIAL_BELOW
from phyloc.phy.paths import PathSet
from phyloc.phy.system import OFDMSystem
from phyloc.phy.waveform import _check_rng, check_symbols


def complex_noise(shape, noise_var, rng: np.random.Generator) -> np.ndarray:
    """Circularly-symmetric complex Gaussian noise ``CN(0, σ²)``.

    Each row (all axes but the last) draws one 64-bit seed from ``rng`` and fills its real and
    imaginary parts, interleaved, from its own stream (:mod:`phyloc.phy._gauss`: a ziggurat on
    xoshiro256**). Rows are filled in parallel, and a row's values depend on ``rng``'s state
    and its position only, so results are identical on any number of threads or workers.

    Parameters
    ----------
    shape : tuple
        Output shape; the last axis is subcarriers (or samples).
    noise_var : float or [shape[0]], float
        Variance σ² [W] per entry, or one per row.
    rng : numpy.random.Generator

    Returns
    -------
    w : shape, complex128

    Examples
    --------
    >>> w = complex_noise((400, 2569), 2.0, np.random.default_rng(0))
    >>> round(float(np.mean(np.abs(w) ** 2)), 2)
    2.0
    """
    _check_rng(rng)
    shape = tuple(int(x) for x in shape)
    z = np.empty((math.prod(shape[:-1]), 2 * shape[-1]))
    _fill_noise(z, np.asarray(noise_var, dtype=np.float64), rng)
    return z.view(np.complex128).reshape(shape)


def _noise_streams(rows: int, nv, rng):
    """``(seeds, scale)`` of ``rows`` noise rows: one 64-bit seed per row drawn from ``rng``
    and the standard deviation ``sqrt(nv/2)`` of each row's real and imaginary parts (``nv`` a
    scalar or one variance per row)."""
    scale = np.sqrt(nv / 2.0)
    if scale.ndim == 1:
        per_row = np.repeat(scale, rows // max(scale.size, 1)) if scale.size else scale
    else:
        per_row = np.full(rows, float(scale))
    seeds = rng.integers(0, 2**64, size=rows, dtype=np.uint64, endpoint=False)
    return seeds, np.ascontiguousarray(per_row, dtype=np.float64)


def _fill_noise(z, nv, rng):
    """Fill the float rows ``z [rows, 2M]`` (complex rows, interleaved) with ``CN(0, nv)``;
    ``nv`` is a scalar or one variance per row."""
    rows = z.shape[0]
    seeds, per_row = _noise_streams(rows, nv, rng)
    kernel = _gauss.normal_rows_serial_kernel if rows < SERIAL_BELOW else _gauss.normal_rows_kernel
    kernel(seeds, per_row, ZIG_X, ZIG_F, ZIG_K, z)


def synthesize(
    paths: PathSet,
    symbols,
    system: OFDMSystem,
    rng: np.random.Generator | None = None,
    *,
    tx_index=None,
    noise_var=None,
) -> np.ndarray:
    """Frequency-domain received symbols of every link (DiPNet eq. (6)).

    Parameters
    ----------
    paths : PathSet
        ``n_links`` links with delays ``τ_l`` [s] (>= 0) and gains ``α_l`` [√W].
    symbols : [n_tx, N] or [N], complex
        Pilot symbols of each transmitter (:func:`~phyloc.phy.waveform.qpsk_symbols`).
    system : OFDMSystem
    rng : numpy.random.Generator or None
        Source of the noise. ``None`` gives the noise-free signal (then ``noise_var`` must be
        None or 0).
    tx_index : [n_links], int, optional
        Row of ``symbols`` each link transmits; default row 0 for every link.
    noise_var : float or [n_links], float, optional
        Noise variance σ² [W] per subcarrier; default ``system.noise_power_w``.

    Returns
    -------
    R : [n_links, N], complex128
        ``R_n = S_n Σ_l α_l e^{−jωnτ_l} + W_n``; column j is subcarrier ``n = j − (N−1)/2``.

    Examples
    --------
    >>> from phyloc.phy import OFDMSystem, PathSet
    >>> from phyloc.phy.waveform import qpsk_symbols
    >>> sysm = OFDMSystem(n_subcarriers=65)
    >>> rng = np.random.default_rng(0)
    >>> S = qpsk_symbols(sysm, 1, rng)
    >>> R = synthesize(PathSet.single_path([1e-7], [1e-6]), S, sysm, rng)
    >>> R.shape
    (1, 65)
    """
    if not isinstance(paths, PathSet):
        raise ValidationError("paths", type(paths).__name__, "a phyloc.phy.PathSet is required")
    S = check_symbols(symbols, system)
    n_links, N = paths.n_links, system.n_subcarriers
    if tx_index is None:
        tx = np.zeros(n_links, dtype=np.int64)
    else:
        tx = np.ascontiguousarray(tx_index, dtype=np.int64)
        if tx.shape != (n_links,):
            raise ValidationError(
                "tx_index", f"shape {tx.shape}", f"must be [n_links] = [{n_links}]"
            )
        if n_links and (tx.min() < 0 or tx.max() >= S.shape[0]):
            raise ValidationError(
                "tx_index",
                f"range [{tx.min()}, {tx.max()}]",
                f"must index symbols rows 0…{S.shape[0] - 1}",
            )
    n_first = -float((N - 1) // 2)
    serial = n_links < SERIAL_BELOW
    if rng is None:
        if noise_var not in (None, 0, 0.0):
            raise ValidationError("rng", None, "a Generator is required when noise_var > 0")
        out = _fft.recycled_empty((n_links, N))
        out.fill(0)
        kernel = _kernels.synthesize_serial_kernel if serial else _kernels.synthesize_kernel
        kernel(S, tx, paths.delays, paths.gains, paths.offsets, system.omega, n_first, out, out)
        return out
    if noise_var is None:  # the system's σ²: one float, checked without array temporaries
        nv = np.float64(system.noise_power_w)
        if not (math.isfinite(nv) and nv >= 0):
            raise ValidationError("noise_var", float(nv), "must be finite and >= 0 W")
    else:
        nv = np.asarray(noise_var, dtype=np.float64)
        if nv.ndim > 1 or (nv.ndim == 1 and nv.shape != (n_links,)):
            raise ValidationError(
                "noise_var", f"shape {nv.shape}", f"must be a scalar or [n_links] = [{n_links}]"
            )
        if not np.all(np.isfinite(nv)) or np.any(nv < 0):
            raise ValidationError("noise_var", nv, "must be finite and >= 0 W")
    _check_rng(rng)
    # one pass per link: its noise row is drawn into its output row, and the multipath sum is
    # added while the row is in cache (the values of drawing all the noise first, bit for bit)
    seeds, scale = _noise_streams(n_links, nv, rng)
    # the memory of a dropped signal of the same size if there is one (fresh pages: a page
    # fault and the kernel's zeroing for every 4 KiB, ~1000 per batch of 256 links)
    out = _fft.recycled_empty((n_links, N))
    kernel = (
        _pipeline_kernels.noisy_synthesize_serial_kernel
        if serial
        else _pipeline_kernels.noisy_synthesize_kernel
    )
    kernel(
        seeds,
        scale,
        ZIG_X,
        ZIG_F,
        ZIG_K,
        S,
        tx,
        paths.delays,
        paths.gains,
        paths.offsets,
        system.omega,
        n_first,
        out,
        out.view(np.float64),
    )
    return out

"""Cross-correlation tables of received signals (DiPNet eqs. (21)–(23), §III-B).

For a link with received frequency-domain symbols ``R_n`` and known pilots ``S_n`` the
cross-correlation with the pilot delayed by ``d/c0`` is

.. math:: f(d) = \\sum_n R_n^* S_n e^{-jωnd/c_0},

which equals ``r^H s(d/c0)`` of DiPNet eq. (23) for ``os = 1`` (and ``r^H s/os`` for
oversampled time vectors, so tables do not depend on the sampling rate). It is a trigonometric
polynomial of period ``c0/f_sc`` in d. :func:`correlation_tables` evaluates it on the grid
``d_k = k·c0/(βB)``, ``k = 0 … L−1`` with ``L = βN``, by one zero-padded FFT of
``c_n = R_n^* S_n`` per link (the "β-interpolated IFFT"); L is chosen 5-smooth (e.g. 20480 for
N = 2569, β ≈ 8: 8·2569 = 20552 has the prime factor 367 and transforms 5–10× slower), and β is
the resulting ratio L/N.

Interpolation between grid points (:meth:`CorrelationTable.evaluate`) uses Lagrange polynomials
on ``order`` neighbouring grid values (2 = linear, 4 = cubic, 6 = quintic). For every link the
error is bounded (Hermite–Genocchi remainder, applied to each exponential of the sum):

.. math:: |\\tilde f(d) - f(d)| \\le \\frac{W_p}{p!} \\sum_n |c_n| \\left(\\frac{2π|n|}{L}\\right)^p
          \\le \\frac{W_p}{p!}\\left(\\frac{π}{β}\\right)^p \\sum_n |c_n|,

``W_p = max_{t∈[0,1]} |Π_m (t − x_m)|`` over the nodes (1/4, 9/16, 225/64 for p = 2, 4, 6). For a
one-path link ``Σ|c_n| = |f(d_peak)|``; at β = 7.97 the relative bound is 1.9e-2 (linear),
5.7e-4 (cubic) and 1.8e-5 (quintic). :meth:`CorrelationTable.interpolation_error_bound` returns
the per-link bound; ``phyloc bench phy`` measures errors and costs. Numba kernels of other
layers that read tables themselves (the direct likelihoods of :mod:`phyloc.localization.direct`)
call the same interpolation through :func:`lagrange_eval`.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.phy import _kernels, _pipeline_kernels
from phyloc.phy import fft as _fft
from phyloc.phy._kernels import _lagrange_eval
from phyloc.phy.system import C0, OFDMSystem
from phyloc.phy.waveform import check_symbols

_ORDERS = {"linear": 2, "cubic": 4, "quintic": 6}


def interpolation_order(method) -> int:
    """Number of grid points of an interpolation method (``"linear"``, ``"cubic"``,
    ``"quintic"`` or the count 2, 4, 6)."""
    if isinstance(method, str):
        if method not in _ORDERS:
            raise ValidationError("interpolation", method, f"one of {sorted(_ORDERS)}")
        return _ORDERS[method]
    if method in (2, 4, 6):
        return int(method)
    raise ValidationError("interpolation", method, f"one of {sorted(_ORDERS)} or 2, 4, 6")


@njit(cache=True, inline="always")
def lagrange_eval(values, row, L, x, order):
    """Lagrange interpolation of one table row at one grid coordinate, for Numba kernels.

    The per-point step of :meth:`CorrelationTable.evaluate`, public so that the ``@njit``
    kernels of other layers interpolate tables exactly as this module does: ``values[row]``
    (periodic with period ``L``) at the grid coordinate ``x = d/spacing_m``, from the
    ``order`` grid values ``−order/2 + 1 … order/2`` around ``floor(x)`` (closed-form weights
    for orders 2 and 4). Inlined into the caller; not validated (kernel rules).

    Parameters
    ----------
    values : [n_links, L] complex128
        :attr:`CorrelationTable.values`.
    row : int
        Link (row of ``values``).
    L : int
        ``values.shape[1]``.
    x : float
        Distance in grid spacings, ``d/spacing_m`` (any real; wrapped into one period).
    order : int
        2, 4 or 6 (:func:`interpolation_order`).

    Returns
    -------
    complex
        The interpolated ``f(d)`` [√W].

    Examples
    --------
    >>> import numpy as np
    >>> values = np.array([[0, 1, 2, 3, 2, 1]], dtype=np.complex128)
    >>> complex(lagrange_eval(values, 0, 6, 1.5, 2))
    (1.5+0j)
    """
    return _lagrange_eval(values, row, L, x, order)


def fft_length(system: OFDMSystem, beta: float) -> int:
    """Padded FFT length ``L``: the 5-smooth length nearest to β·N (and >= N).

    The table's β is then ``L/N`` (7.97 for N = 2569 and a requested β = 8: L = 20480).
    """
    b = v.positive("beta", beta)
    if b < 1.0:
        raise ValidationError("beta", beta, "must be >= 1 (the grid must sample the full band)")
    target = b * system.n_subcarriers
    above = _fft.next_fast_len(math.ceil(target))
    below = _fft.prev_fast_len(math.floor(target))
    if below >= system.n_subcarriers and target - below < above - target:
        return below
    return above


@dataclass(frozen=True, eq=False)
class CorrelationTable:
    """Correlation functions ``f(d)`` of a batch of links on a uniform distance grid.

    Attributes
    ----------
    values : [n_links, L], complex128
        ``f(d_k)``, ``d_k = k·spacing_m`` (periodic in k with period L).
    spectrum : [n_links, N], complex128
        ``c_n = R_n^* S_n``; :meth:`exact` evaluates f from it at any distance.
    spacing_m : float
        Grid spacing ``c0/(βB)`` [m].
    noise_var : [n_links], float64
        Noise variance σ² [W] per subcarrier (per sample for os = 1).
    symbol_energy : [n_links], float64
        ``‖S‖² = Σ_n |S_n|²`` of each link's pilots (``= ‖s‖²`` for os = 1).
    symbol_moment2 : [n_links], float64
        ``Σ_n |S_n|² n²`` (enters the CRB, DiPNet eq. (24), and the ENV, DiPNet eq. (26)).
    system : OFDMSystem
    symbols : [n_tx, N], complex128
        The pilot symbols the tables were built with.
    tx_index : [n_links], int64
        Row of ``symbols`` of each link (``symbols[tx_index[i]]`` are link i's pilots).
    """

    values: np.ndarray
    spectrum: np.ndarray
    spacing_m: float
    noise_var: np.ndarray
    symbol_energy: np.ndarray
    symbol_moment2: np.ndarray
    system: OFDMSystem
    symbols: np.ndarray
    tx_index: np.ndarray

    # -- geometry of the grid ------------------------------------------------------------------
    @property
    def n_links(self) -> int:
        """Number of links."""
        return self.values.shape[0]

    @property
    def n_fft(self) -> int:
        """Grid length L (the padded FFT length)."""
        return self.values.shape[1]

    @property
    def beta(self) -> float:
        """Interpolation factor ``β = L/N``."""
        return self.n_fft / self.system.n_subcarriers

    @property
    def period_m(self) -> float:
        """Period of f in distance, ``c0/f_sc`` [m]."""
        return self.n_fft * self.spacing_m

    def distances(self) -> np.ndarray:
        """The grid ``d_k = k·spacing_m`` [m], ``[L]``: the axis paired with :attr:`values`."""
        return np.arange(self.n_fft) * self.spacing_m

    # -- evaluation ----------------------------------------------------------------------------
    def _rows_and_d(self, d, links):
        d = v.finite_array("d", d)
        if links is None:
            if d.ndim == 0 or d.shape[0] != self.n_links:
                raise ValidationError(
                    "d",
                    f"shape {d.shape}",
                    f"without `links`, the first axis must be n_links = {self.n_links}",
                )
            rows = np.broadcast_to(
                np.arange(self.n_links).reshape((-1,) + (1,) * (d.ndim - 1)), d.shape
            )
        else:
            rows = np.asarray(links, dtype=np.int64)
            try:
                rows, d = np.broadcast_arrays(rows, d)
            except ValueError:
                raise ValidationError(
                    "links", f"shape {rows.shape}", f"must broadcast with d of shape {d.shape}"
                ) from None
            if rows.size and (rows.min() < 0 or rows.max() >= self.n_links):
                raise ValidationError(
                    "links", f"range [{rows.min()}, {rows.max()}]", f"0 … {self.n_links - 1}"
                )
        return np.ascontiguousarray(rows.ravel()), np.ascontiguousarray(d.ravel()), d.shape

    def evaluate(self, d, links=None, *, interpolation="cubic") -> np.ndarray:
        """Interpolated ``f(d)`` [√W] at arbitrary distances (vectorized; Numba kernel).

        Parameters
        ----------
        d : array_like, float
            Distances [m]. Without ``links`` the first axis indexes links (``[n_links, ...]``).
        links : array_like, int, optional
            Link of each distance (broadcast with ``d``).
        interpolation : {"cubic", "linear", "quintic"}
            Lagrange order; see the module docstring for the error bound.
        """
        order = interpolation_order(interpolation)
        rows, x, shape = self._rows_and_d(d, links)
        out = np.empty(x.size, dtype=np.complex128)
        _kernels.interp_kernel(self.values, rows, x / self.spacing_m, order, out)
        return out.reshape(shape)

    def exact(self, d, links=None) -> np.ndarray:
        """``f(d) = Σ_n c_n e^{−jωnd/c0}`` summed directly (O(N) per point; the reference)."""
        rows, x, shape = self._rows_and_d(d, links)
        out = np.empty(x.size, dtype=np.complex128)
        _kernels.spectral_eval_kernel(
            self.spectrum, rows, self.system.subcarrier_indices(), self.system.omega / C0, x, out
        )
        return out.reshape(shape)

    def log_likelihood(self, d, links=None, *, noise_var=None, interpolation="cubic"):
        """One-path log-likelihood ``|f(d)|²/(σ²‖S‖²)`` (DiPNet eq. (22)), up to a constant.

        ``noise_var`` replaces σ² (per link, broadcast like ``d``) — e.g. DiPNet's equivalent
        noise variance of DiPNet eq. (26) turns this into DiPNet eq. (25).
        """
        f = self.evaluate(d, links, interpolation=interpolation)
        rows, _, shape = self._rows_and_d(d, links)
        rows = rows.reshape(shape)
        nv = self.noise_var[rows] if noise_var is None else np.asarray(noise_var, np.float64)
        return (f.real**2 + f.imag**2) / (nv * self.symbol_energy[rows])

    def amplitude(self, d, links=None, *, interpolation="cubic") -> np.ndarray:
        """LOS amplitude estimate ``α̂ = s^H r/‖s‖² = f(d)^*/‖S‖²`` (DiPNet eq. (21)) [√W]."""
        f = self.evaluate(d, links, interpolation=interpolation)
        rows, _, shape = self._rows_and_d(d, links)
        return np.conj(f) / self.symbol_energy[rows.reshape(shape)]

    def snr(self, d, links=None, *, interpolation="cubic") -> np.ndarray:
        """Per-sample SNR estimate ``|α̂|²/σ²`` at distance d, corrected for the noise bias.

        ``E|α̂|² = |α|² + σ²/‖S‖²``, so the estimate is ``max(|α̂|²/σ² − 1/‖S‖², 0)``. The
        post-correlation SNR is ``‖S‖²`` times this (N times for unit-modulus pilots).
        """
        a = self.amplitude(d, links, interpolation=interpolation)
        rows, _, shape = self._rows_and_d(d, links)
        rows = rows.reshape(shape)
        raw = np.abs(a) ** 2 / self.noise_var[rows] - 1.0 / self.symbol_energy[rows]
        return np.maximum(raw, 0.0)

    def peak(self, *, window_m=None, refine: bool = True, n_iter: int = 8) -> np.ndarray:
        """Distance of the largest ``|f(d)|²`` per link [m], ``[n_links]``.

        Parameters
        ----------
        window_m : (float, float), optional
            Search only ``lo <= d <= hi`` (on the periodic grid; ``lo`` may be negative).
            Default: the whole period.
        refine : bool
            Refine the grid maximum by Newton iterations on the exact ``|f(d)|²`` (spectral
            derivatives), so the estimate is the maximum-likelihood delay of the one-path model
            and not limited by the grid.
        """
        L, h = self.n_fft, self.spacing_m
        if window_m is None:
            k = np.arange(L)
        else:
            lo, hi = (v.finite("window_m[0]", window_m[0]), v.finite("window_m[1]", window_m[1]))
            if not lo < hi:
                raise ValidationError("window_m", window_m, "must be (lo, hi) with lo < hi")
            k = np.arange(math.ceil(lo / h), math.floor(hi / h) + 1)
            if k.size == 0:
                raise ValidationError("window_m", window_m, f"must contain a grid point ({h} m)")
        vals = self.values[:, k % L]
        best = np.argmax(vals.real**2 + vals.imag**2, axis=1)
        d0 = np.ascontiguousarray(k[best] * h, dtype=np.float64)
        if not refine:
            return d0
        out = np.empty_like(d0)
        _kernels.refine_peaks_kernel(
            self.spectrum,
            self.system.subcarrier_indices(),
            self.system.omega / C0,
            d0,
            h,
            int(n_iter),
            out,
        )
        return out

    def pilots(self, link: int) -> np.ndarray:
        """The pilot symbols ``S_n`` of one link, ``[N]`` complex128."""
        return self.symbols[self.tx_index[link]]

    def select(self, links) -> CorrelationTable:
        """The tables of a subset of links (in the given order)."""
        idx = np.asarray(links, dtype=np.int64)
        return CorrelationTable(
            values=self.values[idx],
            spectrum=self.spectrum[idx],
            spacing_m=self.spacing_m,
            noise_var=self.noise_var[idx],
            symbol_energy=self.symbol_energy[idx],
            symbol_moment2=self.symbol_moment2[idx],
            system=self.system,
            symbols=self.symbols,
            tx_index=self.tx_index[idx],
        )

    def interpolation_error_bound(self, interpolation="cubic") -> np.ndarray:
        """Per-link bound on ``|evaluate(d) − exact(d)|`` [√W], ``[n_links]`` (module docstring)."""
        p = interpolation_order(interpolation)
        nu = 2.0 * math.pi * np.abs(self.system.subcarrier_indices()) / self.n_fft
        w = _kernels.lagrange_weight_max(p) / math.factorial(p)
        return w * (np.abs(self.spectrum) * nu**p).sum(axis=1)


def correlation_tables(
    R,
    symbols,
    system: OFDMSystem,
    *,
    beta: float = 8.0,
    tx_index=None,
    noise_var=None,
    chunk: int = 64,
    out: np.ndarray | None = None,
) -> CorrelationTable:
    """Correlation tables of a batch of links by one zero-padded FFT per link (DiPNet eq. (23)).

    Parameters
    ----------
    R : [n_links, N], complex
        Received frequency-domain symbols (:func:`~phyloc.phy.synthesis.synthesize`, or
        :func:`~phyloc.phy.waveform.from_time_domain` of recorded samples).
    symbols : [n_tx, N] or [N], complex
        Pilot symbols known to the receiver.
    system : OFDMSystem
    beta : float
        Requested interpolation factor (>= 1); the grid length is the next 5-smooth length
        >= β·N and the table's :attr:`~CorrelationTable.beta` is the resulting ratio.
    tx_index : [n_links], int, optional
        Row of ``symbols`` transmitted on each link (default 0).
    noise_var : float or [n_links], optional
        σ² [W] per subcarrier; default ``system.noise_power_w``.
    chunk : int
        Links per planned FFT (bounds the working memory).
    out : [n_links, L] complex128, optional
        C-contiguous array to hold the table's :attr:`~CorrelationTable.values` (its old
        contents are overwritten; the table keeps a reference); use
        :func:`phyloc.phy.fft.aligned_empty` for SIMD alignment. Without it the values go to
        :func:`phyloc.phy.fft.recycled_empty`, which reuses the memory of a dropped table of
        the same size: fresh pages would cost the operating system's zeroing (L·16 bytes per
        link, ~10 µs at β ≈ 8 against ~66 µs for the FFT; ``phyloc bench phy``). The
        spectrum always goes there.

    Returns
    -------
    CorrelationTable

    Examples
    --------
    >>> from phyloc.phy import OFDMSystem, PathSet, C0
    >>> from phyloc.phy.waveform import qpsk_symbols
    >>> from phyloc.phy.synthesis import synthesize
    >>> sysm = OFDMSystem()
    >>> rng = np.random.default_rng(7)
    >>> S = qpsk_symbols(sysm, 1, rng)
    >>> R = synthesize(PathSet.single_path([42.3 / C0], [1e-6]), S, sysm, rng)
    >>> tab = correlation_tables(R, S, sysm, beta=8)
    >>> tab.n_fft
    20480

    The ML distance is off the true 42.3 m by thermal noise (here by 0.12 m); its standard
    deviation is the √CRB of DiPNet eq. (24) at the link's per-sample SNR ``|α|²/σ²``:

    >>> from phyloc.phy.bounds import crb_range
    >>> d_hat = float(tab.peak()[0])
    >>> std = float(np.sqrt(crb_range(1e-12 / sysm.noise_power_w, S[0], sysm)))
    >>> round(std, 2)
    0.14
    >>> abs(d_hat - 42.3) < 3 * std
    True
    """
    S = check_symbols(symbols, system)
    R = np.asarray(R)
    if R.ndim == 1:
        R = R[None, :]
    N = system.n_subcarriers
    if R.ndim != 2 or R.shape[1] != N:
        raise ValidationError("R", f"array of shape {R.shape}", f"must be [n_links, N = {N}]")
    if R.dtype not in (np.complex64, np.complex128):  # complex64 (stored datasets) as it is
        try:
            R = R.astype(np.complex128)
        except (TypeError, ValueError):
            raise ValidationError("R", "<array>", "must convert to complex128") from None
    R = np.ascontiguousarray(R)
    n_links = R.shape[0]
    tx = np.zeros(n_links, np.int64) if tx_index is None else np.asarray(tx_index, np.int64)
    if tx.shape != (n_links,) or (n_links and (tx.min() < 0 or tx.max() >= S.shape[0])):
        raise ValidationError("tx_index", tx, f"[n_links] indices into 0 … {S.shape[0] - 1}")
    tx = np.ascontiguousarray(tx)
    if noise_var is None:  # the system's σ²: one float, checked without array temporaries
        nv = np.full(n_links, float(system.noise_power_w))
        ok = math.isfinite(nv[0]) and nv[0] > 0 if n_links else True
    else:
        nv = np.broadcast_to(np.asarray(noise_var, dtype=np.float64), (n_links,)).copy()
        ok = bool(np.all(np.isfinite(nv))) and not np.any(nv <= 0)
    if not ok:
        raise ValidationError("noise_var", nv, "must be finite and > 0 W")
    chunk = v.integer("chunk", chunk, minimum=1)

    L = fft_length(system, beta)
    spectrum = _fft.recycled_empty((n_links, N))  # as values: no fresh pages to fault in
    if out is None:
        values = _fft.recycled_empty((n_links, L))
    elif (
        not isinstance(out, np.ndarray)
        or out.shape != (n_links, L)
        or out.dtype != np.complex128
        or not out.flags.c_contiguous
        or not out.flags.writeable
    ):
        got = f"{type(out).__name__} {getattr(out, 'shape', '')} {getattr(out, 'dtype', '')}"
        raise ValidationError(
            "out", got, f"must be a writeable C-contiguous complex128 array [{n_links}, {L}]"
        )
    else:
        values = out
    # per chunk, one pass over R writes c = R^* S into the table's spectrum and straight into
    # the padded input of the FFT (and checks that R is finite)
    kernel = _pipeline_kernels.spectrum_padded_kernel
    finite = True
    h = (N - 1) // 2
    for a in range(0, n_links, chunk):
        b = min(a + chunk, n_links)

        def fill(buf, a=a):
            nonlocal finite
            finite &= kernel(R, S, tx, a, spectrum, buf)

        _fft.batch_fft(b - a, L).filled(fill, b - a, h, out=values[a:b])
    if not finite:
        v.check_finite("R", R)
    energy = np.empty(S.shape[0])
    moment2 = np.empty(S.shape[0])
    _kernels.symbol_moments_kernel(S, -float((N - 1) // 2), energy, moment2)
    energy, moment2 = energy[tx], moment2[tx]
    return CorrelationTable(
        values=values,
        spectrum=spectrum,
        spacing_m=C0 / (L * system.subcarrier_spacing_hz),
        noise_var=nv,
        symbol_energy=energy,
        symbol_moment2=moment2,
        system=system,
        symbols=S,
        tx_index=tx,
    )

"""Ranging variances of the Gaussian ranging model: the one-path ZZB (DiPNet §V-A) or the CRB.

Two-step localization models each range as Gaussian around the true distance with the variance
of the one-path Ziv–Zakai bound at the link's *estimated* per-sample SNR (DiPNet §V-A,
following its refs. [29], [61]); the Cramér–Rao bound of DiPNet eq. (24) is the alternative.

The ZZB is a numerical integral over lags (:func:`phyloc.phy.bounds.zzb_range`; its cost is
dominated by ``1 − Re ρ(h)`` on a few thousand lags × N subcarriers, ~0.1 s per call). It is
therefore computed once per pilot power spectrum ``|S_n|²`` (and system, prior width and
valley-filling flag) on a log-spaced SNR grid and interpolated:

* ``log ZZB`` is interpolated in ``log SNR`` by a monotone cubic (PCHIP) through
  ``_PTS_PER_DECADE`` = 32 points per decade of post-correlation SNR from ``_PC_DB_LO`` = −60 dB
  to ``_PC_DB_HI`` = +90 dB (one :func:`~phyloc.phy.bounds.zzb_range` call, ~0.6 s for the
  paper's system and D = 300 m). Measured against direct single-SNR ``zzb_range`` calls the
  relative error is below 5e-4 (largest in the threshold region, pc SNR ≈ 10–13 dB; the
  tests assert 1 %); ``phyloc bench ranging`` reports it as
  ``ranging.zzb_interp_max_rel_error``.
* Above the grid the ZZB equals the CRB (their ratio is 1 within 1e-6 at +90 dB), so the value
  is extrapolated along the CRB's ``1/SNR`` law.
* Below the grid the ZZB is within 1e-3 of the prior variance ``D²/12`` (its exact value at
  SNR 0, where the error probability is Q(0) = 1/2); it is interpolated linearly in SNR between
  ``SNR = 0`` and the grid's first point. SNR 0 thus gives ``D²/12``: finite, never NaN or inf.

The CRB option returns :func:`~phyloc.phy.bounds.crb_range` capped at the prior variance
``D²/12`` (a range known to lie in an interval of width D never has a larger variance); the cap
only acts at post-correlation SNRs below about −25 dB for D = 300 m, and turns SNR 0 into
``D²/12`` instead of inf.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

K. L. Bell, Y. Steinberg, Y. Ephraim and H. L. Van Trees, "Extended Ziv–Zakai lower bound for
vector parameter estimation," IEEE Trans. Information Theory 43(2), pp. 624–637, 1997.

D. Dardari, A. Conti, U. Ferner, A. Giorgetti and M. Z. Win, "Ranging with ultrawide
bandwidth signals in multipath environments," Proc. IEEE 97(2), pp. 404–426, 2009 (DiPNet
ref. [29]).

S. M. Kay, *Fundamentals of Statistical Signal Processing, Volume I: Estimation Theory*,
Prentice Hall, 1993 (the Cramér–Rao bound, ch. 3).
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict

import numpy as np
from scipy.interpolate import PchipInterpolator

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.phy.bounds import crb_range, zzb_range
from phyloc.phy.correlation import CorrelationTable
from phyloc.phy.system import OFDMSystem
from phyloc.phy.waveform import check_symbols

#: Variance models of :func:`ranging_variance`.
KINDS = ("zzb", "crb")
#: Default width D of the uniform a-priori distance interval [m] (the estimators' default
#: search window 0 … 300 m).
DEFAULT_PRIOR_RANGE_M = 300.0

_PC_DB_LO = -60.0
_PC_DB_HI = 90.0
_PTS_PER_DECADE = 32
_CACHE_SIZE = 32
_CHUNK = 1000
_cache: OrderedDict = OrderedDict()
_lock = threading.Lock()


class _ZZBTable:
    """ZZB of one pilot power spectrum on a log-SNR grid, with its interpolant."""

    def __init__(
        self, power: np.ndarray, system: OFDMSystem, prior_range_m: float, valley_filling: bool
    ):
        energy = float(power.sum())
        n_pts = round((_PC_DB_HI - _PC_DB_LO) / 10.0 * _PTS_PER_DECADE) + 1
        pc = 10.0 ** (np.linspace(_PC_DB_LO, _PC_DB_HI, n_pts) / 10.0)
        self.snr = pc / energy  # per-sample SNR grid
        symbols = np.sqrt(power).astype(np.complex128)  # only |S_n|² enters the bound
        kw = {"prior_range_m": prior_range_m, "valley_filling": valley_filling}
        # one call: the lag integral's cost is dominated by 1 − Re ρ(h), shared by all SNRs
        parts = [
            zzb_range(self.snr[a : a + _CHUNK], symbols, system, **kw)
            for a in range(0, n_pts, _CHUNK)
        ]
        z = np.concatenate(parts)
        self.z0 = prior_range_m**2 / 12.0  # the bound at SNR 0 (Q(0) = 1/2), exactly
        self.log_snr = np.log(self.snr)
        self._interp = PchipInterpolator(self.log_snr, np.log(z), extrapolate=False)
        self.z_lo = float(z[0])
        self.z_hi = float(z[-1])

    def __call__(self, snr: np.ndarray) -> np.ndarray:
        out = np.empty(snr.shape)
        lo, hi = self.snr[0], self.snr[-1]
        below = snr < lo
        above = snr > hi
        mid = ~(below | above)
        out[mid] = np.exp(self._interp(np.log(snr[mid])))
        out[below] = self.z0 + (self.z_lo - self.z0) * (snr[below] / lo)
        out[above] = self.z_hi * (hi / snr[above])  # the CRB's 1/SNR law
        return out


def _canonical_power(power) -> tuple[str, np.ndarray]:
    """A key of a pilot power spectrum ``|S_n|²`` that ignores rounding, and the spectrum the
    key stands for: each bin to 7 digits relative to the largest, the largest to 7 significant
    digits. QPSK pilots ``e^{j(π/4 + kπ/2)}`` have ``|S_n|²`` of 1 or 1 + 4e-16 depending on the
    symbol; without this every transmitter got its own ZZB table (140 ms each: 31 tables, half
    the time of a 30-agent C2 realization), although the bounds differ in the last bits. The
    table is computed from the canonical spectrum, so it does not depend on which transmitter
    (or which task of a worker) asked first."""
    P = np.ascontiguousarray(power, dtype=np.float64)
    top = float(f"{float(P.max()):.7g}") if P.size else 0.0
    rel = np.round(P / top, 7) if top > 0 else P.copy()
    key = f"{top!r}:" + hashlib.sha1(rel.tobytes()).hexdigest()
    return key, (rel * top if top > 0 else rel)


def _zzb_table(power, system, prior_range_m, valley_filling) -> _ZZBTable:
    pkey, power = _canonical_power(power)
    key = (
        pkey,
        system,
        float(prior_range_m),
        bool(valley_filling),
    )
    with _lock:
        tab = _cache.get(key)
        if tab is not None:
            _cache.move_to_end(key)
            return tab
    tab = _ZZBTable(np.asarray(power, np.float64), system, prior_range_m, valley_filling)
    with _lock:
        _cache[key] = tab
        while len(_cache) > _CACHE_SIZE:
            _cache.popitem(last=False)
    return tab


def clear_cache() -> None:
    """Forget the tabulated ZZBs (they are rebuilt on demand)."""
    with _lock:
        _cache.clear()


def _check_snr(snr) -> np.ndarray:
    try:
        s = np.asarray(snr, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValidationError("snr", snr, "a real array of per-sample SNRs is required") from None
    if not np.all(np.isfinite(s)) or np.any(s < 0):
        raise ValidationError("snr", snr, "per-sample SNRs must be finite and >= 0 (linear)")
    return s


def ranging_variance(
    snr,
    table_or_symbols,
    system: OFDMSystem | None = None,
    *,
    kind: str = "zzb",
    prior_range_m: float = DEFAULT_PRIOR_RANGE_M,
    valley_filling: bool = True,
) -> np.ndarray:
    """Variance [m²] of the Gaussian ranging model at a per-sample SNR (DiPNet §V-A).

    Parameters
    ----------
    snr : array_like, float
        Per-sample SNR ``|α|²/σ²`` (linear, finite, >= 0): an estimate such as
        :attr:`RangeEstimates.snr`. With a table, shape ``[n_links]``.
    table_or_symbols : CorrelationTable or [N] complex
        A table (each link uses its own pilots, ``table.pilots(i)``) or one pilot row
        ``S_n`` (then ``snr`` may have any shape).
    system : OFDMSystem, optional
        Required with symbols; ignored (the table's) with a table.
    kind : {"zzb", "crb"}
        The one-path Ziv–Zakai bound (default; interpolated from a cached table, see the module
        docstring for its accuracy) or the Cramér–Rao bound of DiPNet eq. (24), capped at ``D²/12``.
    prior_range_m : float
        D [m], the width of the uniform a-priori distance interval of the ZZB (and the cap of
        the CRB). Default 300 m (the estimators' default window).
    valley_filling : bool
        ZZB with the valley-filling operator (default, the tighter bound).

    Returns
    -------
    variance : like ``snr``, float64 [m²]
        Finite and > 0 for every finite SNR; ``D²/12`` at SNR 0.

    Examples
    --------
    >>> from phyloc.phy import OFDMSystem
    >>> from phyloc.phy.waveform import qpsk_symbols
    >>> sysm = OFDMSystem()
    >>> S = qpsk_symbols(sysm, 1, np.random.default_rng(0))[0]
    >>> float(ranging_variance(0.0, S, sysm)) == 300.0**2 / 12
    True
    """
    if kind not in KINDS:
        raise ValidationError("variance", kind, f"one of {', '.join(KINDS)}")
    D = v.positive("prior_range_m", prior_range_m)
    s = _check_snr(snr)
    if isinstance(table_or_symbols, CorrelationTable):
        tab = table_or_symbols
        if s.shape != (tab.n_links,):
            raise ValidationError(
                "snr", f"shape {s.shape}", f"with a table, one SNR per link: [{tab.n_links}]"
            )
        system = tab.system
        power_rows = np.abs(tab.symbols) ** 2
        rows = tab.tx_index
    else:
        if not isinstance(system, OFDMSystem):
            raise ValidationError("system", system, "an OFDMSystem is required with symbols")
        S = check_symbols(table_or_symbols, system)
        if S.shape[0] != 1:
            raise ValidationError(
                "table_or_symbols", f"{S.shape[0]} rows", "one pilot row [N] or a table"
            )
        power_rows = np.abs(S) ** 2
        rows = np.zeros(s.shape, np.int64)
    out = np.empty(s.shape)
    # links whose pilots have the same power spectrum (to rounding, :func:`_canonical_power`)
    # share one bound (QPSK: all of them), computed from the canonical spectrum
    firsts: dict[str, int] = {}
    row_group = np.empty(power_rows.shape[0], dtype=np.int64)
    for r in range(power_rows.shape[0]):
        row_group[r] = firsts.setdefault(_canonical_power(power_rows[r])[0], len(firsts))
    first = [int(np.argmax(row_group == g)) for g in range(len(firsts))]
    group = row_group[rows]
    for g, r in enumerate(first):
        sel = group == g
        if not np.any(sel):
            continue
        P = power_rows[r]
        if kind == "zzb":
            out[sel] = _zzb_table(P, system, D, valley_filling)(s[sel])
        else:
            with np.errstate(divide="ignore"):
                crb = crb_range(s[sel], np.sqrt(P).astype(np.complex128), system)
            out[sel] = np.minimum(crb, D * D / 12.0)
    return out

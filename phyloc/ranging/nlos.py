"""NLOS identification from the waveform: the energy concentration of a link's correlation.

A LOS link's correlation power ``|f(d)|²`` is dominated by one path, the direct one: its energy
sits in one main lobe. Without the direct path (NLOS) the energy spreads over many paths of
similar strength, and the strongest peak holds a small share of it. The *energy concentration*

.. math:: κ = \\frac{\\max_k P_k / \\sum_k P_k}{ρ_1}, \\qquad
          ρ_1 = \\frac{\\|S\\|^4}{L \\sum_n |S_n|^4},

compares the share of the strongest grid sample in the window (``P_k = |f(d_k)|²``) with ``ρ_1``,
the same share for one path alone (the pilots' own autocorrelation: its peak is ``‖S‖⁴`` and, by
Parseval, its power over one period of ``L`` grid points is ``L Σ_n |S_n|⁴``). ``κ ≈ 1`` for one
dominant path, and falls towards ``1/(number of comparable paths)`` in NLOS; this is the
kurtosis / maximum-to-energy family of NLOS features of the UWB literature (Marano et al. 2010,
Güvenç et al. 2007), normalized so that it needs no training.

Only samples above the detection threshold (``noise_factor`` times the noise floor) count, so
noise alone never lowers κ: at low SNR only the strongest lobe is seen and κ stays near 1 (no
link is rejected that the detection test keeps), while at high SNR every path is seen and κ
approaches its noise-free value. The feature therefore becomes *more* reliable as the SNR rises,
which is what a two-step filter needs when every biased NLOS range is detected (its accuracy
must not fall as the power rises).

References
----------
S. Marano, W. M. Gifford, H. Wymeersch and M. Z. Win, "NLOS identification and mitigation for
localization based on UWB experimental data," IEEE J. Sel. Areas Commun. 28(7), pp. 1026–1035,
2010.

I. Güvenç, C.-C. Chong and F. Watanabe, "NLOS identification and mitigation for UWB
localization systems," Proc. IEEE WCNC, pp. 1571–1576, 2007.
"""

from __future__ import annotations

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.ranging.results import (
    DEFAULT_NOISE_FACTOR,
    DEFAULT_WINDOW_M,
    check_noise_factor,
    check_table,
    noise_floor,
    window_indices,
)


def single_path_share(table) -> np.ndarray:
    """``ρ_1 = ‖S‖⁴ / (L Σ_n |S_n|⁴)`` per link: the share of one path's correlation power in
    its strongest grid sample (module docstring), ``[n_links]``."""
    table = check_table(table)
    S2 = np.abs(table.symbols[table.tx_index]) ** 2
    return S2.sum(axis=1) ** 2 / (table.n_fft * (S2**2).sum(axis=1))


def energy_concentration(
    table, *, window_m=DEFAULT_WINDOW_M, noise_factor=DEFAULT_NOISE_FACTOR
) -> np.ndarray:
    """Energy concentration ``κ`` of each link's correlation in the search window, ``[n_links]``.

    ``κ = (max_k P_k / Σ_k P_k) / ρ_1`` over the window's grid samples with
    ``P_k >= noise_factor · σ²‖S‖²`` (module docstring); 1 for one path, smaller in dense
    multipath. Links with no sample above the threshold get ``κ = 1`` (nothing seen, nothing
    to judge: the detection test is what rejects them).

    Parameters
    ----------
    table : CorrelationTable
    window_m : (float, float)
        Search window [m], as the range estimators take it.
    noise_factor : float or None
        Threshold on ``|f|²`` in units of the noise floor (None or 0: every sample counts).

    Examples
    --------
    >>> from phyloc.phy import OFDMSystem, PathSet, C0
    >>> from phyloc.phy.waveform import qpsk_symbols
    >>> from phyloc.phy.synthesis import synthesize
    >>> from phyloc.phy.correlation import correlation_tables
    >>> sysm = OFDMSystem()
    >>> rng = np.random.default_rng(3)
    >>> S = qpsk_symbols(sysm, 1, rng)
    >>> one = PathSet.single_path([57.2 / C0], [1e-5])
    >>> two = PathSet.from_lists([[50.0 / C0, 90.0 / C0]], [[1e-5, 1e-5]])  # two equal paths
    >>> k1 = energy_concentration(correlation_tables(synthesize(one, S, sysm, rng), S, sysm))
    >>> k2 = energy_concentration(correlation_tables(synthesize(two, S, sysm, rng), S, sysm))
    >>> round(float(k1[0]), 1), round(float(k2[0]), 1)
    (1.0, 0.5)
    """
    table = check_table(table)
    kappa = check_noise_factor(noise_factor)
    _, _, k = window_indices(table, window_m)
    vals = table.values[:, k % table.n_fft]
    P = vals.real**2 + vals.imag**2
    P = np.where(P >= kappa * noise_floor(table)[:, None], P, 0.0)
    total = P.sum(axis=1)
    seen = total > 0
    share = np.divide(P.max(axis=1), total, out=np.ones_like(total), where=seen)
    return np.where(seen, share / single_path_share(table), 1.0)


def check_min_concentration(value, key="los_min_concentration") -> float:
    """A concentration threshold in [0, 1] (0: no link is rejected); ``key`` names it."""
    x = v.positive(key, value, allow_zero=True)
    if x > 1:
        raise ValidationError(key, value, "in [0, 1] (0: off; one path has 1)")
    return x

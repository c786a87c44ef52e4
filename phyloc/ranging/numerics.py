"""Peak numerics of the range estimators, public for the Numba kernels of other layers.

The range estimators refine correlation peaks on a link's correlation spectrum ``x`` (the
:attr:`~phyloc.phy.correlation.CorrelationTable.spectrum` row, subcarriers ``n_k = n0 + k``,
``w = ω/c0`` [rad/m]) with ``F(d) = Σ_k x_k e^{−j w n_k d}``, the correlation of DiPNet
eq. (23) at any distance. The ``@njit`` functions here are those steps, so that kernels
outside :mod:`phyloc.ranging` (the peak-mixture likelihood of
:mod:`phyloc.localization.direct`) refine and measure peaks exactly as the estimators do:

:func:`correlate_derivs`
    ``F``, ``F'``, ``F''`` at one distance, summed exactly over the subcarriers;
:func:`newton_peak`
    the Newton iterations on ``|F(d)|²`` from a grid maximum.

Both are inlined into their callers' compiled code; they take arrays and scalars only and do
not validate (kernel rules).

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

from numba import njit

from phyloc.ranging._kernels import _correlate_derivs, _newton_peak


@njit(cache=True, inline="always")
def correlate_derivs(x, n0, w, d):
    """``(T0, T1, T2)`` with ``T_m = Σ_k n_k^m x_k e^{−j w n_k d}`` at the distance ``d``.

    ``F(d) = T0``, ``F'(d) = −jw T1`` and ``F''(d) = −w² T2``, summed exactly (block phasors
    re-seeded from exact exponentials, ~1e-14 relative rounding for any N).

    Parameters
    ----------
    x : [N] complex128
        Correlation spectrum of one link.
    n0 : float
        Index of the first subcarrier (``n_k = n0 + k``).
    w : float
        ``ω/c0`` [rad/m].
    d : float
        Distance [m] (on the table's axis: the round trip for two-way ranging).

    Returns
    -------
    T0, T1, T2 : complex
    """
    return _correlate_derivs(x, n0, w, d)


@njit(cache=True, inline="always")
def newton_peak(x, n0, w, d0, spacing, n_iter):
    """The maximum of ``g(d) = |F(d)|²`` near ``d0`` by Newton iterations.

    ``g' = 2 Re(F* F')``, ``g'' = 2(|F'|² + Re(F* F''))`` from :func:`correlate_derivs`. A
    step is taken only where ``g'' < 0`` and is clipped to half a ``spacing``; at most
    ``n_iter`` steps, fewer once a step is below ``1e-9·spacing``. A result farther than one
    ``spacing`` from ``d0`` is discarded (``d0`` is returned).

    Parameters
    ----------
    x : [N] complex128
        Correlation spectrum of one link.
    n0 : float
        Index of the first subcarrier.
    w : float
        ``ω/c0`` [rad/m].
    d0 : float
        Start, typically the grid maximum of the table [m].
    spacing : float
        The table's grid spacing [m].
    n_iter : int
        Largest number of Newton steps.

    Returns
    -------
    float
        The refined peak distance [m].
    """
    return _newton_peak(x, n0, w, d0, spacing, n_iter)

"""Bounds and analysis: Fisher information of ranging and localization (DiPNet §III-A).

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

P. Tichavský, C. H. Muravchik and A. Nehorai, "Posterior Cramér–Rao bounds for discrete-time
nonlinear filtering," IEEE Trans. Signal Processing 46(5), pp. 1386–1396, 1998.

PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from phyloc.analysis.efim import (
    direction_vectors,
    efim,
    equivalent_noise_variance,
    equivalent_ranging_information,
    position_crb,
    projected_variance,
    ranging_information,
    spectral_moment2,
)
from phyloc.analysis.pcrlb import PCRLBResult, pcrlb, pcrlb_recursion, range_information

__all__ = [
    "PCRLBResult",
    "direction_vectors",
    "efim",
    "equivalent_noise_variance",
    "equivalent_ranging_information",
    "pcrlb",
    "pcrlb_recursion",
    "position_crb",
    "projected_variance",
    "range_information",
    "ranging_information",
    "spectral_moment2",
]

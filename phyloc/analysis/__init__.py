"""Bounds and analysis: Fisher information of ranging and localization (DiPNet §III-A)."""

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

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

__all__ = [
    "direction_vectors",
    "efim",
    "equivalent_noise_variance",
    "equivalent_ranging_information",
    "position_crb",
    "projected_variance",
    "ranging_information",
    "spectral_moment2",
]

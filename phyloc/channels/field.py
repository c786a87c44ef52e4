"""Physics of the ``field`` channel model: ground permittivity, Fresnel reflection, geometry.

The ``field`` model (scenario files with ``model = "field"``, e.g. ``channels/field_grass_5g.toml``)
describes an open grass field with metallic structures around it. Per link of distance ``d``,
antenna heights ``h_t``, ``h_r`` and carrier ``f`` (wavelength ``λ = c0/f``, ``k = 2π/λ``) it
has the paths (delays relative to ``d/c0``; amplitudes for unit antenna gains):

* **direct**: amplitude ``λ/(4π d)`` (Friis), excess delay 0;
* **ground reflection** (two-ray): path length ``L_g = sqrt(d² + (h_t + h_r)²)``, grazing angle
  ``ψ = atan((h_t + h_r)/d)``, amplitude ``|Γ(ψ)|·λ/(4π L_g)`` and phase
  ``arg Γ(ψ) − k (L_g − d)`` relative to the direct path, excess delay ``(L_g − d)/c0``;
* **specular paths of metallic structures**: ``K_s`` paths with excess delays
  ``τ ~ U[τ_min, τ_max]``, amplitude ``10^(−L_refl/20)·λ/(4π (d + c0 τ))`` (image method: free
  space over the unfolded path, times a stated reflection loss) and a uniform phase;
* **diffuse multipath**: ``N_d`` rays with excess delays ``τ ~ Exp`` of mean ``τ_DS`` (an
  exponential power-delay profile whose rms delay spread is ``τ_DS``), equal powers summing to
  ``10^(r/10)·(λ/(4π d))²`` and uniform phases.

The sampler (:func:`phyloc.channels.draw_links`) only knows link distances, not end-point
positions, so the structures are drawn per link (their delays) rather than placed in the area.
The direct path's phase is the link's uniform carrier phase; the ground reflection keeps its
deterministic phase relative to it, so ``|1 + Γ·(d/L_g)·e^{−jk(L_g − d)}|²`` fades the pair at
the distances where the two rays cancel.

Ground: complex relative permittivity ``η = ε_r − j·60·σ·λ`` (σ in S/m, λ in m; the
``e^{jωt}`` convention of the signal model, whose paths carry ``e^{−j2π f τ}``) with the
frequency laws ``ε_r = a·(f/1 GHz)^b`` and ``σ = c·(f/1 GHz)^d`` of ITU-R P.2040-1, Table 3
(ground rows, 1–10 GHz). Fresnel coefficients in grazing-angle form, with the sign convention
in which both tend to −1 at grazing incidence (the two-ray model's)::

    Γ_h = (sin ψ − sqrt(η − cos²ψ)) / (sin ψ + sqrt(η − cos²ψ))
    Γ_v = (η sin ψ − sqrt(η − cos²ψ)) / (η sin ψ + sqrt(η − cos²ψ))

References
----------
ITU-R Recommendation P.2040-1, "Effects of building materials and structures on radiowave
propagation above about 100 MHz," 2015, Sec. 3 and Table 3 (ground rows: very dry, medium dry
and wet ground, 1–10 GHz).

ITU-R Recommendation P.527-3, "Electrical characteristics of the surface of the Earth," 1992,
Fig. 1 (permittivity and conductivity of ground types against frequency).

T. S. Rappaport, "Wireless Communications: Principles and Practice," 2nd ed., Prentice Hall,
2002, Sec. 4.5 (reflection from dielectrics, Fresnel coefficients) and Sec. 4.6 (two-ray
ground reflection model).

3GPP TR 38.901, "Study on channel model for frequencies from 0.5 to 100 GHz," Sec. 7.6.8
(explicit ground reflection model: the same direct + ground-reflected pair with Fresnel
coefficients inside a stochastic channel).
"""

from __future__ import annotations

import math

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.phy.system import C0

POLARIZATIONS = ("vertical", "horizontal")


def ground_permittivity(fc_hz: float, a: float, b: float, c: float, d: float) -> complex:
    """Complex relative permittivity of the ground ``η = ε_r − j·60·σ·λ``.

    Parameters
    ----------
    fc_hz : float
        Carrier frequency [Hz], > 0.
    a, b : float
        ``ε_r = a·(f / 1 GHz)^b`` (ITU-R P.2040-1 Table 3).
    c, d : float
        ``σ = c·(f / 1 GHz)^d`` [S/m] (ITU-R P.2040-1 Table 3).

    Returns
    -------
    complex
        ``η``; its imaginary part is ``−σ/(2π f ε0)`` (``60·λ = 1/(2π f ε0)`` to 0.1 %).

    Examples
    --------
    >>> eta = ground_permittivity(5.5e9, 15.0, -0.1, 0.035, 1.63)   # medium dry ground
    >>> round(eta.real, 2), round(eta.imag, 2)
    (12.65, -1.84)
    """
    f = v.positive("fc_hz", fc_hz)
    f_ghz = f / 1e9
    eps_r = a * f_ghz**b
    sigma = c * f_ghz**d
    return complex(eps_r, -60.0 * sigma * (C0 / f))


def fresnel_reflection(eta, grazing_rad, polarization: str) -> np.ndarray:
    """Fresnel reflection coefficient of a flat ground at grazing angle ψ.

    Parameters
    ----------
    eta : complex
        Complex relative permittivity of the ground (:func:`ground_permittivity`).
    grazing_rad : array_like, float
        Grazing angle ψ [rad] (angle between the ray and the ground), in [0, π/2].
    polarization : {"vertical", "horizontal"}

    Returns
    -------
    complex128 array, the shape of ``grazing_rad``
        Γ; ``−1`` at ψ = 0 for both polarizations (module docstring).

    Examples
    --------
    >>> g = fresnel_reflection(15.0 - 2.0j, [0.0, math.pi / 2], "horizontal")
    >>> normal = (1 - np.sqrt(15 - 2j)) / (1 + np.sqrt(15 - 2j))
    >>> bool(np.isclose(g[0], -1)), bool(np.isclose(g[1], normal))
    (True, True)
    """
    if polarization not in POLARIZATIONS:
        raise ValidationError("polarization", polarization, "'vertical' or 'horizontal'")
    psi = v.finite_array("grazing_rad", grazing_rad)
    if psi.size and (psi.min() < 0 or psi.max() > math.pi / 2 + 1e-12):
        raise ValidationError("grazing_rad", float(psi.min()), "angles in [0, π/2]")
    eta = complex(eta)
    s = np.sin(psi)
    root = np.sqrt(eta - np.cos(psi) ** 2 + 0j)
    num = eta * s if polarization == "vertical" else s + 0j
    return (num - root) / (num + root)


def ground_reflection_geometry(distances_m, h_tx_m, h_rx_m):
    """Path length, excess length and grazing angle of the ground reflection (flat ground).

    Parameters
    ----------
    distances_m : array_like, float
        Horizontal link distances d [m], > 0 (phyloc's link distance).
    h_tx_m, h_rx_m : float or array_like
        Antenna heights above the ground [m], > 0.

    Returns
    -------
    length_m : float64 array
        ``L_g = sqrt(d² + (h_t + h_r)²)``.
    excess_m : float64 array
        ``L_g − d``, computed as ``(h_t + h_r)²/(L_g + d)`` (no cancellation at large d).
    grazing_rad : float64 array
        ``ψ = atan((h_t + h_r)/d)``.

    Examples
    --------
    >>> L, dl, psi = ground_reflection_geometry(4.0, 1.5, 1.5)
    >>> float(L), float(dl), round(float(np.degrees(psi)), 2)
    (5.0, 1.0, 36.87)
    """
    d = v.finite_array("distances_m", distances_m)
    ht = v.finite_array("h_tx_m", h_tx_m)
    hr = v.finite_array("h_rx_m", h_rx_m)
    if d.size and d.min() <= 0:
        raise ValidationError("distances_m", float(d.min()), "distances must be > 0 m")
    for name, h in (("h_tx_m", ht), ("h_rx_m", hr)):
        if h.size and h.min() <= 0:
            raise ValidationError(name, float(h.min()), "antenna heights must be > 0 m")
    hs = ht + hr
    length = np.hypot(d, hs)
    return length, hs * hs / (length + d), np.arctan2(hs, d)


__all__ = [
    "POLARIZATIONS",
    "fresnel_reflection",
    "ground_permittivity",
    "ground_reflection_geometry",
]

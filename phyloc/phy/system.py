"""The OFDM system and the link budget.

Signal model (:doc:`/guide/design`; DiPNet §II-B, DiPNet eq. (5)): subcarriers
``n = -(N-1)/2 … (N-1)/2`` with N odd and spacing ``f_sc``, ``ω = 2π f_sc``, bandwidth
``B = N f_sc``, time samples at ``T = 1/(os·N·f_sc)``. The thermal noise power in the band is
``σ² = k·T_K·B·NF``.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc._validate import from_table
from phyloc.errors import ValidationError

#: Speed of light in vacuum [m/s].
C0 = 299_792_458.0
#: Boltzmann constant [J/K] (exact, SI 2019).
K_BOLTZMANN = 1.380649e-23


def db_to_linear(x_db):
    """Power ratio from decibels: ``10**(x/10)``."""
    return 10.0 ** (np.asarray(x_db, dtype=np.float64) / 10.0)


def linear_to_db(x):
    """Decibels from a power ratio: ``10·log10(x)``."""
    return 10.0 * np.log10(np.asarray(x, dtype=np.float64))


def dbm_to_watt(p_dbm):
    """Power in W from dBm."""
    return 10.0 ** ((np.asarray(p_dbm, dtype=np.float64) - 30.0) / 10.0)


def watt_to_dbm(p_w):
    """Power in dBm from W."""
    return 10.0 * np.log10(np.asarray(p_w, dtype=np.float64)) + 30.0


@dataclass(frozen=True)
class OFDMSystem:
    """An OFDM ranging system (DiPNet §V-A defaults).

    Parameters
    ----------
    n_subcarriers : int
        N, odd, >= 3. Subcarrier indices run ``-(N-1)/2 … (N-1)/2``. Default 2569.
    subcarrier_spacing_hz : float
        ``f_sc`` [Hz], > 0. Default 14.65 kHz.
    carrier_frequency_hz : float
        ``f_c`` [Hz], > 0 (used by path-loss models only). Default 5.2 GHz.
    tx_power_dbm : float
        Transmit power [dBm]. Default 0 dBm (1 mW).
    temperature_k : float
        Noise temperature [K], > 0. Default 300 K.
    noise_figure_db : float
        Receiver noise figure [dB], >= 0. Default 15 dB.
    oversampling : int
        ``os >= 1``: time-domain samples per symbol are ``os·N``. Default 1.

    Examples
    --------
    >>> sysm = OFDMSystem()
    >>> round(sysm.bandwidth_hz / 1e6, 3)
    37.636
    >>> round(float(watt_to_dbm(sysm.noise_power_w)), 2)
    -83.07
    """

    n_subcarriers: int = 2569
    subcarrier_spacing_hz: float = 14.65e3
    carrier_frequency_hz: float = 5.2e9
    tx_power_dbm: float = 0.0
    temperature_k: float = 300.0
    noise_figure_db: float = 15.0
    oversampling: int = 1

    def __post_init__(self):
        n = v.integer("system.n_subcarriers", self.n_subcarriers, minimum=3)
        if n % 2 == 0:
            raise ValidationError(
                "system.n_subcarriers", self.n_subcarriers, "must be odd (e.g. 2569), >= 3"
            )
        object.__setattr__(self, "n_subcarriers", n)
        object.__setattr__(
            self,
            "subcarrier_spacing_hz",
            v.positive("system.subcarrier_spacing_hz", self.subcarrier_spacing_hz),
        )
        object.__setattr__(
            self,
            "carrier_frequency_hz",
            v.positive("system.carrier_frequency_hz", self.carrier_frequency_hz),
        )
        object.__setattr__(self, "tx_power_dbm", v.finite("system.tx_power_dbm", self.tx_power_dbm))
        object.__setattr__(
            self, "temperature_k", v.positive("system.temperature_k", self.temperature_k)
        )
        object.__setattr__(
            self,
            "noise_figure_db",
            v.positive("system.noise_figure_db", self.noise_figure_db, allow_zero=True),
        )
        object.__setattr__(
            self, "oversampling", v.integer("system.oversampling", self.oversampling, minimum=1)
        )

    # -- derived quantities -------------------------------------------------------------------
    @property
    def bandwidth_hz(self) -> float:
        """``B = N·f_sc`` [Hz]."""
        return self.n_subcarriers * self.subcarrier_spacing_hz

    @property
    def omega(self) -> float:
        """``ω = 2π f_sc`` [rad/s]."""
        return 2.0 * math.pi * self.subcarrier_spacing_hz

    @property
    def n_samples(self) -> int:
        """Time-domain samples per symbol, ``os·N``."""
        return self.oversampling * self.n_subcarriers

    @property
    def sample_period_s(self) -> float:
        """``T = 1/(os·N·f_sc)`` [s]."""
        return 1.0 / (self.n_samples * self.subcarrier_spacing_hz)

    @property
    def symbol_duration_s(self) -> float:
        """``1/f_sc`` [s]: the period of s(t), hence the delay ambiguity."""
        return 1.0 / self.subcarrier_spacing_hz

    @property
    def unambiguous_range_m(self) -> float:
        """``c0/f_sc`` [m]: distances are known modulo this length."""
        return C0 / self.subcarrier_spacing_hz

    @property
    def noise_power_w(self) -> float:
        """In-band thermal noise ``σ² = k·T·B·NF`` [W]."""
        return (
            K_BOLTZMANN
            * self.temperature_k
            * self.bandwidth_hz
            * float(db_to_linear(self.noise_figure_db))
        )

    @property
    def tx_power_w(self) -> float:
        """Transmit power [W]."""
        return float(dbm_to_watt(self.tx_power_dbm))

    def subcarrier_indices(self) -> np.ndarray:
        """Subcarrier indices ``n = -(N-1)/2 … (N-1)/2`` as float64, shape ``(N,)``."""
        h = (self.n_subcarriers - 1) // 2
        return np.arange(-h, h + 1, dtype=np.float64)

    def received_power_w(self, path_loss_db):
        """Received power [W] for a path loss [dB]: ``P_tx[dBm] − PL`` (link budget).

        Parameters
        ----------
        path_loss_db : array_like, float
            Path loss including shadowing [dB]; any shape; finite.
        """
        pl = v.finite_array("path_loss_db", path_loss_db)
        return dbm_to_watt(self.tx_power_dbm - pl)

    def replace(self, **changes) -> OFDMSystem:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    @classmethod
    def from_dict(cls, d: dict, *, section: str = "system") -> OFDMSystem:
        """Build from a recipe section; unknown keys are errors naming the closest valid key."""
        return from_table(cls, d, section)

    def to_dict(self) -> dict:
        """The init fields as a plain dict (recipe form)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


def free_space_path_loss_db(distance_m, carrier_frequency_hz):
    """Free-space path loss ``20·log10(4π d f_c / c0)`` [dB] (d > 0 [m], f_c [Hz])."""
    d = v.finite_array("distance_m", distance_m)
    if np.any(d <= 0):
        raise ValidationError("distance_m", float(d.min()), "distances must be > 0")
    fc = v.positive("carrier_frequency_hz", carrier_frequency_hz)
    return 20.0 * np.log10(4.0 * math.pi * d * fc / C0)

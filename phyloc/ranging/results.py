"""The result of a range estimator (:class:`RangeEstimates`) and the helpers the estimators share:
search windows, detection thresholds, SNR estimates and the ranging variance.

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

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.phy.correlation import CorrelationTable
from phyloc.phy.system import C0
from phyloc.ranging import _kernels
from phyloc.ranging.variance import KINDS, ranging_variance

#: Default detection threshold κ on ``|f(d)|²/(σ²‖S‖²)`` (12 dB above the noise floor); see
#: :func:`~phyloc.ranging.estimators.first_peak`.
DEFAULT_NOISE_FACTOR = 16.0
#: Default search window [m].
DEFAULT_WINDOW_M = (0.0, 300.0)


@dataclass(frozen=True, eq=False)
class RangeEstimates:
    """Range estimates of a batch of links (one estimator, one correlation table).

    Attributes
    ----------
    method : str
        Estimator name (``"corr"``, ``"first_peak"``, ``"sage"``, ``"sage_los"``).
    range_m : [n_links], float64
        Distance estimate [m]. Always finite: for an invalid link it is a placeholder (the
        strongest peak, or strongest path, in the search window) that carries no claim.
    snr : [n_links], float64
        Per-sample SNR estimate ``|α̂|²/σ² − 1/‖S‖²`` of the ranged path, clipped at 0
        (bias-corrected: ``E|α̂|² = |α|² + σ²/‖S‖²``).
    variance_m2 : [n_links], float64
        Variance of the Gaussian ranging model at ``snr`` [m²] (one-path ZZB, DiPNet §V-A, or
        CRB; :func:`~phyloc.ranging.variance.ranging_variance`). Finite and > 0.
    valid : [n_links], bool
        False where the estimator found nothing above its detection threshold, or (oracle
        methods) where the link was rejected. Consumers must drop invalid links.
    oracle : bool
        True when ground truth was used (NLOS-rejected SAGE): never a realizable estimator, a
        benchmark only, and to be labelled so wherever it is shown.
    path_distance_m : [n_links·P], float64, optional
        SAGE only: the distances ``c0·τ_l`` of all estimated paths, per link sorted ascending;
        link i's paths are ``path_offsets[i]:path_offsets[i+1]``.
    path_amplitude : [n_links·P], complex128, optional
        SAGE only: the complex amplitudes ``α_l`` [√W] of those paths.
    path_offsets : [n_links + 1], int64, optional
        SAGE only: offsets of each link's paths in the flat arrays.
    """

    method: str
    range_m: np.ndarray
    snr: np.ndarray
    variance_m2: np.ndarray
    valid: np.ndarray
    oracle: bool = False
    path_distance_m: np.ndarray | None = None
    path_amplitude: np.ndarray | None = None
    path_offsets: np.ndarray | None = None

    def __post_init__(self):
        r = v.finite_array("range_m", self.range_m, ndim=1)
        n = r.size
        for name in ("snr", "variance_m2"):
            a = v.finite_array(name, getattr(self, name), ndim=1)
            if a.size != n:
                raise ValidationError(name, f"{a.size} entries", f"one per link ({n})")
            object.__setattr__(self, name, a)
        valid = np.asarray(self.valid, dtype=bool)
        if valid.shape != (n,):
            raise ValidationError("valid", f"shape {valid.shape}", f"[n_links] = [{n}]")
        object.__setattr__(self, "range_m", r)
        object.__setattr__(self, "valid", valid)
        object.__setattr__(self, "oracle", bool(self.oracle))

    @property
    def n_links(self) -> int:
        """Number of links."""
        return self.range_m.size

    @property
    def label(self) -> str:
        """The method name, marked ``(oracle)`` for oracle methods: use it in tables and plots."""
        return f"{self.method} (oracle)" if self.oracle else self.method

    def paths(self, link: int) -> tuple[np.ndarray, np.ndarray]:
        """``(distances [m], amplitudes)`` of one link's estimated paths (SAGE only)."""
        if self.path_offsets is None:
            raise ValidationError("paths", self.method, "only SAGE estimates carry paths")
        a, b = self.path_offsets[link], self.path_offsets[link + 1]
        return self.path_distance_m[a:b], self.path_amplitude[a:b]


# -- helpers shared by the estimators ---------------------------------------------------------
def check_table(table) -> CorrelationTable:
    """The table itself, or a :class:`ValidationError` naming what is expected."""
    if not isinstance(table, CorrelationTable):
        raise ValidationError(
            "table",
            type(table).__name__,
            "a CorrelationTable (phyloc.phy.correlation.correlation_tables) is required",
        )
    return table


def window_indices(table: CorrelationTable, window_m) -> tuple[float, float, np.ndarray]:
    """``(lo, hi, k)``: the window [m] and the grid indices ``k`` with ``lo <= k·h <= hi``
    (not reduced modulo L)."""
    try:
        lo, hi = window_m
    except (TypeError, ValueError):
        raise ValidationError("window_m", window_m, "a pair (lo, hi) of distances [m]") from None
    lo = v.finite("window_m[0]", lo)
    hi = v.finite("window_m[1]", hi)
    if not lo < hi:
        raise ValidationError("window_m", window_m, "must be (lo, hi) with lo < hi")
    if hi - lo >= table.period_m:
        raise ValidationError(
            "window_m",
            window_m,
            f"must be shorter than the unambiguous range c0/f_sc = {table.period_m:.1f} m",
        )
    h = table.spacing_m
    k = np.arange(math.ceil(lo / h), math.floor(hi / h) + 1)
    if k.size < 3:
        raise ValidationError("window_m", window_m, f"must span >= 3 grid points ({h:.3f} m)")
    return lo, hi, k


def noise_floor(table: CorrelationTable) -> np.ndarray:
    """``σ²‖S‖²``: the mean of ``|f(d)|²`` for noise only, ``[n_links]``."""
    return table.noise_var * table.symbol_energy


def check_noise_factor(noise_factor) -> float:
    """κ >= 0 (``None`` means 0: no noise threshold)."""
    if noise_factor is None:
        return 0.0
    return v.positive("noise_factor", noise_factor, allow_zero=True)


def exact_at(table: CorrelationTable, d: np.ndarray, spectrum=None) -> np.ndarray:
    """Exact ``F_i(d_i) = Σ_n c_{i,n} e^{−jωnd_i/c0}`` per link (``spectrum`` defaults to the
    table's)."""
    spec = np.ascontiguousarray(table.spectrum if spectrum is None else spectrum)
    system = table.system
    out = np.empty(d.size, dtype=np.complex128)
    _kernels.correlate_kernel(
        spec,
        float(system.subcarrier_indices()[0]),
        system.omega / C0,
        np.ascontiguousarray(d, dtype=np.float64),
        out,
    )
    return out


def refine(table: CorrelationTable, d0: np.ndarray, spacing: float, spectrum=None, n_iter=8):
    """Newton refinement of ``|F|²`` maxima from ``d0`` (steps clipped to ``spacing``/2, a
    result farther than ``spacing`` from ``d0`` discarded: the PHY core's refinement)."""
    spec = np.ascontiguousarray(table.spectrum if spectrum is None else spectrum)
    system = table.system
    out = np.empty(d0.size)
    _kernels.refine_kernel(
        spec,
        float(system.subcarrier_indices()[0]),
        system.omega / C0,
        np.ascontiguousarray(d0, dtype=np.float64),
        float(spacing),
        int(n_iter),
        out,
    )
    return out


def snr_from_amplitude(table: CorrelationTable, amplitude: np.ndarray) -> np.ndarray:
    """Bias-corrected per-sample SNR ``max(|α̂|²/σ² − 1/‖S‖², 0)``."""
    raw = (amplitude.real**2 + amplitude.imag**2) / table.noise_var - 1.0 / table.symbol_energy
    return np.maximum(raw, 0.0)


def check_variance(kind) -> str:
    """The variance model name, or an error listing the valid ones."""
    if kind not in KINDS:
        raise ValidationError("variance", kind, f"one of {', '.join(KINDS)}")
    return kind


def variance_for(table, snr, kind, prior_range_m, lo, hi) -> np.ndarray:
    """Ranging variance at the estimated SNRs; the ZZB prior defaults to the window width."""
    D = (hi - lo) if prior_range_m is None else v.positive("prior_range_m", prior_range_m)
    return ranging_variance(snr, table, kind=kind, prior_range_m=D)

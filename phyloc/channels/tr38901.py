"""The ``tr38901`` channel model: the system-level scenarios of 3GPP TR 38.901 in the delay domain.

Scenario files with ``model = "tr38901"`` (``channels/tr38901_*.toml``) hold one scenario of
TR 38.901 Sec. 7.4–7.5 (UMi street canyon, UMa, RMa, InH office, InF): its LOS probability
(Table 7.4.2-1), its path-loss laws and shadow fading (Table 7.4.1-1), and the large-scale and
cluster parameters of Table 7.5-6 that matter for a single-antenna link in the delay domain.
Per link of (3D) length ``d`` between antennas at heights ``h_BS = max(h_tx, h_rx)`` and
``h_UT = min(h_tx, h_rx)`` (the recipe's ``[channel] h_tx_m`` / ``h_rx_m``), carrier ``f_c``
(the system's; ``fc`` below in GHz):

* **Geometry.** phyloc's link distance is the length of the direct path, ``d_3D = d`` (the LOS
  path arrives at ``d/c0``); ``d_2D = sqrt(max(d² − (h_BS − h_UT)², 0))``.
* **LOS probability** (Table 7.4.2-1) of ``d_2D`` (:class:`Tr38901LosProbability`).
* **Path loss** (Table 7.4.1-1; :class:`Tr38901PathLoss`): ``PL = A + B·log10(d_3D) +
  C·log10(fc)`` terms, the dual slope of UMi/UMa with the breakpoint
  ``d'_BP = 4 h'_BS h'_UT f_c / c`` (``h' = h − h_E``, ``c = 3·10⁸ m/s``, ``f_c`` in Hz), the
  RMa laws with their own breakpoint ``d_BP = 2π h_BS h_UT f_c / c``, and in NLOS
  ``PL = max(PL_LOS, PL'_NLOS)``. Shadow fading ``SF ~ N(0, σ_SF²)`` with the law's σ_SF.
* **Large-scale parameters** (Sec. 7.5 step 4, Table 7.5-6): one standard-normal vector per link
  with the cross-correlation of ``[SF, K, DS]`` (LOS) or ``[SF, DS]`` (NLOS), the sub-matrix of
  Table 7.5-6's correlation matrix, imposed with its Cholesky factor;
  ``DS = 10^(μ_lgDS + σ_lgDS·x_DS)`` s with ``μ``, ``σ`` of ``fc`` (clamped below at the table's
  ``fc_min_ghz``), ``K = μ_K + σ_K·x_K`` dB. The angle spreads (ASD, ASA, ZSD, ZSA) and XPR are
  not drawn.
* **Cluster delays** (step 5): ``τ'_n = −r_τ·DS·ln X_n``, ``X_n ~ U(0, 1]`` (equation 7.5-1),
  ``τ_n = sort(τ'_n − min τ')`` (equation 7.5-2); in LOS divided by
  ``C_τ = 0.7705 − 0.0433K + 0.0002K² + 0.000017K³`` (equations 7.5-3, 7.5-4; :func:`c_tau`) with
  the link's K; the powers use the unscaled delays.
* **Cluster powers** (step 6): ``P'_n = exp(−τ_n (r_τ − 1)/(r_τ DS))·10^(−Z_n/10)``,
  ``Z_n ~ N(0, ζ²)`` (equation 7.5-5), ``P_n = P'_n / Σ P'`` (equation 7.5-6). Clusters more than
  ``removal_threshold_db`` (25 dB) below the strongest are removed, and the remaining powers
  are normalized to sum to 1 again. In LOS the clusters carry ``P_n/(K_R + 1)`` and the direct
  path ``K_R/(K_R + 1)``, ``K_R = 10^(K/10)`` (equations 7.5-7, 7.5-8).
* **Sub-clusters** (step 11, Table 7.5-5): each of the two strongest clusters becomes three
  paths at ``τ_n + {0, 1.28, 2.56}·c_DS`` with ``10/20, 6/20, 4/20`` of its power; ``c_DS`` is
  the intra-cluster delay spread of Table 7.5-6 (a constant, the UMa law
  ``max(0.25, 6.5622 − 3.4084·log10(fc))`` ns, or, where the table says N/A, 3.91 ns).
* **LOS direct path** at excess delay 0 (the first cluster's delay).

Every (sub-)cluster is one path with its power and a uniform phase: the 20 rays of a cluster
differ in angle only (and in the two strongest clusters, in their sub-cluster delay), which a
single-antenna link does not resolve. Not modelled: angles and everything built on them
(antenna arrays and patterns, angular spreads, the ray angles of steps 7–8, coupling of
rays, XPR and polarization, Doppler), spatial consistency (LSPs and clusters are drawn
independently per link, no decorrelation distances), O2I penetration loss, blockage, the
absolute time of arrival of Sec. 7.6.9 and the oxygen absorption of Sec. 7.6.1.

References
----------
3GPP TR 38.901, "Study on channel model for frequencies from 0.5 to 100 GHz," Sec. 7.4.1
(Table 7.4.1-1, path loss), Sec. 7.4.2 (Table 7.4.2-1, LOS probability), Sec. 7.5 steps 4–6 and
11 (equations 7.5-1 to 7.5-8, Table 7.5-5) and Table 7.5-6 (large-scale and cluster
parameters); the tables as in V16.1 (also V17 and V18). How the values were read:
``channels/PROVENANCE.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from phyloc.channels import _schema as s
from phyloc.channels.pathloss import D_FAR_FIELD_M, free_space_db
from phyloc.errors import ValidationError

#: Coefficients of C_τ(K) (TR 38.901 equation 7.5-3), K in dB.
C_TAU_COEFFS = (0.7705, -0.0433, 0.0002, 0.000017)
#: K-factor [dB] below which C_τ(K) is evaluated at this value (C_τ > 0 above about −61 dB).
C_TAU_K_MIN_DB = -60.0
#: Intra-cluster delay spread [ns] where Table 7.5-6 gives N/A (TR 38.901 Sec. 7.5 step 11).
C_DS_NOT_AVAILABLE_NS = 3.91
#: Speed of light in the breakpoint distances (TR 38.901 Table 7.4.1-1, note 1) [m/s].
C_BREAKPOINT_M_S = 3.0e8
#: Default heights of :meth:`Tr38901LosProbability.__call__` [m] (phyloc's device default).
DEFAULT_HEIGHT_M = 1.5

_COEF = s.Num(-1000.0, 1000.0)
_SF = s.Num(0.0, 30.0)
_CORR = s.Num(-1.0, 1.0, default=0.0)
_DIST = s.Num(0.0, 1.0e6, lo_open=True)

# ---------------------------------------------------------------------------------------------
# LOS probability (TR 38.901 Table 7.4.2-1)
LOS_LAWS: dict[str, dict] = {
    # UMi street canyon: 1 for d <= d_near, else d_near/d + exp(-d/d_decay)(1 - d_near/d)
    "umi": {"d_near_m": _DIST, "d_decay_m": _DIST},
    # UMa: the UMi form times (1 + C'(h_UT) 5/4 (d/100 m)^3 exp(-d/150 m)),
    # C'(h_UT) = 0 for h_UT <= 13 m, ((h_UT - 13 m)/10 m)^1.5 above
    "uma": {"d_near_m": _DIST, "d_decay_m": _DIST},
    # RMa: 1 for d <= d_unity, else exp(-(d - d_unity)/d_decay)
    "rma": {"d_unity_m": s.Num(0.0, 1.0e5), "d_decay_m": _DIST},
    # InH office: 1 for d <= d_unity; exp(-(d - d_unity)/d_decay1) up to d_knee;
    # far_scale exp(-(d - d_knee)/d_decay2) beyond
    "inh": {
        "d_unity_m": s.Num(0.0, 1.0e5),
        "d_decay1_m": _DIST,
        "d_knee_m": s.Num(0.0, 1.0e5),
        "d_decay2_m": _DIST,
        "far_scale": s.Num(0.0, 1.0),
    },
    # InF: exp(-d/k), k = -d_clutter/ln(1 - r) (SL, DL), times (h_BS - h_UT)/(h_c - h_UT) (SH, DH)
    "inf": {
        "subscenario": s.Choice(("SL", "DL", "SH", "DH")),
        "clutter_density": s.Num(0.0, 1.0, lo_open=True, hi_open=True),
        "clutter_size_m": _DIST,
        "clutter_height_m": _DIST,
    },
    # InF-HH and other LOS-only cases
    "constant": {"value": s.Num(0.0, 1.0)},
}


def ground_distance(d3d_m, h_bs_m, h_ut_m) -> np.ndarray:
    """2D distance ``sqrt(max(d_3D² − (h_BS − h_UT)², 0))`` of links of (3D) length ``d3d_m``."""
    d = np.asarray(d3d_m, dtype=np.float64)
    dh = np.asarray(h_bs_m, dtype=np.float64) - np.asarray(h_ut_m, dtype=np.float64)
    return np.sqrt(np.maximum(d * d - dh * dh, 0.0))


def los_probability(law: str, coeffs: dict, d2d_m, h_bs_m, h_ut_m) -> np.ndarray:
    """P_LOS of TR 38.901 Table 7.4.2-1 at 2D distances ``d2d_m`` [m].

    Parameters
    ----------
    law : str
        One of :data:`LOS_LAWS`.
    coeffs : dict
        The law's keys (distances in m).
    d2d_m : array_like
        2D distances [m], >= 0.
    h_bs_m, h_ut_m : float or array_like
        Antenna heights [m] (UMa: ``h_UT``; InF-SH/DH: both).

    Returns
    -------
    float64 array in [0, 1], the shape of ``d2d_m``.

    Examples
    --------
    >>> float(los_probability("umi", {"d_near_m": 18.0, "d_decay_m": 36.0}, 36.0, 10, 1.5)[()])
    0.6839397205857212
    """
    d = np.asarray(d2d_m, dtype=np.float64)
    c = coeffs
    h_bs = np.broadcast_to(np.asarray(h_bs_m, dtype=np.float64), d.shape)
    h_ut = np.broadcast_to(np.asarray(h_ut_m, dtype=np.float64), d.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        if law in ("umi", "uma"):
            dn, dd = c["d_near_m"], c["d_decay_m"]
            safe = np.maximum(d, dn)
            p = dn / safe + np.exp(-safe / dd) * (1.0 - dn / safe)
            if law == "uma":
                c_ut = np.where(h_ut <= 13.0, 0.0, ((h_ut - 13.0) / 10.0) ** 1.5)
                p = p * (1.0 + c_ut * 1.25 * (safe / 100.0) ** 3 * np.exp(-safe / 150.0))
            p = np.where(d <= dn, 1.0, p)
        elif law == "rma":
            p = np.where(d <= c["d_unity_m"], 1.0, np.exp(-(d - c["d_unity_m"]) / c["d_decay_m"]))
        elif law == "inh":
            near = np.exp(-(d - c["d_unity_m"]) / c["d_decay1_m"])
            far = c["far_scale"] * np.exp(-(d - c["d_knee_m"]) / c["d_decay2_m"])
            p = np.where(d <= c["d_unity_m"], 1.0, np.where(d <= c["d_knee_m"], near, far))
        elif law == "inf":
            k = -c["clutter_size_m"] / math.log(1.0 - c["clutter_density"])
            if c["subscenario"] in ("SH", "DH"):
                k = k * (h_bs - h_ut) / (c["clutter_height_m"] - h_ut)
            k = np.broadcast_to(k, d.shape)
            p = np.where(k > 0, np.exp(-d / np.where(k > 0, k, 1.0)), 0.0)
        elif law == "constant":
            p = np.full(d.shape, c["value"])
        else:  # pragma: no cover - guarded by from_table
            raise ValidationError("los_probability.law", law, ", ".join(LOS_LAWS))
    return np.clip(p, 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class Tr38901LosProbability:
    """P_LOS(d) of a TR 38.901 scenario (Table 7.4.2-1), a function of ``d_2D`` and the heights.

    Parameters
    ----------
    law : str
        One of :data:`LOS_LAWS`.
    coeffs : dict
        The law's validated keys.
    """

    law: str
    coeffs: dict

    @classmethod
    def from_table(cls, table, where: str) -> Tr38901LosProbability:
        """Validate the ``[los_probability]`` table of a ``tr38901`` file."""
        if not isinstance(table, dict):
            raise ValidationError(where, table, "must be a table")
        law = table.get("law", s.MISSING)
        if law not in LOS_LAWS:
            raise ValidationError(f"{where}.law", law, "one of " + ", ".join(map(repr, LOS_LAWS)))
        vals = s.parse(table, {"law": s.Choice(tuple(LOS_LAWS)), **LOS_LAWS[law]}, where)
        vals.pop("law")
        if law == "inh" and vals["d_knee_m"] < vals["d_unity_m"]:
            raise ValidationError(
                f"{where}.d_knee_m", vals["d_knee_m"], f"must be >= d_unity_m = {vals['d_unity_m']}"
            )
        return cls(law, vals)

    def check_heights(self, h_bs_m, h_ut_m, names=("h_tx_m", "h_rx_m")) -> None:
        """InF-SH/DH: the lower antenna must be below the clutter height (else an error)."""
        if self.law == "inf" and self.coeffs["subscenario"] in ("SH", "DH"):
            hc = self.coeffs["clutter_height_m"]
            top = float(np.max(h_ut_m))
            if top >= hc:
                raise ValidationError(
                    f"{names[0]} / {names[1]}",
                    top,
                    f"the InF-{self.coeffs['subscenario']} LOS probability (TR 38.901 Table "
                    f"7.4.2-1) needs the lower antenna below the clutter height h_c = {hc:g} m",
                )

    def __call__(self, d3d_m, h_bs_m=DEFAULT_HEIGHT_M, h_ut_m=DEFAULT_HEIGHT_M) -> np.ndarray:
        """P_LOS of links of (3D) length ``d3d_m`` [m] between antennas at these heights."""
        h_bs = np.asarray(h_bs_m, dtype=np.float64)
        h_ut = np.asarray(h_ut_m, dtype=np.float64)
        self.check_heights(h_bs, h_ut)
        d2 = ground_distance(d3d_m, h_bs, h_ut)
        return los_probability(self.law, self.coeffs, d2, h_bs, h_ut)

    def same_as(self, other) -> bool:
        """True if both laws are identical."""
        return (
            isinstance(other, Tr38901LosProbability)
            and self.law == other.law
            and self.coeffs == other.coeffs
        )


# ---------------------------------------------------------------------------------------------
# Path loss (TR 38.901 Table 7.4.1-1)
@dataclass(frozen=True)
class _Terms:
    """A list of log-distance terms (inline tables), e.g. the NLOS laws of InF-DL."""

    keys: dict
    default: object = s.REQUIRED

    def describe(self) -> str:
        return "a non-empty list of tables with keys " + ", ".join(self.keys)

    def check(self, field: str, value):
        if not isinstance(value, list) or not value:
            raise ValidationError(field, value, self.describe())
        return tuple(s.parse(t, self.keys, f"{field}[{i}]") for i, t in enumerate(value))


_TERM = {
    "intercept_db": _COEF,
    "log10_d3d": _COEF,
    "log10_fc_ghz": _COEF,
    "h_ut_slope_db_per_m": s.Num(-100.0, 100.0, default=0.0),  # × (h_UT − 1.5 m)
}
_BP_TERM = {
    "intercept_db": _COEF,
    "log10_d3d": _COEF,
    "log10_fc_ghz": _COEF,
    "log10_bp": _COEF,  # × log10(d'_BP² + (h_BS − h_UT)²)
}
_RANGE = {
    "d_min_m": _DIST,
    "d_max_m": _DIST,
    "free_space_floor": s.Flag(default=True),
}
PATHLOSS_LAWS: dict[str, dict] = {
    # UMi / UMa LOS: PL1 for d_2D < d'_BP, PL2 beyond
    "dual_slope": {
        **_RANGE,
        "sf_std_db": _SF,
        "environment_height_m": s.Num(0.0, 100.0),
        "environment_height_random": s.Flag(default=False),
        "pl1": _TERM,
        "pl2": _BP_TERM,
    },
    # InH / InF LOS: one term
    "single_slope": {**_RANGE, "sf_std_db": _SF, "pl": _TERM},
    # NLOS: max(PL_LOS, PL'_1, PL'_2, ...) with the [los.pathloss] law of the same file
    "max_with_los": {**_RANGE, "sf_std_db": _SF, "terms": _Terms(_TERM)},
    # RMa LOS: own formula (h: average building height), sigma_SF per segment
    "rma_los": {
        **_RANGE,
        "sf_std_db": _SF,
        "sf_std_db_beyond_breakpoint": _SF,
        "avg_building_height_m": s.Num(5.0, 50.0),
    },
    # RMa NLOS: max(PL_RMa-LOS, PL'_RMa-NLOS) (W: average street width)
    "rma_nlos": {
        **_RANGE,
        "sf_std_db": _SF,
        "avg_building_height_m": s.Num(5.0, 50.0),
        "street_width_m": s.Num(5.0, 50.0),
    },
}


def _term(t: dict, d3, lf, h_ut):
    return (
        t["intercept_db"]
        + t["log10_d3d"] * np.log10(d3)
        + t["log10_fc_ghz"] * lf
        + t["h_ut_slope_db_per_m"] * (h_ut - 1.5)
    )


def breakpoint_distance(fc_hz: float, h_bs_m, h_ut_m, h_e_m) -> np.ndarray:
    """``d'_BP = 4 (h_BS − h_E)(h_UT − h_E) f_c / c`` [m] (TR 38.901 Table 7.4.1-1, note 1).

    Examples
    --------
    >>> float(breakpoint_distance(3.0e9, 10.0, 1.5, 1.0))
    180.0
    """
    hb = np.asarray(h_bs_m, dtype=np.float64) - h_e_m
    hu = np.asarray(h_ut_m, dtype=np.float64) - h_e_m
    return 4.0 * hb * hu * fc_hz / C_BREAKPOINT_M_S


def rma_los_db(d2d, d3d, fc_hz: float, h_bs, h_ut, h_avg: float):
    """RMa LOS path loss [dB] and a flag "beyond the breakpoint" (TR 38.901 Table 7.4.1-1).

    ``PL1 = 20 log10(40π d_3D fc/3) + min(0.03 h^1.72, 10) log10(d_3D) − min(0.044 h^1.72,
    14.77) + 0.002 log10(h) d_3D`` (fc in GHz), ``PL2 = PL1(d_BP) + 40 log10(d_3D/d_BP)``,
    ``d_BP = 2π h_BS h_UT f_c/c`` with the actual heights.
    """
    fc = fc_hz / 1e9
    d_bp = 2.0 * math.pi * np.asarray(h_bs) * np.asarray(h_ut) * fc_hz / C_BREAKPOINT_M_S

    def pl1(x):
        return (
            20.0 * np.log10(40.0 * math.pi * x * fc / 3.0)
            + min(0.03 * h_avg**1.72, 10.0) * np.log10(x)
            - min(0.044 * h_avg**1.72, 14.77)
            + 0.002 * math.log10(h_avg) * x
        )

    beyond = d2d >= d_bp
    pl = np.where(beyond, pl1(d_bp) + 40.0 * np.log10(d3d / d_bp), pl1(d3d))
    return pl, beyond


def rma_nlos_prime_db(d3d, fc_hz: float, h_bs, h_ut, h_avg: float, w: float):
    """``PL'_RMa-NLOS`` [dB] of TR 38.901 Table 7.4.1-1 (fc in GHz, heights and W in m)."""
    h_bs = np.asarray(h_bs, dtype=np.float64)
    h_ut = np.asarray(h_ut, dtype=np.float64)
    return (
        161.04
        - 7.1 * math.log10(w)
        + 7.5 * math.log10(h_avg)
        - (24.37 - 3.7 * (h_avg / h_bs) ** 2) * np.log10(h_bs)
        + (43.42 - 3.1 * np.log10(h_bs)) * (np.log10(d3d) - 3.0)
        + 20.0 * math.log10(fc_hz / 1e9)
        - (3.2 * np.log10(11.75 * h_ut) ** 2 - 4.97)
    )


@dataclass(frozen=True, eq=False)
class Tr38901PathLoss:
    """A path-loss law of TR 38.901 Table 7.4.1-1 with its shadow-fading std.

    Parameters
    ----------
    law : str
        One of :data:`PATHLOSS_LAWS`.
    coeffs : dict
        The law's validated keys.
    los_law : Tr38901PathLoss or None
        NLOS laws (``max_with_los``): the LOS law of the same file, ``PL_LOS`` in
        ``max(PL_LOS, PL'_NLOS)``. ``rma_nlos`` uses the RMa LOS formula with its own keys.
    """

    law: str
    coeffs: dict
    los_law: Tr38901PathLoss | None = None

    @property
    def d_min_m(self) -> float:
        """Lower end of the law's distance range [m] (2D distance)."""
        return self.coeffs["d_min_m"]

    @property
    def uses_environment_height(self) -> bool:
        """True if the law has a breakpoint ``d'_BP`` with ``h_E`` (itself or its LOS law)."""
        law = self if self.law == "dual_slope" else self.los_law
        return law is not None and law.law == "dual_slope"

    def environment_heights(self, d2d, h_ut, rng, h_e_m=None) -> np.ndarray:
        """``h_E`` per link [m] for the breakpoint ``d'_BP`` (TR 38.901 Table 7.4.1-1, note 1).

        ``h_e_m`` (the recipe's ``[channel] h_e_m``) overrides the file. Otherwise the file's
        ``environment_height_m``, or with ``environment_height_random`` the UMa rule: ``h_E =
        1 m`` with probability ``1/(1 + C(d_2D, h_UT))``, else uniform on ``{12, 15, …,
        h_UT − 1.5}`` m, ``C = 0`` for ``h_UT < 13 m``, else ``((h_UT − 13)/10)^1.5·g(d_2D)``,
        ``g = 0`` for ``d_2D <= 18 m``, else ``(5/4)(d_2D/100)³ exp(−d_2D/150)``. The UMa rule
        draws two uniforms per link (always, so the stream does not depend on the heights);
        for ``13 m < h_UT < 13.5 m`` the set is empty and 12 m is used.
        """
        n = np.size(d2d)
        law = self if self.law == "dual_slope" else self.los_law
        if law is None or law.law != "dual_slope":
            return np.zeros(n)
        if h_e_m is not None:
            return np.full(n, float(h_e_m))
        c = law.coeffs
        if not c["environment_height_random"]:
            return np.full(n, c["environment_height_m"])
        u1, u2 = rng.random(n), rng.random(n)
        d2 = np.asarray(d2d, dtype=np.float64)
        h_ut = np.broadcast_to(np.asarray(h_ut, dtype=np.float64), d2.shape)
        g = np.where(d2 <= 18.0, 0.0, 1.25 * (d2 / 100.0) ** 3 * np.exp(-d2 / 150.0))
        cc = np.where(h_ut < 13.0, 0.0, np.maximum(h_ut - 13.0, 0.0) ** 1.5 / 10.0**1.5 * g)
        n_set = np.maximum(np.floor((h_ut - 1.5 - 12.0) / 3.0), 0.0) + 1.0
        pick = 12.0 + 3.0 * np.minimum(np.floor(u2 * n_set), n_set - 1.0)
        return np.where(u1 < 1.0 / (1.0 + cc), c["environment_height_m"], pick)

    def check_heights(self, h_bs_m, h_ut_m, h_e_m, names=("h_tx_m", "h_rx_m")) -> None:
        """Raise :class:`ValidationError` if ``h − h_E <= 0`` in the breakpoint of a dual-slope
        law (also inside an NLOS law that uses it)."""
        law = self if self.law == "dual_slope" else self.los_law
        if law is None or law.law != "dual_slope":
            return
        low = float(np.min(np.asarray(h_ut_m) - np.asarray(h_e_m)))
        if low <= 0:
            raise ValidationError(
                f"{names[0]} / {names[1]}",
                float(np.min(h_ut_m)),
                "the lower antenna must be above the environment height h_E "
                f"(h_UT − h_E = {low:g} m; TR 38.901 Table 7.4.1-1, d'_BP with h' = h − h_E)",
            )

    def _law(self, d2, d3, fc_hz: float, h_bs, h_ut, h_e):
        """The bare formula: ``(PL [dB], σ_SF [dB])``."""
        c = self.coeffs
        lf = math.log10(fc_hz / 1e9)
        if self.law == "dual_slope":
            d_bp = breakpoint_distance(fc_hz, h_bs, h_ut, h_e)
            p1, p2 = c["pl1"], c["pl2"]
            pl1 = p1["intercept_db"] + p1["log10_d3d"] * np.log10(d3) + p1["log10_fc_ghz"] * lf
            pl1 = pl1 + p1["h_ut_slope_db_per_m"] * (h_ut - 1.5)
            pl2 = (
                p2["intercept_db"]
                + p2["log10_d3d"] * np.log10(d3)
                + p2["log10_fc_ghz"] * lf
                + p2["log10_bp"] * np.log10(d_bp * d_bp + (h_bs - h_ut) ** 2)
            )
            pl = np.where(d2 < d_bp, pl1, pl2)
            sf = np.full(pl.shape, c["sf_std_db"])
        elif self.law == "single_slope":
            pl = _term(c["pl"], d3, lf, h_ut)
            sf = np.full(pl.shape, c["sf_std_db"])
        elif self.law == "max_with_los":
            pl, _ = self.los_law._law(d2, d3, fc_hz, h_bs, h_ut, h_e)
            for t in c["terms"]:
                pl = np.maximum(pl, _term(t, d3, lf, h_ut))
            sf = np.full(pl.shape, c["sf_std_db"])
        elif self.law == "rma_los":
            pl, beyond = rma_los_db(d2, d3, fc_hz, h_bs, h_ut, c["avg_building_height_m"])
            sf = np.where(beyond, c["sf_std_db_beyond_breakpoint"], c["sf_std_db"])
        elif self.law == "rma_nlos":
            h = c["avg_building_height_m"]
            pl_los, _ = rma_los_db(d2, d3, fc_hz, h_bs, h_ut, h)
            pl_nlos = rma_nlos_prime_db(d3, fc_hz, h_bs, h_ut, h, c["street_width_m"])
            pl = np.maximum(pl_los, pl_nlos)
            sf = np.full(pl.shape, c["sf_std_db"])
        else:  # pragma: no cover - guarded by the parser
            raise ValidationError("pathloss.law", self.law, ", ".join(PATHLOSS_LAWS))
        return pl, sf

    def evaluate(self, d3d_m, fc_hz: float, h_bs_m, h_ut_m, h_e_m=None):
        """Path loss and shadow-fading std per link.

        Parameters
        ----------
        d3d_m : [n] float64
            Link lengths (3D distances) [m], > 0. Distances below 1 m are evaluated at 1 m.
        fc_hz : float
            Carrier frequency [Hz].
        h_bs_m, h_ut_m : float or [n] float64
            Higher and lower antenna heights [m].
        h_e_m : float or [n] float64, optional
            Environment height of the breakpoint (dual-slope laws); default the file's.

        Returns
        -------
        path_loss_db, sf_std_db : [n] float64
            The law as tabulated for ``d_2D >= d_min_m``; below, the law extrapolated, and with
            ``free_space_floor`` at least ``min(FSPL(d_3D), PL(d_min))`` (as the phyloc laws of
            :mod:`phyloc.channels.pathloss`).
        """
        d = np.asarray(d3d_m, dtype=np.float64)
        h_bs = np.broadcast_to(np.asarray(h_bs_m, dtype=np.float64), d.shape)
        h_ut = np.broadcast_to(np.asarray(h_ut_m, dtype=np.float64), d.shape)
        if h_e_m is None:
            law = self if self.law == "dual_slope" else self.los_law
            h_e_m = law.coeffs["environment_height_m"] if law and law.law == "dual_slope" else 0.0
        h_e = np.broadcast_to(np.asarray(h_e_m, dtype=np.float64), d.shape)
        d2 = ground_distance(d, h_bs, h_ut)
        d3 = np.maximum(d, D_FAR_FIELD_M)
        pl, sf = self._law(d2, d3, fc_hz, h_bs, h_ut, h_e)
        below = d2 < self.d_min_m
        if self.coeffs["free_space_floor"] and np.any(below):
            d2m = np.full(d.shape, self.d_min_m)
            d3m = np.hypot(d2m, h_bs - h_ut)
            at_min, _ = self._law(d2m, d3m, fc_hz, h_bs, h_ut, h_e)
            floor = np.minimum(free_space_db(d3, fc_hz), at_min)
            pl = np.where(below, np.maximum(pl, floor), pl)
        return np.ascontiguousarray(pl, np.float64), np.ascontiguousarray(sf, np.float64)


def _parse_pathloss(table, where: str, los_law: Tr38901PathLoss | None) -> Tr38901PathLoss:
    if not isinstance(table, dict):
        raise ValidationError(where, table, "must be a table")
    law = table.get("law", s.MISSING)
    if law not in PATHLOSS_LAWS:
        raise ValidationError(f"{where}.law", law, "one of " + ", ".join(map(repr, PATHLOSS_LAWS)))
    vals = s.parse(table, {"law": s.Choice(tuple(PATHLOSS_LAWS)), **PATHLOSS_LAWS[law]}, where)
    vals.pop("law")
    if vals["d_max_m"] <= vals["d_min_m"]:
        raise ValidationError(
            f"{where}.d_max_m", vals["d_max_m"], f"must exceed d_min_m = {vals['d_min_m']:g}"
        )
    if law == "max_with_los":
        if los_law is None:
            raise ValidationError(
                f"{where}.law",
                law,
                "needs the [los.pathloss] law of the same file (PL = max(PL_LOS, PL'_NLOS))",
            )
        return Tr38901PathLoss(law, vals, los_law)
    return Tr38901PathLoss(law, vals)


# ---------------------------------------------------------------------------------------------
# Large-scale parameters and clusters (TR 38.901 Table 7.5-6)
_LOG_LAW = {
    "a": _COEF,
    "b": s.Num(0.0, 1000.0, default=0.0),
    "c": _COEF,
    "fc_coeff": s.Num(0.0, 10.0, default=1.0),
    "vs_coeff": s.Num(0.0, 1000.0, default=0.0),
}


@dataclass(frozen=True)
class _IntraClusterDs:
    """``intra_cluster_ds_ns``: a number, "N/A" (3.91 ns) or the UMa law table."""

    default: object = s.REQUIRED

    def describe(self) -> str:
        return (
            'a number of ns in [0, 100], "N/A" (then 3.91 ns, TR 38.901 Sec. 7.5 step 11) or '
            "{ floor_ns, intercept_ns, log10_fc_ns } for max(floor, intercept + log10_fc·log10(fc))"
        )

    def check(self, field: str, value):
        if value == "N/A":
            return {"floor_ns": C_DS_NOT_AVAILABLE_NS, "intercept_ns": 0.0, "log10_fc_ns": 0.0}
        if isinstance(value, dict):
            spec = {"floor_ns": s.Num(0.0, 100.0), "intercept_ns": _COEF, "log10_fc_ns": _COEF}
            return s.parse(value, spec, field)
        x = s.Num(0.0, 100.0).check(field, value) if not isinstance(value, str) else None
        if x is None:
            raise ValidationError(field, value, self.describe())
        return {"floor_ns": x, "intercept_ns": 0.0, "log10_fc_ns": 0.0}


def _lsp_spec(condition: str) -> dict:
    spec = {
        "fc_min_ghz": s.Num(0.0, 100.0, default=0.0),
        "ds_log10_s_mu": _LOG_LAW,
        "ds_log10_s_sigma": _LOG_LAW,
        "hall_size_m": s.Vec(s.Num(0.0, 1.0e4, lo_open=True), n=3, default=None),
        "cross_correlation": {"ds_sf": _CORR},
    }
    if condition == "los":
        spec["k_factor_db_mu"] = s.Num(-30.0, 40.0)
        spec["k_factor_db_sigma"] = s.Num(0.0, 20.0)
        spec["cross_correlation"] = {"ds_sf": _CORR, "ds_k": _CORR, "sf_k": _CORR}
    return spec


_CLUSTERS = {
    "num_clusters": s.Num(1, 100, integer=True),
    "r_tau": s.Num(1.0, 20.0),
    "cluster_shadowing_std_db": s.Num(0.0, 30.0),
    "intra_cluster_ds_ns": _IntraClusterDs(),
    "removal_threshold_db": s.Num(0.0, 1000.0, default=25.0),
}
_SUBCLUSTERS = {
    "num_split": s.Num(0, 100, integer=True),
    "delay_offsets_c_ds": s.Vec(s.Num(0.0, 100.0)),
    "power_fractions": s.Vec(s.Num(0.0, 1.0, lo_open=True)),
}


def log_law(p: dict, fc_ghz: float, vs_m: float = 0.0) -> float:
    """``a·log10(b + fc_coeff·fc + vs_coeff·V/S) + c`` (``c`` alone when ``a = 0``): the form of
    the DS entries of TR 38.901 Table 7.5-6 (fc in GHz; InF: ``V/S`` of the hall in m).

    Examples
    --------
    >>> round(log_law({"a": -0.24, "b": 1.0, "c": -7.14, "fc_coeff": 1.0, "vs_coeff": 0.0}, 3.0), 6)
    -7.284494
    """
    if p["a"] == 0.0:
        return float(p["c"])
    x = p["b"] + p["fc_coeff"] * fc_ghz + p["vs_coeff"] * vs_m
    return float(p["a"] * math.log10(x) + p["c"])


def hall_volume_surface_m(size_m) -> float:
    """``V/S`` [m] of a hall of length, width, height ``size_m`` (TR 38.901 Table 7.5-6 Part-3:
    ``V`` the volume, ``S`` the total surface of walls, floor and ceiling).

    Examples
    --------
    >>> hall_volume_surface_m([120.0, 60.0, 10.0])
    4.0
    """
    a, b, h = (float(x) for x in size_m)
    return a * b * h / (2.0 * (a * b + a * h + b * h))


def c_tau(k_db) -> np.ndarray:
    """LOS delay scaling ``C_τ = 0.7705 − 0.0433K + 0.0002K² + 0.000017K³`` (TR 38.901
    equation 7.5-3; K in dB, evaluated at ``max(K, −60 dB)`` where ``C_τ`` stays > 0).

    Examples
    --------
    >>> c_tau(np.array([0.0, 9.0])).round(4).tolist()
    [0.7705, 0.4094]
    """
    k = np.maximum(np.asarray(k_db, dtype=np.float64), C_TAU_K_MIN_DB)
    c0, c1, c2, c3 = C_TAU_COEFFS
    return c0 + k * (c1 + k * (c2 + k * c3))


@dataclass(frozen=True, eq=False)
class Tr38901Condition:
    """Parameters of one condition (LOS or NLOS) of a TR 38.901 scenario.

    Attributes
    ----------
    condition : {"los", "nlos"}
    pathloss : Tr38901PathLoss
        Path-loss law and σ_SF (Table 7.4.1-1).
    los_probability : Tr38901LosProbability
        The scenario's P_LOS (Table 7.4.2-1), for the height checks.
    fc_min_ghz : float
        LSP tables: ``fc`` below this is evaluated at it (Table 7.5-6 notes).
    ds_mu, ds_sigma : dict
        ``lgDS = log10(DS/1 s)``: mean and std as :func:`log_law` coefficients.
    hall_vs_m : float
        ``V/S`` of the InF hall [m] (0 when not given).
    k_db_mu, k_db_sigma : float
        K-factor mean and std [dB] (NaN in NLOS).
    correlation, cholesky : ndarray
        Correlation of ``[SF, K, DS]`` (LOS) or ``[SF, DS]`` (NLOS) and its lower Cholesky factor.
    num_clusters : int
    r_tau : float
    cluster_shadowing_std_db : float
        ζ [dB].
    c_ds : dict
        Intra-cluster delay spread law (:meth:`c_ds_s`).
    removal_threshold_db : float
        Clusters this far below the strongest are removed (25 dB).
    num_split : int
        Strongest clusters split into sub-clusters (2).
    subcluster_offsets_c_ds, subcluster_fractions : tuple of float
        Sub-cluster delays in units of ``c_DS`` and their power fractions (Table 7.5-5).
    nlos_bias_mean_s : float
        Mean of the Exp NLOS bias on every path [s] (NLOS only; 0 in LOS).
    """

    condition: str
    pathloss: Tr38901PathLoss
    los_probability: Tr38901LosProbability
    fc_min_ghz: float
    ds_mu: dict
    ds_sigma: dict
    hall_vs_m: float
    k_db_mu: float
    k_db_sigma: float
    correlation: np.ndarray
    cholesky: np.ndarray
    num_clusters: int
    r_tau: float
    cluster_shadowing_std_db: float
    c_ds: dict
    removal_threshold_db: float
    num_split: int
    subcluster_offsets_c_ds: tuple
    subcluster_fractions: tuple
    nlos_bias_mean_s: float = 0.0

    def lsp_fc_ghz(self, fc_hz: float) -> float:
        """The frequency [GHz] the LSP tables are evaluated at: ``max(fc, fc_min_ghz)``."""
        return max(fc_hz / 1e9, self.fc_min_ghz)

    def ds_log10_params(self, fc_hz: float) -> tuple[float, float]:
        """``(μ_lgDS, σ_lgDS)`` at carrier ``fc_hz`` (Table 7.5-6)."""
        f = self.lsp_fc_ghz(fc_hz)
        return log_law(self.ds_mu, f, self.hall_vs_m), log_law(self.ds_sigma, f, self.hall_vs_m)

    def c_ds_s(self, fc_hz: float) -> float:
        """Intra-cluster delay spread ``c_DS`` [s] at ``fc_hz``: ``max(floor, intercept +
        log10_fc·log10(fc))`` ns (UMa: ``max(0.25, 6.5622 − 3.4084·log10(fc))``; a constant
        is its floor; N/A: 3.91 ns)."""
        c = self.c_ds
        f = self.lsp_fc_ghz(fc_hz)
        law = c["intercept_ns"] + c["log10_fc_ns"] * math.log10(f)
        return max(c["floor_ns"], law) * 1e-9

    @property
    def max_paths_per_link(self) -> int:
        """Paths of a link without cluster removal: clusters, sub-clusters, direct path."""
        extra = min(self.num_split, self.num_clusters) * (len(self.subcluster_offsets_c_ds) - 1)
        return self.num_clusters + extra + (self.condition == "los")


def _correlation(condition: str, cc: dict, where: str):
    """[SF, K, DS] (LOS) or [SF, DS] (NLOS) correlation and its Cholesky factor."""
    names = ("sf", "k", "ds") if condition == "los" else ("sf", "ds")
    return s.correlation_cholesky(cc, names, where)


def _parse_condition(
    condition: str, table, where: str, pl: Tr38901PathLoss, plos: Tr38901LosProbability
) -> Tr38901Condition:
    spec = {
        "pathloss": s.Raw(),
        "lsp": _lsp_spec(condition),
        "clusters": _CLUSTERS,
        "subclusters": _SUBCLUSTERS,
    }
    if condition == "nlos":
        spec["nlos_bias_mean_s"] = s.Num(0.0, 1.0e-4)
    vals = s.parse(table, spec, where)
    lsp, cl, sub = vals["lsp"], vals["clusters"], vals["subclusters"]
    uses_vs = lsp["ds_log10_s_mu"]["vs_coeff"] or lsp["ds_log10_s_sigma"]["vs_coeff"]
    if uses_vs and lsp["hall_size_m"] is None:
        raise ValidationError(
            f"{where}.lsp.hall_size_m",
            s.MISSING,
            "the DS law uses V/S of the hall (vs_coeff != 0): give [length, width, height] in m",
        )
    vs = hall_volume_surface_m(lsp["hall_size_m"]) if lsp["hall_size_m"] else 0.0
    corr, chol = _correlation(condition, lsp["cross_correlation"], where)
    offs, fracs = sub["delay_offsets_c_ds"], sub["power_fractions"]
    if len(offs) != len(fracs):
        raise ValidationError(
            f"{where}.subclusters.power_fractions",
            list(fracs),
            f"one fraction per delay offset ({len(offs)} offsets)",
        )
    if abs(sum(fracs) - 1.0) > 1e-9:
        raise ValidationError(
            f"{where}.subclusters.power_fractions", list(fracs), "fractions must sum to 1"
        )
    if offs[0] != 0.0:
        raise ValidationError(
            f"{where}.subclusters.delay_offsets_c_ds",
            list(offs),
            "the first sub-cluster stays at the cluster delay (offset 0, Table 7.5-5)",
        )
    if sub["num_split"] > cl["num_clusters"]:
        raise ValidationError(
            f"{where}.subclusters.num_split",
            sub["num_split"],
            f"an integer in [0, num_clusters = {cl['num_clusters']}]",
        )
    return Tr38901Condition(
        condition=condition,
        pathloss=pl,
        los_probability=plos,
        fc_min_ghz=lsp["fc_min_ghz"],
        ds_mu=lsp["ds_log10_s_mu"],
        ds_sigma=lsp["ds_log10_s_sigma"],
        hall_vs_m=vs,
        k_db_mu=lsp.get("k_factor_db_mu", math.nan),
        k_db_sigma=lsp.get("k_factor_db_sigma", math.nan),
        correlation=corr,
        cholesky=chol,
        num_clusters=cl["num_clusters"],
        r_tau=cl["r_tau"],
        cluster_shadowing_std_db=cl["cluster_shadowing_std_db"],
        c_ds=cl["intra_cluster_ds_ns"],
        removal_threshold_db=cl["removal_threshold_db"],
        num_split=sub["num_split"],
        subcluster_offsets_c_ds=offs,
        subcluster_fractions=fracs,
        nlos_bias_mean_s=vals.get("nlos_bias_mean_s", 0.0),
    )


def parse_tr38901(los_probability_table, los_table, nlos_table, label: str):
    """Validate the LOS probability and the ``[los]`` / ``[nlos]`` tables of a ``tr38901`` file.

    The NLOS path loss ``max_with_los`` refers to the ``[los.pathloss]`` law, so both conditions
    are parsed together.

    Returns
    -------
    (Tr38901LosProbability, dict)
        The LOS-probability law and ``{"los": Tr38901Condition, "nlos": ...}`` for the tables
        present.
    """
    plos = Tr38901LosProbability.from_table(los_probability_table, f"{label}: los_probability")
    conds = {}
    los_pl = None
    for cond, table in (("los", los_table), ("nlos", nlos_table)):
        if table is None:
            continue
        where = f"{label}: {cond}"
        if not isinstance(table, dict):
            raise ValidationError(where, table, "must be a table")
        if "pathloss" not in table:
            raise ValidationError(f"{where}.pathloss", s.MISSING, "required key; a table")
        pl = _parse_pathloss(table["pathloss"], f"{where}.pathloss", los_pl)
        if cond == "los":
            los_pl = pl
        conds[cond] = _parse_condition(cond, table, where, pl, plos)
    return plos, conds


# ---------------------------------------------------------------------------------------------
def draw_tr38901(
    p: Tr38901Condition,
    d3d_m: np.ndarray,
    fc_hz: float,
    h_bs_m: np.ndarray,
    h_ut_m: np.ndarray,
    rng: np.random.Generator,
    *,
    h_e_m=None,
) -> dict:
    """Draw ``n = d3d_m.size`` links of one condition (TR 38.901 Sec. 7.5 steps 4–6 and 11).

    Random streams in this order: the UMa environment heights (only with
    ``environment_height_random`` and no ``h_e_m``), the LSP normals ``[n, 3]`` (LOS) or
    ``[n, 2]`` (NLOS), the cluster-delay uniforms ``[n, N]``, the cluster-shadowing normals
    ``[n, N]``.

    Returns
    -------
    dict
        The keys of the sampler's drawers (``sf_db``, ``ds_s``, ``k_db``, ``counts``,
        ``delays``, ``fractions``) and ``pl_db``, ``sf_std_db`` (Table 7.4.1-1) per link.
        Each link's fractions sum to 1; its paths are sorted by delay, the direct path first.
    """
    n = d3d_m.size
    is_los = p.condition == "los"
    d2 = ground_distance(d3d_m, h_bs_m, h_ut_m)
    h_e = p.pathloss.environment_heights(d2, h_ut_m, rng, h_e_m)
    p.pathloss.check_heights(h_bs_m, h_ut_m, h_e)
    pl, sf_std = p.pathloss.evaluate(d3d_m, fc_hz, h_bs_m, h_ut_m, h_e)

    # step 4: [SF, K, DS] (LOS) or [SF, DS] (NLOS) with the Table 7.5-6 cross-correlation
    x = rng.standard_normal((n, p.cholesky.shape[0])) @ p.cholesky.T
    mu, sigma = p.ds_log10_params(fc_hz)
    # Table 7.5-6 correlates SF as a gain (the received power is P_tx − PL + SF: Sec. 7.5
    # step 12 scales the channel by sqrt(10^(SF/10))); phyloc's draw holds the loss added to
    # the path loss, so the drawn gain enters with its sign flipped
    sf = -sf_std * x[:, 0]
    ds = 10.0 ** (mu + sigma * x[:, -1])
    k_db = p.k_db_mu + p.k_db_sigma * x[:, 1] if is_los else np.full(n, math.nan)

    # step 5: cluster delays (equations 7.5-1, 7.5-2)
    nc = p.num_clusters
    u = 1.0 - rng.random((n, nc))  # (0, 1]
    tau = -p.r_tau * ds[:, None] * np.log(u)
    tau.sort(axis=1)
    tau -= tau[:, :1]
    # step 6: cluster powers (equations 7.5-5, 7.5-6), removal of weak clusters
    z = p.cluster_shadowing_std_db * rng.standard_normal((n, nc))
    slope = (p.r_tau - 1.0) / (p.r_tau * ds)
    pw = np.exp(-tau * slope[:, None] - z * (math.log(10.0) / 10.0))
    pw /= pw.sum(axis=1, keepdims=True)
    keep = pw >= pw.max(axis=1, keepdims=True) * 10.0 ** (-p.removal_threshold_db / 10.0)
    pw = np.where(keep, pw, 0.0)
    pw /= pw.sum(axis=1, keepdims=True)
    if is_los:
        kr = 10.0 ** (k_db / 10.0)
        tau = tau / c_tau(k_db)[:, None]  # equation 7.5-4 (powers above used the unscaled delays)
        pw = pw / (kr + 1.0)[:, None]  # equation 7.5-8

    # step 11: sub-clusters of the strongest clusters (Table 7.5-5)
    cols_t, cols_p, cols_ok = [tau], [pw], [keep]
    ns = min(p.num_split, nc)
    if ns and len(p.subcluster_offsets_c_ds) > 1:
        c_ds = p.c_ds_s(fc_hz)
        offs = np.asarray(p.subcluster_offsets_c_ds[1:]) * c_ds
        fr = np.asarray(p.subcluster_fractions)
        top = np.argsort(-pw, axis=1, kind="stable")[:, :ns]
        rows = np.arange(n)[:, None]
        ok = keep[rows, top]
        ps, ts = pw[rows, top], tau[rows, top]
        pw[rows, top] = np.where(ok, ps * fr[0], ps)
        cols_t.append((ts[:, :, None] + offs).reshape(n, -1))
        cols_p.append((ps[:, :, None] * fr[1:]).reshape(n, -1))
        cols_ok.append(np.repeat(ok, offs.size, axis=1))
    if is_los:  # the direct path, first among equal delays
        cols_t.insert(0, np.zeros((n, 1)))
        cols_p.insert(0, (kr / (kr + 1.0))[:, None])
        cols_ok.insert(0, np.ones((n, 1), dtype=bool))
    tau_all = np.hstack(cols_t)
    pw_all = np.hstack(cols_p)
    ok_all = np.hstack(cols_ok)
    tau_all = np.where(ok_all, tau_all, np.inf)
    order = np.argsort(tau_all, axis=1, kind="stable")
    tau_all = np.take_along_axis(tau_all, order, axis=1)
    pw_all = np.take_along_axis(pw_all, order, axis=1)
    ok_all = np.take_along_axis(ok_all, order, axis=1)
    return {
        "pl_db": pl,
        "sf_std_db": sf_std,
        "sf_db": sf,
        "ds_s": ds,
        "k_db": k_db,
        "counts": ok_all.sum(axis=1).astype(np.int64),
        "delays": tau_all[ok_all],
        "fractions": pw_all[ok_all],
    }


__all__ = [
    "C_DS_NOT_AVAILABLE_NS",
    "C_TAU_COEFFS",
    "LOS_LAWS",
    "PATHLOSS_LAWS",
    "Tr38901Condition",
    "Tr38901LosProbability",
    "Tr38901PathLoss",
    "breakpoint_distance",
    "c_tau",
    "draw_tr38901",
    "ground_distance",
    "hall_volume_surface_m",
    "log_law",
    "los_probability",
    "parse_tr38901",
    "rma_los_db",
    "rma_nlos_prime_db",
]

"""Path-loss laws and LOS-probability laws of the channel scenarios.

All formulas take distances in m and the carrier frequency in Hz and return dB; the coefficient
names follow WINNER II D1.1.2 Part I, Table 4-4 (path loss) and Table 4-7 (LOS probability);
which table each value comes from is in ``channels/PROVENANCE.md``. Frequencies enter as
``log10(f_c / f_ref)`` with ``f_ref = 5 GHz`` (D1.1.2 writes ``log10(f_c[GHz]/5.0)``).

**Device-to-device adaptation** (applies to every law, see also ``channels/README.md``):

* **Antenna heights.** WINNER II formulas have a base-station height ``h_BS`` and a mobile
  height ``h_MS``. phyloc links are between devices with heights ``h_tx_m`` and ``h_rx_m``
  (default 1.5 m both); it uses ``h_BS = max(h_tx, h_rx)`` and ``h_MS = min(h_tx, h_rx)`` so that
  path loss is reciprocal.
* **Below the minimum distance** of a law (e.g. 10 m LOS / 50 m NLOS in C2 and D1) the formula is
  *extrapolated* (``below_min_distance = "extrapolate"``, the shipped choice) rather than clamped:
  a log-distance law keeps its slope toward short range, whereas clamping would give a 5 m
  NLOS link the loss of a 50 m one (C2: ~45 dB too much) and a flat loss over most of a 100 m
  network. ``"clamp"`` evaluates the law at ``max(d, d_min)`` instead. In both modes distances
  below 1 m are evaluated at 1 m (far-field reference distance) — delays always use the true
  distance.
* **Free-space floor** (``free_space_floor = true``, shipped) in the extrapolated region only:
  for ``d < d_min``, ``PL(d) = max(PL_law(d), min(FSPL(d), PL_law(d_min)))``. The extrapolated
  NLOS laws would otherwise predict more power than free space at a few metres (C2 NLOS below
  2.9 m); the cap at ``PL_law(d_min)`` keeps the loss continuous at ``d_min`` and
  non-increasing toward shorter links. Inside ``[d_min, d_max]`` the WINNER II law is used as
  is, even where it is below free space (A1 LOS beyond 2 m, B1/C2/D1 LOS near 10 m: the
  measured laws include ground reflection and wave-guiding).
* **Above the maximum distance** the law is extrapolated (irrelevant for networks of < 1 km).
* **Shadow-fading std** is the one of the law's segment (dual slope: ``seg1`` before and ``seg2``
  beyond the breakpoint), as in WINNER II D1.1.2 Table 4-4; the σ_SF of WINNER II D1.1.2
  Table 4-5 equals the ``seg1`` value in every scenario.

References
----------
WINNER II: IST-4-027756 WINNER II Deliverable D1.1.2 V1.2, Part I (channel models), 2007,
updated 2008; the table each value of the shipped channel files comes from is given in
``channels/PROVENANCE.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from phyloc.channels import _schema as s
from phyloc.errors import ValidationError
from phyloc.phy.system import C0

#: Distances below this are evaluated at it in every law [m] (far-field reference distance).
D_FAR_FIELD_M = 1.0

_COEF = s.Num(-1000.0, 1000.0)  # dimensionless dB coefficients of a law
_SF = s.Num(0.0, 30.0)  # shadow-fading std [dB]

_DUAL_SLOPE_LAW = {
    "seg1": {"A": s.Num(0.0, 100.0), "B": _COEF, "C": _COEF},
    "seg2": {
        "A": s.Num(0.0, 100.0),
        "B": _COEF,
        "C": _COEF,
        "D_log10_hbs": _COEF,
        "E_log10_hms": _COEF,
    },
    "breakpoint_height_offset_m": s.Num(0.0, 10.0),
    "breakpoint_speed_of_light_m_s": s.Num(1.0e8, 4.0e8, default=3.0e8),
}


def _with_sf(law: dict) -> dict:
    out = dict(law)
    out["seg1"] = {**law["seg1"], "sf_std_db": _SF}
    out["seg2"] = {**law["seg2"], "sf_std_db": _SF}
    return out


#: Coefficient keys of each path-loss model (besides the common keys below).
PATHLOSS_MODELS: dict[str, dict] = {
    # PL = 20 log10(4π d f_c / c0) + excess_db
    "free_space": {"excess_db": s.Num(-50.0, 200.0, default=0.0), "sf_std_db": _SF},
    # PL = A log10 d + B + C log10(f_c/f_ref)            (A1 LOS)
    "single_slope": {"A": s.Num(0.0, 100.0), "B": _COEF, "C": _COEF, "sf_std_db": _SF},
    # dual slope with breakpoint d_bp = 4 h_BS' h_MS' f_c / c    (B1, C2, D1 LOS)
    "dual_slope_los": _with_sf(_DUAL_SLOPE_LAW),
    # PL = (A + Ah log10 h_BS) log10 d + B + D log10 h_BS + C log10(f_c/f_ref)   (C2 NLOS)
    "hata_like_nlos": {
        "A": s.Num(0.0, 100.0),
        "Ah_log10_hbs": _COEF,
        "B": _COEF,
        "D_log10_hbs": _COEF,
        "C": _COEF,
        "sf_std_db": _SF,
    },
    # PL = A log10 d + B + hbs_coeff (h_BS − hbs_ref) log10(d/d_ref)
    #      + hms_coeff (h_MS − hms_ref) + C log10(f_c/f_ref)                    (D1 NLOS)
    "rural_nlos": {
        "A": s.Num(0.0, 100.0),
        "B": _COEF,
        "C": _COEF,
        "hbs_coeff": _COEF,
        "hbs_ref_m": s.Num(0.0, 1000.0),
        "d_ref_m": s.Num(0.0, 1.0e5, lo_open=True),
        "hms_coeff": _COEF,
        "hms_ref_m": s.Num(0.0, 1000.0),
        "sf_std_db": _SF,
    },
    # PL = A log10 d + B + C log10(f_c/f_ref) + X_w · max(n_w − walls_excluded, 0),
    # n_w = max(floor(d / wall_spacing_m), 1)                                   (A1 NLOS)
    "indoor_walls": {
        "A": s.Num(0.0, 100.0),
        "B": _COEF,
        "C": _COEF,
        "wall_loss_db": s.Num(0.0, 100.0),
        "wall_spacing_m": s.Num(0.0, 1000.0, lo_open=True),
        "walls_excluded": s.Num(0.0, 10.0, integer=True),
        "sf_std_db": _SF,
    },
    # PL = PL_LOS(d1) + offset_db + nj_coeff n_j + d2_slope_factor n_j log10 d2
    #      + C log10(f_c/f_ref),
    # n_j = max(nj_a + nj_b_per_m d1, nj_min), d1 = d2 = d/√2                  (B1 NLOS)
    "manhattan_nlos": {
        "los_law": _DUAL_SLOPE_LAW,
        "offset_db": _COEF,
        "nj_coeff": _COEF,
        "nj_a": _COEF,
        "nj_b_per_m": _COEF,
        "nj_min": _COEF,
        "d2_slope_factor": _COEF,
        "C": _COEF,
        "sf_std_db": _SF,
    },
}

#: Keys every ``[<condition>.pathloss]`` table may carry besides its model's coefficients.
PATHLOSS_COMMON = {
    "model": s.Choice(tuple(PATHLOSS_MODELS)),
    "d_min_m": s.Num(0.0, 1.0e5, lo_open=True),
    "d_max_m": s.Num(0.0, 1.0e6, lo_open=True),
    "fc_ref_hz": s.Num(0.0, 1.0e12, lo_open=True, default=5.0e9),
    "below_min_distance": s.Choice(("extrapolate", "clamp"), default="extrapolate"),
    "free_space_floor": s.Flag(default=True),
}


def free_space_db(d, fc_hz):
    """Free-space loss ``20·log10(4π d f_c / c0)`` [dB] (no input checks)."""
    return 20.0 * np.log10(4.0 * math.pi * d * fc_hz / C0)


@dataclass(frozen=True, eq=False)
class PathLoss:
    """A path-loss law with its shadow-fading std (WINNER II D1.1.2 Table 4-4).

    Parameters
    ----------
    model : str
        One of :data:`PATHLOSS_MODELS`.
    coeffs : dict
        The model's validated coefficients (nested dicts for segments).
    d_min_m, d_max_m : float
        Distance range of the law [m] (documentation and ``below_min_distance = "clamp"``).
    fc_ref_hz : float
        Reference frequency of the ``C·log10(f_c/f_ref)`` term [Hz].
    below_min_distance : {"extrapolate", "clamp"}
        What happens below ``d_min_m`` (module docstring).
    free_space_floor : bool
        Below ``d_min_m``, never return less than ``min(FSPL(d), PL_law(d_min))``.
    """

    model: str
    coeffs: dict
    d_min_m: float
    d_max_m: float
    fc_ref_hz: float = 5.0e9
    below_min_distance: str = "extrapolate"
    free_space_floor: bool = True

    @classmethod
    def from_table(cls, table: dict, where: str) -> PathLoss:
        """Validate a ``[<condition>.pathloss]`` table (``where`` names it in errors)."""
        if not isinstance(table, dict):
            raise ValidationError(where, table, "must be a table")
        model = table.get("model", s.MISSING)
        if model not in PATHLOSS_MODELS:
            raise ValidationError(f"{where}.model", model, PATHLOSS_COMMON["model"].describe())
        vals = s.parse(table, {**PATHLOSS_COMMON, **PATHLOSS_MODELS[model]}, where)
        if vals["d_max_m"] <= vals["d_min_m"]:
            raise ValidationError(
                f"{where}.d_max_m", vals["d_max_m"], f"must exceed d_min_m = {vals['d_min_m']:g}"
            )
        common = {k: vals.pop(k) for k in PATHLOSS_COMMON}
        return cls(coeffs=vals, **common)

    # ------------------------------------------------------------------------------------------
    def evaluate(self, distances_m, fc_hz: float, h_bs_m, h_ms_m):
        """Path loss and shadow-fading std per link.

        Parameters
        ----------
        distances_m : [n_links], float64
            Link distances [m], > 0.
        fc_hz : float
            Carrier frequency [Hz].
        h_bs_m, h_ms_m : float or [n_links], float64
            Higher and lower antenna height [m].

        Returns
        -------
        path_loss_db : [n_links], float64
            Distance-dependent path loss without shadowing [dB].
        sf_std_db : [n_links], float64
            Log-normal shadow-fading standard deviation of each link [dB].
        """
        d_true = np.asarray(distances_m, dtype=np.float64)
        lower = self.d_min_m if self.below_min_distance == "clamp" else D_FAR_FIELD_M
        d = np.maximum(d_true, max(lower, D_FAR_FIELD_M))
        h_bs = np.broadcast_to(np.asarray(h_bs_m, dtype=np.float64), d.shape)
        h_ms = np.broadcast_to(np.asarray(h_ms_m, dtype=np.float64), d.shape)
        pl, sf = self._law(d, fc_hz, h_bs, h_ms)
        below = d_true < self.d_min_m
        if self.free_space_floor and np.any(below):
            # extrapolated region only: between free space and the law's value at d_min
            at_min, _ = self._law(np.full(d.shape, self.d_min_m), fc_hz, h_bs, h_ms)
            floor = np.minimum(free_space_db(d, fc_hz), at_min)
            pl = np.where(below, np.maximum(pl, floor), pl)
        return np.ascontiguousarray(pl, dtype=np.float64), np.ascontiguousarray(sf, np.float64)

    def _law(self, d, fc_hz, h_bs, h_ms):
        """The bare formula (no distance limits): ``(PL [dB], σ_SF [dB])``."""
        lf = math.log10(fc_hz / self.fc_ref_hz)
        c = self.coeffs
        m = self.model
        if m == "free_space":
            pl = free_space_db(d, fc_hz) + c["excess_db"]
            sf = np.full(d.shape, c["sf_std_db"])
        elif m == "single_slope":
            pl = c["A"] * np.log10(d) + c["B"] + c["C"] * lf
            sf = np.full(d.shape, c["sf_std_db"])
        elif m == "dual_slope_los":
            pl, beyond = _dual_slope(c, d, fc_hz, lf, h_bs, h_ms)
            sf = np.where(beyond, c["seg2"]["sf_std_db"], c["seg1"]["sf_std_db"])
        elif m == "hata_like_nlos":
            lh = np.log10(h_bs)
            pl = (c["A"] + c["Ah_log10_hbs"] * lh) * np.log10(d) + c["B"]
            pl = pl + c["D_log10_hbs"] * lh + c["C"] * lf
            sf = np.full(d.shape, c["sf_std_db"])
        elif m == "rural_nlos":
            pl = (
                c["A"] * np.log10(d)
                + c["B"]
                + c["hbs_coeff"] * (h_bs - c["hbs_ref_m"]) * np.log10(d / c["d_ref_m"])
                + c["hms_coeff"] * (h_ms - c["hms_ref_m"])
                + c["C"] * lf
            )
            sf = np.full(d.shape, c["sf_std_db"])
        elif m == "indoor_walls":
            n_w = np.maximum(np.floor(d / c["wall_spacing_m"]), 1.0)
            walls = np.maximum(n_w - c["walls_excluded"], 0.0)
            pl = c["A"] * np.log10(d) + c["B"] + c["C"] * lf + c["wall_loss_db"] * walls
            sf = np.full(d.shape, c["sf_std_db"])
        elif m == "manhattan_nlos":
            # Device-to-device: the street geometry is unknown, so the link is taken to turn one
            # corner halfway, d1 = d2 = d/√2 (D1.1.2 evaluates both orderings and keeps the
            # minimum; with d1 = d2 they coincide).
            d1 = d / math.sqrt(2.0)
            d2 = d1
            pl_los, _ = _dual_slope(c["los_law"], d1, fc_hz, lf, h_bs, h_ms)
            n_j = np.maximum(c["nj_a"] + c["nj_b_per_m"] * d1, c["nj_min"])
            pl = (
                pl_los
                + c["offset_db"]
                + c["nj_coeff"] * n_j
                + c["d2_slope_factor"] * n_j * np.log10(d2)
                + c["C"] * lf
            )
            sf = np.full(d.shape, c["sf_std_db"])
        else:  # pragma: no cover - guarded by from_table
            raise ValidationError("pathloss.model", m, PATHLOSS_COMMON["model"].describe())
        return pl, sf

    def check_heights(self, h_bs_m, h_ms_m, names=("h_tx_m", "h_rx_m")) -> None:
        """Raise :class:`ValidationError` if the law cannot use these heights."""
        law = None
        if self.model == "dual_slope_los":
            law = self.coeffs
        elif self.model == "manhattan_nlos":
            law = self.coeffs["los_law"]
        if law is None:
            return
        off = law["breakpoint_height_offset_m"]
        low = float(np.min(h_ms_m))
        if low <= off:
            raise ValidationError(
                f"{names[0]} / {names[1]}",
                low,
                f"antenna heights must exceed the breakpoint height offset {off:g} m of the "
                f"'{self.model}' path-loss law (effective height h − {off:g} m must be > 0)",
            )


def _dual_slope(c, d, fc_hz, lf, h_bs, h_ms):
    """Dual-slope LOS law (WINNER II D1.1.2 Table 4-4): ``(PL [dB], beyond breakpoint [bool])``."""
    off = c["breakpoint_height_offset_m"]
    hb = h_bs - off
    hm = h_ms - off
    d_bp = 4.0 * hb * hm * fc_hz / c["breakpoint_speed_of_light_m_s"]
    s1, s2 = c["seg1"], c["seg2"]
    ld = np.log10(d)
    pl1 = s1["A"] * ld + s1["B"] + s1["C"] * lf
    pl2 = (
        s2["A"] * ld
        + s2["B"]
        + s2["D_log10_hbs"] * np.log10(hb)
        + s2["E_log10_hms"] * np.log10(hm)
        + s2["C"] * lf
    )
    beyond = d >= d_bp
    return np.where(beyond, pl2, pl1), beyond


# ---------------------------------------------------------------------------------------------
#: Keys of each LOS-probability law (d in m).
LOS_LAWS: dict[str, dict] = {
    # P = value
    "constant": {"value": s.Num(0.0, 1.0)},
    # P = exp(−d/d_decay)                                              (D1)
    "exp": {"d_decay_m": s.Num(0.0, 1.0e6, lo_open=True)},
    # P = min(d_near/d, 1)(1 − exp(−d/d_decay)) + exp(−d/d_decay)      (C2)
    "min_exp": {
        "d_near_m": s.Num(0.0, 1.0e5, lo_open=True),
        "d_decay_m": s.Num(0.0, 1.0e6, lo_open=True),
    },
    # P = 1 for d <= d_unity, else 1 − scale (1 − (a + b log10 d)³)^(1/3), clipped to [0, 1]
    # (A1, B1)
    "cubic": {
        "a": _COEF,
        "b": _COEF,
        "scale": s.Num(0.0, 1.0),
        "d_unity_m": s.Num(0.0, 1.0e5),
    },
}


@dataclass(frozen=True, eq=False)
class LosProbability:
    """P_LOS(d), WINNER II D1.1.2 Table 4-7 (the NLOS probability is ``1 − P_LOS``).

    Parameters
    ----------
    law : str
        One of :data:`LOS_LAWS`.
    coeffs : dict
        The law's validated coefficients.
    """

    law: str
    coeffs: dict

    @classmethod
    def from_table(cls, table: dict, where: str) -> LosProbability:
        """Validate a ``[los_probability]`` table."""
        if not isinstance(table, dict):
            raise ValidationError(where, table, "must be a table")
        law = table.get("law", s.MISSING)
        if law not in LOS_LAWS:
            raise ValidationError(f"{where}.law", law, "one of " + ", ".join(map(repr, LOS_LAWS)))
        vals = s.parse(table, {"law": s.Choice(tuple(LOS_LAWS)), **LOS_LAWS[law]}, where)
        vals.pop("law")
        return cls(law, vals)

    def __call__(self, distances_m) -> np.ndarray:
        """P_LOS at each distance [m]; ``[n]`` float64 in [0, 1]."""
        d = np.asarray(distances_m, dtype=np.float64)
        c = self.coeffs
        if self.law == "constant":
            p = np.full(d.shape, c["value"])
        elif self.law == "exp":
            p = np.exp(-d / c["d_decay_m"])
        elif self.law == "min_exp":
            e = np.exp(-d / c["d_decay_m"])
            p = np.minimum(c["d_near_m"] / d, 1.0) * (1.0 - e) + e
        else:  # cubic
            x = c["a"] + c["b"] * np.log10(np.maximum(d, 1e-300))
            p = 1.0 - c["scale"] * np.cbrt(1.0 - x**3)
            p = np.where(d <= c["d_unity_m"], 1.0, p)
        return np.clip(p, 0.0, 1.0)

    def same_as(self, other: LosProbability) -> bool:
        """True if both laws are identical."""
        return self.law == other.law and self.coeffs == other.coeffs

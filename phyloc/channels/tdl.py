"""The ``tdl`` channel model: the tapped delay lines TDL-A to TDL-E of 3GPP TR 38.901.

Scenario files with ``model = "tdl"`` (``channels/tdl_a.toml`` … ``channels/tdl_e.toml``) list the
taps of one TR 38.901 table (Tables 7.7.2-1 to 7.7.2-5) as rows ``[tap, normalized delay,
power in dB, fading]``, with ``fading`` ``"Rayleigh"`` or, for the specular part of the first tap
of the LOS models TDL-D and TDL-E, ``"LOS"``. Per link of distance ``d`` (delays relative to
``d/c0``):

* **Delay scaling** (TR 38.901 Sec. 7.7.3): tap ``n`` has the excess delay
  ``τ_n = τ_n,model · DS_desired`` with ``DS_desired`` the file's ``delay_spread_s``. The
  normalized delays of each table have an RMS delay spread of 1 up to the tables' rounding
  (:func:`rms_delay_spread`; TDL-D gives 0.9937, the others 1 within 3·10⁻⁴).
* **Powers**: the tap powers of the table, normalized to sum to 1, share the link budget
  ``P_tx − PL(d) − SF`` (path-loss law of the file's ``pathloss`` table: the shipped files use
  free space and no shadowing, since a TDL model has no path loss of its own).
* **Fading**: each ``"Rayleigh"`` row is one path with a complex Gaussian gain of its mean power
  (``|g|² ~ Exp(1)`` and a uniform phase); the ``"LOS"`` row is one path of fixed amplitude and
  uniform phase. The first tap of TDL-D/E is thus two paths at delay 0, as the tables split it;
  their power ratio is the first tap's K-factor ``K1`` (13.3 dB and 22 dB).
* **K-factor scaling** (TR 38.901 Sec. 7.7.6, LOS only, optional ``k_factor_db``): with
  ``K_model = P_LOS − 10·log10 Σ_n 10^(P_n/10)`` over the Rayleigh rows (equation 7.7.6-2), the
  Rayleigh rows become ``P_n − K_desired + K_model`` (equation 7.7.6-1), and the normalized
  delays are divided by the RMS delay spread of the new profile before the delay scaling, so that
  the link's delay spread is ``DS_desired`` again (:func:`scale_k_factor`).
* **No Doppler**: links are static (the TR's Doppler spectra are not used).

The wideband power of a drawn link, ``Σ_n |α_n|²``, is the link budget times
``G = Σ_n p_n |g_n|²`` (``E[G] = 1``): the sampler reports it as the link's received power.

References
----------
3GPP TR 38.901, "Study on channel model for frequencies from 0.5 to 100 GHz," Sec. 7.7.2
(Tables 7.7.2-1 to 7.7.2-5: TDL-A to TDL-E), Sec. 7.7.3 (scaling of delays, Tables 7.7.3-1 and
7.7.3-2), Sec. 7.7.6 (K-factor for LOS channel models); the tables are the same in V16.1, V17.0
and V19.2. How the values were read: ``channels/PROVENANCE.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from phyloc.channels import _schema as s
from phyloc.channels.pathloss import PathLoss
from phyloc.errors import ValidationError

#: Fading distributions of a tap row (the tables' "Fading distribution" column).
FADING = ("LOS", "Rayleigh")

_DELAY = s.Num(0.0, 1000.0)  # a normalized delay (units of the delay spread)
_POWER = s.Num(-100.0, 30.0)  # a tap power [dB]


@dataclass(frozen=True)
class TapRows:
    """The ``taps`` key: a list of rows ``[tap, normalized delay, power in dB, fading]``."""

    default: object = s.REQUIRED

    def describe(self) -> str:
        """What the key accepts."""
        return (
            "a non-empty list of rows [tap number, normalized delay, power in dB, fading], "
            "fading 'LOS' or 'Rayleigh'"
        )

    def check(self, field: str, value):
        """The rows as a tuple of ``(int, float, float, str)``; error naming the bad row."""
        if not isinstance(value, list) or not value:
            raise ValidationError(field, value, self.describe())
        rows = []
        for i, row in enumerate(value):
            where = f"{field}[{i}]"
            if not isinstance(row, list) or len(row) != 4:
                raise ValidationError(where, row, self.describe())
            tap, delay, power, fading = row
            tap = s.Num(1, 10000, integer=True).check(f"{where}[0] (tap number)", tap)
            delay = _DELAY.check(f"{where}[1] (normalized delay)", delay)
            power = _POWER.check(f"{where}[2] (power in dB)", power)
            fading = s.Choice(FADING).check(f"{where}[3] (fading)", fading)
            rows.append((tap, delay, power, fading))
        return tuple(rows)


def _spec(condition: str) -> dict:
    spec = {
        "pathloss": s.Raw(),
        "delay_spread_s": s.Num(0.0, 1.0e-5, lo_open=True),
        "taps": TapRows(),
    }
    if condition == "los":
        spec["first_tap_k_factor_db"] = s.Num(-30.0, 60.0)
        spec["k_factor_db"] = s.Num(-30.0, 40.0, default=None)
    else:
        spec["nlos_bias_mean_s"] = s.Num(0.0, 1.0e-4, default=0.0)
    return spec


# ---------------------------------------------------------------------------------------------
def rms_delay_spread(delays, powers_db) -> float:
    """Power-weighted RMS delay spread of a tap list (in the units of ``delays``).

    ``sqrt(Σ p τ² / Σ p − (Σ p τ / Σ p)²)`` with ``p = 10^(P/10)``; every row counts, the
    specular LOS row included (the normalization of TR 38.901 Tables 7.7.2-1 to 7.7.2-5).

    Examples
    --------
    >>> round(rms_delay_spread([0.0, 2.0], [0.0, 0.0]), 12)
    1.0
    """
    t = np.asarray(delays, dtype=np.float64)
    p = 10.0 ** (np.asarray(powers_db, dtype=np.float64) / 10.0)
    m1 = np.sum(p * t) / np.sum(p)
    return float(np.sqrt(max(np.sum(p * t * t) / np.sum(p) - m1 * m1, 0.0)))


def model_k_factor_db(powers_db, is_los) -> float:
    """K-factor of a LOS tap list [dB]: the specular power over all Rayleigh rows.

    TR 38.901 Sec. 7.7.6, equation 7.7.6-2: ``K_model = P_LOS − 10·log10 Σ_n 10^(P_n/10)``, the
    sum over every row but the LOS one (the Rayleigh part of the first tap included).

    Examples
    --------
    >>> round(model_k_factor_db([0.0, -10.0, -10.0], [True, False, False]), 4)
    6.9897
    """
    p = np.asarray(powers_db, dtype=np.float64)
    los = np.asarray(is_los, dtype=bool)
    if los.sum() != 1:
        raise ValidationError("is_los", los.tolist(), "exactly one LOS row")
    rest = np.sum(10.0 ** (p[~los] / 10.0))
    return float(p[los][0] - 10.0 * math.log10(rest))


def scale_k_factor(delays, powers_db, is_los, k_desired_db):
    """Change the K-factor of a LOS tap list (TR 38.901 Sec. 7.7.6).

    The Rayleigh rows become ``P_n − K_desired + K_model`` (equation 7.7.6-1, ``K_model`` of
    :func:`model_k_factor_db`); the LOS row keeps its power. The scaled profile has another
    RMS delay spread, so the normalized delays are divided by it (:func:`rms_delay_spread`):
    the delay scaling of Sec. 7.7.3 then gives the desired delay spread.

    Returns
    -------
    (delays, powers_db) : two float64 arrays, the row order of the input

    Examples
    --------
    >>> t, p = scale_k_factor([0.0, 0.0, 1.0], [0.0, -10.0, -10.0], [True, False, False], 10.0)
    >>> round(model_k_factor_db(p, [True, False, False]), 9), round(rms_delay_spread(t, p), 9)
    (10.0, 1.0)
    """
    t = np.asarray(delays, dtype=np.float64)
    p = np.array(powers_db, dtype=np.float64)
    los = np.asarray(is_los, dtype=bool)
    k_model = model_k_factor_db(p, los)
    p[~los] += k_model - float(k_desired_db)
    ds = rms_delay_spread(t, p)
    if ds <= 0:
        raise ValidationError("delays", t.tolist(), "taps at more than one delay")
    return t / ds, p


# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class TdlCondition:
    """A TR 38.901 tapped delay line (``model = "tdl"``) of one condition.

    Attributes
    ----------
    condition : {"los", "nlos"}
        ``"los"`` for TDL-D/E (a specular first tap), ``"nlos"`` for TDL-A/B/C.
    pathloss : PathLoss
        Path-loss law of the link budget (the shipped files: free space, no shadowing).
    taps : tuple of (int, float, float, str)
        The file's rows ``(tap, normalized delay, power [dB], fading)`` in table order.
    delay_spread_s : float
        ``DS_desired`` [s] (TR 38.901 Sec. 7.7.3).
    first_tap_k_factor_db : float
        ``K1`` of the table (LOS row over the first tap's Rayleigh row) [dB]; NaN in NLOS.
    k_factor_db_desired : float or None
        ``K_desired`` of TR 38.901 Sec. 7.7.6 [dB]; ``None``: the table's K-factor.
    k_db : float
        K-factor of the drawn profile [dB]: ``K_desired``, or ``K_model`` of the table
        (:func:`model_k_factor_db`); NaN in NLOS.
    excess_delays_s : [n_paths] float64
        Excess delays of the paths [s], sorted (ties in table order, so the LOS row is first).
    power_fractions : [n_paths] float64
        Mean power of each path over the link budget (sum 1), in the same order.
    is_los_path : [n_paths] bool
        True for the specular LOS path.
    nlos_bias_mean_s : float
        Mean of the NLOS bias ``b ~ Exp`` on every path [s] (NLOS only; default 0: none).
    """

    condition: str
    pathloss: PathLoss
    taps: tuple
    delay_spread_s: float
    first_tap_k_factor_db: float
    k_factor_db_desired: float | None
    k_db: float
    excess_delays_s: np.ndarray
    power_fractions: np.ndarray
    is_los_path: np.ndarray
    nlos_bias_mean_s: float = 0.0

    @property
    def paths_per_link(self) -> int:
        """Paths of one link: one per row (the first tap of TDL-D/E gives two)."""
        return len(self.taps)


def parse_tdl_condition(condition: str, table: dict, where: str) -> TdlCondition:
    """Validate the ``[los]`` or ``[nlos]`` table of a ``tdl`` file (``where`` names it).

    Checks, beyond each key's range: an ``[nlos]`` table has no ``"LOS"`` row and no
    ``k_factor_db``; a ``[los]`` table starts with the first tap's ``"LOS"`` row and its
    ``"Rayleigh"`` row, both at delay 0, and has no other ``"LOS"`` row; the tap numbers count
    1, 2, … in order (tap 1 twice in ``[los]``); the earliest delay is 0; the
    ``first_tap_k_factor_db`` equals the power of the LOS row minus that of the first Rayleigh
    row.
    """
    if condition == "nlos" and isinstance(table, dict) and "k_factor_db" in table:
        raise ValidationError(
            f"{where}.k_factor_db",
            table["k_factor_db"],
            "only the LOS models (a [los] table: TDL-D, TDL-E) have a K-factor to scale "
            "(TR 38.901 Sec. 7.7.6)",
        )
    vals = s.parse(table, _spec(condition), where)
    rows = vals["taps"]
    field = f"{where}.taps"
    los_rows = [i for i, r in enumerate(rows) if r[3] == "LOS"]
    if condition == "nlos":
        if los_rows:
            raise ValidationError(
                f"{field}[{los_rows[0]}]",
                list(rows[los_rows[0]]),
                "an [nlos] table has no 'LOS' row (TDL-A/B/C have no LOS path); "
                "put a LOS model in a [los] table",
            )
        expected = list(range(1, len(rows) + 1))
    else:
        ok = (
            len(rows) >= 2
            and los_rows == [0]
            and rows[0][0] == rows[1][0] == 1
            and rows[1][3] == "Rayleigh"
            and rows[0][1] == rows[1][1] == 0.0
        )
        if not ok:
            raise ValidationError(
                field,
                [list(r) for r in rows[:2]],
                "a [los] table starts with the first tap's 'LOS' row and its 'Rayleigh' row, "
                "both tap 1 at delay 0, and has no other 'LOS' row "
                "(as TR 38.901 Tables 7.7.2-4 and 7.7.2-5 list them)",
            )
        expected = [1, *range(1, len(rows))]
    for i, (row, want) in enumerate(zip(rows, expected, strict=True)):
        if row[0] != want:
            raise ValidationError(
                f"{field}[{i}][0] (tap number)",
                row[0],
                f"{want} (taps are numbered 1, 2, … in order; in [los] tap 1 twice)",
            )
    delays = np.array([r[1] for r in rows])
    powers = np.array([r[2] for r in rows])
    is_los = np.array([r[3] == "LOS" for r in rows])
    if delays.min() != 0.0:
        raise ValidationError(
            field, float(delays.min()), "the earliest normalized delay must be 0 (the first tap)"
        )
    k1 = math.nan
    k_desired = None
    if condition == "los":
        k1 = vals["first_tap_k_factor_db"]
        table_k1 = powers[0] - powers[1]
        if abs(k1 - table_k1) > 1e-6:
            raise ValidationError(
                f"{where}.first_tap_k_factor_db",
                k1,
                f"the LOS row's power minus the first Rayleigh row's ({table_k1:.6g} dB)",
            )
        k_desired = vals["k_factor_db"]
        if k_desired is not None:
            delays, powers = scale_k_factor(delays, powers, is_los, k_desired)
        k_db = model_k_factor_db(powers, is_los)
    else:
        k_db = math.nan
    lin = 10.0 ** (powers / 10.0)
    lin /= lin.sum()
    order = np.argsort(delays, kind="stable")
    return TdlCondition(
        condition=condition,
        pathloss=PathLoss.from_table(vals["pathloss"], f"{where}.pathloss"),
        taps=rows,
        delay_spread_s=vals["delay_spread_s"],
        first_tap_k_factor_db=k1,
        k_factor_db_desired=k_desired,
        k_db=k_db,
        excess_delays_s=delays[order] * vals["delay_spread_s"],
        power_fractions=lin[order],
        is_los_path=is_los[order],
        nlos_bias_mean_s=vals.get("nlos_bias_mean_s", 0.0),
    )


# ---------------------------------------------------------------------------------------------
def draw_tdl(p: TdlCondition, sf_std: np.ndarray, rng: np.random.Generator) -> dict:
    """Draw ``n = sf_std.size`` links of a tapped delay line (the sampler's drawer).

    Per link: shadowing ``SF ~ N(0, σ_SF²)`` of the path-loss law (0 for the shipped files),
    then ``|g_n|² ~ Exp(1)`` for every path (the Rayleigh amplitude of ``g_n ~ CN(0, 1)``;
    the sampler adds the uniform phase), set to 1 on the LOS path. The path powers are
    ``p_n |g_n|²`` of the link budget; ``power_gain`` is their sum ``G`` per link.

    Returns
    -------
    dict
        The keys of the sampler's drawers (``sf_db``, ``ds_s``, ``k_db``, ``counts``,
        ``delays``, ``fractions``) and ``power_gain`` ``[n]``.
    """
    n = sf_std.size
    m = p.power_fractions.size
    sf = sf_std * rng.standard_normal(n)
    g2 = rng.standard_exponential((n, m))
    g2[:, p.is_los_path] = 1.0
    frac = p.power_fractions * g2
    return {
        "sf_db": sf,
        "ds_s": np.full(n, p.delay_spread_s),
        "k_db": np.full(n, p.k_db),
        "counts": np.full(n, m, dtype=np.int64),
        "delays": np.tile(p.excess_delays_s, n),
        "fractions": frac.ravel(),
        "power_gain": frac.sum(axis=1),
    }


__all__ = [
    "FADING",
    "TapRows",
    "TdlCondition",
    "draw_tdl",
    "model_k_factor_db",
    "parse_tdl_condition",
    "rms_delay_spread",
    "scale_k_factor",
]

"""phyloc's 3GPP TR 38.901 channels against NVIDIA Sionna's (``phyloc channel-compare``).

:func:`compare` draws the same links in both packages, at the same carrier, antenna heights and
3-D distances, and compares what they produce. Sionna is imported only here and only when a
comparison runs (``pip install sionna``, or ``pip install "phyloc[sionna]"``).

System-level scenarios (``tr38901_umi``, ``_uma``, ``_rma``, ``_inh_mixed``, ``_inh_open``,
``_inf_sl``, ``_inf_dl``, ``_inf_sh``, ``_inf_dh``) run through Sionna's ``UMi``, ``UMa``,
``RMa``, ``InH`` and ``InF`` channel classes with the V16.1 tables (``spec_version="16.1"``,
the release phyloc's files transcribe), one BS and one UT per batch example (so that Sionna's
spatially correlated LSPs are independent between links, as phyloc's are), a single
vertically polarized isotropic element at both ends (``antenna_pattern="omni"``: SISO, every
ray with unit field), outdoor UTs not in a car (UMi, UMa, RMa) or indoor UTs (InH, InF, as
Sionna requires), no spatial consistency, no blockage. Each link's 2-D distance ``d_2D`` is
drawn uniformly on the geometry's range (:data:`GEOMETRIES`), the BS stands at the origin at
height ``h_BS`` and the UT at ``d_2D`` in a random azimuth at height ``h_UT``; phyloc gets
``d_3D = sqrt(d_2D² + (h_BS − h_UT)²)`` and the heights as ``h_tx_m``, ``h_rx_m``. Three draws of
``n_links`` links each: the LOS state drawn by each package (LOS probability), then every link
forced LOS, then forced NLOS (the per-state statistics, paired in distance).

What is compared, per LOS state (Sionna's values from its ``LSP`` object, its ``Rays`` and its
channel impulse response ``a``, ``tau``):

* the tables at the drawn links (exact): path loss per link, σ_SF, μ and σ of lgDS, μ and σ of
  K, N, r_τ, ζ, c_DS, the LOS probability per link;
* large-scale draws (Monte Carlo): shadow fading as a power gain (phyloc's SF is a loss,
  ``P_rx = P_tx − PL − SF``; Sionna's multiplies the channel by ``sqrt(sf)``), log10 DS and K
  (mean, std, quantiles, two-sample Kolmogorov–Smirnov test), the correlations of SF, K and
  lgDS, the number of clusters left after the removal of those 25 dB below the strongest;
* the power-delay profile per link in two forms: the *mean-power PDP* (phyloc's paths, whose
  powers are the clusters' mean powers; Sionna's cluster powers and delays of step 6 split into
  the sub-clusters of step 11 with their ray fractions 10/20, 6/20, 4/20, and the specular ray
  K/(K+1)), and the *realized CIR* (phyloc's paths with equal delays added coherently; Sionna's
  ``|a|²``, whose clusters are sums of 20 rays with random phases): power-weighted mean excess
  delay and RMS delay spread of the paths (relative to the first path), the power share of the
  first path, the number of paths, the received power over ``P_tx − PL``;
* the mean excess delay of the first path over ``d/c0`` (phyloc's NLOS bias; Sionna's delays
  start at the first cluster).

TDL scenarios (``tdl_a`` … ``tdl_e``) run through Sionna's ``TDL`` with the file's delay spread
and no motion: tap delays (exact), the mean power of each tap, the RMS delay spread and
K-factor of the mean PDP, and per link the RMS delay spread of the paths, the first tap's power
share and the wideband gain.

Verdicts: a mean, standard deviation or correlation *agrees* if the difference is within
:data:`Z_CRIT` Monte Carlo standard errors (two-sided level :data:`ALPHA`); a distribution
agrees if the two-sample KS test does not reject at :data:`ALPHA`; a table value agrees if it
is equal to within :data:`EXACT_TOL` (relative) or, for path loss, :data:`PATHLOSS_TOL_DB`.

References
----------
3GPP TR 38.901, "Study on channel model for frequencies from 0.5 to 100 GHz," Sec. 7.4
(Tables 7.4.1-1 path loss, 7.4.2-1 LOS probability), Sec. 7.5 steps 4–6, 10 and 11 (Tables 7.5-5,
7.5-6), Sec. 7.7.2–7.7.3 (TDL); the tables as in V16.1.

NVIDIA Sionna 2.2 (GitHub NVlabs/sionna), ``sionna.phy.channel.tr38901``: ``UMi``, ``UMa``,
``RMa``, ``InH``, ``InF`` (``SystemLevelChannel``, ``LSPGenerator``, ``RaysGenerator``,
``ChannelCoefficientsGenerator``) and ``TDL``.
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy import stats

from phyloc import _validate as v
from phyloc.channels.scenario import load_scenario
from phyloc.channels.sionna_draws import (
    GEOMETRIES,
    INSTALL,
    Geometry,
    cluster_counts,
    draw_phyloc,
    draw_sionna,
    link_distances,
    merge_equal_delays,
    pdp_statistics,
    require_sionna,
    sionna_available,
    sionna_modules,
)
from phyloc.errors import PhylocError, ValidationError

#: Two-sided level of every Monte Carlo test.
ALPHA = 1e-3
#: Critical ``|z|`` at :data:`ALPHA` (two-sided).
Z_CRIT = float(stats.norm.isf(ALPHA / 2))
#: Relative tolerance of the table values (both packages evaluate the same formula).
EXACT_TOL = 1e-6
#: Tolerance of the per-link path loss [dB]: Sionna's breakpoint uses c = 299 792 458 m/s,
#: phyloc's the 3·10⁸ m/s of Table 7.4.1-1 note 1 (at most a few thousandths of a dB).
PATHLOSS_TOL_DB = 0.05
#: Default carrier [Hz].
DEFAULT_CARRIER_HZ = 3.5e9
#: Quantile levels stored for the figures.
CDF_LEVELS = np.linspace(0.0, 1.0, 41)


def check_arguments(scenarios, n_links: int, carrier_frequency_hz: float) -> list[str]:
    """Validate a comparison's arguments before any work; returns the scenario names
    (``"all"`` expands to every name of :data:`GEOMETRIES`).

    Raises :class:`~phyloc.errors.ValidationError` for an unknown scenario, fewer than 100
    links or a carrier outside a scenario file's validity range.
    """
    names: list[str] = []
    for name in scenarios:
        names += list(GEOMETRIES) if name == "all" else [name]
    for name in names:
        if name not in GEOMETRIES:
            raise ValidationError("SCENARIO", name, "'all' or one of " + ", ".join(GEOMETRIES))
    v.integer("--links", n_links, minimum=100)
    fc = v.positive("--carrier-frequency-hz", carrier_frequency_hz)
    for name in names:
        try:
            load_scenario(name).check_frequency(fc)
        except ValidationError as exc:
            raise ValidationError("--carrier-frequency-hz", fc, exc.allowed) from None
    return list(dict.fromkeys(names))


# ---------------------------------------------------------------------------------------------
# Rows of the comparison
def _row(key, label, a, b, test, tolerance=None, p_value=None, agrees=None, note="") -> dict:
    diff = None
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        diff = float(a) - float(b)
    verdict = "—" if agrees is None else ("agrees" if agrees else "DIFFERS")
    return {
        "key": key,
        "statistic": label,
        "phyloc": a,
        "sionna": b,
        "difference": diff,
        "test": test,
        "tolerance": tolerance,
        "p_value": p_value,
        "verdict": verdict,
        "note": note,
    }


def _p_of_z(z: float) -> float:
    return float(math.erfc(abs(z) / math.sqrt(2.0))) if np.isfinite(z) else 0.0


def _mean_row(key, label, a, b, note="") -> dict:
    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    ma, mb = float(a.mean()), float(b.mean())
    se = math.sqrt(a.var(ddof=1) / a.size + b.var(ddof=1) / b.size)
    if se == 0.0:
        same = ma == mb
        return _row(key, label, ma, mb, "exact", 0.0, None, same, note)
    z = (ma - mb) / se
    return _row(key, label, ma, mb, "z", Z_CRIT * se, _p_of_z(z), abs(z) <= Z_CRIT, note)


def _std_se(x: np.ndarray) -> float:
    """Standard error of the sample std (any distribution: (m4 − s⁴)/(4 s² n))."""
    s2 = x.var(ddof=1)
    if s2 == 0:
        return 0.0
    m4 = np.mean((x - x.mean()) ** 4)
    return math.sqrt(max(m4 - s2 * s2, 0.0) / (4.0 * s2 * x.size))


def _std_row(key, label, a, b, note="") -> dict:
    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    sa, sb = float(a.std(ddof=1)), float(b.std(ddof=1))
    se = math.hypot(_std_se(a), _std_se(b))
    if se == 0.0:
        return _row(key, label, sa, sb, "exact", 0.0, None, sa == sb, note)
    z = (sa - sb) / se
    return _row(key, label, sa, sb, "z", Z_CRIT * se, _p_of_z(z), abs(z) <= Z_CRIT, note)


def _corr_row(key, label, xa, ya, xb, yb, note="") -> dict:
    ra = float(np.corrcoef(xa, ya)[0, 1])
    rb = float(np.corrcoef(xb, yb)[0, 1])
    se = math.sqrt(1.0 / (len(xa) - 3) + 1.0 / (len(xb) - 3))
    z = (math.atanh(ra) - math.atanh(rb)) / se
    tol = Z_CRIT * se * (1.0 - ((ra + rb) / 2) ** 2)  # in r units, to first order
    return _row(key, label, ra, rb, "fisher z", tol, _p_of_z(z), abs(z) <= Z_CRIT, note)


def _realized_rows(pr: dict, sr: dict, what: str, first: str) -> list:
    """The two KS rows of a realized impulse response: the RMS delay spread of its paths and
    the power share of its first path (``first``: "path" or "tap")."""
    return [
        _ks_row(
            "real.rms_delay",
            f"{what}: RMS delay spread of paths [ns], KS",
            pr["rms_delay_s"],
            sr["rms_delay_s"],
            1e9,
        ),
        _ks_row(
            "real.first_share",
            f"{what}: power share of the first {first}, KS",
            pr["first_share"],
            sr["first_share"],
        ),
    ]


def _ks_row(key, label, a, b, scale=1.0, note="") -> dict:
    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    res = stats.ks_2samp(a, b)
    qa = [float(q) * scale for q in np.quantile(a, (0.1, 0.5, 0.9))]
    qb = [float(q) * scale for q in np.quantile(b, (0.1, 0.5, 0.9))]
    row = _row(key, label, qa, qb, "KS", None, float(res.pvalue), res.pvalue >= ALPHA, note)
    row["ks_statistic"] = float(res.statistic)
    return row


def _exact_row(key, label, a, b, tol=EXACT_TOL, absolute=False, note="") -> dict:
    a, b = np.asarray(a, float), np.asarray(b, float)
    both = np.isfinite(a) & np.isfinite(b)
    if not both.any():
        return _row(key, label, None, None, "exact", None, None, None, note)
    dev = np.abs(a[both] - b[both])
    if not absolute:
        dev = dev / np.maximum(np.abs(b[both]), 1e-300)
    worst = int(np.argmax(dev))
    ok = bool(dev[worst] <= tol) and bool(np.all(np.isfinite(a) == np.isfinite(b)))
    row = _row(key, label, float(a[both][worst]), float(b[both][worst]), "exact", tol, None, ok)
    row["max_deviation"] = float(dev[worst])
    row["note"] = note or (
        "largest " + ("|difference|" if absolute else "relative difference") + " over the links"
    )
    return row


def _quantiles(x) -> list:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return np.quantile(x, CDF_LEVELS).tolist() if x.size else []


# ---------------------------------------------------------------------------------------------
def _los_probability(geom, d2d, ph, si) -> tuple[list, dict]:
    """Rows and series of the LOS-probability comparison (10 bins of d_2D)."""
    lo, hi = geom.d2d_range_m
    edges = np.linspace(lo, hi, 11)
    which = np.clip(np.digitize(d2d, edges) - 1, 0, 9)
    n = np.bincount(which, minlength=10).astype(float)
    k1 = np.bincount(which, ph["los"].astype(float), 10)
    k2 = np.bincount(which, si["los"].astype(float), 10)
    law = np.bincount(which, ph["p_los"], 10) / np.maximum(n, 1)
    pooled = (k1 + k2) / np.maximum(2 * n, 1)
    se = np.sqrt(pooled * (1 - pooled) * 2 / np.maximum(n, 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(se > 0, (k1 - k2) / np.maximum(n, 1) / np.where(se > 0, se, 1), 0.0)
    df = int(np.sum(se > 0))
    chi2 = float(np.sum(z**2))
    p = float(stats.chi2.sf(chi2, df)) if df else 1.0
    rows = [
        _exact_row(
            "p_los_law",
            "P_LOS(d_2D) of the table at every link",
            ph["p_los"],
            si["p_los"],
            tol=1e-9,
            absolute=True,
        ),
        _mean_row("p_los_fraction", "LOS fraction of the drawn states", ph["los"], si["los"]),
    ]
    worst = int(np.argmax(np.abs(z)))
    rows.append(
        _row(
            "p_los_bins",
            f"LOS fraction in 10 bins of d_2D (χ² over {df} bins; worst bin "
            f"{edges[worst]:.0f}–{edges[worst + 1]:.0f} m)",
            float(k1[worst] / max(n[worst], 1)),
            float(k2[worst] / max(n[worst], 1)),
            "χ²",
            Z_CRIT,
            p,
            p >= ALPHA and bool(np.all(np.abs(z) <= Z_CRIT)),
            note=f"max |z| = {np.max(np.abs(z)):.2f} per bin",
        )
    )
    series = {
        "bin_center_m": (0.5 * (edges[:-1] + edges[1:])).tolist(),
        "links": n.tolist(),
        "los_fraction_phyloc": (k1 / np.maximum(n, 1)).tolist(),
        "los_fraction_sionna": (k2 / np.maximum(n, 1)).tolist(),
        "p_los_law": law.tolist(),
        "z": z.tolist(),
    }
    return rows, series


def _state_rows(cond: str, ph: dict, si: dict, scn) -> tuple[list, dict]:
    """The rows of one forced LOS state of a system-level scenario, and its figure series."""
    rows = []
    # the tables
    ph_pl, si_pl = ph["pl_db"], si["pl_db"]
    rows.append(
        _exact_row(
            "pl_db", "path loss per link [dB]", ph_pl, si_pl, tol=PATHLOSS_TOL_DB, absolute=True
        )
    )
    labels = {
        "sf_std_db": "σ_SF of the table [dB]",
        "ds_mu": "μ_lgDS of the table",
        "ds_sigma": "σ_lgDS of the table",
        "k_mu": "μ_K of the table [dB]",
        "k_sigma": "σ_K of the table [dB]",
        "num_clusters": "N clusters of the table",
        "r_tau": "r_τ of the table",
        "zeta_db": "ζ of the table [dB]",
        "c_ds_ns": "c_DS [ns]",
    }
    for key, label in labels.items():
        if cond == "nlos" and key.startswith("k_"):
            continue
        rows.append(_exact_row("table." + key, label, ph["table"][key], si["table"][key]))
    # large-scale draws
    rows.append(_mean_row("sf_mean", "SF as a gain: mean [dB]", ph["sf_gain_db"], si["sf_gain_db"]))
    rows.append(_std_row("sf_std", "SF: std [dB]", ph["sf_gain_db"], si["sf_gain_db"]))
    rows.append(_mean_row("lgds_mean", "log10 DS [s]: mean", ph["lgds"], si["lgds"]))
    rows.append(_std_row("lgds_std", "log10 DS: std", ph["lgds"], si["lgds"]))
    rows.append(_ks_row("lgds_ks", "log10 DS [s]: q10/q50/q90, KS", ph["lgds"], si["lgds"]))
    if cond == "los":
        rows.append(_mean_row("k_mean", "K [dB]: mean", ph["k_db"], si["k_db"]))
        rows.append(_std_row("k_std", "K [dB]: std", ph["k_db"], si["k_db"]))
        rows.append(_ks_row("k_ks", "K [dB]: q10/q50/q90, KS", ph["k_db"], si["k_db"]))
    corr = _corr_row(
        "corr_sf_ds",
        "corr(SF as a gain, lgDS)",
        ph["sf_gain_db"],
        ph["lgds"],
        si["sf_gain_db"],
        si["lgds"],
    )
    rows.append(corr)
    if cond == "los":
        rows.append(
            _corr_row(
                "corr_sf_k",
                "corr(SF as a gain, K)",
                ph["sf_gain_db"],
                ph["k_db"],
                si["sf_gain_db"],
                si["k_db"],
            )
        )
        rows.append(
            _corr_row("corr_ds_k", "corr(lgDS, K)", ph["lgds"], ph["k_db"], si["lgds"], si["k_db"])
        )
    rows.append(
        _mean_row(
            "clusters",
            "clusters after the −25 dB removal: mean",
            ph["clusters"],
            si["clusters"],
        )
    )
    # power-delay profiles
    pm, sm = ph["mean"], si["mean"]
    rows.append(
        _ks_row(
            "mean.mean_delay",
            "mean-power PDP: mean excess delay [ns] q10/q50/q90, KS",
            pm["mean_delay_s"],
            sm["mean_delay_s"],
            1e9,
        )
    )
    rows.append(
        _ks_row(
            "mean.rms_delay",
            "mean-power PDP: RMS delay spread of paths [ns], KS",
            pm["rms_delay_s"],
            sm["rms_delay_s"],
            1e9,
        )
    )
    rows.append(
        _mean_row(
            "mean.first_share",
            "mean-power PDP: power share of the first path, mean",
            pm["first_share"],
            sm["first_share"],
        )
    )
    rows.append(_mean_row("mean.n_paths", "paths per link: mean", pm["n_paths"], sm["n_paths"]))
    rows.append(
        _mean_row(
            "mean.kept",
            "mean-power PDP: power kept after the removal, mean [dB]",
            ph["kept_db"],
            si["kept_db"],
        )
    )
    pr, sr = ph["real"], si["real"]
    rows += _realized_rows(pr, sr, "realized CIR", "path")
    rows.append(
        _mean_row(
            "real.gain_mean", "realized P_rx / (P_tx − PL): mean [dB]", ph["gain_db"], si["gain_db"]
        )
    )
    rows.append(
        _std_row(
            "real.gain_std", "realized P_rx / (P_tx − PL): std [dB]", ph["gain_db"], si["gain_db"]
        )
    )
    rows.append(
        _mean_row(
            "first_excess",
            "first path: excess delay over d/c0, mean [ns]",
            ph["first_excess_s"] * 1e9,
            si["first_excess_s"] * 1e9,
            note="phyloc: its NLOS bias; Sionna: no absolute delay" if cond == "nlos" else "",
        )
    )
    series = {
        "lgds": {"phyloc": _quantiles(ph["lgds"]), "sionna": _quantiles(si["lgds"])},
        "rms_delay_ns": {
            "phyloc": _quantiles(pm["rms_delay_s"] * 1e9),
            "sionna": _quantiles(sm["rms_delay_s"] * 1e9),
            "sionna_cir": _quantiles(sr["rms_delay_s"] * 1e9),
        },
        "first_share": {
            "phyloc_cir": _quantiles(pr["first_share"]),
            "sionna_cir": _quantiles(sr["first_share"]),
        },
        "corr_sf_ds": [corr["phyloc"], corr["sionna"]],
    }
    if cond == "los":
        series["k_db"] = {"phyloc": _quantiles(ph["k_db"]), "sionna": _quantiles(si["k_db"])}
    return rows, series


def _tdl_rows(ph: dict, si: dict) -> tuple[list, dict]:
    """Rows and series of a TDL scenario: taps, mean PDP, per-link realized statistics."""
    rows = []
    td_ph = np.unique(ph["tap_delays_s"])
    td_si = np.unique(si["tap_delays_s"])
    if td_ph.size == td_si.size:
        rows.append(
            _exact_row(
                "tap_delays",
                f"distinct tap delays [ns] (largest: {td_ph[-1] * 1e9:.1f})",
                td_ph * 1e9,
                td_si * 1e9,
                1e-9,
                absolute=True,
                note="largest |difference| over the taps",
            )
        )
    else:
        rows.append(
            _row(
                "tap_delays",
                "number of distinct tap delays",
                td_ph.size,
                td_si.size,
                "exact",
                0,
                None,
                False,
            )
        )
        return rows, {}

    # per distinct delay, the taps at that delay added (independent phases: the mean of the
    # coherent sum is the sum of the means); TDL-E has two Rayleigh taps at 0.5440 DS
    def by_delay(delays, power, distinct):
        idx = np.searchsorted(distinct, delays)
        out = np.zeros((power.shape[0], distinct.size))
        for j in range(power.shape[1]):
            out[:, idx[j]] += power[:, j]
        return out

    p_ph = by_delay(ph["tap_delays_s"], ph["tap_power"], td_ph)
    p_si = by_delay(si["tap_delays_s"], si["tap_power"], td_si)
    ma, mb = p_ph.mean(axis=0), p_si.mean(axis=0)
    se = np.sqrt(
        p_ph.var(axis=0, ddof=1) / p_ph.shape[0] + p_si.var(axis=0, ddof=1) / p_si.shape[0]
    )
    z = np.where(se > 0, (ma - mb) / np.where(se > 0, se, 1.0), 0.0)
    z_crit = float(stats.norm.isf(ALPHA / 2 / td_ph.size))  # Bonferroni over the taps
    worst = int(np.argmax(np.abs(z)))
    rows.append(
        _row(
            "tap_power",
            f"tap mean power [dB] (worst of {td_ph.size} taps: {td_ph[worst] * 1e9:.1f} ns)",
            float(10 * np.log10(ma[worst])),
            float(10 * np.log10(mb[worst])),
            "z (Bonferroni)",
            z_crit,
            min(1.0, _p_of_z(float(z[worst])) * td_ph.size),
            bool(np.all(np.abs(z) <= z_crit)),
            note=f"max |z| = {np.max(np.abs(z)):.2f}",
        )
    )

    def rms(p):
        m1 = np.sum(p * td_ph) / p.sum()
        return math.sqrt(max(np.sum(p * td_ph**2) / p.sum() - m1 * m1, 0.0)) * 1e9

    rows.append(
        _row(
            "mean_pdp_rms",
            f"RMS delay spread of the mean PDP [ns] (file: {ph['file_delay_spread_s'] * 1e9:g})",
            rms(ma),
            rms(mb),
            "info",
        )
    )
    if ph["tap_is_los"].any():
        spec = ph["tap_power"][:, ph["tap_is_los"]].sum(axis=1)
        rows.append(
            _exact_row(
                "specular_share",
                "specular power share (K/(K+1))",
                spec,
                np.full(spec.size, si["tap_specular_power"]),
            )
        )
    pr, sr = ph["real"], si["real"]
    rows += _realized_rows(pr, sr, "realized", "tap")
    rows.append(
        _mean_row("real.gain_mean", "wideband gain G [dB]: mean", ph["gain_db"], si["gain_db"])
    )
    rows.append(
        _std_row("real.gain_std", "wideband gain G [dB]: std", ph["gain_db"], si["gain_db"])
    )
    series = {
        "tap_delay_ns": (td_ph * 1e9).tolist(),
        "tap_power_phyloc": ma.tolist(),
        "tap_power_sionna": mb.tolist(),
        "rms_delay_ns": {
            "phyloc_cir": _quantiles(pr["rms_delay_s"] * 1e9),
            "sionna_cir": _quantiles(sr["rms_delay_s"] * 1e9),
        },
        "first_share": {
            "phyloc_cir": _quantiles(pr["first_share"]),
            "sionna_cir": _quantiles(sr["first_share"]),
        },
    }
    return rows, series


def compare(
    scenario: str,
    *,
    n_links: int = 4000,
    carrier_frequency_hz: float = DEFAULT_CARRIER_HZ,
    seed: int = 0,
) -> dict:
    """Draw ``n_links`` links of ``scenario`` in phyloc and in Sionna and compare them.

    Parameters
    ----------
    scenario : str
        A name of :data:`GEOMETRIES` (``tr38901_umi`` … ``tdl_e``).
    n_links : int
        Links per draw (>= 100): system-level scenarios draw three times (LOS state drawn,
        forced LOS, forced NLOS), TDL scenarios once.
    carrier_frequency_hz : float
        Carrier [Hz], inside the scenario file's validity range.
    seed : int
        Seeds phyloc's ``numpy.random.Generator`` and Sionna's ``sionna.phy.config.seed`` (which
        also seeds torch's default generator).

    Returns
    -------
    dict
        ``{"scenario", "geometry", "carrier_frequency_hz", "links", "seed", "seconds",
        "sections": {section: [row, ...]}, "series": {...}}``; sections ``los_probability``,
        ``los``, ``nlos`` (TDL: its one state). A row is a dict with ``statistic``, ``phyloc``,
        ``sionna``, ``difference``, ``test``, ``tolerance``, ``p_value``, ``verdict``, ``note``.
        Plain Python, JSON-serializable.
    """
    check_arguments([scenario], n_links, carrier_frequency_hz)
    n, fc = int(n_links), float(carrier_frequency_hz)
    scn = load_scenario(scenario)
    config, _, _ = sionna_modules()
    config.seed = int(seed)
    rng = np.random.default_rng(seed)
    geom = GEOMETRIES[scenario]
    t0 = time.perf_counter()
    d2d, az, d3d = link_distances(geom, n, rng)
    out = {
        "scenario": scenario,
        "geometry": {
            "sionna": geom.sionna,
            "option": geom.option,
            "h_bs_m": geom.h_bs_m,
            "h_ut_m": geom.h_ut_m,
            "d2d_range_m": list(geom.d2d_range_m),
        },
        "carrier_frequency_hz": fc,
        "links": n,
        "seed": int(seed),
        "sections": {},
        "series": {},
    }
    ph = draw_phyloc(scenario, d3d, None, fc, geom, rng)
    si = draw_sionna(geom, d2d, az, None, fc)
    if geom.sionna == "TDL":
        cond = "los" if ph["los"].all() else "nlos"
        rows, series = _tdl_rows(ph, si)
        out["sections"][cond] = rows
        out["series"][cond] = series
    else:
        gap = float(np.max(np.abs(si["d3d_m"] - d3d)))
        if gap > 1e-6:  # pragma: no cover - a defect of the placement
            raise PhylocError(f"Sionna's 3-D distances differ from phyloc's by {gap:g} m")
        rows, series = _los_probability(geom, d2d, ph, si)
        out["sections"]["los_probability"] = rows
        out["series"]["los_probability"] = series
        for cond in ("los", "nlos"):
            ph = draw_phyloc(scenario, d3d, cond, fc, geom, rng)
            si = draw_sionna(geom, d2d, az, cond, fc)
            rows, series = _state_rows(cond, ph, si, scn)
            out["sections"][cond] = rows
            out["series"][cond] = series
    out["seconds"] = time.perf_counter() - t0
    return out


__all__ = [
    "ALPHA",
    "CDF_LEVELS",
    "DEFAULT_CARRIER_HZ",
    "EXACT_TOL",
    "GEOMETRIES",
    "INSTALL",
    "PATHLOSS_TOL_DB",
    "Z_CRIT",
    "Geometry",
    "check_arguments",
    "cluster_counts",
    "compare",
    "draw_phyloc",
    "draw_sionna",
    "merge_equal_delays",
    "pdp_statistics",
    "require_sionna",
    "sionna_available",
]

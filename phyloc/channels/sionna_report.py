"""Tables, JSON and figures of :func:`phyloc.channels.sionna_compare.compare`'s results
(``phyloc channel-compare``): one table per scenario and LOS state, the verdict counts, the
``results.json`` form and back, and the CDF figure.

References
----------
3GPP TR 38.901, "Study on channel model for frequencies from 0.5 to 100 GHz," Sec. 7.4-7.5
and 7.7.2-7.7.3; the tables as in V16.1. NVIDIA Sionna 2.2 (GitHub NVlabs/sionna),
``sionna.phy.channel.tr38901``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from phyloc.channels.sionna_compare import ALPHA, CDF_LEVELS, Z_CRIT
from phyloc.channels.sionna_draws import package_versions

# ---------------------------------------------------------------------------------------------
# Reporting
SECTION_TITLES = {
    "los_probability": "LOS probability (state drawn by each package)",
    "los": "forced LOS",
    "nlos": "forced NLOS",
}
TABLE_HEADERS = ["statistic", "phyloc", "Sionna", "difference", "tolerance or p", "verdict"]


def _cell(x) -> str:
    if x is None:
        return ""
    if isinstance(x, list):
        return " / ".join(_cell(y) for y in x)
    if isinstance(x, bool):
        return str(x)
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    x = float(x)
    if not np.isfinite(x):
        return str(x)
    if x != 0 and (abs(x) >= 1e5 or abs(x) < 1e-3):
        return f"{x:.4g}"
    return f"{x:.4g}"


def _test_cell(row: dict) -> str:
    t = row["test"]
    if t == "KS":
        return f"KS p = {row['p_value']:.3g} (D = {row.get('ks_statistic', float('nan')):.3f})"
    if t == "exact":
        if row.get("max_deviation") is None:
            return "exact"
        return f"≤ {row['tolerance']:g} (dev {row['max_deviation']:.2g})"
    if t in ("z", "fisher z"):
        return f"± {row['tolerance']:.3g} (p = {row['p_value']:.3g})"
    if t == "χ²":
        return f"χ² p = {row['p_value']:.3g}"
    if t.startswith("z (Bonferroni"):
        return f"|z| ≤ {row['tolerance']:.2f} (Bonferroni p = {row['p_value']:.3g})"
    return ""


def summary_rows(result: dict) -> list:
    """Table rows ``(statistic, phyloc, Sionna, difference, tolerance or p, verdict)`` of one
    scenario, with a title row (a string) before each section."""
    out = []
    for section, rows in result["sections"].items():
        out.append(f"{result['scenario']}: {SECTION_TITLES.get(section, section)}")
        for r in rows:
            diff = r["difference"]
            out.append(
                (
                    r["statistic"],
                    _cell(r["phyloc"]),
                    _cell(r["sionna"]),
                    _cell(diff),
                    _test_cell(r),
                    r["verdict"] + (f" ({r['note']})" if r["note"] else ""),
                )
            )
    return out


def format_comparison(result: dict) -> str:
    """The tables of one scenario's comparison as text (one table per section)."""
    from phyloc.reporting import format_table

    g = result["geometry"]
    lines = [
        f"== {result['scenario']} vs Sionna {g['sionna']}"
        + (f" ({g['option']})" if g["option"] else "")
        + f": {result['links']} links per draw, fc = {result['carrier_frequency_hz'] / 1e9:g} GHz,"
        f" h_BS = {g['h_bs_m']:g} m, h_UT = {g['h_ut_m']:g} m, d_2D uniform on "
        f"[{g['d2d_range_m'][0]:g}, {g['d2d_range_m'][1]:g}] m, seed {result['seed']} =="
    ]
    block: list = []
    title = None
    for row in [*summary_rows(result), None]:
        if row is None or isinstance(row, str):
            if title is not None:
                lines += ["", title, format_table(block, TABLE_HEADERS)]
            title, block = row, []
        else:
            block.append(row)
    return "\n".join(lines)


def verdict_counts(results) -> dict:
    """``{"agrees": n, "DIFFERS": n, "—": n}`` over every row of ``results``."""
    out = {"agrees": 0, "DIFFERS": 0, "—": 0}
    for res in results:
        for rows in res["sections"].values():
            for r in rows:
                out[r["verdict"]] += 1
    return out


def to_json(results, meta: dict) -> tuple[dict, dict, dict]:
    """``(figures, meta, series)`` for :func:`phyloc.reporting.write_json`: the figures are
    flat numbers ``<scenario>.<section>.<key>.{phyloc,sionna,p_value,agrees}``; ``meta`` gets
    the versions, the test levels and every row; ``series`` the figure's curves."""
    figures: dict[str, float] = {}
    for res in results:
        for section, rows in res["sections"].items():
            for r in rows:
                base = f"{res['scenario']}.{section}.{r['key']}"
                for side in ("phyloc", "sionna"):
                    val = r[side]
                    if isinstance(val, list):
                        val = val[1] if len(val) == 3 else None  # the median of q10/q50/q90
                    if isinstance(val, (int, float)) and not isinstance(val, bool):
                        figures[f"{base}.{side}"] = float(val)
                if r["p_value"] is not None:
                    figures[f"{base}.p_value"] = float(r["p_value"])
                if r["verdict"] != "—":
                    figures[f"{base}.agrees"] = float(r["verdict"] == "agrees")
    meta = {
        **meta,
        "versions": package_versions(),
        "alpha": ALPHA,
        "z_crit": Z_CRIT,
        "verdicts": verdict_counts(results),
        "comparisons": [{k: v for k, v in r.items() if k != "series"} for r in results],
    }
    series = {r["scenario"]: r["series"] for r in results}
    return figures, meta, series


def results_from_json(doc: dict) -> list:
    """The comparisons of a ``results.json`` written from :func:`to_json`, as :func:`compare`
    returned them (for :func:`format_comparison` and :func:`plot_comparison`)."""
    out = []
    for res in doc["meta"]["comparisons"]:
        out.append({**res, "series": doc.get("series", {}).get(res["scenario"], {})})
    return out


def _cdf(ax, q, label, **kw) -> None:
    if q:
        ax.plot(q, CDF_LEVELS, label=label, **kw)


def plot_comparison(results, path_png) -> Path:
    """One row of panels per scenario: P_LOS against d_2D; CDFs of log10 DS (with the
    correlation of SF and lgDS), K, the RMS delay spread of the paths and the power share of the
    first path (TDL: the mean tap powers and the CDFs of the realized RMS delay spread and
    first-tap share); phyloc solid, Sionna dashed (its realized CIR dotted).

    Parameters
    ----------
    results : list of dict
        :func:`compare` results (or :func:`results_from_json`).
    path_png : str or Path
        Output file.

    Returns
    -------
    Path
    """
    from phyloc.reporting import new_figure, save_figure

    results = list(results)
    fig, axes = new_figure(
        max(len(results), 1), 5, squeeze=False, size=(18.0, 2.7 * max(len(results), 1))
    )
    colors = {"los": "tab:blue", "nlos": "tab:red"}
    for row, res in zip(axes, results, strict=False):
        name = res["scenario"]
        ser = res["series"]
        if "los_probability" in ser:
            _plot_system_level(row, name, ser, colors)
        else:
            _plot_tdl(row, name, ser)
        for ax in row:
            if ax.get_visible() and ax.has_data():
                ax.grid(alpha=0.3)
                ax.legend(fontsize=6)
    fig.suptitle(
        "phyloc vs Sionna 2.2 (TR 38.901): solid phyloc, dashed Sionna, dotted Sionna's CIR",
        fontsize=10,
    )
    out = Path(path_png)
    save_figure(fig, out)
    return out


def _plot_system_level(row, name: str, ser: dict, colors: dict) -> None:
    s = ser["los_probability"]
    ax = row[0]
    ax.plot(s["bin_center_m"], s["p_los_law"], "k-", lw=1, label="table P_LOS")
    ax.plot(s["bin_center_m"], s["los_fraction_phyloc"], "o", ms=4, label="phyloc")
    ax.plot(s["bin_center_m"], s["los_fraction_sionna"], "x", ms=5, label="Sionna")
    ax.set_xlabel("d_2D [m]")
    ax.set_ylabel("LOS fraction")
    ax.set_title(f"{name}: LOS probability", fontsize=9)
    corr = []
    for cond in ("los", "nlos"):
        c = colors[cond]
        st = ser.get(cond, {})
        lg = st.get("lgds", {})
        _cdf(row[1], lg.get("phyloc"), f"phyloc {cond}", color=c)
        _cdf(row[1], lg.get("sionna"), f"Sionna {cond}", color=c, ls="--")
        rd = st.get("rms_delay_ns", {})
        _cdf(row[3], rd.get("phyloc"), f"phyloc {cond}", color=c)
        _cdf(row[3], rd.get("sionna"), f"Sionna {cond}", color=c, ls="--")
        _cdf(row[3], rd.get("sionna_cir"), f"Sionna CIR {cond}", color=c, ls=":")
        fs = st.get("first_share", {})
        _cdf(row[4], fs.get("phyloc_cir"), f"phyloc {cond}", color=c)
        _cdf(row[4], fs.get("sionna_cir"), f"Sionna CIR {cond}", color=c, ls=":")
        if "corr_sf_ds" in st:
            a, b = st["corr_sf_ds"]
            corr.append(f"{cond.upper()} {a:+.2f}/{b:+.2f}")
    k = ser.get("los", {}).get("k_db", {})
    _cdf(row[2], k.get("phyloc"), "phyloc", color="tab:blue")
    _cdf(row[2], k.get("sionna"), "Sionna", color="tab:blue", ls="--")
    row[1].set_xlabel("log10 DS [s]")
    row[2].set_xlabel("K [dB] (LOS)")
    row[3].set_xlabel("RMS delay spread of the paths [ns]")
    row[3].set_xscale("symlog", linthresh=1.0)
    row[4].set_xlabel("power share of the first path (realized)")
    titles = (
        "delay spread; corr(SF gain, lgDS) phyloc/Sionna:\n" + ", ".join(corr),
        "K-factor",
        "paths (mean-power PDP; CIR dotted)",
        "first path",
    )
    for ax, t in zip(row[1:], titles, strict=True):
        ax.set_ylabel("CDF")
        ax.set_title(f"{name}: {t}", fontsize=8)


def _plot_tdl(row, name: str, ser: dict) -> None:
    cond = next(iter(ser), None)
    st = ser.get(cond, {})
    if st:
        ax = row[0]
        ax.plot(st["tap_delay_ns"], 10 * np.log10(st["tap_power_phyloc"]), "o", label="phyloc")
        ax.plot(st["tap_delay_ns"], 10 * np.log10(st["tap_power_sionna"]), "x", label="Sionna")
        ax.set_xlabel("tap delay [ns]")
        ax.set_ylabel("mean tap power [dB]")
        ax.set_title(f"{name}: mean PDP", fontsize=9)
        _cdf(row[1], st["rms_delay_ns"]["phyloc_cir"], "phyloc")
        _cdf(row[1], st["rms_delay_ns"]["sionna_cir"], "Sionna", ls="--")
        row[1].set_xlabel("RMS delay spread of the paths [ns]")
        _cdf(row[2], st["first_share"]["phyloc_cir"], "phyloc")
        _cdf(row[2], st["first_share"]["sionna_cir"], "Sionna", ls="--")
        row[2].set_xlabel("power share of the first tap")
        for ax in row[1:3]:
            ax.set_ylabel("CDF")
            ax.set_title(f"{name}: realized links", fontsize=9)
    for ax in row[3:]:
        ax.set_visible(False)


__all__ = [
    "format_comparison",
    "plot_comparison",
    "results_from_json",
    "summary_rows",
    "to_json",
    "verdict_counts",
]

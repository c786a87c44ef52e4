"""What a static-localization result shows: its summary table and POA-NBP Figs. 9–12, drawn
from ``results`` alone, and the figure-name conventions the static experiment writes.

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import numpy as np

from phyloc.reporting import base_figure, draw_interval, new_figure, save_figure, with_interval

#: Suffixes of the wall-time figures.
TIMING_SUFFIXES = ("_s", "_ratio")


def threshold_name(x: float) -> str:
    """The threshold ``x`` [m] as written in figure names: ``0.5`` → ``0p5m``."""
    return f"{x:g}".replace(".", "p") + "m"


def is_timing(name: str) -> bool:
    """True for the wall-time figures (the only ones that depend on the machine) and their
    interval bounds."""
    return base_figure(name).endswith(TIMING_SUFFIXES)


def summary_headers(results: dict):
    """Headers of :func:`summary_rows`."""
    thr = results["meta"]["outage_thresholds_m"]
    return [
        "method",
        "mean error [m]",
        "RMSE [m]",
        "conv. it.",
        "t/node-it [s]",
        "t conv. [s]",
        *[f"P(e>{x:g} m)" for x in thr],
        "floats/link-it",
        "ops/node",
    ]


def summary_rows(results: dict):
    """Accuracy after convergence, iterations and time to convergence per method (each with
    its 95 % interval over topologies when the run has one)."""
    f, meta = results["figures"], results["meta"]
    tok = f"ns{meta['experiment']['n_samples']}"
    rows = []
    for m in meta["methods"]:
        rows.append(
            (
                meta["labels"].get(m, m),
                with_interval(f, f"{m}.mean_error_m"),
                with_interval(f, f"{m}.rmse_m"),
                with_interval(f, f"{m}.convergence_iteration"),
                with_interval(f, f"{m}.time_per_node_iteration_s"),
                with_interval(f, f"{m}.time_to_convergence_s"),
                *[
                    with_interval(f, f"{m}.outage_{threshold_name(x)}")
                    for x in meta["outage_thresholds_m"]
                ],
                f.get(f"{m}.{tok}.floats_per_link_iteration", float("nan")),
                f.get(f"{m}.{tok}.operations_per_node", float("nan")),
            )
        )
    return rows


def reference_method(methods) -> str:
    """The method the paired ratios compare against every other one: ``poa_nbp`` (the
    POA-NBP paper's proposal) when it runs, otherwise the first method."""
    return "poa_nbp" if "poa_nbp" in methods else methods[0]


def _cell(figures: dict, name: str) -> str:
    """:func:`~phyloc.reporting.with_interval` as text (3 significant digits)."""
    x = with_interval(figures, name)
    return "n/a" if x is None else x if isinstance(x, str) else f"{x:.3g}"


def summary_lines(results: dict):
    """What the intervals are, the start time of the methods with a start (PBP, WLS), the
    paired ratios of the mean error, the polygon study and the sample sweep in a few lines."""
    f, meta = results["figures"], results["meta"]
    L = meta["experiment"]["poa_iterations"]
    label = meta["labels"]
    ref = reference_method(meta["methods"])
    out = [
        "[95 % interval over topologies: bootstrap (errors, iterations, times), "
        "Clopper-Pearson (outages); none "
        "with a single topology]",
        f"{meta['topologies']} topologies x {meta['n_agents']} agents; "
        f"POA containment {f['poa.containment_fraction']:.4f}, "
        f"{f['poa.time_per_node_s'] * 1e3:.2f} ms per node, "
        f"rejection-sampling acceptance {f['poa.rejection_acceptance_rate']:.2f}, "
        f"dropped {f['poa.dropped_fraction']:.4f} of the ranges",
    ]
    starts = [
        f"{label.get(m, m)} {_cell(f, f'{m}.start_time_per_node_s')} of "
        f"{_cell(f, f'{m}.time_to_convergence_s')} s"
        for m in meta["methods"]
        if f"{m}.start_time_per_node_s" in f
    ]
    if starts:
        out.append("start per node, of the time to convergence: " + ", ".join(starts))
    ratios = [
        f"{label.get(m, m)} {_cell(f, f'{ref}_vs_{m}.mean_error_m.ratio')}"
        for m in meta["methods"]
        if f"{ref}_vs_{m}.mean_error_m.ratio" in f
    ]
    if ratios:
        out.append(
            f"mean error of {label.get(ref, ref)} over the other method's (same topologies): "
            + ", ".join(ratios)
        )
    for ne in meta["n_edges"]:
        areas = ", ".join(f"{f[f'poa.ne{ne}.area_it{it}_m2']:.0f}" for it in range(1, L + 1))
        out.append(f"mean polygon area N_E={ne} per iteration [m²]: {areas}")
    for e, what in (("ellipse", "exact ellipses"), ("ellipse_paper", "bounding discs (cited)")):
        if f"{e}.area_it1_m2" in f:
            areas = ", ".join(f"{f[f'{e}.area_it{it}_m2']:.0f}" for it in range(1, L + 1))
            out.append(f"mean area of the {what} per iteration [m²]: {areas}")
    for m in meta["sample_methods"]:
        parts = [
            f"N_S={ns}: {_cell(f, f'{m}.ns{ns}.mean_error_m')} m" for ns in meta["sample_sweep"]
        ]
        if parts:
            out.append(f"{label.get(m, m)} mean error vs samples: " + ", ".join(parts))
    return out


def error_bars(ax, x, figures: dict, names, color) -> bool:
    """The 95 % intervals of the figures ``names`` (one per ``x``) as error bars on ``ax``;
    returns whether there was one to draw (a run of one topology has none)."""
    y = np.array([_finite(figures.get(n)) for n in names])
    lo = np.array([_finite(figures.get(n + ".ci_low")) for n in names])
    hi = np.array([_finite(figures.get(n + ".ci_high")) for n in names])
    ok = np.isfinite(y) & np.isfinite(lo) & np.isfinite(hi)
    if not ok.any():
        return False
    yerr = np.maximum(0.0, [y[ok] - lo[ok], hi[ok] - y[ok]])  # rounding: never negative
    ax.errorbar(
        np.asarray(x, dtype=float)[ok], y[ok], yerr=yerr, fmt="none", ecolor=color, capsize=2, lw=1
    )
    return True


def _finite(x) -> float:
    return np.nan if x is None else float(x)


def plot(results: dict, path) -> None:
    """Figs. 9–12: polygon area vs iteration, mean error vs iteration, outage, samples; the
    95 % intervals over topologies as bands (areas) and error bars (the mean error after
    convergence, the outage at ``outage_thresholds_m``)."""
    f, ser, meta = results["figures"], results["series"], results["meta"]
    fig, ax = new_figure(1, 4, size=(20, 4.6))
    it = ser["poa_iteration"]
    thr = meta["outage_thresholds_m"]
    for ne in meta["n_edges"]:
        (line,) = ax[0].plot(it, ser[f"poa.ne{ne}.area_m2"], "o-", label=f"POA N_E={ne}")
        names = [f"poa.ne{ne}.area_it{i}_m2" for i in range(1, len(it) + 1)]
        draw_interval(ax[0], it, f, names, line.get_color())
    for e, style, label in (
        ("ellipse", "k^--", "exact ellipses"),
        ("ellipse_paper", "kv:", "bounding discs (cited)"),
    ):
        if f"{e}.area_m2" in ser:
            ax[0].plot(it, ser[f"{e}.area_m2"], style, label=label)
            names = [f"{e}.area_it{i}_m2" for i in range(1, len(it) + 1)]
            draw_interval(ax[0], it, f, names, "k")
    ax[0].set(xlabel="iteration", ylabel="mean area [m²]", yscale="log", title="Fig. 9")
    for m in meta["methods"]:
        label = meta["labels"].get(m, m)
        (line,) = ax[1].plot(ser["iteration"], ser[f"{m}.mean_error_m"], "o-", label=label)
        error_bars(ax[1], [len(ser["iteration"])], f, [f"{m}.mean_error_m"], line.get_color())
        (line,) = ax[2].semilogx(ser["outage_threshold_m"], ser[f"{m}.outage"], label=label)
        names = [f"{m}.outage_{threshold_name(x)}" for x in thr]
        error_bars(ax[2], thr, f, names, line.get_color())
    ax[1].set(
        xlabel="iteration", ylabel="mean localization error [m]", yscale="log", title="Fig. 10"
    )
    ax[2].set(xlabel="error threshold [m]", ylabel="outage probability", title="Fig. 11")
    for k, m in enumerate(meta["sample_methods"]):  # the first (POA-NBP) solid, others dashed
        for ns in meta["sample_sweep"]:
            (line,) = ax[3].semilogx(
                ser["outage_threshold_m"],
                ser[f"{m}.ns{ns}.outage"],
                "-" if k == 0 else "--",
                label=f"{meta['labels'].get(m, m)} N_S={ns}",
            )
            names = [f"{m}.ns{ns}.outage_{threshold_name(x)}" for x in thr]
            error_bars(ax[3], thr, f, names, line.get_color())
    if "pbp" in meta["methods"]:  # POA-NBP Fig. 12 draws PBP as the reference curve
        pbp = ser.get("pbp.sweep.outage", ser["pbp.outage"])  # the sweep's topologies
        ax[3].semilogx(ser["outage_threshold_m"], pbp, "k:", label="PBP")
    ax[3].set(xlabel="error threshold [m]", ylabel="outage probability", title="Fig. 12")
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=7)
    fig.suptitle(
        f"{meta['recipe']}: {meta['topologies']} topologies x {meta['n_agents']} agents"
        " (bars, bands: 95 % intervals over topologies)"
    )
    save_figure(fig, path)

"""What a static-localization result shows: its summary table and POA-NBP Figs. 9–12, drawn
from ``results`` alone, and the figure-name conventions the static experiment writes.

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

from phyloc.reporting import new_figure, save_figure

#: Suffixes of the wall-time figures.
TIMING_SUFFIXES = ("_s", "_ratio")


def threshold_name(x: float) -> str:
    return f"{x:g}".replace(".", "p") + "m"


def is_timing(name: str) -> bool:
    """True for the wall-time figures (the only ones that depend on the machine)."""
    return name.endswith(TIMING_SUFFIXES)


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
    """Accuracy after convergence, iterations and time to convergence per method."""
    f, meta = results["figures"], results["meta"]
    tok = f"ns{meta['experiment']['n_samples']}"
    rows = []
    for m in meta["methods"]:
        rows.append(
            (
                meta["labels"].get(m, m),
                f[f"{m}.mean_error_m"],
                f[f"{m}.rmse_m"],
                int(f[f"{m}.convergence_iteration"]),
                f[f"{m}.time_per_node_iteration_s"],
                f[f"{m}.time_to_convergence_s"],
                *[f[f"{m}.outage_{threshold_name(x)}"] for x in meta["outage_thresholds_m"]],
                f.get(f"{m}.{tok}.floats_per_link_iteration", float("nan")),
                f.get(f"{m}.{tok}.operations_per_node", float("nan")),
            )
        )
    return rows


def summary_lines(results: dict):
    """Polygon study and sample sweep in a few lines."""
    f, meta = results["figures"], results["meta"]
    L = meta["experiment"]["poa_iterations"]
    out = [
        f"{meta['topologies']} topologies x {meta['n_agents']} agents; "
        f"POA containment {f['poa.containment_fraction']:.4f}, "
        f"{f['poa.time_per_node_s'] * 1e3:.2f} ms per node, "
        f"rejection-sampling acceptance {f['poa.rejection_acceptance_rate']:.2f}, "
        f"dropped {f['poa.dropped_fraction']:.4f} of the ranges"
    ]
    for ne in meta["n_edges"]:
        areas = ", ".join(f"{f[f'poa.ne{ne}.area_it{it}_m2']:.0f}" for it in range(1, L + 1))
        out.append(f"mean polygon area N_E={ne} per iteration [m²]: {areas}")
    if "ellipse.area_it1_m2" in f:
        areas = ", ".join(f"{f[f'ellipse.area_it{it}_m2']:.0f}" for it in range(1, L + 1))
        out.append(f"mean ellipse area per iteration [m²]: {areas}")
    for m in meta["sample_methods"]:
        parts = [f"N_S={ns}: {f[f'{m}.ns{ns}.mean_error_m']:.3f} m" for ns in meta["sample_sweep"]]
        if parts:
            out.append(f"{meta['labels'].get(m, m)} mean error vs samples: " + ", ".join(parts))
    return out


def plot(results: dict, path) -> None:
    """Figs. 9–12: polygon area vs iteration, mean error vs iteration, outage, samples."""
    ser, meta = results["series"], results["meta"]
    fig, ax = new_figure(1, 4, size=(20, 4.6))
    it = ser["poa_iteration"]
    for ne in meta["n_edges"]:
        ax[0].plot(it, ser[f"poa.ne{ne}.area_m2"], "o-", label=f"POA N_E={ne}")
    if "ellipse.area_m2" in ser:
        ax[0].plot(it, ser["ellipse.area_m2"], "k^--", label="ellipses")
    ax[0].set(xlabel="iteration", ylabel="mean area [m²]", yscale="log", title="Fig. 9")
    for m in meta["methods"]:
        label = meta["labels"].get(m, m)
        ax[1].plot(ser["iteration"], ser[f"{m}.mean_error_m"], "o-", label=label)
        ax[2].semilogx(ser["outage_threshold_m"], ser[f"{m}.outage"], label=label)
    ax[1].set(
        xlabel="iteration", ylabel="mean localization error [m]", yscale="log", title="Fig. 10"
    )
    ax[2].set(xlabel="error threshold [m]", ylabel="outage probability", title="Fig. 11")
    for k, m in enumerate(meta["sample_methods"]):  # the first (POA-NBP) solid, others dashed
        for ns in meta["sample_sweep"]:
            ax[3].semilogx(
                ser["outage_threshold_m"],
                ser[f"{m}.ns{ns}.outage"],
                "-" if k == 0 else "--",
                label=f"{meta['labels'].get(m, m)} N_S={ns}",
            )
    if "pbp" in meta["methods"]:  # POA-NBP Fig. 12 draws PBP as the reference curve
        ax[3].semilogx(ser["outage_threshold_m"], ser["pbp.outage"], "k:", label="PBP")
    ax[3].set(xlabel="error threshold [m]", ylabel="outage probability", title="Fig. 12")
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=7)
    fig.suptitle(f"{meta['recipe']}: {meta['topologies']} topologies x {meta['n_agents']} agents")
    save_figure(fig, path)

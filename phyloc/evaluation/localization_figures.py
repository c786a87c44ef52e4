"""Figures of the localization experiment (DiPNet Fig. 5 layout, the cost against network
size) drawn from its results only, and the initialization suffixes of its figure names.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from phyloc.localization import METHODS as REGISTRY
from phyloc.reporting import draw_interval, new_figure, save_figure, with_interval

INITS = {"truth_free": "", "informed": "_informed", "gauge": "_gauge"}
"""Initializations and the suffix each gives the scenario token in figure names."""


def _reads_tables(name: str) -> bool:
    """True for a direct method on correlation tables (DiPNet and its variants): the rows the
    summary and the per-iteration panels single out, chosen by the method's inputs, not its
    name."""
    method = REGISTRY.get(name)
    return method is not None and method.inputs == "tables"


def _rmse_points(ax, f, meta, tok, n) -> None:
    """The RMSE panel of a run at one network size: per start and method a point with its 95 %
    interval as an error bar, the methods along the x axis (the start first)."""
    names = ["start", *meta["methods"]]
    for k, init in enumerate(meta["inits"]):
        tag = tok + INITS[init]
        shift = (k - (len(meta["inits"]) - 1) / 2) * 0.15
        for i, m in enumerate(names):
            name = f"{m}.{tag}.agents_{n}.framework_rmse_m"
            y = f.get(name, np.nan)
            if y is None or not np.isfinite(y):
                continue
            lo, hi = f.get(name + ".ci_low"), f.get(name + ".ci_high")
            err = None
            if lo is not None and hi is not None and np.isfinite(lo) and np.isfinite(hi):
                err = [[max(y - lo, 0.0)], [max(hi - y, 0.0)]]
            ax.errorbar(
                [i + shift],
                [y],
                yerr=err,
                fmt="*" if m == "start" else "o",
                color="k" if m == "start" else f"C{i - 1}",
                mfc="none" if init != "truth_free" else None,
                capsize=3,
            )
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels(["start\n(centralized)", *meta["methods"]], rotation=30, fontsize=7)
    ax.set_ylabel("RMSE [m]")
    starts = ", ".join(
        f"{init}: {'filled' if init == 'truth_free' else 'hollow'}" for init in meta["inits"]
    )
    ax.set_title(
        f"{tok}, {n} agents: framework distance RMSE, 95 % intervals ({starts})", fontsize=8
    )
    ax.grid(True, axis="y", alpha=0.3)


def _cdf_reach(ax) -> float:
    """An x limit for a CDF panel: a little beyond where every drawn CDF reaches 0.99 (the
    panel then shows the errors there are, not the grid's whole range)."""
    reach = 0.0
    for line in ax.get_lines():
        x, y = np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)
        if x.size == 0:
            continue
        above = np.flatnonzero(y >= 0.99)
        reach = max(reach, x[above[0]] if above.size else x[-1])
    return 1.15 * reach if reach > 0 else 1.0


def plot(results: dict, path) -> None:
    """DiPNet Fig. 5 layout from results only: RMSE vs agents per scenario, CDFs, ESS."""
    f, ser, meta = results["figures"], results["series"], results["meta"]
    toks = list(meta["scenarios"])
    tracking = any(k.endswith(".rmse_by_snapshot") for k in ser)
    n_rows = 3 if tracking else 2
    fig, axes = new_figure(
        n_rows, len(toks) + 1, squeeze=False, size=(4.6 * len(toks) + 4.6, 4.0 * n_rows)
    )
    agents = meta["agents"]
    for j, tok in enumerate(toks):
        ax = axes[0, j]
        if len(agents) == 1:  # one network size: each method a point with its interval
            _rmse_points(ax, f, meta, tok, agents[0])
        for init in meta["inits"] if len(agents) > 1 else ():
            tag = tok + INITS[init]
            ls = "-" if init == "truth_free" else ("--" if init == "informed" else ":")
            for i, m in enumerate(("start", *meta["methods"])):
                names = [f"{m}.{tag}.agents_{n}.framework_rmse_m" for n in agents]
                y = [f.get(k, np.nan) for k in names]
                if m == "start" and not np.any(np.isfinite(np.asarray(y, dtype=float))):
                    continue
                color = "k" if m == "start" else f"C{i - 1}"
                label = "start, centralized" if m == "start" else m
                ax.semilogy(
                    agents,
                    y,
                    ls,
                    marker="*" if m == "start" else "os^vdx"[(i - 1) % 6],
                    color=color,
                    label=f"{label} ({init})",
                )
                draw_interval(ax, agents, f, names, color)
        if len(agents) > 1:  # one legend for every scenario, below the panels (_shared_legend)
            ax.set_title(f"{tok}: framework distance RMSE, 95 % bands")
            ax.set_xlabel("number of agents")
            ax.set_ylabel("RMSE [m]")
            ax.grid(True, which="both", alpha=0.3)
        ax = axes[1, j]
        init = "truth_free" if "truth_free" in meta["inits"] else next(iter(meta["inits"]))
        tag = tok + INITS[init]
        sizes = sorted({*meta["agents"]} & set(_cdf_sizes(ser, meta, tag)))[:2]
        for n, ls in zip(sizes, ("-", "--"), strict=False):
            for i, m in enumerate(meta["methods"]):
                k = f"{m}.{tag}.agents_{n}.error_cdf"
                if k in ser:
                    ax.plot(ser["cdf_grid_m"], ser[k], ls, color=f"C{i}", label=f"{m}, {n} agents")
        ax.set_xlim(0.0, _cdf_reach(ax))
        ax.set_title(f"{tok} ({init.replace('_', '-')} start): error CDF")
        ax.set_xlabel("absolute framework distance error [m]")
        ax.set_ylabel("CDF")
        ax.grid(True, alpha=0.3)
        _cdf_legend(ax, meta["methods"], sizes, colours=len(agents) == 1)
    n = max(agents)
    ax = axes[0, -1]
    ax2 = axes[1, -1]
    tok = toks[0]
    for i, m in enumerate(meta["methods"]):
        if not _reads_tables(m):
            continue
        for init in meta["inits"]:
            base = f"{m}.{tok}{INITS[init]}.agents_{n}"
            if f"{base}.ess_by_iteration" in ser:
                ax.semilogy(ser[f"{base}.ess_by_iteration"], color=f"C{i}", label=f"{m} ({init})")
                ax2.semilogy(
                    ser[f"{base}.published_std_by_iteration"],
                    "--",
                    color=f"C{i}",
                    label=f"{m} ({init}) published std",
                )
                ax2.semilogy(
                    ser[f"{base}.actual_err_by_iteration"],
                    "-",
                    color=f"C{i}",
                    label=f"{m} ({init}) actual error",
                )
    ax.set_title(f"{tok}, {n} agents: mean ESS per iteration")
    ax.set_xlabel("iteration")
    ax2.set_title("published std vs actual error per axis [m]")
    ax2.set_xlabel("iteration")
    for a in (ax, ax2):
        if a.get_legend_handles_labels()[0]:  # a run without per-iteration series draws none
            a.legend(fontsize=6)
        a.grid(True, which="both", alpha=0.3)
    if tracking:
        _plot_tracks(axes[2], ser, meta, toks)
    if len(agents) > 1:
        _shared_legend(fig, axes[0, 0])
    fig.suptitle(
        f"Direct vs two-step localization — {meta['recipe']}{' (fast)' if meta.get('fast') else ''}"
    )
    save_figure(fig, path)
    if len(agents) > 1 and any(k.endswith("_link_exponent") for k in f):
        plot_cost(results, Path(path).with_name(Path(path).stem + "_cost.png"))
    if any(k.endswith(".map_estimates") for k in ser):
        plot_map(results, Path(path).with_name(Path(path).stem + "_map.png"))


def _shared_legend(fig, ax) -> None:
    """The RMSE panels' legend (the same methods in every scenario) once, below the figure, so
    that it takes no width from the panels."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(
            handles, labels, loc="outside lower center", ncol=min(len(labels), 6), fontsize=7
        )


def _cdf_legend(ax, methods, sizes, *, colours: bool) -> None:
    """A CDF panel's legend: a line style per network size and, with ``colours`` (no shared
    legend below the figure names the methods' colours), a colour per method, not one entry
    per method and size."""
    from matplotlib.lines import Line2D

    handles = (
        [Line2D([], [], color=f"C{i}", label=m) for i, m in enumerate(methods)] if colours else []
    )
    handles += [
        Line2D([], [], ls=ls, color="0.3", label=f"{n} agents")
        for n, ls in zip(sizes, ("-", "--"), strict=False)
    ]
    if sizes:
        ax.legend(handles=handles, fontsize=6, loc="best", ncol=2 if len(handles) > 8 else 1)


def plot_map(results: dict, path) -> None:
    """``<recipe>_map.png`` (networks with anchors, whose frame is then absolute): per scenario
    token, the CDF of the absolute position error at the largest size, and a map of the first
    realization's estimates against the true positions (anchors as triangles)."""
    f, ser, meta = results["figures"], results["series"], results["meta"]
    toks = [
        t
        for t in meta["scenarios"]
        if any(k.startswith(f"{t}.") and k.endswith(".map_truth") for k in ser)
    ]
    n = max(meta["agents"])
    init = "truth_free" if "truth_free" in meta["inits"] else next(iter(meta["inits"]))
    fig, axes = new_figure(len(toks), 2, squeeze=False, size=(11.0, 4.6 * len(toks)))
    for j, tok in enumerate(toks):
        tag = tok + INITS[init]
        ax, axm = axes[j]
        truth = np.asarray(ser[f"{tok}.agents_{n}.map_truth"], float)
        anchor = np.asarray(ser[f"{tok}.agents_{n}.map_is_anchor"], bool)
        for i, m in enumerate(meta["methods"]):
            base = f"{m}.{tag}.agents_{n}"
            if base + ".position_error_cdf" in ser:
                label = f"{m}: RMSE {with_interval(f, base + '.position_rmse_m')} m"
                ax.plot(
                    ser["cdf_grid_m"], ser[base + ".position_error_cdf"], color=f"C{i}", label=label
                )
            if base + ".map_estimates" in ser:
                est = np.asarray(ser[base + ".map_estimates"], float)
                axm.scatter(
                    est[:, 0], est[:, 1], s=14, marker="os^vdx"[i % 6], color=f"C{i}", label=m
                )
                for a, b in zip(est, truth[~anchor], strict=False):
                    axm.plot([a[0], b[0]], [a[1], b[1]], color=f"C{i}", lw=0.5, alpha=0.5)
        axm.scatter(
            truth[~anchor, 0],
            truth[~anchor, 1],
            s=40,
            facecolors="none",
            edgecolors="k",
            label="true agents",
        )
        axm.scatter(
            truth[anchor, 0], truth[anchor, 1], s=60, marker="^", color="k", label="anchors"
        )
        ax.set_xlim(0.0, _cdf_reach(ax))
        ax.set(
            xlabel="absolute position error [m]",
            ylabel="CDF",
            title=f"{tok}, {n} agents ({init.replace('_', '-')} start)",
        )
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=6, loc="lower right")
        axm.set(
            xlabel="x [m]", ylabel="y [m]", title=f"{tok}: first realization, estimates and truth"
        )
        axm.set_aspect("equal", adjustable="datalim")
        axm.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    fig.suptitle(f"Absolute positions (anchors fix the frame) — {meta['recipe']}")
    save_figure(fig, path)


def plot_cost(results: dict, path) -> None:
    """``<recipe>_cost.png`` (runs over several sizes): per scenario token, the wall time of one
    filter iteration over the whole network against the number of agents (log–log, with the
    fitted exponent in the legend and a slope-1 guide), the chain of each method per
    realization, and the peak RSS of a realization's task."""
    f, meta = results["figures"], results["meta"]
    agents = np.asarray(meta["agents"], dtype=float)
    toks = list(meta["scenarios"])
    fig, axes = new_figure(len(toks), 3, squeeze=False, size=(13.8, 4.0 * len(toks)))
    for j, tok in enumerate(toks):
        ax, ax2, ax3 = axes[j]
        for init in meta["inits"]:
            tag = tok + INITS[init]
            for i, m in enumerate(meta["methods"]):
                y = [f.get(f"{m}.{tag}.agents_{int(n)}.iteration_s", np.nan) for n in agents]
                b = f.get(f"{m}.{tag}.iteration_s_exponent", np.nan)
                ax.loglog(agents, y, marker="os^vdx"[i % 6], color=f"C{i}", label=f"{m}: N^{b:.2f}")
                c = [f.get(f"{m}.{tag}.agents_{int(n)}.chain_s", np.nan) for n in agents]
                ax2.loglog(agents, c, marker="os^vdx"[i % 6], color=f"C{i}", label=m)
        y0 = f.get(f"{meta['methods'][0]}.{toks[0]}.agents_{int(agents[0])}.iteration_s", np.nan)
        ax.loglog(agents, y0 * agents / agents[0], "k:", lw=1, label="∝ N")
        rss = [f.get(f"{tok}.agents_{int(n)}.peak_rss_mb", np.nan) for n in agents]
        ax3.loglog(agents, rss, "ko-")
        ax.set_title(f"{tok}: one filter iteration, whole network")
        ax.set_ylabel("wall time [s]")
        ax2.set_title(f"{tok}: one realization per method (chain)")
        ax2.set_ylabel("wall time [s]")
        ax3.set_title(f"{tok}: peak RSS of a realization")
        ax3.set_ylabel("MB")
        for a in (ax, ax2, ax3):
            a.set_xlabel("number of agents")
            a.grid(True, which="both", alpha=0.3)
        for a in (ax, ax2):
            a.legend(fontsize=6)
    fig.suptitle(f"Cost against network size — {meta['recipe']}")
    save_figure(fig, path)


def _plot_tracks(axes, ser, meta, toks):
    """Per-snapshot framework RMSE of every method (truth-free start), one panel per token."""
    n = max(meta["agents"])
    for j, tok in enumerate(toks):
        ax = axes[j]
        for i, m in enumerate(meta["methods"]):
            k = f"{m}.{tok}.agents_{n}.rmse_by_snapshot"
            if k in ser:
                ax.semilogy(np.asarray(ser[k]), color=f"C{i}", label=m)
        ax.set_title(f"{tok}, {n} agents: framework RMSE per snapshot")
        ax.set_xlabel("snapshot")
        ax.set_ylabel("RMSE [m]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6)
    axes[-1].set_axis_off()


def _cdf_sizes(ser, meta, tok):
    return [
        n
        for n in meta["agents"]
        if any(f"{m}.{tok}.agents_{n}.error_cdf" in ser for m in meta["methods"])
    ]

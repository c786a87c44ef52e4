"""What a tracking result shows: its summary table and its figures (PF-BP Figs. 1, 4–7), drawn
from ``results`` alone, and the figure-name conventions the tracking experiment writes.

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from phyloc.reporting import base_figure, new_figure, save_figure, with_interval

UNITS = {"p": "p_m", "v": "v_m_s", "a": "a_m_s2"}
OUTAGE_GRID_M = np.logspace(-2, 1.5, 141)
TIMING_SUFFIXES = (".step_s", ".agent_s", ".step_ratio")


def threshold_name(x: float) -> str:
    """A threshold [m] as it is written in figure names: ``1`` → ``1m``, ``0.1`` → ``0p1m``."""
    return f"{x:g}".replace(".", "p") + "m"


def range_text(r) -> str:
    """A communication range [m] for a title: ``None`` (how JSON keeps an infinite range read
    back from ``results.json``) and ``inf`` are ``∞``.

    >>> range_text(18.0), range_text(float("inf")), range_text(None)
    ('18 m', '∞', '∞')
    """
    return "∞" if r is None or not np.isfinite(r) else f"{float(r):g} m"


def is_timing(name: str) -> bool:
    """True for the wall-time figures (the only ones that depend on the machine: the time
    per step, per agent, by stage, and their ratios) and their interval bounds.

    >>> is_timing("pfbp.s1_r18.stage.flow_s.ci_low"), is_timing("pfbp.s1_r18.k1.rmse_v_m_s")
    (True, False)
    """
    base = base_figure(name)
    return base.endswith(TIMING_SUFFIXES) or (".stage." in base and base.endswith("_s"))


def summary_headers(results: dict):
    """Headers of :func:`summary_rows`."""
    meta = results["meta"]
    last = max(meta["report_steps"]) if meta["report_steps"] else None
    return [
        "scenario",
        "method",
        *[f"RMSE_p k={k} [m]" for k in meta["report_steps"]],
        f"RMSE/PCRLB k={last}",
        f"RMSE/PCRLB cond. k={last}",
        "step [s]",
        "per agent [s]",
    ]


def summary_rows(results: dict):
    """Position RMSE at the report steps (with its 95 % interval over runs when the run has
    one), RMSE/PCRLB at the last one, time per step."""
    f, meta = results["figures"], results["meta"]
    steps = meta["report_steps"]
    rows = []
    for tok in meta["scenarios"]:
        for m in meta["methods"]:
            base = f"{m}.{tok}"
            rows.append(
                (
                    tok,
                    m,
                    *[with_interval(f, f"{base}.k{k}.rmse_p_m") for k in steps],
                    f[f"{base}.k{steps[-1]}.rmse_over_pcrlb"] if steps else None,
                    f[f"{base}.k{steps[-1]}.rmse_over_pcrlb_cond"] if steps else None,
                    f[f"{base}.step_s"],
                    f.get(f"{base}.agent_s"),
                )
            )
        for name, label in (("pcrlb", "PCRLB"), ("pcrlb_cond", "PCRLB (cond.)")):
            rows.append(
                (tok, label, *[f[f"{name}.{tok}.k{k}.p_m"] for k in steps], None, None, None, None)
            )
    return rows


def summary_lines(results: dict):
    """Outage probabilities, the paired RMSE ratios of the first method over the others and
    the SIR-BP/PF-BP time ratio."""
    f, meta = results["figures"], results["meta"]
    out = [
        f"{meta['runs']} runs x {meta['n_steps']} steps, {meta['measurements']} measurements; "
        f"times: {meta['timing']} [95 % interval over runs]"
    ]
    first, others = meta["methods"][0], meta["methods"][1:]
    for tok in meta["scenarios"]:
        ratios = [(m, with_interval(f, f"{first}_vs_{m}.{tok}.rmse_p_all_m.ratio")) for m in others]
        if ratios and all(r is not None for _, r in ratios):
            out.append(
                f"{tok}: RMSE_p over the trajectory, {first} / other on the same runs: "
                + "; ".join(f"{m} {_cell(r)}" for m, r in ratios)
            )
        for k in meta["outage_steps"]:
            parts = []
            for m in meta["methods"]:
                o = ", ".join(
                    f"{f[f'{m}.{tok}.k{k}.outage_{threshold_name(x)}']:.2f}"
                    for x in meta["outage_thresholds_m"]
                )
                parts.append(f"{m} {o}")
            thr = "/".join(f"{x:g}" for x in meta["outage_thresholds_m"])
            out.append(f"{tok} k={k} outage P(e > {thr} m): " + "; ".join(parts))
        if sizes := meta.get("memory_agents"):
            first = next(iter(meta["scenarios"]))
            mem = "; ".join(
                f"{m} " + "/".join(f"{f[f'{m}.{first}.agents_{n}.run_rss_mb']:.3g}" for n in sizes)
                for m in meta["methods"]
            )
            if tok == first:
                agents = "/".join(str(n) for n in sizes)
                out.append(f"{tok}: memory of one run [MB] at {agents} agents: {mem}")
        if (key := f"sirbp_over_pfbp.{tok}.step_ratio") in f:
            out.append(f"{tok}: SIR-BP / PF-BP time per step = {f[key]:.3g}")
        if (key := f"sage.{tok}.range_rmse_m") in f:
            out.append(
                f"{tok}: SAGE range RMSE {f[key]:.3g} m over valid links "
                f"({100 * f[f'sage.{tok}.valid_fraction']:.0f} % valid), "
                f"σ given to the trackers {f[f'sage.{tok}.sigma_m']:.3g} m"
            )
    return out


def _cell(x) -> str:
    """A figure or a ``with_interval`` cell as text."""
    return x if isinstance(x, str) else f"{x:.3g}"


def error_bars(ax, x, figures: dict, names, color) -> bool:
    """Error bars of the 95 % intervals of the figures ``names`` (one per ``x``) at their
    values; returns whether there was one to draw (runs of a single unit have none)."""
    val = np.array([figures.get(n, np.nan) for n in names], dtype=float)
    lo = np.array([figures.get(n + ".ci_low", np.nan) for n in names], dtype=float)
    hi = np.array([figures.get(n + ".ci_high", np.nan) for n in names], dtype=float)
    ok = np.isfinite(val) & np.isfinite(lo) & np.isfinite(hi)
    if not ok.any():
        return False
    yerr = np.maximum([val[ok] - lo[ok], hi[ok] - val[ok]], 0.0)
    x = np.asarray(x, dtype=float)[ok]
    ax.errorbar(x, val[ok], yerr=yerr, fmt="none", ecolor=color, capsize=2, lw=0.8)
    return True


def _plot_example(fig, ax, ser, tok) -> None:
    """PF-BP Fig. 3: the first run's true trajectories (x–y), each point coloured by the number
    of anchors the agent ranges to at that step; anchors black, start points red."""
    pos = np.asarray(ser[f"{tok}.example_positions_m"])
    links = np.asarray(ser[f"{tok}.example_anchor_links"])
    anchors = np.asarray(ser[f"{tok}.anchors_m"])
    sc = ax.scatter(pos[..., 0].ravel(), pos[..., 1].ravel(), c=links.ravel(), s=4, cmap="viridis")
    ax.plot(pos[0, :, 0], pos[0, :, 1], "rd", ms=4, label="start")
    ax.plot(anchors[:, 0], anchors[:, 1], "ks", ms=5, label="anchors")
    fig.colorbar(sc, ax=ax, label="anchor connections")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{tok}: run 1, true trajectories", fontsize=9)
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=6)


def plot(results: dict, path) -> None:
    """RMSE of p, v, a versus k with the PCRLB (Fig. 4, 7) and outage curves (Fig. 6), per
    scenario (columns), from results only; error bars: the 95 % intervals over runs of the
    figures at the report steps and outage thresholds."""
    f, ser, meta = results["figures"], results["series"], results["meta"]
    toks = list(meta["scenarios"])
    blocks = meta["blocks"]
    n_rows = len(blocks) + 2
    fig, axes = new_figure(n_rows, len(toks), squeeze=False, size=(4.8 * len(toks), 3.0 * n_rows))
    k = ser["k"]
    ylabel = {"p": "RMSE_p [m]", "v": "RMSE_v [m/s]", "a": "RMSE_a [m/s²]"}
    for j, tok in enumerate(toks):
        for r, b in enumerate(blocks):
            ax = axes[r, j]
            for i, m in enumerate(meta["methods"]):
                reg = meta["options"].get(m, {}).get("regularize", False)  # "reg": dashed
                ax.semilogy(
                    k, ser[f"{m}.{tok}.rmse_{UNITS[b]}"], "--" if reg else "-", color=f"C{i}",
                    label=m,
                )  # fmt: skip
                steps = meta["report_steps"]
                names = [f"{m}.{tok}.k{s}.rmse_{UNITS[b]}" for s in steps]
                error_bars(ax, steps, f, names, f"C{i}")
            ax.semilogy(k, ser[f"pcrlb.{tok}.{UNITS[b]}"], "k--", label="PCRLB")
            ax.semilogy(k, ser[f"pcrlb_cond.{tok}.{UNITS[b]}"], "k:", label="PCRLB (cond.)")
            ax.set_ylabel(ylabel[b])
            ax.set_xlabel("time step k")
            ax.grid(True, which="both", alpha=0.3)
            if r == 0:
                ax.set_title(
                    f"{tok} (r_max = {range_text(meta['scenarios'][tok]['comm_range_m'])})"
                )
                ax.legend(fontsize=7)
        ax = axes[-2, j]
        styles = ("-", "--", ":", "-.")
        for i, m in enumerate(meta["methods"]):
            for ko, ls in zip(meta["outage_steps"], styles, strict=False):
                ax.semilogx(
                    ser["outage_threshold_m"],
                    ser[f"{m}.{tok}.k{ko}.outage"],
                    ls,
                    color=f"C{i}",
                    label=f"{m} k={ko}",
                )
                thr = meta["outage_thresholds_m"]
                names = [f"{m}.{tok}.k{ko}.outage_{threshold_name(x)}" for x in thr]
                error_bars(ax, thr, f, names, f"C{i}")
        ax.set_xlabel("position error threshold [m]")
        ax.set_ylabel("outage probability")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, ncol=2)
        _plot_example(fig, axes[-1, j], ser, tok)
    fast = " (fast)" if meta.get("fast") else ""
    sep = "\n" if len(toks) == 1 else " — "  # one column: the title on two lines
    bars = "\n(bars: 95 % intervals over runs)"
    fig.suptitle(f"Cooperative tracking vs PCRLB{sep}{meta['recipe']}{fast}{bars}")
    save_figure(fig, path)
    if "memory_agents" in ser:
        _plot_memory(results, Path(path).with_name(f"{Path(path).stem}_memory.png"))
    if "flow_example.paths" in ser:
        _plot_flow(results, Path(path).with_name(f"{Path(path).stem}_flow.png"))
    if any(".stage." in name for name in f):
        _plot_stages(results, Path(path).with_name(f"{Path(path).stem}_stages.png"))


def _plot_stages(results: dict, path) -> None:
    """Time per step of each method split by stage (PF-BP Tables I, II by stage): one stacked
    bar per method and scenario, the stages of :data:`~phyloc.localization.tracking.loop.STAGES`
    in the order of a step."""
    from phyloc.localization.tracking.loop import STAGES

    f, meta = results["figures"], results["meta"]
    toks, methods = list(meta["scenarios"]), meta["methods"]
    fig, axes = new_figure(
        len(toks), 1, squeeze=False, size=(7.0, 0.5 + (0.35 * len(methods) + 0.8) * len(toks))
    )
    for j, tok in enumerate(toks):
        ax = axes[j, 0]
        left = np.zeros(len(methods))
        for c, stage in enumerate(STAGES):
            width = np.array([f.get(f"{m}.{tok}.stage.{stage}_s", 0.0) for m in methods])
            if np.any(width > 0):
                ax.barh(methods, width, left=left, color=f"C{c}", label=stage)
                left += width
        ax.invert_yaxis()
        ax.set_xlabel("time per step [s] (each run's median step, mean over runs)")
        r = range_text(meta["scenarios"][tok]["comm_range_m"])
        ax.set_title(f"{meta['recipe']}: {tok} (r_max = {r}), time per step by stage", fontsize=9)
        ax.grid(True, axis="x", alpha=0.3)
        ax.legend(fontsize=6, loc="center left", bbox_to_anchor=(1.0, 0.5))
    save_figure(fig, path)


def _plot_flow(results: dict, path) -> None:
    """PF-BP Fig. 1: particle paths of the flow (dash-dotted) over each agent's anchor
    likelihood (colour map: two ring crossings each), anchors and their links."""
    ser = results["series"]
    g = np.asarray(ser["flow_example.grid_m"])
    maps = np.asarray(ser["flow_example.anchor_loglik"])
    paths = np.asarray(ser["flow_example.paths"])  # [λ-steps + 1, M, agent, xy]
    anchors = np.asarray(ser["flow_example.anchors"])
    truth = np.asarray(ser["flow_example.truth"])
    fig, ax = new_figure(size=(5.6, 5.0))
    dens = np.exp(maps - maps.max(axis=(1, 2), keepdims=True)).sum(axis=0)
    ax.pcolormesh(g, g, dens.T, cmap="viridis", shading="auto")
    for a, k in np.asarray(ser["flow_example.links"]):
        other = anchors[k] if k < 3 else truth[1]
        ax.plot(*np.stack([truth[a], other]).T, color="0.6", lw=0.8, zorder=1)
    for agent in range(2):
        for m in range(paths.shape[1]):
            ax.plot(*paths[:, m, agent].T, "-.", color="limegreen", lw=0.6, zorder=2)
        ax.plot(*paths[0, :, agent].T, ".", color="white", ms=3, zorder=3)
        ax.plot(*paths[-1, :, agent].T, ".", color="red", ms=3, zorder=4)
    ax.plot(*anchors.T, "o", color="0.7", mec="k", ms=9, label="anchors", zorder=5)
    ax.plot(*truth.T, "x", color="k", ms=9, mew=2, label="agents (truth)", zorder=6)
    ax.set_xlim(g[0], g[-1])
    ax.set_ylim(g[0], g[-1])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title(
        "PF-BP Fig. 1: particle flow of two cooperating agents\n"
        "(white: prior particles, red: after the flow; colour: anchor likelihood)",
        fontsize=8,
    )
    save_figure(fig, path)


def _plot_memory(results: dict, path) -> None:
    """Peak RSS added by each method's run versus the number of agents (the memory study)."""
    fig_, ser, meta = results["figures"], results["series"], results["meta"]
    first = next(iter(meta["scenarios"]))
    n = ser["memory_agents"]
    fig, ax = new_figure(size=(5.5, 4.0))
    for i, m in enumerate(meta["methods"]):
        name = [f"{m}.{first}.agents_{a}.run_rss_mb" for a in n]
        run = np.maximum([fig_[k] for k in name], 0.1)
        ax.loglog(n, run, "o-", color=f"C{i}", label=m)
        lo, hi = (
            np.array([fig_.get(k + end) for k in name], dtype=float)  # None (JSON null): NaN
            for end in (".ci_low", ".ci_high")
        )
        if np.any(np.isfinite(lo) & np.isfinite(hi)):  # repeated measurements: 95 % intervals
            err = [run - np.maximum(lo, 0.1), np.maximum(hi, 0.1) - run]
            ax.errorbar(n, run, yerr=np.nan_to_num(err), fmt="none", ecolor=f"C{i}", capsize=3)
    ax.set_xlabel("number of agents")
    ax.set_ylabel("memory of one run [MB] (peak RSS added)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    r = range_text(meta["scenarios"][first]["comm_range_m"])
    ax.set_title(f"{meta['recipe']}: memory vs network size (r_max = {r})", fontsize=9)
    save_figure(fig, path)

"""Pooling the per-realization outputs of the localization experiment
(:mod:`phyloc.evaluation.localization_experiment`, DiPNet Fig. 5 and the dense networks) into
its figures and series: framework and position errors with their intervals, error CDFs and
their 50/80/90 % points, outliers, observability, link biases, belief calibration, times and
their fitted cost exponents, and the paired comparisons. The figure names are documented in
:mod:`phyloc.evaluation.localization_experiment`.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import math

import numpy as np

from phyloc.evaluation.localization_figures import INITS
from phyloc.evaluation.statistics import Paired, Pooled, Quantile
from phyloc.localization import METHODS as REGISTRY

#: Error grid of the stored CDFs [m].
CDF_GRID_M = np.linspace(0.0, 30.0, 301)
#: A pair's absolute framework distance error above this is an outlier [m] (DiPNet §V-A
#: speaks of outliers beside "the sub-meter error range" of its Fig. 5 CDFs).
OUTLIER_M = 1.0

_CHI2_MEDIAN = {1: 0.454936423119573, 2: 2.0 * math.log(2.0), 3: 2.365973884375338}
"""Median of the χ² distribution with 1, 2, 3 degrees of freedom (NEES of a calibrated belief)."""


def aggregate(keys, results, exp, tokens):
    """Pool the per-realization outputs (keyed ``(token, n_agents, realization)``)."""
    figures: dict[str, float] = {}
    series: dict[str, object] = {"cdf_grid_m": CDF_GRID_M}
    n_max = max(exp.agents)
    for tok in tokens:
        parts = [res for (t, _, _), res in zip(keys, results, strict=True) if t == tok]
        figures[f"{tok}.los_fraction"] = Pooled.fraction([p["los"] for p in parts])
        for cond, want in (("los", True), ("nlos", False)):
            figures[f"{tok}.link_bias.{cond}_mean_m"] = Pooled.mean(
                [p["link_err_corr"][p["link_valid_corr"] & (p["los"] == want)] for p in parts]
            )
        for n in exp.agents:
            runs = [r for (t, nn, _), r in zip(keys, results, strict=True) if t == tok and nn == n]
            if _observable(runs) is not None:
                # pairs of one realization are not independent: bootstrap over realizations
                figures[f"{tok}.agents_{n}.unobservable_pair_fraction"] = Pooled.mean(
                    [~r["observable"] for r in runs]
                )
            if "neighbours" in runs[0]:
                figures[f"{tok}.agents_{n}.mean_neighbours"] = float(
                    np.mean([r["neighbours"] for r in runs])
                )
            for stage in runs[0].get("stage_s", {}):
                figures[f"{tok}.agents_{n}.{stage}_s"] = float(
                    np.mean([r["stage_s"][stage] for r in runs])
                )
            if "peak_rss_mb" in runs[0]:
                figures[f"{tok}.agents_{n}.peak_rss_mb"] = float(
                    max(r["peak_rss_mb"] for r in runs)
                )
        for init in exp.inits:
            tag = tok + INITS[init]
            for n in exp.agents:
                runs = [
                    r for (t, nn, _), r in zip(keys, results, strict=True) if t == tok and nn == n
                ]
                start = Pooled.rmse([r.get(f"start|{init}|err", np.full(0, np.nan)) for r in runs])
                figures[f"start.{tag}.agents_{n}.framework_rmse_m"] = start
                if all(f"start|{init}|pos_err" in r for r in runs):
                    figures[f"start.{tag}.agents_{n}.position_rmse_m"] = Pooled.rmse(
                        [r[f"start|{init}|pos_err"] for r in runs]
                    )
                und = [r.get(f"start|{init}|undetermined") for r in runs]
                if und and all(u is not None for u in und):
                    figures[f"start.{tag}.agents_{n}.undetermined_agent_fraction"] = Pooled.mean(
                        und
                    )
            for m in exp.methods:
                key = f"{m}|{init}"
                for n in exp.agents:
                    runs = [
                        res
                        for (t, nn, _), res in zip(keys, results, strict=True)
                        if t == tok and nn == n
                    ]
                    err = np.concatenate([r[key + "|err"] for r in runs])
                    obs = _observable(runs)
                    base = f"{m}.{tag}.agents_{n}"
                    figures[base + ".framework_rmse_m"] = Pooled.rmse(
                        [r[key + "|err"] for r in runs]
                    )
                    if key + "|pos_err" in runs[0]:  # anchors: absolute position errors
                        figures[base + ".position_rmse_m"] = Pooled.rmse(
                            [r[key + "|pos_err"] for r in runs]
                        )
                        figures.update(_error_points(runs, key, base))
                        pos = np.concatenate([r[key + "|pos_err"] for r in runs])
                        series[base + ".position_error_cdf"] = np.searchsorted(
                            np.sort(pos), CDF_GRID_M, side="right"
                        ) / max(pos.size, 1)
                        if n == max(exp.agents) and runs[0].get("map_truth") is not None:
                            # the map panel: the first realization's first snapshot
                            series[base + ".map_estimates"] = np.round(
                                runs[0][key + "|estimates"][0], 3
                            )
                            series[f"{tok}.agents_{n}.map_truth"] = np.round(
                                runs[0]["map_truth"], 3
                            )
                            series[f"{tok}.agents_{n}.map_is_anchor"] = runs[0]["map_is_anchor"]
                    figures[base + ".outlier_fraction"] = Pooled.mean(
                        [np.abs(r[key + "|err"]) > OUTLIER_M for r in runs]
                    )
                    if obs is not None:
                        figures[base + ".framework_rmse_observable_m"] = Pooled.rmse(
                            [r[key + "|err"][r["observable"]] for r in runs]
                        )
                    if key + "|iteration_s" in runs[0]:
                        figures[base + ".iteration_s"] = float(
                            np.mean([r[key + "|iteration_s"] for r in runs])
                        )
                        figures[base + ".chain_s"] = float(
                            np.mean([_chain_s(r, m, init) for r in runs])
                        )
                    dim = runs[0]["dim"]
                    nees = np.concatenate([r[key + "|nees"] for r in runs])
                    nees = nees[np.isfinite(nees)]
                    figures[base + ".nees"] = Pooled.mean([r[key + "|nees"] for r in runs])
                    figures[base + ".error_to_belief_ratio"] = (
                        float(math.sqrt(nees.mean() / dim)) if nees.size else float("nan")
                    )
                    figures[base + ".error_to_belief_ratio_median"] = (
                        float(math.sqrt(np.median(nees) / _CHI2_MEDIAN[dim]))
                        if nees.size
                        else float("nan")
                    )
                    figures[base + ".shape_difference_m"] = Pooled.rmse(
                        [r[key + "|shape"] for r in runs]
                    )
                    figures[base + ".ess_min"] = float(np.mean([r[key + "|ess_min"] for r in runs]))
                    figures[base + ".agent_snapshot_s"] = float(
                        np.mean([r[key + "|agent_snapshot_s"] for r in runs])
                    )
                    rmse_t = np.array([r[key + "|rmse_t"] for r in runs])
                    if rmse_t.shape[1] > 1:  # tracking: RMSE per snapshot over realizations
                        series[base + ".rmse_by_snapshot"] = np.sqrt(np.mean(rmse_t**2, axis=0))
                    if n in exp.cdf_agents:
                        series[base + ".error_cdf"] = (
                            np.searchsorted(np.sort(err), CDF_GRID_M, side="right") / err.size
                        )
                    if n == n_max:
                        for what in ("ess", "published_std", "actual_err"):
                            series[f"{base}.{what}_by_iteration"] = np.mean(
                                [r[f"{key}|{what}"] for r in runs], axis=0
                            )
            _comparisons(figures, exp.methods, tag, exp.agents)
        for m in exp.methods:
            figures[f"{m}.runtime_per_agent_iteration_s"] = float(
                np.mean([r[f"{m}|{i}|sec_per_agent_it"] for r in results for i in exp.inits])
            )
            # Numba compilation (or cache loading) during the runs, left out of the runtimes
            figures[f"{m}.jit_compile_s"] = float(
                np.sum([r.get(f"{m}|{i}|jit_s", 0.0) for r in results for i in exp.inits])
            )
            for init in exp.inits:
                tag = tok + INITS[init]
                fit = cost_exponent(
                    exp.agents,
                    [figures.get(f"{m}.{tag}.agents_{n}.iteration_s") for n in exp.agents],
                )
                if fit is not None:
                    figures[f"{m}.{tag}.iteration_s_exponent"] = fit
                links = [
                    figures.get(f"{tok}.agents_{n}.mean_neighbours", math.nan) * n
                    for n in exp.agents
                ]
                fit = cost_exponent(
                    links,
                    [figures.get(f"{m}.{tag}.agents_{n}.iteration_s") for n in exp.agents],
                )
                if fit is not None:  # 1: linear in the links (the neighbourhoods grow at the
                    figures[f"{m}.{tag}.iteration_s_link_exponent"] = fit  # border)
    return figures, series


def _comparisons(figures, methods, tag, agents):
    """Paired ratios of ``framework_rmse_m`` over the same realizations: every method against
    the start it ran from (``<m>_vs_start``) and the first method against every other
    (``<first>_vs_<m>``); a ratio below 1 favours the method named first."""
    for n in agents:
        fig = f"{tag}.agents_{n}.framework_rmse_m"
        start = figures.get(f"start.{fig}")
        for m in methods:
            if isinstance(start, Pooled) and start.den.sum() > 0:
                figures[f"{m}_vs_start.{fig}"] = Paired(figures[f"{m}.{fig}"], start)
            if m != methods[0]:
                figures[f"{methods[0]}_vs_{m}.{fig}"] = Paired(
                    figures[f"{methods[0]}.{fig}"], figures[f"{m}.{fig}"]
                )


def _chain_s(run, label, init) -> float:
    """Wall time of one method's whole chain on one realization [s]: waveforms, tables, the
    correlation-peak ranges (the truth-free start reads them), the start, the ranges of the
    method's own estimator (two-step methods) and the method itself."""
    stage = run["stage_s"]
    inputs = REGISTRY[run["methods"][label]].inputs if "methods" in run else "tables"
    own = inputs.split(":", 1)[1] if inputs.startswith("ranges:") else None
    total = sum(stage.get(k, 0.0) for k in ("waveforms", "tables", "ranging_corr"))
    total += stage.get(f"start_{init}", 0.0) + run[f"{label}|{init}|wall_s"]
    if own is not None and own != "corr":
        total += stage.get(f"ranging_{own}", 0.0)
    return total


#: The points of an absolute error CDF reported with intervals (3GPP positioning: 50/80/90 %).
ERROR_POINTS = (50, 80, 90)


def _error_points(runs, key, base) -> dict:
    """With anchors: the 50/80/90 % points of the position errors and, in 3-D, the
    horizontal RMSE and points (:class:`~phyloc.evaluation.statistics.Quantile`, a unit per
    realization)."""
    out = {}
    for tag, suffix in (("position", "|pos_err"), ("horizontal", "|hpos_err")):
        if key + suffix not in runs[0]:
            continue
        errs = [r[key + suffix] for r in runs]
        if tag == "horizontal":
            out[base + ".horizontal_rmse_m"] = Pooled.rmse(errs)
        for q in ERROR_POINTS:
            out[f"{base}.{tag}_error_p{q}_m"] = Quantile(errs, q / 100.0)
    return out


def _observable(runs):
    """The observable-pair flags of ``runs`` pooled, or None when a run left them out
    (range-limited networks above :data:`~phyloc.evaluation.front_end.RIGIDITY_MAX_NODES`)."""
    if any(r["observable"] is None for r in runs):
        return None
    return np.concatenate([r["observable"] for r in runs])


def cost_exponent(sizes, seconds):
    """The exponent ``b`` of ``seconds ≈ a · sizes^b``, least squares in log–log over the sizes
    with a positive time; None with fewer than two such sizes.

    >>> round(cost_exponent([30, 100, 300], [0.3, 1.0, 3.0]), 6)
    1.0
    """
    pts = [
        (math.log(n), math.log(t))
        for n, t in zip(sizes, seconds, strict=True)
        if t is not None and t > 0 and n > 0
    ]
    if len({x for x, _ in pts}) < 2:
        return None
    x, y = np.array(pts).T
    return float(np.polyfit(x, y, 1)[0])


__all__ = ["CDF_GRID_M", "ERROR_POINTS", "OUTLIER_M", "aggregate", "cost_exponent"]

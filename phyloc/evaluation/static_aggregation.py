"""Pooling the per-topology outputs of the static experiment
(:mod:`phyloc.evaluation.static_experiment`, POA-NBP Figs. 9–12, Table I) into its figures and
series: errors and outage per iteration, polygon areas, the convergence rule of the paper's
footnote 5, overhead, times, the sample sweep and the paired comparisons. The figure names
are documented in :mod:`phyloc.evaluation.static_experiment`.

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import dataclasses

import numpy as np

from phyloc.evaluation.static_figures import reference_method, threshold_name
from phyloc.evaluation.statistics import Paired, Pooled
from phyloc.localization import METHODS as REGISTRY

#: Error thresholds [m] of the stored outage curves.
OUTAGE_GRID_M = np.logspace(-2, 1.7, 149)
#: The communication-overhead diagnostics a static method reports.
OVERHEAD = (
    "floats_per_link_iteration",
    "operations_per_node",
    "support_floats_per_link_iteration",
)


def overhead_of(res) -> dict:
    """A method result's :data:`OVERHEAD` diagnostics (NaN where it reports none)."""
    return {k: float(res.diagnostics.get(k, np.nan)) for k in OVERHEAD}


def _overhead_figures(figures, base, parts) -> None:
    """Mean over topologies of each overhead diagnostic, as ``<base>.<name>`` (NaN: none;
    an existing figure is kept), pooled over the topologies (a topology without the
    diagnostic contributes nothing)."""
    for k in OVERHEAD:
        vals = np.array([p[k] for p in parts], dtype=np.float64)
        if vals.size and not np.all(np.isnan(vals)):
            figures.setdefault(
                f"{base}.{k}", _as_computed(Pooled.mean(list(vals)), np.nanmean(vals))
            )


def convergence_from_curve(curve, rel: float, abs_m: float) -> int:
    """Iterations to convergence by the paper's rule (§V footnote 5): ``l − 1`` for the first
    ``l >= 2`` (1-based) with ``|e_l − e_{l−1}| <= max(rel·e_{l−1}, abs_m)``; ``len(curve)``
    when the curve never stops changing notably."""
    c = np.asarray(curve, dtype=np.float64)
    for it in range(1, c.size):
        if abs(c[it] - c[it - 1]) <= max(rel * abs(c[it - 1]), abs_m):
            return it
    return int(c.size)


def settling_from_curve(curve, rel: float, abs_m: float) -> int:
    """1-based first iteration from which ``curve`` stays within ``max(rel·curve[-1], abs_m)``
    of its last value (a stricter reading of convergence)."""
    c = np.asarray(curve, dtype=np.float64)
    band = max(rel * abs(c[-1]), abs_m)
    outside = np.flatnonzero(np.abs(c - c[-1]) > band)
    return int(outside[-1]) + 2 if outside.size else 1


def aggregate(results, exp, names=None):
    """Pool the per-topology outputs: a figure pooled over topologies is a
    :class:`~phyloc.evaluation.statistics.Pooled` value (its interval resamples topologies;
    :func:`_comparisons` adds the paired ratios), so are the convergence iteration and the wall
    times (one value per topology); the readings of the pooled curve are plain. ``names``:
    ``{label: registered method}`` (default: every label is its method)."""
    names = names or {}
    figures: dict[str, object] = {}
    series: dict[str, object] = {
        "iteration": np.arange(1, exp.n_iterations + 1),
        "poa_iteration": np.arange(1, exp.poa_iterations + 1),
        "outage_threshold_m": OUTAGE_GRID_M,
    }
    for ne in exp.n_edges:
        areas = [r[f"poa|{ne}|area"] for r in results]  # per topology [L, agents]
        mean_area = _finite_mean(np.concatenate(areas, axis=1))  # [L] over topo·agents
        series[f"poa.ne{ne}.area_m2"] = mean_area
        for it in range(exp.poa_iterations):
            figures[f"poa.ne{ne}.area_it{it + 1}_m2"] = _as_computed(
                Pooled.mean([a[it] for a in areas]), mean_area[it]
            )
        figures[f"poa.ne{ne}.containment_fraction"] = Pooled.fraction(
            [r[f"poa|{ne}|contained"] for r in results]
        )
        figures[f"poa.ne{ne}.operations_per_node"] = _as_computed(
            Pooled.mean([r[f"poa|{ne}|ops"] for r in results]),
            np.mean([r[f"poa|{ne}|ops"] for r in results]),
        )
        fl = np.array([r[f"poa|{ne}|floats"] for r in results], dtype=np.float64)
        if not np.all(np.isnan(fl)):  # NaN: no broadcast (poa_iterations = 1)
            figures[f"poa.ne{ne}.floats_per_link_iteration"] = _as_computed(
                Pooled.mean(list(fl)), np.nanmean(fl)
            )
    for e in ("ellipse", "ellipse_paper") if exp.ellipses else ():
        if e == "ellipse_paper" and any(f"{e}|area" not in r for r in results):
            continue  # topologies stored before the bounding discs (a resumed run)
        areas = [r[f"{e}|area"] for r in results]
        mean_area = _finite_mean(np.concatenate(areas, axis=1))
        series[f"{e}.area_m2"] = mean_area
        for it in range(exp.poa_iterations):
            figures[f"{e}.area_it{it + 1}_m2"] = _as_computed(
                Pooled.mean([a[it] for a in areas]), mean_area[it]
            )
    figures["poa.containment_fraction"] = Pooled.fraction([r["poa|contained"] for r in results])
    figures["poa.time_per_node_s"] = _per_topology([r["poa|time_per_node_s"] for r in results])
    accept = [r["poa|acceptance"] for r in results]
    figures["poa.rejection_acceptance_rate"] = _as_computed(
        _mean_units(accept), np.mean(np.concatenate(accept))
    )
    dropped = sum(r["poa|dropped"][0] for r in results)
    n_meas = sum(r["poa|dropped"][1] for r in results)
    figures["poa.dropped_fraction"] = (
        Pooled(
            [r["poa|dropped"][0] for r in results],
            [r["poa|dropped"][1] for r in results],
            "fraction",
        )
        if n_meas > 0
        else dropped / max(n_meas, 1)
    )
    for m in exp.methods:
        errs = [r[f"{m}|err"][-1] for r in results]  # per topology: errors after convergence
        err = np.concatenate([r[f"{m}|err"] for r in results], axis=1)  # [n_iter, topo·agents]
        curve = err.mean(axis=1)
        series[f"{m}.mean_error_m"] = curve
        final = err[-1]
        figures[f"{m}.mean_error_m"] = _as_computed(_mean_units(errs), final.mean())
        for it in range(exp.n_iterations):  # Fig. 10 per iteration, with units (ratios)
            figures[f"{m}.mean_error_it{it + 1}_m"] = _as_computed(
                _mean_units([r[f"{m}|err"][it] for r in results]), curve[it]
            )
        figures[f"{m}.rmse_m"] = _as_computed(Pooled.rmse(errs), np.sqrt(np.mean(final**2)))
        # per topology: the paper's rule on its own mean-error curve, its times
        conv = [
            float(convergence_from_curve(e, exp.convergence_rel, exp.convergence_abs_m))
            for e in (r[f"{m}|err"].mean(axis=1) for r in results)
        ]
        t_it = [r[f"{m}|time"] for r in results]
        t_sup = [r[f"{m}|t_support"] for r in results]
        figures[f"{m}.convergence_iteration"] = _per_topology(conv)
        figures[f"{m}.curve_convergence_iteration"] = float(
            convergence_from_curve(curve, exp.convergence_rel, exp.convergence_abs_m)
        )
        figures[f"{m}.settling_iteration"] = float(
            settling_from_curve(curve, exp.convergence_rel, exp.convergence_abs_m)
        )
        figures[f"{m}.time_per_node_iteration_s"] = _per_topology(t_it)
        figures[f"{m}.time_to_convergence_s"] = _per_topology(
            [c * t + u for c, t, u in zip(conv, t_it, t_sup, strict=True)]
        )
        if "start" in {
            f.name for f in dataclasses.fields(REGISTRY[names.get(m, m)].options)
        }:  # pbp, wls: the start alone
            figures[f"{m}.start_time_per_node_s"] = _per_topology(t_sup)
        series[f"{m}.outage"] = np.mean(final[:, None] > OUTAGE_GRID_M, axis=0)
        for x in exp.outage_thresholds_m:
            figures[f"{m}.outage_{threshold_name(x)}"] = Pooled.fraction([e > x for e in errs])
        _overhead_figures(figures, f"{m}.ns{exp.n_samples}", [r[f"{m}|overhead"] for r in results])
    for m in exp.sample_methods:
        for ns in exp.sample_sweep:
            swept = [r for r in results if f"{m}|ns{ns}|err" in r]  # sample_sweep_topologies
            errs = [r[f"{m}|ns{ns}|err"] for r in swept]
            e = np.concatenate(errs)
            base = f"{m}.ns{ns}"
            figures[f"{base}.topologies"] = float(len(swept))
            figures[f"{base}.mean_error_m"] = _as_computed(_mean_units(errs), e.mean())
            figures[f"{base}.time_per_node_iteration_s"] = _per_topology(
                [r[f"{m}|ns{ns}|time"] for r in swept]
            )
            series[f"{base}.outage"] = np.mean(e[:, None] > OUTAGE_GRID_M, axis=0)
            for x in exp.outage_thresholds_m:
                figures[f"{base}.outage_{threshold_name(x)}"] = Pooled.fraction(
                    [ei > x for ei in errs]
                )
            _overhead_figures(figures, base, [r[f"{m}|ns{ns}|overhead"] for r in swept])
    _sweep_references(figures, series, results, exp)
    if "poa_nbp" in exp.methods:  # POA-NBP Table I: POA-NBP against the other NBP variants
        for m in exp.methods:
            nbp = REGISTRY[names.get(m, m)].options is REGISTRY["poa_nbp"].options
            if m != "poa_nbp" and nbp:
                figures[f"poa_nbp_vs_{m}.time_to_convergence_ratio"] = (
                    figures["poa_nbp.time_to_convergence_s"].value
                    / figures[f"{m}.time_to_convergence_s"].value
                )
    _comparisons(figures, exp)
    return figures, series


#: Methods of the comparison (step 2) whose accuracy figures are also given over the sample
#: sweep's topologies only, as ``<m>.sweep.*`` (:func:`_sweep_references`): PBP, the reference
#: curve of POA-NBP Fig. 12, which the sweep does not run.
SWEEP_REFERENCES = ("pbp",)


def _sweep_references(figures, series, results, exp) -> None:
    """The figures of every method of :data:`SWEEP_REFERENCES` that runs, restricted to the
    topologies of the sample sweep (the first ``exp.sweep_topologies``; none when the sweep
    does not run): ``<m>.sweep.topologies``, ``<m>.sweep.mean_error_m``,
    ``<m>.sweep.outage_<x>m`` (units: those topologies, as the sweep's figures) and the
    series ``<m>.sweep.outage``."""
    if not (exp.sample_methods and exp.sample_sweep):
        return
    swept = results[: exp.sweep_topologies]  # task i is topology i (StaticExperiment.tasks)
    for m in (m for m in SWEEP_REFERENCES if m in exp.methods):
        errs = [r[f"{m}|err"][-1] for r in swept]  # after convergence
        e = np.concatenate(errs)
        base = f"{m}.sweep"
        figures[f"{base}.topologies"] = float(len(swept))
        figures[f"{base}.mean_error_m"] = _as_computed(_mean_units(errs), e.mean())
        series[f"{base}.outage"] = np.mean(e[:, None] > OUTAGE_GRID_M, axis=0)
        for x in exp.outage_thresholds_m:
            figures[f"{base}.outage_{threshold_name(x)}"] = Pooled.fraction([ei > x for ei in errs])


#: The figures of a method compared by a paired ratio (:func:`_comparisons`), besides the
#: outages ``outage_<x>m``.
COMPARED = ("mean_error_m", "rmse_m")


def _comparisons(figures, exp) -> None:
    """Paired ratios over the same topologies (every method runs on the same ranges):
    :func:`~phyloc.evaluation.static_figures.reference_method` ``a`` against every other
    method ``m``, ``<a>_vs_<m>.mean_error_m``, ``.rmse_m`` and ``.outage_<x>m``; in the sample
    sweep the first of ``sample_methods`` against the others at every ``N_S``,
    ``<a>_vs_<m>.ns<n>.mean_error_m`` and ``.ns<n>.outage_<x>m``, and against the
    ``<m>.sweep`` figures of :data:`SWEEP_REFERENCES` (PBP, the same at every ``N_S``) under
    the same names. A ratio below 1 favours ``a``; there is none where ``m``'s figure is 0
    (an outage no agent had)."""
    outages = [f"outage_{threshold_name(x)}" for x in exp.outage_thresholds_m]
    a = reference_method(exp.methods)
    pairs = [
        (f"{a}_vs_{m}", f"{a}.{q}", f"{m}.{q}", q)
        for m in exp.methods
        if m != a
        for q in (*COMPARED, *outages)
    ]
    a, *others = exp.sample_methods or ("",)
    pairs += [
        (f"{a}_vs_{m}", f"{a}.ns{ns}.{q}", f"{m}.ns{ns}.{q}", f"ns{ns}.{q}")
        for m in others
        for ns in exp.sample_sweep
        for q in ("mean_error_m", *outages)
    ]
    pairs += [  # the sweep against PBP (Fig. 12's reference) over the sweep's topologies
        (f"{a}_vs_{m}", f"{a}.ns{ns}.{q}", f"{m}.sweep.{q}", f"ns{ns}.{q}")
        for m in SWEEP_REFERENCES
        if f"{m}.sweep.mean_error_m" in figures
        for ns in exp.sample_sweep
        for q in ("mean_error_m", *outages)
    ]
    for head, x, y, q in pairs:
        if figures[y].value != 0:
            figures[f"{head}.{q}"] = Paired(figures[x], figures[y])


def _mean_units(arrays) -> Pooled:
    """The mean of every value of ``arrays`` (one per topology) as a ``"mean"``
    :class:`Pooled` figure; unlike :meth:`Pooled.mean` a NaN is kept (the figure is NaN, as
    the mean of the pooled values was)."""
    arrs = [np.asarray(a, dtype=np.float64).ravel() for a in arrays]
    return Pooled([float(np.sum(a)) for a in arrs], [a.size for a in arrs], "mean")


def _per_topology(values) -> Pooled:
    """One number per topology (an iteration count, a wall time) as a ``"mean"``
    :class:`Pooled` figure: their mean over topologies (a NaN kept, as :func:`_mean_units`),
    its point value that of :func:`numpy.mean`."""
    vals = np.asarray(values, dtype=np.float64)
    return _as_computed(_mean_units(list(vals)), np.mean(vals))


def _as_computed(p: Pooled, value) -> Pooled:
    """``p`` with the point value computed from all the values at once, so that it stays bit
    for bit what it was (:meth:`~phyloc.evaluation.statistics.Pooled.at`)."""
    return p.at(value)


def _finite_mean(area):
    """Mean over agents of the finite areas per iteration (unbounded agents excluded)."""
    fin = np.isfinite(area)
    n = fin.sum(axis=1)
    return np.where(n > 0, np.where(fin, area, 0.0).sum(axis=1) / np.maximum(n, 1), np.nan)


__all__ = [
    "OUTAGE_GRID_M",
    "OVERHEAD",
    "aggregate",
    "convergence_from_curve",
    "overhead_of",
    "settling_from_curve",
]

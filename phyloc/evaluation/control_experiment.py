"""Mobile-anchor control: track loss and MSE of FIM-controlled anchors against baselines.

A recipe of ``kind = "control"`` runs ``experiment.trials`` Monte Carlo trials of the closed
loop of :mod:`phyloc.control.loop` for every policy of ``experiment.policies``: the scenario is
the ``[network]`` section (:class:`~phyloc.control.ControlScenario`; defaults: the FIM paper's
case study), the estimation layer ``experiment.estimator = "spbp" | "pfbp"`` with that
tracker's options in ``[localization.<estimator>]``. ``[experiment.variants.<label>]`` adds a
policy under its own label (``policy = "fim_rh"``, ``horizon = 5``, ``search = "vbest"``,
``beam = 10``, …). Every trial's
random stream is ``SeedSequence(seed).spawn(trials)[t]`` whatever the worker count or the
grouping of trials into tasks (``experiment.task_trials``); the policies of a trial share its
truth and noise draws.

Figures, for every policy label ``p`` (agent tracks pooled over trials and agents; a track is
*lost* when the final position error exceeds the threshold, and a diverged estimator counts
as lost)::

    p.track_loss_pct                 at experiment.track_loss_m (5 m by default)
    p.track_loss_ci_low_pct, p.track_loss_ci_high_pct   Wilson 95 % interval of it
    p.track_loss_fraction            the same as a fraction, with its exact (Clopper–Pearson)
                                     95 % interval .ci_low / .ci_high over the tracks
    p.track_loss_pct_<T>m            at every threshold of experiment.thresholds_m
    p.track_loss_fraction_<T>m       the same as a fraction, with .ci_low / .ci_high
    p.k<K>.log10_mse_mean            mean over trials of log₁₀ MSE at the last step K
                                     (MSE: mean over agents of the squared position error)
    p.late_log10_mse_mean            the same averaged over the last 10 steps
    p.decision_s                     mean controller time per decision [s]
    p.diverged_pct                   trials whose estimator diverged
    p.diverged_fraction              the same as a fraction, with .ci_low / .ci_high
    <a>_vs_<b>.track_loss_fraction.ratio   tracks lost by ``a`` over those lost by ``b`` on the
                                     same trials, with .ci_low / .ci_high (paired bootstrap
                                     over trials): every FIM-controlled label against
                                     ``static`` and ``random``, every receding-horizon label
                                     against every myopic one (:func:`comparisons`; none where
                                     ``b`` lost no track)

The ``_fraction`` figures and the two log-MSE means carry a 95 % interval, ``<name>.ci_low`` and
``<name>.ci_high`` (:mod:`phyloc.evaluation.statistics`; NaN with a single trial), and their
per-trial values in the series ``<name>.units``. Their unit is the *trial*, not the task (a
block of ``experiment.task_trials`` trials): every trial is an independent draw, and the
intervals do not depend on the grouping. The log-MSE means are resampled over trials
(bootstrap); the track-loss and divergence fractions use the exact binomial interval on the
totals (tracks of one trial treated as independent). The ``_pct`` figures keep their earlier
form (they are 100 × the fractions).

Series: ``p.log10_mse_by_step`` (FIM Fig. 5), the example trial ``experiment.example_trial``
(FIM Fig. 4): ``example.truth`` ``[K + 1, n_agents, dim]``, ``example.static``,
``p.example.mobile`` ``[K + 1, M₁, dim]``, ``p.example.estimates``.

References
----------
FIM: W. Zhang, B. Teague and F. Meyer, "Cooperative localization: a Fisher information
approach," arXiv:2212.14554, 2022.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from phyloc import _validate as v
from phyloc.control.loop import (
    ESTIMATORS,
    ControlScenario,
    draw_trial,
    make_estimator,
    run_policy,
)
from phyloc.control.policies import POLICIES, PolicySpec
from phyloc.errors import ValidationError
from phyloc.evaluation.experiment import Experiment, experiment_from_dict
from phyloc.evaluation.methods import check_labels, method_plan
from phyloc.evaluation.statistics import Paired, Pooled
from phyloc.reporting import grouped_bars, new_figure, save_figure, with_interval

#: Squared errors of a diverged estimator count as this [m²] in the log-MSE means.
DIVERGED_M2 = 1e12
LATE_STEPS = 10


@dataclass(frozen=True)
class ControlExperimentSpec:
    """``[experiment]`` of a ``control`` recipe (``[experiment.fast]`` for ``--fast``).

    Parameters
    ----------
    trials : int
        Monte Carlo trials (the paper: 10 000).
    estimator : str
        Label of the estimation layer: ``"spbp"`` (the paper) or ``"pfbp"``, or a label whose
        ``[localization.<label>]`` table names one (``method = ...``); its options are that
        table's keys (and shared ``[localization]`` keys).
    policies : list of str
        Policy labels: ``static``, ``random``, ``fim_myopic``, ``fim_rh`` or variant labels.
    variants : dict
        ``{label: {"policy": name, <PolicySpec key>: value}}``.
    fim_rh : dict
        Options of the plain ``fim_rh`` label (``horizon``, ``search``, ``discount``, ``beam``,
        ``agent_terms``); default ``horizon = 3``, exact search.
    track_loss_m : float
        Threshold of ``p.track_loss_pct`` [m].
    thresholds_m : list of float
        Thresholds of ``p.track_loss_pct_<T>m`` [m].
    example_trial : int
        The trial kept for the example figure.
    task_trials : int
        Trials per Dask task (no effect on the numbers).
    """

    trials: int = 100
    estimator: str = "spbp"
    policies: tuple = POLICIES
    variants: dict = field(default_factory=dict)
    fim_rh: dict = field(default_factory=dict)
    track_loss_m: float = 5.0
    thresholds_m: tuple = (1.0, 5.0, 20.0)
    example_trial: int = 0
    task_trials: int = 20

    def __post_init__(self):
        v.integer_field(self, "trials", "experiment.trials", minimum=1)
        if not isinstance(self.variants, dict):
            raise ValidationError("experiment.variants", self.variants, "a table of labels")
        pols = check_labels(self.policies, "experiment.policies")
        if not pols:
            raise ValidationError("experiment.policies", [], "at least one policy")
        for p in pols:
            if p not in POLICIES and p not in self.variants:
                raise ValidationError(
                    "experiment.policies", p, f"one of {', '.join(POLICIES)} or a variant label"
                )
        if len(set(pols)) != len(pols):
            raise ValidationError("experiment.policies", list(pols), "labels must be unique")
        object.__setattr__(self, "policies", pols)
        v.positive("experiment.track_loss_m", self.track_loss_m)
        th = tuple(v.positive("experiment.thresholds_m", t) for t in self.thresholds_m)
        if not th:
            raise ValidationError("experiment.thresholds_m", [], "at least one threshold [m]")
        object.__setattr__(self, "thresholds_m", th)
        v.integer_field(self, "example_trial", "experiment.example_trial", minimum=0)
        v.integer_field(self, "task_trials", "experiment.task_trials", minimum=1)
        self.plan()  # every policy table is checked before any work

    def plan(self) -> dict:
        """``{label: PolicySpec}``."""
        out = {}
        for label in self.policies:
            if label in self.variants:
                var = self.variants[label]
                if not isinstance(var, dict) or var.get("policy") not in POLICIES:
                    raise ValidationError(
                        f"experiment.variants.{label}.policy",
                        var.get("policy") if isinstance(var, dict) else var,
                        f"one of {', '.join(POLICIES)}",
                    )
                out[label] = PolicySpec.from_dict(var, f"experiment.variants.{label}")
            elif label == "fim_rh":
                out[label] = PolicySpec.from_dict(
                    {"policy": "fim_rh", **self.fim_rh}, "experiment.fim_rh"
                )
            else:
                out[label] = PolicySpec(label)
        return out


def _estimator(recipe, exp):
    """``(registered name, options)`` of the estimation layer: the label ``experiment.estimator``
    and its ``[localization.<label>]`` table (:mod:`phyloc.evaluation.methods`)."""
    loc = recipe.section("localization")
    if "method" in loc:
        raise ValidationError(
            "localization.method",
            loc["method"],
            'name the estimator in [experiment]: estimator = "spbp" or "pfbp" (or a label '
            'whose [localization.<label>] table holds method = "spbp" or "pfbp"), its options '
            "in [localization.<label>]",
        )
    plan = method_plan(loc, (exp.estimator,), "tracking", labels_key="experiment.estimator")
    name, opts = plan[exp.estimator]
    if name not in ESTIMATORS:
        where = (
            f"localization.{exp.estimator}.method"
            if name != exp.estimator
            else "experiment.estimator"
        )
        raise ValidationError(where, name, f"one of {', '.join(ESTIMATORS)}")
    return name, opts


def _task(payload, _seed_seq):
    """Run a block of trials; each trial's stream comes from its index, not from the task."""
    scenario, plan, est_name, est_opts, seed, trials, example = payload
    estimator = make_estimator(est_name, est_opts)
    out = {label: {"err2": [], "decision_s": []} for label in plan}
    ex = None
    for t in trials:
        draws_ss, policy_ss, est_ss = np.random.SeedSequence(seed, spawn_key=(t,)).spawn(3)
        draws = draw_trial(scenario, np.random.default_rng(draws_ss))
        keep = t == example
        if keep:
            ex = {"truth": draws.truth[:, :, : scenario.dim], "static": draws.static, "by": {}}
        for label, spec in plan.items():
            r = run_policy(
                scenario,
                draws,
                spec,
                estimator,
                np.random.default_rng(policy_ss),
                np.random.default_rng(est_ss),
                keep=keep,
            )
            out[label]["err2"].append(r["err2"])
            out[label]["decision_s"].append(r["decision_s"])
            if keep:
                ex["by"][label] = {"mobile": r["mobile"], "estimates": r["estimates"]}
    return out, ex


def wilson(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval of a proportion ``k/n`` (95 % by default), as fractions.

    Examples
    --------
    >>> lo, hi = wilson(0, 100)
    >>> lo, round(hi, 4)
    (0.0, 0.037)
    """
    if n <= 0:
        return float("nan"), float("nan")
    p = k / n
    den = 1.0 + z * z / n
    c = (p + z * z / (2 * n)) / den
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    lo = 0.0 if k == 0 else max(0.0, c - h)  # exact ends (c − h rounds to ±1e-18 there)
    hi = 1.0 if k == n else min(1.0, c + h)
    return lo, hi


def _fmt_m(t: float) -> str:
    return f"{t:g}".replace(".", "p")


def _aggregate(results, exp, plan, scenario):
    """Pool the trials: the track-loss fractions and the log-MSE means are
    :class:`~phyloc.evaluation.statistics.Pooled` figures whose units are the trials (their
    intervals do not depend on how trials are grouped into tasks); :func:`_comparisons` adds
    the paired ratios."""
    figures: dict[str, object] = {}
    series: dict[str, object] = {}
    K = scenario.steps
    example = None
    for _, ex in results:
        if ex is not None:
            example = ex
    for label in plan:
        err2 = np.concatenate([np.asarray(r[label]["err2"]) for r, _ in results])  # [n, K, A]
        dec = np.concatenate([np.asarray(r[label]["decision_s"]) for r, _ in results])
        final = err2[:, -1, :]
        diverged = ~np.all(np.isfinite(err2), axis=(1, 2))
        n_tracks = final.size

        def loss(th, final=final, n_tracks=n_tracks):
            lost = int(np.sum(~(final <= th * th)))
            return lost, 100.0 * lost / n_tracks

        lost, pct = loss(exp.track_loss_m)
        lo, hi = wilson(lost, n_tracks)
        figures[f"{label}.track_loss_pct"] = pct
        figures[f"{label}.track_loss_ci_low_pct"] = 100.0 * lo
        figures[f"{label}.track_loss_ci_high_pct"] = 100.0 * hi
        figures[f"{label}.track_loss_fraction"] = Pooled.fraction(
            ~(final <= exp.track_loss_m**2)  # one row of tracks per trial
        )
        for th in exp.thresholds_m:
            figures[f"{label}.track_loss_pct_{_fmt_m(th)}m"] = loss(th)[1]
            figures[f"{label}.track_loss_fraction_{_fmt_m(th)}m"] = Pooled.fraction(
                ~(final <= th * th)
            )
        mse = np.mean(np.where(np.isfinite(err2), err2, DIVERGED_M2), axis=2)  # [n, K]
        log_mse = np.log10(np.maximum(mse, 1e-300))
        by_step = log_mse.mean(axis=0)
        figures[f"{label}.k{K}.log10_mse_mean"] = _as_computed(
            Pooled.mean(log_mse[:, -1]), by_step[-1]
        )
        figures[f"{label}.late_log10_mse_mean"] = _as_computed(
            Pooled.mean(log_mse[:, -LATE_STEPS:]), by_step[-LATE_STEPS:].mean()
        )
        figures[f"{label}.decision_s"] = float(dec.mean())
        figures[f"{label}.diverged_pct"] = 100.0 * float(diverged.mean())
        figures[f"{label}.diverged_fraction"] = Pooled.fraction(diverged[:, None])
        series[f"{label}.log10_mse_by_step"] = by_step
        if example is not None:
            series[f"{label}.example.mobile"] = np.round(example["by"][label]["mobile"], 3)
            series[f"{label}.example.estimates"] = np.round(example["by"][label]["estimates"], 3)
    if example is not None:
        series["example.truth"] = np.round(example["truth"], 3)
        series["example.static"] = np.round(example["static"], 3)
    _comparisons(figures, plan)
    return figures, series


#: The policies the FIM paper's controllers are compared against.
BASELINES = ("static", "random")


def comparisons(plan) -> list[tuple[str, str]]:
    """The pairs ``(a, b)`` of policy labels compared by a paired ratio: every FIM-controlled
    label (``fim_myopic``, ``fim_rh`` and their variants) against every baseline
    (:data:`BASELINES`), and every receding-horizon label against every myopic one."""
    kind = {label: spec.policy for label, spec in plan.items()}
    fim = [p for p in plan if kind[p] not in BASELINES]
    return [(a, b) for a in fim for b in plan if kind[b] in BASELINES] + [
        (a, b) for a in fim for b in fim if kind[a] == "fim_rh" and kind[b] == "fim_myopic"
    ]


def _comparisons(figures, plan) -> None:
    """``<a>_vs_<b>.track_loss_fraction``: the paired ratio of the tracks lost over the same
    trials (the policies share every trial's draws) for the pairs of :func:`comparisons`;
    below 1 favours ``a``. None where ``b`` lost no track."""
    for a, b in comparisons(plan):
        x, y = figures[f"{a}.track_loss_fraction"], figures[f"{b}.track_loss_fraction"]
        if y.value != 0:
            figures[f"{a}_vs_{b}.track_loss_fraction"] = Paired(x, y)


def _as_computed(p: Pooled, value) -> Pooled:
    """``p`` with the point value computed from all the values at once, so that it stays bit
    for bit what it was (:meth:`~phyloc.evaluation.statistics.Pooled.at`)."""
    return p.at(value)


def _pct(figures: dict, name: str):
    """The fraction ``name`` and its interval in percent as one table cell
    (:func:`~phyloc.reporting.with_interval`)."""
    keys = (name, name + ".ci_low", name + ".ci_high")
    scaled = {k: 100.0 * figures[k] for k in keys if figures.get(k) is not None}
    return with_interval(scaled, name)


def summary_rows(results: dict):
    """Per policy: track loss with its 95 % interval, per threshold, final log-MSE with its
    interval over trials, decision time."""
    f, meta = results["figures"], results["meta"]
    K = meta["steps"]
    rows = []
    for p in meta["policies"]:
        per = " / ".join(
            f"{f[f'{p}.track_loss_pct_{_fmt_m(t)}m']:.2f}" for t in meta["thresholds_m"]
        )
        loss = (
            _pct(f, f"{p}.track_loss_fraction")
            if f"{p}.track_loss_fraction" in f  # runs stored before the intervals: Wilson
            else f"{f[f'{p}.track_loss_pct']:.3g} [{f[f'{p}.track_loss_ci_low_pct']:.3g}, "
            f"{f[f'{p}.track_loss_ci_high_pct']:.3g}]"
        )
        rows.append(
            (
                p,
                loss,
                per,
                with_interval(f, f"{p}.k{K}.log10_mse_mean"),
                1e3 * f[f"{p}.decision_s"],
            )
        )
    return rows


def summary_lines(results: dict):
    """Trials, thresholds, the scenario, the intervals and the paired track-loss ratios."""
    f, meta = results["figures"], results["meta"]
    th = ", ".join(f"{t:g}" for t in meta["thresholds_m"])
    out = [
        f"{meta['trials']} trials, {meta['steps']} steps; {meta['agents']} agent(s), "
        f"{meta['mobile_anchors']} mobile + {meta['static_anchors']} static anchor(s), "
        f"|U| = {meta['controls']}, estimator {meta['estimator']}",
        f"track lost: final position error > {meta['track_loss_m']:g} m "
        f"(per-threshold column: {th} m)",
        "[95 % intervals: Clopper-Pearson over tracks (track loss), bootstrap over trials "
        "(log10 MSE)]",
    ]
    ratios = [
        f"{k.split('.')[0].replace('_vs_', '/')} {_text(with_interval(f, k))}"
        for k in f
        if k.endswith(".track_loss_fraction.ratio")
    ]
    if ratios:
        out.append("tracks lost, ratio over the same trials: " + ", ".join(ratios))
    return out


def _text(x) -> str:
    return "n/a" if x is None else x if isinstance(x, str) else f"{x:.3g}"


def _loss_bars(ax, pols, figures, thresholds) -> None:
    """The 95 % intervals of the track-loss fractions (in percent) as error bars on the bars
    of :func:`~phyloc.reporting.grouped_bars` (the same positions)."""
    width = 0.8 / len(thresholds)
    x = np.arange(len(pols))
    for j, t in enumerate(thresholds):
        names = [f"{p}.track_loss_fraction_{_fmt_m(t)}m" for p in pols]
        y, lo, hi = (
            100.0 * np.array([_num(figures.get(n + s)) for n in names])
            for s in ("", ".ci_low", ".ci_high")
        )
        ok = np.isfinite(y) & np.isfinite(lo) & np.isfinite(hi)
        if ok.any():
            err = np.maximum(0.0, [y[ok] - lo[ok], hi[ok] - y[ok]])
            ax.errorbar(
                (x + j * width)[ok], y[ok], yerr=err, fmt="none", ecolor="k", capsize=2, lw=1
            )


def _num(x) -> float:
    return np.nan if x is None else float(x)


def plot(results: dict, path) -> None:
    """FIM Fig. 5 (mean log₁₀ MSE per step, its 95 % interval over trials at the last step),
    Fig. 4 (example trial in 3-D), track loss (95 % intervals as error bars)."""
    f, ser, meta = results["figures"], results["series"], results["meta"]
    pols = meta["policies"]
    fig, _ = new_figure(0, 0, size=(16.0, 5.0))  # panels added one by one (one in 3-D)
    color = {p: f"C{i}" for i, p in enumerate(pols)}
    ax = fig.add_subplot(1, 3, 1)
    K = meta["steps"]
    for i, p in enumerate(pols):
        y = np.asarray(ser[f"{p}.log10_mse_by_step"])
        ax.plot(np.arange(1, y.size + 1), y, color=color[p], label=p)
        name = f"{p}.k{K}.log10_mse_mean"
        lo, hi = _num(f.get(name + ".ci_low")), _num(f.get(name + ".ci_high"))
        if np.isfinite(lo) and np.isfinite(hi):  # side by side just right of k = K
            k = K + 0.15 * (i + 1) * max(1, K // 10)
            ax.plot([k, k], [lo, hi], "-", color=color[p], lw=2.5, alpha=0.6)
    ax.set_xlabel("time step k")
    ax.set_ylabel("mean of log10 MSE [m²]")
    ax.set_title(f"agent position MSE ({meta['trials']} trials; bar at k = K: 95 % interval)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    truth = ser.get("example.truth")
    ax = fig.add_subplot(
        1, 3, 2, projection="3d" if truth is not None and np.asarray(truth).shape[-1] == 3 else None
    )
    if truth is not None:
        truth = np.asarray(truth)
        three = truth.shape[-1] == 3

        def line(a, *args, **kw):
            ax.plot(*[a[..., d] for d in range(3 if three else 2)], *args, **kw)

        for i in range(truth.shape[1]):
            line(truth[:, i], "-", color="k", lw=1.5, label="agent (truth)" if i == 0 else None)
        st = np.asarray(ser["example.static"])
        if st.size:
            line(st, "ks", ms=7, label="static anchor")
        for p in pols:
            mob = np.asarray(ser[f"{p}.example.mobile"])
            for j in range(mob.shape[1]):
                line(mob[:, j], "-", color=color[p], lw=1.0, label=p if j == 0 else None)
                line(mob[:1, j], "o", color=color[p], ms=4)
        ax.set_title(f"example trial {meta['example_trial']}: mobile anchors' paths")
        ax.legend(fontsize=7)
    ax = fig.add_subplot(1, 3, 3)
    groups = {
        f"> {t:g} m": [f[f"{p}.track_loss_pct_{_fmt_m(t)}m"] for p in pols]
        for t in meta["thresholds_m"]
    }
    grouped_bars(ax, pols, groups)
    _loss_bars(ax, pols, f, meta["thresholds_m"])
    ax.set_ylabel("tracks lost [%]")
    ax.set_title("track loss (final position error; 95 % intervals)")
    fig.suptitle(f"Mobile-anchor control — {meta['recipe']}{' (fast)' if meta.get('fast') else ''}")
    save_figure(fig, path)


class ControlExperiment(Experiment):
    """``kind = "control"``: one task per block of trials; every policy on the same draws."""

    kind = "control"
    title = "mobile anchors steered by Fisher information (anchor control)"
    unit = "trial block"
    spec = ControlExperimentSpec
    task = staticmethod(_task)
    progress_label = "control trials"
    headers = (
        "policy",
        "track loss % [95 % CI]",
        "loss % per threshold",
        "log10 MSE (k=K) [95 % CI]",
        "decision [ms]",
    )

    def experiment_spec(self, recipe, *, fast=False):
        table = {
            k: tuple(x) if isinstance(x, list) else x
            for k, x in recipe.section("experiment").items()
        }
        return experiment_from_dict(ControlExperimentSpec, table, fast=fast)

    def prepare(self, recipe, *, fast=False):
        exp = self.experiment_spec(recipe, fast=fast)
        scenario = ControlScenario.from_dict(dict(recipe.section("network")))
        est_name, est_opts = _estimator(recipe, exp)  # checked before any work
        return SimpleNamespace(
            exp=exp,
            scenario=scenario,
            est_name=est_name,
            est_opts=est_opts,
            policies=exp.plan(),
            example=min(exp.example_trial, exp.trials - 1),
            seed=recipe.seed,
        )

    def tasks(self, plan):
        exp = plan.exp
        blocks = [
            list(range(s, min(s + exp.task_trials, exp.trials)))
            for s in range(0, exp.trials, exp.task_trials)
        ]
        return [
            (
                b[0],
                (
                    plan.scenario,
                    plan.policies,
                    plan.est_name,
                    plan.est_opts,
                    plan.seed,
                    b,
                    plan.example,
                ),
            )
            for b in blocks
        ]

    def aggregate(self, plan, keys, results, ctx):
        return _aggregate(results, plan.exp, plan.policies, plan.scenario)

    def meta(self, plan, ctx):
        exp, scenario, est_name, example = plan.exp, plan.scenario, plan.est_name, plan.example
        policies = plan.policies
        return {
            "trials": exp.trials,
            "policies": list(policies),
            "policy_specs": {
                k: {"policy": p.policy, "horizon": p.horizon, "search": p.search, "beam": p.beam}
                for k, p in policies.items()
            },
            "estimator": est_name,
            "steps": scenario.steps,
            "agents": scenario.agents,
            "mobile_anchors": scenario.mobile_anchors,
            "static_anchors": scenario.static_anchors,
            "controls": int(scenario.controls.shape[0]),
            "track_loss_m": exp.track_loss_m,
            "thresholds_m": list(exp.thresholds_m),
            "example_trial": example,
        }

    summary_rows = staticmethod(summary_rows)
    summary_lines = staticmethod(summary_lines)
    plot = staticmethod(plot)


CONTROL = ControlExperiment()

"""Direct localization over time: the DiPNet rover experiments (DiPNet §V-B, Figs. 6–7).

A recipe of ``kind = "direct_tracking"`` runs one or more *experiments* (``[experiment.runs]``),
each a network given by ``[network]`` updated by the run's own ``network`` table — in the
replica ``datasets/dipnet_fig7_rover.toml`` five stationary agents in a pentagon (15 m and
30 m) and a sixth on a rover following waypoints (:func:`phyloc.network.waypoint_trajectory`)
— and localizes every snapshot of it with every method of ``experiment.methods`` from the same
waveforms, truth-free: snapshot 0 from Gaussian priors around a coarse MDS/SMACOF solution,
every later one from the prediction of the previous belief with the same random-walk mobility
model for every agent (moving or not, the agents do not know; DiPNet §V-B). The methods are
those of the direct family (:data:`phyloc.localization.METHODS`), by default the paper's four::

    ``dipnet``           DiPNet (Gaussian moments exchanged, direct likelihood)
    ``dpe_sampled``      sample-based DPE (particle sets exchanged, direct likelihood of DiPNet
                         eq. (22), O(Q²) per link)
    ``sage_parametric``  two-step EL-DPF on SAGE ranges (Gaussian moments exchanged)
    ``sage_sampled``     sample-based SAGE (particle sets exchanged, Gaussian SAGE ranges)

A label of ``experiment.methods`` that is not a registered name runs the method its
``[localization.<label>]`` table names (``method = "<registered name>"`` plus option keys,
e.g. ``n_particles = 400``), the grammar of every kind (:mod:`phyloc.evaluation.methods`).

Figures, for every method label ``m`` and run ``e`` (errors: the absolute framework distance
errors of DiPNet eq. (4), pooled over snapshots and realizations)::

    m.e.median_error_m, m.e.p90_error_m, m.e.errors_over_2m_pct, m.e.rmse_m
    m.e.rmse_slow_m, m.e.rmse_fast_m   RMSE over the snapshots where every agent's true speed is
                                       at most / above ``experiment.fast_speed_m_s``
    m.e.agent_snapshot_s               filter time per agent and snapshot
    m.e.agent_iteration_s              filter time per agent-iteration
    a_vs_m.e.rmse_m.ratio (and .rmse_slow_m.ratio, .rmse_fast_m.ratio where the run has such
                                       snapshots)   the first method ``a`` of
                                       ``experiment.methods`` over each other one: the ratio of
                                       their RMSEs on the same realizations (below 1 favours
                                       ``a``; DiPNet against parametric SAGE, sample-based DPE
                                       and sample-based SAGE in the replica)

95 % intervals (the unit is a realization, :mod:`phyloc.evaluation.statistics`): ``rmse_m``,
``rmse_slow_m``, ``rmse_fast_m`` and ``errors_over_2m_pct`` (a mean of 100·[error > 2 m]) have
``<name>.ci_low`` / ``<name>.ci_high`` (bootstrap over realizations) and their per-realization
values in the series ``<name>.units``; every ``….ratio`` has the paired bootstrap's interval
(``.ratio.ci_low`` / ``.ratio.ci_high``). With one realization per run they are NaN. Median,
90th percentile and the timings carry none.

Series: ``m.e.rmse_by_snapshot`` (Fig. 7 a, b), ``m.e.error_cdf`` on ``cdf_grid_m``
(Fig. 7 c, d), ``e.true_track`` (realization 0), ``m.e.track`` for the first run (realization
0, estimates rigidly aligned to the truth per snapshot, Fig. 6 c, d) and ``dipnet.e.particles``
for the last run (realization 0, :data:`PARTICLES_SHOWN` per agent at snapshot
``experiment.particles_snapshot``, aligned likewise, Fig. 6 b); pictures are rounded to 1 mm.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from phyloc import _validate as v
from phyloc._validate import check_keys
from phyloc.channels import ChannelSpec
from phyloc.datasets.simulate import check_heights, simulate_realization
from phyloc.errors import ValidationError
from phyloc.evaluation.experiment import Experiment
from phyloc.evaluation.front_end import localize_realization
from phyloc.evaluation.methods import check_labels
from phyloc.evaluation.metrics import rigid_align
from phyloc.evaluation.sections import LocalizationSpec, RangingSpec
from phyloc.evaluation.statistics import Paired, Pooled
from phyloc.evaluation.tracking_experiment import pooled_at
from phyloc.evaluation.tracking_figures import error_bars
from phyloc.localization import METHODS as REGISTRY
from phyloc.localization import DirectOptions
from phyloc.network import NetworkSpec
from phyloc.reporting import grouped_bars, new_figure, save_figure, with_interval

PAPER_METHODS = ("dipnet", "dpe_sampled", "sage_parametric", "sage_sampled")
"""The four methods of DiPNet Figs. 6–7."""
CDF_GRID_M = np.linspace(0.0, 10.0, 401)
THRESHOLD_M = 2.0
"""Errors above this count in ``errors_over_2m_pct``."""
PARTICLES_SHOWN = 200
"""Particles per agent kept for Fig. 6 b (drawn by weight)."""
PICTURE_DECIMALS = 3
"""Tracks and particles are stored rounded to 1 mm (pictures, not estimates)."""


def _merge(base: dict, over: dict) -> dict:
    """``base`` updated by ``over``, subtables merged key by key."""
    out = dict(base)
    for k, val in over.items():
        out[k] = (
            _merge(out[k], val) if isinstance(val, dict) and isinstance(out.get(k), dict) else val
        )
    return out


@dataclass(frozen=True)
class DirectTrackingExperimentSpec:
    """``[experiment]`` of a ``direct_tracking`` recipe (``[experiment.fast]`` for ``--fast``).

    Parameters
    ----------
    runs : dict
        ``{name: {"network": {...}}}``: each run's network table updates ``[network]``
        (subtables such as ``motion`` key by key). At least one run.
    methods : tuple of str
        Method labels: registered direct-family methods, or labels whose
        ``[localization.<label>]`` table names one (``method = ...``).
    realizations : int
        Independent realizations (network noise and channels) per run.
    particles_snapshot : int
        Snapshot whose particles are kept for Fig. 6 b (clipped to the run's last snapshot).
    fast_speed_m_s : float
        Snapshots where some agent moves faster than this are the "fast" segment [m/s].
    max_snapshots : int
        Keep only the first snapshots of every run (0: all); a ``--fast`` setting.
    particle_scale : float
        Multiply every method's ``n_particles`` (keeping the ratios); a ``--fast`` setting.
    """

    runs: dict = field(default_factory=dict)
    methods: tuple = PAPER_METHODS
    realizations: int = 1
    particles_snapshot: int = 0
    fast_speed_m_s: float = 2.0
    max_snapshots: int = 0
    particle_scale: float = 1.0

    def __post_init__(self):
        if not isinstance(self.runs, dict) or not self.runs:
            raise ValidationError(
                "experiment.runs", self.runs, "a table of runs, e.g. [experiment.runs.exp1]"
            )
        for name, run in self.runs.items():
            if not isinstance(run, dict):
                raise ValidationError(
                    f"experiment.runs.{name}", run, "a table with a network table"
                )
            check_keys(run, ["network"], f"experiment.runs.{name}")
            if not isinstance(run.get("network", {}), dict):
                raise ValidationError(
                    f"experiment.runs.{name}.network",
                    run["network"],
                    "a table of [network] keys this run changes, e.g. n_agents = 6",
                )
        methods = check_labels(self.methods)
        if not methods:
            raise ValidationError("experiment.methods", [], "at least one method")
        object.__setattr__(self, "methods", methods)
        v.integer_field(self, "realizations", "experiment.realizations", minimum=1)
        v.integer_field(self, "particles_snapshot", "experiment.particles_snapshot", minimum=0)
        v.positive("experiment.fast_speed_m_s", self.fast_speed_m_s)
        v.integer_field(self, "max_snapshots", "experiment.max_snapshots", minimum=0)
        v.positive("experiment.particle_scale", self.particle_scale)

    def networks(self, base: dict) -> dict:
        """``{run: NetworkSpec}``: ``[network]`` updated by each run (``max_snapshots`` applied)."""
        out = {}
        for name, run in self.runs.items():
            d = _merge(base, run.get("network", {}))
            if self.max_snapshots and isinstance(d.get("motion", {}), dict):
                motion = dict(d.get("motion", {}))
                n = motion.get("n_snapshots", 1)
                if isinstance(n, int) and not isinstance(n, bool):  # else NetworkSpec names it
                    motion["n_snapshots"] = min(n, self.max_snapshots)
                d["motion"] = motion
            try:
                out[name] = NetworkSpec.from_dict(d)
            except ValidationError as exc:
                raise ValidationError(
                    f"experiment.runs.{name}: {exc.field}", exc.value, exc.allowed
                ) from None
        return out

    def plan(self, lspec: LocalizationSpec) -> dict:
        """``{label: (registered name, options)}`` (:meth:`LocalizationSpec.plan
        <phyloc.evaluation.sections.LocalizationSpec.plan>`) with ``particle_scale`` applied."""
        plan = lspec.plan(self.methods)
        if self.particle_scale == 1.0:
            return plan
        out = {}
        for label, (name, opts) in plan.items():
            if isinstance(opts, DirectOptions):
                own = {k: x for k, x in lspec.method_options.get(label, {}).items()}
                own.pop("method", None)
                q = max(10, round(opts.dpf.n_particles * self.particle_scale))
                table = {**lspec.options, **own, "n_particles": q}
                opts = REGISTRY[name].make_options(table, f"localization.{label}")
            out[label] = (name, opts)
        return out


def _task(payload, seed_seq):
    """One realization of one run: simulate, localize every snapshot, keep what the figures
    need (errors per snapshot, realization-0 tracks and particles)."""
    system, net_spec, chan_spec, rspec, lspec, plan, keep, first = payload
    real = simulate_realization(system, net_spec, chan_spec, np.random.default_rng(seed_seq))
    out = localize_realization(real, system, rspec, lspec, plan, ("truth_free",), seed_seq, (keep,))
    truth = real.network.positions
    vel = real.network.velocities
    speed = np.linalg.norm(vel, axis=2).max(axis=1) if vel is not None else np.zeros(truth.shape[0])
    res = {"speed": speed}
    for label in plan:
        key = f"{label}|truth_free"
        est = out[key + "|estimates"]
        res[label] = {
            "err": out[key + "|err"],
            "rmse_t": out[key + "|rmse_t"],
            "agent_snapshot_s": out[key + "|agent_snapshot_s"],
            "agent_iteration_s": out[key + "|sec_per_agent_it"],
        }
        if first:  # realization 0: tracks and particles for Fig. 6
            res[label]["track"] = _aligned_track(est, truth, real.network.is_anchor)
            parts = out[key + "|particles_at"].get(keep)
            if parts is not None:
                res[label]["particles"] = _aligned_particles(
                    parts, est[keep], truth[keep], real.network.is_anchor
                )
    if first:
        res["truth"] = truth
    return res


def _full(est_agents, truth_t, is_anchor):
    full = truth_t.copy()  # anchors (if any) at their known positions
    full[~is_anchor] = est_agents
    return full


def _aligned_track(est, truth, is_anchor):
    """Estimates per snapshot, rigidly aligned to the truth (DiPNet §V-B, Fig. 6 c, d)."""
    return np.stack(
        [
            rigid_align(
                _full(est[t], truth[t], is_anchor), truth[t], is_anchor=_anchors(is_anchor)
            )[2]
            for t in range(est.shape[0])
        ]
    )


def _anchors(is_anchor):
    return is_anchor if is_anchor.any() else None


def _aligned_particles(parts, est_t, truth_t, is_anchor):
    """Up to :data:`PARTICLES_SHOWN` particles per agent, drawn by weight (a fixed stream: a
    picture, not an estimate), mapped by the snapshot's alignment of the estimates."""
    X, lw = parts
    R, t, _ = rigid_align(_full(est_t, truth_t, is_anchor), truth_t, is_anchor=_anchors(is_anchor))
    rng = np.random.default_rng(0)
    n = min(PARTICLES_SHOWN, X.shape[1])
    out = np.empty((X.shape[0], n, X.shape[2]))
    for a in range(X.shape[0]):
        w = np.exp(lw[a] - lw[a].max())
        idx = rng.choice(X.shape[1], size=n, p=w / w.sum())
        out[a] = X[a, idx] @ R.T + t
    return out


def _rmse(x):
    return float(math.sqrt(np.mean(np.square(x)))) if np.size(x) else float("nan")


def _particles_method(labels):
    """The method whose particles Fig. 6 b shows: DiPNet if it runs, else the first."""
    return "dipnet" if "dipnet" in labels else labels[0]


def _aggregate(keys, results, exp, runs, labels):
    figures: dict[str, object] = {}
    series: dict[str, object] = {"cdf_grid_m": CDF_GRID_M}
    for run_name in runs:
        parts = [res for (name, _), res in zip(keys, results, strict=True) if name == run_name]
        fast_t = parts[0]["speed"] > exp.fast_speed_m_s
        figures[f"{run_name}.fast_snapshots"] = int(fast_t.sum())
        if "truth" in parts[0]:
            series[f"{run_name}.true_track"] = np.round(parts[0]["truth"], PICTURE_DECIMALS)
        for m in labels:
            err = np.concatenate([p[m]["err"] for p in parts])
            rmse_t = np.array([p[m]["rmse_t"] for p in parts])
            base = f"{m}.{run_name}"
            figures[base + ".median_error_m"] = float(np.median(err))
            figures[base + ".p90_error_m"] = float(np.percentile(err, 90))
            figures[base + ".errors_over_2m_pct"] = pooled_at(  # in percent: a mean, not a
                Pooled.mean([100.0 * (p[m]["err"] > THRESHOLD_M) for p in parts]),  # fraction
                100.0 * np.mean(err > THRESHOLD_M),
            )
            figures[base + ".rmse_m"] = pooled_at(
                Pooled.rmse([p[m]["err"] for p in parts]), _rmse(err)
            )
            for seg, sel in (("slow", ~fast_t), ("fast", fast_t)):  # per realization: its
                figures[f"{base}.rmse_{seg}_m"] = pooled_at(  # per-snapshot RMSEs there
                    Pooled.rmse([r[sel] for r in rmse_t]), _rmse(rmse_t[:, sel])
                )
            figures[base + ".agent_snapshot_s"] = float(
                np.mean([p[m]["agent_snapshot_s"] for p in parts])
            )
            figures[base + ".agent_iteration_s"] = float(
                np.mean([p[m]["agent_iteration_s"] for p in parts])
            )
            series[base + ".rmse_by_snapshot"] = np.sqrt(np.mean(rmse_t**2, axis=0))
            series[base + ".error_cdf"] = (
                np.searchsorted(np.sort(err), CDF_GRID_M, side="right") / err.size
            )
            # pictures: tracks of the first run (Fig. 6 c, d), particles of the last (Fig. 6 b)
            if run_name == runs[0] and "track" in parts[0][m]:
                series[base + ".track"] = np.round(parts[0][m]["track"], PICTURE_DECIMALS)
            if (
                run_name == runs[-1]
                and m == _particles_method(labels)
                and "particles" in parts[0][m]
            ):
                series[base + ".particles"] = np.round(parts[0][m]["particles"], PICTURE_DECIMALS)
        _comparisons(figures, labels, run_name, fast_t)
    return figures, series


def _comparisons(figures, labels, run_name, fast_t):
    """Paired ratios of the RMSEs over the same realizations: the first method against every
    other (``<first>_vs_<m>``; below 1 favours the first); the slow and fast segments only
    where the run has such snapshots."""
    names = ["rmse_m"] + [
        f"rmse_{seg}_m" for seg, sel in (("slow", ~fast_t), ("fast", fast_t)) if sel.any()
    ]
    a = labels[0]
    for m in labels[1:]:
        for name in names:
            figures[f"{a}_vs_{m}.{run_name}.{name}"] = Paired(
                figures[f"{a}.{run_name}.{name}"], figures[f"{m}.{run_name}.{name}"]
            )


def summary_rows(results: dict):
    """Per run and method: error median, 90th percentile, outliers, RMSE, runtime (outliers
    and RMSEs with their 95 % intervals over realizations when the run has them)."""
    f, meta = results["figures"], results["meta"]
    rows = []
    for run_name in meta["runs"]:
        for m in meta["methods"]:
            b = f"{m}.{run_name}"
            rows.append(
                (
                    run_name,
                    m,
                    f[b + ".median_error_m"],
                    f[b + ".p90_error_m"],
                    with_interval(f, b + ".errors_over_2m_pct"),
                    with_interval(f, b + ".rmse_slow_m"),
                    with_interval(f, b + ".rmse_fast_m"),
                    1e3 * f[b + ".agent_snapshot_s"],
                )
            )
    return rows


def summary_lines(results: dict):
    """Snapshots, particle counts, the fast segment and the paired RMSE ratios of the first
    method over the others."""
    f, meta = results["figures"], results["meta"]
    runs = ", ".join(
        f"{r}: {meta['n_snapshots'][r]} snapshots ({f[f'{r}.fast_snapshots']} fast)"
        for r in meta["runs"]
    )
    q = ", ".join(f"{m} {n}" for m, n in meta["n_particles"].items())
    out = [
        (
            "absolute framework distance errors (DiPNet eq. (4)) pooled over snapshots; "
            "truth-free [95 % interval over realizations]"
        ),
        f"{runs}; fast: some agent faster than {meta['fast_speed_m_s']} m/s",
        f"particles per agent: {q}",
    ]
    first = meta["methods"][0]
    for r in meta["runs"]:
        cells = [
            (m, with_interval(f, f"{first}_vs_{m}.{r}.rmse_m.ratio")) for m in meta["methods"][1:]
        ]
        if cells and all(c is not None for _, c in cells):
            out.append(
                f"{r}: RMSE {first} / other on the same realizations: "
                + "; ".join(f"{m} {c if isinstance(c, str) else f'{c:.3g}'}" for m, c in cells)
            )
    return out


def plot(results: dict, path) -> None:
    """DiPNet Fig. 7 (RMSE per snapshot, error CDFs) and Fig. 6 (trajectories, particles)."""
    f, ser, meta = results["figures"], results["series"], results["meta"]
    runs, methods = meta["runs"], meta["methods"]
    fig, axes = new_figure(3, len(runs) + 1, size=(4.8 * (len(runs) + 1), 12.0), squeeze=False)
    color = {m: f"C{i}" for i, m in enumerate(methods)}
    for j, r in enumerate(runs):
        ax = axes[0, j]
        for m in methods:
            ax.semilogy(np.asarray(ser[f"{m}.{r}.rmse_by_snapshot"]), color=color[m], label=m)
        ax.set_title(f"{r}: framework RMSE per snapshot")
        ax.set_xlabel("snapshot")
        ax.set_ylabel("RMSE [m]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        ax = axes[1, j]
        for m in methods:
            ax.plot(ser["cdf_grid_m"], ser[f"{m}.{r}.error_cdf"], color=color[m], label=m)
        ax.set_title(f"{r}: CDF of the absolute framework distance error")
        ax.set_xlabel("error [m]")
        ax.set_ylabel("CDF")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    # Fig. 6 c, d: true and estimated trajectories of the first run, two methods
    r0 = runs[0]
    shown = [m for m in ("sage_parametric", "dipnet") if m in methods] or methods[:2]
    for j, m in enumerate(shown[: len(runs) + 1]):
        ax = axes[2, j]
        _track_panel(ax, ser, r0, m, color[m])
    for ax in axes[2, len(shown) :]:
        ax.set_axis_off()
    # Fig. 6 b: true trajectories of the last run and DiPNet's particles at one snapshot
    ax = axes[0, -1]
    rl = runs[-1]
    m6 = _particles_method(methods)
    truth = ser.get(f"{rl}.true_track")
    if truth is not None:
        truth = np.asarray(truth)
        for u in range(truth.shape[1]):
            ax.plot(truth[:, u, 0], truth[:, u, 1], "-", color="0.3", lw=0.8)
        parts = ser.get(f"{m6}.{rl}.particles")
        snap = meta["particles_snapshot"][rl]
        if parts is not None:
            parts = np.asarray(parts)
            for a in range(parts.shape[0]):
                ax.plot(parts[a, :, 0], parts[a, :, 1], ".", ms=2, color=f"C{a}", zorder=3)
        ax.plot(
            truth[snap, :, 0],
            truth[snap, :, 1],
            "k^",
            ms=9,
            mfc="none",
            zorder=1,
            label=f"truth, snapshot {snap}",
        )
        ax.set_aspect("equal", adjustable="datalim")
        ax.legend(fontsize=7)
    ax.set_title(f"{rl}: true trajectories, {m6} particles")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax = axes[1, -1]
    groups = {r: [f[f"{m}.{r}.errors_over_2m_pct"] for m in methods] for r in runs}
    grouped_bars(ax, methods, groups, fontsize=7)
    width = 0.8 / len(runs)  # the bars' positions in grouped_bars
    for j, r in enumerate(runs):
        names = [f"{m}.{r}.errors_over_2m_pct" for m in methods]
        error_bars(ax, np.arange(len(methods)) + j * width, f, names, "k")
    ax.set_ylabel("errors > 2 m [%]")
    ax.set_title("outliers (bars: 95 % intervals over realizations)")
    fig.suptitle(
        f"Direct localization over time — {meta['recipe']}{' (fast)' if meta.get('fast') else ''}"
    )
    save_figure(fig, path)


def _track_panel(ax, ser, run_name, m, color):
    truth = ser.get(f"{run_name}.true_track")
    track = ser.get(f"{m}.{run_name}.track")
    if truth is None or track is None:
        ax.set_axis_off()
        return
    truth, track = np.asarray(truth), np.asarray(track)
    for u in range(truth.shape[1]):
        ax.plot(truth[:, u, 0], truth[:, u, 1], "-", color="0.3", lw=1.0)
        ax.plot(track[:, u, 0], track[:, u, 1], ".", color=color, ms=2)
    ax.plot([], [], "-", color="0.3", label="truth")
    ax.plot([], [], ".", color=color, label=f"{m} (aligned)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{run_name}: true and estimated trajectories, {m}")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(fontsize=7)


class DirectTrackingExperiment(Experiment):
    """``kind = "direct_tracking"``: one task per (run, realization), every snapshot of a moving
    network localized by every method."""

    kind = "direct_tracking"
    title = "direct localization over the snapshots of moving networks (DiPNet Figs. 6–7)"
    unit = "realization"
    spec = DirectTrackingExperimentSpec
    task = staticmethod(_task)
    headers = (
        "run",
        "method",
        "median [m]",
        "p90 [m]",
        "> 2 m [%]",
        "RMSE slow [m]",
        "RMSE fast [m]",
        "ms / agent-snapshot",
    )

    def prepare(self, recipe, *, fast=False):
        raw = recipe.section("experiment")
        for table, where in ((raw, "experiment"), (raw.get("fast"), "experiment.fast")):
            if isinstance(table, dict) and "variants" in table:
                raise ValidationError(
                    f"{where}.variants",
                    "a table",
                    "a variant is a label of experiment.methods with a [localization.<label>] "
                    'table: method = "<registered name>" and its options',
                )
        exp = self.experiment_spec(recipe, fast=fast)
        lspec = recipe.section("localization", LocalizationSpec)
        chan = recipe.section("channel", ChannelSpec)
        nets = exp.networks(dict(recipe.section("network")))
        check_heights(nets.values(), chan)
        return SimpleNamespace(
            system=recipe.system,
            exp=exp,
            rspec=recipe.section("ranging", RangingSpec),
            lspec=lspec,
            chan=chan,
            nets=nets,
            plan=exp.plan(lspec),
        )

    def tasks(self, plan):
        work = []
        for name, net in plan.nets.items():
            keep = min(plan.exp.particles_snapshot, net.motion.n_snapshots - 1)
            for r in range(plan.exp.realizations):
                payload = (plan.system, net, plan.chan, plan.rspec, plan.lspec, plan.plan, keep)
                work.append(((name, r), (*payload, r == 0)))
        return work

    def aggregate(self, plan, keys, results, ctx):
        return _aggregate(keys, results, plan.exp, list(plan.nets), list(plan.plan))

    def meta(self, plan, ctx):
        exp, nets = plan.exp, plan.nets
        plan = plan.plan
        return {
            "runs": list(nets),
            "methods": list(plan),
            "labels": {label: REGISTRY[name].label for label, (name, _) in plan.items()},
            "n_particles": {
                label: opts.dpf.n_particles
                for label, (_, opts) in plan.items()
                if isinstance(opts, DirectOptions)
            },
            "n_snapshots": {name: net.motion.n_snapshots for name, net in nets.items()},
            "particles_snapshot": {
                name: min(exp.particles_snapshot, net.motion.n_snapshots - 1)
                for name, net in nets.items()
            },
            "realizations": exp.realizations,
            "fast_speed_m_s": exp.fast_speed_m_s,
        }

    summary_rows = staticmethod(summary_rows)
    summary_lines = staticmethod(summary_lines)
    plot = staticmethod(plot)


DIRECT_TRACKING = DirectTrackingExperiment()

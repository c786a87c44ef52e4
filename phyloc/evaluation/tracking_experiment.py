"""Range-level cooperative tracking: PF-BP against SIR-BP, SP-BP, EDH and the PCRLB (PF-BP §VI).

A recipe of ``kind = "tracking"`` runs, for every scenario token of ``experiment.scenarios``
(``{token = {n_agents = N, comm_range_m = r_max}}``; ``comm_range_m`` omitted or ``inf``: fully
connected) and every Monte Carlo run (one task each): a network of PF-BP §VI
(:func:`~phyloc.evaluation.range_scenarios.scenario_network_spec`: agents uniform in a
``side_m`` cube, 9 anchors at its corners and centre in 3-D (5 in 2-D), initial velocity a unit
vector toward the centre, CA/CV motion with ``dt_s``, ``accel_std``), range measurements, the
prior of PF-BP eq. (31) (:func:`~phyloc.localization.tracking.paper_prior`, ``sigma_p``) and
every method of ``experiment.methods`` — any method of the ``"tracking"`` family of
:data:`phyloc.localization.METHODS` — on the *same* measurements (without the truth) from the
*same* prior::

    ``pfbp``      PF-BP, PF-BP Algorithm 1 (:func:`~phyloc.localization.tracking.run_pfbp`)
    ``pfbp_reg``  PF-BP with the regularization of PF-BP eqs. (32), (33) ("reg" in the paper)
    ``sirbp``     bootstrap-particle BP, PF-BP §V-B
                  (:func:`~phyloc.localization.tracking.run_sirbp`)
    ``spbp``      sigma-point BP (:func:`~phyloc.localization.tracking.run_spbp`)
    ``edh``       centralized EDH particle-flow filter, PF-BP Appendix B
                  (:func:`~phyloc.localization.tracking.run_edh`)
    ``sirbp_reg``, ``spbp_reg``, ``edh_reg``   the same with the regularization of PF-BP
                  eqs. (32), (33), as the paper runs every method (dashed in the figure)

Method options are ``[localization.<method>]`` tables (the keys of the method's options
dataclass, :class:`~phyloc.localization.tracking.PFBPOptions`,
:class:`~phyloc.localization.tracking.SIRBPOptions`,
:class:`~phyloc.localization.tracking.SPBPOptions`, over the method's registered defaults:
``pfbp_reg`` has ``regularize = true``); ``experiment.method_options`` (usually in
``[experiment.fast]``) overrides single keys, e.g. SIR-BP's particle count in the CI setting.
The PCRLB (:mod:`phyloc.analysis.pcrlb`) is the Tichavský recursion with the range information
averaged over the true trajectories of all runs (the Bayesian bound, ``pcrlb.*``);
``pcrlb_cond.*`` averages the per-trajectory bounds instead (the conditional bound, never
lower; see :mod:`phyloc.analysis.pcrlb`).

Measurements (``experiment.measurements``)::

    ``"gaussian"``  the paper's model (PF-BP eq. (8)): ``z = ‖p_i − p_j‖ + N(0, σ²)``,
                    ``σ = sigma_r``, for every pair within ``comm_range_m``
                    (:func:`~phyloc.evaluation.range_scenarios.simulate_scenario`).
    ``"sage"``      ranges estimated from simulated waveforms: per realization
                    :func:`~phyloc.datasets.simulate.simulate_realization` draws the network
                    (the same spec; ``[system]``, ``[channel]`` — e.g. WINNER II C2), channels
                    and received signals of every snapshot; at every time step SAGE
                    (``[ranging]``, ``[ranging.sage]``) estimates the range of each link an
                    agent receives; invalid links are NaN (no measurement). The trackers use one
                    σ per realization, by ``sage_sigma_m``: a number [m]; ``"zzb"``, the root of
                    the median estimator (ZZB) variance over the valid links — a LOS noise level,
                    overconfident by two orders of magnitude when NLOS links are biased by tens
                    of metres; or ``"residual"`` (default), truth-free and honest about outliers:
                    the RMS range residual of the coarse MDS/SMACOF fit (anchors fixing the
                    frame, :func:`~phyloc.localization.initialization.coarse_positions`) of the
                    first snapshot's valid ranges (``"zzb"`` where that range graph is
                    disconnected). The PCRLB is that of the Gaussian
                    model at ``sigma_r`` on the valid links (it knows no NLOS bias).

Figures (``results.json``; ``<m>`` a method, ``<s>`` a scenario token, ``<k>`` a time step of
``experiment.report_steps`` (≤ ``n_steps``), ``<ko>`` one of ``experiment.outage_steps``,
``<x>`` a threshold of ``experiment.outage_thresholds_m`` written with ``p`` for the decimal
point, e.g. ``1`` → ``1m``, ``0.1`` → ``0p1m``)::

    ``<m>.<s>.k<k>.rmse_p_m``        position RMSE at step k over runs and agents [m] (Fig. 4, 7)
    ``<m>.<s>.k<k>.rmse_v_m_s``      velocity RMSE [m/s]
    ``<m>.<s>.k<k>.rmse_a_m_s2``     acceleration RMSE [m/s²] (CA only)
    ``<m>.<s>.k<k>.rmse_over_pcrlb`` ``rmse_p_m`` over ``pcrlb.<s>.k<k>.p_m``
    ``<m>.<s>.k<k>.rmse_over_pcrlb_cond``  ``rmse_p_m`` over ``pcrlb_cond.<s>.k<k>.p_m``
    ``pcrlb.<s>.k<k>.p_m`` / ``v_m_s`` / ``a_m_s2``   PCRLB on the position/velocity/acceleration
                                     RMSE
    ``pcrlb_cond.<s>.k<k>.p_m`` / ...   the conditional bound (per-trajectory bounds averaged)
    ``pcrlb_cond_one_range.<s>.k<k>.p_m`` / ...  the conditional bound with one range per agent
                                     pair (``pcrlb(..., pairs="one")``): the pair information
                                     PF-BP's distributed factor (eq. (17)) sees at one agent
    ``<m>.<s>.k<ko>.outage_<x>m``    fraction of (run, agent) position errors > x at step ko
                                     (Fig. 6)
    ``<m>.<s>.rmse_p_all_m``         position RMSE over the whole trajectory
    ``<m>.<s>.runs``                 runs the method ran in (``runs``, or fewer by
                                     ``experiment.method_runs``; its ratios then use the
                                     bounds of those runs)
    ``<m>.<s>.step_s``               wall time per time step, joint processing [s] (Tables I, II):
                                     each run's median step, averaged over runs (with an
                                     interval over runs)
    ``<m>.<s>.agent_s``              ... per agent, distributed processing [s] (not for methods
                                     without a distributed form, whose ``agent_s`` is NaN:
                                     ``edh``)
    ``<m>.<s>.stage.<stage>_s``      ``step_s`` split by stage (each run's median step of the
                                     stage, averaged over runs, with an interval): the stages
                                     of :data:`~phyloc.localization.tracking.loop.STAGES` the
                                     method has (``predict``, ``sample``, ``flow``,
                                     ``weights``, ``resample``, ``covariance``,
                                     ``regularize``, ``estimate``, ``other``)
    ``<m>.<s>.floats_per_link_iteration``   floats one agent sends one neighbour per
                                     message-passing iteration (its belief: particles, or mean
                                     and covariance; PF-BP §VI), from the method's
                                     ``diagnostics`` (not for ``edh``, which exchanges none)
    ``sirbp_over_pfbp.<s>.step_ratio``   ``sirbp.<s>.step_s / pfbp.<s>.step_s``
    ``<s>.anchor_localizable_fraction``  share of the (run, step, agent) positions whose agent
                                     measures ranges to ``dim + 1`` anchors not on one
                                     hyperplane, i.e. is located by the anchors alone
                                     (:func:`~phyloc.evaluation.range_scenarios.anchor_localizable`;
                                     PF-BP Fig. 3), with an interval over runs
    ``<s>.min_anchor_links``         the fewest anchors any agent measured at any step of any run
    ``sage.<s>.range_rmse_m``, ``sage.<s>.valid_fraction``, ``sage.<s>.sigma_m``   (``"sage"``
                                     only) SAGE range RMSE over valid links, fraction of valid
                                     links, mean σ given to the trackers
    ``<a>_vs_<m>.<s>.k<k>.rmse_p_m.ratio``, ``<a>_vs_<m>.<s>.rmse_p_all_m.ratio``   the first
                                     method ``<a>`` of ``experiment.methods`` over each other
                                     one ``<m>``: the ratio of their position RMSEs on the same
                                     runs (below 1 favours ``<a>``; with ``method_runs``, over
                                     the runs both ran)

95 % intervals (the unit is a run, :mod:`phyloc.evaluation.statistics`): every RMSE figure
(``k<k>.rmse_*``, ``rmse_p_all_m``, ``sage.<s>.range_rmse_m``) and the mean ``sage.<s>.sigma_m``
have ``<name>.ci_low`` / ``<name>.ci_high`` (bootstrap over runs) and their per-run values in
the series ``<name>.units``; the fractions (``outage_<x>m``, ``sage.<s>.valid_fraction``) have
Clopper–Pearson intervals; every ``…_vs_….ratio`` has the paired bootstrap's interval
(``.ratio.ci_low`` / ``.ratio.ci_high``). The conditional bound ``pcrlb_cond.*`` averages the
runs' own bounds: it has an interval over runs and per-run values (``.units``), and
``rmse_over_pcrlb_cond`` has the paired bootstrap's interval over the runs the method ran (the
errors and the bounds of the same trajectories resampled together). So do the mean time per
step ``step_s`` / ``agent_s``, its stages ``stage.<stage>_s`` and
``sirbp_over_pfbp.<s>.step_ratio`` (paired over runs). The
Bayesian ``pcrlb.*`` averages the information over runs, not per-run bounds: it and
``rmse_over_pcrlb`` carry none, nor do ``pcrlb_cond_one_range.*`` and the memory figures.

Series: ``k`` (1 … K); ``<m>.<s>.rmse_p_m`` / ``rmse_v_m_s`` / ``rmse_a_m_s2`` and
``pcrlb.<s>.p_m`` / ``v_m_s`` / ``a_m_s2`` (and ``pcrlb_cond.*``) per step;
``outage_threshold_m`` (log grid) with
``<m>.<s>.k<ko>.outage`` (outage probability versus threshold, Fig. 6) and
``<m>.<s>.error_cf`` (cumulative frequency of the position error over the whole trajectory,
Fig. 4a, = 1 − outage over all steps). With PF-BP among the methods, ``flow_example.*``: the
particle flow of two cooperating agents near three anchors (PF-BP Fig. 1,
:func:`~phyloc.evaluation.range_scenarios.flow_example`), drawn as ``<recipe>_flow.png``.
With ``memory_agents``, the memory study
(:func:`~phyloc.evaluation.tracking_memory.memory_study`): figures
``<m>.<s>.peak_rss_mb`` / ``run_rss_mb`` (and per size ``<m>.<s>.agents_<n>.*``; means over
``memory_repeats`` fresh-process measurements, with their intervals and units), series
``memory_agents`` and ``<m>.<s>.peak_rss_mb_by_agents``, drawn as ``<recipe>_memory.png``.
The time per step by stage (``<m>.<s>.stage.<stage>_s``) is drawn as ``<recipe>_stages.png``.

Timings are wall times of this process; with several workers on a shared machine they include
contention. Everything except the timings is identical for a seed whatever the worker count.

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from phyloc import _validate as v
from phyloc._validate import check_keys
from phyloc.analysis.pcrlb import pcrlb
from phyloc.channels import ChannelSpec
from phyloc.errors import ValidationError
from phyloc.evaluation.experiment import Experiment
from phyloc.evaluation.methods import check_labels
from phyloc.evaluation.methods import method_plan as plan_methods
from phyloc.evaluation.range_scenarios import anchor_localizable, flow_example
from phyloc.evaluation.sections import RangingSpec, scenario_specs
from phyloc.evaluation.statistics import Paired, Pooled
from phyloc.evaluation.tracking_figures import (
    OUTAGE_GRID_M,
    UNITS,
    plot,
    summary_headers,
    summary_lines,
    summary_rows,
    threshold_name,
)
from phyloc.evaluation.tracking_memory import memory_study
from phyloc.evaluation.tracking_scenarios import gaussian_run, run_network_spec, sage_run
from phyloc.localization import METHODS
from phyloc.localization.tracking import STATE_MODELS, RangeModel, paper_prior

FAMILY = "tracking"
#: The methods of PF-BP §VI, the default of ``experiment.methods``.
DEFAULT_METHODS = ("pfbp", "pfbp_reg", "sirbp", "sirbp_reg", "spbp", "spbp_reg", "edh", "edh_reg")
MEASUREMENTS = ("gaussian", "sage")
SAGE_SIGMA_RULES = ("residual", "zzb")


@dataclass(frozen=True)
class TrackingExperimentSpec:
    """``[experiment]`` of a tracking recipe (``[experiment.fast]`` overrides for ``--fast``).

    Parameters
    ----------
    scenarios : dict
        ``{token: {"n_agents": int, "comm_range_m": float}}``; r_max omitted or ``inf``: fully
        connected.
    runs : int
        Monte Carlo runs (tasks) per scenario (PF-BP §VI: 200).
    n_steps : int
        K (40).
    methods : tuple of str
        Registered methods of the ``"tracking"`` family (default :data:`DEFAULT_METHODS`), or
        *variants*: names defined by a ``[localization.<name>]`` table whose ``method`` key
        names the registered method they run with that table's options (e.g. ``sirbp_mil``,
        SIR-BP with 10⁶ particles; checked against the recipe by :func:`method_options`).
    motion, dim, side_m, dt_s, accel_std, sigma_r
        State model, dimension, cube side [m], ΔT [s], σ_a [m/s²], range σ [m] (PF-BP §VI:
        CA, 3, 20, 0.1, 0.15, 0.1).
    sigma_p, accel_init_factor
        Prior of PF-BP eq. (31): σ_p [m] (20) and σ_ainit / σ_a (10).
    report_steps, outage_steps : tuple of int
        Steps k with scalar RMSE figures / outage curves (those > ``n_steps`` are skipped).
    outage_thresholds_m : tuple of float
        Thresholds of the scalar outage figures [m].
    measurements : {"gaussian", "sage"}
        See the module docstring.
    sage_sigma_m : float or {"residual", "zzb"}
        σ given to the trackers with ``"sage"`` measurements (see the module docstring).
    method_options : dict
        ``{method: {key: value}}`` overriding ``[localization.<method>]`` keys.
    method_runs : dict
        ``{method: n}``: run that method only in the first ``min(n, runs)`` runs of each
        scenario (its figures are over those runs, ``<m>.<s>.runs`` says how many, and its
        PCRLB ratios use the bounds of the same runs). For a method whose full setting would
        dominate the wall time (SIR-BP with 10⁶ particles: ~10 min per run); the other methods
        and every run's random streams are unchanged by it.
    memory_agents : tuple of int
        Network sizes of the memory study (:func:`memory_study`; default none: no study). Each
        method runs once per size in a fresh process and its peak resident set size is
        reported (``<m>.<s>.agents_<n>.peak_rss_mb``, ``<s>`` the first scenario, whose
        communication range the study uses); with any size the study also measures every
        scenario at its own size (``<m>.<s>.peak_rss_mb``).
    memory_steps : int
        Time steps of each memory run (1: the arrays of a step are all a run allocates).
    memory_repeats : int
        Fresh-process measurements per method and size (default 1). The figures are their
        means; with two or more they carry 95 % intervals and the methods compare paired (each
        repeat draws its own network, the same for every method), so the ledger can decide a
        claim on memory.
    """

    scenarios: dict = field(
        default_factory=lambda: {
            "s1_r18": {"n_agents": 5, "comm_range_m": 18.0},
            "s1_rinf": {"n_agents": 5},
        }
    )
    runs: int = 200
    n_steps: int = 40
    methods: tuple = DEFAULT_METHODS
    motion: str = "constant_acceleration"
    dim: int = 3
    side_m: float = 20.0
    dt_s: float = 0.1
    accel_std: float = 0.15
    sigma_r: float = 0.1
    sigma_p: float = 20.0
    accel_init_factor: float = 10.0
    report_steps: tuple = (1, 10, 20, 40)
    outage_steps: tuple = (1, 20, 40)
    outage_thresholds_m: tuple = (0.1, 0.3, 1.0)
    measurements: str = "gaussian"
    sage_sigma_m: float | str = "residual"
    method_options: dict = field(default_factory=dict)
    method_runs: dict = field(default_factory=dict)
    memory_agents: tuple = ()
    memory_steps: int = 1
    memory_repeats: int = 1

    def __post_init__(self):
        if not isinstance(self.scenarios, dict) or not self.scenarios:
            raise ValidationError(
                "experiment.scenarios", self.scenarios, "a table token = {n_agents, comm_range_m}"
            )
        scen = {}
        for tok, s in self.scenarios.items():
            name = f"experiment.scenarios.{tok}"
            if not isinstance(s, dict):
                raise ValidationError(name, s, "a table {n_agents = N, comm_range_m = r_max}")
            check_keys(s, ["n_agents", "comm_range_m"], name)
            if "n_agents" not in s:
                raise ValidationError(name + ".n_agents", "missing", "an integer >= 1")
            n = v.integer(name + ".n_agents", s["n_agents"], minimum=1)
            raw = s.get("comm_range_m", math.inf)
            try:
                r = math.nan if isinstance(raw, bool) else float(raw)
            except (TypeError, ValueError):
                r = math.nan
            if not r > 0 or math.isnan(r):
                raise ValidationError(
                    name + ".comm_range_m", raw, "a number > 0 [m] (inf: fully connected)"
                )
            scen[tok] = {"n_agents": n, "comm_range_m": r}
        object.__setattr__(self, "scenarios", scen)
        v.integer_field(self, "runs", "experiment.runs", minimum=1)
        K = v.integer("experiment.n_steps", self.n_steps, minimum=1)
        methods = check_labels(self.methods)
        known = METHODS.family(FAMILY)
        if not methods:
            raise ValidationError("experiment.methods", [], f"at least one of {', '.join(known)}")
        if len(set(methods)) != len(methods):
            raise ValidationError("experiment.methods", list(methods), "each name once")
        object.__setattr__(self, "methods", methods)
        if self.motion not in STATE_MODELS:
            raise ValidationError("experiment.motion", self.motion, f"one of {STATE_MODELS}")
        if self.dim not in (2, 3):
            raise ValidationError("experiment.dim", self.dim, "2 or 3")
        for name in ("side_m", "dt_s", "sigma_r", "sigma_p"):
            v.positive(f"experiment.{name}", getattr(self, name))
        v.positive("experiment.accel_std", self.accel_std, allow_zero=True)
        v.positive("experiment.accel_init_factor", self.accel_init_factor, allow_zero=True)
        for name in ("report_steps", "outage_steps"):
            steps = tuple(
                v.integer(f"experiment.{name}", k, minimum=1) for k in getattr(self, name)
            )
            object.__setattr__(self, name, tuple(k for k in steps if k <= K))
        thr = tuple(
            v.positive("experiment.outage_thresholds_m", x) for x in self.outage_thresholds_m
        )
        object.__setattr__(self, "outage_thresholds_m", thr)
        if self.measurements not in MEASUREMENTS:
            raise ValidationError(
                "experiment.measurements", self.measurements, f"one of {MEASUREMENTS}"
            )
        if not (isinstance(self.sage_sigma_m, str) and self.sage_sigma_m in SAGE_SIGMA_RULES):
            if isinstance(self.sage_sigma_m, str):
                raise ValidationError(
                    "experiment.sage_sigma_m",
                    self.sage_sigma_m,
                    f"a number [m] or one of {', '.join(SAGE_SIGMA_RULES)}",
                )
            v.positive("experiment.sage_sigma_m", self.sage_sigma_m)
        if not isinstance(self.method_options, dict):
            raise ValidationError(
                "experiment.method_options", self.method_options, "a table {method = {key = value}}"
            )
        for m in self.method_options:
            if m not in methods:
                raise ValidationError(
                    "experiment.method_options", m, f"keys from {', '.join(methods)}"
                )
        if not isinstance(self.method_runs, dict):
            raise ValidationError(
                "experiment.method_runs", self.method_runs, "a table {method = runs}"
            )
        runs = {}
        for m, n in self.method_runs.items():
            if m not in methods:
                raise ValidationError(
                    "experiment.method_runs", m, f"keys from {', '.join(methods)}"
                )
            runs[m] = v.integer(f"experiment.method_runs.{m}", n, minimum=1)
        object.__setattr__(self, "method_runs", runs)
        sizes = tuple(
            v.integer("experiment.memory_agents", n, minimum=1) for n in self.memory_agents
        )
        object.__setattr__(self, "memory_agents", sizes)
        v.integer_field(self, "memory_steps", "experiment.memory_steps", minimum=1)
        v.integer_field(self, "memory_repeats", "experiment.memory_repeats", minimum=1)

    def model(self) -> RangeModel:
        """The :class:`RangeModel` of the recipe."""
        return RangeModel(self.motion, self.dim, self.dt_s, self.accel_std, self.sigma_r)


def method_plan(localization: dict, exp: TrackingExperimentSpec) -> dict:
    """``{label: (registered name, options)}`` of ``experiment.methods``
    (:func:`phyloc.evaluation.methods.method_plan`): shared ``[localization]`` keys, the
    label's ``[localization.<label>]`` table, then ``experiment.method_options.<label>``."""
    return plan_methods(localization, exp.methods, FAMILY, overrides=exp.method_options)


def method_bases(localization: dict, exp: TrackingExperimentSpec) -> dict:
    """The registered method each label of ``experiment.methods`` runs."""
    return {label: name for label, (name, _) in method_plan(localization, exp).items()}


def method_options(localization: dict, exp: TrackingExperimentSpec) -> dict:
    """The options object of every label of ``experiment.methods``."""
    return {label: opts for label, (_, opts) in method_plan(localization, exp).items()}


def _task(payload, seed_seq):
    """One Monte Carlo run of one scenario: measurements, prior, every method."""
    exp, scen, options, bases, extra, run_index = payload
    streams = seed_seq.spawn(2 + len(exp.methods))
    rng = np.random.default_rng(streams[0])
    if exp.measurements == "gaussian":
        sc, info = gaussian_run(exp, scen, rng)
        meas = sc.measurements()
    else:
        sc, info = sage_run(exp, scen, *extra, rng)
        model = dataclasses.replace(sc.model, sigma_r=info["sigma_m"])
        meas = dataclasses.replace(sc.measurements(), model=model)
    prior = paper_prior(
        meas,
        np.random.default_rng(streams[1]),
        sigma_p=exp.sigma_p,
        accel_init_factor=exp.accel_init_factor,
    )
    d = exp.dim
    out = {"scenario": sc, "prior_cov": prior.cov, "sage": info}
    for s, m in zip(streams[2:], exp.methods, strict=True):
        if run_index >= exp.method_runs.get(m, exp.runs):
            continue  # experiment.method_runs: this method runs in the first runs only
        res = METHODS[bases[m]].run(meas, prior, np.random.default_rng(s), options[m])
        for b, name in enumerate("pva"[: sc.model.order]):
            e = res.estimates[..., b * d : (b + 1) * d] - sc.states[..., b * d : (b + 1) * d]
            out[f"{m}|e_{name}"] = np.linalg.norm(e, axis=-1)  # [K, n_agents]
        out[f"{m}|step_s"] = res.timing.step_s
        out[f"{m}|agent_s"] = res.timing.agent_s
        out[f"{m}|stage_s"] = res.diagnostics.get("stage_s", {})
        out[f"{m}|floats"] = float(res.diagnostics.get("floats_per_link_iteration", np.nan))
    return out


def pooled_at(p: Pooled, point) -> Pooled:
    """``p`` with the point value computed over every unit's values at once
    (:meth:`~phyloc.evaluation.statistics.Pooled.at`)."""
    return p.at(point)


def _bound_units(mean_square) -> Pooled:
    """Per-run mean-square bounds ``[runs]`` as an RMSE-type figure over runs (one unit per
    run, as the errors' units: each run's agents weigh alike)."""
    ms = np.asarray(mean_square, dtype=np.float64)
    return Pooled(ms, np.ones_like(ms), "rmse")


def _comparisons(figures, parts, methods, tok, report_steps):
    """Paired ratios of the position RMSE (at the report steps and over the whole trajectory)
    over the same runs: the first method against every other (``<first>_vs_<m>``; a ratio
    below 1 favours the first). With ``experiment.method_runs`` the ratio is over the runs
    both methods ran (then not the ratio of the two written figures)."""
    a = methods[0]
    names = [f"k{k}.rmse_p_m" for k in report_steps] + ["rmse_p_all_m"]
    for b in methods[1:]:
        both = [p for p in parts if f"{a}|e_p" in p and f"{b}|e_p" in p]
        same = all((f"{a}|e_p" in p) == (f"{b}|e_p" in p) for p in parts)
        for name in names:
            if same:
                pa, pb = figures[f"{a}.{tok}.{name}"], figures[f"{b}.{tok}.{name}"]
            else:
                pa, pb = (_rmse_p_units(both, m, name) for m in (a, b))
            figures[f"{a}_vs_{b}.{tok}.{name}"] = Paired(pa, pb)


def _rmse_p_units(parts, m, name) -> Pooled:
    """The position RMSE ``name`` (``k<k>.rmse_p_m`` or ``rmse_p_all_m``) of method ``m`` over
    the runs ``parts``."""
    if name == "rmse_p_all_m":
        return Pooled.rmse([p[f"{m}|e_p"] for p in parts])
    k = int(name.split(".")[0][1:])
    return Pooled.rmse([p[f"{m}|e_p"][k - 1] for p in parts])


def _aggregate(keys, results, exp):
    K = exp.n_steps
    figures: dict[str, object] = {}
    series: dict[str, object] = {
        "k": np.arange(1, K + 1),
        "outage_threshold_m": OUTAGE_GRID_M,
    }
    blocks = "pva"[: exp.model().order]
    for tok in exp.scenarios:
        parts = [res for (t, _), res in zip(keys, results, strict=True) if t == tok]
        scs, P0 = [p["scenario"] for p in parts], parts[0]["prior_cov"]
        first = scs[0]  # PF-BP Fig. 3: one realization, coloured by its anchor connections
        series[f"{tok}.example_positions_m"] = first.positions()
        series[f"{tok}.example_anchor_links"] = np.isfinite(first.z[:, :, first.n_agents :]).sum(
            axis=2
        )
        series[f"{tok}.anchors_m"] = first.anchors
        # PF-BP Fig. 3 over every run: positions the anchors alone locate, fewest anchor links
        figures[f"{tok}.anchor_localizable_fraction"] = Pooled.mean(
            [anchor_localizable(sc).ravel() for sc in scs]
        )
        figures[f"{tok}.min_anchor_links"] = int(
            min(np.isfinite(sc.z[:, :, sc.n_agents :]).sum(axis=2).min() for sc in scs)
        )
        bound = pcrlb(scs, P0).bounds
        cond_all = pcrlb(scs, P0, average="bound")
        cond, cond_runs = cond_all.bounds, cond_all.per_scenario  # per run: [runs, K]
        cond_one = pcrlb(scs, P0, average="bound", pairs="one").bounds
        for b in blocks:
            series[f"pcrlb.{tok}.{UNITS[b]}"] = bound[b]
            series[f"pcrlb_cond.{tok}.{UNITS[b]}"] = cond[b]
            for k in exp.report_steps:
                figures[f"pcrlb.{tok}.k{k}.{UNITS[b]}"] = float(bound[b][k - 1])
                # the conditional bound averages the runs' own bounds: an interval over runs
                figures[f"pcrlb_cond.{tok}.k{k}.{UNITS[b]}"] = pooled_at(
                    _bound_units(cond_runs[b][:, k - 1]), cond[b][k - 1]
                )
            for k in exp.report_steps:
                figures[f"pcrlb_cond_one_range.{tok}.k{k}.{UNITS[b]}"] = float(cond_one[b][k - 1])
        if exp.measurements == "sage":
            info = [p["sage"] for p in parts]
            n_valid = sum(i["n_valid"] for i in info)
            sq = sum(i["sq_err_sum"] for i in info)
            figures[f"sage.{tok}.range_rmse_m"] = pooled_at(
                Pooled([i["sq_err_sum"] for i in info], [i["n_valid"] for i in info], "rmse"),
                math.sqrt(sq / n_valid) if n_valid else math.nan,
            )
            n_links = sum(i["n_links"] for i in info)
            valid = n_valid / max(n_links, 1)  # no links at all: 0
            figures[f"sage.{tok}.valid_fraction"] = (
                pooled_at(
                    Pooled([i["n_valid"] for i in info], [i["n_links"] for i in info], "fraction"),
                    valid,
                )
                if n_links
                else valid
            )
            sigma = [i["sigma_m"] for i in info]
            figures[f"sage.{tok}.sigma_m"] = pooled_at(Pooled.mean(sigma), np.mean(sigma))
        for m in exp.methods:
            base = f"{m}.{tok}"
            ran = [i for i, p in enumerate(parts) if f"{m}|e_p" in p]  # experiment.method_runs
            m_parts = [parts[i] for i in ran]
            figures[f"{base}.runs"] = len(m_parts)
            m_bound, m_cond = bound, cond
            if len(m_parts) < len(parts):  # the bounds of the runs this method ran
                m_bound = pcrlb([p["scenario"] for p in m_parts], P0).bounds
                # the conditional bound averages per-run bounds: those of its runs, kept above
                m_cond = {b: np.sqrt(cond_runs[b][ran].mean(axis=0)) for b in blocks}
            for b in blocks:
                e = np.concatenate([p[f"{m}|e_{b}"] for p in m_parts], axis=1)  # [K, runs·agents]
                rmse = np.sqrt(np.mean(e**2, axis=1))
                series[f"{base}.rmse_{UNITS[b]}"] = rmse
                for k in exp.report_steps:  # per run: its agents' errors at step k
                    figures[f"{base}.k{k}.rmse_{UNITS[b]}"] = pooled_at(
                        Pooled.rmse([p[f"{m}|e_{b}"][k - 1] for p in m_parts]), rmse[k - 1]
                    )
            ep = np.concatenate([p[f"{m}|e_p"] for p in m_parts], axis=1)
            for k in exp.report_steps:
                rmse_k = figures[f"{base}.k{k}.rmse_p_m"]
                # the Bayesian bound averages information, not per-run bounds: no interval
                figures[f"{base}.k{k}.rmse_over_pcrlb"] = float(rmse_k.value / m_bound["p"][k - 1])
                # over the conditional bound of the same runs: the paired bootstrap over runs
                m_cond_k = pooled_at(_bound_units(cond_runs["p"][ran, k - 1]), m_cond["p"][k - 1])
                figures[f"{base}.k{k}.rmse_over_pcrlb_cond"] = Paired(rmse_k, m_cond_k, suffix="")
            figures[f"{base}.rmse_p_all_m"] = pooled_at(
                Pooled.rmse([p[f"{m}|e_p"] for p in m_parts]), np.sqrt(np.mean(ep**2))
            )
            for k in exp.outage_steps:
                ek = ep[k - 1]
                series[f"{base}.k{k}.outage"] = np.mean(ek[:, None] > OUTAGE_GRID_M, axis=0)
                for x in exp.outage_thresholds_m:
                    figures[f"{base}.k{k}.outage_{threshold_name(x)}"] = pooled_at(
                        Pooled.fraction([p[f"{m}|e_p"][k - 1] > x for p in m_parts]),
                        np.mean(ek > x),
                    )
            series[f"{base}.error_cf"] = np.mean(ep.reshape(-1)[:, None] <= OUTAGE_GRID_M, axis=0)
            # wall times: per run its median step, the figure their mean over runs
            figures[f"{base}.step_s"] = Pooled.mean(
                [[np.median(p[f"{m}|step_s"])] for p in m_parts]
            )
            if not np.all(np.isnan(m_parts[0][f"{m}|agent_s"])):  # NaN: no distributed form
                figures[f"{base}.agent_s"] = Pooled.mean(
                    [[np.median(p[f"{m}|agent_s"])] for p in m_parts]
                )
            for stage in m_parts[0][f"{m}|stage_s"]:  # the step by stage, the same way
                figures[f"{base}.stage.{stage}_s"] = Pooled.mean(
                    [[np.median(p[f"{m}|stage_s"][stage])] for p in m_parts]
                )
            floats = m_parts[0][f"{m}|floats"]
            if not np.isnan(floats):  # NaN: exchanges no beliefs (edh)
                figures[f"{base}.floats_per_link_iteration"] = floats
        _comparisons(figures, parts, exp.methods, tok, exp.report_steps)
        if "sirbp" in exp.methods and "pfbp" in exp.methods:
            sir, pf = figures[f"sirbp.{tok}.step_s"], figures[f"pfbp.{tok}.step_s"]
            if sir.n_units == pf.n_units:  # both ran every run: paired over runs
                figures[f"sirbp_over_pfbp.{tok}.step_ratio"] = Paired(sir, pf, suffix="")
            else:
                figures[f"sirbp_over_pfbp.{tok}.step_ratio"] = sir.value / pf.value
    return figures, series


class TrackingExperiment(Experiment):
    """``kind = "tracking"``: one task per (scenario token, Monte Carlo run), every method on
    the same trajectories and ranges; then PF-BP Fig. 1's flow example and the memory study."""

    kind = "tracking"
    title = "range-level cooperative tracking against the PCRLB (PF-BP Figs. 4–7, Tables I–II)"
    unit = "run"
    spec = TrackingExperimentSpec
    task = staticmethod(_task)

    def prepare(self, recipe, *, fast=False):
        exp = self.experiment_spec(recipe, fast=fast)
        exp.model()  # validates the model
        plan = method_plan(recipe.section("localization"), exp)
        options = {label: opts for label, (_, opts) in plan.items()}
        bases = {label: name for label, (name, _) in plan.items()}
        extra = None
        if exp.measurements == "sage":
            chan = recipe.section("channel", ChannelSpec)
            chan = scenario_specs(chan, {"channel": chan.scenario})["channel"]
            extra = (recipe.system, chan, recipe.section("ranging", RangingSpec))
        for tok, scen in exp.scenarios.items():  # every network before any work starts
            try:
                run_network_spec(exp, scen)
            except ValidationError as exc:
                raise ValidationError(
                    f"experiment.scenarios.{tok}.{exc.field}", exc.value, exc.allowed
                ) from None
        return SimpleNamespace(exp=exp, options=options, bases=bases, extra=extra)

    def tasks(self, plan):
        exp = plan.exp
        return [
            ((tok, r), (exp, scen, plan.options, plan.bases, plan.extra, r))
            for tok, scen in exp.scenarios.items()
            for r in range(exp.runs)
        ]

    def aggregate(self, plan, keys, results, ctx):
        exp, options, bases = plan.exp, plan.options, plan.bases
        figures, series = _aggregate(keys, results, exp)
        if "pfbp" in bases.values():  # PF-BP Fig. 1: the flow of two cooperating agents
            example = flow_example(np.random.default_rng(np.random.SeedSequence(ctx.seed)))
            for key, value in example.items():
                series[f"flow_example.{key}"] = value
        if exp.memory_agents:
            mem = memory_study(exp, options, bases, ctx.seed, progress=ctx.progress)
            figures.update(mem)
            first = next(iter(exp.scenarios))
            series["memory_agents"] = np.asarray(exp.memory_agents)
            for m in exp.methods:
                series[f"{m}.{first}.peak_rss_mb_by_agents"] = np.array(
                    [mem[f"{m}.{first}.agents_{n}.peak_rss_mb"].value for n in exp.memory_agents]
                )
        return figures, series

    def meta(self, plan, ctx):
        exp, options, bases = plan.exp, plan.options, plan.bases
        meta = {
            "runs": exp.runs,
            "method_runs": {m: min(n, exp.runs) for m, n in exp.method_runs.items()},
            "n_steps": exp.n_steps,
            "scenarios": {t: dict(s) for t, s in exp.scenarios.items()},
            "methods": list(exp.methods),
            "blocks": list("pva"[: exp.model().order]),
            "report_steps": list(exp.report_steps),
            "outage_steps": list(exp.outage_steps),
            "outage_thresholds_m": list(exp.outage_thresholds_m),
            "measurements": exp.measurements,
            "options": {m: dataclasses.asdict(o) for m, o in options.items()},
            "labels": {m: METHODS[m].label if m == b else m for m, b in bases.items()},
            "bases": dict(bases),
            "memory_agents": list(exp.memory_agents),
            "memory_repeats": exp.memory_repeats,
            "timing": "median wall time over all steps of all runs (includes worker contention)",
        }
        if exp.measurements == "sage":
            meta["pcrlb_note"] = (
                "Gaussian-model PCRLB at experiment.sigma_r on the valid SAGE links"
            )
        if exp.measurements == "sage":
            meta["pcrlb_note"] = (
                "Gaussian-model PCRLB at experiment.sigma_r on the valid SAGE links"
            )
        return meta

    summary_rows = staticmethod(summary_rows)
    summary_headers = staticmethod(summary_headers)
    summary_lines = staticmethod(summary_lines)
    plot = staticmethod(plot)


TRACKING = TrackingExperiment()

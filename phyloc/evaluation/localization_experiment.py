"""Direct versus two-step network localization (DiPNet Fig. 5).

A recipe of ``kind = "localization"`` runs, for every scenario token, network size and
realization: a network (``[network]``, anchor-free and fully meshed in the paper), channel draws,
received signals and correlation tables, the range estimators, and then every method of
``experiment.methods`` under every initialization of ``experiment.inits`` — all on the *same*
waveforms and, per initialization, from the *same* prior particles (per particle count).

A network with motion (``[network.motion]``, or a stored dataset with several snapshots) is
localized over **all** its snapshots: snapshot 0 from the prior, every later snapshot from the
prediction of the previous belief with the methods' mobility model (the DPF of
:func:`phyloc.localization.direct.run`, ``process_std_m``; DiPNet §II-C), the same model for
every agent. Errors are then pooled over snapshots; the RMSE per snapshot is a series. Methods::

    ``dipnet``            DiPNet with phyloc's safeguards: the marginal equivalent likelihood
                          (:class:`~phyloc.localization.direct.likelihoods.MarginalDirectLikelihood`,
                          DiPNet eq. (22) marginalized over the neighbour's projected uncertainty
                          instead of the ENV of DiPNet eq. (26)), adaptive tempering,
                          resample-move, covariance floor (:class:`~phyloc.localization.DPFOptions`)
    ``dipnet_published``  DiPNet Algorithm 1 as published: DiPNet eqs. (25)–(28) with the ENV, no
                          safeguards
    ``corr`` / ``first_peak`` / ``sage``   the two-step EL-DPF on that estimator's ranges with the
                          ZZB ranging variance (DiPNet §V-A), same safeguards as ``dipnet``,
                          its per-link outlier bound ``outlier_nats`` included (``inf`` gives
                          DiPNet §V-A's plain Gaussian, whose error grows with the SNR in NLOS
                          channels: see :class:`~phyloc.localization.GaussianRangeLikelihood`)
    ``sage_los``          SAGE on LOS links only — an oracle benchmark (ground-truth NLOS rejection)

The methods are the direct family of :data:`phyloc.localization.METHODS` (any registered
direct method runs here too): per realization the experiment builds one
:class:`~phyloc.localization.LinkMeasurements` — the correlation tables and the ranges of every
estimator a method's ``inputs`` names — and calls ``method.run(measurements, prior, rng,
method.make_options([localization]))``; the truth enters only the metrics.

Initializations (labelled in every figure name)::

    ``truth_free`` (token ``<s>``)  Gaussian priors around a coarse two-step solution (MDS → SMACOF
                          on the correlation-peak ranges, the shorter of a pair's two
                          directions, then Cauchy-reweighted SMACOF so NLOS-biased ranges stop
                          pulling — one-sided: only ranges longer than the fit; links the NLOS
                          identification rejects left out; anchors fix the frame when present)
    ``informed`` (``<s>_informed``)  Gaussian priors around the truth plus N(0, σ0²) — an informed
                          start, not a truth-free result
    ``gauge`` (``<s>_gauge``)  the paper's uninformative anchor-free gauge priors (shows the
                          pitfall)

Figures: ``<method>.<token>.agents_<n>.framework_rmse_m`` (DiPNet eq. (4), pooled over
realizations and snapshots), ``<method>.<token>.agents_<n>.agent_snapshot_s`` (filter time per
agent and snapshot),
``<method>.<token>.agents_<n>.shape_difference_m`` (DiPNet eq. (1)),
``<method>.<token>.agents_<n>.ess_min`` (smallest effective sample size of any agent in any
iteration, mean over runs),
``start.<token>.agents_<n>.framework_rmse_m`` (the prior centres themselves: what a method
starts from — the coarse truth-free solution, or the perturbed truth),
with anchors ``<method>.<token>.agents_<n>.position_rmse_m`` and the 50 / 80 / 90 % points of
the absolute position errors ``.position_error_p{50,80,90}_m``, in 3-D also
``.horizontal_rmse_m`` and ``.horizontal_error_p{50,80,90}_m`` (the horizontal error 3GPP
positioning studies report; intervals from the cluster bootstrap over realizations,
:class:`~phyloc.evaluation.statistics.Quantile`),
``<method>.<token>.agents_<n>.framework_rmse_observable_m`` (DiPNet eq. (4) over the *observable*
pairs only: those whose distance the detected links determine, :func:`observable_pairs`),
``<token>.agents_<n>.unobservable_pair_fraction`` (the share of pairs left out there: no method,
the oracle included, can estimate them),
``<method>.<token>.agents_<n>.nees`` (normalized estimation error squared ``eᵀP⁻¹e`` of the
published covariance, per agent after rigid alignment, mean over agents and realizations:
``dim`` when calibrated) and ``.error_to_belief_ratio`` ``= sqrt(nees/dim)`` (> 1: overconfident;
``.error_to_belief_ratio_median`` the same from the median NEES over the median of χ²_dim, robust
to a few lost agents),
``<method>.runtime_per_agent_iteration_s``, ``<s>.link_bias.<los|nlos>_mean_m`` (correlation-peak
range bias, pooled over snapshots). Cost per size: ``<s>.agents_<n>.<stage>_s`` (``waveforms``,
``tables``, ``ranging_<estimator>``, ``start_<init>``), ``<method>.<s>.agents_<n>.iteration_s``
and ``.chain_s``, ``<s>.agents_<n>.peak_rss_mb``, ``<s>.agents_<n>.mean_neighbours``, the
start's ``start.<s>.agents_<n>.undetermined_agent_fraction`` and, over several sizes,
``<method>.<s>.iteration_s_exponent`` / ``_link_exponent`` (drawn as ``<recipe>_cost.png``).
In a range-limited network DiPNet eq. (4) runs over the links
(:func:`~phyloc.evaluation.front_end.scored_pairs`). Series: error CDFs at
``experiment.cdf_agents``, per iteration at the largest network (snapshot 0): mean ESS,
published std ``sqrt(tr C/dim)`` and actual error of the published means; with several snapshots
``<method>.<token>.agents_<n>.rmse_by_snapshot``.

Uncertainty (:mod:`phyloc.evaluation.statistics`; the unit is a realization): the RMSE figures
(methods and start, all pairs and observable pairs), ``shape_difference_m``, ``nees``,
``<method>.<token>.agents_<n>.outlier_fraction`` (the share of pairs whose error exceeds
:data:`~phyloc.evaluation.localization_aggregation.OUTLIER_M`), the unobservable-pair and
undetermined-agent fractions and the link biases
carry ``.ci_low`` / ``.ci_high`` (95 %; bootstrap over realizations, the LOS fraction exact
binomial) and their per-realization values in ``series`` (``<name>.units``). Paired ratios of
``framework_rmse_m`` over the same realizations: ``<method>_vs_start.<token>.agents_<n>.
framework_rmse_m.ratio`` (a method against the start it ran from) and
``<first>_vs_<method>...ratio`` (the recipe's first method against each other one), each with
its interval.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from phyloc import _validate as v
from phyloc.channels import ChannelSpec
from phyloc.datasets.simulate import check_heights, simulate_realization
from phyloc.errors import ValidationError
from phyloc.evaluation.experiment import Experiment, RunContext
from phyloc.evaluation.front_end import localize_realization
from phyloc.evaluation.localization_aggregation import aggregate
from phyloc.evaluation.localization_figures import INITS, _reads_tables, plot, plot_cost  # noqa: F401
from phyloc.evaluation.rss import peak_rss_mb, reset_peak_rss, status_mb
from phyloc.evaluation.sections import (
    LocalizationSpec,
    RangingSpec,
    network_specs,
    scenario_specs,
)
from phyloc.localization import METHODS as REGISTRY
from phyloc.reporting import with_interval

METHODS = REGISTRY.family("direct")
"""The methods this experiment can run: every registered method of the direct family."""


@dataclass(frozen=True)
class LocalizationExperimentSpec:
    """``[experiment]`` of a localization recipe (``[experiment.fast]`` for ``--fast``).

    ``scenario_localization`` (``{token: {key: value}}``, default none) replaces top-level
    ``[localization]`` keys for one scenario, e.g. a channel's own range model error:
    ``scenario_localization = { d1 = { model_error_m = 0.55 } }``. A method's own subtable
    ``[localization.<method>]`` still wins over it.
    """

    scenarios: dict = field(default_factory=lambda: {"c2": "winner2_c2", "d1": "winner2_d1"})
    agents: tuple = (3, 6, 9, 12, 15, 18, 21, 24, 27, 30)
    realizations: int = 10
    methods: tuple = METHODS
    inits: tuple = ("truth_free", "informed")
    cdf_agents: tuple = (3, 30)
    scenario_localization: dict = field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.scenarios, dict) or not self.scenarios:
            raise ValidationError("experiment.scenarios", self.scenarios, "token = scenario name")
        if not isinstance(self.scenario_localization, dict):
            raise ValidationError(
                "experiment.scenario_localization",
                self.scenario_localization,
                "a table {token = {[localization] key = value}}",
            )
        for tok, over in self.scenario_localization.items():
            if tok not in self.scenarios:
                raise ValidationError(
                    "experiment.scenario_localization",
                    tok,
                    f"a scenario token of experiment.scenarios: {', '.join(self.scenarios)}",
                )
            if not isinstance(over, dict):
                raise ValidationError(
                    f"experiment.scenario_localization.{tok}",
                    over,
                    "a table of [localization] keys",
                )
        for key in ("agents", "methods", "inits", "cdf_agents"):
            value = getattr(self, key)
            if isinstance(value, str | bytes | dict) or not hasattr(value, "__iter__"):
                raise ValidationError(f"experiment.{key}", value, "a list")
        agents = tuple(v.integer("experiment.agents", a, minimum=2) for a in self.agents)
        if not agents:
            raise ValidationError("experiment.agents", [], "at least one size >= 2")
        object.__setattr__(self, "agents", agents)
        v.integer_field(self, "realizations", "experiment.realizations", minimum=1)
        if isinstance(self.methods, str) or not tuple(self.methods):
            direct = REGISTRY.family("direct")
            raise ValidationError(
                "experiment.methods", list(self.methods), f"at least one of {', '.join(direct)}"
            )
        for i in self.inits:
            if i not in INITS:
                raise ValidationError("experiment.inits", i, f"each one of {', '.join(INITS)}")
        object.__setattr__(self, "methods", tuple(self.methods))
        object.__setattr__(self, "inits", tuple(self.inits))
        object.__setattr__(self, "cdf_agents", tuple(int(a) for a in self.cdf_agents))


def _task(payload, seed_seq):
    """Simulate one realization (stream: the task's seed sequence itself) and localize."""
    system, net_spec, chan_spec, rspec, lspec, methods, inits = payload
    own_peak = reset_peak_rss()  # the task's own peak RSS where the kernel allows it
    clock = time.perf_counter()
    real = simulate_realization(system, net_spec, chan_spec, np.random.default_rng(seed_seq))
    waveforms_s = time.perf_counter() - clock
    out = localize_realization(real, system, rspec, lspec, methods, inits, seed_seq)
    out["stage_s"] = {"waveforms": waveforms_s, **out["stage_s"]}
    out["peak_rss_mb"] = status_mb("VmHWM") if own_peak else peak_rss_mb()
    return out


def _dataset_task(payload, seed_seq):
    """Read one stored realization and localize (same streams as the in-memory path)."""
    from phyloc.datasets import open as open_dataset

    path, r, rspec, lspec, methods, inits = payload
    with open_dataset(path) as ds:
        real = ds.realization(r)
        system = ds.system
    return localize_realization(real, system, rspec, lspec, methods, inits, seed_seq)


@dataclass(frozen=True)
class LocalizationPlan:
    """What a localization run runs: the system, ``[experiment]``, ``[ranging]``, the
    ``[localization]`` of every scenario token, the networks per size and the channels per
    token."""

    system: object
    exp: LocalizationExperimentSpec
    rspec: RangingSpec
    lspec: LocalizationSpec
    lspecs: dict
    nets: dict
    specs: dict
    dataset: str | None = None


def scenario_localization_specs(recipe, exp, lspec) -> dict:
    """``{token: LocalizationSpec}``: ``lspec`` with ``experiment.scenario_localization``
    applied per scenario (errors name the key under ``experiment.scenario_localization``)."""
    raw = recipe.section("localization")
    out = {}
    for tok in exp.scenarios:
        over = exp.scenario_localization.get(tok)
        if not over:
            out[tok] = lspec
            continue
        try:
            out[tok] = LocalizationSpec.from_dict({**raw, **over})
        except ValidationError as exc:
            key = exc.field.removeprefix("localization").lstrip(".")
            where = f"experiment.scenario_localization.{tok}" + (f".{key}" if key else "")
            raise ValidationError(where, exc.value, exc.allowed) from None
    return out


class LocalizationExperiment(Experiment):
    """``kind = "localization"``: one task per (scenario token, network size, realization),
    every method and initialization on the same waveforms."""

    kind = "localization"
    title = "direct versus two-step network localization (DiPNet Fig. 5)"
    unit = "realization"
    spec = LocalizationExperimentSpec
    task = staticmethod(_task)

    def prepare(self, recipe, *, fast=False) -> LocalizationPlan:
        exp = self.experiment_spec(recipe, fast=fast)
        rspec = recipe.section("ranging", RangingSpec)
        lspec = recipe.section("localization", LocalizationSpec)
        nets = network_specs(recipe.section("network"), exp.agents)
        specs = scenario_specs(recipe.section("channel", ChannelSpec), exp.scenarios)
        check_heights(nets.values(), specs.values())
        lspecs = scenario_localization_specs(recipe, exp, lspec)
        for spec in lspecs.values():  # every label a direct-family method (methods.py)
            spec.plan(exp.methods)
        return LocalizationPlan(recipe.system, exp, rspec, lspec, lspecs, nets, specs)

    def tasks(self, plan: LocalizationPlan):
        exp = plan.exp
        return [
            (
                (tok, n, r),
                (
                    plan.system,
                    plan.nets[n],
                    spec,
                    plan.rspec,
                    plan.lspecs[tok],
                    exp.methods,
                    exp.inits,
                ),
            )
            for tok, spec in plan.specs.items()
            for n in exp.agents
            for r in range(exp.realizations)
        ]

    def aggregate(self, plan, keys, results, ctx):
        return aggregate(keys, results, plan.exp, list(plan.specs))

    def meta(self, plan, ctx):
        exp, lspec = plan.exp, plan.lspec
        return {
            "agents": list(exp.agents),
            "realizations": exp.realizations,
            "scenarios": dict(exp.scenarios),
            "scenario_localization": {k: dict(o) for k, o in exp.scenario_localization.items()},
            "methods": list(exp.methods),
            "inits": {i: i.replace("_", "-") for i in exp.inits},
            "labels": {
                "informed": "informed start (truth + N(0, σ0²))",
                "gauge": "uninformative gauge priors",
                "truth_free": "truth-free",
                "sage_los": "oracle: NLOS links rejected by ground truth",
            },
            "n_particles": lspec.dpf.n_particles,
            "n_iterations": lspec.dpf.n_iterations,
        }

    def summary_rows(self, results):
        return summary_rows(results)

    def summary_headers(self, results):
        return summary_headers(results)

    def summary_lines(self, results):
        return summary_lines(results)

    def plot(self, results, path):
        plot(results, path)


class DatasetLocalization(LocalizationExperiment):
    """``phyloc evaluate DATASET.h5``: the localization experiment on a dataset's stored
    waveforms (one task per stored realization)."""

    task = staticmethod(_dataset_task)

    def prepare_dataset(self, path, *, fast: bool = False):
        """The recipe stored in dataset ``path`` and the plan of evaluating it (with ``fast``
        the first realization only)."""
        from phyloc.datasets import open as open_dataset

        with open_dataset(path) as ds:
            recipe = ds.load_recipe()
            n_real = ds.n_realizations
            net = ds.realization(0).network
        exp, rspec, lspec, token = dataset_specs(recipe, net.n_agents, 1 if fast else n_real)
        plan = LocalizationPlan(
            None, exp, rspec, lspec, {token: lspec}, {net.n_agents: None}, {token: None}, str(path)
        )
        return recipe, plan

    def tasks(self, plan: LocalizationPlan):
        ((token, n),) = ((t, n) for t in plan.specs for n in plan.nets)
        exp = plan.exp
        return [
            ((token, n, r), (plan.dataset, r, plan.rspec, plan.lspec, exp.methods, exp.inits))
            for r in range(exp.realizations)
        ]

    def run_dataset(self, path, *, fast=False, workers=None, scheduler=None, progress=True):
        """Run the localization methods on the waveforms of a dataset (``phyloc generate``).

        Methods, initializations and filter options come from the dataset's stored recipe
        (``[experiment]`` methods/inits, ``[ranging]``, ``[localization]``; defaults
        otherwise); every realization is one task, seeded like the realization itself, so the
        results equal those of the same recipe evaluated in memory (up to the complex64
        storage of the samples). With ``fast`` only the first realization is used.
        """
        recipe, plan = self.prepare_dataset(path, fast=fast)
        ctx = RunContext(recipe.seed, fast, workers, scheduler, progress)
        res = self.execute(plan, ctx)
        head = {"recipe": recipe.name, "kind": "localization", "seed": recipe.seed, "fast": fast}
        res["meta"] = {**head, **res["meta"], "dataset": str(path)}
        return res


DATASET_EXPERIMENT_KEYS = ("methods", "inits", "fast")
"""Keys of a dataset recipe's ``[experiment]`` (what ``phyloc evaluate DATASET`` runs)."""


def dataset_specs(recipe, n_agents: int, n_realizations: int):
    """What ``phyloc evaluate DATASET`` runs on a dataset of ``recipe``: the experiment
    (``[experiment]`` methods and inits), ranging and localization specs, and the scenario
    token. Validates those sections with the messages ``evaluate`` gives (``phyloc generate``
    calls it through :func:`check_dataset_recipe` before any work).
    """
    raw = dict(recipe.section("experiment"))
    v.check_keys(raw, DATASET_EXPERIMENT_KEYS, "experiment")
    raw.pop("fast", None)
    scenario = recipe.section("channel", ChannelSpec).scenario
    token = scenario.split("_", 1)[1] if scenario.startswith("winner2_") else scenario
    exp = LocalizationExperimentSpec(
        scenarios={token: scenario},
        agents=(n_agents,),
        realizations=n_realizations,
        methods=raw.get("methods", METHODS),
        inits=raw.get("inits", ("truth_free",)),
        cdf_agents=(n_agents,),
    )
    rspec = recipe.section("ranging", RangingSpec)
    lspec = recipe.section("localization", LocalizationSpec)
    lspec.plan(exp.methods)  # every label a direct-family method, before any work
    return exp, rspec, lspec, token


def check_dataset_recipe(recipe) -> None:
    """Validate the sections of a dataset recipe that only ``phyloc evaluate`` reads
    (``[experiment]``, ``[ranging]``, ``[localization]``), so ``phyloc generate`` fails before
    hours of work instead of ``evaluate`` after them."""
    from phyloc.datasets.plan import plan_dataset

    plan = plan_dataset(recipe)
    dataset_specs(plan.recipe, plan.network.n_agents, plan.dataset.realizations)


SUMMARY_HEADERS = ["scenario", "method"]


#: The label of the start's row in the printed table: the coarse solution every filter starts
#: from is computed centrally (from every link's range), the filters are distributed.
START_ROW = "start (centralized)"


def summary_rows(results: dict):
    """Framework RMSE [m] per method and scenario token (columns: network sizes), with its
    95 % interval when the run has one; the start each method ran from is the first row of a
    scenario (labelled as the centralized solution it is)."""
    f, meta = results["figures"], results["meta"]
    rows = []
    for tok in meta["scenarios"]:
        for init in meta["inits"]:
            tag = tok + INITS[init]
            for m in ("start", *meta["methods"]):
                name = {"start": START_ROW, "sage_los": "sage_los (oracle)"}.get(m, m)
                cells = [
                    with_interval(f, f"{m}.{tag}.agents_{n}.framework_rmse_m")
                    for n in meta["agents"]
                ]
                if m == "start" and all(c is None for c in cells):
                    continue
                rows.append((tag, name, *cells))
    return rows


def summary_headers(results: dict):
    """Headers of :func:`summary_rows`."""
    return [*SUMMARY_HEADERS, *[f"{n} agents" for n in results["meta"]["agents"]]]


#: The error/belief ratios (from the median) inside which a method's beliefs are called
#: calibrated; outside, ``phyloc evaluate`` prints a warning.
CALIBRATED_RATIO = (0.67, 1.5)


def belief_warnings(figures: dict, methods, tag: str, n: int) -> list[str]:
    """Warnings for the methods whose beliefs are much narrower or wider than their errors at
    ``n`` agents (``error_to_belief_ratio_median`` outside :data:`CALIBRATED_RATIO`), with
    what to set.

    >>> f = {"dipnet.c2.agents_12.error_to_belief_ratio_median": 4.0,
    ...      "corr.c2.agents_12.error_to_belief_ratio_median": 1.1}
    >>> [w[:52] for w in belief_warnings(f, ["dipnet", "corr"], "c2", 12)]
    ['warning: dipnet at 12 agents (c2): its error is 4x i']
    """
    lo, hi = CALIBRATED_RATIO
    out = []
    for m in methods:
        r = figures.get(f"{m}.{tag}.agents_{n}.error_to_belief_ratio_median", math.nan)
        if not math.isfinite(r) or lo <= r <= hi:
            continue
        side = "narrower" if r > hi else "wider"
        out.append(
            f"warning: {m} at {n} agents ({tag}): its error is {r:.2g}x its belief's spread "
            f"(beliefs {side} than the errors; calibrated is {lo}-{hi}). "
            + (
                "Its reported covariances understate its error: a larger [localization] "
                "model_error_m widens the likelihood of links with unresolved multipath "
                "(docs: guide/experiments)"
                if r > hi
                else "Its priors or model error may be wider than the links support"
            )
        )
    return out


def summary_lines(results: dict):
    """ESS and runtime lines."""
    f, meta = results["figures"], results["meta"]
    n = max(meta["agents"])
    out = [
        "framework distance RMSE [m] (DiPNet eq. (4)) [95 % interval over realizations]; "
        "informed-start rows are not truth-free; the start is a centralized solution "
        "(every link's range in one place), the methods are distributed"
    ]
    for tok in meta["scenarios"]:
        for init in meta["inits"]:
            tag = tok + INITS[init]
            ess = ", ".join(
                f"{m} {f[f'{m}.{tag}.agents_{n}.ess_min']:.0f}"
                for m in meta["methods"]
                if _reads_tables(m)
            )
            out.append(f"{tag}, {n} agents, smallest ESS: {ess} (of {meta['n_particles']})")
            ratio = ", ".join(
                f"{m} {f.get(f'{m}.{tag}.agents_{n}.error_to_belief_ratio', math.nan):.3g}"
                f" ({f.get(f'{m}.{tag}.agents_{n}.error_to_belief_ratio_median', math.nan):.3g})"
                for m in meta["methods"]
            )
            out.append(
                f"{tag}, {n} agents, error/belief ratio sqrt(NEES/dim) (from the median): {ratio}"
            )
            out += belief_warnings(f, meta["methods"], tag, n)
            pos = [
                f"{m} {with_interval(f, f'{m}.{tag}.agents_{n}.position_rmse_m')}"
                for m in ("start", *meta["methods"])
                if f"{m}.{tag}.agents_{n}.position_rmse_m" in f
            ]
            if pos:
                out.append(
                    f"{tag}, {n} agents, absolute position RMSE [m] (anchors fix the frame): "
                    + ", ".join(pos)
                )
        for k in meta["agents"]:
            frac = f.get(f"{tok}.agents_{k}.unobservable_pair_fraction", 0.0)
            for init in meta["inits"] if frac > 0 else ():
                tag = tok + INITS[init]
                obs = ", ".join(
                    f"{m} {f[f'{m}.{tag}.agents_{k}.framework_rmse_observable_m']:.3g}"
                    for m in meta["methods"]
                )
                out.append(
                    f"{tag}, {k} agents: {100 * frac:.1f} % of the pairs unobservable "
                    f"(no detected links fix them); RMSE over the rest [m]: {obs}"
                )
    rt = ", ".join(
        f"{m} {1e6 * f[f'{m}.runtime_per_agent_iteration_s']:.0f} µs" for m in meta["methods"]
    )
    out.append(f"runtime per agent-iteration (JIT compilation excluded): {rt}")
    return out


LOCALIZATION = LocalizationExperiment()
DATASET_LOCALIZATION = DatasetLocalization()

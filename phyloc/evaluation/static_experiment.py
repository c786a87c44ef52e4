"""Static cooperative localization with polygon-constrained NBP: the POA-NBP paper §V.

A ``kind = "static"`` recipe runs, on ``topologies`` random networks of the paper's setup
(:func:`~phyloc.evaluation.static_scenarios.paper_static_scenario`: agents uniform in a
square, 13 fixed anchors — layout
:data:`~phyloc.evaluation.static_scenarios.PAPER_ANCHOR_UNITS`,
communication range, one-sided exponential ranging errors of mean 0.38 m, POA-NBP eq. (2)):

1. **Polygon support outer-approximation** (POA-NBP Fig. 9): POA
   (:func:`~phyloc.localization.static.poa_network.poa`)
   for every ``N_E`` of ``experiment.n_edges`` over ``poa_iterations`` iterations, and the
   ellipse outer-approximation baseline — mean area per iteration; the fraction of polygons
   that contain their agent (with non-negative errors: all of them); POA time per node.
2. **Localization** (POA-NBP Figs. 10, 11, Table I): every method of ``experiment.methods``,
   looked up in :data:`phyloc.localization.METHODS` (family ``"static"``) and run as
   ``run(measurements, prior, rng, options)`` on the scenario's truth-free measurements. The
   paper's comparison (:data:`METHODS`, in the column order of POA-NBP Table I, with
   ``nbp_mixture`` as an extra column; see :mod:`phyloc.localization.static`)::

       ``nbp_min_entropy``   [19] NBP sampling the incoming message of least entropy ('NBP min.')
       ``nbp_aux``           [27] NBP sampling the product of the anchor messages by
                             auxiliary-variable importance resampling ('NBP aux.')
       ``nbp_parsimonious``  [25] NBP sampling the previous belief ('NBP par.')
       ``nbp_ellipse``       [39] NBP with the uniform proposal in the ellipse
                             outer-approximation ('NBP ell.'; ``poa_n_fs`` iterations)
       ``pbp``               [19] parametric (Gaussian) BP ('PBP')
       ``wls``               [5] weighted least squares by Gauss–Newton ('WLS')
       ``poa_nbp``           NBP with the uniform proposal in each agent's POA polygon ('NBP
                             prop.', POA-NBP eq. (21); ``N_E = poa_n_edges``, ``N_FS = poa_n_fs``)
       ``nbp_mixture``       [27] NBP sampling the mixture of incoming messages (plus a uniform
                             fraction; not in Table I)

   The table columns follow the order of ``experiment.methods``. Any other registered static
   method may be listed too, e.g. ``nbp_bounding`` (NBP in the S-procedure bounding discs of
   the feasible sets: the ellipses POA-NBP cites, :mod:`~phyloc.localization.static.bounding`),
   and so may *variants*: a label that is not a registered name and whose
   ``[localization.<label>]`` table names its method (``method = "nbp_min_entropy"``) with its
   own options, e.g. the paper's form of a baseline (``datasets/poa_nbp.toml``: the
   ``<method>_paper`` labels). Figures are named after the labels.

   A method's options are its registered defaults (e.g. the proposal of an NBP variant),
   updated by the shared ``[localization]`` keys its options have (the NBP methods'
   ``bandwidth``, ``uniform_fraction``, …), by ``[experiment]`` (``n_iterations``,
   ``n_samples``, ``poa_n_edges``, ``poa_n_fs``, ``baseline_start``) where the options have
   those fields and by its ``[localization.<label>]`` table (``[localization.pbp]``,
   ``[localization.wls]``; :mod:`phyloc.evaluation.methods`). A label's table may also set
   ``start`` (``pbp``, ``wls``), which replaces ``baseline_start`` for that label. Methods with
   POA support receive the proposal polygons computed for the figures through their prior (so
   POA runs once per topology, on its own random stream).

   Random streams (children of the topology's seed sequence, :func:`_streams`): scenario,
   polygon study, proposal polygons, one per label that is a registered method, one per sweep
   run, the rejection-acceptance measurement, then one per variant label. Adding variants
   therefore changes no other figure of a recipe.
3. **Samples** (POA-NBP Fig. 12): ``poa_nbp`` and ``nbp_min_entropy`` (or the methods of
   ``sample_methods``) at every ``N_S`` of ``experiment.sample_sweep``.

Convergence is read by the paper's rule (POA-NBP §V, footnote 5: "convergence is achieved if
the average localization error does not change notably for successive iterations") in every
topology, on its own mean-error curve ``e_l`` (mean over its agents): it has converged after
iteration ``l − 1`` for the first ``l >= 2`` with
``|e_l − e_{l−1}| <= max(convergence_rel · e_{l−1}, convergence_abs_m)`` (never:
``n_iterations``); ``<m>.convergence_iteration`` is the mean over topologies of that count. The
same rule on the mean-error curve over all topologies gives ``<m>.curve_convergence_iteration``
(one number). A stricter reading of that curve is reported next to it as the *settling*
iteration: the first iteration from which the curve stays within
``max(convergence_rel · e_final, convergence_abs_m)`` of its final value; it counts the slow
Monte Carlo refinement a particle method keeps making after its curve has flattened.
The time to convergence per node of a topology is its mean time per node and iteration times
its convergence iteration, plus the method's setup time per node (its
``setup_time_per_node_s`` diagnostic: the outer-approximation of ``poa_nbp`` and
``nbp_ellipse``, the start of ``pbp`` and ``wls`` — MDS/SMACOF with ``baseline_start = "mds"``,
0 where the heuristic start is used); ``<m>.time_to_convergence_s`` is its mean over
topologies, and ``<m>.start_time_per_node_s`` the start's share (methods with a ``start``
option: ``pbp``, ``wls``), so that the start and the iterations can be told apart.
Errors "after convergence" are those of the last iteration (``n_iterations`` >= convergence).

Communication and operations: the scenario token ``<s>`` of the overhead figures names the
run, ``ns<n>`` with its ``N_S``: the comparison of step 2 at ``N_S = n_samples`` gives
``<m>.ns<n_samples>.*`` for every method (PBP and WLS too, which have no samples: the token
names the run), each sample-sweep run gives ``<m>.ns<n>.*``; where a sweep run repeats the
comparison's method and ``N_S`` the comparison's value is kept. The numbers come from each
method's ``Result.diagnostics`` (``floats_per_link_iteration``, ``operations_per_node``,
``support_floats_per_link_iteration``; see :mod:`phyloc.localization.static.nbp` and
:mod:`phyloc.localization.static.gaussian_bp` for what is counted) and from
:class:`~phyloc.localization.static.poa_network.POAResult` for the polygon study; a NaN (no
messages: ``wls`` in joint mode, centralized; no support phase) gives no figure.

Figures (``results.json``; ``<m>`` a method, ``<ne>`` an ``N_E``, ``<l>`` an iteration, ``<n>``
an ``N_S`` of the sweep, ``<s>`` a run token ``ns<n>``, ``<x>`` an outage threshold written
with ``p`` for the decimal point)::

    ``poa.containment_fraction``        fraction of (topology, agent) polygons of the proposal
                                        setting (``poa_n_edges``, ``poa_n_fs``) containing the
                                        agent; ``poa.ne<ne>.containment_fraction`` per N_E
    ``poa.ne<ne>.area_it<l>_m2``        mean polygon area after iteration l [m²] (Fig. 9)
    ``ellipse.area_it<l>_m2``           mean ellipse area [m²] (Fig. 9): the exact
                                        minimum-area ellipses
                                        (:func:`~phyloc.localization.static.ellipses.
                                        ellipse_outer_approximation`)
    ``ellipse_paper.area_it<l>_m2``     the same for the ellipses the paper cites: the
                                        S-procedure bounding discs
                                        (:func:`~phyloc.localization.static.bounding.
                                        feasible_set_bounding`)
    ``poa.time_per_node_s``             POA time per agent (``poa_n_fs`` iterations) [s]
    ``poa.rejection_acceptance_rate``   mean acceptance rate of sampling the proposal polygons by
                                        rejection from their bounding boxes (the paper's way;
                                        phyloc samples exactly by triangle fan)
    ``poa.dropped_fraction``            fraction of measurements POA dropped as inconsistent
    ``poa.ne<ne>.floats_per_link_iteration``  floats per agent–agent link and broadcast of the
                                        polygon study's POA (2 per vertex; POA-NBP Algorithm 1)
    ``poa.ne<ne>.operations_per_node``  POA operations per agent over ``poa_iterations``
                                        iterations (Algorithms 2–4; mean per node and run)
    ``<m>.<s>.floats_per_link_iteration``   floats one agent sends one neighbour per
                                        message-passing iteration (NBP: ``2·N_S``; PBP: 5;
                                        none for joint WLS)
    ``<m>.<s>.operations_per_node``     operations per agent and run (NBP: KDE kernel
                                        evaluations, plus POA's operations for ``poa_nbp``)
    ``<m>.<s>.support_floats_per_link_iteration``   floats per link and broadcast of the
                                        support phase (``poa_nbp``: polygons; ``nbp_ellipse``:
                                        5 per ellipse)
    ``<m>.mean_error_m``                average localization error after convergence [m]
                                        (Fig. 10)
    ``<m>.mean_error_it<l>_m``          average localization error after iteration ``l``
                                        (1 … ``n_iterations``; Fig. 10's curve point by
                                        point, so that two iterations compare paired) [m]
    ``<m>.rmse_m``                      RMSE after convergence [m]
    ``<m>.convergence_iteration``       iterations to convergence, paper's rule, in each
                                        topology; mean over topologies (Fig. 10)
    ``<m>.curve_convergence_iteration`` iterations to convergence of the mean-error curve over
                                        all topologies (paper's rule; one number)
    ``<m>.settling_iteration``          iterations until that curve stays near its final value
    ``<m>.time_per_node_iteration_s``   wall time per node and iteration (each topology: the
                                        mean over its iterations and agent updates); mean over
                                        topologies [s]
    ``<m>.time_to_convergence_s``       time per node to convergence (Table I, t_conv + t_poly):
                                        each topology's ``convergence iteration × time per
                                        node-iteration + setup time per node``; mean over
                                        topologies [s]
    ``<m>.start_time_per_node_s``       the start alone (``setup_time_per_node_s`` of ``pbp``,
                                        ``wls``: methods with a ``start`` option), per node;
                                        mean over topologies [s]; part of
                                        ``time_to_convergence_s``
    ``<m>.outage_<x>m``                 fraction of agents with error > x after convergence
                                        (Fig. 11)
    ``<m>.ns<n>.mean_error_m``, ``<m>.ns<n>.outage_<x>m``, ``<m>.ns<n>.time_per_node_iteration_s``
                                        the sample sweep (Fig. 12)
    ``<m>.ns<n>.topologies``            topologies the sweep ran in (``sample_sweep_topologies``)
    ``pbp.sweep.mean_error_m``, ``pbp.sweep.outage_<x>m``   PBP's figures (comparison run)
                                        restricted to the sweep's topologies, so that the sweep
                                        can be compared with PBP (POA-NBP Fig. 12's reference)
                                        over the same topologies; ``pbp.sweep.topologies``
                                        (the methods of :data:`SWEEP_REFERENCES` that run)
    ``poa_nbp_vs_<m>.time_to_convergence_ratio``   ``poa_nbp`` over NBP variant ``<m>``
    ``<a>_vs_<m>.mean_error_m.ratio``, ``.rmse_m.ratio``, ``.outage_<x>m.ratio``
                                        method ``<a>`` over method ``<m>`` on the same
                                        topologies (``<a>``: ``poa_nbp`` when it runs,
                                        otherwise the first method; every other ``<m>``;
                                        none where ``<m>``'s figure is 0)
    ``<a>_vs_<m>.ns<n>.mean_error_m.ratio``, ``.ns<n>.outage_<x>m.ratio``   the same in the
                                        sample sweep (``<a>`` the first of ``sample_methods``);
                                        for ``<m> = pbp`` against ``pbp.sweep.*`` (PBP has
                                        no N_S: the same figure at every ``<n>``)

Intervals: every figure pooled over topologies — the areas, containment and dropped
fractions, acceptance rate, overhead means, mean errors (per iteration too), RMSEs and
outages (sweep and ``pbp.sweep`` included), ``convergence_iteration`` and the wall times
``poa.time_per_node_s``, ``<m>.time_per_node_iteration_s``, ``<m>.time_to_convergence_s``,
``<m>.start_time_per_node_s`` and ``<m>.ns<n>.time_per_node_iteration_s`` — has a 95 % interval
``<name>.ci_low`` / ``<name>.ci_high`` (:mod:`phyloc.evaluation.statistics`: bootstrap over
topologies; fractions and outages: exact binomial interval on the totals) and its per-topology
values in the series ``<name>.units`` (one unit per topology of the figure: the sweep's figures
have those of the sweep); a ratio has ``<name>.ratio.ci_low`` / ``.ratio.ci_high`` (paired
bootstrap over topologies). With a single topology the intervals are NaN. The readings of the
pooled curve (``curve_convergence_iteration``, ``settling_iteration``), the
``time_to_convergence_ratio`` figures and ``.topologies`` are plain numbers.

Definitions changed with the per-topology units (values of stored runs before them are not
comparable): ``<m>.convergence_iteration`` was read off the mean-error curve over all
topologies (now ``<m>.curve_convergence_iteration``); ``<m>.time_to_convergence_s`` was that
count times the mean time per node-iteration plus the mean setup time (so also
``poa_nbp_vs_<m>.time_to_convergence_ratio``). With one topology both are unchanged.

Series: ``iteration``; ``<m>.mean_error_m`` per iteration; ``poa.ne<ne>.area_m2``,
``ellipse.area_m2`` and ``ellipse_paper.area_m2`` per POA iteration; ``outage_threshold_m``
(grid) with ``<m>.outage``, ``<m>.ns<n>.outage`` and ``pbp.sweep.outage``.

Timings are wall times of this process (with several workers they include contention);
everything else is identical for a seed whatever the worker count.

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.evaluation.experiment import Experiment
from phyloc.evaluation.methods import check_labels
from phyloc.evaluation.methods import method_plan as plan_methods
from phyloc.evaluation.static_aggregation import (
    aggregate,
    overhead_of,
)
from phyloc.evaluation.static_figures import (
    plot,
    summary_headers,
    summary_lines,
    summary_rows,
)
from phyloc.evaluation.static_scenarios import paper_static_scenario
from phyloc.localization import METHODS as REGISTRY
from phyloc.localization.static import StaticPrior
from phyloc.localization.static.bounding import feasible_set_bounding
from phyloc.localization.static.ellipses import ellipse_outer_approximation
from phyloc.localization.static.poa_network import poa
from phyloc.localization.static.static_ranges import range_error_model

#: The methods of the POA-NBP paper's comparison (the default of ``experiment.methods``); any
#: method registered in :data:`phyloc.localization.METHODS` with family ``"static"`` may be
#: listed.
METHODS = (
    "nbp_min_entropy",
    "nbp_aux",
    "nbp_parsimonious",
    "nbp_ellipse",
    "pbp",
    "wls",
    "poa_nbp",
    "nbp_mixture",
)
#: Option keys filled from ``[experiment]`` (a recipe's ``[localization.<table>]`` must not set
#: them) where the method's options have them; ``proposal`` and ``support`` are set by the
#: method's registered defaults.
_FROM_EXPERIMENT = ("n_iterations", "n_samples", "poa_n_edges", "poa_n_fs", "start")
_FROM_METHOD = ("proposal", "support")
ERRORS = ("exponential", "gaussian")
BASELINE_STARTS = ("mds", "heuristic")


@dataclass(frozen=True)
class StaticExperimentSpec:
    """``[experiment]`` of a ``kind = "static"`` recipe (``[experiment.fast]`` for ``--fast``).

    Parameters
    ----------
    topologies : int
        Random networks (tasks) (paper: 200).
    n_agents, side_m, comm_range_m
        100 agents in a 100 m square, r_com = 20 m (POA-NBP §V-A).
    error : {"exponential", "gaussian"}
        Ranging error model; ``mean_error_m`` (exponential, 0.38 m) or ``error_std_m``.
    n_edges : tuple of int
        N_E of the polygon study (4, 8, 16, 32).
    poa_iterations : int
        Iterations of the polygon study (5).
    ellipses : bool
        Run the ellipse baselines of the polygon study (the exact minimum-area ellipses and
        the S-procedure bounding discs the paper cites).
    poa_n_edges, poa_n_fs : int
        N_E and N_FS of the polygons used as proposals (16, 2; POA-NBP §V-B).
    methods : tuple of str
        Names of static methods of :data:`phyloc.localization.METHODS` (default
        :data:`METHODS`).
    n_iterations : int
        Message-passing iterations of every method (10).
    n_samples : int
        N_S of the NBP methods (200).
    sample_sweep : tuple of int
        N_S values of POA-NBP Fig. 12 (empty: skip).
    sample_methods : tuple of str
        Sample-based methods of the sweep (options with ``n_samples``; ``poa_nbp``,
        ``nbp_min_entropy``).
    sample_sweep_topologies : int, optional
        Run the sweep in the first this many topologies only (default: all). The sweep's cost
        grows as N_S² (its N_S = 1600 point costs 64x the N_S = 200 methods), so the full
        setting limits it; its figures say over how many topologies
        (``<m>.ns<N_S>.topologies``), and every other figure and random stream is unchanged.
    outage_thresholds_m : tuple of float
        Thresholds of the scalar outage figures.
    convergence_rel, convergence_abs_m : float
        Convergence band on the mean-error curve (0.05, 0.02 m).
    baseline_start : {"mds", "heuristic"}
        Start of ``pbp`` and ``wls``: the truth-free MDS/SMACOF solution of the measured ranges
        with the anchors fixing the frame (:func:`~phyloc.localization.initialization.
        coarse_positions`; the heuristic start where the range graph is disconnected), or the
        centroid of the anchors each agent hears
        (:func:`~phyloc.localization.static.gaussian_bp.heuristic_start`): the ``start`` option
        of every method that has one. Both are Gauss–Newton-type local methods; from the
        heuristic start they stall in wrong local optima.
    """

    topologies: int = 200
    n_agents: int = 100
    side_m: float = 100.0
    comm_range_m: float = 20.0
    error: str = "exponential"
    mean_error_m: float = 0.38
    error_std_m: float = 0.38
    n_edges: tuple = (4, 8, 16, 32)
    poa_iterations: int = 5
    ellipses: bool = True
    poa_n_edges: int = 16
    poa_n_fs: int = 2
    methods: tuple = METHODS
    n_iterations: int = 10
    n_samples: int = 200
    sample_sweep: tuple = (50, 100, 200, 400)
    sample_methods: tuple = ("poa_nbp", "nbp_min_entropy")
    sample_sweep_topologies: int | None = None
    outage_thresholds_m: tuple = (0.5, 1.0, 2.0, 5.0)
    convergence_rel: float = 0.05
    convergence_abs_m: float = 0.02
    baseline_start: str = "mds"

    def __post_init__(self):
        s = "experiment."
        for name, lo in (
            ("topologies", 1),
            ("n_agents", 1),
            ("poa_iterations", 1),
            ("poa_n_edges", 3),
            ("poa_n_fs", 1),
            ("n_iterations", 2),
            ("n_samples", 2),
        ):
            object.__setattr__(self, name, v.integer(s + name, getattr(self, name), minimum=lo))
        for name in ("side_m", "comm_range_m", "mean_error_m", "error_std_m", "convergence_abs_m"):
            object.__setattr__(self, name, v.positive(s + name, getattr(self, name)))
        if self.error not in ERRORS:
            raise ValidationError(s + "error", self.error, f"one of {', '.join(ERRORS)}")
        ne = tuple(v.integer(s + "n_edges", x, minimum=3) for x in self.n_edges)
        object.__setattr__(self, "n_edges", ne)
        methods = check_labels(self.methods)
        static = REGISTRY.family("static")
        if not methods:
            raise ValidationError(s + "methods", [], f"at least one of {', '.join(static)}")
        object.__setattr__(self, "methods", methods)  # labels: checked by method_options
        sweep = tuple(v.integer(s + "sample_sweep", x, minimum=2) for x in self.sample_sweep)
        object.__setattr__(self, "sample_sweep", sweep)
        sampled = tuple(m for m in static if "n_samples" in _fields(REGISTRY[m].options))
        for m in self.sample_methods:
            if m not in sampled:
                raise ValidationError(s + "sample_methods", m, f"each one of {', '.join(sampled)}")
        object.__setattr__(self, "sample_methods", tuple(self.sample_methods))
        if self.sample_sweep_topologies is not None:
            n = v.integer(s + "sample_sweep_topologies", self.sample_sweep_topologies, minimum=1)
            object.__setattr__(self, "sample_sweep_topologies", min(n, self.topologies))
        thr = tuple(v.positive(s + "outage_thresholds_m", x) for x in self.outage_thresholds_m)
        object.__setattr__(self, "outage_thresholds_m", thr)
        if self.baseline_start not in BASELINE_STARTS:
            raise ValidationError(
                s + "baseline_start", self.baseline_start, f"one of {', '.join(BASELINE_STARTS)}"
            )
        rel = v.positive(s + "convergence_rel", self.convergence_rel)
        if rel >= 1:
            raise ValidationError(s + "convergence_rel", rel, "must be in (0, 1)")

    @property
    def sweep_topologies(self) -> int:
        """Topologies the sample sweep runs in (the first ones)."""
        return (
            self.topologies
            if self.sample_sweep_topologies is None
            else self.sample_sweep_topologies
        )

    def error_model(self):
        """The ranging error model of the recipe."""
        if self.error == "exponential":
            return range_error_model("exponential", mean_m=self.mean_error_m)
        return range_error_model("gaussian", std_m=self.error_std_m)


def _fields(options_cls) -> set[str]:
    return {f.name for f in dataclasses.fields(options_cls)}


def method_options(
    localization: dict, exp: StaticExperimentSpec, n_samples=None, labels=None
) -> dict:
    """Options of every label of ``exp.methods``
    (:func:`phyloc.evaluation.methods.method_plan`): the method's registered defaults, the
    shared ``[localization]`` keys its options have (e.g. the NBP methods' ``bandwidth``), the
    values of ``[experiment]`` (``n_iterations``, ``n_samples`` — or the argument ``n_samples``
    of a sweep —, ``poa_n_edges``, ``poa_n_fs``, ``baseline_start`` as ``start``) where the
    options have those fields, and the label's ``[localization.<label>]`` table (``pbp``,
    ``wls``, …; a variant label names its method, ``method = "<name>"``). A label's table may
    set ``start`` (methods with a start: ``pbp``, ``wls``), which then replaces
    ``experiment.baseline_start`` for that label (e.g. a paper-form variant). Unknown keys name
    ``localization.<key>`` or ``localization.<label>.<key>``. ``labels`` (default
    ``exp.methods``) selects other labels, e.g. those of the sweep."""
    plan = method_plan(localization, exp, n_samples, labels)
    return {label: opts for label, (_, opts) in plan.items()}


def method_plan(localization: dict, exp: StaticExperimentSpec, n_samples=None, labels=None) -> dict:
    """``{label: (registered method name, options)}`` of :func:`method_options` (a label that is
    not a registered name runs the method its table names)."""
    values = {
        "n_iterations": exp.n_iterations,
        "n_samples": exp.n_samples if n_samples is None else n_samples,
        "poa_n_edges": exp.poa_n_edges,
        "poa_n_fs": exp.poa_n_fs,
        "start": exp.baseline_start,
    }
    tables, starts = _label_starts(localization)
    return plan_methods(
        tables,
        exp.methods if labels is None else labels,
        "static",
        check_shared=labels is None,
        experiment_values=values,
        overrides=starts,
        forbidden=_FROM_METHOD,
        old_tables={"nbp": _OLD_NBP_TABLE},
    )


def _label_starts(localization):
    """``(localization without the labels' start keys, {label: {"start": value}})``: a label's
    ``start`` replaces ``experiment.baseline_start`` (checked here so that an error names
    ``localization.<label>.start``)."""
    if not isinstance(localization, dict):
        return localization, {}
    out, starts = dict(localization), {}
    for label, table in localization.items():
        if not isinstance(table, dict) or "start" not in table:
            continue
        start = table["start"]
        if start not in BASELINE_STARTS:
            raise ValidationError(
                f"localization.{label}.start", start, f"one of {', '.join(BASELINE_STARTS)}"
            )
        name = table.get("method", label)
        if name in REGISTRY and "start" not in _fields(REGISTRY[name].options):
            raise ValidationError(
                f"localization.{label}.start", start, "only for a method with a start (pbp, wls)"
            )
        out[label] = {k: x for k, x in table.items() if k != "start"}
        starts[label] = {"start": start}
    return out, starts


_OLD_NBP_TABLE = (
    "the NBP methods' shared options are [localization] keys now (e.g. [localization] "
    'bandwidth = "lscv"); a [localization.<label>] table holds one label\'s options'
)


def _errors(res, truth_agents):
    return np.linalg.norm(res.estimates - truth_agents[None], axis=-1)  # [n_iter, n_agents]


def _task(payload, seed_seq):
    """One topology: scenario, polygon study, every method, the sample sweep."""
    exp, localization, index = payload
    plan = method_plan(localization, exp)
    streams, method_streams, sweep_start, accept = _streams(seed_seq, exp, plan)
    rng = np.random.default_rng(streams[0])
    sc = paper_static_scenario(
        rng,
        n_agents=exp.n_agents,
        side_m=exp.side_m,
        comm_range_m=exp.comm_range_m,
        error_model=exp.error_model(),
    )
    truth = sc.agent_positions  # the evaluation's only use of the truth: errors, containment
    meas = sc.measurements()
    out: dict = {}
    # 1. polygon study (Fig. 9)
    prng = np.random.default_rng(streams[1])
    for ne in exp.n_edges:
        r = poa(
            meas.positions,
            meas.ranges,
            meas.is_anchor,
            rng=prng,
            n_edges=ne,
            n_iterations=exp.poa_iterations,
            region=sc.region,
        )
        out[f"poa|{ne}|area"] = r.area_history
        out[f"poa|{ne}|contained"] = _contained(r.polygons, truth)
        out[f"poa|{ne}|ops"] = r.operations_per_node
        out[f"poa|{ne}|floats"] = r.floats_per_link_iteration
    # the proposal polygons: N_E = poa_n_edges, N_FS = poa_n_fs, their own stream; methods that
    # use POA support get them through the prior (computed once, as the figures need them)
    prop = poa(
        meas.positions,
        meas.ranges,
        meas.is_anchor,
        rng=np.random.default_rng(streams[2]),
        n_edges=exp.poa_n_edges,
        n_iterations=exp.poa_n_fs,
        region=sc.region,
    )
    out["poa|contained"] = _contained(prop.polygons, truth)
    # the paper samples the polygon by rejection from its bounding box: measured acceptance
    arng = np.random.default_rng(accept)
    out["poa|acceptance"] = np.array(
        [p.sample_rejection(exp.n_samples, arng)[1] for p in prop.polygons if p is not None]
    )
    out["poa|time_per_node_s"] = float(prop.time_s.sum(axis=0).mean())
    n_meas = int(np.isfinite(meas.ranges[~meas.is_anchor]).sum())
    out["poa|dropped"] = (int(prop.dropped.shape[0]), n_meas)
    priors = {
        "poa": StaticPrior(
            sc.region,
            polygons=list(prop.polygons),
            polygon_time_per_node_s=out["poa|time_per_node_s"],
            polygon_operations_per_node=prop.operations_per_node,
            polygon_floats_per_link_iteration=prop.floats_per_link_iteration,
        ),
        None: StaticPrior(sc.region),
    }
    if exp.ellipses:  # Fig. 9's baselines: exact ellipses and the cited bounding discs
        for key, bound in (
            ("ellipse", ellipse_outer_approximation),
            ("ellipse_paper", feasible_set_bounding),
        ):
            out[f"{key}|area"] = bound(
                meas.positions,
                meas.ranges,
                meas.is_anchor,
                n_iterations=exp.poa_iterations,
                region=sc.region,
            ).area_history
    # 2. localization (Fig. 10, 11, Table I)
    for m in exp.methods:
        mrng = np.random.default_rng(method_streams[m])
        name, opts = plan[m]
        res = _run_method(name, meas, priors, opts, mrng)
        out[f"{m}|err"] = _errors(res, truth)
        out[f"{m}|time"] = float(np.mean(res.timing.agent_s))
        out[f"{m}|t_support"] = float(res.diagnostics.get("setup_time_per_node_s", 0.0))
        out[f"{m}|overhead"] = overhead_of(res)
    # 3. sample sweep (Fig. 12), in the first experiment.sample_sweep_topologies topologies
    s = sweep_start
    for m in exp.sample_methods if index < exp.sweep_topologies else ():
        for ns in exp.sample_sweep:
            mrng = np.random.default_rng(streams[s])
            s += 1
            opts = method_options(localization, exp, ns, labels=(m,))[m]
            res = _run_method(m, meas, priors, opts, mrng)
            out[f"{m}|ns{ns}|err"] = _errors(res, truth)[-1]
            out[f"{m}|ns{ns}|time"] = float(np.mean(res.timing.agent_s))
            out[f"{m}|ns{ns}|overhead"] = overhead_of(res)
    return out


def _streams(seed_seq, exp: StaticExperimentSpec, plan: dict):
    """The random streams of one topology: ``(streams, {label: stream}, index of the first
    sweep stream, acceptance stream)``. Children of ``seed_seq`` in this order: 0 scenario,
    1 polygon study, 2 proposal polygons, then one per label that is a registered method (in
    the order of ``exp.methods``), one per sweep run, the rejection-acceptance measurement, and
    after it one per variant label (a label naming another method), in their order. Adding a
    variant therefore leaves every other stream — and figure — of a recipe unchanged."""
    base = [m for m in exp.methods if plan[m][0] == m]
    variants = [m for m in exp.methods if plan[m][0] != m]
    n0 = 4 + len(base) + len(exp.sample_sweep) * len(exp.sample_methods)
    streams = seed_seq.spawn(n0 + len(variants))
    own = {m: streams[3 + k] for k, m in enumerate(base)}
    own.update({m: streams[n0 + k] for k, m in enumerate(variants)})
    return streams, own, 3 + len(base), streams[n0 - 1]


#: Overhead diagnostics of a static method's ``Result`` that become figures (NaN: none).
def _contained(polygons, truth):
    return np.array(
        [p is None or bool(p.contains(x[None])[0]) for p, x in zip(polygons, truth, strict=True)]
    )


def _run_method(name, meas, priors, options, rng):
    """Run a registered method; the prior carries the POA polygons of the proposal setting
    when the method's options ask for POA support (``support = "poa"``)."""
    prior = priors["poa"] if getattr(options, "support", None) == "poa" else priors[None]
    return REGISTRY[name].run(meas, prior, rng, options)


class StaticExperiment(Experiment):
    """``kind = "static"``: one task per topology, every method on the same ranges."""

    kind = "static"
    title = "static cooperative localization with polygon-constrained NBP (POA-NBP Figs. 9–12)"
    unit = "topology"
    spec = StaticExperimentSpec
    task = staticmethod(_task)
    progress_label = "topologies"

    def prepare(self, recipe, *, fast=False):
        exp = self.experiment_spec(recipe, fast=fast)
        localization = recipe.section("localization")
        plan = method_plan(localization, exp)
        return SimpleNamespace(
            exp=exp,
            localization=localization,
            opts={m: opts for m, (_, opts) in plan.items()},
            names={m: name for m, (name, _) in plan.items()},
        )

    def tasks(self, plan):
        return [(i, (plan.exp, plan.localization, i)) for i in range(plan.exp.topologies)]

    def aggregate(self, plan, keys, results, ctx):
        return aggregate(results, plan.exp, plan.names)

    def meta(self, plan, ctx):
        exp, opts = plan.exp, plan.opts
        return {
            "topologies": exp.topologies,
            "n_agents": exp.n_agents,
            "methods": list(exp.methods),
            "labels": {
                **{m: REGISTRY[m].label for m in REGISTRY.family("static")},
                **{m: f"{REGISTRY[n].label} ({m})" for m, n in plan.names.items() if m != n},
            },
            "method_of": dict(plan.names),
            "n_edges": list(exp.n_edges),
            "sample_sweep": list(exp.sample_sweep),
            "sample_methods": list(exp.sample_methods),
            "sample_sweep_topologies": exp.sweep_topologies,
            "outage_thresholds_m": list(exp.outage_thresholds_m),
            "experiment": dataclasses.asdict(exp),
            "options": {m: dataclasses.asdict(o) for m, o in opts.items()},
            "timing": "wall time per node of this process (includes worker contention)",
            "convergence": (
                "converged after iteration l-1 at the first l with |e_l - e_(l-1)| <= "
                "max(convergence_rel * e_(l-1), convergence_abs_m) (paper footnote 5); settling: "
                "first iteration from which e stays within max(convergence_rel * e_final, "
                "convergence_abs_m) of e_final"
            ),
        }

    summary_rows = staticmethod(summary_rows)
    summary_headers = staticmethod(summary_headers)
    summary_lines = staticmethod(summary_lines)
    plot = staticmethod(plot)


STATIC = StaticExperiment()

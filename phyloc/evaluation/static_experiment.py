"""Static cooperative localization with polygon-constrained NBP: the POA-NBP paper §V.

A ``kind = "static"`` recipe runs, on ``topologies`` random networks of the paper's setup
(:func:`~phyloc.localization.static.static_ranges.paper_static_scenario`: agents uniform in a square,
13 fixed anchors — layout :data:`~phyloc.localization.static.static_ranges.PAPER_ANCHOR_UNITS`,
communication range, one-sided exponential ranging errors of mean 0.38 m, eq. (2)):

1. **Polygon support outer-approximation** (Fig. 9): POA (:func:`~phyloc.localization.static.polygons.poa`)
   for every ``N_E`` of ``experiment.n_edges`` over ``poa_iterations`` iterations, and the
   ellipse outer-approximation baseline — mean area per iteration; the fraction of polygons
   that contain their agent (with non-negative errors: all of them); POA time per node.
2. **Localization** (Fig. 10, 11, Table I): every method of ``experiment.methods``:

   ``poa_nbp``           NBP with the uniform proposal in each agent's POA polygon (eq. (21);
                         ``N_E = poa_n_edges``, ``N_FS = poa_n_fs``)
   ``nbp_ellipse``       NBP with the uniform proposal in the ellipse outer-approximation
                         ('NBP ell.'; ``poa_n_fs`` iterations, like the polygons)
   ``nbp_min_entropy``   NBP sampling the incoming message of least entropy ('NBP min.')
   ``nbp_mixture``       NBP sampling the mixture of incoming messages (plus a uniform fraction)
   ``nbp_parsimonious``  NBP sampling the previous belief ('NBP par.')
   ``pbp``               parametric (Gaussian) BP ('PBP')
   ``wls``               weighted least squares by Gauss–Newton ('WLS')

   NBP options come from ``[localization.nbp]`` (``proposal`` is set by the method),
   ``[localization.pbp]``, ``[localization.wls]``.
3. **Samples** (Fig. 12): ``poa_nbp`` and ``nbp_min_entropy`` (or the methods of
   ``sample_methods``) at every ``N_S`` of ``experiment.sample_sweep``.

Convergence is read off the mean-error curve ``e_l`` over all topologies by the paper's rule
(§V, footnote 5: "convergence is achieved if the average localization error does not change
notably for successive iterations"): the run has converged after iteration ``l − 1`` for the
first ``l >= 2`` with ``|e_l − e_{l−1}| <= max(convergence_rel · e_{l−1}, convergence_abs_m)``
(never: ``n_iterations``). A stricter reading is reported next to it as the *settling*
iteration: the first iteration from which the curve stays within
``max(convergence_rel · e_final, convergence_abs_m)`` of its final value; it counts the slow
Monte Carlo refinement a particle method keeps making after its curve has flattened.
The time to convergence per node is the mean time per node and iteration times that number of
iterations, plus (``poa_nbp``, ``nbp_ellipse``) the time of the outer-approximation per node.
Errors "after convergence" are those of the last iteration (``n_iterations`` >= convergence).

Figures (``results.json``; ``<m>`` a method, ``<ne>`` an ``N_E``, ``<l>`` an iteration, ``<n>``
an ``N_S`` of the sweep, ``<x>`` an outage threshold written with ``p`` for the decimal point)
    ``poa.containment_fraction``        fraction of (topology, agent) polygons of the proposal
                                        setting (``poa_n_edges``, ``poa_n_fs``) containing the
                                        agent; ``poa.ne<ne>.containment_fraction`` per N_E
    ``poa.ne<ne>.area_it<l>_m2``        mean polygon area after iteration l [m²] (Fig. 9)
    ``ellipse.area_it<l>_m2``           mean ellipse area [m²] (Fig. 9)
    ``poa.time_per_node_s``             POA time per agent (``poa_n_fs`` iterations) [s]
    ``poa.rejection_acceptance_rate``   mean acceptance rate of sampling the proposal polygons by
                                        rejection from their bounding boxes (the paper's way;
                                        phyloc samples exactly by triangle fan)
    ``poa.dropped_fraction``            fraction of measurements POA dropped as inconsistent
    ``<m>.mean_error_m``                average localization error after convergence [m]
                                        (Fig. 10)
    ``<m>.rmse_m``                      RMSE after convergence [m]
    ``<m>.convergence_iteration``       iterations to convergence, paper's rule (Fig. 10)
    ``<m>.settling_iteration``          iterations until the curve stays near its final value
    ``<m>.time_per_node_iteration_s``   mean wall time per node and iteration [s]
    ``<m>.time_to_convergence_s``       time per node to convergence [s] (Table I, t_conv + t_poly)
    ``<m>.outage_<x>m``                 fraction of agents with error > x after convergence
                                        (Fig. 11)
    ``<m>.ns<n>.mean_error_m``, ``<m>.ns<n>.outage_<x>m``, ``<m>.ns<n>.time_per_node_iteration_s``
                                        the sample sweep (Fig. 12)
    ``poa_nbp_vs_<m>.time_to_convergence_ratio``   ``poa_nbp`` over NBP variant ``<m>``
Series: ``iteration``; ``<m>.mean_error_m`` per iteration; ``poa.ne<ne>.area_m2`` and
``ellipse.area_m2`` per POA iteration; ``outage_threshold_m`` (grid) with ``<m>.outage`` and
``<m>.ns<n>.outage``.

Timings are wall times of this process (with several workers they include contention);
everything else is identical for a seed whatever the worker count.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from phyloc import _validate as v
from phyloc._validate import check_keys
from phyloc.config import Recipe
from phyloc.errors import ValidationError
from phyloc.evaluation._common import experiment_from_dict
from phyloc.localization.static.gaussian_bp import (
    GaussianBPOptions,
    WLSOptions,
    run_gaussian_bp,
    run_wls,
)
from phyloc.localization.static.nbp import NBPOptions, run_nbp
from phyloc.localization.static.polygons import ellipse_outer_approximation, poa
from phyloc.localization.static.static_ranges import paper_static_scenario, range_error_model
from phyloc.parallel import run_tasks

NBP_METHODS = {
    "poa_nbp": "polygon",
    "nbp_ellipse": "polygon",
    "nbp_min_entropy": "min_entropy",
    "nbp_mixture": "mixture",
    "nbp_parsimonious": "parsimonious",
}
METHODS = (*NBP_METHODS, "pbp", "wls")
LABELS = {
    "poa_nbp": "POA-NBP",
    "nbp_ellipse": "NBP ell.",
    "nbp_min_entropy": "NBP min.",
    "nbp_mixture": "NBP mix.",
    "nbp_parsimonious": "NBP par.",
    "pbp": "PBP",
    "wls": "WLS",
}
ERRORS = ("exponential", "gaussian")
BASELINE_STARTS = ("mds", "heuristic")
OUTAGE_GRID_M = np.logspace(-2, 1.7, 149)
_TIMING = ("_s", "_ratio")


def _threshold_name(x: float) -> str:
    return f"{x:g}".replace(".", "p") + "m"


@dataclass(frozen=True)
class StaticExperimentSpec:
    """``[experiment]`` of a ``kind = "static"`` recipe (``[experiment.fast]`` for ``--fast``).

    Parameters
    ----------
    topologies : int
        Random networks (tasks) (paper: 200).
    n_agents, side_m, comm_range_m
        100 agents in a 100 m square, r_com = 20 m (§V-A).
    error : {"exponential", "gaussian"}
        Ranging error model; ``mean_error_m`` (exponential, 0.38 m) or ``error_std_m``.
    n_edges : tuple of int
        N_E of the polygon study (4, 8, 16, 32).
    poa_iterations : int
        Iterations of the polygon study (5).
    ellipses : bool
        Run the ellipse baseline of the polygon study (and allow ``nbp_ellipse``).
    poa_n_edges, poa_n_fs : int
        N_E and N_FS of the polygons used as proposals (16, 2; §V-B).
    methods : tuple of str
        From :data:`METHODS`.
    n_iterations : int
        Message-passing iterations of every method (10).
    n_samples : int
        N_S of the NBP methods (200).
    sample_sweep : tuple of int
        N_S values of Fig. 12 (empty: skip).
    sample_methods : tuple of str
        NBP methods of the sweep (``poa_nbp``, ``nbp_min_entropy``).
    outage_thresholds_m : tuple of float
        Thresholds of the scalar outage figures.
    convergence_rel, convergence_abs_m : float
        Convergence band on the mean-error curve (0.05, 0.02 m).
    baseline_start : {"mds", "heuristic"}
        Start of ``pbp`` and ``wls``: the truth-free MDS/SMACOF solution of the measured ranges
        with the anchors fixing the frame (:func:`~phyloc.localization.initialization.
        coarse_positions`; the heuristic start where the range graph is disconnected), or the
        centroid of the anchors each agent hears
        (:func:`~phyloc.localization.static.gaussian_bp.heuristic_start`). Both are Gauss–Newton-type
        local methods; from the heuristic start they stall in wrong local optima.
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
        methods = tuple(self.methods)
        if not methods:
            raise ValidationError(s + "methods", [], f"at least one of {', '.join(METHODS)}")
        for m in methods:
            if m not in METHODS:
                raise ValidationError(s + "methods", m, f"each one of {', '.join(METHODS)}")
        if "nbp_ellipse" in methods and not self.ellipses:
            raise ValidationError(s + "ellipses", False, "must be true for method nbp_ellipse")
        object.__setattr__(self, "methods", methods)
        sweep = tuple(v.integer(s + "sample_sweep", x, minimum=2) for x in self.sample_sweep)
        object.__setattr__(self, "sample_sweep", sweep)
        for m in self.sample_methods:
            if m not in NBP_METHODS:
                raise ValidationError(
                    s + "sample_methods", m, f"each one of {', '.join(NBP_METHODS)}"
                )
        object.__setattr__(self, "sample_methods", tuple(self.sample_methods))
        thr = tuple(v.positive(s + "outage_thresholds_m", x) for x in self.outage_thresholds_m)
        object.__setattr__(self, "outage_thresholds_m", thr)
        if self.baseline_start not in BASELINE_STARTS:
            raise ValidationError(
                s + "baseline_start", self.baseline_start, f"one of {', '.join(BASELINE_STARTS)}"
            )
        rel = v.positive(s + "convergence_rel", self.convergence_rel)
        if rel >= 1:
            raise ValidationError(s + "convergence_rel", rel, "must be in (0, 1)")

    @classmethod
    def from_dict(cls, d: dict, *, fast: bool = False) -> StaticExperimentSpec:
        """From ``[experiment]``; with ``fast`` the ``[experiment.fast]`` values win."""
        return experiment_from_dict(cls, d, fast=fast)

    def error_model(self):
        """The ranging error model of the recipe."""
        if self.error == "exponential":
            return range_error_model("exponential", mean_m=self.mean_error_m)
        return range_error_model("gaussian", std_m=self.error_std_m)


@dataclass(frozen=True)
class MethodOptions:
    """Options of every method family, from ``[localization.nbp|pbp|wls]``."""

    nbp: NBPOptions = field(default_factory=NBPOptions)
    pbp: GaussianBPOptions = field(default_factory=GaussianBPOptions)
    wls: WLSOptions = field(default_factory=WLSOptions)


def method_options(localization: dict, exp: StaticExperimentSpec) -> MethodOptions:
    """``[localization.nbp]`` / ``[localization.pbp]`` / ``[localization.wls]``, with the
    experiment's iteration and sample counts; unknown keys name ``localization.<family>.<key>``."""
    check_keys(localization, ["nbp", "pbp", "wls"], "localization")
    out = {}
    for fam, cls in (("nbp", NBPOptions), ("pbp", GaussianBPOptions), ("wls", WLSOptions)):
        raw = localization.get(fam, {})
        if not isinstance(raw, dict):
            raise ValidationError(f"localization.{fam}", raw, "a table of method options")
        for key in ("n_iterations", "n_samples", "proposal"):
            if key in raw:
                raise ValidationError(
                    f"localization.{fam}.{key}",
                    raw[key],
                    "is set by [experiment] (n_iterations, n_samples) or by the method name",
                )
        extra = {"n_iterations": exp.n_iterations}
        if fam == "nbp":
            extra["n_samples"] = exp.n_samples
        try:
            out[fam] = cls.from_dict({**raw, **extra}, section=f"localization.{fam}")
        except ValidationError as exc:
            if exc.field.startswith("localization"):
                raise
            raise ValidationError(
                f"localization.{fam}.{exc.field}", exc.value, exc.allowed
            ) from None
    return MethodOptions(**out)


class _EllipseRegion:
    """An ellipse ``{x : (x − c)ᵀ Σ⁻¹ (x − c) <= 1}`` with the polygon-proposal interface
    (``area``, ``contains``, ``sample_uniform``) of :func:`~phyloc.localization.static.nbp.run_nbp`."""

    def __init__(self, center, shape):
        self.center = np.asarray(center, dtype=np.float64)
        self.shape = np.asarray(shape, dtype=np.float64)
        det = float(np.linalg.det(self.shape))
        self.area = math.pi * math.sqrt(det) if det > 0 else 0.0
        if self.area > 0:
            self._L = np.linalg.cholesky(self.shape)
            self._inv = np.linalg.inv(self.shape)

    def contains(self, points, tol=1e-9):
        d = np.asarray(points, dtype=np.float64).reshape(-1, 2) - self.center
        if self.area == 0:
            return np.zeros(d.shape[0], bool)
        return np.einsum("ni,ij,nj->n", d, self._inv, d) <= 1.0 + tol

    def sample_uniform(self, n, rng):
        r = np.sqrt(rng.uniform(size=n))
        t = rng.uniform(0.0, 2.0 * np.pi, size=n)
        u = np.stack([r * np.cos(t), r * np.sin(t)], axis=1)
        return self.center + u @ self._L.T


def _errors(res, truth_agents):
    return np.linalg.norm(res.estimates - truth_agents[None], axis=-1)  # [n_iter, n_agents]


def _task(payload, seed_seq):
    """One topology: scenario, polygon study, every method, the sample sweep."""
    exp, opts = payload
    streams = seed_seq.spawn(4 + len(exp.methods) + len(exp.sample_sweep) * len(exp.sample_methods))
    rng = np.random.default_rng(streams[0])
    sc = paper_static_scenario(
        rng,
        n_agents=exp.n_agents,
        side_m=exp.side_m,
        comm_range_m=exp.comm_range_m,
        error_model=exp.error_model(),
    )
    truth = sc.agent_positions
    out: dict = {}
    # 1. polygon study (Fig. 9)
    prng = np.random.default_rng(streams[1])
    for ne in exp.n_edges:
        r = poa(
            sc.positions,
            sc.ranges,
            sc.is_anchor,
            rng=prng,
            n_edges=ne,
            n_iterations=exp.poa_iterations,
            region=sc.region,
        )
        out[f"poa|{ne}|area"] = r.area_history
        out[f"poa|{ne}|contained"] = _contained(r.polygons, truth)
    # the proposal polygons: N_E = poa_n_edges, N_FS = poa_n_fs, their own stream
    prop = poa(
        sc.positions,
        sc.ranges,
        sc.is_anchor,
        rng=np.random.default_rng(streams[2]),
        n_edges=exp.poa_n_edges,
        n_iterations=exp.poa_n_fs,
        region=sc.region,
    )
    out["poa|contained"] = _contained(prop.polygons, truth)
    # the paper samples the polygon by rejection from its bounding box: measured acceptance
    arng = np.random.default_rng(streams[-1])
    out["poa|acceptance"] = np.array(
        [p.sample_rejection(exp.n_samples, arng)[1] for p in prop.polygons if p is not None]
    )
    out["poa|time_per_node_s"] = float(prop.time_s.sum(axis=0).mean())
    n_meas = int(np.isfinite(sc.ranges[~sc.is_anchor]).sum())
    out["poa|dropped"] = (int(prop.dropped.shape[0]), n_meas)
    supports = {"poa_nbp": (list(prop.polygons), out["poa|time_per_node_s"])}
    if exp.ellipses:

        def ellipses(n_iterations):
            return ellipse_outer_approximation(
                sc.positions, sc.ranges, sc.is_anchor, n_iterations=n_iterations, region=sc.region
            )

        out["ellipse|area"] = ellipses(exp.poa_iterations).area_history
        # the proposal ellipses: as many iterations as the proposal polygons (N_FS)
        t0 = time.perf_counter()
        ell = ellipses(exp.poa_n_fs)
        t_ell = (time.perf_counter() - t0) / max(exp.n_agents, 1)
        regions = [
            _EllipseRegion(c, s) if b else None
            for c, s, b in zip(ell.centers, ell.shapes, ell.bounded, strict=True)
        ]
        supports["nbp_ellipse"] = (regions, t_ell)
    if exp.baseline_start == "mds" and ({"pbp", "wls"} & set(exp.methods)):
        supports["start"] = _mds_start(sc)
    # 2. localization (Fig. 10, 11, Table I)
    s = 3
    for m in exp.methods:
        mrng = np.random.default_rng(streams[s])
        s += 1
        res, t_support = _run_method(m, sc, opts, exp.n_samples, supports, mrng)
        out[f"{m}|err"] = _errors(res, truth)
        out[f"{m}|time"] = float(np.mean(res.time_per_node_s))
        out[f"{m}|t_support"] = t_support
    # 3. sample sweep (Fig. 12)
    for m in exp.sample_methods:
        for ns in exp.sample_sweep:
            mrng = np.random.default_rng(streams[s])
            s += 1
            res, _ = _run_method(m, sc, opts, ns, supports, mrng)
            out[f"{m}|ns{ns}|err"] = _errors(res, truth)[-1]
            out[f"{m}|ns{ns}|time"] = float(np.mean(res.time_per_node_s))
    return out


def _contained(polygons, truth):
    return np.array(
        [p is None or bool(p.contains(x[None])[0]) for p, x in zip(polygons, truth, strict=True)]
    )


def _run_method(m, sc, opts, n_samples, supports, rng):
    kw = {"region": sc.region, "error_model": sc.error_model}
    if m in NBP_METHODS:
        o = dataclasses.replace(opts.nbp, proposal=NBP_METHODS[m], n_samples=n_samples)
        polys, t_support = supports.get(m, (None, 0.0))
        res = run_nbp(sc.ranges, sc.is_anchor, sc.anchor_positions, rng, o, polygons=polys, **kw)
        return res, t_support
    initial, t_start = supports.get("start", (None, 0.0))
    kw["initial"] = initial
    if m == "pbp":
        res = run_gaussian_bp(sc.ranges, sc.is_anchor, sc.anchor_positions, opts.pbp, **kw)
    else:
        res = run_wls(sc.ranges, sc.is_anchor, sc.anchor_positions, opts.wls, **kw)
    return res, t_start


def _mds_start(sc):
    """Truth-free MDS/SMACOF start of the baselines in the anchors' frame, clipped to the
    region; ``(None, 0)`` (heuristic start) when the range graph is disconnected."""
    from phyloc.localization.initialization import coarse_positions

    t0 = time.perf_counter()
    j, i = np.nonzero(np.isfinite(sc.ranges))
    links = np.stack([j, i], axis=1)
    try:
        sol = coarse_positions(
            links,
            sc.ranges[j, i],
            sc.positions.shape[0],
            2,
            is_anchor=sc.is_anchor,
            anchor_positions=sc.anchor_positions,
        )
    except ValidationError:
        return None, 0.0
    x0, y0, x1, y1 = sc.region
    start = np.clip(sol.positions[~sc.is_anchor], [x0, y0], [x1, y1])
    return start, (time.perf_counter() - t0) / max(int((~sc.is_anchor).sum()), 1)


def run(recipe: Recipe, *, fast: bool = False, workers=None, scheduler=None, progress=True):
    """Run a ``kind = "static"`` recipe; returns ``{"figures", "series", "meta"}``."""
    exp = StaticExperimentSpec.from_dict(recipe.section("experiment"), fast=fast)
    opts = method_options(recipe.section("localization"), exp)
    results = run_tasks(
        _task,
        [(exp, opts)] * exp.topologies,
        recipe.seed,
        workers=workers,
        scheduler=scheduler,
        desc="topologies",
        progress=progress,
    )
    figures, series = _aggregate(results, exp)
    meta = {
        "recipe": recipe.name,
        "kind": recipe.kind,
        "seed": recipe.seed,
        "fast": fast,
        "topologies": exp.topologies,
        "n_agents": exp.n_agents,
        "methods": list(exp.methods),
        "labels": {m: LABELS[m] for m in METHODS},
        "n_edges": list(exp.n_edges),
        "sample_sweep": list(exp.sample_sweep),
        "sample_methods": list(exp.sample_methods),
        "outage_thresholds_m": list(exp.outage_thresholds_m),
        "experiment": dataclasses.asdict(exp),
        "options": {
            "nbp": dataclasses.asdict(opts.nbp),
            "pbp": dataclasses.asdict(opts.pbp),
            "wls": dataclasses.asdict(opts.wls),
        },
        "timing": "wall time per node of this process (includes worker contention)",
        "convergence": (
            "converged after iteration l-1 at the first l with |e_l - e_(l-1)| <= "
            "max(convergence_rel * e_(l-1), convergence_abs_m) (paper footnote 5); settling: "
            "first iteration from which e stays within max(convergence_rel * e_final, "
            "convergence_abs_m) of e_final"
        ),
    }
    return {"figures": figures, "series": series, "meta": meta}


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


def _aggregate(results, exp: StaticExperimentSpec):
    figures: dict[str, float] = {}
    series: dict[str, object] = {
        "iteration": np.arange(1, exp.n_iterations + 1),
        "poa_iteration": np.arange(1, exp.poa_iterations + 1),
        "outage_threshold_m": OUTAGE_GRID_M,
    }
    for ne in exp.n_edges:
        area = np.concatenate([r[f"poa|{ne}|area"] for r in results], axis=1)  # [L, topo·ag]
        mean_area = _finite_mean(area)
        series[f"poa.ne{ne}.area_m2"] = mean_area
        for it in range(exp.poa_iterations):
            figures[f"poa.ne{ne}.area_it{it + 1}_m2"] = float(mean_area[it])
        cont = np.concatenate([r[f"poa|{ne}|contained"] for r in results])
        figures[f"poa.ne{ne}.containment_fraction"] = float(cont.mean())
    if exp.ellipses:
        area = np.concatenate([r["ellipse|area"] for r in results], axis=1)
        mean_area = _finite_mean(area)
        series["ellipse.area_m2"] = mean_area
        for it in range(exp.poa_iterations):
            figures[f"ellipse.area_it{it + 1}_m2"] = float(mean_area[it])
    figures["poa.containment_fraction"] = float(
        np.concatenate([r["poa|contained"] for r in results]).mean()
    )
    figures["poa.time_per_node_s"] = float(np.mean([r["poa|time_per_node_s"] for r in results]))
    figures["poa.rejection_acceptance_rate"] = float(
        np.mean(np.concatenate([r["poa|acceptance"] for r in results]))
    )
    dropped = sum(r["poa|dropped"][0] for r in results)
    n_meas = sum(r["poa|dropped"][1] for r in results)
    figures["poa.dropped_fraction"] = dropped / max(n_meas, 1)
    for m in exp.methods:
        err = np.concatenate([r[f"{m}|err"] for r in results], axis=1)  # [n_iter, topo·agents]
        curve = err.mean(axis=1)
        series[f"{m}.mean_error_m"] = curve
        final = err[-1]
        figures[f"{m}.mean_error_m"] = float(final.mean())
        figures[f"{m}.rmse_m"] = float(np.sqrt(np.mean(final**2)))
        conv = convergence_from_curve(curve, exp.convergence_rel, exp.convergence_abs_m)
        figures[f"{m}.convergence_iteration"] = float(conv)
        figures[f"{m}.settling_iteration"] = float(
            settling_from_curve(curve, exp.convergence_rel, exp.convergence_abs_m)
        )
        t_it = float(np.mean([r[f"{m}|time"] for r in results]))
        t_sup = float(np.mean([r[f"{m}|t_support"] for r in results]))
        figures[f"{m}.time_per_node_iteration_s"] = t_it
        figures[f"{m}.time_to_convergence_s"] = conv * t_it + t_sup
        series[f"{m}.outage"] = np.mean(final[:, None] > OUTAGE_GRID_M, axis=0)
        for x in exp.outage_thresholds_m:
            figures[f"{m}.outage_{_threshold_name(x)}"] = float(np.mean(final > x))
    for m in exp.sample_methods:
        for ns in exp.sample_sweep:
            e = np.concatenate([r[f"{m}|ns{ns}|err"] for r in results])
            base = f"{m}.ns{ns}"
            figures[f"{base}.mean_error_m"] = float(e.mean())
            figures[f"{base}.time_per_node_iteration_s"] = float(
                np.mean([r[f"{m}|ns{ns}|time"] for r in results])
            )
            series[f"{base}.outage"] = np.mean(e[:, None] > OUTAGE_GRID_M, axis=0)
            for x in exp.outage_thresholds_m:
                figures[f"{base}.outage_{_threshold_name(x)}"] = float(np.mean(e > x))
    if "poa_nbp" in exp.methods:
        for m in exp.methods:
            if m in NBP_METHODS and m != "poa_nbp":
                figures[f"poa_nbp_vs_{m}.time_to_convergence_ratio"] = (
                    figures["poa_nbp.time_to_convergence_s"] / figures[f"{m}.time_to_convergence_s"]
                )
    return figures, series


def _finite_mean(area):
    """Mean over agents of the finite areas per iteration (unbounded agents excluded)."""
    fin = np.isfinite(area)
    n = fin.sum(axis=1)
    return np.where(n > 0, np.where(fin, area, 0.0).sum(axis=1) / np.maximum(n, 1), np.nan)


def is_timing(name: str) -> bool:
    """True for the wall-time figures (the only ones that depend on the machine)."""
    return name.endswith(_TIMING)


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
    ]


def summary_rows(results: dict):
    """Accuracy after convergence, iterations and time to convergence per method."""
    f, meta = results["figures"], results["meta"]
    rows = []
    for m in meta["methods"]:
        rows.append(
            (
                LABELS[m],
                f[f"{m}.mean_error_m"],
                f[f"{m}.rmse_m"],
                int(f[f"{m}.convergence_iteration"]),
                f[f"{m}.time_per_node_iteration_s"],
                f[f"{m}.time_to_convergence_s"],
                *[f[f"{m}.outage_{_threshold_name(x)}"] for x in meta["outage_thresholds_m"]],
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
            out.append(f"{LABELS[m]} mean error vs samples: " + ", ".join(parts))
    return out


def plot(results: dict, path) -> None:
    """Figs. 9–12: polygon area vs iteration, mean error vs iteration, outage, samples."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ser, meta = results["series"], results["meta"]
    fig, ax = plt.subplots(1, 4, figsize=(20, 4.6))
    it = ser["poa_iteration"]
    for ne in meta["n_edges"]:
        ax[0].plot(it, ser[f"poa.ne{ne}.area_m2"], "o-", label=f"POA N_E={ne}")
    if "ellipse.area_m2" in ser:
        ax[0].plot(it, ser["ellipse.area_m2"], "k^--", label="ellipses")
    ax[0].set(xlabel="iteration", ylabel="mean area [m²]", yscale="log", title="Fig. 9")
    for m in meta["methods"]:
        ax[1].plot(ser["iteration"], ser[f"{m}.mean_error_m"], "o-", label=LABELS[m])
        ax[2].semilogx(ser["outage_threshold_m"], ser[f"{m}.outage"], label=LABELS[m])
    ax[1].set(
        xlabel="iteration", ylabel="mean localization error [m]", yscale="log", title="Fig. 10"
    )
    ax[2].set(xlabel="error threshold [m]", ylabel="outage probability", title="Fig. 11")
    for m in meta["sample_methods"]:
        for ns in meta["sample_sweep"]:
            ax[3].semilogx(
                ser["outage_threshold_m"],
                ser[f"{m}.ns{ns}.outage"],
                "-" if m == "poa_nbp" else "--",
                label=f"{LABELS[m]} N_S={ns}",
            )
    if "pbp" in meta["methods"]:
        ax[3].semilogx(ser["outage_threshold_m"], ser["pbp.outage"], "k:", label="PBP")
    ax[3].set(xlabel="error threshold [m]", ylabel="outage probability", title="Fig. 12")
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=7)
    fig.suptitle(f"{meta['recipe']}: {meta['topologies']} topologies x {meta['n_agents']} agents")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)

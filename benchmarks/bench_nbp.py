"""POA / NBP / PBP / WLS benchmarks on the static network of the POA-NBP paper (§V-A).

One topology of :func:`~phyloc.evaluation.static_scenarios.paper_static_scenario`: 100 agents
and 13 anchors in a 100 m × 100 m square, r_com = 20 m, exponential range errors of mean
0.38 m. POA uses N_E = 16 and N_FS = 2 (POA-NBP §V-B); its polygons are the proposals of
POA-NBP (handed to the ``poa_nbp`` method through its prior).
NBP runs ``N_ITER`` = 4 iterations (2 with ``quick``) with LSCV bandwidths, after a JIT warm-up. A
*node-iteration* is one agent's belief update; its time is the mean of the per-agent update times
(``Result.timing.agent_s``) over the agents, best of iterations 2 … N_ITER: from iteration 2 on
every agent with a path to an anchor sends messages (iteration 1 of the min-entropy proposal sees
only anchor messages), and the best iteration, as in ``_timing.best_seconds``, is the one least
disturbed by other load on the machine. The KDE work unit is POA-NBP eq. (8): N_S points × N_S
centres × 10 messages shaped like range messages (rings of radius 8–18 m, LSCV bandwidth), evaluated
around the agent. Figures (names are the interface):

``poa.time_per_node_s``                      POA per agent, both iterations summed [s]
``poa.intersect_s``                          one :func:`intersect` of two 16-gons [s]
``poa.intersect_kernel_s``                   the same clipping, numba kernel alone [s]
``poa.intersect_numpy_s``                    ... its NumPy twin (``tests/naive_static.py``) [s]
``poa.intersect_speedup_vs_numpy``           NumPy twin time / kernel time
``nbp.ns<N>.time_per_node_iteration_s``      POA-NBP (polygon proposal), N in 100 200 400 800 [s]
``nbp_min_entropy.ns<N>.time_per_node_iteration_s``   NBP with the min-entropy proposal [s]
``nbp_aux.ns<N>.time_per_node_iteration_s``   NBP with the auxiliary (anchor) proposal [s]
``nbp.cost_exponent``                        d log(time) / d log(N_S) of POA-NBP (least squares)
``nbp_min_entropy.cost_exponent``            ... of min-entropy NBP
``nbp_aux.cost_exponent``                    ... of auxiliary-proposal NBP
``nbp.kde.ns<N>.time_s``                     one POA-NBP eq. (8) KDE evaluation, numba kernel,
                                             1 thread [s]
``nbp.kde.cost_exponent``                    d log(time) / d log(N_S) of the KDE (2: N_S²)
``nbp.kde.speedup_vs_numpy``                 NumPy twin time / kernel time at N_S = 200
``pbp.time_per_node_iteration_s``            Gaussian BP (PBP, n_inner = 3) [s]
``wls.time_per_node_iteration_s``            joint WLS (LM step / number of agents) [s]
``nbp.n_agents``, ``nbp.n_iterations``       the setup

The total NBP cost is far from quadratic at these sizes: besides the O(N_S²) KDE, each of
the ≈ 10 messages per agent costs a fixed Python/SciPy overhead (bandwidth rule, ``logsumexp``,
message objects), O(N_S) sampling and an LSCV score that is quadratic up to 256 samples and
constant above. ``nbp.cost_exponent`` is therefore near 1 over 100 … 800 (the KDE is about
a tenth of the time at N_S = 100 and well over half at 800); ``nbp.kde.cost_exponent`` shows the
quadratic term alone.

The NumPy twins are test code, loaded by :func:`benchmarks._reference.naive` from the source
checkout's ``tests/naive_static.py``; without one the ``*numpy*`` / ``*speedup_vs_numpy``
figures are not measured (``MISSING``).

References
----------
POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import math

import numba
import numpy as np
from threadpoolctl import threadpool_limits

from phyloc.evaluation.static_scenarios import paper_static_scenario
from phyloc.localization.static import _polygon_kernels as PK
from phyloc.localization.static._nbp_kernels import kde_logpdf_kernel
from phyloc.localization.static.gaussian_bp import (
    GaussianBPOptions,
    WLSOptions,
    run_gaussian_bp,
    run_wls,
)
from phyloc.localization.static.kde import lscv_bandwidth
from phyloc.localization.static.messages import range_message_samples
from phyloc.localization.static.nbp import NBPOptions, run_nbp
from phyloc.localization.static.poa_network import poa
from phyloc.localization.static.polygons import anchor_polygon, intersect
from phyloc.localization.static.static_ranges import ExponentialRangeError
from phyloc.reporting import format_table

try:
    from phyloc.benchmarks._reference import MISSING, naive
    from phyloc.benchmarks._timing import best_seconds
except ImportError:  # run from the source tree by asv
    from benchmarks._reference import MISSING, naive
    from benchmarks._timing import best_seconds

N_AGENTS = 100
N_EDGES = 16
N_FS = 2
N_ITER = 4
SAMPLE_SWEEP = (100, 200, 400, 800)
KDE_MESSAGES = 10
PROPOSALS = {"nbp": "polygon", "nbp_min_entropy": "min_entropy", "nbp_aux": "auxiliary"}


def make_scenario(seed: int = 0, n_agents: int = N_AGENTS):
    """The POA-NBP §V-A network and its POA polygons (N_E = 16, N_FS = 2)."""
    rng = np.random.default_rng(seed)
    sc = paper_static_scenario(rng, n_agents=n_agents)
    res = _poa(sc, rng)
    return sc, res


def _poa(sc, rng):
    meas = sc.measurements()
    return poa(
        meas.positions,
        meas.ranges,
        meas.is_anchor,
        rng=rng,
        n_edges=N_EDGES,
        n_iterations=N_FS,
        region=sc.region,
    )


def _run_nbp(sc, polygons, n_samples, proposal, n_iterations, seed=1):
    opt = NBPOptions(n_samples=n_samples, n_iterations=n_iterations, proposal=proposal)
    prior = sc.prior(polygons=list(polygons) if proposal == "polygon" else None)
    return run_nbp(sc.measurements(), prior, np.random.default_rng(seed), opt)


def warm_up() -> None:
    """Compile (or load from the cache) every kernel NBP, POA and PBP touch, on a small network."""
    sc, res = make_scenario(seed=99, n_agents=10)
    for proposal in PROPOSALS.values():
        _run_nbp(sc, res.polygons, 300, proposal, 2)  # > 256 samples: the LSCV subset path too
    run_gaussian_bp(sc.measurements(), sc.prior())
    run_wls(sc.measurements(), sc.prior())
    pts, centers, lw, h = kde_case(50)
    kde_logpdf_kernel(pts, centers, lw, h, np.empty((centers.shape[0], pts.shape[0])))


def _steady(agent_s: np.ndarray) -> float:
    """Time per node-iteration from ``Result.timing.agent_s`` (mean over agents per
    iteration): the best of iterations 2 … L (1 if L = 1)."""
    t = agent_s[1:] if agent_s.shape[0] > 1 else agent_s
    return float(t.min())


def kde_case(n_samples: int, n_messages: int = KDE_MESSAGES, seed: int = 0):
    """Inputs of one POA-NBP eq. (8) evaluation: ``(points [N_S, 2], centers [M, N_S, 2],
    log_weights [M, N_S], bandwidths [M])`` for an agent at the origin with ``M`` agent
    neighbours 8–18 m away (beliefs of 1 m spread), its proposal samples uniform in a
    6 m × 6 m square."""
    rng = np.random.default_rng(seed)
    model = ExponentialRangeError()
    ang = rng.uniform(0.0, 2.0 * math.pi, n_messages)
    dist = rng.uniform(8.0, 18.0, n_messages)
    nb = np.column_stack([dist * np.cos(ang), dist * np.sin(ang)])
    centers = np.empty((n_messages, n_samples, 2))
    log_w = np.empty((n_messages, n_samples))
    h = np.empty(n_messages)
    for m in range(n_messages):
        belief = nb[m] + rng.normal(0.0, 1.0, (n_samples, 2))
        z = dist[m] + float(model.sample(1, rng)[0])
        y, w = range_message_samples(belief, z, model, rng)
        centers[m], log_w[m] = y, np.log(w)
        h[m] = max(lscv_bandwidth(y, w, rng=rng), 0.01)
    points = rng.uniform(-3.0, 3.0, (n_samples, 2))
    return points, centers, log_w, h


def intersect_case():
    """Two overlapping 16-gons: anchor polygons of radii 10 m and 7 m, centres 8.5 m apart."""
    P = anchor_polygon([0.0, 0.0], 10.0, N_EDGES)
    Q = anchor_polygon([8.0, 3.0], 7.0, N_EDGES, offset_rad=0.1)
    A, c = Q.halfspaces()
    return P, Q, (P.vertices, A, c, np.array([0, A.shape[0]], dtype=np.int64), 1e-12, False)


def _slope(x, t) -> float:
    return float(np.polyfit(np.log(x), np.log(t), 1)[0])


# -- asv ----------------------------------------------------------------------------------------
class TimePOA:
    """asv: POA (N_E = 16, N_FS = 2) on the 100-agent network."""

    def setup(self):
        self.sc, _ = make_scenario()

    def time_poa(self):
        _poa(self.sc, np.random.default_rng(0))


class TimeIntersect:
    """asv: one intersection of two 16-gons, numba kernel or NumPy twin."""

    params = [["numba", "numpy"]]
    param_names = ["backend"]

    def setup(self, backend):
        _, _, self.args = intersect_case()
        if backend == "numba":
            self.fn = PK.clip_groups_kernel
        else:
            twin = naive("naive_static")
            if twin is None:
                raise NotImplementedError(MISSING)  # asv skips the parameter
            self.fn = twin.clip_groups_numpy
        self.fn(*self.args)

    def time_intersect(self, backend):
        self.fn(*self.args)


class TimeKDE:
    """asv: the POA-NBP eq. (8) KDE, N_S points × N_S centres × 10 messages."""

    params = [list(SAMPLE_SWEEP), ["numba", "numpy"]]
    param_names = ["n_samples", "backend"]

    def setup(self, n_samples, backend):
        self.pts, self.centers, self.lw, self.h = kde_case(n_samples)
        self.out = np.empty((self.centers.shape[0], self.pts.shape[0]))
        self.twin = None
        if backend == "numpy":
            self.twin = naive("naive_static")
            if self.twin is None:
                raise NotImplementedError(MISSING)  # asv skips the parameter
        self.time_kde(n_samples, backend)

    def time_kde(self, n_samples, backend):
        if backend == "numba":
            kde_logpdf_kernel(self.pts, self.centers, self.lw, self.h, self.out)
        else:
            self.twin.kde_logpdf_numpy(self.pts, self.centers, self.lw, self.h)


class TimeNBP:
    """asv: two NBP iterations on the 100-agent network."""

    params = [list(SAMPLE_SWEEP), list(PROPOSALS.values())]
    param_names = ["n_samples", "proposal"]
    timeout = 120

    def setup(self, n_samples, proposal):
        warm_up()
        self.sc, res = make_scenario()
        self.polygons = res.polygons

    def time_nbp(self, n_samples, proposal):
        _run_nbp(self.sc, self.polygons, n_samples, proposal, 2)


class TimeBaselines:
    """asv: PBP and joint WLS, 10 iterations each (one BLAS thread, as in :func:`report`)."""

    def setup(self):
        self.limits = threadpool_limits(limits=1, user_api="blas")
        self.sc, _ = make_scenario()
        self.args = (self.sc.measurements(), self.sc.prior(), None)
        self.time_pbp()
        self.time_wls()

    def teardown(self):
        self.limits.restore_original_limits()

    def time_pbp(self):
        run_gaussian_bp(*self.args, GaussianBPOptions(n_iterations=10))

    def time_wls(self):
        run_wls(*self.args, WLSOptions(n_iterations=10))


# -- phyloc bench -------------------------------------------------------------------------------
def report(quick: bool = False) -> dict[str, float]:
    """Measure every figure of the module docstring (``quick``: 2 NBP iterations, fewer repeats).

    One BLAS thread and one numba thread throughout, as in the experiment runner: a node's
    update is one core's work, and on a busy machine idle BLAS threads spinning beside numba's
    made the joint WLS step about 60× slower (1.6 ms instead of 0.02 ms per node).
    """
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        with threadpool_limits(limits=1, user_api="blas"):
            return _report(quick)
    finally:
        numba.set_num_threads(before)


def _report(quick: bool) -> dict[str, float]:
    n_iter = 2 if quick else N_ITER
    repeat = 3 if quick else 5
    warm_up()
    sc, _ = make_scenario()
    fig: dict[str, float] = {"nbp.n_agents": sc.agents.size, "nbp.n_iterations": n_iter}
    twin = naive("naive_static")

    # POA: best of `repeat` runs of the per-agent time (fresh offsets each run)
    runs = [_poa(sc, np.random.default_rng(r)) for r in range(repeat)]
    fig["poa.time_per_node_s"] = min(float(r.time_s.sum(axis=0).mean()) for r in runs)
    polygons = runs[0].polygons
    P, Q, args = intersect_case()
    fig["poa.intersect_s"] = best_seconds(lambda: intersect(P, Q), repeat=repeat, min_time=0.2)
    fig["poa.intersect_kernel_s"] = best_seconds(
        lambda: PK.clip_groups_kernel(*args), repeat=repeat, min_time=0.2
    )
    if twin is not None:
        fig["poa.intersect_numpy_s"] = best_seconds(
            lambda: twin.clip_groups_numpy(*args), repeat=repeat, min_time=0.2
        )
        fig["poa.intersect_speedup_vs_numpy"] = (
            fig["poa.intersect_numpy_s"] / fig["poa.intersect_kernel_s"]
        )

    # the KDE of POA-NBP eq. (8) alone (a serial kernel)
    t_kde = []
    for ns in SAMPLE_SWEEP:
        pts, centers, lw, h = kde_case(ns)
        out = np.empty((centers.shape[0], ns))
        t = best_seconds(
            lambda pts=pts, c=centers, lw=lw, h=h, out=out: kde_logpdf_kernel(pts, c, lw, h, out),
            repeat=repeat,
            min_time=0.1,
        )
        fig[f"nbp.kde.ns{ns}.time_s"] = t
        t_kde.append(t)
        if ns == 200 and twin is not None:
            t_np = best_seconds(
                lambda pts=pts, c=centers, lw=lw, h=h: twin.kde_logpdf_numpy(pts, c, lw, h),
                repeat=max(2, repeat - 2),
            )
            fig["nbp.kde.speedup_vs_numpy"] = t_np / t
    fig["nbp.kde.cost_exponent"] = _slope(SAMPLE_SWEEP, t_kde)

    # NBP sample sweep, one run per size after the warm-up
    for name, proposal in PROPOSALS.items():
        ts = []
        for ns in SAMPLE_SWEEP:
            res = _run_nbp(sc, polygons, ns, proposal, n_iter)
            t = _steady(res.timing.agent_s)
            fig[f"{name}.ns{ns}.time_per_node_iteration_s"] = t
            ts.append(t)
        fig[f"{name}.cost_exponent"] = _slope(SAMPLE_SWEEP, ts)

    # parametric baselines (cheap: 10 iterations each)
    args = (sc.measurements(), sc.prior(), None)
    pbp = run_gaussian_bp(*args, GaussianBPOptions(n_iterations=10))
    fig["pbp.time_per_node_iteration_s"] = _steady(pbp.timing.agent_s)
    wls = run_wls(*args, WLSOptions(n_iterations=10))
    fig["wls.time_per_node_iteration_s"] = _steady(wls.timing.agent_s)
    return fig


def summarize(fig: dict) -> str:
    """The printed form of :func:`report`."""
    ms = 1e3
    rows = []
    for ns in SAMPLE_SWEEP:
        rows.append(
            (
                f"N_S = {ns}",
                ms * fig[f"nbp.ns{ns}.time_per_node_iteration_s"],
                ms * fig[f"nbp_min_entropy.ns{ns}.time_per_node_iteration_s"],
                ms * fig[f"nbp.kde.ns{ns}.time_s"],
            )
        )
    rows.append(
        (
            "exponent d log t / d log N_S",
            fig["nbp.cost_exponent"],
            fig["nbp_min_entropy.cost_exponent"],
            fig["nbp.kde.cost_exponent"],
        )
    )
    t1 = format_table(
        rows,
        [
            f"{int(fig['nbp.n_agents'])} agents, {int(fig['nbp.n_iterations'])} iterations",
            "POA-NBP [ms/node-it]",
            "NBP min. [ms/node-it]",
            "KDE x10 msgs [ms]",
        ],
    )
    rows2 = [
        ("POA (N_E = 16, N_FS = 2)", ms * fig["poa.time_per_node_s"], "per node, total"),
        ("PBP", ms * fig["pbp.time_per_node_iteration_s"], "per node-iteration"),
        ("WLS (joint)", ms * fig["wls.time_per_node_iteration_s"], "per node-iteration"),
    ]
    t2 = format_table(rows2, ["method", "time [ms]", ""])
    if "poa.intersect_speedup_vs_numpy" in fig:
        ratios = (
            f"{fig['poa.intersect_speedup_vs_numpy']:.3g}x the NumPy twin); KDE kernel "
            f"{fig['nbp.kde.speedup_vs_numpy']:.3g}x its NumPy twin at N_S = 200"
        )
    else:
        ratios = f"NumPy twin MISSING)\nMISSING: {MISSING}"
    t3 = (
        f"one intersection of two 16-gons: {1e6 * fig['poa.intersect_s']:.3g} us "
        f"(kernel {1e6 * fig['poa.intersect_kernel_s']:.3g} us, {ratios}"
    )
    return f"{t1}\n\n{t2}\n\n{t3}"

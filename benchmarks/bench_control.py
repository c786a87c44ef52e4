"""Control benchmarks: decisions per second of the FIM searches and their growth.

The problem is the FIM case study's (one agent with the planar CV state of
:class:`~phyloc.control.ControlScenario`, prior ``diag(10², 10², 50², 0.1, 0.1)``, one static
anchor, ``M₁`` mobile anchors, σ = 0.1 m) at a fixed random geometry. The control sets are
3-D :func:`~phyloc.control.control_set` grids: 8 azimuths × {1, 3, 5} elevation rings + the 2
poles (|U| = 10, 26, 42) and 14 azimuths × 3 rings + 2 (|U| = 44). Figures (names are the
interface; times are the best of several calls, after a JIT warm-up)::

    control.myopic.decisions_per_s            T = 1, exact, |U| = 26
    control.rh.t2.exact.decisions_per_s       T = 2, exact (|U|² = 676 leaves)
    control.rh.t3.exact.decisions_per_s       T = 3, exact (17 576 leaves)
    control.rh.t2.approx.decisions_per_s      one anchor at a time, greedy in time
    control.rh.t3.approx.decisions_per_s
    control.rh.t5.vbest10.decisions_per_s     V-best sequences, V = 10
    control.exact.exponent_in_U               d log t / d log |U| at T = 3, M₁ = 1, divided by T
                                              (theory 1: t ∝ |U|^{M₁T})
    control.exact.exponent_in_T               log_{|U|} t(T = 3)/t(T = 2), |U| = 26 (theory 1)
    control.exact.exponent_in_M1              log t(M₁ = 2)/t(M₁ = 1) / log |U|^T at |U| = 10,
                                              T = 3 (theory 1)
    control.approx.exponent_in_U              d log t / d log |U| (theory 1 in evaluations; the
                                              |U| candidates of a step are one vectorized call,
                                              so the time is nearly flat)
    control.approx.exponent_in_T              d log t / d log T, T = 1 … 8 (theory 1 in the
                                              number of cost evaluations, O(M₁|U|T))
    control.approx.exponent_in_M1             d log t / d log M₁, M₁ = 1, 2, 4 (theory 1)
    control.level.kernel_s                    one level of 26³ nodes, Numba kernels (prediction
                                              per node, covariances written) [s]
    control.level.last_s                      the same level as a search's last: 26² parents
                                              predicted once for their 26 children, costs alone [s]
    control.level.numpy_s                     the same, NumPy twin (tests/naive_control.py)
    control.level.speedup_vs_numpy            twin time / kernel time

Small trees are dominated by fixed per-call costs (Python, array set-up), so the exact
search's exponents are measured where the leaves dominate (10³–10⁶ leaves; ``--quick`` uses
smaller trees and reads lower). The approximate search makes ``M₁·T`` vectorized calls of
``|U|`` candidates, so its time grows with ``M₁·T`` and hardly with ``|U|``.

References
----------
FIM: W. Zhang, B. Teague and F. Meyer, "Cooperative localization: a Fisher information
approach," arXiv:2212.14554, 2022.
"""

from __future__ import annotations

import numpy as np
from threadpoolctl import threadpool_limits

from phyloc.control import ControlProblem, ControlScenario, control_set, search
from phyloc.control.fim import range_information
from phyloc.reporting import format_table

try:
    from phyloc.benchmarks._reference import MISSING, naive
    from phyloc.benchmarks._timing import best_seconds
except ModuleNotFoundError:  # run from a source checkout
    from benchmarks._reference import MISSING, naive
    from benchmarks._timing import best_seconds

U_SETS = {10: (8, (0.0,)), 26: (8, (-45.0, 0.0, 45.0)), 42: (8, (-60, -30, 0, 30, 60)),
          44: (14, (-45.0, 0.0, 45.0))}  # fmt: skip


def problem(n_controls: int = 26, n_mobile: int = 1, seed: int = 0) -> ControlProblem:
    """The case-study problem with ``n_mobile`` mobile anchors and a |U| of ``U_SETS``."""
    sc = ControlScenario()
    F, Q = sc.model.matrices()
    rng = np.random.default_rng(seed)
    mean = np.r_[rng.uniform(-100, 100, 3), 0.0, 0.0][None]
    n_az, elev = U_SETS[n_controls]
    return ControlProblem(
        mean,
        np.diag(sc.prior_var)[None],
        F,
        Q,
        rng.uniform(-100, 100, (n_mobile, 3)),
        rng.uniform(-100, 100, (1, 3)),
        control_set(2.0, n_az, elev),
        1.0,
        0.1,
    )


def _time(p, T, method="exact", beam=10, quick=False):
    return best_seconds(lambda: search(p, T, method=method, beam=beam), repeat=2 if quick else 5)


def _slope(x, t) -> float:
    return float(np.polyfit(np.log(x), np.log(t), 1)[0])


def report(quick: bool = False) -> dict[str, float]:
    """Measure every figure of the module docstring; ``quick`` shortens the runs."""
    fig: dict[str, float] = {}
    with threadpool_limits(limits=1, user_api="blas"):
        p = problem()
        fig["control.myopic.decisions_per_s"] = 1.0 / _time(p, 1, quick=quick)
        for T in (2, 3):
            fig[f"control.rh.t{T}.exact.decisions_per_s"] = 1.0 / _time(p, T, quick=quick)
            t = _time(p, T, "approx", quick=quick)
            fig[f"control.rh.t{T}.approx.decisions_per_s"] = 1.0 / t
        fig["control.rh.t5.vbest10.decisions_per_s"] = 1.0 / _time(p, 5, "vbest", quick=quick)
        sizes = [10, 26, 42, 44]
        T_u = 2 if quick else 3  # leaf-dominated trees: |U|^T >= 1000
        t_ex = [_time(problem(n), T_u, quick=quick) for n in sizes]
        t_ap = [_time(problem(n), 3, "approx", quick=quick) for n in sizes]
        fig["control.exact.exponent_in_U"] = _slope(sizes, t_ex) / T_u
        fig["control.approx.exponent_in_U"] = _slope(sizes, t_ap)
        t2, t3 = _time(p, 2, quick=quick), _time(p, 3, quick=quick)
        fig["control.exact.exponent_in_T"] = float(np.log(t3 / t2) / np.log(26))
        Ta = [1, 2, 4, 8]
        t_a = [_time(p, T, "approx", quick=quick) for T in Ta]
        fig["control.approx.exponent_in_T"] = _slope(Ta, t_a)
        T_m = 2 if quick else 3
        t_m = [_time(problem(10, m), T_m, quick=quick) for m in (1, 2)]
        fig["control.exact.exponent_in_M1"] = float(np.log(t_m[1] / t_m[0]) / np.log(10**T_m))
        Ms = [1, 2, 4]
        t_am = [_time(problem(26, m), 3, "approx", quick=quick) for m in Ms]
        fig["control.approx.exponent_in_M1"] = _slope(Ms, t_am)
        fig.update(_level(quick))
    return fig


def _level(quick: bool) -> dict[str, float]:
    """One level of 26³ nodes: the Numba kernels against their NumPy twin, and the same level
    as the last of a search."""
    p = problem()
    rng = np.random.default_rng(1)
    N = 26**3
    covs = np.repeat(p.cov[None], N, axis=0)
    pos = p.mobile[None] + rng.uniform(-6, 6, (N, 1, 3))
    means = p.predicted_means(1)[None, 0]
    sinfo = range_information(means[0], p.static, p.sigma_r)[None]
    parents = covs[: N // 26]

    def kernel():
        p.level(covs, pos, 0, means, sinfo)

    def last():
        p.level(parents, pos, 0, means, sinfo, reps=26, want_covs=False)

    fig = {"control.level.kernel_s": best_seconds(kernel, repeat=3 if quick else 7)}
    fig["control.level.last_s"] = best_seconds(last, repeat=3 if quick else 7)
    twin = naive("naive_control")
    if twin is None:
        print(MISSING)
        fig["control.level.numpy_s"] = float("nan")
        fig["control.level.speedup_vs_numpy"] = float("nan")
        return fig
    t_np = best_seconds(
        lambda: twin.level_numpy(covs, p.F, p.Q, means[0], pos, sinfo[0], p.sigma_r),
        repeat=2 if quick else 5,
    )
    fig["control.level.numpy_s"] = t_np
    fig["control.level.speedup_vs_numpy"] = t_np / fig["control.level.kernel_s"]
    return fig


def summarize(fig: dict[str, float]) -> str:
    """Decisions per second, cost per decision, exponents against the theory."""
    rows = []
    for key in (
        "control.myopic",
        "control.rh.t2.exact",
        "control.rh.t3.exact",
        "control.rh.t2.approx",
        "control.rh.t3.approx",
        "control.rh.t5.vbest10",
    ):
        d = fig[f"{key}.decisions_per_s"]
        rows.append((key, f"{d:.1f} /s", f"{1e3 / d:.3f} ms", ""))
    theory = {
        "control.exact.exponent_in_U": "1 (|U|^(M1·T), per T)",
        "control.exact.exponent_in_T": "1 (|U|^T)",
        "control.exact.exponent_in_M1": "1 (|U|^(M1·T), per M1)",
        "control.approx.exponent_in_U": "~0 (one vectorized call)",
        "control.approx.exponent_in_T": "1 in evaluations",
        "control.approx.exponent_in_M1": "1",
    }
    for k, th in theory.items():
        rows.append((k, f"{fig[k]:.2f}", "", th))
    rows.append(
        (
            "control.level (26³ nodes)",
            f"{1e3 * fig['control.level.kernel_s']:.2f} ms",
            f"{1e3 * fig['control.level.numpy_s']:.2f} ms NumPy",
            f"{fig['control.level.speedup_vs_numpy']:.1f}× faster",
        )
    )
    if "control.level.last_s" in fig:
        rows.append(
            (
                "control.level, a search's last",
                f"{1e3 * fig['control.level.last_s']:.2f} ms",
                "26² parents x 26 children",
                f"{fig['control.level.kernel_s'] / fig['control.level.last_s']:.1f}× faster "
                "than the full level",
            )
        )
    return format_table(rows, ["figure", "value", "per decision / twin", "theory"])

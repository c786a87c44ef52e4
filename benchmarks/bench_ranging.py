"""Range-estimator benchmarks: ranges per second of each estimator, SAGE's cost per sweep.

Work unit: one link of the DiPNet system (N = 2569 subcarriers) with 24 paths (exponential
excess delays, mean 50 ns), in batches of 256 links, correlation tables at β ≈ 8 (L = 20480),
the estimators' defaults (window 0–300 m; SAGE with L+1 = 5 paths and 10 sweeps). The reference
("floor") is building the correlation tables themselves, which every estimator needs. Figures
(names are the interface):

``ranging.table_links_per_s``            correlation tables built per second (the floor)
``ranging.<m>.ranges_per_s``             ranges per second, m = corr, first_peak, sage (and
                                         links judged per second for m = energy_concentration,
                                         the NLOS identification of ``phyloc.ranging.nlos``)
``ranging.<m>.cost_over_table``          (1/ranges_per_s) / (1/table_links_per_s)
``ranging.sage.us_per_iteration``        µs per SAGE sweep (all L+1 paths) and link:
                                         (t(10 sweeps) − t(0 sweeps)) / (10 · links)
``ranging.sage_numpy.ranges_per_s``      SAGE with its plain-NumPy twins (reference, 8 links)
``ranging.sage.speedup_vs_numpy``        sage / sage_numpy
``ranging.zzb_table_s``                  building the cached ZZB table (one pilot spectrum)
``ranging.zzb_interp_max_rel_error``     max relative error of the interpolated ZZB against
                                         direct ``zzb_range`` at random SNRs (−40…60 dB pc)

The NumPy twins of the SAGE and residual kernels are test code (``tests/naive_ranging.py``),
loaded from the source checkout by :func:`benchmarks._reference.naive`; without one the two
``sage_numpy`` figures are not measured (the table says ``MISSING``).
"""

from __future__ import annotations

import time
from contextlib import contextmanager

import numpy as np

from phyloc.phy.bounds import zzb_range
from phyloc.phy.correlation import correlation_tables
from phyloc.phy.synthesis import synthesize
from phyloc.ranging import (
    _kernels,
    correlation_peak,
    energy_concentration,
    first_peak,
    ranging_variance,
    sage,
)
from phyloc.ranging.variance import clear_cache

try:
    from phyloc.benchmarks._reference import MISSING, naive
    from phyloc.benchmarks._timing import best_seconds
    from phyloc.benchmarks.bench_phy import BETA, N_LINKS, N_PATHS, make_batch
except ImportError:  # run from the source tree by asv
    from benchmarks._reference import MISSING, naive
    from benchmarks._timing import best_seconds
    from benchmarks.bench_phy import BETA, N_LINKS, N_PATHS, make_batch

METHODS = {
    "corr": correlation_peak,
    "first_peak": first_peak,
    "sage": sage,
    "energy_concentration": energy_concentration,  # the NLOS identification (per link)
}
SAGE_ITERATIONS = 10


def make_tables(n_links=N_LINKS, n_paths=N_PATHS, seed=0):
    """The benchmark batch (:func:`bench_phy.make_batch`) as correlation tables."""
    system, S, paths, rng = make_batch(n_links=n_links, n_paths=n_paths, seed=seed)
    R = synthesize(paths, S, system, rng)
    return R, S, system, correlation_tables(R, S, system, beta=BETA)


class Estimators:
    """asv: ranges of 256 multipath links per estimator."""

    params = [list(METHODS)]
    param_names = ["method"]

    def setup(self, method):
        _R, _S, _system, self.table = make_tables()
        METHODS[method](self.table)  # compile kernels, plan FFTs, tabulate the ZZB

    def time_estimate(self, method):
        METHODS[method](self.table)


class SageSweeps:
    """asv: SAGE with 0 sweeps (SIC initialization only) and with 10 sweeps."""

    params = [[0, SAGE_ITERATIONS]]
    param_names = ["n_iter"]

    def setup(self, n_iter):
        _R, _S, _system, self.table = make_tables()
        sage(self.table, n_iter=n_iter)

    def time_sage(self, n_iter):
        sage(self.table, n_iter=n_iter)


class Tables:
    """asv: the floor, building the correlation tables of the batch."""

    def setup(self):
        self.R, self.S, self.system, _ = make_tables()

    def time_tables(self):
        correlation_tables(self.R, self.S, self.system, beta=BETA)


@contextmanager
def numpy_twins(twin):
    """Within the block, :func:`sage` runs its SAGE and residual steps on the NumPy twins
    ``twin.sage_numpy`` / ``twin.residual_numpy`` (``twin`` = the ``naive_ranging`` module)
    instead of the Numba kernels; the kernels are restored on exit."""

    def sage_kernel(*args):
        args[6][:], args[7][:] = twin.sage_numpy(*args)  # dist, gain are updated in place

    def residual_kernel(*args):
        args[-1][:] = twin.residual_numpy(*args[:-1])

    saved = _kernels.sage_kernel, _kernels.residual_kernel
    _kernels.sage_kernel, _kernels.residual_kernel = sage_kernel, residual_kernel
    try:
        yield
    finally:
        _kernels.sage_kernel, _kernels.residual_kernel = saved


def _sage_numpy_seconds(twin, table) -> float:
    with numpy_twins(twin):
        return best_seconds(lambda: sage(table), repeat=1)


def _zzb_accuracy(S, system, n: int, seed: int = 3) -> tuple[float, float]:
    clear_cache()
    t0 = time.perf_counter()
    ranging_variance(1.0, S, system)
    build = time.perf_counter() - t0
    rng = np.random.default_rng(seed)
    pc_db = rng.uniform(-40.0, 60.0, n)
    snr = 10 ** (pc_db / 10) / system.n_subcarriers
    got = ranging_variance(snr, S, system)
    ref = np.array([zzb_range(s, S, system, prior_range_m=300.0) for s in snr])
    return build, float(np.max(np.abs(got / ref - 1.0)))


def report(quick: bool = False) -> dict[str, float]:
    """Measure every figure of the module docstring; ``quick`` shortens the runs."""
    repeat = 2 if quick else 5
    R, S, system, table = make_tables()
    fig: dict[str, float] = {
        "n_links": N_LINKS,
        "n_paths": N_PATHS,
        "n_fft": table.n_fft,
        "beta": table.beta,
        "sage_paths": 5,
        "sage_sweeps": SAGE_ITERATIONS,
    }
    t_table = best_seconds(lambda: correlation_tables(R, S, system, beta=BETA), repeat=repeat)
    fig["ranging.table_links_per_s"] = N_LINKS / t_table
    for name, fn in METHODS.items():
        t = best_seconds(lambda fn=fn: fn(table), repeat=repeat)
        fig[f"ranging.{name}.ranges_per_s"] = N_LINKS / t
        fig[f"ranging.{name}.cost_over_table"] = t / t_table
    t0 = best_seconds(lambda: sage(table, n_iter=0), repeat=repeat)
    t10 = best_seconds(lambda: sage(table, n_iter=SAGE_ITERATIONS), repeat=repeat)
    fig["ranging.sage.us_per_iteration"] = 1e6 * max(t10 - t0, 0.0) / (SAGE_ITERATIONS * N_LINKS)
    twin = naive("naive_ranging")
    if twin is not None:
        t_np = _sage_numpy_seconds(twin, table.select(np.arange(8)))
        fig["ranging.sage_numpy.ranges_per_s"] = 8 / t_np
        fig["ranging.sage.speedup_vs_numpy"] = fig["ranging.sage.ranges_per_s"] / (8 / t_np)
    build, err = _zzb_accuracy(S[0], system, 4 if quick else 16)
    fig["ranging.zzb_table_s"] = build
    fig["ranging.zzb_interp_max_rel_error"] = err
    return fig


def summarize(fig: dict) -> str:
    """The printed form of :func:`report`'s figures."""
    from phyloc.reporting import format_table

    floor = fig["ranging.table_links_per_s"]
    rows = [("correlation tables (floor)", floor, 1e6 / floor, 1.0)]
    for name in METHODS:
        rate = fig[f"ranging.{name}.ranges_per_s"]
        rows.append((name, rate, 1e6 / rate, fig[f"ranging.{name}.cost_over_table"]))
    has_twin = "ranging.sage_numpy.ranges_per_s" in fig
    if has_twin:
        rate = fig["ranging.sage_numpy.ranges_per_s"]
        rows.append(("sage (NumPy twins)", rate, 1e6 / rate, floor / rate))
    else:
        rows.append(("sage (NumPy twins)", "MISSING", None, None))
    head = (
        f"N = 2569 subcarriers, {int(fig['n_paths'])} paths/link, batches of "
        f"{int(fig['n_links'])} links, beta = {fig['beta']:.3f}; SAGE: "
        f"{int(fig['sage_paths'])} paths, {int(fig['sage_sweeps'])} sweeps"
    )
    t1 = format_table(rows, ["estimator", "ranges/s", "us/range", "x table cost"])
    extra_rows = [("SAGE sweep (all paths), us per link", fig["ranging.sage.us_per_iteration"])]
    if has_twin:
        extra_rows.append(("SAGE speed-up over NumPy twins", fig["ranging.sage.speedup_vs_numpy"]))
    extra_rows += [
        ("ZZB table build [s]", fig["ranging.zzb_table_s"]),
        ("ZZB interpolation max rel. error", fig["ranging.zzb_interp_max_rel_error"]),
    ]
    extra = format_table(extra_rows, ["figure", "value"])
    missing = "" if has_twin else f"\nMISSING: {MISSING}"
    return f"{head}\n{t1}{missing}\n\n{extra}"

"""Analysis benchmarks: the DiPNet §IV concavity indicator and belief shift.

Figures (names are the interface; times are the best of several calls)::

    analysis.cci.curvature_ns_per_path      closed-form curvature of DiPNet eq. (40) per path
                                            (N = 2569), vectorized over 10⁶ paths [ns]
    analysis.cci.sum_ns_per_path            the same by the plain-NumPy sum of eq. (40) over
                                            the 2N − 1 values of S (the reference) [ns]
    analysis.cci.speedup_vs_sum             reference time / closed-form time
    analysis.cci.mc_us_per_link             Monte Carlo CCI of C2 at 30 m: draw + curvature,
                                            per link [µs]
    analysis.cci.draw_us_per_link           draw_links alone (the floor of the Monte Carlo) [µs]
    analysis.cci.mc_over_draw               the ratio of the two
    analysis.cci.curves_s                   the closed-form curves of one scenario, 400 d0 [s]
    analysis.belief_shift.figure3_s         DiPNet Fig. 3, 401 offsets, ν = 1 [s]

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import math

import numpy as np

from phyloc.analysis import cci
from phyloc.analysis.belief_shift import figure3
from phyloc.channels import draw_links
from phyloc.phy.system import C0, OFDMSystem
from phyloc.reporting import format_table

try:
    from phyloc.benchmarks._timing import best_seconds
except ModuleNotFoundError:  # run from a source checkout
    from benchmarks._timing import best_seconds


def report(quick: bool = False) -> dict[str, float]:
    """Run the analysis benchmarks; returns the figures of the module docstring."""
    system = OFDMSystem()
    n, f_sc = system.n_subcarriers, system.subcarrier_spacing_hz
    w = 2.0 * math.pi * f_sc
    rng = np.random.default_rng(0)
    m = 100_000 if quick else 1_000_000
    x = rng.exponential(100e-9, m)
    tau0 = 30.0 / C0
    repeat = 2 if quick else 5
    fig = {}
    t = best_seconds(lambda: cci.normalized_curvature(x, tau0, n, f_sc), repeat=repeat)
    fig["analysis.cci.curvature_ns_per_path"] = 1e9 * t / m
    xs = x[:200]
    ts = np.full(xs.size, tau0)
    t_sum = best_seconds(lambda: cci._curvature_sum(xs, ts, n, w), repeat=repeat)
    fig["analysis.cci.sum_ns_per_path"] = 1e9 * t_sum / xs.size
    fig["analysis.cci.speedup_vs_sum"] = (
        fig["analysis.cci.sum_ns_per_path"] / fig["analysis.cci.curvature_ns_per_path"]
    )
    links = 5000 if quick else 20000
    d = np.full(links, 30.0)
    t_mc = best_seconds(
        lambda: cci.cci_monte_carlo("winner2_c2", 30.0, links, np.random.default_rng(1), system),
        repeat=repeat,
    )
    t_draw = best_seconds(
        lambda: draw_links("winner2_c2", d, np.random.default_rng(1), system=system),
        repeat=repeat,
    )
    fig["analysis.cci.mc_us_per_link"] = 1e6 * t_mc / links
    fig["analysis.cci.draw_us_per_link"] = 1e6 * t_draw / links
    fig["analysis.cci.mc_over_draw"] = t_mc / t_draw
    fig["analysis.cci.curves_s"] = best_seconds(
        lambda: cci.cci_curves("winner2_c2", system), repeat=1 if quick else 3
    )
    fig["analysis.belief_shift.figure3_s"] = best_seconds(
        lambda: figure3(1.0, n, 20.0, 81 if quick else 401), repeat=1
    )
    return fig


def summarize(fig: dict[str, float]) -> str:
    """Per-path and per-link costs with their references."""
    rows = [
        (
            "curvature per path (eq. (40), N = 2569)",
            f"{fig['analysis.cci.curvature_ns_per_path']:.1f} ns",
            f"{fig['analysis.cci.sum_ns_per_path'] / 1e3:.1f} µs by the sum",
            f"{fig['analysis.cci.speedup_vs_sum']:.0f}× faster",
        ),
        (
            "Monte Carlo CCI per link (C2, 30 m)",
            f"{fig['analysis.cci.mc_us_per_link']:.2f} µs",
            f"{fig['analysis.cci.draw_us_per_link']:.2f} µs draw_links alone",
            f"{fig['analysis.cci.mc_over_draw']:.2f}× the floor",
        ),
        ("closed-form curves, 400 d0", f"{fig['analysis.cci.curves_s'] * 1e3:.1f} ms", "", ""),
        ("DiPNet Fig. 3", f"{fig['analysis.belief_shift.figure3_s']:.2f} s", "", ""),
    ]
    return format_table(rows, ["work", "cost", "reference", "ratio"])


if __name__ == "__main__":  # pragma: no cover
    print(summarize(report()))

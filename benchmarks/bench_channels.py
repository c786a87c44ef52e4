"""Channel-sampler benchmarks: link draws per second per scenario.

Work unit: one link (condition, path loss, shadowing, large-scale parameters, clusters,
sub-clusters, NLOS bias, phases) with distances between points uniform in a 100 m × 100 m
square (DiPNet §V-A), drawn in one batch of 10⁵ links. Figures (names are the interface):

``channels.<scenario>.link_draws_per_s``   links drawn per second, best of several batches
                                            (scenario = winner2_c2, winner2_d1, winner2_b1,
                                            winner2_a1, exponential, awgn)
"""

from __future__ import annotations

import numpy as np

from phyloc.channels import draw_links
from phyloc.channels.stats import square_pair_distances

try:
    from phyloc.benchmarks._timing import best_seconds
except ImportError:  # run from the source tree by asv
    from benchmarks._timing import best_seconds

SCENARIOS = ["winner2_c2", "winner2_d1", "winner2_b1", "winner2_a1", "exponential", "awgn"]
N_LINKS = 100_000
N_LINKS_QUICK = 10_000
SQUARE_M = 100.0


class LinkDraws:
    """asv: draw 10⁵ links of one scenario."""

    params = [SCENARIOS]
    param_names = ["scenario"]

    def setup(self, scenario):
        self.rng = np.random.default_rng(0)
        self.d = square_pair_distances(N_LINKS, SQUARE_M, self.rng)
        draw_links(scenario, self.d[:100], self.rng)  # load and validate the files

    def time_draw_links(self, scenario):
        draw_links(scenario, self.d, self.rng)


def report(quick: bool = False) -> dict[str, float]:
    """Link draws per second for each scenario (``quick``: 10⁴ links, fewer rounds)."""
    n = N_LINKS_QUICK if quick else N_LINKS
    out: dict[str, float] = {}
    for name in SCENARIOS:
        rng = np.random.default_rng(0)
        d = square_pair_distances(n, SQUARE_M, rng)
        sec = best_seconds(
            lambda name=name, d=d, rng=rng: draw_links(name, d, rng), repeat=2 if quick else 3
        )
        out[f"channels.{name}.link_draws_per_s"] = n / sec
    return out


def summarize(fig: dict) -> str:
    """The printed form of :func:`report`: rate, cost per link and cost in AWGN draws (the
    floor: one path, no random large-scale parameters)."""
    from phyloc.reporting import format_table

    floor = fig["channels.awgn.link_draws_per_s"]
    rows = []
    for name in SCENARIOS:
        rate = fig[f"channels.{name}.link_draws_per_s"]
        rows.append((name, rate, 1e6 / rate, floor / rate))
    return format_table(rows, ["scenario", "link draws/s", "us/link", "x AWGN draw"])

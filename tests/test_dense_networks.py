"""Range-limited networks in the localization experiment: eq. (4) over the links, the sparse
start, the cost figures and their fit (DiPNet eq. (4); the dense-network recipe family).

References: the framework errors recomputed here from the stored estimates and the network's
own links; a closed-form power law for the fitted exponent."""

import math

import numpy as np
import pytest
import tiny
from tiny import tiny_recipe

from phyloc.config import load_recipe
from phyloc.datasets.simulate import simulate_realization
from phyloc.evaluation import localization_aggregation as lagg
from phyloc.evaluation import localization_experiment as lx
from phyloc.evaluation.front_end import scored_pairs
from phyloc.network import NetworkSpec, make_network
from phyloc.parallel import task_seeds


def _dense(agents, **loc):
    base = tiny.BASE["network"]
    tiny.BASE["network"] = {"n_agents": 8}  # the density sets the region
    try:
        text = tiny_recipe(
            "localization",
            "dense_tiny",
            seed=361,
            network={
                "n_agents": 8,
                "density_per_km2": 3000.0,
                "comm_range_m": 40.0,
                "on_isolated": "allow",
            },
            localization={"n_particles": 64, "n_iterations": 2, "init_solver": "sparse", **loc},
            experiment={
                "scenarios": {"c2": "winner2_c2"},
                "agents": agents,
                "realizations": 1,
                "methods": ["dipnet", "corr"],
                "inits": ["truth_free"],
                "cdf_agents": [agents[-1]],
            },
        )
    finally:
        tiny.BASE["network"] = base
    return text


def test_scored_pairs_are_the_links_of_a_range_limited_network_only():
    spec = NetworkSpec.from_dict({"n_agents": 12, "comm_range_m": 40.0, "on_isolated": "allow"})
    net = make_network(spec, np.random.default_rng(0))
    assert np.array_equal(scored_pairs(net, net.links), net.links)
    meshed = make_network(spec.replace(comm_range_m=None), np.random.default_rng(0))
    assert scored_pairs(meshed, meshed.links) is None


def test_dense_recipe_reports_cost_and_eq4_over_the_links(tmp_path):
    res = lx.LOCALIZATION.run(load_recipe(_dense([8, 16])), progress=False)
    f = res["figures"]
    for n in (8, 16):
        for stage in ("waveforms", "tables", "ranging_corr", "start_truth_free"):
            assert f[f"c2.agents_{n}.{stage}_s"] >= 0
        assert f[f"c2.agents_{n}.peak_rss_mb"] > 0
        assert 0.0 <= f[f"start.c2.agents_{n}.undetermined_agent_fraction"] <= 1.0
        for m in ("dipnet", "corr"):
            it = f[f"{m}.c2.agents_{n}.iteration_s"]
            assert 0 < it < f[f"{m}.c2.agents_{n}.chain_s"]
    assert set(k for k in f if k.endswith("_exponent")) == {
        f"{m}.c2.iteration_s{x}_exponent" for m in ("dipnet", "corr") for x in ("", "_link")
    }
    lx.LOCALIZATION.plot(res, tmp_path / "dense_tiny.png")
    assert (tmp_path / "dense_tiny_cost.png").stat().st_size > 0


def test_range_limited_errors_are_counted_per_link():
    """The pooled error count of a range-limited run equals its number of agent-receiver links
    (eq. (4) over the edges), not |M|(|V|-1)."""
    recipe = load_recipe(_dense([10]))
    plan = lx.LOCALIZATION.prepare(recipe)
    ((_, payload),) = lx.LOCALIZATION.tasks(plan)
    seed = task_seeds(recipe.seed, 1)[0]
    out = lx._task(payload, seed)
    real = simulate_realization(
        plan.system, plan.nets[10], payload[2], np.random.default_rng(task_seeds(recipe.seed, 1)[0])
    )
    n_links = real.links[0].shape[0]
    assert out["dipnet|truth_free|err"].size == n_links < 10 * 9
    assert out["start|truth_free|err"].size == n_links


def test_cost_exponent_recovers_a_power_law():
    sizes = [30, 100, 300, 1000]
    assert lagg.cost_exponent(sizes, [2e-3 * n**1.07 for n in sizes]) == pytest.approx(1.07)
    assert lagg.cost_exponent([30], [1.0]) is None
    assert lagg.cost_exponent(sizes, [None, 0.0, 1.0, math.nan]) is None

"""Localization on stored waveforms equals localization on the same waveforms in memory."""

import numpy as np
import pytest

from phyloc.config import load_recipe
from phyloc.datasets import generate
from phyloc.evaluation import localization_experiment as lx

COMMON = """
seed = 77
[system]
n_subcarriers = 257
subcarrier_spacing_hz = 146.5e3
[network]
n_agents = 4
region_m = [60.0, 60.0]
[channel]
scenario = "winner2_c2"
[ranging]
window_m = [0.0, 200.0]
[localization]
n_particles = 300
n_iterations = 3
resample_move = false
"""

DATASET = (
    'kind = "dataset"\nname = "tiny"\n'
    + COMMON.replace("[channel]", "[dataset]\nrealizations = 2\nshard_size = 1\n[channel]")
    + '[experiment]\nmethods = ["dipnet_published", "corr"]\ninits = ["truth_free"]\n'
)

IN_MEMORY = (
    'kind = "localization"\nname = "tiny"\n'
    + COMMON
    + """
[experiment]
scenarios = { c2 = "winner2_c2" }
agents = [4]
realizations = 2
methods = ["dipnet_published", "corr"]
inits = ["truth_free"]
cdf_agents = [4]
"""
)


@pytest.fixture(autouse=True)
def _quiet(monkeypatch):
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")


def test_dataset_and_in_memory_results_agree(tmp_path):
    h5 = tmp_path / "tiny.h5"
    generate(load_recipe(DATASET), h5, progress=False)
    stored = lx.run_dataset(h5)["figures"]
    memory = lx.run(load_recipe(IN_MEMORY))["figures"]
    for m in ("dipnet_published", "corr"):
        key = f"{m}.c2.agents_4.framework_rmse_m"
        # complex64 storage of the samples is the only difference
        assert stored[key] == pytest.approx(memory[key], rel=1e-3, abs=1e-3)
    assert stored["c2.los_fraction"] == memory["c2.los_fraction"]
    assert np.isfinite(stored["dipnet_published.c2.agents_4.framework_rmse_m"])

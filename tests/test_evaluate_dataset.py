"""Localization on stored waveforms equals localization on the same waveforms in memory."""

import numpy as np
import pytest
from tiny import tiny_recipe

from phyloc.config import load_recipe
from phyloc.datasets import generate
from phyloc.evaluation import localization_experiment as lx
from phyloc.reporting import is_measurement

COMMON = tiny_recipe(
    seed=77, localization={"n_particles": 300, "n_iterations": 3, "resample_move": False}
)

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
    stored = lx.DATASET_LOCALIZATION.run_dataset(h5)["figures"]
    memory = lx.LOCALIZATION.run(load_recipe(IN_MEMORY))["figures"]
    for m in ("dipnet_published", "corr"):
        key = f"{m}.c2.agents_4.framework_rmse_m"
        # complex64 storage of the samples is the only difference
        assert stored[key] == pytest.approx(memory[key], rel=1e-3, abs=1e-3)
    assert stored["c2.los_fraction"] == memory["c2.los_fraction"]
    assert np.isfinite(stored["dipnet_published.c2.agents_4.framework_rmse_m"])


MOTION = """
[network.motion]
model = "constant_velocity"
n_snapshots = 4
dt_s = 0.5
accel_std = 0.3
initial_velocity = "toward_center"
initial_speed_m_s = 2.0
"""
TRACK_METHODS = 'methods = ["dipnet_published", "corr", "dpe_sampled"]'
SAMPLED = "[localization.dpe_sampled]\nn_particles = 60\n"


def _tracking(text):
    text = text.replace("[channel]", MOTION + "[channel]").replace(
        "[experiment]", SAMPLED + "[experiment]"
    )
    return text.replace('methods = ["dipnet_published", "corr"]', TRACK_METHODS)


def _non_timing(figures):
    return {k: v for k, v in figures.items() if not is_measurement(k)}


def test_tracking_runs_every_snapshot_and_equals_in_memory_on_any_worker_count(tmp_path):
    """A dataset with motion is localized over all its snapshots, from the same streams as in
    memory, with the same numbers on 1 and 2 workers."""
    h5 = tmp_path / "track.h5"
    generate(load_recipe(_tracking(DATASET)), h5, progress=False)
    one = lx.DATASET_LOCALIZATION.run_dataset(h5, workers=1, progress=False)
    two = lx.DATASET_LOCALIZATION.run_dataset(h5, workers=2, progress=False)
    memory = lx.LOCALIZATION.run(load_recipe(_tracking(IN_MEMORY)), progress=False)
    assert _non_timing(one["figures"]) == _non_timing(two["figures"])
    for m in ("dipnet_published", "corr", "dpe_sampled"):
        base = f"{m}.c2.agents_4"
        per_t = np.asarray(one["series"][base + ".rmse_by_snapshot"])
        assert per_t.shape == (4,) and np.all(np.isfinite(per_t))
        np.testing.assert_array_equal(per_t, two["series"][base + ".rmse_by_snapshot"])
        # complex64 storage of the samples is the only difference from memory
        np.testing.assert_allclose(
            per_t, memory["series"][base + ".rmse_by_snapshot"], rtol=1e-3, atol=1e-3
        )
        # the pooled RMSE is the RMSE over snapshots of equal size
        assert one["figures"][base + ".framework_rmse_m"] == pytest.approx(
            np.sqrt(np.mean(per_t**2)), rel=1e-9
        )


def test_evaluate_refuses_a_corrupt_shard_and_names_it(tmp_path, capsys):
    """A flipped bit in a shard, or a truncated shard: ``phyloc evaluate`` stops before reading
    (exit 2, one line naming the shard and the repair); ``--no-verify`` reads anyway. A sound
    dataset records the cost of the check as ``run.verify_s``."""
    import json

    from phyloc.cli import main

    h5 = tmp_path / "tiny.h5"
    generate(load_recipe(DATASET), h5, progress=False)
    out = tmp_path / "ok"
    assert main(["evaluate", str(h5), "--out", str(out), "--fast", "--no-progress"]) == 0
    figures = json.loads((out / "results.json").read_text())["figures"]
    assert 0 < figures["run.verify_s"] < figures["run.wall_s"]
    assert "checked 2 shard checksums" in capsys.readouterr().out
    shard = sorted((tmp_path / "tiny.h5.shards").glob("shard-*.h5"))[1]
    data = bytearray(shard.read_bytes())
    data[len(data) // 3] ^= 0x10
    shard.write_bytes(bytes(data))
    bad = tmp_path / "bad"
    assert main(["evaluate", str(h5), "--out", str(bad), "--fast", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "shard 1" in err and shard.name in err and "--resume" in err
    assert not bad.exists()  # nothing written
    shard.write_bytes(bytes(data[: len(data) // 2]))  # truncated
    assert main(["evaluate", str(h5), "--out", str(bad), "--fast", "--no-progress"]) == 2
    assert "shard 1" in capsys.readouterr().err
    # --fast reads realization 0 only (shard 0, sound): the escape hatch reads it
    assert (
        main(["evaluate", str(h5), "--out", str(bad), "--fast", "--no-progress", "--no-verify"])
        == 0
    )


TWO_SCENARIOS = (
    'kind = "localization"\nname = "tiny2"\n'
    + COMMON
    + "model_error_m = 0.3\n[localization.corr]\nmodel_error_m = 0.0\n"
    + """
[experiment]
scenarios = { c2 = "winner2_c2", d1 = "winner2_d1" }
agents = [4]
realizations = 1
methods = ["dipnet", "corr"]
inits = ["truth_free"]
cdf_agents = [4]
"""
)


def test_scenario_localization_replaces_keys_for_its_scenario_only():
    """``experiment.scenario_localization`` gives one scenario its own [localization] keys; a
    method's own subtable still wins, and the other scenario is untouched."""
    over = TWO_SCENARIOS + "scenario_localization = { d1 = { model_error_m = 0.55 } }\n"
    recipe = load_recipe(over)
    plan = lx.LOCALIZATION.prepare(recipe)
    specs, lspec = plan.lspecs, plan.lspec
    assert specs == lx.scenario_localization_specs(recipe, plan.exp, lspec)
    assert specs["c2"] is lspec
    assert specs["c2"].options_for("dipnet").model_error_m == 0.3
    assert specs["d1"].options_for("dipnet").model_error_m == 0.55
    assert specs["d1"].options_for("corr").model_error_m == 0.0  # its own subtable wins
    base = lx.LOCALIZATION.run(load_recipe(TWO_SCENARIOS))["figures"]
    same = lx.LOCALIZATION.run(
        load_recipe(TWO_SCENARIOS + "scenario_localization = { d1 = { model_error_m = 0.3 } }\n")
    )["figures"]
    changed = lx.LOCALIZATION.run(recipe)["figures"]
    np.testing.assert_equal(_non_timing(same), _non_timing(base))  # restating the base value
    for key in ("dipnet.c2.agents_4.framework_rmse_m", "corr.d1.agents_4.framework_rmse_m"):
        assert changed[key] == base[key]
    assert changed["dipnet.d1.agents_4.nees"] != base["dipnet.d1.agents_4.nees"]


@pytest.mark.parametrize(
    ("line", "match"),
    [
        ("scenario_localization = { x1 = { model_error_m = 0.5 } }", r"scenario_localization = x1"),
        ("scenario_localization = { d1 = 0.5 }", r"scenario_localization\.d1 = 0\.5"),
        (
            "scenario_localization = { d1 = { model_error_m = -1.0 } }",
            r"scenario_localization\.d1\.model_error_m",
        ),
    ],
)
def test_scenario_localization_errors_name_the_key(line, match):
    from phyloc.errors import ValidationError

    with pytest.raises(ValidationError, match=match):
        lx.LOCALIZATION.run(load_recipe(TWO_SCENARIOS + line + "\n"))

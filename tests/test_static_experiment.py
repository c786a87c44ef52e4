"""The ``kind = "static"`` experiment (POA-NBP §V): figure names, containment, convergence
rule, ellipse proposal, seeds and workers, recipe errors, the command line."""

import math
from pathlib import Path

import numpy as np
import pytest

from phyloc.cli import main
from phyloc.config import load_recipe
from phyloc.errors import ValidationError
from phyloc.evaluation import static_experiment as se
from phyloc.evaluation import static_figures
from phyloc.evaluation.experiment import experiment_from_dict
from phyloc.localization.static.ellipses import EllipseRegion

DATASETS = Path(__file__).resolve().parents[1] / "datasets"

TINY = """
kind = "static"
name = "tiny_static"
seed = 5

[experiment]
topologies = 2
n_agents = 30
side_m = 60.0
n_edges = [4, 16]
poa_iterations = 3
methods = ["nbp_aux", "poa_nbp", "nbp_ellipse", "nbp_min_entropy", "pbp", "wls"]
n_iterations = 3
n_samples = 40
sample_sweep = [20, 40]
sample_methods = ["poa_nbp"]
outage_thresholds_m = [1.0]

[localization]
bandwidth = "silverman"
"""


@pytest.fixture(scope="module")
def tiny():
    return se.STATIC.run(load_recipe(TINY), progress=False)


def test_every_documented_figure_is_there(tiny):
    f, ser, meta = tiny["figures"], tiny["series"], tiny["meta"]
    expected = [
        "poa.containment_fraction",
        "poa.time_per_node_s",
        "poa.dropped_fraction",
        "poa.rejection_acceptance_rate",
        "poa_nbp_vs_nbp_min_entropy.time_to_convergence_ratio",
        "poa_nbp_vs_nbp_ellipse.time_to_convergence_ratio",
    ]
    for ne in (4, 16):
        expected.append(f"poa.ne{ne}.containment_fraction")
        expected += [f"poa.ne{ne}.area_it{it}_m2" for it in (1, 2, 3)]
        assert ser[f"poa.ne{ne}.area_m2"].shape == (3,)
    expected += [f"ellipse.area_it{it}_m2" for it in (1, 2, 3)]
    for m in meta["methods"]:
        expected += [
            f"{m}.{q}"
            for q in (
                "mean_error_m",
                "rmse_m",
                "convergence_iteration",
                "settling_iteration",
                "time_per_node_iteration_s",
                "time_to_convergence_s",
                "outage_1m",
            )
        ]
        assert ser[f"{m}.mean_error_m"].shape == (3,)
        out = ser[f"{m}.outage"]
        assert np.all(np.diff(out) <= 0) and 0 <= out[-1] <= out[0] <= 1
    for ns in (20, 40):
        expected += [f"poa_nbp.ns{ns}.{q}" for q in ("mean_error_m", "outage_1m")]
    missing = [n for n in expected if n not in f]
    assert not missing, missing
    assert all(math.isfinite(f[n]) for n in expected)
    for m in meta["methods"]:
        assert 1 <= f[f"{m}.settling_iteration"] <= 3 and f[f"{m}.convergence_iteration"] <= 3
        # RMSE >= mean error (Cauchy–Schwarz) and the outage is a fraction
        assert f[f"{m}.rmse_m"] >= f[f"{m}.mean_error_m"] - 1e-12
        assert 0.0 <= f[f"{m}.outage_1m"] <= 1.0


def test_polygons_contain_every_agent_and_shrink(tiny):
    """Non-negative (exponential) ranging errors: every polygon contains its agent (POA-NBP
    Theorem 1), and more iterations or edges never enlarge the mean area."""
    f = tiny["figures"]
    assert f["poa.containment_fraction"] == 1.0
    assert f["poa.ne4.containment_fraction"] == 1.0
    assert f["poa.ne16.containment_fraction"] == 1.0
    assert f["poa.dropped_fraction"] == 0.0
    for ne in (4, 16):
        a = [f[f"poa.ne{ne}.area_it{it}_m2"] for it in (1, 2, 3)]
        assert a[0] >= a[1] >= a[2] > 0
    assert 0.0 < f["poa.rejection_acceptance_rate"] <= 1.0
    # a 16-gon circumscribes each anchor disk more tightly than a square
    assert f["poa.ne16.area_it1_m2"] < f["poa.ne4.area_it1_m2"]


def test_overhead_figures_follow_the_methods_complexity(tiny):
    """Floats per link-iteration and operations per node (POA-NBP §II-B, §V-C2): NBP broadcasts
    N_S samples × 2 coordinates, PBP mean + covariance (5), joint WLS nothing (no figure); NBP's
    kernel evaluations grow as N_S² (the POA share is the same at both N_S); POA sends 2 floats
    per vertex and its operations grow with N_E."""
    f = tiny["figures"]
    assert f["poa_nbp.ns20.floats_per_link_iteration"] == 40.0
    assert f["poa_nbp.ns40.floats_per_link_iteration"] == 80.0
    for m in ("nbp_aux", "nbp_ellipse", "nbp_min_entropy"):
        assert f[f"{m}.ns40.floats_per_link_iteration"] == 80.0
        assert f[f"{m}.ns40.operations_per_node"] > 0
    assert f["pbp.ns40.floats_per_link_iteration"] == 5.0
    assert "wls.ns40.floats_per_link_iteration" not in f
    assert "wls.ns40.operations_per_node" not in f
    ratio = f["poa_nbp.ns40.operations_per_node"] / f["poa_nbp.ns20.operations_per_node"]
    assert 3.0 < ratio < 4.5, ratio
    assert f["poa.ne16.floats_per_link_iteration"] > f["poa.ne4.floats_per_link_iteration"] >= 6
    assert f["poa.ne16.operations_per_node"] > f["poa.ne4.operations_per_node"] > 0
    assert f["poa_nbp.ns40.support_floats_per_link_iteration"] >= 6.0
    assert f["nbp_ellipse.ns40.support_floats_per_link_iteration"] == 5.0
    headers = se.summary_headers(tiny)
    rows = se.summary_rows(tiny)
    assert headers[-2:] == ["floats/link-it", "ops/node"]
    assert [r[0] for r in rows][:2] == ["NBP aux.", "POA-NBP"]  # the recipe's column order
    assert rows[1][-2] == 80.0 and math.isnan(rows[-1][-2])


def test_default_methods_follow_table_1():
    assert se.METHODS == (
        "nbp_min_entropy",
        "nbp_aux",
        "nbp_parsimonious",
        "nbp_ellipse",
        "pbp",
        "wls",
        "poa_nbp",
        "nbp_mixture",
    )
    recipe = load_recipe(DATASETS / "poa_nbp.toml")
    exp = experiment_from_dict(se.StaticExperimentSpec, recipe.section("experiment"))
    assert exp.methods == se.METHODS
    assert max(exp.sample_sweep) >= 1000 and {800, 1600} <= set(exp.sample_sweep)
    fast = experiment_from_dict(se.StaticExperimentSpec, recipe.section("experiment"), fast=True)
    assert max(fast.sample_sweep) <= 100


def test_convergence_and_settling_from_curve():
    curve = [10.0, 5.0, 2.0, 1.05, 1.0, 1.02]
    # paper's rule: the first small successive change (1.05 -> 1.0: 4.8 % <= 5 %) means
    # converged after iteration 4
    assert se.convergence_from_curve(curve, 0.05, 0.01) == 4
    assert se.convergence_from_curve(curve, 0.01, 0.001) == 6  # every change > 1 %
    assert se.convergence_from_curve(curve, 0.6, 0.0) == 1  # 10 -> 5 is within 60 %
    assert se.convergence_from_curve([3.0, 3.0], 0.05, 0.01) == 1
    # settling: stays within the band around the final value from then on
    assert se.settling_from_curve(curve, 0.05, 0.01) == 4  # |1.05 - 1.02| <= 0.051
    assert se.settling_from_curve(curve, 0.01, 0.001) == 6  # |1.0 - 1.02| > 0.0102
    assert se.settling_from_curve([3.0, 3.0], 0.05, 0.01) == 1
    # a late excursion resets settling but not the paper's rule
    late = [5.0, 1.0, 1.0, 3.0, 1.0]
    assert se.settling_from_curve(late, 0.05, 0.01) == 5
    assert se.convergence_from_curve(late, 0.05, 0.01) == 2


def test_ellipse_region_is_uniform():
    """Uniform samples in an ellipse {x: xᵀΣ⁻¹x <= 1}: all inside, mean = centre, covariance
    = Σ/4 (closed form), area = π sqrt(det Σ)."""
    shape = np.array([[9.0, 2.0], [2.0, 4.0]])
    e = EllipseRegion([1.0, -2.0], shape)
    assert e.area == pytest.approx(math.pi * math.sqrt(np.linalg.det(shape)))
    x = e.sample_uniform(200_000, np.random.default_rng(0))
    assert e.contains(x).all()
    np.testing.assert_allclose(x.mean(axis=0), [1.0, -2.0], atol=0.02)
    np.testing.assert_allclose(np.cov(x.T), shape / 4, atol=0.03)
    assert not e.contains(np.array([[1.0 + 3.1, -2.0]]))[0]
    flat = EllipseRegion([0.0, 0.0], np.zeros((2, 2)))
    assert flat.area == 0.0 and not flat.contains(np.zeros((1, 2)))[0]


def test_same_results_with_one_and_two_workers(tiny):
    two = se.STATIC.run(load_recipe(TINY), workers=2, progress=False)
    names = [n for n in tiny["figures"] if not static_figures.is_timing(n)]
    assert names == [n for n in two["figures"] if not static_figures.is_timing(n)]
    assert "poa_nbp.mean_error_m" in names and "poa.time_per_node_s" not in names
    for n in names:
        assert tiny["figures"][n] == two["figures"][n], n
    for n, x in tiny["series"].items():
        np.testing.assert_array_equal(x, two["series"][n], err_msg=n)


def test_sample_sweep_topologies_limits_the_sweep_only(tiny):
    """``sample_sweep_topologies = 1`` in the 2-topology recipe: the sweep's figures are those
    of a 1-topology run; every other figure is that of the unlimited recipe."""
    limited = se.STATIC.run(
        load_recipe(TINY.replace("topologies = 2", "topologies = 2\nsample_sweep_topologies = 1")),
        progress=False,
    )
    one = se.STATIC.run(
        load_recipe(TINY.replace("topologies = 2", "topologies = 1")), progress=False
    )
    f = limited["figures"]
    swept = [n for n in f if n.startswith(("poa_nbp.ns20.", "poa_nbp.ns40."))]
    assert "poa_nbp.ns20.mean_error_m" in swept
    assert f["poa_nbp.ns20.topologies"] == 1.0 and tiny["figures"]["poa_nbp.ns20.topologies"] == 2
    for n in f:
        if static_figures.is_timing(n) or n.endswith("topologies"):
            continue
        # N_S = 40 is also the comparison's: its overhead figures come from the comparison
        from_sweep = n in swept and not (n.startswith("poa_nbp.ns40.") and n.endswith(_OVERHEAD))
        assert f[n] == (one if from_sweep else tiny)["figures"][n], n
    assert limited["meta"]["sample_sweep_topologies"] == 1
    assert tiny["meta"]["sample_sweep_topologies"] == 2


_OVERHEAD = (
    "floats_per_link_iteration",
    "operations_per_node",
    "support_floats_per_link_iteration",
)


@pytest.mark.parametrize(
    ("edit", "key"),
    [
        (("topologies = 2", "topologis = 2"), "experiment.topologis"),
        (
            ("topologies = 2", "topologies = 2\nsample_sweep_topologies = 0"),
            "experiment.sample_sweep_topologies",
        ),
        (('"pbp", "wls"]', '"pbp", "lws"]'), "experiment.methods"),
        (('bandwidth = "silverman"', 'proposal = "mixture"'), "localization.proposal"),
        (('bandwidth = "silverman"', 'bandwith = "silverman"'), "localization.bandwith"),
        (("[localization]", "[localization.nbp]"), "localization.nbp"),  # the earlier form
        (
            ('bandwidth = "silverman"', 'bandwidth = "silverman"\n[localization.pbp]\nn_inner = 0'),
            "localization.pbp.n_inner",
        ),
        (("n_samples = 40", "n_samples = 1"), "experiment.n_samples"),
        (('sample_methods = ["poa_nbp"]', 'sample_methods = ["wls"]'), "experiment.sample_methods"),
    ],
)
def test_recipe_errors_name_the_key(edit, key):
    recipe = load_recipe(TINY.replace(*edit))
    with pytest.raises(ValidationError) as exc:
        se.STATIC.run(recipe, progress=False)
    assert exc.value.field == key


def test_shipped_recipe_validates():
    recipe = load_recipe(DATASETS / "poa_nbp.toml")
    exp = experiment_from_dict(se.StaticExperimentSpec, recipe.section("experiment"))
    assert exp.topologies == 200 and exp.n_agents == 100 and exp.poa_n_edges == 16
    fast = experiment_from_dict(se.StaticExperimentSpec, recipe.section("experiment"), fast=True)
    assert fast.topologies < exp.topologies
    se.method_options(recipe.section("localization"), exp)


def test_cli_evaluate_static(tmp_path, capsys):
    path = tmp_path / "tiny.toml"
    path.write_text(
        TINY.replace("topologies = 2", "topologies = 1").replace(
            '"poa_nbp", "nbp_ellipse", "nbp_min_entropy", "pbp", "wls"', '"poa_nbp", "wls"'
        )
    )
    out = tmp_path / "out"
    assert main(["evaluate", str(path), "--out", str(out), "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "POA-NBP" in text and "WLS" in text and "containment 1.0000" in text
    assert (out / "results.json").exists() and (out / "tiny_static.png").stat().st_size > 10_000
    # nothing already written is overwritten
    assert main(["evaluate", str(path), "--out", str(out), "--no-progress"]) != 0

"""The ``kind = "static"`` experiment (POA-NBP §V): figure names, containment, convergence
rule, ellipse proposal, seeds and workers, recipe errors, the command line."""

import math
from pathlib import Path

import numpy as np
import pytest

from phyloc.cli import main
from phyloc.config import load_recipe
from phyloc.errors import ValidationError
from phyloc.evaluation import static_aggregation as sa
from phyloc.evaluation import static_experiment as se
from phyloc.evaluation import static_figures
from phyloc.evaluation.experiment import experiment_from_dict
from phyloc.evaluation.statistics import Pooled
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
    # Table I in phyloc's form, then each in the paper's form (a variant of the same method)
    assert exp.methods == se.METHODS + tuple(f"{m}_paper" for m in se.METHODS)
    plan = se.method_plan(recipe.section("localization"), exp)
    for m in se.METHODS:
        name, opts = plan[f"{m}_paper"]
        assert name == ("nbp_bounding" if m == "nbp_ellipse" else m)
        if hasattr(opts, "jacobian_weights"):  # POA-NBP eq. (5): equal message weights
            assert opts.jacobian_weights is False and plan[m][1].jacobian_weights is True
        else:  # PBP, WLS: the truth-free heuristic start, not the centralized MDS solution
            assert opts.start == "heuristic" and plan[m][1].start == "mds"
    assert max(exp.sample_sweep) >= 1000 and {800, 1600} <= set(exp.sample_sweep)
    fast = experiment_from_dict(se.StaticExperimentSpec, recipe.section("experiment"), fast=True)
    assert max(fast.sample_sweep) <= 100


def test_convergence_and_settling_from_curve():
    curve = [10.0, 5.0, 2.0, 1.05, 1.0, 1.02]
    # paper's rule: the first small successive change (1.05 -> 1.0: 4.8 % <= 5 %) means
    # converged after iteration 4
    assert sa.convergence_from_curve(curve, 0.05, 0.01) == 4
    assert sa.convergence_from_curve(curve, 0.01, 0.001) == 6  # every change > 1 %
    assert sa.convergence_from_curve(curve, 0.6, 0.0) == 1  # 10 -> 5 is within 60 %
    assert sa.convergence_from_curve([3.0, 3.0], 0.05, 0.01) == 1
    # settling: stays within the band around the final value from then on
    assert sa.settling_from_curve(curve, 0.05, 0.01) == 4  # |1.05 - 1.02| <= 0.051
    assert sa.settling_from_curve(curve, 0.01, 0.001) == 6  # |1.0 - 1.02| > 0.0102
    assert sa.settling_from_curve([3.0, 3.0], 0.05, 0.01) == 1
    # a late excursion resets settling but not the paper's rule
    late = [5.0, 1.0, 1.0, 3.0, 1.0]
    assert sa.settling_from_curve(late, 0.05, 0.01) == 5
    assert sa.convergence_from_curve(late, 0.05, 0.01) == 2


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
        assert _same(tiny["figures"][n], two["figures"][n]), n
    for n, x in tiny["series"].items():
        if static_figures.is_timing(n):  # the per-topology wall times (``<name>.units``)
            continue
        y = two["series"][n]
        if n.endswith(".units"):  # {"kind", "num", "den"}: the per-topology values
            assert x["kind"] == y["kind"], n
            x, y = np.array([x["num"], x["den"]]), np.array([y["num"], y["den"]])
        np.testing.assert_array_equal(x, y, err_msg=n)


def _same(x, y) -> bool:
    """Equal, or both NaN (an interval that a single topology, or a ratio whose resamples
    divide by 0, leaves undefined)."""
    return x == y or (math.isnan(x) and math.isnan(y))


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
    swept = [n for n in f if n.startswith(("poa_nbp.ns20.", "poa_nbp.ns40.", "pbp.sweep."))]
    swept += [n for n in f if n.startswith("poa_nbp_vs_pbp.ns")]  # the sweep against PBP
    assert "poa_nbp.ns20.mean_error_m" in swept
    assert f["poa_nbp.ns20.topologies"] == 1.0 and tiny["figures"]["poa_nbp.ns20.topologies"] == 2
    for n in f:
        if static_figures.is_timing(n) or n.endswith("topologies"):
            continue
        # N_S = 40 is also the comparison's: its overhead figures come from the comparison
        base = n.removesuffix(".ci_low").removesuffix(".ci_high")  # the figure of an interval
        from_sweep = n in swept and not (n.startswith("poa_nbp.ns40.") and base.endswith(_OVERHEAD))
        assert _same(f[n], (one if from_sweep else tiny)["figures"][n]), n
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


# -- 95 % intervals over topologies -------------------------------------------------------------
def _pooled(res):
    """Names of the figures the run resolved from per-topology values (their ``.units``)."""
    return [k.removesuffix(".units") for k in res["series"] if k.endswith(".units")]


def _from_units(u) -> float:
    """Brute force: the pooled figure from its stored per-unit numerators and denominators."""
    num, den = np.sum(np.asarray(u["num"], float)), np.sum(np.asarray(u["den"], float))
    return math.sqrt(num / den) if u["kind"] == "rmse" else num / den


def test_pooled_figures_carry_intervals_over_the_topologies(tiny):
    """Every figure pooled over the 2 topologies has a finite interval around it, one value
    per topology, and is the pooled value of those; the table shows the intervals; a paired
    ratio is the ratio of its two figures, present unless the second is 0."""
    f, ser, meta = tiny["figures"], tiny["series"], tiny["meta"]
    names = _pooled(tiny)
    expected = ["poa.containment_fraction", "poa.dropped_fraction", "ellipse.area_it3_m2"]
    expected += [f"{m}.{q}" for m in meta["methods"] for q in ("mean_error_m", "rmse_m")]
    expected += [f"{m}.outage_1m" for m in meta["methods"]]
    expected += ["poa.ne4.area_it1_m2", "poa_nbp.ns20.mean_error_m", "poa_nbp.ns40.outage_1m"]
    assert not set(expected) - set(names), set(expected) - set(names)
    for n in names:
        lo, x, hi = f[n + ".ci_low"], f[n], f[n + ".ci_high"]
        assert math.isfinite(lo) and math.isfinite(hi), n
        slack = 1e-12 * abs(x)  # a point value kept as computed may differ in the last bit
        assert lo - slack <= x <= hi + slack, (n, lo, x, hi)
        u = ser[n + ".units"]
        assert len(u["num"]) == len(u["den"]) == meta["topologies"] == 2, n
        assert x == pytest.approx(_from_units(u), rel=1e-12, abs=1e-300), n
    for m in meta["methods"]:
        u = ser[f"{m}.outage_1m.units"]
        assert list(u["den"]) == [30, 30] and all(float(k).is_integer() for k in u["num"])
        assert f"{m}.curve_convergence_iteration.ci_low" not in f  # the pooled curve: plain
        assert f"{m}.settling_iteration.ci_low" not in f
    assert "poa.time_per_node_s.ci_low" in f  # wall times: per topology too
    assert "poa_nbp_vs_wls.time_to_convergence_ratio.ci_low" not in f
    ratios = 0
    for m in meta["methods"]:
        for q in ("mean_error_m", "rmse_m", "outage_1m"):
            key = f"poa_nbp_vs_{m}.{q}.ratio"
            if m == "poa_nbp" or f[f"{m}.{q}"] == 0:
                assert key not in f
                continue
            assert f[key] == f[f"poa_nbp.{q}"] / f[f"{m}.{q}"], key
            ratios += 1
    assert ratios >= 14
    row = se.summary_rows(tiny)[1]
    assert row[0] == "POA-NBP" and f"{f['poa_nbp.mean_error_m']:.3g} [" in row[1]
    assert any("over the other method's" in line for line in se.summary_lines(tiny))


def _fake_static(exp, n_topo, seed=3):
    """Task results of ``n_topo`` topologies (random numbers of the task's shapes)."""
    rng = np.random.default_rng(seed)
    n, out = exp.n_agents, []
    for t in range(n_topo):
        r = {}
        for ne in exp.n_edges:
            area = rng.gamma(2.0, 50.0, (exp.poa_iterations, n))
            area[:, rng.random(n) < 0.05] = np.inf  # unbounded agents: left out of the mean
            r[f"poa|{ne}|area"] = area
            r[f"poa|{ne}|contained"] = rng.random(n) < 0.97
            r[f"poa|{ne}|ops"] = float(rng.integers(100, 1000))
            r[f"poa|{ne}|floats"] = float(rng.uniform(6.0, 20.0))
        r["ellipse|area"] = rng.gamma(2.0, 60.0, (exp.poa_iterations, n))
        r["ellipse_paper|area"] = 1.3 * r["ellipse|area"]
        r["poa|contained"] = rng.random(n) < 0.97
        r["poa|acceptance"] = rng.uniform(0.3, 0.9, n)
        r["poa|time_per_node_s"] = 1e-4
        r["poa|dropped"] = (int(rng.integers(0, 5)), 300)
        over = {"floats_per_link_iteration": 80.0, "support_floats_per_link_iteration": np.nan}
        for m in exp.methods:
            r[f"{m}|err"] = rng.exponential(1.0, (exp.n_iterations, n))
            r[f"{m}|time"], r[f"{m}|t_support"] = 1e-3, 0.0
            r[f"{m}|overhead"] = {**over, "operations_per_node": float(rng.integers(1, 9) * 1e3)}
        for m in exp.sample_methods if t < exp.sweep_topologies else ():
            for ns in exp.sample_sweep:
                r[f"{m}|ns{ns}|err"] = rng.exponential(1.0, n)
                r[f"{m}|ns{ns}|time"] = 1e-3
                r[f"{m}|ns{ns}|overhead"] = r[f"{m}|overhead"]
        out.append(r)
    return out


def test_pooled_point_values_are_those_of_all_values_at_once():
    """Many agents in 3 topologies (the pooled sums then differ from one sum over all values
    in the last bits): every point value is still, bit for bit, the figure computed from all
    the values at once, and its units are the topologies' own sums and counts."""
    exp = se.StaticExperimentSpec(
        topologies=3,
        n_agents=700,
        n_edges=(4,),
        poa_iterations=2,
        methods=("poa_nbp", "nbp_min_entropy", "wls"),
        n_iterations=3,
        n_samples=40,
        sample_sweep=(20, 40),
        sample_methods=("poa_nbp", "nbp_min_entropy"),
        sample_sweep_topologies=2,
        outage_thresholds_m=(1.0, 2.0),
    )
    res = _fake_static(exp, 3)
    f, _ = sa.aggregate(res, exp)
    for m in exp.methods:
        final = np.concatenate([r[f"{m}|err"][-1] for r in res])
        assert f[f"{m}.mean_error_m"].value == final.mean()
        assert f[f"{m}.rmse_m"].value == math.sqrt(np.mean(final**2))
        assert f[f"{m}.outage_2m"].value == np.mean(final > 2.0)
        p = f[f"{m}.mean_error_m"]
        np.testing.assert_array_equal(p.num, [np.sum(r[f"{m}|err"][-1]) for r in res])
        np.testing.assert_array_equal(p.den, [700, 700, 700])
        assert p.value == pytest.approx(p.num.sum() / p.den.sum(), rel=1e-13)
        for it in range(exp.n_iterations):  # Fig. 10 point by point, with its own units
            e_it = np.concatenate([r[f"{m}|err"][it] for r in res])
            q = f[f"{m}.mean_error_it{it + 1}_m"]
            assert q.value == e_it.mean()
            np.testing.assert_array_equal(q.num, [np.sum(r[f"{m}|err"][it]) for r in res])
        assert f[f"{m}.mean_error_it3_m"].value == p.value  # the last iteration
    area = np.concatenate([r["poa|4|area"][1] for r in res])
    assert f["poa.ne4.area_it2_m2"].value == area[np.isfinite(area)].mean()
    assert f["poa.ne4.area_it2_m2"].den.sum() == np.isfinite(area).sum()
    cont = np.concatenate([r["poa|contained"] for r in res])
    assert f["poa.containment_fraction"].value == cont.mean()
    assert f["poa.dropped_fraction"].value == sum(r["poa|dropped"][0] for r in res) / 900
    sweep = np.concatenate([r["nbp_min_entropy|ns20|err"] for r in res[:2]])
    assert f["nbp_min_entropy.ns20.mean_error_m"].value == sweep.mean()
    assert f["nbp_min_entropy.ns20.mean_error_m"].n_units == 2
    r = f["poa_nbp_vs_wls.rmse_m"]
    assert r.value == f["poa_nbp.rmse_m"].value / f["wls.rmse_m"].value
    assert f["poa_nbp_vs_nbp_min_entropy.ns40.outage_1m"].a is f["poa_nbp.ns40.outage_1m"]
    assert isinstance(f["poa_nbp.convergence_iteration"], Pooled)
    assert not isinstance(f["poa_nbp.curve_convergence_iteration"], Pooled)
    assert not isinstance(f["poa_nbp.settling_iteration"], Pooled)


# -- per-topology iteration counts and wall times; PBP over the sweep's topologies -------------
@pytest.fixture(scope="module")
def tiny3():
    """The tiny recipe with 3 topologies, the sample sweep in the first 2 of them."""
    recipe = TINY.replace("topologies = 2", "topologies = 3\nsample_sweep_topologies = 2")
    return se.STATIC.run(load_recipe(recipe), progress=False)


def _per_topology_names(meta) -> list[tuple[str, int]]:
    """The figures given one value per topology, or pooled over the sweep's topologies
    (``pbp.sweep``), with the number of topologies each pools."""
    n, s = meta["topologies"], meta["sample_sweep_topologies"]
    names = [("poa.time_per_node_s", n)]
    for m in meta["methods"]:
        q = ("convergence_iteration", "time_per_node_iteration_s", "time_to_convergence_s")
        names += [(f"{m}.{x}", n) for x in q]
    names += [(f"{m}.start_time_per_node_s", n) for m in ("pbp", "wls")]
    names += [
        (f"{m}.ns{ns}.time_per_node_iteration_s", s)
        for m in meta["sample_methods"]
        for ns in meta["sample_sweep"]
    ]
    return names + [(f"pbp.sweep.{q}", s) for q in ("mean_error_m", "outage_1m")]


def _units(res, name) -> tuple[np.ndarray, np.ndarray]:
    u = res["series"][name + ".units"]
    return np.asarray(u["num"], dtype=float), np.asarray(u["den"], dtype=float)


def test_per_topology_figures_carry_intervals_and_units(tiny3):
    """Every new figure pooled over topologies has a finite 95 % interval around it and one
    unit per topology it pools (3, or the sweep's 2); only the methods with a start option
    have a start time."""
    f, meta = tiny3["figures"], tiny3["meta"]
    assert meta["topologies"] == 3 and meta["sample_sweep_topologies"] == 2
    for name, n_units in _per_topology_names(meta):
        lo, x, hi = f[name + ".ci_low"], f[name], f[name + ".ci_high"]
        assert math.isfinite(lo) and math.isfinite(hi), name
        slack = 1e-12 * abs(x)  # a point value kept as np.mean computed it
        assert lo - slack <= x <= hi + slack, (name, lo, x, hi)
        num, den = _units(tiny3, name)
        assert num.size == den.size == n_units, name
    for m in ("nbp_aux", "poa_nbp", "nbp_ellipse", "nbp_min_entropy"):
        assert f"{m}.start_time_per_node_s" not in f
    assert f["pbp.sweep.topologies"] == 2.0


def test_per_topology_units_reproduce_the_figures(tiny3):
    """One value per topology (denominator 1): each figure is the plain mean of its stored
    values; the convergence iteration is a whole count in 1..n_iterations in every topology;
    a topology's time to convergence is its count times its time per node-iteration plus its
    setup per node — the start for PBP and WLS, the proposal polygons' POA time for POA-NBP,
    at least 0 for the others — and the start is part of it."""
    f, meta = tiny3["figures"], tiny3["meta"]
    for name, _ in _per_topology_names(meta):
        if name.startswith("pbp.sweep."):
            continue
        num, den = _units(tiny3, name)
        assert tiny3["series"][name + ".units"]["kind"] == "mean" and np.all(den == 1.0), name
        assert f[name] == pytest.approx(math.fsum(num) / num.size, rel=1e-12), name
    n_it = meta["experiment"]["n_iterations"]
    poa_time = _units(tiny3, "poa.time_per_node_s")[0]
    for m in meta["methods"]:
        conv = _units(tiny3, f"{m}.convergence_iteration")[0]
        assert np.all(conv == np.round(conv)) and np.all((conv >= 1) & (conv <= n_it)), m
        t_it = _units(tiny3, f"{m}.time_per_node_iteration_s")[0]
        t_conv = _units(tiny3, f"{m}.time_to_convergence_s")[0]
        setup = {
            "pbp": _units(tiny3, "pbp.start_time_per_node_s")[0],
            "wls": _units(tiny3, "wls.start_time_per_node_s")[0],
            "poa_nbp": poa_time,
        }.get(m)
        if setup is None:
            assert np.all(t_conv >= conv * t_it * (1 - 1e-12)), m
        else:
            assert np.all(setup >= 0.0), m
            np.testing.assert_allclose(t_conv, conv * t_it + setup, rtol=1e-12, err_msg=m)
            assert np.all(setup <= t_conv), m


def test_pbp_sweep_figures_are_pbp_over_the_sweep_topologies(tiny3):
    """``pbp.sweep.*`` are PBP's figures recomputed from its per-topology units restricted to
    the sweep's topologies (the first 2 of 3), and the paired ratios of the sweep against PBP
    are ratios over those same topologies."""
    f, meta = tiny3["figures"], tiny3["meta"]
    s = meta["sample_sweep_topologies"]
    for q in ("mean_error_m", "outage_1m"):
        num, den = _units(tiny3, f"pbp.{q}")
        assert num.size == 3
        sw_num, sw_den = _units(tiny3, f"pbp.sweep.{q}")
        np.testing.assert_array_equal(sw_num, num[:s])
        np.testing.assert_array_equal(sw_den, den[:s])
        assert f[f"pbp.sweep.{q}"] == pytest.approx(num[:s].sum() / den[:s].sum(), rel=1e-12)
        for ns in meta["sample_sweep"]:
            key = f"poa_nbp_vs_pbp.ns{ns}.{q}.ratio"
            assert _units(tiny3, f"poa_nbp.ns{ns}.{q}")[0].size == s
            if f[f"pbp.sweep.{q}"] == 0:
                assert key not in f
            else:
                assert f[key] == f[f"poa_nbp.ns{ns}.{q}"] / f[f"pbp.sweep.{q}"], key
    assert tiny3["series"]["pbp.sweep.outage"].shape == sa.OUTAGE_GRID_M.shape


def test_convergence_is_counted_per_topology():
    """Three topologies whose mean-error curves converge after 3 (never), 2 and 1 iterations
    by the paper's rule (5 % or 2 cm): the convergence iteration is their mean, 2, while the
    curve pooled over all topologies, (10/3, 2, 5/3), never converges (3); a topology's time
    to convergence is its count times its own time per node-iteration plus its setup."""
    exp = se.StaticExperimentSpec(
        topologies=3,
        n_agents=5,
        n_edges=(4,),
        poa_iterations=2,
        methods=("poa_nbp", "pbp"),
        n_iterations=3,
        sample_sweep=(),
        outage_thresholds_m=(1.0,),
    )
    res = _fake_static(exp, 3)
    curves = ([4.0, 2.0, 1.0], [4.0, 2.0, 2.0], [2.0, 2.0, 2.0])
    t_it, t_setup = (1e-3, 2e-3, 3e-3), (4e-4, 5e-4, 6e-4)
    for r, c, t, u in zip(res, curves, t_it, t_setup, strict=True):
        for m in exp.methods:
            r[f"{m}|err"] = np.repeat(np.array(c)[:, None], exp.n_agents, axis=1)
            r[f"{m}|time"], r[f"{m}|t_support"] = t, u
    f, _ = sa.aggregate(res, exp)
    for m in exp.methods:
        np.testing.assert_array_equal(f[f"{m}.convergence_iteration"].num, [3.0, 2.0, 1.0])
        assert f[f"{m}.convergence_iteration"].value == 2.0
        assert f[f"{m}.curve_convergence_iteration"] == 3.0
        expected = (3 * 1e-3 + 4e-4 + 2 * 2e-3 + 5e-4 + 1 * 3e-3 + 6e-4) / 3
        assert f[f"{m}.time_to_convergence_s"].value == pytest.approx(expected, rel=1e-12)
        assert f[f"{m}.time_per_node_iteration_s"].value == pytest.approx(2e-3, rel=1e-12)
    assert f["pbp.start_time_per_node_s"].value == pytest.approx(5e-4, rel=1e-12)
    assert "poa_nbp.start_time_per_node_s" not in f
    assert not any(k.startswith("pbp.sweep.") for k in f)  # no sweep: no PBP sweep figures


# -- variants: a label that names its method (the paper's form of a baseline) --------------------
VARIANTS = """
[localization.poa_nbp_paper]
method = "poa_nbp"
jacobian_weights = false

[localization.nbp_ellipse_paper]
method = "nbp_bounding"
jacobian_weights = false

[localization.wls_paper]
method = "wls"
mode = "distributed"
start = "heuristic"
"""


def _with_variants(text, labels):
    return (
        text.replace("topologies = 2", "topologies = 1").replace(
            '"pbp", "wls"]', '"pbp", "wls", ' + ", ".join(f'"{m}"' for m in labels) + "]"
        )
        + VARIANTS
    )


def test_variants_run_their_method_and_change_no_other_figure():
    """Variant labels run the method their table names with its options, on streams after
    every other one: the figures of the other labels are those of the run without variants
    (non-timing figures, bit for bit)."""
    labels = ["poa_nbp_paper", "nbp_ellipse_paper", "wls_paper"]
    one = load_recipe(TINY.replace("topologies = 2", "topologies = 1"))
    base = se.STATIC.run(one, progress=False)
    res = se.STATIC.run(load_recipe(_with_variants(TINY, labels)), progress=False)
    f, meta = res["figures"], res["meta"]
    for n, x in base["figures"].items():
        if static_figures.is_timing(n) or n.endswith("time_to_convergence_ratio"):
            continue
        assert _same(x, f[n]), n
    assert meta["method_of"]["wls_paper"] == "wls" and meta["method_of"]["wls"] == "wls"
    assert meta["labels"]["nbp_ellipse_paper"] == "NBP bound. (nbp_ellipse_paper)"
    opts = meta["options"]
    assert opts["poa_nbp_paper"]["jacobian_weights"] is False
    assert opts["poa_nbp"]["jacobian_weights"] is True
    assert (opts["wls_paper"]["start"], opts["wls_paper"]["mode"]) == ("heuristic", "distributed")
    assert opts["wls"]["start"] == "mds"  # experiment.baseline_start
    for m in labels:
        assert math.isfinite(f[f"{m}.mean_error_m"]) and f"poa_nbp_vs_{m}.mean_error_m.ratio" in f
    # the disc proposal's support: 3 floats per broadcast; POA-NBP shares its polygons
    assert f["nbp_ellipse_paper.ns40.support_floats_per_link_iteration"] == 3.0
    assert "wls_paper.start_time_per_node_s" in f


def test_bounding_discs_are_no_tighter_than_the_exact_ellipses(tiny):
    """Fig. 9 with the cited ellipses: in iteration 1 (the same anchor constraints) the mean
    S-procedure disc is at least the mean exact minimum-area ellipse, less the inflation of
    the exact baseline's 64-gons (π r² tan²(π/64) for ranges r <= 25 m); no disc grows."""
    f, ser = tiny["figures"], tiny["series"]
    slack = math.pi * 25.0**2 * math.tan(math.pi / 64) ** 2
    assert f["ellipse_paper.area_it1_m2"] >= f["ellipse.area_it1_m2"] - slack
    a = ser["ellipse_paper.area_m2"]
    assert a.shape == (3,) and np.all(np.diff(a) <= 1e-9 * a[:-1])


@pytest.mark.parametrize(
    ("edit", "key"),
    [
        (('start = "heuristic"', 'start = "truth"'), "localization.wls_paper.start"),
        (
            ("jacobian_weights = false\n\n[localization.nbp", 'start = "mds"\n\n[localization.nbp'),
            "localization.poa_nbp_paper.start",
        ),
        (
            ('method = "nbp_bounding"', 'method = "nbp_bound"'),
            "localization.nbp_ellipse_paper.method",
        ),
    ],
)
def test_variant_errors_name_the_key(edit, key):
    text = _with_variants(TINY, ["poa_nbp_paper", "nbp_ellipse_paper", "wls_paper"])
    recipe = load_recipe(text.replace(*edit))
    with pytest.raises(ValidationError) as exc:
        se.STATIC.run(recipe, progress=False)
    assert exc.value.field == key


def test_summary_and_figure_show_both_ellipse_baselines(tiny, tmp_path):
    """Fig. 9's two ellipse baselines (the exact ellipses and the cited bounding discs) each
    get a summary line with their per-iteration areas, and the cited discs are never smaller
    than the exact minimum-area ellipses of the same constraint sets."""
    f = tiny["figures"]
    lines = "\n".join(se.STATIC.summary_lines(tiny))
    for e, what in (("ellipse", "exact ellipses"), ("ellipse_paper", "bounding discs (cited)")):
        areas = ", ".join(f"{f[f'{e}.area_it{it}_m2']:.0f}" for it in (1, 2, 3))
        assert f"mean area of the {what} per iteration [m²]: {areas}" in lines
    for it in (1, 2, 3):
        assert f[f"ellipse_paper.area_it{it}_m2"] >= f[f"ellipse.area_it{it}_m2"] * (1 - 1e-9)
    se.STATIC.plot(tiny, tmp_path / "s.png")
    assert (tmp_path / "s.png").stat().st_size > 1000

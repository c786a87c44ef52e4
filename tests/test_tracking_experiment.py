"""The ``kind = "tracking"`` experiment (PF-BP §VI): figure names, bound sanity, seeds, recipe
errors."""

import math
from pathlib import Path

import numpy as np
import pytest

from phyloc.config import load_recipe
from phyloc.errors import ValidationError
from phyloc.evaluation import tracking_experiment as te
from phyloc.evaluation import tracking_scenarios
from phyloc.evaluation.tracking_figures import is_timing

DATASETS = Path(__file__).resolve().parents[1] / "datasets"

TINY = """
kind = "tracking"
name = "tiny"
seed = 3

[experiment]
scenarios = { s1 = { n_agents = 3, comm_range_m = 18.0 } }
runs = 2
n_steps = 3
methods = ["pfbp", "sirbp", "spbp", "edh"]
report_steps = [1, 3]
outage_steps = [3]
method_options = { sirbp = { n_particles = 500 } }

[localization.pfbp]
n_particles = 30
n_lambda = 5

[localization.edh]
n_particles = 30
n_lambda = 5
"""


@pytest.fixture(scope="module")
def fast_s1():
    recipe = load_recipe(DATASETS / "pfbp_scenario1.toml")
    return te.TRACKING.run(recipe, fast=True, progress=False)


@pytest.fixture(scope="module")
def tiny():
    return te.TRACKING.run(load_recipe(TINY), progress=False)


def _pooled(res) -> list:
    """The figures a run declared pooled over runs (those with per-unit values)."""
    return [n.removesuffix(".units") for n in res["series"] if n.endswith(".units")]


def test_pooled_figures_have_intervals_and_one_value_per_run(tiny):
    """Every figure pooled over runs: a finite 95 % interval around it (2 runs), one numerator
    and denominator per run, the figure recomputed from them by hand; the denominators are
    the errors each run contributes (agents at a step, agents x steps over the trajectory),
    and the RMSE over the trajectory is the RMS of the per-step RMSE series."""
    f, ser, meta = tiny["figures"], tiny["series"], tiny["meta"]
    runs, K, n_agents = meta["runs"], meta["n_steps"], 3
    names = _pooled(tiny)
    expected = []
    for m in meta["methods"]:
        expected.append(f"{m}.s1.rmse_p_all_m")
        for k in meta["report_steps"]:
            expected += [f"{m}.s1.k{k}.rmse_{q}" for q in ("p_m", "v_m_s", "a_m_s2")]
        for k in meta["outage_steps"]:
            expected += [f"{m}.s1.k{k}.outage_{x}" for x in ("0p1m", "0p3m", "1m")]
        expected += [f"{m}.s1.step_s"] + ([f"{m}.s1.agent_s"] if m != "edh" else [])
        stages = [n for n in f if n.startswith(f"{m}.s1.stage.") and n.endswith("_s")]
        assert {f"{m}.s1.stage.{s}_s" for s in ("predict", "estimate", "other")} <= set(stages)
        expected += stages
    expected.append("s1.anchor_localizable_fraction")
    for k in meta["report_steps"]:  # the conditional bound: the mean of the runs' own bounds
        expected += [f"pcrlb_cond.s1.k{k}.{q}" for q in ("p_m", "v_m_s", "a_m_s2")]
    assert sorted(names) == sorted(expected)
    for n in names:
        u = ser[n + ".units"]
        num, den = list(map(float, u["num"])), list(map(float, u["den"]))
        assert len(num) == len(den) == runs, n
        total = 0.0
        for x in num:
            total += x
        ref = total / sum(den)
        ref = math.sqrt(ref) if u["kind"] == "rmse" else ref
        assert f[n] == pytest.approx(ref, rel=1e-12), n
        lo, hi = f[n + ".ci_low"], f[n + ".ci_high"]
        assert math.isfinite(lo) and math.isfinite(hi), n
        assert lo <= f[n] * (1 + 1e-12) and f[n] <= hi * (1 + 1e-12), n
        if n.endswith(("step_s", "agent_s")):  # per run: its median step time
            assert u["kind"] == "mean" and den == [1.0] * runs and all(x > 0 for x in num)
        elif ".stage." in n:  # per run: the median step of the stage, below the whole step's
            assert u["kind"] == "mean" and den == [1.0] * runs and all(x >= 0 for x in num)
            step = ser[n.split(".stage.")[0] + ".step_s.units"]["num"]
            assert all(x <= 1.05 * s for x, s in zip(num, step, strict=True)), n
        elif n.endswith("anchor_localizable_fraction"):  # per run: its positions
            assert u["kind"] == "mean" and den == [K * n_agents] * runs
            assert all(x == int(x) and 0 <= x <= K * n_agents for x in num)
        elif ".outage_" in n:
            assert u["kind"] == "fraction" and den == [n_agents] * runs
            assert all(x == int(x) and 0 <= x <= n_agents for x in num)
        elif n.startswith("pcrlb_cond."):  # per run: its mean-square bound, weight 1
            assert u["kind"] == "rmse" and den == [1.0] * runs and all(x > 0 for x in num)
            k = int(n.split(".")[2][1:])
            assert f[n] == pytest.approx(ser[n.replace(f".k{k}.", ".")][k - 1], rel=1e-12)
        elif n.endswith("rmse_p_all_m"):
            assert den == [K * n_agents] * runs
            per_step = np.asarray(ser[n.replace("rmse_p_all_m", "rmse_p_m")])
            assert f[n] == pytest.approx(math.sqrt(np.mean(per_step**2)), rel=1e-12)
        else:
            assert u["kind"] == "rmse" and den == [n_agents] * runs
            k = int(n.split(".")[2][1:])
            assert f[n] == ser[n.replace(f".k{k}.", ".")][k - 1]  # the series, bit for bit


def test_first_method_over_the_others_on_the_same_runs(tiny):
    """``pfbp_vs_<m>.*.ratio``: the ratio of the two written figures, with a paired interval
    around it; no other pairs."""
    f = tiny["figures"]
    ratios = sorted(n for n in f if n.endswith(".ratio"))
    names = ["k1.rmse_p_m", "k3.rmse_p_m", "rmse_p_all_m"]
    assert ratios == sorted(
        f"pfbp_vs_{m}.s1.{n}.ratio" for m in ("sirbp", "spbp", "edh") for n in names
    )
    for m in ("sirbp", "spbp", "edh"):
        for n in names:
            r = f[f"pfbp_vs_{m}.s1.{n}.ratio"]
            assert r == f[f"pfbp.s1.{n}"] / f[f"{m}.s1.{n}"]
            lo, hi = f[f"pfbp_vs_{m}.s1.{n}.ratio.ci_low"], f[f"pfbp_vs_{m}.s1.{n}.ratio.ci_high"]
            assert math.isfinite(lo) and lo <= r * (1 + 1e-12) and r <= hi * (1 + 1e-12)
    rows = te.summary_rows(tiny)
    assert rows[0][:2] == ("s1", "pfbp")
    assert rows[0][2].startswith(f"{f['pfbp.s1.k1.rmse_p_m']:.3g} [")
    assert any("pfbp / other on the same runs" in line for line in te.summary_lines(tiny))


def test_rmse_over_the_conditional_bound_is_paired_over_runs(tiny):
    """``rmse_over_pcrlb_cond``: the RMSE over the conditional bound of the same runs, with
    the interval of the paired bootstrap that resamples each run's errors and bound together
    (recomputed here from the stored per-run values); so is SIR-BP / PF-BP time per step."""
    from phyloc.evaluation.statistics import Paired, paired_interval, units_of

    f, ser, seed = tiny["figures"], tiny["series"], tiny["meta"]["seed"]
    for m in tiny["meta"]["methods"]:
        for k in tiny["meta"]["report_steps"]:
            n = f"{m}.s1.k{k}.rmse_over_pcrlb_cond"
            a, b = units_of(ser, f"{m}.s1.k{k}.rmse_p_m"), units_of(ser, f"pcrlb_cond.s1.k{k}.p_m")
            assert f[n] == pytest.approx(a.value / b.value, rel=1e-12)
            assert (f[n + ".ci_low"], f[n + ".ci_high"]) == paired_interval(
                Paired(a, b), seed=seed, name=n
            )
            assert f[n + ".ci_low"] <= f[n] * (1 + 1e-12) <= f[n + ".ci_high"] * (1 + 1e-12)
            assert n + ".ratio" not in f
    n = "sirbp_over_pfbp.s1.step_ratio"
    a, b = units_of(ser, "sirbp.s1.step_s"), units_of(ser, "pfbp.s1.step_s")
    assert f[n] == pytest.approx(a.value / b.value, rel=1e-12)
    assert (f[n + ".ci_low"], f[n + ".ci_high"]) == paired_interval(Paired(a, b), seed=seed, name=n)


def test_fast_scenario1_has_every_documented_figure(fast_s1, tmp_path):
    f, ser, meta = fast_s1["figures"], fast_s1["series"], fast_s1["meta"]
    K = meta["n_steps"]
    assert meta["scenarios"].keys() == {"s1_r18", "s1_rinf"}
    assert meta["methods"] == [
        "pfbp", "pfbp_reg", "pfbp_cen", "sirbp", "sirbp_reg", "sirbp_mil", "sirbp_mil_reg",
        "spbp", "spbp_reg", "edh", "edh_reg",
    ]  # fmt: skip
    assert meta["options"]["sirbp"]["n_particles"] == 10_000  # [experiment.fast] override
    assert meta["options"]["sirbp_reg"]["n_particles"] == 10_000
    assert meta["bases"]["sirbp_mil"] == meta["bases"]["sirbp_mil_reg"] == "sirbp"
    for m in meta["methods"]:  # "reg" is the registered default of every *_reg variant
        assert meta["options"][m]["regularize"] is m.endswith("_reg")
    expected = []
    for s in meta["scenarios"]:
        expected.append(f"sirbp_over_pfbp.{s}.step_ratio")
        for k in meta["report_steps"]:
            for b in ("pcrlb", "pcrlb_cond", "pcrlb_cond_one_range"):
                expected += [f"{b}.{s}.k{k}.p_m", f"{b}.{s}.k{k}.v_m_s", f"{b}.{s}.k{k}.a_m_s2"]
            # Jensen: the conditional bound (averaged inverses) is never below the Bayesian one
            assert f[f"pcrlb_cond.{s}.k{k}.p_m"] >= f[f"pcrlb.{s}.k{k}.p_m"] * (1 - 1e-9)
            # less information, never a lower bound
            assert f[f"pcrlb_cond_one_range.{s}.k{k}.p_m"] >= f[f"pcrlb_cond.{s}.k{k}.p_m"]
        for m in meta["methods"]:
            expected += [f"{m}.{s}.step_s", f"{m}.{s}.rmse_p_all_m"]
            if not m.startswith("edh"):  # centralized: no time per agent, no messages
                expected += [f"{m}.{s}.agent_s", f"{m}.{s}.floats_per_link_iteration"]
            for k in meta["report_steps"]:
                expected += [
                    f"{m}.{s}.k{k}.{q}"
                    for q in (
                        "rmse_p_m",
                        "rmse_v_m_s",
                        "rmse_a_m_s2",
                        "rmse_over_pcrlb",
                        "rmse_over_pcrlb_cond",
                    )
                ]
            for k in meta["outage_steps"]:
                expected += [f"{m}.{s}.k{k}.outage_{x}" for x in ("0p1m", "0p3m", "1m")]
                assert ser[f"{m}.{s}.k{k}.outage"].shape == te.OUTAGE_GRID_M.shape
            for q in ("rmse_p_m", "rmse_v_m_s", "rmse_a_m_s2"):
                assert ser[f"{m}.{s}.{q}"].shape == (K,)
            cf = ser[f"{m}.{s}.error_cf"]
            assert np.all(np.diff(cf) >= 0) and 0 <= cf[0] <= cf[-1] <= 1
        for q in ("p_m", "v_m_s", "a_m_s2"):
            assert ser[f"pcrlb.{s}.{q}"].shape == (K,)
    # the names quoted in the module docstring and the issue, at the fast setting's steps
    expected += [
        "pfbp.s1_rinf.k10.rmse_p_m",
        "spbp.s1_rinf.k10.rmse_p_m",
        "sirbp.s1_rinf.step_s",
        f"pfbp.s1_rinf.k{K}.rmse_over_pcrlb",
        f"pfbp.s1_rinf.k{K}.outage_1m",
        f"pcrlb.s1_rinf.k{K}.p_m",
    ]
    missing = [n for n in expected if n not in f]
    assert not missing, missing
    assert all(math.isfinite(f[n]) for n in expected)
    for s, scen in meta["scenarios"].items():  # PF-BP Fig. 3: anchors within r_max, by hand
        pos, anchors = ser[f"{s}.example_positions_m"], ser[f"{s}.anchors_m"]
        d = np.linalg.norm(pos[:, :, None, :] - anchors[None, None], axis=-1)
        count = (d <= scen["comm_range_m"]).sum(axis=2)
        np.testing.assert_array_equal(ser[f"{s}.example_anchor_links"], count)
        assert pos.shape == (K, 5, 3) and 0 < count.min() and count.max() <= 9
    for s in meta["scenarios"]:  # what one agent sends a neighbour per iteration, 9-D states
        M = meta["options"]["sirbp"]["n_particles"]
        assert f[f"sirbp.{s}.floats_per_link_iteration"] == 3 * M
        assert f[f"spbp.{s}.floats_per_link_iteration"] == 9 + 45
        assert f[f"pfbp.{s}.floats_per_link_iteration"] == 9 + 45  # exchange = "gaussian"
    assert all(0.0 <= f[n] <= 1.0 for n in f if ".outage_" in n)
    te.plot(fast_s1, tmp_path / "t.png")
    assert (tmp_path / "t.png").stat().st_size > 10_000
    assert (tmp_path / "t_stages.png").stat().st_size > 10_000  # the step by stage
    rows = te.summary_rows(fast_s1)
    assert len(rows) == 2 * (len(meta["methods"]) + 2)  # + the two PCRLB rows
    assert all(len(r) == len(te.summary_headers(fast_s1)) for r in rows)
    assert te.summary_lines(fast_s1)


def test_pfbp_is_not_below_the_pcrlb(fast_s1):
    """A loose sanity check of estimator vs bound: PF-BP RMSE >= 0.8 PCRLB at the last step."""
    f, K = fast_s1["figures"], fast_s1["meta"]["n_steps"]
    for s in ("s1_r18", "s1_rinf"):
        assert f[f"pfbp.{s}.k{K}.rmse_p_m"] >= 0.8 * f[f"pcrlb.{s}.k{K}.p_m"]
        # the bound decreases as the measurements accumulate
        assert f[f"pcrlb.{s}.k{K}.p_m"] < f[f"pcrlb.{s}.k1.p_m"]


def test_same_results_with_one_and_two_workers():
    recipe = load_recipe(TINY)
    one = te.TRACKING.run(recipe, workers=1, progress=False)
    two = te.TRACKING.run(recipe, workers=2, progress=False)
    names = [n for n in one["figures"] if not is_timing(n)]
    assert names == [n for n in two["figures"] if not is_timing(n)]
    assert any(n.startswith("sirbp.") for n in names)
    for n in names:
        assert one["figures"][n] == two["figures"][n], n
    for n, x in one["series"].items():
        if is_timing(n):  # the per-run wall times of a timing figure: the machine's
            continue
        if isinstance(x, dict):  # the per-run values of a pooled figure
            assert x.keys() == two["series"][n].keys()
            for key, val in x.items():
                np.testing.assert_array_equal(val, two["series"][n][key], err_msg=n)
        else:
            np.testing.assert_array_equal(x, two["series"][n], err_msg=n)
    # different runs really see different scenarios
    other = te.TRACKING.run(load_recipe(TINY.replace("seed = 3", "seed = 4")), progress=False)
    assert other["figures"]["pfbp.s1.k3.rmse_p_m"] != one["figures"]["pfbp.s1.k3.rmse_p_m"]


@pytest.mark.parametrize(
    ("edit", "fast", "key"),
    [
        (("runs = 2", "rnus = 2"), False, "experiment.rnus"),
        (("n_lambda = 5\n\n[loc", "n_lamda = 5\n\n[loc"), False, "localization.pfbp.n_lamda"),
        (
            ("n_particles = 500", "n_partcles = 500"),
            False,
            "experiment.method_options.sirbp.n_partcles",
        ),
        (("comm_range_m = 18.0", "comm_range = 18.0"), False, "experiment.scenarios.s1.comm_range"),
        (('"edh"]', '"ekf"]'), False, "experiment.methods"),
        (("runs = 2", 'runs = 2\nsage_sigma_m = "mad"'), False, "experiment.sage_sigma_m"),
        (("runs = 2", "runs = 2\nsage_sigma_m = -1.0"), False, "experiment.sage_sigma_m"),
        (("[localization.edh]", "[localization.ed]"), False, "localization.ed"),
        (("runs = 2", "runs = 2\nmemory_agents = [5, 0]"), False, "experiment.memory_agents"),
        (("runs = 2", "runs = 2\nmemory_steps = 0"), False, "experiment.memory_steps"),
        (("runs = 2", "runs = 2\nmemory_repeats = 0"), False, "experiment.memory_repeats"),
        (("runs = 2", "runs = 2\nmethod_runs = { sirpb = 1 }"), False, "experiment.method_runs"),
        (
            ("runs = 2", "runs = 2\nmethod_runs = { sirbp = 0 }"),
            False,
            "experiment.method_runs.sirbp",
        ),
        (
            ("[localization.pfbp]", "[experiment.fast]\nrun = 1\n\n[localization.pfbp]"),
            True,
            "experiment.fast.run",
        ),
    ],
)
def test_bad_recipe_keys_fail_before_any_work(monkeypatch, edit, fast, key):
    def no_work(*args, **kwargs):
        raise AssertionError("work started")

    import phyloc.evaluation.experiment as runner

    monkeypatch.setattr(runner, "run_tasks", no_work)  # the one runner every kind uses
    old, new = edit
    assert old in TINY
    recipe = load_recipe(TINY.replace(old, new, 1))
    with pytest.raises(ValidationError) as err:
        te.TRACKING.run(recipe, fast=fast, progress=False)
    assert err.value.field == key


def test_sage_measurements_on_c2_waveforms():
    """``measurements = "sage"``: PF-BP runs on SAGE ranges of simulated C2 waveforms."""
    recipe = load_recipe(DATASETS / "pfbp_sage_c2.toml")
    res = te.TRACKING.run(recipe, fast=True, progress=False)
    f = res["figures"]
    assert res["meta"]["measurements"] == "sage"
    assert 0.0 < f["sage.c2.valid_fraction"] <= 1.0
    assert f["sage.c2.range_rmse_m"] > 0 and f["sage.c2.sigma_m"] > 0
    assert math.isfinite(f["pfbp.c2.k4.rmse_p_m"]) and math.isfinite(f["pcrlb.c2.k4.p_m"])


def test_residual_sigma_is_the_range_noise_scale():
    """The truth-free σ of SAGE ranges (``sage_sigma_m = "residual"``): the RMS residual of the
    MDS/SMACOF fit is ~0 for exact ranges and of the order of the noise for noisy ones (a bit
    below it: the fit absorbs 2 degrees of freedom per agent)."""
    from types import SimpleNamespace

    rng = np.random.default_rng(4)
    n_ag, anchors = 10, np.array([[0.0, 0.0], [50.0, 0.0], [0.0, 50.0], [50.0, 50.0]])
    pos = np.vstack([rng.uniform(0, 50, (n_ag, 2)), anchors])
    is_anchor = np.r_[np.zeros(n_ag, bool), np.ones(4, bool)]
    net = SimpleNamespace(
        n_nodes=pos.shape[0],
        is_anchor=is_anchor,
        positions=pos[None],
        anchor_index=np.flatnonzero(is_anchor),
    )
    u, w = np.nonzero(~np.eye(pos.shape[0], dtype=bool) & ~is_anchor[:, None])
    links = np.stack([u, w], axis=1)
    d = np.linalg.norm(pos[u] - pos[w], axis=1)
    assert tracking_scenarios.residual_sigma(net, (links, d), dim=2) < 1e-3
    sigma = tracking_scenarios.residual_sigma(net, (links, d + rng.normal(0, 0.5, d.size)), dim=2)
    assert 0.25 < sigma < 0.5
    assert tracking_scenarios.residual_sigma(net, None, dim=2) is None


def test_a_variant_runs_its_base_method_with_its_own_table():
    """``[localization.sirbp_small] method = "sirbp"`` defines a method name: the run equals
    the registered method with the same options at the same place of ``experiment.methods``
    (the same random stream), next to the base method itself."""
    variant = TINY.replace(
        'methods = ["pfbp", "sirbp", "spbp", "edh"]', 'methods = ["pfbp", "sirbp_small"]'
    ).replace(
        "method_options = { sirbp = { n_particles = 500 } }",
        '[localization.sirbp_small]\nmethod = "sirbp"\nn_particles = 300\nregularize = true\n',
    )
    plain = TINY.replace(
        'methods = ["pfbp", "sirbp", "spbp", "edh"]', 'methods = ["pfbp", "sirbp"]'
    ).replace(
        "method_options = { sirbp = { n_particles = 500 } }",
        "method_options = { sirbp = { n_particles = 300, regularize = true } }",
    )
    a = te.TRACKING.run(load_recipe(variant), progress=False)
    b = te.TRACKING.run(load_recipe(plain), progress=False)
    assert a["meta"]["bases"] == {"pfbp": "pfbp", "sirbp_small": "sirbp"}
    assert a["meta"]["labels"]["sirbp_small"] == "sirbp_small"
    assert a["meta"]["options"]["sirbp_small"]["n_particles"] == 300
    fa = {n: x for n, x in a["figures"].items() if not is_timing(n)}
    fb = {n.replace("sirbp.", "sirbp_small.", 1): x for n, x in b["figures"].items()}
    fb = {n.replace("sirbp_over_pfbp", "x"): x for n, x in fb.items() if not is_timing(n)}
    fa = {n.replace("sirbp_over_pfbp", "x"): x for n, x in fa.items()}
    assert fa.keys() == fb.keys()
    # the bootstrap's stream follows the figure's name: a renamed figure's interval differs
    same = [n for n in fa if ".ci_" not in n or not n.startswith(("sirbp", "pfbp_vs_sirbp"))]
    assert {n: fa[n] for n in same} == {n: fb[n] for n in same}
    # a variant's table needs a registered base; a registered name cannot be redefined
    for old, new, key in (
        ('method = "sirbp"', 'method = "sirbpp"', "localization.sirbp_small.method"),
        ("[localization.pfbp]\n", '[localization.pfbp]\nmethod = "sirbp"\n', "localization.pfbp"),
        ('method = "sirbp"\n', "", "localization.sirbp_small"),  # no base: an unknown table
    ):
        with pytest.raises(ValidationError) as err:
            te.TRACKING.run(load_recipe(variant.replace(old, new, 1)), progress=False)
        assert err.value.field.startswith(key), err.value.field


@pytest.mark.slow  # 24 fresh processes: ~2 min
def test_memory_study_grows_as_the_methods_store_particles(tmp_path, capsys):
    """The memory recipe's fast setting from the command line (3 and 6 agents, SIR-BP with 10⁴
    particles, 2 repeats): SIR-BP's run needs at least one [M, 9] float64 particle array more
    per added agent (its belief), PF-BP's (200 particles, Gaussian messages) stays below a
    tenth of SIR-BP's in each repeat, every figure is measured (peak above the run's own part,
    both finite), each is the mean of its two stored repeats with an interval around it, and
    the memory figure is written and named."""
    import json

    from phyloc.cli import main

    recipe = Path(__file__).parents[1] / "datasets/pfbp_memory.toml"
    out = tmp_path / "mem"
    assert main(["evaluate", str(recipe), "--fast", "--out", str(out), "--no-progress"]) == 0
    res = json.loads((out / "results.json").read_text())
    f = res["figures"]
    one_array_mb = 10_000 * 9 * 8 / 2**20
    grow = f["sirbp.s1_r18.agents_6.run_rss_mb"] - f["sirbp.s1_r18.agents_3.run_rss_mb"]
    assert grow >= 3 * one_array_mb
    units = {
        m: np.array(res["series"][f"{m}.s1_r18.agents_6.run_rss_mb.units"]["num"])
        for m in ("pfbp", "sirbp")
    }
    assert units["pfbp"].shape == (2,) and np.all(units["pfbp"] < 0.1 * units["sirbp"])
    for m in ("pfbp", "sirbp", "spbp", "edh"):
        for n in (3, 6):
            name = f"{m}.s1_r18.agents_{n}"
            peak, run = f[f"{name}.peak_rss_mb"], f[f"{name}.run_rss_mb"]
            assert math.isfinite(peak) and 0 <= run < peak
            for fig in ("peak_rss_mb", "run_rss_mb"):
                u = res["series"][f"{name}.{fig}.units"]
                assert u["kind"] == "mean" and u["den"] == [1.0, 1.0]
                assert f[f"{name}.{fig}"] == pytest.approx(np.mean(u["num"]), rel=1e-12)
                lo, hi = f[f"{name}.{fig}.ci_low"], f[f"{name}.{fig}.ci_high"]
                assert lo <= f[f"{name}.{fig}"] <= hi  # two repeats: [min, max]
    assert res["series"]["memory_agents"] == [3, 6]
    memory_png = out / "pfbp_memory_memory.png"
    assert memory_png.stat().st_size > 0
    assert str(memory_png) in capsys.readouterr().out


def test_flow_example_moves_the_particles_to_the_crossing_the_cooperative_range_selects():
    """PF-BP Fig. 1 (``flow_example``): each agent's two anchor rings cross twice (the map has
    equal peaks at the truth and at the mirror crossing), the prior particles start about 2 m
    off, and the flow, recorded one λ-step at a time, ends where the library's
    :func:`edh_flow` over the whole schedule ends, within 0.5 m of both agents."""
    from phyloc.evaluation.range_scenarios import flow_example
    from phyloc.localization.tracking._flow import edh_flow, lambda_schedule, range_linearization

    for seed in range(4):
        ex = flow_example(np.random.default_rng(seed), n_lambda=20)
        paths, truth = ex["paths"], ex["truth"]
        assert paths.shape[0] == 21 and paths.shape[2:] == (2, 2)
        assert np.all(np.linalg.norm(paths[0].mean(axis=0) - truth, axis=1) > 1.5)
        assert np.all(np.linalg.norm(paths[-1].mean(axis=0) - truth, axis=1) < 0.5)
        links = ex["links"]
        off_a = 2 * links[:, 0]
        off_b = np.array([-1] * 4 + [2])
        anchor_pos = np.vstack([ex["anchors"][links[:4, 1]], [[0.0, 0.0]]])
        lambdas, steps = lambda_schedule(20)
        X1, _ = edh_flow(
            paths[0].reshape(-1, 4),
            ex["prior_mean"].reshape(-1),
            np.eye(4) * 2.5**2,
            lambda xb, a=off_a, b=off_b, p=anchor_pos: range_linearization(xb, a, b, p, 2),
            ex["ranges_m"],
            np.eye(5) * 0.01,
            lambdas,
            steps,
        )
        np.testing.assert_allclose(paths[-1].reshape(-1, 4), X1, rtol=1e-9, atol=1e-9)
    g, maps = ex["grid_m"], ex["anchor_loglik"]

    def at(agent, p):
        return maps[agent, np.argmin(np.abs(g - p[0])), np.argmin(np.abs(g - p[1]))]

    for agent, mirror in ((0, (4.0, -3.0)), (1, (10.83, 6.28))):
        assert abs(at(agent, truth[agent]) - at(agent, mirror)) < 1.0  # two equal modes
        assert at(agent, truth[agent]) - at(agent, (0.5 * 11, 11.0)) > 5.0  # and a valley


def test_method_runs_limits_one_method_and_leaves_the_others_alone():
    """``method_runs = { sirbp = 1 }`` in a 3-run recipe: SIR-BP's figures are those of a
    1-run recipe (task streams do not depend on the number of runs), with the bounds of that
    run; every other method's figures are those of the recipe without ``method_runs``."""
    base = TINY.replace("runs = 2", "runs = 3")
    limited = te.TRACKING.run(
        load_recipe(base.replace("runs = 3", "runs = 3\nmethod_runs = { sirbp = 1 }")),
        progress=False,
    )
    full = te.TRACKING.run(load_recipe(base), progress=False)
    one = te.TRACKING.run(load_recipe(TINY.replace("runs = 2", "runs = 1")), progress=False)
    f, g, h = limited["figures"], full["figures"], one["figures"]
    assert f["sirbp.s1.runs"] == 1 and f["pfbp.s1.runs"] == g["sirbp.s1.runs"] == 3
    assert limited["meta"]["method_runs"] == {"sirbp": 1}
    checked = 0
    for k, val in f.items():
        if is_timing(k) or not k.startswith(("sirbp.", "pfbp.", "spbp.", "edh.")):
            continue
        ref = h[k] if k.startswith("sirbp.") else g[k]
        assert val == pytest.approx(ref, rel=1e-12, nan_ok=True), k
        checked += 1
    assert checked > 40
    assert math.isnan(f["sirbp.s1.k3.rmse_p_m.ci_low"])  # one run: no interval
    # pfbp against sirbp over the one run both ran: the ratio of the 1-run recipe's figures
    for n in ("k3.rmse_p_m", "rmse_p_all_m"):
        assert f[f"pfbp_vs_sirbp.s1.{n}.ratio"] == pytest.approx(
            h[f"pfbp.s1.{n}"] / h[f"sirbp.s1.{n}"], rel=1e-12
        )
        assert f[f"pfbp_vs_spbp.s1.{n}.ratio"] == f[f"pfbp.s1.{n}"] / f[f"spbp.s1.{n}"]
    # the limited method's ratio uses the bound of its own run, not of all three
    assert f["sirbp.s1.k3.rmse_over_pcrlb_cond"] != pytest.approx(
        f["sirbp.s1.k3.rmse_p_m"] / f["pcrlb_cond.s1.k3.p_m"], rel=1e-9
    )


def _localizable_brute(anchors, heard, dim):
    """Reference: an agent is located by the anchors alone when some dim + 1 of the anchors it
    hears span the space (a nonzero simplex volume), found by trying every subset."""
    from itertools import combinations

    idx = np.flatnonzero(heard)
    for sub in combinations(idx, dim + 1):
        a = anchors[list(sub)]
        if abs(np.linalg.det(a[1:] - a[0])) > 1e-6:
            return True
    return False


def test_anchor_localizable_matches_a_subset_search():
    """:func:`anchor_localizable` against trying every (dim + 1)-subset of the heard anchors,
    on random hearing patterns over anchors that include a coplanar group (3-D) and a
    collinear group (2-D)."""
    from types import SimpleNamespace

    from phyloc.evaluation.range_scenarios import anchor_localizable

    rng = np.random.default_rng(20261127)
    for dim, anchors in (
        (3, np.array([[0, 0, 0], [20, 0, 0], [0, 20, 0], [20, 20, 0], [10, 10, 0], [5, 5, 20]])),
        (2, np.array([[0, 0], [10, 0], [20, 0], [30, 0], [15, 12]])),
    ):
        anchors = anchors.astype(float)
        K, n_agents = 30, 4
        heard = rng.random((K, n_agents, len(anchors))) < 0.7
        z = np.full((K, n_agents, n_agents + len(anchors)), np.nan)
        z[:, :, n_agents:] = np.where(heard, 5.0, np.nan)
        sc = SimpleNamespace(
            anchors=anchors, z=z, n_agents=n_agents, model=SimpleNamespace(dim=dim)
        )
        got = anchor_localizable(sc)
        ref = np.array(
            [
                [_localizable_brute(anchors, heard[k, i], dim) for i in range(n_agents)]
                for k in range(K)
            ]
        )
        assert got.shape == (K, n_agents)
        assert np.array_equal(got, ref)
        assert 0 < ref.mean() < 1  # both outcomes occur


def test_anchor_figures_count_the_stored_runs(tiny):
    """``s1.min_anchor_links`` is the fewest anchors any agent measured (the example run's
    series bounds it from above), and the localizable fraction lies in [0, 1] and is 0 where
    an agent hears fewer than dim + 1 anchors throughout."""
    f, ser = tiny["figures"], tiny["series"]
    example = np.asarray(ser["s1.example_anchor_links"])
    assert f["s1.min_anchor_links"] <= example.min()
    assert 0.0 <= f["s1.anchor_localizable_fraction"] <= 1.0
    if example.max() < 4:
        assert f["s1.anchor_localizable_fraction"] == 0.0


def test_a_number_as_a_method_name_is_a_one_line_error(tmp_path, capsys):
    """A fuzzer find: ``methods = [0]`` in a tracking recipe reached difflib's close-match
    search and ended in "internal error: TypeError: object of type 'int' has no len()"."""
    from phyloc.cli import main

    recipe = tmp_path / "r.toml"
    recipe.write_text(TINY.replace('methods = ["pfbp", "sirbp", "spbp", "edh"]', "methods = [0]"))
    assert main(["evaluate", str(recipe), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.splitlines() == [
        "phyloc: error: experiment.methods = 0 is not allowed: method names (non-empty strings)"
    ]

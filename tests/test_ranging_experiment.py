"""The ranging experiment (DiPNet Fig. 4): its pooled figures carry 95 % intervals over the
realizations, and their point values are the pooled figures of the links themselves."""

from __future__ import annotations

import math

import numpy as np
import pytest

from phyloc.config import load_recipe
from phyloc.evaluation.experiment import RunContext
from phyloc.evaluation.ranging_experiment import RANGING
from phyloc.evaluation.statistics import Pooled, interval, resolve

AGENTS = (4, 5)
REALIZATIONS = 2

RECIPE = f"""
kind = "ranging"
name = "ci"
seed = 5
[system]
n_subcarriers = 257
subcarrier_spacing_hz = 146.5e3
[network]
region_m = [60.0, 60.0]
[ranging]
methods = ["corr", "sage", "sage_los"]
[ranging.sage]
n_paths = 3
n_iter = 3
[experiment]
scenarios = {{ c2 = "winner2_c2", d1 = "winner2_d1" }}
agents = {list(AGENTS)}
realizations = {REALIZATIONS}
distance_bins_m = [0, 30, 60, 90]
awgn_snr_db = [20, 30]
awgn_links = 40
"""


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The experiment's own steps (tasks → aggregate → resolve), keeping the task results."""
    path = tmp_path_factory.mktemp("ranging") / "ci.toml"
    path.write_text(RECIPE)
    recipe = load_recipe(path)
    plan = RANGING.prepare(recipe)
    work = RANGING.tasks(plan)
    ctx = RunContext(recipe.seed, progress=False)
    results = ctx.run_tasks(RANGING.task, [p for _, p in work], desc="test")
    keys = [k for k, _ in work]
    figures, series = RANGING.aggregate(plan, keys, results, ctx)
    figures, series = resolve(figures, series, seed=ctx.seed)
    res = {"figures": figures, "series": series, "meta": RANGING.meta(plan, ctx)}
    res["meta"].update(recipe=recipe.name, fast=False)
    return keys, results, res


def _units(keys, results, tok):
    return [r for k, r in zip(keys, results, strict=True) if k[0] == tok]


def _rmse(x):
    x = np.asarray(x, float)
    return math.sqrt(np.mean(x**2)) if x.size else math.nan


@pytest.mark.parametrize("tok", ["c2", "d1"])
def test_pooled_figures_are_the_link_figures_with_an_interval(run, tok):
    keys, results, res = run
    f, s = res["figures"], res["series"]
    parts = _units(keys, results, tok)
    n_units = len(AGENTS) * REALIZATIONS
    assert len(parts) == n_units
    d = np.concatenate([p["distance_m"] for p in parts])
    los = np.concatenate([p["los"] for p in parts])
    # the LOS fraction: the share of LOS links, its units the links of each network
    name = f"{tok}.los_fraction"
    assert f[name] == los.mean()
    u = s[name + ".units"]
    assert u["kind"] == "fraction" and len(u["den"]) == n_units
    links = [n * (n - 1) for n in AGENTS for _ in range(REALIZATIONS)]  # fully meshed, directed
    assert list(u["den"]) == links
    assert 0.0 <= f[name + ".ci_low"] <= f[name] <= f[name + ".ci_high"] <= 1.0
    for m in ("corr", "sage", "sage_los"):
        err = np.concatenate([p[f"{m}.range_m"] for p in parts]) - d
        valid = np.concatenate([p[f"{m}.valid"] for p in parts])
        for fig, sel in (("rmse_m", valid), ("rmse_los_m", valid & los)):
            name = f"{m}.{tok}.{fig}"
            # the point value: the RMSE over the links (pooled in another order: to rounding)
            assert f[name] == pytest.approx(_rmse(err[sel]), rel=1e-13)
            u = s[name + ".units"]
            assert u["kind"] == "rmse" and len(u["num"]) == n_units
            m_sel = [
                (p[f"{m}.range_m"] - p["distance_m"])[
                    p[f"{m}.valid"] & (p["los"] if fig == "rmse_los_m" else True)
                ]
                for p in parts
            ]
            assert list(u["den"]) == [x.size for x in m_sel]
            assert np.allclose(u["num"], [np.sum(x**2) for x in m_sel], rtol=1e-13, atol=0)
            # summed in ascending order, as every pooled figure (order-free: same bits for any
            # order of the units)
            assert f[name] == math.sqrt(np.sum(np.sort(u["num"])) / np.sum(np.sort(u["den"])))
            lo, hi = f[name + ".ci_low"], f[name + ".ci_high"]
            assert np.isfinite(lo) and np.isfinite(hi) and lo <= f[name] <= hi
        name = f"{m}.{tok}.valid_fraction"
        assert f[name] == valid.mean()  # integer counts: exact
        assert list(s[name + ".units"]["den"]) == links
        assert f[name + ".ci_low"] <= f[name] <= f[name + ".ci_high"]


@pytest.mark.parametrize("tok", ["c2", "d1"])
def test_paired_ratios_are_the_ratios_of_the_figures(run, tok):
    f = run[2]["figures"]
    for a, b in (("corr", "sage"), ("corr", "sage_los"), ("sage", "sage_los")):
        name = f"{a}_vs_{b}.{tok}.rmse_m.ratio"
        assert f[name] == f[f"{a}.{tok}.rmse_m"] / f[f"{b}.{tok}.rmse_m"]
        lo, hi = f[name + ".ci_low"], f[name + ".ci_high"]
        assert np.isfinite(lo) and lo <= hi
    assert f"sage_vs_corr.{tok}.rmse_m.ratio" not in f  # every pair once, in method order
    for m in ("corr", "sage", "sage_los"):
        # RMSE over √ZZB of the same links: the plain figure, now with a paired interval
        name = f"{m}_vs_zzb.{tok}.rmse_m.ratio"
        assert f[name] == pytest.approx(f[f"{m}.{tok}.rmse_over_zzb"], rel=1e-13)
        assert np.isfinite(f[name + ".ci_low"]) and f[name + ".ci_low"] <= f[name + ".ci_high"]


def test_bounds_and_single_task_figures_stay_plain(run):
    f, s = run[2]["figures"], run[2]["series"]
    plain = [
        "crb.c2.rmse_m",
        "zzb.c2.rmse_m",
        "c2.n_links",
        "corr.c2.rmse_over_zzb",
        "corr.awgn.crb_ratio_20db",
        "corr.awgn.crb_ratio_30db",
        "corr.awgn.threshold_snr_db",
    ]
    for name in plain:
        assert name in f and name + ".ci_low" not in f and name + ".units" not in s
    # the pooled figures and the paired ratios are all there is with an interval
    with_ci = {k.removesuffix(".ci_low") for k in f if k.endswith(".ci_low")}
    assert all(k + ".units" in s or k.endswith(".ratio") for k in with_ci)
    assert len(with_ci) == 2 * (1 + 3 * 4 + 3 + 3)  # per token: LOS, 4 per method, ratios


def test_distance_bins_carry_intervals_over_the_realizations(run):
    keys, results, res = run
    s = res["series"]
    edges = np.array([0, 30, 60, 90.0])
    parts = _units(keys, results, "c2")
    name = "sage.c2.rmse_by_distance_m"
    lo, hi = np.asarray(s[name + ".ci_low"]), np.asarray(s[name + ".ci_high"])
    y = np.asarray(s[name])
    assert lo.shape == hi.shape == y.shape == (edges.size - 1,)
    ok = np.isfinite(lo)
    assert ok.any() and np.all(lo[ok] <= hi[ok])
    # one bin from scratch: per unit the squared errors of the valid links in that bin
    j = int(np.flatnonzero(ok)[0])
    num, den = [], []
    for p in parts:
        b = np.digitize(p["distance_m"], edges) - 1
        sel = p["sage.valid"] & (b == j)
        # added in link order, as the code's np.bincount does (np.sum adds pairwise, which can
        # differ in the last bit, by the CPU's SIMD width)
        num.append(float(sum((p["sage.range_m"] - p["distance_m"])[sel] ** 2)))
        den.append(sel.sum())
    assert y[j] == pytest.approx(math.sqrt(sum(num) / sum(den)), rel=1e-13)
    assert (lo[j], hi[j]) == interval(Pooled(num, den, "rmse"), seed=5, name=f"{name}[{j}]")


def test_table_and_plot_show_the_intervals(run, tmp_path):
    res = run[2]
    rows = RANGING.summary_rows(res)
    assert len(rows) == 2 * (3 + 2)
    corr = next(r for r in rows if r[:2] == ("c2", "corr"))
    lo, hi = res["figures"]["corr.c2.rmse_m.ci_low"], res["figures"]["corr.c2.rmse_m.ci_high"]
    assert corr[2] == f"{res['figures']['corr.c2.rmse_m']:.3g} [{lo:.3g}, {hi:.3g}]"
    lines = RANGING.summary_lines(res)
    assert any(line.startswith("c2: RMSE ratios") and "corr/sage" in line for line in lines)
    png = tmp_path / "r.png"
    RANGING.plot(res, png)
    assert png.stat().st_size > 10_000

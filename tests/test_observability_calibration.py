"""The localization experiment's observability rule and NEES calibration figures."""

import math
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from phyloc.config import load_recipe
from phyloc.evaluation import front_end
from phyloc.evaluation import localization_experiment as lx


def _net(pos, is_anchor):
    pos = np.asarray(pos, dtype=np.float64)
    return SimpleNamespace(
        positions=pos[None], is_anchor=np.asarray(is_anchor), n_nodes=len(pos), dim=pos.shape[1]
    )


def test_three_agents_with_one_silent_pair_leave_its_distance_out():
    """The 3-agent C2 failure: the pair with no detected link (either direction) flexes."""
    net = _net([[0.0, 0.0], [50.0, 0.0], [20.0, 40.0]], [False] * 3)
    links = np.array([[0, 1], [1, 0], [0, 2], [2, 0], [1, 2], [2, 1]])
    detected = np.array([True, False, False, False, False, True])  # 0-1 and 1-2 only
    obs = front_end.observable_pairs(net, 0, links, detected, np.random.default_rng(0))
    # pairs in framework_distance_errors order: (0,1) (0,2) (1,0) (1,2) (2,0) (2,1)
    assert obs.tolist() == [True, False, True, True, False, True]
    every = front_end.observable_pairs(net, 0, links, np.ones(6, bool), np.random.default_rng(0))
    assert every.all()


def test_nees_is_the_closed_form_with_anchors_and_averages_dim():
    """Anchors fix the frame (no alignment residual): NEES = eᵀP⁻¹e exactly, and errors drawn
    from P give a mean NEES of dim (a calibrated belief)."""
    rng = np.random.default_rng(8)
    n_ag = 4000
    anchors = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 100.0], [100.0, 100.0]])
    truth = np.vstack([rng.uniform(0, 100, (n_ag, 2)), anchors])
    is_anchor = np.r_[np.zeros(n_ag, bool), np.ones(4, bool)]
    A = rng.normal(0, 1.0, (n_ag, 2, 2))
    P = A @ A.transpose(0, 2, 1) + 0.1 * np.eye(2)
    e = np.einsum("nij,nj->ni", np.linalg.cholesky(P), rng.standard_normal((n_ag, 2)))
    est = truth.copy()
    est[:n_ag] += e
    got = front_end._nees(est, P, truth, is_anchor)
    want = np.einsum("ni,ni->n", e, np.linalg.solve(P, e[..., None])[..., 0])
    np.testing.assert_allclose(got, want, rtol=1e-9)
    assert abs(got.mean() - 2.0) < 4 * 2.0 / np.sqrt(n_ag)  # χ²₂: mean 2, std 2


def test_nees_is_invariant_to_the_anchor_free_gauge_and_survives_singular_beliefs():
    """Rotating and shifting an anchor-free estimate (and its covariances) leaves the NEES
    unchanged; a singular covariance gives NaN, not inf."""
    rng = np.random.default_rng(2)
    truth = rng.uniform(0, 50, (6, 2))
    est = truth + rng.normal(0, 1.0, (6, 2))
    P = np.repeat(np.eye(2)[None] * 0.5, 6, axis=0)
    P[1] = np.diag([2.0, 0.3])
    th = 0.7
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    moved = est @ R.T + np.array([30.0, -12.0])
    free = np.zeros(6, bool)
    a = front_end._nees(est, P, truth, free)
    b = front_end._nees(moved, R @ P @ R.T, truth, free)
    np.testing.assert_allclose(a, b, rtol=1e-9)
    P[2] = 0.0
    P[3] = np.nan  # a method that publishes no covariance for one agent
    P[4] = [[1e-300, 0.0], [0.0, 1e-300]]  # near-singular: a huge, finite NEES
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        c = front_end._nees(est, P, truth, free)
    assert np.all(np.isnan(c[2:4])) and np.all(np.isfinite(np.delete(c, [2, 3])))
    assert c[4] > 1e250
    assert np.all(np.isnan(front_end._nees(est, None, truth, free)))


def test_truth_free_start_keys_are_validated():
    import pytest

    from phyloc.errors import ValidationError

    spec = lx.LocalizationSpec.from_dict({"init_robust_scale_m": 0.0, "init_pair_range": "mean"})
    assert spec.init_robust_scale_m == (0.0,) and spec.options == {}  # not a method option
    assert lx.LocalizationSpec().init_pair_range == "min"
    with pytest.raises(ValidationError, match="init_pair_range"):
        lx.LocalizationSpec.from_dict({"init_pair_range": "median"})
    with pytest.raises(ValidationError, match="init_robust_scale_m"):
        lx.LocalizationSpec.from_dict({"init_robust_scale_m": -2.0})


INFORMED_ONLY = """
kind = "localization"
name = "informed_only"
seed = 3
[system]
n_subcarriers = 257
subcarrier_spacing_hz = 146.5e3
tx_power_dbm = -40.0
[network]
region_m = [80.0, 80.0]
[ranging]
window_m = [0.0, 200.0]
[localization]
n_particles = 100
n_iterations = 2
[experiment]
scenarios = { c2 = "winner2_c2" }
agents = [4]
realizations = 2
methods = ["corr"]
inits = ["informed"]
cdf_agents = [4]
"""


def test_an_informed_only_run_reports_and_plots_its_own_rows(tmp_path, monkeypatch):
    """Without a truth-free start, the unobservable-pair line and the CDF panel read the
    informed rows (they used to look up truth-free keys: a KeyError and an empty panel)."""
    from phyloc.config import load_recipe

    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    res = lx.LOCALIZATION.run(load_recipe(INFORMED_ONLY), progress=False)
    frac = res["figures"]["c2.agents_4.unobservable_pair_fraction"]
    assert frac > 0  # at −40 dBm some pairs have no detected link
    lines = lx.summary_lines(res)
    unobs = [ln for ln in lines if "unobservable" in ln]
    assert len(unobs) == 1 and unobs[0].startswith("c2_informed, 4 agents")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. "No artists with labels found to put in legend"
        lx.plot(res, tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 0


def test_a_warning_names_exactly_the_methods_whose_beliefs_are_off(monkeypatch):
    """The summary warns for a method at the largest size exactly when its error/belief ratio
    (from the median) leaves [0.67, 1.5], and says which key to set when beliefs are too
    narrow; checked on a run, and on the same figures with the ratios moved in and out."""
    from phyloc.config import load_recipe

    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    res = lx.LOCALIZATION.run(load_recipe(INFORMED_ONLY), progress=False)
    f = res["figures"]
    key = "corr.c2_informed.agents_4.error_to_belief_ratio_median"
    for ratio, warned in ((4.0, True), (1.0, False), (0.3, True), (1.49, False)):
        f[key] = ratio
        lines = [ln for ln in lx.summary_lines(res) if ln.startswith("warning: corr")]
        assert bool(lines) == warned, ratio
        if ratio > 1.5:
            assert "model_error_m" in lines[0]


def test_a_single_size_run_draws_points_and_fitted_cdfs(monkeypatch):
    """One network size: the RMSE panel has the start and every method along its x axis, each
    a point with its interval (no line over one size), and the CDF panel's x axis ends a
    little beyond where the CDFs reach 0.99, not at the end of the error grid."""
    from phyloc.config import load_recipe
    from phyloc.evaluation import localization_figures as lf

    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    res = lx.LOCALIZATION.run(load_recipe(INFORMED_ONLY), progress=False)
    drawn = {}
    monkeypatch.setattr(lf, "save_figure", lambda fig, path: drawn.setdefault("fig", fig))
    lf.plot(res, "unused.png")
    rmse_ax, cdf_ax = drawn["fig"].axes[0], drawn["fig"].axes[2]
    labels = [t.get_text() for t in rmse_ax.get_xticklabels()]
    assert labels == ["start\n(centralized)", *res["meta"]["methods"]]
    assert not any(
        len(line.get_xdata()) > 1
        for line in rmse_ax.get_lines()
        if line.get_marker() in ("o", "*") and line.get_linestyle() != "None"
    )
    grid = np.asarray(res["series"]["cdf_grid_m"])
    right = cdf_ax.get_xlim()[1]
    cdf = np.asarray(res["series"]["corr.c2_informed.agents_4.error_cdf"])
    above = np.flatnonzero(cdf >= 0.99)
    reach = grid[above[0]] if above.size else grid[-1]
    assert right == pytest.approx(1.15 * reach)


WITH_ANCHORS = (
    INFORMED_ONLY.replace("tx_power_dbm = -40.0", "tx_power_dbm = 0.0")
    .replace("region_m = [80.0, 80.0]", "region_m = [80.0, 80.0]\nanchors = 4")
    .replace('inits = ["informed"]', 'inits = ["truth_free"]')
)


def test_with_anchors_absolute_position_errors_and_a_map(tmp_path, monkeypatch):
    """A network with anchors (its frame then absolute) reports the absolute position RMSE
    of every method and the start, equal to the RMS of the stored per-agent errors, prints
    it, and draws the map figure beside the main one; an anchor-free run has none of it."""
    import json

    from phyloc.cli import main

    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    recipe = tmp_path / "a.toml"
    recipe.write_text(WITH_ANCHORS)
    assert main(["evaluate", str(recipe), "--out", str(tmp_path / "o")]) == 0
    doc = json.loads((tmp_path / "o" / "results.json").read_text())
    f, ser = doc["figures"], doc["series"]
    for m in ("start", "corr"):
        name = f"{m}.c2.agents_4.position_rmse_m"
        u = ser[name + ".units"]
        assert f[name] == pytest.approx(math.sqrt(sum(u["num"]) / sum(u["den"])), rel=1e-12)
        assert sum(u["den"]) == 2 * 4  # 2 realizations x 4 agents, one snapshot
    est = np.asarray(ser["corr.c2.agents_4.map_estimates"])
    truth = np.asarray(ser["c2.agents_4.map_truth"])
    anchor = np.asarray(ser["c2.agents_4.map_is_anchor"], bool)
    assert est.shape == (4, 2) and truth.shape == (8, 2) and anchor.sum() == 4
    (png,) = (tmp_path / "o").glob(f"{doc['meta']['recipe']}_map.png")
    assert png.stat().st_size > 1000
    plain = lx.LOCALIZATION.run(
        load_recipe(WITH_ANCHORS.replace("\nanchors = 4", "")), progress=False
    )
    assert not any("position_rmse" in k for k in plain["figures"])

"""The ``kind = "direct_tracking"`` experiment (DiPNet §V-B, Figs. 6–7): figure names, the
statistics' mutual consistency, the replica recipe's geometry, seeds and recipe errors."""

import math
from pathlib import Path

import numpy as np
import pytest

from phyloc.config import load_recipe
from phyloc.errors import ValidationError
from phyloc.evaluation import direct_tracking_experiment as dt
from phyloc.evaluation.experiment import experiment_from_dict
from phyloc.network import make_network, pentagon
from phyloc.reporting import is_measurement

DATASETS = Path(__file__).resolve().parents[1] / "datasets"

TINY = """
kind = "direct_tracking"
name = "tiny_rover"
seed = 11

[system]
n_subcarriers = 257
subcarrier_spacing_hz = 146.5e3
carrier_frequency_hz = 5.5e9
tx_power_dbm = 20.0

[network]
n_agents = 4
region_m = [40.0, 40.0]

[network.motion]
model = "waypoints"
movers = [3]
dt_s = 1.0

[channel]
scenario = "awgn"
ranging = "two_way"
backward_carrier_frequency_hz = 5.7e9

[ranging]
window_m = [0.0, 200.0]

[localization]
n_particles = 300
n_iterations = 3
prior_std_m = 3.0
process_std_m = 1.0

[localization.dpe_sampled]
n_particles = 40

[localization.corr2]
method = "corr"
n_particles = 100

[experiment]
methods = ["dipnet", "dpe_sampled", "corr2"]
particles_snapshot = 2
max_snapshots = 9

[experiment.runs.a.network]
agents_m = [[10.0, 10.0], [20.0, 10.0], [15.0, 18.0], [5.0, 25.0]]
[experiment.runs.a.network.motion]
n_snapshots = 5
waypoints_m = [[5.0, 25.0], [30.0, 25.0]]
speeds_m_s = [1.0]

[experiment.runs.b.network]
agents_m = [[10.0, 10.0], [20.0, 10.0], [15.0, 18.0], [5.0, 25.0]]
[experiment.runs.b.network.motion]
n_snapshots = 4
waypoints_m = [[5.0, 25.0], [6.5, 25.0], [6.5, 35.0]]
speeds_m_s = [1.0, 3.0]
"""

METHODS = ("dipnet", "dpe_sampled", "corr2")


@pytest.fixture(scope="module")
def tiny():
    return dt.DIRECT_TRACKING.run(load_recipe(TINY), progress=False)


@pytest.fixture(scope="module")
def two_realizations():
    """Run b alone (slow and fast snapshots), two realizations."""
    head = TINY[: TINY.index("[experiment.runs.a.network]")]
    tail = TINY[TINY.index("[experiment.runs.b.network]") :]
    recipe = head.replace("particles_snapshot = 2", "particles_snapshot = 2\nrealizations = 2")
    return dt.DIRECT_TRACKING.run(load_recipe(recipe + tail), progress=False)


def test_pooled_figures_have_intervals_and_one_value_per_realization(two_realizations, tmp_path):
    """Every figure pooled over realizations: a finite 95 % interval around it, one numerator
    and denominator per realization, the figure recomputed from them by hand. Per
    realization, the slow and fast segments' squared per-snapshot RMSEs add up to its
    squared errors over every snapshot (equal pairs per snapshot), and the outlier share
    counts whole errors."""
    res = two_realizations
    f, ser = res["figures"], res["series"]
    T = res["meta"]["n_snapshots"]["b"]
    names = [n.removesuffix(".units") for n in ser if n.endswith(".units")]
    what = ("rmse_m", "rmse_slow_m", "rmse_fast_m", "errors_over_2m_pct")
    assert sorted(names) == sorted(f"{m}.b.{w}" for m in METHODS for w in what)
    for n in names:
        u = ser[n + ".units"]
        num, den = [float(x) for x in u["num"]], [float(x) for x in u["den"]]
        assert len(num) == len(den) == 2, n
        ref = sum(num) / sum(den)
        assert f[n] == pytest.approx(math.sqrt(ref) if u["kind"] == "rmse" else ref, rel=1e-12)
        lo, hi = f[n + ".ci_low"], f[n + ".ci_high"]
        assert math.isfinite(lo) and math.isfinite(hi), n
        assert lo <= f[n] * (1 + 1e-12) and f[n] <= hi * (1 + 1e-12), n
    for m in METHODS:
        b = f"{m}.b"
        full, slow, fast = (ser[f"{b}.{w}.units"] for w in what[:3])
        np.testing.assert_array_equal(np.add(slow["den"], fast["den"]), [T, T])
        pairs = np.asarray(full["den"]) / T  # framework pairs per snapshot
        np.testing.assert_allclose(
            pairs * (np.asarray(slow["num"]) + np.asarray(fast["num"])), full["num"], rtol=1e-9
        )
        out = ser[f"{b}.errors_over_2m_pct.units"]
        assert out["kind"] == "mean" and list(out["den"]) == list(full["den"])
        assert all(x % 100 == 0 for x in out["num"])  # 100 per error above 2 m
    dt.plot(res, tmp_path / "r.png")
    assert (tmp_path / "r.png").stat().st_size > 10_000


def test_first_method_over_the_others_on_the_same_realizations(two_realizations):
    """``dipnet_vs_<m>.b.*.ratio``: the ratio of the two written figures, a paired interval
    around it, for the RMSE over all snapshots and over each segment; the table shows the
    intervals and a line the ratios."""
    f = two_realizations["figures"]
    ratios = sorted(n for n in f if n.endswith(".ratio"))
    what = ("rmse_m", "rmse_slow_m", "rmse_fast_m")
    assert ratios == sorted(f"dipnet_vs_{m}.b.{w}.ratio" for m in METHODS[1:] for w in what)
    for m in METHODS[1:]:
        for w in what:
            r = f"dipnet_vs_{m}.b.{w}.ratio"
            assert f[r] == f[f"dipnet.b.{w}"] / f[f"{m}.b.{w}"]
            lo, hi = f[r + ".ci_low"], f[r + ".ci_high"]
            assert math.isfinite(lo) and lo <= f[r] * (1 + 1e-12) and f[r] <= hi * (1 + 1e-12)
    rows = dt.summary_rows(two_realizations)
    assert all(isinstance(c, str) and "[" in c for c in rows[0][4:7])
    lines = dt.summary_lines(two_realizations)
    assert any(line.startswith("b: RMSE dipnet / other") for line in lines)


def test_every_documented_figure_and_series(tiny):
    f, ser, meta = tiny["figures"], tiny["series"], tiny["meta"]
    assert meta["runs"] == ["a", "b"] and meta["methods"] == list(METHODS)
    assert meta["n_particles"] == {"dipnet": 300, "dpe_sampled": 40, "corr2": 100}
    assert meta["n_snapshots"] == {"a": 5, "b": 4}
    for r, T in (("a", 5), ("b", 4)):
        assert np.asarray(ser[f"{r}.true_track"]).shape == (T, 4, 2)
        for m in METHODS:
            b = f"{m}.{r}"
            for what in ("median_error_m", "p90_error_m", "errors_over_2m_pct", "agent_snapshot_s"):
                assert np.isfinite(f[f"{b}.{what}"]), b + what
            assert np.asarray(ser[b + ".rmse_by_snapshot"]).shape == (T,)
            # pictures: tracks of the first run (Fig. 6 c, d), DiPNet's particles of the last
            assert (b + ".track" in ser) == (r == "a")
            assert (b + ".particles" in ser) == (b == "dipnet.b")
    assert np.asarray(ser["dipnet.a.track"]).shape == (5, 4, 2)
    assert np.asarray(ser["dipnet.b.particles"]).shape == (4, dt.PARTICLES_SHOWN, 2)


def test_statistics_agree_with_each_other(tiny):
    f, ser = tiny["figures"], tiny["series"]
    grid = np.asarray(ser["cdf_grid_m"])
    for r in ("a", "b"):
        for m in METHODS:
            b = f"{m}.{r}"
            cdf = np.asarray(ser[b + ".error_cdf"])
            assert np.all(np.diff(cdf) >= 0) and 0 <= cdf[0] and cdf[-1] <= 1
            assert f[b + ".median_error_m"] <= f[b + ".p90_error_m"]
            # the outlier share is 1 − CDF(2 m)
            at2 = cdf[np.searchsorted(grid, 2.0)]
            assert f[b + ".errors_over_2m_pct"] == pytest.approx(100 * (1 - at2), abs=1e-9)
            # pooled RMSE = RMS of the per-snapshot RMSEs (equal pairs per snapshot)
            per_t = np.asarray(ser[b + ".rmse_by_snapshot"])
            assert f[b + ".rmse_m"] == pytest.approx(math.sqrt(np.mean(per_t**2)), rel=1e-9)


def test_fast_segment_is_where_the_rover_exceeds_the_speed(tiny):
    f = tiny["figures"]
    assert f["a.fast_snapshots"] == 0  # 1 m/s throughout
    assert math.isnan(f["dipnet.a.rmse_fast_m"])
    assert "dipnet_vs_corr2.a.rmse_fast_m.ratio" not in f  # no fast snapshot: no comparison
    assert math.isnan(f["dipnet.a.rmse_m.ci_low"])  # one realization: no interval
    # run b: 1 m/s on a 1.5 m leg, then 3 m/s: snapshots at 2 s and 3 s are on the fast leg
    assert f["b.fast_snapshots"] == 2
    for m in METHODS:
        assert np.isfinite(f[f"{m}.b.rmse_fast_m"]) and np.isfinite(f[f"{m}.b.rmse_slow_m"])
        # the pooled RMSE lies between the two segments' RMSEs
        lo, hi = sorted((f[f"{m}.b.rmse_fast_m"], f[f"{m}.b.rmse_slow_m"]))
        assert lo - 1e-12 <= f[f"{m}.b.rmse_m"] <= hi + 1e-12


def test_tracks_are_rigidly_aligned_estimates(tiny):
    """The alignment is rigid: the framework errors (DiPNet eq. (4)) of the aligned track are
    the filter's own, i.e. its per-snapshot RMSE (one realization), and it is optimal: no
    translation of it fits the truth better."""
    ser = tiny["series"]
    true = np.asarray(ser["a.true_track"])
    for m in METHODS:
        track = np.asarray(ser[f"{m}.a.track"])
        per_t = np.asarray(ser[f"{m}.a.rmse_by_snapshot"])
        off = ~np.eye(4, dtype=bool)
        for t in range(true.shape[0]):
            d_track = np.linalg.norm(track[t][:, None] - track[t][None], axis=-1)
            d_true = np.linalg.norm(true[t][:, None] - true[t][None], axis=-1)
            rms = math.sqrt(np.mean((d_track - d_true)[off] ** 2))
            # (tracks are stored rounded to 1 mm: distances move by at most √2 mm)
            assert rms == pytest.approx(per_t[t], abs=1.5e-3)
            # optimal translation: the aligned centroid is the true centroid
            np.testing.assert_allclose(track[t].mean(0), true[t].mean(0), atol=1e-3)


def test_same_seed_same_numbers_on_two_workers(tiny):
    two = dt.DIRECT_TRACKING.run(load_recipe(TINY), workers=2, progress=False)
    for k, v in tiny["figures"].items():
        if not is_measurement(k):
            assert two["figures"][k] == v or (math.isnan(v) and math.isnan(two["figures"][k])), k


def test_replica_recipe_geometry():
    """The replica: pentagons of 15 m and 30 m, 260 and 330 snapshots, the fast zig-zag of
    experiment 2 from snapshot ≈ 250 to the end."""
    recipe = load_recipe(DATASETS / "dipnet_fig7_rover.toml")
    exp = experiment_from_dict(dt.DirectTrackingExperimentSpec, recipe.section("experiment"))
    nets = exp.networks(dict(recipe.section("network")))
    for name, diameter, T in (("exp1", 15.0, 260), ("exp2", 30.0, 330)):
        net = make_network(nets[name], np.random.default_rng(0))
        assert net.positions.shape == (T, 6, 2)
        np.testing.assert_allclose(
            net.positions[:, :5],
            np.broadcast_to(pentagon(diameter, [25.0, 40.0]), (T, 5, 2)),
            atol=1e-3,
        )
        speed = np.linalg.norm(net.velocities[:, 5], axis=1)
        fast = np.flatnonzero(speed > exp.fast_speed_m_s)
        if name == "exp1":
            assert fast.size == 0
        else:
            assert 245 <= fast[0] <= 255 and fast.size >= 70
        assert np.all((net.positions[..., 0] >= 0) & (net.positions[..., 0] <= 50))
        assert np.all((net.positions[..., 1] >= 0) & (net.positions[..., 1] <= 80))
    plan = exp.plan(recipe.section("localization", dt.LocalizationSpec))
    q = {m: o.dpf.n_particles for m, (_, o) in plan.items()}
    assert q["dipnet"] == q["sage_parametric"] == 7157
    assert q["dpe_sampled"] == q["sage_sampled"] == 100 and q["dpe_sampled_x4"] == 400


@pytest.mark.parametrize(
    "edit, key",
    [
        (("methods = [", 'methods = ["nope", '), "experiment.methods"),
        (('method = "corr"', 'method = "nbp"'), "localization.corr2.method"),
        (("[localization.corr2]", "[experiment.variants.corr2]"), "experiment.variants"),
        (("[experiment.runs.a.network]", "[experiment.runs.a.net]"), "experiment.runs.a"),
        (("speeds_m_s = [1.0]", "speeds_m_s = [-1.0]"), "speeds_m_s"),
        (
            (
                TINY[TINY.index("[experiment.runs.b.network]") :],
                "[experiment.runs.b]\nnetwork = nan\n",
            ),
            "experiment.runs.b.network",
        ),
        (
            (
                TINY[TINY.index("[experiment.runs.b.network.motion]") :],
                "motion = 2.0\n",
            ),
            "experiment.runs.b: network.motion",
        ),
        (("n_snapshots = 4", 'n_snapshots = "four"'), "n_snapshots"),
    ],
)
def test_bad_recipe_keys_fail_before_any_work(monkeypatch, edit, key):
    import phyloc.evaluation.experiment as runner

    monkeypatch.setattr(runner, "run_tasks", lambda *a, **k: pytest.fail("work started"))
    with pytest.raises(ValidationError, match=key):
        dt.DIRECT_TRACKING.run(load_recipe(TINY.replace(*edit)), progress=False)

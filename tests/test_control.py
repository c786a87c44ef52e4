"""Fisher-information control of mobile anchors (phyloc.control): known answers, brute force,
twins, edge cases, and the experiment's reproducibility."""

from __future__ import annotations

import math

import numpy as np
import pytest
from naive_control import brute_force, level_numpy, sequence_cost

from phyloc.config import load_recipe
from phyloc.control import (
    ControlProblem,
    ControlScenario,
    PolicySpec,
    control_set,
    decide,
    draw_trial,
    make_estimator,
    position_cost,
    range_information,
    realized_network,
    run_policy,
    search,
)
from phyloc.control._kernels import level_kernel, predict_kernel
from phyloc.errors import ValidationError
from phyloc.evaluation import control_experiment as ce
from phyloc.localization.tracking import (
    GaussianPrior,
    RangeMeasurements,
    RangeModel,
    SPBPOptions,
    run_spbp,
)
from phyloc.localization.tracking.spbp import SPBPTracker

DATASETS = __import__("pathlib").Path(__file__).resolve().parents[1] / "datasets"


def _static_problem(mean, P, mobile, static, U, sigma=1.0, **kw):
    """A problem with static agents (F = I, Q = 0) in the dimension of ``mean``."""
    d = mean.shape[1]
    return ControlProblem(
        np.asarray(mean, float),
        np.asarray(P, float),
        np.eye(d),
        np.zeros((d, d)),
        np.asarray(mobile, float).reshape(-1, d),
        np.asarray(static, float).reshape(-1, d),
        np.asarray(U, float),
        1.0,
        sigma,
        **kw,
    )


# -- the cost ----------------------------------------------------------------------------------
def test_cost_equals_hand_computation_and_orthogonal_directions_lower_it():
    """Agent at the origin, P = I, σ = 1, anchors at (3, 4) and (−5, 0):
    J = [[2.36, 0.48], [0.48, 1.64]], det 3.64, tr J⁻¹ = 4/3.64. With the first anchor at
    (0, 5) the directions are orthogonal: J = 2I, cost 1."""
    P = np.eye(2)[None]
    agent = np.zeros((1, 2))
    c = position_cost(P, agent, np.array([[3.0, 4.0], [-5.0, 0.0]]), 1.0)
    assert c == pytest.approx(4.0 / 3.64, rel=1e-14)
    c_orth = position_cost(P, agent, np.array([[0.0, 5.0], [-5.0, 0.0]]), 1.0)
    assert c_orth == pytest.approx(1.0, rel=1e-14)
    assert c_orth < c


def test_cost_ignores_coincident_and_out_of_range_nodes_without_nan():
    P = np.diag([4.0, 9.0])[None]
    agent = np.array([[1.0, 2.0]])
    A = range_information(agent, agent.copy(), 0.1)
    assert np.all(A == 0.0)
    c = position_cost(P, agent, np.array([[1.0, 2.0], [500.0, 0.0]]), 0.1, comm_range_m=100.0)
    assert c == pytest.approx(13.0)  # the prior alone


def test_kernel_equals_numpy_twin():
    rng = np.random.default_rng(4)
    m = RangeModel("constant_velocity", 3, dt_s=1.0, accel_std=0.05, planar=True)
    F, Q = m.matrices()
    n, nd, N, M1 = 3, m.state_dim, 50, 2
    L = rng.standard_normal((N, n, nd, nd))
    covs = L @ np.swapaxes(L, -1, -2) + np.eye(nd)
    means = rng.uniform(-50, 50, (n, 3))
    pos = rng.uniform(-50, 50, (N, M1, 3))
    pos[0, 0] = means[0]  # a coincident node
    sinfo = range_information(means, rng.uniform(-50, 50, (1, 3)), 0.3)
    pred = np.empty_like(covs)
    predict_kernel(covs, F, Q, pred)
    np.testing.assert_allclose(pred, F @ covs @ F.T + Q, rtol=1e-12)
    for comm in (None, 60.0):
        out = np.empty_like(covs)
        cost = np.empty(N)
        level_kernel(pred, 1, means, pos, sinfo, 1 / 0.09, comm or 0.0, True, out, cost)
        ref_c, ref_cost = level_numpy(covs, F, Q, means, pos, sinfo, 0.3, comm)
        np.testing.assert_allclose(out, ref_c, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(cost, ref_cost, rtol=1e-12)
        assert np.all(np.isfinite(out))
        # the cost alone (a search's last level): the same bits as with the covariances
        alone = np.empty(N)
        level_kernel(pred, 1, means, pos, sinfo, 1 / 0.09, comm or 0.0, False, out[:1], alone)
        np.testing.assert_array_equal(alone, cost)


def test_children_share_their_parents_prediction():
    """``level(parents, positions, reps=r)`` gives exactly the bits of the same level on the
    parents repeated r times (the tree search's children), and the cost alone is the same."""
    rng = np.random.default_rng(11)
    problem = _cv_problem(rng, n_agents=2, M1=2)
    T = 2
    means = problem.predicted_means(T)
    sinfo = problem.static_information(means)
    L = rng.standard_normal((4, 2, 4, 4))
    parents = L @ np.swapaxes(L, -1, -2) + np.eye(4)
    r = 7
    pos = rng.uniform(-30, 30, (4 * r, 2, 2))
    covs, cost = problem.level(parents, pos, 1, means, sinfo, reps=r)
    ref_covs, ref_cost = problem.level(np.repeat(parents, r, axis=0), pos, 1, means, sinfo)
    np.testing.assert_array_equal(covs, ref_covs)
    np.testing.assert_array_equal(cost, ref_cost)
    none, alone = problem.level(parents, pos, 1, means, sinfo, reps=r, want_covs=False)
    assert none is None
    np.testing.assert_array_equal(alone, ref_cost)
    with pytest.raises(ValidationError, match="parents x"):
        problem.level(parents, pos[:-1], 1, means, sinfo, reps=r)


# -- searches ----------------------------------------------------------------------------------
def _cv_problem(rng, n_agents=2, M1=2, U=None, **kw):
    m = RangeModel("constant_velocity", 2, dt_s=1.0, accel_std=0.1)
    F, Q = m.matrices()
    mean = np.c_[rng.uniform(-20, 20, (n_agents, 2)), rng.normal(0, 0.3, (n_agents, 2))]
    P = np.repeat(np.diag([30.0, 20.0, 0.1, 0.1])[None], n_agents, axis=0)
    U = control_set(2.0, 6, ()) if U is None else U
    return ControlProblem(
        mean,
        P,
        F,
        Q,
        rng.uniform(-20, 20, (M1, 2)),
        rng.uniform(-20, 20, (1, 2)),
        U,
        3.0,
        1.0,
        **kw,
    )


@pytest.mark.parametrize("agent_terms", [False, True])
def test_exact_search_equals_brute_force_and_approximations_never_beat_it(agent_terms):
    """|U| = 6, T = 2, M₁ = 2: the exact tree equals enumerating all 6⁴ sequences with an
    independent cost (explicit inverses)."""
    rng = np.random.default_rng(11 + agent_terms)
    for _ in range(3):
        p = _cv_problem(rng, agent_terms=agent_terms)
        u, c = search(p, 2, method="exact")
        ub, cb = brute_force(p, 2, 0.9)
        np.testing.assert_allclose(u, ub)
        assert c == pytest.approx(cb, rel=1e-10)
        for method in ("approx", "approx_parallel", "vbest"):
            ua, ca = search(p, 2, method=method, beam=3)
            assert ca >= c - 1e-9 * c
            seq_cost = sequence_cost(p, np.stack([ua, ua]), 0.9)
            assert np.isfinite(seq_cost)
        # V-best with V = |J|^{T−1} keeps every node: the exact search
        uv, cv = search(p, 2, method="vbest", beam=36)
        np.testing.assert_allclose(uv, u)
        assert cv == pytest.approx(c, rel=1e-12)


def test_approximate_search_matches_exact_where_the_problem_decouples():
    """Two agents 1 km apart, each with its own mobile anchor within a 100 m range: the cost is
    a sum of independent terms, so optimizing one anchor at a time is exact (T = 1)."""
    U = control_set(2.0, 8, ())
    mean = np.array([[0.0, 0.0], [1000.0, 0.0]])
    P = np.repeat(np.diag([9.0, 1.0])[None], 2, axis=0)
    mobile = np.array([[20.0, 5.0], [1000.0, 30.0]])
    static = np.array([[0.0, -40.0], [960.0, 0.0]])
    p = _static_problem(mean, P, mobile, static, U, comm_range_m=100.0)
    u, c = search(p, 1)
    for method in ("approx", "approx_parallel"):
        ua, ca = search(p, 1, method=method)
        np.testing.assert_allclose(ua, u)
        assert ca == pytest.approx(c, rel=1e-12)


def test_uninformative_ranges_make_every_policy_equal():
    """σ → ∞: the ranges carry no information, every control has the prior's cost."""
    rng = np.random.default_rng(5)
    p = _cv_problem(rng)
    p = ControlProblem(**{**p.__dict__, "sigma_r": 1e9})
    P = p.cov
    costs = []
    for spec in (PolicySpec("static"), PolicySpec("random"), PolicySpec("fim_myopic")):
        u = decide(spec, p, np.random.default_rng(0))
        costs.append(sequence_cost(p, u[None], 0.9))
    P_pred = p.F @ P @ p.F.T + p.Q
    prior_cost = float(np.trace(P_pred[:, :2, :2], axis1=1, axis2=2).sum())
    np.testing.assert_allclose(costs, prior_cost, rtol=1e-9)
    _, c_rh = search(p, 2)
    P2 = p.F @ P_pred @ p.F.T + p.Q
    rh_prior = prior_cost + 0.9 * float(np.trace(P2[:, :2, :2], axis1=1, axis2=2).sum())
    assert c_rh == pytest.approx(rh_prior, rel=1e-9)


@pytest.mark.parametrize("dim", [2, 3])
def test_single_anchor_myopic_move_is_perpendicular_to_the_agent_direction(dim):
    """One anchor on the x axis informs x only; the prior is wide across: the best move turns
    the range direction most, i.e. it is perpendicular to the agent direction."""
    U = control_set(2.0, 8, (-45.0, 0.0, 45.0) if dim == 3 else ())
    P = np.diag([1.0] + [16.0] * (dim - 1))[None]
    mobile = np.zeros((1, dim))
    mobile[0, 0] = 30.0
    p = _static_problem(np.zeros((1, dim)), P, mobile, np.zeros((0, dim)), U, sigma=0.5)
    u = decide(PolicySpec("fim_myopic"), p, np.random.default_rng(0))[0]
    assert abs(u[0]) < 1e-12 and np.linalg.norm(u) == pytest.approx(2.0)
    radial = decide(PolicySpec("static"), p, np.random.default_rng(0))
    assert position_cost(P, np.zeros((1, dim)), mobile + u, 0.5) < position_cost(
        P, np.zeros((1, dim)), mobile + radial, 0.5
    )


def test_control_set_is_a_spherical_grid_of_equal_speeds():
    U = control_set(2.0)
    assert U.shape == (26, 3)
    np.testing.assert_allclose(np.linalg.norm(U, axis=1), 2.0)
    assert len({tuple(np.round(u, 9)) for u in U}) == 26
    np.testing.assert_allclose(U.sum(axis=0), 0.0, atol=1e-12)  # symmetric grid
    with pytest.raises(ValidationError, match="elevations_deg"):
        control_set(2.0, 8, (90.0,))


def test_exact_search_refuses_trees_that_do_not_fit():
    rng = np.random.default_rng(0)
    p = _cv_problem(rng, M1=3, U=control_set(2.0))
    with pytest.raises(ValidationError, match="vbest"):
        search(p, 3)


# -- models and trackers -----------------------------------------------------------------------
def test_planar_model_matrices_closed_form():
    dt, sa = 0.5, 0.2
    m = RangeModel("constant_velocity", 3, dt_s=dt, accel_std=sa, planar=True)
    F, Q = m.matrices()
    assert m.state_dim == 5 and m.block_sizes == (3, 2)
    F_ref = np.eye(5)
    F_ref[0, 3] = F_ref[1, 4] = dt
    np.testing.assert_array_equal(F, F_ref)
    q = sa**2 * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
    Q_ref = np.zeros((5, 5))
    for a in (0, 1):
        idx = [a, 3 + a]
        Q_ref[np.ix_(idx, idx)] = q
    np.testing.assert_allclose(Q, Q_ref, rtol=1e-15, atol=1e-18)
    with pytest.raises(ValidationError, match="planar"):
        RangeModel("constant_velocity", 2, planar=True)


def test_tracker_with_per_step_anchors_equals_stepping():
    """run_spbp on anchors given per step = SPBPTracker.step with each step's anchors."""
    rng = np.random.default_rng(2)
    m = RangeModel("constant_velocity", 2, dt_s=1.0, accel_std=0.1)
    K = 4
    anchors = rng.uniform(0, 30, (K, 2, 2))
    z = np.full((K, 1, 3), np.nan)
    z[:, 0, 1:] = rng.uniform(5, 20, (K, 2))
    prior = GaussianPrior(np.array([[10.0, 10.0, 0.0, 0.0]]), np.diag([9.0, 9, 0.1, 0.1])[None])
    res = run_spbp(RangeMeasurements(m, anchors, z), prior)
    t = SPBPTracker(m, prior, options=SPBPOptions())
    for k in range(K):
        mean, cov = t.step(z[k], anchors[k])
        np.testing.assert_array_equal(mean, res.estimates[k])
        np.testing.assert_array_equal(cov, res.covariances[k])
    static = run_spbp(RangeMeasurements(m, anchors[0], z), prior)
    assert not np.allclose(static.estimates[-1], res.estimates[-1])
    with pytest.raises(ValidationError, match="one row per time step"):
        RangeMeasurements(m, anchors[:2], z)


# -- the closed loop ---------------------------------------------------------------------------
SMALL = {"steps": 6, "region_m": [-30.0, 30.0]}


def test_trial_draws_are_shared_and_anchors_follow_the_controls():
    sc = ControlScenario(**{**SMALL, "region_m": (-30.0, 30.0)})
    draws = draw_trial(sc, np.random.default_rng(3))
    est = make_estimator("spbp", {})
    out = {}
    for label in ("static", "fim_myopic"):
        out[label] = run_policy(
            sc,
            draws,
            PolicySpec(label),
            est,
            np.random.default_rng(1),
            np.random.default_rng(2),
            keep=True,
        )
    mob = out["fim_myopic"]["mobile"]
    steps = np.linalg.norm(np.diff(mob, axis=0), axis=-1)
    np.testing.assert_allclose(steps, sc.speed_m_s * sc.dt_s)
    assert np.all(out["static"]["mobile"] == draws.mobile0)
    assert np.all(np.isfinite(out["fim_myopic"]["err2"]))
    net = realized_network(sc, draws, mob)
    np.testing.assert_array_equal(net.positions[:, sc.agents : sc.agents + 1], mob)
    np.testing.assert_array_equal(net.positions[:, : sc.agents], draws.truth[:, :, :3])
    assert net.is_anchor.sum() == 2 and net.n_snapshots == sc.steps + 1
    with pytest.raises(ValidationError, match="anchors must be static"):
        type(net)(net.positions, net.is_anchor)


def _tiny_recipe(tmp_path, extra=""):
    text = (DATASETS / "fim_control.toml").read_text()
    text = text.replace("trials = 2000", "trials = 6").replace("steps = 50", "steps = 8")
    text = text.replace("task_trials = 20", "task_trials = 4")
    text += extra
    path = tmp_path / "tiny_control.toml"
    path.write_text(text)
    return load_recipe(path)


def _non_timing(fig):
    """The figures that are not wall times; NaN (an interval a ratio's resamples leave
    undefined) as a string, so that two runs compare equal."""
    return {
        k: "nan" if isinstance(v, float) and math.isnan(v) else v
        for k, v in fig.items()
        if not k.endswith("decision_s")
    }


def test_control_experiment_same_numbers_on_one_and_two_workers(tmp_path):
    recipe = _tiny_recipe(tmp_path)
    one = ce.CONTROL.run(recipe, progress=False)
    two = ce.CONTROL.run(recipe, workers=2, progress=False)
    assert _non_timing(one["figures"]) == _non_timing(two["figures"])
    f = one["figures"]
    for p in one["meta"]["policies"]:
        assert f[f"{p}.track_loss_ci_low_pct"] <= f[f"{p}.track_loss_pct"]
        assert f[f"{p}.track_loss_pct"] <= f[f"{p}.track_loss_ci_high_pct"]
        # track loss can only fall as the threshold grows
        assert f[f"{p}.track_loss_pct_1m"] >= f[f"{p}.track_loss_pct_5m"]
        assert f[f"{p}.track_loss_pct_5m"] >= f[f"{p}.track_loss_pct_20m"]


def test_grouping_of_trials_into_tasks_does_not_change_the_numbers(tmp_path):
    a = ce.CONTROL.run(_tiny_recipe(tmp_path), progress=False)
    (tmp_path / "b").mkdir()
    text = (
        (tmp_path / "tiny_control.toml").read_text().replace("task_trials = 4", "task_trials = 1")
    )
    (tmp_path / "b" / "tiny_control.toml").write_text(text)
    b = ce.CONTROL.run(load_recipe(tmp_path / "b" / "tiny_control.toml"), progress=False)
    assert _non_timing(a["figures"]) == _non_timing(b["figures"])


def test_wilson_interval_closed_form():
    lo, hi = ce.wilson(50, 100)
    h = 1.959963984540054 * math.sqrt(0.25 / 100 + 1.959963984540054**2 / 40000)
    den = 1 + 1.959963984540054**2 / 100
    assert lo == pytest.approx(0.5 - h / den) and hi == pytest.approx(0.5 + h / den)


@pytest.mark.parametrize(
    ("section", "key", "value", "match"),
    [
        ("experiment", "policies", '["static", "fim_magic"]', "experiment.policies"),
        ("experiment", "trials", "0", "experiment.trials"),
        ("network", "prior_var", "[1.0, 2.0]", "network.prior_var"),
        ("network", "agents", "0", "network.agents"),
        ("network", "planar", "1", "network.planar"),
        ("experiment", "estimator", '"sirbp"', "experiment.estimator"),
    ],
)
def test_recipe_errors_name_the_key_before_any_work(tmp_path, section, key, value, match):
    text = (DATASETS / "fim_control.toml").read_text()
    lines = text.splitlines()
    start = lines.index(f"[{section}]")
    out, done = [], False
    for i, line in enumerate(lines):
        if i > start and not done and (line.startswith(f"{key} =") or line.startswith("[")):
            out.append(f"{key} = {value}")
            done = True
            if line.startswith("["):
                out.append(line)
            continue
        out.append(line)
    path = tmp_path / "bad.toml"
    path.write_text("\n".join(out) + "\n")
    with pytest.raises(ValidationError, match=match):
        ce.CONTROL.run(load_recipe(path), progress=False)


def test_the_earlier_estimator_form_shows_the_current_one(tmp_path):
    """``[localization] method = ...`` named the estimator before ``experiment.estimator``."""
    text = (DATASETS / "fim_control.toml").read_text()
    path = tmp_path / "old.toml"
    path.write_text(
        text.replace("\n[experiment]\n", '\n[localization]\nmethod = "spbp"\n\n[experiment]\n')
    )
    with pytest.raises(ValidationError, match=r"localization\.method .*estimator = "):
        ce.CONTROL.prepare(load_recipe(path))


# -- 95 % intervals over trials -------------------------------------------------------------------
def _from_units(u) -> float:
    """Brute force: the pooled figure from its stored per-unit numerators and denominators."""
    return float(np.sum(np.asarray(u["num"], float)) / np.sum(np.asarray(u["den"], float)))


def test_control_figures_carry_intervals_over_trials(tmp_path):
    """6 trials in 2 tasks: every pooled figure has a finite interval around it and one value
    per trial (not per task), and is the pooled value of those; the fractions are the
    percentages / 100; a paired ratio is the ratio of its two figures; the table shows the
    intervals."""
    res = ce.CONTROL.run(_tiny_recipe(tmp_path), progress=False)
    f, ser, meta = res["figures"], res["series"], res["meta"]
    names = [k.removesuffix(".units") for k in ser if k.endswith(".units")]
    K = meta["steps"]
    for p in meta["policies"]:
        want = {f"{p}.track_loss_fraction", f"{p}.diverged_fraction", f"{p}.k{K}.log10_mse_mean"}
        want |= {f"{p}.late_log10_mse_mean", f"{p}.track_loss_fraction_20m"}
        assert want <= set(names), want - set(names)
        assert f[f"{p}.track_loss_fraction"] == pytest.approx(f[f"{p}.track_loss_pct"] / 100)
        assert f[f"{p}.diverged_fraction"] == pytest.approx(f[f"{p}.diverged_pct"] / 100)
        assert f"{p}.decision_s.ci_low" not in f  # wall times are plain
    for n in names:
        lo, x, hi = f[n + ".ci_low"], f[n], f[n + ".ci_high"]
        assert math.isfinite(lo) and math.isfinite(hi), n
        slack = 1e-12 * abs(x)  # a point value kept as computed may differ in the last bit
        assert lo - slack <= x <= hi + slack, (n, lo, x, hi)
        u = ser[n + ".units"]
        assert len(u["num"]) == len(u["den"]) == meta["trials"] == 6, n
        assert x == pytest.approx(_from_units(u), rel=1e-12, abs=1e-15), n
    ratios = [k for k in f if k.endswith(".track_loss_fraction.ratio")]
    pairs = ce.comparisons(ce.CONTROL.prepare(_tiny_recipe(tmp_path)).policies)
    assert ("fim_rh", "static") in pairs and ("fim_rh", "fim_myopic") in pairs
    assert ("static", "fim_rh") not in pairs and ("random", "static") not in pairs
    for a, b in pairs:
        key = f"{a}_vs_{b}.track_loss_fraction.ratio"
        if f[f"{b}.track_loss_fraction"] == 0:
            assert key not in f
        else:
            assert f[key] == f[f"{a}.track_loss_fraction"] / f[f"{b}.track_loss_fraction"]
    assert ratios
    rows = ce.summary_rows(res)
    x, lo, hi = (100 * f[f"static.track_loss_fraction{s}"] for s in ("", ".ci_low", ".ci_high"))
    assert rows[0][1] == f"{x:.3g} [{lo:.3g}, {hi:.3g}]"
    assert rows[0][3].startswith(f"{f[f'static.k{K}.log10_mse_mean']:.3g} [")
    assert len(rows[0]) == len(ce.CONTROL.headers)


def _fake_control(plan, n_trials, K, A, block, seed=2):
    """Task results of ``n_trials`` trials in blocks of ``block`` (random squared errors,
    some diverged)."""
    rng = np.random.default_rng(seed)
    err2 = {p: rng.lognormal(1.0, 2.0, (n_trials, K, A)) for p in plan}
    for p in plan:
        err2[p][rng.random(n_trials) < 0.2, -3:, 0] = np.inf  # diverged trials
    out = []
    for s in range(0, n_trials, block):
        t = range(s, min(s + block, n_trials))
        out.append(
            (
                {p: {"err2": [err2[p][i] for i in t], "decision_s": [1e-3] * len(t)} for p in plan},
                None,
            )
        )
    return out, err2


def test_control_point_values_are_those_of_all_trials_at_once_and_units_are_trials():
    """37 trials: the log-MSE means are, bit for bit, the mean over trials of log10 of the
    mean over agents (diverged errors as DIVERGED_M2), with one unit per trial; grouping the
    trials into tasks of 5 or 1 changes neither the figures nor their units."""
    from types import SimpleNamespace

    from phyloc.evaluation.statistics import Pooled, resolve

    exp = ce.ControlExperimentSpec(trials=37, policies=("static", "random", "fim_rh"))
    plan, K, A = exp.plan(), 12, 3
    scenario = SimpleNamespace(steps=K)
    res5, err2 = _fake_control(plan, 37, K, A, 5)
    res1, _ = _fake_control(plan, 37, K, A, 1)
    f5, _ = ce._aggregate(res5, exp, plan, scenario)
    f1, _ = ce._aggregate(res1, exp, plan, scenario)
    for p in plan:
        e = err2[p]
        log_mse = np.log10(np.where(np.isfinite(e), e, ce.DIVERGED_M2).mean(axis=2))
        by_step = log_mse.mean(axis=0)  # the established figure: sequential over trials
        fig = f5[f"{p}.k{K}.log10_mse_mean"]
        assert fig.value == by_step[-1]
        np.testing.assert_array_equal(fig.num, log_mse[:, -1])
        assert fig.n_units == 37 and np.all(fig.den == 1)
        assert f5[f"{p}.late_log10_mse_mean"].value == by_step[-10:].mean()
        lost = ~(e[:, -1, :] <= 25.0)  # track_loss_m = 5 m
        loss = f5[f"{p}.track_loss_fraction"]
        assert loss.value == lost.sum() / lost.size and loss.n_units == 37
        np.testing.assert_array_equal(loss.num, lost.sum(axis=1))
        assert f5[f"{p}.track_loss_pct"] == 100.0 * lost.sum() / lost.size
        div = ~np.all(np.isfinite(e), axis=(1, 2))
        assert f5[f"{p}.diverged_fraction"].value == div.mean()
    for k, x in f5.items():
        y = f1[k]
        if isinstance(x, Pooled):
            assert x.value == y.value and x.kind == y.kind, k
            np.testing.assert_array_equal([x.num, x.den], [y.num, y.den], err_msg=k)
        elif not k.endswith("decision_s") and not hasattr(x, "a"):
            assert x == y, k
    r5, _ = resolve(f5, {}, seed=4)
    r1, _ = resolve(f1, {}, seed=4)
    assert _non_timing(r5) == _non_timing(r1)
    assert r5["fim_rh_vs_static.track_loss_fraction.ratio"] == (
        r5["fim_rh.track_loss_fraction"] / r5["static.track_loss_fraction"]
    )

"""Contract of the direct family: every registered method runs on truth-free measurements.

One tiny problem (three anchors, two agents, two snapshots), measurements built only from
what radios would give — correlation tables of the received signals and synthetic ranges per
estimator — and the anchors' known positions. Every method of ``METHODS.family("direct")``
must return finite estimates of the right shape, the same result for the same seed, and must
not need the agents' positions.
"""

import dataclasses
import math

import numpy as np
import pytest
from tiny import tiny_recipe

from phyloc.errors import ValidationError
from phyloc.localization import (
    METHODS,
    Method,
    Result,
    Timing,
    coarse_positions,
    gaussian_log_prior,
    gaussian_priors,
)
from phyloc.localization.direct import (
    NAMES,
    DirectOptions,
    DPFOptions,
    LinkMeasurements,
    LinkRanges,
    Prior,
    link_likelihood,
    run,
    run_dpf,
)
from phyloc.phy import C0, OFDMSystem, PathSet
from phyloc.phy.correlation import correlation_tables
from phyloc.phy.synthesis import synthesize
from phyloc.phy.waveform import qpsk_symbols

SYSTEM = OFDMSystem(n_subcarriers=129, subcarrier_spacing_hz=1.0e6)
ANCHORS = np.array([[0.0, 0.0], [40.0, 0.0], [0.0, 40.0]])
T = 2


def _problem(seed=0):
    """Truth (kept here, in the test) and the measurements made from it."""
    rng = np.random.default_rng(seed)
    agents = np.array([[12.0, 17.0], [25.0, 9.0]]) + np.cumsum(rng.normal(0, 0.5, (T, 2, 2)), 0)
    links = np.array([(u, v) for u in (3, 4) for v in range(5) if v != u])
    tables, ranges = [], {}
    est_names = {m.inputs.split(":", 1)[1] for m in METHODS.values() if ":" in m.inputs}
    per_est = {name: ([], [], []) for name in est_names}
    for t in range(T):
        pos = np.vstack([ANCHORS, agents[t]])
        d = np.linalg.norm(pos[links[:, 0]] - pos[links[:, 1]], axis=1)
        S = qpsk_symbols(SYSTEM, 5, rng)
        snr = 10 ** (30.0 / 10) / SYSTEM.n_subcarriers
        gains = math.sqrt(snr * SYSTEM.noise_power_w) * np.exp(2j * np.pi * rng.random(d.size))
        R = synthesize(PathSet.single_path(d / C0, gains), S, SYSTEM, rng, tx_index=links[:, 1])
        tables.append(correlation_tables(R, S, SYSTEM, tx_index=links[:, 1]))
        for r, var, ok in per_est.values():
            r.append(d + rng.normal(0, 0.3, d.size))
            var.append(np.full(d.size, 0.09))
            ok.append(np.ones(d.size, bool))
    ranges = {k: LinkRanges(*v) for k, v in per_est.items()}
    meas = LinkMeasurements(
        n_nodes=5,
        dim=2,
        anchor_nodes=[0, 1, 2],
        anchor_positions=np.repeat(ANCHORS[None], T, axis=0),
        links=[links] * T,
        tables=tables,
        ranges=ranges,
        window_m=(0.0, 100.0),
    )
    return meas, agents


def _prior(seed, Q=200):
    """Truth-free prior: uniform over the anchors' bounding box (with a log density)."""
    rng = np.random.default_rng(seed)
    X = rng.uniform(-5.0, 45.0, (2, Q, 2))

    def logp(x):
        inside = np.all((x >= -5.0) & (x <= 45.0), axis=2)
        return np.where(inside, 0.0, -np.inf)

    return Prior(X, logp, "uniform box")


def _options(method):
    table = {"n_iterations": 3} if method.options is DirectOptions else {}
    return method.make_options(table)


@pytest.fixture(scope="module")
def problem():
    return _problem()


def test_measurements_carry_no_truth(problem):
    meas, _ = problem
    fields = {f.name for f in dataclasses.fields(LinkMeasurements)}
    assert not fields & {"positions", "truth", "states", "agent_positions"}
    assert meas.agent_nodes.tolist() == [3, 4]  # the agents are known only as node indices


def test_every_direct_method_is_registered():
    assert set(NAMES) <= set(METHODS.family("direct"))
    assert METHODS["dipnet"].label == "DiPNet"
    for name in NAMES:
        m = METHODS[name]
        assert m.inputs == "tables" or m.inputs.startswith("ranges:")


@pytest.mark.parametrize("name", METHODS.family("direct"))
def test_contract_finite_reproducible_truth_free(problem, name):
    meas, _ = problem
    method = METHODS[name]
    out = []
    for _ in range(2):
        rng = np.random.default_rng(7)
        out.append(method.run(meas, _prior(3), rng, _options(method)))
    res = out[0]
    assert isinstance(res, Result)
    assert res.estimates.shape[1:] == (meas.n_agents, meas.dim)
    assert np.all(np.isfinite(res.estimates))
    np.testing.assert_array_equal(out[0].estimates, out[1].estimates)
    if res.covariances is not None:
        assert np.all(np.isfinite(res.covariances))
    assert res.timing.wall_s >= 0


@pytest.mark.parametrize("name", NAMES)
def test_direct_methods_localize_the_tiny_problem(problem, name):
    """From a truth-free coarse prior (MDS/SMACOF on the ranges), every snapshot within 1.5 m."""
    meas, agents = problem  # the truth enters here, in the evaluation, only
    r = meas.range_set("corr")
    sol = coarse_positions(
        meas.links[0],
        r.range_m[0],
        meas.n_nodes,
        meas.dim,
        is_anchor=meas.is_anchor,
        anchor_positions=meas.anchor_positions[0],
    )
    centers = sol.positions[meas.agent_nodes]
    rng = np.random.default_rng(1)
    prior = Prior(
        gaussian_priors(centers, 3.0, 300, rng),
        lambda x: gaussian_log_prior(x, centers, 3.0),
        "truth-free",
    )
    method = METHODS[name]
    res = method.run(meas, prior, rng, _options(method))
    assert res.estimates.shape == (T, 2, 2)
    assert res.diagnostics["mean_history"].shape == (T, 4, 2, 2)
    assert res.timing.agent_iterations == T * 2 * 3
    err = np.linalg.norm(res.estimates - agents, axis=2)
    assert np.all(err < 1.5), err


def test_run_is_run_dpf_then_prediction(problem):
    """Snapshot 0 of ``run`` is exactly ``run_dpf`` on the anchors' positions."""
    meas, _ = problem
    opts = DirectOptions(likelihood="gaussian", ranges="sage", dpf=DPFOptions(n_iterations=2))
    one = LinkMeasurements(
        5, 2, meas.anchor_nodes, meas.anchor_positions[:1], meas.links[:1],
        ranges={"sage": LinkRanges(*(x[:1] for x in dataclasses.astuple(meas.ranges["sage"])))},
    )  # fmt: skip
    res = run(one, _prior(2), np.random.default_rng(4), opts)
    lik = link_likelihood(one, 0, opts)
    ref = run_dpf(
        lik, _prior(2), ANCHORS, one.is_anchor, np.random.default_rng(4), opts.filter_options()
    )
    np.testing.assert_array_equal(res.estimates[0], ref.means[3:])
    np.testing.assert_array_equal(res.particles, ref.particles)
    assert res.timing.agent_iterations == ref.agent_iterations


def test_options_select_the_likelihood_not_the_name():
    pub = METHODS["dipnet_published"].make_options({"n_particles": 50, "resample_move": True})
    f = pub.filter_options()
    assert pub.likelihood == "env" and not f.resample_move and f.cov_floor_m == 0
    assert f.n_particles == 50
    sage = METHODS["sage"].make_options({})
    assert (sage.likelihood, sage.ranges) == ("gaussian", "sage")
    with pytest.raises(ValidationError, match="likelihood"):
        DirectOptions(likelihood="matched")
    with pytest.raises(ValidationError, match=r"localization\.bogus"):
        METHODS["dipnet"].make_options({"bogus": 1})


def test_missing_inputs_are_named(problem):
    meas, _ = problem
    bare = LinkMeasurements(5, 2, meas.anchor_nodes, meas.anchor_positions, meas.links)
    with pytest.raises(ValidationError, match="tables"):
        run(bare, _prior(0), np.random.default_rng(0), DirectOptions())
    with pytest.raises(ValidationError, match="ranges"):
        run(bare, _prior(0), np.random.default_rng(0), METHODS["sage"].make_options({}))


@dataclasses.dataclass(frozen=True)
class _ShrinkOptions:
    factor: float = 1.0


def _shrink(measurements, prior, rng, options):
    """A user's direct method: the prior mean, scaled (no diagnostics, one step)."""
    mean = options.factor * prior.particles.mean(axis=1)
    return Result(mean[None], None, Timing(0.0, np.zeros(1), np.zeros(1)), label=prior.label)


RECIPE = tiny_recipe(
    "localization",
    "tiny_user",
    localization={"n_particles": 100, "n_iterations": 2, "shrink_test": {"factor": 1.0}},
    experiment={
        "scenarios": {"c2": "winner2_c2"},
        "agents": [4],
        "realizations": 1,
        "methods": ["shrink_test", "corr"],
        "inits": ["truth_free"],
        "cdf_agents": [4],
    },
)


def test_a_users_direct_method_runs_in_the_localization_experiment(monkeypatch):
    from phyloc.config import load_recipe
    from phyloc.evaluation import localization_experiment as lx

    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    method = Method("shrink_test", family="direct", run=_shrink, options=_ShrinkOptions)
    monkeypatch.setitem(METHODS._methods, "shrink_test", method)  # registered for this test only
    res = lx.LOCALIZATION.run(load_recipe(RECIPE), progress=False)
    f = res["figures"]
    assert np.isfinite(f["shrink_test.c2.agents_4.framework_rmse_m"])
    # the start figure is the prior centres' RMSE; the user's method returns the mean of Q =
    # 100 particles around them (std 10 m): the two differ by ~1 m per axis, not more
    start = f["start.c2.agents_4.framework_rmse_m"]
    assert np.isfinite(start)
    assert abs(f["shrink_test.c2.agents_4.framework_rmse_m"] - start) < 3 * 2 * 10 / 10
    assert np.isnan(f["shrink_test.c2.agents_4.ess_min"])  # no ESS diagnostics: NaN
    assert f["corr.c2.agents_4.ess_min"] > 0
    # the method's own options come from [localization.shrink_test] only
    spec = lx.LocalizationSpec.from_dict({"n_particles": 100, "shrink_test": {"factor": 0.5}})
    assert spec.options_for("shrink_test") == _ShrinkOptions(0.5)
    assert spec.options_for("corr").dpf.n_particles == 100

"""Contract of every registered tracking method (one test for all, as scikit-learn's
``check_estimator``): it runs on truth-free measurements, gives finite output of the documented
shapes and the same result for the same seed."""

import dataclasses

import numpy as np
import pytest

from phyloc.localization import METHODS, Result
from phyloc.localization.tracking import GaussianPrior, RangeMeasurements, RangeModel

TRACKING = METHODS.family("tracking")
#: Small option values for a fast contract run (applied where the options have the key).
SMALL = {"n_particles": 300, "n_lambda": 5}


def _tiny_problem():
    """Two agents moving at constant velocity in 2-D among three anchors, 4 time steps.

    Only the measurements (ranges with NaN where absent) and a prior go to the methods; the
    true positions stay in this function's return value for the test's own check.
    """
    rng = np.random.default_rng(5)
    model = RangeModel("constant_velocity", 2, dt_s=0.1, accel_std=0.1, sigma_r=0.1)
    anchors = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    x0 = np.array([[3.0, 4.0, 1.0, 0.0], [6.0, 5.0, 0.0, -1.0]])
    F, _ = model.matrices()
    K = 4
    truth = np.stack([x0 @ np.linalg.matrix_power(F, k + 1).T for k in range(K)])
    nodes = np.concatenate([truth[..., :2], np.broadcast_to(anchors, (K, 3, 2))], axis=1)
    d = np.linalg.norm(truth[:, :, None, :2] - nodes[:, None], axis=-1)  # [K, 2, 5]
    z = d + rng.normal(0.0, 0.1, d.shape)
    z[:, [0, 1], [0, 1]] = np.nan  # no self-range
    z[1, 0, 4] = np.nan  # a missing link
    meas = RangeMeasurements(model, anchors, z)
    P0 = np.diag([1.0, 1.0, 0.5, 0.5])
    prior = GaussianPrior(x0 + rng.normal(size=x0.shape) * [0.5, 0.5, 0.2, 0.2], [P0, P0])
    return meas, prior, truth


def _options(method):
    names = {f.name for f in dataclasses.fields(method.options)}
    return method.make_options({k: v for k, v in SMALL.items() if k in names})


def test_the_paper_methods_are_registered():
    assert set(TRACKING) >= {"pfbp", "pfbp_reg", "sirbp", "spbp", "edh"}
    assert METHODS["pfbp_reg"].make_options().regularize is True
    assert METHODS["pfbp"].make_options().regularize is False


@pytest.mark.parametrize("name", TRACKING)
def test_contract(name):
    method = METHODS[name]
    meas, prior, truth = _tiny_problem()
    assert not any(hasattr(meas, a) for a in ("states", "initial_states", "positions"))
    opt = _options(method)
    a = method.run(meas, prior, np.random.default_rng(9), opt)
    b = method.run(meas, prior, np.random.default_rng(9), opt)
    assert isinstance(a, Result)
    K, n_ag, nd = meas.n_steps, meas.n_agents, meas.model.state_dim
    assert a.estimates.shape == (K, n_ag, nd)
    assert np.all(np.isfinite(a.estimates))
    if a.covariances is not None:
        assert a.covariances.shape == (K, n_ag, nd, nd)
        assert np.all(np.isfinite(a.covariances))
        assert np.all(np.linalg.eigvalsh(a.covariances) > -1e-9)
    if a.particles is not None:
        assert a.particles.shape[0] == n_ag and a.particles.shape[2] == nd
        assert a.log_weights.shape == a.particles.shape[:2]
    assert a.timing.step_s.shape == (K,) and a.timing.agent_s.shape == (K,)
    assert np.all(a.timing.step_s >= 0) and a.timing.wall_s >= a.timing.step_s.sum()
    assert a.timing.agent_iterations >= K
    np.testing.assert_array_equal(a.estimates, b.estimates)  # reproducible for a seed
    if a.covariances is not None:
        np.testing.assert_array_equal(a.covariances, b.covariances)
    # and it localizes: the last position estimates are near the truth (prior σ 0.5 m)
    err = np.linalg.norm(a.estimates[-1, :, :2] - truth[-1, :, :2], axis=-1)
    assert np.all(err < 0.5), err


@pytest.mark.parametrize("name", TRACKING)
def test_a_different_seed_changes_a_random_method(name):
    method = METHODS[name]
    meas, prior, _ = _tiny_problem()
    opt = _options(method)
    a = method.run(meas, prior, np.random.default_rng(1), opt)
    b = method.run(meas, prior, np.random.default_rng(2), opt)
    if a.particles is None:  # Gaussian (deterministic) methods ignore the generator
        np.testing.assert_array_equal(a.estimates, b.estimates)
    else:
        assert not np.array_equal(a.estimates, b.estimates)


def _updates(meas):
    """One :class:`~phyloc.localization.tracking.loop.Update` per method, small options."""
    from phyloc.localization.tracking.edh import EDHUpdate
    from phyloc.localization.tracking.pfbp import PFBPOptions, PFBPUpdate
    from phyloc.localization.tracking.sirbp import SIRBPOptions, SIRBPUpdate
    from phyloc.localization.tracking.spbp import SPBPOptions, SPBPUpdate

    m, pf = meas.model, PFBPOptions(n_particles=300, n_lambda=5, regularize=True)
    return {
        "pfbp": PFBPUpdate(m, pf),
        "sirbp": SIRBPUpdate(m, SIRBPOptions(n_particles=300), meas.anchor_bounds()),
        "spbp": SPBPUpdate(m, SPBPOptions(regularize=True)),
        "edh": EDHUpdate(m, pf),
    }


@pytest.mark.parametrize("name", ["pfbp", "sirbp", "spbp", "edh"])
def test_stepping_the_loop_equals_track(name):
    """The one loop of the family (``tracking.loop``): ``Tracker.step`` step by step gives
    what ``track`` records, and the particles and random draws carry over between steps."""
    from phyloc.localization.tracking.loop import Tracker, track

    meas, prior, _ = _tiny_problem()
    res = track(meas, prior, np.random.default_rng(3), _updates(meas)[name])
    t = Tracker(_updates(meas)[name], prior, np.random.default_rng(3))
    for k in range(meas.n_steps):
        mean, cov = t.step(meas.z[k], meas.anchors_at(k))
        np.testing.assert_array_equal(mean, res.estimates[k])
        np.testing.assert_array_equal(cov, res.covariances[k])
    assert res.label == name and (res.particles is None) == (name == "spbp")
    joint = name == "edh"
    assert t.belief.joint == joint and np.isnan(res.timing.agent_s).all() == joint


#: The stages each method times within its update (besides predict, estimate and other), with
#: the regularized options of :func:`_updates`.
UPDATE_STAGES = {
    "pfbp": {"flow", "weights", "resample", "covariance", "regularize"},
    "sirbp": {"weights", "resample"},
    "spbp": {"covariance"},
    "edh": {"flow", "weights", "resample", "covariance", "regularize"},
}


@pytest.mark.parametrize("name", ["pfbp", "sirbp", "spbp", "edh"])
def test_the_stages_split_each_step(name):
    """``diagnostics["stage_s"]``: the stages of :data:`STAGES` the method has, each a
    non-negative time per step, and together the step's wall time (the clock's own cost, a few
    microseconds per stage, aside)."""
    from phyloc.localization.tracking.loop import STAGES, track

    meas, prior, _ = _tiny_problem()
    res = track(meas, prior, np.random.default_rng(3), _updates(meas)[name])
    stages = res.diagnostics["stage_s"]
    assert set(stages) == UPDATE_STAGES[name] | {"predict", "estimate", "other"}
    assert list(stages) == [s for s in STAGES if s in stages]  # in the order of a step
    total = np.zeros(meas.n_steps)
    for seconds in stages.values():
        assert seconds.shape == (meas.n_steps,) and np.all(seconds >= 0)
        total += seconds
    np.testing.assert_allclose(total, res.timing.step_s, rtol=0.05, atol=2e-4)


@pytest.mark.parametrize("name", ["pfbp", "edh"])
def test_a_slow_flow_is_counted_in_the_flow_stage(name):
    """A flow that sleeps 20 ms per call (installed with ``use_flow``) adds its time to the
    ``flow`` stage of every step, at least 20 ms per call, and to no other stage."""
    import time

    from phyloc.localization.tracking import _flow
    from phyloc.localization.tracking.loop import track

    calls = []

    def slow(X, mean, *args):
        calls.append(1)
        time.sleep(0.02)
        return np.array(X, dtype=float), np.array(mean, dtype=float)

    meas, prior, _ = _tiny_problem()
    with _flow.use_flow(slow):
        res = track(meas, prior, np.random.default_rng(3), _updates(meas)[name])
    flow = res.diagnostics["stage_s"]["flow"]
    assert flow.sum() >= 0.02 * len(calls) > 0
    for stage, seconds in res.diagnostics["stage_s"].items():
        if stage != "flow":
            assert np.all(seconds < 0.02), (stage, seconds)


def test_an_unknown_stage_is_refused():
    from phyloc.errors import ValidationError
    from phyloc.localization.tracking.loop import StageClock

    with pytest.raises(ValidationError, match="stage"), StageClock()("flw"):
        pass


def test_pfbp_with_gaussian_messages_times_its_sampling():
    """With ``exchange = "gaussian"`` (PF-BP §VI) an agent draws its neighbours' particles from
    their Gaussian beliefs: a ``sample`` stage, which particle messages do not have."""
    from phyloc.localization.tracking.loop import track
    from phyloc.localization.tracking.pfbp import PFBPOptions, PFBPUpdate

    meas, prior, _ = _tiny_problem()
    opt = PFBPOptions(n_particles=300, n_lambda=5, exchange="gaussian")
    res = track(meas, prior, np.random.default_rng(3), PFBPUpdate(meas.model, opt))
    assert "sample" in res.diagnostics["stage_s"] and "regularize" not in res.diagnostics["stage_s"]
    assert np.all(res.diagnostics["stage_s"]["sample"] > 0)

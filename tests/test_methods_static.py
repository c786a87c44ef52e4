"""Every registered method of the static family (POA-NBP §II-B, §IV, §V): one call shape
``run(measurements, prior, rng, options) -> Result``, finite output, reproducible for a seed,
and nothing but truth-free measurements as input."""

import dataclasses

import numpy as np
import pytest

from phyloc.errors import ValidationError
from phyloc.evaluation.static_scenarios import simulate_ranges
from phyloc.localization import METHODS, Result
from phyloc.localization.static import (
    GaussianRangeError,
    StaticMeasurements,
    StaticPrior,
    ellipse_outer_approximation,
    poa,
)

STATIC = METHODS.family("static")
REGION = (-5.0, -5.0, 25.0, 25.0)
ANCHORS = np.array([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0], [20.0, 20.0]])
AGENTS = np.array([[7.0, 11.0], [13.0, 6.0], [10.0, 15.0]])  # the truth: used only to simulate


def _tiny(seed=0):
    """4 anchors (nodes 0–3), 3 agents (nodes 4–6); the measurements never see the agents."""
    rng = np.random.default_rng(seed)
    model = GaussianRangeError(0.1)
    truth = np.vstack([ANCHORS, AGENTS])
    ranges = simulate_ranges(truth, 100.0, model, rng, anchors=np.arange(4))
    known = np.full_like(truth, np.nan)  # agent rows unknown: only anchor rows are passed on
    known[:4] = ANCHORS
    return StaticMeasurements(ranges, np.arange(4), known, model), StaticPrior(REGION)


def _options(method, n_iterations=3):
    fields = {f.name for f in dataclasses.fields(method.options)}
    table = {"n_iterations": n_iterations}
    if "n_samples" in fields:
        table["n_samples"] = 80
    return method.make_options(table)


def test_the_paper_methods_are_registered_with_labels():
    assert STATIC[:8] == (
        "poa_nbp",
        "nbp_ellipse",
        "nbp_min_entropy",
        "nbp_mixture",
        "nbp_parsimonious",
        "pbp",
        "wls",
        "nbp_aux",
    )
    labels = [METHODS[m].label for m in STATIC[:8]]
    assert labels == [
        "POA-NBP",
        "NBP ell.",
        "NBP min.",
        "NBP mix.",
        "NBP par.",
        "PBP",
        "WLS",
        "NBP aux.",
    ]
    assert METHODS["nbp_aux"].make_options().proposal == "auxiliary"
    assert METHODS["poa_nbp"].make_options().proposal == "polygon"
    assert METHODS["poa_nbp"].make_options().support == "poa"
    assert METHODS["nbp_ellipse"].make_options().support == "ellipse"
    assert METHODS["pbp"].make_options().start == "mds"
    # the ellipses the paper cites (S-procedure discs), after the paper's eight
    assert STATIC[8] == "nbp_bounding" and METHODS["nbp_bounding"].label == "NBP bound."
    assert METHODS["nbp_bounding"].make_options().proposal == "polygon"


def test_measurements_hold_no_agent_positions():
    meas, _ = _tiny()
    names = {f.name for f in dataclasses.fields(StaticMeasurements)}
    assert names == {"ranges", "is_anchor", "anchor_positions", "error_model"}
    assert meas.anchor_positions.shape == (4, 2) and meas.n_agents == 3
    assert np.isnan(meas.positions[meas.agent_nodes]).all()
    assert not meas.ranges.flags.writeable


@pytest.mark.parametrize("name", STATIC)
def test_every_static_method_is_finite_reproducible_and_truth_free(name):
    meas, prior = _tiny()
    m = METHODS[name]
    opts = _options(m)
    a = m.run(meas, prior, np.random.default_rng(3), opts)
    b = m.run(meas, prior, np.random.default_rng(3), opts)
    assert isinstance(a, Result)
    assert a.estimates.shape == (3, 3, 2) and np.all(np.isfinite(a.estimates))
    np.testing.assert_array_equal(a.estimates, b.estimates)
    if a.covariances is not None:
        assert a.covariances.shape == (3, 3, 2, 2) and np.all(np.isfinite(a.covariances))
        np.testing.assert_array_equal(a.covariances, b.covariances)
    assert a.timing.step_s.shape == (3,) and a.timing.agent_s.shape == (3,)
    assert a.timing.agent_iterations == 9 and a.timing.wall_s > 0
    assert a.diagnostics["agent_time_s"].shape == (3, 3)
    assert np.isfinite(a.diagnostics["setup_time_per_node_s"])
    # a well-posed tiny network: every method ends near the (never seen) truth
    err = np.linalg.norm(a.estimates[-1] - AGENTS, axis=1)
    assert err.max() < 1.5, (name, err)


@pytest.mark.parametrize(
    "name",
    [n for n in STATIC if "n_samples" in {f.name for f in dataclasses.fields(METHODS[n].options)}],
)
def test_particle_methods_publish_their_particles_and_depend_on_the_seed(name):
    meas, prior = _tiny()
    m = METHODS[name]
    a = m.run(meas, prior, np.random.default_rng(3), _options(m))
    c = m.run(meas, prior, np.random.default_rng(4), _options(m))
    assert a.particles.shape == (3, 80, 2) and a.log_weights.shape == (3, 80)
    np.testing.assert_allclose(np.exp(a.log_weights).sum(axis=1), 1.0)
    assert a.diagnostics["ess"].shape == (3, 3) and np.all(a.diagnostics["ess"] >= 1.0)
    assert not np.array_equal(a.estimates, c.estimates)


def test_poa_nbp_draws_its_polygons_first_from_the_run_generator():
    """Without prior polygons, poa_nbp runs POA (POA-NBP Algorithm 1) on the measurements with
    the run's generator and then NBP on the same stream: identical to handing it those
    polygons and the generator after POA."""
    meas, prior = _tiny()
    m = METHODS["poa_nbp"]
    opts = _options(m)
    own = m.run(meas, prior, np.random.default_rng(9), opts)
    assert own.diagnostics["support"] == "poa"
    assert own.diagnostics["poa_area_m2"].shape == (opts.poa_n_fs, 3)
    rng = np.random.default_rng(9)
    ref = poa(
        meas.positions,
        meas.ranges,
        meas.is_anchor,
        rng=rng,
        n_edges=opts.poa_n_edges,
        n_iterations=opts.poa_n_fs,
        region=REGION,
    )
    given = m.run(meas, StaticPrior(REGION, polygons=list(ref.polygons)), rng, opts)
    assert given.diagnostics["support"] == "prior"
    np.testing.assert_array_equal(own.estimates, given.estimates)
    # every weighted particle lies in its agent's polygon (the proposal's support, POA-NBP eq. (21))
    for a, P in enumerate(ref.polygons):
        live = np.exp(own.log_weights[a]) > 0
        assert P.contains(own.particles[a][live]).all()


def test_nbp_ellipse_samples_inside_the_ellipses():
    meas, prior = _tiny()
    m = METHODS["nbp_ellipse"]
    opts = _options(m)
    res = m.run(meas, prior, np.random.default_rng(2), opts)
    assert res.diagnostics["support"] == "ellipse"
    ell = ellipse_outer_approximation(
        meas.positions, meas.ranges, meas.is_anchor, n_iterations=opts.poa_n_fs, region=REGION
    )
    for a, E in enumerate(ell.regions()):
        live = np.exp(res.log_weights[a]) > 0
        assert E.contains(res.particles[a][live]).all()


def test_baselines_start_from_the_prior_or_their_rule():
    meas, _ = _tiny()
    start = np.array([[8.0, 10.0], [12.0, 7.0], [9.0, 14.0]])
    for name in ("pbp", "wls"):
        m = METHODS[name]
        res = m.run(meas, StaticPrior(REGION, initial=start), None, _options(m, 1))
        assert res.diagnostics["start"] == "prior"
        assert res.diagnostics["setup_time_per_node_s"] == 0.0
        mds = m.run(meas, StaticPrior(REGION), None, _options(m, 1))
        assert mds.diagnostics["start"] == "mds"
        heur = m.run(meas, StaticPrior(REGION), None, m.make_options({"start": "heuristic"}))
        assert heur.diagnostics["start"] == "heuristic"
    with pytest.raises(ValidationError, match="start"):
        METHODS["wls"].make_options({"start": "truth"})

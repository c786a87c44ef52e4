"""Communication and operation counts of the static family (POA-NBP §II-B, §V-C2): floats
per link and message-passing iteration, POA's operation counter (Algorithms 2–4) checked
against hand counts, NBP's kernel evaluations against closed forms, and the counting
Sutherland–Hodgman kernel against its plain-NumPy twin."""

import math

import numpy as np
import pytest
from naive_static import clip_groups_count_numpy

from phyloc.evaluation.static_scenarios import paper_static_scenario
from phyloc.localization import METHODS
from phyloc.localization.static import (
    GaussianBPOptions,
    StaticMeasurements,
    StaticPrior,
    WLSOptions,
    poa,
    run_gaussian_bp,
    run_wls,
)
from phyloc.localization.static import _polygon_kernels as K
from phyloc.localization.static.nbp import NBPOptions, run_nbp

TOL = 1e-9


def _random_convex(rng, n, center, radius):
    ang = np.sort(rng.uniform(0.0, 2.0 * math.pi, n))
    return center + radius * np.column_stack([np.cos(ang), np.sin(ang)])


def _halfspaces(v):
    e = np.roll(v, -1, axis=0) - v
    a = np.column_stack([e[:, 1], -e[:, 0]])
    a /= np.linalg.norm(a, axis=1)[:, None]
    return a, np.einsum("ij,ij->i", a, v)


@pytest.mark.parametrize("allow_drop", [False, True])
def test_counting_clip_kernel_matches_numpy_twin(allow_drop):
    rng = np.random.default_rng(11)
    for trial in range(40):
        subject = _random_convex(rng, int(rng.integers(3, 12)), rng.uniform(-2, 2, 2), 5.0)
        groups = []
        for _ in range(int(rng.integers(1, 4))):  # some far away: empty intersections
            far = trial % 5 == 0
            groups.append(
                _halfspaces(
                    _random_convex(
                        rng, int(rng.integers(3, 10)), rng.uniform(-3, 3, 2) + 20.0 * far, 4.0
                    )
                )
            )
        A = np.concatenate([g[0] for g in groups])
        c = np.concatenate([g[1] for g in groups])
        off = np.r_[0, np.cumsum([g[0].shape[0] for g in groups])].astype(np.int64)
        out, drop, n = K.clip_groups_count_kernel(subject, A, c, off, TOL, allow_drop)
        ref_out, ref_drop, ref_n = clip_groups_count_numpy(subject, A, c, off, TOL, allow_drop)
        assert n == ref_n
        np.testing.assert_array_equal(drop, ref_drop)
        np.testing.assert_allclose(out, ref_out, atol=1e-9)
        plain, plain_drop = K.clip_groups_kernel(subject, A, c, off, TOL, allow_drop)
        np.testing.assert_array_equal(plain, out)
        np.testing.assert_array_equal(plain_drop, drop)


def test_poa_operations_one_anchor_one_agent_hand_count():
    """One anchor at the centre of the 10 m × 10 m region, one agent, ``ẑ = 100`` m, ``N_E = 8``,
    ``N_FS = 2``. Whatever the anchor polygon's random offset, its circumscribing octagon of
    inradius 100 m contains the whole region, so:

    * iteration 1, Algorithm 2: 8 anchor-polygon vertices (halfspaces) → 8;
    * iteration 1, Algorithm 3: the subject is the region (4 vertices), clipped by 8 halfspaces
      none of which cuts it: 8 × 4 = 32 vertex–halfspace tests (the list stays at 4);
    * iteration 2: no agent neighbour, nothing to scale or clip → 0.

    Total 8 + 32 = 40 operations for the one agent; no agent–agent link, no broadcast: NaN
    floats.
    """
    pos = np.array([[5.0, 5.0], [np.nan, np.nan]])
    z = np.full((2, 2), np.nan)
    z[1, 0] = 100.0
    for seed in range(3):
        res = poa(pos, z, [0], rng=np.random.default_rng(seed), n_edges=8, region=(0, 0, 10, 10))
        np.testing.assert_array_equal(res.operations, [[40], [0]])
        assert res.operations_per_node == 40.0
        assert math.isnan(res.floats_per_link_iteration)


def test_poa_operations_two_agents_hand_count():
    """Two agents, no anchor, region the 10 m × 10 m square, ``ẑ = 1`` m both ways.

    * iteration 1: each agent's polygon is the region; no anchor polygon, no clip → 0;
    * iteration 2 (and again 3): each agent receives the other's square (4 vertices: 8
      floats on the link), shifts its 4 halfspaces by 1 m (Algorithm 4: 4 operations) and
      clips its own square (4 vertices) by them; none cuts it: 4 × 4 = 16 tests (Algorithm 3).

    Per agent: 0 + 20 (+ 20) → 20 operations with ``N_FS = 2``, 40 with ``N_FS = 3``;
    8 floats per link and broadcast.
    """
    pos = np.full((2, 2), np.nan)
    z = np.array([[np.nan, 1.0], [1.0, np.nan]])
    for n_fs, total in ((2, 20.0), (3, 40.0)):
        res = poa(
            pos, z, [], rng=np.random.default_rng(0), n_iterations=n_fs, region=(0, 0, 10, 10)
        )
        assert res.operations_per_node == total
        assert res.operations[0].tolist() == [0, 0]
        assert res.operations[1].tolist() == [20, 20]
        assert res.floats_per_link_iteration == 8.0


def test_poa_floats_and_operations_grow_with_the_number_of_edges():
    """POA-NBP §V-C2: every operation of POA is O(N_E) or O(N_E²) per neighbour, and Algorithm 1
    broadcasts the vertices; more anchor-polygon edges give more vertices to send and clip."""
    sc = paper_static_scenario(np.random.default_rng(4), n_agents=30)
    meas = sc.measurements()
    floats, ops = [], []
    for ne in (4, 8, 16, 32):
        r = poa(
            meas.positions,
            meas.ranges,
            meas.is_anchor,
            rng=np.random.default_rng(1),
            n_edges=ne,
            n_iterations=2,
            region=sc.region,
        )
        floats.append(r.floats_per_link_iteration)
        ops.append(r.operations_per_node)
    assert np.all(np.diff(floats) > 0) and np.all(np.diff(ops) > 0), (floats, ops)
    # the broadcast polygons are clipped N_E-gons: at most a few times N_E vertices each
    assert 2 * 3 <= floats[0] and floats[-1] <= 2 * 32 * 4


def _one_agent_two_anchors():
    anchors = np.array([[0.0, 0.0], [12.0, 0.0]])
    z = np.full((3, 3), np.nan)
    z[2, :2] = [7.3, 8.1]  # node 2, the agent, measured its ranges to the two anchors
    return StaticMeasurements(z, [0, 1], anchors), StaticPrior((-10, -10, 20, 20))


@pytest.mark.parametrize(
    ("proposal", "per_iteration"),
    [
        # KDE of both anchor messages (N_S centres each) at the N_S proposal samples
        ("mixture", lambda n, L: 2 * n * n),
        # the least-entropy message's KDE at the N_S samples
        ("min_entropy", lambda n, L: n * n),
        # both anchor KDEs at the L·N_S candidates; the final weights need no KDE
        ("auxiliary", lambda n, L: 2 * L * n * n),
        # the previous belief's KDE (N_S centres) at the samples drawn from it (the first
        # iteration, from the uniform prior, uses the mixture: 2·N_S²)
        ("parsimonious", None),
    ],
)
def test_nbp_kernel_evaluations_match_closed_forms_and_floats_are_2ns(proposal, per_iteration):
    """One agent, two anchor neighbours (no agent message): the kernel evaluations per iteration
    are the closed forms of the parametrisation, so over 3 iterations they grow as N_S²; the
    belief broadcast is N_S samples × 2 coordinates."""
    meas, prior = _one_agent_two_anchors()
    for ns in (30, 60):
        opts = NBPOptions(n_samples=ns, n_iterations=3, proposal=proposal, aux_oversampling=3)
        d = run_nbp(meas, prior, np.random.default_rng(2), opts).diagnostics
        assert d["floats_per_link_iteration"] == 2 * ns
        expected = (
            [2 * ns * ns, ns * ns, ns * ns] if per_iteration is None else [per_iteration(ns, 3)] * 3
        )
        np.testing.assert_array_equal(d["kernel_evaluations"][:, 0], expected)
        assert d["operations_per_node"] == sum(expected)
        assert math.isnan(d["support_floats_per_link_iteration"])


def test_poa_nbp_counts_its_polygons_and_the_gaussian_methods_their_messages():
    sc = paper_static_scenario(np.random.default_rng(7), n_agents=12, side_m=40.0)
    meas, prior = sc.measurements(), sc.prior()
    m = METHODS["poa_nbp"]
    opts = m.make_options({"n_samples": 20, "n_iterations": 2, "poa_n_edges": 8})
    d = m.run(meas, prior, np.random.default_rng(5), opts).diagnostics
    ref = poa(
        meas.positions,
        meas.ranges,
        meas.is_anchor,
        rng=np.random.default_rng(5),
        n_edges=8,
        n_iterations=2,
        region=sc.region,
    )  # the method draws its polygons first from the same generator
    assert d["support_operations_per_node"] == ref.operations_per_node > 0
    assert d["support_floats_per_link_iteration"] == ref.floats_per_link_iteration
    assert d["operations_per_node"] == d["kde_operations_per_node"] + ref.operations_per_node
    assert d["floats_per_link_iteration"] == 40
    # PBP sends mean (2) and covariance (3); joint WLS is centralized (NaN), distributed WLS
    # sends its estimate (2)
    assert (
        run_gaussian_bp(meas, prior, None, GaussianBPOptions(n_iterations=1)).diagnostics[
            "floats_per_link_iteration"
        ]
        == 5.0
    )
    wls = run_wls(meas, prior, None, WLSOptions(n_iterations=1))
    assert math.isnan(wls.diagnostics["floats_per_link_iteration"])
    wls_d = run_wls(meas, prior, None, WLSOptions(n_iterations=1, mode="distributed"))
    assert wls_d.diagnostics["floats_per_link_iteration"] == 2.0

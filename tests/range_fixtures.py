"""Shared range-tracking fixtures of the PF-BP and SP-BP tests."""

import numpy as np

from phyloc.evaluation.range_scenarios import RangeScenario
from phyloc.localization.tracking import RangeModel


def degenerate_scenario(K):
    """Coplanar anchors, two agents near them and one agent far from everything (no ranges).

    Returns ``rng, model, anchors, states, z, scenario, prior mean m, prior covariance P, F``;
    ``rng`` (seed 11) has drawn the range noise and is passed on to the trackers.
    """
    rng = np.random.default_rng(11)
    model = RangeModel("constant_acceleration", 3)
    n_ag = 3
    states = np.zeros((K, n_ag, 9))
    states[:, 0, :3] = [5.0, 5.0, 5.0]
    states[:, 1, :3] = [8.0, 4.0, 6.0]
    states[:, 2, :3] = [500.0, 500.0, 500.0]  # far from everything
    anchors = np.array([[0.0, 0, 0], [20, 0, 0], [0, 20, 0], [20, 20, 0]])  # coplanar
    nodes = np.concatenate([states[0, :, :3], anchors])
    d = np.linalg.norm(states[0, :, None, :3] - nodes[None], axis=-1)
    z = np.where((d < 30) & (d > 0), d + 0.1 * rng.normal(size=d.shape), np.nan)
    sc = RangeScenario(model, anchors, states[0], states, np.repeat(z[None], K, axis=0), 30.0)
    m = states[0] + 1.0
    P = np.repeat(np.diag(np.r_[np.full(3, 4.0), np.full(6, 0.1)])[None], n_ag, axis=0)
    F, _ = model.matrices()
    return rng, model, anchors, states, z, sc, m, P, F

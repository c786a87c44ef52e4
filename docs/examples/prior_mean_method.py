"""A user's own localization method, registered as a plugin of ``phyloc evaluate``.

``prior_mean`` is a baseline of the direct family: every agent stays at the mean of its prior
particles (for a truth-free start, the coarse MDS/SMACOF solution of the correlation-peak
ranges), optionally shrunk toward their centroid. It shows the whole contract of a method:
an options dataclass, a ``run`` with the family's call shape returning a
:class:`~phyloc.localization.Result`, and one :func:`~phyloc.localization.register_method`
call. Run it with::

    phyloc evaluate datasets/quickstart_c2.toml --plugin docs/examples/prior_mean_method.py

after adding ``"prior_mean"`` to the recipe's ``experiment.methods``; a
``[localization.prior_mean]`` table sets its options. The test suite runs this file that way
(``tests/test_plugins.py``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from phyloc.localization import Result, Timing, register_method


@dataclass(frozen=True)
class PriorMeanOptions:
    """Options of ``prior_mean``.

    Parameters
    ----------
    shrink : float
        Estimates are ``c + shrink · (m_u − c)`` for prior means ``m_u`` with centroid ``c``
        (1: the prior means themselves; < 1 shrinks the network's shape).
    """

    shrink: float = 1.0


def run(measurements, prior, rng, options):
    """``run(measurements, prior, rng, options) -> Result`` of the direct family.

    Parameters
    ----------
    measurements : phyloc.localization.LinkMeasurements
        Links, correlation tables or ranges and the anchors' positions (never the truth).
    prior : phyloc.localization.Prior
        ``particles [n_agents, Q, dim]`` per agent.
    rng : numpy.random.Generator
        Unused: this method draws nothing.
    options : PriorMeanOptions
    """
    t0 = time.perf_counter()
    mean = prior.particles.mean(axis=1)  # [n_agents, dim]
    if options.shrink != 1.0:
        centroid = mean.mean(axis=0)
        mean = centroid + options.shrink * (mean - centroid)
    wall = time.perf_counter() - t0
    return Result(
        estimates=mean[None],  # one snapshot
        covariances=None,
        timing=Timing(wall, np.array([wall]), np.array([wall / max(len(mean), 1)])),
        label=prior.label,
    )


register_method(
    "prior_mean",
    family="direct",
    run=run,
    options=PriorMeanOptions,
    inputs="ranges:corr",
    label="prior mean",
    description="every agent at the mean of its prior (a baseline)",
    replace=True,
)

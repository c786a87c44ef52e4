"""Channel-model sampling: LOS/NLOS, path loss, shadowing, clusters, NLOS bias.

Scenarios are data: the TOML files of the project's ``channels/`` folder (shipped as
``phyloc.scenarios``) or a user's own file, validated by :func:`load_scenario`. The sampler
:func:`draw_links` turns a batch of link distances into :class:`~phyloc.phy.PathSet` channels
(WINNER II D1.1.2 Sec. 4.2; DiPNet §II-B, §IV-A, §V-A); :func:`two_way_composite` and
:class:`ChannelSpec` add two-way ranging. :mod:`phyloc.channels.stats` checks realized
statistics against the tables.

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(7)
>>> draw = draw_links("winner2_c2", np.array([10.0, 40.0, 90.0]), rng)
>>> bool(np.allclose(draw.paths.total_power(), draw.received_power_w, rtol=1e-12))
True

References
----------
WINNER II: IST-4-027756 WINNER II Deliverable D1.1.2 V1.2, Part I (channel models), 2007,
updated 2008; the table each value of the shipped channel files comes from is given in
``channels/PROVENANCE.md``.

DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from phyloc.channels.sampler import ChannelDraw, draw_links
from phyloc.channels.scenario import (
    DEFAULT_NLOS_BIAS_MEAN_S,
    Scenario,
    load_file,
    load_scenario,
    scenario_names,
)
from phyloc.channels.spec import ChannelSpec, two_way_composite

__all__ = [
    "DEFAULT_NLOS_BIAS_MEAN_S",
    "ChannelDraw",
    "ChannelSpec",
    "Scenario",
    "draw_links",
    "load_file",
    "load_scenario",
    "scenario_names",
    "two_way_composite",
]

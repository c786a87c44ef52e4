"""One realization of a network's received waveforms: the composition every consumer shares.

:func:`simulate_realization` is what ``phyloc generate`` stores and what ``phyloc evaluate``
runs on when given a recipe instead of a dataset, so the two give identical signals for the
same random stream. Random numbers are consumed in a fixed order: network (deployment and
motion), then per snapshot the channel draw of every link, then the pilot symbols (once), then
per snapshot the noise of every link.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

WINNER II: IST-4-027756 WINNER II Deliverable D1.1.2 V1.2, Part I (channel models), 2007,
updated 2008; the table each value of the shipped channel files comes from is given in
``channels/PROVENANCE.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from phyloc.channels import ChannelDraw, ChannelSpec
from phyloc.errors import ValidationError
from phyloc.network import Network, NetworkSpec, make_network
from phyloc.phy.synthesis import synthesize
from phyloc.phy.system import OFDMSystem
from phyloc.phy.waveform import qpsk_symbols


@dataclass(frozen=True, eq=False)
class Realization:
    """Received signals of every link of a network over its snapshots.

    Attributes
    ----------
    network : Network
    symbols : [n_nodes, N] complex128  pilot symbols of each node (transmitter)
    links : list of [n_links_t, 2] int64  directed links (u receives from v) per snapshot
    received : list of [n_links_t, N] complex128  frequency-domain received symbols ``R_n``
    channels : list of ChannelDraw  the channel truth per snapshot
    ways : int  1 (one-way) or 2 (two-way ranging: delays are round trips)
    """

    network: Network
    symbols: np.ndarray
    links: list
    received: list
    channels: list
    ways: int

    @property
    def n_snapshots(self) -> int:
        """Number of snapshots."""
        return len(self.links)


def check_heights(networks, channels) -> None:
    """Refuse, before any work, a ``[channel] heights = "nodes"`` with a 2-D network (a node's
    height is its third coordinate). ``networks``, ``channels``: specs, or iterables of them."""
    nets = [networks] if isinstance(networks, NetworkSpec) else list(networks)
    chans = [channels] if isinstance(channels, ChannelSpec) else list(channels)
    if any(c.heights == "nodes" for c in chans) and any(n.dim != 3 for n in nets):
        raise ValidationError(
            "channel.heights", "nodes", "needs network.dim = 3 (a node's height is its z)"
        )


def simulate_realization(
    system: OFDMSystem, network: NetworkSpec, channel: ChannelSpec, rng: np.random.Generator
) -> Realization:
    """Draw a network, its channels and the received signals of all links and snapshots."""
    check_heights(network, channel)
    net = make_network(network, rng)
    links, draws = [], []
    for t in range(net.n_snapshots):
        lk = net.links_at(t)
        links.append(lk)
        heights = None
        if channel.heights == "nodes":  # (transmitter, receiver): u receives from v
            z = net.positions[t][:, 2]
            heights = (z[lk[:, 1]], z[lk[:, 0]])
        draws.append(channel.draw(net.distances(t), rng, system=system, heights=heights))
    symbols = qpsk_symbols(system, net.n_nodes, rng)
    received = [
        synthesize(d.paths, symbols, system, rng, tx_index=lk[:, 1])
        for lk, d in zip(links, draws, strict=True)
    ]
    ways = 2 if channel.ranging == "two_way" else 1
    return Realization(net, symbols, links, received, draws, ways)


__all__ = ["ChannelDraw", "Realization", "check_heights", "simulate_realization"]

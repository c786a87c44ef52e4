"""The ``[channel]`` section of a recipe (:class:`ChannelSpec`) and two-way ranging's composite
channel (:func:`two_way_composite`): what a recipe says about the channel, turned into the
per-link draws of :func:`phyloc.channels.sampler.draw_links`.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020. Two-way ranging: its §II-B.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc._validate import from_table
from phyloc.channels.sampler import (
    ChannelDraw,
    _conditions,
    _environment_height,
    draw_links,
)
from phyloc.channels.scenario import CONDITIONS, Scenario, load_scenario
from phyloc.errors import ValidationError
from phyloc.phy.paths import PathSet
from phyloc.phy.system import OFDMSystem

RANGING_MODES = ("one_way", "two_way")
#: ``[channel] heights``: the recipe's two antenna heights, or each node's own (3-D networks).
HEIGHTS = ("fixed", "nodes")


def two_way_composite(forward: PathSet, backward: PathSet) -> PathSet:
    """Composite channel of two-way ranging: the convolution of forward and backward channels.

    For every link, every pair of a forward path ``(τ_i, α_i)`` and a backward path
    ``(τ'_j, α'_j)`` gives a composite path ``(τ_i + τ'_j, α_i·α'_j)`` (DiPNet §II-B: two-way
    ranging is analogous to synchronized one-way ranging over the convolution of the forward
    and backward channels).

    Parameters
    ----------
    forward, backward : PathSet
        One-way channels of the same ``n_links`` links.

    Returns
    -------
    PathSet
        ``n_paths = forward.n_paths · backward.n_paths`` per link; the pairs of link k are
        ordered forward-major (``i`` outer, ``j`` inner).

    Examples
    --------
    >>> f = PathSet.from_lists([[1.0, 2.0]], [[1.0, 0.5]])
    >>> b = PathSet.from_lists([[10.0]], [[2.0j]])
    >>> c = two_way_composite(f, b)
    >>> c.delays.tolist(), c.gains.tolist()
    ([11.0, 12.0], [2j, 1j])
    """
    if not isinstance(forward, PathSet) or not isinstance(backward, PathSet):
        raise ValidationError("forward/backward", type(forward).__name__, "two PathSet objects")
    if forward.n_links != backward.n_links:
        raise ValidationError(
            "backward", f"{backward.n_links} links", f"must match forward ({forward.n_links})"
        )
    n = forward.n_links
    nf, nb = forward.n_paths, backward.n_paths
    cnt = nf * nb
    off = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(cnt, out=off[1:])
    link = np.repeat(np.arange(n), cnt)
    k = np.arange(off[-1]) - off[link]
    nbl = nb[link]
    fi = forward.offsets[link] + k // nbl
    bj = backward.offsets[link] + k % nbl
    delays = forward.delays[fi] + backward.delays[bj]
    return PathSet(delays, forward.gains[fi] * backward.gains[bj], off)


# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ChannelSpec:
    """The ``[channel]`` section of a recipe.

    Parameters
    ----------
    scenario : str
        Scenario name or path of a scenario file (:func:`~phyloc.channels.scenario_names`).
        Default ``"winner2_c2"``.
    ranging : {"one_way", "two_way"}
        Synchronized one-way ranging (default) or two-way ranging (composite channel,
        DiPNet §II-B).
    nlos_bias_mean_s : float or None
        Mean NLOS bias [s] (>= 0); ``None`` uses the scenario file's value.
    h_tx_m, h_rx_m : float
        Antenna heights [m] (> 0), default 1.5 m.
    condition : {None, "los", "nlos"}
        Force every link's condition; ``None`` draws it from P_LOS(d).
    backward_carrier_frequency_hz : float or None
        Two-way ranging only: carrier frequency [Hz], > 0, of the backward (responder →
        initiator) transmission, e.g. 5.7e9 with a 5.5e9 forward carrier (DiPNet §V-B uses
        different frequencies for forward and backward links). It enters the backward
        draw's path loss, which must be within the scenario's validity range. ``None``
        (default): the system's carrier, as the forward draw.
    h_e_m : float or None
        tr38901 scenarios only: environment height ``h_E`` [m] (>= 0) of the breakpoint
        distance (TR 38.901 Table 7.4.1-1); ``None`` (default): the scenario file's.
    heights : {"fixed", "nodes"}
        ``"fixed"`` (default): every link's ends are at ``h_tx_m`` / ``h_rx_m``. ``"nodes"``:
        each end is at its node's height, the third coordinate of a 3-D network (anchors on
        a ceiling, devices near the floor); ``h_tx_m`` / ``h_rx_m`` are then unused.
    """

    scenario: str = "winner2_c2"
    ranging: str = "one_way"
    nlos_bias_mean_s: float | None = None
    h_tx_m: float = 1.5
    h_rx_m: float = 1.5
    condition: str | None = None
    backward_carrier_frequency_hz: float | None = None
    h_e_m: float | None = None
    heights: str = "fixed"

    def __post_init__(self):
        if not isinstance(self.scenario, str):
            raise ValidationError("channel.scenario", self.scenario, "a scenario name or path")
        if self.ranging not in RANGING_MODES:
            raise ValidationError("channel.ranging", self.ranging, "'one_way' or 'two_way'")
        if self.nlos_bias_mean_s is not None:
            object.__setattr__(
                self,
                "nlos_bias_mean_s",
                v.positive("channel.nlos_bias_mean_s", self.nlos_bias_mean_s, allow_zero=True),
            )
        object.__setattr__(self, "h_tx_m", v.positive("channel.h_tx_m", self.h_tx_m))
        object.__setattr__(self, "h_rx_m", v.positive("channel.h_rx_m", self.h_rx_m))
        if self.heights not in HEIGHTS:
            raise ValidationError("channel.heights", self.heights, "'fixed' or 'nodes'")
        if self.condition is not None and self.condition not in CONDITIONS:
            raise ValidationError("channel.condition", self.condition, "'los', 'nlos' or absent")
        scn = self.load()
        if self.condition is not None:
            _conditions(scn, self.condition, np.ones(1), None)
        fb = self.backward_carrier_frequency_hz
        if fb is not None:
            key = "channel.backward_carrier_frequency_hz"
            fb = v.positive(key, fb)
            if self.ranging != "two_way":
                raise ValidationError(
                    key, fb, "only used with ranging = 'two_way' (remove it or set that)"
                )
            try:
                scn.check_frequency(fb)
            except ValidationError as err:
                raise ValidationError(key, fb, err.allowed) from None
            object.__setattr__(self, "backward_carrier_frequency_hz", fb)
        if self.h_e_m is not None:
            try:
                h_e = _environment_height(scn, self.h_e_m)
            except ValidationError as err:
                raise ValidationError("channel.h_e_m", self.h_e_m, err.allowed) from None
            object.__setattr__(self, "h_e_m", h_e)

    def load(self) -> Scenario:
        """The validated :class:`Scenario`."""
        return load_scenario(self.scenario)

    @classmethod
    def from_dict(cls, d: dict, *, section: str = "channel") -> ChannelSpec:
        """Build from a recipe section; unknown keys name the closest valid key."""
        return from_table(cls, d, section)

    def to_dict(self) -> dict:
        """The fields as a plain dict (``None`` entries dropped: TOML has no null)."""
        return {
            f.name: getattr(self, f.name)
            for f in dataclasses.fields(self)
            if getattr(self, f.name) is not None
            and not (f.name == "heights" and self.heights == "fixed")  # the default
        }

    def draw(
        self, distances_m, rng: np.random.Generator, *, system=None, heights=None
    ) -> ChannelDraw:
        """Draw the channels of a batch of links.

        One-way: :func:`draw_links`. Two-way: the condition is drawn once per link (it is a
        property of the geometry), then the forward and backward channels are drawn
        independently given it. The responder amplifies and forwards what it receives at its
        transmit power, so the forward gains are normalised by ``√P_forward`` and the
        composite ``two_way_composite(forward/√P_f, backward)`` carries exactly the backward
        received power. Delays are round-trip: ``τ ≥ 2d/c0 + b_f + b_b``. The forward draw
        uses the system's carrier, the backward draw ``backward_carrier_frequency_hz`` when
        given (a copy of ``system`` with that carrier). The random streams are consumed alike
        either way; only the backward link's frequency-dependent quantities change (its path
        loss and, for a dual-slope law, the breakpoint distance and hence possibly σ_SF).

        ``heights``: ``(h_tx, h_rx)`` per link [m] (``heights = "nodes"``: the transmitter's
        and the receiver's node heights), replacing ``h_tx_m`` / ``h_rx_m``.
        """
        h_tx, h_rx = (self.h_tx_m, self.h_rx_m) if heights is None else heights
        kw = dict(
            system=system,
            nlos_bias_mean_s=self.nlos_bias_mean_s,
            h_tx_m=h_tx,
            h_rx_m=h_rx,
            h_e_m=self.h_e_m,
        )
        scn = self.load()
        fwd = draw_links(scn, distances_m, rng, condition=self.condition, **kw)
        if self.ranging == "one_way":
            return fwd
        kw["h_tx_m"], kw["h_rx_m"] = h_rx, h_tx
        if self.backward_carrier_frequency_hz is not None:
            base = OFDMSystem() if system is None else system
            kw["system"] = dataclasses.replace(
                base, carrier_frequency_hz=self.backward_carrier_frequency_hz
            )
        bwd = draw_links(scn, fwd.distances_m, rng, condition=fwd.los, **kw)
        p = fwd.paths
        scale = 1.0 / np.sqrt(fwd.received_power_w)[p.link_index()]
        relay = PathSet(p.delays, p.gains * scale, p.offsets)
        return dataclasses.replace(
            bwd,
            paths=two_way_composite(relay, bwd.paths),
            nlos_bias_s=fwd.nlos_bias_s + bwd.nlos_bias_s,
            ranging="two_way",
            components=(fwd, bwd),
        )


__all__ = ["HEIGHTS", "RANGING_MODES", "ChannelSpec", "two_way_composite"]

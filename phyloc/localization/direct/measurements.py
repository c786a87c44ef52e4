"""Measurements of the direct family: links, anchors, correlation tables or ranges — no truth.

:class:`LinkMeasurements` is what every method of :mod:`phyloc.localization.direct` consumes:
the problem size (``n_nodes``, ``dim``), the anchors as known positions, the directed links of
each snapshot and, per snapshot, the link correlation tables (DiPNet's input, DiPNet eq. (23))
and/or the ranges of one or more range estimators (:class:`LinkRanges`, the two-step input).
Agents are the nodes that are not anchors, in increasing node order; nothing here knows where
they are. Recorded data from real radios fills the same fields.

Examples
--------
Three anchors and one agent, one snapshot, ranges from an estimator called ``"corr"``:

>>> import numpy as np
>>> links = np.array([[3, 0], [3, 1], [3, 2]])
>>> ranges = LinkRanges.single(np.array([5.0, 5.0, 5.0]), np.full(3, 0.01))
>>> meas = LinkMeasurements(
...     n_nodes=4, dim=2, anchor_nodes=[0, 1, 2],
...     anchor_positions=[[[0.0, 0.0], [8.0, 0.0], [4.0, 8.0]]],
...     links=[links], ranges={"corr": ranges})
>>> meas.n_snapshots, meas.n_agents, meas.agent_nodes.tolist()
(1, 1, [3])

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from phyloc.errors import ValidationError
from phyloc.phy.correlation import CorrelationTable


def _per_snapshot(name, seq, n_snap=None):
    if isinstance(seq, np.ndarray | CorrelationTable) or seq is None:
        raise ValidationError(name, type(seq).__name__, "a sequence with one entry per snapshot")
    out = tuple(seq)
    if n_snap is not None and len(out) != n_snap:
        raise ValidationError(name, f"{len(out)} snapshots", f"{n_snap} (one per snapshot)")
    return out


@dataclass(frozen=True, eq=False)
class LinkRanges:
    """Range estimates of every link of every snapshot (one range estimator).

    Attributes
    ----------
    range_m : tuple of [n_links_t] float64
        One-way distance estimates [m] per snapshot (two-way estimates already halved).
    variance_m2 : tuple of [n_links_t] float64
        Model variances of the estimates [m²] (DiPNet §V-A: the ranging ZZB).
    valid : tuple of [n_links_t] bool
        Links with a usable range (False: left out of the likelihood).
    """

    range_m: tuple
    variance_m2: tuple
    valid: tuple

    def __post_init__(self):
        r = _per_snapshot("ranges.range_m", self.range_m)
        n = len(r)
        var = _per_snapshot("ranges.variance_m2", self.variance_m2, n)
        ok = _per_snapshot("ranges.valid", self.valid, n)
        r = tuple(np.asarray(x, dtype=np.float64) for x in r)
        var = tuple(np.asarray(x, dtype=np.float64) for x in var)
        ok = tuple(np.asarray(x, dtype=bool) for x in ok)
        for t in range(n):
            if not (r[t].ndim == 1 and r[t].shape == var[t].shape == ok[t].shape):
                raise ValidationError(
                    f"ranges[{t}]",
                    f"shapes {r[t].shape}, {var[t].shape}, {ok[t].shape}",
                    "range_m, variance_m2 and valid of equal shape [n_links]",
                )
        object.__setattr__(self, "range_m", r)
        object.__setattr__(self, "variance_m2", var)
        object.__setattr__(self, "valid", ok)

    @classmethod
    def single(cls, range_m, variance_m2, valid=None) -> LinkRanges:
        """Ranges of one snapshot (``valid`` default: finite ranges)."""
        r = np.asarray(range_m, dtype=np.float64)
        ok = np.isfinite(r) if valid is None else valid
        return cls((r,), (variance_m2,), (ok,))

    @property
    def n_snapshots(self) -> int:
        """Number of snapshots."""
        return len(self.range_m)


@dataclass(frozen=True, eq=False)
class LinkMeasurements:
    """What the direct family localizes from (never the agents' positions).

    Attributes
    ----------
    n_nodes : int
        Nodes in the network (anchors and agents).
    dim : int
        Dimension of the positions (2 or 3).
    anchor_nodes : [n_anchors] int
        Node indices of the anchors (may be empty: an anchor-free network).
    anchor_positions : [T, n_anchors, dim] float64
        Known anchor positions per snapshot [m].
    links : tuple of [n_links_t, 2] int
        Directed links ``(u, v)`` per snapshot: node u received from node v (rx, tx).
    tables : tuple of CorrelationTable, optional
        One table per snapshot, row j belonging to ``links[t][j]`` (direct likelihoods).
    ranges : mapping str -> LinkRanges
        Range estimates by estimator name (e.g. ``"corr"``, ``"sage"``), rows as ``links``
        (two-step likelihoods; a method's ``inputs = "ranges:<name>"`` names its estimator).
    ways : int
        1 for synchronized one-way tables, 2 for two-way tables (the table's distance axis is
        the round trip).
    window_m : (float, float)
        Search window of the correlation peak [m] (direct likelihoods, DiPNet eq. (21)).
    usable : tuple of [n_links_t] bool, optional
        Links an NLOS identification kept (e.g. by the energy concentration of
        :func:`phyloc.ranging.nlos.energy_concentration`); the others are left out of every
        likelihood, direct and two-step. None: every link.
    """

    n_nodes: int
    dim: int
    anchor_nodes: np.ndarray
    anchor_positions: np.ndarray
    links: tuple
    tables: tuple | None = None
    ranges: Mapping = field(default_factory=dict)
    ways: int = 1
    window_m: tuple = (0.0, 300.0)
    usable: tuple | None = None

    def __post_init__(self):
        n_nodes = int(self.n_nodes)
        dim = int(self.dim)
        if n_nodes < 1:
            raise ValidationError("n_nodes", self.n_nodes, ">= 1")
        if dim not in (1, 2, 3):
            raise ValidationError("dim", self.dim, "1, 2 or 3")
        links = tuple(np.asarray(x, dtype=np.int64) for x in _per_snapshot("links", self.links))
        T = len(links)
        if T < 1:
            raise ValidationError("links", "no snapshot", "at least one snapshot")
        for t, lk in enumerate(links):
            if lk.ndim != 2 or lk.shape[1] != 2:
                raise ValidationError(f"links[{t}]", f"shape {lk.shape}", "[n_links, 2] (rx, tx)")
            if lk.size and (lk.min() < 0 or lk.max() >= n_nodes):
                raise ValidationError(f"links[{t}]", "a node index", f"in [0, {n_nodes})")
        nodes = np.asarray(self.anchor_nodes, dtype=np.int64).reshape(-1)
        if nodes.size and (nodes.min() < 0 or nodes.max() >= n_nodes):
            raise ValidationError("anchor_nodes", nodes.tolist(), f"node indices in [0, {n_nodes})")
        if np.unique(nodes).size != nodes.size:
            raise ValidationError("anchor_nodes", nodes.tolist(), "distinct node indices")
        pos = np.asarray(self.anchor_positions, dtype=np.float64)
        if nodes.size == 0 and pos.size == 0:
            pos = np.zeros((T, 0, dim))
        if pos.shape != (T, nodes.size, dim) or not np.all(np.isfinite(pos)):
            raise ValidationError(
                "anchor_positions", f"shape {pos.shape}", f"finite [T={T}, {nodes.size}, {dim}]"
            )
        if self.tables is not None:
            tables = _per_snapshot("tables", self.tables, T)
            for t, tab in enumerate(tables):
                if not isinstance(tab, CorrelationTable) or tab.n_links != len(links[t]):
                    raise ValidationError(
                        f"tables[{t}]", type(tab).__name__, f"a CorrelationTable of {len(links[t])}"
                    )
            object.__setattr__(self, "tables", tables)
        ranges = dict(self.ranges)
        for name, rs in ranges.items():
            if not isinstance(rs, LinkRanges) or rs.n_snapshots != T:
                raise ValidationError(f"ranges[{name!r}]", type(rs).__name__, f"LinkRanges of {T}")
            for t in range(T):
                if rs.range_m[t].size != len(links[t]):
                    raise ValidationError(
                        f"ranges[{name!r}][{t}]", f"{rs.range_m[t].size} links", len(links[t])
                    )
        if self.usable is not None:
            usable = tuple(
                np.asarray(u, dtype=bool) for u in _per_snapshot("usable", self.usable, T)
            )
            for t, u in enumerate(usable):
                if u.shape != (len(links[t]),):
                    raise ValidationError(f"usable[{t}]", f"shape {u.shape}", f"[{len(links[t])}]")
            object.__setattr__(self, "usable", usable)
        if int(self.ways) not in (1, 2):
            raise ValidationError("ways", self.ways, "1 (one-way) or 2 (two-way)")
        lo, hi = (float(x) for x in self.window_m)
        if not 0 <= lo < hi:
            raise ValidationError("window_m", self.window_m, "(lo, hi) with 0 <= lo < hi [m]")
        object.__setattr__(self, "n_nodes", n_nodes)
        object.__setattr__(self, "dim", dim)
        object.__setattr__(self, "anchor_nodes", nodes)
        object.__setattr__(self, "anchor_positions", pos)
        object.__setattr__(self, "links", links)
        object.__setattr__(self, "ranges", ranges)
        object.__setattr__(self, "ways", int(self.ways))
        object.__setattr__(self, "window_m", (lo, hi))

    @property
    def n_snapshots(self) -> int:
        """Number of snapshots T."""
        return len(self.links)

    @property
    def is_anchor(self) -> np.ndarray:
        """``[n_nodes]`` bool: True for anchors."""
        mask = np.zeros(self.n_nodes, bool)
        mask[self.anchor_nodes] = True
        return mask

    @property
    def agent_nodes(self) -> np.ndarray:
        """``[n_agents]`` int: node index of each agent (the non-anchors, increasing)."""
        return np.flatnonzero(~self.is_anchor)

    @property
    def n_agents(self) -> int:
        """Number of agents."""
        return self.n_nodes - self.anchor_nodes.size

    def agent_of_node(self) -> np.ndarray:
        """``[n_nodes]`` int: agent index of each node, −1 for anchors."""
        out = -np.ones(self.n_nodes, np.int64)
        out[self.agent_nodes] = np.arange(self.n_agents)
        return out

    def table(self, t: int) -> CorrelationTable:
        """The correlation table of snapshot ``t`` (error when the measurements have none)."""
        if self.tables is None:
            raise ValidationError("measurements.tables", None, "correlation tables per snapshot")
        return self.tables[t]

    def usable_links(self, t: int) -> np.ndarray:
        """``[n_links_t]`` bool: the links of snapshot ``t`` the likelihoods may use."""
        if self.usable is None:
            return np.ones(len(self.links[t]), bool)
        return self.usable[t]

    def range_set(self, name: str) -> LinkRanges:
        """The ranges of the estimator ``name``."""
        if name not in self.ranges:
            have = ", ".join(self.ranges) or "none"
            raise ValidationError("measurements.ranges", name, f"one of the given ({have})")
        return self.ranges[name]

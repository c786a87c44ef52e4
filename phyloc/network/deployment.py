"""Network deployments: agents, anchors, connectivity, directed links and trajectories.

A :class:`NetworkSpec` (the ``[network]`` recipe section) describes a network; a seed makes it
(:func:`make_network`), and the result is a plain :class:`Network` of arrays.

Conventions (DiPNet §II-A; PF-BP §II):

- **Node order**: :func:`make_network` puts the agents first (nodes ``0 … n_agents−1``) and the
  anchors last (``n_agents … n_nodes−1``), as in the PF-BP joint state vector. A
  :class:`Network` built by hand may order them freely; use :attr:`Network.agent_index` and
  :attr:`Network.anchor_index`.
- **Links** are directed pairs ``(u, v)`` meaning "u receives from v". Both directions of every
  connected pair are listed (two-way ranging measures both). Anchor–anchor pairs carry no
  measurement and are not links (DiPNet's virtual anchor links, §II-A, are implied by
  :attr:`Network.is_anchor`). Links are sorted lexicographically by ``(u, v)``.
- **Connectivity**: ``u`` and ``v`` are connected at a snapshot when their distance is
  ``<= comm_range_m`` (or always, for a fully meshed network); links change with motion.
- **Agents** are uniform in the region at snapshot 0, or placed explicitly (``agents_m``).
  The DiPNet experiments (§V-B) are written as explicit agents plus a waypoint rover: five
  stationary agents on a regular pentagon (:func:`pentagon` gives the coordinates to paste
  into a recipe) and a sixth agent moved by ``[network.motion] model = "waypoints"``::

      [network]
      n_agents = 6
      agents_m = [[25.0, 47.5], [17.87, 42.32], [20.59, 33.93], [29.41, 33.93],
                  [32.13, 42.32], [0.0, 0.0]]   # pentagon(15.0, [25.0, 40.0]) + the rover
      [network.motion]
      model = "waypoints"
      movers = [5]
      waypoints_m = [[5.0, 5.0], [45.0, 5.0], [45.0, 75.0], [5.0, 75.0]]
      speeds_m_s = 1.0
      loop = true
      corner_radius_m = 3.0
      n_snapshots = 260
      dt_s = 1.0

  (the rover's ``agents_m`` entry is a placeholder: its first waypoint overrides it).

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from phyloc import _validate as v
from phyloc._validate import check_keys, check_types
from phyloc.errors import ValidationError
from phyloc.network.motion import MotionSpec, simulate_motion

#: Rules placing a count of anchors (:attr:`NetworkSpec.anchor_layout`).
ANCHOR_LAYOUTS = ("corners", "corners_center", "grid", "uniform")
#: What :func:`make_network` does when a node has no neighbour.
ON_ISOLATED = ("error", "warn", "allow")
#: Side length per axis [m] when ``region_m`` is not given.
DEFAULT_SIDE_M = 100.0


class IsolatedNodesWarning(UserWarning):
    """A communication range leaves nodes without neighbours (``on_isolated="warn"``)."""


def pentagon(diameter_m: float, center, rotation_deg: float = 90.0) -> np.ndarray:
    """Vertices of a regular pentagon in the plane (DiPNet §V-B: five stationary agents).

    Parameters
    ----------
    diameter_m : float
        Diameter ``D`` of the circumscribed circle [m], > 0 (every vertex is at ``D/2`` from
        the centre; the side length is ``D·sin 36°``). DiPNet's "dimension" of the formation
        (15 m and 30 m) is read as this diameter.
    center : [2] float64
        Centre [m].
    rotation_deg : float, optional
        Polar angle of the first vertex [deg]; the others follow counter-clockwise every 72°.
        Default 90 (first vertex straight "up", +y).

    Returns
    -------
    vertices : [5, 2] float64
        ``center + D/2·(cos φ_k, sin φ_k)``, ``φ_k = rotation_deg + 72°·k``, ``k = 0 … 4``.

    Examples
    --------
    >>> pentagon(15.0, [25.0, 40.0]).round(2).tolist()[:2]
    [[25.0, 47.5], [17.87, 42.32]]
    """
    d = v.positive("diameter_m", diameter_m)
    c = v.finite_array("center", center, ndim=1)
    if c.shape != (2,):
        raise ValidationError("center", f"shape {c.shape}", "must be a 2-D point [x, y]")
    rot = v.finite("rotation_deg", rotation_deg)
    phi = np.deg2rad(rot + 72.0 * np.arange(5))
    return c[None] + 0.5 * d * np.stack([np.cos(phi), np.sin(phi)], axis=1)


def corner_order(dim: int) -> np.ndarray:
    """The ``2**dim`` corners of the unit box in the order anchors are placed.

    Corners are sorted by their number of non-zero coordinates, so the first ``dim + 1`` are the
    origin and the unit points of the axes: any ``dim + 1`` leading corners are affinely
    independent (3 anchors span the square, 4 anchors the cube, never a face).

    Returns
    -------
    corners : [2**dim, dim] float64 of 0/1
        2-D: (0,0), (1,0), (0,1), (1,1). 3-D: (0,0,0), (1,0,0), (0,1,0), (0,0,1), (1,1,0),
        (1,0,1), (0,1,1), (1,1,1).
    """
    bits = list(itertools.product((0, 1), repeat=dim))
    bits.sort(key=lambda b: (sum(b), [-x for x in b]))
    return np.array(bits, dtype=np.float64)


def anchor_positions(
    layout: str, n_anchors: int, region_m, rng: np.random.Generator | None = None
) -> np.ndarray:
    """Anchor coordinates placed by a rule inside the box ``[0, side]`` per axis.

    Parameters
    ----------
    layout : {"corners", "corners_center", "grid", "uniform"}
        ``"corners"``: the first ``n_anchors`` corners of the region in the order of
        :func:`corner_order` (``n_anchors <= 2**dim``). ``"corners_center"``: the first
        ``n_anchors − 1`` corners and the centre of the region, last (``n_anchors <= 2**dim +
        1``; 9 anchors in 3-D are PF-BP Scenario I's 8 cube corners + centre). ``"grid"``: a
        regular ``m × … × m`` grid at the cell centres ``(i + ½)·side/m``, ``i = 0 … m−1``,
        listed with axis 0 fastest (``n_anchors = m**dim``). ``"uniform"``: independent
        uniform draws in the region (needs ``rng``).
    n_anchors : int
        >= 1.
    region_m : sequence of float
        Side lengths [m]; its length is the dimension.
    rng : numpy.random.Generator, optional
        Used by ``"uniform"`` only.

    Returns
    -------
    positions : [n_anchors, dim] float64 [m]
    """
    v.choice("network.anchor_layout", layout, ANCHOR_LAYOUTS)
    side = np.asarray(region_m, dtype=np.float64)
    dim = side.size
    n = v.integer("network.anchors", n_anchors, minimum=1)
    if layout == "uniform":
        if rng is None:
            raise ValidationError("rng", None, "anchor_layout='uniform' needs a Generator")
        return rng.uniform(0.0, side, size=(n, dim))
    if layout == "grid":
        m = round(n ** (1.0 / dim))
        if m**dim != n:
            lo = max(1, int(n ** (1.0 / dim)))
            raise ValidationError(
                "network.anchors",
                n,
                f"anchor_layout='grid' needs m**{dim} anchors "
                f"(e.g. {lo**dim} or {(lo + 1) ** dim})",
            )
        ticks = (np.arange(m) + 0.5) / m
        mesh = np.stack(np.meshgrid(*([ticks] * dim), indexing="ij"), axis=-1)
        unit = mesh.transpose(*reversed(range(dim)), dim).reshape(-1, dim)
        return unit * side
    corners = corner_order(dim)
    n_corners = corners.shape[0]
    if layout == "corners":
        if n > n_corners:
            raise ValidationError(
                "network.anchors",
                n,
                f"anchor_layout='corners' places at most {n_corners} in {dim}-D",
            )
        return corners[:n] * side
    if n > n_corners + 1:
        raise ValidationError(
            "network.anchors",
            n,
            f"anchor_layout='corners_center' places at most {n_corners + 1} in {dim}-D",
        )
    return np.vstack([corners[: n - 1], np.full((1, dim), 0.5)]) * side


@dataclass(frozen=True)
class NetworkSpec:
    """A network recipe: agents, anchors, connectivity and motion (the ``[network]`` section).

    Parameters
    ----------
    n_agents : int
        Number of agents, >= 1 (>= 2 without anchors). Their snapshot-0 positions are uniform
        in the region unless ``agents_m`` gives them.
    dim : int
        2 or 3. Default 2.
    region_m : tuple of float, optional
        Side lengths of the deployment box ``[0, side_0] × … × [0, side_{dim−1}]`` [m], one per
        axis, each > 0. Default ``(100.0,) * dim``.
    anchors : None, int or list of coordinates
        ``None`` or 0: anchor-free (only the shape of the network is observable, DiPNet §II-A).
        An int: that many anchors placed by ``anchor_layout``. A list of ``dim``-vectors:
        explicit anchor coordinates [m] (finite; they may lie outside the region).
    anchor_layout : {"corners", "corners_center", "grid", "uniform"}
        Rule used when ``anchors`` is an int; see :func:`anchor_positions`. Default
        ``"corners"``.
    comm_range_m : float, optional
        Communication range [m], > 0: two nodes are neighbours at a snapshot when their
        distance is <= this range. ``None`` (default): fully meshed. Links of a range-limited
        network are found with a k-d tree (:class:`scipy.spatial.cKDTree`), in
        ``O(n log n + n_links)``: no ``n × n`` matrix is built, so networks of thousands of
        nodes cost what their links cost.
    density_per_km2 : float, optional
        Constant-density deployment (2-D only): the region is the square that holds
        ``n_agents`` at this many agents per km² — side ``sqrt(n_agents / density) km`` —
        so networks of any size have the same density and, with ``comm_range_m``, the same
        mean number of neighbours (``density · π · comm_range² `` away from the border).
        30 agents per 100 m × 100 m is ``3000``. Excludes ``region_m``.
    on_isolated : {"error", "warn", "allow"}
        What :func:`make_network` does when, at some snapshot, a node has no neighbour:
        raise :class:`~phyloc.errors.ValidationError` naming the nodes and the range
        (default), emit :class:`IsolatedNodesWarning`, or accept it silently.
    motion : MotionSpec
        Agent motion over the snapshots (anchors are static). Default: static, 1 snapshot.
        With ``model = "waypoints"`` the movers must be agent indices ``< n_agents`` and the
        waypoints ``dim``-vectors.
    agents_m : list of coordinates, optional
        Explicit snapshot-0 agent positions [m]: ``n_agents`` finite ``dim``-vectors (they may
        lie outside the region), agent ``i`` at row ``i``. Given, :func:`make_network` draws
        no agent positions; absent (default), it draws them uniformly as before. A waypoint
        mover's row is overridden by its first waypoint. There is no pentagon shorthand in
        recipes (a table cannot say where the other agents go): paste the coordinates of
        :func:`pentagon`.
    agent_height_m : float, optional
        3-D networks with drawn agents: every agent's snapshot-0 height (its third coordinate)
        [m], > 0, instead of a uniform draw — devices at a common height under anchors on
        the ceiling (the TR 38.901 InF layouts). The draws are those without it (the drawn
        heights are replaced), so the horizontal positions do not change.
    cooperation : bool
        True (default): agents measure each other as well as the anchors. False: only
        agent–anchor links (a non-cooperative network; anchors required), the baseline a
        cooperative method is compared with.

    Examples
    --------
    >>> spec = NetworkSpec.from_dict({"n_agents": 20, "dim": 3, "region_m": [20, 20, 20],
    ...                               "anchors": 9, "anchor_layout": "corners_center",
    ...                               "comm_range_m": 18.0, "on_isolated": "allow",
    ...                               "motion": {"model": "constant_acceleration",
    ...                                          "n_snapshots": 50}})
    >>> net = make_network(spec, np.random.default_rng(1))
    >>> net.positions.shape, net.n_anchors
    ((50, 29, 3), 9)
    """

    n_agents: int
    dim: int = 2
    region_m: tuple[float, ...] | None = None
    anchors: int | tuple | list | None = None
    anchor_layout: str = "corners"
    comm_range_m: float | None = None
    on_isolated: str = "error"
    motion: MotionSpec = field(default_factory=MotionSpec)
    agents_m: tuple[tuple[float, ...], ...] | None = None
    density_per_km2: float | None = None
    agent_height_m: float | None = None
    cooperation: bool = True

    def __post_init__(self):
        s = "network"
        n_agents = v.integer(f"{s}.n_agents", self.n_agents, minimum=1)
        object.__setattr__(self, "n_agents", n_agents)
        dim = v.integer(f"{s}.dim", self.dim)
        if dim not in (2, 3):
            raise ValidationError(f"{s}.dim", self.dim, "must be 2 or 3")
        object.__setattr__(self, "dim", dim)

        region = (DEFAULT_SIDE_M,) * dim if self.region_m is None else self.region_m
        if self.density_per_km2 is not None:
            rho = v.positive(f"{s}.density_per_km2", self.density_per_km2)
            if dim != 2:
                raise ValidationError(
                    f"{s}.density_per_km2", rho, "is a 2-D deployment (network.dim = 2)"
                )
            object.__setattr__(self, "density_per_km2", rho)
            side = 1000.0 * math.sqrt(n_agents / rho)
            region = (side, side)
        try:
            region = tuple(float(x) for x in region)
        except (TypeError, ValueError):
            raise ValidationError(
                f"{s}.region_m", self.region_m, f"must be {dim} side lengths [m]"
            ) from None
        if len(region) != dim:
            raise ValidationError(
                f"{s}.region_m", self.region_m, f"must have dim = {dim} side lengths [m]"
            )
        for x in region:
            v.positive(f"{s}.region_m", x)
        object.__setattr__(self, "region_m", region)

        v.choice(f"{s}.anchor_layout", self.anchor_layout, ANCHOR_LAYOUTS)
        v.choice(f"{s}.on_isolated", self.on_isolated, ON_ISOLATED)
        anchors = self.anchors
        if anchors is None or (isinstance(anchors, (int, np.integer)) and anchors == 0):
            anchors = None
        elif isinstance(anchors, (int, np.integer, float)) and not isinstance(anchors, bool):
            anchors = v.integer(f"{s}.anchors", anchors, minimum=0) or None
        elif isinstance(anchors, (list, tuple, np.ndarray)):
            arr = v.finite_array(f"{s}.anchors", anchors)
            if arr.size == 0:
                anchors = None
            elif arr.ndim != 2 or arr.shape[1] != dim:
                raise ValidationError(
                    f"{s}.anchors",
                    f"array of shape {arr.shape}",
                    f"explicit anchors must be a list of {dim}-D coordinates [m]",
                )
            else:
                anchors = tuple(tuple(float(x) for x in row) for row in arr)
        else:
            raise ValidationError(
                f"{s}.anchors", anchors, "must be None, a count, or a list of coordinates [m]"
            )
        object.__setattr__(self, "anchors", anchors)
        if isinstance(anchors, int) and self.anchor_layout != "uniform":
            anchor_positions(self.anchor_layout, anchors, region)  # checks the count fits
        if n_agents + self.n_anchors < 2:
            raise ValidationError(
                f"{s}.n_agents", n_agents, "an anchor-free network needs at least 2 agents"
            )

        if self.comm_range_m is not None:
            object.__setattr__(
                self, "comm_range_m", v.positive(f"{s}.comm_range_m", self.comm_range_m)
            )
        if isinstance(self.motion, dict):
            object.__setattr__(self, "motion", MotionSpec.from_dict(self.motion))
        elif not isinstance(self.motion, MotionSpec):
            raise ValidationError(f"{s}.motion", self.motion, "must be a MotionSpec or a table")
        m = self.motion
        if m.model == "waypoints":
            if max(m.movers) >= n_agents:
                raise ValidationError(
                    f"{s}.motion.movers",
                    list(m.movers),
                    f"must be agent indices in [0, {n_agents}) (n_agents = {n_agents})",
                )
            wp_dim = len(m.waypoints_m[0])
            if wp_dim != dim:
                raise ValidationError(
                    f"{s}.motion.waypoints_m",
                    f"{wp_dim}-D points",
                    f"must be {dim}-D points (network.dim = {dim})",
                )
        if self.agents_m is not None:
            arr = v.finite_array(f"{s}.agents_m", self.agents_m)
            if arr.ndim != 2 or arr.shape[1] != dim:
                raise ValidationError(
                    f"{s}.agents_m",
                    f"array of shape {arr.shape}",
                    f"must be a list of {dim}-D coordinates [m], one per agent",
                )
            if arr.shape[0] != n_agents:
                raise ValidationError(
                    f"{s}.agents_m",
                    f"{arr.shape[0]} positions",
                    f"must give exactly n_agents = {n_agents} positions",
                )
            object.__setattr__(self, "agents_m", tuple(tuple(float(x) for x in row) for row in arr))
        self._check_height_and_cooperation(s, dim)

    def _check_height_and_cooperation(self, s: str, dim: int) -> None:
        if self.agent_height_m is not None:
            h = v.positive(f"{s}.agent_height_m", self.agent_height_m)
            if dim != 3:
                raise ValidationError(f"{s}.agent_height_m", h, "needs network.dim = 3")
            if self.agents_m is not None:
                raise ValidationError(
                    f"{s}.agent_height_m",
                    h,
                    "cannot be given with agents_m (give the heights there)",
                )
            object.__setattr__(self, "agent_height_m", h)
        if not isinstance(self.cooperation, bool):
            raise ValidationError(f"{s}.cooperation", self.cooperation, "true or false")
        if not self.cooperation and self.n_anchors == 0:
            raise ValidationError(
                f"{s}.cooperation",
                False,
                "a non-cooperative network measures only agent-anchor links: give anchors",
            )

    @property
    def n_anchors(self) -> int:
        """Number of anchors (0 when anchor-free)."""
        if self.anchors is None:
            return 0
        return self.anchors if isinstance(self.anchors, int) else len(self.anchors)

    @property
    def n_nodes(self) -> int:
        """Agents + anchors."""
        return self.n_agents + self.n_anchors

    def replace(self, **changes) -> NetworkSpec:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    @classmethod
    def from_dict(cls, d: dict, *, section: str = "network") -> NetworkSpec:
        """Build from a recipe section (``motion`` a nested table); unknown keys are errors."""
        if not isinstance(d, dict):
            raise ValidationError(section, d, "must be a table (dict) of network settings")
        check_keys(d, [f.name for f in dataclasses.fields(cls)], section)
        check_types(cls, d, section)
        if "n_agents" not in d:
            raise ValidationError(f"{section}.n_agents", None, "is required (number of agents)")
        if "density_per_km2" in d and "region_m" in d:
            raise ValidationError(
                f"{section}.region_m",
                d["region_m"],
                "cannot be given with density_per_km2 (the density sets the region); "
                "delete one of the two",
            )
        d = dict(d)
        if "motion" in d:
            d["motion"] = MotionSpec.from_dict(d["motion"], section=f"{section}.motion")
        return cls(**d)

    def to_dict(self) -> dict:
        """Recipe form (TOML-compatible: ``None`` fields are omitted, tuples become lists)."""
        out = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if value is None or (f.name == "region_m" and self.density_per_km2 is not None):
                continue
            if f.name == "cooperation" and value:  # the default, left out of older recipes
                continue
            if f.name == "motion":
                value = value.to_dict()
            elif f.name == "region_m":
                value = list(value)
            elif f.name in ("anchors", "agents_m") and not isinstance(value, int):
                value = [list(row) for row in value]
            out[f.name] = value
        return out


@dataclass(frozen=True, eq=False)
class Network:
    """A realized network: node positions over snapshots, anchor flags and connectivity.

    Arrays are stored read-only. Links are derived from the positions and the range on demand
    (and cached per snapshot).

    Parameters
    ----------
    positions : [n_snapshots, n_nodes, dim] float64
        True positions [m]; anchors must not move unless ``anchors_move``.
    is_anchor : [n_nodes] bool
    comm_range_m : float, optional
        Communication range [m]; ``None``: fully meshed.
    velocities : [n_snapshots, n_nodes, dim] float64, optional
        [m/s], when the motion model tracks them (CV, CA, waypoints); anchors have zero
        velocity.
    accelerations : [n_snapshots, n_nodes, dim] float64, optional
        [m/s²], CA only.
    dt_s : float, optional
        Sampling period between snapshots [s].
    anchors_move : bool
        Anchors may change position between snapshots (mobile anchors whose trajectory is the
        output of a control loop, :func:`phyloc.control.loop.realized_network`); their
        positions are known to the localizers at every snapshot. Default False: a moving anchor
        is an error.
    cooperative : bool
        False: only agent–anchor pairs are links (:attr:`NetworkSpec.cooperation`).
    """

    positions: np.ndarray
    is_anchor: np.ndarray
    comm_range_m: float | None = None
    velocities: np.ndarray | None = None
    accelerations: np.ndarray | None = None
    dt_s: float | None = None
    anchors_move: bool = False
    cooperative: bool = True
    _links: dict = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self):
        pos = v.finite_array("positions", self.positions, ndim=3).copy()
        if pos.shape[2] not in (2, 3) or pos.shape[1] < 1 or pos.shape[0] < 1:
            raise ValidationError(
                "positions", f"array of shape {pos.shape}", "[n_snapshots >= 1, n_nodes >= 1, 2|3]"
            )
        anchor = np.asarray(self.is_anchor)
        if anchor.dtype != np.bool_ or anchor.shape != (pos.shape[1],):
            raise ValidationError(
                "is_anchor",
                f"{anchor.dtype} array of shape {anchor.shape}",
                f"must be a bool array of shape ({pos.shape[1]},)",
            )
        anchor = anchor.copy()
        moving = v.boolean("anchors_move", self.anchors_move)
        if not moving and np.any(pos[:, anchor] != pos[:1, anchor]):
            raise ValidationError(
                "positions", "moving anchors", "anchors must be static (or anchors_move=True)"
            )
        for arr in (pos, anchor):
            arr.setflags(write=False)
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "is_anchor", anchor)
        for name in ("velocities", "accelerations"):
            value = getattr(self, name)
            if value is not None:
                arr = v.finite_array(name, value, ndim=3).copy()
                if arr.shape != pos.shape:
                    raise ValidationError(
                        name, f"array of shape {arr.shape}", f"must match positions {pos.shape}"
                    )
                arr.setflags(write=False)
                object.__setattr__(self, name, arr)
        if self.comm_range_m is not None:
            object.__setattr__(self, "comm_range_m", v.positive("comm_range_m", self.comm_range_m))
        if self.dt_s is not None:
            object.__setattr__(self, "dt_s", v.positive("dt_s", self.dt_s))

    # -- sizes and indices -------------------------------------------------------------------
    @property
    def n_snapshots(self) -> int:
        """Number of snapshots."""
        return self.positions.shape[0]

    @property
    def n_nodes(self) -> int:
        """Agents + anchors."""
        return self.positions.shape[1]

    @property
    def dim(self) -> int:
        """Spatial dimension (2 or 3)."""
        return self.positions.shape[2]

    @property
    def n_anchors(self) -> int:
        """Number of anchors."""
        return int(self.is_anchor.sum())

    @property
    def n_agents(self) -> int:
        """Number of agents."""
        return self.n_nodes - self.n_anchors

    @property
    def agent_index(self) -> np.ndarray:
        """Node indices of the agents, ascending, int64 ``[n_agents]``."""
        return np.flatnonzero(~self.is_anchor).astype(np.int64)

    @property
    def anchor_index(self) -> np.ndarray:
        """Node indices of the anchors, ascending, int64 ``[n_anchors]``."""
        return np.flatnonzero(self.is_anchor).astype(np.int64)

    # -- connectivity --------------------------------------------------------------------------
    def _snapshot(self, snapshot) -> int:
        k = v.integer("snapshot", snapshot)
        if not -self.n_snapshots <= k < self.n_snapshots:
            raise ValidationError("snapshot", snapshot, f"must be in [0, {self.n_snapshots})")
        return k % self.n_snapshots

    def distance_matrix(self, snapshot: int = 0) -> np.ndarray:
        """Pairwise true distances ``d_uv`` [m], ``[n_nodes, n_nodes]`` float64."""
        p = self.positions[self._snapshot(snapshot)]
        return np.linalg.norm(p[:, None, :] - p[None, :, :], axis=-1)

    def adjacency(self, snapshot: int = 0) -> np.ndarray:
        """Who hears whom: ``[n_nodes, n_nodes]`` bool, symmetric, zero diagonal.

        ``u`` and ``v`` are adjacent when ``u != v``, not both are anchors, one of them is an
        anchor if the network is not ``cooperative``, and ``d_uv <= comm_range_m`` (always,
        when fully meshed).
        """
        k = self._snapshot(snapshot)
        n = self.n_nodes
        if self.comm_range_m is not None:
            adj = np.zeros((n, n), dtype=bool)
            lk = self.links_at(k)
            adj[lk[:, 0], lk[:, 1]] = True
            return adj
        adj = ~np.eye(n, dtype=bool)
        adj &= ~(self.is_anchor[:, None] & self.is_anchor[None, :])
        if not self.cooperative:  # agent-anchor links only
            adj &= self.is_anchor[:, None] | self.is_anchor[None, :]
        return adj

    def _range_links(self, k: int) -> np.ndarray:
        """Directed links of a range-limited snapshot, sorted by ``(u, v)``: candidate pairs
        from a k-d tree, kept by the same test as :meth:`adjacency` (``‖p_u − p_v‖ <=
        comm_range_m``, computed as :meth:`distance_matrix` computes it)."""
        from scipy.spatial import cKDTree

        p = self.positions[k]
        r = self.comm_range_m
        pairs = cKDTree(p).query_pairs(r * (1.0 + 1e-9) + 1e-12, output_type="ndarray")
        pairs = pairs.astype(np.int64).reshape(-1, 2)
        d = np.linalg.norm(p[pairs[:, 0]] - p[pairs[:, 1]], axis=-1)
        a0, a1 = self.is_anchor[pairs[:, 0]], self.is_anchor[pairs[:, 1]]
        keep = (d <= r) & ~(a0 & a1)
        if not self.cooperative:  # agent-anchor links only
            keep &= a0 | a1
        pairs = pairs[keep]
        links = np.concatenate([pairs, pairs[:, ::-1]])
        return links[np.lexsort((links[:, 1], links[:, 0]))]

    def links_at(self, snapshot: int) -> np.ndarray:
        """Directed links ``(u, v)`` ("u receives from v") at a snapshot.

        Returns
        -------
        links : [n_links, 2] int64
            Both directions of every connected pair, sorted by ``(u, v)``; read-only.
        """
        k = self._snapshot(snapshot)
        if k not in self._links:
            if self.comm_range_m is None:
                links = np.argwhere(self.adjacency(k)).astype(np.int64)
            else:
                links = self._range_links(k)
            links.setflags(write=False)
            self._links[k] = links
        return self._links[k]

    @property
    def links(self) -> np.ndarray:
        """Directed links at snapshot 0, ``[n_links, 2]`` int64 (see :meth:`links_at`)."""
        return self.links_at(0)

    def distances(self, snapshot: int = 0) -> np.ndarray:
        """True link distances ``d_uv = ||p_u − p_v||`` [m], ``[n_links]``, in link order."""
        k = self._snapshot(snapshot)
        links = self.links_at(k)
        p = self.positions[k]
        return np.linalg.norm(p[links[:, 0]] - p[links[:, 1]], axis=-1)

    def neighbors(self, u: int, snapshot: int = 0) -> np.ndarray:
        """Nodes ``v`` that ``u`` receives from at a snapshot, ascending int64."""
        u = v.integer("u", u)
        if not 0 <= u < self.n_nodes:
            raise ValidationError("u", u, f"must be a node index in [0, {self.n_nodes})")
        lk = self.links_at(snapshot)
        return lk[lk[:, 0] == u, 1].copy()

    def isolated_nodes(self, snapshot: int = 0) -> np.ndarray:
        """Nodes without any neighbour at a snapshot, ascending int64."""
        heard = np.zeros(self.n_nodes, bool)
        heard[self.links_at(snapshot)[:, 0]] = True
        return np.flatnonzero(~heard).astype(np.int64)


def _report_isolated(net: Network, spec: NetworkSpec) -> None:
    if spec.on_isolated == "allow":
        return
    found = {}
    for k in range(net.n_snapshots):
        iso = net.isolated_nodes(k)
        if iso.size:
            found[k] = iso
    if not found:
        return
    k0, iso = next(iter(found.items()))
    names = ", ".join(f"{'anchor' if net.is_anchor[i] else 'agent'} node {i}" for i in iso[:10])
    more = f" and {iso.size - 10} more" if iso.size > 10 else ""
    snaps = f" (isolated nodes at {len(found)} of {net.n_snapshots} snapshots)"
    rng_text = "fully meshed" if spec.comm_range_m is None else f"{spec.comm_range_m} m"
    message = (
        f"leaves {names}{more} without neighbours at snapshot {k0}{snaps}; increase "
        "comm_range_m, add anchors, or set network.on_isolated to 'warn' or 'allow'"
    )
    if spec.on_isolated == "error":
        raise ValidationError("network.comm_range_m", rng_text, message)
    warnings.warn(
        f"network.comm_range_m = {rng_text}: {message}", IsolatedNodesWarning, stacklevel=3
    )


def make_network(spec: NetworkSpec, rng: np.random.Generator) -> Network:
    """Draw a network from its recipe.

    Agents are uniform in the region at snapshot 0 (or at ``spec.agents_m``) and move by
    ``spec.motion``; anchors are static. Nodes are ordered agents first, anchors last.

    Parameters
    ----------
    spec : NetworkSpec
    rng : numpy.random.Generator
        Draw order: agent positions ``[n_agents, dim]`` (not drawn when ``spec.agents_m`` is
        given), then anchor positions (layout ``"uniform"`` only), then the motion
        (:func:`~phyloc.network.motion.simulate_motion`; none for static and waypoints).
        The snapshot-0 deployment therefore does not depend on the motion settings (except
        that waypoint movers start at their first waypoint).

    Returns
    -------
    Network

    Raises
    ------
    ValidationError
        When ``comm_range_m`` leaves a node without neighbours at some snapshot and
        ``spec.on_isolated == "error"`` (the message names the nodes, the snapshot and the
        range).
    """
    if not isinstance(spec, NetworkSpec):
        raise ValidationError("spec", type(spec).__name__, "must be a NetworkSpec")
    if not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", type(rng).__name__, "must be a numpy.random.Generator")
    side = np.asarray(spec.region_m)
    if spec.agents_m is None:
        agents0 = rng.uniform(0.0, side, size=(spec.n_agents, spec.dim))
        if spec.agent_height_m is not None:
            agents0[:, 2] = spec.agent_height_m
    else:
        agents0 = np.asarray(spec.agents_m, dtype=np.float64)
    if spec.anchors is None:
        anchors = np.zeros((0, spec.dim))
    elif isinstance(spec.anchors, int):
        anchors = anchor_positions(spec.anchor_layout, spec.anchors, spec.region_m, rng)
    else:
        anchors = np.asarray(spec.anchors, dtype=np.float64)
    m = spec.motion
    p_ag, v_ag, a_ag = simulate_motion(m, agents0, rng, center=0.5 * side)
    K, n_an = m.n_snapshots, anchors.shape[0]

    def with_anchors(agent_part, anchor_value):
        if agent_part is None:
            return None
        return np.concatenate(
            [agent_part, np.broadcast_to(anchor_value, (K, n_an, spec.dim))], axis=1
        )

    net = Network(
        positions=with_anchors(p_ag, anchors[None]),
        is_anchor=np.r_[np.zeros(spec.n_agents, bool), np.ones(n_an, bool)],
        comm_range_m=spec.comm_range_m,
        velocities=with_anchors(v_ag, 0.0),
        accelerations=with_anchors(a_ag, 0.0),
        dt_s=m.dt_s if m.n_snapshots > 1 else None,
        cooperative=spec.cooperation,
    )
    _report_isolated(net, spec)
    return net

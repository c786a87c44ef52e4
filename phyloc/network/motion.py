"""Motion models: static, random walk, constant velocity (CV) and acceleration (CA), waypoints.

The CV and CA models are the discrete white-noise-acceleration models of PF-BP eqs. (1)–(3)
and (48): the state of an agent stacks position, velocity (and acceleration), each a
``dim``-vector,

.. math::

    \\mathbf{x}^{(k)} = [\\mathbf{p}^{(k)T}\\ \\mathbf{v}^{(k)T}\\ \\mathbf{a}^{(k)T}]^T,
    \\qquad
    \\mathbf{x}^{(k)} = \\mathbf{F}\\mathbf{x}^{(k-1)} + \\mathbf{G}\\mathbf{u}^{(k-1)},
    \\qquad \\mathbf{u}^{(k-1)} \\sim \\mathcal{N}(\\mathbf{0}, \\sigma_a^2\\mathbf{I}_{dim}),

with (CA, PF-BP eqs. (2), (3))

.. math::

    \\mathbf{F} = \\begin{bmatrix} 1 & \\Delta T & \\Delta T^2/2 \\\\ 0 & 1 & \\Delta T \\\\
    0 & 0 & 1 \\end{bmatrix} \\otimes \\mathbf{I}_{dim}, \\qquad
    \\mathbf{G} = \\begin{bmatrix} \\Delta T^2/2 \\\\ \\Delta T \\\\ 1 \\end{bmatrix}
    \\otimes \\mathbf{I}_{dim},

and ``Q = G (σ_a² I) Gᵀ`` (PF-BP eq. (48)). The CV model is the same construction with the
acceleration row and column removed: ``F = [[1, ΔT], [0, 1]] ⊗ I``, ``G = [ΔT²/2, ΔT]ᵀ ⊗ I``
(the acceleration is white noise held constant over one sampling period). In 3-D the CA state
is 9-dimensional, the CV state 6-dimensional.

The deterministic ``"waypoints"`` model moves a few agents (``movers``) along a user-given
polyline at given speeds while every other agent stays put: the DiPNet experiments (§V-B)
have five stationary agents in a pentagon and a sixth on a rover. :func:`waypoint_trajectory`
samples the path by exact arc length: the mover is at time ``t`` at the point of arc length
``∫₀ᵗ speed dt`` along the path, whose interior corners may be rounded by circular arcs
(``corner_radius_m``). It consumes no randomness.

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."

Y. Bar-Shalom, X. R. Li and T. Kirubarajan, *Estimation with Applications to Tracking and
Navigation*, Wiley, 2001 (direct discrete-time kinematic models, §6.3).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc._validate import from_table
from phyloc.errors import ValidationError

#: Motion models understood by :class:`MotionSpec` and :func:`simulate_motion`.
MOTION_MODELS = ("static", "random_walk", "constant_velocity", "constant_acceleration", "waypoints")
#: Models with a linear-Gaussian state transition (:func:`transition_matrices`).
KINEMATIC_MODELS = ("constant_velocity", "constant_acceleration")
#: How the initial velocity of CV/CA agents is drawn.
INITIAL_VELOCITIES = ("gaussian", "toward_center", "zero")

_ORDER = {"constant_velocity": 2, "constant_acceleration": 3}
#: Keys used by ``model = "waypoints"`` only, with their defaults (other models reject them).
_WAYPOINT_KEYS = {
    "movers": None,
    "waypoints_m": None,
    "speeds_m_s": None,
    "loop": False,
    "corner_radius_m": 0.0,
}
#: Turning angles [rad] closer than this to 0 (straight on) or π (U-turn) are not rounded.
_ANGLE_TOL = 1e-9


@dataclass(frozen=True)
class MotionSpec:
    """How agents move over the snapshots of a network (anchors never move).

    Parameters
    ----------
    model : {"static", "random_walk", "constant_velocity", "constant_acceleration", "waypoints"}
        ``"static"``: positions repeated at every snapshot. ``"random_walk"``:
        ``p_k = p_{k-1} + w_k``, ``w_k ~ N(0, step_std_m² I)``. ``"constant_velocity"`` and
        ``"constant_acceleration"``: PF-BP eqs. (1)–(3) (see the module docstring).
        ``"waypoints"``: the agents ``movers`` follow the path ``waypoints_m`` at
        ``speeds_m_s`` (:func:`waypoint_trajectory`), every other agent is static; no
        randomness. Default ``"static"``.
    n_snapshots : int
        Number of snapshots K >= 1 (snapshot 0 is the deployment). Default 1.
    dt_s : float
        Sampling period ΔT [s], > 0. Default 0.1 s (PF-BP §VI).
    accel_std : float
        σ_a [m/s²], >= 0: standard deviation of each component of the white acceleration noise
        ``u`` of PF-BP eq. (1). Default 0.15 m/s² (PF-BP §VI).
    step_std_m : float
        Random walk: standard deviation of each component of a step [m], >= 0. Default 1 m.
    initial_velocity : {"gaussian", "toward_center", "zero"}
        CV/CA initial velocity: ``"gaussian"`` draws each component from
        ``N(0, initial_speed_std²)``; ``"toward_center"`` points at the centre of the region
        with speed ``initial_speed_m_s`` (PF-BP §VI: a unit vector toward the centre; an agent
        exactly at the centre starts at rest); ``"zero"`` starts at rest. Default
        ``"gaussian"``.
    initial_speed_std : float
        Per-component standard deviation of a ``"gaussian"`` initial velocity [m/s], >= 0.
        Default 1 m/s.
    initial_speed_m_s : float
        Speed of a ``"toward_center"`` initial velocity [m/s], >= 0. Default 1 m/s.
    initial_accel_std : float
        CA: per-component standard deviation of the initial acceleration [m/s²], >= 0.
        Default 0 (PF-BP §VI starts at zero acceleration).
    movers : list of int, optional
        ``"waypoints"`` only (required there): indices of the agents that move (agent ``i`` is
        node ``i`` of :func:`~phyloc.network.make_network`), distinct, >= 0 and
        ``< n_agents``. All movers follow the same path, so two movers coincide (a link
        between them has distance 0, which the channel rejects): use one mover per network.
    waypoints_m : list of dim-vectors, optional
        ``"waypoints"`` only (required there): >= 2 finite points [m] of the network's
        dimension, no two consecutive ones equal. The first is the movers' start: it
        overrides their snapshot-0 positions. With ``loop`` the closing leg back to the first
        point is implicit (do not repeat the first point at the end).
    speeds_m_s : float or list of float, optional
        ``"waypoints"`` only (required there): speed [m/s], > 0, of every leg (one number) or
        of each leg (``len(waypoints_m) − 1`` numbers, or ``len(waypoints_m)`` with ``loop``,
        the last one for the closing leg).
    loop : bool
        ``"waypoints"`` only: after the last waypoint go back to the first and repeat
        (period = Σ leg time). Default false: the movers stop at the last waypoint (zero
        velocity from then on).
    corner_radius_m : float
        ``"waypoints"`` only, >= 0: radius of the circular arc rounding each interior corner
        (not the first waypoint, which is always passed exactly). Default 0: sharp corners.
        See :func:`waypoint_trajectory` for the clipping of arcs that do not fit.

    Examples
    --------
    >>> MotionSpec.from_dict({"model": "constant_acceleration", "n_snapshots": 50}).dt_s
    0.1
    >>> rover = MotionSpec.from_dict({"model": "waypoints", "movers": [5],
    ...     "waypoints_m": [[0, 0], [40, 0], [40, 30]], "speeds_m_s": 1.5,
    ...     "n_snapshots": 300, "dt_s": 0.5})
    >>> rover.tracks_velocity, rover.speeds_m_s
    (True, 1.5)
    """

    model: str = "static"
    n_snapshots: int = 1
    dt_s: float = 0.1
    accel_std: float = 0.15
    step_std_m: float = 1.0
    initial_velocity: str = "gaussian"
    initial_speed_std: float = 1.0
    initial_speed_m_s: float = 1.0
    initial_accel_std: float = 0.0
    movers: tuple[int, ...] | None = None
    waypoints_m: tuple[tuple[float, ...], ...] | None = None
    speeds_m_s: float | tuple[float, ...] | None = None
    loop: bool = False
    corner_radius_m: float = 0.0

    def __post_init__(self):
        s = "network.motion"
        v.choice(f"{s}.model", self.model, MOTION_MODELS)
        v.choice(f"{s}.initial_velocity", self.initial_velocity, INITIAL_VELOCITIES)
        object.__setattr__(
            self, "n_snapshots", v.integer(f"{s}.n_snapshots", self.n_snapshots, minimum=1)
        )
        object.__setattr__(self, "dt_s", v.positive(f"{s}.dt_s", self.dt_s))
        for name in (
            "accel_std",
            "step_std_m",
            "initial_speed_std",
            "initial_speed_m_s",
            "initial_accel_std",
        ):
            value = v.positive(f"{s}.{name}", getattr(self, name), allow_zero=True)
            object.__setattr__(self, name, value)
        if self.model != "waypoints":
            for name, default in _WAYPOINT_KEYS.items():
                value = getattr(self, name)
                if not (value is default or (default is not None and value == default)):
                    raise ValidationError(
                        f"{s}.{name}", value, "is only used by model = 'waypoints'"
                    )
            return
        object.__setattr__(self, "movers", _check_movers(f"{s}.movers", self.movers))
        if not isinstance(self.loop, (bool, np.bool_)):
            raise ValidationError(f"{s}.loop", self.loop, "must be true or false")
        object.__setattr__(self, "loop", bool(self.loop))
        wp = _check_waypoints(f"{s}.waypoints_m", self.waypoints_m, self.loop)
        object.__setattr__(self, "waypoints_m", tuple(tuple(float(x) for x in r) for r in wp))
        n_legs = wp.shape[0] if self.loop else wp.shape[0] - 1
        speeds = _check_speeds(f"{s}.speeds_m_s", self.speeds_m_s, n_legs, self.loop)
        object.__setattr__(self, "speeds_m_s", speeds)
        object.__setattr__(
            self,
            "corner_radius_m",
            v.positive(f"{s}.corner_radius_m", self.corner_radius_m, allow_zero=True),
        )

    @property
    def tracks_velocity(self) -> bool:
        """Whether trajectories carry velocities (CV, CA and waypoints)."""
        return self.model in KINEMATIC_MODELS or self.model == "waypoints"

    @property
    def tracks_acceleration(self) -> bool:
        """Whether trajectories carry accelerations (CA)."""
        return self.model == "constant_acceleration"

    @classmethod
    def from_dict(cls, d: dict, *, section: str = "network.motion") -> MotionSpec:
        """Build from a recipe section; unknown keys are errors naming the closest valid key."""
        if not isinstance(d, dict):
            raise ValidationError(section, d, "must be a table (dict) of motion settings")
        return from_table(cls, d, section)

    def to_dict(self) -> dict:
        """The init fields as a plain dict (recipe form: tuples become lists).

        The waypoint-only keys appear for ``model = "waypoints"`` only, so the recipe form
        (and a dataset fingerprint) of every other model is the one it had before they
        existed.
        """
        out = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name in _WAYPOINT_KEYS and self.model != "waypoints":
                continue
            if f.name == "waypoints_m":
                value = [list(row) for row in value]
            elif isinstance(value, tuple):
                value = list(value)
            out[f.name] = value
        return out


def _check_movers(name: str, movers) -> tuple[int, ...]:
    if movers is None:
        raise ValidationError(name, None, "is required by model = 'waypoints' (agent indices)")
    if isinstance(movers, (str, bytes)) or not hasattr(movers, "__iter__"):
        raise ValidationError(name, movers, "must be a list of agent indices, e.g. [5]")
    out = tuple(v.integer(name, i, minimum=0) for i in movers)
    if not out:
        raise ValidationError(name, list(movers), "must list at least one agent index")
    if len(set(out)) != len(out):
        raise ValidationError(name, list(out), "agent indices must be distinct")
    return out


def _check_waypoints(name: str, waypoints, loop: bool) -> np.ndarray:
    if waypoints is None:
        raise ValidationError(name, None, "is required by model = 'waypoints' (list of points)")
    wp = v.finite_array(name, waypoints)
    if wp.ndim != 2 or wp.shape[0] < 2 or wp.shape[1] not in (2, 3):
        raise ValidationError(
            name,
            f"array of shape {wp.shape}",
            "must be a list of >= 2 points of 2 or 3 coordinates",
        )
    legs = np.linalg.norm(np.diff(wp, axis=0), axis=1)
    if np.any(legs == 0):
        i = int(np.flatnonzero(legs == 0)[0])
        raise ValidationError(
            name, f"points {i} and {i + 1} equal", "consecutive waypoints must differ"
        )
    if loop and np.array_equal(wp[0], wp[-1]):
        raise ValidationError(
            name,
            "last point equal to the first",
            "with loop = true the closing leg is implicit: do not repeat the first point",
        )
    return wp


def _check_speeds(name: str, speeds, n_legs: int, loop: bool):
    if speeds is None:
        raise ValidationError(name, None, "is required by model = 'waypoints' (m/s)")
    if isinstance(speeds, (list, tuple, np.ndarray)):
        out = tuple(v.positive(name, x) for x in speeds)
        if len(out) != n_legs:
            legs = "legs (the last one closes the loop)" if loop else "legs"
            raise ValidationError(
                name,
                list(out),
                f"one speed for every leg or {n_legs} speeds: the path has {n_legs} {legs}",
            )
        return out
    return v.positive(name, speeds)


def _kinematic_blocks(model: str, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis ``F`` [order, order] and ``G`` [order] of PF-BP eqs. (2), (3)."""
    dt = dt_s
    if model == "constant_acceleration":
        f = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
        g = np.array([0.5 * dt * dt, dt, 1.0])
    else:
        f = np.array([[1.0, dt], [0.0, 1.0]])
        g = np.array([0.5 * dt * dt, dt])
    return f, g


def _check_kinematic(model, dim, dt_s):
    v.choice("model", model, KINEMATIC_MODELS)
    dim = v.integer("dim", dim, minimum=1)
    dt_s = v.positive("dt_s", dt_s)
    return model, dim, dt_s


def noise_gain_matrix(model: str, dim: int, dt_s: float) -> np.ndarray:
    """The noise gain ``G`` of PF-BP eq. (3) (CA) or its CV counterpart.

    Parameters
    ----------
    model : {"constant_velocity", "constant_acceleration"}
    dim : int
        Spatial dimension (2 or 3; any >= 1 works).
    dt_s : float
        Sampling period ΔT [s], > 0.

    Returns
    -------
    G : [order·dim, dim] float64
        ``[ΔT²/2, ΔT, 1]ᵀ ⊗ I_dim`` (CA, order 3) or ``[ΔT²/2, ΔT]ᵀ ⊗ I_dim`` (CV, order 2).
        Sampling the process noise as ``G u`` with ``u ~ N(0, σ_a² I_dim)`` avoids factoring
        the rank-``dim`` covariance ``Q``.
    """
    model, dim, dt_s = _check_kinematic(model, dim, dt_s)
    _, g = _kinematic_blocks(model, dt_s)
    return np.kron(g[:, None], np.eye(dim))


def transition_matrices(
    model: str, dim: int, dt_s: float, accel_std: float
) -> tuple[np.ndarray, np.ndarray]:
    """State transition ``F`` and process noise covariance ``Q`` of the CV/CA models.

    The state is ``[p; v]`` (CV) or ``[p; v; a]`` (CA), each block a ``dim``-vector, so
    ``x[:dim]`` is the position (PF-BP §II, ordering of ``x_i^{(k)}``).

    Parameters
    ----------
    model : {"constant_velocity", "constant_acceleration"}
    dim : int
        Spatial dimension (2 or 3).
    dt_s : float
        Sampling period ΔT [s], > 0.
    accel_std : float
        σ_a [m/s²], >= 0: per-component standard deviation of the white acceleration noise.

    Returns
    -------
    F : [order·dim, order·dim] float64
        PF-BP eq. (2) (CA) or ``[[1, ΔT], [0, 1]] ⊗ I_dim`` (CV).
    Q : [order·dim, order·dim] float64
        ``G (σ_a² I_dim) Gᵀ`` (PF-BP eq. (48)) with ``G`` from :func:`noise_gain_matrix`;
        symmetric, positive semi-definite, of rank ``dim`` (when σ_a > 0).

    Examples
    --------
    >>> F, Q = transition_matrices("constant_acceleration", 3, 0.1, 0.15)
    >>> F.shape, Q.shape
    ((9, 9), (9, 9))
    """
    model, dim, dt_s = _check_kinematic(model, dim, dt_s)
    sa = v.positive("accel_std", accel_std, allow_zero=True)
    f, g = _kinematic_blocks(model, dt_s)
    eye = np.eye(dim)
    F = np.kron(f, eye)
    Q = (sa * sa) * np.kron(np.outer(g, g), eye)
    return F, Q


def _path_pieces(wp: np.ndarray, speeds: np.ndarray, loop: bool, radius: float) -> list:
    """The path as line and arc pieces ``(kind, length, speed, geometry)``, in travel order."""
    n_legs = wp.shape[0] if loop else wp.shape[0] - 1
    start = wp[:n_legs]
    delta = np.roll(wp, -1, axis=0)[:n_legs] - start
    length = np.linalg.norm(delta, axis=1)
    unit = delta / length[:, None]
    # corner i (i = 1 … n_legs−1) joins leg i−1 and leg i at waypoint i; waypoint 0 stays sharp
    tangent = np.zeros(n_legs + 1)  # tangent length t_i of corner i (0: sharp)
    arcs = {}
    for i in range(1, n_legs):
        u_in, u_out = unit[i - 1], unit[i]
        theta = math.acos(min(1.0, max(-1.0, float(u_in @ u_out))))
        if radius == 0.0 or theta < _ANGLE_TOL or theta > math.pi - _ANGLE_TOL:
            continue
        half = math.tan(0.5 * theta)
        t = min(radius * half, 0.5 * length[i - 1], 0.5 * length[i])
        r = t / half
        normal = u_out - (u_out @ u_in) * u_in
        normal /= np.linalg.norm(normal)
        tangent[i] = t
        centre = wp[i] - t * u_in + r * normal
        arcs[i] = (centre, r, u_in, normal, theta)
    pieces = []
    for j in range(n_legs):
        a, b = tangent[j], tangent[j + 1]
        if length[j] - a - b > 0:
            pieces.append(("line", length[j] - a - b, speeds[j], (start[j] + a * unit[j], unit[j])))
        if j + 1 in arcs:
            centre, r, u_in, normal, theta = arcs[j + 1]
            half_angle = 0.5 * theta
            # first half of the arc at the incoming leg's speed, second half at the outgoing one
            for phi0, spd in ((0.0, speeds[j]), (half_angle, speeds[j + 1])):
                pieces.append(("arc", r * half_angle, spd, (centre, r, u_in, normal, phi0)))
    return pieces


def waypoint_trajectory(
    waypoints_m,
    speeds_m_s,
    n_snapshots: int,
    dt_s: float,
    *,
    loop: bool = False,
    corner_radius_m: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities of a mover following a polyline at given leg speeds.

    The path starts at ``waypoints_m[0]`` and runs through the waypoints in order (with
    ``loop``, back to the first one and around again). At time ``t_k = k·ΔT`` the mover is at
    the point of arc length ``s(t_k) = ∫₀^{t_k} speed dt`` along the path — an exact
    arc-length parametrization, no integration error. Its velocity is the unit tangent of the
    path at that point times the current speed (not a finite difference).

    **Rounded corners.** Every interior corner (each waypoint but the first, and but the last
    without ``loop``) with turning angle ``θ`` (angle between the incoming and outgoing leg
    directions; ``0 < θ < π``) is replaced by a circular arc tangent to both legs, in their
    plane: its tangent points lie ``t = r·tan(θ/2)`` before and after the waypoint, its centre
    at distance ``r`` from both legs, and its length is ``r·θ``. When ``t`` exceeds half of
    an adjacent leg, ``t`` is clipped to that half (so consecutive arcs never overlap) and the
    arc's radius becomes ``t / tan(θ/2) < corner_radius_m``. Straight continuations (``θ = 0``)
    and U-turns (``θ = π``) stay sharp. The first waypoint is never rounded, so the mover
    starts there and, with ``loop``, passes it exactly once per period; to round every corner
    of a closed course, start it in the middle of a leg.

    **Speeds.** Leg ``j`` runs from waypoint ``j`` to ``j+1``; its speed applies on its
    straight part and on the half of each adjacent arc that belongs to it: the first half
    (by arc length) of a corner's arc is travelled at the incoming leg's speed, the second
    half at the outgoing leg's speed. The speed thus changes stepwise, at waypoints (sharp
    corners) or at arc midpoints.

    Parameters
    ----------
    waypoints_m : [n_waypoints, dim] float64
        ``n_waypoints >= 2`` finite points [m], ``dim`` 2 or 3; consecutive points differ
        (with ``loop``, the last also differs from the first).
    speeds_m_s : float or [n_legs] float64
        Speed [m/s], > 0, of every leg or of each leg; ``n_legs = n_waypoints − 1``, or
        ``n_waypoints`` with ``loop`` (the last leg closes the loop).
    n_snapshots : int
        Number of samples K >= 1 (``t_k = k·ΔT``, ``k = 0 … K−1``).
    dt_s : float
        Sampling period ΔT [s], > 0.
    loop : bool, optional
        Repeat the closed course with period ``T = Σ_pieces length / speed``
        (``= total length / speed`` for one speed). Default false: the mover stops at the
        last waypoint once it reaches it (``t >= T``) and its velocity is zero from then on.
    corner_radius_m : float, optional
        Radius of the corner arcs [m], >= 0. Default 0 (sharp corners: the path is the
        polyline).

    Returns
    -------
    positions : [n_snapshots, dim] float64
        [m]; ``positions[0] = waypoints_m[0]``.
    velocities : [n_snapshots, dim] float64
        [m/s]; ``|velocities[k]|`` is the speed of the piece the mover is on at ``t_k`` (the
        piece starting at ``t_k`` when it is on a boundary), 0 after stopping.

    Examples
    --------
    >>> p, vel = waypoint_trajectory([[0, 0], [4, 0], [4, 3]], 2.0, 5, 1.0)
    >>> p.tolist()
    [[0.0, 0.0], [2.0, 0.0], [4.0, 0.0], [4.0, 2.0], [4.0, 3.0]]
    >>> vel.tolist()
    [[2.0, 0.0], [2.0, 0.0], [0.0, 2.0], [0.0, 2.0], [0.0, 0.0]]
    """
    if not isinstance(loop, (bool, np.bool_)):
        raise ValidationError("loop", loop, "must be True or False")
    loop = bool(loop)
    wp = _check_waypoints("waypoints_m", waypoints_m, loop)
    n_legs = wp.shape[0] if loop else wp.shape[0] - 1
    speeds = np.broadcast_to(
        np.asarray(_check_speeds("speeds_m_s", speeds_m_s, n_legs, loop), dtype=np.float64),
        (n_legs,),
    )
    K = v.integer("n_snapshots", n_snapshots, minimum=1)
    dt = v.positive("dt_s", dt_s)
    radius = v.positive("corner_radius_m", corner_radius_m, allow_zero=True)

    pieces = _path_pieces(wp, speeds, loop, radius)
    lengths = np.array([pc[1] for pc in pieces])
    piece_speed = np.array([pc[2] for pc in pieces])
    t_start = np.concatenate(([0.0], np.cumsum(lengths / piece_speed)))
    period = t_start[-1]
    t = np.arange(K) * dt
    if loop:
        t = np.mod(t, period)
    dim = wp.shape[1]
    positions = np.empty((K, dim))
    velocities = np.zeros((K, dim))
    done = t >= period  # never with loop (np.mod < period)
    positions[done] = wp[-1]
    idx = np.searchsorted(t_start, t, side="right") - 1
    for k in np.flatnonzero(~done):
        j = idx[k]
        kind, length, spd, geo = pieces[j]
        s = min(max((t[k] - t_start[j]) * spd, 0.0), length)
        if kind == "line":
            origin, direction = geo
            positions[k] = origin + s * direction
            velocities[k] = spd * direction
        else:
            centre, r, u_in, normal, phi0 = geo
            phi = phi0 + s / r
            positions[k] = centre + r * (math.sin(phi) * u_in - math.cos(phi) * normal)
            velocities[k] = spd * (math.cos(phi) * u_in + math.sin(phi) * normal)
    return positions, velocities


def simulate_motion(
    spec: MotionSpec,
    initial_positions: np.ndarray,
    rng: np.random.Generator,
    *,
    center: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Trajectories of moving nodes from their initial positions.

    No boundary is enforced: nodes may leave the deployment region (no reflection), so that the
    CV/CA trajectories follow PF-BP eq. (1) exactly.

    Parameters
    ----------
    spec : MotionSpec
    initial_positions : [n, dim] float64
        Positions at snapshot 0 [m].
    rng : numpy.random.Generator
        Draw order: initial velocity, initial acceleration (CA, only if
        ``initial_accel_std > 0``), then the noise ``u^{(k)}`` of every step as one
        ``[K−1, n, dim]`` block (random walk: the steps). Static and waypoints: unused.
    center : [dim] float64, optional
        Centre of the region, required by ``initial_velocity="toward_center"``.

    Returns
    -------
    positions : [K, n, dim] float64
        ``K = spec.n_snapshots``.
    velocities : [K, n, dim] float64 or None
        CV, CA and waypoints [m/s] (waypoints: zero for the static nodes).
    accelerations : [K, n, dim] float64 or None
        CA only [m/s²].
    """
    p0 = v.finite_array("initial_positions", initial_positions, ndim=2)
    n, dim = p0.shape
    K = spec.n_snapshots
    if spec.model == "static":
        return np.repeat(p0[None], K, axis=0), None, None
    if spec.model == "waypoints":
        movers = np.asarray(spec.movers, dtype=np.int64)
        if movers.max() >= n:
            raise ValidationError(
                "network.motion.movers", list(spec.movers), f"agent indices must be < {n}"
            )
        wp = np.asarray(spec.waypoints_m)
        if wp.shape[1] != dim:
            raise ValidationError(
                "network.motion.waypoints_m",
                f"{wp.shape[1]}-D points",
                f"must have the network's dimension {dim}",
            )
        path, vel = waypoint_trajectory(
            wp,
            spec.speeds_m_s,
            K,
            spec.dt_s,
            loop=spec.loop,
            corner_radius_m=spec.corner_radius_m,
        )
        positions = np.repeat(p0[None], K, axis=0)
        velocities = np.zeros((K, n, dim))
        positions[:, movers] = path[:, None]
        velocities[:, movers] = vel[:, None]
        return positions, velocities, None
    if spec.model == "random_walk":
        steps = rng.normal(0.0, spec.step_std_m, size=(K - 1, n, dim))
        positions = np.empty((K, n, dim))
        positions[0] = p0
        positions[1:] = p0[None] + np.cumsum(steps, axis=0)
        return positions, None, None

    order = _ORDER[spec.model]
    state = np.zeros((n, order, dim))  # per node: rows p, v(, a) — the layout of F ⊗ I_dim
    state[:, 0] = p0
    if spec.initial_velocity == "gaussian":
        state[:, 1] = rng.normal(0.0, spec.initial_speed_std, size=(n, dim))
    elif spec.initial_velocity == "toward_center":
        if center is None:
            raise ValidationError("center", None, "required for initial_velocity='toward_center'")
        c = v.finite_array("center", center, ndim=1)
        if c.shape != (dim,):
            raise ValidationError("center", f"shape {c.shape}", f"must have shape ({dim},)")
        to_c = c[None] - p0
        norm = np.linalg.norm(to_c, axis=1, keepdims=True)
        unit = np.divide(to_c, norm, out=np.zeros_like(to_c), where=norm > 0)
        state[:, 1] = spec.initial_speed_m_s * unit
    if order == 3 and spec.initial_accel_std > 0:
        state[:, 2] = rng.normal(0.0, spec.initial_accel_std, size=(n, dim))

    f, g = _kinematic_blocks(spec.model, spec.dt_s)
    noise = rng.normal(0.0, spec.accel_std, size=(K - 1, n, dim))
    out = np.empty((K, n, order, dim))
    out[0] = state
    for k in range(1, K):
        # x_k = (f ⊗ I) x_{k-1} + (g ⊗ I) u_{k-1}  (PF-BP eq. (1)), on the [order, dim] layout
        out[k] = (
            np.einsum("ij,njd->nid", f, out[k - 1]) + g[None, :, None] * noise[k - 1][:, None, :]
        )
    positions = np.ascontiguousarray(out[:, :, 0])
    velocities = np.ascontiguousarray(out[:, :, 1])
    accelerations = np.ascontiguousarray(out[:, :, 2]) if order == 3 else None
    return positions, velocities, accelerations

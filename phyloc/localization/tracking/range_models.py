"""Range-level models of the PF-BP paper: agent states, Gaussian range measurements, scenarios.

The state of agent ``i`` at time ``k`` is ``x_i = [p_i; v_i; a_i]`` (constant acceleration, CA,
PF-BP eqs. (1)–(3)), ``[p_i; v_i]`` (constant velocity, CV) or ``p_i`` (static), each block a
``dim``-vector (2-D or 3-D). The transition is ``x_i^{(k)} = F x_i^{(k−1)} + G u`` with ``F``,
``Q = G σ_a² Gᵀ`` from :func:`phyloc.network.motion.transition_matrices` (static: ``F = I``,
``Q = 0``).

A range measurement (PF-BP eq. (8)) is ``z_ij = ‖p_j − p_i‖ + n_ij``, ``n_ij ~ N(0, σ²)`` iid.
A scenario stores them densely: ``z[k−1, i, j]`` is the measurement agent ``i`` made of node
``j`` at time ``k`` (NaN when ``i`` and ``j`` are not connected, i.e. farther than ``r_max``).
Nodes are ordered agents first, anchors last (as in :class:`~phyloc.network.Network`), so
columns ``n_agents …`` are anchors. Both agents of a connected pair measure, each with its own
noise: ``z_ij ≠ z_ji``.

Factors (PF-BP §V-A): *distributed* — agent ``i`` uses only its own row ``z[i, :]`` (``f_ij ≠
f_ji``, eq. (17)); *centralized* — agent ``i`` also uses ``z[j, i]`` of every agent ``j``
(``f_ij = f_ji``, eq. (18)). :func:`agent_measurements` lists the measurements of one agent
under either rule; :func:`all_measurements` lists every measurement (the joint likelihood used by
the EDH filter and the PCRLB).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.network.motion import noise_gain_matrix, transition_matrices

#: State models understood by :class:`RangeModel`.
STATE_MODELS = ("static", "constant_velocity", "constant_acceleration")
#: Factor rules of PF-BP §V-A.
FACTORS = ("distributed", "centralized")
_ORDER = {"static": 1, "constant_velocity": 2, "constant_acceleration": 3}


@dataclass(frozen=True)
class RangeModel:
    """Agent state model and Gaussian range measurement model (PF-BP §II).

    Parameters
    ----------
    motion : {"static", "constant_velocity", "constant_acceleration"}
        State model; CA is PF-BP eqs. (1)–(3) (9-D in 3-D). Default CA.
    dim : int
        Spatial dimension, 2 or 3. Default 3.
    dt_s : float
        Sampling period ΔT [s], > 0. Default 0.1 s (PF-BP §VI).
    accel_std : float
        σ_a [m/s²], >= 0 (CV/CA). Default 0.15 m/s².
    sigma_r : float
        Range noise standard deviation σ [m], > 0 (eq. (8)). Default 0.1 m.

    Examples
    --------
    >>> m = RangeModel("constant_acceleration", 3)
    >>> m.state_dim, m.matrices()[0].shape
    (9, (9, 9))
    """

    motion: str = "constant_acceleration"
    dim: int = 3
    dt_s: float = 0.1
    accel_std: float = 0.15
    sigma_r: float = 0.1

    def __post_init__(self):
        v.choice("motion", self.motion, STATE_MODELS)
        dim = v.integer("dim", self.dim)
        if dim not in (2, 3):
            raise ValidationError("dim", self.dim, "must be 2 or 3")
        object.__setattr__(self, "dim", dim)
        object.__setattr__(self, "dt_s", v.positive("dt_s", self.dt_s))
        object.__setattr__(
            self, "accel_std", v.positive("accel_std", self.accel_std, allow_zero=True)
        )
        object.__setattr__(self, "sigma_r", v.positive("sigma_r", self.sigma_r))

    @property
    def order(self) -> int:
        """1 (static), 2 (CV) or 3 (CA): number of ``dim``-blocks in the state."""
        return _ORDER[self.motion]

    @property
    def state_dim(self) -> int:
        """N_D = order · dim."""
        return self.order * self.dim

    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """``(F, Q)`` of PF-BP eqs. (2), (48); static: ``(I, 0)``."""
        if self.motion == "static":
            return np.eye(self.dim), np.zeros((self.dim, self.dim))
        return transition_matrices(self.motion, self.dim, self.dt_s, self.accel_std)

    def noise_gain(self) -> np.ndarray:
        """``G`` of PF-BP eq. (3), ``[N_D, dim]`` (static: zeros)."""
        if self.motion == "static":
            return np.zeros((self.dim, self.dim))
        return noise_gain_matrix(self.motion, self.dim, self.dt_s)

    def regularization_cov(self, std_vel: float = 0.15, std_acc: float = 0.15) -> np.ndarray:
        """The regularization kernel ``Σ_r`` of PF-BP eq. (32): zero on position.

        Returns ``[N_D, N_D]`` diagonal: ``0`` (position), ``σ_r,vel²`` (velocity),
        ``σ_r,acc²`` (acceleration), for the blocks the model has.
        """
        diag = [
            0.0,
            v.positive("std_vel", std_vel, allow_zero=True) ** 2,
            v.positive("std_acc", std_acc, allow_zero=True) ** 2,
        ][: self.order]
        return np.diag(np.repeat(diag, self.dim))

    def predict_particles(self, X: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Draw ``x^{(k)} = F x^{(k−1)} + G u`` for particles ``X [..., N_D]`` (eq. (1))."""
        F, _ = self.matrices()
        out = X @ F.T
        if self.motion != "static" and self.accel_std > 0:
            u = rng.normal(0.0, self.accel_std, size=(*X.shape[:-1], self.dim))
            out += u @ self.noise_gain().T
        return out

    def predict_cov(self, P: np.ndarray) -> np.ndarray:
        """``F P Fᵀ + Q`` for ``P [..., N_D, N_D]`` (PF-BP eq. (29))."""
        F, Q = self.matrices()
        return F @ P @ F.T + Q


@dataclass(frozen=True, eq=False)
class RangeScenario:
    """True trajectories and range measurements of one realization.

    Time ``k = 1 … K`` is stored at index ``k − 1``; ``initial_states`` is ``x^{(0)}``.

    Parameters
    ----------
    model : RangeModel
    anchors : [n_anchors, dim] float64
        Anchor positions [m].
    initial_states : [n_agents, N_D] float64
        ``x_i^{(0)}``.
    states : [K, n_agents, N_D] float64
        ``x_i^{(k)}``.
    z : [K, n_agents, n_agents + n_anchors] float64
        ``z[k−1, i, j]``: range agent ``i`` measured to node ``j`` [m]; NaN where absent (and on
        the diagonal).
    comm_range_m : float
        r_max [m] (``inf``: fully connected).
    """

    model: RangeModel
    anchors: np.ndarray
    initial_states: np.ndarray
    states: np.ndarray
    z: np.ndarray
    comm_range_m: float = np.inf

    @property
    def n_agents(self) -> int:
        return self.states.shape[1]

    @property
    def n_anchors(self) -> int:
        return self.anchors.shape[0]

    @property
    def n_steps(self) -> int:
        return self.states.shape[0]

    def positions(self) -> np.ndarray:
        """True agent positions ``[K, n_agents, dim]``."""
        return self.states[..., : self.model.dim]


@dataclass(frozen=True, eq=False)
class TrackResult:
    """Estimates of a range-level tracker (PF-BP, SIR-BP, EDH).

    Attributes
    ----------
    mean : [K, n_agents, N_D] float64
        MMSE estimates (eq. (20)).
    cov : [K, n_agents, N_D, N_D] float64
        Belief covariances (UKF, eq. (30), for the flow methods; sample covariance for SIR-BP).
    step_s : [K] float64
        Wall time per time step (joint processing) [s].
    agent_s : [K] float64
        Mean wall time per agent and time step (distributed processing) [s]; for the
        centralized EDH filter the joint time divided by the number of agents.
    label : str
    """

    mean: np.ndarray
    cov: np.ndarray
    step_s: np.ndarray
    agent_s: np.ndarray
    label: str = ""


def state_errors(result: TrackResult, scenario: RangeScenario) -> dict[str, np.ndarray]:
    """RMSE per time step of position, velocity, acceleration (PF-BP §VI ``RMSE_p/v/a``).

    Returns a dict with keys ``"p"``, ``"v"``, ``"a"`` (those the model has), each ``[K]``
    = ``sqrt(mean_i ‖x̂_i − x_i‖²)`` over the block.
    """
    d = scenario.model.dim
    out = {}
    for b, name in enumerate("pva"[: scenario.model.order]):
        e = result.mean[..., b * d : (b + 1) * d] - scenario.states[..., b * d : (b + 1) * d]
        out[name] = np.sqrt(np.mean(np.sum(e * e, axis=-1), axis=-1))
    return out


def network_states(network, model: RangeModel) -> np.ndarray:
    """Agent states ``[n_snapshots, n_agents, N_D]`` of a realized network.

    Velocity and acceleration come from the network when it carries them, zeros otherwise.
    """
    agents = ~np.asarray(network.is_anchor)
    blocks = [network.positions, network.velocities, network.accelerations][: model.order]
    blocks = [np.zeros_like(network.positions) if b is None else b for b in blocks]
    return np.concatenate([b[:, agents] for b in blocks], axis=-1)


def simulate_scenario(
    network,
    model: RangeModel,
    rng: np.random.Generator,
    *,
    comm_range_m: float | None = None,
    n_steps: int | None = None,
) -> RangeScenario:
    """Range measurements (PF-BP eq. (8)) along the trajectories of a realized network.

    Snapshot 0 of the network is ``x^{(0)}`` (the prior time, no measurement); snapshots
    ``1 … K`` carry measurements. Agents ``i`` and node ``j`` are connected at time ``k`` when
    ``‖p_i − p_j‖ <= r_max``; then agent ``i`` measures ``z_ij`` and (if ``j`` is an agent) ``j``
    measures ``z_ji`` with independent noise.

    Parameters
    ----------
    network : phyloc.network.Network
        From :func:`phyloc.network.make_network` (agents first, anchors last), at least
        ``n_steps + 1`` snapshots. Its own ``comm_range_m`` is ignored.
    model : RangeModel
        ``dim`` must match the network.
    rng : numpy.random.Generator
        Draws the noise ``[K, n_agents, n_nodes]`` in one block.
    comm_range_m : float, optional
        r_max [m]; ``None``: fully connected.
    n_steps : int, optional
        K; default ``network.n_snapshots − 1``.

    Returns
    -------
    RangeScenario
    """
    if not isinstance(model, RangeModel):
        raise ValidationError("model", type(model).__name__, "must be a RangeModel")
    if not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", type(rng).__name__, "must be a numpy.random.Generator")
    pos = np.asarray(network.positions)
    if pos.shape[2] != model.dim:
        raise ValidationError("model.dim", model.dim, f"must match the network ({pos.shape[2]})")
    K = pos.shape[0] - 1 if n_steps is None else v.integer("n_steps", n_steps, minimum=1)
    if K < 1 or K + 1 > pos.shape[0]:
        raise ValidationError(
            "n_steps", K, f"needs 1 <= n_steps <= n_snapshots − 1 = {pos.shape[0] - 1}"
        )
    r_max = np.inf if comm_range_m is None else v.positive("comm_range_m", comm_range_m)
    is_anchor = np.asarray(network.is_anchor)
    agents = np.flatnonzero(~is_anchor)
    order = np.r_[agents, np.flatnonzero(is_anchor)]
    states = network_states(network, model)[: K + 1]
    p = pos[1 : K + 1][:, order]  # [K, n_nodes, dim], agents first
    n_ag = agents.size
    d = np.linalg.norm(p[:, :n_ag, None, :] - p[:, None, :, :], axis=-1)  # [K, n_ag, n_nodes]
    noise = rng.normal(0.0, model.sigma_r, size=d.shape)
    z = d + noise
    connected = d <= r_max
    connected[:, np.arange(n_ag), np.arange(n_ag)] = False
    z[~connected] = np.nan
    return RangeScenario(
        model=model,
        anchors=np.ascontiguousarray(pos[0, is_anchor]),
        initial_states=states[0],
        states=states[1:],
        z=z,
        comm_range_m=float(r_max),
    )


def scenario_network_spec(
    n_agents: int = 5,
    n_steps: int = 40,
    *,
    motion: str = "constant_acceleration",
    dim: int = 3,
    side_m: float = 20.0,
    dt_s: float = 0.1,
    accel_std: float = 0.15,
):
    """The network of PF-BP §VI Scenario I (5 agents) / II (20 agents).

    Agents uniform in a ``side_m`` cube (square in 2-D), 9 anchors at its corners and centre
    (``"corners_center"``; 5 in 2-D), initial velocity a unit vector toward the centre,
    zero initial acceleration, CA (or CV) motion with ``ΔT``, ``σ_a``; ``n_steps + 1``
    snapshots (snapshot 0 is ``x^{(0)}``). A static model gives a static network.
    """
    from phyloc.network import MotionSpec, NetworkSpec

    v.choice("motion", motion, STATE_MODELS)
    ms = MotionSpec(
        model=motion,
        n_snapshots=n_steps + 1,
        dt_s=dt_s,
        accel_std=accel_std,
        initial_velocity="toward_center",
        initial_speed_m_s=1.0,
    )
    return NetworkSpec(
        n_agents=n_agents,
        dim=dim,
        region_m=(side_m,) * dim,
        anchors=2**dim + 1,
        anchor_layout="corners_center",
        on_isolated="allow",
        motion=ms,
    )


def paper_prior(
    scenario: RangeScenario,
    rng: np.random.Generator,
    *,
    sigma_p: float = 20.0,
    region_m=None,
    accel_init_factor: float = 10.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Gaussian prior of ``x^{(0)}`` of PF-BP eq. (31).

    ``P_i^{(0)} = diag(σ_p² I, ΔT² σ_ainit² I, σ_ainit² I)`` with ``σ_ainit = 10 σ_a``; the
    velocity and acceleration means are drawn from ``N(0, P^{(0)})`` blocks, the position mean
    uniformly in the region (default: the bounding box of the anchors). Static model: only the
    position block.

    Returns
    -------
    mean : [n_agents, N_D] float64
    cov : [n_agents, N_D, N_D] float64
    """
    m = scenario.model
    sp = v.positive("sigma_p", sigma_p)
    sai = v.positive("accel_init_factor", accel_init_factor, allow_zero=True) * m.accel_std
    var = [sp**2, (m.dt_s * sai) ** 2, sai**2][: m.order]
    diag = np.repeat(var, m.dim)
    n = scenario.n_agents
    if region_m is None:
        lo, hi = scenario.anchors.min(axis=0), scenario.anchors.max(axis=0)
    else:
        lo, hi = np.zeros(m.dim), np.asarray(region_m, dtype=float) * np.ones(m.dim)
    mean = np.zeros((n, m.state_dim))
    mean[:, : m.dim] = rng.uniform(lo, hi, size=(n, m.dim))
    if m.order > 1:
        mean[:, m.dim :] = rng.normal(size=(n, m.state_dim - m.dim)) * np.sqrt(diag[m.dim :])
    cov = np.repeat(np.diag(diag)[None], n, axis=0)
    return mean, cov


def agent_measurements(z_k: np.ndarray, agent: int, factors: str = "distributed"):
    """Measurements entering the belief of one agent at one time step.

    Parameters
    ----------
    z_k : [n_agents, n_nodes] float64
        One time step of :attr:`RangeScenario.z`.
    agent : int
    factors : {"distributed", "centralized"}
        Distributed: ``z[agent, j]`` only (eq. (17)); centralized: also ``z[j, agent]`` of every
        agent ``j`` (eq. (18)).

    Returns
    -------
    rx, tx : [L] int64
        The measurement is ``‖p_rx − p_tx‖ + n``; ``rx == agent`` or ``tx == agent``.
    z : [L] float64
    partners : [P] int64
        Sorted agents (≠ ``agent``) that appear in a measurement.
    """
    v.choice("factors", factors, FACTORS)
    row = z_k[agent]
    tx = np.flatnonzero(np.isfinite(row))
    rx = np.full(tx.size, agent)
    zz = row[tx]
    if factors == "centralized":
        col = z_k[:, agent]
        other = np.flatnonzero(np.isfinite(col))
        rx = np.r_[rx, other]
        tx = np.r_[tx, np.full(other.size, agent)]
        zz = np.r_[zz, col[other]]
    n_ag = z_k.shape[0]
    nodes = np.r_[rx, tx]
    partners = np.unique(nodes[(nodes < n_ag) & (nodes != agent)])
    return rx.astype(np.int64), tx.astype(np.int64), zz, partners.astype(np.int64)


def all_measurements(z_k: np.ndarray):
    """Every measurement of a time step: ``rx, tx [L] int64, z [L]`` (the joint likelihood)."""
    rx, tx = np.nonzero(np.isfinite(z_k))
    return rx.astype(np.int64), tx.astype(np.int64), z_k[rx, tx]


def flow_links(rx, tx, z, local_index, n_agents, anchors, dim, state_dim):
    """Convert measurements to the offset form of the flow kernels.

    ``local_index[node]`` is the slot of an agent in the stacked state (its position occupies
    ``slot·N_D … slot·N_D + dim``). Anchors get offset −1 and their coordinates in ``anchor_pos``.
    Returns ``off_a, off_b [L] int64, anchor_pos [L, dim], z [L]`` (``rx`` is always an agent).
    """
    off_a = local_index[rx] * state_dim
    is_anchor = tx >= n_agents
    off_b = np.where(is_anchor, -1, local_index[np.minimum(tx, n_agents - 1)] * state_dim)
    anchor_pos = np.zeros((rx.size, dim))
    if is_anchor.any():
        anchor_pos[is_anchor] = anchors[tx[is_anchor] - n_agents]
    return (
        np.ascontiguousarray(off_a, dtype=np.int64),
        np.ascontiguousarray(off_b, dtype=np.int64),
        anchor_pos,
        np.ascontiguousarray(z, dtype=np.float64),
    )


def sample_gaussian(mean: np.ndarray, cov: np.ndarray, n: int, rng: np.random.Generator):
    """``n`` draws per agent from ``N(mean_i, cov_i)``: ``[n_agents, n, N_D]``.

    ``mean [n_agents, N_D]``, ``cov [n_agents, N_D, N_D]`` (PSD; a singular block is jittered).
    """
    from phyloc.localization.tracking._flow import robust_cholesky

    mean = v.finite_array("prior_mean", mean, ndim=2)
    cov = v.finite_array("prior_cov", cov, ndim=3)
    if cov.shape != (*mean.shape, mean.shape[1]):
        raise ValidationError(
            "prior_cov", f"array of shape {cov.shape}", f"must be {(*mean.shape, mean.shape[1])}"
        )
    L = np.stack([robust_cholesky(c) for c in cov])
    w = rng.standard_normal((mean.shape[0], n, mean.shape[1]))
    return mean[:, None, :] + np.einsum("aij,anj->ani", L, w)


def check_prior(scenario: RangeScenario, prior_mean, prior_cov):
    """Validate a per-agent Gaussian prior against a scenario; returns float64 copies."""
    if not isinstance(scenario, RangeScenario):
        raise ValidationError("scenario", type(scenario).__name__, "must be a RangeScenario")
    n, nd = scenario.n_agents, scenario.model.state_dim
    mean = v.finite_array("prior_mean", prior_mean, ndim=2)
    cov = v.finite_array("prior_cov", prior_cov, ndim=3)
    if mean.shape != (n, nd):
        raise ValidationError("prior_mean", f"array of shape {mean.shape}", f"must be ({n}, {nd})")
    if cov.shape != (n, nd, nd):
        raise ValidationError(
            "prior_cov", f"array of shape {cov.shape}", f"must be ({n}, {nd}, {nd})"
        )
    return mean.copy(), cov.copy()


def check_run_args(options, options_cls, rng, *, rng_required: bool = True):
    """Validate the common arguments of the range-level trackers; returns the options."""
    opt = options_cls() if options is None else options
    if not isinstance(opt, options_cls):
        raise ValidationError("options", type(opt).__name__, f"must be {options_cls.__name__}")
    if (rng_required or rng is not None) and not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", type(rng).__name__, "must be a numpy.random.Generator")
    return opt

"""Simulated range-tracking scenarios of the PF-BP paper: the truth and the ranges measured in it.

A :class:`RangeScenario` holds the true agent states of one realization and the range
measurements (PF-BP eq. (8)) taken along them; a tracker only ever sees
:meth:`RangeScenario.measurements` (a :class:`~phyloc.localization.tracking.RangeMeasurements`,
no truth), and :func:`state_errors` compares its estimates with the truth. The networks are
those of PF-BP §VI (:func:`scenario_network_spec`); :func:`network_states` reads the true
states off a realized network.

Examples
--------
>>> import numpy as np
>>> from phyloc.network import make_network
>>> from phyloc.localization import METHODS
>>> from phyloc.localization.tracking import RangeModel, paper_prior
>>> rng = np.random.default_rng(1)
>>> net = make_network(scenario_network_spec(n_agents=3, n_steps=2), rng)
>>> sc = simulate_scenario(net, RangeModel(), rng)
>>> meas = sc.measurements()
>>> m = METHODS["pfbp"]
>>> res = m.run(meas, paper_prior(meas, rng), rng, m.make_options({"n_particles": 50}))
>>> res.estimates.shape, state_errors(res, sc)["p"].shape
((2, 3, 9), (2,))

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.localization.results import Result
from phyloc.localization.tracking import STATE_MODELS, RangeMeasurements, RangeModel

__all__ = [
    "RangeScenario",
    "anchor_localizable",
    "flow_example",
    "network_states",
    "scenario_network_spec",
    "simulate_scenario",
    "state_errors",
]


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
        ``x_i^{(0)}`` (truth).
    states : [K, n_agents, N_D] float64
        ``x_i^{(k)}`` (truth).
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
        """Number of agents."""
        return self.states.shape[1]

    @property
    def n_anchors(self) -> int:
        """Number of anchors."""
        return self.anchors.shape[0]

    @property
    def n_steps(self) -> int:
        """Number of time steps K."""
        return self.states.shape[0]

    def positions(self) -> np.ndarray:
        """True agent positions ``[K, n_agents, dim]``."""
        return self.states[..., : self.model.dim]

    def measurements(self) -> RangeMeasurements:
        """What a tracker sees: the model, the anchors and the ranges (no truth)."""
        return RangeMeasurements(self.model, self.anchors, self.z)


def state_errors(result, scenario: RangeScenario) -> dict[str, np.ndarray]:
    """RMSE per time step of position, velocity, acceleration (PF-BP §VI ``RMSE_p/v/a``).

    Parameters
    ----------
    result : Result or [K, n_agents, N_D] float64
        Estimates of a tracker (``Result.estimates``).
    scenario : RangeScenario
        The truth.

    Returns
    -------
    dict of str -> [K] float64
        Keys ``"p"``, ``"v"``, ``"a"`` (those the model has), each
        ``sqrt(mean_i ‖x̂_i − x_i‖²)`` over the block [m, m/s, m/s²].
    """
    est = result.estimates if isinstance(result, Result) else np.asarray(result)
    if est.shape != scenario.states.shape:
        raise ValidationError(
            "result.estimates", f"array of shape {est.shape}", f"must be {scenario.states.shape}"
        )
    d = scenario.model.dim
    out = {}
    for b, name in enumerate("pva"[: scenario.model.order]):
        e = est[..., b * d : (b + 1) * d] - scenario.states[..., b * d : (b + 1) * d]
        out[name] = np.sqrt(np.mean(np.sum(e * e, axis=-1), axis=-1))
    return out


def anchor_localizable(scenario: RangeScenario) -> np.ndarray:
    """Which agent positions the anchors alone determine (PF-BP Fig. 3): at step ``k`` agent
    ``i`` measures ranges to at least ``dim + 1`` anchors that are not all on one hyperplane
    (a plane in 3-D, a line in 2-D), so that its position follows from them without any
    cooperation (trilateration needs ``dim + 1`` affinely independent anchors).

    Parameters
    ----------
    scenario : RangeScenario

    Returns
    -------
    [K, n_agents] bool

    Examples
    --------
    Four anchors on the floor of a room are one plane: hearing all four does not locate a
    3-D agent; a fifth on the ceiling does.

    >>> from types import SimpleNamespace
    >>> floor = [[0, 0, 0], [10, 0, 0], [0, 10, 0], [10, 10, 0]]
    >>> z = np.full((1, 1, 1 + 5), 1.0); z[0, 0, 0] = np.nan
    >>> sc = SimpleNamespace(anchors=np.array([*floor, [5, 5, 3]], float), z=z, n_agents=1,
    ...                      model=SimpleNamespace(dim=3))
    >>> bool(anchor_localizable(sc)[0, 0])
    True
    >>> z[0, 0, -1] = np.nan  # the ceiling anchor out of range
    >>> bool(anchor_localizable(sc)[0, 0])
    False
    """
    dim = scenario.model.dim
    anchors = np.asarray(scenario.anchors, dtype=np.float64)
    heard = np.isfinite(scenario.z[:, :, scenario.n_agents :])  # [K, n_agents, n_anchors]
    if heard.size == 0:
        return np.zeros(heard.shape[:2], dtype=bool)
    patterns, which = np.unique(heard.reshape(-1, heard.shape[-1]), axis=0, return_inverse=True)
    scale = max(float(np.ptp(anchors)), 1.0)
    ok = np.zeros(len(patterns), dtype=bool)
    for j, pat in enumerate(patterns):
        a = anchors[pat]
        if len(a) > dim:
            sv = np.linalg.svd(a[1:] - a[0], compute_uv=False)
            ok[j] = sv.size >= dim and sv[dim - 1] > 1e-9 * scale
    return ok[which.reshape(-1)].reshape(heard.shape[:2])


def network_states(network, model: RangeModel) -> np.ndarray:
    """True agent states ``[n_snapshots, n_agents, N_D]`` of a realized network.

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

    Returns
    -------
    phyloc.network.NetworkSpec
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


def flow_example(rng, *, n_particles: int = 60, n_lambda: int = 20, sigma_r: float = 0.1) -> dict:
    """PF-BP Fig. 1: the particle flow of two cooperating agents near three anchors.

    Two agents in the plane, each ranging to two of three anchors (so each agent's position
    alone is ambiguous: two rings cross twice) and to each other. Particles of the joint
    position state ``[p_1, p_2]`` are drawn from a Gaussian prior (``σ = 2.5`` m, its mean
    2.2 m off each agent, between the two crossings) and moved by the exact Daum–Huang flow of
    PF-BP eqs. (13), (24), (25), linearized at the flowing mean, with ``n_lambda``
    exponentially spaced λ-steps
    (:func:`~phyloc.localization.tracking._flow.lambda_schedule`); every intermediate position
    is kept. The cooperative range selects the crossing the particles flow to.

    Returns
    -------
    dict
        ``anchors [3, 2]``, ``truth [2, 2]``, ``links`` (``[[agent, node], …]``, nodes 0–2
        anchors, 3 the other agent), ``paths [n_lambda + 1, M, 2, 2]`` (λ-step, particle,
        agent, xy), ``prior_mean [2, 2]``, ``ranges_m [5]`` (the four anchor ranges in
        ``links`` order, then the agent–agent range), ``grid_m [G]`` and
        ``anchor_loglik [2, G, G]`` (each agent's log-likelihood of its two anchor ranges on
        the grid, with the range σ widened to 0.5 m so that the two crossings show: the
        multimodal map the figure shows).
    """
    from phyloc.localization.tracking._flow import lambda_schedule, range_linearization

    M = v.integer("n_particles", n_particles, minimum=2)
    N = v.integer("n_lambda", n_lambda, minimum=1)
    sigma = v.positive("sigma_r", sigma_r)
    anchors = np.array([[0.0, 0.0], [12.0, 0.0], [6.0, 10.0]])
    truth = np.array([[4.0, 3.0], [7.0, 4.0]])
    # agent 1 ranges anchors 0 and 1, agent 2 anchors 1 and 2, and each other (offsets into x);
    # their second ring crossings lie at (4, −3) and (10.8, 6.3)
    pairs = [(0, 0), (0, 1), (1, 1), (1, 2)]
    off_a = np.array([2 * a for a, _ in pairs] + [0])
    off_b = np.array([-1] * len(pairs) + [2])
    anchor_pos = np.array([anchors[k] for _, k in pairs] + [[0.0, 0.0]])
    x_true = truth.reshape(-1)
    z = range_linearization(x_true, off_a, off_b, anchor_pos, 2)[1]
    z = z + rng.normal(0.0, sigma, z.size)
    prior_mean = truth + np.array([[-1.0, -2.0], [2.0, 1.0]])
    P = np.eye(4) * 2.5**2
    X = prior_mean.reshape(-1) + rng.normal(0.0, 2.5, (M, 4))
    R = np.eye(z.size) * sigma**2
    lambdas, steps = lambda_schedule(N)
    paths = [X.copy()]
    mean = prior_mean.reshape(-1).copy()
    m0 = mean.copy()
    for lam, dl in zip(lambdas, steps, strict=True):  # one λ-step at a time, m0 fixed

        def linearize(xb):
            return range_linearization(xb, off_a, off_b, anchor_pos, 2)

        X, mean = _edh_step(X, mean, m0, P, linearize, z, R, lam, dl)
        paths.append(X.copy())
    grid = np.linspace(-5.0, 15.0, 201)
    gx, gy = np.meshgrid(grid, grid, indexing="ij")
    maps = np.zeros((2, grid.size, grid.size))
    shown = max(sigma, 0.5)  # the map's range σ: wide enough to see the ring crossings
    for q, (a, k) in enumerate(pairs):
        d = np.hypot(gx - anchors[k, 0], gy - anchors[k, 1])
        maps[a] += -0.5 * ((d - z[q]) / shown) ** 2
    return {
        "anchors": anchors,
        "truth": truth,
        "links": np.array([[a, k] for a, k in pairs] + [[0, 3]]),
        "paths": np.stack(paths).reshape(N + 1, M, 2, 2),
        "prior_mean": prior_mean,
        "ranges_m": z,
        "grid_m": grid,
        "anchor_loglik": maps,
    }


def _edh_step(X, mean, m0, P, linearize, z, R, lam, dl):
    """One λ-step of :func:`~phyloc.localization.tracking._flow.edh_flow` from ``(X, mean)``
    (the prior mean ``m0`` kept): ``x ← x + Δ_l (A(λ) x + b(λ))``, PF-BP eqs. (21), (24), (25)."""
    from phyloc.localization.tracking._flow import flow_parameters

    H, h = linearize(mean)
    A, b = flow_parameters(P, H, R, z, h - H @ mean, m0, lam)
    return X + dl * (X @ A.T + b), mean + dl * (A @ mean + b)

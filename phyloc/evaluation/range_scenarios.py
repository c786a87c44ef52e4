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
from phyloc.localization.tracking.range_models import (
    STATE_MODELS,
    RangeMeasurements,
    RangeModel,
)

__all__ = [
    "RangeScenario",
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

"""The closed loop estimation ↔ control: one Monte Carlo trial of mobile-anchor control.

Per time step ``k = 1 … K`` (FIM §II–III):

1. the controller sees the agents' beliefs at ``k − 1`` and the anchors' positions and picks the
   mobile anchors' controls (:func:`phyloc.control.policies.decide`);
2. the mobile anchors move, ``p_j ← p_j + T_Δ u_j`` [2] — an anchor's trajectory is an output of
   the loop, never drawn in advance;
3. the agents move by their motion model with white acceleration noise [1];
4. every agent measures its range to every anchor (and, with ``agent_ranges``, to every other
   agent) within ``comm_range_m``, ``z = ‖p_i − p_j‖ + n``, ``n ~ N(0, σ²)`` [3]–[4];
5. the estimation layer (SP-BP as in the paper, or PF-BP) updates the beliefs from those ranges
   and the anchors' current positions.

The policies of one trial share the agents' true trajectories and the measurement noise draws
(common random numbers): their differences are the control's alone.

References
----------
FIM: W. Zhang, B. Teague and F. Meyer, "Cooperative localization: a Fisher information
approach," arXiv:2212.14554, 2022.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from phyloc import _validate as v
from phyloc._validate import check_keys, check_types
from phyloc.control.fim import control_set
from phyloc.control.policies import PolicySpec, decide
from phyloc.control.search import ControlProblem
from phyloc.errors import ValidationError
from phyloc.localization.tracking import GaussianPrior, PFBPOptions, RangeModel, SPBPOptions
from phyloc.localization.tracking.pfbp import PFBPTracker
from phyloc.localization.tracking.spbp import SPBPTracker
from phyloc.network import Network

ESTIMATORS = {"spbp": (SPBPTracker, SPBPOptions), "pfbp": (PFBPTracker, PFBPOptions)}
"""Estimation layers: name → (step-by-step tracker, options)."""


@dataclass(frozen=True)
class ControlScenario:
    """A mobile-anchor control scenario (the ``[network]`` section of a ``control`` recipe).

    Defaults are the FIM paper's case study: one mobile agent, one mobile and one static anchor,
    initial positions uniform in ``[−100, 100]³`` m, ``T_Δ = 1`` s, 50 steps, agent state
    ``[x, y, z, ẋ, ẏ]`` (constant height, 2-D constant velocity, driving-noise variance
    0.001 m²/s⁴), prior ``diag(10², 10², 50², 0.1, 0.1)``, σ = 0.1 m, anchors at 2 m/s.

    Parameters
    ----------
    agents, mobile_anchors, static_anchors : int
        Numbers of nodes (agents >= 1, anchors >= 0, at least one anchor).
    steps : int
        K.
    dt_s : float
        T_Δ [s].
    region_m : [lo, hi]
        Initial positions (prior means of the agents, the anchors) are uniform in
        ``[lo, hi]^dim``; nothing confines the motion afterwards.
    dim : int
        2 or 3.
    planar : bool
        Agents at constant height (3-D only): state ``[x, y, z, ẋ, ẏ]``.
    accel_var : float
        Driving-noise variance σ_a² [m²/s⁴].
    prior_var : list of float
        Diagonal of the prior covariance, one entry per state component (position first).
        The prior means are the uniform positions and zero rates; the true initial state is
        drawn from the prior.
    sigma_r : float
        Range noise σ [m].
    comm_range_m : float
        Ranges only within this distance; 0: every pair.
    agent_ranges : bool
        Agents also range to each other (cooperative localization).
    speed_m_s, n_azimuth, elevations_deg
        The control set U (:func:`~phyloc.control.fim.control_set`); ``elevations_deg = []``
        in 2-D.
    """

    agents: int = 1
    mobile_anchors: int = 1
    static_anchors: int = 1
    steps: int = 50
    dt_s: float = 1.0
    region_m: tuple = (-100.0, 100.0)
    dim: int = 3
    planar: bool = True
    accel_var: float = 0.001
    prior_var: tuple = (100.0, 100.0, 2500.0, 0.1, 0.1)
    sigma_r: float = 0.1
    comm_range_m: float = 0.0
    agent_ranges: bool = False
    speed_m_s: float = 2.0
    n_azimuth: int = 8
    elevations_deg: tuple = (-45.0, 0.0, 45.0)
    model: RangeModel = field(init=False, repr=False, compare=False)
    controls: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        s = "network"
        v.integer_field(self, "agents", f"{s}.agents", minimum=1)
        m1 = v.integer(f"{s}.mobile_anchors", self.mobile_anchors, minimum=0)
        m0 = v.integer(f"{s}.static_anchors", self.static_anchors, minimum=0)
        if m0 + m1 == 0:
            raise ValidationError(f"{s}.mobile_anchors", 0, "at least one anchor in all")
        v.integer_field(self, "steps", f"{s}.steps", minimum=1)
        lo, hi = (v.finite(f"{s}.region_m", x) for x in _pair(self.region_m, f"{s}.region_m"))
        if not lo < hi:
            raise ValidationError(f"{s}.region_m", list(self.region_m), "[lo, hi] with lo < hi")
        object.__setattr__(self, "region_m", (lo, hi))
        v.positive(f"{s}.comm_range_m", self.comm_range_m, allow_zero=True)
        v.boolean(f"{s}.agent_ranges", self.agent_ranges)
        try:
            model = RangeModel(
                "constant_velocity",
                self.dim,
                dt_s=self.dt_s,
                accel_std=float(np.sqrt(v.positive("accel_var", self.accel_var, allow_zero=True))),
                sigma_r=self.sigma_r,
                planar=self.planar,
            )
            controls = control_set(
                self.speed_m_s,
                self.n_azimuth,
                tuple(self.elevations_deg) if self.dim == 3 else (),
            )
        except ValidationError as exc:
            raise ValidationError(f"{s}.{exc.field}", exc.value, exc.allowed) from None
        pv = np.asarray(self.prior_var, dtype=float)
        if pv.shape != (model.state_dim,) or not np.all(np.isfinite(pv)) or np.any(pv <= 0):
            raise ValidationError(
                f"{s}.prior_var",
                list(self.prior_var),
                f"{model.state_dim} positive variances (the state: position, then rates)",
            )
        object.__setattr__(self, "prior_var", tuple(pv.tolist()))
        object.__setattr__(self, "elevations_deg", tuple(self.elevations_deg))
        object.__setattr__(self, "model", model)
        object.__setattr__(self, "controls", controls)

    @classmethod
    def from_dict(cls, d: dict) -> ControlScenario:
        """From ``[network]``; unknown keys are errors naming the closest valid key."""
        names = [f.name for f in dataclasses.fields(cls) if f.init]
        check_keys(d, names, "network")
        check_types(cls, d, "network")
        d = {k: tuple(x) if isinstance(x, list) else x for k, x in d.items()}
        return cls(**d)

    @property
    def n_anchors(self) -> int:
        """Mobile + static anchors."""
        return self.mobile_anchors + self.static_anchors


def _pair(x, name):
    if not isinstance(x, (list, tuple)) or len(x) != 2:
        raise ValidationError(name, x, "[lo, hi] in metres")
    return x


def make_estimator(name: str, options: dict, where: str = "localization"):
    """``(tracker class, options)`` of an estimation layer: ``"spbp"`` (the paper) or
    ``"pfbp"``; ``options`` are the tracker's option keys, or its options object."""
    v.choice(f"{where}.method", name, tuple(ESTIMATORS))
    cls, opt_cls = ESTIMATORS[name]
    if isinstance(options, opt_cls):
        return cls, options
    return cls, opt_cls.from_dict(dict(options), where)


@dataclass
class TrialDraws:
    """What the policies of one trial share: initial geometry, truth and noise draws."""

    prior: GaussianPrior
    truth: np.ndarray  # [K + 1, n_agents, N_D]
    mobile0: np.ndarray  # [M1, dim]
    static: np.ndarray  # [M0, dim]
    noise: np.ndarray  # [K, n_agents, n_agents + M] standard normals


def draw_trial(sc: ControlScenario, rng: np.random.Generator) -> TrialDraws:
    """Draw a trial's prior, true trajectories, anchors and measurement noise (in that order)."""
    model = sc.model
    dim, nd, n = sc.dim, model.state_dim, sc.agents
    lo, hi = sc.region_m
    mean = np.zeros((n, nd))
    mean[:, :dim] = rng.uniform(lo, hi, size=(n, dim))
    cov = np.repeat(np.diag(sc.prior_var)[None], n, axis=0)
    x = mean + rng.standard_normal((n, nd)) * np.sqrt(np.asarray(sc.prior_var))
    mobile0 = rng.uniform(lo, hi, size=(sc.mobile_anchors, dim))
    static = rng.uniform(lo, hi, size=(sc.static_anchors, dim))
    F, _ = model.matrices()
    G = model.noise_gain()
    w = rng.standard_normal((sc.steps, n, G.shape[1])) * model.accel_std
    truth = np.empty((sc.steps + 1, n, nd))
    truth[0] = x
    for k in range(sc.steps):
        x = x @ F.T + w[k] @ G.T
        truth[k + 1] = x
    noise = rng.standard_normal((sc.steps, n, n + sc.n_anchors))
    prior = GaussianPrior(mean, cov, label="uniform position, zero rates")
    return TrialDraws(prior, truth, mobile0, static, noise)


def measure(sc: ControlScenario, pos: np.ndarray, anchors: np.ndarray, noise: np.ndarray):
    """Ranges ``z [n_agents, n_agents + M]`` at true positions ``pos [n_agents, dim]`` with
    anchors at ``anchors [M, dim]`` and standard normals ``noise`` (NaN where not measured)."""
    n = pos.shape[0]
    nodes = np.concatenate([pos, anchors])
    d = np.linalg.norm(pos[:, None, :] - nodes[None], axis=-1)
    z = d + sc.sigma_r * noise
    mask = np.ones_like(z, dtype=bool)
    mask[:, :n] = sc.agent_ranges
    mask[np.arange(n), np.arange(n)] = False
    if sc.comm_range_m > 0:
        mask &= d <= sc.comm_range_m
    return np.where(mask, z, np.nan)


def run_policy(sc, draws, spec: PolicySpec, estimator, policy_rng, estimator_rng, keep=False):
    """Run one policy through a trial's draws.

    Returns
    -------
    dict
        ``err2 [K, n_agents]`` (squared position errors [m²], non-finite where the estimator
        diverged), ``decision_s`` (mean seconds per decision), and with ``keep``: ``estimates
        [K, n_agents, dim]``, ``mobile [K + 1, M₁, dim]`` (the anchors' trajectory).
    """
    tracker_cls, opts = estimator
    model = sc.model
    F, Q = model.matrices()
    dim = sc.dim
    tracker = tracker_cls(model, draws.prior, estimator_rng, opts)  # SP-BP ignores the rng
    mean, cov = draws.prior.mean.copy(), draws.prior.cov.copy()
    mobile = draws.mobile0.copy()
    K = sc.steps
    err2 = np.empty((K, sc.agents))
    est = np.empty((K, sc.agents, dim))
    path = [mobile.copy()]
    t_decide = 0.0
    for k in range(K):
        problem = ControlProblem(
            mean,
            cov,
            F,
            Q,
            mobile,
            draws.static,
            sc.controls,
            sc.dt_s,
            sc.sigma_r,
            sc.comm_range_m or None,
            spec.agent_terms,
        )
        t0 = time.perf_counter()
        u = decide(spec, problem, policy_rng)
        t_decide += time.perf_counter() - t0
        mobile = mobile + sc.dt_s * u
        path.append(mobile.copy())
        anchors = np.concatenate([mobile, draws.static])
        pos = draws.truth[k + 1, :, :dim]
        z = measure(sc, pos, anchors, draws.noise[k])
        try:
            mean, cov = tracker.step(z, anchors)
        except np.linalg.LinAlgError:
            mean = np.full_like(mean, np.nan)
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(cov))):
            err2[k:] = np.inf  # diverged: lost from here on
            est[k:] = np.nan
            break
        est[k] = mean[:, :dim]
        err2[k] = np.sum((mean[:, :dim] - pos) ** 2, axis=1)
    out = {"err2": err2, "decision_s": t_decide / K}
    if keep:
        while len(path) < K + 1:
            path.append(path[-1])
        out["estimates"] = est
        out["mobile"] = np.stack(path)
    return out


def realized_network(sc: ControlScenario, draws: TrialDraws, mobile: np.ndarray) -> Network:
    """The trial as a :class:`~phyloc.network.Network`: the agents' true positions and the
    anchors' positions at every step ``0 … K`` (the mobile ones from the control loop,
    ``mobile [K + 1, M₁, dim]`` as returned by :func:`run_policy` with ``keep``), anchors last.

    Examples
    --------
    >>> sc = ControlScenario(steps=3)
    >>> draws = draw_trial(sc, np.random.default_rng(0))
    >>> r = run_policy(sc, draws, PolicySpec("random"), make_estimator("spbp", {}),
    ...                np.random.default_rng(1), None, keep=True)
    >>> net = realized_network(sc, draws, r["mobile"])
    >>> net.positions.shape, bool(net.anchors_move)
    ((4, 3, 3), True)
    """
    K = sc.steps
    mobile = np.asarray(mobile, dtype=float)
    if mobile.shape != (K + 1, sc.mobile_anchors, sc.dim):
        raise ValidationError(
            "mobile", f"array of shape {mobile.shape}", f"({K + 1}, {sc.mobile_anchors}, {sc.dim})"
        )
    static = np.broadcast_to(draws.static, (K + 1, *draws.static.shape))
    pos = np.concatenate([draws.truth[:, :, : sc.dim], mobile, static], axis=1)
    is_anchor = np.r_[np.zeros(sc.agents, bool), np.ones(sc.n_anchors, bool)]
    comm = sc.comm_range_m or None
    return Network(pos, is_anchor, comm_range_m=comm, dt_s=sc.dt_s, anchors_move=True)

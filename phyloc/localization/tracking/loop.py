"""The one tracking loop of the family: time steps, prediction, estimates, results, timing.

PF-BP, SIR-BP, SP-BP and the EDH filter share the loop of PF-BP Algorithm 1 over time steps
``k = 1 … K``; a method supplies only its :class:`Update`:

1. **predict** every :class:`Belief` through the motion model of
   :class:`~phyloc.localization.tracking.model.RangeModel` (done here, for every method):
   particles by PF-BP eq. (1) (drawing the process noise), Gaussian means by ``F x̂``,
   covariances by PF-BP eq. (29) per agent or PF-BP eqs. (45)–(48) for a joint covariance;
2. **update** by the step's ranges (the method's :meth:`Update.update`): for the distributed
   methods, :func:`message_passing` — ``U`` iterations with all beliefs updated in parallel from
   those of the previous iteration (extrinsic information approximated by beliefs, PF-BP
   eq. (19)); for the centralized EDH filter, one joint update;
3. **estimate** (PF-BP eq. (20)) and record: estimates and covariances of every step, the wall
   time of each step and of its stages (:class:`StageClock`), the agent updates performed, and
   what one agent sends a neighbour per iteration (:func:`message_floats`).

:class:`Tracker` runs the loop one step at a time (a closed loop whose next measurements
depend on the current beliefs, e.g. :mod:`phyloc.control`); :func:`track` runs it over
:class:`~phyloc.localization.tracking.measurements.RangeMeasurements` and assembles the
:class:`~phyloc.localization.results.Result`. Random numbers are drawn in the order prediction
(particles), then the method's update.

Examples
--------
A method that keeps its prediction (no measurement update), to show the loop alone:

>>> from phyloc.localization.tracking import GaussianPrior, RangeMeasurements, RangeModel
>>> class Predict(Update):
...     label = "predict"
...     def initial(self, mean0, cov0, rng):
...         return Belief(mean=mean0, cov=cov0)
...     def update(self, pred, z_k, anchors_k, rng):
...         return pred
...     def estimate(self, belief):
...         return belief.mean.copy(), belief.cov.copy()
...     def floats_per_link_iteration(self):
...         return message_floats("none", self.model.state_dim)
>>> model = RangeModel("constant_velocity", 2, dt_s=1.0, accel_std=0.0)
>>> meas = RangeMeasurements(model, [[0.0, 0.0]], np.full((2, 1, 2), np.nan))
>>> prior = GaussianPrior(np.array([[0.0, 0.0, 1.0, 2.0]]), np.eye(4)[None])
>>> res = track(meas, prior, None, Predict(model, None))
>>> res.estimates[:, 0, :2].tolist(), res.timing.agent_iterations
([[1.0, 2.0], [2.0, 4.0]], 2)

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
"""

from __future__ import annotations

import abc
import time
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from phyloc.errors import ValidationError
from phyloc.localization.results import Result, Timing
from phyloc.localization.tracking.measurements import RangeMeasurements
from phyloc.localization.tracking.model import RangeModel
from phyloc.localization.tracking.priors import GaussianPrior, check_prior


@dataclass(frozen=True, eq=False)
class Belief:
    """The beliefs of all agents at one time: particles, a Gaussian, or both.

    Attributes
    ----------
    particles : [n_agents, M, N_D] float64 or None
        Equally weighted particles per agent; ``joint``: ``[M, n_agents, N_D]``, ``M`` joint
        particles.
    mean : [n_agents, N_D] float64 or None
        Gaussian means (SP-BP).
    cov : [n_agents, N_D, N_D] float64 or None
        Covariances per agent; ``joint``: one ``[n_agents·N_D, n_agents·N_D]`` covariance.
    joint : bool
        One belief of the joint state (the EDH filter), not one per agent.
    """

    particles: np.ndarray | None = None
    mean: np.ndarray | None = None
    cov: np.ndarray | None = None
    joint: bool = False


#: The stages a step's wall time is split into (:class:`StageClock`), in the order of a step.
STAGES = (
    "predict",  # the motion model (PF-BP eqs. (1), (29), (45)), for every method
    "sample",  # PF-BP: the neighbours' particles drawn from their Gaussian beliefs
    "flow",  # PF-BP, EDH: the particle flow (PF-BP eqs. (23)–(27), (42), (43))
    "weights",  # likelihoods and log weights (PF-BP eqs. (16)–(18), (22), (44))
    "resample",  # PF-BP, EDH, SIR-BP: systematic resampling
    "covariance",  # PF-BP, EDH: the UKF covariance (PF-BP eqs. (30), (49)); SP-BP: its update
    "regularize",  # the kernel of PF-BP eqs. (32), (33)
    "estimate",  # PF-BP eq. (20)
    "other",  # the rest of the step: message-passing bookkeeping, link tables, copies
)


class StageClock:
    """Wall time of the stages of one time step (PF-BP Tables I, II, split by stage).

    A method times a part of its update with ``with clock("flow"): …``; :meth:`take` returns
    the seconds per stage since the last call. Stage names are those of :data:`STAGES`.

    Examples
    --------
    >>> clock = StageClock()
    >>> with clock("flow"):
    ...     pass
    >>> with clock("flow"):
    ...     pass
    >>> seconds = clock.take()
    >>> list(seconds), seconds["flow"] >= 0.0, clock.take()
    (['flow'], True, {})
    """

    def __init__(self):
        self._seconds: dict[str, float] = {}

    @contextmanager
    def __call__(self, stage: str):
        if stage not in STAGES:
            raise ValidationError("stage", stage, f"one of {STAGES}")
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self._seconds[stage] = self._seconds.get(stage, 0.0) + time.perf_counter() - t0

    def take(self) -> dict[str, float]:
        """The seconds per stage timed since the last call; the clock starts again at zero."""
        seconds, self._seconds = self._seconds, {}
        return seconds


class Update(abc.ABC):
    """What a tracker supplies to the loop: its beliefs at time 0 and its update of one step.

    Subclasses set :attr:`label` (and :attr:`distributed`) and implement :meth:`initial`,
    :meth:`update`, :meth:`estimate` and :meth:`floats_per_link_iteration`; they may time parts
    of :meth:`update` with :attr:`clock` (what they leave untimed counts as ``"other"``).

    Parameters
    ----------
    model : RangeModel
        The model the tracker assumes.
    options
        The tracker's options (validated by the caller, e.g. :func:`check_run_args`).
    """

    #: ``Result.label``.
    label = ""
    #: True: the agents update their beliefs themselves (``Timing.agent_s = step_s / n_agents``);
    #: False: a centralized filter (``agent_s`` NaN).
    distributed = True

    def __init__(self, model: RangeModel, options):
        if not isinstance(model, RangeModel):
            raise ValidationError("model", type(model).__name__, "must be a RangeModel")
        self.model, self.options = model, options
        #: :class:`StageClock` of the current step.
        self.clock = StageClock()

    @property
    def iterations(self) -> int:
        """Message-passing iterations per time step (``Timing.agent_iterations``): ``U``."""
        return getattr(self.options, "n_iterations", 1)

    @abc.abstractmethod
    def initial(self, mean0: np.ndarray, cov0: np.ndarray, rng) -> Belief:
        """Beliefs at time 0 from the prior ``mean0 [n_agents, N_D]``, ``cov0`` (copies)."""

    @abc.abstractmethod
    def update(self, pred: Belief, z_k: np.ndarray, anchors_k: np.ndarray, rng) -> Belief:
        """Update the predicted beliefs by one step's ranges ``z_k`` with anchors at
        ``anchors_k``."""

    @abc.abstractmethod
    def estimate(self, belief: Belief) -> tuple[np.ndarray, np.ndarray]:
        """``(mean [n_agents, N_D], cov [n_agents, N_D, N_D])``, new arrays."""

    @abc.abstractmethod
    def floats_per_link_iteration(self) -> float:
        """What one agent sends a neighbour per iteration (:func:`message_floats`)."""


class Tracker:
    """The loop one time step at a time: predict, the method's update, estimate.

    Parameters
    ----------
    update : Update
        The method (its ``model`` is the tracker's).
    prior : GaussianPrior
        Beliefs at time 0 (:meth:`Update.initial`).
    rng : numpy.random.Generator or None
        Draws the process noise of particles and the method's random numbers (None for a
        deterministic method); may be replaced between steps.

    Attributes
    ----------
    belief : Belief
        The current beliefs; :attr:`particles`, :attr:`mean`, :attr:`cov` are its fields.
    stage_s : dict
        Seconds per stage of the last :meth:`step` (:data:`STAGES`; ``"other"`` the part of
        the step no stage timed).
    """

    def __init__(self, update: Update, prior: GaussianPrior, rng):
        if not isinstance(update, Update):
            raise ValidationError("update", type(update).__name__, "must be an Update")
        mean0, cov0 = check_prior(prior, update.model)
        self.update, self.model, self.options, self.rng = update, update.model, update.options, rng
        self.belief = update.initial(mean0, cov0, rng)
        self.stage_s: dict[str, float] = {}
        self._joint = None
        if self.belief.joint:  # PF-BP eqs. (46), (47)
            F, Q = self.model.matrices()
            eye = np.eye(self.belief.cov.shape[0] // self.model.state_dim)
            self._joint = (np.kron(eye, F), np.kron(eye, Q))

    @property
    def particles(self) -> np.ndarray | None:
        """Current particles (layout of :class:`Belief`)."""
        return self.belief.particles

    @property
    def mean(self) -> np.ndarray | None:
        """Current Gaussian means."""
        return self.belief.mean

    @property
    def cov(self) -> np.ndarray | None:
        """Current covariances."""
        return self.belief.cov

    def predict(self, belief: Belief) -> Belief:
        """Predict ``belief`` one step through the motion model: particles first (PF-BP
        eq. (1), drawing from :attr:`rng`), then means, then covariances (PF-BP eq. (29);
        joint: PF-BP eq. (45))."""
        model = self.model
        X = None
        if belief.particles is not None:
            X = model.predict_particles(belief.particles, self.rng)
        mean = None if belief.mean is None else belief.mean @ model.matrices()[0].T
        cov = belief.cov
        if cov is not None and belief.joint:
            Ft, W = self._joint
            cov = Ft @ cov @ Ft.T + W
        elif cov is not None:
            cov = model.predict_cov(cov)
        return Belief(X, mean, cov, belief.joint)

    def step(self, z_k: np.ndarray, anchors_k: np.ndarray):
        """Predict and update by one step's ranges ``z_k [n_agents, n_agents + n_anchors]``
        with anchors at ``anchors_k [n_anchors, dim]``; returns ``(mean, cov)`` (new arrays,
        :meth:`Update.estimate`); :attr:`stage_s` gets the step's seconds per stage."""
        clock = self.update.clock
        clock.take()
        t0 = time.perf_counter()
        with clock("predict"):
            pred = self.predict(self.belief)
        self.belief = self.update.update(pred, z_k, anchors_k, self.rng)
        with clock("estimate"):
            out = self.update.estimate(self.belief)
        stages = clock.take()
        stages["other"] = max(time.perf_counter() - t0 - sum(stages.values()), 0.0)
        self.stage_s = stages
        return out


def track(measurements: RangeMeasurements, prior: GaussianPrior, rng, update: Update) -> Result:
    """Run a tracker over all time steps; the ``run`` function of every method of the family.

    Parameters
    ----------
    measurements : RangeMeasurements
        Ranges, anchors (fixed or per step), model (no truth).
    prior : GaussianPrior
    rng : numpy.random.Generator or None
    update : Update
        The method, built for ``measurements.model``.

    Returns
    -------
    Result
        ``estimates [K, n_agents, N_D]``, ``covariances [K, n_agents, N_D, N_D]``; the final
        ``particles [n_agents, M, N_D]`` (joint particles split by agent) with uniform
        ``log_weights``, or None; ``timing.step_s`` per step, ``agent_s = step_s / n_agents``
        (NaN when not distributed), ``agent_iterations = K · U · n_agents``;
        ``diagnostics["floats_per_link_iteration"]``; ``diagnostics["stage_s"]``, the seconds
        of each stage of :data:`STAGES` the method has in each step (``{stage: [K]}``, summing
        to ``timing.step_s`` up to the clock's own cost); ``label = update.label``.
    """
    t_start = time.perf_counter()
    check_inputs(measurements, prior)
    tracker = Tracker(update, prior, rng)
    nd, n_ag, K = measurements.model.state_dim, measurements.n_agents, measurements.n_steps
    out_mean = np.empty((K, n_ag, nd))
    out_cov = np.empty((K, n_ag, nd, nd))
    step_s = np.empty(K)
    stage_s: dict[str, np.ndarray] = {}
    for k in range(K):
        z_k, anchors_k = measurements.z[k], measurements.anchors_at(k)
        t0 = time.perf_counter()
        out_mean[k], out_cov[k] = tracker.step(z_k, anchors_k)
        step_s[k] = time.perf_counter() - t0
        for stage, seconds in tracker.stage_s.items():
            stage_s.setdefault(stage, np.zeros(K))[k] = seconds
    agent_s = step_s / n_ag if update.distributed else np.full(K, np.nan)
    timing = Timing(time.perf_counter() - t_start, step_s, agent_s, K * update.iterations * n_ag)
    particles, log_weights = tracker.particles, None
    if particles is not None:
        if tracker.belief.joint:
            particles = np.ascontiguousarray(particles.transpose(1, 0, 2))
        log_weights = np.full(particles.shape[:2], -np.log(particles.shape[1]))
    return Result(
        out_mean,
        out_cov,
        timing,
        particles=particles,
        log_weights=log_weights,
        diagnostics={
            "floats_per_link_iteration": update.floats_per_link_iteration(),
            "stage_s": {stage: stage_s[stage] for stage in STAGES if stage in stage_s},
        },
        label=update.label,
    )


def message_passing(n_iterations: int, beliefs: tuple, agent_update, share=None) -> tuple:
    """``U`` message-passing iterations, all agents' beliefs updated in parallel.

    Iteration ``u`` reads only the beliefs of iteration ``u − 1`` (extrinsic information
    approximated by beliefs, PF-BP eq. (19)); the schedule of PF-BP Algorithm 1, lines 10–18.

    Parameters
    ----------
    n_iterations : int
        ``U``.
    beliefs : tuple of arrays
        The beliefs at ``u = 0`` (the prediction), each with the agent on the first axis, e.g.
        ``(particles, covariances)``.
    agent_update : callable
        ``agent_update(i, *beliefs, shared) -> tuple`` of agent ``i``'s new entries.
    share : callable, optional
        ``share(u, *beliefs)``: what the agents broadcast once per iteration besides the
        beliefs (passed to ``agent_update`` as ``shared``; default None).

    Returns
    -------
    tuple of arrays
        The beliefs after ``U`` iterations.

    Examples
    --------
    >>> avg = lambda i, x, shared: (0.5 * (x[i] + shared),)  # move to the network mean
    >>> message_passing(2, (np.array([0.0, 4.0]),), avg, lambda u, x: x.mean())
    (array([1.5, 2.5]),)
    """
    for u in range(n_iterations):
        shared = None if share is None else share(u, *beliefs)
        new = tuple(np.empty_like(b) for b in beliefs)
        for i in range(beliefs[0].shape[0]):
            for dst, value in zip(new, agent_update(i, *beliefs, shared), strict=True):
                dst[i] = value
        beliefs = new
    return beliefs


def message_floats(kind: str, state_dim: int, n_particles: int = 0, dim: int = 0) -> float:
    """Floats one agent sends one neighbour per message-passing iteration (its belief).

    ``"gaussian"``: mean and covariance, ``N_D + N_D(N_D + 1)/2`` (a symmetric matrix);
    ``"particles+cov"``: ``M·N_D`` particle states and the covariance; ``"positions"``: ``M·dim``
    particle positions (all a neighbour's range factor reads, SIR-BP); ``"none"``: NaN (a
    centralized filter exchanges no beliefs).

    >>> message_floats("gaussian", 9), message_floats("positions", 9, 100_000, 3)
    (54.0, 300000.0)
    """
    cov = state_dim * (state_dim + 1) / 2
    if kind == "gaussian":
        return state_dim + cov
    if kind == "particles+cov":
        return n_particles * state_dim + cov
    if kind == "positions":
        return float(n_particles * dim)
    if kind == "none":
        return float("nan")
    raise ValidationError("kind", kind, "gaussian, particles+cov, positions or none")


def check_inputs(measurements, prior):
    """Validate a tracker's measurements and prior; returns float64 copies of the prior."""
    if not isinstance(measurements, RangeMeasurements):
        raise ValidationError(
            "measurements", type(measurements).__name__, "must be a RangeMeasurements"
        )
    return check_prior(prior, measurements.model, measurements.n_agents)


def check_run_args(options, options_cls, rng, *, rng_required: bool = True):
    """Validate the common arguments of the range-level trackers; returns the options."""
    opt = options_cls() if options is None else options
    if not isinstance(opt, options_cls):
        raise ValidationError("options", type(opt).__name__, f"must be {options_cls.__name__}")
    if (rng_required or rng is not None) and not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", type(rng).__name__, "must be a numpy.random.Generator")
    return opt

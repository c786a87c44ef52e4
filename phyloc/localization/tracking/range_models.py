"""Range-level models of the PF-BP paper: agent states, range measurements, Gaussian priors.

The state of agent ``i`` at time ``k`` is ``x_i = [p_i; v_i; a_i]`` (constant acceleration, CA,
PF-BP eqs. (1)–(3)), ``[p_i; v_i]`` (constant velocity, CV) or ``p_i`` (static), each block a
``dim``-vector (2-D or 3-D). The transition is ``x_i^{(k)} = F x_i^{(k−1)} + G u`` with ``F``,
``Q = G σ_a² Gᵀ`` from :func:`phyloc.network.motion.transition_matrices` (static: ``F = I``,
``Q = 0``).

A range measurement (PF-BP eq. (8)) is ``z_ij = ‖p_j − p_i‖ + n_ij``, ``n_ij ~ N(0, σ²)`` iid.
:class:`RangeMeasurements` stores them densely: ``z[k−1, i, j]`` is the measurement agent ``i``
made of node ``j`` at time ``k`` (NaN when ``i`` and ``j`` are not connected). Nodes are ordered
agents first, anchors last (as in :class:`~phyloc.network.Network`), so columns ``n_agents …``
are anchors, whose positions are known. Both agents of a connected pair measure, each with its
own noise: ``z_ij ≠ z_ji``. The measurements carry no truth; simulated ones come from
:func:`phyloc.evaluation.range_scenarios.simulate_scenario`. :class:`GaussianPrior` is the
prior of every tracker (:func:`paper_prior`: PF-BP eq. (31)).

Factors (PF-BP §V-A): *distributed* — agent ``i`` uses only its own row ``z[i, :]`` (``f_ij ≠
f_ji``, PF-BP eq. (17)); *centralized* — agent ``i`` also uses ``z[j, i]`` of every agent ``j``
(``f_ij = f_ji``, PF-BP eq. (18)). :func:`agent_measurements` lists the measurements of one
agent under either rule; :func:`all_measurements` lists every measurement (the joint likelihood
used by the EDH filter).

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
        Range noise standard deviation σ [m], > 0 (PF-BP eq. (8)). Default 0.1 m.
    planar : bool
        3-D position at constant height: the velocity (and acceleration) blocks have only the
        x and y components, e.g. the state ``[x, y, z, ẋ, ẏ]`` of the mobile agents in
        Zhang, Teague and Meyer's Fisher-information control case study. Requires ``dim = 3``
        and a CV or CA model. Default False.

    Examples
    --------
    >>> m = RangeModel("constant_acceleration", 3)
    >>> m.state_dim, m.matrices()[0].shape
    (9, (9, 9))
    >>> RangeModel("constant_velocity", 3, dt_s=1.0, planar=True).state_dim
    5
    """

    motion: str = "constant_acceleration"
    dim: int = 3
    dt_s: float = 0.1
    accel_std: float = 0.15
    sigma_r: float = 0.1
    planar: bool = False

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
        planar = v.boolean("planar", self.planar)
        if planar and (dim != 3 or self.motion == "static"):
            raise ValidationError(
                "planar", self.planar, "needs dim = 3 and a constant_velocity/acceleration model"
            )
        object.__setattr__(self, "planar", planar)

    @property
    def order(self) -> int:
        """1 (static), 2 (CV) or 3 (CA): number of blocks in the state."""
        return _ORDER[self.motion]

    @property
    def motion_dim(self) -> int:
        """Components of the velocity/acceleration blocks: ``dim``, or 2 when ``planar``."""
        return 2 if self.planar else self.dim

    @property
    def block_sizes(self) -> tuple[int, ...]:
        """Sizes of the position, velocity, acceleration blocks the model has."""
        return (self.dim, self.motion_dim, self.motion_dim)[: self.order]

    @property
    def state_dim(self) -> int:
        """N_D = Σ block sizes (``order · dim`` unless ``planar``)."""
        return sum(self.block_sizes)

    def _kept(self) -> np.ndarray:
        """Indices of the state within the full ``order · dim`` state (``planar``: no z rates)."""
        idx = np.arange(self.order * self.dim).reshape(self.order, self.dim)
        return np.concatenate([idx[0], idx[1:, : self.motion_dim].ravel()])

    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """``(F, Q)`` of PF-BP eqs. (2), (48); static: ``(I, 0)``; ``planar``: the rows and
        columns of the 3-D model without the vertical rates, ``Q = σ_a² G Gᵀ``."""
        if self.motion == "static":
            return np.eye(self.dim), np.zeros((self.dim, self.dim))
        F, Q = transition_matrices(self.motion, self.dim, self.dt_s, self.accel_std)
        if not self.planar:
            return F, Q
        keep = self._kept()
        G = self.noise_gain()
        return F[np.ix_(keep, keep)], (self.accel_std**2) * (G @ G.T)

    def noise_gain(self) -> np.ndarray:
        """``G`` of PF-BP eq. (3), ``[N_D, motion_dim]`` (static: zeros)."""
        if self.motion == "static":
            return np.zeros((self.dim, self.dim))
        G = noise_gain_matrix(self.motion, self.dim, self.dt_s)
        if not self.planar:
            return G
        return G[self._kept()][:, : self.motion_dim]

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
        return np.diag(np.repeat(diag, self.block_sizes))

    def predict_particles(self, X: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Draw ``x^{(k)} = F x^{(k−1)} + G u`` for particles ``X [..., N_D]`` (PF-BP eq. (1))."""
        F, _ = self.matrices()
        out = X @ F.T
        if self.motion != "static" and self.accel_std > 0:
            u = rng.normal(0.0, self.accel_std, size=(*X.shape[:-1], self.motion_dim))
            out += u @ self.noise_gain().T
        return out

    def predict_cov(self, P: np.ndarray) -> np.ndarray:
        """``F P Fᵀ + Q`` for ``P [..., N_D, N_D]`` (PF-BP eq. (29))."""
        F, Q = self.matrices()
        return F @ P @ F.T + Q


@dataclass(frozen=True, eq=False)
class RangeMeasurements:
    """Range measurements of a network over time: what the trackers see (no truth).

    Time ``k = 1 … K`` is stored at index ``k − 1``. Problem sizes come from ``z``: ``K``,
    ``n_agents`` and ``n_agents + n_anchors``.

    Parameters
    ----------
    model : RangeModel
        State model and range noise σ the trackers assume.
    anchors : [n_anchors, dim] or [K, n_anchors, dim] float64
        Known anchor positions [m]: fixed, or per time step (anchors that move, e.g. under
        :mod:`phyloc.control`); :meth:`anchors_at` gives the positions at one step.
    z : [K, n_agents, n_agents + n_anchors] float64
        ``z[k−1, i, j]``: range agent ``i`` measured to node ``j`` at time ``k`` [m]
        (PF-BP eq. (8)); NaN where absent (and on the diagonal). Nodes: agents first, anchors last.

    Examples
    --------
    >>> z = np.full((2, 1, 2), np.nan)
    >>> z[:, 0, 1] = 5.0
    >>> meas = RangeMeasurements(RangeModel("static", 2), np.zeros((1, 2)), z)
    >>> meas.n_steps, meas.n_agents, meas.n_anchors
    (2, 1, 1)
    >>> moving = RangeMeasurements(RangeModel("static", 2), [[[0, 0]], [[1, 0]]], z)
    >>> moving.anchors_at(1)
    array([[1., 0.]])
    """

    model: RangeModel
    anchors: np.ndarray
    z: np.ndarray

    def __post_init__(self):
        if not isinstance(self.model, RangeModel):
            raise ValidationError("model", type(self.model).__name__, "must be a RangeModel")
        dim = self.model.dim
        shape = np.shape(self.anchors)
        if len(shape) == 3:
            anchors = v.finite_array("anchors", self.anchors, ndim=3)
            if shape[2] != dim:
                raise ValidationError(
                    "anchors", f"array of shape {shape}", f"must be (K, n_anchors, {dim})"
                )
        else:
            anchors = v.finite_array("anchors", np.reshape(self.anchors, (-1, dim)), ndim=2)
            if shape not in (anchors.shape, (0,)):
                raise ValidationError(
                    "anchors", f"array of shape {shape}", f"must be (n_anchors, {dim})"
                )
        n_anchors = anchors.shape[-2]
        try:
            z = np.asarray(self.z, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValidationError("z", "<array>", "must convert to float64") from None
        if z.ndim != 3 or z.shape[2] != z.shape[1] + n_anchors or z.shape[1] < 1:
            raise ValidationError(
                "z",
                f"array of shape {z.shape}",
                f"must be (K, n_agents, n_agents + n_anchors) with n_anchors = {n_anchors}",
            )
        if anchors.ndim == 3 and anchors.shape[0] != z.shape[0]:
            raise ValidationError(
                "anchors",
                f"array of shape {anchors.shape}",
                f"per-step anchors need one row per time step (K = {z.shape[0]})",
            )
        if np.any(np.isinf(z)):
            raise ValidationError("z", "inf", "ranges must be finite or NaN (not measured)")
        object.__setattr__(self, "anchors", anchors)
        object.__setattr__(self, "z", z)

    def anchors_at(self, k: int) -> np.ndarray:
        """Anchor positions ``[n_anchors, dim]`` at time index ``k`` (0-based, ``z[k]``)."""
        return self.anchors[k] if self.anchors.ndim == 3 else self.anchors

    def anchor_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounding box ``(lo, hi)`` of every anchor position (all steps)."""
        flat = self.anchors.reshape(-1, self.model.dim)
        return flat.min(axis=0), flat.max(axis=0)

    @property
    def n_agents(self) -> int:
        """Number of agents (rows of ``z``)."""
        return self.z.shape[1]

    @property
    def n_anchors(self) -> int:
        """Number of anchors."""
        return self.anchors.shape[-2]

    @property
    def n_steps(self) -> int:
        """Number of time steps K."""
        return self.z.shape[0]


@dataclass(frozen=True, eq=False)
class GaussianPrior:
    """Independent Gaussian priors of the agent states at time 0, ``N(mean_i, cov_i)``.

    Parameters
    ----------
    mean : [n_agents, N_D] float64
        ``x̄_i^{(0)}``.
    cov : [n_agents, N_D, N_D] float64
        ``P_i^{(0)}`` (symmetric PSD; a singular block is jittered where it is factorized).
    label : str
        Describes the prior in results (e.g. ``"PF-BP eq. (31)"``).
    """

    mean: np.ndarray
    cov: np.ndarray
    label: str = ""

    def __post_init__(self):
        mean = v.finite_array("prior.mean", self.mean, ndim=2)
        cov = v.finite_array("prior.cov", self.cov, ndim=3)
        if cov.shape != (*mean.shape, mean.shape[1]):
            shape = (*mean.shape, mean.shape[1])
            raise ValidationError("prior.cov", f"array of shape {cov.shape}", f"must be {shape}")
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "cov", cov)


def paper_prior(
    measurements: RangeMeasurements,
    rng: np.random.Generator,
    *,
    sigma_p: float = 20.0,
    region_m=None,
    accel_init_factor: float = 10.0,
) -> GaussianPrior:
    """Gaussian prior of ``x^{(0)}`` of PF-BP eq. (31); it uses no truth.

    ``P_i^{(0)} = diag(σ_p² I, ΔT² σ_ainit² I, σ_ainit² I)`` with ``σ_ainit = 10 σ_a``; the
    velocity and acceleration means are drawn from ``N(0, P^{(0)})`` blocks, the position mean
    uniformly in the region (default: the bounding box of the anchors). Static model: only the
    position block.

    Parameters
    ----------
    measurements : RangeMeasurements
        Gives the model, the number of agents and the anchors.
    rng : numpy.random.Generator
        Draws the positions ``[n_agents, dim]`` then the other blocks.
    sigma_p : float
        σ_p [m] (PF-BP §VI: 20 m).
    region_m : float or [dim] float, optional
        Region ``[0, region_m]`` of the position means (default: the anchors' bounding box).
    accel_init_factor : float
        σ_ainit / σ_a (10).

    Returns
    -------
    GaussianPrior
        ``mean [n_agents, N_D]``, ``cov [n_agents, N_D, N_D]``.

    Examples
    --------
    >>> z = np.full((1, 2, 3), np.nan)
    >>> meas = RangeMeasurements(RangeModel(dim=2), np.zeros((1, 2)), z)
    >>> paper_prior(meas, np.random.default_rng(0)).cov.shape
    (2, 6, 6)
    """
    if not isinstance(measurements, RangeMeasurements):
        raise ValidationError(
            "measurements", type(measurements).__name__, "must be a RangeMeasurements"
        )
    m = measurements.model
    sp = v.positive("sigma_p", sigma_p)
    sai = v.positive("accel_init_factor", accel_init_factor, allow_zero=True) * m.accel_std
    var = [sp**2, (m.dt_s * sai) ** 2, sai**2][: m.order]
    diag = np.repeat(var, m.block_sizes)
    n = measurements.n_agents
    if region_m is None:
        if measurements.n_anchors == 0:
            raise ValidationError("region_m", None, "required when there are no anchors")
        lo, hi = measurements.anchor_bounds()
    else:
        lo, hi = np.zeros(m.dim), np.asarray(region_m, dtype=float) * np.ones(m.dim)
    mean = np.zeros((n, m.state_dim))
    mean[:, : m.dim] = rng.uniform(lo, hi, size=(n, m.dim))
    if m.order > 1:
        mean[:, m.dim :] = rng.normal(size=(n, m.state_dim - m.dim)) * np.sqrt(diag[m.dim :])
    cov = np.repeat(np.diag(diag)[None], n, axis=0)
    return GaussianPrior(mean, cov, label="PF-BP eq. (31)")


def agent_measurements(z_k: np.ndarray, agent: int, factors: str = "distributed"):
    """Measurements entering the belief of one agent at one time step.

    Parameters
    ----------
    z_k : [n_agents, n_nodes] float64
        One time step of :attr:`RangeMeasurements.z`.
    agent : int
    factors : {"distributed", "centralized"}
        Distributed: ``z[agent, j]`` only (PF-BP eq. (17)); centralized: also ``z[j, agent]``
        of every agent ``j`` (PF-BP eq. (18)).

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


def check_inputs(measurements, prior):
    """Validate a tracker's measurements and prior; returns float64 copies of the prior."""
    if not isinstance(measurements, RangeMeasurements):
        raise ValidationError(
            "measurements", type(measurements).__name__, "must be a RangeMeasurements"
        )
    return check_prior(prior, measurements.model, measurements.n_agents)


def check_prior(prior, model, n_agents=None):
    """Validate a prior for ``model`` (and ``n_agents`` when given); returns float64 copies."""
    if not isinstance(prior, GaussianPrior):
        raise ValidationError("prior", type(prior).__name__, "must be a GaussianPrior")
    if not isinstance(model, RangeModel):
        raise ValidationError("model", type(model).__name__, "must be a RangeModel")
    n = prior.mean.shape[0] if n_agents is None else n_agents
    nd = model.state_dim
    if prior.mean.shape != (n, nd):
        raise ValidationError(
            "prior.mean", f"array of shape {prior.mean.shape}", f"must be ({n}, {nd})"
        )
    return prior.mean.copy(), prior.cov.copy()


def check_run_args(options, options_cls, rng, *, rng_required: bool = True):
    """Validate the common arguments of the range-level trackers; returns the options."""
    opt = options_cls() if options is None else options
    if not isinstance(opt, options_cls):
        raise ValidationError("options", type(opt).__name__, f"must be {options_cls.__name__}")
    if (rng_required or rng is not None) and not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", type(rng).__name__, "must be a numpy.random.Generator")
    return opt

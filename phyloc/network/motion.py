"""Motion models: static, random walk, constant velocity (CV) and constant acceleration (CA).

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

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."

Y. Bar-Shalom, X. R. Li and T. Kirubarajan, *Estimation with Applications to Tracking and
Navigation*, Wiley, 2001 (direct discrete-time kinematic models, §6.3).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc._validate import check_keys
from phyloc.errors import ValidationError

#: Motion models understood by :class:`MotionSpec` and :func:`simulate_motion`.
MOTION_MODELS = ("static", "random_walk", "constant_velocity", "constant_acceleration")
#: Models with a linear-Gaussian state transition (:func:`transition_matrices`).
KINEMATIC_MODELS = ("constant_velocity", "constant_acceleration")
#: How the initial velocity of CV/CA agents is drawn.
INITIAL_VELOCITIES = ("gaussian", "toward_center", "zero")

_ORDER = {"constant_velocity": 2, "constant_acceleration": 3}


@dataclass(frozen=True)
class MotionSpec:
    """How agents move over the snapshots of a network (anchors never move).

    Parameters
    ----------
    model : {"static", "random_walk", "constant_velocity", "constant_acceleration"}
        ``"static"``: positions repeated at every snapshot. ``"random_walk"``:
        ``p_k = p_{k-1} + w_k``, ``w_k ~ N(0, step_std_m² I)``. ``"constant_velocity"`` and
        ``"constant_acceleration"``: PF-BP eqs. (1)–(3) (see the module docstring). Default
        ``"static"``.
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

    Examples
    --------
    >>> MotionSpec.from_dict({"model": "constant_acceleration", "n_snapshots": 50}).dt_s
    0.1
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

    @property
    def tracks_velocity(self) -> bool:
        """Whether trajectories carry velocities (CV and CA)."""
        return self.model in KINEMATIC_MODELS

    @property
    def tracks_acceleration(self) -> bool:
        """Whether trajectories carry accelerations (CA)."""
        return self.model == "constant_acceleration"

    @classmethod
    def from_dict(cls, d: dict, *, section: str = "network.motion") -> MotionSpec:
        """Build from a recipe section; unknown keys are errors naming the closest valid key."""
        if not isinstance(d, dict):
            raise ValidationError(section, d, "must be a table (dict) of motion settings")
        check_keys(d, [f.name for f in dataclasses.fields(cls)], section)
        return cls(**d)

    def to_dict(self) -> dict:
        """The init fields as a plain dict (recipe form)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


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
        ``[K−1, n, dim]`` block (random walk: the steps).
    center : [dim] float64, optional
        Centre of the region, required by ``initial_velocity="toward_center"``.

    Returns
    -------
    positions : [K, n, dim] float64
        ``K = spec.n_snapshots``.
    velocities : [K, n, dim] float64 or None
        CV and CA only [m/s].
    accelerations : [K, n, dim] float64 or None
        CA only [m/s²].
    """
    p0 = v.finite_array("initial_positions", initial_positions, ndim=2)
    n, dim = p0.shape
    K = spec.n_snapshots
    if spec.model == "static":
        return np.repeat(p0[None], K, axis=0), None, None
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

"""The state-space model the range trackers assume: agent motion and Gaussian range noise.

:class:`RangeModel` holds one idea, the model of PF-BP §II. The state of agent ``i`` at time
``k`` is ``x_i = [p_i; v_i; a_i]`` (constant acceleration, CA, PF-BP eqs. (1)–(3)),
``[p_i; v_i]`` (constant velocity, CV) or ``p_i`` (static), each block a ``dim``-vector (2-D or
3-D). The transition is ``x_i^{(k)} = F x_i^{(k−1)} + G u`` with ``F``, ``Q = G σ_a² Gᵀ`` from
:func:`phyloc.network.motion.transition_matrices` (static: ``F = I``, ``Q = 0``). A range
measurement (PF-BP eq. (8)) is ``z_ij = ‖p_j − p_i‖ + n_ij``, ``n_ij ~ N(0, σ²)`` iid.

The measurements themselves are in :mod:`~phyloc.localization.tracking.measurements`, the
priors in :mod:`~phyloc.localization.tracking.priors`.

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
        columns of the 3-D model without the vertical rates, ``Q = σ_a² G Gᵀ``.

        Built once per model and returned as fresh copies (a tracking or control loop asks for
        them every step; building them costs ~1 ms, copying them ~1 µs)."""
        F, Q = self._once("_matrices", self._build_matrices)
        return F.copy(), Q.copy()

    def _once(self, key, build):
        """``build()``, computed on the first call for this model and kept (the model is frozen,
        so its matrices never change)."""
        value = self.__dict__.get(key)
        if value is None:
            value = build()
            object.__setattr__(self, key, value)
        return value

    def _build_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        if self.motion == "static":
            return np.eye(self.dim), np.zeros((self.dim, self.dim))
        F, Q = transition_matrices(self.motion, self.dim, self.dt_s, self.accel_std)
        if not self.planar:
            return F, Q
        keep = self._kept()
        G = self.noise_gain()
        return F[np.ix_(keep, keep)], (self.accel_std**2) * (G @ G.T)

    def noise_gain(self) -> np.ndarray:
        """``G`` of PF-BP eq. (3), ``[N_D, motion_dim]`` (static: zeros); built once per model,
        returned as a fresh copy."""
        return self._once("_noise_gain", self._build_noise_gain).copy()

    def _build_noise_gain(self) -> np.ndarray:
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

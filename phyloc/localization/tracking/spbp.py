"""Sigma-point belief propagation (SP-BP), the Gaussian baseline of the PF-BP paper.

After Meyer, Hlinka, Hlawatsch, "Sigma point belief propagation" (SP-BP). Every agent ``i``
holds a Gaussian belief ``N(x̂_i, P_i)``. Per time step:

1. predict by the linear motion model (PF-BP eqs. (1), (29)): ``x̂_i ← F x̂_i``,
   ``P_i ← F P_i Fᵀ + Q``;
2. for ``u = 1 … U`` message-passing iterations, all beliefs in parallel (the schedule of
   :func:`~phyloc.localization.tracking.pfbp.run_pfbp`, extrinsic information approximated by
   beliefs): stack the agent's *predicted* state with its neighbours' beliefs of iteration
   ``u − 1`` into β with mean ``[x̂_i; x̂_j …]`` and block-diagonal covariance ``P̃_i`` (as
   PF-BP eq. (28)); the message product and marginalization are one unscented update of β by
   the agent's range measurements, of which the agent's block is kept:

   .. math::

       x̂_i ← [β̄ + P_{βz} P_{zz}^{-1} (z − \\bar z)]_i, \\qquad
       P_i ← [P̃_i − P_{βz} P_{zz}^{-1} P_{βz}ᵀ]_{ii};

3. the estimate is ``x̂_i``.

Steps 1 and 3 are the family's loop (:func:`~phyloc.localization.tracking.loop.track`); this
module supplies :class:`SPBPUpdate`, step 2.

The sigma points (``sigma_points``) are by default those of the PF-BP UKF covariance step
(:func:`~phyloc.localization.tracking._flow.ukf_covariance_update`, PF-BP eq. (30)), the
cubature rule: ``β̄ ± √n L_j`` with ``L Lᵀ = P̃_i`` (Cholesky), weights ``1/(2n)``, no centre
point (Julier's κ = 0), so the covariance update is the Schur complement of a PSD matrix and
stays PSD. ``"scaled"`` is the scaled unscented transform of the UKF reference the PF-BP paper
cites for its UKF steps (Wan and van der Merwe): ``2n + 1`` points ``β̄``,
``β̄ ± √(n + λ) L_j`` with ``λ = α²(n + κ) − n``, mean weights ``λ/(n + λ)`` (centre) and
``1/(2(n + λ))``, the centre's covariance weight raised by ``1 − α² + β`` (defaults
``α = 10⁻³``, ``β = 2``, ``κ = 0``). The two differ by far when the prior is wide: with the
20 m prior of PF-BP §VI and a 45-D stacked state the cubature points lie ``√45 σ_p ≈ 134 m``
from the mean, the scaled ones ``α √45 σ_p ≈ 0.13 m``.
Measurements follow ``factors`` as in PF-BP (distributed: PF-BP eq. (17);
centralized: PF-BP eq. (18)). An agent without measurements keeps its prediction. Optional
regularization adds ``Σ_r`` (PF-BP eq. (32)) to every updated covariance, as PF-BP §VI does for
SP-BP (PF-BP eq. (33)). SP-BP is deterministic; ``rng`` is accepted only for the common call
shape.

References
----------
PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."
SP-BP: F. Meyer, O. Hlinka and F. Hlawatsch, "Sigma point belief propagation," IEEE Signal
Processing Letters 21(2), pp. 145–149, 2014.
UKF: E. Wan and R. van der Merwe, "The unscented Kalman filter for nonlinear estimation," Proc.
IEEE Adaptive Systems for Signal Processing, Communications, and Control Symposium, 2000.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag

from phyloc import _validate as v
from phyloc._validate import from_table
from phyloc.errors import ValidationError
from phyloc.localization.results import Result
from phyloc.localization.tracking import _flow
from phyloc.localization.tracking.loop import (
    Belief,
    Tracker,
    Update,
    check_inputs,
    check_run_args,
    message_floats,
    message_passing,
    track,
)
from phyloc.localization.tracking.measurements import (
    FACTORS,
    RangeMeasurements,
    agent_measurements,
)
from phyloc.localization.tracking.priors import GaussianPrior

#: The sigma-point rules of :class:`SPBPOptions`.
SIGMA_POINTS = ("cubature", "scaled")


@dataclass(frozen=True)
class SPBPOptions:
    """Options of SP-BP (defaults: the PF-BP §VI schedule).

    Parameters
    ----------
    n_iterations : int
        Message-passing iterations U (2).
    factors : {"distributed", "centralized"}
        PF-BP §V-A.
    regularize : bool
        Add the kernel ``Σ_r`` of PF-BP eq. (32) to every updated covariance (PF-BP eq. (33))
        (off).
    reg_std_vel, reg_std_acc : float
        σ_r,vel [m/s], σ_r,acc [m/s²] of PF-BP eq. (32) (0.15).
    sigma_points : {"cubature", "scaled"}
        The cubature rule of PF-BP eq. (30) as phyloc computes it (default), or the scaled
        unscented transform of the UKF reference (module docstring).
    ut_alpha, ut_beta, ut_kappa : float
        α > 0, β ≥ 0, κ ≥ 0 of ``"scaled"`` (10⁻³, 2, 0: the reference's usual values).
    """

    n_iterations: int = 2
    factors: str = "distributed"
    regularize: bool = False
    reg_std_vel: float = 0.15
    reg_std_acc: float = 0.15
    sigma_points: str = "cubature"
    ut_alpha: float = 1e-3
    ut_beta: float = 2.0
    ut_kappa: float = 0.0

    def __post_init__(self):
        object.__setattr__(
            self, "n_iterations", v.integer("n_iterations", self.n_iterations, minimum=1)
        )
        if self.factors not in FACTORS:
            raise ValidationError("factors", self.factors, f"must be one of {FACTORS}")
        if self.sigma_points not in SIGMA_POINTS:
            raise ValidationError(
                "sigma_points", self.sigma_points, f"must be one of {SIGMA_POINTS}"
            )
        for name in ("reg_std_vel", "reg_std_acc", "ut_beta", "ut_kappa"):
            object.__setattr__(self, name, v.positive(name, getattr(self, name), allow_zero=True))
        object.__setattr__(self, "ut_alpha", v.positive("ut_alpha", self.ut_alpha))

    @property
    def unscented(self) -> tuple[float, float, float] | None:
        """``(α, β, κ)`` of the scaled unscented transform, or None for the cubature rule."""
        if self.sigma_points == "cubature":
            return None
        return self.ut_alpha, self.ut_beta, self.ut_kappa

    @classmethod
    def from_dict(cls, d: dict, section: str = "localization") -> SPBPOptions:
        """Build from a recipe table; unknown keys are errors naming the closest valid key."""
        return from_table(cls, d, section)


def unscented_range_update(mean, P, off_a, off_b, anchor_pos, z, r_var, dim, n_out, scaled=None):
    """Unscented update of a stacked Gaussian by range measurements; the leading block.

    Parameters
    ----------
    mean : [n] float64
        Stacked mean β̄.
    P : [n, n] float64
        Its covariance ``P̃`` (PSD; jittered when singular).
    off_a, off_b, anchor_pos : as in :mod:`phyloc.localization.tracking._flow`
        Measurement ``q`` is ``‖β[off_a:off_a+dim] − β[off_b:off_b+dim]‖`` (anchor
        ``anchor_pos[q]`` when ``off_b[q] < 0``).
    z : [L] float64
        Ranges [m].
    r_var : [L] float64
        Noise variances σ² [m²].
    dim : int
    n_out : int
        Size of the leading block returned.
    scaled : (α, β, κ), optional
        The scaled unscented transform (module docstring) instead of the cubature rule.

    Returns
    -------
    mean_out : [n_out] float64
    cov_out : [n_out, n_out] float64
        With the cubature rule equal to
        :func:`~phyloc.localization.tracking._flow.ukf_covariance_update` (same sigma points).
    """
    if scaled is not None:
        return _scaled_range_update(
            mean, P, off_a, off_b, anchor_pos, z, r_var, dim, n_out, *scaled
        )
    n = mean.size
    L = _flow.robust_cholesky(P) * np.sqrt(n)
    pts = np.concatenate([mean + L.T, mean - L.T])  # [2n, n]
    Z = _flow.sigma_point_ranges(pts, off_a, off_b, anchor_pos, dim)
    z_bar = Z.mean(axis=0)
    dz = Z - z_bar
    dx = pts[:, :n_out] - mean[:n_out]
    w = 1.0 / (2 * n)
    Pzz = w * dz.T @ dz + np.diag(r_var)
    Pxz = w * dx.T @ dz
    G = np.linalg.solve(Pzz, Pxz.T).T  # gain, Pzz symmetric
    m_out = mean[:n_out] + G @ (z - z_bar)
    c_out = P[:n_out, :n_out] - G @ Pxz.T
    return m_out, 0.5 * (c_out + c_out.T)


def _scaled_range_update(mean, P, off_a, off_b, anchor_pos, z, r_var, dim, n_out, a, b, k):
    """:func:`unscented_range_update` with the scaled unscented transform (α, β, κ) = (a, b, k)
    (Wan and van der Merwe): a centre point and ``±√(n + λ) L_j``."""
    n = mean.size
    lam = a * a * (n + k) - n
    L = _flow.robust_cholesky(P) * np.sqrt(n + lam)
    pts = np.concatenate([mean[None], mean + L.T, mean - L.T])  # [2n + 1, n]
    wm = np.full(2 * n + 1, 0.5 / (n + lam))
    wm[0] = lam / (n + lam)
    wc = wm.copy()
    wc[0] += 1.0 - a * a + b
    Z = _flow.sigma_point_ranges(pts, off_a, off_b, anchor_pos, dim)
    D = Z - Z[0]  # about the centre first: the weights reach ±10⁶ and would cancel the ranges
    d_bar = wm @ D
    z_bar = Z[0] + d_bar
    dz = D - d_bar
    dx = pts[:, :n_out] - mean[:n_out]
    Pzz = (wc[:, None] * dz).T @ dz + np.diag(r_var)
    Pxz = (wc[:, None] * dx).T @ dz
    G = np.linalg.solve(Pzz, Pxz.T).T
    m_out = mean[:n_out] + G @ (z - z_bar)
    c_out = P[:n_out, :n_out] - G @ Pxz.T
    return m_out, 0.5 * (c_out + c_out.T)


def run_spbp(
    measurements: RangeMeasurements,
    prior: GaussianPrior,
    rng: np.random.Generator | None = None,
    options: SPBPOptions | None = None,
) -> Result:
    """Track all agents with sigma-point BP (SP-BP); registered as ``spbp``.

    Parameters
    ----------
    measurements : RangeMeasurements
        Ranges, anchors, model (no truth).
    prior : GaussianPrior
        ``x̂_i^{(0)}``, ``P_i^{(0)}`` (e.g. :func:`~phyloc.localization.tracking.paper_prior`,
        PF-BP eq. (31)).
    rng : numpy.random.Generator, optional
        Unused (SP-BP is deterministic); accepted for the common call shape.
    options : SPBPOptions, optional

    Returns
    -------
    Result
        ``estimates [K, n_agents, N_D]``, ``covariances [K, n_agents, N_D, N_D]`` (Gaussian
        beliefs), no particles; ``timing.agent_s = step_s / n_agents``,
        ``agent_iterations = K · U · n_agents``; ``label="spbp"``;
        ``diagnostics["floats_per_link_iteration"]``: a Gaussian belief, mean and covariance
        (:func:`~phyloc.localization.tracking.loop.message_floats`).

    Examples
    --------
    >>> from phyloc.localization.tracking import GaussianPrior, RangeMeasurements, RangeModel
    >>> z = np.full((2, 1, 4), np.nan)
    >>> z[:, 0, 1:] = [5.0, 5.0, 5.0]
    >>> anchors = np.array([[0.0, 0.0], [8.0, 0.0], [0.0, 8.0]])
    >>> meas = RangeMeasurements(RangeModel("static", 2), anchors, z)
    >>> prior = GaussianPrior(np.array([[3.0, 3.0]]), np.eye(2)[None] * 4.0)
    >>> run_spbp(meas, prior).estimates.shape
    (2, 1, 2)
    """
    opt = check_run_args(options, SPBPOptions, rng, rng_required=False)
    check_inputs(measurements, prior)
    return track(measurements, prior, rng, SPBPUpdate(measurements.model, opt))


class SPBPUpdate(Update):
    """One time step of SP-BP for :func:`~phyloc.localization.tracking.loop.track`: a Gaussian
    belief per agent, ``U`` iterations of unscented message products (deterministic).

    Parameters
    ----------
    model : RangeModel
    options : SPBPOptions
    """

    label = "spbp"

    def __init__(self, model, options: SPBPOptions):
        super().__init__(model, options)
        self._var = model.sigma_r**2
        self._Sr = None
        if options.regularize:  # PF-BP eq. (32)
            self._Sr = model.regularization_cov(options.reg_std_vel, options.reg_std_acc)

    def initial(self, mean0, cov0, rng) -> Belief:
        """The prior itself."""
        return Belief(mean=mean0, cov=cov0)

    def update(self, pred, z_k, anchors_k, rng) -> Belief:
        """All agents in parallel from the predicted ``pred.mean`` (PF-BP eq. (1)) and
        ``pred.cov`` (PF-BP eq. (29))."""
        x_pred, P_pred = pred.mean, pred.cov

        def agent(i, x_bel, P_bel, _shared):
            x, P = self._agent_update(i, z_k, anchors_k, x_pred, P_pred, x_bel, P_bel)
            return x, (P if self._Sr is None else P + self._Sr)  # PF-BP eq. (33)

        x_bel, P_bel = message_passing(self.options.n_iterations, (x_pred, P_pred), agent)
        return Belief(mean=x_bel, cov=P_bel)

    def estimate(self, belief):
        """The Gaussian beliefs (copies)."""
        return belief.mean.copy(), belief.cov.copy()

    def floats_per_link_iteration(self) -> float:
        """A Gaussian belief: mean and covariance."""
        return message_floats("gaussian", self.model.state_dim)

    def _agent_update(self, i, z_k, anchors_k, x_pred, P_pred, x_bel, P_bel):
        """One belief update of agent ``i``: unscented product of its prediction and the
        messages."""
        dim, nd, n_ag = self.model.dim, self.model.state_dim, x_pred.shape[0]
        rx, tx, zz, partners = agent_measurements(z_k, i, self.options.factors)
        if zz.size == 0:
            return x_pred[i], P_pred[i]
        local = np.full(n_ag, -1, dtype=np.int64)
        local[i] = 0
        local[partners] = np.arange(1, partners.size + 1)
        off_a, off_b, apos, zz = _flow.flow_links(rx, tx, zz, local, n_ag, anchors_k, dim, nd)
        beta = np.concatenate([x_pred[i]] + [x_bel[j] for j in partners])  # β̄
        P_t = block_diag(P_pred[i], *[P_bel[j] for j in partners])  # as PF-BP eq. (28)
        r_var = np.full(zz.size, self._var)
        with self.clock("covariance"):
            return unscented_range_update(
                beta, P_t, off_a, off_b, apos, zz, r_var, dim, nd, self.options.unscented
            )


class SPBPTracker(Tracker):
    """SP-BP one time step at a time (:class:`~phyloc.localization.tracking.loop.Tracker` with
    :class:`SPBPUpdate`), for a closed loop whose next measurements depend on the current
    beliefs (e.g. anchors steered by :mod:`phyloc.control`).

    Parameters
    ----------
    model : RangeModel
    prior : GaussianPrior
        Beliefs at time 0.
    rng : numpy.random.Generator, optional
        Unused (SP-BP is deterministic).
    options : SPBPOptions, optional

    Attributes
    ----------
    mean, cov : [n_agents, N_D], [n_agents, N_D, N_D]
        The current Gaussian beliefs.

    Examples
    --------
    >>> from phyloc.localization.tracking import GaussianPrior, RangeModel
    >>> t = SPBPTracker(RangeModel("static", 2), GaussianPrior(np.ones((1, 2)), np.eye(2)[None]))
    >>> z = np.array([[np.nan, 1.0, 1.0]])  # one agent, two anchors
    >>> mean, cov = t.step(z, np.array([[0.0, 1.0], [1.0, 0.0]]))
    >>> bool(np.trace(cov[0]) < 2.0)
    True
    """

    def __init__(self, model, prior: GaussianPrior, rng=None, options: SPBPOptions | None = None):
        opt = check_run_args(options, SPBPOptions, rng, rng_required=False)
        super().__init__(SPBPUpdate(model, opt), prior, rng)

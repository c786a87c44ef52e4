"""Fisher information of one-path ranging and of a node's position (DiPNet §III-A).

The equivalent-likelihood (EL) idea: a neighbour ``v`` known only through its belief mean and
covariance is treated as an anchor whose ranging uncertainty is inflated by its position
uncertainty projected on the link (DiPNet eqs. (13)–(18)):

- ranging information intensity (RII) ``ν = 1/CRB`` of a one-path OFDM link (DiPNet eq. (24)):
  :func:`ranging_information`;
- projected neighbour variance ``σ²_{v→uv} = e_uvᵀ I_v⁻¹ e_uv`` (DiPNet eq. (15)), with the belief
  covariance standing in for ``I_v⁻¹``: :func:`projected_variance`;
- equivalent RII ``ν̃ = ν/(1 + νσ²_{v→uv})``, i.e. ``1/ν̃ = 1/ν + σ²_{v→uv}`` (DiPNet eqs. (14),
  (18)): :func:`equivalent_ranging_information`;
- the equivalent noise variance (ENV) of DiPNet's likelihood (DiPNet eq. (26)), the noise variance
  that turns DiPNet eq. (24) into ``1/ν̃``: :func:`equivalent_noise_variance`;
- the EFIM/EBIM ``J_u = I_u⁽⁰⁾ + Σ_v ν_uv e_uv e_uvᵀ`` (DiPNet eqs. (13), (17)) and the position
  error bound ``tr J_u⁻¹``: :func:`efim`, :func:`position_crb`.

Coincident nodes (``p_u = p_v``) leave the direction ``e_uv`` undefined. phyloc then uses the
direction-averaged (isotropic) value, ``E[e eᵀ] = I/dim`` for a uniformly random unit ``e``:
``σ²_{v→uv} = tr(C_v)/dim`` and a link contribution ``ν I/dim`` (same trace ``ν`` as any
other link). Nothing here returns NaN for finite input.

Units: positions [m], ``ν`` [1/m²], variances of distances [m²], ``ω`` [rad/s], noise
variances and ``|α|²`` in the same (arbitrary) power unit.

These are the one implementation of each equation in phyloc: DiPNet eq. (24) itself is
:func:`phyloc.phy.bounds.ranging_crb` (which :func:`ranging_information` inverts), the
localizers' likelihoods call :func:`ranging_information`, :func:`projected_variance` and
:func:`equivalent_noise_variance`, and their covariance floor calls :func:`efim` and
:func:`position_crb`.

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import numpy as np

from phyloc import _validate as v
from phyloc.errors import ValidationError
from phyloc.phy.bounds import ranging_crb
from phyloc.phy.system import C0

COINCIDENT_TOL_M = 1e-12
"""Distances [m] at or below this count as coincident nodes (direction undefined)."""


def _nonneg(name: str, value, *, allow_inf: bool = False) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValidationError(name, value, "a real number or array is required") from None
    ok = ~np.isnan(a) & (a >= 0)
    if not allow_inf:
        ok &= np.isfinite(a)
    if not np.all(ok):
        bad = a[~ok].ravel()[0]
        allowed = "must be >= 0" + (" (inf allowed)" if allow_inf else " and finite")
        raise ValidationError(name, bad, allowed)
    return a


def spectral_moment2(symbols) -> np.ndarray:
    """``M = Σ_n |S_n|² n²`` over ``n = −(N−1)/2 … (N−1)/2`` (the sum in DiPNet eqs. (24), (26)).

    Parameters
    ----------
    symbols : [..., N] complex
        Pilot symbols ``S_n`` in subcarrier order, N odd.

    Returns
    -------
    M : [...] float64
        Dimensionless.

    Examples
    --------
    >>> float(spectral_moment2(np.ones(3)))  # n = -1, 0, 1
    2.0
    """
    S = np.asarray(symbols, dtype=np.complex128)
    if S.ndim < 1 or S.shape[-1] % 2 == 0 or not np.all(np.isfinite(S)):
        raise ValidationError(
            "symbols", f"array of shape {S.shape}", "must be finite [..., N] with N odd"
        )
    N = S.shape[-1]
    n = np.arange(N) - (N - 1) // 2
    return (np.abs(S) ** 2) @ (n.astype(np.float64) ** 2)


def ranging_information(snr, symbols_power_moment2, omega) -> np.ndarray:
    """Ranging information intensity ``ν = 1/CRB_d`` of a one-path OFDM link (DiPNet eq. (24)).

    The inverse of :func:`phyloc.phy.bounds.ranging_crb`, the one implementation of DiPNet
    eq. (24).

    .. math:: ν = \\frac{1}{\\mathrm{CRB}_{uv}}
              = \\frac{2 |α|^2 ω^2 \\sum_n |S_n|^2 n^2}{c_0^2 σ^2}
              = \\frac{2\\,\\mathrm{SNR}\\,ω^2 M}{c_0^2}

    Parameters
    ----------
    snr : array_like float64
        Per-sample SNR ``|α|²/σ²`` (linear, >= 0; 0 gives ν = 0).
    symbols_power_moment2 : array_like float64
        ``M = Σ_n |S_n|² n²`` (>= 0), see :func:`spectral_moment2`.
    omega : float
        ``ω = 2π f_sc`` [rad/s], > 0.

    Returns
    -------
    nu : broadcast shape, float64 [1/m²]

    Examples
    --------
    >>> nu = ranging_information(1.0, 2.0, C0)  # 2·1·c0²·2/c0²
    >>> float(nu)
    4.0
    """
    s = _nonneg("snr", snr)
    m = _nonneg("symbols_power_moment2", symbols_power_moment2)
    w = v.positive("omega", omega)
    with np.errstate(divide="ignore"):
        return 1.0 / ranging_crb(s, m, w)


def direction_vectors(position_u, positions_v) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors ``e_uv = (p_u − p_v)/‖p_u − p_v‖`` (DiPNet eq. (15)) and a coincidence mask.

    Parameters
    ----------
    position_u : [..., dim] float64
        [m].
    positions_v : [..., dim] float64
        [m], broadcast against ``position_u``.

    Returns
    -------
    e : [..., dim] float64
        Unit vectors; zero rows where the nodes coincide.
    coincident : [...] bool
        ``‖p_u − p_v‖ <= COINCIDENT_TOL_M``.
    """
    pu = v.finite_array("position_u", position_u)
    pv = v.finite_array("positions_v", positions_v)
    try:
        diff = pu - pv
    except ValueError:
        raise ValidationError(
            "positions_v", f"array of shape {pv.shape}", f"must broadcast with {pu.shape}"
        ) from None
    if diff.ndim < 1:
        raise ValidationError("position_u", "a scalar", "positions must be [..., dim]")
    norm = np.linalg.norm(diff, axis=-1)
    coincident = norm <= COINCIDENT_TOL_M
    e = np.divide(diff, norm[..., None], out=np.zeros_like(diff), where=~coincident[..., None])
    return e, coincident


def projected_variance(cov_v, e_uv) -> np.ndarray:
    """Neighbour variance projected on the link, ``σ²_{v→uv} = eᵀ C_v e`` (DiPNet eq. (15)).

    The belief covariance ``C_v`` stands for ``(I_v^{(k−1)})^{-1}``. ``e_uv`` is normalized
    here; a zero vector (coincident means, direction undefined) gives the isotropic value
    ``tr(C_v)/dim``.

    Parameters
    ----------
    cov_v : [..., dim, dim] float64
        Neighbour position covariance [m²] (symmetric positive semi-definite).
    e_uv : [..., dim] float64
        Link direction (any non-zero length, or zero), broadcast against ``cov_v``.

    Returns
    -------
    sigma2 : [...] float64
        [m²].

    Examples
    --------
    >>> float(projected_variance(np.diag([4.0, 1.0]), [3.0, 4.0]))  # (9·4 + 16·1)/25
    2.08
    """
    C = v.finite_array("cov_v", cov_v)
    e = v.finite_array("e_uv", e_uv)
    if C.ndim < 2 or C.shape[-1] != C.shape[-2] or e.ndim < 1 or e.shape[-1] != C.shape[-1]:
        raise ValidationError(
            "cov_v",
            f"array of shape {C.shape} with e_uv {e.shape}",
            "[..., dim, dim] and [..., dim]",
        )
    dim = C.shape[-1]
    norm = np.linalg.norm(e, axis=-1)
    zero = norm <= 0.0
    u = np.divide(e, norm[..., None], out=np.zeros_like(e), where=~zero[..., None])
    # a PSD form, but a singular C (a collapsed belief) orthogonal to e rounds to −1e-17 or
    # −5e-324; the variance is clamped at 0 so callers never see a negative
    proj = np.maximum(np.einsum("...i,...ij,...j->...", u, C, u), 0.0)
    iso = np.maximum(np.trace(C, axis1=-2, axis2=-1) / dim, 0.0)
    return np.where(zero, iso, proj)


def equivalent_ranging_information(nu, sigma2_proj) -> np.ndarray:
    """Equivalent RII ``ν̃ = ν/(1 + ν σ²_{v→uv})`` (DiPNet eq. (14)).

    Computed as ``1/(1/ν + σ²)`` (DiPNet eq. (18)), which also covers the limits: ``ν = 0`` or
    ``σ² = inf`` give 0, ``ν = inf`` gives ``1/σ²`` (``inf`` when ``σ² = 0``).

    Parameters
    ----------
    nu : array_like float64
        RII ``ν`` [1/m²], >= 0 (inf allowed).
    sigma2_proj : array_like float64
        ``σ²_{v→uv}`` [m²], >= 0 (inf allowed).

    Returns
    -------
    nu_eq : broadcast shape, float64 [1/m²]

    Examples
    --------
    >>> float(equivalent_ranging_information(4.0, 0.25))  # 4 / (1 + 1)
    2.0
    """
    n = _nonneg("nu", nu, allow_inf=True)
    s = _nonneg("sigma2_proj", sigma2_proj, allow_inf=True)
    with np.errstate(divide="ignore"):
        return 1.0 / (1.0 / n + s)


def equivalent_noise_variance(noise_var, sigma2_proj, alpha_abs2, moment2, omega) -> np.ndarray:
    """Equivalent noise variance (ENV) of DiPNet's equivalent likelihood (DiPNet eq. (26)).

    .. math:: \\tilde σ^2_{uv} = σ^2 + \\frac{2 ω^2 σ^2_{v→uv}}{c_0^2} |α|^2 \\sum_n |S_n|^2 n^2

    It is the noise variance for which DiPNet eq. (24) gives the equivalent ranging
    uncertainty of DiPNet eq. (18): ``c0² σ̃²/(2|α|²ω²M) = 1/ν + σ²_{v→uv}``.

    Parameters
    ----------
    noise_var : array_like float64
        σ² (> 0 unless ``alpha_abs2·moment2·sigma2_proj > 0``; >= 0), power unit.
    sigma2_proj : array_like float64
        ``σ²_{v→uv}`` [m²], >= 0.
    alpha_abs2 : array_like float64
        ``|α̂_{uv,0}|²`` (>= 0), same power unit as ``noise_var``.
    moment2 : array_like float64
        ``M = Σ_n |S_n|² n²`` (>= 0), see :func:`spectral_moment2`.
    omega : float
        ``ω = 2π f_sc`` [rad/s], > 0.

    Returns
    -------
    env : broadcast shape, float64 (power unit)
    """
    s2 = _nonneg("noise_var", noise_var)
    p = _nonneg("sigma2_proj", sigma2_proj)
    a = _nonneg("alpha_abs2", alpha_abs2)
    m = _nonneg("moment2", moment2)
    w = v.positive("omega", omega)
    return s2 + 2.0 * w**2 * p * a * m / C0**2


def efim(position_u, neighbor_positions, nu, prior_info=None, *, neighbor_cov=None) -> np.ndarray:
    """Equivalent Fisher (Bayesian) information matrix of one node's position.

    .. math:: J_u = I_u^{(0)} + \\sum_{v} ν_{uv}\\, e_{uv} e_{uv}^T

    With ``nu`` the RII ``ν`` of each link and no ``neighbor_cov`` this is DiPNet eq. (17)
    with the neighbours known (anchors); with ``neighbor_cov`` each ``ν`` is first replaced by
    the equivalent RII ``ν̃ = ν/(1 + ν σ²_{v→uv})`` (DiPNet eqs. (14), (15)), giving the EBIM
    of DiPNet eq. (13) (neighbour uncertainty projected on the link). ``e_uv`` is evaluated at
    the given positions (the means ``p̄`` of DiPNet eq. (15)). A coincident neighbour
    contributes ``ν I/dim`` (see the module docstring). ``J`` is exactly symmetric (its upper
    triangle mirrors the lower one).

    Parameters
    ----------
    position_u : [dim] float64
        [m].
    neighbor_positions : [K, dim] float64
        [m], K >= 0.
    nu : [K] float64
        Ranging information per link [1/m²], finite, >= 0.
    prior_info : [dim, dim] float64, optional
        ``I_u^{(0)}``, the prior information [1/m²] (symmetric PSD). Default 0.
    neighbor_cov : [K, dim, dim] float64, optional
        Neighbour position covariances [m²]; anchors have zero covariance.

    Returns
    -------
    J : [dim, dim] float64
        [1/m²], symmetric positive semi-definite.

    Examples
    --------
    >>> J = efim([0.0, 0.0], [[1.0, 0.0], [0.0, 2.0]], [1.0, 3.0])
    >>> J.tolist()
    [[1.0, 0.0], [0.0, 3.0]]
    """
    pu = v.finite_array("position_u", position_u, ndim=1)
    dim = pu.size
    if dim < 1:
        raise ValidationError("position_u", "empty array", "must be [dim]")
    P = v.finite_array("neighbor_positions", neighbor_positions)
    if P.size == 0:
        P = P.reshape(0, dim)
    if P.ndim != 2 or P.shape[1] != dim:
        raise ValidationError(
            "neighbor_positions", f"array of shape {P.shape}", f"must be [K, {dim}]"
        )
    K = P.shape[0]
    nu_a = _nonneg("nu", nu).reshape(-1) if np.size(nu) else np.zeros(0)
    if nu_a.shape != (K,):
        raise ValidationError("nu", f"array of shape {np.shape(nu)}", f"must be ({K},)")
    J = np.zeros((dim, dim))
    if prior_info is not None:
        I0 = v.finite_array("prior_info", prior_info, ndim=2)
        if I0.shape != (dim, dim):
            raise ValidationError("prior_info", f"array of shape {I0.shape}", f"({dim}, {dim})")
        J += 0.5 * (I0 + I0.T)
    if K == 0:
        return J
    e, coincident = direction_vectors(pu, P)
    if neighbor_cov is not None:
        C = v.finite_array("neighbor_cov", neighbor_cov)
        if C.shape != (K, dim, dim):
            raise ValidationError(
                "neighbor_cov", f"array of shape {C.shape}", f"must be ({K}, {dim}, {dim})"
            )
        nu_a = equivalent_ranging_information(nu_a, projected_variance(C, e))
    J += np.einsum("k,ki,kj->ij", nu_a, e, e)
    J += np.eye(dim) * (nu_a[coincident].sum() / dim)
    # rounding can leave J[i, j] != J[j, i]: mirror the lower triangle (what eigvalsh reads)
    return np.tril(J) + np.tril(J, -1).T


def position_crb(J) -> np.ndarray:
    """Position error bound ``tr(J⁻¹)`` [m²] (the mean squared position error bound).

    Computed from the eigenvalues of the symmetric ``J`` as ``Σ 1/λ_i``; a singular ``J`` (an
    eigenvalue <= ``1e-12·λ_max``, including ``J = 0``) gives ``inf``, never NaN. Slightly
    negative eigenvalues from rounding count as singular.

    Parameters
    ----------
    J : [..., dim, dim] float64
        Information matrices [1/m²], symmetric positive semi-definite, finite.

    Returns
    -------
    crb : [...] float64
        [m²]; ``inf`` where ``J`` is singular.

    Raises
    ------
    ValidationError
        Non-finite, non-square, or clearly indefinite ``J`` (an eigenvalue below
        ``−1e-9·λ_max``).

    Examples
    --------
    >>> float(position_crb(np.diag([1.0, 4.0])))
    1.25
    >>> float(position_crb(np.diag([1.0, 0.0])))
    inf
    """
    A = v.finite_array("J", J)
    if A.ndim < 2 or A.shape[-1] != A.shape[-2] or A.shape[-1] < 1:
        raise ValidationError("J", f"array of shape {A.shape}", "must be [..., dim, dim]")
    lam = np.linalg.eigvalsh(0.5 * (A + np.swapaxes(A, -1, -2)))
    top = np.max(np.abs(lam), axis=-1, keepdims=True)
    if np.any(lam < -1e-9 * top):
        raise ValidationError("J", "an indefinite matrix", "information must be PSD")
    singular = np.any(lam <= 1e-12 * top, axis=-1) | (top[..., 0] == 0.0)
    safe = np.where(singular[..., None], 1.0, lam)
    return np.where(singular, np.inf, np.sum(1.0 / safe, axis=-1))

"""Link likelihoods of the equivalent-likelihood distributed particle filter (DiPNet §III).

The likelihoods see a neighbour only through its published mean and covariance (the first two
moments of its belief, DiPNet Algorithm 1 line 5) and inflate the link's uncertainty by the
projected neighbour variance ``σ²_{v→uv} = e_uvᵀ C_v e_uv`` (DiPNet eq. (15)):

:class:`DirectLikelihood` (DiPNet)
    ``log p̃ = |f_uv(‖p_u − p̂_v‖)|² / (σ̃²_uv ‖S‖²)`` (DiPNet eq. (25)) from the link's
    correlation table, with the equivalent noise variance (ENV) of DiPNet eq. (26)
    ``σ̃² = σ² + 2ω²σ²_{v→uv}·|α̂|²·Σ|S_n|²n² / c0²``.
:class:`MarginalDirectLikelihood` (phyloc's default DiPNet likelihood)
    the one-path likelihood of DiPNet eq. (22) as a mixture of its Laplace peaks, convolved
    with the neighbour's projected uncertainty along the link, its evidence bounded by an
    outlier floor.
:class:`GaussianRangeLikelihood` (two-step EL-DPF)
    ``log p̃ = −(‖p_u − p̂_v‖ − r̂_uv)² / (2(var_uv + σ²_{v→uv}))``: the Gaussian ranging model
    with the equivalent ranging variance (ERV) of DiPNet eq. (18).

Each is a :class:`~phyloc.localization.likelihoods.Likelihood`; the sample-based exchange,
where a neighbour is its particle set, is :mod:`phyloc.localization.direct.sampled_exchange`.
Links are the directed pairs ``(u, v)`` with u an agent (u uses its own received signal from
v). Tempering multiplies every log-likelihood by γ ∈ (0, 1]. The ENV and the ranging
information are those of :mod:`phyloc.analysis.efim` (one implementation of each equation).

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import math

import numpy as np

from phyloc import _validate as v
from phyloc.analysis.efim import (
    COINCIDENT_TOL_M,
    equivalent_noise_variance,
    projected_variance,
    ranging_information,
)
from phyloc.errors import ValidationError
from phyloc.localization.direct import _kernels as K
from phyloc.localization.likelihoods import IncomingLinks
from phyloc.phy.correlation import CorrelationTable, interpolation_order
from phyloc.phy.system import C0


def projected_variances(centers, covs, rx, tx) -> np.ndarray:
    """``σ²_{v→uv} = e_uvᵀ C_v e_uv`` per link (DiPNet eq. (15)), ``e_uv = (c_u − c_v)/‖·‖``.

    :func:`phyloc.analysis.efim.projected_variance` per link ``(rx, tx)`` at the published
    means ``centers``. Coincident means (``‖c_u − c_v‖ <= COINCIDENT_TOL_M``) leave the
    direction undefined; the link then uses the isotropic value ``trace(C_v)/dim`` (never NaN).
    """
    diff = centers[rx] - centers[tx]
    ok = np.linalg.norm(diff, axis=1) > COINCIDENT_TOL_M
    return projected_variance(covs[tx], np.where(ok[:, None], diff, 0.0))


class DirectLikelihood:
    """DiPNet's equivalent likelihood from correlation tables (DiPNet eqs. (25), (26)).

    Parameters
    ----------
    table : CorrelationTable
        One table row per link of ``links`` (same order).
    links : [n_links, 2] int
        Directed pairs (u, v): u receives from v.
    agent_of_node : [n_nodes] int
        Agent index of each node, −1 for anchors.
    interpolation : str
        Table interpolation (see :mod:`phyloc.phy.correlation`).
    window_m : (float, float)
        Where the amplitude ``|α̂|`` of DiPNet eq. (21) is estimated (the correlation peak).
    ways : int
        1 for synchronized one-way ranging, 2 for two-way (the table's distance axis is then
        the round trip, so the likelihood is evaluated at ``2‖p_u − p̂_v‖``).
    use_env : bool
        Inflate σ² by the neighbour's projected variance (DiPNet eq. (26)); False treats
        neighbours as exactly known.
    """

    kind = "direct"

    def __init__(
        self,
        table: CorrelationTable,
        links,
        agent_of_node,
        n_agents,
        *,
        interpolation="cubic",
        window_m=(0.0, 300.0),
        ways=1,
        use_env=True,
    ):
        if table.n_links != len(links):
            raise ValidationError("table", f"{table.n_links} links", f"one per link ({len(links)})")
        self.csr = IncomingLinks(links, agent_of_node, n_agents)
        idx = self.csr.link_index
        self.table = table
        self.rows = idx.astype(np.int64)
        self.order = interpolation_order(interpolation)
        self.ways = int(ways)
        self.use_env = bool(use_env)
        peak = table.peak(window_m=window_m)
        snr = table.snr(peak[:, None])[:, 0]
        self.noise_var = table.noise_var[idx]
        self.alpha_abs2 = (snr * table.noise_var)[idx]
        self.energy = table.symbol_energy[idx]
        self.moment2 = table.symbol_moment2[idx]
        self.omega = table.system.omega
        # ranging information ν = 1/CRB (DiPNet eq. (24)) of each link, for covariance floors
        self.nu = ranging_information(snr[idx], self.moment2, self.omega)

    def env(self, centers, covs) -> np.ndarray:
        """Equivalent noise variance σ̃² per link (DiPNet eq. (26))."""
        if not self.use_env:
            return self.noise_var.copy()
        s2 = projected_variances(centers, covs, self.csr.rx, self.csr.tx) * self.ways**2
        return equivalent_noise_variance(
            self.noise_var, s2, self.alpha_abs2, self.moment2, self.omega
        )

    def loglik(self, particles, centers, covs, gamma=1.0) -> np.ndarray:
        """``γ Σ_v log p̃(r_uv | x, p̂_v)`` for every particle, ``[n_agents, Q]``."""
        scale = gamma / (self.env(centers, covs) * self.energy)
        out = np.empty(particles.shape[:2])
        K.direct_loglik_kernel(
            particles,
            self.csr.offsets,
            self.csr.tx,
            self.rows,
            scale,
            np.ascontiguousarray(centers, dtype=np.float64),
            self.table.values,
            self.ways / self.table.spacing_m,
            self.order,
            out,
        )
        return out


class GaussianRangeLikelihood:
    """Two-step equivalent likelihood: Gaussian ranges with the ERV of DiPNet eq. (18).

    Parameters
    ----------
    ranges, variances : [n_links] float
        Range estimates [m] and their model variances [m²] (e.g. the one-path ZZB at the
        estimated SNR, DiPNet §V-A).
    valid : [n_links] bool
        Links without a range are left out (NLOS-rejected SAGE drops NLOS links this way).
    outlier_nats : float
        Bound on one link's evidence [nats] (default ``inf``: the plain Gaussian). A finite
        ``f`` makes each link a mixture with an outlier component,
        ``log(e^{−(d − r̂)²/(2σ²)} + e^{−f})``, the robustness
        :class:`MarginalDirectLikelihood` has by the same key.
    model_error_m : float
        Range model error [m] added to every link's variance (``σ² = var + model_error_m²``
        + the ERV term), for the range errors the thermal-noise variance leaves out.
    one_sided : bool
        With a finite ``outlier_nats``, the outlier component covers only ranges *longer* than
        the distance (an NLOS excess delay is positive): where the distance exceeds the range
        the link keeps the Gaussian's pull (``−(d − r̂)²/(2σ²) + log(1 + e^{−f})``), so a
        particle too far from a neighbour is always pulled in. Default False (both sides).

    The model variance of a range estimator (its ZZB/CRB at the estimated SNR) is a thermal
    noise variance: it goes to 0 as the SNR grows, while an NLOS or multipath bias does not.
    Without a bound and a floor, a biased range at high SNR is then *certain*, one link can
    outweigh all the others, and a two-step filter's error grows with the transmit power;
    ``outlier_nats`` and ``model_error_m`` keep the evidence of one link bounded.
    """

    kind = "gaussian"

    def __init__(
        self,
        ranges,
        variances,
        valid,
        links,
        agent_of_node,
        n_agents,
        *,
        use_erv=True,
        outlier_nats=np.inf,
        model_error_m=0.0,
        one_sided=False,
    ):
        links = np.asarray(links, dtype=np.int64)
        valid = np.asarray(valid, bool)
        r = np.asarray(ranges, float)
        var = np.asarray(variances, float)
        if not (r.shape == var.shape == valid.shape == (len(links),)):
            raise ValidationError("ranges", f"shape {r.shape}", f"[n_links] = [{len(links)}]")
        keep = valid & np.isfinite(r) & np.isfinite(var) & (var > 0)
        self.csr = IncomingLinks(links[keep], agent_of_node, n_agents)
        idx = np.flatnonzero(keep)[self.csr.link_index]
        self.outlier_nats = float(outlier_nats)
        if not self.outlier_nats > 0:
            raise ValidationError("outlier_nats", outlier_nats, "> 0 (inf: no bound)")
        self.model_error_m = v.positive("model_error_m", model_error_m, allow_zero=True)
        if not isinstance(one_sided, bool | np.bool_):
            raise ValidationError("one_sided", one_sided, "true or false")
        self.one_sided = bool(one_sided)
        self.ranges = r[idx]
        self.var = var[idx] + self.model_error_m**2
        self.use_erv = bool(use_erv)
        self.nu = 1.0 / self.var

    def loglik(self, particles, centers, covs, gamma=1.0) -> np.ndarray:
        """``γ Σ_v log p̃(r̂_uv | x, p̂_v)`` for every particle, ``[n_agents, Q]``."""
        return self.frozen(particles, centers, covs, gamma)(particles)

    def frozen(self, particles, centers, covs, gamma=1.0):
        """``loglik`` with the neighbours' moments frozen, as a function of the particles.

        The ERV variances are computed once. Returns ``fn(x, agents=None) -> [n_rows, Q']``
        for ``x [n_rows, Q', dim]``, row ``r`` being agent ``agents[r]`` (all agents when
        None); ``particles`` is unused (the signature of
        :meth:`MarginalDirectLikelihood.frozen`).
        """
        var = self.var.copy()
        if self.use_erv:
            var += projected_variances(centers, covs, self.csr.rx, self.csr.tx)
        inv_var = gamma / var
        c = np.ascontiguousarray(centers, dtype=np.float64)
        every = np.arange(self.csr.offsets.size - 1, dtype=np.int64)

        def fn(x, agents=None):
            rows = every if agents is None else np.asarray(agents, dtype=np.int64)
            out = np.empty(x.shape[:2])
            K.gauss_loglik_kernel(
                np.ascontiguousarray(x, dtype=np.float64),
                rows,
                self.csr.offsets,
                self.csr.tx,
                self.ranges,
                inv_var,
                c,
                out,
                self.outlier_nats,
                float(gamma),
                self.one_sided,
            )
            return out

        return fn


class MarginalDirectLikelihood:
    """DiPNet's direct likelihood marginalized over the neighbour's projected uncertainty.

    The one-path likelihood of DiPNet eq. (22), ``exp(ℓ(d))`` with ``ℓ = |f(d)|²/(σ²‖S‖²)``, is
    represented by the Laplace approximations of its peaks in the search window (position
    ``d_i``, height ``h_i = ℓ(d_i)``, curvature ``c_i = −ℓ''(d_i)``, all from the exact spectral
    sum) plus the floor ``exp(0)``, and convolved with ``N(0, σ²_{v→uv})`` along the distance
    axis — the neighbour's position uncertainty projected on the link (DiPNet eq. (15)):

    .. math:: \\log\\tilde p(r_{uv}|p_u, \\hat p_v) = \\log\\Big(1 + \\sum_i
              \\frac{e^{h_i}}{\\sqrt{1 + c_i σ^2_{v→uv}}}
              \\exp\\Big(-\\frac{(\\|p_u - \\hat p_v\\| - d_i)^2}
              {2(1/c_i + σ^2_{v→uv})}\\Big)\\Big).

    At each peak its curvature is ``1/(1/c_i + σ²_{v→uv})`` — the equivalent ranging
    information of DiPNet eqs. (14)/(18), as the ENV of DiPNet eq. (26) also gives — but,
    unlike DiPNet eq. (25) with the ENV, its height does not vanish when the neighbour is
    uncertain: DiPNet eq. (25) divides the whole bump by σ̃², which for a neighbour known to
    10 m leaves a bump of ~0.1 nat (height ``≈ 6c0²/(ω²N²σ²_{v→uv})``) and no pull beyond the
    correlation main lobe; the marginal keeps the full evidence spread over the uncertain range.
    This is phyloc's default DiPNet likelihood (a departure from DiPNet eq. (25), documented as
    such); ``DirectLikelihood`` is DiPNet eq. (25).

    Peaks are the grid maxima of ``|f|²`` in ``window_m`` with ``h_i >= max h − drop_nats``, at
    most ``max_peaks`` per link (the highest). Heights are stored relative to each link's
    highest, ``pk_ref`` (``pk_h = h − pk_ref``), and ``loglik`` returns the log-likelihood minus
    ``Σ pk_ref`` over the agent's links — a constant per agent, which no weight sees, that keeps
    the evidence bound exact at extreme SNR (``h ≈ 1e20`` nats at +200 dBm, where float64
    resolves only ~1e4 nats).

    Robustness (``outlier_nats``, default 10): the floor ``e^0`` is raised to
    ``e^{h_max − outlier_nats}`` (``h_max`` the link's highest smoothed peak), i.e. a mixture
    with an outlier component, so one link can move the log-weights by at most
    ``outlier_nats``. Without it, while neighbours are uncertain (large σ²_{v→uv}) the
    smoothed peaks act like a Gaussian ranging model around whatever peak is strongest —
    including an NLOS peak 90 m late — and a minority of NLOS links can pull an agent to a
    wrong solution; DiPNet eq. (25)'s bounded ``|f|²`` evidence has this robustness by construction.
    ``outlier_nats=inf`` gives the plain marginal.

    Model error (``model_error_m``, default 0): a range error the one-path model leaves out —
    the shift of a correlation peak by unresolved multipath — as an extra ``N(0,
    model_error_m²)`` in the smoothing (added to ``σ²_{v→uv}``). The Laplace curvature of a
    peak reflects the noise only (centimetres at 37.6 MHz and high SNR), so without it the
    filter's beliefs in multipath channels are several times narrower than its errors.
    """

    kind = "marginal"

    def __init__(
        self,
        table: CorrelationTable,
        links,
        agent_of_node,
        n_agents,
        *,
        window_m=(0.0, 300.0),
        ways=1,
        drop_nats=25.0,
        max_peaks=32,
        use_env=True,
        outlier_nats=10.0,
        interpolation=None,
        tabulate=True,
        model_error_m=0.0,
    ):
        if table.n_links != len(links):
            raise ValidationError("table", f"{table.n_links} links", f"one per link ({len(links)})")
        self.csr = IncomingLinks(links, agent_of_node, n_agents)
        idx = self.csr.link_index
        self.ways = int(ways)
        self.use_env = bool(use_env)
        self.tabulate = bool(tabulate)
        self.outlier_nats = float(outlier_nats)
        if not self.outlier_nats > 0:
            raise ValidationError("outlier_nats", outlier_nats, "> 0 (inf: no clipping)")
        self.model_error_m = v.positive("model_error_m", model_error_m, allow_zero=True)
        sysm = table.system
        h = table.spacing_m
        lo, hi = float(window_m[0]), float(window_m[1])
        k = np.arange(math.ceil(lo / h), math.floor(hi / h) + 1)
        inv_scale = 1.0 / (table.noise_var * table.symbol_energy)
        counts, rows, d0, sc = [], [], [], []
        for link in idx:
            g = np.abs(table.values[link, k % table.n_fft]) ** 2
            interior = np.zeros(g.size, bool)
            interior[1:-1] = (g[1:-1] > g[:-2]) & (g[1:-1] >= g[2:])
            cand = np.flatnonzero(interior)
            if cand.size == 0:
                cand = np.array([int(np.argmax(g))])
            ell = g[cand] * inv_scale[link]
            keep = cand[ell >= ell.max() - drop_nats]
            if keep.size > max_peaks:
                keep = keep[np.argsort(g[keep])[::-1][:max_peaks]]
            counts.append(keep.size)
            rows.append(np.full(keep.size, link))
            d0.append(k[keep] * h)
            sc.append(np.full(keep.size, inv_scale[link]))
        self.pk_off = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        rows = np.concatenate(rows).astype(np.int64) if rows else np.zeros(0, np.int64)
        d0 = np.concatenate(d0) if d0 else np.zeros(0)
        sc = np.concatenate(sc) if sc else np.zeros(0)
        self.pk_d = np.empty(d0.size)
        self.pk_h = np.empty(d0.size)
        self.pk_c = np.empty(d0.size)
        K.peak_laplace_kernel(
            table.spectrum,
            rows,
            float(-(sysm.n_subcarriers - 1) // 2),
            sysm.omega / C0,
            d0,
            h,
            8,
            sc,
            self.pk_d,
            self.pk_h,
            self.pk_c,
        )
        # ranging information ν of the strongest peak per link (for covariance floors)
        self.nu = np.zeros(len(idx))
        # heights relative to each link's highest peak (a per-link constant, which no weight
        # sees): at extreme SNR h reaches 1e20 nats, where the absolute floor h_max − f would
        # lose the f nats to rounding (float64 resolves ~1e4 nats there)
        self.pk_ref = np.zeros(len(idx))
        for j in range(len(idx)):
            a, b = self.pk_off[j], self.pk_off[j + 1]
            if b > a:
                top = a + np.argmax(self.pk_h[a:b])
                self.nu[j] = self.pk_c[top] * self.ways**2
                self.pk_ref[j] = self.pk_h[top]
                self.pk_h[a:b] -= self.pk_ref[j]

    def loglik(self, particles, centers, covs, gamma=1.0) -> np.ndarray:
        """``γ Σ_v log p̃(r_uv | x, p̂_v)`` for every particle, ``[n_agents, Q]``."""
        s2 = self._smoothing(centers, covs)
        floor = self._floors(s2)
        out = np.empty(particles.shape[:2])
        K.mixture_loglik_kernel(
            particles,
            self.csr.offsets,
            self.csr.tx,
            self.pk_off,
            self.pk_d,
            self.pk_h,
            self.pk_c,
            s2,
            floor,
            float(self.ways),
            float(gamma),
            np.ascontiguousarray(centers, dtype=np.float64),
            out,
        )
        return out

    def frozen(self, particles, centers, covs, gamma=1.0):
        """``loglik`` with the neighbours' moments frozen, as a function of the particles.

        With ``tabulate`` (the default), each link's smoothed log-likelihood is tabulated once
        along the distance over the range the agent's ``particles`` cover (``[n_agents, Q,
        dim]``, see :func:`~phyloc.localization.direct._kernels.mixture_grid_kernel`) and read
        back by 4-point Lagrange interpolation; distances outside the grid are evaluated
        exactly. The spacing keeps the interpolation error below ~1e-3 nats per link (tested), so a
        particle costs one square root and one cubic per link however many peaks the link
        has. The safeguarded filter evaluates the same frozen likelihood many times per
        iteration (tempering steps × Metropolis–Hastings moves); the table is built once.

        Returns ``fn(x, agents=None) -> [n_rows, Q']`` for ``x [n_rows, Q', dim]``, row ``r``
        being agent ``agents[r]`` (all agents when None), or None when ``tabulate`` is off (the
        caller then evaluates :meth:`loglik`).
        """
        if not self.tabulate:
            return None
        centers = np.array(centers, dtype=np.float64)
        covs = np.array(covs, dtype=np.float64)
        s2 = self._smoothing(centers, covs)
        floor = self._floors(s2)
        ways, gamma = float(self.ways), float(gamma)
        X = np.ascontiguousarray(particles, dtype=np.float64)
        n_links = self.csr.rx.size
        lo, inv_h = np.zeros(n_links), np.zeros(n_links)
        count = np.zeros(n_links, np.int64)
        K.mixture_grid_kernel(
            X,
            self.csr.offsets,
            self.csr.tx,
            self.pk_off,
            self.pk_h,
            self.pk_c,
            s2,
            floor,
            ways,
            centers,
            TABLE_RESOLUTION,
            TABLE_MAX_POINTS,
            TABLE_MARGIN,
            lo,
            inv_h,
            count,
        )
        t_off = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
        table = np.empty((int(count.sum()), 4))  # cubic pieces
        K.mixture_table_kernel(
            self.csr.offsets,
            self.pk_off,
            self.pk_d,
            self.pk_h,
            self.pk_c,
            s2,
            floor,
            lo,
            inv_h,
            count,
            t_off,
            table,
        )
        every = np.arange(X.shape[0], dtype=np.int64)

        def tabulated(x, agents=None):
            rows = every if agents is None else np.asarray(agents, dtype=np.int64)
            out = np.empty(x.shape[:2])
            K.mixture_tabulated_kernel(
                np.ascontiguousarray(x, dtype=np.float64),
                rows,
                self.csr.offsets,
                self.csr.tx,
                self.pk_off,
                self.pk_d,
                self.pk_h,
                self.pk_c,
                s2,
                floor,
                ways,
                gamma,
                centers,
                lo,
                inv_h,
                count,
                t_off,
                table,
                out,
            )
            return out

        tabulated.table_points = int(count.sum())
        return tabulated

    def _smoothing(self, centers, covs) -> np.ndarray:
        """Per-link smoothing variance on the table's distance axis: the neighbour's projected
        variance (DiPNet eq. (15), with ``use_env``) plus the range model error
        ``model_error_m²``, both times ``ways²``."""
        if self.use_env:
            s2 = projected_variances(centers, covs, self.csr.rx, self.csr.tx)
        else:
            s2 = np.zeros(self.csr.rx.size)
        return (s2 + self.model_error_m**2) * self.ways**2

    def _floors(self, s2) -> np.ndarray:
        """Per-link floor ``max(0, max_i(h_i − ½log(1 + c_i s²)) − outlier_nats)``, on the
        relative scale of ``pk_h`` (heights minus the link's highest, ``pk_ref``): the noise
        level ``0`` is ``−pk_ref`` there."""
        n_links = self.pk_off.size - 1
        if not np.isfinite(self.outlier_nats) or self.pk_d.size == 0:
            return -self.pk_ref
        link_of_peak = np.repeat(np.arange(n_links), np.diff(self.pk_off))
        height = self.pk_h - 0.5 * np.log1p(self.pk_c * s2[link_of_peak])
        top = np.full(n_links, -np.inf)
        np.maximum.at(top, link_of_peak, height)
        return np.maximum(-self.pk_ref, top - self.outlier_nats)


TABLE_RESOLUTION = 0.15
"""Grid spacing of :meth:`MarginalDirectLikelihood.frozen` in units of the steepest
transition ``1/√(hp·(base − floor))`` of a link's smoothed log-likelihood."""
TABLE_MARGIN = 0.25
"""Widening of each link's grid beyond the particles' distance range, as a fraction of it."""
TABLE_MAX_POINTS = 4096
"""Links that would need a larger grid are evaluated exactly."""

"""Link likelihoods of the equivalent-likelihood distributed particle filter (DiPNet §III).

Both likelihoods see a neighbour only through its published mean and covariance (the first two
moments of its belief, Algorithm 1 line 5) and inflate the link's uncertainty by the projected
neighbour variance ``σ²_{v→uv} = e_uvᵀ C_v e_uv`` (eq. (15)):

:class:`DirectLikelihood` (DiPNet)
    ``log p̃ = |f_uv(‖p_u − p̂_v‖)|² / (σ̃²_uv ‖S‖²)`` (eq. (25)) from the link's correlation
    table, with the equivalent noise variance (ENV) of eq. (26)
    ``σ̃² = σ² + 2ω²σ²_{v→uv}|α̂|² Σ|S_n|²n² / c0²``.
:class:`GaussianRangeLikelihood` (two-step EL-DPF)
    ``log p̃ = −(‖p_u − p̂_v‖ − r̂_uv)² / (2(var_uv + σ²_{v→uv}))``: the Gaussian ranging model
    with the equivalent ranging variance (ERV) of eq. (18).

Links are the directed pairs ``(u, v)`` with u an agent (u uses its own received signal from
v). Tempering multiplies every log-likelihood by γ ∈ (0, 1].
"""

from __future__ import annotations

import numpy as np

from phyloc.errors import ValidationError
from phyloc.localization import _kernels as K
from phyloc.phy.correlation import CorrelationTable, interpolation_order
from phyloc.phy.system import C0


def projected_variances(centers, covs, rx, tx) -> np.ndarray:
    """``σ²_{v→uv} = e_uvᵀ C_v e_uv`` per link (eq. (15)), ``e_uv = (c_u − c_v)/‖c_u − c_v‖``.

    Coincident means leave the direction undefined; the link then uses the isotropic value
    ``trace(C_v)/dim`` (never NaN).
    """
    diff = centers[rx] - centers[tx]
    norm = np.linalg.norm(diff, axis=1)
    C = covs[tx]
    dim = centers.shape[1]
    iso = np.trace(C, axis1=1, axis2=2) / dim
    ok = norm > 1e-12
    e = np.zeros_like(diff)
    e[ok] = diff[ok] / norm[ok, None]
    proj = np.einsum("li,lij,lj->l", e, C, e)
    return np.where(ok, proj, iso)


class _Links:
    """CSR layout of the incoming links of each agent."""

    def __init__(self, links, agent_of_node, n_agents):
        links = np.asarray(links, dtype=np.int64)
        if links.ndim != 2 or links.shape[1] != 2:
            raise ValidationError("links", f"shape {links.shape}", "[n_links, 2] (u, v) pairs")
        rx_agent = agent_of_node[links[:, 0]]
        keep = np.flatnonzero(rx_agent >= 0)  # only links received by agents
        order = keep[np.argsort(rx_agent[keep], kind="stable")]
        self.link_index = order  # rows into the caller's link arrays
        self.rx = links[order, 0]
        self.tx = links[order, 1]
        counts = np.bincount(rx_agent[order], minlength=n_agents)
        self.offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


class DirectLikelihood:
    """DiPNet's equivalent likelihood from correlation tables (eqs. (25), (26)).

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
        Where the amplitude |α̂| of eq. (21) is estimated (the correlation peak).
    ways : int
        1 for synchronized one-way ranging, 2 for two-way (the table's distance axis is then
        the round trip, so the likelihood is evaluated at ``2‖p_u − p̂_v‖``).
    use_env : bool
        Inflate σ² by the neighbour's projected variance (eq. (26)); False treats neighbours as
        exactly known.
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
        self.csr = _Links(links, agent_of_node, n_agents)
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
        # ranging information ν = 1/CRB (eq. (24)) of each link, for covariance floors
        self.nu = 2.0 * self.alpha_abs2 * self.omega**2 * self.moment2 / (C0**2 * self.noise_var)

    def env(self, centers, covs) -> np.ndarray:
        """Equivalent noise variance σ̃² per link (eq. (26))."""
        if not self.use_env:
            return self.noise_var.copy()
        s2 = projected_variances(centers, covs, self.csr.rx, self.csr.tx) * self.ways**2
        return self.noise_var + 2.0 * self.omega**2 * s2 * self.alpha_abs2 * self.moment2 / C0**2

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
    """Two-step equivalent likelihood: Gaussian ranges with the ERV of eq. (18).

    Parameters
    ----------
    ranges, variances : [n_links] float
        Range estimates [m] and their model variances [m²] (e.g. the one-path ZZB at the
        estimated SNR, DiPNet §V-A).
    valid : [n_links] bool
        Links without a range are left out (NLOS-rejected SAGE drops NLOS links this way).
    """

    kind = "gaussian"

    def __init__(self, ranges, variances, valid, links, agent_of_node, n_agents, *, use_erv=True):
        links = np.asarray(links, dtype=np.int64)
        valid = np.asarray(valid, bool)
        r = np.asarray(ranges, float)
        var = np.asarray(variances, float)
        if not (r.shape == var.shape == valid.shape == (len(links),)):
            raise ValidationError("ranges", f"shape {r.shape}", f"[n_links] = [{len(links)}]")
        keep = valid & np.isfinite(r) & np.isfinite(var) & (var > 0)
        self.csr = _Links(links[keep], agent_of_node, n_agents)
        idx = np.flatnonzero(keep)[self.csr.link_index]
        self.ranges = r[idx]
        self.var = var[idx]
        self.use_erv = bool(use_erv)
        self.nu = 1.0 / self.var

    def loglik(self, particles, centers, covs, gamma=1.0) -> np.ndarray:
        """``γ Σ_v log p̃(r̂_uv | x, p̂_v)`` for every particle, ``[n_agents, Q]``."""
        var = self.var.copy()
        if self.use_erv:
            var += projected_variances(centers, covs, self.csr.rx, self.csr.tx)
        out = np.empty(particles.shape[:2])
        K.gauss_loglik_kernel(
            particles,
            self.csr.offsets,
            self.csr.tx,
            self.ranges,
            gamma / var,
            np.ascontiguousarray(centers, dtype=np.float64),
            out,
        )
        return out

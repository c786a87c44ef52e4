"""Per-link channel draws: LOS/NLOS, path loss, shadowing, clusters, NLOS bias, phases.

For every link u←v at distance d the sampler returns paths with absolute delays
``τ_l = d/c0 + b + δ_l`` and complex gains ``α_l = √A_l·e^{jφ_l}`` (the signal model of
:doc:`/guide/design`; DiPNet eq. (6), §II-B), where ``b > 0`` only in NLOS and ``δ_0 = 0`` is
the LOS path, absent in NLOS. The path powers sum to the link-budget received power
``P_tx − PL(d) − SF`` (:meth:`phyloc.phy.OFDMSystem.received_power_w`).

WINNER II model (D1.1.2 Part I, Sec. 4.2), per link
----------------------------------------------------
1. Condition: LOS with probability P_LOS(d) (WINNER II D1.1.2 Table 4-7), unless forced.
2. Path loss PL(d) and shadow-fading std σ_SF(d) (WINNER II D1.1.2 Table 4-4; see
   :mod:`phyloc.channels.pathloss` for the device-to-device adaptation: heights, distances
   below the law's minimum).
3. Large-scale parameters (step 4): one standard-normal vector ``x`` per link with the
   tabulated cross-correlation of ``[DS, SF, K]`` (LOS) or ``[DS, SF]`` (NLOS), imposed with a
   Cholesky factor; ``DS = 10^(μ_DS + σ_DS·x_DS)`` s, ``SF = σ_SF(d)·x_SF`` dB,
   ``K = μ_K + σ_K·x_K`` dB. The angle spreads (ASD, ASA) are not drawn (single-antenna links
   have no use for them), and LSPs are *not* spatially correlated across links.
4. Cluster delays (step 5): ``τ'_n = −r_τ·DS·ln X_n``, ``X_n ~ U(0, 1]`` (WINNER II eq. (4.1)), or
   ``τ'_n ~ U(0, τ_max)`` for uniform-delay scenarios (B1 NLOS); ``τ_n = sort(τ'_n − min τ')``
   (WINNER II eq. (4.2)).
5. Cluster powers (step 6): ``P'_n = exp(−τ_n (r_τ − 1)/(r_τ DS))·10^(−Z_n/10)``
   (WINNER II eq. (4.5)) or ``exp(−τ_n/DS)·10^(−Z_n/10)`` for uniform delays (WINNER II
   eq. (4.6)), ``Z_n ~ N(0, ζ²)``; ``P_n = P'_n / Σ P'`` (WINNER II eq. (4.7)).
6. LOS: ``K_R = 10^(K/10)``; the direct path (``δ_0 = 0``) carries ``K_R/(K_R + 1)`` and the
   clusters are scaled by ``1/(K_R + 1)`` (WINNER II eq. (4.8)); cluster delays are divided by
   ``D(K) = 0.7705 − 0.0433K + 0.0002K² + 0.000017K³`` (WINNER II eqs. (4.3)–(4.4)) with the
   link's own K (K is limited to [−30, 40] dB inside D only, where D stays positive); powers
   use the unscaled delays.
7. Sub-clusters (step 11): the two strongest clusters are each split into three paths at
   +0/5/10 ns carrying 10/20, 6/20, 4/20 of the cluster power.
8. Every path gets an independent uniform phase. Each (sub-)cluster is one path of its
   power (the clustered-delay-line form): the 20 rays of a WINNER II cluster differ only in
   angle, which single-antenna links do not resolve.
9. NLOS: no direct path and a bias ``b ~ Exp`` with mean ``nlos_bias_mean_s`` (default
   0.3 µs, DiPNet §V-A) on every path. WINNER II gives only relative delays; the bias is
   phyloc's addition. The first NLOS path arrives at exactly ``d/c0 + b``.

Exponential model (DiPNet §IV-A, Appendix III): ``L = 1 + Poisson(L̄ − 1)`` components with
``δ_l ~ Exp`` (mean ``excess_delay_mean_s``) and i.i.d. exponential powers normalised to the
scatter power; LOS: direct path with the fixed ratio K; NLOS: bias as above.
AWGN: one direct path.

Field model (:mod:`phyloc.channels.field`, LOS only): the free-space direct path, the ground
reflection (Fresnel coefficient of the ground, fixed phase relative to the direct path, so the
pair interferes as in the two-ray model), ``K_s`` specular paths of metallic structures with
uniform excess delays and ``N_d`` diffuse rays with exponential excess delays; no shadowing.
The path loss is ``−10·log10 Σ_l |a_l|²`` of the link's path amplitudes.

TDL model (:mod:`phyloc.channels.tdl`, 3GPP TR 38.901 Sec. 7.7.2): the table's taps at
``δ_n = τ_n,model · DS``, one path each with mean power ``p_n`` of the link budget (Rayleigh:
power ``p_n |g_n|²``, ``|g_n|² ~ Exp(1)``; the specular LOS row of TDL-D/E: ``p_n``), uniform
phases, no Doppler. Its received power is the realized ``Σ_n |α_n|²``, the link budget times
``G = Σ_n p_n |g_n|²`` (``E[G] = 1``).

TR 38.901 system-level model (:mod:`phyloc.channels.tr38901`, Sec. 7.4–7.5): LOS probability,
path loss and σ_SF of the scenario's tables (heights from ``h_tx_m``/``h_rx_m``, the link
distance taken as the 3D distance), DS/K/SF with the cross-correlation of Table 7.5-6,
exponential cluster delays (LOS: divided by C_τ), cluster powers with shadowing, removal of
clusters 25 dB below the strongest, sub-clusters of the two strongest at 0, 1.28, 2.56·c_DS,
the direct path in LOS; NLOS bias as above.

Paths of a link are sorted by delay (the LOS path first at a tie). The random streams are
consumed in a fixed order, so a draw depends only on the seed, the scenario and the batch.

References
----------
WINNER II: IST-4-027756 WINNER II Deliverable D1.1.2 V1.2, Part I (channel models), 2007,
updated 2008; the table each value of the shipped channel files comes from is given in
``channels/PROVENANCE.md``.

DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from phyloc import _validate as v
from phyloc.channels.field import (
    fresnel_reflection,
    ground_permittivity,
    ground_reflection_geometry,
)
from phyloc.channels.pathloss import D_FAR_FIELD_M
from phyloc.channels.scenario import (
    CONDITIONS,
    AwgnCondition,
    ExponentialCondition,
    FieldCondition,
    Scenario,
    Winner2Condition,
    load_scenario,
)
from phyloc.channels.tdl import TdlCondition, draw_tdl
from phyloc.channels.tr38901 import Tr38901Condition, draw_tr38901
from phyloc.errors import ValidationError
from phyloc.phy.paths import PathSet
from phyloc.phy.system import C0, OFDMSystem

#: K-factor range [dB] inside the LOS delay scaling D(K) (D > 0 on it).
K_RANGE_FOR_DELAY_SCALING_DB = (-30.0, 40.0)


@dataclass(frozen=True, eq=False)
class ChannelDraw:
    """The channels of a batch of links.

    Attributes
    ----------
    paths : PathSet
        Absolute delays ``τ_l`` [s] and complex gains ``α_l`` [√W] per link. One-way:
        ``τ_l = d/c0 + b + δ_l``. Two-way: the composite channel, ``τ ≥ 2d/c0 + b`` (round trip).
    los : [n_links], bool
        True for LOS links.
    nlos_bias_s : [n_links], float64
        NLOS bias ``b`` [s] (0 for LOS; two-way: forward + backward bias).
    path_loss_db : [n_links], float64
        Distance-dependent path loss [dB] (without shadowing).
    shadowing_db : [n_links], float64
        Shadow fading SF [dB] as a loss; the link budget uses ``PL + SF``. The tables
        correlate the gain ``−SF`` with DS and K (WINNER II Table 4-5, TR 38.901 Table 7.5-6).
    shadowing_std_db : [n_links], float64
        σ_SF of the link's path-loss segment [dB].
    received_power_w : [n_links], float64
        ``P_tx − PL − SF`` [W] = ``Σ_l |α_l|²``; tdl model: ``Σ_l |α_l|²``, the link budget
        times the link's wideband fading gain ``G`` (mean 1) of its Rayleigh taps.
    delay_spread_s : [n_links], float64
        The large-scale delay spread drawn for the link [s] (WINNER II step 4; exponential
        model: ``excess_delay_mean_s``; field model: the diffuse ``delay_spread_s``; tdl
        model: the file's ``delay_spread_s``; AWGN: 0).
        Not the rms spread of ``paths``.
    k_factor_db : [n_links], float64
        Ricean K-factor [dB] of LOS links (exponential model: the fixed ratio; field model:
        direct-path power over the power of all other paths, the ground reflection included;
        tdl model: the mean specular power over the mean power of all Rayleigh taps, TR 38.901
        Sec. 7.7.6; AWGN: +inf); NaN for NLOS links, which have no direct path.
    distances_m : [n_links], float64
        Link distances [m].
    scenario : str
        Name of the scenario drawn from.
    ranging : {"one_way", "two_way"}
        How ``paths`` is to be read (see above).
    components : (ChannelDraw, ChannelDraw) or None
        Two-way only: the forward and backward one-way draws. The per-link fields other than
        ``los`` and ``nlos_bias_s`` are those of the backward link (whose power reaches the
        initiator after amplify-and-forward; its path loss at the backward carrier,
        :attr:`ChannelSpec.backward_carrier_frequency_hz`).
    """

    paths: PathSet
    los: np.ndarray
    nlos_bias_s: np.ndarray
    path_loss_db: np.ndarray
    shadowing_db: np.ndarray
    shadowing_std_db: np.ndarray
    received_power_w: np.ndarray
    delay_spread_s: np.ndarray
    k_factor_db: np.ndarray
    distances_m: np.ndarray
    scenario: str
    ranging: str = "one_way"
    components: tuple | None = None

    @property
    def n_links(self) -> int:
        """Number of links."""
        return self.distances_m.size

    @property
    def ways(self) -> int:
        """1 for one-way, 2 for two-way ranging: the LOS delay is ``ways·d/c0``."""
        return 2 if self.ranging == "two_way" else 1

    def excess_delays(self) -> np.ndarray:
        """``τ_l − ways·d/c0`` per path [s], ``[n_paths_total]`` (includes the NLOS bias)."""
        link = self.paths.link_index()
        return self.paths.delays - self.ways * self.distances_m[link] / C0

    def rms_delay_spread(self) -> np.ndarray:
        """Power-weighted rms delay spread of each link's paths [s], ``[n_links]``."""
        link = self.paths.link_index()
        w = np.abs(self.paths.gains) ** 2
        n = self.n_links
        tot = np.bincount(link, w, n)
        t = self.excess_delays()
        m1 = np.bincount(link, w * t, n) / tot
        m2 = np.bincount(link, w * (t - m1[link]) ** 2, n) / tot
        return np.sqrt(m2)


# ---------------------------------------------------------------------------------------------
def draw_links(
    scenario,
    distances_m,
    rng: np.random.Generator,
    *,
    system: OFDMSystem | None = None,
    condition=None,
    nlos_bias_mean_s: float | None = None,
    h_tx_m=1.5,
    h_rx_m=1.5,
    h_e_m=None,
) -> ChannelDraw:
    """Draw the multipath channels of a batch of links (one-way).

    Parameters
    ----------
    scenario : str, os.PathLike or Scenario
        Scenario name (``"winner2_c2"`` draws each link's condition from P_LOS(d);
        ``"winner2_c2_los"`` / ``"_nlos"`` force it; ``"awgn"``, ``"exponential"``, ...), the
        path of a scenario TOML file, or a loaded :class:`Scenario`.
    distances_m : [n_links], float64
        Link distances d [m], finite and > 0.
    rng : numpy.random.Generator
        Source of all randomness.
    system : OFDMSystem, optional
        Carrier frequency (path loss) and transmit power (link budget); default
        ``OFDMSystem()`` (DiPNet §V-A: 5.2 GHz, 0 dBm).
    condition : {None, "los", "nlos"} or [n_links] bool, optional
        Force the condition of every link (a string) or of each link (True = LOS).
        ``None`` draws it from P_LOS(d) (or uses the scenario's forced condition).
    nlos_bias_mean_s : float, optional
        Mean NLOS bias [s], >= 0; default: the scenario file's value (0.3 µs, DiPNet §V-A).
    h_tx_m, h_rx_m : float or [n_links] float64
        Antenna heights [m], > 0 (default 1.5 m, device to device). The path-loss laws use
        ``h_BS = max`` and ``h_MS = min`` of the two; the field model's ground reflection uses
        both (its path length ``sqrt(d² + (h_tx + h_rx)²)``).
    h_e_m : float, optional
        tr38901 model only: the environment height ``h_E`` [m] (>= 0) of the breakpoint
        distance ``d'_BP`` (TR 38.901 Table 7.4.1-1, note 1); default the file's (UMi: 1 m;
        UMa: drawn per link).

    Returns
    -------
    ChannelDraw
        Paths and per-link large-scale quantities; ``paths.total_power()`` equals
        ``received_power_w``.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> draw = draw_links("winner2_c2_nlos", np.array([30.0, 80.0]), rng)
    >>> draw.paths.n_paths.tolist(), bool(draw.los.any())
    ([24, 24], False)
    >>> bool(np.all(draw.paths.first_delay() == draw.distances_m / C0 + draw.nlos_bias_s))
    True
    """
    scn = load_scenario(scenario)
    d = np.atleast_1d(v.finite_array("distances_m", distances_m))
    if d.ndim != 1:
        raise ValidationError("distances_m", f"array of shape {d.shape}", "must be 1-D")
    if d.size and d.min() <= 0:
        raise ValidationError("distances_m", float(d.min()), "distances must be > 0 m")
    if not isinstance(rng, np.random.Generator):
        raise ValidationError(
            "rng", type(rng).__name__, "a numpy.random.Generator, e.g. np.random.default_rng(seed)"
        )
    system = OFDMSystem() if system is None else system
    if not isinstance(system, OFDMSystem):
        raise ValidationError("system", type(system).__name__, "an OFDMSystem")
    fc = system.carrier_frequency_hz
    scn.check_frequency(fc)
    n = d.size
    h_tx = _heights("h_tx_m", h_tx_m, n)
    h_rx = _heights("h_rx_m", h_rx_m, n)
    h_bs, h_ms = np.maximum(h_tx, h_rx), np.minimum(h_tx, h_rx)
    if nlos_bias_mean_s is not None:
        nlos_bias_mean_s = v.positive("nlos_bias_mean_s", nlos_bias_mean_s, allow_zero=True)
    if h_e_m is not None:
        h_e_m = _environment_height(scn, h_e_m)

    los = _conditions(scn, condition, d, rng, h_bs, h_ms)

    pl = np.zeros(n)
    sf_std = np.zeros(n)
    sf = np.zeros(n)
    ds = np.zeros(n)
    k_db = np.full(n, math.nan)
    bias = np.zeros(n)
    fading_gain = np.ones(n)  # tdl model: Σ_n p_n |g_n|² of the link (else 1)
    counts = np.zeros(n, dtype=np.int64)
    chunks = []
    for cond, mask in (("los", los), ("nlos", ~los)):
        idx = np.flatnonzero(mask)
        if idx.size == 0:
            continue
        par = scn.params(cond)
        if isinstance(par, FieldCondition):  # path loss from the paths themselves
            res = _draw_field(par, d[idx], fc, h_tx[idx], h_rx[idx], rng)
            pl[idx] = res["pl_db"]
        elif isinstance(par, Tr38901Condition):  # heights and h_E enter the path loss
            res = draw_tr38901(par, d[idx], fc, h_bs[idx], h_ms[idx], rng, h_e_m=h_e_m)
            pl[idx], sf_std[idx] = res["pl_db"], res["sf_std_db"]
        else:
            par.pathloss.check_heights(h_bs[idx], h_ms[idx])
            pl[idx], sf_std[idx] = par.pathloss.evaluate(d[idx], fc, h_bs[idx], h_ms[idx])
            res = _DRAWERS[type(par)](par, sf_std[idx], rng)
        mean_b = par.nlos_bias_mean_s if nlos_bias_mean_s is None else nlos_bias_mean_s
        sf[idx], ds[idx], k_db[idx] = res["sf_db"], res["ds_s"], res["k_db"]
        if cond == "nlos" and mean_b > 0:
            bias[idx] = rng.exponential(mean_b, idx.size)
        counts[idx] = res["counts"]
        if "power_gain" in res:
            fading_gain[idx] = res["power_gain"]
        chunks.append((idx, res))

    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    rel = np.empty(offsets[-1])
    frac = np.empty(offsets[-1])
    fixed_phases = []
    for idx, res in chunks:
        c = res["counts"]
        local = np.zeros(idx.size + 1, dtype=np.int64)
        np.cumsum(c, out=local[1:])
        owner = np.repeat(np.arange(idx.size), c)
        pos = offsets[idx][owner] + (np.arange(local[-1]) - local[owner])
        rel[pos] = res["delays"]
        frac[pos] = res["fractions"]
        if "phase_rel" in res:
            fixed_phases.append((pos, offsets[idx][owner], res["phase_rel"]))
    link = np.repeat(np.arange(n), counts)
    p_rx = system.received_power_w(pl + sf) if n else np.zeros(0)
    phase = rng.uniform(0.0, 2.0 * math.pi, offsets[-1])
    for pos, first, prel in fixed_phases:
        # field model: phases fixed relative to the link's first path (the direct path)
        keep = np.isfinite(prel)
        phase[pos[keep]] = phase[first[keep]] + prel[keep]
    gains = np.sqrt(frac * p_rx[link]) * np.exp(1j * phase)
    delays = (d / C0 + bias)[link] + rel
    return ChannelDraw(
        paths=PathSet(delays, gains, offsets),
        los=los,
        nlos_bias_s=bias,
        path_loss_db=pl,
        shadowing_db=sf,
        shadowing_std_db=sf_std,
        received_power_w=np.asarray(p_rx * fading_gain, dtype=np.float64),
        delay_spread_s=ds,
        k_factor_db=k_db,
        distances_m=d,
        scenario=scn.name,
    )


def _heights(name: str, h, n: int) -> np.ndarray:
    arr = v.finite_array(name, h)
    if arr.ndim > 1 or (arr.ndim == 1 and arr.size != n):
        raise ValidationError(name, f"array of shape {arr.shape}", f"a scalar or shape ({n},)")
    if arr.size and arr.min() <= 0:
        raise ValidationError(name, float(arr.min()), "antenna heights must be > 0 m")
    return np.ascontiguousarray(np.broadcast_to(arr, (n,)), dtype=np.float64)


def _environment_height(scn: Scenario, h_e_m) -> float:
    """The recipe's ``h_e_m`` (tr38901 model only), >= 0."""
    if scn.model != "tr38901":
        raise ValidationError(
            "h_e_m",
            h_e_m,
            f"only the tr38901 model has an environment height; scenario '{scn.name}' is "
            f"{scn.model} (remove h_e_m)",
        )
    if not any(p is not None and p.pathloss.uses_environment_height for p in (scn.los, scn.nlos)):
        raise ValidationError(
            "h_e_m",
            h_e_m,
            f"scenario '{scn.name}' has no breakpoint with an environment height h_E "
            "(TR 38.901 UMi and UMa have one; remove h_e_m)",
        )
    return v.positive("h_e_m", h_e_m, allow_zero=True)


def _conditions(scn: Scenario, condition, d: np.ndarray, rng, h_bs=1.5, h_ms=1.5) -> np.ndarray:
    """LOS flag per link: forced, given, or drawn from P_LOS(d) (WINNER II D1.1.2 Table 4-7;
    TR 38.901 Table 7.4.2-1, which also depends on the antenna heights)."""
    n = d.size
    if condition is None:
        if scn.forced is not None:
            return np.full(n, scn.forced == "los")
        return rng.random(n) < scn.p_los(d, h_bs, h_ms)
    if isinstance(condition, str):
        if condition not in CONDITIONS:
            raise ValidationError("condition", condition, "None, 'los', 'nlos' or a bool array")
        los = np.full(n, condition == "los")
    else:
        los = np.asarray(condition)
        if los.dtype != np.bool_ or los.shape != (n,):
            raise ValidationError(
                "condition", f"array {los.dtype} {los.shape}", f"a bool array of shape ({n},)"
            )
    for cond, present in (("los", los.any()), ("nlos", (~los).any())):
        if present:
            if scn.forced is not None and scn.forced != cond:
                raise ValidationError(
                    "condition", cond, f"scenario '{scn.name}' forces {scn.forced.upper()}"
                )
            scn.params(cond)
    return los


def los_delay_scaling(k_db, coeffs) -> np.ndarray:
    """LOS delay scaling ``D(K) = c0 + c1·K + c2·K² + c3·K³`` (WINNER II D1.1.2 eq. (4.3)).

    Parameters
    ----------
    k_db : [n], float64
        Ricean K-factor [dB]; limited to :data:`K_RANGE_FOR_DELAY_SCALING_DB` (where D > 0).
    coeffs : (c0, c1, c2, c3)
        Polynomial coefficients (WINNER II: 0.7705, −0.0433, 0.0002, 0.000017).

    Returns
    -------
    [n], float64
        D; cluster delays of a LOS link are ``τ_n / D`` (WINNER II eq. (4.4)).

    Examples
    --------
    >>> los_delay_scaling(np.array([7.0]), (0.7705, -0.0433, 0.0002, 0.000017)).round(3)
    array([0.483])
    """
    k = np.clip(np.asarray(k_db, dtype=np.float64), *K_RANGE_FOR_DELAY_SCALING_DB)
    c0, c1, c2, c3 = coeffs
    return c0 + k * (c1 + k * (c2 + k * c3))


def _draw_winner2(p: Winner2Condition, sf_std: np.ndarray, rng) -> dict:
    """WINNER II steps 4–6 and 11 for ``n`` links of one condition (WINNER II eqs. (4.1)–(4.9))."""
    n = sf_std.size
    is_los = p.condition == "los"
    x = rng.standard_normal((n, p.cholesky.shape[0])) @ p.cholesky.T
    ds = 10.0 ** (p.ds_log10_mu + p.ds_log10_sigma * x[:, 0])
    # Table 4-5 correlates SF as a gain (P_rx = P_tx − PL + SF; the WINNER II reference code
    # multiplies the channel by sqrt(10^(SF/10))); ``shadowing_db`` is a loss added to PL
    sf = -sf_std * x[:, 1]
    k_db = p.k_db_mu + p.k_db_sigma * x[:, 2] if is_los else np.full(n, math.nan)
    nc = p.num_clusters
    if p.delay_distribution == "exponential":
        u = 1.0 - rng.random((n, nc))  # (0, 1]
        tau = -p.r_tau * ds[:, None] * np.log(u)  # WINNER II eq. (4.1)
    else:
        tau = rng.uniform(0.0, p.uniform_delay_max_s, (n, nc))
    tau.sort(axis=1)
    tau -= tau[:, :1]  # WINNER II eq. (4.2)
    z = p.cluster_shadowing_std_db * rng.standard_normal((n, nc))
    if p.delay_distribution == "exponential":
        pw = np.exp(-tau * ((p.r_tau - 1.0) / (p.r_tau * ds))[:, None] - z * (math.log(10) / 10))
    else:
        pw = np.exp(-tau / ds[:, None] - z * (math.log(10) / 10))  # WINNER II eq. (4.6)
    pw /= pw.sum(axis=1, keepdims=True)  # WINNER II eq. (4.7)
    if is_los:
        kr = 10.0 ** (k_db / 10.0)
        pw *= (1.0 / (kr + 1.0))[:, None]  # WINNER II eq. (4.8)
        tau /= los_delay_scaling(k_db, p.los_delay_scaling)[:, None]  # WINNER II eq. (4.4)
        # (the powers above used the unscaled delays, as D1.1.2 prescribes)
    ns = p.num_split
    if ns:
        offs = np.asarray(p.subcluster_offsets_s)
        fr = np.asarray(p.subcluster_fractions)
        if ns < nc:
            top = np.argpartition(-pw, ns - 1, axis=1)[:, :ns]
        else:
            top = np.broadcast_to(np.arange(nc), (n, nc))
        rows = np.arange(n)[:, None]
        ps, ts = pw[rows, top], tau[rows, top]
        pw[rows, top] = ps * fr[0]
        tau[rows, top] = ts + offs[0]
        tau = np.hstack([tau, (ts[:, :, None] + offs[1:]).reshape(n, -1)])
        pw = np.hstack([pw, (ps[:, :, None] * fr[1:]).reshape(n, -1)])
    if is_los:
        tau = np.hstack([np.zeros((n, 1)), tau])
        pw = np.hstack([(kr / (kr + 1.0))[:, None], pw])
    order = np.argsort(tau, axis=1, kind="stable")
    tau = np.take_along_axis(tau, order, axis=1)
    pw = np.take_along_axis(pw, order, axis=1)
    return {
        "sf_db": sf,
        "ds_s": ds,
        "k_db": k_db,
        "counts": np.full(n, tau.shape[1], dtype=np.int64),
        "delays": tau.ravel(),
        "fractions": pw.ravel(),
    }


def _draw_exponential(p: ExponentialCondition, sf_std: np.ndarray, rng) -> dict:
    """DiPNet analysis model (§IV-A): Poisson path count, Exp excess delays and powers."""
    n = sf_std.size
    is_los = p.condition == "los"
    sf = sf_std * rng.standard_normal(n)
    n_mpc = 1 + rng.poisson(p.mean_path_count - 1.0, n)
    total = int(n_mpc.sum())
    owner = np.repeat(np.arange(n), n_mpc)
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(n_mpc, out=start[1:])
    rank = np.arange(total) - start[owner]  # 0 … L−1 within the link
    # L i.i.d. Exp(μ) delays, drawn already sorted (Rényi: the k-th spacing of the order
    # statistics is Exp(μ/(L − k))); powers are independent of delays, so this equals sorting.
    spacing = rng.exponential(p.excess_delay_mean_s, total) / (n_mpc[owner] - rank)
    run = np.cumsum(spacing)
    delta = run - np.concatenate(([0.0], run))[start[:-1]][owner]
    a = rng.exponential(1.0, total)
    a /= np.bincount(owner, a, n)[owner]
    if is_los:
        kr = 10.0 ** (p.k_db / 10.0)
        counts = n_mpc + 1
        off = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(counts, out=off[1:])
        scatter = np.ones(off[-1], dtype=bool)
        scatter[off[:-1]] = False
        tau = np.zeros(off[-1])
        pw = np.empty(off[-1])
        tau[scatter] = delta
        pw[scatter] = a / (kr + 1.0)
        pw[off[:-1]] = kr / (kr + 1.0)
        k_db = np.full(n, p.k_db)
    else:
        counts, tau, pw = n_mpc, delta, a
        k_db = np.full(n, math.nan)
    return {
        "sf_db": sf,
        "ds_s": np.full(n, p.excess_delay_mean_s),
        "k_db": k_db,
        "counts": counts,
        "delays": tau,
        "fractions": pw,
    }


def _draw_awgn(p: AwgnCondition, sf_std: np.ndarray, rng) -> dict:
    """A single direct path per link."""
    n = sf_std.size
    return {
        "sf_db": sf_std * rng.standard_normal(n),
        "ds_s": np.zeros(n),
        "k_db": np.full(n, math.inf),
        "counts": np.ones(n, dtype=np.int64),
        "delays": np.zeros(n),
        "fractions": np.ones(n),
    }


def _draw_field(
    p: FieldCondition, d: np.ndarray, fc: float, h_tx: np.ndarray, h_rx: np.ndarray, rng
) -> dict:
    """Field model (:mod:`phyloc.channels.field`): direct path, ground reflection, specular
    paths of structures, diffuse rays; returns path-power fractions and the path loss [dB]
    ``−10·log10 Σ_l |a_l|²`` (no shadowing: the two-ray interference is the fading)."""
    n = d.size
    lam = C0 / fc
    k = 2.0 * math.pi / lam
    friis = lam / (4.0 * math.pi)
    a_dir = friis / np.maximum(d, D_FAR_FIELD_M)
    length, excess, psi = ground_reflection_geometry(d, h_tx, h_rx)
    eta = ground_permittivity(
        fc, p.permittivity_a, p.permittivity_b, p.conductivity_c_s_m, p.conductivity_d
    )
    gamma = fresnel_reflection(eta, psi, p.polarization)
    ks, nd = p.scatterer_count, p.diffuse_ray_count
    lo, hi = p.scatterer_excess_delay_s
    tau_s = rng.uniform(lo, hi, (n, ks))
    tau_d = rng.exponential(p.diffuse_delay_spread_s, (n, nd))
    n_paths = 2 + ks + nd
    tau = np.empty((n, n_paths))
    amp2 = np.empty((n, n_paths))
    prel = np.full((n, n_paths), math.nan)
    tau[:, 0] = 0.0
    amp2[:, 0] = a_dir**2
    prel[:, 0] = 0.0
    tau[:, 1] = excess / C0
    amp2[:, 1] = (np.abs(gamma) * friis / length) ** 2 if p.ground_reflection else 0.0
    prel[:, 1] = np.angle(gamma) - k * excess
    loss = 10.0 ** (-p.scatterer_reflection_loss_db / 10.0)
    tau[:, 2 : 2 + ks] = tau_s
    amp2[:, 2 : 2 + ks] = loss * (friis / (d[:, None] + C0 * tau_s)) ** 2
    tau[:, 2 + ks :] = tau_d
    if nd:
        ratio = 10.0 ** (p.diffuse_power_ratio_db / 10.0)
        amp2[:, 2 + ks :] = (ratio / nd) * (a_dir**2)[:, None]
    order = np.argsort(tau, axis=1, kind="stable")  # the direct path (τ = 0) stays first
    tau = np.take_along_axis(tau, order, axis=1)
    amp2 = np.take_along_axis(amp2, order, axis=1)
    prel = np.take_along_axis(prel, order, axis=1)
    total = amp2.sum(axis=1)
    with np.errstate(divide="ignore"):
        k_db = 10.0 * np.log10(amp2[:, 0] / amp2[:, 1:].sum(axis=1))
    return {
        "pl_db": -10.0 * np.log10(total),
        "sf_db": np.zeros(n),
        "ds_s": np.full(n, p.diffuse_delay_spread_s),
        "k_db": k_db,
        "counts": np.full(n, n_paths, dtype=np.int64),
        "delays": tau.ravel(),
        "fractions": (amp2 / total[:, None]).ravel(),
        "phase_rel": prel.ravel(),
    }


_DRAWERS = {
    Winner2Condition: _draw_winner2,
    ExponentialCondition: _draw_exponential,
    AwgnCondition: _draw_awgn,
    TdlCondition: draw_tdl,
}

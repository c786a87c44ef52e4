"""Realized channel statistics against the scenario tables (``phyloc channel-stats``).

:func:`channel_stats` draws links between points uniform in a square and compares what the
sampler produced with the numbers of the scenario file. Figure names (stable, part of the
public interface; a figure is omitted when its condition has no links in the draw):

================================  ===============================================================
``los_fraction``                  fraction of LOS links
``los_fraction_table``            mean of P_LOS(d) over the same distances
                                  (WINNER II D1.1.2 Table 4-7)
``ds_log10_mean_los``             mean of log10(DS / 1 s) over LOS links (the drawn LSP)
``ds_log10_std_los``              its std; ``*_nlos`` the same over NLOS links
``rms_ds_log10_mean_los``         mean of log10 of the rms delay spread of the generated paths
                                  (``*_nlos`` likewise); WINNER II does not make this equal DS
``k_factor_db_mean``              mean of the K-factor [dB] over LOS links
``k_factor_db_std``               its std
``sf_std_db_los``                 std of the shadow fading [dB] over LOS links (``*_nlos``)
``path_count_mean``               mean number of paths per link
``excess_delay_mean_s``           mean over links of the power-weighted mean of ``τ_l − d/c0`` [s]
                                  (includes the NLOS bias)
``nlos_bias_mean_s``              mean NLOS bias over NLOS links [s]
``distance_mean_m``               mean link distance [m]
``carrier_gain_db_median``        field model: median over links of the narrowband power at the
                                  carrier, ``|Σ_l α_l|²``, relative to the free-space power
                                  ``P_tx·(λ/(4π d))²`` [dB] (the two-ray fading)
``carrier_gain_db_p10``           its 10th percentile [dB]
``pdp_rms_delay_spread_s_los``    tdl model: RMS delay spread of the mean power-delay profile
                                  (path powers over the link budget, averaged over links) [s];
                                  table: the file's ``delay_spread_s`` (``*_nlos`` likewise)
``tap_power_db_max_dev_los``      tdl model: largest ``|10·log10(mean power / table power)|``
                                  over the taps [dB] (``*_nlos`` likewise)
``corr_ds_sf_los``                tr38901 model: correlation of log10 DS and SF (as a gain, the
                                  received power over the path loss) over LOS links;
                                  table: TR 38.901 Table 7.5-6 (``corr_ds_k``, ``corr_sf_k``:
                                  LOS only; ``corr_ds_sf_nlos``)
``cluster_count_mean_los``        tr38901 model: clusters per link after the removal of those
                                  25 dB below the strongest (before: the table's N)
================================  ===============================================================

Each figure with a table value has a twin ``<name>_table``. Table values: DS and K from
WINNER II D1.1.2 Table 4-5 (μ, σ); SF: ``sqrt(mean σ_SF(d)²)`` over the drawn links (the law's
segment std, WINNER II D1.1.2 Table 4-4); path count: the expected count given
``los_fraction_table``; NLOS bias: the file's mean. Series: ``distance_bin_m``,
``los_fraction_by_distance``, ``los_probability_by_distance``.

References
----------
WINNER II: IST-4-027756 WINNER II Deliverable D1.1.2 V1.2, Part I (channel models), 2007,
updated 2008; the table each value of the shipped channel files comes from is given in
``channels/PROVENANCE.md``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from phyloc import _validate as v
from phyloc.channels.sampler import ChannelDraw, draw_links
from phyloc.channels.scenario import (
    AwgnCondition,
    ExponentialCondition,
    FieldCondition,
    Winner2Condition,
    load_scenario,
)
from phyloc.channels.tdl import TdlCondition
from phyloc.channels.tr38901 import Tr38901Condition
from phyloc.errors import ValidationError
from phyloc.phy.system import C0, OFDMSystem
from phyloc.reporting import new_figure, save_figure


def square_pair_distances(n_links: int, side_m: float, rng: np.random.Generator) -> np.ndarray:
    """Distances between pairs of points drawn uniformly in a ``side_m × side_m`` square.

    Returns ``[n_links]`` float64 [m]; values below 1 mm (probability ~1e-10) are raised to
    1 mm so that every distance is > 0.
    """
    n = v.integer("n_links", n_links, minimum=1)
    side = v.positive("square_m", side_m)
    p = rng.uniform(0.0, side, (n, 2, 2))
    return np.maximum(np.hypot(*(p[:, 0] - p[:, 1]).T), 1e-3)


def _expected_paths(par) -> float:
    if isinstance(par, Winner2Condition):
        return float(par.paths_per_link)
    if isinstance(par, ExponentialCondition):
        return par.mean_path_count + (par.condition == "los")
    if isinstance(par, AwgnCondition):
        return 1.0
    if isinstance(par, FieldCondition | TdlCondition):
        return float(par.paths_per_link)
    return math.nan  # tr38901: the count varies with the removal of weak clusters


def _rms_ds_figure(put, rms, mask, cond) -> None:
    """``rms_ds_log10_mean_<cond>``: mean log10 of the links' path rms delay spreads (links of
    ``mask`` with a positive spread; none: no figure)."""
    ok = mask & (rms > 0)
    if ok.any():
        put(
            f"rms_ds_log10_mean_{cond}",
            f"log10 rms delay spread of paths [s] mean, {cond.upper()}",
            np.log10(rms[ok]).mean(),
        )


def channel_stats(
    scenario,
    *,
    square_m: float = 100.0,
    n_links: int = 20000,
    rng: np.random.Generator,
    system=None,
    png_path=None,
    h_tx_m: float = 1.5,
    h_rx_m: float = 1.5,
) -> dict:
    """Draw links in a square and compare realized statistics with the scenario tables.

    Parameters
    ----------
    scenario : str, os.PathLike or Scenario
        As for :func:`~phyloc.channels.draw_links`.
    square_m : float
        Side of the square the link end points are drawn in [m] (default 100 m, DiPNet §V-A).
    n_links : int
        Number of links (>= 1).
    rng : numpy.random.Generator
        Source of randomness.
    system : OFDMSystem, optional
        Carrier frequency and transmit power (default ``OFDMSystem()``).
    png_path : str or Path, optional
        If given, also write example power-delay profiles of this draw there
        (:func:`plot_power_delay_profiles`).
    h_tx_m, h_rx_m : float
        Antenna heights [m] of every link (default 1.5 m; the tr38901 laws use them).

    Returns
    -------
    dict
        ``{"figures": {name: float}, "series": {name: list}, "table": [(quantity, realized,
        table value or None), ...], "draw": ChannelDraw}`` (names: module docstring).
        Everything but ``"draw"`` (the links drawn, for :func:`plot_power_delay_profiles`)
        is plain Python and JSON-serializable.

    Examples
    --------
    >>> out = channel_stats("winner2_d1", n_links=2000, rng=np.random.default_rng(3))
    >>> 0.9 < out["figures"]["los_fraction"] <= 1.0
    True
    """
    scn = load_scenario(scenario)
    if not isinstance(rng, np.random.Generator):
        raise ValidationError("rng", type(rng).__name__, "a numpy.random.Generator")
    d = square_pair_distances(n_links, square_m, rng)
    draw = draw_links(scn, d, rng, system=system, h_tx_m=h_tx_m, h_rx_m=h_rx_m)
    h_bs, h_ut = max(h_tx_m, h_rx_m), min(h_tx_m, h_rx_m)
    fig: dict[str, float] = {}
    rows: list[tuple[str, float, float | None]] = []

    def put(name: str, label: str, realized, table=None):
        fig[name] = float(realized)
        if table is not None and np.isfinite(table):
            fig[name + "_table"] = float(table)
            rows.append((label, float(realized), float(table)))
        else:
            rows.append((label, float(realized), None))

    p_los = scn.p_los(d, h_bs, h_ut)
    put("distance_mean_m", "link distance mean [m]", d.mean())
    put("los_fraction", "LOS fraction", draw.los.mean(), p_los.mean())
    rms = draw.rms_delay_spread()
    for cond, mask in (("los", draw.los), ("nlos", ~draw.los)):
        if not mask.any():
            continue
        par = scn.params(cond)
        w2 = isinstance(par, Winner2Condition)
        ex = isinstance(par, ExponentialCondition)
        if w2 or ex:
            lg = np.log10(draw.delay_spread_s[mask])
            mu = par.ds_log10_mu if w2 else math.log10(par.excess_delay_mean_s)
            sd = par.ds_log10_sigma if w2 else 0.0
            put(f"ds_log10_mean_{cond}", f"log10 DS [s] mean, {cond.upper()}", lg.mean(), mu)
            put(
                f"ds_log10_std_{cond}",
                f"log10 DS [s] std, {cond.upper()}",
                lg.std(ddof=1) if mask.sum() > 1 else 0.0,
                sd,
            )
            _rms_ds_figure(put, rms, mask, cond)
        if isinstance(par, FieldCondition):
            _field_figures(put, draw, mask, rms, system)
        if isinstance(par, TdlCondition):
            _tdl_figures(put, draw, mask, rms, system, par)
        if isinstance(par, Tr38901Condition):
            _tr38901_figures(put, draw, mask, rms, system, par)
        sf = draw.shadowing_db[mask]
        put(
            f"sf_std_db_{cond}",
            f"shadow fading std [dB], {cond.upper()}",
            sf.std(ddof=1) if sf.size > 1 else 0.0,
            math.sqrt(np.mean(draw.shadowing_std_db[mask] ** 2)),
        )
        if cond == "los" and (w2 or ex):
            k = draw.k_factor_db[mask]
            put("k_factor_db_mean", "K-factor [dB] mean", k.mean(), par.k_db_mu if w2 else par.k_db)
            put(
                "k_factor_db_std",
                "K-factor [dB] std",
                k.std(ddof=1) if k.size > 1 else 0.0,
                par.k_db_sigma if w2 else 0.0,
            )
        if cond == "nlos":
            put(
                "nlos_bias_mean_s",
                "NLOS bias mean [s]",
                draw.nlos_bias_s[mask].mean(),
                par.nlos_bias_mean_s,
            )
    pf = float(p_los.mean())
    expected = 0.0
    for cond, weight in (("los", pf), ("nlos", 1.0 - pf)):
        if weight > 0:
            expected += weight * _expected_paths(scn.params(cond))
    put("path_count_mean", "paths per link mean", draw.paths.n_paths.mean(), expected)
    link = draw.paths.link_index()
    pw = np.abs(draw.paths.gains) ** 2
    mean_exc = np.bincount(link, pw * draw.excess_delays(), draw.n_links) / draw.received_power_w
    put("excess_delay_mean_s", "power-weighted excess delay mean [s]", mean_exc.mean())

    edges = np.linspace(0.0, float(d.max()) * (1 + 1e-12), 21)
    which = np.digitize(d, edges) - 1
    cnt = np.bincount(which, minlength=20)[:20]
    los_cnt = np.bincount(which, weights=draw.los.astype(float), minlength=20)[:20]
    centres = 0.5 * (edges[:-1] + edges[1:])
    keep = cnt > 0
    series = {
        "distance_bin_m": centres[keep].tolist(),
        "los_fraction_by_distance": (los_cnt[keep] / cnt[keep]).tolist(),
        "los_probability_by_distance": scn.p_los(centres[keep], h_bs, h_ut).tolist(),
    }
    if png_path is not None:
        plot_power_delay_profiles(draw, png_path)
    return {"figures": fig, "series": series, "table": rows, "draw": draw}


def _field_figures(put, draw: ChannelDraw, mask, rms, system) -> None:
    """Realized K-factor, rms delay spread and narrowband carrier gain of field-model links."""
    k = draw.k_factor_db[mask]
    put("k_factor_db_mean", "K-factor [dB] mean (direct / other paths)", k.mean())
    put("k_factor_db_std", "K-factor [dB] std", k.std(ddof=1) if k.size > 1 else 0.0)
    _rms_ds_figure(put, rms, mask, "los")
    system = OFDMSystem() if system is None else system
    lam = C0 / system.carrier_frequency_hz
    coherent = np.abs(np.add.reduceat(draw.paths.gains, draw.paths.offsets[:-1])) ** 2
    free = system.tx_power_w * (lam / (4.0 * math.pi * draw.distances_m)) ** 2
    gain_db = 10.0 * np.log10(coherent[mask] / free[mask])
    put("carrier_gain_db_median", "carrier power / free space [dB] median", np.median(gain_db))
    put(
        "carrier_gain_db_p10",
        "carrier power / free space [dB] 10th pct",
        np.percentile(gain_db, 10),
    )


def _tdl_figures(put, draw: ChannelDraw, mask, rms, system, par: TdlCondition) -> None:
    """Mean power-delay profile of tdl-model links against the file's taps (TR 38.901
    Sec. 7.7.2): its RMS delay spread, the tap powers and (LOS) the K-factor."""
    cond = par.condition
    system = OFDMSystem() if system is None else system
    budget = system.received_power_w(draw.path_loss_db + draw.shadowing_db)  # mean link power
    m = par.power_fractions.size
    rows = np.flatnonzero(mask)
    start = draw.paths.offsets[rows][:, None] + np.arange(m)
    q = (np.abs(draw.paths.gains[start]) ** 2 / budget[rows][:, None]).mean(axis=0)
    tau = par.excess_delays_s
    m1 = np.sum(q * tau) / q.sum()
    ds = math.sqrt(max(np.sum(q * tau * tau) / q.sum() - m1 * m1, 0.0))
    put(
        f"pdp_rms_delay_spread_s_{cond}",
        f"rms delay spread of the mean PDP [s], {cond.upper()}",
        ds,
        par.delay_spread_s,
    )
    dev = np.max(np.abs(10.0 * np.log10(q / par.power_fractions)))
    put(f"tap_power_db_max_dev_{cond}", f"tap power vs table, max |dev| [dB], {cond.upper()}", dev)
    _rms_ds_figure(put, rms, mask, cond)
    if cond == "los":
        los = par.is_los_path
        k = 10.0 * math.log10(q[los].sum() / q[~los].sum())
        put("k_factor_db_mean", "K-factor [dB] of the mean PDP (specular / Rayleigh)", k, par.k_db)


def _tr38901_figures(put, draw: ChannelDraw, mask, rms, system, par: Tr38901Condition) -> None:
    """Drawn LSPs of tr38901 links against TR 38.901 Table 7.5-6 at the system's carrier: log10
    DS mean and std, K-factor mean and std (LOS), the correlations of SF, K and log10 DS, and
    the cluster count after the removal of weak clusters."""
    cond = par.condition
    system = OFDMSystem() if system is None else system
    mu, sigma = par.ds_log10_params(system.carrier_frequency_hz)
    lg = np.log10(draw.delay_spread_s[mask])
    many = lg.size > 2
    up = cond.upper()
    put(f"ds_log10_mean_{cond}", f"log10 DS [s] mean, {up}", lg.mean(), mu)
    put(f"ds_log10_std_{cond}", f"log10 DS [s] std, {up}", lg.std(ddof=1) if many else 0.0, sigma)
    _rms_ds_figure(put, rms, mask, cond)
    sf = -draw.shadowing_db[mask]  # SF as a gain, as Table 7.5-6 correlates it
    corr = par.correlation  # [SF, K, DS] (LOS) or [SF, DS] (NLOS)

    def rho(a, b):
        return float(np.corrcoef(a, b)[0, 1]) if many else math.nan

    if cond == "los":
        k = draw.k_factor_db[mask]
        put("k_factor_db_mean", "K-factor [dB] mean", k.mean(), par.k_db_mu)
        put("k_factor_db_std", "K-factor [dB] std", k.std(ddof=1) if many else 0.0, par.k_db_sigma)
        put("corr_ds_sf_los", "corr(log10 DS, SF), LOS", rho(lg, sf), corr[0, 2])
        put("corr_ds_k", "corr(log10 DS, K), LOS", rho(lg, k), corr[1, 2])
        put("corr_sf_k", "corr(SF, K), LOS", rho(sf, k), corr[0, 1])
    else:
        put("corr_ds_sf_nlos", "corr(log10 DS, SF), NLOS", rho(lg, sf), corr[0, 1])
    extra = min(par.num_split, par.num_clusters) * (len(par.subcluster_offsets_c_ds) - 1)
    clusters = draw.paths.n_paths[mask] - extra - (cond == "los")
    put(
        f"cluster_count_mean_{cond}",
        f"clusters per link after the -{par.removal_threshold_db:g} dB removal, mean "
        f"(table N = {par.num_clusters}), {up}",
        clusters.mean(),
    )


def plot_power_delay_profiles(draw: ChannelDraw, path_png, n_examples: int = 6) -> Path:
    """Write a PNG with example power-delay profiles of a draw.

    One panel per link: path powers relative to the link's received power [dB] against the
    excess delay ``τ_l − d/c0`` [ns] (NLOS bias included, marked by a dashed line). Links are
    picked half LOS, half NLOS where both exist. Uses matplotlib's Agg canvas (no pyplot, no
    global backend change).

    Parameters
    ----------
    draw : ChannelDraw
    path_png : str or Path
        Output file.
    n_examples : int
        Number of panels (>= 1).

    Returns
    -------
    Path
        The file written.
    """
    n_ex = v.integer("n_examples", n_examples, minimum=1)
    los_idx = np.flatnonzero(draw.los)
    nlos_idx = np.flatnonzero(~draw.los)
    half = n_ex // 2
    picks = list(los_idx[: max(n_ex - min(half, nlos_idx.size), 0)])
    picks += list(nlos_idx[: n_ex - len(picks)])
    picks = picks[:n_ex]
    cols = min(3, max(len(picks), 1))
    rows = max(math.ceil(len(picks) / cols), 1)
    fig, axes = new_figure(rows, cols, squeeze=False, size=(4.2 * cols, 3.0 * rows))
    axes = axes.ravel()
    exc = draw.excess_delays()
    for ax, i in zip(axes, picks, strict=False):
        a, b = draw.paths.offsets[i], draw.paths.offsets[i + 1]
        p_db = 10 * np.log10(np.abs(draw.paths.gains[a:b]) ** 2 / draw.received_power_w[i])
        t_ns = exc[a:b] * 1e9
        color = "tab:blue" if draw.los[i] else "tab:red"
        ax.vlines(t_ns, -60.0, p_db, color=color, lw=1.2)
        ax.plot(t_ns, p_db, "o", ms=3, color=color)
        if not draw.los[i]:
            ax.axvline(draw.nlos_bias_s[i] * 1e9, ls="--", color="0.4", lw=0.8, label="bias b")
            ax.legend(loc="upper right", fontsize=7)
        ax.set_ylim(-50.0, 3.0)
        ax.set_xlabel("excess delay τ − d/c0 [ns]")
        ax.set_ylabel("power / P_rx [dB]")
        cond = "LOS" if draw.los[i] else "NLOS"
        ax.set_title(
            f"link {i}: d = {draw.distances_m[i]:.1f} m, {cond}, {b - a} paths", fontsize=9
        )
        ax.grid(alpha=0.3)
    for ax in axes[len(picks) :]:
        ax.set_visible(False)
    fig.suptitle(f"Power-delay profiles — {draw.scenario} ({draw.ranging})", fontsize=10)
    out = Path(path_png)
    save_figure(fig, out)
    return out


__all__ = ["channel_stats", "plot_power_delay_profiles", "square_pair_distances"]

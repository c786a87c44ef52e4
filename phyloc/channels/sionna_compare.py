"""phyloc's 3GPP TR 38.901 channels against NVIDIA Sionna's (``phyloc channel-compare``).

:func:`compare` draws the same links in both packages, at the same carrier, antenna heights and
3-D distances, and compares what they produce. Sionna is imported only here and only when a
comparison runs (``pip install sionna``, or ``pip install "phyloc[sionna]"``).

System-level scenarios (``tr38901_umi``, ``_uma``, ``_rma``, ``_inh_mixed``, ``_inh_open``,
``_inf_sl``, ``_inf_dl``, ``_inf_sh``, ``_inf_dh``) run through Sionna's ``UMi``, ``UMa``,
``RMa``, ``InH`` and ``InF`` channel classes with the V16.1 tables (``spec_version="16.1"``,
the release phyloc's files transcribe), one BS and one UT per batch example (so that Sionna's
spatially correlated LSPs are independent between links, as phyloc's are), a single
vertically polarized isotropic element at both ends (``antenna_pattern="omni"``: SISO, every
ray with unit field), outdoor UTs not in a car (UMi, UMa, RMa) or indoor UTs (InH, InF, as
Sionna requires), no spatial consistency, no blockage. Each link's 2-D distance ``d_2D`` is
drawn uniformly on the geometry's range (:data:`GEOMETRIES`), the BS stands at the origin at
height ``h_BS`` and the UT at ``d_2D`` in a random azimuth at height ``h_UT``; phyloc gets
``d_3D = sqrt(d_2D² + (h_BS − h_UT)²)`` and the heights as ``h_tx_m``, ``h_rx_m``. Three draws of
``n_links`` links each: the LOS state drawn by each package (LOS probability), then every link
forced LOS, then forced NLOS (the per-state statistics, paired in distance).

What is compared, per LOS state (Sionna's values from its ``LSP`` object, its ``Rays`` and its
channel impulse response ``a``, ``tau``):

* the tables at the drawn links (exact): path loss per link, σ_SF, μ and σ of lgDS, μ and σ of
  K, N, r_τ, ζ, c_DS, the LOS probability per link;
* large-scale draws (Monte Carlo): shadow fading as a power gain (phyloc's SF is a loss,
  ``P_rx = P_tx − PL − SF``; Sionna's multiplies the channel by ``sqrt(sf)``), log10 DS and K
  (mean, std, quantiles, two-sample Kolmogorov–Smirnov test), the correlations of SF, K and
  lgDS, the number of clusters left after the removal of those 25 dB below the strongest;
* the power-delay profile per link in two forms: the *mean-power PDP* (phyloc's paths, whose
  powers are the clusters' mean powers; Sionna's cluster powers and delays of step 6 split into
  the sub-clusters of step 11 with their ray fractions 10/20, 6/20, 4/20, and the specular ray
  K/(K+1)), and the *realized CIR* (phyloc's paths with equal delays added coherently; Sionna's
  ``|a|²``, whose clusters are sums of 20 rays with random phases): power-weighted mean excess
  delay and RMS delay spread of the paths (relative to the first path), the power share of the
  first path, the number of paths, the received power over ``P_tx − PL``;
* the mean excess delay of the first path over ``d/c0`` (phyloc's NLOS bias; Sionna's delays
  start at the first cluster).

TDL scenarios (``tdl_a`` … ``tdl_e``) run through Sionna's ``TDL`` with the file's delay spread
and no motion: tap delays (exact), the mean power of each tap, the RMS delay spread and
K-factor of the mean PDP, and per link the RMS delay spread of the paths, the first tap's power
share and the wideband gain.

Verdicts: a mean, standard deviation or correlation *agrees* if the difference is within
:data:`Z_CRIT` Monte Carlo standard errors (two-sided level :data:`ALPHA`); a distribution
agrees if the two-sample KS test does not reject at :data:`ALPHA`; a table value agrees if it
is equal to within :data:`EXACT_TOL` (relative) or, for path loss, :data:`PATHLOSS_TOL_DB`.

References
----------
3GPP TR 38.901, "Study on channel model for frequencies from 0.5 to 100 GHz," Sec. 7.4
(Tables 7.4.1-1 path loss, 7.4.2-1 LOS probability), Sec. 7.5 steps 4–6, 10 and 11 (Tables 7.5-5,
7.5-6), Sec. 7.7.2–7.7.3 (TDL); the tables as in V16.1.

NVIDIA Sionna 2.2 (GitHub NVlabs/sionna), ``sionna.phy.channel.tr38901``: ``UMi``, ``UMa``,
``RMa``, ``InH``, ``InF`` (``SystemLevelChannel``, ``LSPGenerator``, ``RaysGenerator``,
``ChannelCoefficientsGenerator``) and ``TDL``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import stats

from phyloc import _validate as v
from phyloc.channels.sampler import draw_links
from phyloc.channels.scenario import load_scenario
from phyloc.errors import PhylocError, ValidationError
from phyloc.phy.system import OFDMSystem

#: How to install the comparison's one optional dependency.
INSTALL = 'pip install sionna (or pip install "phyloc[sionna]")'
#: Two-sided level of every Monte Carlo test.
ALPHA = 1e-3
#: Critical ``|z|`` at :data:`ALPHA` (two-sided).
Z_CRIT = float(stats.norm.isf(ALPHA / 2))
#: Relative tolerance of the table values (both packages evaluate the same formula).
EXACT_TOL = 1e-6
#: Tolerance of the per-link path loss [dB]: Sionna's breakpoint uses c = 299 792 458 m/s,
#: phyloc's the 3·10⁸ m/s of Table 7.4.1-1 note 1 (at most a few thousandths of a dB).
PATHLOSS_TOL_DB = 0.05
#: Default carrier [Hz].
DEFAULT_CARRIER_HZ = 3.5e9
#: Quantile levels stored for the figures.
CDF_LEVELS = np.linspace(0.0, 1.0, 41)
#: Sionna's sub-clusters (TR 38.901 Table 7.5-5): delay offsets in c_DS and ray fractions.
SUBCLUSTER_OFFSETS = (0.0, 1.28, 2.56)
SUBCLUSTER_FRACTIONS = (10 / 20, 6 / 20, 4 / 20)
#: Links per Sionna call (memory: 20 rays × N clusters complex numbers per link and tensor).
CHUNK = 2000


@dataclass(frozen=True)
class Geometry:
    """How one phyloc scenario is drawn in Sionna.

    Attributes
    ----------
    sionna : str
        Sionna's class: ``"UMi"``, ``"UMa"``, ``"RMa"``, ``"InH"``, ``"InF"`` or ``"TDL"``.
    option : str or None
        ``indoor_scenario`` (InH), ``factory_scenario`` (InF) or ``model`` (TDL).
    h_bs_m, h_ut_m : float
        Antenna heights [m] (the TR's evaluation defaults; InF-SH/DH: an 8 m BS).
    d2d_range_m : (float, float)
        Range of the uniform 2-D distances [m].
    """

    sionna: str
    option: str | None
    h_bs_m: float
    h_ut_m: float
    d2d_range_m: tuple[float, float]


#: The scenarios :func:`compare` knows, by phyloc name.
GEOMETRIES: dict[str, Geometry] = {
    "tr38901_umi": Geometry("UMi", None, 10.0, 1.5, (10.0, 500.0)),
    "tr38901_uma": Geometry("UMa", None, 25.0, 1.5, (10.0, 1000.0)),
    "tr38901_rma": Geometry("RMa", None, 35.0, 1.5, (10.0, 5000.0)),
    "tr38901_inh_mixed": Geometry("InH", "mixed", 3.0, 1.0, (1.0, 100.0)),
    "tr38901_inh_open": Geometry("InH", "open", 3.0, 1.0, (1.0, 100.0)),
    "tr38901_inf_sl": Geometry("InF", "SL", 1.5, 1.5, (1.0, 100.0)),
    "tr38901_inf_dl": Geometry("InF", "DL", 1.5, 1.5, (1.0, 100.0)),
    "tr38901_inf_sh": Geometry("InF", "SH", 8.0, 1.5, (1.0, 100.0)),
    "tr38901_inf_dh": Geometry("InF", "DH", 8.0, 1.5, (1.0, 100.0)),
    "tdl_a": Geometry("TDL", "A", 1.5, 1.5, (10.0, 100.0)),
    "tdl_b": Geometry("TDL", "B", 1.5, 1.5, (10.0, 100.0)),
    "tdl_c": Geometry("TDL", "C", 1.5, 1.5, (10.0, 100.0)),
    "tdl_d": Geometry("TDL", "D", 1.5, 1.5, (10.0, 100.0)),
    "tdl_e": Geometry("TDL", "E", 1.5, 1.5, (10.0, 100.0)),
}


def sionna_available() -> bool:
    """True if Sionna's TR 38.901 channels can be imported."""
    try:
        _sionna()
    except PhylocError:
        return False
    return True


def require_sionna() -> None:
    """Raise :class:`~phyloc.errors.PhylocError` (one line naming ``pip install sionna``) if
    Sionna cannot be imported."""
    _sionna()


def check_arguments(scenarios, n_links: int, carrier_frequency_hz: float) -> list[str]:
    """Validate a comparison's arguments before any work; returns the scenario names
    (``"all"`` expands to every name of :data:`GEOMETRIES`).

    Raises :class:`~phyloc.errors.ValidationError` for an unknown scenario, fewer than 100
    links or a carrier outside a scenario file's validity range.
    """
    names: list[str] = []
    for name in scenarios:
        names += list(GEOMETRIES) if name == "all" else [name]
    for name in names:
        if name not in GEOMETRIES:
            raise ValidationError("SCENARIO", name, "'all' or one of " + ", ".join(GEOMETRIES))
    v.integer("--links", n_links, minimum=100)
    fc = v.positive("--carrier-frequency-hz", carrier_frequency_hz)
    for name in names:
        try:
            load_scenario(name).check_frequency(fc)
        except ValidationError as exc:
            raise ValidationError("--carrier-frequency-hz", fc, exc.allowed) from None
    return list(dict.fromkeys(names))


def _sionna():
    """``(sionna.phy.config, sionna.phy.channel.tr38901, torch)``; a one-line error without
    Sionna."""
    try:
        import torch
        from sionna.phy import config
        from sionna.phy.channel import tr38901
    except ImportError as exc:
        raise PhylocError(
            f"phyloc channel-compare needs NVIDIA Sionna ({exc.name or exc}): {INSTALL}"
        ) from None
    return config, tr38901, torch


def _versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for pkg in ("phyloc", "sionna", "torch", "numpy", "scipy"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    return out


# ---------------------------------------------------------------------------------------------
# Per-link statistics of a set of paths (flat arrays with a link index)
def merge_equal_delays(link, delay, gain):
    """Add the complex gains of paths of one link that arrive at the same delay.

    Parameters
    ----------
    link : [n_paths] int
        Link of each path.
    delay : [n_paths] float
        Delay of each path [s].
    gain : [n_paths] complex or float
        Complex gains (coherent sum) or powers (incoherent sum).

    Returns
    -------
    link, delay, gain : arrays
        One entry per distinct ``(link, delay)``, sorted by link and delay.
    """
    link = np.asarray(link)
    delay = np.asarray(delay, dtype=np.float64)
    gain = np.asarray(gain)
    if link.size == 0:
        return link, delay, gain
    order = np.lexsort((delay, link))
    lk, dl, g = link[order], delay[order], gain[order]
    new = np.ones(lk.size, dtype=bool)
    new[1:] = (lk[1:] != lk[:-1]) | (dl[1:] != dl[:-1])
    group = np.cumsum(new) - 1
    m = int(group[-1]) + 1
    if np.iscomplexobj(g):
        out = np.bincount(group, g.real, m) + 1j * np.bincount(group, g.imag, m)
    else:
        out = np.bincount(group, g, m)
    return lk[new], dl[new], out


def pdp_statistics(link, delay, power, n_links: int) -> dict:
    """Per-link statistics of a power-delay profile given as paths.

    Parameters
    ----------
    link : [n_paths] int
        Link of each path (0 … ``n_links`` − 1).
    delay : [n_paths] float
        Path delays [s] (any reference: each link's are taken relative to its first path).
    power : [n_paths] float
        Path powers (>= 0; paths of zero power are ignored).
    n_links : int

    Returns
    -------
    dict of [n_links] arrays
        ``power`` (total), ``mean_delay_s`` (power-weighted mean excess delay over the first
        path), ``rms_delay_s`` (RMS delay spread of the paths), ``first_share`` (power of the
        paths at the first delay over the total), ``n_paths`` (paths of non-zero power).

    Examples
    --------
    >>> s = pdp_statistics([0, 0], [1e-6, 2e-6], [1.0, 1.0], 1)
    >>> round(float(s["mean_delay_s"][0]) * 1e9, 3), round(float(s["rms_delay_s"][0]) * 1e9, 3)
    (500.0, 500.0)
    """
    link = np.asarray(link, dtype=np.int64)
    delay = np.asarray(delay, dtype=np.float64)
    power = np.asarray(power, dtype=np.float64)
    ok = power > 0
    link, delay, power = link[ok], delay[ok], power[ok]
    first = np.full(n_links, np.inf)
    np.minimum.at(first, link, delay)
    t = delay - first[link]
    tot = np.bincount(link, power, n_links)
    with np.errstate(invalid="ignore", divide="ignore"):
        m1 = np.bincount(link, power * t, n_links) / tot
        m2 = np.bincount(link, power * (t - m1[link]) ** 2, n_links) / tot
        share = np.bincount(link, power * (t == 0.0), n_links) / tot
    return {
        "power": tot,
        "mean_delay_s": m1,
        "rms_delay_s": np.sqrt(np.maximum(m2, 0.0)),
        "first_share": share,
        "n_paths": np.bincount(link, minlength=n_links).astype(np.float64),
    }


def _cluster_counts(paths_without_los, num_split: int, extra_per_split: int) -> np.ndarray:
    """Clusters behind a path count: ``c`` clusters give ``c + extra·min(c, num_split)`` paths."""
    m = np.asarray(paths_without_los, dtype=np.int64)
    full = num_split * (1 + extra_per_split)
    return np.where(m >= full, m - num_split * extra_per_split, m // (1 + extra_per_split))


# ---------------------------------------------------------------------------------------------
# The two packages' draws
def _link_distances(geom: Geometry, n: int, rng: np.random.Generator):
    lo, hi = geom.d2d_range_m
    d2 = rng.uniform(lo, hi, n)
    az = rng.uniform(0.0, 2.0 * math.pi, n)
    return d2, az, np.hypot(d2, geom.h_bs_m - geom.h_ut_m)


def draw_phyloc(scenario: str, d3d_m, condition, fc_hz: float, geom: Geometry, rng) -> dict:
    """Draw links in phyloc (:func:`~phyloc.channels.draw_links`) and return per-link arrays.

    Parameters
    ----------
    scenario : str
        phyloc scenario name.
    d3d_m : [n] float
        3-D link distances [m].
    condition : {None, "los", "nlos"}
        Forced state, or None to draw it from P_LOS.
    fc_hz : float
        Carrier frequency [Hz].
    geom : Geometry
        Heights.
    rng : numpy.random.Generator

    Returns
    -------
    dict
        ``los``, ``p_los`` and, for forced draws, the table values, the large-scale draws and
        the mean-power and realized PDP statistics (see the module docstring).
    """
    system = OFDMSystem(carrier_frequency_hz=fc_hz)
    scn = load_scenario(scenario)
    d = np.asarray(d3d_m, dtype=np.float64)
    dr = draw_links(
        scn, d, rng, system=system, condition=condition, h_tx_m=geom.h_bs_m, h_rx_m=geom.h_ut_m
    )
    out = {"los": dr.los.copy(), "p_los": scn.p_los(d, geom.h_bs_m, geom.h_ut_m)}
    if condition is None and scn.model != "tdl":
        return out
    n = d.size
    cond = "los" if dr.los.all() else "nlos"
    par = scn.params(cond)
    link = dr.paths.link_index()
    gains = dr.paths.gains
    excess = dr.excess_delays()
    out["first_excess_s"] = excess[dr.paths.offsets[:-1]]
    if scn.model == "tdl":
        budget = system.received_power_w(dr.path_loss_db + dr.shadowing_db)
        out["tap_delays_s"] = np.asarray(par.excess_delays_s, dtype=np.float64)
        m = out["tap_delays_s"].size
        rows = dr.paths.offsets[:-1][:, None] + np.arange(m)
        out["tap_power"] = np.abs(gains[rows]) ** 2 / budget[:, None]
        out["tap_is_los"] = np.asarray(par.is_los_path, dtype=bool)
        out["file_delay_spread_s"] = float(par.delay_spread_s)
        lk, dl, g = merge_equal_delays(link, excess, gains)
        real = pdp_statistics(lk, dl, np.abs(g) ** 2 / budget[lk], n)
        out["real"] = real
        out["gain_db"] = 10.0 * np.log10(real["power"])
        return out
    mu, sigma = par.ds_log10_params(fc_hz)
    out["table"] = {
        "sf_std_db": dr.shadowing_std_db,
        "ds_mu": np.full(n, mu),
        "ds_sigma": np.full(n, sigma),
        "k_mu": np.full(n, par.k_db_mu),
        "k_sigma": np.full(n, par.k_db_sigma),
        "num_clusters": np.full(n, float(par.num_clusters)),
        "r_tau": np.full(n, par.r_tau),
        "zeta_db": np.full(n, par.cluster_shadowing_std_db),
        "c_ds_ns": np.full(n, par.c_ds_s(fc_hz) * 1e9),
    }
    out["pl_db"] = dr.path_loss_db
    out["sf_gain_db"] = -dr.shadowing_db
    out["lgds"] = np.log10(dr.delay_spread_s)
    out["k_db"] = dr.k_factor_db
    power = np.abs(gains) ** 2
    lk, dl, p = merge_equal_delays(link, excess, power)
    out["mean"] = pdp_statistics(lk, dl, p, n)
    budget = system.received_power_w(dr.path_loss_db + dr.shadowing_db)
    out["kept_db"] = 10.0 * np.log10(out["mean"]["power"] / budget)
    lk, dl, g = merge_equal_delays(link, excess, gains)
    out["real"] = pdp_statistics(lk, dl, np.abs(g) ** 2, n)
    p_tx = system.tx_power_w
    out["gain_db"] = 10.0 * np.log10(out["real"]["power"] / p_tx) + dr.path_loss_db
    extra = len(par.subcluster_offsets_c_ds) - 1
    out["clusters"] = _cluster_counts(
        dr.paths.n_paths - (cond == "los"), min(par.num_split, par.num_clusters), extra
    ).astype(np.float64)
    return out


def _make_sionna_channel(geom: Geometry, fc_hz: float):
    _, tr, _ = _sionna()
    kw = {"precision": "double", "device": "cpu"}
    ant = tr.Antenna(
        polarization="single",
        polarization_type="V",
        antenna_pattern="omni",
        carrier_frequency=fc_hz,
        **kw,
    )
    common = {
        "carrier_frequency": fc_hz,
        "ut_array": ant,
        "bs_array": ant,
        "direction": "downlink",
        "spec_version": "16.1",
        **kw,
    }
    if geom.sionna in ("UMi", "UMa"):
        cls = tr.UMi if geom.sionna == "UMi" else tr.UMa
        return cls(o2i_model="low", **common)
    if geom.sionna == "RMa":
        return tr.RMa(**common)
    if geom.sionna == "InH":
        return tr.InH(indoor_scenario=geom.option, **common)
    if geom.sionna == "InF":
        return tr.InF(factory_scenario=geom.option, **common)
    raise ValidationError("geometry", geom.sionna, "UMi, UMa, RMa, InH or InF")  # pragma: no cover


def _sionna_mean_pdp(rays, lsp, c_ds_s, los: np.ndarray):
    """Sionna's mean-power PDP (flat paths) from its step-6 clusters: the two strongest split
    into the sub-clusters of step 11 with their ray fractions, LOS scaled by 1/(K+1) plus the
    specular ray K/(K+1) at delay 0."""
    p = rays.powers.numpy()[:, 0, 0, :].copy()
    t = rays.delays.numpy()[:, 0, 0, :].copy()
    top = rays.strongest_cluster_indices.numpy()[:, 0, 0, :]
    k = lsp.k_factor.numpy()[:, 0, 0]
    n = p.shape[0]
    scale = np.where(los, 1.0 / (k + 1.0), 1.0)
    p *= scale[:, None]
    rows = np.arange(n)[:, None]
    ps, ts = p[rows, top], t[rows, top]
    p[rows, top] = ps * SUBCLUSTER_FRACTIONS[0]
    fr = np.asarray(SUBCLUSTER_FRACTIONS[1:])
    off = np.asarray(SUBCLUSTER_OFFSETS[1:])
    extra_p = (ps[:, :, None] * fr).reshape(n, -1)
    extra_t = (ts[:, :, None] + off * c_ds_s[:, None, None]).reshape(n, -1)
    spec_p = np.where(los, k / (k + 1.0), 0.0)[:, None]
    allp = np.hstack([spec_p, p, extra_p])
    allt = np.hstack([np.zeros((n, 1)), t, extra_t])
    link = np.repeat(np.arange(n), allp.shape[1])
    return link, allt.ravel(), allp.ravel()


def draw_sionna(geom: Geometry, d2d_m, azimuth_rad, condition, fc_hz: float) -> dict:
    """Draw links in Sionna (its randomness from ``sionna.phy.config.seed``, set by
    :func:`compare`) and return the per-link arrays of :func:`draw_phyloc`.

    Parameters
    ----------
    geom : Geometry
        Sionna class, heights.
    d2d_m, azimuth_rad : [n] float
        UT position around the BS: 2-D distance [m] and azimuth [rad].
    condition : {None, "los", "nlos"}
        Forced state (Sionna's ``los=True/False``) or None (``"random"``).
    fc_hz : float
        Carrier frequency [Hz].

    Returns
    -------
    dict
        As :func:`draw_phyloc`, plus ``d3d_m`` (Sionna's 3-D distances).
    """
    _, _, torch = _sionna()
    d2d_m = np.asarray(d2d_m, dtype=np.float64)
    if geom.sionna == "TDL":
        return _draw_sionna_tdl(geom, d2d_m.size, fc_hz)
    ch = _make_sionna_channel(geom, fc_hz)
    indoor = geom.sionna in ("InH", "InF")
    los_arg = {None: "random", "los": True, "nlos": False}[condition]
    parts: dict[str, list] = {}

    def put(key, value):
        parts.setdefault(key, []).append(value)

    for lo in range(0, d2d_m.size, CHUNK):
        sl = slice(lo, lo + CHUNK)
        d2, az = d2d_m[sl], np.asarray(azimuth_rad, dtype=np.float64)[sl]
        b = d2.size
        ut = np.zeros((b, 1, 3))
        ut[:, 0, 0], ut[:, 0, 1], ut[:, 0, 2] = d2 * np.cos(az), d2 * np.sin(az), geom.h_ut_m
        bs = np.zeros((b, 1, 3))
        bs[:, 0, 2] = geom.h_bs_m
        zeros = torch.zeros((b, 1, 3), dtype=torch.float64)
        kw = {}
        if geom.sionna == "RMa":
            kw["in_car"] = torch.zeros((b, 1), dtype=torch.bool)
        ch.reset_topology()
        ch.set_topology(
            torch.from_numpy(ut),
            torch.from_numpy(bs),
            zeros,
            zeros,
            zeros,
            torch.full((b, 1), indoor, dtype=torch.bool),
            los=los_arg,
            **kw,
        )
        scn = ch._scenario  # the topology's scenario (Sionna keeps it private)
        los = scn.los.numpy()[:, 0, 0].copy()
        put("los", los)
        put("p_los", scn.los_probability.numpy()[:, 0, 0].copy())
        put("d3d_m", scn.distance_3d.numpy()[:, 0, 0].copy())
        if condition is None:
            continue
        ch.return_rays = True
        a, tau, rays = ch(1, 1.0)
        lsp = ch._lsp  # the LSPs this CIR was drawn with (cached by set_topology)
        mean_log = scn.lsp_log_mean.numpy()[:, 0, 0, :]
        std_log = scn.lsp_log_std.numpy()[:, 0, 0, :]
        n_cl = scn.num_clusters_los if condition == "los" else scn.num_clusters_nlos
        c_ds = scn.get_param("cDS").numpy()[:, 0, 0]
        put("table.sf_std_db", 10.0 * std_log[:, 3])
        put("table.ds_mu", mean_log[:, 0])
        put("table.ds_sigma", std_log[:, 0])
        put("table.k_mu", np.where(los, 10.0 * mean_log[:, 4], np.nan))
        put("table.k_sigma", np.where(los, 10.0 * std_log[:, 4], np.nan))
        put("table.num_clusters", np.full(b, float(n_cl)))
        put("table.r_tau", scn.get_param("rTau").numpy()[:, 0, 0])
        put("table.zeta_db", scn.get_param("zeta").numpy()[:, 0, 0])
        put("table.c_ds_ns", c_ds)
        put("pl_db", lsp.pathloss.numpy()[:, 0, 0].copy())
        put("sf_gain_db", 10.0 * np.log10(lsp.sf.numpy()[:, 0, 0]))
        put("lgds", np.log10(lsp.ds.numpy()[:, 0, 0]))
        put("k_db", np.where(los, 10.0 * np.log10(lsp.k_factor.numpy()[:, 0, 0]), np.nan))
        put("clusters", (rays.powers.numpy()[:, 0, 0, :] > 0).sum(axis=1).astype(np.float64))
        lk, dl, pw = merge_equal_delays(*_sionna_mean_pdp(rays, lsp, c_ds * 1e-9, los))
        mean = pdp_statistics(lk, dl, pw, b)
        put("kept_db", 10.0 * np.log10(mean["power"]))
        h = a.numpy()[:, 0, 0, 0, 0, :, 0]
        t = tau.numpy()[:, 0, 0, :]
        lk, dl, g = merge_equal_delays(np.repeat(np.arange(b), h.shape[1]), t.ravel(), h.ravel())
        real = pdp_statistics(lk, dl, np.abs(g) ** 2, b)
        for key, val in mean.items():
            put("mean." + key, val)
        for key, val in real.items():
            put("real." + key, val)
        put("gain_db", 10.0 * np.log10(real["power"]) + lsp.pathloss.numpy()[:, 0, 0])
        put("first_excess_s", np.zeros(b))
    out: dict = {}
    for key, vals in parts.items():
        arr = np.concatenate(vals)
        head, _, tail = key.partition(".")
        if tail:
            out.setdefault(head, {})[tail] = arr
        else:
            out[key] = arr
    return out


def _draw_sionna_tdl(geom: Geometry, n: int, fc_hz: float) -> dict:
    _, tr, _ = _sionna()
    scn = load_scenario(f"tdl_{geom.option.lower()}")
    par = scn.params("los" if scn.los is not None else "nlos")
    model = tr.TDL(
        model=geom.option,
        delay_spread=par.delay_spread_s,
        carrier_frequency=fc_hz,
        min_speed=0.0,
        precision="double",
        device="cpu",
        spec_version="16.1",
    )
    taps, real_parts = [], []
    delays = None
    for lo in range(0, n, CHUNK):
        b = min(CHUNK, n - lo)
        a, tau = model(b, 1, 1.0)
        h = a.numpy()[:, 0, 0, 0, 0, :, 0]
        delays = tau.numpy()[0, 0, 0, :].copy()
        taps.append(np.abs(h) ** 2)
        lk = np.repeat(np.arange(b), h.shape[1])
        t = np.broadcast_to(delays, h.shape).ravel()
        lk, t, g = merge_equal_delays(lk, t, h.ravel())
        real_parts.append(pdp_statistics(lk, t, np.abs(g) ** 2, b))
    real = {k: np.concatenate([r[k] for r in real_parts]) for k in real_parts[0]}
    return {
        "los": np.full(n, bool(model.los)),
        "tap_delays_s": delays,
        "tap_power": np.vstack(taps),
        "tap_specular_power": float(model.mean_power_los) if model.los else 0.0,
        "real": real,
        "gain_db": 10.0 * np.log10(real["power"]),
        "first_excess_s": np.zeros(n),
    }


# ---------------------------------------------------------------------------------------------
# Rows of the comparison
def _row(key, label, a, b, test, tolerance=None, p_value=None, agrees=None, note="") -> dict:
    diff = None
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        diff = float(a) - float(b)
    verdict = "—" if agrees is None else ("agrees" if agrees else "DIFFERS")
    return {
        "key": key,
        "statistic": label,
        "phyloc": a,
        "sionna": b,
        "difference": diff,
        "test": test,
        "tolerance": tolerance,
        "p_value": p_value,
        "verdict": verdict,
        "note": note,
    }


def _p_of_z(z: float) -> float:
    return float(math.erfc(abs(z) / math.sqrt(2.0))) if np.isfinite(z) else 0.0


def _mean_row(key, label, a, b, note="") -> dict:
    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    ma, mb = float(a.mean()), float(b.mean())
    se = math.sqrt(a.var(ddof=1) / a.size + b.var(ddof=1) / b.size)
    if se == 0.0:
        same = ma == mb
        return _row(key, label, ma, mb, "exact", 0.0, None, same, note)
    z = (ma - mb) / se
    return _row(key, label, ma, mb, "z", Z_CRIT * se, _p_of_z(z), abs(z) <= Z_CRIT, note)


def _std_se(x: np.ndarray) -> float:
    """Standard error of the sample std (any distribution: (m4 − s⁴)/(4 s² n))."""
    s2 = x.var(ddof=1)
    if s2 == 0:
        return 0.0
    m4 = np.mean((x - x.mean()) ** 4)
    return math.sqrt(max(m4 - s2 * s2, 0.0) / (4.0 * s2 * x.size))


def _std_row(key, label, a, b, note="") -> dict:
    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    sa, sb = float(a.std(ddof=1)), float(b.std(ddof=1))
    se = math.hypot(_std_se(a), _std_se(b))
    if se == 0.0:
        return _row(key, label, sa, sb, "exact", 0.0, None, sa == sb, note)
    z = (sa - sb) / se
    return _row(key, label, sa, sb, "z", Z_CRIT * se, _p_of_z(z), abs(z) <= Z_CRIT, note)


def _corr_row(key, label, xa, ya, xb, yb, note="") -> dict:
    ra = float(np.corrcoef(xa, ya)[0, 1])
    rb = float(np.corrcoef(xb, yb)[0, 1])
    se = math.sqrt(1.0 / (len(xa) - 3) + 1.0 / (len(xb) - 3))
    z = (math.atanh(ra) - math.atanh(rb)) / se
    tol = Z_CRIT * se * (1.0 - ((ra + rb) / 2) ** 2)  # in r units, to first order
    return _row(key, label, ra, rb, "fisher z", tol, _p_of_z(z), abs(z) <= Z_CRIT, note)


def _realized_rows(pr: dict, sr: dict, what: str, first: str) -> list:
    """The two KS rows of a realized impulse response: the RMS delay spread of its paths and
    the power share of its first path (``first``: "path" or "tap")."""
    return [
        _ks_row(
            "real.rms_delay",
            f"{what}: RMS delay spread of paths [ns], KS",
            pr["rms_delay_s"],
            sr["rms_delay_s"],
            1e9,
        ),
        _ks_row(
            "real.first_share",
            f"{what}: power share of the first {first}, KS",
            pr["first_share"],
            sr["first_share"],
        ),
    ]


def _ks_row(key, label, a, b, scale=1.0, note="") -> dict:
    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    res = stats.ks_2samp(a, b)
    qa = [float(q) * scale for q in np.quantile(a, (0.1, 0.5, 0.9))]
    qb = [float(q) * scale for q in np.quantile(b, (0.1, 0.5, 0.9))]
    row = _row(key, label, qa, qb, "KS", None, float(res.pvalue), res.pvalue >= ALPHA, note)
    row["ks_statistic"] = float(res.statistic)
    return row


def _exact_row(key, label, a, b, tol=EXACT_TOL, absolute=False, note="") -> dict:
    a, b = np.asarray(a, float), np.asarray(b, float)
    both = np.isfinite(a) & np.isfinite(b)
    if not both.any():
        return _row(key, label, None, None, "exact", None, None, None, note)
    dev = np.abs(a[both] - b[both])
    if not absolute:
        dev = dev / np.maximum(np.abs(b[both]), 1e-300)
    worst = int(np.argmax(dev))
    ok = bool(dev[worst] <= tol) and bool(np.all(np.isfinite(a) == np.isfinite(b)))
    row = _row(key, label, float(a[both][worst]), float(b[both][worst]), "exact", tol, None, ok)
    row["max_deviation"] = float(dev[worst])
    row["note"] = note or (
        "largest " + ("|difference|" if absolute else "relative difference") + " over the links"
    )
    return row


def _quantiles(x) -> list:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return np.quantile(x, CDF_LEVELS).tolist() if x.size else []


# ---------------------------------------------------------------------------------------------
def _los_probability(geom, d2d, ph, si) -> tuple[list, dict]:
    """Rows and series of the LOS-probability comparison (10 bins of d_2D)."""
    lo, hi = geom.d2d_range_m
    edges = np.linspace(lo, hi, 11)
    which = np.clip(np.digitize(d2d, edges) - 1, 0, 9)
    n = np.bincount(which, minlength=10).astype(float)
    k1 = np.bincount(which, ph["los"].astype(float), 10)
    k2 = np.bincount(which, si["los"].astype(float), 10)
    law = np.bincount(which, ph["p_los"], 10) / np.maximum(n, 1)
    pooled = (k1 + k2) / np.maximum(2 * n, 1)
    se = np.sqrt(pooled * (1 - pooled) * 2 / np.maximum(n, 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(se > 0, (k1 - k2) / np.maximum(n, 1) / np.where(se > 0, se, 1), 0.0)
    df = int(np.sum(se > 0))
    chi2 = float(np.sum(z**2))
    p = float(stats.chi2.sf(chi2, df)) if df else 1.0
    rows = [
        _exact_row(
            "p_los_law",
            "P_LOS(d_2D) of the table at every link",
            ph["p_los"],
            si["p_los"],
            tol=1e-9,
            absolute=True,
        ),
        _mean_row("p_los_fraction", "LOS fraction of the drawn states", ph["los"], si["los"]),
    ]
    worst = int(np.argmax(np.abs(z)))
    rows.append(
        _row(
            "p_los_bins",
            f"LOS fraction in 10 bins of d_2D (χ² over {df} bins; worst bin "
            f"{edges[worst]:.0f}–{edges[worst + 1]:.0f} m)",
            float(k1[worst] / max(n[worst], 1)),
            float(k2[worst] / max(n[worst], 1)),
            "χ²",
            Z_CRIT,
            p,
            p >= ALPHA and bool(np.all(np.abs(z) <= Z_CRIT)),
            note=f"max |z| = {np.max(np.abs(z)):.2f} per bin",
        )
    )
    series = {
        "bin_center_m": (0.5 * (edges[:-1] + edges[1:])).tolist(),
        "links": n.tolist(),
        "los_fraction_phyloc": (k1 / np.maximum(n, 1)).tolist(),
        "los_fraction_sionna": (k2 / np.maximum(n, 1)).tolist(),
        "p_los_law": law.tolist(),
        "z": z.tolist(),
    }
    return rows, series


def _state_rows(cond: str, ph: dict, si: dict, scn) -> tuple[list, dict]:
    """The rows of one forced LOS state of a system-level scenario, and its figure series."""
    rows = []
    # the tables
    ph_pl, si_pl = ph["pl_db"], si["pl_db"]
    rows.append(
        _exact_row(
            "pl_db", "path loss per link [dB]", ph_pl, si_pl, tol=PATHLOSS_TOL_DB, absolute=True
        )
    )
    labels = {
        "sf_std_db": "σ_SF of the table [dB]",
        "ds_mu": "μ_lgDS of the table",
        "ds_sigma": "σ_lgDS of the table",
        "k_mu": "μ_K of the table [dB]",
        "k_sigma": "σ_K of the table [dB]",
        "num_clusters": "N clusters of the table",
        "r_tau": "r_τ of the table",
        "zeta_db": "ζ of the table [dB]",
        "c_ds_ns": "c_DS [ns]",
    }
    for key, label in labels.items():
        if cond == "nlos" and key.startswith("k_"):
            continue
        rows.append(_exact_row("table." + key, label, ph["table"][key], si["table"][key]))
    # large-scale draws
    rows.append(_mean_row("sf_mean", "SF as a gain: mean [dB]", ph["sf_gain_db"], si["sf_gain_db"]))
    rows.append(_std_row("sf_std", "SF: std [dB]", ph["sf_gain_db"], si["sf_gain_db"]))
    rows.append(_mean_row("lgds_mean", "log10 DS [s]: mean", ph["lgds"], si["lgds"]))
    rows.append(_std_row("lgds_std", "log10 DS: std", ph["lgds"], si["lgds"]))
    rows.append(_ks_row("lgds_ks", "log10 DS [s]: q10/q50/q90, KS", ph["lgds"], si["lgds"]))
    if cond == "los":
        rows.append(_mean_row("k_mean", "K [dB]: mean", ph["k_db"], si["k_db"]))
        rows.append(_std_row("k_std", "K [dB]: std", ph["k_db"], si["k_db"]))
        rows.append(_ks_row("k_ks", "K [dB]: q10/q50/q90, KS", ph["k_db"], si["k_db"]))
    corr = _corr_row(
        "corr_sf_ds",
        "corr(SF as a gain, lgDS)",
        ph["sf_gain_db"],
        ph["lgds"],
        si["sf_gain_db"],
        si["lgds"],
    )
    rows.append(corr)
    if cond == "los":
        rows.append(
            _corr_row(
                "corr_sf_k",
                "corr(SF as a gain, K)",
                ph["sf_gain_db"],
                ph["k_db"],
                si["sf_gain_db"],
                si["k_db"],
            )
        )
        rows.append(
            _corr_row("corr_ds_k", "corr(lgDS, K)", ph["lgds"], ph["k_db"], si["lgds"], si["k_db"])
        )
    rows.append(
        _mean_row(
            "clusters",
            "clusters after the −25 dB removal: mean",
            ph["clusters"],
            si["clusters"],
        )
    )
    # power-delay profiles
    pm, sm = ph["mean"], si["mean"]
    rows.append(
        _ks_row(
            "mean.mean_delay",
            "mean-power PDP: mean excess delay [ns] q10/q50/q90, KS",
            pm["mean_delay_s"],
            sm["mean_delay_s"],
            1e9,
        )
    )
    rows.append(
        _ks_row(
            "mean.rms_delay",
            "mean-power PDP: RMS delay spread of paths [ns], KS",
            pm["rms_delay_s"],
            sm["rms_delay_s"],
            1e9,
        )
    )
    rows.append(
        _mean_row(
            "mean.first_share",
            "mean-power PDP: power share of the first path, mean",
            pm["first_share"],
            sm["first_share"],
        )
    )
    rows.append(_mean_row("mean.n_paths", "paths per link: mean", pm["n_paths"], sm["n_paths"]))
    rows.append(
        _mean_row(
            "mean.kept",
            "mean-power PDP: power kept after the removal, mean [dB]",
            ph["kept_db"],
            si["kept_db"],
        )
    )
    pr, sr = ph["real"], si["real"]
    rows += _realized_rows(pr, sr, "realized CIR", "path")
    rows.append(
        _mean_row(
            "real.gain_mean", "realized P_rx / (P_tx − PL): mean [dB]", ph["gain_db"], si["gain_db"]
        )
    )
    rows.append(
        _std_row(
            "real.gain_std", "realized P_rx / (P_tx − PL): std [dB]", ph["gain_db"], si["gain_db"]
        )
    )
    rows.append(
        _mean_row(
            "first_excess",
            "first path: excess delay over d/c0, mean [ns]",
            ph["first_excess_s"] * 1e9,
            si["first_excess_s"] * 1e9,
            note="phyloc: its NLOS bias; Sionna: no absolute delay" if cond == "nlos" else "",
        )
    )
    series = {
        "lgds": {"phyloc": _quantiles(ph["lgds"]), "sionna": _quantiles(si["lgds"])},
        "rms_delay_ns": {
            "phyloc": _quantiles(pm["rms_delay_s"] * 1e9),
            "sionna": _quantiles(sm["rms_delay_s"] * 1e9),
            "sionna_cir": _quantiles(sr["rms_delay_s"] * 1e9),
        },
        "first_share": {
            "phyloc_cir": _quantiles(pr["first_share"]),
            "sionna_cir": _quantiles(sr["first_share"]),
        },
        "corr_sf_ds": [corr["phyloc"], corr["sionna"]],
    }
    if cond == "los":
        series["k_db"] = {"phyloc": _quantiles(ph["k_db"]), "sionna": _quantiles(si["k_db"])}
    return rows, series


def _tdl_rows(ph: dict, si: dict) -> tuple[list, dict]:
    """Rows and series of a TDL scenario: taps, mean PDP, per-link realized statistics."""
    rows = []
    td_ph = np.unique(ph["tap_delays_s"])
    td_si = np.unique(si["tap_delays_s"])
    if td_ph.size == td_si.size:
        rows.append(
            _exact_row(
                "tap_delays",
                f"distinct tap delays [ns] (largest: {td_ph[-1] * 1e9:.1f})",
                td_ph * 1e9,
                td_si * 1e9,
                1e-9,
                absolute=True,
                note="largest |difference| over the taps",
            )
        )
    else:
        rows.append(
            _row(
                "tap_delays",
                "number of distinct tap delays",
                td_ph.size,
                td_si.size,
                "exact",
                0,
                None,
                False,
            )
        )
        return rows, {}

    # per distinct delay, the taps at that delay added (independent phases: the mean of the
    # coherent sum is the sum of the means); TDL-E has two Rayleigh taps at 0.5440 DS
    def by_delay(delays, power, distinct):
        idx = np.searchsorted(distinct, delays)
        out = np.zeros((power.shape[0], distinct.size))
        for j in range(power.shape[1]):
            out[:, idx[j]] += power[:, j]
        return out

    p_ph = by_delay(ph["tap_delays_s"], ph["tap_power"], td_ph)
    p_si = by_delay(si["tap_delays_s"], si["tap_power"], td_si)
    ma, mb = p_ph.mean(axis=0), p_si.mean(axis=0)
    se = np.sqrt(
        p_ph.var(axis=0, ddof=1) / p_ph.shape[0] + p_si.var(axis=0, ddof=1) / p_si.shape[0]
    )
    z = np.where(se > 0, (ma - mb) / np.where(se > 0, se, 1.0), 0.0)
    z_crit = float(stats.norm.isf(ALPHA / 2 / td_ph.size))  # Bonferroni over the taps
    worst = int(np.argmax(np.abs(z)))
    rows.append(
        _row(
            "tap_power",
            f"tap mean power [dB] (worst of {td_ph.size} taps: {td_ph[worst] * 1e9:.1f} ns)",
            float(10 * np.log10(ma[worst])),
            float(10 * np.log10(mb[worst])),
            "z (Bonferroni)",
            z_crit,
            min(1.0, _p_of_z(float(z[worst])) * td_ph.size),
            bool(np.all(np.abs(z) <= z_crit)),
            note=f"max |z| = {np.max(np.abs(z)):.2f}",
        )
    )

    def rms(p):
        m1 = np.sum(p * td_ph) / p.sum()
        return math.sqrt(max(np.sum(p * td_ph**2) / p.sum() - m1 * m1, 0.0)) * 1e9

    rows.append(
        _row(
            "mean_pdp_rms",
            f"RMS delay spread of the mean PDP [ns] (file: {ph['file_delay_spread_s'] * 1e9:g})",
            rms(ma),
            rms(mb),
            "info",
        )
    )
    if ph["tap_is_los"].any():
        spec = ph["tap_power"][:, ph["tap_is_los"]].sum(axis=1)
        rows.append(
            _exact_row(
                "specular_share",
                "specular power share (K/(K+1))",
                spec,
                np.full(spec.size, si["tap_specular_power"]),
            )
        )
    pr, sr = ph["real"], si["real"]
    rows += _realized_rows(pr, sr, "realized", "tap")
    rows.append(
        _mean_row("real.gain_mean", "wideband gain G [dB]: mean", ph["gain_db"], si["gain_db"])
    )
    rows.append(
        _std_row("real.gain_std", "wideband gain G [dB]: std", ph["gain_db"], si["gain_db"])
    )
    series = {
        "tap_delay_ns": (td_ph * 1e9).tolist(),
        "tap_power_phyloc": ma.tolist(),
        "tap_power_sionna": mb.tolist(),
        "rms_delay_ns": {
            "phyloc_cir": _quantiles(pr["rms_delay_s"] * 1e9),
            "sionna_cir": _quantiles(sr["rms_delay_s"] * 1e9),
        },
        "first_share": {
            "phyloc_cir": _quantiles(pr["first_share"]),
            "sionna_cir": _quantiles(sr["first_share"]),
        },
    }
    return rows, series


def compare(
    scenario: str,
    *,
    n_links: int = 4000,
    carrier_frequency_hz: float = DEFAULT_CARRIER_HZ,
    seed: int = 0,
) -> dict:
    """Draw ``n_links`` links of ``scenario`` in phyloc and in Sionna and compare them.

    Parameters
    ----------
    scenario : str
        A name of :data:`GEOMETRIES` (``tr38901_umi`` … ``tdl_e``).
    n_links : int
        Links per draw (>= 100): system-level scenarios draw three times (LOS state drawn,
        forced LOS, forced NLOS), TDL scenarios once.
    carrier_frequency_hz : float
        Carrier [Hz], inside the scenario file's validity range.
    seed : int
        Seeds phyloc's ``numpy.random.Generator`` and Sionna's ``sionna.phy.config.seed`` (which
        also seeds torch's default generator).

    Returns
    -------
    dict
        ``{"scenario", "geometry", "carrier_frequency_hz", "links", "seed", "seconds",
        "sections": {section: [row, ...]}, "series": {...}}``; sections ``los_probability``,
        ``los``, ``nlos`` (TDL: its one state). A row is a dict with ``statistic``, ``phyloc``,
        ``sionna``, ``difference``, ``test``, ``tolerance``, ``p_value``, ``verdict``, ``note``.
        Plain Python, JSON-serializable.
    """
    check_arguments([scenario], n_links, carrier_frequency_hz)
    n, fc = int(n_links), float(carrier_frequency_hz)
    scn = load_scenario(scenario)
    config, _, _ = _sionna()
    config.seed = int(seed)
    rng = np.random.default_rng(seed)
    geom = GEOMETRIES[scenario]
    t0 = time.perf_counter()
    d2d, az, d3d = _link_distances(geom, n, rng)
    out = {
        "scenario": scenario,
        "geometry": {
            "sionna": geom.sionna,
            "option": geom.option,
            "h_bs_m": geom.h_bs_m,
            "h_ut_m": geom.h_ut_m,
            "d2d_range_m": list(geom.d2d_range_m),
        },
        "carrier_frequency_hz": fc,
        "links": n,
        "seed": int(seed),
        "sections": {},
        "series": {},
    }
    ph = draw_phyloc(scenario, d3d, None, fc, geom, rng)
    si = draw_sionna(geom, d2d, az, None, fc)
    if geom.sionna == "TDL":
        cond = "los" if ph["los"].all() else "nlos"
        rows, series = _tdl_rows(ph, si)
        out["sections"][cond] = rows
        out["series"][cond] = series
    else:
        gap = float(np.max(np.abs(si["d3d_m"] - d3d)))
        if gap > 1e-6:  # pragma: no cover - a defect of the placement
            raise PhylocError(f"Sionna's 3-D distances differ from phyloc's by {gap:g} m")
        rows, series = _los_probability(geom, d2d, ph, si)
        out["sections"]["los_probability"] = rows
        out["series"]["los_probability"] = series
        for cond in ("los", "nlos"):
            ph = draw_phyloc(scenario, d3d, cond, fc, geom, rng)
            si = draw_sionna(geom, d2d, az, cond, fc)
            rows, series = _state_rows(cond, ph, si, scn)
            out["sections"][cond] = rows
            out["series"][cond] = series
    out["seconds"] = time.perf_counter() - t0
    return out


# ---------------------------------------------------------------------------------------------
# Reporting
SECTION_TITLES = {
    "los_probability": "LOS probability (state drawn by each package)",
    "los": "forced LOS",
    "nlos": "forced NLOS",
}
TABLE_HEADERS = ["statistic", "phyloc", "Sionna", "difference", "tolerance or p", "verdict"]


def _cell(x) -> str:
    if x is None:
        return ""
    if isinstance(x, list):
        return " / ".join(_cell(y) for y in x)
    if isinstance(x, bool):
        return str(x)
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    x = float(x)
    if not np.isfinite(x):
        return str(x)
    if x != 0 and (abs(x) >= 1e5 or abs(x) < 1e-3):
        return f"{x:.4g}"
    return f"{x:.4g}"


def _test_cell(row: dict) -> str:
    t = row["test"]
    if t == "KS":
        return f"KS p = {row['p_value']:.3g} (D = {row.get('ks_statistic', float('nan')):.3f})"
    if t == "exact":
        if row.get("max_deviation") is None:
            return "exact"
        return f"≤ {row['tolerance']:g} (dev {row['max_deviation']:.2g})"
    if t in ("z", "fisher z"):
        return f"± {row['tolerance']:.3g} (p = {row['p_value']:.3g})"
    if t == "χ²":
        return f"χ² p = {row['p_value']:.3g}"
    if t.startswith("z (Bonferroni"):
        return f"|z| ≤ {row['tolerance']:.2f} (Bonferroni p = {row['p_value']:.3g})"
    return ""


def summary_rows(result: dict) -> list:
    """Table rows ``(statistic, phyloc, Sionna, difference, tolerance or p, verdict)`` of one
    scenario, with a title row (a string) before each section."""
    out = []
    for section, rows in result["sections"].items():
        out.append(f"{result['scenario']}: {SECTION_TITLES.get(section, section)}")
        for r in rows:
            diff = r["difference"]
            out.append(
                (
                    r["statistic"],
                    _cell(r["phyloc"]),
                    _cell(r["sionna"]),
                    _cell(diff),
                    _test_cell(r),
                    r["verdict"] + (f" ({r['note']})" if r["note"] else ""),
                )
            )
    return out


def format_comparison(result: dict) -> str:
    """The tables of one scenario's comparison as text (one table per section)."""
    from phyloc.reporting import format_table

    g = result["geometry"]
    lines = [
        f"== {result['scenario']} vs Sionna {g['sionna']}"
        + (f" ({g['option']})" if g["option"] else "")
        + f": {result['links']} links per draw, fc = {result['carrier_frequency_hz'] / 1e9:g} GHz,"
        f" h_BS = {g['h_bs_m']:g} m, h_UT = {g['h_ut_m']:g} m, d_2D uniform on "
        f"[{g['d2d_range_m'][0]:g}, {g['d2d_range_m'][1]:g}] m, seed {result['seed']} =="
    ]
    block: list = []
    title = None
    for row in [*summary_rows(result), None]:
        if row is None or isinstance(row, str):
            if title is not None:
                lines += ["", title, format_table(block, TABLE_HEADERS)]
            title, block = row, []
        else:
            block.append(row)
    return "\n".join(lines)


def verdict_counts(results) -> dict:
    """``{"agrees": n, "DIFFERS": n, "—": n}`` over every row of ``results``."""
    out = {"agrees": 0, "DIFFERS": 0, "—": 0}
    for res in results:
        for rows in res["sections"].values():
            for r in rows:
                out[r["verdict"]] += 1
    return out


def to_json(results, meta: dict) -> tuple[dict, dict, dict]:
    """``(figures, meta, series)`` for :func:`phyloc.reporting.write_json`: the figures are
    flat numbers ``<scenario>.<section>.<key>.{phyloc,sionna,p_value,agrees}``; ``meta`` gets
    the versions, the test levels and every row; ``series`` the figure's curves."""
    figures: dict[str, float] = {}
    for res in results:
        for section, rows in res["sections"].items():
            for r in rows:
                base = f"{res['scenario']}.{section}.{r['key']}"
                for side in ("phyloc", "sionna"):
                    val = r[side]
                    if isinstance(val, list):
                        val = val[1] if len(val) == 3 else None  # the median of q10/q50/q90
                    if isinstance(val, (int, float)) and not isinstance(val, bool):
                        figures[f"{base}.{side}"] = float(val)
                if r["p_value"] is not None:
                    figures[f"{base}.p_value"] = float(r["p_value"])
                if r["verdict"] != "—":
                    figures[f"{base}.agrees"] = float(r["verdict"] == "agrees")
    meta = {
        **meta,
        "versions": _versions(),
        "alpha": ALPHA,
        "z_crit": Z_CRIT,
        "verdicts": verdict_counts(results),
        "comparisons": [{k: v for k, v in r.items() if k != "series"} for r in results],
    }
    series = {r["scenario"]: r["series"] for r in results}
    return figures, meta, series


def results_from_json(doc: dict) -> list:
    """The comparisons of a ``results.json`` written from :func:`to_json`, as :func:`compare`
    returned them (for :func:`format_comparison` and :func:`plot_comparison`)."""
    out = []
    for res in doc["meta"]["comparisons"]:
        out.append({**res, "series": doc.get("series", {}).get(res["scenario"], {})})
    return out


def _cdf(ax, q, label, **kw) -> None:
    if q:
        ax.plot(q, CDF_LEVELS, label=label, **kw)


def plot_comparison(results, path_png) -> Path:
    """One row of panels per scenario: P_LOS against d_2D; CDFs of log10 DS (with the
    correlation of SF and lgDS), K, the RMS delay spread of the paths and the power share of the
    first path (TDL: the mean tap powers and the CDFs of the realized RMS delay spread and
    first-tap share); phyloc solid, Sionna dashed (its realized CIR dotted).

    Parameters
    ----------
    results : list of dict
        :func:`compare` results (or :func:`results_from_json`).
    path_png : str or Path
        Output file.

    Returns
    -------
    Path
    """
    from phyloc.reporting import new_figure, save_figure

    results = list(results)
    fig, axes = new_figure(
        max(len(results), 1), 5, squeeze=False, size=(18.0, 2.7 * max(len(results), 1))
    )
    colors = {"los": "tab:blue", "nlos": "tab:red"}
    for row, res in zip(axes, results, strict=False):
        name = res["scenario"]
        ser = res["series"]
        if "los_probability" in ser:
            _plot_system_level(row, name, ser, colors)
        else:
            _plot_tdl(row, name, ser)
        for ax in row:
            if ax.get_visible() and ax.has_data():
                ax.grid(alpha=0.3)
                ax.legend(fontsize=6)
    fig.suptitle(
        "phyloc vs Sionna 2.2 (TR 38.901): solid phyloc, dashed Sionna, dotted Sionna's CIR",
        fontsize=10,
    )
    out = Path(path_png)
    save_figure(fig, out)
    return out


def _plot_system_level(row, name: str, ser: dict, colors: dict) -> None:
    s = ser["los_probability"]
    ax = row[0]
    ax.plot(s["bin_center_m"], s["p_los_law"], "k-", lw=1, label="table P_LOS")
    ax.plot(s["bin_center_m"], s["los_fraction_phyloc"], "o", ms=4, label="phyloc")
    ax.plot(s["bin_center_m"], s["los_fraction_sionna"], "x", ms=5, label="Sionna")
    ax.set_xlabel("d_2D [m]")
    ax.set_ylabel("LOS fraction")
    ax.set_title(f"{name}: LOS probability", fontsize=9)
    corr = []
    for cond in ("los", "nlos"):
        c = colors[cond]
        st = ser.get(cond, {})
        lg = st.get("lgds", {})
        _cdf(row[1], lg.get("phyloc"), f"phyloc {cond}", color=c)
        _cdf(row[1], lg.get("sionna"), f"Sionna {cond}", color=c, ls="--")
        rd = st.get("rms_delay_ns", {})
        _cdf(row[3], rd.get("phyloc"), f"phyloc {cond}", color=c)
        _cdf(row[3], rd.get("sionna"), f"Sionna {cond}", color=c, ls="--")
        _cdf(row[3], rd.get("sionna_cir"), f"Sionna CIR {cond}", color=c, ls=":")
        fs = st.get("first_share", {})
        _cdf(row[4], fs.get("phyloc_cir"), f"phyloc {cond}", color=c)
        _cdf(row[4], fs.get("sionna_cir"), f"Sionna CIR {cond}", color=c, ls=":")
        if "corr_sf_ds" in st:
            a, b = st["corr_sf_ds"]
            corr.append(f"{cond.upper()} {a:+.2f}/{b:+.2f}")
    k = ser.get("los", {}).get("k_db", {})
    _cdf(row[2], k.get("phyloc"), "phyloc", color="tab:blue")
    _cdf(row[2], k.get("sionna"), "Sionna", color="tab:blue", ls="--")
    row[1].set_xlabel("log10 DS [s]")
    row[2].set_xlabel("K [dB] (LOS)")
    row[3].set_xlabel("RMS delay spread of the paths [ns]")
    row[3].set_xscale("symlog", linthresh=1.0)
    row[4].set_xlabel("power share of the first path (realized)")
    titles = (
        "delay spread; corr(SF gain, lgDS) phyloc/Sionna:\n" + ", ".join(corr),
        "K-factor",
        "paths (mean-power PDP; CIR dotted)",
        "first path",
    )
    for ax, t in zip(row[1:], titles, strict=True):
        ax.set_ylabel("CDF")
        ax.set_title(f"{name}: {t}", fontsize=8)


def _plot_tdl(row, name: str, ser: dict) -> None:
    cond = next(iter(ser), None)
    st = ser.get(cond, {})
    if st:
        ax = row[0]
        ax.plot(st["tap_delay_ns"], 10 * np.log10(st["tap_power_phyloc"]), "o", label="phyloc")
        ax.plot(st["tap_delay_ns"], 10 * np.log10(st["tap_power_sionna"]), "x", label="Sionna")
        ax.set_xlabel("tap delay [ns]")
        ax.set_ylabel("mean tap power [dB]")
        ax.set_title(f"{name}: mean PDP", fontsize=9)
        _cdf(row[1], st["rms_delay_ns"]["phyloc_cir"], "phyloc")
        _cdf(row[1], st["rms_delay_ns"]["sionna_cir"], "Sionna", ls="--")
        row[1].set_xlabel("RMS delay spread of the paths [ns]")
        _cdf(row[2], st["first_share"]["phyloc_cir"], "phyloc")
        _cdf(row[2], st["first_share"]["sionna_cir"], "Sionna", ls="--")
        row[2].set_xlabel("power share of the first tap")
        for ax in row[1:3]:
            ax.set_ylabel("CDF")
            ax.set_title(f"{name}: realized links", fontsize=9)
    for ax in row[3:]:
        ax.set_visible(False)


__all__ = [
    "ALPHA",
    "GEOMETRIES",
    "INSTALL",
    "Z_CRIT",
    "Geometry",
    "check_arguments",
    "compare",
    "draw_phyloc",
    "draw_sionna",
    "format_comparison",
    "merge_equal_delays",
    "pdp_statistics",
    "plot_comparison",
    "require_sionna",
    "results_from_json",
    "sionna_available",
    "summary_rows",
    "to_json",
    "verdict_counts",
]

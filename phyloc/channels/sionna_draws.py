"""Drawing the same TR 38.901 links in phyloc and in NVIDIA Sionna, for
:mod:`phyloc.channels.sionna_compare`: the geometry of each scenario in Sionna
(:data:`GEOMETRIES`), Sionna's availability, each package's draws at given distances and LOS
states, and the power-delay-profile statistics both are reduced to.

Sionna is imported only here and only when a draw runs (``pip install sionna``, or
``pip install "phyloc[sionna]"``).

References
----------
3GPP TR 38.901, Sec. 7.4-7.5 and 7.7.2-7.7.3 (the tables as in V16.1). NVIDIA Sionna 2.2
(GitHub NVlabs/sionna), ``sionna.phy.channel.tr38901``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from phyloc.channels.sampler import draw_links
from phyloc.channels.scenario import load_scenario
from phyloc.errors import PhylocError, ValidationError
from phyloc.phy.system import OFDMSystem

#: How to install the comparison's one optional dependency.
INSTALL = 'pip install sionna (or pip install "phyloc[sionna]")'
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
        sionna_modules()
    except PhylocError:
        return False
    return True


def require_sionna() -> None:
    """Raise :class:`~phyloc.errors.PhylocError` (one line naming ``pip install sionna``) if
    Sionna cannot be imported."""
    sionna_modules()


def sionna_modules():
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


def package_versions() -> dict:
    """The installed versions of phyloc, Sionna, torch, NumPy and SciPy (None: absent)."""
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


def cluster_counts(paths_without_los, num_split: int, extra_per_split: int) -> np.ndarray:
    """Clusters behind a path count: ``c`` clusters give ``c + extra·min(c, num_split)`` paths."""
    m = np.asarray(paths_without_los, dtype=np.int64)
    full = num_split * (1 + extra_per_split)
    return np.where(m >= full, m - num_split * extra_per_split, m // (1 + extra_per_split))


# ---------------------------------------------------------------------------------------------
# The two packages' draws
def link_distances(geom: Geometry, n: int, rng: np.random.Generator):
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
    out["clusters"] = cluster_counts(
        dr.paths.n_paths - (cond == "los"), min(par.num_split, par.num_clusters), extra
    ).astype(np.float64)
    return out


def _make_sionna_channel(geom: Geometry, fc_hz: float):
    _, tr, _ = sionna_modules()
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
    _, _, torch = sionna_modules()
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
    _, tr, _ = sionna_modules()
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


__all__ = [
    "CHUNK",
    "GEOMETRIES",
    "INSTALL",
    "SUBCLUSTER_FRACTIONS",
    "SUBCLUSTER_OFFSETS",
    "Geometry",
    "cluster_counts",
    "draw_phyloc",
    "draw_sionna",
    "link_distances",
    "merge_equal_delays",
    "package_versions",
    "pdp_statistics",
    "require_sionna",
    "sionna_available",
    "sionna_modules",
]

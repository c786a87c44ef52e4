"""Tests of phyloc.channels: scenario files, loader validation, sampler statistics, two-way.

Key table numbers are copied here from WINNER II D1.1.2 (sources: channels/PROVENANCE.md) and
the DiPNet paper, independently of the loader, so a wrong transcription in channels/*.toml
fails a test.
"""

from __future__ import annotations

import json
import math
import tomllib

import numpy as np
import pytest

from phyloc.channels import (
    ChannelSpec,
    draw_links,
    load_scenario,
    scenario_names,
    two_way_composite,
)
from phyloc.channels.sampler import los_delay_scaling
from phyloc.channels.scenario import shipped_root
from phyloc.channels.stats import channel_stats, square_pair_distances
from phyloc.errors import ValidationError
from phyloc.phy import OFDMSystem, PathSet

C0 = 299_792_458.0
FC = 5.2e9  # DiPNet §V-A

# --- independent copy of the tables (D1.1.2 Table 4-4 / 4-5; channels/PROVENANCE.md) ----------
# name: (ds_log10 mu, sigma), (K mu, sigma) or None, clusters N, sf std per segment
TABLE = {
    "winner2_c2_los": ((-7.39, 0.63), (7.0, 3.0), 8),
    "winner2_c2_nlos": ((-6.63, 0.32), None, 20),
    "winner2_d1_los": ((-7.80, 0.57), (7.0, 6.0), 11),
    "winner2_d1_nlos": ((-7.60, 0.48), None, 10),
    "winner2_b1_los": ((-7.44, 0.25), (9.0, 6.0), 8),
    "winner2_b1_nlos": ((-7.12, 0.12), None, 16),
    "winner2_a1_los": ((-7.42, 0.27), (7.0, 6.0), 12),
    "winner2_a1_nlos": ((-7.60, 0.19), None, 16),
}
# (distance range [m] with 1.5 m heights at 5.2 GHz, expected SF std [dB])
SF_CASES = [
    ("winner2_c2_los", (1.0, 17.0), 4.0),  # d < d_bp = 4·0.5·0.5·5.2e9/3e8 = 17.33 m
    ("winner2_c2_los", (18.0, 140.0), 6.0),
    ("winner2_c2_nlos", (1.0, 140.0), 8.0),
    ("winner2_d1_los", (1.0, 150.0), 4.0),  # d_bp = 4·1.5·1.5·5.2e9/3e8 = 156 m
    ("winner2_d1_los", (160.0, 1000.0), 6.0),
    ("winner2_d1_nlos", (1.0, 140.0), 8.0),
    ("winner2_b1_los", (1.0, 140.0), 3.0),
    ("winner2_b1_nlos", (1.0, 140.0), 4.0),
    ("winner2_a1_los", (1.0, 100.0), 3.0),
    ("winner2_a1_nlos", (1.0, 100.0), 4.0),
]
ZETA_DB = {name: 6.0 if name == "winner2_a1_los" else 3.0 for name in TABLE}  # per-cluster ζ
# delay law (Table 4-5): r_tau for exponential delays; B1 NLOS uniform on [0, 800 ns]
R_TAU = {
    "winner2_c2_los": 2.5,
    "winner2_c2_nlos": 2.3,
    "winner2_d1_los": 3.8,
    "winner2_d1_nlos": 1.7,
    "winner2_b1_los": 3.2,
    "winner2_b1_nlos": None,
    "winner2_a1_los": 3.0,
    "winner2_a1_nlos": 2.4,
}
WINNER_D_COEFFS = (0.7705, -0.0433, 0.0002, 0.000017)  # eq. (4.3)
DS_SF_CORR = {"winner2_c2_los": -0.4, "winner2_d1_los": -0.5, "winner2_b1_nlos": -0.7}
NLOS_BIAS_MEAN_S = 0.3e-6  # DiPNet §V-A
N_STAT = 20_000


def fspl_db(d):
    return 20 * np.log10(4 * np.pi * d * FC / C0)


def rng_(seed=0):
    return np.random.default_rng(seed)


# --- scenario files and names ------------------------------------------------------------------
EXPECTED_NAMES = {
    "awgn",
    "exponential",
    "exponential_los",
    "exponential_nlos",
    *(f"winner2_{s}{c}" for s in ("a1", "b1", "c2", "d1") for c in ("", "_los", "_nlos")),
}


def test_scenario_names_cover_the_shipped_scenarios():
    assert EXPECTED_NAMES <= set(scenario_names())


@pytest.mark.parametrize(
    "entry",
    [e for e in shipped_root().iterdir() if e.name.endswith(".toml")],
    ids=lambda e: e.name,
)
def test_shipped_files_name_their_source(entry):
    doc = tomllib.loads(entry.read_text())
    assert doc["name"] == entry.name[:-5]
    assert doc["schema"] == "phyloc.channel.v1"
    if doc["model"] == "winner2":
        assert "D1.1.2" in doc["source"] and "Table 4-5" in doc["source"]
    load_scenario(doc["name"])  # validates


def test_unknown_scenario_lists_valid_names():
    with pytest.raises(
        ValidationError, match=r"unknown scenario; valid names: .*winner2_c2.*"
    ) as e:
        draw_links("winner2_c3", np.ones(3), rng_())
    assert e.value.field == "scenario" and e.value.value == "winner2_c3"
    with pytest.raises(ValidationError, match="winner2_d1_nlos"):
        ChannelSpec(scenario="urban")


def _user_copy(tmp_path, stem="winner2_c2_nlos"):
    src = shipped_root() / f"{stem}.toml"
    dst = tmp_path / "mine.toml"
    dst.write_text(src.read_text())
    return dst


def test_user_file_equals_shipped(tmp_path):
    path = _user_copy(tmp_path)
    d = np.linspace(5, 120, 50)
    a = draw_links(str(path), d, rng_(3))
    b = draw_links(path, d, rng_(3))
    c = draw_links("winner2_c2_nlos", d, rng_(3))
    np.testing.assert_array_equal(a.paths.delays, c.paths.delays)
    np.testing.assert_array_equal(b.paths.gains, c.paths.gains)


def test_user_file_missing_key(tmp_path):
    path = _user_copy(tmp_path)
    path.write_text(path.read_text().replace("ds_log10_s_sigma = 0.32\n", ""))
    with pytest.raises(ValidationError) as e:
        load_scenario(path)
    msg = str(e.value)
    assert "mine.toml: nlos.lsp.ds_log10_s_sigma" in msg
    assert "<missing>" in msg and "[0, 3]" in msg


def test_user_file_out_of_range_key(tmp_path):
    path = _user_copy(tmp_path)
    path.write_text(path.read_text().replace("r_tau = 2.3", "r_tau = 0.5"))
    with pytest.raises(ValidationError) as e:
        load_scenario(path)
    assert e.value.field == "mine.toml: nlos.clusters.r_tau"
    assert e.value.value == 0.5 and "[1, 20]" in str(e.value)


def test_user_file_unknown_key_names_closest(tmp_path):
    path = _user_copy(tmp_path)
    path.write_text(path.read_text().replace("num_clusters = 20", "num_cluster = 20"))
    with pytest.raises(ValidationError, match="did you mean 'num_clusters'"):
        load_scenario(path)


def test_user_file_bad_subcluster_fractions(tmp_path):
    path = _user_copy(tmp_path)
    path.write_text(path.read_text().replace("[0.5, 0.3, 0.2]", "[0.5, 0.3, 0.3]"))
    with pytest.raises(ValidationError, match="sum to 1"):
        load_scenario(path)


def test_user_file_pathloss_key_out_of_range(tmp_path):
    path = _user_copy(tmp_path)
    path.write_text(path.read_text().replace("sf_std_db = 8.0", "sf_std_db = -1.0"))
    with pytest.raises(ValidationError) as e:
        load_scenario(path)
    assert e.value.field == "mine.toml: nlos.pathloss.sf_std_db" and "[0, 30]" in str(e.value)


def test_non_positive_definite_cross_correlation(tmp_path):
    path = _user_copy(tmp_path, "winner2_c2_los")
    text = path.read_text().replace(
        "{ ds_sf = -0.4, ds_k = -0.4, sf_k = 0.3 }", "{ ds_sf = 0.9, ds_k = 0.9, sf_k = -0.9 }"
    )
    path.write_text(text)
    with pytest.raises(ValidationError, match="positive definite"):
        load_scenario(path)


# --- LOS probability ---------------------------------------------------------------------------
def test_los_probability_laws():
    d = np.array([5.0, 18.0, 50.0, 100.0, 300.0])
    e = np.exp(-d / 63)
    c2 = np.minimum(18 / d, 1) * (1 - e) + e
    np.testing.assert_allclose(load_scenario("winner2_c2").p_los(d), c2, rtol=1e-14)
    np.testing.assert_allclose(load_scenario("winner2_d1").p_los(d), np.exp(-d / 1000), 1e-14)
    b1 = np.where(d <= 15, 1.0, 1 - np.cbrt(1 - (1.56 - 0.48 * np.log10(d)) ** 3))
    np.testing.assert_allclose(load_scenario("winner2_b1").p_los(d), b1, rtol=1e-12)
    a1 = np.where(d <= 2.5, 1, 1 - 0.9 * np.cbrt(1 - (1.24 - 0.61 * np.log10(d)) ** 3))
    np.testing.assert_allclose(load_scenario("winner2_a1").p_los(d), np.clip(a1, 0, 1), 1e-12)


@pytest.mark.parametrize(("name", "target"), [("winner2_c2", 0.66), ("winner2_d1", 0.95)])
def test_los_fraction_in_100m_square(name, target):
    # 66 % ± 1 % (C2) and 95 % ± 1 % (D1); DiPNet reports 65.6 % and 95.1 %
    rng = rng_(11)
    d = square_pair_distances(100_000, 100.0, rng)
    draw = draw_links(name, d, rng)
    assert abs(draw.los.mean() - target) <= 0.01


# --- large-scale parameters --------------------------------------------------------------------
@pytest.mark.parametrize("name", list(TABLE))
def test_lsp_statistics(name):
    (mu, sigma), k, _ = TABLE[name]
    rng = rng_(5)
    draw = draw_links(name, rng.uniform(5.0, 140.0, N_STAT), rng)
    lg = np.log10(draw.delay_spread_s)
    assert abs(lg.mean() - mu) <= 0.05 * abs(mu)  # within 5 % of the table
    assert abs(lg.std(ddof=1) - sigma) <= 0.05 * sigma
    # and statistically tight: SE(mean) <= 0.0045, SE(std)/std ~ 0.5 % at N_STAT links
    assert abs(lg.mean() - mu) <= 0.05
    assert abs(lg.std(ddof=1) - sigma) <= 0.025 * sigma
    if k is None:
        assert np.all(np.isnan(draw.k_factor_db))
    else:
        assert abs(draw.k_factor_db.mean() - k[0]) <= 0.5
        assert abs(draw.k_factor_db.std(ddof=1) - k[1]) <= 0.5


@pytest.mark.parametrize(("name", "span", "sf_std"), SF_CASES)
def test_shadow_fading_std(name, span, sf_std):
    rng = rng_(6)
    draw = draw_links(name, rng.uniform(*span, N_STAT), rng)
    assert abs(draw.shadowing_db.std(ddof=1) - sf_std) <= 0.05 * sf_std
    assert abs(draw.shadowing_db.mean()) <= 5 * sf_std / math.sqrt(N_STAT)
    np.testing.assert_array_equal(draw.shadowing_std_db, sf_std)


@pytest.mark.parametrize(("name", "rho"), list(DS_SF_CORR.items()))
def test_ds_sf_cross_correlation(name, rho):
    rng = rng_(8)
    draw = draw_links(name, rng.uniform(20.0, 140.0, N_STAT), rng)
    # Table 4-5 correlates SF as a gain: a stronger link has a smaller delay spread
    r = np.corrcoef(np.log10(draw.delay_spread_s), -draw.shadowing_db)[0, 1]
    assert abs(r - rho) <= 0.03


@pytest.mark.parametrize(("name", "rho"), [("winner2_c2_los", 0.3), ("winner2_a1_los", 0.4)])
def test_sf_k_cross_correlation_is_for_sf_as_a_gain(name, rho):
    # WINNER II Table 4-5: SF vs K +0.3 (C2 LOS), +0.4 (A1 LOS): a stronger link has a larger
    # K. Checked on the power the link budget delivers, above its distance-dependent mean.
    rng = rng_(18)
    draw = draw_links(name, rng.uniform(20.0, 80.0, N_STAT), rng)
    above_mean_db = 10 * np.log10(draw.received_power_w) + draw.path_loss_db
    r = np.corrcoef(above_mean_db, draw.k_factor_db)[0, 1]
    assert abs(r - rho) <= 0.03


@pytest.mark.parametrize("name", list(TABLE))
def test_realized_rms_delay_spread_close_to_table(name):
    # the generated clusters (eqs. 4.1–4.9, D(K), sub-clusters) reproduce the drawn DS on average
    (mu, _), _, _ = TABLE[name]
    rng = rng_(9)
    draw = draw_links(name, rng.uniform(5.0, 140.0, N_STAT), rng)
    assert abs(np.log10(draw.rms_delay_spread()).mean() - mu) <= 0.1


@pytest.mark.parametrize("name", list(TABLE))
def test_cluster_delay_law(name):
    # eqs. (4.1)-(4.2): the last cluster of N i.i.d. Exp(r_τ·DS) delays shifted to the first
    # has mean r_τ·DS·(H_N − 1/N); LOS delays are divided by D(K) (eq. (4.4)). Uniform delays
    # on [0, τ_max]: E[max − min] = τ_max (N − 1)/(N + 1). (Sub-cluster offsets of 10 ns
    # contaminate this by < 2 %.)
    n = TABLE[name][2]
    rng = rng_(10)
    draw = draw_links(name, rng.uniform(5.0, 140.0, N_STAT), rng)
    rel = draw.excess_delays() - draw.nlos_bias_s[draw.paths.link_index()]
    last = np.maximum.reduceat(rel, draw.paths.offsets[:-1])
    if R_TAU[name] is None:
        assert abs(last.mean() / (800e-9 * (n - 1) / (n + 1)) - 1) < 0.03
        return
    if name.endswith("_los"):
        last = last * los_delay_scaling(draw.k_factor_db, WINNER_D_COEFFS)
    expected = R_TAU[name] * (np.sum(1.0 / np.arange(1, n + 1)) - 1.0 / n)
    assert abs(np.mean(last / draw.delay_spread_s) / expected - 1) < 0.03


def _cluster_powers(draw, n_paths, is_los):
    """Undo the sub-cluster split: per link the N cluster delays (rel., unscaled) and powers."""
    n = draw.n_links
    t = draw.excess_delays().reshape(n, n_paths) - draw.nlos_bias_s[:, None]
    p = (np.abs(draw.paths.gains) ** 2).reshape(n, n_paths) / draw.received_power_w[:, None]
    if is_los:
        t, p = t[:, 1:], p[:, 1:]  # the direct path
    dt = t[:, None, :] - t[:, :, None]  # [link, base, other]
    ratio = p[:, None, :] / p[:, :, None]
    base5 = np.isclose(dt, 5e-9, rtol=0, atol=1e-13) & np.isclose(ratio, 0.6, rtol=1e-9)
    base10 = np.isclose(dt, 10e-9, rtol=0, atol=1e-13) & np.isclose(ratio, 0.4, rtol=1e-9)
    is_base = base5.any(2) & base10.any(2)
    assert np.all(is_base.sum(1) == 2)  # exactly two clusters were split
    drop = ((base5 | base10) & is_base[:, :, None]).any(1)  # their +5/+10 ns partners
    p = np.where(is_base, p / 0.5, p)
    keep = ~drop
    k = keep.sum(1)[0]
    return t[keep].reshape(n, k), p[keep].reshape(n, k)


@pytest.mark.parametrize("name", list(TABLE))
def test_cluster_power_law_and_shadowing(name):
    # eq. (4.5): 10log10 P_n = −(10/ln 10)·τ_n (r_τ − 1)/(r_τ DS) − Z_n + const, Z_n ~ N(0, ζ²);
    # eq. (4.6) for uniform delays: −(10/ln 10)·τ_n/DS. The within-link variance of the
    # residual, pooled over links, estimates ζ².
    n_cl = TABLE[name][2]
    is_los = name.endswith("_los")
    rng = rng_(20)
    draw = draw_links(name, rng.uniform(5.0, 140.0, 2000), rng)
    t, p = _cluster_powers(draw, n_cl + 4 + is_los, is_los)
    assert t.shape[1] == n_cl
    if is_los:
        t = t * los_delay_scaling(draw.k_factor_db, WINNER_D_COEFFS)[:, None]
    r = R_TAU[name]
    slope = (r - 1) / r if r is not None else 1.0
    resid = 10 * np.log10(p) + 10 / np.log(10) * t * slope / draw.delay_spread_s[:, None]
    zeta2 = resid.var(axis=1, ddof=1).mean()
    assert abs(np.sqrt(zeta2) / ZETA_DB[name] - 1) < 0.05


def test_los_delay_scaling_reference_values():
    # WINNER II D1.1.2 eq. 4.3 (channels/PROVENANCE.md): D(7 dB) = 0.483, D(0) = 0.7705,
    # D(−5 dB) = 0.990
    coeffs = WINNER_D_COEFFS
    got = los_delay_scaling(np.array([7.0, 0.0, -5.0]), coeffs)
    np.testing.assert_allclose(got, [0.483, 0.7705, 0.990], atol=6e-4)
    assert np.all(los_delay_scaling(np.linspace(-100, 100, 2001), coeffs) > 0)


# --- path loss ---------------------------------------------------------------------------------
def test_path_loss_formulas_at_device_heights():
    d = np.array([60.0, 90.0, 130.0])
    lf = np.log10(FC / 5e9)
    hp = 0.5  # effective height 1.5 m − 1 m (C2, B1)
    expect = {
        "winner2_c2_los": 40 * np.log10(d) + 13.47 - 28 * np.log10(hp) + 6 * lf,  # d > d_bp
        "winner2_c2_nlos": (44.9 - 6.55 * np.log10(1.5)) * np.log10(d)
        + 34.46
        + 5.83 * np.log10(1.5)
        + 23 * lf,
        "winner2_d1_los": 21.5 * np.log10(d) + 44.2 + 20 * lf,  # d < d_bp = 156 m
        "winner2_d1_nlos": 25.1 * np.log10(d)
        + 55.4
        - 0.13 * (1.5 - 25) * np.log10(d / 100)
        + 21.3 * lf,
        "winner2_a1_los": 18.7 * np.log10(d) + 46.8 + 20 * lf,
        "awgn": fspl_db(d),
    }
    for name, pl in expect.items():
        draw = draw_links(name, d, rng_())
        np.testing.assert_allclose(draw.path_loss_db, pl, atol=1e-9)  # as tabulated in range


def test_path_loss_short_links_extrapolated_with_free_space_floor():
    lf = np.log10(FC / 5e9)
    a = 44.9 - 6.55 * np.log10(1.5)

    def c2_nlos(d):
        return a * np.log10(d) + 34.46 + 5.83 * np.log10(1.5) + 23 * lf

    d = np.array([0.2, 1.0, 2.0, 5.0, 20.0, 49.9, 50.0])
    pl = draw_links("winner2_c2_nlos", d, rng_()).path_loss_db
    de = np.maximum(d, 1.0)  # far-field reference distance
    np.testing.assert_allclose(pl, np.maximum(c2_nlos(de), fspl_db(de)), atol=1e-9)
    assert pl[3] > fspl_db(5.0) + 5  # extrapolated, not free space, not clamped
    assert pl[3] < c2_nlos(50.0) - 20
    # C2 LOS just below 10 m: the floor is capped by the law's value at d_min (continuity)
    d = np.array([1.0, 5.0, 9.0, 9.999999, 10.0, 12.0])
    pl = draw_links("winner2_c2_los", d, rng_()).path_loss_db
    law = 26 * np.log10(d) + 39 + 20 * lf
    np.testing.assert_allclose(pl, np.maximum(law, np.minimum(fspl_db(d), law[4])), atol=1e-9)
    assert np.all(np.diff(pl) >= 0) and abs(pl[3] - pl[4]) < 1e-4
    for name in ("winner2_d1_nlos", "winner2_b1_nlos", "winner2_a1_nlos", "winner2_b1_los"):
        pl = draw_links(name, np.geomspace(1.0, 140.0, 200), rng_()).path_loss_db
        assert np.all(np.diff(pl) >= -1e-9)  # continuous, non-decreasing through d_min


def test_heights_below_breakpoint_offset_rejected():
    with pytest.raises(ValidationError, match="h_tx_m / h_rx_m"):
        draw_links("winner2_c2_los", np.array([50.0]), rng_(), h_tx_m=1.0)


def test_frequency_outside_validity_rejected():
    with pytest.raises(ValidationError, match="carrier_frequency_hz"):
        draw_links(
            "winner2_c2", np.array([50.0]), rng_(), system=OFDMSystem(carrier_frequency_hz=900e6)
        )


# --- causality, power, structure ---------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(EXPECTED_NAMES | {"awgn_los"}))
def test_causality_and_power(name):
    rng = rng_(2)
    d = square_pair_distances(3000, 100.0, rng)
    system = OFDMSystem(tx_power_dbm=10.0)
    draw = draw_links(name, d, rng, system=system)
    link = draw.paths.link_index()
    los_of_path = draw.los[link]
    # no path before d/c0
    assert np.all(draw.paths.delays >= d[link] / C0)
    # NLOS: b > 0, no LOS path, no path before d/c0 + b
    b = draw.nlos_bias_s
    assert np.all(b[draw.los] == 0)
    assert np.all(b[~draw.los] > 0)
    nl = ~los_of_path
    assert np.all(draw.paths.delays[nl] >= d[link][nl] / C0 + b[link][nl])
    assert not np.any(draw.paths.delays[nl] <= d[link][nl] / C0)
    # LOS: the direct path arrives at exactly d/c0
    first = draw.paths.first_delay()
    np.testing.assert_array_equal(first[draw.los], d[draw.los] / C0)
    # total power = link budget P_tx − PL − SF, to 1e-9 relative
    budget = 10 ** ((10.0 - draw.path_loss_db - draw.shadowing_db - 30) / 10)
    np.testing.assert_allclose(draw.paths.total_power(), budget, rtol=1e-9)
    np.testing.assert_allclose(draw.received_power_w, budget, rtol=1e-12)
    # paths sorted by delay within each link
    same = link[1:] == link[:-1]
    assert np.all(np.diff(draw.paths.delays)[same] >= 0)


@pytest.mark.parametrize("name", ["winner2_c2", "winner2_d1", "winner2_b1", "winner2_a1"])
def test_winner2_structure(name):
    n_los = TABLE[name + "_los"][2]
    n_nlos = TABLE[name + "_nlos"][2]
    rng = rng_(4)
    draw = draw_links(name, rng.uniform(5.0, 140.0, 400), rng)
    counts = draw.paths.n_paths
    # N clusters, the two strongest split in three (+4 paths), + the direct path in LOS
    np.testing.assert_array_equal(counts[draw.los], n_los + 4 + 1)
    np.testing.assert_array_equal(counts[~draw.los], n_nlos + 4)
    # NLOS: the first cluster sits exactly at d/c0 + b
    first = draw.paths.first_delay()
    nl = ~draw.los
    np.testing.assert_array_equal(first[nl], draw.distances_m[nl] / C0 + draw.nlos_bias_s[nl])
    # LOS: the direct path carries K_R/(K_R + 1)
    i = np.flatnonzero(draw.los)
    kr = 10 ** (draw.k_factor_db[i] / 10)
    p0 = np.abs(draw.paths.gains[draw.paths.offsets[i]]) ** 2 / draw.received_power_w[i]
    np.testing.assert_allclose(p0, kr / (kr + 1), rtol=1e-12)


def _subcluster_triplets(t, p):
    """Brute force: (base index, total power) of paths with partners at +5/+10 ns, 6:4 of 10."""
    out = []
    for j in range(t.size):
        m5 = np.flatnonzero(np.isclose(t, t[j] + 5e-9, rtol=0, atol=1e-13))
        m10 = np.flatnonzero(np.isclose(t, t[j] + 10e-9, rtol=0, atol=1e-13))
        for a in m5:
            for c in m10:
                if np.isclose(p[a], 0.6 * p[j], rtol=1e-9) and np.isclose(p[c], 0.4 * p[j], 1e-9):
                    out.append((j, p[j] + p[a] + p[c]))
    return out


@pytest.mark.parametrize("name", ["winner2_c2_nlos", "winner2_d1_los", "winner2_b1_nlos"])
def test_two_strongest_clusters_split(name):
    rng = rng_(12)
    draw = draw_links(name, rng.uniform(5.0, 140.0, 30), rng)
    for i in range(draw.n_links):
        t, g = draw.paths.link(i)
        p = np.abs(g) ** 2
        if draw.los[i]:
            t, p = t[1:], p[1:]  # drop the direct path
        trip = _subcluster_triplets(t, p)
        assert len(trip) == 2
        used = {j for j, _ in trip}
        for j, _ in trip:
            used |= set(np.flatnonzero(np.isclose(t, t[j] + 5e-9, rtol=0, atol=1e-13)))
            used |= set(np.flatnonzero(np.isclose(t, t[j] + 10e-9, rtol=0, atol=1e-13)))
        rest = np.delete(p, sorted(used))
        assert min(pw for _, pw in trip) >= rest.max() * (1 - 1e-12)


def test_phases_uniform():
    rng = rng_(13)
    draw = draw_links("winner2_c2_nlos", rng.uniform(5, 140, 5000), rng)
    ph = np.angle(draw.paths.gains)
    hist, _ = np.histogram(ph, bins=8, range=(-np.pi, np.pi))
    expected = ph.size / 8
    assert np.all(np.abs(hist - expected) < 5 * np.sqrt(expected))
    assert abs(np.mean(np.exp(1j * ph))) < 5 / np.sqrt(ph.size)


def test_nlos_bias_is_exponential_and_configurable():
    rng = rng_(14)
    d = rng.uniform(5, 140, N_STAT)
    b = draw_links("winner2_d1_nlos", d, rng).nlos_bias_s
    assert abs(b.mean() / NLOS_BIAS_MEAN_S - 1) < 0.03
    assert abs(b.std() / NLOS_BIAS_MEAN_S - 1) < 0.05  # exponential: std = mean
    b2 = draw_links("winner2_d1_nlos", d, rng, nlos_bias_mean_s=50e-9).nlos_bias_s
    assert abs(b2.mean() / 50e-9 - 1) < 0.03


def test_condition_forcing():
    rng = rng_(15)
    d = np.full(200, 30.0)
    assert draw_links("winner2_c2", d, rng, condition="los").los.all()
    assert not draw_links("winner2_c2", d, rng, condition="nlos").los.any()
    mask = np.arange(200) % 3 == 0
    np.testing.assert_array_equal(draw_links("winner2_c2", d, rng, condition=mask).los, mask)
    with pytest.raises(ValidationError, match="forces LOS"):
        draw_links("winner2_c2_los", d, rng, condition="nlos")
    with pytest.raises(ValidationError, match="forces LOS"):
        draw_links("awgn", d, rng, condition="nlos")
    with pytest.raises(ValidationError, match="bool array"):
        draw_links("winner2_c2", d, rng, condition=np.ones(3, bool))


def test_reproducible_for_a_seed():
    d = np.linspace(2.0, 130.0, 300)
    a = draw_links("winner2_c2", d, rng_(21))
    b = draw_links("winner2_c2", d, rng_(21))
    c = draw_links("winner2_c2", d, rng_(22))
    for field in ("delays", "gains", "offsets"):
        np.testing.assert_array_equal(getattr(a.paths, field), getattr(b.paths, field))
    np.testing.assert_array_equal(a.los, b.los)
    np.testing.assert_array_equal(a.shadowing_db, b.shadowing_db)
    assert not np.array_equal(a.shadowing_db, c.shadowing_db)


def test_input_validation():
    with pytest.raises(ValidationError, match="distances_m"):
        draw_links("awgn", np.array([1.0, 0.0]), rng_())
    with pytest.raises(ValidationError, match="distances_m"):
        draw_links("awgn", np.array([1.0, np.nan]), rng_())
    with pytest.raises(ValidationError, match="Generator"):
        draw_links("awgn", np.array([1.0]), np.random.RandomState(0))
    with pytest.raises(ValidationError, match="h_rx_m"):
        draw_links("awgn", np.array([1.0]), rng_(), h_rx_m=-1.0)
    empty = draw_links("winner2_c2", np.zeros(0), rng_())
    assert empty.paths.n_links == 0


# --- exponential (DiPNet analysis) model and AWGN ----------------------------------------------
def test_exponential_model():
    rng = rng_(16)
    d = rng.uniform(5.0, 140.0, N_STAT)
    nl = draw_links("exponential_nlos", d, rng)
    exc = nl.excess_delays() - nl.nlos_bias_s[nl.paths.link_index()]
    assert abs(exc.mean() / 234e-9 - 1) < 0.02  # δ ~ Exp(mean 234 ns)
    assert abs(nl.paths.n_paths.mean() / 24 - 1) < 0.02
    assert nl.paths.n_paths.min() >= 1
    assert abs(nl.nlos_bias_s.mean() / NLOS_BIAS_MEAN_S - 1) < 0.03
    lo = draw_links("exponential_los", d, rng)
    exc = lo.excess_delays()
    i = lo.paths.offsets[:-1]
    np.testing.assert_array_equal(exc[i], 0.0)  # direct path first
    scatter = np.ones(exc.size, bool)
    scatter[i] = False
    assert abs(exc[scatter].mean() / 40.7e-9 - 1) < 0.02
    kr = 10**0.7
    p0 = np.abs(lo.paths.gains[i]) ** 2 / lo.received_power_w
    np.testing.assert_allclose(p0, kr / (kr + 1), rtol=1e-12)
    assert abs(lo.paths.n_paths.mean() / 13 - 1) < 0.02


def test_awgn_single_free_space_path():
    d = np.array([3.0, 40.0, 99.0])
    draw = draw_links("awgn", d, rng_())
    np.testing.assert_array_equal(draw.paths.n_paths, 1)
    np.testing.assert_array_equal(draw.paths.delays, d / C0)
    np.testing.assert_allclose(draw.received_power_w, 1e-3 * 10 ** (-fspl_db(d) / 10), 1e-12)


# --- two-way ranging ---------------------------------------------------------------------------
def _random_pathset(rng, n_links, max_paths):
    counts = rng.integers(0, max_paths + 1, n_links)
    d = [rng.uniform(0, 1e-6, c) for c in counts]
    g = [rng.standard_normal(c) + 1j * rng.standard_normal(c) for c in counts]
    return PathSet.from_lists(d, g)


def test_two_way_composite_matches_double_loop():
    rng = rng_(17)
    f = _random_pathset(rng, 40, 6)
    b = _random_pathset(rng, 40, 5)
    c = two_way_composite(f, b)
    np.testing.assert_array_equal(c.n_paths, f.n_paths * b.n_paths)
    for k in range(40):
        fd, fg = f.link(k)
        bd, bg = b.link(k)
        dd, gg = [], []
        for i in range(fd.size):
            for j in range(bd.size):
                dd.append(fd[i] + bd[j])
                gg.append(fg[i] * bg[j])
        cd, cg = c.link(k)
        np.testing.assert_array_equal(cd, dd)
        np.testing.assert_allclose(cg, gg, rtol=1e-15, atol=0)
    with pytest.raises(ValidationError, match="match forward"):
        two_way_composite(f, b.select(range(3)))


def test_channel_spec_two_way():
    spec = ChannelSpec.from_dict({"scenario": "winner2_c2", "ranging": "two_way"})
    rng = rng_(18)
    d = rng.uniform(5.0, 140.0, 500)
    draw = spec.draw(d, rng)
    fwd, bwd = draw.components
    np.testing.assert_array_equal(fwd.los, bwd.los)
    np.testing.assert_array_equal(draw.paths.n_paths, fwd.paths.n_paths * bwd.paths.n_paths)
    np.testing.assert_allclose(draw.paths.total_power(), bwd.received_power_w, rtol=1e-9)
    rt = 2 * d / C0 + draw.nlos_bias_s
    first = draw.paths.first_delay()
    assert np.all(first >= rt * (1 - 1e-14))
    np.testing.assert_allclose(first, rt, rtol=1e-14)  # LOS·LOS and first-cluster pairs
    assert draw.ranging == "two_way" and draw.ways == 2


def test_channel_spec_from_dict():
    spec = ChannelSpec.from_dict({"scenario": "winner2_d1_los", "nlos_bias_mean_s": 1e-7})
    assert spec.ranging == "one_way" and spec.h_tx_m == 1.5
    assert ChannelSpec.from_dict(spec.to_dict()) == spec
    with pytest.raises(ValidationError, match="did you mean 'ranging'"):
        ChannelSpec.from_dict({"rangin": "two_way"})
    with pytest.raises(ValidationError, match="one_way"):
        ChannelSpec(ranging="three_way")
    with pytest.raises(ValidationError, match="forces LOS"):
        ChannelSpec(scenario="winner2_c2_los", condition="nlos")
    one = ChannelSpec(scenario="winner2_c2").draw(np.array([20.0, 70.0]), rng_(1))
    ref = draw_links("winner2_c2", np.array([20.0, 70.0]), rng_(1))
    np.testing.assert_array_equal(one.paths.gains, ref.paths.gains)


# --- statistics report -------------------------------------------------------------------------
def test_channel_stats_figures(tmp_path):
    out = channel_stats("winner2_c2", n_links=4000, rng=rng_(19), png_path=tmp_path / "p.png")
    fig = out["figures"]
    for key in (
        "los_fraction",
        "ds_log10_mean_los",
        "ds_log10_std_los",
        "ds_log10_mean_nlos",
        "ds_log10_std_nlos",
        "k_factor_db_mean",
        "k_factor_db_std",
        "path_count_mean",
        "excess_delay_mean_s",
    ):
        assert key in fig
    assert fig["ds_log10_mean_los_table"] == -7.39 and fig["k_factor_db_std_table"] == 3.0
    assert abs(fig["los_fraction"] - fig["los_fraction_table"]) < 0.03
    json.dumps({k: v for k, v in out.items() if k != "draw"})
    assert (tmp_path / "p.png").stat().st_size > 10_000

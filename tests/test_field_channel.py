"""Tests of the field channel model (``model = "field"``, ``channels/field_grass_5g.toml``).

The references are written here independently of :mod:`phyloc.channels.field`: the two-ray
field with Fresnel coefficients of a lossy ground (brute force over a distance grid, and the
textbook approximation ``|1 + Γ e^{−jkΔ}|²·(λ/4πd)²``), the image-method reflection point, the
exponential power-delay profile's moments and the source numbers of the file (ITU-R P.2040-1
Table 3, medium dry ground; WINNER II D1.1.2 Table 4-5, B1 LOS).
"""

from __future__ import annotations

import cmath
import itertools
import math
import tomllib

import numpy as np
import pytest

from phyloc.channels import ChannelSpec, draw_links, load_scenario, scenario_names
from phyloc.channels.field import (
    fresnel_reflection,
    ground_permittivity,
    ground_reflection_geometry,
)
from phyloc.channels.scenario import shipped_root
from phyloc.channels.stats import channel_stats
from phyloc.config import dumps_toml
from phyloc.errors import ValidationError
from phyloc.phy import OFDMSystem

C0 = 299_792_458.0
EPS0 = 8.8541878128e-12
NAME = "field_grass_5g"
H = 1.5  # antenna heights of the tests [m]

# --- independent copy of the source numbers -----------------------------------------------------
# ITU-R P.2040-1 Table 3, medium dry ground: eps_r = a f^b, sigma = c f^d (f in GHz), 1-10 GHz
P2040_MEDIUM_DRY = (15.0, -0.1, 0.035, 1.63)
# WINNER II D1.1.2 Table 4-5, B1 LOS: median DS 10^-7.44 s, K-factor mean 9 dB
B1_LOS_DS_S = 10**-7.44
B1_LOS_K_DB = 9.0


def _doc() -> dict:
    with (shipped_root() / f"{NAME}.toml").open("rb") as f:
        return tomllib.load(f)


def _variant(tmp_path, edit, name="v.toml"):
    """A copy of the shipped file with ``edit(doc)`` applied, written to ``tmp_path``."""
    doc = _doc()
    edit(doc)
    path = tmp_path / name
    path.write_text(dumps_toml(doc))
    return path


def _two_ray_only(doc, polarization="vertical"):
    doc["los"]["scatterers"]["count"] = 0
    doc["los"]["diffuse"]["ray_count"] = 0
    doc["los"]["ground"]["polarization"] = polarization


def _eta_ref(fc):
    """η = ε_r − j·60·σ·λ (the file's stated form)."""
    a, b, c, d = P2040_MEDIUM_DRY
    f = fc / 1e9
    return complex(a * f**b, -60.0 * (c * f**d) * C0 / fc)


def _gamma_ref(eta, psi, pol):
    """Fresnel coefficient, grazing-angle form, both -> -1 at grazing incidence."""
    root = cmath.sqrt(eta - math.cos(psi) ** 2)
    s = math.sin(psi)
    num = eta * s if pol == "vertical" else s
    return (num - root) / (num + root)


def _two_ray_power_ref(d, fc, pol, p_tx=1e-3):
    """Brute force: P_tx |λ/(4π)·(e^{−jkd}/d + Γ e^{−jkL}/L)|², image-method path length."""
    lam = C0 / fc
    k = 2 * math.pi / lam
    eta = _eta_ref(fc)
    out = []
    for x in d:
        xr = x * H / (2 * H)  # reflection point (equal heights: halfway)
        length = math.hypot(xr, H) + math.hypot(x - xr, H)
        psi = math.atan2(H, xr)
        g = _gamma_ref(eta, psi, pol)
        field = cmath.exp(-1j * k * x) / x + g * cmath.exp(-1j * k * length) / length
        out.append(p_tx * abs(lam / (4 * math.pi) * field) ** 2)
    return np.array(out)


def _carrier_power(draw):
    """Narrowband power at the carrier, |Σ_l α_l|², per link (independent of the common phase)."""
    g = draw.paths.gains
    off = draw.paths.offsets
    return np.array([abs(g[a:b].sum()) ** 2 for a, b in itertools.pairwise(off)])


# --- the file ----------------------------------------------------------------------------------
def test_the_field_scenario_is_shipped_los_only_with_its_source_numbers():
    assert {NAME, NAME + "_los"} <= set(scenario_names())
    scn = load_scenario(NAME)
    assert scn.model == "field" and scn.forced == "los" and scn.nlos is None
    p = scn.los
    got = (p.permittivity_a, p.permittivity_b, p.conductivity_c_s_m, p.conductivity_d)
    assert got == P2040_MEDIUM_DRY
    assert p.diffuse_delay_spread_s == pytest.approx(B1_LOS_DS_S, rel=2e-3)  # 36.3 ns
    assert p.diffuse_power_ratio_db == -B1_LOS_K_DB
    assert scn.carrier_frequency_range_hz == (1.0e9, 10.0e9)  # P.2040-1 ground rows
    with pytest.raises(ValidationError, match="forces LOS"):
        draw_links(NAME, np.array([10.0]), np.random.default_rng(0), condition="nlos")


# --- ground permittivity and Fresnel coefficients ---------------------------------------------
@pytest.mark.parametrize("fc", [1.0e9, 5.5e9, 5.7e9, 10.0e9])
def test_ground_permittivity_is_eps_r_minus_j_sigma_over_omega_eps0(fc):
    eta = ground_permittivity(fc, *P2040_MEDIUM_DRY)
    a, b, c, d = P2040_MEDIUM_DRY
    sigma = c * (fc / 1e9) ** d
    assert eta.real == pytest.approx(a * (fc / 1e9) ** b, rel=1e-12)
    # σ/(ω ε0): 60·λ = 1/(2π f ε0) to 0.07 % (60 ≈ 1/(2π c ε0) = 59.96)
    assert eta.imag == pytest.approx(-sigma / (2 * math.pi * fc * EPS0), rel=1e-3)
    assert eta == pytest.approx(_eta_ref(fc), rel=1e-12)


def test_ground_permittivity_at_5_5_ghz():
    # 15·5.5^-0.1 = 12.649, 0.035·5.5^1.63 = 0.5636 S/m, 60·σ·λ = 1.843
    eta = ground_permittivity(5.5e9, *P2040_MEDIUM_DRY)
    assert eta.real == pytest.approx(12.649, abs=2e-3)
    assert -eta.imag == pytest.approx(60 * 0.5636 * C0 / 5.5e9, rel=1e-3)


@pytest.mark.parametrize("pol", ["vertical", "horizontal"])
@pytest.mark.parametrize("eta", [4.0, 12.65 - 1.84j, 15.2 - 4.5j, 80.0 - 40.0j])
def test_fresnel_tends_to_minus_one_at_grazing(pol, eta):
    g = fresnel_reflection(eta, [0.0, 1e-7, 1e-4], pol)
    np.testing.assert_allclose(g[0], -1.0, atol=1e-15)
    assert abs(g[1] + 1) < 1e-5
    assert abs(g[2] + 1) < abs(eta) * 1e-3  # 1 + Γ = O(ψ) near grazing


def test_fresnel_closed_form_at_known_angles():
    # lossless η = 4 at ψ = 30°: cos²ψ = 3/4, sqrt(4 − 3/4) = sqrt(3.25) = 1.802776
    r = math.sqrt(3.25)
    gh = fresnel_reflection(4.0, [math.pi / 6], "horizontal")[0]
    gv = fresnel_reflection(4.0, [math.pi / 6], "vertical")[0]
    assert gh == pytest.approx((0.5 - r) / (0.5 + r), abs=1e-14)  # −0.565741
    assert gv == pytest.approx((2.0 - r) / (2.0 + r), abs=1e-14)  # +0.051863
    assert gh.real == pytest.approx(-0.565741, abs=1e-6)
    assert gv.real == pytest.approx(0.051863, abs=1e-6)
    # normal incidence: Γ_h = (1 − √η)/(1 + √η) = −Γ_v, for a lossy ground too
    eta = 12.65 - 1.84j
    gh, gv = (fresnel_reflection(eta, [math.pi / 2], p)[0] for p in ("horizontal", "vertical"))
    ref = (1 - cmath.sqrt(eta)) / (1 + cmath.sqrt(eta))
    assert abs(gh - ref) < 1e-14 and abs(gv + ref) < 1e-14
    # Brewster angle of a lossless ground: tan ψ_B = 1/√η, Γ_v = 0 there
    psi_b = math.atan(1 / math.sqrt(15.0))
    assert abs(fresnel_reflection(15.0, [psi_b], "vertical")[0]) < 1e-14
    # |Γ| < 1 strictly between grazing and normal incidence, for both polarizations
    psi = np.linspace(0.01, 1.5, 50)
    for p in ("vertical", "horizontal"):
        assert np.all(np.abs(fresnel_reflection(12.65 - 1.84j, psi, p)) < 1)


def test_fresnel_rejects_bad_input():
    with pytest.raises(ValidationError, match="polarization"):
        fresnel_reflection(4.0, [0.1], "circular")
    with pytest.raises(ValidationError, match="grazing_rad"):
        fresnel_reflection(4.0, [-0.1], "vertical")


# --- geometry -----------------------------------------------------------------------------------
@pytest.mark.parametrize(("ht", "hr"), [(1.5, 1.5), (0.4, 2.0), (3.0, 1.2)])
def test_reflection_path_length_equals_the_image_method(ht, hr):
    d = np.array([0.5, 3.0, 17.0, 82.6, 400.0, 1.0e4])
    length, excess, psi = ground_reflection_geometry(d, ht, hr)
    for i, x in enumerate(d):
        xr = x * ht / (ht + hr)  # specular point: equal angles on both sides
        ref = math.hypot(xr, ht) + math.hypot(x - xr, hr)
        assert length[i] == pytest.approx(ref, rel=1e-13)
        assert psi[i] == pytest.approx(math.atan2(ht, xr), rel=1e-13)
        assert psi[i] == pytest.approx(math.atan2(hr, x - xr), rel=1e-13)
        # excess without cancellation: (L − d)(L + d) = (h_t + h_r)²
        assert excess[i] * (length[i] + x) == pytest.approx((ht + hr) ** 2, rel=1e-13)
    # far links: L − d → (h_t + h_r)²/(2d)
    assert excess[-1] == pytest.approx((ht + hr) ** 2 / 2e4, rel=1e-7)


def test_drawn_ground_path_arrives_at_l_over_c(tmp_path):
    path = _variant(tmp_path, _two_ray_only)
    d = np.array([2.0, 10.0, 41.3, 90.0])
    draw = draw_links(path, d, np.random.default_rng(1), h_tx_m=H, h_rx_m=H)
    assert draw.paths.n_paths.tolist() == [2, 2, 2, 2]
    t = draw.paths.delays.reshape(-1, 2)
    np.testing.assert_array_equal(t[:, 0], d / C0)  # the direct path at exactly d/c0
    np.testing.assert_allclose(t[:, 1], np.hypot(d, 2 * H) / C0, rtol=1e-14)


# --- two-ray fading ----------------------------------------------------------------------------
@pytest.mark.parametrize("pol", ["vertical", "horizontal"])
@pytest.mark.parametrize("fc", [5.5e9, 5.7e9])
def test_carrier_power_is_the_two_ray_formula(tmp_path, pol, fc):
    """Scatterers and diffuse power off: |Σ α|² equals the brute-force two-ray power at every
    distance, whatever the drawn common phase."""
    path = _variant(tmp_path, lambda doc: _two_ray_only(doc, pol))
    d = np.linspace(3.0, 120.0, 1500)
    system = OFDMSystem(carrier_frequency_hz=fc, tx_power_dbm=0.0)
    draw = draw_links(path, d, np.random.default_rng(2), system=system, h_tx_m=H, h_rx_m=H)
    ref = _two_ray_power_ref(d, fc, pol)
    np.testing.assert_allclose(_carrier_power(draw), ref, rtol=1e-9)
    # the textbook approximation |1 + Γ e^{−jkΔ}|² (λ/4πd)² (d/L ≈ 1) agrees to O((h/d)²)
    lam = C0 / fc
    k = 2 * math.pi / lam
    eta = _eta_ref(fc)
    approx = np.array(
        [
            1e-3
            * (lam / (4 * math.pi * x)) ** 2
            * abs(
                1
                + _gamma_ref(eta, math.atan(2 * H / x), pol)
                * cmath.exp(-1j * k * (math.hypot(x, 2 * H) - x))
            )
            ** 2
            for x in d
        ]
    )
    far = d > 30.0
    np.testing.assert_allclose(ref[far], approx[far], rtol=0.01, atol=1e-3 * ref[far].max())


@pytest.mark.parametrize(("pol", "depth_db"), [("vertical", -7.0), ("horizontal", -25.0)])
def test_deep_fades_at_the_predicted_distances(tmp_path, pol, depth_db):
    """With Γ ≈ −1 the two rays cancel where kΔ = 2πm, Δ ≈ 2 h_t h_r / d: d_m = 2 h² / (m λ)
    (82.6 m, 41.3 m, 27.5 m at 5.5 GHz with 1.5 m antennas). The drawn carrier power has its
    minima there (within 1 %), below free space by the fade depth of the polarization."""
    fc = 5.5e9
    lam = C0 / fc
    path = _variant(tmp_path, lambda doc: _two_ray_only(doc, pol))
    d = np.linspace(15.0, 110.0, 40001)
    system = OFDMSystem(carrier_frequency_hz=fc, tx_power_dbm=0.0)
    draw = draw_links(path, d, np.random.default_rng(3), system=system, h_tx_m=H, h_rx_m=H)
    free = 1e-3 * (lam / (4 * math.pi * d)) ** 2
    rel_db = 10 * np.log10(_carrier_power(draw) / free)
    for m in (1, 2):
        d_m = 2 * H * H / (m * lam)
        win = np.abs(d - d_m) < 0.15 * d_m
        at = d[win][np.argmin(rel_db[win])]
        assert at == pytest.approx(d_m, rel=0.01)
        assert rel_db[win].min() < (depth_db if m == 1 else depth_db + 4.0)
        # and the constructive peak halfway (in 1/d) is above free space
        d_peak = 2 * H * H / ((m + 0.5) * lam)
        assert rel_db[np.argmin(np.abs(d - d_peak))] > 2.0
    # brute-force minima of the reference coincide with those of the draw
    ref_db = 10 * np.log10(_two_ray_power_ref(d[::40], fc, pol) / free[::40])
    np.testing.assert_allclose(rel_db[::40], ref_db, atol=1e-7)


# --- structures and diffuse tail ------------------------------------------------------------------
def test_structure_paths_follow_the_image_amplitude_law(tmp_path):
    def edit(doc):
        doc["los"]["diffuse"]["ray_count"] = 0
        doc["los"]["scatterers"]["count"] = 6

    path = _variant(tmp_path, edit)
    doc = _doc()["los"]["scatterers"]
    lo, hi, loss_db = (
        doc["excess_delay_min_s"],
        doc["excess_delay_max_s"],
        doc["reflection_loss_db"],
    )
    fc = 5.5e9
    lam = C0 / fc
    rng = np.random.default_rng(4)
    d = rng.uniform(2.0, 100.0, 3000)
    system = OFDMSystem(carrier_frequency_hz=fc, tx_power_dbm=0.0)
    draw = draw_links(path, d, rng, system=system, h_tx_m=H, h_rx_m=H)
    assert set(draw.paths.n_paths.tolist()) == {8}
    t = draw.paths.delays.reshape(-1, 8)
    g = draw.paths.gains.reshape(-1, 8)
    exc = t[:, 2:] - d[:, None] / C0  # the ground path (< 10 ns) is second
    assert exc.min() >= lo - 1e-15 and exc.max() <= hi + 1e-15
    unfolded = d[:, None] + C0 * exc
    ref = 1e-3 * 10 ** (-loss_db / 10) * (lam / (4 * math.pi * unfolded)) ** 2
    np.testing.assert_allclose(np.abs(g[:, 2:]) ** 2, ref, rtol=1e-9)
    # uniform excess delays: mean (lo + hi)/2, std (hi − lo)/√12, n = 18000
    n = exc.size
    sd = (hi - lo) / math.sqrt(12)
    assert abs(exc.mean() - (lo + hi) / 2) < 5 * sd / math.sqrt(n)
    # phases uniform relative to the direct path's: mean resultant length ~ 1/√n
    rel = g[:, 2:] / g[:, :1]
    assert abs(np.mean(rel / np.abs(rel))) < 5 / math.sqrt(n)


def test_diffuse_delay_spread_matches_the_file(tmp_path):
    """Diffuse rays: i.i.d. Exp(τ_DS) excess delays of equal power summing to
    10^(r/10)·(direct power). Pooled over links the PDP is exponential with rms spread τ_DS;
    per link the mean squared rms spread of N rays is τ_DS²·(1 − 1/N)."""
    path = _variant(tmp_path, lambda doc: doc["los"]["scatterers"].update(count=0))
    p = load_scenario(path).los
    tau_ds, n_rays, r_db = p.diffuse_delay_spread_s, p.diffuse_ray_count, p.diffuse_power_ratio_db
    fc = 5.5e9
    lam = C0 / fc
    rng = np.random.default_rng(5)
    d = rng.uniform(2.0, 100.0, 4000)
    system = OFDMSystem(carrier_frequency_hz=fc, tx_power_dbm=0.0)
    draw = draw_links(path, d, rng, system=system, h_tx_m=H, h_rx_m=H)
    direct = 1e-3 * (lam / (4 * math.pi * d)) ** 2
    ray = direct * 10 ** (r_db / 10) / n_rays
    link = draw.paths.link_index()
    power = np.abs(draw.paths.gains) ** 2
    diffuse = np.isclose(power, ray[link], rtol=1e-9, atol=0)
    assert np.array_equal(np.bincount(link, diffuse, d.size), np.full(d.size, n_rays))
    tot = np.bincount(link, power * diffuse, d.size)
    np.testing.assert_allclose(tot, direct * 10 ** (r_db / 10), rtol=1e-9)
    exc = (draw.paths.delays - d[link] / C0)[diffuse]
    n = exc.size  # 80000 delays
    assert abs(exc.mean() / tau_ds - 1) < 5 / math.sqrt(n)  # mean of Exp = τ_DS
    assert abs(exc.std() / tau_ds - 1) < 5 * math.sqrt(2 / n)  # sd of s ≈ τ√(2/n)
    per = exc.reshape(d.size, n_rays)
    ms = per.var(axis=1)  # equal powers: the rms spread² of each link's diffuse PDP
    # E[s²] = τ²(1 − 1/N); var(s²) ≤ E[s⁴] bounded by moments of Exp: use the sample sd
    assert abs(ms.mean() - tau_ds**2 * (1 - 1 / n_rays)) < 5 * ms.std() / math.sqrt(ms.size)
    assert np.all(draw.delay_spread_s == tau_ds)


# --- the draw's contract ------------------------------------------------------------------------
def test_power_budget_k_factor_and_order():
    rng = np.random.default_rng(6)
    d = rng.uniform(1.0, 100.0, 2000)
    system = OFDMSystem(carrier_frequency_hz=5.5e9, tx_power_dbm=20.0)
    draw = draw_links(NAME, d, rng, system=system)
    assert np.all(draw.los) and np.all(draw.nlos_bias_s == 0)
    assert np.all(draw.shadowing_db == 0) and np.all(draw.shadowing_std_db == 0)
    budget = 10 ** ((20.0 - draw.path_loss_db - 30) / 10)
    np.testing.assert_allclose(draw.paths.total_power(), budget, rtol=1e-9)
    np.testing.assert_allclose(draw.received_power_w, budget, rtol=1e-12)
    np.testing.assert_array_equal(draw.paths.first_delay(), d / C0)
    link = draw.paths.link_index()
    same = link[1:] == link[:-1]
    assert np.all(np.diff(draw.paths.delays)[same] >= 0)
    p = np.abs(draw.paths.gains) ** 2
    first = draw.paths.offsets[:-1]
    rest = np.bincount(link, p, d.size) - p[first]
    np.testing.assert_allclose(draw.k_factor_db, 10 * np.log10(p[first] / rest), rtol=1e-9)
    # the direct path carries the Friis power
    lam = C0 / 5.5e9
    np.testing.assert_allclose(p[first], 0.1 * (lam / (4 * math.pi * d)) ** 2, rtol=1e-9)


def test_reproducible_with_a_seed():
    d = np.linspace(2.0, 90.0, 50)
    a = draw_links(NAME, d, np.random.default_rng(7))
    b = draw_links(NAME, d, np.random.default_rng(7))
    c = draw_links(NAME, d, np.random.default_rng(8))
    for f in ("delays", "gains", "offsets"):
        np.testing.assert_array_equal(getattr(a.paths, f), getattr(b.paths, f))
    assert not np.array_equal(a.paths.gains, c.paths.gains)


def test_two_way_uses_the_backward_carrier_for_the_backward_fade(tmp_path):
    path = _variant(tmp_path, _two_ray_only)
    spec = ChannelSpec(scenario=str(path), ranging="two_way", backward_carrier_frequency_hz=5.7e9)
    d = np.linspace(20.0, 100.0, 300)
    system = OFDMSystem(carrier_frequency_hz=5.5e9, tx_power_dbm=0.0)
    draw = spec.draw(d, np.random.default_rng(9), system=system)
    fwd, bwd = draw.components
    np.testing.assert_allclose(
        _carrier_power(fwd), _two_ray_power_ref(d, 5.5e9, "vertical"), rtol=1e-9
    )
    np.testing.assert_allclose(
        _carrier_power(bwd), _two_ray_power_ref(d, 5.7e9, "vertical"), rtol=1e-9
    )
    with pytest.raises(ValidationError, match="carrier_frequency_hz"):
        draw_links(NAME, d, np.random.default_rng(0), system=OFDMSystem(carrier_frequency_hz=12e9))


def test_channel_stats_reports_the_fading():
    out = channel_stats(NAME, n_links=400, rng=np.random.default_rng(10))
    f = out["figures"]
    assert f["los_fraction"] == 1.0
    assert f["path_count_mean"] == f["path_count_mean_table"] == 26
    assert f["carrier_gain_db_p10"] < f["carrier_gain_db_median"]
    assert f["sf_std_db_los"] == 0.0


# --- bad files ------------------------------------------------------------------------------------
BAD = [
    (lambda d: d["los"]["ground"].update(polarization="circular"), "los.ground.polarization"),
    (lambda d: d["los"]["ground"].update(permittivity_a=0.5), "los.ground.permittivity_a"),
    (lambda d: d["los"]["ground"].pop("conductivity_d"), "los.ground.conductivity_d"),
    (lambda d: d["los"]["ground"].update(permitivity_b=-0.1), "permitivity_b"),
    (lambda d: d["los"]["scatterers"].update(count=-1), "los.scatterers.count"),
    (lambda d: d["los"]["scatterers"].update(count=2.5), "los.scatterers.count"),
    (
        lambda d: d["los"]["scatterers"].update(excess_delay_min_s=4e-7),
        "los.scatterers.excess_delay_max_s",
    ),
    (lambda d: d["los"]["diffuse"].update(delay_spread_s=0.0), "los.diffuse.delay_spread_s"),
    (lambda d: d["los"]["diffuse"].update(power_ratio_db="low"), "los.diffuse.power_ratio_db"),
    (lambda d: d.update(nlos=dict(d["los"])), "nlos"),
]


@pytest.mark.parametrize(("edit", "key"), BAD, ids=[k for _, k in BAD])
def test_bad_values_give_one_line_errors_naming_the_key(tmp_path, edit, key):
    path = _variant(tmp_path, edit)
    with pytest.raises(ValidationError) as err:
        load_scenario(path)
    msg = str(err.value)
    assert key in msg and "\n" not in msg
    assert msg.startswith("v.toml")


def test_ground_reflection_off_keeps_every_other_path_of_the_same_draw(tmp_path):
    """``[los.ground] reflection = false``: the ground-reflected path carries no power and the
    same seed gives the same direct, structure and diffuse paths (a paired switch)."""
    on = _variant(tmp_path, lambda doc: None, "on.toml")
    off = _variant(tmp_path, lambda doc: doc["los"]["ground"].update(reflection=False), "off.toml")
    d = np.linspace(5.0, 90.0, 400)
    a = draw_links(str(on), d, np.random.default_rng(12))
    b = draw_links(str(off), d, np.random.default_rng(12))
    ga, gb = np.abs(a.paths.gains) ** 2, np.abs(b.paths.gains) ** 2
    np.testing.assert_array_equal(a.paths.offsets, b.paths.offsets)
    np.testing.assert_array_equal(a.paths.delays, b.paths.delays)
    changed = np.abs(ga - gb) > 1e-9 * ga
    # per link exactly one path differs (the ground one) and it carries no power when off;
    # every other path, the direct one included, keeps its power (to rounding)
    per_link = np.bincount(a.paths.link_index()[changed], minlength=d.size)
    np.testing.assert_array_equal(per_link, np.ones(d.size, dtype=np.int64))
    assert np.all(gb[changed] == 0.0) and np.all(ga[changed] > 0.0)
    np.testing.assert_allclose(ga[~changed], gb[~changed], rtol=1e-9)
    ground = (a.excess_delays()[changed] * C0 - (np.sqrt(d**2 + 3.0**2) - d)) / d
    assert np.max(np.abs(ground)) < 1e-9  # at the two-ray excess (L_g - d)/c0, h = 1.5 m

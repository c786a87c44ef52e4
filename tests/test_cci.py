"""Concavity indicator (DiPNet §IV-A, eqs. (35)–(44), App. II–III, Fig. 2)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.integrate import quad

from phyloc.analysis import cci
from phyloc.channels import draw_links
from phyloc.channels.scenario import shipped_root
from phyloc.cli import main
from phyloc.errors import ValidationError
from phyloc.evaluation import cci_experiment
from phyloc.phy.system import C0, OFDMSystem

SYSTEM = OFDMSystem()
N_BIG, FSC_BIG = SYSTEM.n_subcarriers, SYSTEM.subcarrier_spacing_hz


# -- references written from the equations ----------------------------------------------------
def curvature_sum_eq40(x, tau0, n, f_sc):
    """DiPNet eq. (40) literally: −π Σ_{m,n} (S²ω² + jSω/τ0) e^{jSωx}, S = m + n."""
    w = 2 * np.pi * f_sc
    m = np.arange(n) - (n - 1) / 2
    s = (m[:, None] + m[None, :]).ravel()
    terms = (s**2 * w**2 + 1j * s * w / tau0) * np.exp(1j * s * w * x)
    return float(np.real(-np.pi * terms.sum()))


def curvature_by_multiplicity(x, tau0, n, f_sc):
    """The same sum grouped by S (N − |S| pairs each), for large N."""
    w = 2 * np.pi * f_sc
    s = np.arange(-(n - 1), n, dtype=float)
    wt = n - np.abs(s)
    terms = wt * (s**2 * w**2 + 1j * s * w / tau0) * np.exp(1j * s * w * x)
    return float(np.real(-np.pi * terms.sum()))


def theta_average_d2(dtau, x, tau0, n, f_sc, n_theta=4096):
    """∫₀^{2π} D_l(‖p_u − p_v‖)² dθ with D the Dirichlet kernel of DiPNet eq. (36)."""
    w = 2 * np.pi * f_sc
    th = np.arange(n_theta) * (2 * np.pi / n_theta)
    tau = np.sqrt(tau0**2 + dtau**2 - 2 * tau0 * dtau * np.cos(th))  # DiPNet eq. (32)
    arg = tau0 + x - tau  # τ_l − τ
    m = np.arange(n) - (n - 1) / 2
    d = np.exp(1j * w * np.outer(arg, m)).sum(axis=1).real
    return float(np.sum(d * d) * (2 * np.pi / n_theta))


# -- one path: eqs. (36), (40), (41), (43) ------------------------------------------------------
@pytest.mark.parametrize(
    "x",
    [0.0, 1e-13, -3e-12, 2e-10, 4.3e-10, 7e-9, -2.2e-8, 3.1e-7, 1.7e-6, 1 / FSC_BIG + 1e-12],
)
@pytest.mark.parametrize("tau0", [3e-10, 3.3e-8, 3.3e-6])
def test_normalized_curvature_equals_the_sum_of_eq40(x, tau0):
    ref = curvature_by_multiplicity(x, tau0, N_BIG, FSC_BIG) / abs(
        cci.los_curvature(N_BIG, FSC_BIG)
    )
    got = float(cci.normalized_curvature(x, tau0, N_BIG, FSC_BIG))
    assert got == pytest.approx(ref, rel=1e-7, abs=1e-9)


def test_grouped_sum_equals_the_double_sum():
    for x in (0.0, 1.3e-7, -4e-8):
        assert curvature_by_multiplicity(x, 5e-8, 33, 3e5) == pytest.approx(
            curvature_sum_eq40(x, 5e-8, 33, 3e5), rel=1e-10
        )


@pytest.mark.parametrize("n,f_sc", [(33, 3.0e5), (257, 1.0e5)])
@pytest.mark.parametrize("x", [0.0, 2.0e-8, 1.1e-7])
def test_eq40_and_eq41_are_the_second_derivative_of_the_theta_average(n, f_sc, x):
    """Finite differences in Δτ of the θ-integrated D² (DiPNet eqs. (32), (36)) at Δτ = 0."""
    tau0 = 6.0e-8
    h = 2e-3 / (n * f_sc)
    f0 = theta_average_d2(0.0, x, tau0, n, f_sc)
    fh = theta_average_d2(h, x, tau0, n, f_sc)
    f2h = theta_average_d2(2 * h, x, tau0, n, f_sc)
    # f is even in Δτ (θ → θ + π); fourth-order one-sided stencil of the even extension
    second = (-f2h + 16 * fh - 15 * f0) / (6 * h * h)
    ref = cci.normalized_curvature(x, tau0, n, f_sc) * abs(cci.los_curvature(n, f_sc))
    assert second == pytest.approx(float(ref), rel=2e-5)
    if x == 0.0:
        w = 2 * np.pi * f_sc
        assert second == pytest.approx(-np.pi * w**2 * n**2 * (n**2 - 1) / 6, rel=2e-5)


def test_curvature_never_exceeds_the_bound_of_eq43():
    x = np.linspace(-2e-6, 2e-6, 400001)
    for d0 in (0.1, 1.0, 30.0):
        r = cci.normalized_curvature(x, d0 / C0, N_BIG, FSC_BIG)
        bound = cci.curvature_bound(d0, SYSTEM.bandwidth_hz)
        assert r.max() <= bound * (1 + 1e-12)
        assert r.max() > 0.5 * (bound - 1.0)  # and the 1/(πBd0) excess is really reached
        assert r.min() >= -bound * (1 + 1e-12)  # (43) with |S| bounds both signs


# -- Appendix III -------------------------------------------------------------------------------
def eq_III3(tau0, a_l, n, f_sc):
    w = 2 * np.pi * f_sc
    m = np.arange(n) - (n - 1) / 2
    s = (m[:, None] + m[None, :]).ravel()
    return np.pi * (a_l / tau0 - a_l**2) * np.sum(s**2 * w**2 / (s**2 * w**2 + a_l**2))


def eq_III1(tau0, a_n, a_b, n, f_sc):
    w = 2 * np.pi * f_sc
    m = np.arange(n) - (n - 1) / 2
    s2 = ((m[:, None] + m[None, :]).ravel() * w) ** 2
    num = s2 * (tau0 * s2 - a_n * a_b * tau0 + a_b + a_n)
    return np.pi * a_n * a_b * np.sum(num / (tau0 * (s2 + a_n**2) * (s2 + a_b**2)))


@pytest.mark.parametrize("tau0", [1e-9, 2e-8, 4e-7])
def test_appendix3_equals_numerical_integration_of_eq40(tau0):
    n, f_sc = 33, 3.0e5  # B = 9.9 MHz: quad resolves the oscillations
    a_l, a_n, a_b = 1 / 40e-9, 1 / 120e-9, 1 / 300e-9
    scale = abs(cci.los_curvature(n, f_sc))

    def los(x):
        return a_l * math.exp(-a_l * x) * curvature_sum_eq40(x, tau0, n, f_sc)

    def nlos(x):  # δ + b: the hypo-exponential density
        p = a_n * a_b / (a_b - a_n) * (math.exp(-a_n * x) - math.exp(-a_b * x))
        return p * curvature_sum_eq40(x, tau0, n, f_sc)

    num_l = quad(los, 0, 40 / a_l, limit=400, epsabs=0, epsrel=1e-10)[0]
    num_n = quad(nlos, 0, 40 / a_n, limit=400, epsabs=0, epsrel=1e-10)[0]
    assert eq_III3(tau0, a_l, n, f_sc) == pytest.approx(num_l, rel=1e-7)
    assert eq_III1(tau0, a_n, a_b, n, f_sc) == pytest.approx(num_n, rel=1e-7)
    got_l = cci.expected_exponential_curvature(tau0, a_l, math.inf, n, f_sc) * scale
    got_n = cci.expected_exponential_curvature(tau0, a_n, a_b, n, f_sc) * scale
    assert float(got_l) == pytest.approx(num_l, rel=1e-7)
    assert float(got_n) == pytest.approx(num_n, rel=1e-7)


def test_appendix3_at_full_size_equals_its_literal_sum():
    tau0 = np.array([3e-10, 3e-8, 3e-6])
    a_l, a_n, a_b = 1 / 40.7e-9, 1 / 234e-9, 1 / 300e-9
    scale = abs(cci.los_curvature(N_BIG, FSC_BIG))
    got_l = cci.expected_exponential_curvature(tau0, a_l, math.inf, N_BIG, FSC_BIG) * scale
    got_n = cci.expected_exponential_curvature(tau0, a_n, a_b, N_BIG, FSC_BIG) * scale
    for i, t in enumerate(tau0):
        assert got_l[i] == pytest.approx(eq_III3(t, a_l, N_BIG, FSC_BIG), rel=1e-9)
        assert got_n[i] == pytest.approx(eq_III1(t, a_n, a_b, N_BIG, FSC_BIG), rel=1e-9)


# -- scenario level -----------------------------------------------------------------------------
LOS_SCENARIOS = ["winner2_c2", "winner2_d1", "winner2_b1", "winner2_a1", "exponential"]


@pytest.mark.parametrize("name", [*LOS_SCENARIOS, "winner2_c2_los"])
def test_bound_lies_above_the_exponential_form_and_both_tend_to_awgn(name):
    c = cci.cci_curves(name, SYSTEM, points=200)
    assert np.all(c["bound"] >= c["exponential"] - 1e-12)
    lower = (
        c["awgn"] - cci.curvature_bound(c["d0_m"], SYSTEM.bandwidth_hz) * c["powers"].other_power
    )
    assert np.all(c["exponential"] >= lower - 1e-12)
    # the CCI minus the AWGN benchmark is the non-direct power times a curvature in [-1, bound]
    excess = c["bound"] - c["awgn"]
    assert np.allclose(
        excess, cci.curvature_bound(c["d0_m"], SYSTEM.bandwidth_hz) * c["powers"].other_power
    )
    # the crossing found is a crossing: negative everywhere above it
    d = c["negative_above_m"]
    fine = np.geomspace(d * 1.0001, 1000.0, 500)
    assert np.all(cci.cci_bound(cci.expected_powers(name, fine, SYSTEM), SYSTEM) < 0)


def test_awgn_scenario_is_its_own_benchmark():
    c = cci.cci_curves("awgn", SYSTEM, points=50)
    for key in ("bound", "exponential", "awgn"):
        assert np.all(c[key] == -1.0)
    assert c["negative_above_m"] == 0.1


def test_expected_powers_equal_the_means_of_drawn_links():
    """Gauss–Hermite over correlated SF and K (WINNER II Table 4-5) against the sampler."""
    n = 200_000
    rng = np.random.default_rng(3)
    for d0 in (8.0, 60.0):
        pw = cci.expected_powers("winner2_c2", [d0], SYSTEM)
        los = draw_links("winner2_c2_los", np.full(n, d0), rng, system=SYSTEM)
        nlos = draw_links("winner2_c2_nlos", np.full(n, d0), rng, system=SYSTEM)
        k = 10 ** (los.k_factor_db / 10)
        direct = los.received_power_w * k / (k + 1)
        scatter = los.received_power_w / (k + 1)
        norm = pw.los_direct_w[0]
        for sample, expect in (
            (direct, 1.0),
            (scatter, pw.los_scatter[0]),
            (nlos.received_power_w, pw.nlos_total[0]),
        ):
            se = sample.std() / math.sqrt(n) / norm
            assert abs(sample.mean() / norm - expect) < 4.5 * se


def test_monte_carlo_agrees_with_the_closed_form_for_the_exponential_scenario():
    rng = np.random.default_rng(2024)
    rates = cci.exponential_rates("exponential")
    d = np.array([0.15, 0.6, 2.0, 25.0, 90.0, 400.0])
    pw = cci.expected_powers("exponential", d, SYSTEM)
    closed = cci.cci_exponential(pw, rates, SYSTEM)
    z = []
    for i, d0 in enumerate(d):
        m, se = cci.cci_monte_carlo("exponential", d0, 20_000, rng, SYSTEM)
        z.append((m - closed[i]) / se)
    assert np.max(np.abs(z)) < 4.0, z


def test_monte_carlo_stays_below_the_bound_for_winner2():
    rng = np.random.default_rng(7)
    for name in ("winner2_c2", "winner2_d1"):
        for d0 in (0.2, 1.0, 40.0):
            m, se = cci.cci_monte_carlo(name, d0, 5000, rng, SYSTEM)
            b = cci.cci_bound(cci.expected_powers(name, [d0], SYSTEM), SYSTEM)[0]
            assert m < b + 4 * se


def test_min_bandwidth_puts_the_bound_at_zero():
    for name, d0 in (("winner2_c2", 0.5), ("winner2_d1", 3.0), ("exponential", 20.0)):
        pw = cci.expected_powers(name, [d0], SYSTEM)
        b = float(cci.min_bandwidth_hz(pw)[0])
        sys_b = OFDMSystem(subcarrier_spacing_hz=b / SYSTEM.n_subcarriers)
        assert cci.cci_bound(pw, sys_b)[0] == pytest.approx(0.0, abs=1e-12)
        wider = OFDMSystem(subcarrier_spacing_hz=1.01 * b / SYSTEM.n_subcarriers)
        assert cci.cci_bound(pw, wider)[0] < 0


def test_no_bandwidth_helps_when_other_paths_outweigh_the_direct_one(tmp_path):
    text = _read_shipped("exponential.toml").replace(
        "los_to_scatter_power_db = 7.0", "los_to_scatter_power_db = -3.0"
    )
    f = tmp_path / "weak_los.toml"
    f.write_text(text.replace('name = "exponential"', 'name = "weak_los"'))
    pw = cci.expected_powers(f, [5.0], SYSTEM)
    assert math.isinf(cci.min_bandwidth_hz(pw)[0])
    c = cci.cci_curves(f, SYSTEM, points=50)
    assert math.isinf(c["negative_above_m"])  # a user's file works like a shipped one


def _read_shipped(fname):
    return (shipped_root() / fname).read_text()


# -- errors ---------------------------------------------------------------------------------
def test_bad_inputs_name_the_key():
    with pytest.raises(ValidationError, match=r"scenario.*LOS"):
        cci.expected_powers("winner2_c2_nlos", [1.0])
    with pytest.raises(ValidationError, match="d0_m"):
        cci.expected_powers("winner2_c2", [0.0, 1.0])
    with pytest.raises(ValidationError, match="bias_rate"):
        cci.expected_exponential_curvature(1e-8, 1e7, -1.0, 33, 1e5)
    with pytest.raises(ValidationError, match=r"experiment\.scenarios\[1\]"):
        spec = cci_experiment.CCIExperimentSpec(scenarios=("winner2_c2", "nope"), links=0)
        cci_experiment.study(spec.scenarios, SYSTEM, spec)
    with pytest.raises(ValidationError, match="listed twice"):
        cci_experiment.study(["winner2_c2", "winner2_c2"], SYSTEM)
    with pytest.raises(ValidationError, match=r"experiment\.links"):
        cci_experiment.CCIExperimentSpec(links=1)
    with pytest.raises(ValidationError, match=r"experiment\.d0_range_m"):
        cci_experiment.CCIExperimentSpec(d0_range_m=(10.0, 1.0))


@pytest.mark.parametrize(
    "argv,key",
    [
        (["winner2_c2_nlos"], "scenario"),
        (["no_such_scenario"], "SCENARIO[0]"),
        (["exponential", "--bandwidth-hz", "-3"], "--bandwidth-hz"),
        (["exponential", "--subcarriers", "64"], "--subcarriers"),
        (["exponential", "--mc-points", "1"], "--mc-points"),
        (["exponential", "--distance-m", "0"], "--distance-m"),
        (["exponential", "--carrier-hz", "9e9"], "system.carrier_frequency_hz"),
        (["BAD_FILE"], "los.clusters.r_tau"),
    ],
)
def test_cli_errors_are_one_line(argv, key, capsys, tmp_path):
    bad = tmp_path / "mine.toml"
    bad.write_text(_read_shipped("winner2_c2_los.toml").replace("r_tau = 2.5", "r_tau = 0.5"))
    argv = [str(bad) if a == "BAD_FILE" else a for a in argv]
    code = main(["analyze", "cci", *argv, "--png", str(tmp_path / "x.png"), "--links", "0"])
    err = capsys.readouterr().err.strip()
    assert code != 0 and len(err.splitlines()) == 1 and key in err, err
    assert not (tmp_path / "x.png").exists()


def test_cli_writes_the_named_figures(tmp_path, capsys):
    out = tmp_path / "cci.json"
    png = tmp_path / "cci.png"
    argv = ["analyze", "cci", "exponential", "awgn", "--links", "3000", "--mc-points", "4"]
    assert main([*argv, "--json", str(out), "--png", str(png), "--no-progress"]) == 0
    doc = json.loads(out.read_text())
    f = doc["figures"]
    c = cci.cci_curves("exponential", SYSTEM)
    assert f["cci.exponential.negative_above_m"] == pytest.approx(c["negative_above_m"])
    assert f["cci.exponential.exponential.negative_above_m"] == pytest.approx(
        c["exponential_negative_above_m"]
    )
    assert f["cci.exponential.mc_z"] < 4.0
    assert f["cci.awgn.mc_z"] == 0.0  # one path of curvature −1 per link: no variance
    pw = cci.expected_powers("exponential", [10.0], SYSTEM)
    assert f["cci.exponential.min_bandwidth_hz"] == pytest.approx(cci.min_bandwidth_hz(pw)[0])
    assert png.stat().st_size > 10_000
    # nothing is overwritten without --force
    assert main([*argv, "--json", str(out), "--png", str(tmp_path / "other.png")]) != 0
    assert "exists" in capsys.readouterr().err


def test_recipe_runs_and_is_the_same_on_two_workers(tmp_path):
    from pathlib import Path

    from phyloc.config import load_recipe

    recipe = load_recipe(Path(__file__).parents[1] / "datasets" / "dipnet_fig2_cci.toml")
    one = cci_experiment.CCI.run(recipe, fast=True, progress=False)
    two = cci_experiment.CCI.run(recipe, fast=True, workers=2, progress=False)
    assert (
        one["series"]["cci.winner2_c2.mc"].tolist() == two["series"]["cci.winner2_c2.mc"].tolist()
    )
    assert set(one["meta"]["scenarios"]) == {"winner2_c2", "winner2_d1"}


def test_figures_are_exact_or_grid_statistics_without_intervals():
    """No CCI figure is pooled over units (one unit: one Monte Carlo distance, estimating the
    CCI there): no interval keys, no per-unit values; the Monte Carlo figures are the grid
    statistics of the per-distance means and standard errors in the series."""
    spec = cci_experiment.CCIExperimentSpec(
        scenarios=("exponential",), links=400, mc_points=3, points=50
    )
    res = cci_experiment.study(spec.scenarios, SYSTEM, spec, seed=3, progress=False)
    f, s = res["figures"], res["series"]
    assert not [k for k in f if k.endswith((".ci_low", ".ci_high", ".ratio"))]
    assert not [k for k in s if k.endswith(".units")]
    p = "cci.exponential"
    d, m, se = (np.asarray(s[f"{p}.{k}"]) for k in ("mc_d0_m", "mc", "mc_se"))
    assert d.size == m.size == se.size == 3 and np.all(se > 0)
    pw = cci.expected_powers("exponential", d, SYSTEM)
    closed = cci.cci_exponential(pw, cci.exponential_rates("exponential"), SYSTEM)
    assert f[f"{p}.mc_z"] == pytest.approx(np.max(np.abs(m - closed) / se), rel=1e-12)
    bound = cci.cci_bound(pw, SYSTEM)
    assert f[f"{p}.mc_above_bound_z"] == pytest.approx(np.max((m - bound) / se), rel=1e-12)
    assert f[f"{p}.mc.negative_above_m"] == cci.negative_above(d, m)


# -- the expected SCF of eq. (35) ---------------------------------------------------------------
@pytest.mark.parametrize("name", ["awgn", "exponential", "winner2_c2", "winner2_d1"])
@pytest.mark.parametrize("d0", [0.2, 10.0, 200.0])
def test_expected_scf_curvature_at_the_truth_is_the_cci(name, d0):
    """Finite differences of eq. (35) at Δd = 0 equal CCI·ω²(N² − 1)/12/c0² (eqs. (41)–(42))."""
    h = 0.002 * C0 / SYSTEM.bandwidth_hz
    f = cci.expected_scf(name, d0, [0.0, h, 2 * h], SYSTEM)
    second = (-f[2] + 16 * f[1] - 15 * f[0]) / (6 * h * h)
    pw = cci.expected_powers(name, [d0], SYSTEM)
    c = cci.cci_exponential(pw, cci.exponential_rates(name), SYSTEM)[0]
    n = SYSTEM.n_subcarriers
    assert second == pytest.approx(c * SYSTEM.omega**2 * (n * n - 1) / 12 / C0**2, rel=1e-4)
    # at the truth: the LOS power plus every other path's kernel value E[D²(δ + b)]/N² ≤ power
    assert f[0] <= pw.p_los[0] + pw.other_power[0] + 1e-12


def test_expected_scf_peak_leaves_the_truth_only_where_the_cci_is_positive():
    off = np.linspace(0.0, 0.5, 201) * C0 / SYSTEM.bandwidth_hz
    d1_near = cci.expected_scf("winner2_d1", 0.2, off, SYSTEM)  # exponential CCI > 0 here
    assert np.argmax(d1_near) > 0
    d1_far = cci.expected_scf("winner2_d1", 10.0, off, SYSTEM)  # CCI < 0
    assert np.argmax(d1_far) == 0 and np.all(np.diff(d1_far) < 0)


def test_expected_scf_equals_the_theta_average_of_drawn_paths():
    """Eq. (35) for the exponential scenario against the mean SCF of drawn links (θ uniform,
    noise-free)."""
    rng = np.random.default_rng(9)
    d0, n_links = 5.0, 40_000
    draw = draw_links("exponential", np.full(n_links, d0), rng, system=SYSTEM)
    norm = cci.expected_powers("exponential", [d0], SYSTEM).los_direct_w[0]
    link = draw.paths.link_index()
    theta = rng.uniform(0, 2 * np.pi, n_links)[link]
    dd = 0.7 * C0 / SYSTEM.bandwidth_hz
    tau = np.sqrt(d0**2 + dd**2 - 2 * d0 * dd * np.cos(theta)) / C0
    u = 0.5 * SYSTEM.omega * (draw.paths.delays - tau)
    n = SYSTEM.n_subcarriers
    kern = np.where(np.abs(np.sin(u)) < 1e-12, n, np.sin(n * u) / np.sin(u))
    # the SCF itself, |Σ_l α_l D(τ_l − τ)|²: cross terms included (zero mean, DiPNet App. II)
    amp = draw.paths.gains * kern
    re = np.bincount(link, amp.real, n_links)
    im = np.bincount(link, amp.imag, n_links)
    q = (re**2 + im**2) / (norm * n * n)
    expect = cci.expected_scf("exponential", d0, [dd], SYSTEM, n_theta=256)[0]
    assert abs(q.mean() - expect) < 4 * q.std() / np.sqrt(n_links)


# -- models without closed-form powers: tr38901 and tdl (powers from drawn links) -------------
def test_drawn_powers_agree_with_the_closed_form_where_there_is_one():
    """The estimator the tr38901 and tdl models use, applied to WINNER II C2, reproduces the
    Gauss-Hermite closed form within its Monte Carlo error (lognormal SF: the relative s.e.
    of a mean of 10^(SF/10) over n links is sqrt(exp((σ ln10/10)²) − 1)/sqrt(n))."""
    n = 40_000
    d = np.array([3.0, 40.0, 150.0])
    closed = cci.expected_powers("winner2_c2", d, SYSTEM)
    drawn = cci.drawn_powers("winner2_c2", d, SYSTEM, links=n, seed=77)
    np.testing.assert_array_equal(drawn.p_los, closed.p_los)
    for sigma_db, a, b in (
        (8.0, drawn.los_direct_w, closed.los_direct_w),  # σ_SF <= 8 dB in C2
        (8.0, drawn.nlos_total * drawn.los_direct_w, closed.nlos_total * closed.los_direct_w),
        (8.0, drawn.los_scatter, closed.los_scatter),
    ):
        s = sigma_db * math.log(10) / 10
        rel_se = math.sqrt(math.expm1(s * s)) / math.sqrt(n)
        assert np.all(np.abs(a / b - 1) < 4.5 * rel_se), (a / b - 1, rel_se)


@pytest.mark.parametrize("name", ["tr38901_umi", "tr38901_inf_dh", "tdl_d"])
def test_the_los_ray_leads_every_drawn_los_link(name):
    # drawn_powers takes the first path of a LOS link as its direct power: K/(K+1) of the
    # link (TR 38.901 step 6), at excess delay 0
    d = draw_links(name, np.linspace(5.0, 200.0, 2000), np.random.default_rng(5), condition="los")
    first = d.paths.offsets[:-1]
    assert np.all(d.excess_delays()[first] == 0.0)
    if not name.startswith("tdl"):  # tdl: the other taps fade, so only the order is fixed
        k = 10 ** (d.k_factor_db / 10)
        p0 = np.abs(d.paths.gains[first]) ** 2
        np.testing.assert_allclose(p0 / d.received_power_w, k / (k + 1), rtol=1e-12)


@pytest.mark.parametrize("name", ["tr38901_umi", "tr38901_inh_mixed", "tdl_d"])
def test_drawn_model_monte_carlo_stays_below_its_bound(name):
    """DiPNet eq. (44) bounds the CCI for any delays: the Monte Carlo CCI of TR 38.901 and TDL
    links lies below the bound computed from their drawn powers (within its error)."""
    rng = np.random.default_rng(2026)
    d = np.array([0.3, 5.0, 30.0, 120.0])
    pw = cci.expected_powers(name, d, SYSTEM)
    bound = cci.cci_bound(pw, SYSTEM)
    for i, d0 in enumerate(d):
        m, se = cci.cci_monte_carlo(name, d0, 3000, rng, SYSTEM)
        assert m - bound[i] < 4.0 * se + 0.02 * abs(bound[i]), (d0, m, bound[i], se)
        assert m >= -pw.p_los[i] * 1.3 - 4 * se  # the direct path gives exactly −P_LOS


def test_analyze_cci_of_tr38901_has_no_exponential_curve(tmp_path, capsys):
    out = tmp_path / "c.json"
    png = tmp_path / "c.png"
    args = ["analyze", "cci", "tr38901_umi", "--links", "200", "--mc-points", "3"]
    assert main([*args, "--json", str(out), "--png", str(png), "--no-progress"]) == 0
    f = json.loads(out.read_text())["figures"]
    assert f["cci.tr38901_umi.exponential.negative_above_m"] is None  # NaN: no App. III
    assert "cci.tr38901_umi.mc_z" not in f and "cci.tr38901_umi.scf_argmax_offset_m" not in f
    assert "n/a (drawn)" in capsys.readouterr().out and png.exists()


def test_the_tr38901_cci_recipe_runs_fast_and_its_monte_carlo_respects_the_bound(
    tmp_path, capsys, monkeypatch
):
    """``datasets/cci_tr38901.toml --fast`` (the CI setting of a recipe on the new channels):
    every scenario's Monte Carlo CCI lies below the bound (44) within its error."""
    from pathlib import Path

    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    recipe = Path(__file__).parents[1] / "datasets" / "cci_tr38901.toml"
    out = tmp_path / "res"
    assert main(["evaluate", str(recipe), "--fast", "--out", str(out)]) == 0
    doc = json.loads((out / "results.json").read_text())
    f = doc["figures"]
    assert len(doc["meta"]["scenarios"]) == 7
    for s in doc["meta"]["scenarios"]:
        assert f[f"cci.{s}.mc_above_bound_z"] < 4.0, s
        assert f[f"cci.{s}.exponential.negative_above_m"] is None
    assert (out / "cci_tr38901.png").exists()

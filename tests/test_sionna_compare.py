"""phyloc's TR 38.901 channels against Sionna's (``phyloc channel-compare``).

The statistics helpers are checked against closed forms and a per-link loop; the comparison
itself runs where Sionna is installed (``pip install sionna``) and is skipped elsewhere; the
stored run under ``docs/results/sionna_tr38901`` must print and draw from its JSON alone.
"""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from phyloc.channels import sionna_compare as sc
from phyloc.channels import sionna_report as sr
from phyloc.cli import main

STORED = Path(__file__).resolve().parents[1] / "docs" / "results" / "sionna_tr38901"
SKIP = "Sionna is not installed (pip install sionna): the comparison with Sionna is skipped"


@pytest.fixture(scope="module")
def umi():
    """UMi at 3.5 GHz, 3000 links per draw (LOS state drawn, forced LOS, forced NLOS)."""
    pytest.importorskip("sionna", reason=SKIP)
    return sc.compare("tr38901_umi", n_links=3000, carrier_frequency_hz=3.5e9, seed=11)


def _row(result, section, key):
    return next(r for r in result["sections"][section] if r["key"] == key)


# -- helpers (no Sionna) ---------------------------------------------------------------------
def test_two_equal_paths_have_the_closed_form_statistics():
    """Two paths of equal power Δ apart: mean excess delay Δ/2, RMS spread Δ/2, first share
    1/2; a path of zero power is ignored."""
    s = sc.pdp_statistics([0, 0, 0, 1], [3e-7, 5e-7, 9e-7, 2e-7], [2.0, 2.0, 0.0, 1.0], 2)
    assert s["mean_delay_s"][0] == pytest.approx(1e-7)
    assert s["rms_delay_s"][0] == pytest.approx(1e-7)
    assert s["first_share"].tolist() == [0.5, 1.0]
    assert s["n_paths"].tolist() == [2, 1]
    assert s["rms_delay_s"][1] == 0.0


def test_pdp_statistics_match_a_per_link_loop():
    rng = np.random.default_rng(4)
    n = 50
    counts = rng.integers(1, 9, n)
    link = np.repeat(np.arange(n), counts)
    delay = rng.uniform(0, 1e-6, link.size)
    power = rng.exponential(1.0, link.size)
    s = sc.pdp_statistics(link, delay, power, n)
    for i in range(n):
        t, p = delay[link == i], power[link == i]
        t = t - t.min()
        m1 = np.sum(p * t) / p.sum()
        assert s["mean_delay_s"][i] == pytest.approx(m1, rel=1e-9, abs=1e-20)
        rms = np.sqrt(np.sum(p * (t - m1) ** 2) / p.sum())
        assert s["rms_delay_s"][i] == pytest.approx(rms, rel=1e-9, abs=1e-20)
        assert s["first_share"][i] == pytest.approx(p[t == 0].sum() / p.sum())


def test_paths_at_one_delay_add_coherently_or_in_power():
    link, delay = [0, 0, 0, 1], [1.0, 1.0, 2.0, 1.0]
    lk, dl, g = sc.merge_equal_delays(link, delay, np.array([1.0, -1.0, 2j, 1.0]))
    assert lk.tolist() == [0, 0, 1] and dl.tolist() == [1.0, 2.0, 1.0]
    assert np.allclose(g, [0.0, 2j, 1.0])  # opposite phases cancel
    _, _, p = sc.merge_equal_delays(link, delay, np.array([1.0, 1.0, 4.0, 1.0]))
    assert p.tolist() == [2.0, 4.0, 1.0]


@pytest.mark.parametrize("clusters", range(1, 26))
def test_cluster_count_is_recovered_from_the_path_count(clusters):
    """``c`` clusters, the two strongest split into three paths each: ``c + 2·min(c, 2)``."""
    paths = clusters + 2 * min(clusters, 2)
    assert sc.cluster_counts(np.array([paths]), 2, 2).tolist() == [clusters]


def test_without_sionna_the_command_says_how_to_install_it(monkeypatch, tmp_path, capsys):
    for mod in ("sionna", "sionna.phy", "sionna.phy.channel", "sionna.phy.channel.tr38901"):
        monkeypatch.setitem(sys.modules, mod, None)
    png = tmp_path / "c.png"
    assert main(["channel-compare", "tr38901_umi", "--png", str(png)]) == 2
    err = capsys.readouterr().err.strip()
    assert "pip install sionna" in err and len(err.splitlines()) == 1
    assert not png.exists()
    assert not sc.sionna_available()


def test_outputs_and_arguments_are_checked_before_any_work(monkeypatch, tmp_path, capsys):
    def no_work(*a, **k):
        raise AssertionError("the comparison ran")

    monkeypatch.setattr(sc, "compare", no_work)
    png = tmp_path / "c.png"
    png.write_bytes(b"x")
    assert main(["channel-compare", "tr38901_umi", "--png", str(png)]) == 2
    assert "--force" in capsys.readouterr().err
    cases = [
        ["tr38901_foo"],
        ["tr38901_umi", "--links", "10"],
        ["tr38901_rma", "--carrier-frequency-hz", "28e9"],
    ]
    for extra in cases:
        assert main(["channel-compare", *extra, "--png", str(tmp_path / "d.png")]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("phyloc: error:") and len(err.splitlines()) == 1
    assert sc.check_arguments(["all"], 100, 3.5e9) == list(sc.GEOMETRIES)


# -- the stored run (no Sionna) --------------------------------------------------------------
def test_the_stored_comparison_prints_and_draws_from_its_json(tmp_path):
    doc = json.loads((STORED / "results.json").read_text())
    assert doc["meta"]["command"] == "channel-compare"
    results = sr.results_from_json(doc)
    names = {r["scenario"] for r in results}
    assert {"tr38901_umi", "tr38901_uma", "tr38901_rma"} <= names
    for res in results:
        text = sr.format_comparison(res)
        assert res["scenario"] in text and "verdict" in text
    out = sr.plot_comparison(results, tmp_path / "c.png")
    assert out.stat().st_size > 10000
    counts = sr.verdict_counts(results)
    assert counts == doc["meta"]["verdicts"]


# -- against Sionna --------------------------------------------------------------------------
def test_the_same_links_are_drawn_at_the_same_distances(umi):
    """Both packages evaluate the same P_LOS and path loss at every link (the placement of
    Sionna's UT gives phyloc's 3-D distances)."""
    assert _row(umi, "los_probability", "p_los_law")["verdict"] == "agrees"
    for cond in ("los", "nlos"):
        row = _row(umi, cond, "pl_db")
        assert row["max_deviation"] < sc.PATHLOSS_TOL_DB


def test_umi_los_probability_agrees_in_every_distance_bin(umi):
    s = umi["series"]["los_probability"]
    n = np.asarray(s["links"])
    p1, p2 = np.asarray(s["los_fraction_phyloc"]), np.asarray(s["los_fraction_sionna"])
    pooled = (p1 + p2) / 2
    se = np.sqrt(pooled * (1 - pooled) * 2 / n)
    z = np.where(se > 0, (p1 - p2) / np.where(se > 0, se, 1), 0.0)
    assert np.all(np.abs(z) <= sc.Z_CRIT), z
    # and each package follows the table: the law averaged over the bin, 4 standard errors
    law = np.asarray(s["p_los_law"])
    se_law = np.sqrt(law * (1 - law) / n) + 1e-12
    assert np.all(np.abs(p1 - law) <= 4 * se_law)
    assert np.all(np.abs(p2 - law) <= 4 * se_law)


@pytest.mark.parametrize("cond, sigma_sf", [("los", 4.0), ("nlos", 7.82)])
def test_umi_shadow_fading_std_agrees(umi, cond, sigma_sf):
    row = _row(umi, cond, "sf_std")
    assert row["verdict"] == "agrees"
    se = sigma_sf / np.sqrt(2 * (umi["links"] - 1))
    for side in ("phyloc", "sionna"):
        assert abs(row[side] - sigma_sf) <= sc.Z_CRIT * se  # both draw Table 7.4.1-1's σ_SF


@pytest.mark.parametrize("cond", ["los", "nlos"])
def test_umi_log_delay_spread_passes_the_ks_test(umi, cond):
    row = _row(umi, cond, "lgds_ks")
    assert row["p_value"] >= 0.01


@pytest.mark.parametrize("cond", ["los", "nlos"])
def test_umi_mean_power_delay_profiles_agree(umi, cond):
    """Cluster delays and powers, the 25 dB removal and the sub-clusters: the mean-power PDPs
    of the two packages have the same distributions."""
    for key in ("mean.mean_delay", "mean.rms_delay", "clusters", "mean.n_paths"):
        assert _row(umi, cond, key)["verdict"] == "agrees", key


@pytest.mark.parametrize("cond", ["los", "nlos"])
def test_umi_shadow_fading_correlates_with_the_delay_spread_as_in_sionna(umi, cond):
    assert _row(umi, cond, "corr_sf_ds")["verdict"] == "agrees"


def test_tdl_d_taps_agree_with_sionna():
    pytest.importorskip("sionna", reason=SKIP)
    res = sc.compare("tdl_d", n_links=2000, seed=3)
    rows = {r["key"]: r for r in res["sections"]["los"]}
    for key in ("tap_delays", "tap_power", "specular_share", "real.rms_delay"):
        assert rows[key]["verdict"] == "agrees", key

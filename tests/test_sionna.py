"""phyloc's synthesis against Sionna's (``phyloc bench sionna``): the two compute the same
signal. Runs where Sionna is installed (``pip install "phyloc[sionna]"``), skipped elsewhere."""

import numpy as np
import pytest

from phyloc.cli import main
from phyloc.commands import _import_benchmark
from phyloc.phy.synthesis import synthesize

# the installed package (phyloc.benchmarks) or, when phyloc is the working tree, ./benchmarks
bench_sionna = _import_benchmark("phyloc.benchmarks.bench_sionna")


def test_without_sionna_the_benchmark_says_how_to_install_it(monkeypatch, capsys):
    monkeypatch.setattr(bench_sionna, "available", lambda: False)
    fig = bench_sionna.report(quick=True)  # phyloc's one-link figures only
    assert set(fig) == {
        "sionna.one_link_phyloc_s",
        "sionna.one_link_validation_s",
        "sionna.one_link_validation_share",
    }
    share = fig["sionna.one_link_validation_s"] / fig["sionna.one_link_phyloc_s"]
    assert fig["sionna.one_link_validation_share"] == share > 0
    assert main(["bench", "sionna", "--quick"]) == 0
    assert 'pip install "phyloc[sionna]"' in capsys.readouterr().out


@pytest.mark.skipif(not bench_sionna.available(), reason=bench_sionna.INSTALL)
@pytest.mark.parametrize("precision, tol", [("double", 1e-12), ("single", 1e-5)])
def test_sionna_builds_the_same_noise_free_signal(precision, tol):
    """``cir_to_ofdm_channel`` (h(f) = Σ a e^{−j2πfτ}) times the pilots equals phyloc's
    noise-free synthesis of the same paths on the same subcarriers, to rounding."""
    system, S, paths, _ = bench_sionna.make_batch(n_links=8, seed=5)
    ours = synthesize(paths, S, system, None)
    theirs = bench_sionna.SionnaLinks(system, S, paths, precision).received(noise=False)
    err = np.abs(ours - theirs.numpy()).max() / np.abs(ours).max()
    assert err < tol


@pytest.mark.skipif(not bench_sionna.available(), reason=bench_sionna.INSTALL)
def test_sionna_noise_has_the_variance_phyloc_adds():
    """The comparison adds the same noise power on both sides: Sionna's AWGN at ``no`` and
    phyloc's at ``system.noise_power_w`` have the same per-subcarrier variance (10 %)."""
    system, S, paths, rng = bench_sionna.make_batch(n_links=64, seed=6)
    clean = synthesize(paths, S, system, None)
    w_ours = synthesize(paths, S, system, rng) - clean
    sl = bench_sionna.SionnaLinks(system, S, paths, "double")
    w_theirs = sl.received().numpy() - sl.received(noise=False).numpy()
    v = system.noise_power_w
    assert np.mean(np.abs(w_ours) ** 2) == pytest.approx(v, rel=0.1)
    assert np.mean(np.abs(w_theirs) ** 2) == pytest.approx(v, rel=0.1)

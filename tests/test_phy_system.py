"""OFDM system parameters, link budget and noise (issue: PHY core)."""

import math

import numpy as np
import pytest

from phyloc.errors import ValidationError
from phyloc.phy import OFDMSystem, PathSet, dbm_to_watt, free_space_path_loss_db, watt_to_dbm
from phyloc.phy.synthesis import complex_noise, synthesize
from phyloc.phy.waveform import qpsk_symbols, to_time_domain


def test_defaults_are_the_papers_system(paper_system):
    s = paper_system
    assert (s.n_subcarriers, s.subcarrier_spacing_hz, s.carrier_frequency_hz) == (
        2569,
        14.65e3,
        5.2e9,
    )
    assert s.bandwidth_hz == pytest.approx(37.63585e6)
    assert s.sample_period_s == pytest.approx(1 / 37.63585e6)
    assert s.omega == pytest.approx(2 * math.pi * 14650)


def test_noise_power_of_the_defaults(paper_system):
    # By hand: kT = -173.83 dBm/Hz at 300 K, B = 37.636 MHz = 75.76 dB-Hz, NF = 15 dB.
    assert float(watt_to_dbm(paper_system.noise_power_w)) == pytest.approx(-83.07, abs=0.01)


def test_noise_power_reference_temperature_explains_minus_83_2():
    # The often quoted -83.2 dBm is the same budget at the reference temperature T0 = 290 K.
    s = OFDMSystem(temperature_k=290.0)
    assert float(watt_to_dbm(s.noise_power_w)) == pytest.approx(-83.2, abs=0.1)


def test_link_budget(paper_system):
    assert paper_system.received_power_w(60.0) == pytest.approx(1e-9)  # 0 dBm - 60 dB = 1 nW
    assert float(dbm_to_watt(30.0)) == pytest.approx(1.0)
    # free space at 5.2 GHz and 100 m: 20 log10(4π·100·5.2e9/c0) = 86.76 dB
    assert float(free_space_path_loss_db(100.0, 5.2e9)) == pytest.approx(86.76, abs=0.01)


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("n_subcarriers", 2568, "n_subcarriers = 2568 .*odd"),
        ("n_subcarriers", 1, "n_subcarriers .*>= 3"),
        ("subcarrier_spacing_hz", 0.0, "subcarrier_spacing_hz = 0.0 .*> 0"),
        ("subcarrier_spacing_hz", -5.0, "subcarrier_spacing_hz"),
        ("temperature_k", float("nan"), "temperature_k"),
        ("noise_figure_db", -1.0, "noise_figure_db = -1.0 .*>= 0"),
        ("oversampling", 0, "oversampling = 0 .*>= 1"),
        ("tx_power_dbm", float("inf"), "tx_power_dbm"),
    ],
)
def test_bad_system_parameters_name_the_field(field, value, match):
    with pytest.raises(ValidationError, match=match):
        OFDMSystem(**{field: value})


def test_recipe_section_rejects_unknown_key_with_suggestion():
    with pytest.raises(ValidationError, match=r"system\.n_subcarier.*did you mean 'n_subcarriers'"):
        OFDMSystem.from_dict({"n_subcarier": 65})
    s = OFDMSystem.from_dict({"n_subcarriers": 65, "oversampling": 2})
    assert OFDMSystem.from_dict(s.to_dict()) == s


def test_noise_sample_variance_matches_sigma2(paper_system, rng):
    sigma2 = paper_system.noise_power_w
    w = complex_noise((64, paper_system.n_subcarriers), sigma2, rng)
    assert np.var(w) / sigma2 == pytest.approx(1.0, rel=0.02)
    # circular: real and imaginary parts carry half each and are uncorrelated
    assert np.var(w.real) / sigma2 == pytest.approx(0.5, rel=0.03)
    assert abs(np.mean(w.real * w.imag)) / sigma2 < 0.01


def test_time_domain_noise_of_a_received_signal_has_variance_sigma2(paper_system, rng):
    # os = 1: the unitary DFT keeps white noise white with the same variance per sample
    S = qpsk_symbols(paper_system, 1, rng)
    empty = PathSet(np.zeros(0), np.zeros(0, complex), np.zeros(33, np.int64))
    r = to_time_domain(synthesize(empty, S, paper_system, rng), paper_system)
    assert np.var(r) / paper_system.noise_power_w == pytest.approx(1.0, rel=0.02)

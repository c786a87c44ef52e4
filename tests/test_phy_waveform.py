"""Pilot symbols and the time/frequency forms of s(t) (DiPNet eq. (5))."""

import numpy as np
import pytest

from naive import symbol_samples
from phyloc.errors import ValidationError
from phyloc.phy import OFDMSystem
from phyloc.phy.waveform import (
    from_time_domain,
    qpsk_symbols,
    time_domain_symbol,
    to_time_domain,
)


def test_qpsk_symbols_are_unit_modulus_qpsk_and_reproducible(small_system):
    S1 = qpsk_symbols(small_system, 3, np.random.default_rng(5))
    S2 = qpsk_symbols(small_system, 3, np.random.default_rng(5))
    assert S1.shape == (3, 65)
    np.testing.assert_array_equal(S1, S2)
    np.testing.assert_allclose(np.abs(S1), 1.0, rtol=1e-15)
    phases = np.angle(S1.ravel()) / (np.pi / 4)
    assert set(np.round(phases).astype(int)) <= {1, 3, -1, -3}
    assert not np.array_equal(S1[0], S1[1])  # transmitters differ


def test_qpsk_requires_a_generator(small_system):
    with pytest.raises(ValidationError, match="rng"):
        qpsk_symbols(small_system, 1, 42)


@pytest.mark.parametrize("os", [1, 3])
@pytest.mark.parametrize("delay", [0.0, 3.3e-8, 0.71e-6])
def test_time_domain_symbol_equals_the_direct_sum(rng, os, delay):
    sysm = OFDMSystem(n_subcarriers=33, subcarrier_spacing_hz=1e6, oversampling=os)
    S = qpsk_symbols(sysm, 1, rng)[0]
    ref = symbol_samples(S, 33, 1e6, os, delay)
    got = time_domain_symbol(S, sysm, delay)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_time_and_frequency_forms_round_trip(rng):
    sysm = OFDMSystem(n_subcarriers=65, oversampling=2)
    R = rng.standard_normal((4, 65)) + 1j * rng.standard_normal((4, 65))
    np.testing.assert_allclose(from_time_domain(to_time_domain(R, sysm), sysm), R, atol=1e-12)


def test_oversampled_samples_contain_the_critically_sampled_ones(rng):
    s1 = OFDMSystem(n_subcarriers=65)
    s2 = s1.replace(oversampling=2)
    R = rng.standard_normal((2, 65)) + 1j * rng.standard_normal((2, 65))
    np.testing.assert_allclose(to_time_domain(R, s2)[:, ::2], to_time_domain(R, s1), atol=1e-12)


def test_symbol_shape_is_checked(small_system):
    with pytest.raises(ValidationError, match=r"symbols .*\[n_transmitters, N\].*65"):
        time_domain_symbol(np.ones(64), small_system)

"""Shared fixtures: small systems for brute-force comparisons, the paper's system for statistics."""

import numpy as np
import pytest

from phyloc.phy import OFDMSystem


@pytest.fixture
def rng():
    """A fresh seeded Generator per test (tests never share random streams)."""
    return np.random.default_rng(20261121)


@pytest.fixture
def small_system():
    """N = 65 subcarriers: small enough for the direct sums of tests/naive.py."""
    return OFDMSystem(n_subcarriers=65, subcarrier_spacing_hz=1.0e6)


@pytest.fixture(scope="session")
def paper_system():
    """The DiPNet §V-A system (N = 2569, 14.65 kHz, 5.2 GHz, 0 dBm, 300 K, NF 15 dB)."""
    return OFDMSystem()

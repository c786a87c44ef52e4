"""Shared fixtures: small systems for brute-force comparisons, the paper's system for statistics."""

import os

import numpy as np
import pytest

from phyloc.phy import OFDMSystem

try:  # the fuzzers' profiles (tests/test_fuzz_*.py), chosen with PHYLOC_FUZZ
    from hypothesis import HealthCheck, settings
except ImportError:  # pragma: no cover - the fuzz modules skip themselves
    pass
else:
    _quiet = {"deadline": None, "suppress_health_check": list(HealthCheck)}
    # fast (default, CI): the same 40 examples every run, so CI is deterministic; slow: 600
    # new ones every run, or those of --hypothesis-seed=N
    settings.register_profile("fast", max_examples=40, derandomize=True, **_quiet)
    settings.register_profile("slow", max_examples=600, **_quiet)
    settings.load_profile(os.environ.get("PHYLOC_FUZZ", "fast"))


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

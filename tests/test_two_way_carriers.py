"""Two-way ranging with different forward and backward carriers (DiPNet §V-B: 5.5 / 5.7 GHz).

Expected path-loss differences come from the laws' frequency terms: free space
``20·log10(4π d f/c0)`` differs by ``20·log10(f_b/f_f)``; a WINNER II law with
``C·log10(f/5 GHz)`` by ``C·log10(f_b/f_f)`` (A1 LOS: C = 20; C2 NLOS: C = 23, WINNER II
D1.1.2 Table 4-4), inside the law's distance range.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from phyloc.channels import ChannelSpec, draw_links, two_way_composite
from phyloc.errors import ValidationError
from phyloc.phy import OFDMSystem, PathSet

F_FWD, F_BWD = 5.5e9, 5.7e9
C0 = 299_792_458.0
SYSTEM = OFDMSystem(carrier_frequency_hz=F_FWD)


def _fspl_db(d, f):
    return 20 * np.log10(4 * math.pi * d * f / C0)


def test_awgn_backward_power_follows_friis():
    spec = ChannelSpec.from_dict(
        {"scenario": "awgn", "ranging": "two_way", "backward_carrier_frequency_hz": F_BWD}
    )
    d = np.array([3.0, 17.0, 60.0, 95.0])
    draw = spec.draw(d, np.random.default_rng(1), system=SYSTEM)
    fwd, bwd = draw.components
    np.testing.assert_allclose(fwd.path_loss_db, _fspl_db(d, F_FWD), atol=1e-10)
    np.testing.assert_allclose(bwd.path_loss_db, _fspl_db(d, F_BWD), atol=1e-10)
    np.testing.assert_allclose(
        bwd.path_loss_db - fwd.path_loss_db, 20 * math.log10(F_BWD / F_FWD), atol=1e-10
    )
    # no shadowing in AWGN: the received powers differ by (f_b/f_f)²
    np.testing.assert_allclose(fwd.received_power_w / bwd.received_power_w, (F_BWD / F_FWD) ** 2)
    np.testing.assert_allclose(draw.paths.total_power(), bwd.received_power_w, rtol=1e-12)
    np.testing.assert_allclose(draw.paths.delays, 2 * d / C0, rtol=1e-15)


@pytest.mark.parametrize(
    ("scenario", "c_coeff", "d_range"),
    [("winner2_a1_los", 20.0, (3.0, 100.0)), ("winner2_c2_nlos", 23.0, (50.0, 140.0))],
)
def test_winner2_backward_components_scale_by_the_frequency_term(scenario, c_coeff, d_range):
    d = np.random.default_rng(4).uniform(*d_range, 200)
    same = ChannelSpec(scenario=scenario, ranging="two_way")
    other = dataclasses.replace(same, backward_carrier_frequency_hz=F_BWD)
    a = same.draw(d, np.random.default_rng(8), system=SYSTEM)
    b = other.draw(d, np.random.default_rng(8), system=SYSTEM)
    delta_db = c_coeff * math.log10(F_BWD / F_FWD)
    # forward component untouched, bit for bit
    np.testing.assert_array_equal(a.components[0].paths.gains, b.components[0].paths.gains)
    np.testing.assert_array_equal(a.components[0].path_loss_db, b.components[0].path_loss_db)
    # backward: same random draws, path loss higher by C·log10(f_b/f_f)
    ab, bb = a.components[1], b.components[1]
    np.testing.assert_array_equal(ab.shadowing_db, bb.shadowing_db)
    np.testing.assert_allclose(bb.path_loss_db - ab.path_loss_db, delta_db, atol=1e-10)
    np.testing.assert_allclose(
        bb.received_power_w / ab.received_power_w, 10 ** (-delta_db / 10), rtol=1e-12
    )
    # the composite (amplify-and-forward) carries the backward power: every gain scales alike
    np.testing.assert_array_equal(a.paths.delays, b.paths.delays)
    np.testing.assert_allclose(
        np.abs(b.paths.gains / a.paths.gains), 10 ** (-delta_db / 20), rtol=1e-12
    )
    np.testing.assert_array_equal(b.path_loss_db, bb.path_loss_db)


def test_absent_backward_carrier_is_the_old_two_way_draw():
    d = np.random.default_rng(2).uniform(5.0, 140.0, 60)
    spec = ChannelSpec(scenario="winner2_c2", ranging="two_way")
    got = spec.draw(d, np.random.default_rng(13), system=SYSTEM)
    # the two-way draw written out from the one-way sampler (ChannelSpec.draw's documented recipe)
    rng = np.random.default_rng(13)
    fwd = draw_links("winner2_c2", d, rng, system=SYSTEM)
    bwd = draw_links("winner2_c2", d, rng, system=SYSTEM, condition=fwd.los)
    p = fwd.paths
    relay = PathSet(p.delays, p.gains / np.sqrt(fwd.received_power_w)[p.link_index()], p.offsets)
    ref = two_way_composite(relay, bwd.paths)
    np.testing.assert_array_equal(got.paths.gains, ref.gains)
    np.testing.assert_array_equal(got.paths.delays, ref.delays)
    # stating the system's own carrier gives the same arrays
    explicit = dataclasses.replace(spec, backward_carrier_frequency_hz=F_FWD)
    again = explicit.draw(d, np.random.default_rng(13), system=SYSTEM)
    np.testing.assert_array_equal(again.paths.gains, got.paths.gains)
    # and the recipe form without the key is unchanged (dataset fingerprints)
    assert "backward_carrier_frequency_hz" not in spec.to_dict()
    assert ChannelSpec.from_dict(explicit.to_dict()) == explicit


def test_default_system_uses_its_carrier_forward():
    spec = ChannelSpec(scenario="awgn", ranging="two_way", backward_carrier_frequency_hz=F_BWD)
    d = np.array([10.0])
    fwd, bwd = spec.draw(d, np.random.default_rng(0)).components
    np.testing.assert_allclose(fwd.path_loss_db, _fspl_db(d, OFDMSystem().carrier_frequency_hz))
    np.testing.assert_allclose(bwd.path_loss_db, _fspl_db(d, F_BWD))


@pytest.mark.parametrize(
    ("kwargs", "text"),
    [
        ({"ranging": "one_way", "backward_carrier_frequency_hz": F_BWD}, "two_way"),
        ({"ranging": "two_way", "backward_carrier_frequency_hz": 0.0}, "> 0"),
        ({"ranging": "two_way", "backward_carrier_frequency_hz": -5.7e9}, "> 0"),
        ({"ranging": "two_way", "backward_carrier_frequency_hz": "fast"}, "real number"),
        ({"ranging": "two_way", "backward_carrier_frequency_hz": 7.0e9}, r"valid for \[2e\+09"),
    ],
)
def test_backward_carrier_errors_name_the_key(kwargs, text):
    with pytest.raises(ValidationError, match=text) as err:
        ChannelSpec.from_dict({"scenario": "winner2_c2", **kwargs})
    assert err.value.field == "channel.backward_carrier_frequency_hz"

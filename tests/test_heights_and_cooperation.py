"""3-D layouts for indoor positioning: agents at a common device height, node heights in the
channel (``[channel] heights = "nodes"``) and non-cooperative networks (agent-anchor links
only)."""

import math

import numpy as np
import pytest

from phyloc.channels import ChannelSpec
from phyloc.cli import main
from phyloc.datasets.simulate import simulate_realization
from phyloc.errors import ValidationError
from phyloc.network import NetworkSpec, make_network
from phyloc.phy.system import C0, OFDMSystem

CEILING = [[0.0, 0.0, 8.0], [60.0, 0.0, 8.0], [0.0, 30.0, 8.0], [60.0, 30.0, 8.0]]
HALL = {"n_agents": 6, "dim": 3, "region_m": [60.0, 30.0, 3.0], "anchors": CEILING}


def _net(seed=1, **extra):
    return make_network(NetworkSpec.from_dict({**HALL, **extra}), np.random.default_rng(seed))


def test_agent_height_fixes_the_height_and_keeps_the_horizontal_draw():
    free, fixed = _net(), _net(agent_height_m=1.5)
    np.testing.assert_array_equal(fixed.positions[0, :6, 2], np.full(6, 1.5))
    np.testing.assert_array_equal(fixed.positions[0, :6, :2], free.positions[0, :6, :2])
    np.testing.assert_array_equal(fixed.positions[0, 6:], np.array(CEILING))


@pytest.mark.parametrize(
    ("extra", "allowed"),
    [
        ({"dim": 2, "region_m": [60.0, 30.0], "anchors": 4}, "network.dim = 3"),
        ({"agents_m": [[1.0, 1.0, 1.0]] * 6}, "agents_m"),
        ({"agent_height_m": -1.0}, "> 0"),
    ],
)
def test_agent_height_is_refused_where_it_cannot_apply(extra, allowed):
    with pytest.raises(ValidationError, match="agent_height_m") as info:
        NetworkSpec.from_dict({**HALL, "agent_height_m": 1.5, **extra})
    assert allowed in str(info.value)


@pytest.mark.parametrize("comm_range_m", [None, 40.0])
def test_a_non_cooperative_network_links_agents_to_anchors_only(comm_range_m):
    extra = {} if comm_range_m is None else {"comm_range_m": comm_range_m, "on_isolated": "allow"}
    coop, alone = _net(**extra), _net(cooperation=False, **extra)
    anchor = alone.is_anchor
    lk = alone.links_at(0)
    assert lk.size and np.all(anchor[lk[:, 0]] ^ anchor[lk[:, 1]])  # one end an anchor
    full = coop.links_at(0)
    keep = anchor[full[:, 0]] | anchor[full[:, 1]]
    np.testing.assert_array_equal(lk, full[keep])  # the cooperative links minus agent-agent
    assert np.any(~keep)  # and the cooperative network had agent-agent links to drop


def test_a_non_cooperative_network_needs_anchors():
    with pytest.raises(ValidationError, match=r"network\.cooperation"):
        NetworkSpec.from_dict({"n_agents": 4, "cooperation": False})


def test_node_heights_reach_every_link_of_the_channel():
    """``heights = "nodes"`` on the field model: each link's ground reflection arrives
    ``sqrt(d² + (z_u + z_v)²) − d`` after its direct path (the two-ray geometry of its own end
    heights: 8 m anchors, 1.5 m agents), not that of the recipe's fixed heights."""
    spec = NetworkSpec.from_dict({**HALL, "agent_height_m": 1.5})
    chan = ChannelSpec(scenario="field_grass_5g", heights="nodes")
    real = simulate_realization(OFDMSystem(), spec, chan, np.random.default_rng(4))
    net, draw, lk = real.network, real.channels[0], real.links[0]
    z = net.positions[0][:, 2]
    d = net.distances(0)
    ground = np.sqrt(d**2 + (z[lk[:, 0]] + z[lk[:, 1]]) ** 2) - d
    excess = draw.excess_delays() * C0
    for i in range(lk.shape[0]):
        a, b = draw.paths.offsets[i], draw.paths.offsets[i + 1]
        assert np.min(np.abs(excess[a:b] - ground[i])) < 1e-6 * max(1.0, ground[i])
    assert {z[u] + z[v] for u, v in lk} == {3.0, 9.5}  # agent-agent and agent-anchor links
    assert not math.isclose(ground.max(), ground.min())


def test_node_heights_in_a_2d_network_are_refused_before_any_work(tmp_path, capsys):
    recipe = tmp_path / "r.toml"
    recipe.write_text(
        'kind = "localization"\nname = "r"\nseed = 1\n[network]\nregion_m = [60.0, 30.0]\n'
        'anchors = 4\n[channel]\nheights = "nodes"\n[experiment]\n'
        'scenarios = { c2 = "winner2_c2" }\nagents = [4]\nrealizations = 1\n'
        'methods = ["dipnet"]\ninits = ["informed"]\ncdf_agents = [4]\n'
    )
    assert main(["evaluate", str(recipe), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "channel.heights" in err and "network.dim = 3" in err
    assert not (tmp_path / "o").exists()


def test_a_3d_run_with_anchors_reports_horizontal_error_points(tmp_path, capsys, monkeypatch):
    """Horizontal errors (x, y only) and their 50/80/90 % points, each with an interval over
    realizations; the horizontal RMSE never exceeds the 3-D one (it drops a coordinate)."""
    import json

    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    recipe = tmp_path / "hall.toml"
    recipe.write_text(
        'kind = "localization"\nname = "hall"\nseed = 3\n[system]\nn_subcarriers = 257\n'
        "subcarrier_spacing_hz = 146.5e3\n[network]\ndim = 3\nregion_m = [60.0, 30.0, 3.0]\n"
        f'anchors = {CEILING}\nagent_height_m = 1.5\n[channel]\nheights = "nodes"\n'
        "[ranging]\nbeta = 8.0\nwindow_m = [0.0, 300.0]\n[localization]\nn_particles = 100\n"
        "n_iterations = 2\ninformed_std_m = 3.0\n[experiment]\n"
        'scenarios = { sl = "tr38901_inf_sl" }\nagents = [4]\nrealizations = 3\n'
        'methods = ["corr"]\ninits = ["informed"]\ncdf_agents = [4]\n'
    )
    out = tmp_path / "res"
    assert main(["evaluate", str(recipe), "--out", str(out)]) == 0
    f = json.loads((out / "results.json").read_text())["figures"]
    base = "corr.sl_informed.agents_4"
    assert f[base + ".horizontal_rmse_m"] <= f[base + ".position_rmse_m"] + 1e-12
    p = [f[f"{base}.horizontal_error_p{q}_m"] for q in (50, 80, 90)]
    assert p[0] <= p[1] <= p[2]
    for q in (50, 80, 90):
        lo, hi = (
            f[f"{base}.horizontal_error_p{q}_m.ci_low"],
            f[f"{base}.horizontal_error_p{q}_m.ci_high"],
        )
        assert lo <= f[f"{base}.horizontal_error_p{q}_m"] <= hi


@pytest.mark.parametrize("name", ["inf_positioning", "inf_positioning_noncoop"])
def test_the_inf_positioning_recipes_run_fast(tmp_path, monkeypatch, name):
    """The CI setting of the indoor-factory recipes (TR 38.901 InF, ceiling anchors): every
    method reports horizontal errors no larger than its 3-D ones, and ordered CDF points."""
    import json
    from pathlib import Path

    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    recipe = Path(__file__).parents[1] / "datasets" / f"{name}.toml"
    out = tmp_path / "res"
    assert main(["evaluate", str(recipe), "--fast", "--out", str(out)]) == 0
    doc = json.loads((out / "results.json").read_text())
    f = doc["figures"]
    for m in doc["meta"]["methods"]:
        for s in ("sl", "dh"):
            base = f"{m}.{s}.agents_6"
            assert f[base + ".horizontal_rmse_m"] <= f[base + ".position_rmse_m"] + 1e-9
            p = [f[f"{base}.horizontal_error_p{q}_m"] for q in (50, 80, 90)]
            assert all(math.isfinite(x) for x in p) and p[0] <= p[1] <= p[2]

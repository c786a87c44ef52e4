"""Recorded snapshots as raw arrays: ``phyloc import`` / ``phyloc export``.

The round trip (dataset → raw arrays → dataset) must store the same waveforms and give the same
localization results; every missing, unknown or mis-shaped array must be an error that names it
(with the shape seen and the shape expected) and writes nothing.
"""

import math

import h5py
import numpy as np
import pytest

import phyloc.datasets as pds
from phyloc.cli import main
from phyloc.config import load_recipe
from phyloc.errors import ValidationError
from phyloc.evaluation import localization_experiment as lx
from phyloc.phy.system import K_BOLTZMANN
from phyloc.reporting import OutputExistsError, is_measurement

#: Anchor-free, one snapshot, WINNER II C2 (as tests/test_evaluate_dataset.py), 2 realizations.
C2 = """
kind = "dataset"
name = "tiny"
seed = 77
[system]
n_subcarriers = 257
subcarrier_spacing_hz = 146.5e3
[network]
n_agents = 4
region_m = [60.0, 60.0]
[dataset]
realizations = 2
shard_size = 1
[channel]
scenario = "winner2_c2"
[ranging]
window_m = [0.0, 200.0]
[localization]
n_particles = 200
n_iterations = 3
resample_move = false
[experiment]
methods = ["dipnet_published", "corr", "sage_los"]
inits = ["truth_free"]
"""

#: Anchors, moving agents within a range (ragged links), two-way ranging, 3 snapshots.
MOVING = """
kind = "dataset"
name = "moving"
seed = 5
[system]
n_subcarriers = 33
subcarrier_spacing_hz = 2.0e6
[network]
n_agents = 4
region_m = [60.0, 60.0]
anchors = 2
comm_range_m = 50.0
on_isolated = "allow"
[network.motion]
model = "constant_velocity"
n_snapshots = 3
dt_s = 1.0
initial_speed_std = 6.0
[channel]
scenario = "winner2_b1"
ranging = "two_way"
[dataset]
realizations = 2
shard_size = 1
"""

#: Arrays whose bytes the round trip must preserve (the channel draws are not imported).
KEPT = (
    "nodes/positions",
    "nodes/is_anchor",
    "links/count",
    "links/pairs",
    "links/valid",
    "symbols",
    "received",
    "channel/los",
)


@pytest.fixture(autouse=True)
def _quiet(monkeypatch):
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")


@pytest.fixture(scope="module")
def c2(tmp_path_factory):
    d = tmp_path_factory.mktemp("c2")
    pds.generate(load_recipe(C2), d / "c2.h5", progress=False)
    pds.export_arrays(d / "c2.h5", d / "c2.npz")
    return d


@pytest.fixture(scope="module")
def moving(tmp_path_factory):
    d = tmp_path_factory.mktemp("moving")
    pds.generate(load_recipe(MOVING), d / "moving.h5", progress=False)
    pds.export_arrays(d / "moving.h5", d / "moving.h5.arrays.h5")
    return d


def _load(path) -> dict:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def _checksums(path, names=KEPT) -> dict:
    with pds.open(path) as ds:
        sums = ds.checksums()
    return {k: sums[k] for k in names}


def _same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


# -- round trips ---------------------------------------------------------------------------
def test_exported_and_imported_dataset_gives_identical_localization(c2, tmp_path):
    out = pds.import_arrays(c2 / "c2.npz", tmp_path / "back.h5")
    assert _checksums(out) == _checksums(c2 / "c2.h5")  # same bytes: samples, pilots, links
    assert pds.verify(out)["ok"]
    with pds.open(out) as ds, pds.open(c2 / "c2.h5") as orig:
        assert ds.system == orig.system and ds.ways == orig.ways == 1
        assert ds.load_recipe().seed == 77 and ds.name == "tiny"
    a = lx.DATASET_LOCALIZATION.run_dataset(c2 / "c2.h5", progress=False)
    b = lx.DATASET_LOCALIZATION.run_dataset(out, progress=False)
    fa, fb = a["figures"], b["figures"]
    assert fa.keys() == fb.keys()
    timing = [k for k in fa if is_measurement(k)]
    differ = [k for k in fa if k not in timing and not _same(fa[k], fb[k])]
    assert not differ, {k: (fa[k], fb[k]) for k in differ}
    for m in ("dipnet_published", "corr", "sage_los"):
        key = f"{m}.c2.agents_4.framework_rmse_m"
        assert np.isfinite(fa[key]) and fa[key] == fb[key]
    for k, series in a["series"].items():
        if isinstance(series, dict):  # per-unit values of a pooled figure
            assert series.keys() == b["series"][k].keys()
            for part in series:
                np.testing.assert_array_equal(series[part], b["series"][k][part])
        else:
            np.testing.assert_array_equal(series, b["series"][k])


def test_round_trip_through_hdf5_with_anchors_ragged_links_and_two_way(moving, tmp_path):
    src = moving / "moving.h5.arrays.h5"
    with h5py.File(src, "r") as f:
        assert f["received"].shape[:2] == (2, 3) and f["received"].dtype == np.complex128
        counts = f["link_mask"][...].sum(axis=2)
    assert np.unique(counts).size > 1  # links do vary between snapshots and realizations
    out = pds.import_arrays(src, tmp_path / "back.h5")
    assert _checksums(out) == _checksums(moving / "moving.h5")
    with pds.open(out) as ds, pds.open(moving / "moving.h5") as orig:
        assert ds.ways == 2 and ds.dt_s == orig.dt_s == 1.0
        assert ds.ranging == "two_way" and ds.load_recipe().seed == 5
        assert int(ds.file.attrs["n_anchors"]) == 2
        np.testing.assert_allclose(
            ds["channel/distance_m"][...], orig["channel/distance_m"][...], rtol=1e-12
        )
        assert (ds.file.attrs["node_order"] == np.arange(6)).all()
        real = ds.realization(1)  # what evaluate reads
        ref = orig.realization(1)
        for t in range(3):
            np.testing.assert_array_equal(real.received[t], ref.received[t])
            np.testing.assert_array_equal(real.links[t], ref.links[t])


def test_node_order_and_link_rows_are_normalized(moving, tmp_path):
    """Anchors listed first, link rows shuffled, junk in masked rows: the stored dataset is the
    original one (agents first, recorded rows first and sorted)."""
    with h5py.File(moving / "moving.h5.arrays.h5", "r") as f:
        a = {k: f[k][()] for k in f}
    r = 1  # one realization, without the realization axis
    arrays = {
        k: (v[r] if isinstance(v, np.ndarray) and v.ndim and v.shape[0] == 2 else v)
        for k, v in a.items()
        if k != "recipe"
    }
    L = arrays["links"].shape[1]
    perm = np.r_[4, 5, 0, 1, 2, 3]  # source node i is the original (stored) node perm[i]
    inv = np.argsort(perm)  # original node j is source node inv[j]
    arrays["is_anchor"] = arrays["is_anchor"][perm]
    arrays["symbols"] = arrays["symbols"][perm]
    arrays["positions"] = arrays["positions"][:, perm]
    arrays["links"] = np.where(arrays["link_mask"][..., None], inv[arrays["links"]], -7)
    rng = np.random.default_rng(0)
    for t in range(3):
        order = rng.permutation(L)
        for k in ("links", "link_mask", "received", "los"):
            arrays[k][t] = arrays[k][t][order]
    arrays["received"][~arrays["link_mask"]] = np.nan  # never read
    out = pds.import_arrays(arrays, tmp_path / "norm.h5", recipe=a["recipe"].decode())
    with pds.open(out) as ds, pds.open(moving / "moving.h5") as orig:
        got = ds.checksums()
        want = orig.checksums()
        pad = orig["links/count"][r].max()
        for name in KEPT:
            g, w = ds[name][...], orig[name][r : r + 1]
            if name in ("links/pairs", "links/valid", "received", "channel/los"):
                w = w[:, :, :pad]
            np.testing.assert_array_equal(g, w, err_msg=name)
        np.testing.assert_array_equal(ds.file.attrs["node_order"][0], inv)
    assert got != want  # one realization of two


def test_oversampled_dataset_round_trips_to_complex64_rounding(tmp_path):
    text = MOVING.replace(
        "subcarrier_spacing_hz = 2.0e6", "subcarrier_spacing_hz = 2.0e6\noversampling = 2"
    )
    pds.generate(load_recipe(text), tmp_path / "os2.h5", progress=False)
    pds.export_arrays(tmp_path / "os2.h5", tmp_path / "os2.npz")
    out = pds.import_arrays(tmp_path / "os2.npz", tmp_path / "back.h5")
    with pds.open(out) as ds, pds.open(tmp_path / "os2.h5") as orig:
        assert ds.system.oversampling == 1 and orig.system.oversampling == 2
        assert ds.system.replace(oversampling=2) == orig.system
        for t in range(3):
            a, b = ds.snapshot(0, t).received, orig.snapshot(0, t).received
            assert np.max(np.abs(a - b)) <= 1e-6 * np.max(np.abs(b))


def test_measured_noise_variance_sets_the_noise_power(c2, tmp_path):
    arrays = _load(c2 / "c2.npz")
    for k in ("temperature_k", "noise_figure_db"):
        del arrays[k]
    arrays["noise_variance_w"] = np.float64(3.7e-13)
    out = pds.import_arrays(arrays, tmp_path / "nv.h5")
    with pds.open(out) as ds:
        assert ds.system.noise_power_w == pytest.approx(3.7e-13, rel=1e-12)
        assert ds.system.noise_figure_db == 0.0
        N, fsc = ds.system.n_subcarriers, ds.system.subcarrier_spacing_hz
        assert ds.system.temperature_k == pytest.approx(3.7e-13 / (K_BOLTZMANN * N * fsc))


def test_link_count_selects_the_first_rows(c2, tmp_path):
    arrays = _load(c2 / "c2.npz")
    del arrays["link_mask"]
    arrays["link_count"] = np.array([[12], [10]])  # realization 1: the last two rows not recorded
    arrays["received"][1, 0, 10:] = np.nan  # never read
    out = pds.import_arrays(arrays, tmp_path / "lc.h5")
    with pds.open(out) as ds, pds.open(c2 / "c2.h5") as orig:
        np.testing.assert_array_equal(ds["links/count"][...], [[12], [10]])
        a, b = ds.snapshot(1, 0), orig.snapshot(1, 0)
        np.testing.assert_array_equal(a.links, b.links[:10])
        np.testing.assert_array_equal(a.samples, b.samples[:10])
        np.testing.assert_array_equal(ds["received"][0], orig["received"][0])
    arrays["link_count"] = np.array([[12], [13]])
    with pytest.raises(ValidationError, match=r"link_count = 13 .* 0 … L = 12"):
        pds.import_arrays(arrays, tmp_path / "bad.h5")


def test_a_recording_with_a_missing_link_evaluates(c2, tmp_path):
    """Recorded links need not be every link the network's range allows: evaluate scores the
    links the dataset holds (before, the link errors assumed the range's links and crashed)."""
    arrays = _load(c2 / "c2.npz")
    arrays["link_mask"][:, 0, 3] = False
    out = pds.import_arrays(arrays, tmp_path / "sub.h5")
    with pds.open(out) as ds:
        assert ds["links/count"][...].tolist() == [[11], [11]]
        los = ds["channel/los"][:, 0, :11]
    res = lx.DATASET_LOCALIZATION.run_dataset(out, progress=False)["figures"]
    assert np.isfinite(res["corr.c2.agents_4.framework_rmse_m"])
    assert res["c2.los_fraction"] == los.mean()  # the 22 recorded links, no more


# -- ground truth that is missing ----------------------------------------------------------
def test_without_los_the_oracle_is_an_error_or_left_out(c2, tmp_path):
    arrays = _load(c2 / "c2.npz")
    del arrays["los"]
    with pytest.raises(ValidationError, match=r"^los = missing.*sage_los"):
        pds.import_arrays(arrays, tmp_path / "a.h5")  # its recipe lists sage_los
    assert not (tmp_path / "a.h5").exists()
    recipe = str(arrays.pop("recipe")).replace(
        'methods = ["dipnet_published", "corr", "sage_los"]\n', ""
    )
    out = pds.import_arrays(arrays, tmp_path / "b.h5", recipe=recipe)
    with pds.open(out) as ds:
        methods = ds.load_recipe().section("experiment")["methods"]
        assert ds.file.attrs["truth"] == "positions"
    assert "sage_los" not in methods and {"dipnet", "corr", "sage"} <= set(methods)


def test_without_positions_info_works_and_evaluate_refuses(c2, tmp_path):
    arrays = _load(c2 / "c2.npz")
    del arrays["positions"]
    arrays["dim"] = np.int64(2)  # anchor-free: nothing else gives the dimension
    out = pds.import_arrays(arrays, tmp_path / "np.h5")
    assert pds.verify(out)["ok"]
    with pds.open(out) as ds:
        assert np.isnan(ds["nodes/positions"][...]).all()
        assert ds.snapshot(0, 0).received.shape == (12, 257)
    with pytest.raises(pds.DatasetError, match="no ground-truth positions"):
        lx.DATASET_LOCALIZATION.run_dataset(out, progress=False)
    re_export = pds.export_arrays(out, tmp_path / "again.npz")
    assert "positions" not in _load(re_export)  # NaN is not passed off as truth
    arrays["recipe"] = np.asarray(str(arrays["recipe"]).replace('"truth_free"', '"informed"'))
    with pytest.raises(ValidationError, match=r"^positions = missing.*informed"):
        pds.import_arrays(arrays, tmp_path / "inf.h5")


# -- errors ----------------------------------------------------------------------------------
def _mutations():
    """(id, mutate(arrays) -> None, substrings the message must hold)."""

    def drop(name):
        return lambda a: a.pop(name)

    def put(name, fn):
        def f(a):
            a[name] = fn(a)

        return f

    return [
        ("missing received", drop("received"), ["received = missing", "[K, L, N]"]),
        ("missing links", drop("links"), ["links = missing"]),
        ("missing symbols", drop("symbols"), ["symbols = missing"]),
        ("missing is_anchor", drop("is_anchor"), ["is_anchor = missing"]),
        ("missing spacing", drop("subcarrier_spacing_hz"), ["subcarrier_spacing_hz = missing"]),
        ("missing ways", drop("ways"), ["ways = missing"]),
        (
            "missing noise",
            lambda a: [a.pop("temperature_k"), a.pop("noise_figure_db")],
            ["noise_variance_w = missing", "temperature_k and noise_figure_db"],
        ),
        ("half the noise", drop("noise_figure_db"), ["noise_figure_db = missing"]),
        (
            "received 2-D",
            put("received", lambda a: a["received"][0, 0]),
            ["received", "shape (12, 257)", "[K, L, N]", "[R, K, L, N]"],
        ),
        (
            "received real",
            put("received", lambda a: a["received"].real),
            ["received", "float64", "complex"],
        ),
        (
            "received even N",
            put("received", lambda a: a["received"][..., :-1]),
            ["received", "(2, 1, 12, 256)", "N = 256", "odd"],
        ),
        (
            "links 3 columns",
            put("links", lambda a: np.zeros((2, 12, 3), np.int64)),
            ["links", "shape (2, 12, 3)", "[R, L, 2] = (2, 12, 2)", "[R, K, L, 2] = (2, 1, 12, 2)"],
        ),
        (
            "links float",
            put("links", lambda a: a["links"].astype(float)),
            ["links", "float64", "integer"],
        ),
        (
            "link_mask shape",
            put("link_mask", lambda a: np.ones((2, 1, 13), bool)),
            ["link_mask", "shape (2, 1, 13)", "[R, K, L] = (2, 1, 12)"],
        ),
        (
            "link_count with mask",
            put("link_count", lambda a: np.full((2, 1), 12)),
            ["link_count", "not both"],
        ),
        (
            "symbols N",
            put("symbols", lambda a: a["symbols"][..., :-2]),
            ["symbols", "shape (2, 4, 255)", "[R, n, N] = (2, 4, 257)"],
        ),
        (
            "is_anchor no realization axis",
            put("is_anchor", lambda a: a["is_anchor"][0]),
            ["is_anchor", "shape (4,)", "[R, n]"],
        ),
        (
            "positions snapshots",
            put("positions", lambda a: np.zeros((2, 3, 4, 2))),
            ["positions", "shape (2, 3, 4, 2)", "[R, K, n, D] = (2, 1, 4, 2)"],
        ),
        (
            "positions dim 4",
            put("positions", lambda a: np.zeros((2, 1, 4, 4))),
            ["positions", "shape (2, 1, 4, 4)", "D = 2 or 3"],
        ),
        (
            "positions NaN",
            put("positions", lambda a: np.where(a["positions"] > 30, np.nan, a["positions"])),
            ["positions", "finite"],
        ),
        (
            "los shape",
            put("los", lambda a: a["los"][:, :, :-1]),
            ["los", "shape (2, 1, 11)", "[R, K, L] = (2, 1, 12)"],
        ),
        (
            "los not flags",
            put("los", lambda a: a["los"] * 2.5),
            ["los", "bool"],
        ),
        (
            "scalar as vector",
            put("subcarrier_spacing_hz", lambda a: np.array([1e6, 2e6])),
            ["subcarrier_spacing_hz", "shape (2,)", "scalar"],
        ),
        ("three ways", put("ways", lambda a: np.int64(3)), ["ways = 3", "1 (one-way)"]),
        (
            "n_subcarriers disagrees",
            put("n_subcarriers", lambda a: np.int64(255)),
            ["n_subcarriers = 255", "N = 257"],
        ),
        (
            "both noise forms",
            put("noise_variance_w", lambda a: np.float64(1e-12)),
            ["noise_variance_w", "not", "temperature_k and noise_figure_db"],
        ),
        (
            "unknown name",
            put("recieved", lambda a: a["received"]),
            ["recieved = unknown array", "did you mean 'received'"],
        ),
        (
            "self link",
            put("links", lambda a: np.where(np.arange(12)[:, None] == 3, 2, a["links"])),
            ["links", "realization 0, snapshot 0, row 3", "itself"],
        ),
        (
            "index out of range",
            put("links", lambda a: np.where(a["links"] == 3, 4, a["links"])),
            ["links", "0 … n - 1 = 3"],
        ),
        (
            "duplicate link",
            put("links", lambda a: a["links"][..., [0, 0, *range(2, 12)], :]),
            ["links", "twice", "at most once"],
        ),
        (
            "NaN samples in a recorded row",
            put("received", lambda a: np.where(np.arange(12)[:, None] == 5, np.nan, a["received"])),
            ["received", "non-finite", "link row 5"],
        ),
    ]


@pytest.mark.parametrize("case", _mutations(), ids=lambda c: c[0])
def test_every_bad_array_is_named_and_nothing_is_written(c2, tmp_path, case):
    _, mutate, expected = case
    arrays = _load(c2 / "c2.npz")
    mutate(arrays)
    out = tmp_path / "bad.h5"
    with pytest.raises(ValidationError) as exc:
        pds.import_arrays(arrays, out)
    msg = str(exc.value)
    for s in expected:
        assert s in msg, msg
    assert "\n" not in msg
    assert not out.exists() and not pds.schema.shard_dir(out).exists()


def test_anchor_errors(moving, tmp_path):
    with h5py.File(moving / "moving.h5.arrays.h5", "r") as f:
        base = {k: f[k][()] for k in f if k != "recipe"}
    a = dict(base)
    del a["positions"], a["anchor_positions"]
    with pytest.raises(ValidationError, match=r"^anchor_positions = missing.*2 anchors"):
        pds.import_arrays(a, tmp_path / "x.h5")
    a = dict(base, anchor_positions=base["anchor_positions"][:, :1])
    with pytest.raises(ValidationError, match=r"anchor_positions = array of shape \(2, 1, 2\)"):
        pds.import_arrays(a, tmp_path / "x.h5")
    a = dict(base, anchor_positions=base["anchor_positions"] + 1.0)
    with pytest.raises(ValidationError, match="differs from the anchor rows of positions"):
        pds.import_arrays(a, tmp_path / "x.h5")
    pairs = base["links"].copy()
    pairs[0, 0, 0] = [4, 5]  # both anchors (nodes 4 and 5)
    assert base["link_mask"][0, 0, 0]
    a = dict(base, links=pairs)
    with pytest.raises(ValidationError, match="anchor-anchor pairs are not links"):
        pds.import_arrays(a, tmp_path / "x.h5")
    moved = base["positions"].copy()
    moved[0, 2, 5] += 1.0
    with pytest.raises(ValidationError, match="moving anchors in realization 0"):
        pds.import_arrays(dict(base, positions=moved), tmp_path / "x.h5")
    # without positions the anchors alone place the network (2-D from their coordinates)
    a = dict(base)
    del a["positions"]
    out = pds.import_arrays(a, tmp_path / "ok.h5")
    with pds.open(out) as ds:
        pos = ds["nodes/positions"][...]
    assert np.isnan(pos[:, :, :4]).all()
    np.testing.assert_array_equal(pos[:, :, 4:], base["positions"][:, :, 4:])


def test_existing_output_is_never_overwritten_without_force(c2, tmp_path):
    out = pds.import_arrays(c2 / "c2.npz", tmp_path / "o.h5")
    before = out.read_bytes()
    with pytest.raises(OutputExistsError, match="--force"):
        pds.import_arrays(c2 / "c2.npz", out)
    assert out.read_bytes() == before
    arrays = _load(c2 / "c2.npz")
    del arrays["links"]
    with pytest.raises(ValidationError, match="links = missing"):
        pds.import_arrays(arrays, out, force=True)  # a bad source leaves the old output
    assert out.read_bytes() == before
    pds.import_arrays(c2 / "c2.npz", out, force=True)
    assert pds.verify(out)["ok"]
    with pytest.raises(OutputExistsError):
        pds.export_arrays(c2 / "c2.h5", c2 / "c2.npz")
    with pytest.raises(ValidationError, match=r"\.npz, \.h5 or \.hdf5"):
        pds.export_arrays(c2 / "c2.h5", tmp_path / "x.mat")
    with pytest.raises(ValidationError, match="already a phyloc dataset"):
        pds.import_arrays(c2 / "c2.h5", tmp_path / "y.h5")


# -- command line ----------------------------------------------------------------------------
def test_import_and_export_from_the_command_line(c2, tmp_path, capsys):
    out = tmp_path / "cli.h5"
    recipe = tmp_path / "eval.toml"
    recipe.write_text(
        'kind = "localization"\nname = "lab"\nseed = 9\n[channel]\nscenario = "winner2_b1"\n'
        '[experiment]\nmethods = ["corr"]\n'
    )
    assert main(["import", str(c2 / "c2.npz"), "-o", str(out), "--recipe", str(recipe)]) == 0
    assert "2 realization(s) x 1 snapshot(s), 4 agents + 0 anchors" in capsys.readouterr().out
    with pds.open(out) as ds:
        stored = ds.load_recipe()
    assert (stored.name, stored.seed, stored.section("experiment")["methods"]) == (
        "lab",
        9,
        ["corr"],
    )
    assert stored.section("channel")["scenario"] == "winner2_b1"
    assert main(["info", str(out), "--verify"]) == 0
    before = out.read_bytes()
    capsys.readouterr()
    assert main(["import", str(c2 / "c2.npz"), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "exists" in err and "--force" in err and err.count("\n") == 1
    assert out.read_bytes() == before
    bad = tmp_path / "bad.npz"
    arrays = _load(c2 / "c2.npz")
    arrays["symbols"] = arrays["symbols"][:, :3]
    np.savez(bad, **arrays)
    assert main(["import", str(bad), "-o", str(tmp_path / "bad.h5")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("phyloc: error: symbols = array of shape (2, 3, 257)")
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "bad.h5").exists()
    assert main(["import", str(tmp_path / "nope.npz"), "-o", str(tmp_path / "n.h5")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["import", str(c2 / "c2.npz"), "-o", str(out), "--force"]) == 0
    exported = tmp_path / "again.npz"
    assert main(["export", str(out), "-o", str(exported)]) == 0
    assert main(["export", str(out), "-o", str(exported)]) == 2
    assert "exists" in capsys.readouterr().err
    again = _load(exported)
    orig = _load(c2 / "c2.npz")
    for k in ("received", "links", "link_mask", "symbols", "positions", "los"):
        np.testing.assert_array_equal(again[k], orig[k], err_msg=k)

"""HDF5 waveform datasets: schema, sharded generation (serial and Dask), resume, verify, read."""

import fcntl
import os
import re
import shutil
import subprocess
import sys
import textwrap

import h5py
import numpy as np
import pytest
from masters import edited_master, restamp

import phyloc.datasets as pds
from phyloc.datasets import schema as sc
from phyloc.datasets.integrity import check_shard_files
from phyloc.datasets.shard import CRASH_ENV
from phyloc.errors import PhylocError, ValidationError
from phyloc.parallel import task_seeds
from phyloc.phy.correlation import correlation_tables
from phyloc.phy.waveform import to_time_domain
from phyloc.reporting import OutputExistsError

TINY = """
kind = "dataset"
name = "tiny"
seed = 11

[system]
n_subcarriers = 65
subcarrier_spacing_hz = 1.0e6

[network]
n_agents = 4
region_m = [60.0, 60.0]

[channel]
scenario = "winner2_c2"

[dataset]
realizations = 4
shard_size = 1
"""

TRACKING = """
kind = "dataset"
name = "tiny_tracking"
seed = 3

[system]
n_subcarriers = 33
subcarrier_spacing_hz = 2.0e6
oversampling = 2

[network]
n_agents = 5
region_m = [60.0, 60.0]
anchors = 3
comm_range_m = 45.0
on_isolated = "allow"

[network.motion]
model = "constant_velocity"
n_snapshots = 6
dt_s = 1.0
initial_speed_std = 3.0

[channel]
scenario = "winner2_b1"
ranging = "two_way"

[dataset]
realizations = 3
shard_size = 2
compression = "gzip"
"""


@pytest.fixture(autouse=True)
def _quiet(monkeypatch):
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    monkeypatch.delenv(CRASH_ENV, raising=False)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The tiny dataset generated once, uninterrupted, in this process."""
    out = tmp_path_factory.mktemp("ref") / "ref.h5"
    summary = pds.generate(TINY, out, progress=False)
    return out, summary


def _copy_dataset(src, dst_dir):
    dst = dst_dir / src.name
    shutil.copy2(src, dst)
    shutil.copytree(sc.shard_dir(src), sc.shard_dir(dst))
    return dst


def _shard_sums(path):
    with h5py.File(path, "r") as f:
        return f["shards/array_sha256"][:], f["shards/file_sha256"][:]


def _checksums(path):
    with pds.open(path) as ds:
        return ds.checksums()


# -- recipes ---------------------------------------------------------------------------------
def test_realization_streams_are_the_spawned_task_streams():
    spawned = task_seeds(11, 6)
    for i in (0, 3, 5):
        a = np.random.default_rng(pds.realization_seed(11, i)).random(3)
        np.testing.assert_array_equal(a, np.random.default_rng(spawned[i]).random(3))


def test_dataset_spec_checks_every_key():
    spec = pds.DatasetSpec.from_dict({"realizations": 5, "shard_size": 2})
    assert spec.n_shards == 3 and spec.shard_range(2) == (4, 5)
    with pytest.raises(ValidationError, match=r"dataset.realisations.*did you mean 'realizations'"):
        pds.DatasetSpec.from_dict({"realisations": 4})
    with pytest.raises(ValidationError, match=r"dataset.realizations.*required"):
        pds.DatasetSpec.from_dict({"shard_size": 4})
    with pytest.raises(ValidationError, match=r"dataset.realizations.*>= 1"):
        pds.DatasetSpec.from_dict({"realizations": 0})
    with pytest.raises(ValidationError, match=r"dataset.shard_size.*integer"):
        pds.DatasetSpec.from_dict({"realizations": 2, "shard_size": "two"})
    with pytest.raises(ValidationError, match=r"dataset.compression.*gzip"):
        pds.DatasetSpec.from_dict({"realizations": 2, "compression": "zip"})


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ("realizations = 4", "realisations = 4", r"dataset.realisations.*realizations"),
        ("realizations = 4", "realizations = 0", r"dataset.realizations.*>= 1"),
        ("shard_size = 1", 'shard_size = "one"', r"dataset.shard_size.*integer"),
        ("n_subcarriers = 65", "n_subcarriers = 64", r"system.n_subcarriers.*odd"),
        ("n_agents = 4", "n_agent = 4", r"network.n_agent.*n_agents"),
        (
            "region_m = [60.0, 60.0]",
            "region_m = [60.0, 60.0]\n[network.motion]\nmodle = 1",
            r"network.motion.modle.*model",
        ),
        ('scenario = "winner2_c2"', 'scenario = "winner3"', r"scenario"),
        ('kind = "dataset"', 'kind = "localization"', r"kind.*dataset"),
        ("[dataset]\nrealizations = 4\nshard_size = 1", "", r"\[dataset\].*required"),
    ],
)
def test_bad_recipes_fail_before_any_work(tmp_path, old, new, match):
    assert old in TINY
    out = tmp_path / "bad.h5"
    with pytest.raises(ValidationError, match=match):
        pds.generate(TINY.replace(old, new), out, progress=False)
    assert not out.exists() and not sc.shard_dir(out).exists()


def test_recipes_shipped_in_datasets_folder_validate():
    root = os.path.join(os.path.dirname(__file__), "..", "datasets")
    for name in ("quickstart_c2.toml", "example_tracking.toml"):
        plan = pds.plan_dataset(os.path.join(root, name))
        assert plan.dataset.realizations >= 1
    plan = pds.plan_dataset(os.path.join(root, "quickstart_c2.toml"))
    assert plan.network.n_agents == 12 and plan.network.n_anchors == 0
    assert plan.channel.scenario == "winner2_c2"


# -- round trip ------------------------------------------------------------------------------
def test_round_trip_equals_in_memory_simulation(reference):
    out, summary = reference
    assert summary["shards_written"] == 4 and summary["links"] == 4 * 12
    with pds.open(out) as ds:
        assert (ds.n_realizations, ds.n_snapshots, ds.max_links) == (4, 1, 12)
        assert ds.system.n_subcarriers == 65 and ds.complete and "[dataset]" in ds.recipe
        assert ds.received.dtype == np.complex64 and ds.received.chunks is None  # virtual
        for r in range(ds.n_realizations):
            mem = pds.simulate_recipe_realization(TINY, r)
            snap = ds.snapshot(r, 0)
            np.testing.assert_array_equal(snap.positions, mem.network.positions[0])
            np.testing.assert_array_equal(snap.links, mem.links[0])
            np.testing.assert_array_equal(snap.tx_index, mem.links[0][:, 1])
            np.testing.assert_array_equal(
                snap.samples, to_time_domain(mem.received[0], ds.system).astype(np.complex64)
            )
            scale = np.abs(mem.received[0]).max()
            np.testing.assert_allclose(snap.received, mem.received[0], rtol=0, atol=1e-6 * scale)
            np.testing.assert_allclose(snap.symbols, mem.symbols, rtol=0, atol=1e-7)
            draw = mem.channels[0]
            np.testing.assert_array_equal(snap.los, draw.los)
            np.testing.assert_array_equal(snap.nlos_bias_s, draw.nlos_bias_s)
            np.testing.assert_array_equal(snap.path_loss_db, draw.path_loss_db)
            np.testing.assert_array_equal(snap.shadowing_db, draw.shadowing_db)
            np.testing.assert_array_equal(snap.paths.delays, draw.paths.delays)
            np.testing.assert_array_equal(snap.paths.gains, draw.paths.gains)
            np.testing.assert_array_equal(snap.paths.offsets, draw.paths.offsets)
            np.testing.assert_allclose(
                10 ** (snap.snr_db / 10) * ds.system.noise_power_w,
                draw.received_power_w,
                rtol=1e-12,
            )
            # correlation tables from the stored waveforms match the in-memory ones
            a = correlation_tables(snap.received, snap.symbols, ds.system, tx_index=snap.tx_index)
            b = correlation_tables(
                mem.received[0], mem.symbols, ds.system, tx_index=mem.links[0][:, 1]
            )
            np.testing.assert_allclose(a.values, b.values, atol=1e-5 * np.abs(b.values).max())
            np.testing.assert_array_equal(
                np.abs(a.values).argmax(axis=1), np.abs(b.values).argmax(axis=1)
            )
        # the rebuilt Realization is what evaluate consumes
        real = ds.realization(2)
        mem = pds.simulate_recipe_realization(TINY, 2)
        np.testing.assert_array_equal(real.network.links_at(0), mem.links[0])
        assert real.ways == 1 and real.channels[0].scenario == "winner2_c2"
        assert [r.network.n_nodes for r in ds] == [4] * 4
        assert len(list(ds.snapshots())) == 4


def test_ragged_links_over_snapshots_are_padded_with_a_mask(tmp_path):
    out = tmp_path / "track.h5"
    pds.generate(TRACKING, out, progress=False)
    with pds.open(out) as ds:
        counts = ds["links/count"][:]
        assert ds.max_links == counts.max() and counts.min() < counts.max()  # links change
        valid = ds["links/valid"][:].astype(bool)
        pairs = ds["links/pairs"][:]
        np.testing.assert_array_equal(valid.sum(axis=-1), counts)
        assert np.all(pairs[~valid] == -1) and np.all(ds["received"][:][~valid] == 0)
        assert ds["received"].shape[-1] == 2 * 33 and ds.ways == 2
        for r in range(3):
            mem = pds.simulate_recipe_realization(TRACKING, r)
            real = ds.realization(r)
            for t in range(6):
                snap = ds.snapshot(r, t)
                np.testing.assert_array_equal(snap.links, mem.links[t])
                np.testing.assert_array_equal(snap.velocities, mem.network.velocities[t])
                np.testing.assert_array_equal(
                    real.channels[t].paths.delays, mem.channels[t].paths.delays
                )
                scale = np.abs(mem.received[t]).max()
                np.testing.assert_allclose(real.received[t], mem.received[t], atol=1e-6 * scale)
    assert pds.info(out, verify=True)["ok"]


# -- workers, existing outputs, crashes ------------------------------------------------------
def test_one_and_two_dask_workers_write_identical_data(tmp_path, reference):
    ref, _ = reference
    out = tmp_path / "two.h5"
    summary = pds.generate(TINY, out, workers=2, progress=False)
    assert summary["shards_written"] == 4 and summary["workers"] == 2
    a_arr, a_file = _shard_sums(ref)
    b_arr, b_file = _shard_sums(out)
    np.testing.assert_array_equal(a_arr, b_arr)  # every array of every shard
    np.testing.assert_array_equal(a_file, b_file)  # and the shard files, byte for byte
    assert _checksums(ref) == _checksums(out)


def test_existing_output_is_never_overwritten(tmp_path, reference):
    out = _copy_dataset(reference[0], tmp_path)
    before = sc.sha256_file(out)
    with pytest.raises(OutputExistsError, match="--resume") as exc:
        pds.generate(TINY, out, progress=False)
    assert isinstance(exc.value, PhylocError)
    assert sc.sha256_file(out) == before
    other = TINY.replace("seed = 11", "seed = 12")
    with pytest.raises(pds.DatasetMismatchError, match="different recipe"):
        pds.generate(other, out, resume=True, progress=False)
    # resume of a complete dataset redoes nothing
    s = pds.generate(TINY, out, resume=True, progress=False)
    assert (s["shards_written"], s["shards_reused"]) == (0, 4)


def test_killed_generation_keeps_finished_shards_and_resume_matches(tmp_path, reference):
    out = tmp_path / "killed.h5"
    recipe = tmp_path / "tiny.toml"
    recipe.write_text(TINY)
    code = textwrap.dedent(f"""
        import phyloc.datasets as pds
        pds.generate({str(recipe)!r}, {str(out)!r}, progress=False)
    """)
    env = dict(os.environ, **{CRASH_ENV: "2:kill"})
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, timeout=120)
    assert proc.returncode == -9, proc.stderr.decode()
    sdir = sc.shard_dir(out)
    done = sorted(p.name for p in sdir.glob("shard-*.h5"))
    assert done == ["shard-00000.h5", "shard-00001.h5"]
    assert list(sdir.glob(".shard-00002.h5.tmp-*"))  # the half-written shard of the crash
    kept = {p: (p.stat().st_ino, p.stat().st_mtime_ns) for p in sdir.glob("shard-*.h5")}
    status = pds.info(out, verify=True)
    assert not status["ok"] and not status["complete"]
    s = pds.generate(recipe, out, resume=True, progress=False)
    assert (s["shards_written"], s["shards_reused"]) == (2, 2)
    assert kept == {p: (p.stat().st_ino, p.stat().st_mtime_ns) for p in kept}  # not redone
    assert not list(sdir.glob(".shard-*.tmp-*"))
    np.testing.assert_array_equal(_shard_sums(out)[0], _shard_sums(reference[0])[0])
    assert _checksums(out) == _checksums(reference[0])
    assert pds.info(out, verify=True)["ok"]


def test_failed_shard_is_reported_and_resume_finishes(tmp_path, reference, monkeypatch):
    out = tmp_path / "failed.h5"
    monkeypatch.setenv(CRASH_ENV, "1")
    with pytest.raises(pds.ShardGenerationError, match=r"1 of 4 shards failed.*--resume"):
        pds.generate(TINY, out, progress=False)
    monkeypatch.delenv(CRASH_ENV)
    info = pds.info(out)
    assert info["shards_complete"] == 3 and not info["complete"]
    assert info["realizations_available"] == 3
    with pds.open(out) as ds:
        assert not ds.available(1) and ds.available(2)
        with pytest.raises(pds.DatasetError, match=r"shard 1.*--resume"):
            ds.snapshot(1, 0)
    s = pds.generate(TINY, out, resume=True, progress=False)
    assert (s["shards_written"], s["shards_reused"]) == (1, 3)
    assert _checksums(out) == _checksums(reference[0])


def test_verify_finds_truncated_and_bit_flipped_shards_and_resume_repairs(tmp_path, reference):
    out = _copy_dataset(reference[0], tmp_path)
    sdir = sc.shard_dir(out)
    truncated, flipped = sdir / "shard-00001.h5", sdir / "shard-00002.h5"
    with open(truncated, "r+b") as fh:
        fh.truncate(truncated.stat().st_size // 2)
    with h5py.File(flipped, "r") as f:  # a byte inside the received samples
        offset = f["received"].id.get_chunk_info(0).byte_offset + 101
    with open(flipped, "r+b") as fh:
        fh.seek(offset)
        byte = fh.read(1)[0]
        fh.seek(offset)
        fh.write(bytes([byte ^ 0x10]))
    status = pds.info(out, verify=True)
    assert not status["ok"] and status["corrupt_shards"] == [1, 2] and status["shards_ok"] == 2
    (sdir / "shard-00003.h5").unlink()
    status = pds.verify(out)
    assert status["missing_shards"] == [3] and status["corrupt_shards"] == [1, 2]
    s = pds.generate(TINY, out, resume=True, progress=False)
    assert (s["shards_written"], s["shards_reused"]) == (3, 1)
    assert pds.verify(out)["ok"]
    assert _checksums(out) == _checksums(reference[0])


def test_array_checksum_catches_flip_without_master_record(tmp_path, reference):
    """A flipped sample is caught by the array checksum alone (master record not consulted)."""
    out = _copy_dataset(reference[0], tmp_path)
    shard = sc.shard_dir(out) / "shard-00000.h5"
    with h5py.File(shard, "r+") as f:
        x = f["received"][0, 0, 0, 0]
        f["received"][0, 0, 0, 0] = x + np.complex64(1e-3)
    arrays = sc.arrays_for({})
    rec, kind, reason = sc.check_shard(
        shard,
        index=0,
        start=0,
        stop=1,
        fingerprint=pds.plan_dataset(TINY).fingerprint,
        arrays=arrays,
    )
    assert rec is None and kind == "corrupt" and "received" in reason


def test_newer_schema_and_foreign_files_are_refused(tmp_path, reference):
    out = _copy_dataset(reference[0], tmp_path)
    with edited_master(out) as f:
        f.attrs["schema_version"] = "2.0"
    for call in (pds.open, pds.info):
        with pytest.raises(pds.SchemaVersionError, match=r"schema 2.0, newer.*upgrade phyloc"):
            call(out)
    with pytest.raises(pds.SchemaVersionError):
        pds.generate(TINY, out, resume=True, progress=False)
    with edited_master(out) as f:
        f.attrs["schema_version"] = "1.7"  # a newer minor version is readable
    assert pds.info(out)["schema_version"] == "1.7"
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = 1
    with pytest.raises(pds.DatasetError, match="not a phyloc dataset"):
        pds.open(other)
    with pytest.raises(pds.DatasetError, match="does not exist"):
        pds.open(tmp_path / "nothing.h5")


def test_concurrent_generation_of_one_output_is_refused(tmp_path, reference):
    out = _copy_dataset(reference[0], tmp_path)
    with open(sc.shard_dir(out) / ".lock", "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        with pytest.raises(pds.DatasetBusyError, match="another phyloc generate"):
            pds.generate(TINY, out, resume=True, progress=False)


def test_master_records_schema_and_units(reference):
    out, _ = reference
    with h5py.File(out, "r") as f:
        assert f.attrs["format"] == sc.MASTER_FORMAT
        assert f.attrs["schema_version"] == pds.SCHEMA_VERSION
        assert f.attrs["seed"] == 11 and "n_subcarriers = 65" in f.attrs["recipe"]
        assert f["system"].attrs["noise_power_w"] > 0
        assert f["received"].is_virtual and f["received"].attrs["units"] == "sqrt(W)"
        assert f["nodes/positions"].attrs["units"] == "m"
        assert f["channel/nlos_bias_s"].attrs["units"] == "s"
        assert list(f["shards/complete"][:]) == [1, 1, 1, 1]
    with h5py.File(sc.shard_dir(out) / "shard-00000.h5", "r") as f:
        assert f.attrs["format"] == sc.SHARD_FORMAT
        for name in sc.ARRAY_NAMES:
            if name in f:
                assert f[name].attrs["sha256"] == sc.sha256_h5(f[name])


def test_recipe_built_in_code_is_stored_as_loadable_toml(tmp_path):
    import tomllib

    from phyloc.config import parse_recipe

    recipe = parse_recipe(tomllib.loads(TINY.replace("realizations = 4", "realizations = 1")))
    assert recipe.text == ""
    out = tmp_path / "code.h5"
    pds.generate(recipe, out, progress=False)
    with pds.open(out) as ds:
        again = pds.plan_dataset(ds.load_recipe())
    assert again.fingerprint == pds.plan_dataset(recipe).fingerprint


def test_every_master_array_has_named_dimension_scales(reference):
    """Schema 1.1: each array of the master (and of its shard table) has one attached HDF5
    dimension scale per axis, named as its ``axes`` attribute says, of the right length."""
    out, _ = reference
    with h5py.File(out, "r") as f:
        names = [sc._text(x) for x in f["shards/array_sha256"].attrs["arrays"]]
        assert set(names) == {a.name for a in sc.arrays_for({})}
        for name in names:
            d = f[name]
            axes = sc._text(d.attrs["axes"]).split(",")
            assert len(d.dims) == len(axes)
            for i, ax in enumerate(axes):
                (scale,) = d.dims[i].values()
                assert scale.name == f"/{ax}" and scale.shape == (d.shape[i],), (name, ax)
        for d in f["shards"].values():
            assert f["shards/complete"].shape[0] == len(f["shard"]) == d.shape[0]
            assert d.dims[0][0].name == "/shard"


def test_xarray_opens_the_master_with_named_dimensions_and_coordinates(reference):
    """``open_xarray`` (h5netcdf) gives named dimensions, no ``phony_dim``, coordinate values
    (subcarrier frequencies n·f_sc, sample times i·T), units, and the same numbers as h5py."""
    pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    out, _ = reference
    tree = pds.open_xarray(out)
    root, nodes = tree.dataset, tree["nodes"].dataset
    assert root["received"].dims == ("realization", "snapshot", "link", "sample")
    assert nodes["positions"].dims == ("realization", "snapshot", "node", "coordinate")
    assert tree["channel/paths"].dataset["gains"].dims == ("path",)
    assert tree["shards"].dataset["array_sha256"].dims == ("shard", "array")
    every = [d for node in tree.subtree for d in node.dataset.dims]
    assert every and not any(str(d).startswith("phony_dim") for d in every)
    n = np.arange(65) - 32
    np.testing.assert_allclose(root["subcarrier"].values, n * 1.0e6)
    assert root["subcarrier"].attrs["units"] == "Hz"
    np.testing.assert_allclose(np.diff(root["sample"].values), 1.0 / (65 * 1.0e6), rtol=1e-12)
    assert nodes["positions"].attrs["units"] == "m"
    with h5py.File(out, "r") as f:
        np.testing.assert_array_equal(root["received"].values, f["received"][...])
        np.testing.assert_array_equal(nodes["positions"].values, f["nodes/positions"][...])


def _h5dump(*args):
    exe = shutil.which("h5dump")
    if exe is None:
        pytest.skip("h5dump (hdf5-tools) is not installed")
    return subprocess.run([exe, *args], capture_output=True, text=True, check=True).stdout


def test_h5dump_sees_every_array_its_dimension_scales_and_the_shards(reference):
    """The HDF5 command-line tool (not h5py) reads the master as datasets/README.md says:
    every array of the schema with its shape, a DIMENSION_LIST naming the scales of its
    ``axes`` in order, virtual mappings to relative shard paths, and the waveform values."""
    out, _ = reference
    with h5py.File(out, "r") as f:
        names = [sc._text(x) for x in f["shards/array_sha256"].attrs["arrays"]]
        for name in names:
            attrs = _h5dump("-A", "-d", f"/{name}", str(out))  # header and attribute values
            space = re.search(r"DATASPACE\s+SIMPLE { \( ([\d, ]+) \)", attrs)
            assert tuple(int(x) for x in space.group(1).split(",")) == f[name].shape, name
            scales = re.findall(r'\(DATASET \d+ "(/[^"]+)"\)', attrs)
            axes = sc._text(f[name].attrs["axes"]).split(",")
            assert scales == [f"/{ax}" for ax in axes], name
        layout = _h5dump("-p", "-H", "-A", "0", "-d", "/received", str(out))
        files = re.findall(r'FILE "([^"]+)"', layout)
        assert files == [f"ref.h5.shards/shard-{j:05d}.h5" for j in range(4)]
        dump = _h5dump(
            "-A", "0", "-m", "%.9g", "-d", "/received", "-s", "2,0,1,0", "-c", "1,1,1,3", str(out)
        )
        data = re.sub(r"\(\d+(,\d+)*\):", "", dump.split("DATA {", 1)[1])
        values = [float(x) for x in re.findall(r"[-+]?\d[\d.]*(?:e[-+]?\d+)?", data)]
        expected = f["received"][2, 0, 1, :3]
        np.testing.assert_allclose(values[0::2], expected.real, rtol=1e-7)
        np.testing.assert_allclose(values[1::2], expected.imag, rtol=1e-7)


def test_schema_1_0_files_stay_readable_but_are_not_opened_by_xarray(tmp_path, reference):
    """A master of schema 1.0 (no dimension scales) reads as before; ``open_xarray`` refuses it
    with the reason instead of returning phony dimensions."""
    out = _copy_dataset(reference[0], tmp_path)
    with edited_master(out) as f:
        for name in ("realization", "snapshot", "node", "coordinate", "link", "end"):
            del f[name]  # the scales a 1.0 writer never made (detached with them)
        f.attrs["schema_version"] = "1.0"
    with pds.open(out) as ds:
        assert ds.schema_version == "1.0" and ds.realization(0).network.n_nodes == 4
    with pytest.raises(pds.DatasetError, match=r"schema 1\.0, without dimension scales"):
        pds.open_xarray(out)


def _flip_stored_byte(path, dataset, index=0):
    """Flip one bit of ``dataset``'s raw bytes in the file itself (contiguous storage)."""
    with h5py.File(path, "r") as f:
        d = f[dataset]
        offset = d.id.get_offset() + index * d.dtype.itemsize
    with open(path, "r+b") as fh:
        fh.seek(offset)
        byte = fh.read(1)
        fh.seek(offset)
        fh.write(bytes([byte[0] ^ 0x04]))


def test_verify_checks_the_master_itself(tmp_path, reference):
    """The master's own content is checksummed: a bit flipped in its shard table on disk, an
    attribute changed or a group deleted is reported by ``verify`` (and makes ``ok`` False),
    while every shard still verifies; a missing root attribute is a clear DatasetError."""
    sound = pds.verify(reference[0])
    assert sound["ok"] and sound["master_ok"] and "master" not in sound["problems"]
    with h5py.File(reference[0], "r") as f:
        assert len(sc._text(f.attrs[sc.MASTER_DIGEST_ATTR])) == 64

    cases = {
        "flip": lambda p: (_flip_stored_byte(p, "shards/bytes", 1), restamp(p)),
        "attribute": lambda p: _edit(p, lambda f: f.attrs.__setitem__("seed", 12)),
        "group": lambda p: _edit(p, lambda f: f.__delitem__("channel")),
        "units": lambda p: _edit(p, lambda f: f["received"].attrs.__setitem__("units", "W")),
    }
    for name, damage in cases.items():
        case = tmp_path / name
        case.mkdir()
        out = _copy_dataset(reference[0], case)
        damage(out)
        res = pds.verify(out)
        assert not res["ok"] and not res["master_ok"], name
        assert res["shards_ok"] == 4 and "master" in res["problems"], name
        with pytest.raises(pds.DatasetError, match="master"):
            check_shard_files(out)
    out = _copy_dataset(reference[0], tmp_path)
    _edit(out, lambda f: f.attrs.__delitem__("scenario"))
    with pytest.raises(pds.DatasetError, match=r"master file is corrupt.*scenario.*--resume"):
        pds.open(out)


def test_a_master_whose_bytes_changed_is_refused_before_hdf5_reads_it(tmp_path, reference):
    """Schema 1.2: the master's bytes carry their SHA-256 in a 512-byte user block. A bit
    flipped anywhere in the file (the header, HDF5 metadata, free space, the shard table) is
    refused by open, verify and the evaluation's shard check with the rebuild command, before
    HDF5 parses it: a flip in a virtual dataset's mapping made HDF5 crash the process."""
    src = reference[0]
    data = src.read_bytes()
    assert data.startswith(sc.MASTER_HEADER_MAGIC)
    assert data[sc.MASTER_HEADER_BYTES :].startswith(sc.HDF5_SIGNATURE)
    with h5py.File(src, "r") as f:  # every HDF5 reader skips the user block
        assert f.userblock_size == sc.MASTER_HEADER_BYTES and "received" in f
    out = _copy_dataset(src, tmp_path)
    for offset in [0, 40, 100, 511, *range(512, len(data), max(1, len(data) // 97))]:
        out.write_bytes(data[:offset] + bytes([data[offset] ^ 0x10]) + data[offset + 1 :])
        for call in (pds.open, pds.verify, check_shard_files):
            with pytest.raises(pds.DatasetError, match=r"header|SHA-256 in its header"):
                call(out)
    out.write_bytes(data)
    assert pds.verify(out)["ok"]


def test_a_master_without_its_header_is_reported_by_verify(tmp_path, reference):
    """A 1.2 master whose user block was stripped (HDF5 signature first) still opens, but
    ``verify`` reports the missing byte checksum."""
    out = _copy_dataset(reference[0], tmp_path)
    out.write_bytes(out.read_bytes()[sc.MASTER_HEADER_BYTES :])
    with pds.open(out) as ds:
        assert ds.n_shards == 4
    res = pds.verify(out)
    assert not res["ok"] and "byte checksum header is missing" in res["problems"]["master"]


def _edit(path, change):
    with edited_master(path) as f:
        change(f)

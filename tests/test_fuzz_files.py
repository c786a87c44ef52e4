"""Property-based file fuzzing: a dataset damaged anywhere (a bit flipped at a random offset of
the master or of a shard, or a file truncated) is reported by ``verify`` or refused by the
reader with phyloc's error; when ``verify`` finds nothing, every array reads back exactly as
before. Never a silent wrong read.

Profiles as in ``test_fuzz_recipes.py`` (``PHYLOC_FUZZ=slow``: 600 examples).
"""

import os
import shutil
import tempfile
from pathlib import Path

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import phyloc.datasets as pds  # noqa: E402
from phyloc.datasets import schema as sc  # noqa: E402
from phyloc.errors import PhylocError  # noqa: E402

RECIPE = """
kind = "dataset"
name = "fz"
seed = 5
[system]
n_subcarriers = 33
subcarrier_spacing_hz = 2.0e6
[network]
n_agents = 3
region_m = [40.0, 40.0]
[channel]
scenario = "winner2_c2"
[dataset]
realizations = 2
shard_size = 1
"""


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    os.environ["PHYLOC_NO_PROGRESS"] = "1"
    out = tmp_path_factory.mktemp("fz") / "fz.h5"
    pds.generate(RECIPE, out, progress=False)
    with pds.open(out) as ds:
        sums = ds.checksums()
    return out, sums


def _copy(src: Path, folder: Path) -> Path:
    dst = folder / src.name
    shutil.copy2(src, dst)
    shutil.copytree(sc.shard_dir(src), sc.shard_dir(dst))
    return dst


def _target(path: Path, which: str) -> Path:
    if which == "master":
        return path
    return sorted(sc.shard_dir(path).glob("shard-*.h5"))[int(which[-1])]


@given(
    which=st.sampled_from(["master", "shard0", "shard1"]),
    where=st.floats(0.0, 1.0, exclude_max=True),
    damage=st.sampled_from(["flip", "flip", "truncate"]),
    bit=st.integers(0, 7),
)
def test_damage_anywhere_is_reported_or_harmless(original, which, where, damage, bit):
    src, sums = original
    with tempfile.TemporaryDirectory() as tmp:
        path = _copy(src, Path(tmp))
        target = _target(path, which)
        data = bytearray(target.read_bytes())
        at = int(where * len(data))
        if damage == "flip":
            data[at] ^= 1 << bit
        else:
            data = data[:at]
        target.write_bytes(bytes(data))
        try:
            report = pds.verify(path)
        except PhylocError:
            return  # refused with a clear error
        if which != "master" or damage == "truncate":
            # shards are checksummed as files; a truncated master cannot hold its content
            assert not report["ok"], (which, damage, at)
            return
        if report["ok"]:  # a flip the master does not read (free space, padding)
            try:
                with pds.open(path) as ds:
                    assert ds.checksums() == sums, (which, at, bit)
            except PhylocError:
                pass

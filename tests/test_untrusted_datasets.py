"""A dataset from someone else cannot make phyloc read files outside its own folder: a master
whose shard table names a path outside, or a shard that is a link to a file elsewhere, is
refused in one line before anything is read."""

import os
import shutil

import h5py
import pytest

from phyloc.cli import main

RECIPE = (
    'kind = "dataset"\nname = "d"\nseed = 3\n[system]\nn_subcarriers = 65\n'
    '[network]\nn_agents = 3\n[channel]\nscenario = "awgn"\n'
    "[dataset]\nrealizations = 2\nshard_size = 1\n"
)


@pytest.fixture
def dataset(tmp_path, monkeypatch):
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    folder = tmp_path / "given"
    folder.mkdir()
    (folder / "d.toml").write_text(RECIPE)
    h5 = folder / "d.h5"
    assert main(["generate", str(folder / "d.toml"), "-o", str(h5)]) == 0
    assert main(["info", str(h5), "--verify"]) == 0
    return h5


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("name", ["../outside.h5", "/etc/passwd", "d.h5.shards/../../x.h5"])
def test_a_shard_table_naming_files_outside_is_refused(dataset, capsys, name):
    with h5py.File(dataset, "r+") as f:
        files = f["shards/file"]
        files[0] = name
    capsys.readouterr()
    assert main(["info", str(dataset)]) == 2
    line = _one_line(capsys)
    assert "shards/file" in line and repr(name) in line and "outside" in line


def test_a_shard_linked_to_a_file_elsewhere_is_refused(dataset, tmp_path, capsys):
    shard = sorted((dataset.parent / "d.h5.shards").glob("shard-*.h5"))[0]
    elsewhere = tmp_path / "elsewhere.h5"
    shutil.move(shard, elsewhere)
    os.symlink(elsewhere, shard)
    capsys.readouterr()
    assert main(["info", str(dataset)]) == 2
    line = _one_line(capsys)
    assert shard.name in line and "outside" in line

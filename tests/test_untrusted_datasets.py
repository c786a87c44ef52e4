"""A dataset or a recipe from someone else cannot make phyloc read files outside its own
folder: a master whose shard table names a path outside, a shard that is a link to a file
elsewhere, or a recipe naming a scenario file outside its folder is refused in one line before
anything is read."""

import os
import shutil

import h5py
import pytest
from masters import edited_master

from phyloc.cli import main
from phyloc.errors import ValidationError

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
    with edited_master(dataset) as f:
        files = f["shards/file"]
        files[0] = name
    capsys.readouterr()
    assert main(["info", str(dataset)]) == 2
    line = _one_line(capsys)
    assert "shards/file" in line and repr(name) in line and "outside" in line


@pytest.mark.parametrize(
    "edit, words",
    [
        (lambda f: f.attrs.modify("n_shards", 3), "rows where n_shards = 3"),
        (lambda f: f.attrs.modify("n_shards", 1), "rows where n_shards = 1"),
        (lambda f: f["shards/realization_stop"].__setitem__(1, 7), "realization ranges"),
        (lambda f: f["shards/realization_start"].__setitem__(0, -1), "realization ranges"),
    ],
)
def test_a_shard_table_disagreeing_with_the_master_is_refused(dataset, capsys, edit, words):
    """A bit flip in n_shards once made ``info --verify`` index past the table."""
    with edited_master(dataset) as f:
        edit(f)
    capsys.readouterr()
    for command in (["info", str(dataset)], ["info", str(dataset), "--verify"]):
        assert main(command) == 2
        line = _one_line(capsys)
        assert words in line and "--resume" in line and str(dataset) in line


def test_a_shard_linked_to_a_file_elsewhere_is_refused(dataset, tmp_path, capsys):
    shard = sorted((dataset.parent / "d.h5.shards").glob("shard-*.h5"))[0]
    elsewhere = tmp_path / "elsewhere.h5"
    shutil.move(shard, elsewhere)
    os.symlink(elsewhere, shard)
    capsys.readouterr()
    assert main(["info", str(dataset)]) == 2
    line = _one_line(capsys)
    assert shard.name in line and "outside" in line


# -- recipes: a scenario file named in a recipe must lie in the recipe's folder ---------------
def _recipe_naming(folder, scenario, key="scenario"):
    text = RECIPE.replace('scenario = "awgn"', f"{key} = {scenario!r}".replace("'", '"'))
    path = folder / "r.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("where", ["absolute", "parent", "link"])
def test_a_recipe_cannot_name_a_scenario_file_outside_its_folder(tmp_path, capsys, where):
    outside = tmp_path / "secret.toml"
    outside.write_text("secret = 1\n")
    folder = tmp_path / "given"
    folder.mkdir()
    value = {"absolute": str(outside), "parent": "../secret.toml", "link": "chan.toml"}[where]
    if where == "link":
        os.symlink(outside, folder / "chan.toml")
    recipe = _recipe_naming(folder, value)
    out = folder / "d.h5"
    assert main(["generate", str(recipe), "-o", str(out)]) == 2
    line = _one_line(capsys)
    assert "channel.scenario" in line and value in line and str(folder) in line
    assert "secret = 1" not in line and "secret" not in line.replace("secret.toml", "")
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        ["r.toml", *(["chan.toml"] if where == "link" else [])]
    )


def test_the_refusal_shows_a_long_path_whole_and_cuts_other_values(tmp_path, capsys):
    deep = tmp_path / ("d" * 60) / ("e" * 60)
    deep.mkdir(parents=True)
    outside = deep / "secret.toml"
    outside.write_text("secret = 1\n")
    folder = tmp_path / "given"
    folder.mkdir()
    recipe = _recipe_naming(folder, str(outside))
    assert len(str(outside)) > 80
    assert main(["generate", str(recipe), "-o", str(folder / "d.h5")]) == 2
    assert str(outside) in _one_line(capsys)
    # a value that is not plain text (here a list) is cut at 80 characters
    with pytest.raises(ValidationError) as err:
        raise ValidationError("x", list(range(100)), "less")
    shown = str(err.value).split(" = ", 1)[1].split(" is not allowed")[0]
    assert len(shown) == 80 and shown.endswith("...")


def test_a_scenario_file_next_to_the_recipe_is_read_from_there(tmp_path, capsys, monkeypatch):
    from phyloc.channels.scenario import shipped_root

    folder = tmp_path / "given"
    (folder / "chan").mkdir(parents=True)
    shutil.copy(shipped_root() / "awgn.toml", folder / "chan" / "mine.toml")
    recipe = _recipe_naming(folder, "chan/mine.toml")
    elsewhere = tmp_path / "cwd"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # relative to the recipe, not to the working folder
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    assert main(["generate", str(recipe), "-o", str(folder / "d.h5")]) == 0


def test_scenario_lists_and_tables_are_checked_too(tmp_path, capsys):
    from phyloc.config import scenario_files_inside
    from phyloc.errors import ValidationError

    doc = {"experiment": {"scenarios": ["winner2_c2", "/etc/passwd"]}}
    with pytest.raises(ValidationError, match=r"experiment\.scenarios\[1\]"):
        scenario_files_inside(doc, tmp_path)
    doc = {"experiment": {"scenarios": {"c2": "winner2_c2", "x": "../x.toml"}}}
    with pytest.raises(ValidationError, match=r"experiment\.scenarios\.x"):
        scenario_files_inside(doc, tmp_path)
    ok = {"experiment": {"scenarios": {"s1": {"n_agents": 5}}, "scenario_localization": {}}}
    assert scenario_files_inside(ok, tmp_path) == ok


# -- HDF5 references to other files: external links, external raw data, virtual sources ------
def test_a_master_with_an_external_link_is_refused(dataset, tmp_path, capsys):
    target = tmp_path / "elsewhere.h5"
    with h5py.File(target, "w") as f:
        f["x"] = [1, 2, 3]
    with edited_master(dataset) as f:
        f["sneaky"] = h5py.ExternalLink(str(target), "/x")
    capsys.readouterr()
    assert main(["info", str(dataset)]) == 2
    line = _one_line(capsys)
    assert "sneaky" in line and "external link" in line and str(target) in line


def test_a_shard_keeping_data_in_an_external_file_is_refused(dataset, tmp_path, capsys):
    """The crafted case: the shard's and the master's checksums recomputed to match, so only
    the structure gives it away."""
    from phyloc.datasets import schema as sc

    secret = tmp_path / "secret.bin"
    secret.write_bytes(b"\x01" * 64)
    shard = sorted((dataset.parent / "d.h5.shards").glob("shard-*.h5"))[0]
    with h5py.File(shard, "r+") as f:
        f.create_dataset("leak", shape=(64,), dtype="u1", external=[(str(secret), 0, 64)])
    with edited_master(dataset) as f:
        f["shards/file_sha256"][0] = sc.sha256_file(shard).encode()
        f.attrs[sc.MASTER_DIGEST_ATTR] = sc.master_digest(f)
    capsys.readouterr()
    assert main(["evaluate", str(dataset), "--fast", "--out", str(tmp_path / "res")]) == 2
    line = _one_line(capsys)
    assert shard.name in line and "leak" in line and "external file" in line
    assert not (tmp_path / "res").exists()


def test_an_import_source_with_an_external_link_is_refused(tmp_path, capsys):
    target = tmp_path / "elsewhere.h5"
    with h5py.File(target, "w") as f:
        f["positions"] = [[0.0, 0.0]]
    src = tmp_path / "given.h5"
    with h5py.File(src, "w") as f:
        f["received"] = h5py.ExternalLink(str(target), "/positions")
    capsys.readouterr()
    assert main(["import", str(src), "-o", str(tmp_path / "out.h5")]) == 2
    line = _one_line(capsys)
    assert "external link" in line and str(target) in line


# -- absurd declared sizes: refused from the headers, nothing allocated ----------------------
def _declare_huge(path, name, n_samples=2**36):
    """Replace array ``name`` by one of the same leading shape but ``n_samples`` along its
    last axis: chunked, nothing written (HDF5 keeps only the header; reading it would
    allocate terabytes of fill values). Its attributes are kept."""
    with h5py.File(path, "r+") as f:
        old = f[name]
        shape, dtype, attrs = old.shape, old.dtype, dict(old.attrs)
        del f[name]
        new = f.create_dataset(
            name, shape=(*shape[:-1], n_samples), dtype=dtype, chunks=(*shape[:-1], 64)
        )
        for k, val in attrs.items():
            new.attrs[k] = val


def test_a_shard_declaring_terabytes_is_refused_before_it_is_read(dataset, tmp_path, capsys):
    """The crafted case: the shard's ``received`` declares 2³⁶ samples per link (6 TiB at
    this size), the checksums of the file and the master recomputed to match. ``verify`` used
    to end in "internal error: MemoryError: Unable to allocate 6.00 TiB"; the header gives it
    away now, and the reads through the master never reach it."""
    from phyloc.datasets import schema as sc

    shard = sorted((dataset.parent / "d.h5.shards").glob("shard-*.h5"))[0]
    _declare_huge(shard, "received")
    with edited_master(dataset) as f:
        f["shards/file_sha256"][0] = sc.sha256_file(shard).encode()
        f.attrs[sc.MASTER_DIGEST_ATTR] = sc.master_digest(f)
    capsys.readouterr()
    assert main(["info", str(dataset), "--verify"]) == 1
    out = capsys.readouterr()
    assert "Traceback" not in out.err and "internal error" not in out.err
    assert "array received declares shape (1, 1, 6, 68719476736)" in out.out
    assert "refused before reading" in out.out


@pytest.mark.parametrize("where", ["received", "extra"])
def test_a_master_declaring_more_than_the_memory_is_refused(dataset, capsys, where):
    """A master whose ``received`` declares more per realization than this machine's memory,
    or which holds an extra dataset of 2⁴⁰ elements (``verify`` reads the master's own
    datasets whole to checksum them: it used to end in "internal error: MemoryError"):
    refused in one line when it is opened, before its checksum is computed."""
    with edited_master(dataset) as f:
        if where == "received":
            del f["received"]  # the virtual dataset; an ordinary one declaring 2^40 samples
            f.create_dataset("received", shape=(2, 1, 6, 2**40), dtype="c8", chunks=(1, 1, 6, 64))
        else:
            f.create_dataset("extra", shape=(2**40,), dtype="c8", chunks=(64,))
    for argv in (["info", str(dataset)], ["info", str(dataset), "--verify"]):
        capsys.readouterr()
        assert main(argv) == 2
        line = _one_line(capsys)
        assert "more than this machine's" in line and "refusing it before reading" in line
        assert ("GB per realization" if where == "received" else "master file's own") in line

"""A full disk: one line naming the path, nothing half-written, --resume finishes the work.

Faults are injected the way the cluster tests inject a killed worker: a fake allocation that
fails from a chosen shard on, a failing ``posix_fallocate`` and ``open``, and — where the
tests may mount one (root) — a real 6 MB file system that fills.
"""

import errno
import json
import os
import pickle
import shutil
import subprocess
import sys
import uuid
from pathlib import Path

import pytest
from test_datasets import TINY

import phyloc._files as files
import phyloc.datasets as pds
import phyloc.datasets.shard as shard_mod
from phyloc.datasets import schema as sc

PHYLOC = [sys.executable, "-m", "phyloc.cli"]  # the command line, in a child process


@pytest.fixture(autouse=True)
def _quiet(monkeypatch):
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")


def _checksums(path):
    with pds.open(path) as ds:
        return ds.checksums()


def test_disk_full_error_names_the_folder_and_survives_pickling(tmp_path):
    exc = files.DiskFullError(tmp_path, 5_000_000, 1_000, "shard 3")
    again = pickle.loads(pickle.dumps(exc))  # crosses from a Dask worker to the client
    for e in (exc, again):
        assert e.errno == errno.ENOSPC and e.filename == str(tmp_path)
        assert (e.need, e.free) == (5_000_000, 1_000)
        assert "shard 3" in e.strerror and "5.0 MB" in e.strerror


def test_require_space_compares_with_the_free_bytes(tmp_path, monkeypatch):
    monkeypatch.setattr(files, "free_bytes", lambda folder: 10 * files.SPACE_MARGIN_BYTES)
    files.require_space(tmp_path, 9 * files.SPACE_MARGIN_BYTES, "fits")
    with pytest.raises(files.DiskFullError, match="too big"):
        files.require_space(tmp_path, 9 * files.SPACE_MARGIN_BYTES + 1, "too big")


def test_reserve_space_allocates_and_reports_a_full_disk(tmp_path, monkeypatch):
    f = tmp_path / "a.bin"
    f.write_bytes(b"x")
    files.reserve_space(f, 4096, "a file")
    assert f.stat().st_size == 4096 and f.read_bytes()[:1] == b"x"

    def full(fd, offset, length):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "posix_fallocate", full, raising=False)
    with pytest.raises(files.DiskFullError, match="a file") as info:
        files.reserve_space(f, 10**6, "a file")
    assert info.value.filename == str(tmp_path)

    def unsupported(fd, offset, length):  # e.g. a network file system
        raise OSError(errno.EOPNOTSUPP, "Operation not supported")

    checked = []
    monkeypatch.setattr(os, "posix_fallocate", unsupported)
    monkeypatch.setattr(files, "require_space", lambda *a: checked.append(a))
    files.reserve_space(f, 123, "a file")
    assert checked == [(tmp_path, 123, "a file")]


def test_write_atomic_keeps_the_old_file_and_names_the_path(tmp_path, monkeypatch):
    target = tmp_path / "results.json"
    target.write_text("old")
    files.write_atomic(target, b"new")
    assert target.read_bytes() == b"new"

    real_open = open

    def failing_open(path, mode="r", *args, **kwargs):
        fh = real_open(path, mode, *args, **kwargs)
        if "w" in mode:

            def write(data):
                raise OSError(errno.ENOSPC, "No space left on device")

            fh.write = write
        return fh

    monkeypatch.setattr("builtins.open", failing_open)
    with pytest.raises(OSError) as info:
        files.write_atomic(target, b"newer")
    monkeypatch.undo()
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(target)
    assert target.read_bytes() == b"new"  # the old content stays
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.json"]  # no temporary


def test_generation_stops_at_the_first_full_shard_and_resume_matches(tmp_path, monkeypatch):
    reference = pds.generate(TINY, tmp_path / "ref.h5", progress=False)["path"]
    out = tmp_path / "full.h5"
    tried = []
    real = shard_mod.reserve_space

    def fills_at_shard_2(path, nbytes, what):
        tried.append(what)
        if what == "shard 2":
            raise files.DiskFullError(Path(path).parent, nbytes, 0, what)
        real(path, nbytes, what)

    monkeypatch.setattr(shard_mod, "reserve_space", fills_at_shard_2)
    with pytest.raises(pds.ShardGenerationError) as info:
        pds.generate(TINY, out, progress=False)
    line = str(info.value)
    assert "\n" not in line and "disk is full" in line and "--resume" in line
    assert str(sc.shard_dir(out)) in line and "2 of 4 shards complete" in line
    assert tried == ["shard 0", "shard 1", "shard 2"]  # shard 3 never tried
    sdir = sc.shard_dir(out)
    assert sorted(p.name for p in sdir.iterdir()) == [".lock", "shard-00000.h5", "shard-00001.h5"]
    assert pds.info(out)["shards_complete"] == 2  # the master is current and readable
    monkeypatch.undo()
    s = pds.generate(TINY, out, resume=True, progress=False)
    assert (s["shards_written"], s["shards_reused"]) == (2, 2)
    assert _checksums(out) == _checksums(reference)


def test_master_that_does_not_fit_keeps_the_previous_one(tmp_path, monkeypatch):
    out = tmp_path / "m.h5"
    pds.generate(TINY, out, progress=False)
    before = out.read_bytes()
    monkeypatch.setattr(files, "free_bytes", lambda folder: 0)
    with pytest.raises(files.DiskFullError) as info:
        pds.generate(TINY, out, resume=True, progress=False)
    assert info.value.filename == str(tmp_path)
    assert out.read_bytes() == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def _small_filesystem():
    """A fresh 6 MB tmpfs, or None where this process may not mount one."""
    if not sys.platform.startswith("linux") or shutil.which("mount") is None:
        return None
    where = Path("/tmp") / f"phyloc-full-{uuid.uuid4().hex[:8]}"
    where.mkdir()
    cmd = ["mount", "-t", "tmpfs", "-o", "size=6m", "tmpfs", str(where)]
    if os.geteuid() != 0 or subprocess.run(cmd, capture_output=True).returncode != 0:
        where.rmdir()
        return None
    return where


def test_a_real_full_disk_with_two_workers_is_one_line(tmp_path):
    """The reported case: ``generate --workers 2`` into a 6 MB file system printed tracebacks
    and died of a segmentation fault. Now: one line, exit 2, only complete shards left."""
    where = _small_filesystem()
    if where is None:
        pytest.skip("needs a tmpfs mount (root on Linux)")
    try:
        recipe = tmp_path / "tiny.toml"
        big = TINY.replace("n_subcarriers = 65", "n_subcarriers = 4097")
        recipe.write_text(big.replace("realizations = 4", "realizations = 24"))  # ~14 MB
        out = where / "x.h5"
        proc = subprocess.run(
            [*PHYLOC, "generate", str(recipe), "-o", str(out), "--workers", "2", "--no-progress"],
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert proc.returncode == 2, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
        assert "disk is full" in lines[0] and "--resume" in lines[0]
        names = sorted(p.name for p in sc.shard_dir(out).iterdir())
        assert all(n == ".lock" or n.startswith("shard-") for n in names), names
        assert pds.info(out, verify=True)["corrupt_shards"] == []
    finally:
        subprocess.run(["umount", str(where)], capture_output=True)
        where.rmdir()


def test_evaluate_on_a_full_disk_names_the_task_file_and_resume_finishes(
    tmp_path, capsys, monkeypatch
):
    from test_cli import TINY as RANGING
    from test_cli import _one_line

    from phyloc.cli import main

    recipe = tmp_path / "tiny.toml"
    recipe.write_text(RANGING.replace("realizations = 1", "realizations = 3"))
    out = tmp_path / "res"
    writes = []
    real = files.free_bytes

    def fills_after_two_tasks(folder):
        if Path(folder).parent.name == ".tasks":  # a task file, not the run's metadata
            writes.append(folder)
            if len(writes) > 2:
                return 0
        return real(folder)

    monkeypatch.setattr(files, "free_bytes", fills_after_two_tasks)
    assert main(["evaluate", str(recipe), "--out", str(out)]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "not enough space for 2.pkl" in line and str(out / ".tasks") in line
    assert "finished tasks are kept" in line and "--resume" in line and "shard" not in line
    assert not (out / "results.json").exists()
    assert not list(out.rglob(".*.tmp-*"))  # nothing half-written
    monkeypatch.undo()
    assert main(["evaluate", str(recipe), "--out", str(out), "--resume"]) == 0
    assert main(["evaluate", str(recipe), "--out", str(tmp_path / "fresh")]) == 0

    def numbers(folder):
        figures = json.loads((folder / "results.json").read_text())["figures"]
        return {k: v for k, v in figures.items() if not k.startswith("run.")}

    assert numbers(out) == numbers(tmp_path / "fresh")  # the kept tasks are the same tasks

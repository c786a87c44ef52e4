"""The command line: results, refusals to overwrite, and errors without tracebacks."""

import json

import pytest

from phyloc.cli import main

TINY = """
kind = "ranging"
name = "tiny"
seed = 1
[system]
n_subcarriers = 257
subcarrier_spacing_hz = 146.5e3
[network]
region_m = [60.0, 60.0]
[ranging]
methods = ["corr", "sage"]
[ranging.sage]
n_paths = 3
n_iter = 3
[experiment]
scenarios = { c2 = "winner2_c2" }
agents = [4]
realizations = 1
awgn_snr_db = [20, 30]
awgn_links = 60
"""


def test_evaluate_writes_results_and_never_overwrites(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    recipe = tmp_path / "tiny.toml"
    recipe.write_text(TINY)
    out = tmp_path / "res"
    assert main(["evaluate", str(recipe), "--out", str(out)]) == 0
    doc = json.loads((out / "results.json").read_text())
    f = doc["figures"]
    for name in ("corr.c2.rmse_m", "sage.c2.rmse_m", "corr.awgn.crb_ratio_30db", "c2.n_links"):
        assert name in f
    assert f["c2.n_links"] == 12  # 4 agents, fully meshed, both directions
    assert doc["meta"]["seed"] == 1 and "recipe_text" in doc["meta"]
    # every run records its wall time and worker count among its figures
    assert f["run.workers"] == 1 and f["run.wall_s"] == doc["meta"]["seconds"] > 0
    assert (out / "tiny.png").stat().st_size > 1000
    assert (out / "recipe.toml").read_text() == TINY
    before = (out / "results.json").read_bytes()
    capsys.readouterr()
    assert main(["evaluate", str(recipe), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "exists" in err and "--force" in err and "Traceback" not in err
    assert (out / "results.json").read_bytes() == before


def test_bad_inputs_exit_2_with_one_line(tmp_path, capsys):
    assert main(["channel-stats", "winner2_x"]) == 2
    err = capsys.readouterr().err
    assert "valid names" in err and "winner2_c2" in err and "Traceback" not in err
    bad = tmp_path / "bad.toml"
    bad.write_text(TINY.replace("realizations = 1", "realizations = 0"))
    assert main(["evaluate", str(bad), "--out", str(tmp_path / "x")]) == 2
    assert "experiment.realizations = 0" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()  # nothing started
    existing = tmp_path / "b.json"
    existing.write_text("{}")
    assert main(["bench", "phy", "--json", str(existing)]) == 2
    assert existing.read_text() == "{}"


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert "phyloc" in capsys.readouterr().out


def test_generate_info_and_verify_from_the_command_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    recipe = tmp_path / "d.toml"
    recipe.write_text(
        'kind = "dataset"\nname = "d"\nseed = 3\n[system]\nn_subcarriers = 65\n'
        '[network]\nn_agents = 3\n[channel]\nscenario = "awgn"\n'
        "[dataset]\nrealizations = 2\nshard_size = 1\n"
    )
    h5 = tmp_path / "d.h5"
    assert main(["generate", str(recipe), "-o", str(h5)]) == 0
    assert main(["generate", str(recipe), "-o", str(h5)]) == 2  # never overwritten
    assert "--resume" in capsys.readouterr().err
    assert main(["info", str(h5), "--verify", "--json", str(tmp_path / "i.json")]) == 0
    shard = sorted((tmp_path / "d.h5.shards").glob("shard-*.h5"))[0]
    data = bytearray(shard.read_bytes())
    data[len(data) // 2] ^= 0xFF  # flip a bit in the middle of the shard
    shard.write_bytes(bytes(data))
    assert main(["info", str(h5), "--verify", "--json", str(tmp_path / "bad.json")]) == 1
    # per shard: its status and the digest the master records, which the sound file has
    import hashlib

    shards = json.loads((tmp_path / "bad.json").read_text())["meta"]["shards"]
    assert [x["index"] for x in shards] == [0, 1]
    by_file = {x["file"].split("/")[-1]: x for x in shards}
    assert by_file[shard.name]["status"] == "corrupt" and by_file[shard.name]["reason"]
    (other,) = [x for x in shards if x["file"].split("/")[-1] != shard.name]
    assert other["status"] == "ok" and other["reason"] == ""
    other_file = shard.parent / other["file"].split("/")[-1]
    assert other["sha256"] == hashlib.sha256(other_file.read_bytes()).hexdigest()
    assert by_file[shard.name]["sha256"] != hashlib.sha256(shard.read_bytes()).hexdigest()
    assert main(["generate", str(recipe), "-o", str(h5), "--resume"]) == 0
    assert main(["info", str(h5), "--verify"]) == 0
    assert main(["evaluate", str(recipe)]) == 2  # a dataset recipe is not an experiment
    assert "phyloc generate" in capsys.readouterr().err


def test_quickstart_hands_complete_arguments_to_generate_and_evaluate(tmp_path, monkeypatch):
    """quickstart calls the two sub-commands with every option they read (a Namespace built by
    hand once lacked ``--plugin`` and crashed the README's main command)."""
    from phyloc import cli, commands

    seen = {}
    monkeypatch.setattr(commands, "cmd_generate", lambda a: seen.setdefault("generate", a))
    monkeypatch.setattr(commands, "cmd_evaluate", lambda a: seen.setdefault("evaluate", a) and 0)
    assert main(["quickstart", "--dir", str(tmp_path), "--workers", "2", "--no-progress"]) == 0
    parser = cli.build_parser()
    ref_gen = parser.parse_args(["generate", "r.toml", "-o", "o.h5"])
    ref_ev = parser.parse_args(["evaluate", "o.h5"])
    assert set(vars(seen["generate"])) == set(vars(ref_gen))
    assert set(vars(seen["evaluate"])) == set(vars(ref_ev))
    assert seen["evaluate"].workers == 2 and seen["evaluate"].no_progress
    assert seen["evaluate"].plugin == []
    assert seen["evaluate"].recipe == str(tmp_path / "quickstart_c2.h5")


DATASET = (
    'kind = "dataset"\nname = "d"\nseed = 3\n[system]\nn_subcarriers = 65\n'
    '[network]\nn_agents = 3\n[channel]\nscenario = "awgn"\n'
    "[dataset]\nrealizations = 2\nshard_size = 1\n"
)


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_directories_and_binary_files_are_named_as_such(tmp_path, capsys):
    """A directory given as recipe or dataset is called a directory (not "does not exist"); a
    binary recipe is called not UTF-8; each is one line and exit 2."""
    assert main(["evaluate", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    line = _one_line(capsys.readouterr().err)
    assert f"{tmp_path} is a directory" in line and "TOML" in line
    assert main(["info", str(tmp_path)]) == 2
    assert "is a directory" in _one_line(capsys.readouterr().err)
    binary = tmp_path / "r.toml"
    binary.write_bytes(b'name = "x"\n\xff\xfe\x00garbage')
    assert main(["generate", str(binary), "-o", str(tmp_path / "d.h5")]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "not UTF-8" in line and "0xff" in line and "offset 11" in line
    assert not (tmp_path / "d.h5").exists()


def test_an_empty_method_list_is_refused_before_any_work(tmp_path, capsys):
    recipe = tmp_path / "loc.toml"
    recipe.write_text('kind = "localization"\nname = "loc"\nseed = 1\n[experiment]\nmethods = []\n')
    assert main(["evaluate", str(recipe), "--out", str(tmp_path / "o")]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "experiment.methods" in line and "at least one of" in line and "dipnet" in line
    assert not (tmp_path / "o").exists()


def test_results_json_gets_the_umask_mode_not_0600(tmp_path):
    """``write_json`` goes through a temporary file (mode 0600) but ends with the mode any
    other file gets (``0o666 & ~umask``)."""
    import os

    from phyloc.reporting import write_json

    old = os.umask(0o022)
    try:
        path = write_json(tmp_path / "r.json", {"a": 1.0}, {})
        assert (path.stat().st_mode & 0o777) == 0o644
        os.umask(0o027)
        path = write_json(tmp_path / "s.json", {"a": 1.0}, {})
        assert (path.stat().st_mode & 0o777) == 0o640
    finally:
        os.umask(old)


def test_every_help_page_prints(capsys):
    """``phyloc --help`` and every command's ``--help`` print and exit 0 (argparse expands
    ``%`` in help strings: a bare one breaks the whole page)."""
    from phyloc.cli import ANALYSES, COMMANDS

    names = [c[0] for c in COMMANDS]
    pages = [[], *([n] for n in names), *(["analyze", a[0]] for a in ANALYSES)]
    for argv in pages:
        with pytest.raises(SystemExit) as stop:
            main([*argv, "--help"])
        assert stop.value.code == 0, argv
        assert "usage: phyloc" in capsys.readouterr().out, argv
    assert "claims" in names


def test_force_help_names_only_outputs_the_command_has(capsys):
    for argv, png in ((["info"], False), (["bench"], False), (["channel-stats"], True)):
        with pytest.raises(SystemExit):
            main([*argv, "--help"])
        out = " ".join(capsys.readouterr().out.split())
        assert ("--png" in out) == png, argv
        assert "replace an existing --json" in out


def test_interrupted_generate_says_how_to_finish(tmp_path, capsys, monkeypatch):
    import phyloc.datasets

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(phyloc.datasets, "generate", interrupted)
    recipe = tmp_path / "d.toml"
    recipe.write_text(DATASET)
    assert main(["generate", str(recipe), "-o", str(tmp_path / "d.h5")]) == 130
    line = _one_line(capsys.readouterr().err)
    assert "interrupted" in line and "--resume" in line


def test_a_resume_that_writes_nothing_reports_no_bandwidth(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    recipe = tmp_path / "d.toml"
    recipe.write_text(DATASET)
    h5 = tmp_path / "d.h5"
    assert main(["generate", str(recipe), "-o", str(h5)]) == 0
    assert "write_mb_per_s" in capsys.readouterr().out
    assert (
        main(
            ["generate", str(recipe), "-o", str(h5), "--resume", "--json", str(tmp_path / "g.json")]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "write_mb_per_s" not in out and "nan" not in out
    assert "write_mb_per_s" not in json.loads((tmp_path / "g.json").read_text())["figures"]


@pytest.mark.parametrize(
    ("section", "key"),
    [
        ('[experiment]\nmethods = ["foo"]\n', "experiment.methods"),
        ("[experiment]\nmethods = []\n", "experiment.methods"),
        ("[experiment]\nmethdos = []\n", "experiment.methdos"),
        ("[localization]\nn_particles = 0\n", "n_particles"),
        ("[ranging]\nbeta = 0\n", "ranging.beta"),
        ("[ranging]\nwindow_m = [300, 0]\n", "ranging.window_m"),
    ],
)
def test_generate_validates_what_evaluate_reads_before_any_work(tmp_path, capsys, section, key):
    """The [experiment], [ranging] and [localization] sections of a dataset recipe are only
    read by ``evaluate``; ``generate`` refuses bad ones first, with evaluate's message, and
    leaves no file behind."""
    recipe = tmp_path / "d.toml"
    recipe.write_text(DATASET + section)
    out = tmp_path / "d.h5"
    assert main(["generate", str(recipe), "-o", str(out)]) == 2
    assert key in _one_line(capsys.readouterr().err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.toml"]


def test_an_unreachable_scheduler_is_one_line_and_leaves_nothing_behind(
    tmp_path, capsys, monkeypatch
):
    """generate --scheduler at an address where nobody listens, and at a malformed address:
    exit 2 with one line naming the address, no master, lock or shard folder left, so the
    same command can be rerun as is."""
    import socket

    import phyloc.parallel

    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    monkeypatch.setattr(phyloc.parallel, "SCHEDULER_TIMEOUT_S", 2.0)
    with socket.socket() as s:  # a free port: nothing listens there
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    recipe = tmp_path / "d.toml"
    recipe.write_text(DATASET)
    out = tmp_path / "d.h5"
    for address in (f"tcp://127.0.0.1:{port}", "not a scheduler address"):
        assert main(["generate", str(recipe), "-o", str(out), "--scheduler", address]) == 2
        line = _one_line(capsys.readouterr().err)
        assert "cannot connect to the Dask scheduler" in line and repr(address) in line
        assert sorted(p.name for p in tmp_path.iterdir()) == ["d.toml"]


def test_os_errors_and_defects_are_one_line_and_debug_shows_the_traceback(
    tmp_path, capsys, monkeypatch
):
    """A full disk or a denied permission (simulated: the tests may run as root) is one line
    with the path and the remedy, exit 2; an unexpected exception is one line pointing to
    --debug, exit 1; --debug re-raises it."""
    import errno

    import phyloc.datasets

    recipe = tmp_path / "d.toml"
    recipe.write_text(DATASET)
    out = str(tmp_path / "d.h5")
    cases = [
        (OSError(errno.ENOSPC, "No space left on device", out), 2, "disk is full"),
        (PermissionError(errno.EACCES, "Permission denied", out), 2, "check the permissions"),
        (RuntimeError("a defect"), 1, "run with --debug for the traceback"),
    ]
    for exc, code, text in cases:

        def fail(*args, _exc=exc, **kwargs):
            raise _exc

        monkeypatch.setattr(phyloc.datasets, "generate", fail)
        assert main(["generate", str(recipe), "-o", out]) == code
        line = _one_line(capsys.readouterr().err)
        assert text in line and (code == 1 or out in line)
    with pytest.raises(RuntimeError, match="a defect"):
        main(["--debug", "generate", str(recipe), "-o", out])


def test_evaluate_out_that_is_a_file_is_refused(tmp_path, capsys):
    recipe = tmp_path / "tiny.toml"
    recipe.write_text(TINY)
    target = tmp_path / "results.txt"
    target.write_text("keep me")
    assert main(["evaluate", str(recipe), "--out", str(target)]) == 2
    assert "--out" in _one_line(capsys.readouterr().err)
    assert target.read_text() == "keep me"


def test_sizes_that_cannot_fit_name_the_keys_the_user_wrote(tmp_path, capsys):
    """A network too large for one HDF5 chunk names network.n_agents (not chunk_links, which
    the user never wrote) and the size; a shard beyond this machine's memory names
    dataset.shard_size and how much it would need."""
    huge = tmp_path / "huge.toml"
    huge.write_text(DATASET.replace("n_agents = 3", "n_agents = 1000000000"))
    assert main(["generate", str(huge), "-o", str(tmp_path / "h.h5")]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "network.n_agents = 1000000000" in line and "GiB" in line and "chunk_links" in line
    big = tmp_path / "big.toml"
    big.write_text(
        DATASET.replace("n_subcarriers = 65", "n_subcarriers = 2569")
        .replace("n_agents = 3", "n_agents = 300")
        .replace("realizations = 2\nshard_size = 1", "realizations = 1000\nshard_size = 1000")
    )
    assert main(["generate", str(big), "-o", str(tmp_path / "b.h5")]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "dataset.shard_size = 1000" in line and "of memory" in line and "GiB" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.toml", "huge.toml"]


def test_force_never_touches_a_folder_a_live_run_holds(tmp_path, capsys):
    """A second ``evaluate --force`` into the folder of a run still in progress (its task
    store locked, here by a store held open in this process) is refused in one line naming
    the process, and the live run's kept tasks and its results folder are left as they were;
    without --force the refusal offers --resume first (the finished tasks are kept)."""
    import os

    from phyloc.parallel import TaskStore

    recipe = tmp_path / "tiny.toml"
    recipe.write_text(TINY)
    out = tmp_path / "res"
    live = TaskStore(
        out / ".tasks", {"recipe_sha256": "x", "source": "tiny.toml", "fast": False}, resume=False
    )
    (out / ".tasks" / "abc").mkdir()
    (out / ".tasks" / "abc" / "0.pkl").write_bytes(b"kept")
    before = sorted(p.relative_to(out) for p in out.rglob("*"))
    try:
        capsys.readouterr()
        assert main(["evaluate", str(recipe), "--out", str(out), "--force"]) == 2
        line = _one_line(capsys.readouterr().err)
        assert f"process {os.getpid()}" in line and "--force does not touch" in line
        assert sorted(p.relative_to(out) for p in out.rglob("*")) == before
        assert (out / ".tasks" / "abc" / "0.pkl").read_bytes() == b"kept"
        assert main(["evaluate", str(recipe), "--out", str(out)]) == 2
        line = _one_line(capsys.readouterr().err)
        assert "unfinished run" in line and line.index("--resume") < line.index("--force")
    finally:
        live.close()


def test_force_starts_over_once_the_folder_is_free(tmp_path, capsys):
    """With no live run, --force discards the old tasks (a stale task file is not read back:
    a run from scratch gives the same figures as in a fresh folder) and a complete run leaves
    no task store behind."""
    from phyloc.parallel import TaskStore

    recipe = tmp_path / "tiny.toml"
    recipe.write_text(TINY)
    fresh, out = tmp_path / "fresh", tmp_path / "res"
    assert main(["evaluate", str(recipe), "--out", str(fresh)]) == 0
    stale = TaskStore(
        out / ".tasks", {"recipe_sha256": "x", "source": "t", "fast": False}, resume=False
    )
    stale.close()
    (out / ".tasks" / "junk.pkl").write_bytes(b"stale")
    assert main(["evaluate", str(recipe), "--out", str(out), "--force"]) == 0
    assert not (out / ".tasks").exists() and not (fresh / ".tasks").exists()
    a = json.loads((fresh / "results.json").read_text())["figures"]
    b = json.loads((out / "results.json").read_text())["figures"]
    from phyloc.reporting import is_measurement

    keep = [k for k in a if not k.startswith("run.") and not is_measurement(k)]
    assert keep and sorted(keep) == sorted(
        k for k in b if not k.startswith("run.") and not is_measurement(k)
    )
    assert all(a[k] == b[k] for k in keep)

"""A real Dask cluster: a scheduler and two workers as processes on 127.0.0.1, one worker killed
mid-run. ``generate --scheduler`` finishes and its dataset is bit-identical to an in-process
one; ``evaluate --scheduler`` of a Monte Carlo recipe gives the in-process figures."""

import json
import os
import signal
import socket
import subprocess
import sys
import time

import pytest
from test_cli import TINY
from tiny import tiny_recipe

import phyloc.datasets as pds
from phyloc.cli import main

pytestmark = pytest.mark.cluster

DATASET = tiny_recipe(
    "dataset", "cl", 21, ranging=None, dataset={"realizations": 16, "shard_size": 1}
)

# test_cli's tiny ranging recipe with enough realizations to spread over both workers
RANGING = TINY.replace('name = "tiny"', 'name = "clr"').replace(
    "realizations = 1", "realizations = 6"
)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for(predicate, seconds, what):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if predicate():
            return
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


def _listening(port) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


@pytest.fixture
def cluster(tmp_path):
    """``(address, workers)``: a scheduler and two single-threaded workers without nannies
    (a killed worker stays dead), torn down afterwards."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PHYLOC_NO_PROGRESS": "1"}
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "env": env}
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
             "--port", str(port), "--no-dashboard"],
            **quiet,
        )
    ]  # fmt: skip
    try:
        _wait_for(lambda: _listening(port), 60, "the scheduler")
        workers = [
            subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads",
                 "1", "--no-nanny", "--no-dashboard", "--name", f"w{i}"],
                **quiet,
            )
            for i in range(2)
        ]  # fmt: skip
        procs += workers
        from dask.distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        yield address, workers
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
            p.wait(timeout=30)


def test_generate_on_a_cluster_survives_a_killed_worker_bit_identically(tmp_path, cluster):
    address, workers = cluster
    recipe = tmp_path / "cl.toml"
    recipe.write_text(DATASET)
    out = tmp_path / "cluster.h5"
    env = {**os.environ, "PHYLOC_NO_PROGRESS": "1"}
    run = subprocess.Popen(
        [sys.executable, "-m", "phyloc.cli", "generate", str(recipe), "-o", str(out),
         "--scheduler", address],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    shards = pds.schema.shard_dir(out)
    _wait_for(lambda: len(list(shards.glob("shard-*.h5"))) >= 2, 120, "two finished shards")
    workers[0].send_signal(signal.SIGKILL)
    done_at_kill = len(list(shards.glob("shard-*.h5")))
    assert done_at_kill < 16  # mid-run: shards were still to come
    _, stderr = run.communicate(timeout=240)
    assert run.returncode == 0, stderr
    assert workers[0].wait(timeout=10) == -signal.SIGKILL
    assert pds.verify(out)["ok"]
    ref = tmp_path / "local.h5"
    pds.generate(DATASET, ref, progress=False)
    with pds.open(out) as a, pds.open(ref) as b:
        assert a.checksums() == b.checksums()


def test_evaluate_on_a_cluster_gives_the_in_process_figures(tmp_path, cluster, monkeypatch):
    address, _ = cluster
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    recipe = tmp_path / "clr.toml"
    recipe.write_text(RANGING)
    runs = {}
    for label, extra in (("cluster", ["--scheduler", address]), ("local", [])):
        out = tmp_path / label
        assert main(["evaluate", str(recipe), "--out", str(out), "--no-progress", *extra]) == 0
        runs[label] = json.loads((out / "results.json").read_text())["figures"]
    same = {k for k in runs["local"] if not k.startswith("run.") and "seconds" not in k}
    assert same and {k: runs["cluster"][k] for k in same} == {k: runs["local"][k] for k in same}
    assert runs["cluster"]["run.workers"] == 0  # a scheduler: the worker count is not ours


def test_workers_without_the_plugin_are_named_before_any_work(
    tmp_path, cluster, capsys, monkeypatch
):
    """``evaluate --plugin P --scheduler A`` whose workers were started without the plugin:
    one line saying that the workers do not know the method and how to start them with it
    (not the worker's "method = … is not allowed"), before any task runs."""
    from test_plugins import EXAMPLE, _recipe

    from phyloc.localization import METHODS, registry

    monkeypatch.setattr(METHODS, "_methods", dict(METHODS._methods))
    monkeypatch.setattr(registry, "_loaded", set())
    # set, then deleted: monkeypatch records the variable and restores (or removes) it
    # afterwards; delenv alone records nothing when it is unset, and the --plugin the
    # test passes would leak into later tests (and the workers they start)
    monkeypatch.setenv("PHYLOC_PLUGINS", "")
    monkeypatch.delenv("PHYLOC_PLUGINS")
    address, _ = cluster
    recipe = tmp_path / "p.toml"
    recipe.write_text(_recipe())
    out = tmp_path / "out"
    argv = ["evaluate", str(recipe), "--out", str(out), "--scheduler", address]
    assert main([*argv, "--plugin", str(EXAMPLE)]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "2 of the 2 workers" in err and "prior_mean" in err
    assert f"PHYLOC_PLUGINS={EXAMPLE}" in err and f"dask worker {address}" in err
    assert not out.exists()

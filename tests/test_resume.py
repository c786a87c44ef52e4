"""Resumable runs: finished tasks are kept on disk and read back, never mixed across runs."""

import json

import numpy as np
import pytest

from phyloc import parallel
from phyloc.cli import main
from phyloc.parallel import TaskStore, TaskStoreBusy, TaskStoreMismatch, run_tasks, task_store

ID = {"recipe_sha256": "abc", "source": "r.toml", "fast": True}


_INTERRUPT_AT = [None]  # in-process runs only: the task at which _draw is interrupted


def _draw(payload, seed_seq):
    if payload == _INTERRUPT_AT[0]:
        raise KeyboardInterrupt
    return payload, np.random.default_rng(seed_seq).standard_normal(4)


def _same(a, b):
    assert [p for p, _ in a] == [p for p, _ in b]
    for (_, x), (_, y) in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("workers", [None, 2])
def test_an_interrupted_run_resumes_to_the_uninterrupted_results(tmp_path, workers):
    """Tasks finished before the interrupt are read back (not run again), the rest run with
    their own streams: the results equal those of one uninterrupted run, bit for bit."""
    ref = run_tasks(_draw, range(6), 5, progress=False)
    d = tmp_path / "tasks"
    _INTERRUPT_AT[0] = 3
    try:
        with pytest.raises(KeyboardInterrupt), task_store(TaskStore(d, ID, resume=False)):
            run_tasks(_draw, range(6), 5, progress=False)  # in process: tasks 0-2 finish
    finally:
        _INTERRUPT_AT[0] = None
    (partial,) = [p for p in d.iterdir() if p.is_dir()]
    assert sorted(p.name for p in partial.iterdir()) == ["0.pkl", "1.pkl", "2.pkl"]
    store = TaskStore(d, ID, resume=True)
    with task_store(store):
        got = run_tasks(_draw, range(6), 5, workers=workers, progress=False)
    _same(got, ref)
    assert (store.reused, store.computed, store.invocations) == (3, 3, 2)
    calls = json.loads((d / "run.json").read_text())["calls"]  # progress, for a user to read
    assert calls == {partial.name: {"tasks": 6, "done": 6}}
    # a third invocation reads everything back and runs nothing
    store = TaskStore(d, ID, resume=True)
    with task_store(store):
        _same(run_tasks(_draw, range(6), 5, progress=False, workers=workers), ref)
    assert (store.reused, store.computed) == (6, 0)


def test_another_recipe_setting_or_code_is_refused(tmp_path, monkeypatch):
    d = tmp_path / "tasks"
    with task_store(TaskStore(d, ID, resume=False)):
        run_tasks(_draw, range(2), 5, progress=False)
    with pytest.raises(FileExistsError):  # only --resume may continue a run
        TaskStore(d, ID, resume=False)
    with pytest.raises(TaskStoreMismatch, match="fast"):
        TaskStore(d, dict(ID, fast=False), resume=True)
    monkeypatch.setattr(parallel, "source_fingerprint", lambda: "other code")
    with pytest.raises(TaskStoreMismatch, match="code"):
        TaskStore(d, ID, resume=True)


def test_one_process_at_a_time_works_on_a_store(tmp_path):
    """A second invocation on a store in use (the same long command started twice) is refused
    with the process id of the first, and may resume once the first has stopped."""
    import os

    d = tmp_path / "tasks"
    first = TaskStore(d, ID, resume=False)
    with pytest.raises(TaskStoreBusy, match=str(os.getpid())):
        TaskStore(d, ID, resume=True)
    first.close()
    second = TaskStore(d, ID, resume=True)
    assert second.invocations == 2
    second.close()


def test_other_payloads_or_seed_do_not_read_stored_tasks(tmp_path):
    d = tmp_path / "tasks"
    with task_store(TaskStore(d, ID, resume=False)):
        run_tasks(_draw, range(3), 5, progress=False)
    other_seed, other_payloads = run_tasks(_draw, range(3), 6), run_tasks(_draw, [0, 1, 7], 5)
    with task_store(TaskStore(d, ID, resume=True)) as store:
        _same(run_tasks(_draw, range(3), 6, progress=False), other_seed)
        _same(run_tasks(_draw, [0, 1, 7], 5, progress=False), other_payloads)
    assert (store.reused, store.computed) == (0, 6)


def test_a_damaged_task_file_is_run_again(tmp_path):
    d = tmp_path / "tasks"
    with task_store(TaskStore(d, ID, resume=False)):
        ref = run_tasks(_draw, range(3), 5, progress=False)
    (call,) = [p for p in d.iterdir() if p.is_dir()]
    (call / "1.pkl").write_bytes(b"\x80\x05truncated")
    with task_store(TaskStore(d, ID, resume=True)) as store:
        _same(run_tasks(_draw, range(3), 5, progress=False), ref)
    assert (store.reused, store.computed) == (2, 1)


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
methods = ["corr"]
[experiment]
scenarios = { c2 = "winner2_c2" }
agents = [4]
realizations = 3
awgn_snr_db = [20]
awgn_links = 20
"""


def test_evaluate_resume_finishes_an_interrupted_run(tmp_path, capsys, monkeypatch):
    """``evaluate`` interrupted after one task says how to finish; ``--resume`` finishes it to
    the figures of an uninterrupted run and records the wall time of both invocations."""
    monkeypatch.setenv("PHYLOC_NO_PROGRESS", "1")
    recipe = tmp_path / "tiny.toml"
    recipe.write_text(TINY)
    assert main(["evaluate", str(recipe), "--out", str(tmp_path / "ref")]) == 0
    ref = json.loads((tmp_path / "ref" / "results.json").read_text())["figures"]
    assert not (tmp_path / "ref" / ".tasks").exists()  # a complete run keeps no tasks

    calls = []
    real = parallel._OneBlasThread.__call__

    def interrupt_second(self, payload, seed):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(self, payload, seed)

    out = tmp_path / "res"
    monkeypatch.setattr(parallel._OneBlasThread, "__call__", interrupt_second)
    capsys.readouterr()
    assert main(["evaluate", str(recipe), "--out", str(out)]) == 130
    assert "--resume" in capsys.readouterr().err
    assert not (out / "results.json").exists()
    monkeypatch.setattr(parallel._OneBlasThread, "__call__", real)
    assert main(["evaluate", str(recipe), "--out", str(out)]) == 2  # never silently restarted
    assert main(["evaluate", str(recipe), "--out", str(out), "--resume"]) == 0
    assert "resumed: 1 finished tasks read back" in capsys.readouterr().out
    got = json.loads((out / "results.json").read_text())["figures"]
    assert got["run.invocations"] == 2 and got["run.tasks_reused"] == 1
    for k, val in ref.items():
        if not k.startswith("run.") and "_s" not in k and "per_s" not in k:
            assert got[k] == val, k
    assert not (out / ".tasks").exists()
    capsys.readouterr()
    assert main(["evaluate", str(recipe), "--out", str(out), "--resume"]) == 2
    assert "complete" in capsys.readouterr().err
    assert main(["evaluate", str(recipe), "--out", str(out), "--resume", "--force"]) == 2
    assert "--resume" in capsys.readouterr().err
    # a run that fails before any task finished leaves nothing behind: a plain rerun works
    monkeypatch.setattr(parallel._OneBlasThread, "__call__", interrupt_second)
    calls[:] = [1]  # the next call is the second: the first task is interrupted
    fresh = tmp_path / "fresh"
    assert main(["evaluate", str(recipe), "--out", str(fresh)]) == 130
    assert not fresh.exists()
    monkeypatch.setattr(parallel._OneBlasThread, "__call__", real)
    other = tmp_path / "other.toml"
    other.write_text(TINY.replace("seed = 1", "seed = 2"))
    monkeypatch.setattr(parallel._OneBlasThread, "__call__", interrupt_second)
    calls.clear()
    assert main(["evaluate", str(recipe), "--out", str(tmp_path / "x")]) == 130
    monkeypatch.setattr(parallel._OneBlasThread, "__call__", real)
    capsys.readouterr()
    assert main(["evaluate", str(other), "--out", str(tmp_path / "x"), "--resume"]) == 2
    err = capsys.readouterr().err
    assert "recipe_sha256" in err and "--force" in err and "Traceback" not in err

"""What a first run pays: the modules a command imports and the Numba compilation that a
reported runtime must leave out."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys


def _run(code: str, **env) -> str:
    done = subprocess.run(
        [sys.executable, "-c", code],
        env=dict(os.environ, **env),
        capture_output=True,
        text=True,
        check=True,
    )
    return done.stdout.strip().splitlines()[-1]


def test_the_registry_of_kinds_imports_an_experiment_only_when_it_is_looked_up():
    code = (
        "import sys, json\n"
        "from phyloc.evaluation import kinds\n"
        "before = sorted(m for m in sys.modules if m.endswith('_experiment'))\n"
        "exp = kinds.experiment_for('cci')\n"
        "after = sorted(m for m in sys.modules if m.endswith('_experiment'))\n"
        "print(json.dumps([before, after, exp.kind, list(kinds.KINDS)]))\n"
    )
    before, after, kind, all_kinds = json.loads(_run(code))
    assert before == []
    assert after == ["phyloc.evaluation.cci_experiment"]
    assert kind == "cci"
    assert all_kinds[-1] == "dataset" and "localization" in all_kinds


def test_a_run_reports_its_runtime_without_the_compilation(monkeypatch):
    """A kernel compiled inside the timed filter (as every kernel is on a first run, with an
    empty Numba cache) is left out of the reported wall time; ``jit_s`` holds it."""
    import time

    import numpy as np
    from numba import njit

    from phyloc.localization.direct import (
        DirectOptions,
        LinkMeasurements,
        LinkRanges,
        Prior,
        method,
        run,
    )

    real_run_dpf = method.run_dpf

    def run_dpf_compiling(*args, **kwargs):
        res = real_run_dpf(*args, **kwargs)
        t0 = time.perf_counter()
        njit(lambda x: x * 2.0 + 1.0)(1.0)  # a new function: compiled here, inside the timing
        compiled = time.perf_counter() - t0
        return dataclasses.replace(res, seconds=res.seconds + compiled)

    anchors = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    agent = np.array([3.0, 4.0])
    links = np.array([[3, 0], [3, 1], [3, 2]])
    r = np.linalg.norm(agent - anchors, axis=1)
    ranges = {"corr": LinkRanges.single(r, np.full(3, 0.01))}
    meas = LinkMeasurements(4, 2, [0, 1, 2], anchors[None], [links], ranges=ranges)
    opts = DirectOptions(likelihood="gaussian", ranges="corr", outlier_nats=np.inf)
    prior = Prior(np.random.default_rng(0).uniform(-5.0, 15.0, (1, 500, 2)))
    plain = run(meas, prior, np.random.default_rng(1), opts)  # warm: nothing left to compile
    monkeypatch.setattr(method, "run_dpf", run_dpf_compiling)
    t0 = time.perf_counter()
    res = run(meas, prior, np.random.default_rng(1), opts)
    total = time.perf_counter() - t0
    jit = res.diagnostics["jit_s"]
    assert jit > 0.0
    assert 0.0 <= res.timing.wall_s <= total - jit + 1e-3
    np.testing.assert_array_equal(res.estimates, plain.estimates)

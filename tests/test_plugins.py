"""A user's own method runs through ``phyloc evaluate --plugin`` (the documented example)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from tiny import tiny_recipe

from phyloc.cli import main
from phyloc.localization import METHODS

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "prior_mean_method.py"


def _recipe(**prior_mean) -> str:
    """The tiny recipe running the example plugin ``prior_mean`` (options ``prior_mean``)."""
    return tiny_recipe(
        "localization",
        "tiny_plugin",
        localization={"n_particles": 100, "n_iterations": 2, "prior_mean": prior_mean},
        experiment={
            "scenarios": {"c2": "winner2_c2"},
            "agents": [4],
            "realizations": 2,
            "methods": ["prior_mean", "corr"],
            "inits": ["truth_free"],
            "cdf_agents": [4],
        },
    )


def _evaluate(tmp_path, name, shrink=1.0, extra=()):
    recipe = tmp_path / f"{name}.toml"
    recipe.write_text(_recipe(shrink=shrink))
    out = tmp_path / name
    code = main(["evaluate", str(recipe), "--out", str(out), "--no-progress", *extra])
    return code, out


@pytest.fixture(autouse=True)
def _clean_registry(monkeypatch):
    """Each test registers the example afresh and leaves the registry as it found it."""
    monkeypatch.setattr(METHODS, "_methods", dict(METHODS._methods))
    # set, then deleted: monkeypatch records the variable and restores (or removes) it
    # afterwards; delenv alone records nothing when it is unset, and the --plugin the
    # test passes would leak into later tests (and the workers they start)
    monkeypatch.setenv("PHYLOC_PLUGINS", "")
    monkeypatch.delenv("PHYLOC_PLUGINS")
    from phyloc.localization import registry

    monkeypatch.setattr(registry, "_loaded", set())


def test_plugin_method_runs_from_the_command_line(tmp_path):
    code, out = _evaluate(tmp_path, "one", extra=["--plugin", str(EXAMPLE)])
    assert code == 0
    f = json.loads((out / "results.json").read_text())["figures"]
    rmse = f["prior_mean.c2.agents_4.framework_rmse_m"]
    assert math.isfinite(rmse) and rmse > 0
    assert math.isfinite(f["corr.c2.agents_4.framework_rmse_m"])
    # its options come from [localization.prior_mean]: shrinking the shape changes the
    # framework distances, so the error changes
    code, out2 = _evaluate(tmp_path, "two", shrink=0.5, extra=["--plugin", str(EXAMPLE)])
    assert code == 0
    f2 = json.loads((out2 / "results.json").read_text())["figures"]
    assert f2["prior_mean.c2.agents_4.framework_rmse_m"] != rmse
    assert f2["corr.c2.agents_4.framework_rmse_m"] == f["corr.c2.agents_4.framework_rmse_m"]


def test_plugin_reaches_dask_workers(tmp_path):
    """Worker processes import the plugin too: the same figures on 2 workers as in-process."""
    code, out1 = _evaluate(tmp_path, "serial", extra=["--plugin", str(EXAMPLE)])
    assert code == 0
    code, out2 = _evaluate(tmp_path, "dask", extra=["--plugin", str(EXAMPLE), "--workers", "2"])
    assert code == 0
    f1 = json.loads((out1 / "results.json").read_text())["figures"]
    f2 = json.loads((out2 / "results.json").read_text())["figures"]
    key = "prior_mean.c2.agents_4.framework_rmse_m"
    assert f1[key] == f2[key]


def test_unregistered_method_and_bad_plugin_are_one_line_errors(tmp_path, capsys):
    code, _ = _evaluate(tmp_path, "missing")
    assert code == 2
    err = capsys.readouterr().err
    assert "prior_mean" in err and "Traceback" not in err
    code, _ = _evaluate(tmp_path, "bad", extra=["--plugin", str(tmp_path / "nope.py")])
    assert code == 2
    assert "--plugin" in capsys.readouterr().err
    code, _ = _evaluate(tmp_path, "bad2", extra=["--plugin", "no_such_module_xyz"])
    assert code == 2
    assert "no_such_module_xyz" in capsys.readouterr().err


def test_unknown_option_of_a_plugin_method_names_the_key(tmp_path, capsys):
    recipe = tmp_path / "typo.toml"
    recipe.write_text(_recipe(shrnk=0.5))
    code = main(["evaluate", str(recipe), "--out", str(tmp_path / "t"), "--plugin", str(EXAMPLE)])
    assert code == 2
    err = capsys.readouterr().err
    assert "shrnk" in err and "shrink" in err


def _buggy_plugin(tmp_path) -> Path:
    """The example plugin with a bug in its method: ``run`` raises RuntimeError."""
    text = EXAMPLE.read_text().replace(
        "    t0 = time.perf_counter()\n", '    raise RuntimeError("my bug")\n', 1
    )
    path = tmp_path / "buggy_plugin.py"
    path.write_text(text)
    return path


@pytest.mark.parametrize("workers", [[], ["--workers", "2"]], ids=["in-process", "dask"])
def test_an_exception_in_a_plugin_method_names_the_method_and_file(tmp_path, capfd, workers):
    """A plugin method that raises: a non-zero exit with one line naming the method, the
    plugin file and the exception (no "internal error", and on workers no Dask "Compute
    Failed" log: stderr is captured at the file descriptor, the workers' included)."""
    plugin = _buggy_plugin(tmp_path)
    code, _ = _evaluate(tmp_path, "bug", extra=["--plugin", str(plugin), *workers])
    assert code != 0
    err = capfd.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    line = lines[0]
    assert "internal error" not in line and "Traceback" not in err
    assert "'prior_mean'" in line and "buggy_plugin.py" in line and "RuntimeError: my bug" in line


def test_a_plugin_with_a_syntax_error_names_file_and_line(tmp_path, capsys):
    """A plugin file that does not parse: one line with the file, the line and the error."""
    lines = EXAMPLE.read_text().splitlines()
    bad_line = next(i for i, ln in enumerate(lines) if ln.startswith("def run(")) + 1
    lines[bad_line - 1] = "def run(measurements, prior, rng, options)"  # the colon missing
    plugin = tmp_path / "broken_plugin.py"
    plugin.write_text("\n".join(lines) + "\n")
    code, _ = _evaluate(tmp_path, "broken", extra=["--plugin", str(plugin)])
    assert code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert "internal error" not in err and "Traceback" not in err
    assert "broken_plugin.py" in err and f"line {bad_line}" in err and "SyntaxError" in err

"""The experiment layer: one runner for every kind, one registry, one figure style."""

import ast
import pathlib
from dataclasses import dataclass

import numpy as np
import pytest

from phyloc.config import load_recipe
from phyloc.errors import ValidationError
from phyloc.evaluation.experiment import Experiment, RunContext, experiment_from_dict

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _spawn_key(payload, seed_seq):
    """A task that reports which stream it got and echoes its payload."""
    return {"payload": payload, "key": seed_seq.spawn_key, "draw": seed_seq.generate_state(1)[0]}


@dataclass(frozen=True)
class ToySpec:
    units: int = 3
    scale: float = 1.0


class Toy(Experiment):
    kind = "toy"
    title = "a test experiment"
    unit = "draw"
    spec = ToySpec
    task = staticmethod(_spawn_key)

    def prepare(self, recipe, *, fast=False):
        return self.experiment_spec(recipe, fast=fast)

    def tasks(self, plan):
        return [((f"u{i}",), i * plan.scale) for i in range(plan.units)]

    def aggregate(self, plan, keys, results, ctx):
        self.seen = (keys, results, ctx)
        return {"toy.sum": float(sum(r["payload"] for r in results))}, {}

    def meta(self, plan, ctx):
        return {"units": plan.units}

    def plot(self, results, path):
        pass


TOY = """
kind = "toy"
name = "toy"
seed = 11
[experiment]
units = 4
[experiment.fast]
units = 2
"""


def test_runner_gives_task_i_the_ith_spawned_stream_and_keys_in_order():
    toy = Toy()
    res = toy.run(load_recipe(TOY), progress=False)
    keys, results, ctx = toy.seen
    assert keys == [("u0",), ("u1",), ("u2",), ("u3",)]
    expected = np.random.SeedSequence(11).spawn(4)
    assert [r["key"] for r in results] == [s.spawn_key for s in expected]
    assert [r["draw"] for r in results] == [s.generate_state(1)[0] for s in expected]
    assert res["figures"] == {"toy.sum": 6.0}
    assert list(res["meta"]) == ["recipe", "kind", "seed", "fast", "units"]
    assert (res["meta"]["seed"], res["meta"]["fast"], ctx.seed) == (11, False, 11)


def test_fast_setting_wins_and_unknown_keys_are_named():
    toy = Toy()
    assert toy.run(load_recipe(TOY), fast=True, progress=False)["meta"]["units"] == 2
    with pytest.raises(ValidationError, match=r"experiment\.unit .*did you mean 'units'"):
        toy.prepare(load_recipe(TOY.replace("units = 4", "unit = 4")))
    with pytest.raises(ValidationError, match=r"experiment\.fast\.scale = x .*a number"):
        toy.prepare(load_recipe(TOY + 'scale = "x"\n'), fast=True)


def test_a_plan_without_tasks_still_aggregates():
    toy = Toy()
    res = toy.execute(ToySpec(units=0), RunContext(seed=5))
    assert res["figures"] == {"toy.sum": 0.0} and toy.seen[0] == []


def test_experiment_from_dict_reads_fast_over_full():
    spec = experiment_from_dict(ToySpec, {"units": 5, "fast": {"scale": 2.0}}, fast=True)
    assert spec == ToySpec(units=5, scale=2.0)
    assert experiment_from_dict(ToySpec, {"units": 5, "fast": {"scale": 2.0}}) == ToySpec(5, 1.0)


def test_an_experiment_must_implement_the_shape():
    class Half(Experiment):
        kind = "half"

        def prepare(self, recipe, *, fast=False):
            return None

    with pytest.raises(TypeError, match="abstract"):
        Half()


def test_registry_is_the_one_list_of_kinds():
    """Every registered kind is an Experiment with a title, a unit and a task; the command
    line, the recipe loader and the user guide name exactly these kinds."""
    from phyloc.evaluation.kinds import EXPERIMENTS, KINDS

    assert set(KINDS) == {*EXPERIMENTS, "dataset"}
    for kind, exp in EXPERIMENTS.items():
        assert isinstance(exp, Experiment) and exp.kind == kind
        assert exp.title and exp.unit
        assert exp.kind == "belief_shift" or callable(type(exp).task)
    guide = (ROOT / "docs" / "guide" / "experiments.rst").read_text()
    missing = [k for k in EXPERIMENTS if f"``{k}``" not in guide]
    assert not missing, f"docs/guide/experiments.rst does not list the kinds {missing}"


def _calls(path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            yield node


def test_one_figure_style_no_global_backend():
    """No library module selects a matplotlib backend or picks its own resolution: figures
    are made by phyloc.reporting.new_figure and written by save_figure."""
    offenders = []
    for path in sorted((ROOT / "phyloc").rglob("*.py")):
        if path.name == "reporting.py":
            continue
        for call in _calls(path):
            f = call.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
            if name == "use" and isinstance(f, ast.Attribute) and "matplotlib" in ast.unparse(f):
                offenders.append(f"{path.name}:{call.lineno} matplotlib.use")
            if name == "savefig":
                offenders.append(f"{path.name}:{call.lineno} savefig")
    assert not offenders, offenders

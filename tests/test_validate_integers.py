"""Integer options given as integral floats (``mc_points = 2.0``) are accepted and *stored* as
int: a spec that validated a value but kept the float once handed it to ``np.geomspace``
(an internal TypeError, found by the recipe fuzzer)."""

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from phyloc import _validate as v
from phyloc.config import dumps_toml, load_recipe
from phyloc.errors import ValidationError
from phyloc.evaluation import cci_experiment
from phyloc.evaluation.kinds import validate_recipe
from phyloc.localization.direct.dpf import DPFOptions


def test_a_cci_recipe_with_float_counts_plans_with_ints():
    text = (Path(__file__).resolve().parents[1] / "datasets" / "dipnet_fig2_cci.toml").read_text()
    lines = [
        "mc_points = 3.0" if line.startswith("mc_points =") else line for line in text.splitlines()
    ]
    recipe = load_recipe("\n".join(lines))
    validate_recipe(recipe)
    exp = cci_experiment.CCI.experiment_spec(recipe, fast=False)
    assert type(exp.mc_points) is int and exp.mc_points == 3
    *_, mc_d = cci_experiment.CCI.prepare(recipe)
    assert mc_d.shape == (3,)


def test_dpf_options_store_their_counts_as_int():
    o = DPFOptions(n_particles=np.float64(500.0), n_iterations=3.0)
    assert type(o.n_particles) is int and type(o.n_iterations) is int
    assert (o.n_particles, o.n_iterations) == (500, 3)


def test_integer_field_stores_the_int_and_refuses_a_fraction():
    @dataclass(frozen=True)
    class Spec:
        points: object = 2

    s = Spec(points=4.0)
    assert v.integer_field(s, "points", "experiment.points", minimum=2) == 4
    assert type(s.points) is int
    with pytest.raises(ValidationError, match=r"experiment\.points = 2\.5"):
        v.integer_field(Spec(points=2.5), "points", "experiment.points")
    with pytest.raises(ValidationError, match=r"experiment\.points.*>= 2"):
        v.integer_field(Spec(points=1), "points", "experiment.points", minimum=2)


@pytest.mark.parametrize(
    ("recipe", "table", "key", "value"),
    [  # the recipe fuzzer's finds: counts that reached NumPy as allocations of GiB to PiB
        ("fim_control.toml", "network", "n_azimuth", 1e300),
        ("fim_control.toml", "network", "n_azimuth", 22332067479.0),
        ("fim_control.toml", "network", "n_azimuth", 3601),
        ("cci_tr38901.toml", "experiment", "mc_points", 51937259661980856.0),
        ("cci_tr38901.toml", "experiment", "points", 10**18),
    ],
)
def test_a_count_beyond_its_bound_is_refused_by_name(recipe, table, key, value):
    doc = tomllib.loads((Path(__file__).resolve().parents[1] / "datasets" / recipe).read_text())
    doc[table][key] = value
    with pytest.raises(ValidationError, match=rf"{key} = .*(<=|must be)"):
        validate_recipe(load_recipe(dumps_toml(doc)))


def test_the_default_count_bound():
    assert v.integer("n", 2**31 - 1) == v.MAX_COUNT
    with pytest.raises(ValidationError, match=r"n = 2147483648 .*<= 2147483647"):
        v.integer("n", 2**31)
    assert v.integer("n", 2**40, maximum=None) == 2**40

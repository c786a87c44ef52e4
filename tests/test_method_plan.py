"""The one method grammar of every recipe kind (phyloc.evaluation.methods)."""

import pytest

from phyloc.errors import ValidationError
from phyloc.evaluation.methods import method_plan
from phyloc.localization.tracking import PFBPOptions, SIRBPOptions, SPBPOptions


def test_precedence_defaults_shared_experiment_table_override():
    loc = {"n_iterations": 3, "n_particles": 50, "fast_pfbp": {"method": "pfbp", "n_lambda": 7}}
    plan = method_plan(
        loc,
        ["pfbp", "fast_pfbp", "pfbp_reg"],
        "tracking",
        overrides={"fast_pfbp": {"n_particles": 20}},
    )
    assert plan["pfbp"] == ("pfbp", PFBPOptions(n_iterations=3, n_particles=50))
    name, opts = plan["fast_pfbp"]
    assert name == "pfbp"
    assert (opts.n_iterations, opts.n_lambda, opts.n_particles) == (3, 7, 20)
    # a registered variant keeps its own defaults under the shared keys
    assert plan["pfbp_reg"][1].regularize and plan["pfbp_reg"][1].n_particles == 50


def test_shared_keys_reach_only_the_methods_that_have_them():
    plan = method_plan({"n_particles": 500}, ["sirbp", "spbp"], "tracking")
    assert plan["sirbp"][1] == SIRBPOptions(n_particles=500)
    assert plan["spbp"][1] == SPBPOptions()  # SP-BP has no particles
    with pytest.raises(ValidationError, match=r"localization\.n_particle .*did you mean"):
        method_plan({"n_particle": 500}, ["sirbp"], "tracking")


@pytest.mark.parametrize(
    ("loc", "labels", "field"),
    [
        ({}, ["nope"], "experiment.methods"),
        ({"x": {"method": "nope"}}, ["x"], "localization.x.method"),
        ({"x": {"n_particles": 5}}, ["x"], "localization.x"),  # a label needs a method
        ({"pfbp": {"method": "sirbp"}}, ["pfbp"], "localization.pfbp.method"),
        ({"pfbp": {"n_partcles": 5}}, ["pfbp"], "localization.pfbp.n_partcles"),
        ({"unused": {"method": "pfbp", "bad": 1}}, ["pfbp"], "localization.unused.bad"),
        ({"typo": {"n_particles": 5}}, ["pfbp"], "localization.typo"),
    ],
)
def test_errors_name_the_key(loc, labels, field):
    with pytest.raises(ValidationError) as err:
        method_plan(loc, labels, "tracking")
    assert err.value.field == field


def test_experiment_values_and_forbidden_keys_are_not_the_tables():
    plan = method_plan({}, ["pfbp"], "tracking", experiment_values={"n_iterations": 4})
    assert plan["pfbp"][1].n_iterations == 4
    for loc, field in (
        ({"pfbp": {"n_iterations": 5}}, "localization.pfbp.n_iterations"),
        ({"n_iterations": 5}, "localization.n_iterations"),
    ):
        with pytest.raises(ValidationError) as err:
            method_plan(loc, ["pfbp"], "tracking", experiment_values={"n_iterations": 4})
        assert err.value.field == field


def test_an_earlier_table_form_gets_its_message():
    with pytest.raises(ValidationError, match="the shared options are"):
        method_plan(
            {"nbp": {"bandwidth": "lscv"}},
            ["pfbp"],
            "tracking",
            old_tables={"nbp": "the shared options are [localization] keys now"},
        )

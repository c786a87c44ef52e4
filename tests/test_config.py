"""Recipe loading: every bad key is named before any work starts."""

import pytest

from phyloc.config import RecipeError, load_recipe
from phyloc.errors import ValidationError

GOOD = """
kind = "ranging"
name = "t"
seed = 3
[system]
n_subcarriers = 65
"""


def test_good_recipe_round_trips_the_system():
    r = load_recipe(GOOD)
    assert (r.kind, r.name, r.seed, r.system.n_subcarriers) == ("ranging", "t", 3, 65)
    assert r.section("network") == {}


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (GOOD.replace("seed = 3", "sed = 3"), r"recipe\.sed .*did you mean 'seed'"),
        (GOOD.replace("seed = 3", "seed = -1"), "seed = -1"),
        (GOOD.replace("seed = 3", 'seed = "x"'), "seed = x"),
        (GOOD.replace("n_subcarriers = 65", "n_subcarriers = 64"), r"system\.n_subcarriers = 64"),
        (GOOD.replace("n_subcarriers = 65", "n_subcarrier = 65"), "did you mean 'n_subcarriers'"),
        (GOOD.replace("n_subcarriers = 65", 'n_subcarriers = "many"'), "integer"),
        ("network = 5\n" + GOOD, "network = 5 .*must be a table"),
    ],
)
def test_bad_recipes_name_the_key(text, match):
    with pytest.raises(ValidationError, match=match):
        load_recipe(text)


def test_missing_file_and_bad_toml(tmp_path):
    with pytest.raises(RecipeError, match="does not exist"):
        load_recipe(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("kind = \n")
    with pytest.raises(RecipeError, match=r"bad\.toml: invalid TOML"):
        load_recipe(bad)


def _shipped_recipes():
    from pathlib import Path

    return sorted((Path(__file__).resolve().parents[1] / "datasets").glob("*.toml"))


@pytest.mark.parametrize("path", _shipped_recipes(), ids=lambda p: p.name)
def test_every_shipped_recipe_validates(path):
    """Each recipe in datasets/ loads, and its experiment (full and fast) and localization
    sections pass the consumers' checks — a typo in a shipped recipe fails here, not after
    hours of work."""
    from phyloc.evaluation.kinds import KINDS, validate_recipe
    from phyloc.evaluation.kinds import load_recipe as load_checked

    recipe = load_checked(path)
    assert recipe.kind in KINDS
    validate_recipe(recipe)  # the experiment's own prepare, full and fast, or generate's check


def test_every_shipped_recipe_is_in_the_docs_recipe_table():
    """A recipe a user can run is one the guide's table names (``docs/guide/experiments.rst``)."""
    from pathlib import Path

    table = (Path(__file__).resolve().parents[1] / "docs/guide/experiments.rst").read_text()
    missing = [p.name for p in _shipped_recipes() if f"``{p.name}``" not in table]
    assert not missing, f"add to the recipe table of docs/guide/experiments.rst: {missing}"


def test_kind_is_checked_against_the_registry():
    """The evaluation layer's loader names every registered kind; the low-level loader takes any
    kind name and leaves the check to the command that runs it."""
    from phyloc.evaluation.kinds import EXPERIMENTS, experiment_for
    from phyloc.evaluation.kinds import load_recipe as load_checked

    text = GOOD.replace('kind = "ranging"', 'kind = "dance"')
    with pytest.raises(ValidationError, match=r"kind = dance .*one of ranging, localization"):
        load_checked(text)
    assert load_recipe(text).kind == "dance"
    with pytest.raises(ValidationError, match="evaluate runs ranging, localization"):
        experiment_for("dance")
    assert all(experiment_for(k).kind == k for k in EXPERIMENTS)
    with pytest.raises(ValidationError, match=r"kind = 3 .*a recipe kind"):
        load_recipe(GOOD.replace('kind = "ranging"', "kind = 3"))


@pytest.mark.parametrize("path", _shipped_recipes(), ids=lambda p: p.name)
def test_every_shipped_recipe_round_trips_through_the_toml_writer(path):
    """``dumps_toml`` (the writer of every TOML phyloc writes) gives back each shipped recipe's
    document exactly, arrays of tables and inline tables included."""
    import tomllib

    from phyloc.config import dumps_toml

    doc = tomllib.loads(path.read_text())
    assert tomllib.loads(dumps_toml(doc)) == doc


def test_toml_writer_keeps_what_the_old_one_lost():
    """Keys that need quoting, arrays of tables, special floats and nested tables round-trip;
    None values (no TOML null) are left out."""
    import math
    import tomllib

    from phyloc.config import dumps_toml

    doc = {
        "name": 'quote " and \\ back',
        "a.b": 1,
        "with space": True,
        "x": [math.inf, -math.inf, 1e-300],
        "gone": None,
        "table": {"inner": {"deep": [1, 2]}, "none": None},
        "runs": [{"seed": 1, "tag": "a"}, {"seed": 2, "tag": "b"}],
    }
    back = tomllib.loads(dumps_toml(doc))
    want = {k: val for k, val in doc.items() if k != "gone"}
    want["table"] = {"inner": {"deep": [1, 2]}}
    assert back == want
    assert math.isnan(tomllib.loads(dumps_toml({"v": math.nan}))["v"])


def test_a_recipe_built_in_code_is_written_as_loadable_text():
    """A dataset recipe without text (built in code) is stored as TOML that loads back to the
    same system, network, channel and dataset sections."""
    import tomllib

    from phyloc.config import parse_recipe
    from phyloc.datasets.plan import plan_dataset

    text = (
        'kind = "dataset"\nname = "d"\nseed = 3\n[system]\nn_subcarriers = 65\n'
        '[network]\nn_agents = 3\n[channel]\nscenario = "awgn"\n'
        "[dataset]\nrealizations = 2\nshard_size = 1\n"
    )
    plan = plan_dataset(parse_recipe(tomllib.loads(text)))  # no text kept
    assert plan.recipe.text == ""
    again = plan_dataset(load_recipe(plan.recipe_text()))
    for name in ("system", "network", "channel", "dataset"):
        assert getattr(again, name).to_dict() == getattr(plan, name).to_dict(), name

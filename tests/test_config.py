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
        (GOOD.replace('kind = "ranging"', 'kind = "dance"'), "kind = dance .*one of ranging"),
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

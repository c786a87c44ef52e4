"""The method registry: every recipe's method is registered, names are checked, options merge."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from phyloc.errors import ValidationError
from phyloc.localization import FAMILIES, METHODS, Method, Registry, Result, Timing

RECIPES = sorted((Path(__file__).resolve().parents[1] / "datasets").glob("*.toml"))
FAMILY_OF_KIND = {"localization": "direct", "tracking": "tracking", "static": "static"}


def _recipe_methods():
    for path in RECIPES:
        raw = tomllib.loads(path.read_text())
        family = FAMILY_OF_KIND.get(raw.get("kind", ""))
        if family is None:
            continue
        exp = raw.get("experiment", {})
        tables = raw.get("localization", {})
        for key in ("methods", "sample_methods"):
            for name in exp.get(key, []):
                table = tables.get(name, {})
                base = table.get("method", name) if isinstance(table, dict) else name
                yield path.name, base, family


@pytest.mark.parametrize(("recipe", "name", "family"), list(_recipe_methods()))
def test_every_recipe_method_is_registered_in_its_family(recipe, name, family):
    """Every method a recipe names (a variant: the ``method`` its table names) is registered."""
    assert name in METHODS, f"{recipe}: {name}"
    assert METHODS[name].family == family


def test_the_library_names_dipnet():
    m = METHODS["dipnet"]
    assert m.family == "direct"
    assert "DiPNet" in m.label


def test_every_registered_method_is_well_formed():
    assert len(METHODS) >= 18
    for name, m in METHODS.items():
        assert m.name == name
        assert m.family in FAMILIES
        options = m.make_options()  # the registered defaults are valid options
        assert type(options) is m.options


def test_unknown_name_lists_the_registered_ones():
    with pytest.raises(ValidationError, match="dipnet"):
        METHODS["dipnett"]


def test_membership_and_get_answer_without_raising():
    assert "dipnet" in METHODS and "dipnett" not in METHODS
    assert METHODS.get("dipnett") is None
    assert METHODS.get("dipnet") is METHODS["dipnet"]
    # a recipe can give a list or a table where a name belongs (method = [])
    assert [] not in METHODS and {} not in METHODS and METHODS.get([]) is None
    with pytest.raises(ValidationError, match="registered method"):
        METHODS[[]]


def test_a_label_whose_method_is_a_list_is_one_error_naming_the_key():
    from phyloc.config import load_recipe
    from phyloc.evaluation.kinds import validate_recipe

    text = (RECIPES[0].parent / "poa_nbp.toml").read_text()
    text = text.replace(
        '[localization.wls_paper]\nmethod = "wls"', "[localization.wls_paper]\nmethod = []"
    )
    assert "method = []" in text
    with pytest.raises(ValidationError, match="method"):
        validate_recipe(load_recipe(text))


@dataclass(frozen=True)
class _Opts:
    scale: float = 1.0

    @classmethod
    def from_dict(cls, d, section="localization"):
        from phyloc._validate import check_keys

        check_keys(d, ["scale"], section)
        return cls(**d)


def _run(measurements, prior, rng, options):
    est = np.full((1, 2, 2), options.scale)
    return Result(est, None, Timing(0.0, np.zeros(1), np.zeros(1)))


def test_register_rejects_duplicates_and_bad_fields():
    reg = Registry()
    reg.register(Method("mine", "static", _run, _Opts))
    with pytest.raises(ValidationError, match="already registered"):
        reg.register(Method("mine", "static", _run, _Opts))
    reg.register(Method("mine", "static", _run, _Opts, defaults={"scale": 2.0}), replace=True)
    assert reg["mine"].make_options().scale == 2.0
    with pytest.raises(ValidationError, match="family"):
        Method("x", "telepathy", _run, _Opts)
    with pytest.raises(ValidationError, match="identifier"):
        Method("my method", "static", _run, _Opts)
    with pytest.raises(ValidationError, match="dataclass"):
        Method("x", "static", _run, dict)


def test_make_options_merges_defaults_and_names_unknown_keys():
    m = Method("mine", "static", _run, _Opts, defaults={"scale": 2.0})
    assert m.make_options({"scale": 3.0}).scale == 3.0
    assert m.make_options().scale == 2.0
    with pytest.raises(ValidationError, match=r"localization\.mine\.scal.*did you mean 'scale'"):
        m.make_options({"scal": 1.0}, "localization.mine")
    assert reg_family_order()


def reg_family_order():
    reg = Registry()
    for n, f in (("a", "static"), ("b", "direct"), ("c", "static")):
        reg.register(Method(n, f, _run, _Opts))
    return reg.family("static") == ("a", "c")

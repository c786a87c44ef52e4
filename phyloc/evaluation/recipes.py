"""Which module runs each recipe kind, and the complete check of a recipe before any work.

References
----------
TOML v1.0.0, https://toml.io/en/v1.0.0 (the recipe format); the recipe keys of each experiment
are documented in ``datasets/README.md`` and the user guide's recipe pages.
"""

from __future__ import annotations

import importlib

#: Recipe ``kind`` → the experiment module ``phyloc evaluate`` runs (each has ``prepare`` and
#: ``run``). Dataset recipes (``kind = "dataset"``) are generated, not evaluated.
EXPERIMENTS = {
    "ranging": "phyloc.evaluation.ranging_experiment",
    "localization": "phyloc.evaluation.localization_experiment",
    "tracking": "phyloc.evaluation.tracking_experiment",
    "static": "phyloc.evaluation.static_experiment",
    "direct_tracking": "phyloc.evaluation.direct_tracking_experiment",
    "control": "phyloc.evaluation.control_experiment",
    "cci": "phyloc.evaluation.cci_experiment",
    "belief_shift": "phyloc.evaluation.belief_shift_experiment",
}


def validate_recipe(recipe) -> None:
    """Check everything a recipe's command will read, before any work: a dataset recipe as
    ``phyloc generate`` does (including the sections only ``evaluate`` reads), an experiment
    recipe with both its full and its ``[experiment.fast]`` setting through the experiment's
    own ``prepare``.

    Raises
    ------
    PhylocError
        Naming the key, the value and what is allowed (a :class:`~phyloc.errors.ValidationError`
        or :class:`~phyloc.config.RecipeError`).
    """
    if recipe.kind == "dataset":
        from phyloc.evaluation.localization_experiment import check_dataset_recipe

        check_dataset_recipe(recipe)
        return
    module = importlib.import_module(EXPERIMENTS[recipe.kind])
    for fast in (False, True):
        module.prepare(recipe, fast=fast)

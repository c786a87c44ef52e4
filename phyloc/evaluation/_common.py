"""Pieces the experiment modules share: ``[experiment]`` parsing and scenario expansion."""

from __future__ import annotations

import dataclasses

from phyloc._validate import check_keys, check_types
from phyloc.errors import ValidationError


def experiment_from_dict(cls, d: dict, *, fast: bool = False):
    """Build an ``[experiment]`` spec; with ``fast`` the ``[experiment.fast]`` values win."""
    d = dict(d)
    fast_over = d.pop("fast", {})
    names = [f.name for f in dataclasses.fields(cls)]
    check_keys(d, [*names, "fast"], "experiment")
    check_keys(fast_over, names, "experiment.fast")
    check_types(cls, d, "experiment")
    check_types(cls, fast_over, "experiment.fast")
    if fast:
        d.update(fast_over)
    return cls(**d)


def scenario_specs(channel, scenarios: dict) -> dict:
    """One channel spec per scenario token (``{token: scenario name}``), each loaded once so
    that a bad name fails before any work starts."""
    specs = {tok: dataclasses.replace(channel, scenario=name) for tok, name in scenarios.items()}
    for tok, spec in specs.items():
        try:
            spec.load()
        except ValidationError as exc:
            raise ValidationError(f"experiment.scenarios.{tok}", exc.value, exc.allowed) from None
    return specs


def grouped_bars(ax, labels, groups: dict, *, fontsize: int = 8) -> None:
    """Bars of ``groups`` (``{legend label: one value per x label}``) side by side per label."""
    import numpy as np

    x = np.arange(len(labels))
    width = 0.8 / len(groups)
    for j, (name, values) in enumerate(groups.items()):
        ax.bar(x + j * width, values, width, label=name)
    ax.set_xticks(x + 0.4 - width / 2, labels, rotation=20, fontsize=fontsize)
    ax.legend(fontsize=fontsize)

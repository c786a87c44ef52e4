"""The method plan: which registered method each label of a recipe runs, and with which options.

One grammar and one precedence rule serve every recipe kind::

    [experiment]
    methods = ["pfbp", "pfbp_fast"]     # labels: what the figures are named after

    [localization]                      # keys shared by every method of the run whose
    n_iterations = 2                    # options have them

    [localization.pfbp_fast]            # one label's options; a label that is not itself a
    method = "pfbp"                     # registered method names the one it runs
    n_particles = 100

The options of a label are, later winning: the registered method's own defaults, the shared
``[localization]`` keys its options have, the values the experiment sets itself (e.g. the
static experiment's ``n_iterations``), the label's ``[localization.<label>]`` table, and the
experiment's per-label overrides (``[experiment.fast.method_options.<label>]`` of the tracking
experiment). A label that is a registered name may not name another method; a table for a
label the run does not use is still checked, so a typo in it fails before any work.

References
----------
TOML v1.0.0, https://toml.io/en/v1.0.0 (tables and inline tables of a recipe).
"""

from __future__ import annotations

import dataclasses

from phyloc._validate import check_keys, join
from phyloc.errors import ValidationError
from phyloc.localization import METHODS as REGISTRY


def _fields(options_cls) -> set[str]:
    """The keys a recipe table of ``options_cls`` may hold: its ``recipe_keys()`` where the
    class reads a flat table into nested options (:class:`~phyloc.localization.DirectOptions`),
    else its dataclass fields."""
    keys = getattr(options_cls, "recipe_keys", None)
    return set(keys()) if keys is not None else {f.name for f in dataclasses.fields(options_cls)}


def split_localization(localization: dict, reserved=()) -> tuple[dict, dict, dict]:
    """``(own, shared, tables)`` of a ``[localization]`` table: the experiment's own keys
    (``reserved``), the keys shared by every method and the per-label sub-tables."""
    if not isinstance(localization, dict):
        raise ValidationError("localization", localization, "must be a table [localization]")
    own = {k: x for k, x in localization.items() if k in reserved}
    shared = {k: x for k, x in localization.items() if k not in reserved and not _table(x)}
    tables = {k: x for k, x in localization.items() if k not in reserved and _table(x)}
    return own, shared, tables


def _table(x) -> bool:
    return isinstance(x, dict)


def check_labels(labels, key: str = "experiment.methods") -> tuple:
    """``labels`` as a tuple, each a non-empty string (a one-line error naming ``key``)."""
    if isinstance(labels, str) or not hasattr(labels, "__iter__"):
        raise ValidationError(key, labels, "a list of method names")
    labels = tuple(labels)
    for label in labels:
        if not isinstance(label, str) or not label:
            raise ValidationError(key, label, "method names (non-empty strings)")
    return labels


def method_plan(
    localization: dict,
    labels,
    family: str,
    *,
    reserved=(),
    experiment_values: dict | None = None,
    overrides: dict | None = None,
    forbidden=(),
    old_tables: dict | None = None,
    labels_key: str = "experiment.methods",
    check_shared: bool = True,
) -> dict:
    """``{label: (registered name, options)}`` for every label of ``labels``.

    Parameters
    ----------
    localization : dict
        The recipe's ``[localization]`` table.
    labels : sequence of str
        The labels the experiment runs (``experiment.methods``).
    family : str
        The registry family every method must belong to.
    reserved : sequence of str
        Top-level ``[localization]`` keys the experiment reads itself (not method options).
    experiment_values : dict, optional
        Values the experiment sets, given to every method whose options have the field; a
        table may not set them.
    overrides : dict, optional
        ``{label: {key: value}}`` applied last (errors name ``experiment.method_options``).
    forbidden : sequence of str
        Option keys a table may not set (fixed by the method's name, e.g. a proposal).
    old_tables : dict, optional
        ``{table name: message}`` for sub-tables of an earlier recipe form: the error shows the
        current form.
    labels_key : str
        Where the labels came from, for errors.
    check_shared : bool
        Require every shared key to be an option of some method of ``labels`` (False where the
        caller checks them itself, e.g. against the family's common options).
    """
    check_labels(labels, labels_key)
    _, shared, tables = split_localization(localization, reserved)
    known = REGISTRY.family(family)
    experiment_values = experiment_values or {}
    overrides = overrides or {}
    for key, value in shared.items():
        if key in experiment_values or key in forbidden:
            raise ValidationError(
                f"localization.{key}",
                value,
                "is set by [experiment] or by the method's name, not by [localization]",
            )
    for name, table in tables.items():
        if name in (old_tables or {}) and name not in labels and name not in known:
            raise ValidationError(f"localization.{name}", "a table", old_tables[name])
        base = table.get("method", name)
        if name in known and "method" in table:
            raise ValidationError(
                f"localization.{name}.method", base, "no 'method' key: a registered name"
            )
        if base not in known:
            if "method" in table:
                allowed = f"one of {', '.join(known)}"
                raise ValidationError(f"localization.{name}.method", base, allowed)
            if name in labels:
                raise ValidationError(
                    f"localization.{name}",
                    "a table without a method key",
                    f'a label that is not a registered method names one: method = "<one of '
                    f'{", ".join(known)}>"',
                )
            check_keys({name: table}, [*known, *labels], "localization")
        for key in (*experiment_values, *forbidden):
            if key in table:
                raise ValidationError(
                    f"localization.{name}.{key}",
                    table[key],
                    "is set by [experiment] or by the method's name, not by its table",
                )
    plan = {}
    for label in labels:
        table = tables.get(label, {})
        name = table.get("method", label)
        if name not in known:
            raise ValidationError(
                labels_key,
                label,
                f"each one of {', '.join(known)}, or a label with a [localization.{label}] "
                'table holding method = "<one of those>"',
            )
        plan[label] = (name, _options(name, label, shared, table, experiment_values, overrides))
    for name, table in tables.items():  # tables of labels the run does not use: checked too
        if name not in plan:
            base = table.get("method", name)
            _options(base, name, shared, table, experiment_values, {})
    if check_shared:
        _check_shared(shared, [REGISTRY[n].options for n, _ in plan.values()])
    return plan


def _options(name, label, shared, table, experiment_values, overrides):
    method = REGISTRY[name]
    fields = _fields(method.options)
    common = {k: x for k, x in shared.items() if k in fields}
    fixed = {k: x for k, x in experiment_values.items() if k in fields}
    own = {k: x for k, x in table.items() if k != "method"}
    over = overrides.get(label, {})
    if not isinstance(over, dict):
        raise ValidationError(f"experiment.method_options.{label}", over, "a table of options")
    method.make_options({**common, **fixed}, "localization")  # a bad shared key names itself
    section = f"localization.{label}"
    try:
        opts = method.make_options({**common, **fixed, **own}, section)
        if over:
            opts = method.make_options(
                {**common, **fixed, **own, **over}, f"experiment.method_options.{label}"
            )
    except ValidationError as exc:
        if exc.field.startswith(("localization", "experiment")):
            raise
        raise ValidationError(join(section, exc.field), exc.value, exc.allowed) from None
    return opts


def _check_shared(shared: dict, option_classes) -> None:
    """Every shared key must be an option of some method of the run."""
    if not option_classes:  # no method runs: the caller checks the shared keys
        return
    fields = set().union(*(_fields(c) for c in option_classes))
    check_keys({k: x for k, x in shared.items() if k not in fields}, sorted(fields), "localization")

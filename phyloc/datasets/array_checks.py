"""Declarative checks of named input arrays: the rows of a check table and the loop that runs it.

A table is a tuple of :class:`ArrayCheck` rows, run in order by :func:`run_checks`. A row
names an input array and states what it must be: the sizes it defines from its axes
(:class:`Defines`), its symbolic shapes over the sizes known so far (``"K, L, 2"``; an optional
leading realization axis ``R`` is added when the inputs carry one), the dtype kinds it accepts,
how it is converted to its checked form, and :class:`Rule` s on its values, each with the
message of its error. Rows without a shape relate arrays checked before. The first failing
check raises :class:`~phyloc.errors.ValidationError` naming the array, what was seen and what
is expected, so every error of a table is as specific as a hand-written check.

:mod:`phyloc.datasets.import_checks` holds the table of ``phyloc import``.

References
----------
NumPy, "Data type objects: ``dtype.kind``",
https://numpy.org/doc/stable/reference/generated/numpy.dtype.kind.html.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from phyloc.errors import ValidationError

#: ``ArrayCheck.kinds`` of flags: bool, or numbers that are all 0 or 1.
FLAGS = "flags"


# -- the rows --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Rule:
    """A rule on values: ``bad(value, ctx)`` returns what the error shows as the offending
    value (an entry, a count, a place) or None when the rule holds. ``message`` says what is
    required, with the sizes as fields (``"... 0 … L = {L}"``; ``{prefix}`` is ``"R, "`` when
    the inputs carry a realization axis)."""

    bad: Callable
    message: str


@dataclass(frozen=True)
class Defines:
    """The sizes an array defines, read from its trailing axes (a size already known is kept),
    and the numbers of axes it may have. ``"R"`` among ``sizes`` means the array decides
    whether a leading realization axis is present. When the number of axes or a defined axis
    (against ``values``, e.g. ``{"D": (2, 3)}``) is wrong, ``message`` is the error (``{shape}``
    is the symbolic shape)."""

    sizes: tuple[str, ...]
    ndim: Callable  # (ctx) -> the allowed numbers of axes, realization axis included
    message: str
    values: dict = field(default_factory=dict)  # size -> its allowed values


@dataclass(frozen=True)
class Requirement:
    """When a missing array is required (``when(ctx)``) and the message saying so."""

    when: Callable
    message: str


@dataclass(frozen=True)
class Exclusive:
    """Arrays that may not be given together with this one, and the message saying so."""

    others: tuple[str, ...]
    message: str


@dataclass(frozen=True)
class ArrayCheck:
    """One row of a check table.

    A row with ``shape`` or ``scalar`` checks an input array when it is given, in this order:
    ``excludes``; the sizes it ``defines``; its shape, one of the symbolic ``shape`` options
    (the sizes joined by ", ", without the realization axis; ``hint`` follows the expected
    shapes in the message); its dtype ``kinds`` (``numpy.dtype.kind`` letters, or
    :data:`FLAGS`), described by ``what``; then ``convert`` brings it to its checked form
    (realization axis first) and its ``values`` rules run on that. ``scalar`` (``"real"`` or
    ``"int"``) checks a single finite number instead. A missing array is an error when
    ``required`` says so. Once every rule holds, ``fixes(value, ctx)`` may return sizes the
    checked value fixes (``n_anchors`` from ``is_anchor``, ``D`` from ``dim``).

    A row with neither relates arrays checked before: its ``values`` rules run on the checked
    form of ``name`` (or None), reading the others from the context.
    """

    name: str
    shape: tuple[str, ...] | None = None
    kinds: str = ""
    what: str = ""
    hint: str = ""
    defines: Defines | None = None
    scalar: str | None = None
    convert: Callable | None = None
    required: Requirement | None = None
    excludes: Exclusive | None = None
    values: tuple[Rule, ...] = ()
    fixes: Callable | None = None

    @property
    def is_input(self) -> bool:
        """Whether the row checks the input array itself (else it relates checked arrays)."""
        return self.shape is not None or self.scalar is not None


# -- what the checks know --------------------------------------------------------------------------
class CheckContext:
    """What the checks know so far: the inputs (by name), whether they carry a leading
    realization axis, the sizes defined (``sizes``, also the fields of the messages) and the
    checked arrays and scalars (``arrays``). Tables subclass it for derived quantities."""

    def __init__(self, inputs: dict):
        self.inputs = inputs
        self.lead = False
        self.sizes: dict = {"prefix": "", "R": 1}
        self.arrays: dict = {}

    def per_real(self, a: np.ndarray) -> np.ndarray:
        """``a`` with the realization axis (added when the inputs have none)."""
        return a if self.lead else a[None]

    def fmt(self, text: str) -> str:
        """A message with the sizes filled in."""
        return text.format_map(self.sizes)


# -- the loop --------------------------------------------------------------------------------------
def _shape_error(name, a, options, what=None):
    expected = " or ".join(f"[{sym}] = {shape}" for sym, shape in options)
    extra = f"; {what}" if what else ""
    return ValidationError(name, f"array of shape {tuple(a.shape)}", f"expected {expected}{extra}")


def _scalar(name, a, kind):
    a = np.asarray(a)
    if a.size != 1:
        raise ValidationError(name, f"array of shape {a.shape}", "expected a scalar, shape ()")
    x = a.reshape(()).item()
    if a.dtype.kind not in "iuf":
        raise ValidationError(name, x, "a real number is required")
    if not math.isfinite(x):
        raise ValidationError(name, x, "must be finite")
    if kind == "int" and float(x) != int(x):
        raise ValidationError(name, x, "an integer is required")
    return int(x) if kind == "int" else float(x)


def _define(row: ArrayCheck, a: np.ndarray, c: CheckContext) -> None:
    """Read the sizes ``row`` defines from the axes of ``a``."""
    d = row.defines
    symbols = row.shape[0].split(", ")
    axes = {s: i - len(symbols) for i, s in enumerate(symbols) if s in d.sizes}
    if a.ndim not in d.ndim(c) or any(
        s in d.values and a.shape[axis] not in d.values[s] for s, axis in axes.items()
    ):
        raise ValidationError(
            row.name,
            f"array of shape {a.shape}",
            d.message.format(shape=c.sizes["prefix"] + row.shape[0]),
        )
    if "R" in d.sizes:
        c.lead = a.ndim == len(symbols) + 1
        c.sizes.update(R=a.shape[0] if c.lead else 1, prefix="R, " if c.lead else "")
    for s, axis in axes.items():
        c.sizes.setdefault(s, int(a.shape[axis]))


def _check_form(row: ArrayCheck, a: np.ndarray, c: CheckContext):
    """Shape and dtype of input ``a``; return its checked form."""
    if row.defines is not None:
        _define(row, a, c)
    pre = (c.sizes["R"],) if c.lead else ()
    options = [
        (
            c.sizes["prefix"] + sym,
            (*pre, *(int(s) if s.isdigit() else c.sizes[s] for s in sym.split(", "))),
        )
        for sym in row.shape
    ]
    if not any(tuple(a.shape) == shape for _, shape in options):
        raise _shape_error(row.name, a, options, row.hint)
    if row.kinds == FLAGS:
        if a.dtype.kind != "b" and (a.dtype.kind not in "iuf" or not np.all((a == 0) | (a == 1))):
            raise ValidationError(row.name, f"{a.dtype} array", "expected bool (or 0/1) values")
        return c.per_real(a.astype(bool))
    if a.dtype.kind not in row.kinds:
        raise ValidationError(row.name, f"{a.dtype} array", f"expected {row.what}")
    return row.convert(a, c) if row.convert is not None else c.per_real(a)


def run_checks(checks, c: CheckContext) -> None:
    """Run the rows of ``checks`` in order on the inputs of ``c``, filling its sizes and checked
    arrays; the first failing check raises.

    Raises
    ------
    ValidationError
        Naming the array, what was seen and what the row expects.
    """
    for row in checks:
        if row.is_input:
            a = c.inputs.get(row.name)
            if a is None:
                if row.required is not None and row.required.when(c):
                    raise ValidationError(row.name, "missing", c.fmt(row.required.message))
                continue
            if row.excludes is not None and any(o in c.inputs for o in row.excludes.others):
                given = "/".join(row.excludes.others)
                raise ValidationError(row.name, f"given with {given}", row.excludes.message)
            if row.scalar is not None:
                value = _scalar(row.name, a, row.scalar)
            else:
                value = _check_form(row, a, c)
            c.arrays[row.name] = value
        else:
            value = c.arrays.get(row.name)
        for rule in row.values:
            bad = rule.bad(value, c)
            if bad is not None:
                raise ValidationError(row.name, bad, c.fmt(rule.message))
        if row.fixes is not None:
            c.sizes.update(row.fixes(value, c))


__all__ = [
    "FLAGS",
    "ArrayCheck",
    "CheckContext",
    "Defines",
    "Exclusive",
    "Requirement",
    "Rule",
    "run_checks",
]

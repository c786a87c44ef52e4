"""Declarative checks for the keys of a scenario file (private).

A *spec* is a ``dict`` mapping each allowed key to a checker (:class:`Num`, :class:`Choice`,
:class:`Vec`, :class:`Text`, :class:`TextList`, :class:`Flag`) or to a nested spec (a sub-table).
:func:`parse` walks a TOML table against a spec and returns the validated values; the first
unknown, missing or out-of-range key raises :class:`~phyloc.errors.ValidationError` naming the
key (with its file and section), the value and what is allowed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from phyloc import _validate as v
from phyloc.errors import ValidationError

#: Marks a key without a default (it must be present).
REQUIRED = object()
#: Shown as the value of a key that is absent.
MISSING = "<missing>"


def _interval(lo: float, hi: float, lo_open: bool, hi_open: bool) -> str:
    return f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"


@dataclass(frozen=True)
class Num:
    """A real number (or an integer with ``integer=True``) in an interval."""

    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    hi_open: bool = False
    default: object = REQUIRED
    integer: bool = False

    def describe(self) -> str:
        kind = "an integer" if self.integer else "a real number"
        return f"{kind} in {_interval(self.lo, self.hi, self.lo_open, self.hi_open)}"

    def check(self, field: str, value):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValidationError(field, value, self.describe())
        if self.integer and not float(value).is_integer():
            raise ValidationError(field, value, self.describe())
        x = float(value)
        ok = (
            math.isfinite(x)
            and (x > self.lo if self.lo_open else x >= self.lo)
            and (x < self.hi if self.hi_open else x <= self.hi)
        )
        if not ok:
            raise ValidationError(field, value, self.describe())
        return int(x) if self.integer else x


@dataclass(frozen=True)
class Choice:
    """One of a fixed set of strings."""

    choices: tuple[str, ...]
    default: object = REQUIRED

    def describe(self) -> str:
        return "one of " + ", ".join(repr(c) for c in self.choices)

    def check(self, field: str, value):
        if value not in self.choices:
            raise ValidationError(field, value, self.describe())
        return value


@dataclass(frozen=True)
class Vec:
    """A list of numbers, each checked by ``elem``; of length ``n`` (or >= 1 when ``None``)."""

    elem: Num
    n: int | None = None
    default: object = REQUIRED

    def describe(self) -> str:
        size = f"{self.n} entries" if self.n is not None else "at least one entry"
        return f"a list of {size}, each {self.elem.describe()}"

    def check(self, field: str, value):
        if not isinstance(value, list) or (len(value) != self.n if self.n else not value):
            raise ValidationError(field, value, self.describe())
        return tuple(self.elem.check(f"{field}[{i}]", x) for i, x in enumerate(value))


@dataclass(frozen=True)
class Text:
    """A string (``nonempty`` by default)."""

    default: object = REQUIRED
    nonempty: bool = True

    def describe(self) -> str:
        return "a non-empty string" if self.nonempty else "a string"

    def check(self, field: str, value):
        if not isinstance(value, str) or (self.nonempty and not value.strip()):
            raise ValidationError(field, value, self.describe())
        return value


@dataclass(frozen=True)
class TextList:
    """A list of strings."""

    default: object = ()

    def describe(self) -> str:
        return "a list of strings"

    def check(self, field: str, value):
        if not isinstance(value, list) or not all(isinstance(x, str) for x in value):
            raise ValidationError(field, value, self.describe())
        return tuple(value)


@dataclass(frozen=True)
class Flag:
    """``true`` or ``false``."""

    default: object = REQUIRED

    def describe(self) -> str:
        return "true or false"

    def check(self, field: str, value):
        if not isinstance(value, bool):
            raise ValidationError(field, value, self.describe())
        return value


@dataclass(frozen=True)
class Raw:
    """A sub-table checked elsewhere (returned unchanged)."""

    default: object = REQUIRED

    def describe(self) -> str:
        return "a table"

    def check(self, field: str, value):
        if not isinstance(value, dict):
            raise ValidationError(field, value, self.describe())
        return value


def describe(spec) -> str:
    """What a key of this spec accepts (for 'missing key' messages)."""
    if isinstance(spec, dict):
        return "a table with keys " + ", ".join(spec)
    return spec.describe()


def parse(table, spec: dict, where: str) -> dict:
    """Validate ``table`` against ``spec``; return the checked values (defaults filled in).

    Parameters
    ----------
    table : dict
        A parsed TOML table.
    spec : dict
        Key -> checker or nested spec.
    where : str
        Location used in messages: ``"winner2_c2_los.toml:"`` for a file's top level,
        ``"winner2_c2_los.toml: los.lsp"`` below it.
    """
    if not isinstance(table, dict):
        raise ValidationError(where, table, "must be a table")
    v.check_keys(table, spec, where)
    out = {}
    for key, sub in spec.items():
        field = v.join(where, key)
        if key not in table:
            if isinstance(sub, dict) and not _has_required(sub):
                out[key] = parse({}, sub, field)  # an optional sub-table: all defaults
                continue
            if isinstance(sub, dict) or sub.default is REQUIRED:
                raise ValidationError(field, MISSING, f"required key; {describe(sub)}")
            out[key] = sub.default
        elif isinstance(sub, dict):
            out[key] = parse(table[key], sub, field)
        else:
            out[key] = sub.check(field, table[key])
    return out


def _has_required(spec: dict) -> bool:
    return any(
        _has_required(sub) if isinstance(sub, dict) else sub.default is REQUIRED
        for sub in spec.values()
    )


def correlation_cholesky(cc: dict, names, where: str):
    """``(R, L)``: the correlation matrix of the large-scale parameters ``names`` (in that
    order, e.g. ``("ds", "sf", "k")``) from the pairwise coefficients ``cc`` (keys
    ``"<a>_<b>"`` in either order, e.g. ``ds_sf``) and its Cholesky factor ``L`` (``R = L Lᵀ``).

    Raises
    ------
    ValidationError
        ``R`` is not positive definite (naming ``<where>.lsp.cross_correlation``).

    Examples
    --------
    >>> R, L = correlation_cholesky({"ds_sf": -0.4}, ("ds", "sf"), "c2.los")
    >>> R.tolist()
    [[1.0, -0.4], [-0.4, 1.0]]
    """
    import numpy as np

    from phyloc.errors import ValidationError

    n = len(names)
    corr = np.eye(n)
    for i in range(n):
        for j in range(i + 1, n):
            a, b = names[i], names[j]
            corr[i, j] = corr[j, i] = cc[f"{a}_{b}"] if f"{a}_{b}" in cc else cc[f"{b}_{a}"]
    try:
        chol = np.linalg.cholesky(corr)
    except np.linalg.LinAlgError:
        order = ", ".join(x.upper() for x in names)
        raise ValidationError(
            f"{where}.lsp.cross_correlation",
            cc,
            f"the correlation matrix of [{order}] must be positive definite",
        ) from None
    return corr, chol

"""Small input checks shared by the public functions (they raise :class:`ValidationError`)."""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

import numpy as np

from phyloc.errors import ValidationError


def positive(name: str, value, *, allow_zero: bool = False) -> float:
    """Return ``value`` as float if it is finite and > 0 (or >= 0 with ``allow_zero``)."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValidationError(name, value, "a real number is required") from None
    ok = math.isfinite(x) and (x >= 0 if allow_zero else x > 0)
    if not ok:
        raise ValidationError(
            name, value, "must be finite and " + (">= 0" if allow_zero else "> 0")
        )
    return x


def finite(name: str, value) -> float:
    """Return ``value`` as float if it is a finite real number."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValidationError(name, value, "a real number is required") from None
    if not math.isfinite(x):
        raise ValidationError(name, value, "must be finite")
    return x


#: The largest count any option takes (2³¹ − 1): counts size arrays and loops, and a larger
#: one (``points = 1e300``, an integral float) is a slip that would otherwise reach NumPy as an
#: allocation of petabytes.
MAX_COUNT = 2**31 - 1


def integer(
    name: str, value, *, minimum: int | None = None, maximum: int | None = MAX_COUNT
) -> int:
    """Return ``value`` as int if it is integral (and within ``[minimum, maximum]``).

    Integral floats (``3.0``) are accepted; ``maximum`` defaults to :data:`MAX_COUNT` (``None``
    for no bound).
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if not (isinstance(value, float) and value.is_integer()):
            raise ValidationError(name, value, "an integer is required")
    x = int(value)
    if minimum is not None and x < minimum:
        raise ValidationError(name, value, f"must be an integer >= {minimum}")
    if maximum is not None and x > maximum:
        raise ValidationError(name, value, f"must be an integer <= {maximum}")
    return x


def integer_field(
    obj, attr: str, name: str, *, minimum: int | None = None, maximum: int | None = MAX_COUNT
) -> int:
    """Check the count ``obj.attr`` with :func:`integer` and store it back as int.

    For frozen dataclasses: a recipe's ``points = 3.0`` is accepted, and what the spec keeps is
    ``3``, never the float (which NumPy refuses as a count).
    """
    x = integer(name, getattr(obj, attr), minimum=minimum, maximum=maximum)
    object.__setattr__(obj, attr, x)
    return x


def boolean(name: str, value) -> bool:
    """Return ``value`` if it is a bool (``numpy.bool_`` too); 0/1 and strings are refused."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValidationError(name, value, "must be true or false")
    return bool(value)


def finite_array(name: str, a, *, dtype=np.float64, ndim: int | None = None) -> np.ndarray:
    """Return ``a`` as a C-contiguous array of ``dtype``; reject NaN/inf and wrong ``ndim``."""
    try:
        arr = np.asarray(a, dtype=dtype)
        if arr.ndim and not arr.flags.c_contiguous:
            arr = np.ascontiguousarray(arr)
    except (TypeError, ValueError):
        raise ValidationError(name, "<array>", f"must convert to {np.dtype(dtype).name}") from None
    if ndim is not None and arr.ndim != ndim:
        raise ValidationError(name, f"array of shape {arr.shape}", f"must be {ndim}-D")
    check_finite(name, arr)
    return arr


def check_finite(name: str, arr: np.ndarray) -> None:
    """Raise naming the first non-finite entry of the C-contiguous ``arr`` (if there is one)."""
    flat = arr.view(np.float64) if arr.dtype == np.complex128 and arr.ndim else arr
    if not np.all(np.isfinite(flat)):  # complex128 through its float view: 2x faster
        bad = int(np.flatnonzero(~np.isfinite(arr.ravel()))[0])
        raise ValidationError(
            name, f"{arr.ravel()[bad]} at flat index {bad}", "every entry must be finite"
        )


def choice(name: str, value, allowed) -> str:
    """Return ``value`` if it is one of the strings ``allowed``; else name them all."""
    if not isinstance(value, str) or value not in allowed:
        raise ValidationError(name, value, "must be one of " + ", ".join(repr(a) for a in allowed))
    return value


def join(where: str, key: str) -> str:
    """A field name for messages.

    ``"file.toml:" + "los"`` gives ``"file.toml: los"``; ``"a.b" + "c"`` gives ``"a.b.c"``.
    """
    return f"{where} {key}" if where.endswith(":") else f"{where}.{key}"


def check_keys(table: dict, allowed, where: str) -> None:
    """Raise :class:`ValidationError` for the first key of ``table`` not in ``allowed``.

    The message names the key (``where.key``), its value, the closest valid key ("did you
    mean ...?") and every valid key.
    """
    import difflib

    if not isinstance(table, dict):
        raise ValidationError(where, table, "must be a table ([section] or { key = value })")
    allowed = list(allowed)
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(key, allowed, n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ValidationError(
                join(where, key), table[key], f"unknown key; {hint}valid keys: {', '.join(allowed)}"
            )


_KINDS = {
    "bool": ((bool,), "true or false"),
    "integer": ((int, float), "an integer"),
    "number": ((int, float), "a number"),
    "text": ((str,), "a string"),
    "list": ((list, tuple), "a list [ … ]"),
    "table": ((dict,), "a table { … }"),
}


def _kind(default) -> str | None:
    if isinstance(default, bool):
        return "bool"
    if isinstance(default, int):
        return "integer"
    if isinstance(default, float):
        return "number"
    if isinstance(default, str):
        return "text"
    if isinstance(default, (list, tuple)):
        return "list"
    if isinstance(default, dict):
        return "table"
    return None


def check_types(cls, table: dict, where: str) -> None:
    """Raise :class:`ValidationError` for the first value of ``table`` whose TOML type differs
    from the type of the default of the dataclass field of that name (a number where a list is
    expected, a string where a number is, …), before the dataclass sees it. Fields without a
    default, or with a default of None, are left to the dataclass's own checks."""
    for f in dataclasses.fields(cls):
        if f.name not in table:
            continue
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            continue
        kind = _kind(default)
        if kind is None:
            continue
        types, words = _KINDS[kind]
        value = table[f.name]
        numeric = kind in ("integer", "number")
        bad = not isinstance(value, types) or (numeric and isinstance(value, bool))
        if bad:
            raise ValidationError(join(where, f.name), value, f"must be {words}")


def from_table(cls, table: dict, where: str, *, exclude=()):
    """Build the dataclass ``cls`` from a recipe table: the one section parser of phyloc.

    Unknown keys are errors naming the closest valid key (:func:`check_keys`), values of the
    wrong TOML type are errors naming the expected type (:func:`check_types`), and a field
    whose metadata has ``{"table": SubClass}`` is parsed the same way from its sub-table
    (errors name ``where.field.key``). The dataclass's own ``__post_init__`` checks the
    values. ``exclude`` names fields a recipe may not set.

    Examples
    --------
    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class Opts:
    ...     n_particles: int = 100
    >>> from_table(Opts, {"n_particles": 50}, "localization")
    Opts(n_particles=50)
    >>> from_table(Opts, {"n_particle": 50}, "localization")
    Traceback (most recent call last):
    ...
    phyloc.errors.ValidationError: localization.n_particle = 50 is not allowed: unknown key; \
did you mean 'n_particles'? valid keys: n_particles
    """
    fields = [f for f in dataclasses.fields(cls) if f.init and f.name not in exclude]
    check_keys(table, [f.name for f in fields], where)
    check_types(cls, table, where)
    kw = dict(table)
    for f in fields:
        sub = f.metadata.get("table")
        if sub is not None and f.name in kw:
            kw[f.name] = from_table(sub, kw[f.name], join(where, f.name))
    return cls(**kw)


def unreadable_file(path) -> str | None:
    """Why ``path`` cannot be read as a file (``"… does not exist"``, ``"… is a directory"``,
    ``"… is not readable (permission denied)"``), or None when it can."""
    path = Path(path)
    if path.is_dir():
        return f"{path} is a directory"
    if not path.exists():
        return f"{path} does not exist"
    if not path.is_file():
        return f"{path} is not a regular file"
    if not os.access(path, os.R_OK):
        return f"{path} is not readable (permission denied)"
    return None

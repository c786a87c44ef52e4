"""Recipes: TOML files describing a system, a network, a channel and what to run.

A recipe is read with :func:`load_recipe`, which checks every key before any work starts:
unknown keys are errors that name the key and the closest valid one, wrong types and
impossible values name the key, the value and what is allowed. The common sections map to
frozen dataclasses (``[system]`` → :class:`~phyloc.phy.OFDMSystem`, ``[channel]`` →
:class:`~phyloc.channels.ChannelSpec`); ``[network]`` and the experiment's own sections are
validated by their consumers' ``from_dict`` through :meth:`Recipe.section`.

Top-level keys:

* ``kind``: what the recipe runs: ``"dataset"`` (waveforms for ``phyloc generate``) or an
  experiment kind of :data:`phyloc.evaluation.kinds.EXPERIMENTS` (``phyloc evaluate``; the
  user guide lists them with the paper figures they reproduce);
* ``name``: a short identifier (results folder name, figure prefixes);
* ``seed``: the one seed of all randomness (per-task streams come from
  ``SeedSequence.spawn``);
* ``description``: free text.

References
----------
TOML v1.0.0, https://toml.io/en/v1.0.0 (read with the standard library's ``tomllib``).
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from phyloc import _validate as v
from phyloc._validate import check_keys
from phyloc.errors import PhylocError, ValidationError
from phyloc.phy.system import OFDMSystem

TOP_LEVEL = ("kind", "name", "seed", "description")
SECTIONS = ("system", "network", "channel", "ranging", "experiment", "localization", "dataset")


class RecipeError(PhylocError):
    """A recipe cannot be read (missing file, TOML syntax)."""


@dataclass(frozen=True, eq=False)
class Recipe:
    """A validated recipe.

    Attributes
    ----------
    kind, name : str
    seed : int
    system : OFDMSystem
    sections : dict[str, dict]
        The raw tables of the other sections (validated by :meth:`section`).
    text : str
        The recipe's TOML text (stored with every result and dataset).
    path : Path or None
    """

    kind: str
    name: str
    seed: int
    system: OFDMSystem
    sections: dict = field(default_factory=dict)
    text: str = ""
    path: Path | None = None
    description: str = ""

    def section(self, name: str, spec_cls=None, *, required: bool = False):
        """The table ``[name]`` (``{}`` when absent), or ``spec_cls.from_dict`` of it."""
        if name not in self.sections and required:
            raise ValidationError(name, "missing", f"recipe section [{name}] is required")
        raw = self.sections.get(name, {})
        if not isinstance(raw, dict):
            raise ValidationError(name, raw, f"must be a table: a [{name}] section")
        if spec_cls is None:
            return raw
        try:
            return spec_cls.from_dict(raw)
        except ValidationError as exc:
            if exc.field.startswith(name):
                raise
            raise ValidationError(f"{name}.{exc.field}", exc.value, exc.allowed) from None


def dumps_toml(doc: dict) -> str:
    """TOML text of ``doc`` (by ``tomli_w``; keys whose value is None are left out, since TOML
    has no null). ``tomllib.loads(dumps_toml(doc))`` gives ``doc`` back.

    Examples
    --------
    >>> print(dumps_toml({"name": "x", "skip": None, "network": {"region_m": [60.0, 60.0]}}))
    name = "x"
    <BLANKLINE>
    [network]
    region_m = [
        60.0,
        60.0,
    ]
    <BLANKLINE>
    """
    import tomli_w

    def clean(x):
        if isinstance(x, dict):
            return {str(k): clean(val) for k, val in x.items() if val is not None}
        if isinstance(x, (list, tuple)):
            return [clean(val) for val in x]
        return x

    return tomli_w.dumps(clean(doc))


def load_recipe(source, *, kinds=None) -> Recipe:
    """Read and validate a recipe from a path (or from TOML text starting with a newline or
    containing ``=``).

    ``kinds``: the allowed values of ``kind`` (:data:`phyloc.evaluation.kinds.KINDS`, which
    :func:`phyloc.evaluation.kinds.load_recipe` passes); None accepts any kind name, which the
    command that runs the recipe then checks."""
    path = None
    if isinstance(source, Path) or (isinstance(source, str) and "=" not in source):
        path = Path(source)
        why = v.unreadable_file(path)
        if why:
            raise RecipeError(f"recipe {why} (give the path of a TOML file)")
        raw = path.read_bytes()
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise RecipeError(
                f"recipe {path} is not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset "
                f"{exc.start}); a recipe is a TOML file"
            ) from None
    else:
        text = str(source)
    where = f"{path}: " if path else ""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RecipeError(f"{where}invalid TOML: {exc}") from None
    except RecursionError:  # arrays or inline tables nested thousands deep
        raise RecipeError(
            f"{where}nests arrays or tables too deeply to read (a recipe nests at most "
            f"{MAX_DEPTH} levels)"
        ) from None
    deep = too_deep(doc)
    if deep is not None:
        raise RecipeError(
            f"{where}key {deep} nests more than {MAX_DEPTH} levels of tables or arrays; "
            "a recipe's keys are a few levels deep (e.g. localization.sage.n_particles)"
        )
    return parse_recipe(doc, text=text, path=path, kinds=kinds)


#: The deepest nesting of tables and arrays a recipe may have (the shipped recipes reach 6).
MAX_DEPTH = 16


def too_deep(doc: dict) -> str | None:
    """The dotted key (shortened) of the first value nested deeper than :data:`MAX_DEPTH`
    tables or arrays, or None; iterative, so any depth is measured without recursion."""
    stack = [(doc, ())]
    while stack:
        node, key = stack.pop()
        if len(key) > MAX_DEPTH:
            shown = ".".join(map(str, key[:4]))
            return f"{shown}… ({len(key)}+ levels)"
        items = node.items() if isinstance(node, dict) else enumerate(node)
        for k, x in items:
            if isinstance(x, dict | list):
                stack.append((x, (*key, k)))
    return None


#: Recipe keys whose string values name a channel scenario: a shipped name or a file.
SCENARIO_KEYS = ("scenario", "scenarios")


def scenario_files_inside(doc: dict, folder: Path) -> dict:
    """``doc`` with every scenario *file* it names resolved against the recipe's ``folder``,
    refused when it lies outside that folder (links followed).

    A recipe from someone else must not make phyloc read files elsewhere (a scenario file
    that is ``/etc/passwd`` would be parsed, and its keys echoed in the error). A value of a
    :data:`SCENARIO_KEYS` key is a file when it ends in ``.toml``, contains a path separator,
    or names a file in ``folder``; shipped names (``"winner2_c2"``) pass unchanged.

    >>> scenario_files_inside({"channel": {"scenario": "winner2_c2"}}, Path("."))
    {'channel': {'scenario': 'winner2_c2'}}
    >>> scenario_files_inside({"channel": {"scenario": "/etc/passwd"}}, Path("."))
    Traceback (most recent call last):
    ...
    phyloc.errors.ValidationError: channel.scenario = /etc/passwd is not allowed: ...
    """
    root = Path(folder).resolve()

    def fix(value, key):
        if not isinstance(value, str) or not value:
            return value
        looks = value.endswith(".toml") or "/" in value or "\\" in value or os.sep in value
        candidate = Path(value) if Path(value).is_absolute() else root / value
        if not looks and not candidate.is_file():
            return value  # a shipped name (or a typo the scenario loader names)
        real = candidate.resolve()
        if not real.is_relative_to(root):
            raise ValidationError(
                key,
                value,
                f"a scenario file in the recipe's folder {root} or below (a recipe may "
                "not name files elsewhere: copy the file next to the recipe, or give a "
                "shipped scenario name)",
            )
        return str(real)

    def walk(node, prefix):
        if isinstance(node, dict):
            out = {}
            for k, val in node.items():
                key = f"{prefix}{k}"
                if k in SCENARIO_KEYS and isinstance(val, str):
                    out[k] = fix(val, key)
                elif k in SCENARIO_KEYS and isinstance(val, list):
                    out[k] = [fix(x, f"{key}[{i}]") for i, x in enumerate(val)]
                elif k in SCENARIO_KEYS and isinstance(val, dict):
                    out[k] = {
                        t: fix(x, f"{key}.{t}") if isinstance(x, str) else walk(x, f"{key}.{t}.")
                        for t, x in val.items()
                    }
                else:
                    out[k] = walk(val, key + ".")
            return out
        return node

    return walk(doc, "")


def parse_recipe(doc: dict, *, text: str = "", path: Path | None = None, kinds=None) -> Recipe:
    """Validate a parsed recipe document (``kind`` one of ``kinds`` when given)."""
    check_keys(doc, [*TOP_LEVEL, *SECTIONS], "recipe")
    kind = doc.get("kind")
    if kinds is not None and kind not in kinds:
        raise ValidationError("kind", kind, f"one of {', '.join(kinds)}")
    if not isinstance(kind, str) or not kind.isidentifier():
        raise ValidationError("kind", kind, "a recipe kind: ranging, localization, dataset, …")
    name = doc.get("name", path.stem if path else "recipe")
    if not isinstance(name, str) or not name or any(c in name for c in "/\\ "):
        raise ValidationError("name", name, "a non-empty string without spaces or slashes")
    seed = doc.get("seed")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValidationError("seed", seed, "a non-negative integer is required")
    for s in SECTIONS:
        if s in doc and not isinstance(doc[s], dict):
            raise ValidationError(s, doc[s], f"[{s}] must be a table")
    system_doc = doc.get("system", {})
    try:
        system = OFDMSystem.from_dict(system_doc)
    except TypeError as exc:  # pragma: no cover - from_dict checks keys first
        raise ValidationError("system", system_doc, str(exc)) from None
    if path is not None:
        doc = scenario_files_inside(doc, Path(path).parent)
    sections = {s: doc[s] for s in SECTIONS if s in doc and s != "system"}
    return Recipe(
        kind=kind,
        name=name,
        seed=seed,
        system=system,
        sections=sections,
        text=text,
        path=path,
        description=str(doc.get("description", "")),
    )

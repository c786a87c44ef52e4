"""Property-based recipe fuzzing: every mutation of a shipped recipe is either accepted or
refused with phyloc's own error naming a key, before any work; never another exception.

Profiles: ``fast`` (default, CI: the same examples every run) and ``slow`` (>= 500 examples
per property, new ones every run), chosen with the environment variable ``PHYLOC_FUZZ=slow``.
"""

import copy
import math
import tomllib
from pathlib import Path

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from phyloc.cli import main  # noqa: E402
from phyloc.config import dumps_toml, load_recipe  # noqa: E402
from phyloc.errors import PhylocError  # noqa: E402
from phyloc.evaluation.kinds import validate_recipe  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RECIPES = {p.name: tomllib.loads(p.read_text()) for p in sorted(ROOT.glob("datasets/*.toml"))}

ODD_VALUES = st.one_of(
    st.sampled_from([math.nan, math.inf, -math.inf, 0, -1, 0.0, -0.5, 1e300, 10**18, "", [], {}]),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=False, allow_infinity=False, width=64),
    st.text(max_size=6),
    st.booleans(),
    st.lists(st.integers(-3, 300), max_size=3),
    st.lists(st.floats(-1e3, 1e3), max_size=3),
    st.dictionaries(st.sampled_from(["a", "n", "x"]), st.integers(-2, 2), max_size=2),
)


def _paths(doc, prefix=()):
    for key, val in doc.items():
        yield (*prefix, key)
        if isinstance(val, dict):
            yield from _paths(val, (*prefix, key))


def _keys(doc) -> set:
    out = set()
    for path in _paths(doc):
        out.add(path[-1])
        out.add(".".join(path))
    return out


@st.composite
def mutated_recipes(draw):
    """A shipped recipe with 1–3 keys dropped, renamed (one letter changed or a new name) or
    given a value of another type or an extreme one."""
    name = draw(st.sampled_from(sorted(RECIPES)))
    doc = copy.deepcopy(RECIPES[name])
    for _ in range(draw(st.integers(1, 3))):
        paths = list(_paths(doc))
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        table = doc
        for key in path[:-1]:
            table = table[key]
        key = path[-1]
        op = draw(st.sampled_from(["drop", "rename", "retype", "retype", "retype"]))
        if op == "drop":
            del table[key]
        elif op == "rename":
            new = draw(st.sampled_from([key[:-1] or "x", key + "s", key.upper(), "unknown_key"]))
            table[new] = table.pop(key)
        else:
            table[key] = draw(ODD_VALUES)
    return name, doc


def _refusal_names_a_key(exc: PhylocError, *docs) -> bool:
    msg = str(exc)
    keys = set().union(*(_keys(d) for d in docs)) | {"kind", "recipe", "name", "seed"}
    return any(k and k in msg for k in keys)


@given(mutated_recipes())
def test_a_mutated_recipe_is_accepted_or_refused_by_key(case):
    name, doc = case
    text = dumps_toml(doc)
    try:
        validate_recipe(load_recipe("\n" + text))
    except PhylocError as exc:
        assert _refusal_names_a_key(exc, doc, RECIPES[name]), f"{name}: {exc}"


@given(mutated_recipes())
def test_the_cli_refuses_a_bad_recipe_in_one_line_before_any_work(tmp_path_factory, case):
    """Where the recipe is refused, ``evaluate`` / ``generate`` exit 2 with one line and
    create nothing (accepted recipes are not run here: that would be real work)."""
    name, doc = case
    text = dumps_toml(doc)
    try:
        recipe = load_recipe("\n" + text)
        validate_recipe(recipe)
    except PhylocError:
        pass
    else:
        return
    folder = tmp_path_factory.mktemp("fuzz")
    path = folder / "r.toml"
    path.write_text(text)
    import contextlib
    import io

    err = io.StringIO()
    kind = doc.get("kind")
    argv = ["generate", str(path), "-o", str(folder / "o.h5")]
    if kind != "dataset":
        argv = ["evaluate", str(path), "--out", str(folder / "out")]
    with contextlib.redirect_stderr(err):
        code = main(argv)
    lines = err.getvalue().strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("phyloc: error:"), (name, lines)
    assert sorted(p.name for p in folder.iterdir()) == ["r.toml"]


@given(st.sampled_from(sorted(RECIPES)), st.binary(min_size=1, max_size=12), st.data())
def test_random_bytes_in_a_recipe_are_a_recipe_error_or_harmless(name, junk, data):
    raw = (ROOT / "datasets" / name).read_bytes()
    at = data.draw(st.integers(0, len(raw)))
    broken = raw[:at] + junk + raw[at:]
    try:
        text = broken.decode("utf-8")
    except UnicodeDecodeError:
        return  # the file-level check (test_cli) covers non-UTF-8 files
    try:
        validate_recipe(load_recipe("\n" + text if "=" not in text else text))
    except PhylocError:
        pass

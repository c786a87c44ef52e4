"""The package's structure: imports never run back up the layers (``docs/guide/design.rst``).

The import graph is built from the source with ``ast`` (every ``import`` and ``from … import``,
also those inside functions), so the test needs no import of the package itself.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "phyloc"

#: Bottom to top. A module may import only from its own layer or below.
LAYERS = [
    ["phyloc", "phyloc.errors", "phyloc._validate", "phyloc._jit"],
    # reporting records the FFT backend in its metadata; parallel keeps each task's Numba
    # kernels and FFTs to its share of the cores
    ["phyloc.phy", "phyloc.reporting", "phyloc.parallel"],
    ["phyloc.channels", "phyloc.network", "phyloc.config"],
    ["phyloc.ranging", "phyloc.analysis"],
    ["phyloc.localization"],
    ["phyloc.control", "phyloc.datasets"],
    ["phyloc.evaluation"],
    ["phyloc.commands"],
    ["phyloc.cli"],
]
FAMILIES = ["direct", "tracking", "static"]


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path) -> set[str]:
    """Absolute names of the phyloc modules (or packages) that ``path`` imports."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = _module_name(path)
    if path.name != "__init__.py":
        package = package.rpartition(".")[0]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.split(".")[0] == "phyloc")
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                mod = ".".join([*base, node.module] if node.module else base)
            else:
                mod = node.module or ""
            if mod.split(".")[0] != "phyloc":
                continue
            out.add(mod)
            for a in node.names:  # `from phyloc.x import y` may import the module x.y
                if (ROOT.parent / (mod + "." + a.name).replace(".", "/")).with_suffix(
                    ".py"
                ).exists() or (ROOT.parent / (mod + "." + a.name).replace(".", "/")).is_dir():
                    out.add(f"{mod}.{a.name}")
    return out


def _layer(module: str) -> int:
    best, level = -1, None
    for i, group in enumerate(LAYERS):
        for prefix in group:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best:
                best, level = len(prefix), i
    if level is None:
        raise AssertionError(f"{module} belongs to no layer; add it to LAYERS")
    return level


def _graph() -> dict[str, set[str]]:
    return {_module_name(p): _imports(p) for p in sorted(ROOT.rglob("*.py"))}


def _family(module: str) -> str | None:
    m = re.match(r"phyloc\.localization\.(direct|tracking|static)(\.|$)", module)
    return m.group(1) if m else None


def test_graph_is_read():
    g = _graph()
    assert "phyloc.localization.particles" in g
    assert "phyloc.phy" in g["phyloc.localization.direct.likelihoods"] or any(
        m.startswith("phyloc.phy.") for m in g["phyloc.localization.direct.likelihoods"]
    )


def test_no_import_runs_up_the_layers():
    bad = [
        f"{mod} (layer {_layer(mod)}) imports {imp} (layer {_layer(imp)})"
        for mod, imps in _graph().items()
        for imp in imps
        if _layer(imp) > _layer(mod)
    ]
    assert not bad, "\n".join(bad)


def test_localization_families_do_not_import_each_other():
    bad = []
    for mod, imps in _graph().items():
        fam = _family(mod)
        for imp in imps:
            other = _family(imp)
            if other is None:
                continue
            if fam is not None and other != fam:
                bad.append(f"{mod} imports {imp}")
            if (
                fam is None
                and mod.startswith("phyloc.localization.")
                and mod != "phyloc.localization"
            ):
                bad.append(f"shared module {mod} imports family module {imp}")
    assert not bad, "\n".join(bad)


def test_no_numpy_twin_ships_in_the_package():
    pattern = re.compile(r"^\s*def\s+(\w+_numpy)\s*\(", re.M)
    found = [
        f"{p.relative_to(ROOT.parent)}: {name}"
        for p in ROOT.rglob("*.py")
        for name in pattern.findall(p.read_text(encoding="utf-8"))
    ]
    assert not found, "twins belong in tests/naive_*.py:\n" + "\n".join(found)


@pytest.mark.parametrize("bad", ["phyloc.evaluation.metrics", "phyloc.cli"])
def test_the_layer_check_catches_an_upward_import(bad):
    assert _layer(bad) > _layer("phyloc.localization.particles")


def test_every_package_is_installed():
    """A sub-package missing from pyproject's package list imports from a checkout but not
    from an installed wheel (the test suite runs from the checkout and would not notice)."""
    import tomllib

    listed = set(
        tomllib.loads((ROOT.parent / "pyproject.toml").read_text())["tool"]["setuptools"][
            "packages"
        ]
    )
    packages = {_module_name(p.parent / "__init__.py") for p in ROOT.rglob("__init__.py")}
    assert packages <= listed, f"add to pyproject's packages: {sorted(packages - listed)}"
